//! Instances: a shared [`Mesh`] placed in the world by a transform.

use super::Mesh;
use crate::accel::PACKET;
use crate::geometry::{ShapeHit, SurfacePoint, TraceCounters};
use crate::math::{Aabb, Ray, Transform, Vec3, gamma, normalize_robust};
use glam::{Affine3A, Mat3A, Vec2};
use std::sync::Arc;

/// A mesh placed in the world: a shared mesh and, optionally, a transform.
/// A thousand instances of one mesh cost the memory of one mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshInstance {
    pub mesh: Arc<Mesh>,
    transform: Option<Box<InstanceTransform>>,
    world_bounds: Aabb,
}

/// f32 copies of an instance's transform, for the hot path.
#[derive(Clone, Debug, PartialEq)]
struct InstanceTransform {
    world_from_object: Affine3A,
    object_from_world: Affine3A,
    normal_to_world: Mat3A,
    /// |linear part|, for carrying error bounds to world space.
    abs_linear: Mat3A,
    /// |inverse linear part| and |inverse translation|, for the rounding of
    /// rays taken back into object space.
    abs_inverse: Mat3A,
    abs_inverse_translation: Vec3,
}

impl MeshInstance {
    pub fn new(mesh: Arc<Mesh>, transform: Option<&Transform>) -> Self {
        let transform = transform.filter(|t| **t != Transform::IDENTITY).map(|t| {
            let w = Affine3A::from_mat3_translation(
                t.world_from_object.matrix3.as_mat3(),
                t.world_from_object.translation.as_vec3(),
            );
            let m = w.matrix3;
            let inverse = Affine3A::from_mat3_translation(
                t.object_from_world.matrix3.as_mat3(),
                t.object_from_world.translation.as_vec3(),
            );
            let mi = inverse.matrix3;
            Box::new(InstanceTransform {
                world_from_object: w,
                object_from_world: inverse,
                abs_inverse: Mat3A::from_cols(mi.x_axis.abs(), mi.y_axis.abs(), mi.z_axis.abs()),
                abs_inverse_translation: inverse.translation.abs(),
                normal_to_world: Mat3A::from(t.normal_to_world.as_mat3()),
                abs_linear: Mat3A::from_cols(m.x_axis.abs(), m.y_axis.abs(), m.z_axis.abs()),
            })
        });
        let b = mesh.bounds();
        let world_bounds = match &transform {
            None => b,
            Some(x) => (0..8).fold(Aabb::EMPTY, |acc, i| {
                let c = Vec3::new(
                    if i & 1 == 0 { b.min.x } else { b.max.x },
                    if i & 2 == 0 { b.min.y } else { b.max.y },
                    if i & 4 == 0 { b.min.z } else { b.max.z },
                );
                let w = x.world_from_object.transform_point3a(c);
                acc.union(&Aabb::new(w, w))
            }),
        };
        MeshInstance {
            mesh,
            transform,
            world_bounds,
        }
    }

    pub fn bounds(&self) -> Aabb {
        self.world_bounds
    }

    #[inline(always)]
    fn object_ray(&self, ray: &Ray) -> Ray {
        match &self.transform {
            None => *ray,
            Some(x) => Ray {
                o: x.object_from_world.transform_point3a(ray.o),
                d: x.object_from_world.transform_vector3a(ray.d),
                ..*ray
            },
        }
    }

    /// The world-space corners of triangle `prim` (for area lights).
    pub fn world_triangle(&self, prim: u32) -> [Vec3; 3] {
        let (a, b, c) = self.mesh.vertices(prim);
        match &self.transform {
            None => [a, b, c],
            Some(x) => [a, b, c].map(|v| x.world_from_object.transform_point3a(v)),
        }
    }

    #[inline]
    pub fn intersect(&self, ray: &Ray, counters: &mut TraceCounters) -> Option<ShapeHit> {
        self.mesh.intersect_object(&self.object_ray(ray), counters)
    }

    /// [`MeshInstance::intersect`] for up to [`PACKET`] rays at once
    /// ([`Mesh::intersect_packet`]).
    pub fn intersect_packet(
        &self,
        rays: &[Ray],
        counters: &mut TraceCounters,
        out: &mut [Option<ShapeHit>],
    ) {
        let object = self.object_rays(rays);
        self.mesh
            .intersect_packet(&object[..rays.len()], counters, out);
    }

    #[inline]
    pub fn occludes(&self, ray: &Ray, counters: &mut TraceCounters) -> bool {
        self.mesh.occludes_object(&self.object_ray(ray), counters)
    }

