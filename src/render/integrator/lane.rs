//! The arithmetic of one SIMD lane for [`super::wave`]: structure-of-arrays
//! lanes of [`BATCH`] values, per-component vector helpers written as
//! glam computes them, and copies of the scalar functions with plain
//! selects in place of branches (which the compiler vectorises; the tests
//! check them against the originals bit for bit).

use crate::geometry::batch::{BATCH, Closest, RayBatch};
use crate::math::MIN_OFFSET;
use crate::shading::Fresnel;

/// Lanes computed together (one AVX-512 vector, two AVX2 ones).
pub(super) const GROUP: usize = 16;

pub(super) type Lane = [f32; BATCH];
pub(super) type Lane3 = [Lane; 3];
/// Flags per lane, 0 or 1 (as wide as the `f32` lanes: the compiler
/// vectorises loops whose arrays have elements of one size).
pub(super) type Mask = [u32; BATCH];

#[inline(always)]
pub(super) fn get(v: &Lane3, j: usize) -> [f32; 3] {
    [v[0][j], v[1][j], v[2][j]]
}

#[inline(always)]
pub(super) fn put(v: &mut Lane3, j: usize, x: [f32; 3]) {
    [v[0][j], v[1][j], v[2][j]] = x;
}

/// The point `o + t·d` of lane `j`'s ray at its hit.
#[inline(always)]
pub(super) fn at(rays: &RayBatch, best: &Closest, j: usize) -> [f32; 3] {
    let t = best.t[j];
    [
        rays.o[0][j] + rays.d[0][j] * t,
        rays.o[1][j] + rays.d[1][j] * t,
        rays.o[2][j] + rays.d[2][j] * t,
    ]
}

/// Lane `j` of `v` becomes `x` where `c`.
#[inline(always)]
pub(super) fn put_if(v: &mut Lane3, j: usize, c: bool, x: [f32; 3]) {
    let old = get(v, j);
    put(v, j, pick(c, x, old));
}

/// glam's `a.dot(b)`: `(a.x·b.x + a.y·b.y) + a.z·b.z`.
#[inline(always)]
pub(super) fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    (a[0] * b[0] + a[1] * b[1]) + a[2] * b[2]
}

#[inline(always)]
pub(super) fn neg(a: [f32; 3]) -> [f32; 3] {
    a.map(|x| -x)
}

/// Copies each of the `N` columns' lanes `j < n` with `keep[j] != 0`, in
/// lane order, to the front of the matching column of `dst` (a stream
/// compaction); returns how many were kept. With AVX-512F (detected at run
/// time) sixteen lanes at a time by a compress and a masked store, else
/// lane by lane; the same copies either way.
#[inline(always)]
pub(super) fn compress<const N: usize>(
    keep: &Mask,
    n: usize,
    src: [&Lane; N],
    dst: [&mut Lane; N],
) -> usize {
    // The vector path reads sixteen lanes from each chunk's start.
    assert!(n <= BATCH, "{n} lanes in a batch of {BATCH}");
    #[cfg(target_arch = "x86_64")]
    if crate::scene::simd_level() >= 2 {
        // SAFETY: the CPU has AVX-512F (checked just above).
        return unsafe { compress_avx512(keep, n, src, dst) };
    }
    compress_scalar(keep, n, src, dst)
}

/// [`compress`] lane by lane.
#[inline(always)]
fn compress_scalar<const N: usize>(
    keep: &Mask,
    n: usize,
    src: [&Lane; N],
    mut dst: [&mut Lane; N],
) -> usize {
    let mut at = 0;
    for (j, &k) in keep[..n].iter().enumerate() {
        if k != 0 {
            for (d, s) in dst.iter_mut().zip(&src) {
                d[at] = s[j];
            }
            at += 1;
        }
    }
    at
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn compress_avx512<const N: usize>(
    keep: &Mask,
    n: usize,
    src: [&Lane; N],
    mut dst: [&mut Lane; N],
) -> usize {
    use std::arch::x86_64::*;
    const W: usize = 16;
    const { assert!(BATCH.is_multiple_of(W)) };
    let mut at = 0;
    for chunk in 0..n.div_ceil(W) {
        let base = chunk * W;
        // Lanes past `n` are never kept.
        let valid: u16 = if n - base >= W {
            !0
        } else {
            (1u16 << (n - base)) - 1
        };
        // SAFETY (all): AVX-512F as the caller checked; every load reads
        // 16 lanes at `base ≤ BATCH − 16` (`base < n ≤ BATCH`, checked by
        // the caller, and a multiple of 16), and every store writes the
        // `count ≤ 16` lanes at `at`, where `at + count ≤ base + 16 ≤
        // BATCH`.
        unsafe {
            let flags = _mm512_loadu_si512(keep[base..].as_ptr().cast());
            let mask = _mm512_test_epi32_mask(flags, flags) & valid;
            let count = mask.count_ones() as usize;
            let store = ((1u32 << count) - 1) as u16;
            for (d, s) in dst.iter_mut().zip(&src) {
                let packed = _mm512_maskz_compress_ps(mask, _mm512_loadu_ps(s[base..].as_ptr()));
                _mm512_mask_storeu_ps(d[at..].as_mut_ptr(), store, packed);
            }
            at += count;
        }
    }
    at
}

/// `a` where `c`, else `b`, by masking bits: no branch, so that a loop of
/// them over lanes compiles to vector blends (LLVM turns a plain `if` on a
/// lane mask back into a branch per lane, mispredicted where the mask has
/// no pattern).
#[inline(always)]
pub(super) fn blend(c: bool, a: f32, b: f32) -> f32 {
    let m = (c as u32).wrapping_neg();
    f32::from_bits((a.to_bits() & m) | (b.to_bits() & !m))
}

#[inline(always)]
pub(super) fn pick(c: bool, a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        if c { a[0] } else { b[0] },
        if c { a[1] } else { b[1] },
        if c { a[2] } else { b[2] },
    ]
}

