//! Unidirectional path tracing with next-event estimation and multiple
//! importance sampling.

use super::{Counters, RayKind, Recorder, Tracer, face_forward, intersect};
use crate::light::Light;
use crate::math::{Color, Ray, Vec3};
use crate::render::sampler::PixelSampler;
use crate::scene::{MaterialKind, Scene};
use crate::shading::{Frame, bsdf_at};

/// Path tracing (Kajiya 1986), as pbrt-v4's `PathIntegrator`:
///
/// - at every vertex whose BSDF is not a pure delta, one light is chosen by
///   power and sampled (next-event estimation), and one direction is sampled
///   from the BSDF to continue the path;
/// - light reached both ways is weighted by Veach's power heuristic
///   `w_a = p_a²/(p_a² + p_b²)` (Veach & Guibas 1995), so each estimator
///   covers what it samples well;
/// - delta lights (point, directional) are reached only by light sampling
///   and delta BSDFs (smooth mirrors and glass) only by BSDF sampling, both
///   with weight 1; glass is a surface like any other (light passes it only
///   along sampled paths);
/// - Russian roulette from bounce `rr_depth` on: a path survives with
///   probability `q = min(0.95, max(β·η²))` (as Mitsuba 3) and is
///   reweighted by `1/q`;
/// - `max_depth` bounces at most (`u32::MAX`: no limit but roulette).
///
/// Rays that leave the scene see the environment (the scene's map, or its
/// background colour), which is a light too.
///
/// `sampling` can switch off either strategy (for comparisons such as
/// Veach's glossy plates): light sampling alone still finds emitters behind
/// delta BSDFs, BSDF sampling alone never samples lights.
#[derive(Clone, Copy, Debug)]
pub struct Path {
    pub max_depth: u32,
    pub rr_depth: u32,
    pub sampling: Sampling,
}

pub use crate::settings::Sampling;

/// The power heuristic with β = 2.
#[inline]
fn power_heuristic(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if a2.is_infinite() {
        return 1.0;
    }
    if a2 + b2 == 0.0 { 0.0 } else { a2 / (a2 + b2) }
}

impl Tracer for Path {
    #[inline]
    fn trace<R: Recorder>(
        &self,
        scene: &Scene,
        ray: &Ray,
        sampler: &mut PixelSampler,
        counters: &mut Counters,
        rec: &mut R,
    ) -> Color {
        self.trace_path(scene, ray, sampler, counters, rec)
    }

    fn escaped(&self, scene: &Scene, ray: &Ray) -> Color {
        // The first step of `trace_path` where the ray hits nothing.
        let mut l = Color::ZERO;
        let beta = Color::ONE;
        if let Some((le, w)) = self.environment(scene, ray.d.normalize(), true, 0.0, ray.o) {
            l += beta * le * w;
        }
        l
    }
}

impl Path {
    /// The weight of light found by BSDF sampling (density `p_bsdf`) that
    /// light sampling finds with density `p_light`.
    #[inline]
    fn bsdf_weight(&self, p_bsdf: f32, p_light: f32) -> f32 {
        match self.sampling {
            Sampling::Mis => power_heuristic(p_bsdf, p_light),
            // Light sampling covers what it can sample.
            Sampling::Light => (p_light == 0.0) as u32 as f32,
            Sampling::Bsdf => 1.0,
        }
    }

    /// The environment's radiance along the unit direction `d` of a ray
    /// that left the scene, and its weight: 1 after a specular bounce (or
    /// for the camera ray), else the MIS weight against sampling the
    /// environment from `prev_p`, where the last bounce sampled `d` with
    /// density `prev_pdf`. `None` without an environment.
    #[inline]
    fn environment(
        &self,
        scene: &Scene,
        d: Vec3,
        specular: bool,
        prev_pdf: f32,
        prev_p: Vec3,
    ) -> Option<(Color, f32)> {
        let emitters = &scene.emitters;
        let env = emitters.environment?;
        let light = &emitters.lights[env as usize];
        let le = light.le(Vec3::ZERO, -d);
        let w = if specular {
            1.0
        } else {
            let p_light = emitters.select.pmf(env as usize) * light.pdf_li(prev_p, d, prev_p);
            self.bsdf_weight(prev_pdf, p_light)
        };
        Some((le, w))
    }

