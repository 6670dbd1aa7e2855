//! Axis-aligned box, e.g. the finite checkerboard slab of Whitted's image.

use super::{ShapeHit, SurfacePoint};
use crate::math::{Aabb, Ray, Vec3, gamma};
use glam::{BVec3A, Vec2};

/// A solid axis-aligned box. Intersected with the slab test; the hit face is
/// known from the axis whose plane gave `t_enter` (or `t_exit` from inside).
///
/// Scene file: `{ shape = "box", min = [x, y, z], max = [x, y, z] }`.
#[derive(Clone, Debug, PartialEq)]
pub struct Cuboid {
    pub bounds: Aabb,
}

/// `prim` encodes the face: the axis (0, 1, 2), plus 3 when the ray left the
/// box through it (origin inside).
const EXIT: u32 = 3;

impl Cuboid {
    pub fn new(min: Vec3, max: Vec3) -> Self {
        Cuboid {
            bounds: Aabb::new(min, max),
        }
    }

    /// The entry face if `t_enter ∈ [t_min, t_max)`, else the exit face if
    /// `t_exit` is (the origin is inside the box).
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<ShapeHit> {
        let s = self.bounds.slab(ray.o, ray.inv_d())?;
        if ray.contains(s.t_enter) {
            Some(ShapeHit {
                t: s.t_enter,
                prim: s.axis_enter as u32,
                ..ShapeHit::default()
            })
        } else if ray.contains(s.t_exit) {
            Some(ShapeHit {
                t: s.t_exit,
                prim: EXIT + s.axis_exit as u32,
                ..ShapeHit::default()
            })
        } else {
            None
        }
    }

    /// The coordinate along the face's axis is snapped onto the face's plane,
    /// so the point lies exactly on the box.
    pub fn surface(&self, ray: &Ray, hit: &ShapeHit) -> SurfacePoint {
        let axis = (hit.prim % EXIT) as usize;
        let d_axis = ray.d[axis];
        // Entering, the face looks against the ray; leaving, along it.
        let outward_positive = if hit.prim >= EXIT {
            d_axis > 0.0
        } else {
            d_axis < 0.0
        };
        let (face, sign) = if outward_positive {
            (self.bounds.max, 1.0)
        } else {
            (self.bounds.min, -1.0)
        };
        // Selects rather than indexing the vectors by `axis`, which goes
        // through memory.
        let on_axis = BVec3A::new(axis == 0, axis == 1, axis == 2);
        let p = Vec3::select(on_axis, face, ray.at(hit.t));
        let n = Vec3::select(on_axis, Vec3::splat(sign), Vec3::ZERO);
        let p = p.clamp(self.bounds.min, self.bounds.max);
        SurfacePoint {
            p,
            p_err: gamma(5) * p.abs(),
            n,
            ns: n,
        }
    }

    /// Three corners `p0, p1, p2` of face `face` (axis `face / 2`, on the
    /// max side if `face` is odd): the face is the parallelogram
    /// `p0 + u (p1 − p0) + v (p2 − p0)`, with `(p1 − p0) × (p2 − p0)`
    /// pointing out of the box.
    pub fn face_corners(&self, face: usize) -> [Vec3; 3] {
        let (a, positive) = (face / 2, face % 2 == 1);
        let (b, c) = ((a + 1) % 3, (a + 2) % 3);
        let (lo, hi) = (self.bounds.min, self.bounds.max);
        let mut p0 = lo;
        if positive {
            p0[a] = hi[a];
        }
        let (mut p1, mut p2) = (p0, p0);
        p1[b] = hi[b];
        p2[c] = hi[c];
        if positive { [p0, p1, p2] } else { [p0, p2, p1] }
    }

    /// The face index of [`Cuboid::face_corners`] for the outward normal `n`
    /// of a hit.
    pub fn face_of(n: Vec3) -> u32 {
        let a = if n.x != 0.0 {
            0
        } else if n.y != 0.0 {
            1
        } else {
            2
        };
        (2 * a + (n[a] > 0.0) as usize) as u32
    }

