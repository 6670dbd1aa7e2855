//! Closest and any hits of coherent rays traced together: a packet of up to
//! [`PACKET`] rays (a 4×4 block of camera rays, say) goes down the tree as
//! one, with a mask of the rays still in each subtree (Wald et al.,
//! "Interactive Rendering with Coherent Ray Tracing", 2001; with masks per
//! stack entry as Reshetov et al.'s "Multi-Level Ray Tracing", 2005).
//!
//! One AVX-512 register (or two AVX2 registers) holds a quantity for all
//! sixteen rays, so a child's box is tested against every ray of the packet
//! with the operations that test one ray against eight boxes in the
//! single-ray traversal: a node is eight such tests, whatever the number of
//! rays, and its load, its decisions and their mispredictions are paid once
//! per packet instead of once per ray. Each ray's test is the single-ray fused test (see
//! `RaySetup::new`), operation for operation, with its own constants and its
//! own `t_max`: a ray enters exactly the boxes it would enter alone. A
//! child's entry distances are kept with it on the stack, and a popped
//! entry goes on only with the rays whose closest hit so far does not lie
//! before it, so leaves are tested for a ray only where the single-ray
//! traversal would also test them, if not always in the same order (the
//! packet takes the children in the order of its first ray's octant).
//!
//! Each ray's closest `t` is therefore the single-ray traversal's; where
//! two primitives are hit at exactly that `t` (a shared edge), the one
//! returned may differ, as it may between two traversal orders. Rays that
//! the fused test does not take (and with AVX2, rays of another octant than
//! the first ray's), and packets on CPUs without AVX2, are traced one by
//! one.
//!
//! Any hits (shadow rays) go the same way without the order and the
//! distances, as the single-ray any-hit traversal does: a node's leaves are
//! tested at once for the rays that reach them, and a ray leaves the
//! packet as soon as something blocks it.

#[cfg(target_arch = "x86_64")]
use super::STACK;
use super::{Bvh8, Bvh8Node, LEAF};
use crate::accel::bvh::TraversalCounters;
use crate::math::Ray;
#[cfg(target_arch = "x86_64")]
use std::mem::MaybeUninit;

/// Rays of a packet: one AVX-512 register of f32.
pub const PACKET: usize = 16;

impl Bvh8 {
    /// The closest hit of each ray of `rays` (at most [`PACKET`]), as
    /// [`Bvh8::closest_leaves`] finds it, into `out`: `test(r, first,
    /// count, t_max)` tests ray `r` against a leaf's primitives and returns
    /// the closest hit before `t_max`, the earliest of equals. See the
    /// module documentation for what packets change and what they do not.
    pub fn closest_packet(
        &self,
        rays: &[Ray],
        counters: &mut TraversalCounters,
        mut test: impl FnMut(usize, u32, u32, f32) -> Option<(u32, f32)>,
        out: &mut [Option<(u32, f32)>],
    ) {
        assert!(rays.len() <= PACKET && rays.len() == out.len());
        out.fill(None);
        if self.nodes.is_empty() {
            return;
        }
        #[cfg(target_arch = "x86_64")]
        // SAFETY (both): the CPU has what the lanes need.
        let packed = if avx512::available() {
            unsafe { self.closest_packet_avx512(rays, counters, &mut test, out) }
        } else if avx2::available() {
            unsafe { self.closest_packet_avx2(rays, counters, &mut test, out) }
        } else {
            0
        };
        #[cfg(not(target_arch = "x86_64"))]
        let packed = 0u16;
        // The rest one by one.
        for (r, ray) in rays.iter().enumerate() {
            if packed & 1 << r == 0 {
                out[r] = self.closest_leaves(ray, counters, |first, count, t_max| {
                    test(r, first, count, t_max)
                });
            }
        }
    }

