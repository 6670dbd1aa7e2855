//! Floating-point error bounds and robust ray-origin offsetting (pbrt-v4, §6.8).

use super::Vec3;

/// Half an ulp of 1: the bound on the relative error of one rounded f32 operation.
pub const MACHINE_EPSILON: f32 = f32::EPSILON * 0.5;

/// Smallest offset of a spawned ray's origin: far below any geometric scale a
/// scene can have in f32, yet large enough that dividing it by a direction
/// component of up to 1e8 does not underflow (f32's smallest normal is 1.2e-38).
pub const MIN_OFFSET: f32 = 1e-29;

/// γ(n) = n·ε / (1 − n·ε): bounds the relative error of `n` chained f32 operations
/// (Higham, "Accuracy and Stability of Numerical Algorithms", §3.1).
#[inline]
pub fn gamma(n: i32) -> f32 {
    let ne = n as f32 * MACHINE_EPSILON;
    ne / (1.0 - ne)
}

/// `x.floor()`, bit for bit (NaN stays NaN), without the call to libm's
/// `floorf` that the baseline x86-64 target makes of it (no SSE4.1
/// `roundss`): a float of magnitude 2^23 or more is an integer already,
/// and below that the truncation to i32 is exact and off by one only for
/// negative non-integers.
///
/// Without branches: checkerboards floor coordinates of either sign in no
/// predictable order, and a mispredicted branch costs more than both sides.
#[inline]
pub fn floor(x: f32) -> f32 {
    // NaN and magnitudes from 2^31 on saturate here; they are kept below.
    let t = x as i32 as f32;
    let down = t - f32::from(u8::from(t > x));
    // Integral (which keeps the sign of −0), already an integer, or NaN: x.
    let keep = (t == x) | (x.abs() >= 8_388_608.0) | x.is_nan();
    std::hint::select_unpredictable(keep, x, down)
}

/// Offsets a surface point `p`, known to within `p_err` per component, along the
/// geometric normal `n` to the side that direction `w` leaves towards, so that a
/// ray spawned there cannot hit the same surface again at t ≈ 0.
///
/// The offset distance is `|n|·p_err` (the extent of the error box along the
/// normal), and every moved component is then rounded one more ulp away from the
/// surface (pbrt-v4 `OffsetRayOrigin`).
///
/// Unlike pbrt, the distance is at least [`MIN_OFFSET`]: a point snapped
/// exactly onto a plane through 0 has a zero error bound, and an offset of one
/// denormal ulp is lost again when a later test multiplies it by `1/d`
/// (`(0 − 1e-45)·0.1` rounds to `−0.0`, which passes `t ≥ 0`).
#[inline]
pub fn offset_ray_origin(p: Vec3, p_err: Vec3, n: Vec3, w: Vec3) -> Vec3 {
    let d = n.abs().dot(p_err).max(MIN_OFFSET);
    let n = if w.dot(n) < 0.0 { -n } else { n };
    let po = p + n * d;
    Vec3::new(nudge(po.x, n.x), nudge(po.y, n.y), nudge(po.z, n.z))
}

/// `x.next_up()` where `dir > 0`, `x.next_down()` where `dir < 0`, else `x`,
/// bit for bit, without branches: the signs of a normal's components follow
/// no pattern from one hit to the next, and `next_up`/`next_down` branch on
/// sign, zero and infinity.
///
/// On the bits, a step away from 0 adds 1 and a step towards 0 subtracts 1
/// (the sign bit stays); ±0 steps to the smallest subnormal of `dir`'s
/// sign, an infinity stepped further stays, and NaN stays NaN.
#[inline]
pub fn nudge(x: f32, dir: f32) -> f32 {
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
    let stepped =
        std::hint::select_unpredictable(magnitude == 0 && (up | down), from_zero, stepped);
    let stays = (magnitude > 0x7f80_0000) | ((magnitude == 0x7f80_0000) & away);
    f32::from_bits(std::hint::select_unpredictable(stays, bits, stepped))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nudge_is_next_up_or_next_down_bit_for_bit() {
        let check = |x: f32| {
            for dir in [1.0f32, -1.0, 0.0, -0.0, f32::NAN, 1e-45, -f32::INFINITY] {
                let want = if dir > 0.0 {
                    x.next_up()
                } else if dir < 0.0 {
                    x.next_down()
                } else {
                    x
                };
                let got = nudge(x, dir);
                assert!(
                    got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()),
                    "{x:e} towards {dir}: {got:e} vs {want:e}"
                );
            }
        };
        for bits in (0..=u32::MAX).step_by(101) {
            check(f32::from_bits(bits));
        }
        for bits in [
            0,
            1,
            2,
            0x007f_ffff,
            0x0080_0000,
            0x7f7f_ffff,
            0x7f80_0000,
            0x7fc0_0000,
        ] {
            check(f32::from_bits(bits));
            check(-f32::from_bits(bits));
        }
    }

    #[test]
    fn floor_is_floorf_bit_for_bit() {
        // Every 97th bit pattern (both signs, all exponents), plus the
        // neighbourhoods of the integers near 0 and of 2^23.
        let check = |x: f32| {
            let (a, b) = (floor(x), x.floor());
            assert!(
                a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()),
                "{x:e}: {a} vs {b}"
            );
        };
        for bits in (0..=u32::MAX).step_by(97) {
            check(f32::from_bits(bits));
        }
        for k in -1000..=1000 {
            let x = k as f32 * 0.25;
            for y in [x, x.next_up(), x.next_down()] {
                check(y);
            }
        }
        for x in [
            8_388_608.0f32,
            -8_388_608.0,
            0.0,
            -0.0,
            f32::INFINITY,
            f32::NEG_INFINITY,
        ] {
            for y in [x, x.next_up(), x.next_down()] {
                check(y);
            }
        }
    }

    #[test]
    fn gamma_grows_with_operation_count() {
        assert!(gamma(1) > MACHINE_EPSILON);
        assert!(gamma(3) > 3.0 * MACHINE_EPSILON && gamma(3) < 3.1 * MACHINE_EPSILON);
        assert!(gamma(5) > gamma(3));
    }

    #[test]
    fn offset_moves_strictly_to_the_side_of_w_even_with_zero_error() {
        let p = Vec3::new(0.3, 0.0, -2.0);
        let n = Vec3::Y;
        let up = offset_ray_origin(p, Vec3::ZERO, n, Vec3::new(0.2, 1.0, 0.0));
        assert!(up.y > 0.0);
        let down = offset_ray_origin(p, Vec3::ZERO, n, Vec3::new(0.2, -1.0, 0.0));
        assert!(down.y < 0.0);
        assert_eq!(up.x, p.x);
    }

    #[test]
    fn offset_survives_division_by_long_directions() {
        // Point exactly on the plane y = 0 with a zero error bound; a shadow ray
        // towards a light 1e4 away must still start strictly above the plane
        // after the slab test's (0 − o.y)·(1/d.y).
        let o = offset_ray_origin(Vec3::new(0.5, 0.0, 0.5), Vec3::ZERO, Vec3::Y, Vec3::Y);
        let t = (0.0 - o.y) * (1.0f32 / 1e4);
        assert!(t < 0.0, "{t}");
    }

    #[test]
    fn offset_covers_the_error_box() {
        let p = Vec3::new(1e4, 2e4, -3e4);
        let err = Vec3::splat(0.01);
        let n = Vec3::new(1.0, 1.0, 0.0).normalize();
        let o = offset_ray_origin(p, err, n, n);
        // The offset point lies beyond the error box's extent along n.
        assert!((o - p).dot(n) >= n.abs().dot(err) * 0.999);
    }
}