    /// [`MeshInstance::occludes`] for up to [`PACKET`] rays at once
    /// ([`Mesh::occludes_packet`]).
    pub fn occludes_packet(&self, rays: &[Ray], counters: &mut TraceCounters, out: &mut [bool]) {
        let object = self.object_rays(rays);
        self.mesh
            .occludes_packet(&object[..rays.len()], counters, out);
    }

    /// [`MeshInstance::object_ray`] of each of up to [`PACKET`] rays, in
    /// the first `rays.len()` places.
    #[inline(always)]
    fn object_rays(&self, rays: &[Ray]) -> [Ray; PACKET] {
        let mut object = [Ray::new(Vec3::ZERO, Vec3::X); PACKET];
        for (o, r) in object.iter_mut().zip(rays) {
            *o = self.object_ray(r);
        }
        object
    }

    #[inline(never)]
    pub fn surface(&self, _ray: &Ray, hit: &ShapeHit) -> SurfacePoint {
        let s = self.mesh.surface_object(hit);
        match &self.transform {
            None => s,
            Some(x) => {
                let p = x.world_from_object.transform_point3a(s.p);
                // The object-space bound carried through |M|, plus the rounding
                // of the transform itself (pbrt-v4 §6.8.6), plus the rounding
                // a spawned ray's origin meets when it is taken back into this
                // instance's object space (γ(3)(|M⁻¹||p| + |t⁻¹|) there, times
                // |M| here), so that the offset origin stays off the surface
                // in both spaces.
                let back = gamma(3) * (x.abs_inverse * p.abs() + x.abs_inverse_translation);
                SurfacePoint {
                    p,
                    p_err: x.abs_linear * (s.p_err + back)
                        + gamma(3)
                            * (x.abs_linear * s.p.abs() + x.world_from_object.translation.abs()),
                    n: normalize_robust(x.normal_to_world * s.n),
                    ns: normalize_robust(x.normal_to_world * s.ns),
                }
            }
        }
    }

    #[inline(never)]
    pub fn uv(&self, p: Vec3, prim: u32) -> Option<Vec2> {
        let p = match &self.transform {
            None => p,
            Some(x) => x.object_from_world.transform_point3a(p),
        };
        self.mesh.uv_object(p, prim)
    }

    /// See [`super::Shape::crossings`]. The mesh is taken to be closed: the
    /// crossings are found along the whole ray `[t_min, ∞)`, so that their
    /// parity says whether the segment starts inside (a light inside a glass
    /// mesh, say), and the segment's inside length is summed over the
    /// crossings in `t` order, however many there are. `crossing` is called
    /// for those on the segment only. (A ray exactly through an edge, which
    /// both triangles report, counts twice; such rays are rare enough to
    /// leave to one sample's absorption.)
    #[inline(never)]
    pub fn crossings(
        &self,
        ray: &Ray,
        counters: &mut TraceCounters,
        crossing: &mut impl FnMut(f32),
    ) -> f32 {
        let whole = Ray {
            t_max: f32::INFINITY,
            ..self.object_ray(ray)
        };
        // Kept on the stack up to `LOCAL` crossings, on the heap beyond.
        const LOCAL: usize = 64;
        let mut local = [0f32; LOCAL];
        let mut spill: Vec<f32> = Vec::new();
        let mut n = 0;
        self.mesh.all_hits(&whole, counters, |t, cos, _| {
            if t < ray.t_max {
                crossing(cos);
            }
            if n < LOCAL {
                local[n] = t;
            } else {
                if spill.is_empty() {
                    spill.extend_from_slice(&local);
                }
                spill.push(t);
            }
            n += 1;
        });
        let ts = if n <= LOCAL {
            &mut local[..n]
        } else {
            &mut spill[..]
        };
        ts.sort_unstable_by(f32::total_cmp);
        // Inside at t_min iff an odd number of crossings lie beyond it.
        let mut inside = ts.len() % 2 == 1;
        let mut from = ray.t_min;
        let mut length = 0.0;
        for &t in ts.iter() {
            let t = t.min(ray.t_max);
            if inside {
                length += t - from;
            }
            if t >= ray.t_max {
                break;
            }
            from = t;
            inside = !inside;
        }
        // Past the last crossing the parity is even: the walk ends outside,
        // so the length is finite even for t_max = ∞.
        length * ray.d.length()
    }

    /// Whether the world-space point `p` lies inside the (closed) mesh.
    pub fn contains(&self, p: Vec3) -> bool {
        let p = match &self.transform {
            None => p,
            Some(x) => x.object_from_world.transform_point3a(p),
        };
        self.mesh.contains(p)
    }
}
