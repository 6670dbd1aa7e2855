//! The scene: shapes with materials, lights, camera, and the visibility
//! queries the integrators use: [`Scene::intersect`] (closest hit),
//! [`Scene::occluded`] (any hit) and [`Scene::visit_segment`] (the objects
//! along a shadow ray, for light passing through glass).

mod batch;
mod camera;
pub mod desc;
pub mod files;
mod light;
mod load;
mod material;
mod mesh_scene;
pub mod meshio;
mod texture;

#[cfg(target_arch = "x86_64")]
pub(crate) use batch::simd_level;
pub(crate) use batch::widest;
pub use camera::Camera;
pub use desc::SceneDesc;
pub use light::Light;
pub use load::{
    BUILTIN_WHITTED, SceneError, SceneFile, load_scene_file, parse_scene, parse_scene_desc,
    parse_scene_json,
};
pub use material::{Material, MaterialKind};
pub use mesh_scene::{MeshSceneError, mesh_scene};
pub use texture::{CheckerMode, Texture, is_even};

use crate::accel::{Bvh, PACKET, Tlas, TraversalCounters};
pub use crate::geometry::TraceCounters;
use crate::geometry::batch::{Closest, NO_HIT};
use crate::geometry::{Shape, ShapeHit, SurfacePoint};
use crate::light::LightSet;
use crate::math::{Aabb, Color, Ray, Vec3};

/// A shape with a material (an index into [`Scene::materials`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Object {
    pub shape: Shape,
    pub material: u32,
}

/// The closest hit of a ray: the object and the shape's hit record.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub object: u32,
    pub shape: ShapeHit,
}

impl Closest {
    /// Ray `j`'s hit in the batch's answer ([`Scene::intersect_batch`]),
    /// as [`Scene::intersect`] gives it, if it hit anything.
    #[inline]
    pub fn hit(&self, j: usize) -> Option<Hit> {
        let t = self.t[j];
        (self.object[j] != NO_HIT).then(|| Hit {
            t,
            object: self.object[j],
            shape: ShapeHit {
                t,
                prim: self.prim[j],
                ..ShapeHit::default()
            },
        })
    }
}

/// Everything shading needs to know about a hit point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceInteraction {
    pub p: Vec3,
    /// Bound on the absolute error of `p`, for offsetting spawned rays.
    pub p_err: Vec3,
    /// Unit geometric normal (outward for closed shapes).
    pub n: Vec3,
    /// Unit shading normal (interpolated on smooth meshes, else `n`).
    pub ns: Vec3,
    pub material: u32,
    pub object: u32,
    pub prim: u32,
}

/// Sizes of a scene's geometry (see [`Scene::geometry_stats`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct GeometryStats {
    /// Distinct triangles in memory.
    pub triangles: u64,
    /// Triangles counting every instance.
    pub triangles_instanced: u64,
    pub meshes: u64,
    pub instances: u64,
    /// Nodes of all BVHs (meshes and the top level).
    pub bvh_nodes: u64,
    /// Bytes of BVH nodes and index arrays.
    pub bvh_bytes: u64,
    /// Bytes of mesh data: vertices, normals, uvs, triangles and BVHs.
    pub mesh_bytes: u64,
}

#[derive(Clone, Debug)]
pub struct Scene {
    pub camera: Camera,
    pub objects: Vec<Object>,
    pub materials: Vec<Material>,
    pub lights: Vec<Light>,
    /// Radiance of rays that leave the scene.
    pub background: Color,
    /// Ambient light `A` of Whitted's model.
    pub ambient: Color,
    /// The lights the integrators sample: `lights`, the emissive objects'
    /// area lights and the environment (see [`LightSet::build`]).
    pub emitters: LightSet,
    /// An environment map seen by rays that leave the scene, instead of
    /// `background` (see [`Scene::with_environment`]).
    pub environment: Option<std::sync::Arc<crate::light::EnvMap>>,
    /// Per object: does its material stop shadow rays?
    opaque: Vec<bool>,
    /// The objects' top-level acceleration structure.
    tlas: Tlas,
    /// Few objects: test them in a plain loop, which beats the traversal's
    /// bookkeeping (by 20% of a Whitted frame with 3 objects).
    linear: bool,
    /// A box around everything a ray can hit, enlarged against rounding;
    /// `None` where some object is unbounded (see [`Scene::camera_misses`]).
    reach: Option<Aabb>,
    /// Small opaque meshes merged into one, traced with one BVH instead of
    /// one per object (see [`Merged`]); they are left out of `tlas`.
    merged: Option<Box<Merged>>,
}

