//! Ray–triangle intersection: Möller–Trumbore as the lecture gives it, and
//! the watertight test of Woop et al., scalar and four triangles at once,
//! which meshes use (it is watertight by construction, and a miss, the
//! common case, costs no division).

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

/// Triangles tested at once by [`intersect_watertight_lanes`].
pub const LANES: usize = 4;

/// Four triangles in structure-of-arrays form, one per lane: `v[j][a]`
/// holds coordinate `a` of every lane's vertex `j`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleLanes {
    pub v: [[Vec4; 3]; 3],
}

impl TriangleLanes {
    /// The lanes of four triangles given by their vertices `v[j][a]`
    /// (coordinate `a` of vertex `j`, one lane per triangle).
    #[inline(always)]
    pub fn new(v: [[Vec4; 3]; 3]) -> Self {
        TriangleLanes { v }
    }
}

/// The hits of [`intersect_watertight_lanes`]: bit `i` of `mask` says that
/// lane `i` is hit, at `t[i]` with barycentrics `b1[i]`, `b2[i]`.
#[derive(Clone, Copy, Debug)]
pub struct LaneHits {
    pub mask: u32,
    pub t: Vec4,
    pub b1: Vec4,
    pub b2: Vec4,
}

/// The per-ray constants of the watertight test ([`intersect_watertight`]):
/// the axis `kz` along which the direction is largest and the two after it
/// (`kx`, `ky`), the origin in that order, and the shear `(−d_x/d_z,
/// −d_y/d_z, 1/d_z)` of the permuted direction, which maps the ray onto
/// the +z axis. Made once per ray, shared by every triangle it is tested
/// against.
#[derive(Clone, Copy, Debug)]
pub struct RayShear {
    k: [usize; 3],
    o: Vec3,
    s: Vec3,
}

impl RayShear {
    #[inline(always)]
    pub fn new(o: Vec3, d: Vec3) -> Self {
        let kz = d.abs().max_position();
        let kx = (kz + 1) % 3;
        let ky = (kx + 1) % 3;
        let (dx, dy, dz) = (d[kx], d[ky], d[kz]);
        // The three quotients in one division (each lane rounded as alone).
        let s = Vec4::new(-dx, -dy, 1.0, 1.0) / Vec4::splat(dz);
        RayShear {
            k: [kx, ky, kz],
            o: Vec3::new(o[kx], o[ky], o[kz]),
            s: Vec3::new(s.x, s.y, s.z),
        }
    }

    /// The four triangles' vertices translated to the origin, permuted and
    /// sheared: `p[j] = [x, y, z]` of vertex `j` (z not yet scaled by
    /// `s_z`), as [`intersect_watertight`] makes them.
    #[inline(always)]
    fn shear_lanes(&self, tri: &TriangleLanes) -> [[Vec4; 3]; 3] {
        let [kx, ky, kz] = self.k;
        debug_assert!(kx < 3 && ky < 3 && kz < 3);
        let (ox, oy, oz) = (
            Vec4::splat(self.o.x),
            Vec4::splat(self.o.y),
            Vec4::splat(self.o.z),
        );
        let (sx, sy) = (Vec4::splat(self.s.x), Vec4::splat(self.s.y));
        std::array::from_fn(|j| {
            let v = &tri.v[j];
            // SAFETY: `new` makes every `k` below 3 (a position in a
            // `Vec3`, or one taken modulo 3), and nothing else writes them;
            // unchecked, the kernels keep no bounds checks per block.
            let at = |k: usize| unsafe { *v.get_unchecked(k) };
            let z = at(kz) - oz;
            [(at(kx) - ox) + sx * z, (at(ky) - oy) + sy * z, z]
        })
    }
}

/// An edge function `a_x·b_y − a_y·b_x` in f64, from the f32 coordinates
/// (whose products f64 holds exactly): the sign is exact where the f32
/// value rounded to zero.
#[inline(always)]
fn edge_f64(ax: f32, ay: f32, bx: f32, by: f32) -> f32 {
    (ax as f64 * by as f64 - ay as f64 * bx as f64) as f32
}

/// The edge functions `e` of the lanes in `zero` recomputed in f64 from the
/// sheared vertices, as [`intersect_watertight`] does. Rare (a ray exactly
/// through an edge or vertex, a degenerate triangle), so kept out of line,
/// off the kernels' hot code; it shears the vertices again (the same
/// operations, so the same values) rather than take them from the caller,
/// which would keep them in memory on the hot path.
#[cold]
#[inline(never)]
fn edges_f64(r: &RayShear, tri: &TriangleLanes, e: [Vec4; 3], zero: u32) -> [Vec4; 3] {
    let p = r.shear_lanes(tri);
    let mut lanes = e.map(|v| v.to_array());
    for i in (0..LANES).filter(|i| zero & 1 << i != 0) {
        let c = |j: usize, a: usize| p[j][a][i];
        lanes[0][i] = edge_f64(c(1, 0), c(1, 1), c(2, 0), c(2, 1));
        lanes[1][i] = edge_f64(c(2, 0), c(2, 1), c(0, 0), c(0, 1));
        lanes[2][i] = edge_f64(c(0, 0), c(0, 1), c(1, 0), c(1, 1));
    }
    lanes.map(Vec4::from_array)
}

