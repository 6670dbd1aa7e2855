//! Sphere `|p − c|² = r²`.

use super::{ShapeHit, SurfacePoint};
use crate::math::{Aabb, Ray, Vec3, gamma};
use glam::Vec2;

/// A sphere with centre `center` and radius `radius > 0`.
///
/// Scene file: `{ shape = "sphere", center = [x, y, z], radius = r }`.
#[derive(Clone, Debug, PartialEq)]
pub struct Sphere {
    pub center: Vec3,
    pub radius: f32,
}

impl Sphere {
    pub fn new(center: Vec3, radius: f32) -> Self {
        debug_assert!(radius > 0.0 && center.is_finite());
        Sphere { center, radius }
    }

    pub fn bounds(&self) -> Aabb {
        Aabb::new(
            self.center - Vec3::splat(self.radius),
            self.center + Vec3::splat(self.radius),
        )
    }

    /// Both roots `t0 ≤ t1` of `|o + t·d − c|² = r²`, or `None` if the line
    /// misses the sphere.
    ///
    /// With `f = o − c` the quadratic is `a t² + 2 b t + c′ = 0`, `a = d·d`,
    /// `b = f·d`, `c′ = f·f − r²`. Two cancellations are avoided:
    /// - the discriminant `b² − a c′` is computed as `a r² − |f × d|²` (Lagrange's
    ///   identity: `|f × d|² = |f|²|d|² − (f·d)²`, `a` times the squared distance
    ///   from the centre to the line, as in Haines et al., "Precision Improvements
    ///   for Ray/Sphere Intersection", Ray Tracing Gems, ch. 7), which stays
    ///   accurate for far-away and tiny spheres;
    /// - the roots are `q/a` and `c′/q` with `q = −(b + sign(b)·√Δ)`, so the
    ///   smaller root is not the difference of two nearly equal numbers.
    ///
    /// The arithmetic is done in f64 (as Mitsuba does on the CPU). From f32
    /// inputs `f` is exact and each product in `f × d` is exact, so the
    /// discriminant is correct to a few f64 ulps; the roots are then exact to f32
    /// precision. A miss, the common case, costs no division or square root.
    #[inline]
    pub fn roots(&self, ray: &Ray) -> Option<(f64, f64)> {
        let f = ray.o.as_dvec3() - self.center.as_dvec3();
        let d = ray.d.as_dvec3();
        let r = self.radius as f64;
        let a = d.dot(d);
        let discriminant = a * (r * r) - f.cross(d).length_squared();
        if discriminant < 0.0 {
            return None;
        }
        let b = f.dot(d);
        let q = -(b + discriminant.sqrt().copysign(b));
        if q == 0.0 {
            // b = 0 and Δ = 0: the origin is on the sphere and the ray is tangent.
            return Some((0.0, 0.0));
        }
        let c = f.dot(f) - r * r;
        let (t0, t1) = (q / a, c / q);
        Some(if t0 <= t1 { (t0, t1) } else { (t1, t0) })
    }

