//! The ray `r(t) = o + t·d`, valid for `t ∈ [t_min, t_max)`.

use super::{Vec3, offset_ray_origin};

/// Shadow rays to a point light end at `t = 1 − SHADOW_EPSILON` of the unnormalised
/// direction from the surface to the light (pbrt-v4 `ShadowEpsilon`): relative to
/// the segment, so it is the same at every scene scale.
pub const SHADOW_EPSILON: f32 = 1e-4;

/// A ray `r(t) = o + t·d`, considered for `t ∈ [t_min, t_max)`.
///
/// `d` need not be normalised; `t` is measured in units of `|d|`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Origin.
    pub o: Vec3,
    /// Direction.
    pub d: Vec3,
    /// Smallest parameter value considered (inclusive).
    pub t_min: f32,
    /// Largest parameter value considered (exclusive).
    pub t_max: f32,
}

impl Ray {
    /// A ray over `[0, ∞)`.
    #[inline]
    pub fn new(o: Vec3, d: Vec3) -> Self {
        debug_assert!(o.is_finite() && d.is_finite(), "ray {o:?} + t·{d:?}");
        Ray {
            o,
            d,
            t_min: 0.0,
            t_max: f32::INFINITY,
        }
    }

    /// The point `o + t·d`.
    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.o + self.d * t
    }

    /// A ray leaving the surface point `p` (error bound `p_err`, geometric normal
    /// `n`) in direction `d`, from an origin offset to `d`'s side of the surface.
    #[inline]
    pub fn spawn(p: Vec3, p_err: Vec3, n: Vec3, d: Vec3) -> Self {
        Ray::new(offset_ray_origin(p, p_err, n, d), d)
    }

    /// A shadow ray from the surface point `p` towards `target`, ending just short
    /// of it (at `1 − SHADOW_EPSILON` of the segment).
    #[inline]
    pub fn spawn_to(p: Vec3, p_err: Vec3, n: Vec3, target: Vec3) -> Self {
        let o = offset_ray_origin(p, p_err, n, target - p);
        Ray {
            o,
            d: target - o,
            t_min: 0.0,
            t_max: 1.0 - SHADOW_EPSILON,
        }
    }

    /// `1/d` per component, with IEEE infinities for zero components.
    #[inline]
    pub fn inv_d(&self) -> Vec3 {
        self.d.recip()
    }

    /// Whether `t` lies in `[t_min, t_max)`; false for NaN.
    #[inline]
    pub fn contains(&self, t: f32) -> bool {
        t >= self.t_min && t < self.t_max
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn at_follows_o_plus_t_d() {
        let r = Ray::new(Vec3::new(1.0, 2.0, 3.0), Vec3::new(0.0, -1.0, 2.0));
        assert_eq!(r.at(0.0), r.o);
        assert_eq!(r.at(2.0), Vec3::new(1.0, 0.0, 7.0));
    }

    #[test]
    fn range_is_half_open_and_rejects_nan() {
        let mut r = Ray::new(Vec3::ZERO, Vec3::X);
        r.t_max = 2.0;
        assert!(r.contains(0.0));
        assert!(r.contains(1.999));
        assert!(!r.contains(2.0));
        assert!(!r.contains(-1e-30));
        assert!(!r.contains(f32::NAN));
    }

    #[test]
    fn shadow_ray_ends_short_of_the_light() {
        let light = Vec3::new(0.0, 10.0, 0.0);
        let r = Ray::spawn_to(Vec3::ZERO, Vec3::ZERO, Vec3::Y, light);
        assert!(r.at(r.t_max).y < light.y);
        assert!(r.o.y > 0.0);
    }
}