    /// Whether each ray of `rays` (at most [`PACKET`]) meets a primitive,
    /// as [`Bvh8::any_leaves`] finds it, into `out`: `test(r, first,
    /// count)` says whether ray `r` meets one of a leaf's primitives.
    pub fn any_packet(
        &self,
        rays: &[Ray],
        counters: &mut TraversalCounters,
        mut test: impl FnMut(usize, u32, u32) -> bool,
        out: &mut [bool],
    ) {
        assert!(rays.len() <= PACKET && rays.len() == out.len());
        out.fill(false);
        if self.nodes.is_empty() {
            return;
        }
        #[cfg(target_arch = "x86_64")]
        // SAFETY (both): the CPU has what the lanes need.
        let packed = if avx512::available() {
            unsafe { self.any_packet_avx512(rays, counters, &mut test, out) }
        } else if avx2::available() {
            unsafe { self.any_packet_avx2(rays, counters, &mut test, out) }
        } else {
            0
        };
        #[cfg(not(target_arch = "x86_64"))]
        let packed = 0u16;
        for (r, ray) in rays.iter().enumerate() {
            if packed & 1 << r == 0 {
                out[r] = self.any_leaves(ray, counters, |first, count| test(r, first, count));
            }
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,fma,popcnt,bmi1")]
    fn closest_packet_avx512(
        &self,
        rays: &[Ray],
        counters: &mut TraversalCounters,
        test: &mut impl FnMut(usize, u32, u32, f32) -> Option<(u32, f32)>,
        out: &mut [Option<(u32, f32)>],
    ) -> u16 {
        let lanes = avx512::Lanes16::new(rays, &self.root());
        self.closest_lanes(&lanes, rays, counters, test, out)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,popcnt,bmi1")]
    fn closest_packet_avx2(
        &self,
        rays: &[Ray],
        counters: &mut TraversalCounters,
        test: &mut impl FnMut(usize, u32, u32, f32) -> Option<(u32, f32)>,
        out: &mut [Option<(u32, f32)>],
    ) -> u16 {
        let lanes = avx2::Lanes16::new(rays, &self.root());
        self.closest_lanes(&lanes, rays, counters, test, out)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,fma,popcnt,bmi1")]
    fn any_packet_avx512(
        &self,
        rays: &[Ray],
        counters: &mut TraversalCounters,
        test: &mut impl FnMut(usize, u32, u32) -> bool,
        out: &mut [bool],
    ) -> u16 {
        let lanes = avx512::Lanes16::new(rays, &self.root());
        self.any_lanes(&lanes, rays, counters, test, out)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,popcnt,bmi1")]
    fn any_packet_avx2(
        &self,
        rays: &[Ray],
        counters: &mut TraversalCounters,
        test: &mut impl FnMut(usize, u32, u32) -> bool,
        out: &mut [bool],
    ) -> u16 {
        let lanes = avx2::Lanes16::new(rays, &self.root());
        self.any_lanes(&lanes, rays, counters, test, out)
    }

    /// The closest hits of the rays of `rays` that `lanes` takes, into
    /// `out`; returns the mask of those rays. Inlined into the callers
    /// compiled for the lanes' instructions.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn closest_lanes<L: Lanes>(
        &self,
        lanes: &L,
        rays: &[Ray],
        counters: &mut TraversalCounters,
        test: &mut impl FnMut(usize, u32, u32, f32) -> Option<(u32, f32)>,
        out: &mut [Option<(u32, f32)>],
    ) -> u16 {
        let active = lanes.active();
        if active == 0 {
            return 0;
        }
        let shift = 3 * lanes.octant();
        let mut t_max: [f32; PACKET] =
            std::array::from_fn(|r| rays.get(r).map_or(f32::INFINITY, |ray| ray.t_max));
        let mut bound = lanes.widen(&t_max);
        let mut hull = reach(&t_max, active);
        let mut best = [None; PACKET];
        // The stack: entries, their rays, their rays' entry distances.
        let mut stack = Stack::new();
        let (mut visited, mut tests) = (0u64, 0u64);
        let (mut entry, mut mask) = (0u32, active);
        'visit: loop {
            if entry & LEAF == 0 {
                visited += u64::from(mask.count_ones());
                let node = &self.nodes[entry as usize];
                // Each child against every ray of the mask.
                let mut hit = [0u16; 8];
                let mut enter = [lanes.zero(); 8];
                let maybe = lanes.cull(node, hull);
                for k in 0..8 {
                    if maybe & 1 << k != 0 && node.child[k] != super::EMPTY {
                        (hit[k], enter[k]) = lanes.test(node, k, mask, bound);
                    }
                }
                // Nearest first for the packet's octant: push the others
                // farthest first.
                let mut next = None;
                for j in (0..8).rev() {
                    let k = (node.order[j] >> shift & 7) as usize;
                    if hit[k] != 0
                        && let Some(previous) = next.replace(k)
                    {
                        stack.push(node.child[previous], hit[previous], enter[previous]);
                    }
                }
                if let Some(k) = next {
                    (entry, mask) = (node.child[k], hit[k]);
                    continue;
                }
            } else {
                let (first, count) = Bvh8Node::leaf_range(entry);
                let mut rays_left = mask;
                let mut changed = false;
                while rays_left != 0 {
                    let r = rays_left.trailing_zeros() as usize;
                    rays_left &= rays_left - 1;
                    tests += u64::from(count);
                    if let Some(h) = test(r, first, count, t_max[r]) {
                        (t_max[r], best[r]) = (h.1, Some(h));
                        changed = true;
                    }
                }
                if changed {
                    bound = lanes.widen(&t_max);
                    hull = reach(&t_max, active);
                }
            }
            // Entries go on with the rays whose closest hit so far is not
            // before them.
            while let Some((e, m, d)) = stack.pop() {
                let m = lanes.le(m, d, bound);
                if m != 0 {
                    (entry, mask) = (e, m);
                    continue 'visit;
                }
            }
            break;
        }
        counters.nodes_visited += visited;
        counters.primitive_tests += tests;
        for (r, o) in out.iter_mut().enumerate() {
            if active & 1 << r != 0 {
                *o = best[r];
            }
        }
        active
    }

    /// The any hits of the rays of `rays` that `lanes` takes, into `out`;
    /// returns the mask of those rays.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn any_lanes<L: Lanes>(
        &self,
        lanes: &L,
        rays: &[Ray],
        counters: &mut TraversalCounters,
        test: &mut impl FnMut(usize, u32, u32) -> bool,
        out: &mut [bool],
    ) -> u16 {
        let active = lanes.active();
        if active == 0 {
            return 0;
        }
        let t_max: [f32; PACKET] =
            std::array::from_fn(|r| rays.get(r).map_or(f32::INFINITY, |ray| ray.t_max));
        let bound = lanes.widen(&t_max);
        let hull = reach(&t_max, active);
        // Only nodes go through the stack (distances unused).
        let mut stack = Stack::new();
        let (mut visited, mut tests) = (0u64, 0u64);
        let mut blocked = 0u16;
        let (mut entry, mut mask) = (0u32, active);
        'visit: loop {
            visited += u64::from(mask.count_ones());
            let node = &self.nodes[entry as usize];
            let mut next = None;
            let maybe = lanes.cull(node, hull);
            for k in (0..8).rev() {
                let child = node.child[k];
                if maybe & 1 << k == 0 || child == super::EMPTY {
                    continue;
                }
                let (hit, _) = lanes.test(node, k, mask & !blocked, bound);
                if hit == 0 {
                    continue;
                }
                if child & LEAF == 0 {
                    if let Some((c, m)) = next.replace((child, hit)) {
                        stack.push(c, m, lanes.zero());
                    }
                    continue;
                }
                let (first, count) = Bvh8Node::leaf_range(child);
                let mut rays_left = hit & !blocked;
                while rays_left != 0 {
                    let r = rays_left.trailing_zeros() as usize;
                    rays_left &= rays_left - 1;
                    tests += u64::from(count);
                    if test(r, first, count) {
                        blocked |= 1 << r;
                    }
                }
                if blocked == active {
                    break 'visit;
                }
            }
            if let Some((c, m)) = next
                && m & !blocked != 0
            {
                (entry, mask) = (c, m & !blocked);
                continue;
            }
            while let Some((e, m, _)) = stack.pop() {
                if m & !blocked != 0 {
                    (entry, mask) = (e, m & !blocked);
                    continue 'visit;
                }
            }
            break;
        }
        counters.nodes_visited += visited;
        counters.primitive_tests += tests;
        for (r, o) in out.iter_mut().enumerate() {
            if active & 1 << r != 0 {
                *o = blocked & 1 << r != 0;
            }
        }
        active
    }
}

/// The greatest `t_max` of the rays of `rays` (a mask).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn reach(t_max: &[f32; PACKET], mut rays: u16) -> f32 {
    let mut far = f32::NEG_INFINITY;
    while rays != 0 {
        far = far.max(t_max[rays.trailing_zeros() as usize]);
        rays &= rays - 1;
    }
    far
}

