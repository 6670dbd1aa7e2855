//! Ray–triangle intersection.

use crate::math::{Vec3, gamma};
use glam::Vec4;

/// A ray–triangle hit: the ray parameter and the barycentric coordinates of
/// `v1` and `v2` (that of `v0` is `1 − b1 − b2`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleHit {
    pub t: f32,
    pub b1: f32,
    pub b2: f32,
}

/// Möller–Trumbore, as the lecture gives it ("Fast, Minimum Storage
/// Ray/Triangle Intersection", JGT 1997): with `E1 = v1 − v0`, `E2 = v2 − v0`,
/// `S = o − v0`, `S1 = d × E2`, `S2 = S × E1` and one division by
/// `det = S1·E1`:
///
/// `[t, b1, b2] = [S2·E2, S1·S, S2·d] / det`,
///
/// a hit iff `b1 ≥ 0`, `b2 ≥ 0`, `b1 + b2 ≤ 1` and `t ∈ [t_min, t_max)`.
///
/// The three edge tests are made on the numerators and allow each its
/// floating-point error bound instead of an exact comparison with zero, so
/// that two triangles sharing an edge overlap by a few ulps rather than
/// leave a gap that a ray can slip through (a ray exactly on a shared edge
/// may hit both; the closest-hit search keeps one). The bound must hold
/// against the exact value of each numerator as a polynomial in the inputs
/// `o, d, v0, v1, v2`, so it is taken over the magnitudes of the *factors*:
/// `n1 = (d × E2)·S` is a sum of six products `±d_a·E2_b·S_c`, each formed
/// through at most 7 roundings (E2 and S, the product, the cross product's
/// difference, the dot product's product and two sums), so
/// `|fl(n1) − n1| ≤ γ(7)·(|d| ⊗ |E2|)·|S|`, where `a ⊗ b` is the cross
/// product with every difference made a sum (Higham §3.1). The magnitude of
/// the rounded cross product `|S1|` would not do: where `d × E2` cancels
/// (steep triangles, seen 1–3° from the ray) it is hundreds of times smaller
/// than the error it carries, and rays through shared vertices leaked. The
/// third edge function `det − n1 − n2` is bounded by the sum of the three
/// bounds; the factor γ(12) covers the bounds' own rounding and that sum.
#[inline(always)]
pub fn intersect_mt(
    o: Vec3,
    d: Vec3,
    v0: Vec3,
    v1: Vec3,
    v2: Vec3,
    t_min: f32,
    t_max: f32,
) -> Option<TriangleHit> {
    let e1 = v1 - v0;
    let e2 = v2 - v0;
    let s1 = d.cross(e2);
    let det = s1.dot(e1);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let s = o - v0;
    let s2 = s.cross(e1);
    // Numerators, made positive for det > 0.
    let sign = 1.0f32.copysign(det);
    let n1 = s1.dot(s) * sign;
    let n2 = s2.dot(d) * sign;
    let det_abs = det.abs();
    let g = gamma(12);
    let (d_abs, s_abs) = (d.abs(), s.abs());
    let d_e2 = abs_cross(d_abs, e2.abs());
    let err1 = g * d_e2.dot(s_abs);
    let err2 = g * abs_cross(s_abs, e1.abs()).dot(d_abs);
    let err_det = g * d_e2.dot(e1.abs());
    if n1 < -err1 || n2 < -err2 || n1 + n2 > det_abs + err1 + err2 + err_det {
        return None;
    }
    let inv = 1.0 / det;
    let t = s2.dot(e2) * inv;
    if !(t >= t_min && t < t_max) {
        return None;
    }
    let inv_abs = inv.abs();
    Some(TriangleHit {
        t,
        b1: (n1 * inv_abs).clamp(0.0, 1.0),
        b2: (n2 * inv_abs).clamp(0.0, 1.0),
    })
}

/// `|a| ⊗ |b|` for `a`, `b` already made non-negative: the cross product with
/// its differences made sums, `(a_y·b_z + a_z·b_y, …)`, which bounds the
/// magnitudes that each component of `a × b` is formed from.
#[inline(always)]
fn abs_cross(a: Vec3, b: Vec3) -> Vec3 {
    Vec3::new(
        a.y * b.z + a.z * b.y,
        a.z * b.x + a.x * b.z,
        a.x * b.y + a.y * b.x,
    )
}

