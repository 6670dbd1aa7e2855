//! Traversal of a [`Bvh8`] after Fuetterling et al. ("Accelerated Single
//! Ray Tracing for Wide Vector Units", HPG 2017) and tinybvh's `BVH8_CPU`:
//! the eight slab tests of a node at once, then the children hit pushed onto
//! one stack of nodes and leaves in the node's precomputed order for the
//! ray's octant, farthest first, so that the nearest is popped next. Where
//! the CPU has AVX2 and FMA a node is a handful of 256-bit operations (one
//! fused multiply-add per plane, see [`RaySetup::new`]) with no branch
//! per child (the push is a permute through a table of the 256 masks and one
//! store of eight lanes); elsewhere two 4-lane halves and a loop over the
//! children compute the same numbers and push the same entries in the same
//! order, so results do not depend on the CPU.
//!
//! Any-hit traversal (shadow rays) skips the order: whether something is hit
//! does not depend on it, so a node's leaves hit are tested at once and its
//! interior children hit are pushed in lane order, without distances. That
//! saves a permute, a load and a store per node, about a tenth of a shadow
//! ray's time on igea and lucy.

use super::{Bvh8, Bvh8Node, LEAF, WIDTH};
use crate::accel::bvh::TraversalCounters;
use crate::math::{Aabb, Ray};
use glam::Vec4;
use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};

mod setup;
mod stack;
pub(super) use setup::{RaySetup, WIDEN};
use stack::Stack;

/// A node visit: the slab tests of a ray against the eight boxes of a node.
trait NodeVisit {
    /// For closest hits: of the children hit within `[t_min, t_max]`, in the
    /// node's order for the ray's octant, the first is returned and the
    /// others are pushed with their entry distances, last first.
    fn visit(&self, n: &Bvh8Node, t_max: f32, stack: &mut Stack) -> Option<u32>;

    /// For any hit, where the order does not change the answer: the leaves
    /// hit are returned as a mask of lanes; of the interior children hit, in
    /// lane order, the first is returned and the others are pushed without
    /// distances, last first. This skips the permute into the octant's order
    /// and the distances, which only closest hits use (tinybvh's
    /// `BVH8_CPU::IsOccluded` does not order either).
    ///
    /// The fused test (which needs `t_min ≥ 0`) is made here for `[0,
    /// t_max]` instead of `[t_min, t_max]`: `max(near, 0) ≤ max(near,
    /// t_min)`, so every child the ray's interval takes is taken, and the
    /// only others are boxes the ray leaves before `t_min`, whose
    /// triangles' hits the leaf test refuses (it checks `t ≥ t_min`, and
    /// decides alone, as a test of every triangle would, where its own
    /// rounding puts a hit past `t_min` after all). A few more nodes may
    /// be visited; the ray's `t_min` is not needed in a register (on
    /// AVX2, one fewer value read from the stack per visit). The plain
    /// test keeps `t_min`, which may be negative there.
    fn visit_any(&self, n: &Bvh8Node, t_max: f32, stack: &mut Stack) -> (Option<u32>, u32);

    /// What the visits take as `t_max`, and what entry distances are
    /// pruned against, for an interval ending at `t_max`: `t_max` itself,
    /// or `fl(K·t_max)` for the fused test (see [`RaySetup::new`]).
    fn bound(&self, t_max: f32) -> f32;
}

/// The eight slab tests as two 4-lane halves, plain or fused; the fused
/// test computes each lane with `f32::mul_add` (one rounding, as the AVX2
/// path's FMA): an instruction where the CPU has FMA, a library call where
/// it has not.
struct PortableLanes {
    o: [Vec4; 3],
    inv: [Vec4; 3],
    near_c: [Vec4; 3],
    far_c: [Vec4; 3],
    near: [usize; 3],
    far: [usize; 3],
    t_min: Vec4,
    fused: bool,
    shift: u32,
}

/// `a·b − c` per lane, with one rounding.
#[inline(always)]
fn mul_sub4(a: Vec4, b: Vec4, c: Vec4) -> Vec4 {
    Vec4::new(
        a.x.mul_add(b.x, -c.x),
        a.y.mul_add(b.y, -c.y),
        a.z.mul_add(b.z, -c.z),
        a.w.mul_add(b.w, -c.w),
    )
}

