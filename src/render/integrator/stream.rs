//! Whitted's recursive ray tracing for many camera rays at once, breadth
//! first: the rays of one depth (a "wave") are intersected together, a
//! batch at a time ([`Scene::intersect_batch`]: each object against many
//! rays, in SIMD lanes), and so are their shadow rays. The hits a batch's
//! lanes can shade ([`super::wave`]) are shaded there, their shadow rays
//! tested light by light straight from the lanes, and their secondary rays
//! written into the next wave's columns ([`super::columns`]); the others
//! are shaded one by one, their shadow rays tested with the whole wave's.
//! The ray trees are kept, and each ray's radiance is put together from its
//! children's, deepest first, with the very operations of
//! [`Whitted::trace_ray`] in the same order. So a pixel gets the same value
//! bit for bit, and the render the same counts.
//!
//! It applies where nothing differs between the two orders: scenes of a
//! few spheres, planes and boxes (see [`Scene::batchable`]), no area lights
//! to sample (they draw random numbers in depth-first order), and ray trees
//! that cannot outgrow [`MAX_RAY_TREE`] (whose cut depends on that order).
//! Other scenes without area lights to sample stream only their camera
//! rays' first hits, in packets of 16 ([`Scene::intersect_packet`]: coherent
//! rays go through a mesh's tree together), and trace the rest of each tree
//! depth first, as one by one (the same image, but where two triangles
//! are hit at exactly the same `t`, which may name the other one).

use super::columns::{Nodes, Shadows, Wave};
use super::wave::{Lanes, Plan};
use super::whitted::{AtHit, local_terms, samples_area_lights, through_glass};
use super::{Counters, MAX_RAY_TREE, NoRecord, Tracer, Whitted, from_first_hits};
use crate::geometry::batch::{BATCH, RayBatch};
use crate::math::{Color, Ray};
use crate::render::sampler::PixelSampler;
use crate::scene::{Hit, Scene, TraceCounters};
use std::cell::RefCell;

/// Buffers kept per thread between calls: the ray trees' nodes and their
/// radiance (by component), this wave's and the next's rays, the wave's
/// shadow rays, a batch, and the lanes.
#[derive(Default)]
struct Scratch {
    nodes: Nodes,
    radiance: [Vec<f32>; 3],
    wave: Wave,
    next: Wave,
    shadows: Shadows,
    batch: Option<Box<RayBatch>>,
    shadow_batch: Option<Box<RayBatch>>,
    lanes: Option<Box<Lanes>>,
}

thread_local! {
    static SCRATCH: RefCell<Scratch> = RefCell::new(Scratch::default());
}

impl Whitted {
    /// Whether [`Whitted::stream`] renders this scene: where no area light
    /// is sampled (which would draw random numbers). Scenes it cannot take
    /// breadth first (see the module documentation) get their camera rays'
    /// first hits in packets ([`Scene::intersect_packet`]), and the rest of
    /// each ray tree depth first.
    pub fn streams(&self, scene: &Scene) -> bool {
        !samples_area_lights(scene, self.light_samples)
    }

    /// Whether the stream goes breadth first (see the module documentation).
    pub fn breadth_first(&self, scene: &Scene) -> bool {
        // A full tree of depth d has 2^(d+1) − 2 secondary rays.
        let tree_fits =
            self.max_depth < 31 && (1u64 << (self.max_depth + 1)) - 2 <= MAX_RAY_TREE as u64;
        scene.batchable() && tree_fits
    }

    /// The radiance of each camera ray of `rays` into `out`, as
    /// [`Tracer::trace`] gives it one by one, if [`Whitted::streams`];
    /// returns whether it did.
    pub fn stream(
        &self,
        scene: &Scene,
        rays: &[Ray],
        counters: &mut Counters,
        out: &mut [Color],
    ) -> bool {
        if !self.streams(scene) {
            return false;
        }
        if self.breadth_first(scene) {
            SCRATCH.with(|s| self.stream_in(scene, rays, counters, out, &mut s.borrow_mut()));
            return true;
        }
        // No area light is sampled: the sampler is never asked for a number.
        let mut sampler = PixelSampler::new(0, 0, 0);
        from_first_hits(scene, rays, counters, out, |ray, hit, counters| {
            self.camera_hit(scene, ray, hit, &mut sampler, counters, &mut NoRecord)
        });
        true
    }

