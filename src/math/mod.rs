//! Rays, boxes and the floating-point tools that keep intersections robust.

mod aabb;
mod float;
mod interval;
mod ray;
mod transform;

pub use aabb::{Aabb, SlabHit};
pub use float::{MACHINE_EPSILON, MIN_OFFSET, gamma, offset_ray_origin};
pub use interval::Interval;
pub use ray::{Ray, SHADOW_EPSILON};
pub use transform::Transform;

/// Linear RGB colour. The components are red, green and blue (`x`, `y`, `z`).
pub type Color = glam::Vec3A;

pub use glam::Vec3A as Vec3;

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