impl PortableLanes {
    #[inline(always)]
    fn new(r: &RaySetup) -> Self {
        let negative = |a: usize| r.octant & (1 << a) == 0;
        PortableLanes {
            o: [0, 1, 2].map(|a| Vec4::splat(r.o[a])),
            inv: [0, 1, 2].map(|a| Vec4::splat(r.inv[a])),
            near_c: [0, 1, 2].map(|a| Vec4::splat(r.near_c[a])),
            far_c: [0, 1, 2].map(|a| Vec4::splat(r.far_c[a])),
            fused: r.fused,
            near: std::array::from_fn(|a| a + 3 * negative(a) as usize),
            far: std::array::from_fn(|a| a + 3 * !negative(a) as usize),
            t_min: Vec4::splat(r.t_min),
            shift: 3 * r.octant,
        }
    }

    /// The mask of children hit within `[t_min, t_max]` and the entry
    /// distances: `max` of the near planes' distances and `t_min` against
    /// `min` of the far planes' and `t_max` (already widened by
    /// [`NodeVisit::bound`] for the fused test).
    #[inline(always)]
    fn test(&self, n: &Bvh8Node, t_min: Vec4, t_max: f32, t_enter: &mut [f32; WIDTH]) -> u32 {
        let t_max = Vec4::splat(t_max);
        let mut mask = 0;
        for half in 0..2 {
            let lanes = |row: usize| Vec4::from_slice(&n.planes[row].0[4 * half..4 * half + 4]);
            // Axis `a`'s distances to the planes of `row`; `c` is the fused
            // test's constant for that side.
            let t = |a: usize, row: usize, c: &[Vec4; 3]| {
                if self.fused {
                    mul_sub4(lanes(row), self.inv[a], c[a])
                } else {
                    (lanes(row) - self.o[a]) * self.inv[a]
                }
            };
            let near = |a: usize| t(a, self.near[a], &self.near_c);
            let far = |a: usize| t(a, self.far[a], &self.far_c);
            let (nx, ny, nz) = (near(0), near(1), near(2));
            let (fx, fy, fz) = (far(0), far(1), far(2));
            let enter = nx.max(ny).max(nz.max(t_min));
            let exit = fx.min(fy).min(fz.min(t_max));
            enter.write_to_slice(&mut t_enter[4 * half..4 * half + 4]);
            mask |= enter.cmple(exit).bitmask() << (4 * half);
        }
        mask
    }
}

impl NodeVisit for PortableLanes {
    #[inline(always)]
    fn bound(&self, t_max: f32) -> f32 {
        if self.fused { t_max * WIDEN } else { t_max }
    }

    #[inline(always)]
    fn visit(&self, n: &Bvh8Node, t_max: f32, stack: &mut Stack) -> Option<u32> {
        let mut t = [0f32; WIDTH];
        let mask = self.test(n, self.t_min, t_max, &mut t);
        let mut next = None;
        for j in (0..WIDTH).rev() {
            let k = (n.order[j] >> self.shift & 7) as usize;
            if mask & (1 << k) != 0
                && let Some(previous) = next.replace(k)
            {
                stack.push(n.child[previous], t[previous]);
            }
        }
        next.map(|k| n.child[k])
    }

    #[inline(always)]
    fn visit_any(&self, n: &Bvh8Node, t_max: f32, stack: &mut Stack) -> (Option<u32>, u32) {
        let mut t = [0f32; WIDTH];
        // From 0 for the fused test (see `NodeVisit::visit_any`).
        let t_min = if self.fused { Vec4::ZERO } else { self.t_min };
        let mask = self.test(n, t_min, t_max, &mut t);
        // EMPTY has the high bit too, but is never hit.
        let leaf = (0..WIDTH).fold(0, |m, k| m | (n.child[k] >> 31) << k);
        let mut next = None;
        for k in (0..WIDTH).rev() {
            if mask & !leaf & (1 << k) != 0
                && let Some(previous) = next.replace(k)
            {
                stack.push_entry(n.child[previous]);
            }
        }
        (next.map(|k| n.child[k]), mask & leaf)
    }
}