/// The rays of a packet in SIMD lanes, one quantity of all sixteen rays
/// per [`Lanes::Wide`]: what the packet traversals need of an instruction
/// set. A value exists only where the CPU has its instructions, so its
/// methods, inlined into functions compiled for them, may use them.
#[cfg(target_arch = "x86_64")]
trait Lanes {
    /// Sixteen `f32`, one per ray.
    type Wide: Copy;

    /// The rays that take the packet test (the others are traced alone).
    fn active(&self) -> u16;

    /// The octant whose child order the packet follows.
    fn octant(&self) -> u32;

    /// Child `k` of `node` against the rays of `mask` whose intervals end
    /// at `bound` (widened): the rays that enter its box (a subset of
    /// `mask`), and the entry distances (lanes outside `mask` unspecified).
    fn test(&self, node: &Bvh8Node, k: usize, mask: u16, bound: Self::Wide) -> (u16, Self::Wide);

    /// The children of `node` that a ray of the packet whose `t_max` is at
    /// most `t_max` may enter, as a mask: at least those its per-ray
    /// [`Lanes::test`] takes, from one test of the eight boxes against the
    /// packet's interval (Boulos et al., "Geometric and Arithmetic Culling
    /// Methods for Entire Ray Packets", 2006), so that boxes no ray enters
    /// cost one 8-wide test instead of one per ray.
    fn cull(&self, node: &Bvh8Node, t_max: f32) -> u32;

    /// `t_max` widened as the fused test widens it (`NodeVisit::bound`).
    fn widen(&self, t_max: &[f32; PACKET]) -> Self::Wide;