/// [`crate::math::offset_ray_origin`], per component.
#[inline(always)]
pub(super) fn offset_origin(p: [f32; 3], p_err: [f32; 3], n: [f32; 3], w: [f32; 3]) -> [f32; 3] {
    let d = dot(n.map(f32::abs), p_err).max(MIN_OFFSET);
    let n = pick(dot(w, n) < 0.0, neg(n), n);
    [
        nudge_lane(p[0] + n[0] * d, n[0]),
        nudge_lane(p[1] + n[1] * d, n[1]),
        nudge_lane(p[2] + n[2] * d, n[2]),
    ]
}

pub(super) const Z: Lane = [0.0; BATCH];
pub(super) const Z3: Lane3 = [Z; 3];
pub(super) const F: Mask = [0; BATCH];

/// [`crate::math::nudge`], with plain selects (which the compiler
/// vectorises): one ulp up where `dir > 0`, down where `dir < 0`.
#[inline(always)]
pub(super) fn nudge_lane(x: f32, dir: f32) -> f32 {
    let bits = x.to_bits();
    let magnitude = bits & 0x7fff_ffff;
    let (up, down) = (dir > 0.0, dir < 0.0);
    let negative = bits >> 31 != 0;
    let away = (up & !negative) | (down & negative);
    let towards = (up & negative) | (down & !negative);
    let stepped = bits
        .wrapping_add(u32::from(away))
        .wrapping_sub(u32::from(towards));
    let from_zero = if down { 0x8000_0001 } else { 1 };
    let stepped = if (magnitude == 0) & (up | down) {
        from_zero
    } else {
        stepped
    };
    let stays = (magnitude > 0x7f80_0000) | ((magnitude == 0x7f80_0000) & away);
    f32::from_bits(if stays { bits } else { stepped })
}

/// [`crate::math::floor`], bit for bit, in operations the lane loops
/// vectorise: below 2^23 in magnitude, `(|x| + 2^23) − 2^23` is `|x|`
/// rounded to the nearest integer, exactly; with `x`'s sign that is `y`,
/// and `floor(x) = y − [y > x]`. (`math::floor` goes through a
/// saturating conversion to `i32`, which the lane loops did not
/// vectorise.) Integers, magnitudes from 2^23 on and NaN are `x` itself,
/// as there.
#[inline(always)]
pub(super) fn floor_lane(x: f32) -> f32 {
    const BIG: f32 = 8_388_608.0;
    let y = ((x.abs() + BIG) - BIG).copysign(x);
    let down = if y > x { y - 1.0 } else { y };
    let keep = (y == x) | (x.abs() >= BIG) | x.is_nan();
    if keep { x } else { down }
}

/// [`crate::scene::is_even`] with [`floor_lane`] and float comparisons
/// only: the same answer, in a form the lane loops vectorise.
#[inline(always)]
pub(super) fn is_even_lane(cells: f32) -> bool {
    // `cells·0` is ±0 where `cells` is finite, else NaN.
    (cells * 0.0 == 0.0) & (floor_lane(cells * 0.5) * 2.0 == cells)
}

