//! The node visit in 256-bit registers (AVX2 and FMA), compiled per
//! octant; see [`super`].

use super::{Bvh8Node, COMPRESS, NodeVisit, RaySetup, Stack, WIDEN, WIDTH};
use std::arch::x86_64::*;

/// The eight fused slab tests in one 256-bit register each, and the
/// push as permutes. Only made where the CPU has AVX2 and FMA, for rays
/// that take the fused test ([`RaySetup::fused`]), of octant `OCT` (as
/// [`RaySetup::octant`]), whose near and far planes are then known when
/// compiling.
#[derive(Clone, Copy)]
pub(super) struct Avx2Lanes<const OCT: u32> {
    inv: [__m256; 3],
    near_c: [__m256; 3],
    far_c: [__m256; 3],
    t_min: __m256,
}

impl<const OCT: u32> Avx2Lanes<OCT> {
    /// The row of the near plane of axis `a`: `max` where `d[a] < 0`.
    const NEAR: [usize; 3] = [
        if OCT & 1 != 0 { 0 } else { 3 },
        if OCT & 2 != 0 { 1 } else { 4 },
        if OCT & 4 != 0 { 2 } else { 5 },
    ];
    const FAR: [usize; 3] = [
        (Self::NEAR[0] + 3) % 6,
        (Self::NEAR[1] + 3) % 6,
        (Self::NEAR[2] + 3) % 6,
    ];
    const SHIFT: i32 = 3 * OCT as i32;

    /// The caller makes sure that the CPU has AVX2 and FMA, and that
    /// the ray is of octant `OCT` and takes the fused test.
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    pub(super) fn new(r: &RaySetup) -> Self {
        debug_assert_eq!((r.octant, r.fused), (OCT, true));
        let splat = |v: crate::math::Vec3| [0, 1, 2].map(|a| _mm256_set1_ps(v[a]));
        Avx2Lanes {
            inv: splat(r.inv),
            near_c: splat(r.near_c),
            far_c: splat(r.far_c),
            t_min: _mm256_set1_ps(r.t_min),
        }
    }
}

impl<const OCT: u32> Avx2Lanes<OCT> {
    /// The push of [`NodeVisit::visit`], from a node's slab tests
    /// already made (`enter`, `hit` as [`Avx2Lanes::test`] or
    /// [`Avx2Lanes::test_root`] return them).
    #[inline(always)]
    pub(super) fn push(
        &self,
        n: &Bvh8Node,
        enter: __m256,
        hit: __m256,
        stack: &mut Stack,
    ) -> Option<u32> {
        // SAFETY (all): AVX2 as in `test`; `child` and `order` are 8
        // u32 each, and the stack has room for 8 more entries (checked).
        unsafe {
            let mask = _mm256_movemask_ps(hit) as u32;
            if mask == 0 {
                return None;
            }
            if mask & (mask - 1) == 0 {
                return Some(n.child[mask.trailing_zeros() as usize]);
            }
            // Lane j: the child visited j-th; the mask in that order.
            let order = _mm256_srl_epi32(
                _mm256_load_si256(n.order.as_ptr().cast()),
                _mm_cvtsi32_si128(Self::SHIFT),
            );
            let in_order = _mm256_movemask_ps(_mm256_permutevar8x32_ps(hit, order)) as usize;
            let push = _mm256_permutevar8x32_epi32(
                order,
                _mm256_loadu_si256(COMPRESS[in_order].as_ptr().cast()),
            );
            let child =
                _mm256_permutevar8x32_epi32(_mm256_loadu_si256(n.child.as_ptr().cast()), push);
            let dist = _mm256_permutevar8x32_ps(enter, push);
            // All eight lanes are stored; the first `count − 1` are
            // kept, and the next (the first in order) is returned.
            let len = stack.len;
            let count = in_order.count_ones() as usize;
            let (entries, dists) = (
                &mut stack.entry.0[len..len + WIDTH],
                &mut stack.dist.0[len..len + WIDTH],
            );
            _mm256_storeu_si256(entries.as_mut_ptr().cast(), child);
            _mm256_storeu_ps(dists.as_mut_ptr().cast(), dist);
            stack.len = len + count - 1;
            let k = (n.order[in_order.trailing_zeros() as usize] >> Self::SHIFT) & 7;
            Some(n.child[k as usize])
        }
    }

    /// The slab tests of the root `n` for the interval ending at `t_max`
    /// (widened here as the kernels' visits take it): the same tests as a
    /// kernel's visit of `n`. The per-ray entry makes them, so that a ray
    /// that misses every child of the root leaves at once, and the kernel
    /// starts from them without testing the root again.
    #[inline(always)]
    pub(super) fn test_root(&self, n: &Bvh8Node, t_max: f32) -> RootTest {
        let (enter, hit) = self.test(n, self.bound(t_max));
        RootTest { enter, hit }
    }

    /// The entry distances and the mask of the children hit, as
    /// [`super::PortableLanes::test`]'s fused test, operation for
    /// operation (max and min return their second operand for NaN in
    /// both).
    #[inline(always)]
    fn test(&self, n: &Bvh8Node, t_max: f32) -> (__m256, __m256) {
        self.test_from(n, self.t_min, t_max)
    }

