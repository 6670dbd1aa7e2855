//! The scene's tests of many rays at once, for scenes of a few spheres,
//! planes and boxes ([`Scene::batchable`]): each object against a batch of
//! rays in SIMD lanes, compiled for the widest vector unit the CPU has
//! ([`widest`]).

use super::{Object, Scene};
use crate::geometry::Shape;
use crate::geometry::TraceCounters;
use crate::geometry::batch::{
    BATCH, Closest, RayBatch, any_batch, block_batch, closest_batch, sphere_glass_lanes,
};
use crate::math::Color;

impl Scene {
    /// The transmittance of each shadow ray of the batch (one value: the
    /// same for every channel) where every dielectric of the scene is a
    /// clear glass sphere: 0 where an opaque object meets the segment,
    /// else the product, in the order of the objects, of what each glass
    /// sphere lets through ([`Scene::sphere_glass_batch`]). Counts the
    /// tests as the one-ray code does (up to the first object that blocks
    /// the ray, else all). Into `tr`; `false` (nothing written or counted)
    /// for other scenes.
    pub fn transmittance_lanes(
        &self,
        rays: &RayBatch,
        counters: &mut TraceCounters,
        tr: &mut [f32; BATCH],
    ) -> bool {
        // What a dielectric object lets through: a clear glass sphere's ior.
        let ior = |o: &Object| match (self.materials[o.material as usize].glass(), &o.shape) {
            (Some((ior, absorption)), Shape::Sphere(_)) if absorption == Color::ZERO => Some(ior),
            _ => None,
        };
        let clear = |(i, o): (usize, &Object)| self.is_opaque(i as u32) || ior(o).is_some();
        if !self.objects.iter().enumerate().all(clear) {
            return false;
        }
        let objects = self.objects.len() as u32;
        let (blocked, passed) = widest(
            #[inline(always)]
            || {
                // The object that blocks each ray (its index + 1), if any.
                let mut blocked = [0u32; BATCH];
                let mut passed = [1.0f32; BATCH];
                let mut through = [1.0f32; BATCH];
                for (i, o) in self.objects.iter().enumerate() {
                    let mark = i as u32 + 1;
                    match &o.shape {
                        Shape::Sphere(s) if !self.is_opaque(i as u32) => {
                            let ior = ior(o).expect("a clear glass sphere");
                            sphere_glass_lanes(s, ior, rays, &mut through);
                            for j in 0..BATCH {
                                let open = blocked[j] == 0;
                                passed[j] = if open {
                                    passed[j] * through[j]
                                } else {
                                    passed[j]
                                };
                            }
                        }
                        Shape::Sphere(s) => block_batch(s, rays, mark, &mut blocked),
                        Shape::Plane(s) => block_batch(s, rays, mark, &mut blocked),
                        Shape::Cuboid(s) => block_batch(s, rays, mark, &mut blocked),
                        _ => unreachable!("transmittance_lanes on a scene that is not batchable"),
                    }
                }
                (blocked, passed)
            },
        );
        let mut tests = 0;
        for j in 0..rays.len {
            let open = blocked[j] == 0;
            tests += u64::from(if open { objects } else { blocked[j] });
            tr[j] = if open { passed[j] } else { 0.0 };
        }
        counters.intersection_tests += tests;
        true
    }

    /// Whether [`Scene::intersect_batch`] and [`Scene::occludes_batch`] can
    /// answer for this scene: few objects (tested in a plain loop), all of
    /// them spheres, planes or boxes.
    pub fn batchable(&self) -> bool {
        self.linear
            && self.objects.iter().all(|o| {
                matches!(
                    o.shape,
                    Shape::Sphere(_) | Shape::Plane(_) | Shape::Cuboid(_)
                )
            })
    }

