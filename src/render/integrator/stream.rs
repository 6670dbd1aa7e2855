//! Whitted's recursive ray tracing for many camera rays at once, breadth
//! first: the rays of one depth (a "wave") are intersected together, a
//! batch at a time ([`Scene::intersect_batch`]: each object against many
//! rays, in SIMD lanes), their hits shaded one by one, and the shadow rays
//! of the whole wave tested together too. The ray trees are kept, and each
//! ray's radiance is put together from its children's, deepest first, with
//! the very operations of [`Whitted::trace_ray`] in the same order. So a
//! pixel gets the same value bit for bit, and the render the same counts.
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

use super::wave::{Lanes, Plan};
use super::whitted::{AtHit, LightGain, local_terms, samples_area_lights, through_glass};
use super::{Counters, MAX_RAY_TREE, NoRecord, Tracer, Whitted, from_first_hits};
use crate::geometry::batch::{BATCH, RayBatch};
use crate::math::{Color, Ray};
use crate::render::sampler::PixelSampler;
use crate::scene::{Hit, Scene, TraceCounters};
use std::cell::RefCell;

/// A ray of the trees, in the order traced (so children come after their
/// parents): what its hit gives before its children's radiance (`local`,
/// with each unblocked shadow ray's term added in turn), its children
/// (`children` of them from `first_child`), the absorption on its way (1
/// where none: multiplying by 1 is exact), and the factor its parent puts on
/// its radiance.
#[derive(Clone, Copy, Debug)]
struct Node {
    local: Color,
    absorption: Color,
    factor: Color,
    first_child: u32,
    children: u32,
}

/// A ray to trace in the next wave, with its factor, depth and weight
/// (its ray is at the same place in the wave's rays).
#[derive(Clone, Copy, Debug)]
struct Pending {
    factor: Color,
    depth: u32,
    weight: f32,
}

/// A shadow ray's node and what it adds there if unblocked (its ray is at
/// the same place in the wave's shadow rays).
struct Shadow {
    node: u32,
    gain: LightGain,
}

/// Buffers kept per thread between calls.
#[derive(Default)]
struct Scratch {
    nodes: Vec<Node>,
    radiance: Vec<Color>,
    wave: (Vec<Ray>, Vec<Pending>),
    next: (Vec<Ray>, Vec<Pending>),
    shadows: Vec<Shadow>,
    shadow_rays: Vec<Ray>,
    batch: Option<Box<RayBatch>>,
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
        s.wave.0.clear();
        s.wave.1.clear();
        s.wave.0.extend_from_slice(rays);
        s.wave.1.extend(rays.iter().map(|_| Pending {
            factor: Color::ONE,
            depth: 0,
            weight: 1.0,
        }));
        let mut batch = s.batch.take().unwrap_or_else(|| RayBatch::new(&[]));
        let plan = Plan::new(scene);
        let mut lanes = s.lanes.take().unwrap_or_else(Lanes::new);
        let mut weights = [0.0f32; BATCH];
        while !s.wave.0.is_empty() {
            s.next.0.clear();
            s.next.1.clear();
            s.shadows.clear();
            s.shadow_rays.clear();
            let wave = std::mem::take(&mut s.wave);
            // The nodes of the next wave follow this wave's.
            let next_base = (s.nodes.len() + wave.0.len()) as u32;
            for (rays, pending) in wave.0.chunks(BATCH).zip(wave.1.chunks(BATCH)) {
                batch.fill(rays);
                let best = scene.intersect_batch(&batch, &mut counters.trace);
                if let Some(plan) = &plan {
                    for (w, p) in weights.iter_mut().zip(pending) {
                        *w = p.weight;
                    }
                    lanes.shade(plan, &batch, &best, &weights, self.min_weight);
                }
                for (j, (ray, p)) in rays.iter().zip(pending).enumerate() {
                    let mut node = Node {
                        local: Color::ZERO,
                        absorption: Color::ONE,
                        factor: p.factor,
                        first_child: 0,
                        children: 0,
                    };
                    match best.hit(j) {
                        None => node.local = Tracer::escaped(self, scene, ray),
                        Some(hit) => match &plan {
                            Some(plan) if lanes.shaded(j) => self.shade_lane(
                                plan, &lanes, j, hit.object, p, next_base, counters, s, &mut node,
                            ),
                            _ => self.shade(scene, ray, p, &hit, next_base, counters, s, &mut node),
                        },
                    }
                    s.nodes.push(node);
                }
            }
            // The wave's shadow rays, then their terms, in the order the
            // lights were met.
            for (shadows, rays) in s.shadows.chunks(BATCH).zip(s.shadow_rays.chunks(BATCH)) {
                batch.fill(rays);
                let visibility = transmittance_batch(scene, &batch, rays, &mut counters.trace);
                for (shadow, &v) in shadows.iter().zip(&visibility[..rays.len()]) {
                    if v != Color::ZERO {
                        s.nodes[shadow.node as usize].local += shadow.gain.radiance(v);
                    }
                }
            }
            s.wave = wave;
            std::mem::swap(&mut s.wave, &mut s.next);
        }
        s.batch = Some(batch);
        s.lanes = Some(lanes);
        // Children come after their parents: put the radiance together from
        // the last ray to the first.
        s.radiance.clear();
        s.radiance.resize(s.nodes.len(), Color::ZERO);
        for (i, node) in s.nodes.iter().enumerate().rev() {
            let mut l = node.local;
            let first = node.first_child as usize;
            for c in first..first + node.children as usize {
                l += s.nodes[c].factor * s.radiance[c];
            }
            s.radiance[i] = l * node.absorption;
        }
        out.copy_from_slice(&s.radiance[..rays.len()]);
    }

    /// A hit of the wave, whose node will be the next in `s.nodes`: its
    /// local terms (shadow rays queued), its absorption, and its secondary
    /// rays queued for the next wave (whose nodes start at `next_base`).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn shade(
        &self,
        scene: &Scene,
        ray: &Ray,
        p: &Pending,
        hit: &Hit,
        next_base: u32,
        counters: &mut Counters,
        s: &mut Scratch,
        node: &mut Node,
    ) {
        let at = AtHit::new(scene, ray, hit);
        let index = s.nodes.len() as u32;
        let (shadows, shadow_rays) = (&mut s.shadows, &mut s.shadow_rays);
        node.local = local_terms(scene, &at.si, at.wo, at.n_facing, None, |_, term| {
            counters.rays.shadow += 1;
            shadow_rays.push(term.ray);
            shadows.push(Shadow {
                node: index,
                gain: term.gain,
            });
        });
        if let Some(a) = at.absorption(hit.t * ray.d.length()) {
            node.absorption = a;
        }
        if p.depth < self.max_depth {
            node.first_child = next_base + s.next.0.len() as u32;
            // By reference: moving the array into an iterator copies it.
            let secondaries = self.secondaries(scene, &at, p.weight, &mut super::NoRecord);
            for sec in secondaries.iter().flatten() {
                sec.count(counters);
                node.children += 1;
                s.next.0.push(sec.ray);
                s.next.1.push(Pending {
                    factor: sec.factor,
                    depth: p.depth + 1,
                    weight: sec.weight,
                });
            }
        }
    }
}

