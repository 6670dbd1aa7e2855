//! The per-ray setup of [`super`]'s traversals: the inverse direction, the
//! octant, and the constants of the fused slab test with the argument that
//! it takes every box the plain test takes.

use crate::math::{Aabb, Ray, Vec3};

/// What every lane implementation needs of a ray: origin, finite inverse
/// direction, `t_min`, the octant of the direction as [`Bvh8Node::order`]
/// numbers them, and the constants of the fused slab test.
pub(in crate::accel::bvh8) struct RaySetup {
    pub(super) o: Vec3,
    pub(super) inv: Vec3,
    pub(super) t_min: f32,
    pub(super) octant: u32,
    /// Whether the fused test is used (see [`RaySetup::new`]).
    pub(super) fused: bool,
    /// `c_near` and `c_far` of the fused test, per axis.
    pub(super) near_c: Vec3,
    pub(super) far_c: Vec3,
}

/// `K = 1 + 2⁻²⁰ = 1 + 16u` (`u = 2⁻²⁴`), by which the fused test widens
/// `t_max`.
pub(in crate::accel::bvh8) const WIDEN: f32 = 1.0 + 1.0 / (1 << 20) as f32;

impl RaySetup {
    /// The setup of `ray` for a tree whose root box is `root`. Slab
    /// distances are computed one of two ways, chosen per ray, the same on
    /// every CPU:
    ///
    /// - *plain*: `t = (plane − o)·inv`, a subtraction and a product,
    ///   rounded twice;
    /// - *fused*: `t = plane·inv − c`, one fused multiply-add (FMA) per
    ///   plane, as tinybvh and Embree's fast path compute `plane·inv −
    ///   o·inv`: half the operations and half the latency of a node test.
    ///
    /// The fused test takes every box the plain one takes, by constants that
    /// lean each plane outwards (as pbrt-v4 §6.8 and Ize, "Robust BVH Ray
    /// Traversal", 2013, pad their tests): `c_near = fl(oi + s_near)` and
    /// `c_far = fl(oi − s_far)` with `oi = fl(o·inv)`, `s_near = 8u|oi| +
    /// 2⁻¹²⁶`, `s_far = 8u(|oi| + M) + 2⁻¹²⁶`, `u = 2⁻²⁴`, `M` the largest
    /// plain `|t|` of the root box's two planes on that axis (every box in
    /// the tree lies inside it, so `|τ| ≤ M(1 + 2.001u)` for all its
    /// planes), and `t_max` widened to `fl(K·t_max)`, `K = 1 + 16u`. With
    /// `τ = (plane − o)·inv` exactly and `P` the plain value (`|P − τ| ≤
    /// 2.0001u|τ|`): the error of `oi`, `u|o·inv|`, is absolute where `P`'s
    /// is relative, and the constants outweigh it, so a fused near value is
    /// at most `τ + u|τ| ≤ g(P)` with `g(x) = x + 3.001u|x|`, and a fused
    /// far value at least `τ − u|τ| − 2.001u|oi| + s_far(1 − 2u) ≥ g(P)`
    /// wherever `P ≥ 0` (the `2⁻¹²⁶` covers results in the subnormal
    /// range). `g` is increasing and `g(x) ≥ x`, so for the plain entry `A
    /// = max(near, t_min)` and exit `B = min(far, t_max)` the fused entry is
    /// at most `g(A)`, and where `0 ≤ t_min ≤ A ≤ B` (every far value and
    /// `t_max` then non-negative) the fused exit is at least `g(B) ≥
    /// g(A)`: every box the plain test takes is taken, and an entry the
    /// plain traversal keeps (`A ≤ t_max`) is kept against `fl(K·t_max) ≥
    /// g(t_max)`. The closest hit, taken over leaves in the same order, is
    /// then the one the plain traversal finds, or a hit it passed by.
    ///
    /// The bound needs `t_min ≥ 0` and finite constants (`oi` and `M`
    /// below `10³⁶`, which only an origin past `10⁶` on an axis the ray is
    /// parallel to breaks); other rays keep the plain test.
    #[inline(always)]
    pub(in crate::accel::bvh8) fn new(ray: &Ray, root: &Aabb) -> Self {
        // Finite, so (plane − o)·inv is never 0·∞ = NaN (see `Bvh`).
        let inv = ray.d.recip().clamp(Vec3::splat(-1e30), Vec3::splat(1e30));
        let oi = ray.o * inv;
        // max(|(min − o)·inv|, |(max − o)·inv|), bit for bit (rounding is
        // symmetric and monotonic), with the subtractions, magnitudes and
        // max off the path through the division.
        let m = (root.min - ray.o).abs().max((root.max - ray.o).abs()) * inv.abs();
        let eighth = 1.0 / (1 << 21) as f32;
        let tiny = Vec3::splat(f32::MIN_POSITIVE);
        let far_s = (oi.abs() + m) * eighth + tiny;
        RaySetup {
            o: ray.o,
            inv,
            t_min: ray.t_min,
            // Bit a set unless inv[a] < 0.
            octant: !inv.cmplt(Vec3::ZERO).bitmask() & 7,
            fused: ray.t_min >= 0.0 && (oi.abs() + m).max_element() < 1e36,
            near_c: oi + (oi.abs() * eighth + tiny),
            far_c: oi - far_s,
        }
    }
}