    fn stream_in(
        &self,
        scene: &Scene,
        rays: &[Ray],
        counters: &mut Counters,
        out: &mut [Color],
        s: &mut Scratch,
    ) {
        assert_eq!(rays.len(), out.len());
        s.nodes.clear();
        s.wave.start(rays);
        let mut batch = s.batch.take().unwrap_or_else(|| RayBatch::new(&[]));
        let mut shadow_batch = s.shadow_batch.take().unwrap_or_else(|| RayBatch::new(&[]));
        let plan = Plan::new(scene);
        let mut lanes = s.lanes.take().unwrap_or_else(Lanes::new);
        let mut weights = [0.0f32; BATCH];
        let mut lane = [0u32; BATCH];
        let mut passed = [0.0f32; BATCH];
        let mut visibility = [Color::ZERO; BATCH];
        let mut depth = 0;
        while s.wave.len() > 0 {
            s.next.clear();
            s.shadows.clear();
            let wave = std::mem::take(&mut s.wave);
            let n = wave.len();
            // The wave's nodes, then the next wave's.
            let base = s.nodes.len();
            let next_base = base + n;
            s.nodes.grow_to(next_base);
            for (node, ray) in s.nodes.factor.iter_mut().zip(&wave.factor) {
                node[base..].copy_from_slice(&ray[..n]);
            }
            for start in (0..n).step_by(BATCH) {
                let m = BATCH.min(n - start);
                let first = base + start;
                wave.rays.to_batch(start, m, &mut batch);
                let best = scene.intersect_batch(&batch, &mut counters.trace);
                let lanes = plan.as_ref().map(|plan| {
                    weights[..m].copy_from_slice(&wave.weight[start..start + m]);
                    let spawn = depth < self.max_depth;
                    lanes.shade(plan, &batch, &best, &weights, (self.min_weight, spawn));
                    lanes.write_locals(m, first, &mut s.nodes);
                    // Each light's shadow rays, gathered and tested, then
                    // their terms, in the order of the lights.
                    for k in 0..plan.lights() {
                        lanes.shadow_batch(k, m, &mut shadow_batch, &mut lane);
                        let lit = shadow_batch.len;
                        counters.rays.shadow += lit as u64;
                        let (trace, lane) = (&mut counters.trace, &lane[..lit]);
                        let nodes = &mut s.nodes;
                        if scene.transmittance_lanes(&shadow_batch, trace, &mut passed) {
                            let visibility = |q: usize| Color::splat(passed[q]);
                            lanes.add_light((k, m), lane, visibility, first, nodes);
                        } else {
                            transmittance_batch(scene, &shadow_batch, trace, &mut visibility);
                            let visibility = |q: usize| visibility[q];
                            lanes.add_light((k, m), lane, visibility, first, nodes);
                        }
                    }
                    let (r, t) =
                        lanes.write_secondaries(m, first, next_base, &mut s.nodes, &mut s.next);
                    counters.rays.reflection += r;
                    counters.rays.refraction += t;
                    &*lanes
                });
                for j in 0..m {
                    if lanes.is_some_and(|l| l.shaded(j)) {
                        continue;
                    }
                    let ray = batch.ray(j);
                    match best.hit(j) {
                        None => s
                            .nodes
                            .set_local(first + j, Tracer::escaped(self, scene, &ray)),
                        Some(hit) => {
                            let weight = wave.weight[start + j];
                            let at = (first + j, next_base, depth);
                            self.shade(scene, &ray, weight, &hit, at, counters, s);
                        }
                    }
                }
            }
            // The wave's shadow rays, then their terms, in the order the
            // lights were met.
            for start in (0..s.shadows.len()).step_by(BATCH) {
                let m = BATCH.min(s.shadows.len() - start);
                s.shadows.rays.to_batch(start, m, &mut batch);
                transmittance_batch(scene, &batch, &mut counters.trace, &mut visibility);
                for (j, &v) in visibility[..m].iter().enumerate() {
                    if v != Color::ZERO {
                        let node = s.shadows.node[start + j] as usize;
                        s.nodes
                            .add_local(node, s.shadows.gain[start + j].radiance(v));
                    }
                }
            }
            s.wave = wave;
            std::mem::swap(&mut s.wave, &mut s.next);
            depth += 1;
        }
        s.batch = Some(batch);
        s.shadow_batch = Some(shadow_batch);
        s.lanes = Some(lanes);
        s.nodes.radiance(&mut s.radiance);
        let r = &s.radiance;
        for (i, out) in out.iter_mut().enumerate() {
            *out = Color::new(r[0][i], r[1][i], r[2][i]);
        }
    }

