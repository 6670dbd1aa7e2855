//! Shapes: their bounds, ray intersection, and the surface at a hit.
//!
//! Intersection is two-phase (as in Mitsuba): [`Shape::intersect`] returns only
//! a small [`ShapeHit`] (the parameter `t` and a primitive index), and
//! [`Shape::surface`] then computes the point, its error bound and normal
//! once, for the closest hit only, and [`Shape::uv`] the texture coordinates
//! only for textures that use them. Shapes know nothing of materials.

pub mod batch;
mod cuboid;
pub mod implicit;
mod mesh;
mod plane;
mod sphere;
pub mod testgen;
mod triangle;

pub use cuboid::Cuboid;
pub use implicit::Implicit;
pub use mesh::{CHECKED_SCALES, Mesh, MeshDataError, MeshInstance};
pub use plane::Plane;
pub use sphere::Sphere;
pub use triangle::{
    LANES, LaneHits, RayShear, TriangleHit, TriangleLanes, intersect_mt, intersect_watertight,
    intersect_watertight_lanes,
};

use crate::accel::TraversalCounters;
use crate::math::{Aabb, Ray, Vec3};
use glam::Vec2;

/// A ray–shape hit: the ray parameter, which part of the shape was hit (the
/// face of a box; 0 for shapes with one part), and two numbers the shape keeps
/// for [`Shape::surface`] (an implicit surface keeps the f64 part of `t` lost
/// in rounding it to f32).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ShapeHit {
    pub t: f32,
    pub prim: u32,
    pub u: f32,
    pub v: f32,
}

/// Counts of work done by intersection queries, summed per tile by the renderer.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TraceCounters {
    /// Ray–shape intersection tests.
    pub intersection_tests: u64,
    /// Root searches along rays that entered an implicit surface's bounds.
    pub implicit_searches: u64,
    /// Interval evaluations of implicit surfaces' formulas.
    pub implicit_evaluations: u64,
    /// Root searches that gave up at `MAX_SEARCH_EVALUATIONS`.
    pub implicit_searches_cut: u64,
    /// BVH nodes visited and triangles tested inside meshes.
    pub bvh: TraversalCounters,
}

impl TraceCounters {
    /// Counts a root search that started when `implicit_evaluations` was
    /// `before` as cut if it spent the whole budget.
    #[inline]
    pub fn note_cut(&mut self, before: u64) {
        let spent = self.implicit_evaluations - before;
        self.implicit_searches_cut += (spent >= implicit::roots::MAX_SEARCH_EVALUATIONS) as u64;
    }

    /// The work done since the counters were `before`.
    pub fn since(&self, before: &TraceCounters) -> TraceCounters {
        TraceCounters {
            intersection_tests: self.intersection_tests - before.intersection_tests,
            implicit_searches: self.implicit_searches - before.implicit_searches,
            implicit_evaluations: self.implicit_evaluations - before.implicit_evaluations,
            implicit_searches_cut: self.implicit_searches_cut - before.implicit_searches_cut,
            bvh: TraversalCounters {
                nodes_visited: self.bvh.nodes_visited - before.bvh.nodes_visited,
                primitive_tests: self.bvh.primitive_tests - before.bvh.primitive_tests,
            },
        }
    }
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
    /// Unit shading normal: interpolated from vertex normals on smooth meshes,
    /// `n` elsewhere.
    pub ns: Vec3,
}

/// The closed set of shapes, dispatched by `match` (no vtable in the hot loop).
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    Sphere(Sphere),
    Plane(Plane),
    Cuboid(Cuboid),
    Implicit(Box<Implicit>),
    Mesh(MeshInstance),
}

