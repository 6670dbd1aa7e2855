//! Closest and any hits of coherent rays traced together: a packet of up to
//! [`PACKET`] rays (a 4×4 block of camera rays, say) goes down the tree as
//! one, with a mask of the rays still in each subtree (Wald et al.,
//! "Interactive Rendering with Coherent Ray Tracing", 2001; with masks per
//! stack entry as Reshetov et al.'s "Multi-Level Ray Tracing", 2005).
//!
//! One AVX-512 register holds a quantity for all sixteen rays, so a child's
//! box is tested against every ray of the packet with the operations that
//! test one ray against eight boxes in the single-ray traversal: a node is
//! eight such tests, whatever the number of rays, and its load, its
//! decisions and their mispredictions are paid once per packet instead of
//! once per ray. Each ray's test is the single-ray fused test (see
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
//! the fused test does not take, and packets on CPUs without AVX-512, are
//! traced one by one.
//!
//! Any hits (shadow rays) go the same way without the order and the
//! distances, as the single-ray any-hit traversal does: a node's leaves are
//! tested at once for the rays that reach them, and a ray leaves the
//! packet as soon as something blocks it.

use super::{Bvh8, Bvh8Node, LEAF};
use crate::accel::bvh::TraversalCounters;
use crate::math::Ray;

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
        // SAFETY: the CPU has what `avx512` needs.
        let packed = match avx512::available() {
            true => unsafe { self.closest_avx512(rays, counters, &mut test, out) },
            false => 0,
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
        // SAFETY: the CPU has what `avx512` needs.
        let packed = match avx512::available() {
            true => unsafe { self.any_avx512(rays, counters, &mut test, out) },
            false => 0,
        };
        #[cfg(not(target_arch = "x86_64"))]
        let packed = 0u16;
        for (r, ray) in rays.iter().enumerate() {
            if packed & 1 << r == 0 {
                out[r] = self.any_leaves(ray, counters, |first, count| test(r, first, count));
            }
        }
    }

    /// The closest hits of the rays of `rays` that take the fused test,
    /// into `out`; returns the mask of those rays.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,fma,popcnt,bmi1")]
    fn closest_avx512(
        &self,
        rays: &[Ray],
        counters: &mut TraversalCounters,
        test: &mut impl FnMut(usize, u32, u32, f32) -> Option<(u32, f32)>,
        out: &mut [Option<(u32, f32)>],
    ) -> u16 {
        use std::arch::x86_64::*;
        let lanes = avx512::Lanes16::new(rays, &self.root());
        if lanes.active == 0 {
            return 0;
        }
        let shift = 3 * lanes.octant;
        let mut t_max: [f32; PACKET] =
            std::array::from_fn(|r| rays.get(r).map_or(f32::INFINITY, |ray| ray.t_max));
        let mut bound = avx512::widen(&t_max);
        let mut best = [None; PACKET];
        // The stack: entries, their rays, their rays' entry distances.
        let mut stack = avx512::Stack::new();
        let (mut visited, mut tests) = (0u64, 0u64);
        let (mut entry, mut mask) = (0u32, lanes.active);
        'visit: loop {
            if entry & LEAF == 0 {
                visited += u64::from(mask.count_ones());
                let node = &self.nodes[entry as usize];
                // Each child against every ray of the mask.
                let mut hit = [0u16; 8];
                let mut enter = [_mm512_setzero_ps(); 8];
                for k in 0..8 {
                    if node.child[k] != super::EMPTY {
                        (hit[k], enter[k]) = lanes.test(node, k, mask, bound);
                    }
                }
                // Nearest first for the first ray's octant: push the
                // others farthest first.
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
                    bound = avx512::widen(&t_max);
                }
            }
            // Entries go on with the rays whose closest hit so far is not
            // before them.
            while let Some((e, m, d)) = stack.pop() {
                let m = _mm512_mask_cmp_ps_mask::<_CMP_LE_OQ>(m, d, bound);
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
            if lanes.active & 1 << r != 0 {
                *o = best[r];
            }
        }
        lanes.active
    }

    /// The any hits of the rays of `rays` that take the fused test, into
    /// `out`; returns the mask of those rays.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,fma,popcnt,bmi1")]
    fn any_avx512(
        &self,
        rays: &[Ray],
        counters: &mut TraversalCounters,
        test: &mut impl FnMut(usize, u32, u32) -> bool,
        out: &mut [bool],
    ) -> u16 {
        use std::arch::x86_64::*;
        let lanes = avx512::Lanes16::new(rays, &self.root());
        if lanes.active == 0 {
            return 0;
        }
        let t_max: [f32; PACKET] =
            std::array::from_fn(|r| rays.get(r).map_or(f32::INFINITY, |ray| ray.t_max));
        let bound = avx512::widen(&t_max);
        // Only nodes go through the stack (distances unused).
        let mut stack = avx512::Stack::new();
        let (mut visited, mut tests) = (0u64, 0u64);
        let mut blocked = 0u16;
        let (mut entry, mut mask) = (0u32, lanes.active);
        'visit: loop {
            visited += u64::from(mask.count_ones());
            let node = &self.nodes[entry as usize];
            let mut next = None;
            for k in (0..8).rev() {
                let child = node.child[k];
                if child == super::EMPTY {
                    continue;
                }
                let (hit, _) = lanes.test(node, k, mask & !blocked, bound);
                if hit == 0 {
                    continue;
                }
                if child & LEAF == 0 {
                    if let Some((c, m)) = next.replace((child, hit)) {
                        stack.push(c, m, _mm512_setzero_ps());
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
                if blocked == lanes.active {
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
            if lanes.active & 1 << r != 0 {
                *o = blocked & 1 << r != 0;
            }
        }
        lanes.active
    }
}

#[cfg(target_arch = "x86_64")]
mod avx512 {
    use super::PACKET;
    use crate::accel::bvh8::traverse::WIDEN;
    use crate::accel::bvh8::{Bvh8Node, STACK};
    use crate::math::{Aabb, Ray};
    use std::arch::x86_64::*;
    use std::mem::MaybeUninit;

    /// Whether the packet traversals can run here (AVX-512F, FMA, POPCNT
    /// and BMI1; checked once, then cached by the standard library), and
    /// the portable path is not forced (see
    /// [`crate::accel::force_portable`]).
    #[inline(always)]
    pub(super) fn available() -> bool {
        std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("fma")
            && std::arch::is_x86_feature_detected!("popcnt")
            && std::arch::is_x86_feature_detected!("bmi1")
            && !crate::accel::bvh8::traverse::portable_forced()
    }

    /// Each ray's fused-test constants in its lane (`RaySetup::new` for
    /// sixteen rays at once, operation for operation), the rays that take
    /// that test, and the first one's octant.
    pub(super) struct Lanes16 {
        inv: [__m512; 3],
        near_c: [__m512; 3],
        far_c: [__m512; 3],
        t_min: __m512,
        /// Rays with `d[a] < 0`: their near plane on axis `a` is the max.
        negative: [__mmask16; 3],
        /// The rays that take the fused test (the others are traced alone).
        pub(super) active: u16,
        pub(super) octant: u32,
    }

    impl Lanes16 {
        /// The caller makes sure the CPU has AVX-512F and FMA.
        #[target_feature(enable = "avx512f,fma")]
        #[inline]
        pub(super) fn new(rays: &[Ray], root: &Aabb) -> Lanes16 {
            let n = rays.len();
            // Lane r: ray r's value (lanes from `n` on repeat the last ray's).
            let lane = |f: &dyn Fn(&Ray) -> f32| -> __m512 {
                let v: [f32; PACKET] = std::array::from_fn(|r| f(&rays[r.min(n - 1)]));
                // SAFETY: 16 floats.
                unsafe { _mm512_loadu_ps(v.as_ptr()) }
            };
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
            lanes.t_min = lane(&|r| r.t_min);
            let mut active = _mm512_cmp_ps_mask::<_CMP_GE_OQ>(lanes.t_min, _mm512_setzero_ps());
            active &= ((1u32 << n) - 1) as u16;
            let eighth = _mm512_set1_ps(1.0 / (1 << 21) as f32);
            let tiny = _mm512_set1_ps(f32::MIN_POSITIVE);
            for a in 0..3 {
                let o = lane(&|r| r.o[a]);
                let inv = _mm512_div_ps(_mm512_set1_ps(1.0), lane(&|r| r.d[a]));
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

        /// Child `k` of `node` against the rays of `mask` whose intervals
        /// end at `bound` (widened): the rays that enter its box, and every
        /// lane's entry distance.
        #[inline(always)]
        pub(super) fn test(
            &self,
            node: &Bvh8Node,
            k: usize,
            mask: u16,
            bound: __m512,
        ) -> (u16, __m512) {
            // SAFETY (all): a `Lanes16` exists only where the CPU has AVX-512F and FMA.
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
    }

    /// `t_max` widened as the fused test widens it (`NodeVisit::bound`).
    #[inline(always)]
    pub(super) fn widen(t_max: &[f32; PACKET]) -> __m512 {
        // SAFETY: only called from functions compiled with AVX-512F; 16 floats.
        unsafe { _mm512_mul_ps(_mm512_loadu_ps(t_max.as_ptr()), _mm512_set1_ps(WIDEN)) }
    }

    /// The packets' stack: entries, their rays, and their rays' entry
    /// distances. Not initialised (zeroing 33 kB would cost more than a
    /// packet's traversal): an entry is read only after it is written.
    pub(super) struct Stack {
        entries: [MaybeUninit<u32>; STACK],
        masks: [MaybeUninit<u16>; STACK],
        dists: [MaybeUninit<__m512>; STACK],
        len: usize,
    }

    impl Stack {
        #[inline(always)]
        pub(super) fn new() -> Stack {
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
        pub(super) fn push(&mut self, entry: u32, mask: u16, dist: __m512) {
            self.entries[self.len].write(entry);
            self.masks[self.len].write(mask);
            self.dists[self.len].write(dist);
            self.len += 1;
        }

        #[inline(always)]
        pub(super) fn pop(&mut self) -> Option<(u32, u16, __m512)> {
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
}
