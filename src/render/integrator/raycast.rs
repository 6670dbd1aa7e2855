//! Appel's ray casting.

use super::stream::transmittance_batch;
use super::whitted::{
    LightTerm, area_rotation, local_shading, local_terms, samples_area_lights, transmittance_packet,
};
use super::{Counters, RayKind, Recorder, Tracer, face_forward, intersect};
use crate::accel::PACKET;
use crate::geometry::batch::{BATCH, RayBatch};
use crate::math::{Color, Ray, Vec3};
use crate::render::sampler::PixelSampler;
use crate::scene::{Hit, Scene, SurfaceInteraction};
use std::cell::RefCell;

/// Appel's ray casting: the first hit along the eye ray, shaded by the local
/// terms of its material with a shadow ray to each light. No secondary rays.
/// Area lights get `light_samples` shadow rays (see [`super::Whitted`]).
#[derive(Clone, Copy, Debug)]
pub struct Raycast {
    pub light_samples: u32,
}

impl Default for Raycast {
    fn default() -> Self {
        Raycast { light_samples: 16 }
    }
}

impl Raycast {
    /// The radiance of a camera ray whose first hit is `hit`: the local
    /// terms there (`area` as [`area_rotation`] gives it).
    #[inline(always)]
    fn shade<R: Recorder>(
        &self,
        scene: &Scene,
        ray: &Ray,
        hit: &Hit,
        area: Option<(u32, [f32; 3])>,
        counters: &mut Counters,
        rec: &mut R,
    ) -> Color {
        let (si, wo, n_facing) = at_hit(scene, ray, hit);
        let l = local_shading(scene, &si, wo, n_facing, area, counters, rec);
        rec.end(l, Color::ONE, l);
        l
    }
}

/// The surface at a camera ray's hit, the unit direction back along the
/// ray, and the shading normal on that side.
#[inline(always)]
fn at_hit(scene: &Scene, ray: &Ray, hit: &Hit) -> (SurfaceInteraction, Vec3, Vec3) {
    let si = scene.surface(ray, hit);
    let wo = -ray.d.normalize();
    let n_facing = face_forward(si.ns, face_forward(si.n, wo));
    (si, wo, n_facing)
}

/// Per-thread buffers of [`Raycast::trace_stream`]: each hit's light
/// terms (with the hit's place among the rays), the order in which their
/// shadow rays are traced, their transmittances, and a SIMD batch.
#[derive(Default)]
struct Scratch {
    terms: Vec<(usize, LightTerm)>,
    order: Vec<usize>,
    visibility: Vec<Color>,
    batch: Option<Box<RayBatch>>,
}

thread_local! {
    static SCRATCH: RefCell<Scratch> = RefCell::new(Scratch::default());
}