    /// [`Scene::intersect`] for a batch of rays at once, each object tested
    /// against all of them (SIMD lanes); the same hits, bit for bit, and the
    /// same counts. Only for [`Scene::batchable`] scenes.
    pub fn intersect_batch(&self, rays: &RayBatch, counters: &mut TraceCounters) -> Closest {
        debug_assert!(self.batchable());
        counters.intersection_tests += (self.objects.len() * rays.len) as u64;
        widest(
            #[inline(always)]
            || {
                let mut best = Closest::start(rays);
                for (i, o) in self.objects.iter().enumerate() {
                    match &o.shape {
                        Shape::Sphere(s) => closest_batch(s, rays, &mut best, i as u32),
                        Shape::Plane(s) => closest_batch(s, rays, &mut best, i as u32),
                        Shape::Cuboid(s) => closest_batch(s, rays, &mut best, i as u32),
                        _ => unreachable!("intersect_batch on a scene that is not batchable"),
                    }
                }
                best
            },
        )
    }

    /// [`Shape::occludes`] of object `i` (a sphere, plane or box) for a
    /// batch of rays: `hit[j]` for ray `j`. Counts nothing (the caller
    /// knows which tests it needed).
    pub fn occludes_batch(&self, i: u32, rays: &RayBatch, hit: &mut [bool; BATCH]) {
        // The answers are made in a local array: written through a
        // captured reference, the compiler could not tell them apart from
        // the rays and would not vectorise.
        *hit = widest(
            #[inline(always)]
            || {
                let mut out = [false; BATCH];
                match &self.objects[i as usize].shape {
                    Shape::Sphere(s) => any_batch(s, rays, &mut out),
                    Shape::Plane(s) => any_batch(s, rays, &mut out),
                    Shape::Cuboid(s) => any_batch(s, rays, &mut out),
                    _ => unreachable!("occludes_batch on a shape without a batch test"),
                }
                out
            },
        );
    }

    /// What object `i`, a sphere of glass of index of refraction `ior`,
    /// lets through of each shadow ray of the batch where it does not
    /// absorb: the product of the Fresnel transmittances of the segment's
    /// crossings of its surface (1 where there is none), as
    /// [`Shape::crossings`] gives them. `false` (and nothing written) for
    /// other shapes.
    pub fn sphere_glass_batch(
        &self,
        i: u32,
        ior: f32,
        rays: &RayBatch,
        passed: &mut [f32; BATCH],
    ) -> bool {
        let Shape::Sphere(s) = &self.objects[i as usize].shape else {
            return false;
        };
        *passed = widest(
            #[inline(always)]
            || {
                let mut out = [1.0; BATCH];
                sphere_glass_lanes(s, ior, rays, &mut out);
                out
            },
        );
        true
    }
}

/// `f()`, compiled for the widest vector unit the CPU has (AVX-512F,
/// AVX2 or the baseline, chosen at run time): for the batch tests, whose
/// loops the compiler vectorises. `f` must be inlined (`#[inline(always)]`
/// on the closure) for its code to be compiled for the wider unit.
#[inline(always)]
pub(crate) fn widest<R>(f: impl FnOnce() -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    {
        #[target_feature(enable = "avx512f")]
        fn avx512<R>(f: impl FnOnce() -> R) -> R {
            f()
        }
        #[target_feature(enable = "avx2")]
        fn avx2<R>(f: impl FnOnce() -> R) -> R {
            f()
        }
        if simd_level() >= 2 {
            // SAFETY: the CPU has AVX-512F (checked just above).
            return unsafe { avx512(f) };
        }
        if simd_level() == 1 {
            // SAFETY: the CPU has AVX2 (checked just above).
            return unsafe { avx2(f) };
        }
    }
    f()
}

/// The widest vector unit the batch tests may use: 2 for AVX-512, 1 for
/// AVX2, 0 for the baseline (checked once, then cached).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) fn simd_level() -> u8 {
    use std::sync::atomic::{AtomicU8, Ordering};
    // 0: not checked yet; else 1 + the level.
    static LEVEL: AtomicU8 = AtomicU8::new(0);
    match LEVEL.load(Ordering::Relaxed) {
        0 => {
            let level = if std::arch::is_x86_feature_detected!("avx512f") {
                2
            } else if std::arch::is_x86_feature_detected!("avx2") {
                1
            } else {
                0
            };
            LEVEL.store(1 + level, Ordering::Relaxed);
            level
        }
        l => l - 1,
    }
}