/// Triangles tested at once by [`intersect_mt_lanes`].
pub const LANES: usize = 4;

/// Four triangles in structure-of-arrays form, one per lane, as the test
/// uses them: `v0[a]` holds coordinate `a` of every lane's first vertex,
/// `e1[a]` and `e2[a]` of its edges `v1 − v0` and `v2 − v0` (the same f32
/// subtractions [`intersect_mt`] makes, done once).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleLanes {
    pub v0: [Vec4; 3],
    pub e1: [Vec4; 3],
    pub e2: [Vec4; 3],
}

impl TriangleLanes {
    /// The lanes of four triangles given by their vertices `v[j][a]`
    /// (coordinate `a` of vertex `j`, one lane per triangle).
    #[inline(always)]
    pub fn new(v: [[Vec4; 3]; 3]) -> Self {
        let [v0, v1, v2] = v;
        TriangleLanes {
            v0,
            e1: std::array::from_fn(|a| v1[a] - v0[a]),
            e2: std::array::from_fn(|a| v2[a] - v0[a]),
        }
    }
}

/// The hits of [`intersect_mt_lanes`]: bit `i` of `mask` says that lane `i`
/// is hit, at `t[i]` with barycentrics `b1[i]`, `b2[i]`.
#[derive(Clone, Copy, Debug)]
pub struct LaneHits {
    pub mask: u32,
    pub t: Vec4,
    pub b1: Vec4,
    pub b2: Vec4,
}

