//! The packet lanes on AVX-512: sixteen rays in one 512-bit register per
//! quantity, rays of any octant (see [`Lanes16`]).

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
