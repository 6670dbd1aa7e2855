//! Infinite plane `(p − p′)·N = 0`.

use super::{ShapeHit, SurfacePoint};
use crate::math::{Ray, Vec3, gamma, orthonormal_basis};
use glam::Vec2;

/// The plane through `point` with unit normal `normal`. Its surface
/// coordinates are `uv = ((p − p′)·u, (p − p′)·v)` (in scene units) for an
/// orthonormal frame `(u, v, N)`, see [`Plane::frame`].
///
/// Scene file: `{ shape = "plane", point = [0, 0, 0], normal = [0, 1, 0] }`.
#[derive(Clone, Debug, PartialEq)]
pub struct Plane {
    pub point: Vec3,
    pub normal: Vec3,
}

impl Plane {
    /// # Panics
    /// In debug builds, if `normal` is zero or not finite.
    pub fn new(point: Vec3, normal: Vec3) -> Self {
        debug_assert!(normal.length_squared() > 0.0 && normal.is_finite());
        Plane {
            point,
            normal: normal.normalize(),
        }
    }

    /// The axes `(u, v)` of the surface coordinates: for the common y-up
    /// ground plane `u = x`, `v = z`, so textures line up with world axes;
    /// otherwise any orthonormal frame. Computed when needed, which keeps
    /// the plane small in the object array.
    pub fn frame(&self) -> (Vec3, Vec3) {
        if self.normal == Vec3::Y {
            (Vec3::X, Vec3::Z)
        } else {
            orthonormal_basis(self.normal)
        }
    }

    /// Ray–plane intersection: `t = (p′ − o)·N / (d·N)`.
    /// Returns `None` when `d·N = 0` (parallel) or `t ∉ [t_min, t_max)`.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<ShapeHit> {
        let denom = ray.d.dot(self.normal);
        if denom == 0.0 {
            return None;
        }
        let t = (self.point - ray.o).dot(self.normal) / denom;
        ray.contains(t).then_some(ShapeHit {
            t,
            ..ShapeHit::default()
        })
    }

    /// The hit point `o + t·d` is projected back onto the plane,
    /// `p ← p − ((p − p′)·N) N`, which removes the error `t` carries along the
    /// normal; what is left is bounded by a few ulps of `|p| + |p′|`.
    pub fn surface(&self, ray: &Ray, hit: &ShapeHit) -> SurfacePoint {
        let p_raw = ray.at(hit.t);
        let p = p_raw - (p_raw - self.point).dot(self.normal) * self.normal;
        let p_err = gamma(7) * (p.abs() + self.point.abs());
        SurfacePoint {
            p,
            p_err,
            n: self.normal,
            ns: self.normal,
        }
    }

    /// `((p − p′)·u, (p − p′)·v)` in the plane's [frame](Plane::frame).
    pub fn uv(&self, p: Vec3) -> Vec2 {
        let rel = p - self.point;
        let (u_axis, v_axis) = self.frame();
        Vec2::new(rel.dot(u_axis), rel.dot(v_axis))
    }

    /// See [`super::Shape::crossings`]: at most one crossing, no inside.
    pub fn crossings(&self, ray: &Ray, crossing: &mut impl FnMut(f32)) -> f32 {
        if self.intersect(ray).is_some() {
            crossing((ray.d.dot(self.normal) / ray.d.length()).abs().min(1.0));
        }
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn ground() -> Plane {
        Plane::new(Vec3::ZERO, Vec3::Y)
    }

    #[test]
    fn ray_hits_plane_at_closed_form_t() {
        let r = Ray::new(Vec3::new(1.0, 2.0, 3.0), Vec3::new(0.0, -0.5, 1.0));
        let h = ground().intersect(&r).unwrap();
        assert_eq!(h.t, 4.0);
        let s = ground().surface(&r, &h);
        assert_eq!(s.p, Vec3::new(1.0, 0.0, 7.0));
        assert_eq!(ground().uv(s.p), Vec2::new(1.0, 7.0));
    }

    #[test]
    fn parallel_ray_misses() {
        let r = Ray::new(Vec3::new(0.0, 1.0, 0.0), Vec3::X);
        assert!(ground().intersect(&r).is_none());
        // Even when it lies in the plane.
        let r = Ray::new(Vec3::ZERO, Vec3::X);
        assert!(ground().intersect(&r).is_none());
    }

    #[test]
    fn plane_behind_ray_misses() {
        let r = Ray::new(Vec3::new(0.0, 1.0, 0.0), Vec3::Y);
        assert!(ground().intersect(&r).is_none());
    }

    #[test]
    fn t_outside_range_rejected() {
        let mut r = Ray::new(Vec3::new(0.0, 2.0, 0.0), -Vec3::Y);
        r.t_max = 2.0;
        assert!(ground().intersect(&r).is_none());
        r.t_max = 2.0f32.next_up();
        assert!(ground().intersect(&r).is_some());
        r.t_min = 2.5;
        r.t_max = f32::INFINITY;
        assert!(ground().intersect(&r).is_none());
    }

    #[test]
    fn ray_from_below_hits_too() {
        let r = Ray::new(Vec3::new(0.0, -1.0, 0.0), Vec3::Y);
        assert_eq!(ground().intersect(&r).unwrap().t, 1.0);
    }

    #[test]
    fn frame_is_orthonormal_for_tilted_planes() {
        let p = Plane::new(Vec3::ONE, Vec3::new(1.0, 2.0, -0.5));
        assert!((p.normal.length() - 1.0).abs() < 1e-6);
        let (u, v) = p.frame();
        assert!(u.dot(p.normal).abs() < 1e-6 && v.dot(p.normal).abs() < 1e-6);
    }

    fn vec() -> impl Strategy<Value = Vec3> {
        (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0).prop_map(|(x, y, z)| Vec3::new(x, y, z))
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]

        /// Hit points lie on the plane, and spawned rays leaving it never hit it again.
        #[test]
        fn hit_points_lie_on_the_plane(p in vec(), n in vec(), o in vec(), d in vec(), e in -3.0f32..3.0) {
            prop_assume!(n.length() > 1e-2 && d.length() > 1e-2);
            let s = 10f32.powf(e);
            let plane = Plane::new(p * s, n);
            let ray = Ray::new(o * 10.0 * s, d);
            if let Some(h) = plane.intersect(&ray) {
                let sp = plane.surface(&ray, &h);
                let dist = (sp.p - plane.point).dot(plane.normal).abs();
                prop_assert!(dist <= plane.normal.abs().dot(sp.p_err), "dist {} err {:?}", dist, sp.p_err);
                let w = if d.dot(plane.normal) < 0.0 { plane.normal + d * 0.1 } else { -plane.normal + d * 0.1 };
                let again = Ray::spawn(sp.p, sp.p_err, sp.n, -w);
                prop_assert!(plane.intersect(&again).is_none());
            } else {
                let side_o = (ray.o - plane.point).dot(plane.normal);
                let towards = ray.d.dot(plane.normal) * side_o;
                prop_assert!(towards >= 0.0 || ray.d.dot(plane.normal).abs() < 1e-6);
            }
        }
    }
}
