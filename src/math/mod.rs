//! Rays, boxes and the floating-point tools that keep intersections robust.

mod aabb;
mod float;
mod interval;
mod ray;
mod transform;

pub use aabb::{Aabb, SlabHit};
pub use float::{MACHINE_EPSILON, MIN_OFFSET, floor, gamma, nudge, offset_ray_origin};
pub use interval::Interval;
pub use ray::{Ray, SHADOW_EPSILON};
pub use transform::Transform;

/// Linear RGB colour. The components are red, green and blue (`x`, `y`, `z`).
pub type Color = glam::Vec3A;

pub use glam::Vec3A as Vec3;

/// The unit vector along `v`, or zero for a zero or non-finite `v`, computed
/// in f64: the squared length of an f32 vector overflows f32 above about
/// 1.8e19 and underflows below 1e-19 (so `glam`'s `normalize` fails for
/// meshes written at such scales), but never f64.
#[inline]
pub fn normalize_robust(v: Vec3) -> Vec3 {
    v.as_dvec3().normalize_or_zero().as_vec3a()
}

/// The unit normal `(v1 − v0) × (v2 − v0)/|…|` of a triangle (counter-clockwise
/// winding seen from the side it points to), or zero for a degenerate one;
/// in f64, so that it exists for triangles of any size f32 can hold.
///
/// The cross product is taken in f32 when its squared length lies well
/// inside f32's normal range (the usual case, and the fast one), else in f64.
#[inline]
pub fn triangle_normal(v0: Vec3, v1: Vec3, v2: Vec3) -> Vec3 {
    let c = (v1 - v0).cross(v2 - v0);
    let len2 = c.length_squared();
    if (1e-30..1e30).contains(&len2) {
        return c * len2.sqrt().recip();
    }
    let (v0, v1, v2) = (v0.as_dvec3(), v1.as_dvec3(), v2.as_dvec3());
    (v1 - v0).cross(v2 - v0).normalize_or_zero().as_vec3a()
}

/// `(sin 2πu, cos 2πu)` for a sample `u` (an angle in turns), inlined and
/// without a libm call: sampling routines call it once per bounce, and a
/// call to `sincosf` spills every vector register around it.
///
/// Cody–Waite style reduction to the nearest quarter turn, `u = q/4 + f`
/// with `|f| ≤ 1/8` (exact in f32 for `|u| < 2^21`), then Taylor polynomials
/// of `x = 2πf ∈ [−π/4, π/4]` to degree 9 (sin) and 10 (cos), whose
/// truncation errors (`x¹¹/11!`, `x¹²/12!`) are below 2e-9; the result is
/// within a few f32 ulps of the exact values. The quadrant `q mod 4` then
/// rotates `(sin x, cos x)` by multiples of 90°.
#[inline]
pub fn sin_cos_turns(u: f32) -> (f32, f32) {
    let q = (4.0 * u).round();
    let x = (u - 0.25 * q) * (2.0 * std::f32::consts::PI);
    let x2 = x * x;
    let s = x
        * (1.0
            + x2 * (-1.0 / 6.0
                + x2 * (1.0 / 120.0 + x2 * (-1.0 / 5040.0 + x2 * (1.0 / 362_880.0)))));
    let c = 1.0
        + x2 * (-0.5
            + x2 * (1.0 / 24.0
                + x2 * (-1.0 / 720.0 + x2 * (1.0 / 40_320.0 - x2 * (1.0 / 3_628_800.0)))));
    // Without branches (the quadrant of a sample is unpredictable):
    // odd quadrants swap the two, and the signs follow bit 1 of q (sine)
    // and of q + 1 (cosine).
    let q = q as i32;
    let swap = 0u32.wrapping_sub((q & 1) as u32);
    let (sb, cb) = (s.to_bits(), c.to_bits());
    let sin = (sb & !swap) | (cb & swap);
    let cos = (cb & !swap) | (sb & swap);
    let sin_sign = ((q & 2) as u32) << 30;
    let cos_sign = (((q + 1) & 2) as u32) << 30;
    (
        f32::from_bits(sin ^ sin_sign),
        f32::from_bits(cos ^ cos_sign),
    )
}

/// Builds an orthonormal basis `(b1, b2)` perpendicular to the unit vector `n`.
///
/// Duff et al., "Building an Orthonormal Basis, Revisited", JCGT 6(1), 2017:
/// branch-free and continuous except across `n.z = 0` with `n.z < 0`.
pub fn orthonormal_basis(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let b1 = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let b2 = Vec3::new(b, sign + n.y * n.y * a, -n.y);
    (b1, b2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normals_of_tiny_and_huge_triangles_exist() {
        for scale in [1e-30f32, 1e-12, 1e-6, 1.0, 1e6, 1e12, 1e30] {
            let n = triangle_normal(Vec3::ZERO, Vec3::X * scale, Vec3::Y * scale);
            assert_eq!(n, Vec3::Z, "scale {scale}");
            let v = Vec3::new(3.0, 0.0, 4.0) * scale;
            assert!((normalize_robust(v) - Vec3::new(0.6, 0.0, 0.8)).length() < 1e-6);
        }
        assert_eq!(normalize_robust(Vec3::ZERO), Vec3::ZERO);
        assert_eq!(normalize_robust(Vec3::new(f32::NAN, 0.0, 1.0)), Vec3::ZERO);
        assert_eq!(
            triangle_normal(Vec3::ZERO, Vec3::X, Vec3::X * 2.0),
            Vec3::ZERO
        );
    }

    #[test]
    fn sin_cos_turns_matches_libm() {
        let mut worst = 0.0f64;
        for i in 0..=200_000 {
            let u = i as f32 / 200_000.0;
            let (s, c) = sin_cos_turns(u);
            let (es, ec) = (u as f64 * std::f64::consts::TAU).sin_cos();
            worst = worst.max((s as f64 - es).abs()).max((c as f64 - ec).abs());
        }
        assert!(worst < 4e-7, "worst error {worst}");
        assert_eq!(sin_cos_turns(0.0), (0.0, 1.0));
        assert_eq!(sin_cos_turns(0.25), (1.0, -0.0));
        assert_eq!(sin_cos_turns(0.5).1, -1.0);
        let (s, c) = sin_cos_turns(-0.125);
        assert!((s + 0.5f32.sqrt()).abs() < 1e-7 && (c - 0.5f32.sqrt()).abs() < 1e-7);
    }

    #[test]
    fn orthonormal_basis_is_orthonormal() {
        for n in [
            Vec3::X,
            Vec3::Y,
            Vec3::Z,
            -Vec3::Z,
            Vec3::new(1.0, -2.0, 0.5).normalize(),
            Vec3::new(0.0, 1e-8, -1.0).normalize(),
        ] {
            let (b1, b2) = orthonormal_basis(n);
            assert!((b1.length() - 1.0).abs() < 1e-6, "{n:?}");
            assert!((b2.length() - 1.0).abs() < 1e-6, "{n:?}");
            assert!(b1.dot(n).abs() < 1e-6 && b2.dot(n).abs() < 1e-6 && b1.dot(b2).abs() < 1e-6);
        }
    }
}
