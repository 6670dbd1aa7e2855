//! The scene: shapes with materials, lights, camera, and the two queries the
//! integrators use, [`Scene::intersect`] (closest hit) and the shadow-ray
//! queries [`Scene::occluded`] and [`Scene::transmittance`].

mod camera;
mod light;
mod load;
mod material;
mod texture;

pub use camera::Camera;
pub use light::Light;
pub use load::{BUILTIN_WHITTED, SceneError, SceneFile, load_scene_file, parse_scene};
pub use material::{Fresnel, Material, MaterialKind, fresnel_dielectric, reflect, refract};
pub use texture::{CheckerMode, Texture};

pub use crate::geometry::TraceCounters;
use crate::geometry::{Shape, ShapeHit, SurfacePoint};
use crate::math::{Color, Ray, Vec3};

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
    /// Per object: does its material stop shadow rays?
    opaque: Vec<bool>,
}

impl Scene {
    /// # Panics
    /// If an object names a material index out of range (the loader checks
    /// names before building).
    pub fn new(
        camera: Camera,
        objects: Vec<Object>,
        materials: Vec<Material>,
        lights: Vec<Light>,
        background: Color,
        ambient: Color,
    ) -> Self {
        let opaque = objects
            .iter()
            .map(|o| materials[o.material as usize].is_opaque())
            .collect();
        Scene {
            camera,
            objects,
            materials,
            lights,
            background,
            ambient,
            opaque,
        }
    }

    /// The closest hit with `t ∈ [ray.t_min, ray.t_max)`.
    ///
    /// Tests every object, shrinking `t_max` as hits are found. The scenes of
    /// Whitted's kind hold a handful of objects, for which a list is faster than
    /// any hierarchy; a top-level BVH over objects comes with meshes (issue 3).
    #[inline]
    pub fn intersect(&self, ray: &Ray, counters: &mut TraceCounters) -> Option<Hit> {
        let mut ray = *ray;
        let mut closest = None;
        for (i, object) in self.objects.iter().enumerate() {
            if let Some(h) = object.shape.intersect(&ray, counters) {
                ray.t_max = h.t;
                closest = Some(Hit {
                    t: h.t,
                    object: i as u32,
                    shape: h,
                });
            }
        }
        counters.intersection_tests += self.objects.len() as u64;
        closest
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
        for (i, object) in self.objects.iter().enumerate() {
            if object.shape.occludes(ray, counters) {
                counters.intersection_tests += i as u64 + 1;
                return true;
            }
        }
        counters.intersection_tests += self.objects.len() as u64;
        false
    }

    /// The fraction of light that passes along a shadow ray's segment.
    ///
    /// Opaque objects block it (returns black at the first one found).
    /// Dielectrics let it through straight, without bending it: each crossing
    /// of their surface passes the Fresnel transmittance for light entering the
    /// medium at that angle, and the path inside is attenuated by the
    /// material's absorption. So glass casts a light, coloured shadow that
    /// darkens towards its rim; the focusing of light by glass (caustics) is
    /// not rendered, as in Whitted's ray tracer.
    pub fn transmittance(&self, ray: &Ray, counters: &mut TraceCounters) -> Color {
        let mut tr = Color::ONE;
        for (i, (object, &opaque)) in self.objects.iter().zip(&self.opaque).enumerate() {
            if opaque {
                if object.shape.occludes(ray, counters) {
                    counters.intersection_tests += i as u64 + 1;
                    return Color::ZERO;
                }
                continue;
            }
            if let MaterialKind::Dielectric { ior, absorption } =
                self.materials[object.material as usize].kind
            {
                let mut passed = 1.0f32;
                let inside = object.shape.crossings(ray, counters, &mut |cos| {
                    passed *= fresnel_dielectric(cos, 1.0, ior).transmittance;
                });
                tr *= passed;
                if inside > 0.0 && absorption != Color::ZERO {
                    tr *= (-absorption * inside).exp();
                }
            }
        }
        counters.intersection_tests += self.objects.len() as u64;
        tr
    }
}
