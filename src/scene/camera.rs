//! Pinhole camera.

use crate::math::{Ray, Vec3};

/// A pinhole camera at `position` looking at `look_at`, with vertical field of
/// view `fov_y_deg`. Right-handed: with `up = +y` and the camera looking down
/// `−z`, image right is `+x`.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    pub position: Vec3,
    forward: Vec3,
    right: Vec3,
    up: Vec3,
    tan_half_fov: f32,
}

impl Camera {
    /// Returns `None` when `look_at == position`, `up` is parallel to the view
    /// direction, or the field of view is not in (0°, 180°).
    pub fn try_new(position: Vec3, look_at: Vec3, up: Vec3, fov_y_deg: f32) -> Option<Self> {
        // In f64: an f32 view vector shorter than 1e-19 has no f32 length.
        let forward = match crate::math::normalize_robust(look_at - position) {
            f if f == Vec3::ZERO => return None,
            f => f,
        };
        let right = forward.cross(up).try_normalize()?;
        let up = right.cross(forward);
        if !(fov_y_deg > 0.0 && fov_y_deg < 180.0) {
            return None;
        }
        Some(Camera {
            position,
            forward,
            right,
            up,
            tan_half_fov: (fov_y_deg.to_radians() * 0.5).tan(),
        })
    }

    /// The eye ray through the film point `(x, y)`, in pixels from the top-left
    /// corner of a `width × height` image (pixel `(i, j)` covers
    /// `[i, i+1) × [j, j+1)`; its centre is `(i + ½, j + ½)`). Any aspect ratio:
    /// the vertical field of view is fixed and the horizontal one follows.
    #[inline]
    pub fn ray(&self, x: f32, y: f32, width: u32, height: u32) -> Ray {
        let aspect = width as f32 / height as f32;
        let sx = (2.0 * x / width as f32 - 1.0) * self.tan_half_fov * aspect;
        let sy = (1.0 - 2.0 * y / height as f32) * self.tan_half_fov;
        let d = self.forward + self.right * sx + self.up * sy;
        Ray::new(self.position, d.normalize())
    }

    /// Where the point `p` appears on the film of a `width × height` image,
    /// in pixels from the top-left corner (the inverse of [`Camera::ray`]);
    /// `None` if it is not in front of the camera.
    pub fn project(&self, p: Vec3, width: u32, height: u32) -> Option<(f32, f32)> {
        let rel = p - self.position;
        let z = rel.dot(self.forward);
        if z.is_nan() || z <= 1e-6 * rel.length() {
            return None;
        }
        let aspect = width as f32 / height as f32;
        let sx = rel.dot(self.right) / z / (self.tan_half_fov * aspect);
        let sy = rel.dot(self.up) / z / self.tan_half_fov;
        Some((
            (sx + 1.0) * 0.5 * width as f32,
            (1.0 - sy) * 0.5 * height as f32,
        ))
    }

    /// The unit view direction.
    pub fn forward(&self) -> Vec3 {
        self.forward
    }

    /// The unit up direction of the image (perpendicular to the view).
    pub fn up(&self) -> Vec3 {
        self.up
    }

    /// The vertical field of view, in degrees.
    pub fn fov_y_deg(&self) -> f32 {
        (2.0 * self.tan_half_fov.atan()).to_degrees()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_pixel_looks_at_target_and_corners_span_the_fov() {
        let c = Camera::try_new(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 90.0).unwrap();
        let r = c.ray(50.0, 25.0, 100, 50);
        assert!((r.d - -Vec3::Z).length() < 1e-6);
        // Top edge at 45° above the axis, right edge at atan(2) (aspect 2).
        let top = c.ray(50.0, 0.0, 100, 50).d;
        assert!((top.y / -top.z - 1.0).abs() < 1e-6);
        let right = c.ray(100.0, 25.0, 100, 50).d;
        assert!((right.x / -right.z - 2.0).abs() < 1e-5);
    }

    #[test]
    fn projection_inverts_the_eye_ray() {
        let c = Camera::try_new(Vec3::new(1.0, 2.0, -5.0), Vec3::ZERO, Vec3::Y, 40.0).unwrap();
        for (x, y) in [(0.5, 0.5), (320.0, 240.0), (17.25, 400.75)] {
            let r = c.ray(x, y, 640, 480);
            let (px, py) = c.project(r.o + 7.0 * r.d, 640, 480).unwrap();
            assert!(
                (px - x).abs() < 1e-3 && (py - y).abs() < 1e-3,
                "{x},{y} → {px},{py}"
            );
        }
        assert_eq!(c.project(Vec3::new(1.0, 2.0, -9.0), 640, 480), None);
    }

    #[test]
    fn degenerate_cameras_are_rejected() {
        assert!(Camera::try_new(Vec3::ONE, Vec3::ONE, Vec3::Y, 40.0).is_none());
        assert!(Camera::try_new(Vec3::ZERO, Vec3::Y, Vec3::Y, 40.0).is_none());
        assert!(Camera::try_new(Vec3::ZERO, Vec3::Z, Vec3::Y, 180.0).is_none());
    }
}
