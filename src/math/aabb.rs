//! Axis-aligned bounding boxes and the slab test.

use super::{Ray, Vec3};

/// An axis-aligned box `[min, max]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

impl Aabb {
    /// The empty box (`min = +∞`, `max = −∞`): the identity of [`Aabb::union`].
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::INFINITY,
        max: Vec3::NEG_INFINITY,
    };

    /// The box spanned by two corners, in any order.
    pub fn new(a: Vec3, b: Vec3) -> Self {
        Aabb {
            min: a.min(b),
            max: a.max(b),
        }
    }

    /// The smallest box holding both.
    pub fn union(&self, other: &Aabb) -> Aabb {
        Aabb {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    /// Half the surface area, `e_x·e_y + e_y·e_z + e_z·e_x` for the extents
    /// `e = max − min` (0 for an empty box), in f64: there the extents of
    /// f32 corners and their products are exact, and nothing overflows or
    /// underflows, so surface area heuristic costs (MacDonald and Booth
    /// 1990) order splits the same way at every scale f32 holds. In f32
    /// the products overflow past extents of about 10¹⁹ and vanish below
    /// about 10⁻¹⁹, where every split would cost the same.
    pub fn half_area(&self) -> f64 {
        let e = |a: usize| (self.max[a] as f64 - self.min[a] as f64).max(0.0);
        let (x, y, z) = (e(0), e(1), e(2));
        x * y + y * z + z * x
    }

    /// Whether `p` lies in the closed box.
    pub fn contains(&self, p: Vec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }

    /// The slab test, as the lecture states it.
    ///
    /// Per axis `i` the ray crosses the two planes of the slab at
    /// `t = (min_i − o_i)/d_i` and `t = (max_i − o_i)/d_i`; the nearer is the
    /// slab's entry, the farther its exit. Then `t_enter = max` of the entries,
    /// `t_exit = min` of the exits, and the ray's line meets the box iff
    /// `t_enter < t_exit`; the box is not behind the ray iff `t_exit ≥ 0`.
    /// Returns `(t_enter, t_exit)` and the axes that gave them.
    ///
    /// `inv_d` is `1/d` per component (IEEE infinities where `d_i = 0`). The
    /// near plane is chosen by the sign of `inv_d` instead of by comparing the two
    /// values, and the entries and exits are folded with comparisons, which are
    /// false for NaN: when `d_i = 0` and `o_i` lies exactly on a slab plane,
    /// `0·∞ = NaN` for that plane and the plane is ignored, i.e. the boundary
    /// counts as inside. A ray parallel to a slab and outside it gives
    /// `±∞` entries or exits and misses.
    #[inline]
    pub fn slab(&self, o: Vec3, inv_d: Vec3) -> Option<SlabHit> {
        let (lo, hi) = (self.min.to_array(), self.max.to_array());
        let (o, inv_d) = (o.to_array(), inv_d.to_array());
        let mut t_enter = f32::NEG_INFINITY;
        let mut t_exit = f32::INFINITY;
        let (mut axis_enter, mut axis_exit) = (0u8, 0u8);
        for i in 0..3 {
            let (near, far) = if inv_d[i] >= 0.0 {
                (lo[i], hi[i])
            } else {
                (hi[i], lo[i])
            };
            let t_near = (near - o[i]) * inv_d[i];
            let t_far = (far - o[i]) * inv_d[i];
            if t_near > t_enter {
                t_enter = t_near;
                axis_enter = i as u8;
            }
            if t_far < t_exit {
                t_exit = t_far;
                axis_exit = i as u8;
            }
        }
        (t_enter < t_exit && t_exit >= 0.0).then_some(SlabHit {
            t_enter,
            t_exit,
            axis_enter,
            axis_exit,
        })
    }

    /// Whether the ray meets the box within `[ray.t_min, ray.t_max)`.
    #[inline]
    pub fn hit_by(&self, ray: &Ray, inv_d: Vec3) -> bool {
        match self.slab(ray.o, inv_d) {
            Some(h) => h.t_enter < ray.t_max && h.t_exit >= ray.t_min,
            None => false,
        }
    }
}

/// Result of [`Aabb::slab`]: entry and exit parameters and the axes of the planes
/// they lie on (`t_enter` is `−∞` when the origin is inside every slab).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlabHit {
    pub t_enter: f32,
    pub t_exit: f32,
    pub axis_enter: u8,
    pub axis_exit: u8,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_box() -> Aabb {
        Aabb::new(Vec3::splat(-1.0), Vec3::splat(1.0))
    }

    fn slab(b: &Aabb, o: Vec3, d: Vec3) -> Option<SlabHit> {
        b.slab(o, d.recip())
    }

    #[test]
    fn slab_hit_from_outside() {
        let h = slab(&unit_box(), Vec3::new(0.0, 0.0, -5.0), Vec3::Z).unwrap();
        assert_eq!((h.t_enter, h.t_exit), (4.0, 6.0));
        assert_eq!((h.axis_enter, h.axis_exit), (2, 2));
    }

    #[test]
    fn slab_origin_inside_box() {
        let h = slab(&unit_box(), Vec3::new(0.5, 0.0, 0.0), Vec3::X).unwrap();
        assert!(h.t_enter < 0.0);
        assert_eq!(h.t_exit, 0.5);
    }

    #[test]
    fn slab_box_behind_ray_misses() {
        assert!(slab(&unit_box(), Vec3::new(0.0, 0.0, 5.0), Vec3::Z).is_none());
    }

    #[test]
    fn slab_zero_direction_component() {
        // Parallel to the x and y slabs, inside them: hit.
        let h = slab(&unit_box(), Vec3::new(0.2, -0.3, -4.0), Vec3::Z).unwrap();
        assert_eq!((h.t_enter, h.t_exit), (3.0, 5.0));
        // Parallel to the x slab and outside it: miss.
        assert!(slab(&unit_box(), Vec3::new(2.0, 0.0, -4.0), Vec3::Z).is_none());
    }

    #[test]
    fn slab_origin_on_plane_with_zero_direction_component_gives_no_nan() {
        // o.x lies exactly on the plane x = 1 and d.x = 0: (1 − 1)·∞ = NaN.
        let h = slab(&unit_box(), Vec3::new(1.0, 0.0, -4.0), Vec3::Z).unwrap();
        assert!(!h.t_enter.is_nan() && !h.t_exit.is_nan());
        assert_eq!((h.t_enter, h.t_exit), (3.0, 5.0));
        // Negative zero direction component as well.
        let h = slab(
            &unit_box(),
            Vec3::new(-1.0, 0.0, -4.0),
            Vec3::new(-0.0, 0.0, 1.0),
        )
        .unwrap();
        assert_eq!((h.t_enter, h.t_exit), (3.0, 5.0));
    }

    #[test]
    fn slab_negative_direction() {
        let h = slab(&unit_box(), Vec3::new(3.0, 0.5, 0.5), -Vec3::X).unwrap();
        assert_eq!((h.t_enter, h.t_exit), (2.0, 4.0));
    }

    #[test]
    fn hit_by_respects_ray_interval() {
        let b = unit_box();
        let mut r = Ray::new(Vec3::new(0.0, 0.0, -5.0), Vec3::Z);
        assert!(b.hit_by(&r, r.inv_d()));
        r.t_max = 3.9;
        assert!(!b.hit_by(&r, r.inv_d()));
        r.t_max = f32::INFINITY;
        r.t_min = 6.5;
        assert!(!b.hit_by(&r, r.inv_d()));
    }

    #[test]
    fn union_and_contains() {
        let b = Aabb::EMPTY.union(&unit_box());
        assert_eq!(b, unit_box());
        assert!(b.contains(Vec3::ONE));
        assert!(!b.contains(Vec3::new(0.0, 1.01, 0.0)));
    }
}