/// Opaque meshes of a scene merged into one world-space mesh for tracing.
/// A ray then traverses one BVH over all their triangles instead of one per
/// object (a Cornell box made of 8 meshes traces 4× faster). Hits are
/// mapped back to the objects, whose own data give the surface.
#[derive(Clone, Debug)]
struct Merged {
    /// Three vertices of its own per triangle, so that the BVH's reordering
    /// of triangles leaves `triangles[k][0] / 3` naming the original one.
    mesh: crate::geometry::Mesh,
    /// Per original triangle: its object and its index there.
    owners: Vec<(u32, u32)>,
}

/// At most this many triangles are merged (the merged mesh is a copy).
const MERGE_TRIANGLES: usize = 1 << 20;

impl Merged {
    /// Merges the meshes of `objects` that are opaque, have a mesh of their
    /// own (not instanced) and hold at most [`MERGE_TRIANGLES`] in all, if
    /// there are at least two; returns the merged mesh and which objects it
    /// holds.
    fn build(objects: &[Object], opaque: &[bool]) -> Option<(Merged, Vec<bool>)> {
        let mut uses = std::collections::HashMap::new();
        for o in objects {
            if let Shape::Mesh(m) = &o.shape {
                *uses.entry(std::sync::Arc::as_ptr(&m.mesh)).or_insert(0) += 1;
            }
        }
        let mut taken = vec![false; objects.len()];
        let mut total = 0;
        for (i, o) in objects.iter().enumerate() {
            if let Shape::Mesh(m) = &o.shape
                && opaque[i]
                && uses[&std::sync::Arc::as_ptr(&m.mesh)] == 1
                && total + m.mesh.triangles.len() <= MERGE_TRIANGLES
            {
                taken[i] = true;
                total += m.mesh.triangles.len();
            }
        }
        if taken.iter().filter(|&&t| t).count() < 2 {
            return None;
        }
        let mut positions = Vec::with_capacity(3 * total);
        let mut owners = Vec::with_capacity(total);
        for (i, o) in objects.iter().enumerate() {
            let Shape::Mesh(m) = &o.shape else { continue };
            if !taken[i] {
                continue;
            }
            for prim in 0..m.mesh.triangles.len() as u32 {
                positions.extend(m.world_triangle(prim).map(glam::Vec3::from));
                owners.push((i as u32, prim));
            }
        }
        let triangles = (0..total as u32)
            .map(|k| [3 * k, 3 * k + 1, 3 * k + 2])
            .collect();
        // World positions of valid meshes are finite unless a transform
        // overflowed them; then nothing is merged.
        let mesh = crate::geometry::Mesh::new(positions, triangles, Vec::new(), Vec::new()).ok()?;
        Some((Merged { mesh, owners }, taken))
    }

    /// The scene hit of a hit on the merged mesh.
    #[inline]
    fn hit(&self, h: ShapeHit) -> Hit {
        let original = self.mesh.triangles[h.prim as usize][0] / 3;
        let (object, prim) = self.owners[original as usize];
        Hit {
            t: h.t,
            object,
            shape: ShapeHit { prim, ..h },
        }
    }
}

