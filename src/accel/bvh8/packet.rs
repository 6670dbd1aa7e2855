//! Closest hits of coherent rays traced together: a packet of up to
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

use super::{Bvh8, Bvh8Node, LEAF, STACK};
use crate::accel::bvh::TraversalCounters;
use crate::math::Ray;
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
        let mut packed = 0u16;
        #[cfg(target_arch = "x86_64")]
        if has_avx512() {
            // SAFETY: the CPU has AVX-512F and FMA (`has_avx512`).
            packed = unsafe { self.closest_avx512(rays, counters, &mut test, out) };
        }
        // The rest one by one.
        for (r, ray) in rays.iter().enumerate() {
            if packed & 1 << r == 0 {
                out[r] = self.closest_leaves(ray, counters, |first, count, t_max| {
                    test(r, first, count, t_max)
                });
            }
        }
    }

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
        let n = rays.len();
        if n == 0 {
            return 0;
        }
        // Lane r: ray r's value (lanes from `n` on repeat the last ray's).
        let lane = |f: &dyn Fn(&Ray) -> f32| -> __m512 {
            let v: [f32; PACKET] = std::array::from_fn(|r| f(&rays[r.min(n - 1)]));
            // SAFETY: 16 floats.
            unsafe { _mm512_loadu_ps(v.as_ptr()) }
        };
        let o = [0, 1, 2].map(|a| lane(&|r| r.o[a]));
        let t_min = lane(&|r| r.t_min);
        // `RaySetup::new` for all rays at once, operation for operation.
        let inv = [0, 1, 2].map(|a| {
            let inv = _mm512_div_ps(_mm512_set1_ps(1.0), lane(&|r| r.d[a]));
            _mm512_min_ps(
                _mm512_max_ps(inv, _mm512_set1_ps(-1e30)),
                _mm512_set1_ps(1e30),
            )
        });
        let root = self.root();
        let abs = |v: __m512| _mm512_abs_ps(v);
        let eighth = _mm512_set1_ps(1.0 / (1 << 21) as f32);
        let tiny = _mm512_set1_ps(f32::MIN_POSITIVE);
        let mut near_c = [_mm512_setzero_ps(); 3];
        let mut far_c = [_mm512_setzero_ps(); 3];
        // Rays that take the fused test (the others are traced alone).
        let mut active = _mm512_cmp_ps_mask::<_CMP_GE_OQ>(t_min, _mm512_setzero_ps());
        active &= ((1u32 << n) - 1) as u16;
        for a in 0..3 {
            let oi = _mm512_mul_ps(o[a], inv[a]);
            let plane = |p: f32| {
                abs(_mm512_mul_ps(
                    _mm512_sub_ps(_mm512_set1_ps(p), o[a]),
                    inv[a],
                ))
            };
            let m = _mm512_max_ps(plane(root.min[a]), plane(root.max[a]));
            let reach = _mm512_add_ps(abs(oi), m);
            let far_s = _mm512_add_ps(_mm512_mul_ps(reach, eighth), tiny);
            let near_s = _mm512_add_ps(_mm512_mul_ps(abs(oi), eighth), tiny);
            near_c[a] = _mm512_add_ps(oi, near_s);
            far_c[a] = _mm512_sub_ps(oi, far_s);
            active &= _mm512_cmp_ps_mask::<_CMP_LT_OQ>(reach, _mm512_set1_ps(1e36));
        }
        if active == 0 {
            return 0;
        }
        // Rays with a negative direction on an axis: their near plane is the max.
        let negative: [__mmask16; 3] =
            [0, 1, 2].map(|a| _mm512_cmp_ps_mask::<_CMP_LT_OQ>(inv[a], _mm512_setzero_ps()));
        // The first ray's octant orders the children (bit a: d[a] ≥ 0).
        let first = active.trailing_zeros();
        let octant = (0..3).fold(0, |q, a| q | u32::from(negative[a] >> first & 1 == 0) << a);
        let shift = 3 * octant;
        let mut t_max: [f32; PACKET] =
            std::array::from_fn(|r| rays.get(r).map_or(f32::INFINITY, |ray| ray.t_max));
        // SAFETY: 16 floats.
        let widen = |t: &[f32; PACKET]| unsafe {
            _mm512_mul_ps(
                _mm512_loadu_ps(t.as_ptr()),
                _mm512_set1_ps(super::traverse::WIDEN),
            )
        };
        let mut bound = widen(&t_max);
        let mut best = [None; PACKET];

        // The stack: entries, their rays, their rays' entry distances.
        // (Not initialised: zeroing 33 kB would cost more than a packet's
        // traversal; an entry is read only after it is written.)
        let mut entries = [const { MaybeUninit::<u32>::uninit() }; STACK];
        let mut masks = [const { MaybeUninit::<u16>::uninit() }; STACK];
        let mut dists = [const { MaybeUninit::<__m512>::uninit() }; STACK];
        let mut len = 0usize;
        let (mut visited, mut tests) = (0u64, 0u64);
        let (mut entry, mut mask) = (0u32, active);
        'visit: loop {
            if entry & LEAF == 0 {
                visited += u64::from(mask.count_ones());
                let node = &self.nodes[entry as usize];
                // Each child against every ray of the mask.
                let mut hit = [0u16; 8];
                let mut enter = [_mm512_setzero_ps(); 8];
                for k in 0..8 {
                    if node.child[k] == super::EMPTY {
                        continue;
                    }
                    let plane = |row: usize| _mm512_set1_ps(node.planes[row].0[k]);
                    let t = |a: usize, near: bool| {
                        let (lo, hi) = (plane(a), plane(a + 3));
                        // Near: the min plane, or the max where d[a] < 0.
                        let p = if near {
                            _mm512_mask_blend_ps(negative[a], lo, hi)
                        } else {
                            _mm512_mask_blend_ps(negative[a], hi, lo)
                        };
                        let c = if near { near_c[a] } else { far_c[a] };
                        _mm512_fmsub_ps(p, inv[a], c)
                    };
                    let (nx, ny, nz) = (t(0, true), t(1, true), t(2, true));
                    let (fx, fy, fz) = (t(0, false), t(1, false), t(2, false));
                    let e = _mm512_max_ps(_mm512_max_ps(nx, ny), _mm512_max_ps(nz, t_min));
                    let x = _mm512_min_ps(_mm512_min_ps(fx, fy), _mm512_min_ps(fz, bound));
                    hit[k] = _mm512_mask_cmp_ps_mask::<_CMP_LE_OQ>(mask, e, x);
                    enter[k] = e;
                }
                // Nearest first for the leader's octant: push the others
                // farthest first.
                let mut next = None;
                for j in (0..8).rev() {
                    let k = (node.order[j] >> shift & 7) as usize;
                    if hit[k] != 0
                        && let Some(previous) = next.replace(k)
                    {
                        entries[len].write(node.child[previous]);
                        masks[len].write(hit[previous]);
                        dists[len].write(enter[previous]);
                        len += 1;
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
                    bound = widen(&t_max);
                }
            }
            // Entries go on with the rays whose closest hit so far is not
            // before them.
            while len > 0 {
                len -= 1;
                // SAFETY: entries below `len` were written.
                let (e, m, d) = unsafe {
                    (
                        entries[len].assume_init(),
                        masks[len].assume_init(),
                        dists[len].assume_init(),
                    )
                };
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
            if active & 1 << r != 0 {
                *o = best[r];
            }
        }
        active
    }
}

/// Whether the AVX-512 packet traversal can run here (AVX-512F, FMA,
/// POPCNT and BMI1; checked once, then cached by the standard library), and
/// the portable path is not forced (see [`super::force_portable`]).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn has_avx512() -> bool {
    std::arch::is_x86_feature_detected!("avx512f")
        && std::arch::is_x86_feature_detected!("fma")
        && std::arch::is_x86_feature_detected!("popcnt")
        && std::arch::is_x86_feature_detected!("bmi1")
        && !super::traverse::portable_forced()
}