/// [`intersect_watertight`] for four triangles at once (glam's `Vec4`: SSE
/// on x86-64), lane by lane with exactly the same operations in the same
/// order (nothing is fused), so every lane gives bit for bit the hit, `t`
/// and barycentrics that `intersect_watertight` gives for its triangle
/// (a clamped −0 may come out as +0).
///
/// The common case, a miss, costs the vertices' translation and shear and
/// the three edge functions, with no division: `t` and the barycentrics
/// are made (one reciprocal of the four determinants) only when some lane
/// is inside all three edges. Lanes not hit carry no meaningful `t` or
/// barycentrics.
#[inline(always)]
pub fn intersect_watertight_lanes(
    r: &RayShear,
    tri: &TriangleLanes,
    t_min: f32,
    t_max: f32,
) -> LaneHits {
    // Vertex j translated to the origin, permuted and sheared.
    let p = r.shear_lanes(tri);
    let edge = |a: &[Vec4; 3], b: &[Vec4; 3]| a[0] * b[1] - a[1] * b[0];
    let mut e = [edge(&p[1], &p[2]), edge(&p[2], &p[0]), edge(&p[0], &p[1])];
    let zero = e[0].cmpeq(Vec4::ZERO) | e[1].cmpeq(Vec4::ZERO) | e[2].cmpeq(Vec4::ZERO);
    let inside = |e: &[Vec4; 3]| {
        let neg = e[0].cmplt(Vec4::ZERO) | e[1].cmplt(Vec4::ZERO) | e[2].cmplt(Vec4::ZERO);
        let pos = e[0].cmpgt(Vec4::ZERO) | e[1].cmpgt(Vec4::ZERO) | e[2].cmpgt(Vec4::ZERO);
        !(neg & pos)
    };
    let miss = || LaneHits {
        mask: 0,
        t: Vec4::ZERO,
        b1: Vec4::ZERO,
        b2: Vec4::ZERO,
    };
    // A lane with an edge function of zero is decided by its f64 values,
    // which may differ in sign elsewhere too; the others by their f32 ones.
    if !(inside(&e) | zero).any() {
        return miss();
    }
    let zero = zero.bitmask();
    if zero != 0 {
        e = edges_f64(r, tri, e, zero);
    }
    let det = (e[0] + e[1]) + e[2];
    let candidates = inside(&e) & det.cmpne(Vec4::ZERO);
    if !candidates.any() {
        return miss();
    }
    let inv = det.recip();
    let b = [e[0] * inv, e[1] * inv, e[2] * inv];
    let t = ((b[0] * p[0][2] + b[1] * p[1][2]) + b[2] * p[2][2]) * Vec4::splat(r.s.z);
    let mask = (candidates & t.cmpge(Vec4::splat(t_min)) & t.cmplt(Vec4::splat(t_max))).bitmask();
    if mask == 0 {
        return miss();
    }
    LaneHits {
        mask,
        t,
        b1: b[1].clamp(Vec4::ZERO, Vec4::ONE),
        b2: b[2].clamp(Vec4::ZERO, Vec4::ONE),
    }
}