/// Why [`Scene::new`] could not build a scene from its parts.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SceneBuildError {
    #[error("object {object} has material {material}, but there are only {count} materials")]
    MaterialOutOfRange {
        object: usize,
        material: u32,
        count: usize,
    },
    #[error(
        "the scene has {count} emissive triangles and faces (each an area light of about 100 bytes); at most {} are accepted",
        crate::light::MAX_AREA_LIGHTS
    )]
    TooManyLights { count: u64 },
}

/// Up to this many objects, rays test them one by one instead of using the
/// top-level BVH.
const LINEAR_OBJECTS: usize = 8;

impl Scene {
    /// Builds the top-level BVH over the objects and the lights. Fails if an
    /// object names a material index out of range of `materials`, or if
    /// emissive meshes would make more than [`crate::light::MAX_AREA_LIGHTS`]
    /// area lights.
    pub fn new(
        camera: Camera,
        objects: Vec<Object>,
        materials: Vec<Material>,
        lights: Vec<Light>,
        background: Color,
        ambient: Color,
    ) -> Result<Self, SceneBuildError> {
        if let Some((object, o)) = objects
            .iter()
            .enumerate()
            .find(|(_, o)| o.material as usize >= materials.len())
        {
            return Err(SceneBuildError::MaterialOutOfRange {
                object,
                material: o.material,
                count: materials.len(),
            });
        }
        let area_lights = crate::light::area_light_count(&objects, &materials);
        if area_lights > crate::light::MAX_AREA_LIGHTS {
            return Err(SceneBuildError::TooManyLights { count: area_lights });
        }
        let opaque: Vec<bool> = objects
            .iter()
            .map(|o| materials[o.material as usize].is_opaque())
            .collect();
        let mut bounds: Vec<Aabb> = objects.iter().map(|o| o.shape.bounds()).collect();
        let reach = bounds
            .iter()
            .try_fold(Aabb::EMPTY, |all, b| {
                (b.min.is_finite() && b.max.is_finite()).then(|| all.union(b))
            })
            .map(|b| {
                if b.min.cmpgt(b.max).any() {
                    return b;
                }
                // A thousandth of the box's size and of its distance from
                // the origin: far beyond the f32 rounding of any ray test.
                let margin = Vec3::splat(
                    1e-3 * ((b.max - b.min).max_element()
                        + b.min.abs().max(b.max.abs()).max_element()),
                );
                Aabb::new(b.min - margin, b.max + margin)
            });
        // Merged objects are traced in the merged mesh only (their empty
        // boxes are left out of the top-level BVH; meshes are never
        // unbounded).
        let merged = Merged::build(&objects, &opaque).map(|(m, taken)| {
            for (b, t) in bounds.iter_mut().zip(taken) {
                if t {
                    *b = Aabb::EMPTY;
                }
            }
            Box::new(m)
        });
        let tlas = Tlas::build(&bounds);
        let objects_len = objects.len();
        let emitters = LightSet::build(&objects, &materials, &lights, background, None);
        Ok(Scene {
            camera,
            objects,
            materials,
            lights,
            background,
            ambient,
            emitters,
            environment: None,
            opaque,
            tlas,
            linear: objects_len <= LINEAR_OBJECTS && merged.is_none(),
            reach,
            merged,
        })
    }

    /// The scene with an environment map: rays that leave it see the map,
    /// and the path integrator samples it as a light.
    pub fn with_environment(mut self, map: crate::light::EnvMap) -> Self {
        let map = std::sync::Arc::new(map);
        self.emitters = LightSet::build(
            &self.objects,
            &self.materials,
            &self.lights,
            self.background,
            Some(&map),
        );
        self.environment = Some(map);
        self
    }

    /// Radiance seen along a ray (unit direction `d`) that leaves the scene.
    #[inline]
    pub fn background_le(&self, d: Vec3) -> Color {
        match &self.environment {
            Some(map) => map.le(d.normalize()),
            None => self.background,
        }
    }

