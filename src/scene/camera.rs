//! Pinhole camera.

use crate::math::{Ray, Vec3};

/// How many rays [`Camera::rays`] computes together.
pub const CAMERA_BATCH: usize = 16;

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

    /// [`Camera::ray`] for many film points at once, into `out` (as long as
    /// `points`): the same rays bit for bit, computed lane by lane with the
    /// same operations in the same order (`(f + r·sx) + u·sy`, then
    /// `d / √((dx² + dy²) + dz²)`), laid out so that the compiler computes
    /// `CAMERA_BATCH` square roots and divisions together instead of one
    /// long dependency chain per ray.
    pub fn rays(&self, points: &[(f32, f32)], width: u32, height: u32, out: &mut [Ray]) {
        assert_eq!(points.len(), out.len());
        let aspect = width as f32 / height as f32;
        let (w, h) = (width as f32, height as f32);
        let (f, r, u) = (self.forward, self.right, self.up);
        // Compiled for the widest vector unit the CPU has: the square
        // roots and divisions of a batch in as few instructions as it
        // allows (each correctly rounded, so the same bits on every CPU).
        super::widest(
            #[inline(always)]
            || {
                for (points, out) in points
                    .chunks(CAMERA_BATCH)
                    .zip(out.chunks_mut(CAMERA_BATCH))
                {
                    let mut x = [0.5f32; CAMERA_BATCH];
                    let mut y = [0.5f32; CAMERA_BATCH];
                    for (i, &(px, py)) in points.iter().enumerate() {
                        x[i] = px;
                        y[i] = py;
                    }
                    let mut d = [[0f32; CAMERA_BATCH]; 3];
                    for i in 0..CAMERA_BATCH {
                        let sx = (2.0 * x[i] / w - 1.0) * self.tan_half_fov * aspect;
                        let sy = (1.0 - 2.0 * y[i] / h) * self.tan_half_fov;
                        for k in 0..3 {
                            d[k][i] = f[k] + r[k] * sx + u[k] * sy;
                        }
                    }
                    for i in 0..CAMERA_BATCH {
                        let len =
                            (d[0][i] * d[0][i] + d[1][i] * d[1][i] + d[2][i] * d[2][i]).sqrt();
                        for dk in &mut d {
                            dk[i] /= len;
                        }
                    }
                    for (i, ray) in out.iter_mut().enumerate() {
                        *ray = Ray::new(self.position, Vec3::new(d[0][i], d[1][i], d[2][i]));
                    }
                }
            },
        )
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

    /// The unit direction of the image's right.
    pub fn right(&self) -> Vec3 {
        self.right
    }

    /// `tan(fov_y / 2)`.
    pub fn tan_half_fov(&self) -> f32 {
        self.tan_half_fov
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
    fn batched_rays_equal_single_rays_bit_for_bit() {
        let mut rng = crate::render::Pcg32::new(7, 1);
        for (pos, fov) in [
            (Vec3::new(0.3, 2.2, -7.0), 40.0),
            (Vec3::new(-1e3, 5.0, 2.0), 100.0),
        ] {
            let c = Camera::try_new(pos, Vec3::new(0.1, 1.0, 0.2), Vec3::Y, fov).unwrap();
            // A length that is not a multiple of the batch, for the tail.
            let points: Vec<(f32, f32)> = (0..3 * CAMERA_BATCH + 5)
                .map(|_| (rng.next_f32() * 1280.0, rng.next_f32() * 720.0))
                .collect();
            let mut out = vec![Ray::new(Vec3::ZERO, Vec3::X); points.len()];
            c.rays(&points, 1280, 720, &mut out);
            for (&(x, y), r) in points.iter().zip(&out) {
                let single = c.ray(x, y, 1280, 720);
                assert_eq!(
                    r.d.to_array().map(f32::to_bits),
                    single.d.to_array().map(f32::to_bits)
                );
                assert_eq!(*r, single);
            }
        }
    }

    #[test]
    fn degenerate_cameras_are_rejected() {
        assert!(Camera::try_new(Vec3::ONE, Vec3::ONE, Vec3::Y, 40.0).is_none());
        assert!(Camera::try_new(Vec3::ZERO, Vec3::Y, Vec3::Y, 40.0).is_none());
        assert!(Camera::try_new(Vec3::ZERO, Vec3::Z, Vec3::Y, 180.0).is_none());
    }
}
