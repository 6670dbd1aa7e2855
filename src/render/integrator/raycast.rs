//! Appel's ray casting.

use super::whitted::{area_rotation, local_shading};
use super::{Counters, RayKind, Recorder, Tracer, face_forward, intersect};
use crate::math::{Color, Ray};
use crate::render::sampler::PixelSampler;
use crate::scene::Scene;

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
        let si = scene.surface(ray, &hit);
        let wo = -ray.d.normalize();
        let n_facing = face_forward(si.ns, face_forward(si.n, wo));
        let l = local_shading(
            scene,
            &si,
            wo,
            n_facing,
            area_rotation(scene, self.light_samples, sampler),
            counters,
            rec,
        );
        rec.end(l, Color::ONE, l);
        l
    }

    #[inline]
    fn escaped(&self, scene: &Scene, ray: &Ray) -> Color {
        scene.background_le(ray.d)
    }
}