impl Whitted {
    /// [`Whitted::shade`] for a hit shaded in lane `j` of `lanes` (on
    /// object `object`): the same terms, rays and counts, from the lanes.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn shade_lane(
        &self,
        plan: &Plan,
        lanes: &Lanes,
        j: usize,
        object: u32,
        p: &Pending,
        next_base: u32,
        counters: &mut Counters,
        s: &mut Scratch,
        node: &mut Node,
    ) {
        let index = s.nodes.len() as u32;
        node.local = lanes.local(j);
        let (specular, shininess) = plan.highlight(object);
        for k in 0..plan.lights() {
            if let Some(term) = lanes.shadow(k, j) {
                counters.rays.shadow += 1;
                s.shadow_rays.push(term.ray);
                s.shadows.push(Shadow {
                    node: index,
                    gain: LightGain {
                        irradiance: term.irradiance,
                        diffuse: term.diffuse,
                        specular,
                        n_dot_h: term.n_dot_h,
                        shininess,
                    },
                });
            }
        }
        if p.depth < self.max_depth {
            node.first_child = next_base + s.next.0.len() as u32;
            let reflected = lanes.reflected(j);
            if reflected.is_some() {
                counters.rays.reflection += 1;
            }
            let refracted = lanes.refracted(j);
            if refracted.is_some() {
                counters.rays.refraction += 1;
            }
            for sec in [reflected, refracted].into_iter().flatten() {
                node.children += 1;
                s.next.0.push(sec.ray);
                s.next.1.push(Pending {
                    factor: sec.factor,
                    depth: p.depth + 1,
                    weight: sec.weight,
                });
            }
        }
    }
}

/// [`super::transmittance`] for a batch of shadow rays (`rays`, also as
/// `batch`): opaque objects and clear glass spheres are tested against all
/// rays at once, other glass ray by ray; the same values and counts.
pub(super) fn transmittance_batch(
    scene: &Scene,
    batch: &RayBatch,
    rays: &[Ray],
    counters: &mut TraceCounters,
) -> [Color; BATCH] {
    let n = rays.len();
    let mut tr = [Color::ONE; BATCH];
    let mut blocked = [false; BATCH];
    let mut hit = [false; BATCH];
    let mut passed = [1.0f32; BATCH];
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
                    through_glass(scene, i, &rays[j], counters, &mut tr[j]);
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
    tr
}