    fn trace_path<R: Recorder>(
        &self,
        scene: &Scene,
        camera_ray: &Ray,
        sampler: &mut PixelSampler,
        counters: &mut Counters,
        rec: &mut R,
    ) -> Color {
        let emitters = &scene.emitters;
        let mut l = Color::ZERO;
        let mut beta = Color::ONE;
        let mut ray = *camera_ray;
        ray.d = ray.d.normalize();
        let mut depth = 0u32;
        // What the last bounce was, for weighting emitters it finds.
        let mut specular = true;
        let mut prev_pdf = 0.0f32;
        let mut prev_p = ray.o;
        // The product of η² over refractions, for roulette (pbrt's etaScale).
        let mut eta_scale = 1.0f32;
        rec.begin(RayKind::Camera, &ray, beta);
        // For the recorder: per ray traced, its throughput and what its hit
        // added before that throughput (emission and light samples).
        let mut books: Vec<(Color, Color)> = Vec::new();
        let mut local = Color::ZERO;
        loop {
            if R::RECORDS {
                // The previous ray's hit is done.
                if let Some(b) = books.last_mut() {
                    b.1 = local;
                }
                books.push((beta, Color::ZERO));
            }
            local = Color::ZERO;
            let hit = intersect(scene, &ray, counters, rec);
            let Some(hit) = hit else {
                if let Some((le, w)) = self.environment(scene, ray.d, specular, prev_pdf, prev_p) {
                    l += beta * le * w;
                    local = le * w;
                }
                break;
            };
            let si = scene.surface(&ray, &hit);
            let material = &scene.materials[si.material as usize];
            let wo = -ray.d;
            let front = si.n.dot(wo) > 0.0;

            // Emission found by the path.
            if material.is_emissive() && (material.two_sided || front) {
                let le = material.emission;
                let object = &scene.objects[si.object as usize];
                let w = match emitters.light_of(si.object, si.prim, si.n, &object.shape) {
                    Some(index) if !specular => {
                        let light: &Light = &emitters.lights[index as usize];
                        let p_light =
                            emitters.select.pmf(index as usize) * light.pdf_li(prev_p, ray.d, si.p);
                        self.bsdf_weight(prev_pdf, p_light)
                    }
                    _ => 1.0,
                };
                l += beta * le * w;
                local += le * w;
            }

            // Light absorbed on the way through a dielectric.
            if !front
                && let MaterialKind::Dielectric { absorption, .. } = material.kind
                && absorption != Color::ZERO
            {
                beta *= (-absorption * hit.t).exp();
            }

            if depth == self.max_depth {
                break;
            }
            depth += 1;

            let bsdf = bsdf_at(material, scene.albedo(&si));
            // The frame: for opaque surfaces the shading normal on the
            // viewer's side; for glass, on the outside.
            let n_shading = if bsdf.transmits() {
                face_forward(si.ns, si.n)
            } else {
                face_forward(si.ns, face_forward(si.n, wo))
            };
            let frame = Frame::from_z(n_shading);
            let wo_local = frame.to_local(wo);
            // A pair for the lobe choice and roulette only where they are
            // made (one lobe and an early bounce need neither).
            let (u_lobe, u_rr) = if bsdf.has_lobes() || depth >= self.rr_depth {
                sampler.next_2d()
            } else {
                (0.5, 0.5)
            };
            let u_light_pos = sampler.next_2d();
            let u_bsdf = sampler.next_2d();

            // Next-event estimation.
            // One pair chooses the light (its first number, remapped) and
            // the point on it, so that the points stay stratified over each
            // light.
            if !bsdf.is_delta()
                && self.sampling != Sampling::Bsdf
                && let Some((index, pmf, u0)) = emitters.select.sample_remapped(u_light_pos.0)
            {
                let light = &emitters.lights[index];
                if let Some(ls) = light.sample_li(si.p, (u0, u_light_pos.1)) {
                    let wi_local = frame.to_local(ls.wi);
                    // Reflection must stay on the geometric side of the
                    // viewer, transmission cross it (no light leaks through
                    // shading normals).
                    let same_side = si.n.dot(ls.wi) * si.n.dot(wo) > 0.0;
                    let f = if same_side == (wi_local.z * wo_local.z > 0.0) {
                        bsdf.eval(wo_local, wi_local) * wi_local.z.abs()
                    } else {
                        Color::ZERO
                    };
                    if f != Color::ZERO {
                        let shadow = match ls.target {
                            Some(t) => Ray::spawn_to(si.p, si.p_err, si.n, t),
                            None => Ray::spawn(si.p, si.p_err, si.n, ls.wi),
                        };
                        counters.rays.shadow += 1;
                        if !scene.occluded(&shadow, &mut counters.trace) {
                            let p_light = pmf * ls.pdf;
                            let w = match self.sampling {
                                _ if ls.delta => 1.0,
                                Sampling::Mis => {
                                    power_heuristic(p_light, bsdf.pdf(wo_local, wi_local))
                                }
                                _ => 1.0,
                            };
                            let brought = f * ls.li * (w / p_light);
                            rec.shadow(scene, index, &shadow, Color::ONE, None, brought);
                            local += brought;
                            l += beta * brought;
                        }
                    }
                }
            }

            // Continue the path by sampling the BSDF.
            let Some(bs) = bsdf.sample(wo_local, u_lobe, u_bsdf) else {
                break;
            };
            // Unit up to rounding: the frame is orthonormal.
            let wi = frame.to_world(bs.wi);
            // A sampled direction must leave on the side it claims.
            if (si.n.dot(wi) * si.n.dot(wo) > 0.0) == bs.transmitted {
                break;
            }
            beta *= bs.weight();
            specular = bs.delta;
            prev_pdf = bs.pdf;
            prev_p = si.p;
            if bs.transmitted {
                let eta = bsdf.eta();
                eta_scale *= if front { eta * eta } else { 1.0 / (eta * eta) };
            }
            if !beta.is_finite() || beta == Color::ZERO {
                break;
            }
            // Russian roulette, before the ray is traced.
            if depth >= self.rr_depth {
                let q = (beta * eta_scale).max_element().min(0.95);
                if u_rr >= q {
                    break;
                }
                beta /= q;
            }
            if bs.transmitted {
                counters.rays.refraction += 1;
            } else {
                counters.rays.reflection += 1;
            }
            ray = Ray::spawn(si.p, si.p_err, si.n, wi);
            rec.begin(
                if bs.transmitted {
                    RayKind::Refraction
                } else {
                    RayKind::Reflection
                },
                &ray,
                beta,
            );
        }
        if R::RECORDS {
            if let Some(b) = books.last_mut() {
                b.1 = local;
            }
            // Each ray's radiance: what its hit and everything after it
            // added, over its throughput. Rays end innermost first.
            let mut after = Color::ZERO;
            for &(beta, local) in books.iter().rev() {
                after += beta * local;
                let radiance = Color::select(beta.cmpgt(Color::ZERO), after / beta, Color::ZERO);
                rec.end(local, Color::ONE, radiance);
            }
        }
        l
    }
}