    /// The two world coordinates across the face (x and z on the top face).
    pub fn uv(&self, p: Vec3, prim: u32) -> Vec2 {
        match prim % EXIT {
            0 => Vec2::new(p.z, p.y),
            1 => Vec2::new(p.x, p.z),
            _ => Vec2::new(p.x, p.y),
        }
    }

    /// See [`super::Shape::crossings`].
    pub fn crossings(&self, ray: &Ray, crossing: &mut impl FnMut(f32)) -> f32 {
        let Some(s) = self.bounds.slab(ray.o, ray.inv_d()) else {
            return 0.0;
        };
        let d_len = ray.d.length();
        if ray.contains(s.t_enter) {
            crossing((ray.d[s.axis_enter as usize] / d_len).abs().min(1.0));
        }
        if ray.contains(s.t_exit) {
            crossing((ray.d[s.axis_exit as usize] / d_len).abs().min(1.0));
        }
        let inside = s.t_exit.min(ray.t_max) - s.t_enter.max(ray.t_min);
        inside.max(0.0) * d_len
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn slab() -> Cuboid {
        Cuboid::new(Vec3::new(-4.0, -0.02, -4.0), Vec3::new(4.0, 0.0, 12.0))
    }

    #[test]
    fn top_face_hit_from_above() {
        let r = Ray::new(Vec3::new(0.5, 2.0, 0.0), Vec3::new(0.0, -1.0, 1.0));
        let b = slab();
        let h = b.intersect(&r).unwrap();
        assert_eq!(h.t, 2.0);
        let s = b.surface(&r, &h);
        assert_eq!(s.n, Vec3::Y);
        assert_eq!(s.p, Vec3::new(0.5, 0.0, 2.0));
        assert_eq!(b.uv(s.p, h.prim), Vec2::new(0.5, 2.0));
    }

    #[test]
    fn side_face_hit() {
        let r = Ray::new(Vec3::new(10.0, -0.01, 0.0), -Vec3::X);
        let b = slab();
        let h = b.intersect(&r).unwrap();
        assert_eq!(h.t, 6.0);
        assert_eq!(b.surface(&r, &h).n, Vec3::X);
    }

    #[test]
    fn from_inside_hits_exit_face_with_outward_normal() {
        let b = Cuboid::new(Vec3::splat(-1.0), Vec3::splat(1.0));
        let r = Ray::new(Vec3::ZERO, -Vec3::Z);
        let h = b.intersect(&r).unwrap();
        assert_eq!(h.t, 1.0);
        let s = b.surface(&r, &h);
        assert_eq!(s.n, -Vec3::Z);
        assert_eq!(s.p, Vec3::new(0.0, 0.0, -1.0));
    }

    #[test]
    fn ray_past_the_edge_misses() {
        let r = Ray::new(Vec3::new(4.5, 1.0, 0.0), -Vec3::Y);
        assert!(slab().intersect(&r).is_none());
    }

    #[test]
    fn reflected_ray_leaves_the_top_face() {
        let b = slab();
        let r = Ray::new(Vec3::new(0.3, 2.0, -3.0), Vec3::new(0.1, -1.0, 1.3));
        let h = b.intersect(&r).unwrap();
        let s = b.surface(&r, &h);
        let refl = r.d - 2.0 * r.d.dot(s.n) * s.n;
        assert!(b.intersect(&Ray::spawn(s.p, s.p_err, s.n, refl)).is_none());
        // A shadow ray to a light above as well.
        let sh = Ray::spawn_to(s.p, s.p_err, s.n, Vec3::new(-4.0, 9.0, -7.0));
        assert!(b.intersect(&sh).is_none());
    }

    #[test]
    fn crossings_through_the_box() {
        let b = Cuboid::new(Vec3::splat(-1.0), Vec3::splat(1.0));
        let r = Ray::new(Vec3::new(0.0, 0.0, -3.0), Vec3::Z);
        let mut count = 0;
        assert_eq!(b.crossings(&r, &mut |_| count += 1), 2.0);
        assert_eq!(count, 2);
    }
}