/// For each mask of the children hit, listed in visiting order (bit `j`:
/// the `j`-th child in order is hit; for any hits, in lane order): the
/// positions of its set bits, last first, then zeros. A permute by it
/// gathers the children to push, farthest first.
const COMPRESS: [[u32; WIDTH]; 256] = {
    let mut table = [[0u32; WIDTH]; 256];
    let mut m = 0;
    while m < 256 {
        let (mut j, mut n) = (WIDTH, 0);
        while j > 0 {
            j -= 1;
            if m & (1 << j) != 0 {
                table[m][n] = j as u32;
                n += 1;
            }
        }
        m += 1;
    }
    table
};

#[cfg(target_arch = "x86_64")]
mod avx2;

/// Set by [`force_portable`]: traverse with the portable lanes even where the
/// CPU has AVX2.
static FORCE_PORTABLE: AtomicBool = AtomicBool::new(false);

/// Makes every traversal in the process use the portable (SSE) node visit,
/// or, with `false`, the fastest the CPU has again. The two give
/// bit-identical results; this exists so that tests (and users chasing a
/// suspected kernel bug) can run both on one machine.
pub fn force_portable(portable: bool) {
    FORCE_PORTABLE.store(portable, Ordering::Relaxed);
}

/// Whether [`force_portable`] is on (packets are then traced ray by ray).
pub(super) fn portable_forced() -> bool {
    FORCE_PORTABLE.load(Ordering::Relaxed)
}