    /// The nearest root in `[t_min, t_max)`: the near side from outside, the far
    /// side from inside.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<ShapeHit> {
        let (t0, t1) = self.roots(ray)?;
        let (t0, t1) = (t0 as f32, t1 as f32);
        let t = if ray.contains(t0) {
            t0
        } else if ray.contains(t1) {
            t1
        } else {
            return None;
        };
        Some(ShapeHit {
            t,
            ..ShapeHit::default()
        })
    }

    /// The hit point is re-projected onto the sphere, `p = c + (p′ − c)·r/|p′ − c|`
    /// (pbrt-v4 §6.8.5), which bounds its error by a few ulps of its magnitude.
    pub fn surface(&self, ray: &Ray, hit: &ShapeHit) -> SurfacePoint {
        let p_raw = ray.at(hit.t);
        let offset = p_raw - self.center;
        let len = offset.length();
        let n = if len > 0.0 { offset / len } else { Vec3::Y };
        let p_local = n * self.radius;
        let p = self.center + p_local;
        let p_err = gamma(5) * p_local.abs() + gamma(2) * p.abs();
        SurfacePoint { p, p_err, n, ns: n }
    }

    /// Spherical coordinates scaled to [0, 1]: `u = φ/2π` around the y axis
    /// (from −x), `v = θ/π` from the north pole.
    pub fn uv(&self, p: Vec3) -> Vec2 {
        let n = ((p - self.center) / self.radius).clamp(Vec3::NEG_ONE, Vec3::ONE);
        let u = n.z.atan2(n.x) * (0.5 * std::f32::consts::FRAC_1_PI) + 0.5;
        let v = n.y.acos() * std::f32::consts::FRAC_1_PI;
        Vec2::new(u, v)
    }

    /// See [`super::Shape::crossings`].
    pub fn crossings(&self, ray: &Ray, crossing: &mut impl FnMut(f32)) -> f32 {
        let Some((t0, t1)) = self.roots(ray) else {
            return 0.0;
        };
        let (t0, t1) = (t0 as f32, t1 as f32);
        let d_len = ray.d.length();
        for t in [t0, t1] {
            if ray.contains(t) {
                let n = (ray.at(t) - self.center) / self.radius;
                crossing((n.dot(ray.d) / d_len).abs().min(1.0));
            }
        }
        let inside = t1.min(ray.t_max) - t0.max(ray.t_min);
        inside.max(0.0) * d_len
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn unit() -> Sphere {
        Sphere::new(Vec3::ZERO, 1.0)
    }

    #[test]
    fn ray_from_outside_hits_near_side() {
        let r = Ray::new(Vec3::new(0.0, 0.0, -5.0), Vec3::Z);
        let h = unit().intersect(&r).unwrap();
        assert_eq!(h.t, 4.0);
        let s = unit().surface(&r, &h);
        assert_eq!(s.p, Vec3::new(0.0, 0.0, -1.0));
        assert_eq!(s.n, -Vec3::Z);
    }

    #[test]
    fn ray_from_inside_sphere_hits_far_side() {
        let r = Ray::new(Vec3::new(0.0, 0.5, 0.0), Vec3::Y);
        let h = unit().intersect(&r).unwrap();
        assert_eq!(h.t, 0.5);
        assert_eq!(unit().surface(&r, &h).n, Vec3::Y);
    }

    #[test]
    fn sphere_behind_ray_misses() {
        let r = Ray::new(Vec3::new(0.0, 0.0, 5.0), Vec3::Z);
        assert!(unit().intersect(&r).is_none());
    }

    #[test]
    fn ray_passing_beside_sphere_misses() {
        let r = Ray::new(Vec3::new(1.001, 0.0, -5.0), Vec3::Z);
        assert!(unit().intersect(&r).is_none());
    }

    #[test]
    fn unnormalised_direction_measures_t_in_units_of_d() {
        let r = Ray::new(Vec3::new(0.0, 0.0, -5.0), Vec3::Z * 2.0);
        assert_eq!(unit().intersect(&r).unwrap().t, 2.0);
    }

    #[test]
    fn t_max_excludes_hits_beyond_it() {
        let mut r = Ray::new(Vec3::new(0.0, 0.0, -5.0), Vec3::Z);
        r.t_max = 4.0;
        assert!(unit().intersect(&r).is_none());
    }

    #[test]
    fn far_away_sphere_is_hit_without_cancellation() {
        // A unit sphere 1e5 away: the naive b² − 4ac loses every digit of the
        // discriminant (b² ≈ 4e10 · |d|⁴ in f32) and misses rays near the rim.
        let s = Sphere::new(Vec3::new(0.0, 0.0, 1e5), 1.0);
        let r = Ray::new(Vec3::new(0.999, 0.0, 0.0), Vec3::Z);
        let h = s.intersect(&r).unwrap();
        let expected = 1e5 - (1.0f64 - 0.999f64 * 0.999f64).sqrt();
        assert!((h.t as f64 - expected).abs() / expected < 1e-6, "{}", h.t);
        assert!(
            s.intersect(&Ray::new(Vec3::new(1.001, 0.0, 0.0), Vec3::Z))
                .is_none()
        );
    }

    #[test]
    fn tiny_sphere_is_hit_without_cancellation() {
        let s = Sphere::new(Vec3::new(0.0, 0.0, 1.0), 1e-6);
        let r = Ray::new(Vec3::new(0.5e-6, 0.0, 0.0), Vec3::Z);
        let h = s.intersect(&r).unwrap();
        let expected = 1.0 - (1e-12f64 - 0.25e-12).sqrt();
        assert!((h.t as f64 - expected).abs() < 1e-7, "{}", h.t);
    }

    #[test]
    fn crossings_count_both_sides_and_inside_length() {
        let r = Ray::new(Vec3::new(0.0, 0.0, -5.0), Vec3::Z);
        let mut cos = Vec::new();
        assert_eq!(unit().crossings(&r, &mut |c| cos.push(c)), 2.0);
        assert_eq!(cos, [1.0, 1.0]);
        let mut short = r;
        short.t_max = 5.0;
        let mut count = 0;
        assert_eq!(unit().crossings(&short, &mut |_| count += 1), 1.0);
        assert_eq!(count, 1);
    }

    #[test]
    fn reflected_ray_does_not_rehit_the_sphere() {
        let s = Sphere::new(Vec3::new(3.0, -2.0, 7.0), 2.5);
        let r = Ray::new(Vec3::ZERO, (Vec3::new(2.0, -0.5, 4.0)).normalize());
        let h = s.intersect(&r).unwrap();
        let sp = s.surface(&r, &h);
        let refl = r.d - 2.0 * r.d.dot(sp.n) * sp.n;
        assert!(
            s.intersect(&Ray::spawn(sp.p, sp.p_err, sp.n, refl))
                .is_none()
        );
    }

    fn scale() -> impl Strategy<Value = f32> {
        (-4.0f32..4.0).prop_map(|e| 10f32.powf(e))
    }

    fn vec() -> impl Strategy<Value = Vec3> {
        (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0).prop_map(|(x, y, z)| Vec3::new(x, y, z))
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]

        /// Hit points lie on the sphere, at any scale from 1e-4 to 1e4.
        #[test]
        fn hit_points_lie_on_the_sphere(c in vec(), s in scale(), r in 0.1f32..2.0, o in vec(), target in vec()) {
            let sphere = Sphere::new(c * 3.0 * s, r * s);
            let o = o * 10.0 * s;
            let d = sphere.center + target * sphere.radius - o;
            prop_assume!(d.length() > 1e-3 * s);
            let ray = Ray::new(o, d);
            if let Some(h) = sphere.intersect(&ray) {
                let p = ray.at(h.t);
                let dist = (p - sphere.center).length();
                let tol = 1e-4 * (sphere.radius + sphere.center.abs().max_element() + o.abs().max_element());
                prop_assert!((dist - sphere.radius).abs() <= tol, "dist {} r {}", dist, sphere.radius);
                let sp = sphere.surface(&ray, &h);
                prop_assert!(((sp.p - sphere.center).length() - sphere.radius).abs() <= 4.0 * sp.p_err.max_element() + 1e-6 * sphere.radius);
            } else {
                // A miss is only allowed if the line passes outside the sphere or
                // the sphere lies behind the origin.
                let l = sphere.center - o;
                let dn = d.normalize();
                let closest = (l - dn * l.dot(dn)).length();
                prop_assert!(closest >= sphere.radius * 0.9999 || (l.length() > sphere.radius && l.dot(dn) < 0.0));
            }
        }

        /// Rays spawned from a hit never hit the same sphere again at t ≈ 0.
        #[test]
        fn spawned_rays_do_not_reintersect(c in vec(), s in scale(), o in vec(), target in vec(), w in vec()) {
            let sphere = Sphere::new(c * 3.0 * s, s);
            let o = o * 10.0 * s + Vec3::new(0.0, 0.0, -20.0 * s);
            let ray = Ray::new(o, sphere.center + target * s - o);
            prop_assume!(w.length() > 1e-3);
            if let Some(h) = sphere.intersect(&ray) {
                let sp = sphere.surface(&ray, &h);
                // Any direction into the outside half-space must miss (the sphere is convex).
                let w = if w.dot(sp.n) > 0.0 { w } else { -w };
                prop_assume!(w.normalize().dot(sp.n) > 1e-3);
                prop_assert!(sphere.intersect(&Ray::spawn(sp.p, sp.p_err, sp.n, w)).is_none());
            }
        }
    }
}