impl Shape {
    /// The kind, as scene files name it.
    pub fn name(&self) -> &'static str {
        match self {
            Shape::Sphere(_) => "sphere",
            Shape::Plane(_) => "plane",
            Shape::Cuboid(_) => "box",
            Shape::Implicit(_) => "implicit",
            Shape::Mesh(_) => "mesh",
        }
    }

    /// The closest hit with `t ∈ [ray.t_min, ray.t_max)`.
    // Always inlined: a call would return the 20-byte `Option<ShapeHit>`
    // through memory, which costs ~10% of a Whitted frame.
    #[inline(always)]
    pub fn intersect(&self, ray: &Ray, counters: &mut TraceCounters) -> Option<ShapeHit> {
        match self {
            Shape::Sphere(s) => s.intersect(ray),
            Shape::Plane(s) => s.intersect(ray),
            Shape::Cuboid(s) => s.intersect(ray),
            Shape::Implicit(s) => s.intersect(ray, counters),
            Shape::Mesh(s) => s.intersect(ray, counters),
        }
    }

    /// Whether the shape meets the ray's segment at all (any-hit, for shadow
    /// rays; cheaper than [`Shape::intersect`] where finding the closest hit
    /// costs more than finding one).
    #[inline]
    pub fn occludes(&self, ray: &Ray, counters: &mut TraceCounters) -> bool {
        match self {
            Shape::Implicit(s) => s.occludes(ray, counters),
            Shape::Mesh(s) => s.occludes(ray, counters),
            _ => self.intersect(ray, counters).is_some(),
        }
    }

    /// The surface at a hit returned by [`Shape::intersect`] for the same ray.
    #[inline]
    pub fn surface(&self, ray: &Ray, hit: &ShapeHit) -> SurfacePoint {
        match self {
            Shape::Sphere(s) => s.surface(ray, hit),
            Shape::Plane(s) => s.surface(ray, hit),
            Shape::Cuboid(s) => s.surface(ray, hit),
            Shape::Implicit(s) => s.surface(ray, hit),
            Shape::Mesh(s) => s.surface(ray, hit),
        }
    }

    /// Surface coordinates for textures at the surface point `p` of part
    /// `prim`, or `None` where the shape has none: implicit surfaces, and
    /// meshes whose file gives no texture coordinates (planar textures then
    /// fall back to solid ones, see [`crate::scene::Texture::eval`]).
    #[inline]
    pub fn uv(&self, p: Vec3, prim: u32) -> Option<Vec2> {
        match self {
            Shape::Sphere(s) => Some(s.uv(p)),
            Shape::Plane(s) => Some(s.uv(p)),
            Shape::Cuboid(s) => Some(s.uv(p, prim)),
            Shape::Implicit(_) => None,
            Shape::Mesh(s) => s.uv(p, prim),
        }
    }

    /// For shadow rays through transparent objects: calls `crossing` with
    /// `|cos θ|` (between the ray and the normal) at every crossing of the ray's
    /// segment `[t_min, t_max)` with the surface, and returns the length of the
    /// segment inside the shape (zero for a plane).
    #[inline]
    pub fn crossings(
        &self,
        ray: &Ray,
        counters: &mut TraceCounters,
        crossing: &mut impl FnMut(f32),
    ) -> f32 {
        match self {
            Shape::Sphere(s) => s.crossings(ray, crossing),
            Shape::Plane(s) => s.crossings(ray, crossing),
            Shape::Cuboid(s) => s.crossings(ray, crossing),
            Shape::Implicit(s) => s.crossings(ray, counters, crossing),
            Shape::Mesh(s) => s.crossings(ray, counters, crossing),
        }
    }

    /// A box holding the shape (infinite for a plane).
    pub fn bounds(&self) -> Aabb {
        match self {
            Shape::Sphere(s) => s.bounds(),
            Shape::Plane(_) => Aabb::new(Vec3::NEG_INFINITY, Vec3::INFINITY),
            Shape::Cuboid(s) => s.bounds,
            Shape::Implicit(s) => s.bounds(),
            Shape::Mesh(s) => s.bounds(),
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