    /// Counts and sizes of the scene's meshes and acceleration structures.
    /// Meshes shared by several instances are counted once in `triangles`.
    pub fn geometry_stats(&self) -> GeometryStats {
        let mut seen = std::collections::HashSet::new();
        let mut g = GeometryStats {
            bvh_nodes: self.tlas.bvh().node_count() as u64,
            bvh_bytes: self.tlas.bvh().bytes() as u64,
            ..GeometryStats::default()
        };
        for o in &self.objects {
            if let Shape::Mesh(m) = &o.shape {
                g.instances += 1;
                g.triangles_instanced += m.mesh.triangles.len() as u64;
                if seen.insert(std::sync::Arc::as_ptr(&m.mesh)) {
                    g.meshes += 1;
                    g.triangles += m.mesh.triangles.len() as u64;
                    g.bvh_nodes += m.mesh.bvh.nodes.len() as u64;
                    g.bvh_bytes += m.mesh.bvh.bytes() as u64;
                    g.mesh_bytes += m.mesh.bytes() as u64;
                }
            }
        }
        g
    }

    /// The top-level BVH (over objects with finite bounds).
    pub fn tlas(&self) -> &Bvh {
        self.tlas.bvh()
    }

    /// The closest hit with `t ∈ [ray.t_min, ray.t_max)`: the unbounded
    /// objects (planes) one by one, then the top-level BVH, which visits
    /// objects front to back and prunes by the closest hit so far.
    #[inline]
    pub fn intersect(&self, ray: &Ray, counters: &mut TraceCounters) -> Option<Hit> {
        if self.linear {
            let mut ray = *ray;
            let mut closest = None;
            let mut object = 0;
            for (i, o) in self.objects.iter().enumerate() {
                if let Some(h) = o.shape.intersect(&ray, counters) {
                    ray.t_max = h.t;
                    closest = Some(h);
                    object = i as u32;
                }
            }
            counters.intersection_tests += self.objects.len() as u64;
            return closest.map(|h| Hit {
                t: h.t,
                object,
                shape: h,
            });
        }
        self.intersect_tlas(*ray, counters)
    }

    /// [`Scene::intersect`] for each ray of `rays` (at most [`PACKET`],
    /// coherent ones, such as neighbouring camera rays) into `out`. In a
    /// scene of few objects, each mesh takes all the rays at once
    /// ([`crate::geometry::MeshInstance::intersect_packet`]: as a packet
    /// where their spacing against its triangles makes that pay) and
    /// other shapes take them one by one; a scene with a top-level BVH
    /// traces the mesh merged from its small meshes (see [`Merged`]) as a
    /// packet, and the rest ray by ray. Each ray gets the same `t`, object
    /// and counts of object tests as from `Scene::intersect`; where two
    /// triangles of a mesh are hit at exactly that `t`, either may be named.
    pub fn intersect_packet(
        &self,
        rays: &[Ray],
        counters: &mut TraceCounters,
        out: &mut [Option<Hit>],
    ) {
        assert!(rays.len() <= PACKET && out.len() == rays.len());
        if !self.linear {
            // The merged mesh as a packet, the rest ray by ray.
            let mut merged = [None; PACKET];
            let merged = &mut merged[..rays.len()];
            if let Some(m) = &self.merged {
                m.mesh.intersect_packet(rays, counters, merged);
            }
            for ((o, r), h) in out.iter_mut().zip(rays).zip(merged) {
                *o = self.intersect_tlas_after(*r, *h, counters);
            }
            return;
        }
        let mut segments = [Ray::new(Vec3::ZERO, Vec3::X); PACKET];
        segments[..rays.len()].copy_from_slice(rays);
        let segments = &mut segments[..rays.len()];
        out.fill(None);
        let mut hits = [None; PACKET];
        for (i, o) in self.objects.iter().enumerate() {
            let hits = &mut hits[..rays.len()];
            match &o.shape {
                Shape::Mesh(m) => m.intersect_packet(segments, counters, hits),
                shape => {
                    for (h, r) in hits.iter_mut().zip(segments.iter()) {
                        *h = shape.intersect(r, counters);
                    }
                }
            }
            for ((h, r), out) in hits.iter().zip(segments.iter_mut()).zip(out.iter_mut()) {
                if let Some(h) = *h {
                    r.t_max = h.t;
                    *out = Some(Hit {
                        t: h.t,
                        object: i as u32,
                        shape: h,
                    });
                }
            }
        }
        counters.intersection_tests += (self.objects.len() * rays.len()) as u64;
    }