impl Raycast {
    /// The camera rays' first hits together, then each hit's local terms,
    /// then all the shadow rays, sorted by light (those to one light from
    /// neighbouring hits are coherent) and tested many at a time; each
    /// term is added to its hit in the order [`local_shading`] adds it,
    /// so the radiance is the same bit for bit. Scenes of a few spheres,
    /// planes and boxes ([`Scene::batchable`]) take both in SIMD batches
    /// of [`BATCH`] rays ([`Scene::intersect_batch`],
    /// [`transmittance_batch`]); others in packets of [`PACKET`]
    /// ([`Scene::intersect_packet`], [`transmittance_packet`]: meshes
    /// traversed by the rays together).
    fn trace_many(
        &self,
        scene: &Scene,
        rays: &[Ray],
        counters: &mut Counters,
        out: &mut [Color],
        s: &mut Scratch,
    ) {
        s.terms.clear();
        let mut shade = |j: usize, ray: &Ray, hit: Option<Hit>, counters: &mut Counters| match hit {
            None => self.escaped(scene, ray),
            Some(hit) => {
                let (si, wo, n_facing) = at_hit(scene, ray, &hit);
                let terms = &mut s.terms;
                local_terms(scene, &si, wo, n_facing, None, |_, term| {
                    counters.rays.shadow += 1;
                    terms.push((j, term));
                })
            }
        };
        let batched = scene.batchable();
        let mut batch = s.batch.take().unwrap_or_else(|| RayBatch::new(&[]));
        if batched {
            for (c, (rays, out)) in rays.chunks(BATCH).zip(out.chunks_mut(BATCH)).enumerate() {
                batch.fill(rays);
                let best = scene.intersect_batch(&batch, &mut counters.trace);
                for (i, (ray, out)) in rays.iter().zip(out).enumerate() {
                    *out = shade(c * BATCH + i, ray, best.hit(i), counters);
                }
            }
        } else {
            let mut hits = [None; PACKET];
            for (c, (rays, out)) in rays.chunks(PACKET).zip(out.chunks_mut(PACKET)).enumerate() {
                let hits = &mut hits[..rays.len()];
                scene.intersect_packet(rays, &mut counters.trace, hits);
                for (i, ((ray, &hit), out)) in rays.iter().zip(hits.iter()).zip(out).enumerate() {
                    *out = shade(c * PACKET + i, ray, hit, counters);
                }
            }
        }
        s.order.clear();
        s.order.extend(0..s.terms.len());
        let terms = &s.terms;
        s.order.sort_unstable_by_key(|&k| (terms[k].1.light, k));
        s.visibility.clear();
        s.visibility.resize(terms.len(), Color::ZERO);
        let mut shadow_rays = [Ray::new(Vec3::ZERO, Vec3::X); BATCH];
        let mut visibility = [Color::ZERO; BATCH];
        for chunk in s.order.chunks(if batched { BATCH } else { PACKET }) {
            let n = chunk.len();
            for (r, &k) in shadow_rays.iter_mut().zip(chunk) {
                *r = terms[k].1.ray;
            }
            let shadow_rays = &shadow_rays[..n];
            if batched {
                batch.fill(shadow_rays);
                transmittance_batch(scene, &batch, &mut counters.trace, &mut visibility);
            } else {
                transmittance_packet(
                    scene,
                    shadow_rays,
                    &mut counters.trace,
                    &mut visibility[..n],
                );
            }
            for (&k, &v) in chunk.iter().zip(&visibility[..n]) {
                s.visibility[k] = v;
            }
        }
        s.batch = Some(batch);
        for ((j, term), &v) in terms.iter().zip(&s.visibility) {
            if v != Color::ZERO {
                out[*j] += term.gain.radiance(v);
            }
        }
    }
}

impl Tracer for Raycast {
    fn trace<R: Recorder>(
        &self,
        scene: &Scene,
        ray: &Ray,
        sampler: &mut PixelSampler,
        counters: &mut Counters,
        rec: &mut R,
    ) -> Color {
        rec.begin(RayKind::Camera, ray, Color::ONE);
        let hit = intersect(scene, ray, counters, rec);
        let Some(hit) = hit else {
            let background = self.escaped(scene, ray);
            rec.end(background, Color::ONE, background);
            return background;
        };
        let area = area_rotation(scene, self.light_samples, sampler);
        self.shade(scene, ray, &hit, area, counters, rec)
    }

    #[inline]
    fn escaped(&self, scene: &Scene, ray: &Ray) -> Color {
        scene.background_le(ray.d)
    }

    /// Where no area light is sampled (which would draw random numbers).
    fn streams(&self, scene: &Scene) -> bool {
        !samples_area_lights(scene, self.light_samples)
    }

    /// The camera rays and their shadow rays many at a time
    /// ([`Raycast::trace_many`]).
    fn trace_stream(
        &self,
        scene: &Scene,
        rays: &[Ray],
        counters: &mut Counters,
        out: &mut [Color],
    ) -> bool {
        if !Tracer::streams(self, scene) {
            return false;
        }
        SCRATCH.with(|s| self.trace_many(scene, rays, counters, out, &mut s.borrow_mut()));
        true
    }
}