    /// [`Avx2Lanes::test`] for the interval from `t_min` instead of the
    /// ray's.
    #[inline(always)]
    fn test_from(&self, n: &Bvh8Node, t_min: __m256, t_max: f32) -> (__m256, __m256) {
        // SAFETY: an `Avx2Lanes` exists only where the CPU has AVX2 and
        // FMA.
        unsafe {
            fused_test(
                n,
                (Self::NEAR, Self::FAR),
                (&self.inv, &self.near_c, &self.far_c),
                t_min,
                t_max,
            )
        }
    }
}

/// The eight fused slab tests of a node: the entry distances and the mask
/// of the children hit within `[t_min, t_max]`, for near and far plane rows
/// `rows` (constants, known when compiling the kernel of an octant) and
/// the ray's constants `(inv, near_c, far_c)` splatted. The caller makes sure that the CPU has AVX2 and FMA (this
/// is inlined into callers compiled with them).
#[inline(always)]
unsafe fn fused_test(
    n: &Bvh8Node,
    (near_rows, far_rows): ([usize; 3], [usize; 3]),
    (inv, near_c, far_c): (&[__m256; 3], &[__m256; 3], &[__m256; 3]),
    t_min: __m256,
    t_max: f32,
) -> (__m256, __m256) {
    // SAFETY (all): the CPU has AVX2 and FMA (the caller), and each row
    // is 8 floats aligned to 32 bytes (`Lanes8`).
    let lanes = |row: usize| unsafe { _mm256_load_ps(n.planes[row].0.as_ptr()) };
    let near = |a: usize| unsafe { _mm256_fmsub_ps(lanes(near_rows[a]), inv[a], near_c[a]) };
    let far = |a: usize| unsafe { _mm256_fmsub_ps(lanes(far_rows[a]), inv[a], far_c[a]) };
    let (nx, ny, nz) = (near(0), near(1), near(2));
    let (fx, fy, fz) = (far(0), far(1), far(2));
    unsafe {
        let enter = _mm256_max_ps(_mm256_max_ps(nx, ny), _mm256_max_ps(nz, t_min));
        let exit = _mm256_min_ps(
            _mm256_min_ps(fx, fy),
            _mm256_min_ps(fz, _mm256_set1_ps(t_max)),
        );
        (enter, _mm256_cmp_ps::<_CMP_LE_OQ>(enter, exit))
    }
}

/// What [`Avx2Lanes::test_root`] found: the entry distances and the hit lanes.
pub(super) struct RootTest {
    pub(super) enter: __m256,
    pub(super) hit: __m256,
}

impl RootTest {
    /// Whether any child of the root is hit.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) fn any(&self) -> bool {
        _mm256_movemask_ps(self.hit) != 0
    }
}

impl<const OCT: u32> NodeVisit for Avx2Lanes<OCT> {
    #[inline(always)]
    fn bound(&self, t_max: f32) -> f32 {
        t_max * WIDEN
    }

    /// As [`super::PortableLanes`]'s: the same entries pushed in the
    /// same order. Inlined into the callers compiled with AVX2 enabled.
    #[inline(always)]
    fn visit(&self, n: &Bvh8Node, t_max: f32, stack: &mut Stack) -> Option<u32> {
        let (enter, hit) = self.test(n, t_max);
        self.push(n, enter, hit, stack)
    }

    #[inline(always)]
    fn visit_any(&self, n: &Bvh8Node, t_max: f32, stack: &mut Stack) -> (Option<u32>, u32) {
        // SAFETY (all): as in `push`.
        unsafe {
            // From 0, as the portable visit (see `NodeVisit::visit_any`):
            // a zeroing idiom, where `t_min` would be read from memory.
            let (_, hit) = self.test_from(n, _mm256_setzero_ps(), t_max);
            // The sign bit marks leaves (and EMPTY, never hit).
            let child = _mm256_loadu_si256(n.child.as_ptr().cast());
            let is_leaf = _mm256_castsi256_ps(child);
            let leaves = _mm256_movemask_ps(_mm256_and_ps(hit, is_leaf)) as u32;
            let mask = _mm256_movemask_ps(_mm256_andnot_ps(is_leaf, hit)) as u32;
            if mask & mask.wrapping_sub(1) == 0 {
                let next = (mask != 0).then(|| n.child[mask.trailing_zeros() as usize]);
                return (next, leaves);
            }
            // The children hit, highest lane first; all eight lanes are
            // stored, the first `count − 1` kept, the lowest returned.
            let pushed = _mm256_permutevar8x32_epi32(
                child,
                _mm256_loadu_si256(COMPRESS[mask as usize].as_ptr().cast()),
            );
            let len = stack.len;
            let entries = &mut stack.entry.0[len..len + WIDTH];
            _mm256_storeu_si256(entries.as_mut_ptr().cast(), pushed);
            stack.len = len + mask.count_ones() as usize - 1;
            (Some(n.child[mask.trailing_zeros() as usize]), leaves)
        }
    }
}