    /// A hit of the wave (of weight `weight`), at node `at.0` (the next
    /// wave's nodes start at `at.1`, and the wave is at depth `at.2`): its
    /// local terms (shadow rays queued), its absorption, and its secondary
    /// rays queued for the next wave.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn shade(
        &self,
        scene: &Scene,
        ray: &Ray,
        weight: f32,
        hit: &Hit,
        (index, next_base, depth): (usize, usize, u32),
        counters: &mut Counters,
        s: &mut Scratch,
    ) {
        let at = AtHit::new(scene, ray, hit);
        let shadows = &mut s.shadows;
        let local = local_terms(scene, &at.si, at.wo, at.n_facing, None, |_, term| {
            counters.rays.shadow += 1;
            shadows.push(&term.ray, index as u32, term.gain);
        });
        s.nodes.set_local(index, local);
        if let Some(a) = at.absorption(hit.t * ray.d.length()) {
            s.nodes.set_absorption(index, a);
        }
        if depth < self.max_depth {
            s.nodes.first_child[index] = (next_base + s.next.len()) as u32;
            // By reference: moving the array into an iterator copies it.
            let secondaries = self.secondaries(scene, &at, weight, &mut super::NoRecord);
            for sec in secondaries.iter().flatten() {
                sec.count(counters);
                s.nodes.children[index] += 1;
                s.next.push(&sec.ray, sec.factor, sec.weight);
            }
        }
    }
}

/// [`super::transmittance`] for a batch of shadow rays, into `tr`: opaque objects and clear glass spheres are tested against all
/// rays at once, other glass ray by ray; the same values and counts.
pub(super) fn transmittance_batch(
    scene: &Scene,
    batch: &RayBatch,
    counters: &mut TraceCounters,
    tr: &mut [Color; BATCH],
) {
    let n = batch.len;
    let mut passed = [1.0f32; BATCH];
    if scene.transmittance_lanes(batch, counters, &mut passed) {
        for (tr, &p) in tr[..n].iter_mut().zip(&passed) {
            *tr = Color::splat(p);
        }
        return;
    }
    tr[..n].fill(Color::ONE);
    let mut blocked = [false; BATCH];
    let mut hit = [false; BATCH];
    let objects = scene.objects.len() as u64;
    for i in 0..scene.objects.len() as u32 {
        if scene.is_opaque(i) {
            scene.occludes_batch(i, batch, &mut hit);
            for j in 0..n {
                if hit[j] && !blocked[j] {
                    blocked[j] = true;
                    counters.intersection_tests += i as u64 + 1;
                }
            }
        } else {
            // Glass changes `tr` only where the segment crosses its surface
            // (`tr *= 1` is exact), which is where it would occlude, unless
            // it absorbs (then a segment wholly inside it counts too).
            let glass = scene.materials[scene.objects[i as usize].material as usize].glass();
            let absorbs = glass.is_some_and(|(_, a)| a != Color::ZERO);
            if let Some((ior, _)) = glass
                && !absorbs
                && scene.sphere_glass_batch(i, ior, batch, &mut passed)
            {
                for j in 0..n {
                    if !blocked[j] {
                        tr[j] *= passed[j];
                    }
                }
                continue;
            }
            if !absorbs {
                scene.occludes_batch(i, batch, &mut hit);
            }
            for j in 0..n {
                if !blocked[j] && (absorbs || hit[j]) {
                    through_glass(scene, i, &batch.ray(j), counters, &mut tr[j]);
                }
            }
        }
    }
    for j in 0..n {
        if blocked[j] {
            tr[j] = Color::ZERO;
        } else {
            counters.intersection_tests += objects;
        }
    }
}