/// Whether the 256-bit node visit (AVX2 and FMA) can run here (checked once, then cached
/// by the standard library) and is not switched off by [`force_portable`].
#[inline(always)]
pub(super) fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        // 0: not checked yet; 1: no; 2: yes.
        static DETECTED: AtomicU8 = AtomicU8::new(0);
        let detected = match DETECTED.load(Ordering::Relaxed) {
            0 => {
                let yes = std::arch::is_x86_feature_detected!("avx2")
                    && std::arch::is_x86_feature_detected!("fma")
                    && std::arch::is_x86_feature_detected!("popcnt")
                    && std::arch::is_x86_feature_detected!("bmi1");
                DETECTED.store(1 + yes as u8, Ordering::Relaxed);
                yes
            }
            d => d == 2,
        };
        detected && !FORCE_PORTABLE.load(Ordering::Relaxed)
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Whether the CPU has AVX-512F and AVX-512VL, for the any-hit kernel's
/// AVX-512VL copy (checked once, then cached). Callers check [`has_avx2`]
/// first, which also honours [`force_portable`].
#[inline(always)]
pub(super) fn has_avx512vl() -> bool {
    #[cfg(test)]
    if tests::AVX2_ONLY.with(|only| only.get()) {
        return false;
    }
    #[cfg(target_arch = "x86_64")]
    {
        // 0: not checked yet; 1: no; 2: yes.
        static DETECTED: AtomicU8 = AtomicU8::new(0);
        match DETECTED.load(Ordering::Relaxed) {
            0 => {
                let yes = std::arch::is_x86_feature_detected!("avx512f")
                    && std::arch::is_x86_feature_detected!("avx512vl");
                DETECTED.store(1 + yes as u8, Ordering::Relaxed);
                yes
            }
            d => d == 2,
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// `$body` with the const `$oct` set to `$octant` (0..8), so that each
/// octant gets its own compiled copy of the AVX2 traversal.
macro_rules! by_octant {
    ($octant:expr, $oct:ident => $body:expr) => {
        by_octant!(@arms $octant, $oct, $body, 0 1 2 3 4 5 6)
    };
    (@arms $octant:expr, $oct:ident, $body:expr, $($k:literal)*) => {
        match $octant {
            $($k => {
                const $oct: u32 = $k;
                $body
            })*
            _ => {
                const $oct: u32 = 7;
                $body
            }
        }
    };
}

impl Bvh8 {
    /// The box of everything (empty for an empty tree).
    #[inline(always)]
    pub(super) fn root(&self) -> Aabb {
        self.bounds.unwrap_or(Aabb::EMPTY)
    }

    /// Closest hit, nearer children first, pruning by the closest `t`; as
    /// [`Bvh::closest`](crate::accel::Bvh::closest).
    #[inline]
    pub fn closest(
        &self,
        ray: &Ray,
        counters: &mut TraversalCounters,
        mut test: impl FnMut(u32, f32) -> Option<f32>,
    ) -> Option<(u32, f32)> {
        self.closest_leaves(
            ray,
            counters,
            #[inline(always)]
            |first, count, mut t_max| {
                let mut best = None;
                for prim in first..first + count {
                    if let Some(t) = test(prim, t_max) {
                        t_max = t;
                        best = Some((prim, t));
                    }
                }
                best
            },
        )
    }

    /// Closest hit, with each leaf whose box the ray meets before the
    /// closest hit so far handed to `test` whole, as `(first primitive,
    /// count, t_max)` (for tests that take several primitives at once, with
    /// SIMD, from data laid out per leaf): `test` returns the closest hit
    /// among the leaf's primitives before `t_max`, the earliest of equals.
    /// Leaves and nodes are taken in the order of [`Bvh8Node::order`].
    #[inline]
    pub fn closest_leaves(
        &self,
        ray: &Ray,
        counters: &mut TraversalCounters,
        mut test: impl FnMut(u32, u32, f32) -> Option<(u32, f32)>,
    ) -> Option<(u32, f32)> {
        self.closest_leaves_with(
            ray,
            counters,
            || (),
            #[inline(always)]
            |_, first, count, t_max| test(first, count, t_max),
        )
    }

    /// [`Bvh8::closest_leaves`] for a leaf test with per-ray constants:
    /// `prepare` makes them once the ray is found to meet a child of the
    /// root (most rays past a mesh do not), before the first leaf, and
    /// `test` gets them with every leaf. The traversal holds them as it
    /// holds its own constants, in registers where there is room, rather
    /// than behind the test's captures.
    #[inline]
    pub fn closest_leaves_with<P>(
        &self,
        ray: &Ray,
        counters: &mut TraversalCounters,
        prepare: impl FnOnce() -> P,
        test: impl FnMut(&P, u32, u32, f32) -> Option<(u32, f32)>,
    ) -> Option<(u32, f32)> {
        if self.nodes.is_empty() {
            return None;
        }
        #[cfg(target_arch = "x86_64")]
        if has_avx2() {
            // The octant by the signs of the direction, as in `any_leaves`.
            let octant = !ray.d.is_negative_bitmask() & 7;
            // SAFETY (all): the CPU has AVX2 and FMA (`has_avx2`), and
            // AVX-512F and VL where `has_avx512vl`.
            return unsafe {
                if has_avx512vl() {
                    by_octant!(octant, OCT => self.closest_entry::<OCT, true, P>(ray, counters, prepare, test))
                } else {
                    by_octant!(octant, OCT => self.closest_entry::<OCT, false, P>(ray, counters, prepare, test))
                }
            };
        }
        self.closest_portable(ray, counters, prepare, test)
    }

    /// [`Bvh8::closest_leaves`] with the portable node visit; kept out of
    /// line so that the AVX2 entry's frame stays small.
    #[inline(never)]
    fn closest_portable<P>(
        &self,
        ray: &Ray,
        counters: &mut TraversalCounters,
        prepare: impl FnOnce() -> P,
        test: impl FnMut(&P, u32, u32, f32) -> Option<(u32, f32)>,
    ) -> Option<(u32, f32)> {
        let setup = RaySetup::new(ray, &self.root());
        self.closest_with(
            ray.t_max,
            counters,
            prepare,
            test,
            &PortableLanes::new(&setup),
        )
    }

    /// The per-ray entry where the CPU has AVX2 and FMA, compiled for
    /// the rays of octant `OCT`: the setup, then the root's eight slab
    /// tests ([`avx2::Avx2Lanes::test_root`]); a ray that misses them all
    /// (most camera rays past a mesh) returns here, having visited one
    /// node as the kernel would, without the kernel's frame. The others go
    /// on to the kernel (the AVX-512VL copy where `WIDE`), which starts
    /// from these tests rather than making them again. Each octant has its
    /// own entry, so that the near and far planes of the root's test are
    /// known when compiling, as in the kernels. Rays that cannot take the
    /// fused test, or whose setup names another octant, take the portable
    /// path.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,popcnt,bmi1")]
    fn closest_entry<const OCT: u32, const WIDE: bool, P>(
        &self,
        ray: &Ray,
        counters: &mut TraversalCounters,
        prepare: impl FnOnce() -> P,
        test: impl FnMut(&P, u32, u32, f32) -> Option<(u32, f32)>,
    ) -> Option<(u32, f32)> {
        let setup = RaySetup::new(ray, &self.root());
        if !setup.fused || setup.octant != OCT {
            return self.closest_portable(ray, counters, prepare, test);
        }
        // The ray is of octant `OCT` and takes the fused test.
        let lanes = avx2::Avx2Lanes::<OCT>::new(&setup);
        let root = lanes.test_root(&self.nodes[0], ray.t_max);
        if !root.any() {
            counters.nodes_visited += 1;
            return None;
        }
        // The lanes and the root's tests go by value: their copies for the
        // kernel are then made here, after the miss check, not before it.
        if WIDE {
            // SAFETY: the caller chose `WIDE` where the CPU has AVX-512F
            // and VL.
            unsafe {
                self.closest_avx512::<OCT, P>(lanes, root, ray.t_max, counters, prepare, test)
            }
        } else {
            self.closest_avx2::<OCT, P>(lanes, root, ray.t_max, counters, prepare, test)
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,popcnt,bmi1")]
    #[inline(never)]
    fn closest_avx2<const OCT: u32, P>(
        &self,
        lanes: avx2::Avx2Lanes<OCT>,
        root: avx2::RootTest,
        t_max: f32,
        counters: &mut TraversalCounters,
        prepare: impl FnOnce() -> P,
        test: impl FnMut(&P, u32, u32, f32) -> Option<(u32, f32)>,
    ) -> Option<(u32, f32)> {
        self.closest_from_root::<OCT, P>(&lanes, &root, t_max, counters, prepare, test)
    }

    /// [`Bvh8::closest_avx2`] compiled for AVX-512VL as well, as
    /// [`Bvh8::any_avx512`]: the same operations in the same order, with 32
    /// vector registers, so that the inlined leaf test does not push the
    /// ray's constants out to the stack. Camera rays 3–11 % faster on igea
    /// and the icosphere (six runs alternating in one process); before the
    /// leaf test was inlined this copy gained nothing.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,popcnt,bmi1,avx512f,avx512vl")]
    #[inline(never)]
    fn closest_avx512<const OCT: u32, P>(
        &self,
        lanes: avx2::Avx2Lanes<OCT>,
        root: avx2::RootTest,
        t_max: f32,
        counters: &mut TraversalCounters,
        prepare: impl FnOnce() -> P,
        test: impl FnMut(&P, u32, u32, f32) -> Option<(u32, f32)>,
    ) -> Option<(u32, f32)> {
        self.closest_from_root::<OCT, P>(&lanes, &root, t_max, counters, prepare, test)
    }

    /// The kernels' body: the closest-hit traversal from the root's tests
    /// made by the entry ([`avx2::Avx2Lanes::test_root`]), which are not
    /// made again.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn closest_from_root<const OCT: u32, P>(
        &self,
        lanes: &avx2::Avx2Lanes<OCT>,
        root: &avx2::RootTest,
        t_max: f32,
        counters: &mut TraversalCounters,
        prepare: impl FnOnce() -> P,
        test: impl FnMut(&P, u32, u32, f32) -> Option<(u32, f32)>,
    ) -> Option<(u32, f32)> {
        let lanes = *lanes;
        let mut stack = Stack::new();
        let first = lanes.push(&self.nodes[0], root.enter, root.hit, &mut stack);
        self.closest_after(t_max, counters, (prepare, test), &lanes, (stack, first))
    }

    #[inline(always)]
    fn closest_with<P>(
        &self,
        t_max: f32,
        counters: &mut TraversalCounters,
        prepare: impl FnOnce() -> P,
        test: impl FnMut(&P, u32, u32, f32) -> Option<(u32, f32)>,
        lanes: &impl NodeVisit,
    ) -> Option<(u32, f32)> {
        let mut stack = Stack::new();
        let first = lanes.visit(&self.nodes[0], lanes.bound(t_max), &mut stack);
        self.closest_after(t_max, counters, (prepare, test), lanes, (stack, first))
    }

    /// The closest-hit traversal after the visit of the root, which
    /// returned `first` and pushed the rest of its children hit onto
    /// `stack`; `prepare` and `test` as [`Bvh8::closest_leaves_with`]'s.
    #[inline(always)]
    fn closest_after<P>(
        &self,
        mut t_max: f32,
        counters: &mut TraversalCounters,
        (prepare, mut test): (
            impl FnOnce() -> P,
            impl FnMut(&P, u32, u32, f32) -> Option<(u32, f32)>,
        ),
        lanes: &impl NodeVisit,
        (mut stack, first): (Stack, Option<u32>),
    ) -> Option<(u32, f32)> {
        let mut best = None;
        let mut bound = lanes.bound(t_max);
        let (mut visited, mut tests) = (1u64, 0u64);
        let Some(mut entry) = first else {
            counters.nodes_visited += visited;
            return None;
        };
        let prepared = prepare();
        'visit: loop {
            if entry & LEAF == 0 {
                visited += 1;
                let node = &self.nodes[entry as usize];
                if let Some(c) = lanes.visit(node, bound, &mut stack) {
                    entry = c;
                    continue;
                }
            } else {
                let (first, count) = Bvh8Node::leaf_range(entry);
                tests += count as u64;
                if let Some(h) = test(&prepared, first, count, t_max) {
                    (t_max, best) = (h.1, Some(h));
                    bound = lanes.bound(t_max);
                }
            }
            // Entries now beyond the closest hit so far are dropped.
            while let Some((c, dist)) = stack.pop() {
                if dist <= bound {
                    entry = c;
                    continue 'visit;
                }
            }
            break;
        }
        counters.nodes_visited += visited;
        counters.primitive_tests += tests;
        best
    }

    /// Any hit: stops at the first primitive for which `test(prim)` is true.
    #[inline]
    pub fn any(
        &self,
        ray: &Ray,
        counters: &mut TraversalCounters,
        mut test: impl FnMut(u32) -> bool,
    ) -> bool {
        self.any_leaves(
            ray,
            counters,
            #[inline(always)]
            |first, count| (first..first + count).any(&mut test),
        )
    }

    /// Any hit, with each leaf handed to `test` whole as by
    /// [`Bvh8::closest_leaves`] (`test(first, count)`); stops when `test`
    /// returns true.
    #[inline]
    pub fn any_leaves(
        &self,
        ray: &Ray,
        counters: &mut TraversalCounters,
        mut test: impl FnMut(u32, u32) -> bool,
    ) -> bool {
        self.any_leaves_with(
            ray,
            counters,
            || (),
            #[inline(always)]
            |_, first, count| test(first, count),
        )
    }

    /// [`Bvh8::any_leaves`] for a leaf test with per-ray constants, made by
    /// `prepare` as [`Bvh8::closest_leaves_with`] makes them: once the ray
    /// is found to meet something in the root, before the first leaf.
    #[inline]
    pub fn any_leaves_with<P>(
        &self,
        ray: &Ray,
        counters: &mut TraversalCounters,
        prepare: impl FnOnce() -> P,
        test: impl FnMut(&P, u32, u32) -> bool,
    ) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        #[cfg(target_arch = "x86_64")]
        if has_avx2() {
            // The octant by the signs of the direction: the setup's (the
            // inverse keeps each sign, that of ±0 included) unless a
            // component is NaN, which the kernels check.
            let octant = !ray.d.is_negative_bitmask() & 7;
            // SAFETY (all): the CPU has AVX2 and FMA (`has_avx2`), and
            // AVX-512F and VL where `has_avx512vl`.
            return unsafe {
                if has_avx512vl() {
                    by_octant!(octant, OCT => self.any_avx512::<OCT, P>(ray, counters, prepare, test))
                } else {
                    by_octant!(octant, OCT => self.any_avx2::<OCT, P>(ray, counters, prepare, test))
                }
            };
        }
        self.any_portable(ray, counters, prepare, test)
    }

    /// [`Bvh8::any_leaves`] with the portable node visit, out of line (the
    /// kernels fall back on it for the rare rays the fused test cannot
    /// take).
    #[inline(never)]
    fn any_portable<P>(
        &self,
        ray: &Ray,
        counters: &mut TraversalCounters,
        prepare: impl FnOnce() -> P,
        test: impl FnMut(&P, u32, u32) -> bool,
    ) -> bool {
        let setup = RaySetup::new(ray, &self.root());
        self.any_with(
            ray.t_max,
            counters,
            (prepare, test),
            &PortableLanes::new(&setup),
        )
    }

    /// The any-hit kernel for rays whose direction's signs put them in
    /// octant `OCT`: the ray's setup is computed here, in the kernel's
    /// own vector code, rather than by the caller and handed over through
    /// memory (shadow rays 1–8 % faster on igea and the icosphere,
    /// alternating in one process). Rays that cannot take the fused test,
    /// or whose setup names another octant, take the portable path.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn any_in_octant<const OCT: u32, P>(
        &self,
        ray: &Ray,
        counters: &mut TraversalCounters,
        prepare: impl FnOnce() -> P,
        test: impl FnMut(&P, u32, u32) -> bool,
    ) -> bool {
        let setup = RaySetup::new(ray, &self.root());
        if !setup.fused || setup.octant != OCT {
            return self.any_portable(ray, counters, prepare, test);
        }
        // SAFETY: the callers are compiled for AVX2 and FMA, which the CPU
        // has; the ray is of octant `OCT` and takes the fused test.
        let lanes = unsafe { avx2::Avx2Lanes::<OCT>::new(&setup) };
        self.any_with(ray.t_max, counters, (prepare, test), &lanes)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,popcnt,bmi1")]
    fn any_avx2<const OCT: u32, P>(
        &self,
        ray: &Ray,
        counters: &mut TraversalCounters,
        prepare: impl FnOnce() -> P,
        test: impl FnMut(&P, u32, u32) -> bool,
    ) -> bool {
        self.any_in_octant::<OCT, P>(ray, counters, prepare, test)
    }

    /// [`Bvh8::any_avx2`] compiled for AVX-512VL as well: the same
    /// operations in the same order (so the same answers and counts), with
    /// 32 vector registers instead of 16. The ray's node-test constants and
    /// a leaf's triangle test then fit in registers together: half the
    /// stack spills, and shadow rays 1–3 % faster on igea and the
    /// icosphere (alternating in one process). [`Bvh8::closest_avx512`]
    /// is its closest-hit counterpart.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,popcnt,bmi1,avx512f,avx512vl")]
    fn any_avx512<const OCT: u32, P>(
        &self,
        ray: &Ray,
        counters: &mut TraversalCounters,
        prepare: impl FnOnce() -> P,
        test: impl FnMut(&P, u32, u32) -> bool,
    ) -> bool {
        self.any_in_octant::<OCT, P>(ray, counters, prepare, test)
    }

    #[inline(always)]
    fn any_with<P>(
        &self,
        t_max: f32,
        counters: &mut TraversalCounters,
        (prepare, mut test): (impl FnOnce() -> P, impl FnMut(&P, u32, u32) -> bool),
        lanes: &impl NodeVisit,
    ) -> bool {
        let mut stack = Stack::new();
        let (mut visited, mut tests) = (1u64, 0u64);
        let mut found = false;
        let bound = lanes.bound(t_max);
        // Only nodes go through the stack: a node's leaves are tested when
        // it is visited, in lane order, which ends occluded rays sooner.
        let mut node = &self.nodes[0];
        let (mut next, mut leaves) = lanes.visit_any(node, bound, &mut stack);
        if next.is_none() && leaves == 0 {
            counters.nodes_visited += visited;
            return false;
        }
        let prepared = prepare();
        'visit: loop {
            while leaves != 0 {
                let k = leaves.trailing_zeros() as usize;
                leaves &= leaves - 1;
                let (first, count) = Bvh8Node::leaf_range(node.child[k]);
                tests += count as u64;
                if test(&prepared, first, count) {
                    found = true;
                    break 'visit;
                }
            }
            match next.or_else(|| stack.pop_entry()) {
                Some(c) => {
                    visited += 1;
                    node = &self.nodes[c as usize];
                    (next, leaves) = lanes.visit_any(node, bound, &mut stack);
                }
                None => break,
            }
        }
        counters.nodes_visited += visited;
        counters.primitive_tests += tests;
        found
    }
}

#[cfg(test)]
mod tests;