    /// [`Scene::intersect`] through the top-level BVH (many objects).
    #[inline(never)]
    fn intersect_tlas(&self, ray: Ray, counters: &mut TraceCounters) -> Option<Hit> {
        let merged = self
            .merged
            .as_ref()
            .and_then(|m| m.mesh.intersect_object(&ray, counters));
        self.intersect_tlas_after(ray, merged, counters)
    }

    /// [`Scene::intersect_tlas`] given the ray's closest hit on the merged
    /// mesh, if any.
    #[inline(always)]
    fn intersect_tlas_after(
        &self,
        mut ray: Ray,
        merged: Option<ShapeHit>,
        counters: &mut TraceCounters,
    ) -> Option<Hit> {
        let mut closest = None;
        if let (Some(m), Some(h)) = (&self.merged, merged) {
            ray.t_max = h.t;
            closest = Some(m.hit(h));
        }
        let mut tests = 0;
        let mut top = TraversalCounters::default();
        self.tlas.closest(&ray, &mut top, |i, t_max| {
            tests += 1;
            let r = Ray { t_max, ..ray };
            let h = self.objects[i as usize].shape.intersect(&r, counters)?;
            closest = Some(Hit {
                t: h.t,
                object: i,
                shape: h,
            });
            Some(h.t)
        });
        counters.intersection_tests += tests;
        counters.bvh.nodes_visited += top.nodes_visited;
        closest
    }

    /// Whether every camera ray through the film rectangle `[x0, x1] × [y0,
    /// y1]` (in pixels, of a `width × height` image) certainly misses every
    /// object, so that a tile of them need not be traced (frustum culling of
    /// a coherent bundle of rays).
    ///
    /// The rays form a pyramid from the eye spanned by the rectangle's
    /// corner directions (a camera ray's unnormalised direction is affine in
    /// the film point); the rectangle is widened by a pixel on every side.
    /// They miss when the box around all objects (enlarged by a thousandth,
    /// see `reach`) lies wholly outside one of the pyramid's four side
    /// planes, tested in f64 at its eight corners. False for scenes with
    /// unbounded objects (planes).
    pub fn camera_misses(
        &self,
        x0: f32,
        x1: f32,
        y0: f32,
        y1: f32,
        width: u32,
        height: u32,
    ) -> bool {
        let Some(reach) = &self.reach else {
            return false;
        };
        if reach.min.cmpgt(reach.max).any() {
            // Nothing to hit.
            return true;
        }
        let c = &self.camera;
        let (f, r, u) = (
            c.forward().as_dvec3(),
            c.right().as_dvec3(),
            c.up().as_dvec3(),
        );
        let (w, h) = (width as f64, height as f64);
        let tan = (c.tan_half_fov() as f64).max(0.0);
        let aspect = w / h;
        let dir = |x: f64, y: f64| {
            let sx = (2.0 * x / w - 1.0) * tan * aspect;
            let sy = (1.0 - 2.0 * y / h) * tan;
            f + r * sx + u * sy
        };
        let (x0, x1) = (x0 as f64 - 1.0, x1 as f64 + 1.0);
        let (y0, y1) = (y0 as f64 - 1.0, y1 as f64 + 1.0);
        let corners = [dir(x0, y0), dir(x1, y0), dir(x1, y1), dir(x0, y1)];
        let centre = dir((x0 + x1) * 0.5, (y0 + y1) * 0.5);
        let eye = c.position.as_dvec3();
        let (lo, hi) = (reach.min.as_dvec3() - eye, reach.max.as_dvec3() - eye);
        (0..4).any(|k| {
            let n = corners[k].cross(corners[(k + 1) % 4]);
            // Inward: towards the rectangle's centre.
            let n = if n.dot(centre) < 0.0 { -n } else { n };
            // The box corner farthest along n.
            let p = glam::DVec3::new(
                if n.x >= 0.0 { hi.x } else { lo.x },
                if n.y >= 0.0 { hi.y } else { lo.y },
                if n.z >= 0.0 { hi.z } else { lo.z },
            );
            n.dot(p) < 0.0
        })
    }