/// [`intersect_mt`] for four triangles at once (glam's `Vec4`: SSE on
/// x86-64), lane by lane with exactly the same operations in the same order
/// (glam's `dot` sums `(x + y) + z`; its `cross` forms `a_y·b_z − a_z·b_y`,
/// …; nothing is fused), so every lane gives bit for bit the hit and `t`
/// that `intersect_mt` gives for its triangle (barycentrics equal in value;
/// a clamped −0 may come out as +0).
///
/// The error allowances of the edge tests cost as much as the rest of the
/// test, and decide only lanes whose numerators lie within them of the
/// edge. So the lanes are first decided without allowances, and against
/// cheap upper bounds on them: with `‖·‖₁` the sum of magnitudes and
/// `‖d‖∞` the largest,
///
/// `(|d| ⊗ |E2|)·|S| ≤ ‖d‖∞·‖E2‖₁·‖S‖₁`, `(|S| ⊗ |E1|)·|d| ≤ ‖d‖∞·‖E1‖₁·‖S‖₁`,
/// `(|d| ⊗ |E2|)·|E1| ≤ ‖d‖∞·‖E1‖₁·‖E2‖₁`
///
/// (each term `|x_a|·|y_b|·|z_c|` of the left side is at most `‖d‖∞` times
/// a term of the product of the two sums), doubled to cover their own
/// rounding. A lane inside without allowances is inside with them; a
/// lane outside by more than the upper bounds is outside with them. Only
/// where some lane that could hit falls between the two are the exact
/// allowances computed, so the result is the same, bit for bit.
///
/// The work is staged so that a block of triangles is dropped as early as
/// its lanes allow: `t` first (a lane whose plane is not met within
/// `[t_min, t_max)` is out whatever its edges say, and often that is
/// every lane of a block), then the edge tests without
/// allowances, then the bounds only where a candidate lies outside. Lanes
/// not hit carry no meaningful `t` or barycentrics.
#[inline(always)]
pub fn intersect_mt_lanes(
    o: Vec3,
    d: Vec3,
    tri: &TriangleLanes,
    t_min: f32,
    t_max: f32,
) -> LaneHits {
    type V = [Vec4; 3];
    let sub = |a: &V, b: &V| -> V { [a[0] - b[0], a[1] - b[1], a[2] - b[2]] };
    let cross = |a: &V, b: &V| -> V {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let dot = |a: &V, b: &V| -> Vec4 { (a[0] * b[0] + a[1] * b[1]) + a[2] * b[2] };
    let splat = |v: Vec3| -> V { [Vec4::splat(v.x), Vec4::splat(v.y), Vec4::splat(v.z)] };
    let (v0, e1, e2) = (&tri.v0, tri.e1, tri.e2);
    let ray_d = d;
    let (o, d) = (&splat(o), &splat(d));
    let s1 = cross(d, &e2);
    let det = dot(&s1, &e1);
    let s = sub(o, v0);
    let s2 = cross(&s, &e1);
    let inv = det.recip();
    let t = dot(&s2, &e2) * inv;
    let valid = det.cmpne(Vec4::ZERO) & det.is_finite_mask();
    let in_range = t.cmpge(Vec4::splat(t_min)) & t.cmplt(Vec4::splat(t_max));
    let candidates = valid & in_range;
    let miss = || LaneHits {
        mask: 0,
        t,
        b1: Vec4::ZERO,
        b2: Vec4::ZERO,
    };
    // Lanes whose plane is not met within the interval are out whatever
    // the edge tests say, so the edge tests are skipped where none is
    // left.
    if !candidates.any() {
        return miss();
    }
    let sign = Vec4::ONE.copysign(det);
    let n1 = dot(&s1, &s) * sign;
    let n2 = dot(&s2, d) * sign;
    let det_abs = det.abs();
    let sum = n1 + n2;
    let strict_outside = n1.cmplt(Vec4::ZERO) | n2.cmplt(Vec4::ZERO) | sum.cmpgt(det_abs);
    // Only candidates outside without allowances may change with them.
    let outside = if (candidates & strict_outside).any() {
        // NaN bounds leave the lane undecided.
        let d_max = ray_d.abs().max_element();
        let [big1, big2, big_det] = allowance_bounds(d_max, &s, &e1, &e2);
        let loose_outside =
            n1.cmplt(-big1) | n2.cmplt(-big2) | sum.cmpgt(det_abs + big1 + big2 + big_det);
        if (candidates & strict_outside & !loose_outside).any() {
            let [err1, err2, err_det] = allowances(d, &s, &e1, &e2);
            n1.cmplt(-err1) | n2.cmplt(-err2) | sum.cmpgt(det_abs + err1 + err2 + err_det)
        } else {
            strict_outside
        }
    } else {
        strict_outside
    };
    let mask = (candidates & !outside).bitmask();
    if mask == 0 {
        return miss();
    }
    let inv_abs = inv.abs();
    LaneHits {
        mask,
        t,
        b1: (n1 * inv_abs).clamp(Vec4::ZERO, Vec4::ONE),
        b2: (n2 * inv_abs).clamp(Vec4::ZERO, Vec4::ONE),
    }
}

/// The error allowances of [`intersect_mt`]'s two numerators and of the
/// determinant, lane by lane, from the splatted direction `d`, `S` and the
/// edges: `γ(12)·(|d| ⊗ |E2|)·|S|`, `γ(12)·(|S| ⊗ |E1|)·|d|` and
/// `γ(12)·(|d| ⊗ |E2|)·|E1|`, with the same operations as the scalar test.
#[inline(always)]
fn allowances(d: &[Vec4; 3], s: &[Vec4; 3], e1: &[Vec4; 3], e2: &[Vec4; 3]) -> [Vec4; 3] {
    type V = [Vec4; 3];
    let dot = |a: &V, b: &V| -> Vec4 { (a[0] * b[0] + a[1] * b[1]) + a[2] * b[2] };
    let abs = |a: &V| -> V { [a[0].abs(), a[1].abs(), a[2].abs()] };
    // As `abs_cross`, on operands already made non-negative.
    let abs_cross = |a: &V, b: &V| -> V {
        [
            a[1] * b[2] + a[2] * b[1],
            a[2] * b[0] + a[0] * b[2],
            a[0] * b[1] + a[1] * b[0],
        ]
    };
    let g = Vec4::splat(gamma(12));
    let (d_abs, s_abs) = (abs(d), abs(s));
    let d_e2 = abs_cross(&d_abs, &abs(e2));
    [
        g * dot(&d_e2, &s_abs),
        g * dot(&abs_cross(&s_abs, &abs(e1)), &d_abs),
        g * dot(&d_e2, &abs(e1)),
    ]
}

/// Upper bounds on [`allowances`] from sums of magnitudes (see
/// [`intersect_mt_lanes`]), with `d_max = ‖d‖∞`: `γ(12)·2‖d‖∞·‖E2‖₁·‖S‖₁`,
/// `γ(12)·2‖d‖∞·‖E1‖₁·‖S‖₁` and `γ(12)·2‖d‖∞·‖E1‖₁·‖E2‖₁`. The products
/// are formed in an order whose every partial product bounds (twice over)
/// the partial products of the allowances, so that a bound overflows to
/// infinity wherever an allowance does (and an undefined product is NaN,
/// which decides nothing).
#[inline(always)]
fn allowance_bounds(d_max: f32, s: &[Vec4; 3], e1: &[Vec4; 3], e2: &[Vec4; 3]) -> [Vec4; 3] {
    let norm1 = |a: &[Vec4; 3]| (a[0].abs() + a[1].abs()) + a[2].abs();
    let (s_n, e1_n, e2_n) = (norm1(s), norm1(e1), norm1(e2));
    let (g, d_max) = (Vec4::splat(gamma(12)), Vec4::splat(d_max));
    // |d|·|E2| first, as the allowances of n1 and det form it.
    let d_e2 = (d_max + d_max) * e2_n;
    [
        d_e2 * s_n * g,
        // |S|·|E1| first, as the allowance of n2 forms it.
        (s_n + s_n) * e1_n * d_max * g,
        d_e2 * e1_n * g,
    ]
}

/// The watertight test of Woop, Benthin and Wald ("Watertight Ray/Triangle
/// Intersection", JCGT 2(1), 2013), as pbrt-v4 writes it: vertices are moved
/// into a frame where the ray is the +z axis (translate by −o, permute so that
/// the largest direction component is z, shear), and the 2D edge functions of
/// the projected triangle decide the hit. Edge functions that round to zero
/// are recomputed in f64, so that a ray through a shared edge or vertex is
/// never missed by both triangles. Returns also whether the hit lies exactly
/// on an edge (an edge function is zero), which [`super::Mesh::contains`] uses
/// to recast its ray.
#[inline]
pub fn intersect_watertight(
    o: Vec3,
    d: Vec3,
    v0: Vec3,
    v1: Vec3,
    v2: Vec3,
    t_min: f32,
    t_max: f32,
) -> Option<(TriangleHit, bool)> {
    let kz = d.abs().max_position();
    let kx = (kz + 1) % 3;
    let ky = (kx + 1) % 3;
    let permute = |v: Vec3| Vec3::new(v[kx], v[ky], v[kz]);
    let dp = permute(d);
    let (sx, sy, sz) = (-dp.x / dp.z, -dp.y / dp.z, 1.0 / dp.z);
    let shear = |v: Vec3| {
        let p = permute(v - o);
        Vec3::new(p.x + sx * p.z, p.y + sy * p.z, p.z)
    };
    let (p0, p1, p2) = (shear(v0), shear(v1), shear(v2));
    let mut e0 = p1.x * p2.y - p1.y * p2.x;
    let mut e1 = p2.x * p0.y - p2.y * p0.x;
    let mut e2 = p0.x * p1.y - p0.y * p1.x;
    if e0 == 0.0 || e1 == 0.0 || e2 == 0.0 {
        let f = |a: Vec3, b: Vec3| (a.x as f64 * b.y as f64 - a.y as f64 * b.x as f64) as f32;
        e0 = f(p1, p2);
        e1 = f(p2, p0);
        e2 = f(p0, p1);
    }
    if (e0 < 0.0 || e1 < 0.0 || e2 < 0.0) && (e0 > 0.0 || e1 > 0.0 || e2 > 0.0) {
        return None;
    }
    let det = e0 + e1 + e2;
    if det == 0.0 {
        return None;
    }
    let t_scaled = e0 * p0.z * sz + e1 * p1.z * sz + e2 * p2.z * sz;
    let t = t_scaled / det;
    if !(t >= t_min && t < t_max) {
        return None;
    }
    let on_edge = e0 == 0.0 || e1 == 0.0 || e2 == 0.0;
    Some((
        TriangleHit {
            t,
            b1: e1 / det,
            b2: e2 / det,
        },
        on_edge,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn four_lanes_match_the_scalar_test_bit_for_bit() {
        let mut rng = crate::render::Pcg32::new(17, 5);
        let mut point = |scale: f32| {
            Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 * scale
                - Vec3::splat(scale)
        };
        let (mut hits, mut edge_hits) = (0, 0);
        for round in 0..20_000 {
            // Random triangles, and triangles sharing an edge with a ray
            // aimed exactly at a point of that edge; some degenerate ones.
            let a = point(1.0);
            let b = point(1.0);
            let tris: [[Vec3; 3]; LANES] = std::array::from_fn(|i| match (round + i) % 4 {
                0 => [a, b, point(1.0)],
                1 => [b, a, point(1.0)],
                2 => [a, a, point(1.0)],
                _ => [point(1.0), point(1.0), point(1.0)],
            });
            let o = point(3.0);
            let target = if round % 2 == 0 {
                a.lerp(b, 0.37)
            } else {
                point(1.0)
            };
            let d = target - o;
            let lanes = TriangleLanes::new(std::array::from_fn(|j| {
                std::array::from_fn(|k| Vec4::from_array(std::array::from_fn(|i| tris[i][j][k])))
            }));
            let t_max = if round % 3 == 0 { 0.5 } else { f32::INFINITY };
            let h = intersect_mt_lanes(o, d, &lanes, 0.0, t_max);
            for (i, [v0, v1, v2]) in tris.iter().enumerate() {
                let scalar = intersect_mt(o, d, *v0, *v1, *v2, 0.0, t_max);
                assert_eq!(
                    h.mask & (1 << i) != 0,
                    scalar.is_some(),
                    "round {round} lane {i}"
                );
                if let Some(s) = scalar {
                    assert_eq!(h.t[i].to_bits(), s.t.to_bits());
                    // Equal values (the clamp may turn −0 into +0).
                    assert_eq!(h.b1[i], s.b1);
                    assert_eq!(h.b2[i], s.b2);
                    hits += 1;
                    if (round + i) % 4 < 2 && round % 2 == 0 {
                        edge_hits += 1;
                    }
                }
            }
        }
        // The cases above were exercised, not skipped.
        assert!(
            hits > 10_000 && edge_hits > 1_000,
            "{hits} hits, {edge_hits} on edges"
        );
    }

    /// The cheap bounds on the edge tests' allowances hold, for directions,
    /// edges and offsets of every scale and orientation (from where the
    /// products become subnormal to where they overflow), and are not
    /// vacuous: three in four bounds are within 20× of the exact allowance.
    #[test]
    fn allowance_bounds_hold_at_every_scale() {
        let mut rng = crate::render::Pcg32::new(3, 11);
        let vector = |rng: &mut crate::render::Pcg32| {
            let exponent = rng.next_f32() * 140.0 - 70.0;
            let scale = 2f32.powf(exponent);
            // Some components exactly zero, some tiny next to the others.
            let mut component = || match rng.next_f32() {
                u if u < 0.1 => 0.0,
                u if u < 0.2 => (rng.next_f32() - 0.5) * 1e-6,
                _ => rng.next_f32() * 2.0 - 1.0,
            };
            Vec3::new(component(), component(), component()) * scale
        };
        let lanes = |v: [Vec3; 4]| -> [Vec4; 3] {
            std::array::from_fn(|a| Vec4::from_array(std::array::from_fn(|i| v[i][a])))
        };
        let mut tight = [0; 3];
        for _ in 0..50_000 {
            let d = vector(&mut rng);
            let (s, e1, e2) = (
                lanes(std::array::from_fn(|_| vector(&mut rng))),
                lanes(std::array::from_fn(|_| vector(&mut rng))),
                lanes(std::array::from_fn(|_| vector(&mut rng))),
            );
            let dl = [Vec4::splat(d.x), Vec4::splat(d.y), Vec4::splat(d.z)];
            let exact = allowances(&dl, &s, &e1, &e2);
            let bound = allowance_bounds(d.abs().max_element(), &s, &e1, &e2);
            for k in 0..3 {
                for i in 0..4 {
                    // A bound that is not finite decides nothing (the exact
                    // allowances are then computed); a finite one must be at
                    // least the allowance, which must then be finite too.
                    assert!(
                        !bound[k][i].is_finite() || exact[k][i] <= bound[k][i],
                        "bound {k} lane {i}: {} against {} (d {d})",
                        bound[k][i],
                        exact[k][i]
                    );
                    if exact[k][i] > 0.0 && bound[k][i] <= 20.0 * exact[k][i] {
                        tight[k] += 1;
                    }
                }
            }
        }
        for (k, tight) in tight.into_iter().enumerate() {
            assert!(
                tight > 150_000,
                "{tight} of bound {k} within 20× of the allowance"
            );
        }
    }

    const V0: Vec3 = Vec3::new(0.0, 0.0, 0.0);
    const V1: Vec3 = Vec3::new(1.0, 0.0, 0.0);
    const V2: Vec3 = Vec3::new(0.0, 1.0, 0.0);

    #[test]
    fn hit_returns_t_and_barycentrics() {
        let h = intersect_mt(
            Vec3::new(0.25, 0.5, -2.0),
            Vec3::Z,
            V0,
            V1,
            V2,
            0.0,
            f32::INFINITY,
        )
        .unwrap();
        assert_eq!((h.t, h.b1, h.b2), (2.0, 0.25, 0.5));
        let (w, edge) = intersect_watertight(
            Vec3::new(0.25, 0.5, -2.0),
            Vec3::Z,
            V0,
            V1,
            V2,
            0.0,
            f32::INFINITY,
        )
        .unwrap();
        assert!(!edge);
        assert!(
            (w.t - 2.0).abs() < 1e-6 && (w.b1 - 0.25).abs() < 1e-6 && (w.b2 - 0.5).abs() < 1e-6
        );
    }

    #[test]
    fn misses_outside_behind_and_parallel() {
        let inf = f32::INFINITY;
        assert!(intersect_mt(Vec3::new(0.6, 0.6, -1.0), Vec3::Z, V0, V1, V2, 0.0, inf).is_none());
        assert!(intersect_mt(Vec3::new(0.2, 0.2, 1.0), Vec3::Z, V0, V1, V2, 0.0, inf).is_none());
        assert!(intersect_mt(Vec3::new(0.2, 0.2, 1.0), Vec3::X, V0, V1, V2, 0.0, inf).is_none());
        assert!(intersect_mt(Vec3::new(0.2, 0.2, -1.0), Vec3::Z, V0, V1, V2, 0.0, 0.5).is_none());
        assert!(
            intersect_watertight(Vec3::new(0.6, 0.6, -1.0), Vec3::Z, V0, V1, V2, 0.0, inf)
                .is_none()
        );
    }

    #[test]
    fn both_windings_are_hit() {
        let h = intersect_mt(
            Vec3::new(0.2, 0.2, -1.0),
            Vec3::Z,
            V0,
            V2,
            V1,
            0.0,
            f32::INFINITY,
        )
        .unwrap();
        assert_eq!(h.t, 1.0);
        assert!((h.b1 - 0.2).abs() < 1e-6 && (h.b2 - 0.2).abs() < 1e-6);
    }

    #[test]
    fn degenerate_triangle_is_never_hit() {
        // Collinear vertices: zero area.
        let o = Vec3::new(0.5, 0.0, -1.0);
        assert!(intersect_mt(o, Vec3::Z, V0, V1, V1 * 2.0, 0.0, f32::INFINITY).is_none());
        assert!(intersect_watertight(o, Vec3::Z, V0, V1, V1 * 2.0, 0.0, f32::INFINITY).is_none());
    }

    proptest! {
        /// Hit points lie in the triangle's plane, and MT agrees with the
        /// watertight test away from edges.
        #[test]
        fn mt_agrees_with_watertight(a in -1.0f32..1.0, b in -1.0f32..1.0, c in 0.1f32..3.0, ox in -2.0f32..2.0, oy in -2.0f32..2.0) {
            let (v0, v1, v2) = (Vec3::new(a, b, 0.3), Vec3::new(1.0, -0.5, c), Vec3::new(-0.7, 1.2, -0.4));
            let o = Vec3::new(ox, oy, -5.0);
            let d = Vec3::new(0.1, -0.05, 1.0);
            let mt = intersect_mt(o, d, v0, v1, v2, 0.0, f32::INFINITY);
            let wt = intersect_watertight(o, d, v0, v1, v2, 0.0, f32::INFINITY);
            match (mt, wt.map(|w| w.0)) {
                (Some(m), Some(w)) => {
                    prop_assert!((m.t - w.t).abs() <= 1e-4 * m.t.abs().max(1.0));
                    let p = o + d * m.t;
                    let n = (v1 - v0).cross(v2 - v0).normalize();
                    prop_assert!((p - v0).dot(n).abs() < 1e-4);
                }
                // They may disagree only at an edge.
                (Some(h), None) | (None, Some(h)) => {
                    prop_assert!(h.b1 < 1e-4 || h.b2 < 1e-4 || h.b1 + h.b2 > 1.0 - 1e-4, "{:?}", h);
                }
                (None, None) => {}
            }
        }
    }
}
