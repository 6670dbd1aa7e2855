//! Affine object-to-world transforms, in f64.

use glam::{DAffine3, DMat3, DVec3};

/// An affine transform and its inverse. Named by frames, as in pbrt:
/// `world_from_object` maps object-space points to world space.
#[derive(Clone, Debug, PartialEq)]
pub struct Transform {
    pub world_from_object: DAffine3,
    pub object_from_world: DAffine3,
    /// Inverse transpose of the linear part: maps object-space normals
    /// (gradients) to world space.
    pub normal_to_world: DMat3,
}

impl Transform {
    pub const IDENTITY: Transform = Transform {
        world_from_object: DAffine3::IDENTITY,
        object_from_world: DAffine3::IDENTITY,
        normal_to_world: DMat3::IDENTITY,
    };

    /// Scale (per axis), then rotate about x, then y, then z (degrees,
    /// right-hand rule), then translate. Returns `None` if the transform is
    /// singular (a zero scale).
    pub fn from_parts(scale: DVec3, rotate_deg: DVec3, translate: DVec3) -> Option<Self> {
        let rotation = DMat3::from_rotation_z(rotate_deg.z.to_radians())
            * DMat3::from_rotation_y(rotate_deg.y.to_radians())
            * DMat3::from_rotation_x(rotate_deg.x.to_radians());
        let linear = rotation * DMat3::from_diagonal(scale);
        Transform::from_affine(DAffine3::from_mat3_translation(linear, translate))
    }

    /// Returns `None` if `m` is singular or not finite.
    pub fn from_affine(m: DAffine3) -> Option<Self> {
        let det = m.matrix3.determinant();
        if det.abs() <= 1e-300 || !det.is_finite() {
            return None;
        }
        let inverse = m.inverse();
        Some(Transform {
            world_from_object: m,
            object_from_world: inverse,
            normal_to_world: inverse.matrix3.transpose(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotate_x_minus_90_turns_z_up_into_y_up() {
        let t = Transform::from_parts(
            DVec3::ONE,
            DVec3::new(-90.0, 0.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        )
        .unwrap();
        let p = t.world_from_object.transform_point3(DVec3::Z);
        assert!((p - DVec3::new(0.0, 2.0, 0.0)).length() < 1e-12, "{p}");
        let y = t.world_from_object.transform_vector3(DVec3::Y);
        assert!((y - DVec3::new(0.0, 0.0, -1.0)).length() < 1e-12, "{y}");
        let back = t.object_from_world.transform_point3(p);
        assert!((back - DVec3::Z).length() < 1e-12);
    }

    #[test]
    fn normals_stay_perpendicular_under_non_uniform_scale() {
        let t = Transform::from_parts(
            DVec3::new(1.0, 4.0, 1.0),
            DVec3::new(0.0, 30.0, 0.0),
            DVec3::ZERO,
        )
        .unwrap();
        // The plane x + y = 0 in object space has normal (1, 1, 0).
        let tangent = t
            .world_from_object
            .transform_vector3(DVec3::new(1.0, -1.0, 0.0));
        let n = t.normal_to_world * DVec3::new(1.0, 1.0, 0.0);
        assert!(tangent.dot(n).abs() < 1e-12);
        assert!(
            Transform::from_parts(DVec3::new(1.0, 0.0, 1.0), DVec3::ZERO, DVec3::ZERO).is_none()
        );
    }
}