    /// The rays of `mask` whose `d` is at most `bound`.
    fn le(&self, mask: u16, d: Self::Wide, bound: Self::Wide) -> u16;

    /// Zeros.
    fn zero(&self) -> Self::Wide;
}

/// The rays of a packet as columns: lane `r` of each holds ray `r`'s value,
/// lanes from `rays.len()` on repeat the last ray's.
#[cfg(target_arch = "x86_64")]
struct Columns {
    o: [[f32; PACKET]; 3],
    d: [[f32; PACKET]; 3],
    t_min: [f32; PACKET],
}

#[cfg(target_arch = "x86_64")]
impl Columns {
    #[inline(always)]
    fn new(rays: &[Ray]) -> Columns {
        let mut c = Columns {
            o: [[0.0; PACKET]; 3],
            d: [[0.0; PACKET]; 3],
            t_min: [0.0; PACKET],
        };
        if let Some(last) = rays.last() {
            for r in 0..PACKET {
                let ray = rays.get(r).unwrap_or(last);
                for a in 0..3 {
                    c.o[a][r] = ray.o[a];
                    c.d[a][r] = ray.d[a];
                }
                c.t_min[r] = ray.t_min;
            }
        }
        c
    }
}

/// The packets' stack: entries, their rays, and their rays' entry
/// distances. Not initialised (zeroing 33 kB would cost more than a
/// packet's traversal): an entry is read only after it is written.
#[cfg(target_arch = "x86_64")]
struct Stack<W> {
    entries: [MaybeUninit<u32>; STACK],
    masks: [MaybeUninit<u16>; STACK],
    dists: [MaybeUninit<W>; STACK],
    len: usize,
}

#[cfg(target_arch = "x86_64")]
impl<W: Copy> Stack<W> {
    #[inline(always)]
    fn new() -> Self {
        Stack {
            entries: [const { MaybeUninit::uninit() }; STACK],
            masks: [const { MaybeUninit::uninit() }; STACK],
            dists: [const { MaybeUninit::uninit() }; STACK],
            len: 0,
        }
    }

    /// Pushes an entry (indexing checks the bound; `STACK` covers the
    /// deepest tree, as for single rays).
    #[inline(always)]
    fn push(&mut self, entry: u32, mask: u16, dist: W) {
        self.entries[self.len].write(entry);
        self.masks[self.len].write(mask);
        self.dists[self.len].write(dist);
        self.len += 1;
    }

