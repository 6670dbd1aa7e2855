//! Appel's ray casting.

use super::whitted::{area_rotation, local_shading, samples_area_lights};
use super::{
    Counters, NoRecord, RayKind, Recorder, Tracer, face_forward, from_first_hits, intersect,
};
use crate::math::{Color, Ray};
use crate::render::sampler::PixelSampler;
use crate::scene::{Hit, Scene};

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
        let si = scene.surface(ray, hit);
        let wo = -ray.d.normalize();
        let n_facing = face_forward(si.ns, face_forward(si.n, wo));
        let l = local_shading(scene, &si, wo, n_facing, area, counters, rec);
        rec.end(l, Color::ONE, l);
        l
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

    /// The camera rays' first hits found in packets ([`from_first_hits`]),
    /// then each shaded as [`Tracer::trace`] shades it.
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
        from_first_hits(scene, rays, counters, out, |ray, hit, counters| match hit {
            None => self.escaped(scene, ray),
            Some(hit) => self.shade(scene, ray, &hit, None, counters, &mut NoRecord),
        });
        true
    }
}