/// The watertight test of Woop, Benthin and Wald ("Watertight Ray/Triangle
/// Intersection", JCGT 2(1), 2013), as pbrt-v4 writes it: vertices are moved
/// into a frame where the ray is the +z axis (translate by −o, permute so that
/// the largest direction component is z, shear; see [`RayShear`]), and the
/// 2D edge functions `e_i = a_x·b_y − a_y·b_x` of the projected triangle
/// decide the hit: all three of one sign (zero counts as either), and
/// `det = e0 + e1 + e2 ≠ 0`. Then, with `b_i = e_i/det` and the z
/// coordinates scaled by `1/d_z`,
///
/// `t = b0·z0 + b1·z1 + b2·z2`,
///
/// the barycentrics first: the paper's `(e0·z0 + e1·z1 + e2·z2)/det` grows
/// as the cube of the mesh's size and overflows f32 past about 10¹²
/// (meshes that large rendered empty), where the edge functions and `det`,
/// squares of lengths, hold to about 10¹⁸.
///
/// Every vertex is transformed on its own, the same way whichever triangle
/// it belongs to, and an edge function is antisymmetric in its two
/// vertices bit for bit (`fl(a·b − c·d) = −fl(c·d − a·b)`; nothing is
/// fused), so the two triangles sharing an edge see exactly opposite values
/// for it: a ray that leaves one through the edge enters the other, and
/// one exactly on it (a zero) hits both. No ray slips through a closed mesh
/// at any scale the edge functions hold (sizes and distances from about
/// 10⁻¹⁶ to 10¹⁸, as the mesh tests check), with no allowance to tune.
/// Edge functions that round to zero are recomputed in f64 (exact
/// products), so that the zero is only taken where it is nearly exact.
/// Returns also whether the hit lies exactly on an edge (an edge function
/// is zero), which [`super::Mesh::contains`] uses to recast its ray.
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
    let r = RayShear::new(o, d);
    let [kx, ky, kz] = r.k;
    let shear = |v: Vec3| {
        let z = v[kz] - r.o.z;
        Vec3::new((v[kx] - r.o.x) + r.s.x * z, (v[ky] - r.o.y) + r.s.y * z, z)
    };
    let (p0, p1, p2) = (shear(v0), shear(v1), shear(v2));
    let mut e0 = p1.x * p2.y - p1.y * p2.x;
    let mut e1 = p2.x * p0.y - p2.y * p0.x;
    let mut e2 = p0.x * p1.y - p0.y * p1.x;
    if e0 == 0.0 || e1 == 0.0 || e2 == 0.0 {
        e0 = edge_f64(p1.x, p1.y, p2.x, p2.y);
        e1 = edge_f64(p2.x, p2.y, p0.x, p0.y);
        e2 = edge_f64(p0.x, p0.y, p1.x, p1.y);
    }
    if (e0 < 0.0 || e1 < 0.0 || e2 < 0.0) && (e0 > 0.0 || e1 > 0.0 || e2 > 0.0) {
        return None;
    }
    let det = (e0 + e1) + e2;
    if det == 0.0 {
        return None;
    }
    let inv = 1.0 / det;
    let (b0, b1, b2) = (e0 * inv, e1 * inv, e2 * inv);
    let t = ((b0 * p0.z + b1 * p1.z) + b2 * p2.z) * r.s.z;
    if !(t >= t_min && t < t_max) {
        return None;
    }
    let on_edge = e0 == 0.0 || e1 == 0.0 || e2 == 0.0;
    Some((
        TriangleHit {
            t,
            b1: b1.clamp(0.0, 1.0),
            b2: b2.clamp(0.0, 1.0),
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
            let h = intersect_watertight_lanes(&RayShear::new(o, d), &lanes, 0.0, t_max);
            for (i, [v0, v1, v2]) in tris.iter().enumerate() {
                let scalar = intersect_watertight(o, d, *v0, *v1, *v2, 0.0, t_max).map(|h| h.0);
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
            hits > 8_000 && edge_hits > 1_000,
            "{hits} hits, {edge_hits} on edges"
        );
    }

    /// Lanes against the scalar test where edge functions are exactly zero
    /// (rays along the z axis through the edges and vertices of a grid of
    /// triangles), so that the f64 recomputation decides: the same hits, `t`
    /// and barycentrics, and rays on shared edges hit at least one side.
    #[test]
    fn four_lanes_match_the_scalar_test_on_exact_edges() {
        // Two triangles per unit square of a 2×2 grid, at z = 1.
        let g = |x: f32, y: f32| Vec3::new(x, y, 1.0);
        let mut tris = Vec::new();
        for (x, y) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
            tris.push([g(x, y), g(x + 1.0, y), g(x + 1.0, y + 1.0)]);
            tris.push([g(x, y), g(x + 1.0, y + 1.0), g(x, y + 1.0)]);
        }
        let (mut on_edge, mut rays) = (0, 0);
        for i in 0..=8 {
            for j in 0..=8 {
                let o = Vec3::new(i as f32 * 0.25, j as f32 * 0.25, -2.0);
                let r = RayShear::new(o, Vec3::Z);
                let mut hit_any = false;
                for quad in tris.chunks(LANES) {
                    let lanes = TriangleLanes::new(std::array::from_fn(|v| {
                        std::array::from_fn(|k| {
                            Vec4::from_array(std::array::from_fn(|l| quad[l][v][k]))
                        })
                    }));
                    let h = intersect_watertight_lanes(&r, &lanes, 0.0, f32::INFINITY);
                    for (l, [v0, v1, v2]) in quad.iter().enumerate() {
                        let s = intersect_watertight(o, Vec3::Z, *v0, *v1, *v2, 0.0, f32::INFINITY);
                        assert_eq!(h.mask & (1 << l) != 0, s.is_some(), "ray {o} lane {l}");
                        if let Some((s, edge)) = s {
                            assert_eq!(h.t[l].to_bits(), s.t.to_bits());
                            assert_eq!((h.b1[l], h.b2[l]), (s.b1, s.b2));
                            assert_eq!(s.t, 3.0);
                            hit_any = true;
                            on_edge += edge as u32;
                        }
                    }
                }
                assert!(hit_any, "ray {o} slipped through the grid");
                rays += 1;
            }
        }
        assert_eq!(rays, 81);
        assert!(on_edge > 50, "{on_edge} hits on edges");
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
