//! The packet lanes on AVX2: sixteen rays as two 256-bit halves, the rays
//! of one octant, with interval culling (see [`Lanes16`]).

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
    fn test(&self, node: &Bvh8Node, k: usize, mask: u16, bound: [__m256; 2]) -> (u16, [__m256; 2]) {
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