    #[inline(always)]
    fn pop(&mut self) -> Option<(u32, u16, W)> {
        self.len = self.len.checked_sub(1)?;
        // SAFETY: entries below the old `len` were written.
        unsafe {
            Some((
                self.entries[self.len].assume_init(),
                self.masks[self.len].assume_init(),
                self.dists[self.len].assume_init(),
            ))
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod avx512 {
    use super::{Lanes, PACKET};
    use crate::accel::bvh8::Bvh8Node;
    use crate::accel::bvh8::traverse::WIDEN;
    use crate::math::{Aabb, Ray};
    use std::arch::x86_64::*;

    /// Whether the packet traversals can run here with AVX-512 (AVX-512F,
    /// FMA, POPCNT and BMI1; checked once, then cached by the standard
    /// library), and the portable path is not forced (see
    /// [`crate::accel::force_portable`]).
    #[inline(always)]
    pub(super) fn available() -> bool {
        std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("fma")
            && std::arch::is_x86_feature_detected!("popcnt")
            && std::arch::is_x86_feature_detected!("bmi1")
            && !crate::accel::bvh8::traverse::portable_forced()
    }

    /// Each ray's fused-test constants in its lane of one 512-bit register
    /// (`RaySetup::new` for sixteen rays at once, operation for
    /// operation), the rays that take that test, and the first one's
    /// octant. Rays of other octants take their near planes by a masked
    /// blend and follow the first one's order.
    pub(super) struct Lanes16 {
        inv: [__m512; 3],
        near_c: [__m512; 3],
        far_c: [__m512; 3],
        t_min: __m512,
        /// Rays with `d[a] < 0`: their near plane on axis `a` is the max.
        negative: [__mmask16; 3],
        active: u16,
        octant: u32,
    }

    impl Lanes16 {
        /// The caller makes sure the CPU has AVX-512F and FMA.
        #[target_feature(enable = "avx512f,fma")]
        #[inline]
        pub(super) fn new(rays: &[Ray], root: &Aabb) -> Lanes16 {
            let n = rays.len();
            let columns = super::Columns::new(rays);
            // SAFETY: 16 floats.
            let lane = |c: &[f32; PACKET]| unsafe { _mm512_loadu_ps(c.as_ptr()) };
            let mut lanes = Lanes16 {
                inv: [_mm512_setzero_ps(); 3],
                near_c: [_mm512_setzero_ps(); 3],
                far_c: [_mm512_setzero_ps(); 3],
                t_min: _mm512_setzero_ps(),
                negative: [0; 3],
                active: 0,
                octant: 0,
            };
            if n == 0 {
                return lanes;
            }
            lanes.t_min = lane(&columns.t_min);
            let mut active = _mm512_cmp_ps_mask::<_CMP_GE_OQ>(lanes.t_min, _mm512_setzero_ps());
            active &= ((1u32 << n) - 1) as u16;
            let eighth = _mm512_set1_ps(1.0 / (1 << 21) as f32);
            let tiny = _mm512_set1_ps(f32::MIN_POSITIVE);
            for a in 0..3 {
                let o = lane(&columns.o[a]);
                let inv = _mm512_div_ps(_mm512_set1_ps(1.0), lane(&columns.d[a]));
                let inv = _mm512_min_ps(
                    _mm512_max_ps(inv, _mm512_set1_ps(-1e30)),
                    _mm512_set1_ps(1e30),
                );
                let oi = _mm512_mul_ps(o, inv);
                let plane =
                    |p: f32| _mm512_abs_ps(_mm512_mul_ps(_mm512_sub_ps(_mm512_set1_ps(p), o), inv));
                let m = _mm512_max_ps(plane(root.min[a]), plane(root.max[a]));
                let reach = _mm512_add_ps(_mm512_abs_ps(oi), m);
                let far_s = _mm512_add_ps(_mm512_mul_ps(reach, eighth), tiny);
                let near_s = _mm512_add_ps(_mm512_mul_ps(_mm512_abs_ps(oi), eighth), tiny);
                lanes.inv[a] = inv;
                lanes.near_c[a] = _mm512_add_ps(oi, near_s);
                lanes.far_c[a] = _mm512_sub_ps(oi, far_s);
                lanes.negative[a] = _mm512_cmp_ps_mask::<_CMP_LT_OQ>(inv, _mm512_setzero_ps());
                active &= _mm512_cmp_ps_mask::<_CMP_LT_OQ>(reach, _mm512_set1_ps(1e36));
            }
            lanes.active = active;
            // Bit a: d[a] ≥ 0, as `RaySetup::octant`.
            let first = active.trailing_zeros() % PACKET as u32;
            lanes.octant = (0..3).fold(0, |q, a| {
                q | u32::from(lanes.negative[a] >> first & 1 == 0) << a
            });
            lanes
        }
    }

    // SAFETY (all): a `Lanes16` exists only where the CPU has AVX-512F and
    // FMA.
    impl Lanes for Lanes16 {
        type Wide = __m512;

        #[inline(always)]
        fn active(&self) -> u16 {
            self.active
        }

        #[inline(always)]
        fn octant(&self) -> u32 {
            self.octant
        }

        #[inline(always)]
        fn test(&self, node: &Bvh8Node, k: usize, mask: u16, bound: __m512) -> (u16, __m512) {
            let plane = |row: usize| unsafe { _mm512_set1_ps(node.planes[row].0[k]) };
            let t = |a: usize, near: bool| unsafe {
                let (lo, hi) = (plane(a), plane(a + 3));
                // Near: the min plane, or the max where d[a] < 0.
                let (p, c) = if near {
                    (
                        _mm512_mask_blend_ps(self.negative[a], lo, hi),
                        self.near_c[a],
                    )
                } else {
                    (
                        _mm512_mask_blend_ps(self.negative[a], hi, lo),
                        self.far_c[a],
                    )
                };
                _mm512_fmsub_ps(p, self.inv[a], c)
            };
            let (nx, ny, nz) = (t(0, true), t(1, true), t(2, true));
            let (fx, fy, fz) = (t(0, false), t(1, false), t(2, false));
            unsafe {
                let enter = _mm512_max_ps(_mm512_max_ps(nx, ny), _mm512_max_ps(nz, self.t_min));
                let exit = _mm512_min_ps(_mm512_min_ps(fx, fy), _mm512_min_ps(fz, bound));
                (
                    _mm512_mask_cmp_ps_mask::<_CMP_LE_OQ>(mask, enter, exit),
                    enter,
                )
            }
        }

        /// Rays of several octants have no common near planes: nothing
        /// is culled.
        #[inline(always)]
        fn cull(&self, _: &Bvh8Node, _: f32) -> u32 {
            0xff
        }

        #[inline(always)]
        fn widen(&self, t_max: &[f32; PACKET]) -> __m512 {
            // SAFETY: 16 floats.
            unsafe { _mm512_mul_ps(_mm512_loadu_ps(t_max.as_ptr()), _mm512_set1_ps(WIDEN)) }
        }

        #[inline(always)]
        fn le(&self, mask: u16, d: __m512, bound: __m512) -> u16 {
            unsafe { _mm512_mask_cmp_ps_mask::<_CMP_LE_OQ>(mask, d, bound) }
        }

        #[inline(always)]
        fn zero(&self) -> __m512 {
            unsafe { _mm512_setzero_ps() }
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::{Lanes, PACKET};
    use crate::accel::bvh8::Bvh8Node;
    use crate::accel::bvh8::traverse::WIDEN;
    use crate::math::{Aabb, Ray};
    use std::arch::x86_64::*;

    /// Whether the packet traversals can run here with AVX2: where the
    /// single-ray traversal's 256-bit path runs (AVX2, FMA, POPCNT and
    /// BMI1, and the portable path not forced).
    #[inline(always)]
    pub(super) fn available() -> bool {
        crate::accel::bvh8::traverse::has_avx2()
    }

    /// Sixteen rays as two 256-bit halves (rays 0–7 and 8–15), with each
    /// ray's fused-test constants computed as `RaySetup::new` computes
    /// them, operation for operation. Only the rays of the first one's
    /// octant take the packet test, so that a child's near and far planes
    /// are the same row for all of them: one broadcast each, and no blend,
    /// which AVX2 pays for where AVX-512 has masks. The others (few in a
    /// block of camera rays or of shadow rays to one light) are traced
    /// alone.
    pub(super) struct Lanes16 {
        inv: [[__m256; 2]; 3],
        near_c: [[__m256; 2]; 3],
        far_c: [[__m256; 2]; 3],
        t_min: [__m256; 2],
        /// The rows of the near and far planes of each axis.
        near: [usize; 3],
        far: [usize; 3],
        active: u16,
        octant: u32,
        /// The packet's interval, for [`Lanes::cull`]: per axis the least
        /// and greatest `inv` of its rays, the greatest `near_c` and the
        /// least `far_c`; and the least `t_min`, all broadcast.
        inv_lo: [__m256; 3],
        inv_hi: [__m256; 3],
        near_c_hi: [__m256; 3],
        far_c_lo: [__m256; 3],
        t_min_lo: __m256,
    }

    /// The sign bits of two halves as one mask of sixteen rays.
    #[inline(always)]
    fn bits(v: [__m256; 2]) -> u16 {
        // SAFETY: only inlined into functions compiled with AVX.
        unsafe { (_mm256_movemask_ps(v[0]) as u16) | (_mm256_movemask_ps(v[1]) as u16) << 8 }
    }

    impl Lanes16 {
        /// The caller makes sure the CPU has AVX2 and FMA.
        #[target_feature(enable = "avx2,fma")]
        #[inline]
        pub(super) fn new(rays: &[Ray], root: &Aabb) -> Lanes16 {
            let n = rays.len();
            // Half h: rays 8h to 8h + 7.
            let columns = super::Columns::new(rays);
            // SAFETY: 16 floats.
            let lane = |c: &[f32; PACKET]| unsafe {
                [
                    _mm256_loadu_ps(c.as_ptr()),
                    _mm256_loadu_ps(c.as_ptr().add(8)),
                ]
            };
            let zero = _mm256_setzero_ps();
            let mut lanes = Lanes16 {
                inv: [[zero; 2]; 3],
                near_c: [[zero; 2]; 3],
                far_c: [[zero; 2]; 3],
                t_min: [zero; 2],
                near: [0; 3],
                far: [0; 3],
                active: 0,
                octant: 0,
                inv_lo: [zero; 3],
                inv_hi: [zero; 3],
                near_c_hi: [zero; 3],
                far_c_lo: [zero; 3],
                t_min_lo: zero,
            };
            if n == 0 {
                return lanes;
            }
            lanes.t_min = lane(&columns.t_min);
            let mut active = bits(lanes.t_min.map(|t| _mm256_cmp_ps::<_CMP_GE_OQ>(t, zero)));
            active &= ((1u32 << n) - 1) as u16;
            let eighth = _mm256_set1_ps(1.0 / (1 << 21) as f32);
            let tiny = _mm256_set1_ps(f32::MIN_POSITIVE);
            let sign = _mm256_set1_ps(-0.0);
            let abs = |v: __m256| _mm256_andnot_ps(sign, v);
            let mut negative = [0u16; 3];
            for (a, negative) in negative.iter_mut().enumerate() {
                let o = lane(&columns.o[a]);
                let d = lane(&columns.d[a]);
                let mut reach = [zero; 2];
                for h in 0..2 {
                    let inv = _mm256_div_ps(_mm256_set1_ps(1.0), d[h]);
                    let inv = _mm256_min_ps(
                        _mm256_max_ps(inv, _mm256_set1_ps(-1e30)),
                        _mm256_set1_ps(1e30),
                    );
                    let oi = _mm256_mul_ps(o[h], inv);
                    let plane =
                        |p: f32| abs(_mm256_mul_ps(_mm256_sub_ps(_mm256_set1_ps(p), o[h]), inv));
                    let m = _mm256_max_ps(plane(root.min[a]), plane(root.max[a]));
                    reach[h] = _mm256_add_ps(abs(oi), m);
                    let far_s = _mm256_add_ps(_mm256_mul_ps(reach[h], eighth), tiny);
                    let near_s = _mm256_add_ps(_mm256_mul_ps(abs(oi), eighth), tiny);
                    lanes.inv[a][h] = inv;
                    lanes.near_c[a][h] = _mm256_add_ps(oi, near_s);
                    lanes.far_c[a][h] = _mm256_sub_ps(oi, far_s);
                }
                *negative = bits(lanes.inv[a].map(|inv| _mm256_cmp_ps::<_CMP_LT_OQ>(inv, zero)));
                let big = _mm256_set1_ps(1e36);
                active &= bits(reach.map(|r| _mm256_cmp_ps::<_CMP_LT_OQ>(r, big)));
            }
            if active == 0 {
                return lanes;
            }
            // The first ray's octant (bit a: d[a] ≥ 0, as
            // `RaySetup::octant`), and the rays that share it.
            let first = active.trailing_zeros();
            for (a, &neg) in negative.iter().enumerate() {
                let negative_here = neg >> first & 1 != 0;
                active &= if negative_here { neg } else { !neg };
                lanes.octant |= u32::from(!negative_here) << a;
                lanes.near[a] = a + 3 * usize::from(negative_here);
                lanes.far[a] = a + 3 * usize::from(!negative_here);
            }
            lanes.active = active;
            // The interval of the packet's rays (of those that take it):
            // other lanes are set to the neutral value, then the halves
            // reduced in turn.
            let pick = |h: usize| {
                let bit = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
                let here = _mm256_set1_epi32(i32::from(active >> (8 * h) & 0xff));
                _mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_and_si256(here, bit), bit))
            };
            let taken = [pick(0), pick(1)];
            let hull = |v: &[__m256; 2], max: bool| {
                let neutral = _mm256_set1_ps(if max {
                    f32::NEG_INFINITY
                } else {
                    f32::INFINITY
                });
                let (a, b) = (
                    _mm256_blendv_ps(neutral, v[0], taken[0]),
                    _mm256_blendv_ps(neutral, v[1], taken[1]),
                );
                let op = |x: __m256, y: __m256| {
                    if max {
                        _mm256_max_ps(x, y)
                    } else {
                        _mm256_min_ps(x, y)
                    }
                };
                let x = op(a, b);
                let x = op(x, _mm256_permute2f128_ps::<1>(x, x));
                let x = op(x, _mm256_shuffle_ps::<0b01_00_11_10>(x, x));
                op(x, _mm256_shuffle_ps::<0b10_11_00_01>(x, x))
            };
            for a in 0..3 {
                lanes.inv_lo[a] = hull(&lanes.inv[a], false);
                lanes.inv_hi[a] = hull(&lanes.inv[a], true);
                lanes.near_c_hi[a] = hull(&lanes.near_c[a], true);
                lanes.far_c_lo[a] = hull(&lanes.far_c[a], false);
            }
            lanes.t_min_lo = hull(&lanes.t_min, false);
            lanes
        }
    }

    // SAFETY (all): a `Lanes16` exists only where the CPU has AVX2 and FMA.
    impl Lanes for Lanes16 {
        type Wide = [__m256; 2];

        #[inline(always)]
        fn active(&self) -> u16 {
            self.active
        }

        #[inline(always)]
        fn octant(&self) -> u32 {
            self.octant
        }

        #[inline(always)]
        fn test(
            &self,
            node: &Bvh8Node,
            k: usize,
            mask: u16,
            bound: [__m256; 2],
        ) -> (u16, [__m256; 2]) {
            // Straight-line code: closures and `map` here would not be
            // inlined into the AVX2 callers, nor their intrinsics.
            // SAFETY: AVX2 and FMA (see above).
            unsafe {
                let p = |row: usize| _mm256_broadcast_ss(&node.planes[row].0[k]);
                let [n0, n1, n2] = self.near;
                let [f0, f1, f2] = self.far;
                let (pnx, pny, pnz) = (p(n0), p(n1), p(n2));
                let (pfx, pfy, pfz) = (p(f0), p(f1), p(f2));
                let mut enter = [_mm256_setzero_ps(); 2];
                let mut hit = 0u16;
                for h in 0..2 {
                    // A half without rays is skipped.
                    if mask >> (8 * h) & 0xff == 0 {
                        continue;
                    }
                    let nx = _mm256_fmsub_ps(pnx, self.inv[0][h], self.near_c[0][h]);
                    let ny = _mm256_fmsub_ps(pny, self.inv[1][h], self.near_c[1][h]);
                    let nz = _mm256_fmsub_ps(pnz, self.inv[2][h], self.near_c[2][h]);
                    let fx = _mm256_fmsub_ps(pfx, self.inv[0][h], self.far_c[0][h]);
                    let fy = _mm256_fmsub_ps(pfy, self.inv[1][h], self.far_c[1][h]);
                    let fz = _mm256_fmsub_ps(pfz, self.inv[2][h], self.far_c[2][h]);
                    let e = _mm256_max_ps(_mm256_max_ps(nx, ny), _mm256_max_ps(nz, self.t_min[h]));
                    let x = _mm256_min_ps(_mm256_min_ps(fx, fy), _mm256_min_ps(fz, bound[h]));
                    enter[h] = e;
                    let inside = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(e, x)) as u16;
                    hit |= inside << (8 * h);
                }
                (hit & mask, enter)
            }
        }

        /// Each ray's fused distance `fl(p·inv − c)` to a near plane `p` is
        /// at least `fl(p·inv_lo − near_c_hi)` where `p ≥ 0` and at least
        /// `fl(p·inv_hi − near_c_hi)` where `p < 0`, since one rounding is
        /// monotonic: the lesser of the two bounds every ray's near
        /// distance from below, and likewise the greater of the far ones
        /// (with `far_c_lo`) every far distance from above. A child no
        /// interval of those bounds meets (entry above exit, with the least
        /// `t_min` and `t_max` widened) is entered by no ray.
        #[inline(always)]
        fn cull(&self, node: &Bvh8Node, t_max: f32) -> u32 {
            // SAFETY: AVX2 and FMA; rows are 8 floats aligned to 32 bytes.
            unsafe {
                let row = |r: usize| _mm256_load_ps(node.planes[r].0.as_ptr());
                let [n0, n1, n2] = self.near;
                let [f0, f1, f2] = self.far;
                let (pnx, pny, pnz) = (row(n0), row(n1), row(n2));
                let (pfx, pfy, pfz) = (row(f0), row(f1), row(f2));
                let (lo, hi) = (&self.inv_lo, &self.inv_hi);
                let (nc, fc) = (&self.near_c_hi, &self.far_c_lo);
                let nx = _mm256_min_ps(
                    _mm256_fmsub_ps(pnx, lo[0], nc[0]),
                    _mm256_fmsub_ps(pnx, hi[0], nc[0]),
                );
                let ny = _mm256_min_ps(
                    _mm256_fmsub_ps(pny, lo[1], nc[1]),
                    _mm256_fmsub_ps(pny, hi[1], nc[1]),
                );
                let nz = _mm256_min_ps(
                    _mm256_fmsub_ps(pnz, lo[2], nc[2]),
                    _mm256_fmsub_ps(pnz, hi[2], nc[2]),
                );
                let fx = _mm256_max_ps(
                    _mm256_fmsub_ps(pfx, lo[0], fc[0]),
                    _mm256_fmsub_ps(pfx, hi[0], fc[0]),
                );
                let fy = _mm256_max_ps(
                    _mm256_fmsub_ps(pfy, lo[1], fc[1]),
                    _mm256_fmsub_ps(pfy, hi[1], fc[1]),
                );
                let fz = _mm256_max_ps(
                    _mm256_fmsub_ps(pfz, lo[2], fc[2]),
                    _mm256_fmsub_ps(pfz, hi[2], fc[2]),
                );
                let bound = _mm256_set1_ps(t_max * WIDEN);
                let e = _mm256_max_ps(_mm256_max_ps(nx, ny), _mm256_max_ps(nz, self.t_min_lo));
                let x = _mm256_min_ps(_mm256_min_ps(fx, fy), _mm256_min_ps(fz, bound));
                _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(e, x)) as u32
            }
        }

        #[inline(always)]
        fn widen(&self, t_max: &[f32; PACKET]) -> [__m256; 2] {
            // SAFETY: 16 floats.
            unsafe {
                let k = _mm256_set1_ps(WIDEN);
                [
                    _mm256_mul_ps(_mm256_loadu_ps(t_max.as_ptr()), k),
                    _mm256_mul_ps(_mm256_loadu_ps(t_max.as_ptr().add(8)), k),
                ]
            }
        }

        #[inline(always)]
        fn le(&self, mask: u16, d: [__m256; 2], bound: [__m256; 2]) -> u16 {
            // SAFETY: AVX (see above).
            unsafe {
                let le0 = _mm256_cmp_ps::<_CMP_LE_OQ>(d[0], bound[0]);
                let le1 = _mm256_cmp_ps::<_CMP_LE_OQ>(d[1], bound[1]);
                bits([le0, le1]) & mask
            }
        }

        #[inline(always)]
        fn zero(&self) -> [__m256; 2] {
            unsafe { [_mm256_setzero_ps(); 2] }
        }
    }
}