    /// The surface at a hit returned by [`Scene::intersect`] for the same ray.
    #[inline]
    pub fn surface(&self, ray: &Ray, hit: &Hit) -> SurfaceInteraction {
        let object = &self.objects[hit.object as usize];
        let SurfacePoint { p, p_err, n, ns } = object.shape.surface(ray, &hit.shape);
        SurfaceInteraction {
            p,
            p_err,
            n,
            ns,
            material: object.material,
            object: hit.object,
            prim: hit.shape.prim,
        }
    }

    /// The colour of the surface's material at the point (its texture).
    #[inline]
    pub fn albedo(&self, si: &SurfaceInteraction) -> Color {
        let shape = &self.objects[si.object as usize].shape;
        self.materials[si.material as usize]
            .texture
            .eval(si.p, || shape.uv(si.p, si.prim))
    }

    /// Whether anything at all lies on the ray's segment (any-hit: stops at the
    /// first object found).
    #[inline]
    pub fn occluded(&self, ray: &Ray, counters: &mut TraceCounters) -> bool {
        let mut tests = 0;
        if self.linear {
            let hit = self.objects.iter().any(|o| {
                tests += 1;
                o.shape.occludes(ray, counters)
            });
            counters.intersection_tests += tests;
            return hit;
        }
        self.occluded_tlas(ray, counters)
    }

    #[inline(never)]
    fn occluded_tlas(&self, ray: &Ray, counters: &mut TraceCounters) -> bool {
        if let Some(m) = &self.merged
            && m.mesh.occludes_object(ray, counters)
        {
            counters.intersection_tests += 1;
            return true;
        }
        let mut tests = 0;
        let mut top = TraversalCounters::default();
        let hit = self.tlas.any(ray, &mut top, |i| {
            tests += 1;
            self.objects[i as usize].shape.occludes(ray, counters)
        });
        counters.intersection_tests += tests;
        counters.bvh.nodes_visited += top.nodes_visited;
        hit
    }

    /// Calls `visit(object, counters)` for the objects that may meet the
    /// ray's segment (all of them, or those whose bounds it meets), until
    /// one call returns true; returns whether one did. Merged meshes (which
    /// are opaque) are tested first: if they meet the segment, nothing is
    /// visited and the answer is true. What `visit` does with an object is
    /// the caller's: the scene knows visibility, not light.
    #[inline]
    pub fn visit_segment(
        &self,
        ray: &Ray,
        counters: &mut TraceCounters,
        mut visit: impl FnMut(u32, &mut TraceCounters) -> bool,
    ) -> bool {
        if self.linear {
            for i in 0..self.objects.len() as u32 {
                if visit(i, counters) {
                    counters.intersection_tests += i as u64 + 1;
                    return true;
                }
            }
            counters.intersection_tests += self.objects.len() as u64;
            return false;
        }
        if let Some(m) = &self.merged
            && m.mesh.occludes_object(ray, counters)
        {
            counters.intersection_tests += 1;
            return true;
        }
        self.visit_segment_tlas(ray, counters, visit)
    }

