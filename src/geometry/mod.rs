//! Shapes: their bounds, ray intersection, and the surface at a hit.
//!
//! Intersection is two-phase (as in Mitsuba): [`Shape::intersect`] returns only
//! a small [`ShapeHit`] (the parameter `t` and a primitive index), and
//! [`Shape::surface`] then computes the point, its error bound and normal
//! once, for the closest hit only, and [`Shape::uv`] the texture coordinates
//! only for textures that use them. Shapes know nothing of materials.

mod cuboid;
mod plane;
mod sphere;

pub use cuboid::Cuboid;
pub use plane::Plane;
pub use sphere::Sphere;

use crate::math::{Aabb, Ray, Vec3};
use glam::Vec2;

/// A ray–shape hit: the ray parameter and which part of the shape was hit
/// (the face of a box; 0 for shapes with one part).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShapeHit {
    pub t: f32,
    pub prim: u32,
}

/// The surface at a hit point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint {
    /// The hit point, as close to the true surface as the shape can make it.
    pub p: Vec3,
    /// Conservative bound on the absolute error of each component of `p`.
    pub p_err: Vec3,
    /// Unit geometric normal, pointing out of closed shapes (for a plane: its
    /// stated normal), whichever side the ray came from.
    pub n: Vec3,
}

/// Where a ray segment crosses a shape's surface, for shadow rays that pass
/// through transparent objects: how many crossings lie in `[t_min, t_max)`, the
/// cosine of the angle between the ray and the normal at each, and the length
/// of the segment inside the shape (zero for a plane).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Crossings {
    pub count: u8,
    pub cos: [f32; 2],
    pub inside_length: f32,
}

impl Crossings {
    fn push(&mut self, cos: f32) {
        self.cos[self.count as usize] = cos.abs().min(1.0);
        self.count += 1;
    }
}

/// The closed set of shapes, dispatched by `match` (no vtable in the hot loop).
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    Sphere(Sphere),
    Plane(Plane),
    Cuboid(Cuboid),
}

impl Shape {
    /// The closest hit with `t ∈ [ray.t_min, ray.t_max)`.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<ShapeHit> {
        match self {
            Shape::Sphere(s) => s.intersect(ray),
            Shape::Plane(s) => s.intersect(ray),
            Shape::Cuboid(s) => s.intersect(ray),
        }
    }

    /// The surface at a hit returned by [`Shape::intersect`] for the same ray.
    #[inline]
    pub fn surface(&self, ray: &Ray, hit: &ShapeHit) -> SurfacePoint {
        match self {
            Shape::Sphere(s) => s.surface(ray, hit),
            Shape::Plane(s) => s.surface(ray, hit),
            Shape::Cuboid(s) => s.surface(ray, hit),
        }
    }

    /// Surface coordinates for textures at the surface point `p` of part `prim`.
    #[inline]
    pub fn uv(&self, p: Vec3, prim: u32) -> Vec2 {
        match self {
            Shape::Sphere(s) => s.uv(p),
            Shape::Plane(s) => s.uv(p),
            Shape::Cuboid(s) => s.uv(p, prim),
        }
    }

    /// Every crossing of the ray's segment `[t_min, t_max)` with the surface.
    #[inline]
    pub fn crossings(&self, ray: &Ray) -> Crossings {
        match self {
            Shape::Sphere(s) => s.crossings(ray),
            Shape::Plane(s) => s.crossings(ray),
            Shape::Cuboid(s) => s.crossings(ray),
        }
    }

    /// A box holding the shape (infinite for a plane).
    pub fn bounds(&self) -> Aabb {
        match self {
            Shape::Sphere(s) => s.bounds(),
            Shape::Plane(_) => Aabb::new(Vec3::NEG_INFINITY, Vec3::INFINITY),
            Shape::Cuboid(s) => s.bounds,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shape_enum_stays_small() {
        // The enum sits in the object array scanned by every ray: keep it compact.
        assert!(
            std::mem::size_of::<Shape>() <= 64,
            "{}",
            std::mem::size_of::<Shape>()
        );
    }
}