/// [`crate::shading::fresnel_dielectric`]: `(R, T)`, with selects for its
/// early return.
#[inline(always)]
pub(super) fn fresnel_lane(cos_i: f32, eta_i: f32, eta_t: f32) -> Fresnel {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin_t = eta_i / eta_t * (1.0 - cos_i * cos_i).sqrt();
    let total = (sin_t >= 1.0) | (cos_i == 0.0);
    let cos_t = (1.0 - sin_t * sin_t).sqrt();
    let (ii, tt) = (eta_i * cos_i, eta_t * cos_t);
    let (it, ti) = (eta_i * cos_t, eta_t * cos_i);
    let r_s = (ii - tt) / (ii + tt);
    let r_p = (ti - it) / (ti + it);
    let t_s = 2.0 * ii / (ii + tt);
    let t_p = 2.0 * ii / (ti + it);
    let reflectance = 0.5 * (r_s * r_s + r_p * r_p);
    let transmittance = tt / ii * 0.5 * (t_s * t_s + t_p * t_p);
    Fresnel {
        reflectance: if total { 1.0 } else { reflectance },
        transmittance: if total { 0.0 } else { transmittance },
    }
}

/// Calls `lane(j)` for every lane of the first `groups` groups of
/// [`GROUP`] lanes (loops of a fixed count, which the compiler vectorises).
#[inline(always)]
pub(super) fn for_lanes(groups: usize, mut lane: impl FnMut(usize)) {
    for g in 0..BATCH / GROUP {
        if g >= groups {
            break;
        }
        for j in g * GROUP..(g + 1) * GROUP {
            lane(j);
        }
    }
}

/// [`for_lanes`] for the groups marked in `which`.
#[inline(always)]
pub(super) fn for_lanes_in(which: &[bool; BATCH / GROUP], mut lane: impl FnMut(usize)) {
    for (g, &w) in which.iter().enumerate() {
        if w {
            for j in g * GROUP..(g + 1) * GROUP {
                lane(j);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{floor, nudge};
    use crate::shading::fresnel_dielectric;
    use proptest::prelude::*;

    fn same(a: f32, b: f32) -> bool {
        a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
    }

    #[test]
    fn compress_keeps_the_flagged_lanes_in_order() {
        let mut rng = crate::render::Pcg32::new(7, 3);
        for round in 0..500 {
            let n = (rng.next_f32() * (BATCH + 1) as f32) as usize % (BATCH + 1);
            let dense = rng.next_f32();
            let keep: Mask = std::array::from_fn(|_| u32::from(rng.next_f32() < dense));
            let a: Lane = std::array::from_fn(|j| j as f32 + 0.5);
            let b: Lane = std::array::from_fn(|j| -(j as f32) - round as f32);
            let want: Vec<(f32, f32)> = (0..n)
                .filter(|&j| keep[j] != 0)
                .map(|j| (a[j], b[j]))
                .collect();
            let (mut x, mut y) = ([f32::NAN; BATCH], [f32::NAN; BATCH]);
            let kept = compress(&keep, n, [&a, &b], [&mut x, &mut y]);
            let (mut xs, mut ys) = ([f32::NAN; BATCH], [f32::NAN; BATCH]);
            let kept_scalar = compress_scalar(&keep, n, [&a, &b], [&mut xs, &mut ys]);
            assert_eq!(
                (kept, kept_scalar),
                (want.len(), want.len()),
                "round {round}"
            );
            for (q, &(wa, wb)) in want.iter().enumerate() {
                assert_eq!((x[q], y[q]), (wa, wb), "round {round} lane {q}");
                assert_eq!((xs[q], ys[q]), (wa, wb), "round {round} lane {q}");
            }
        }
    }

    #[test]
    fn lane_helpers_are_the_scalar_functions_bit_for_bit() {
        let specials = [
            0.0f32,
            -0.0,
            1e-45,
            -1e-45,
            0.5,
            -0.5,
            1.0,
            -1.5,
            8_388_607.5,
            8_388_608.0,
            -8_388_609.0,
            3e9,
            -3e9,
            f32::MAX,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        for x in specials
            .into_iter()
            .chain((0..=u32::MAX).step_by(7919).map(f32::from_bits))
        {
            assert!(same(floor_lane(x), floor(x)), "floor {x:e}");
            assert_eq!(is_even_lane(x), crate::scene::is_even(x), "is_even {x:e}");
            for dir in [1.0, -1.0, 0.0, -0.0, f32::NAN] {
                assert!(same(nudge_lane(x, dir), nudge(x, dir)), "nudge {x:e} {dir}");
            }
        }
    }

    proptest! {
        #[test]
        fn fresnel_lane_is_fresnel_dielectric(cos in -0.1f32..1.1, eta in 1.0f32..2.5, inside: bool) {
            let (eta_i, eta_t) = if inside { (eta, 1.0) } else { (1.0, eta) };
            let (a, b) = (fresnel_lane(cos, eta_i, eta_t), fresnel_dielectric(cos, eta_i, eta_t));
            prop_assert!(same(a.reflectance, b.reflectance) && same(a.transmittance, b.transmittance));
        }
    }
}