    /// [`Scene::visit_segment`] after the merged mesh: the objects of the
    /// top-level BVH.
    #[inline]
    fn visit_segment_tlas(
        &self,
        ray: &Ray,
        counters: &mut TraceCounters,
        mut visit: impl FnMut(u32, &mut TraceCounters) -> bool,
    ) -> bool {
        let mut tests = 0;
        let mut top = TraversalCounters::default();
        let mut counted = |i: u32, counters: &mut TraceCounters| {
            tests += 1;
            visit(i, counters)
        };
        let hit = self.tlas.any(ray, &mut top, |i| counted(i, counters));
        counters.intersection_tests += tests;
        counters.bvh.nodes_visited += top.nodes_visited;
        hit
    }

    /// Which of up to [`PACKET`] segments (`rays`) an opaque object
    /// blocks, into `blocked`, as [`Scene::visit_segment`] finds it for
    /// each with a visitor that answers [`Shape::occludes`] for opaque
    /// objects and calls `pass(object, ray, counters)` for the others
    /// (and answers false): `pass` is called for the same objects and
    /// rays, in the same order for each ray, and the counts of object
    /// tests are the same. Meshes (and the merged mesh) are tested for
    /// the rays not yet blocked together, as a packet
    /// ([`crate::geometry::Mesh::occludes_packet`]); the rest ray by ray.
    pub fn segments_packet(
        &self,
        rays: &[Ray],
        counters: &mut TraceCounters,
        blocked: &mut [bool],
        mut pass: impl FnMut(u32, usize, &mut TraceCounters),
    ) {
        let n = rays.len();
        assert!(n <= PACKET && blocked.len() == n);
        blocked.fill(false);
        let mut hit = [false; PACKET];
        if !self.linear {
            if let Some(m) = &self.merged {
                m.mesh.occludes_packet(rays, counters, &mut hit[..n]);
            }
            for (j, (b, ray)) in blocked.iter_mut().zip(rays).enumerate() {
                if hit[j] {
                    counters.intersection_tests += 1;
                    *b = true;
                    continue;
                }
                *b = self.visit_segment_tlas(ray, counters, |i, counters| {
                    if self.is_opaque(i) {
                        return self.objects[i as usize].shape.occludes(ray, counters);
                    }
                    pass(i, j, counters);
                    false
                });
            }
            return;
        }
        let mut open = n;
        for (i, o) in self.objects.iter().enumerate() {
            if open == 0 {
                break;
            }
            let i = i as u32;
            // Ray blocked here: its tests are those of objects 0 to i.
            let mut block = |b: &mut bool, counters: &mut TraceCounters| {
                *b = true;
                open -= 1;
                counters.intersection_tests += u64::from(i) + 1;
            };
            match &o.shape {
                Shape::Mesh(m) if self.is_opaque(i) => {
                    // The rays still open, side by side.
                    let mut sub = [Ray::new(Vec3::ZERO, Vec3::X); PACKET];
                    let mut index = [0usize; PACKET];
                    let mut k = 0;
                    for (j, ray) in rays.iter().enumerate() {
                        if !blocked[j] {
                            (sub[k], index[k]) = (*ray, j);
                            k += 1;
                        }
                    }
                    m.occludes_packet(&sub[..k], counters, &mut hit[..k]);
                    for q in 0..k {
                        if hit[q] {
                            block(&mut blocked[index[q]], counters);
                        }
                    }
                }
                shape if self.is_opaque(i) => {
                    for (b, ray) in blocked.iter_mut().zip(rays) {
                        if !*b && shape.occludes(ray, counters) {
                            block(b, counters);
                        }
                    }
                }
                _ => {
                    for (j, &b) in blocked.iter().enumerate() {
                        if !b {
                            pass(i, j, counters);
                        }
                    }
                }
            }
        }
        counters.intersection_tests += (self.objects.len() * open) as u64;
    }

    /// Whether object `i`'s material stops shadow rays (all but dielectrics).
    #[inline(always)]
    pub fn is_opaque(&self, i: u32) -> bool {
        self.opaque[i as usize]
    }
}
