//! Many rays against one analytic shape at a time (sphere, plane, box):
//! the rays in structure-of-arrays form, [`BATCH`] at a time, and per shape
//! a closest-hit and an any-hit test written without branches, so that the
//! compiler runs them 4, 8 or 16 rays to an instruction (see
//! [`crate::scene::Scene::intersect_batch`], which compiles them for the
//! widest vector unit the CPU has).
//!
//! Each lane does exactly the arithmetic of the shape's one-ray test, in the
//! same order (IEEE operations, no fused multiply–adds), so a ray gets the
//! same hit, bit for bit, either way; the tests below check it.

use super::{Cuboid, Plane, Sphere};
use crate::math::{Ray, Vec3};

/// Rays per batch.
pub const BATCH: usize = 64;

/// Lanes computed together: 16 f32 (one AVX-512 vector, two AVX2 ones).
const GROUP: usize = 16;

/// Up to [`BATCH`] rays, one array per component; lanes from `len` on
/// hold harmless copies and are ignored.
#[derive(Clone, Debug)]
pub struct RayBatch {
    pub len: usize,
    pub o: [[f32; BATCH]; 3],
    pub d: [[f32; BATCH]; 3],
    pub t_min: [f32; BATCH],
    pub t_max: [f32; BATCH],
}

impl RayBatch {
    /// The batch of `rays` (at most [`BATCH`]).
    pub fn new(rays: &[Ray]) -> Box<RayBatch> {
        let mut b = Box::new(RayBatch {
            len: 0,
            o: [[0.0; BATCH]; 3],
            d: [[1.0; BATCH]; 3],
            t_min: [0.0; BATCH],
            t_max: [0.0; BATCH],
        });
        b.fill(rays);
        b
    }

    /// The groups of [`GROUP`] lanes that hold rays (the lanes to compute:
    /// whole vectors, so that none is partly filled).
    #[inline(always)]
    pub fn groups(&self) -> usize {
        self.len.div_ceil(GROUP)
    }

    /// Ray `j` of the batch.
    #[inline]
    pub fn ray(&self, j: usize) -> Ray {
        Ray {
            o: Vec3::new(self.o[0][j], self.o[1][j], self.o[2][j]),
            d: Vec3::new(self.d[0][j], self.d[1][j], self.d[2][j]),
            t_min: self.t_min[j],
            t_max: self.t_max[j],
        }
    }

    /// Replaces the rays by `rays` (at most [`BATCH`]).
    pub fn fill(&mut self, rays: &[Ray]) {
        assert!(rays.len() <= BATCH, "{} rays in a batch", rays.len());
        self.len = rays.len();
        for (j, r) in rays.iter().enumerate() {
            [self.o[0][j], self.o[1][j], self.o[2][j]] = r.o.to_array();
            [self.d[0][j], self.d[1][j], self.d[2][j]] = r.d.to_array();
            self.t_min[j] = r.t_min;
            self.t_max[j] = r.t_max;
        }
    }
}

/// Sentinel object of a lane without a hit in [`Closest`].
pub const NO_HIT: u32 = u32::MAX;

/// The closest hits of a batch so far: `t` (the ray's `t_max` until a hit),
/// the object (or [`NO_HIT`]) and the shape's part (`ShapeHit::prim`).
#[derive(Clone, Debug)]
pub struct Closest {
    pub t: [f32; BATCH],
    pub object: [u32; BATCH],
    pub prim: [u32; BATCH],
}

impl Closest {
    /// No hits yet: `t` is each ray's `t_max`.
    pub fn start(rays: &RayBatch) -> Closest {
        Closest {
            t: rays.t_max,
            object: [NO_HIT; BATCH],
            prim: [0; BATCH],
        }
    }
}

/// `t ∈ [t_min, t_max)`, as [`Ray::contains`].
#[inline(always)]
fn contains(t: f32, t_min: f32, t_max: f32) -> bool {
    (t >= t_min) & (t < t_max)
}

/// A shape with a one-lane test for the batch tests: lane `j`'s hit as the
/// shape's `intersect` finds it on the ray's segment ending at `t_max`,
/// `(hit, t, prim)` (`t` and `prim` meaningless without a hit), in
/// straight-line code the compiler can run on many lanes at once.
pub trait Lanes {
    fn lane(&self, rays: &RayBatch, j: usize, t_max: f32) -> (bool, f32, u32);

    /// Whether lane `j`'s line certainly misses the shape (so `lane` has no
    /// hit there), by a test cheaper than `lane`: whole groups of lanes
    /// that miss are skipped. Never, unless a shape says otherwise.
    #[inline(always)]
    fn misses(&self, _rays: &RayBatch, _j: usize) -> bool {
        false
    }
}

impl<T: Lanes + ?Sized> Lanes for &T {
    #[inline(always)]
    fn lane(&self, rays: &RayBatch, j: usize, t_max: f32) -> (bool, f32, u32) {
        (**self).lane(rays, j, t_max)
    }

    #[inline(always)]
    fn misses(&self, rays: &RayBatch, j: usize) -> bool {
        (**self).misses(rays, j)
    }
}

/// Calls `group(first)` with the first lane of each group of lanes of the
/// batch that `shape` may meet (whole groups of [`GROUP`] lanes).
#[inline(always)]
fn for_groups_met(shape: &impl Lanes, rays: &RayBatch, mut group: impl FnMut(usize)) {
    for g in 0..BATCH / GROUP {
        if g >= rays.groups() {
            break;
        }
        let first = g * GROUP;
        let mut all_miss = true;
        for j in first..first + GROUP {
            all_miss &= shape.misses(rays, j);
        }
        if !all_miss {
            group(first);
        }
    }
}

/// Calls `lane(j)` for each lane `j` of the groups of lanes of the batch
/// that `shape` may meet (the loops over a group's lanes have a fixed count
/// and bounds the compiler can see, so they are vectorised).
#[inline(always)]
fn for_lanes_met(shape: &impl Lanes, rays: &RayBatch, mut lane: impl FnMut(usize)) {
    for_groups_met(
        shape,
        rays,
        #[inline(always)]
        |first| {
            for j in first..first + GROUP {
                lane(j);
            }
        },
    );
}

/// The shape's `intersect` for every ray of the batch, keeping the closer
/// of its hit and `best`'s (which it updates for object `object`).
#[inline(always)]
pub fn closest_batch(shape: &impl Lanes, rays: &RayBatch, best: &mut Closest, object: u32) {
    for_lanes_met(shape, rays, |j| {
        let (hit, t, prim) = shape.lane(rays, j, best.t[j]);
        best.t[j] = if hit { t } else { best.t[j] };
        best.object[j] = if hit { object } else { best.object[j] };
        best.prim[j] = if hit { prim } else { best.prim[j] };
    });
}

/// [`Shape::occludes`](super::Shape::occludes) for every ray of the batch.
#[inline(always)]
pub fn any_batch(shape: &impl Lanes, rays: &RayBatch, hit: &mut [bool; BATCH]) {
    hit.fill(false);
    for_lanes_met(shape, rays, |j| {
        hit[j] = shape.lane(rays, j, rays.t_max[j]).0
    });
}

/// Marks the lanes of the batch whose segment the shape occludes
/// ([`Shape::occludes`](super::Shape::occludes)) with `index`, where
/// `blocked` has no mark yet (0).
#[inline(always)]
pub fn block_batch(shape: &impl Lanes, rays: &RayBatch, index: u32, blocked: &mut [u32; BATCH]) {
    for_lanes_met(shape, rays, |j| {
        let hit = shape.lane(rays, j, rays.t_max[j]).0;
        blocked[j] = if hit & (blocked[j] == 0) {
            index
        } else {
            blocked[j]
        };
    });
}

/// [`Sphere::roots`] for lane `j` as f32 (as its callers round them); the
/// same operations, with selects for its early returns. Where the line
/// misses (`Δ < 0`), `√Δ` is NaN and so are both roots, which no segment
/// contains: no test of `Δ` is needed.
#[inline(always)]
fn sphere_roots(s: &Sphere, rays: &RayBatch, j: usize) -> (f32, f32) {
    let (f, d, a, discriminant) = sphere_discriminant(s, rays, j);
    let r = s.radius as f64;
    let b = f[0] * d[0] + f[1] * d[1] + f[2] * d[2];
    let q = -(b + discriminant.sqrt().copysign(b));
    let cc = (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]) - r * r;
    let (t0, t1) = (q / a, cc / q);
    let (t0, t1) = if q == 0.0 {
        (0.0, 0.0)
    } else if t0 <= t1 {
        (t0, t1)
    } else {
        (t1, t0)
    };
    (t0 as f32, t1 as f32)
}

/// The first steps of [`Sphere::roots`] for lane `j`: the origin
/// relative to the centre `f`, the direction `d`, `a = d·d`, and the
/// discriminant `Δ = a·r² − |f × d|²` (the line misses where `Δ < 0`).
#[inline(always)]
fn sphere_discriminant(s: &Sphere, rays: &RayBatch, j: usize) -> ([f64; 3], [f64; 3], f64, f64) {
    let (c, r) = (s.center.as_dvec3(), s.radius as f64);
    let f = [
        rays.o[0][j] as f64 - c.x,
        rays.o[1][j] as f64 - c.y,
        rays.o[2][j] as f64 - c.z,
    ];
    let d = [
        rays.d[0][j] as f64,
        rays.d[1][j] as f64,
        rays.d[2][j] as f64,
    ];
    let a = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    let x = [
        f[1] * d[2] - f[2] * d[1],
        f[2] * d[0] - f[0] * d[2],
        f[0] * d[1] - f[1] * d[0],
    ];
    let discriminant = a * (r * r) - (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
    (f, d, a, discriminant)
}

impl Lanes for Sphere {
    /// The same operations as [`Sphere::roots`] and [`Sphere::intersect`],
    /// with selects for their early returns.
    #[inline(always)]
    fn lane(&self, rays: &RayBatch, j: usize, t_max: f32) -> (bool, f32, u32) {
        let (t0, t1) = sphere_roots(self, rays, j);
        let t_min = rays.t_min[j];
        let (in0, in1) = (contains(t0, t_min, t_max), contains(t1, t_min, t_max));
        (in0 | in1, if in0 { t0 } else { t1 }, 0)
    }

    /// The line certainly misses the sphere: `Δ < 0` as [`Sphere::roots`]
    /// computes it, decided in f32 ([`sphere_misses_f32`]).
    #[inline(always)]
    fn misses(&self, rays: &RayBatch, j: usize) -> bool {
        sphere_misses_f32(
            self.center.to_array(),
            self.radius,
            [rays.o[0][j], rays.o[1][j], rays.o[2][j]],
            [rays.d[0][j], rays.d[1][j], rays.d[2][j]],
        )
    }
}

/// Relative error bound of [`sphere_misses_f32`]'s discriminant: 32 units
/// of f32 rounding (2⁻²⁴ each), about 1.3 times what the analysis there
/// needs.
const SPHERE_MISS_MARGIN: f32 = 32.0 / 16_777_216.0;

/// Whether the line `o + t·d` certainly misses the sphere of centre `c` and
/// radius `r`: whether the discriminant `Δ = a·r² − |f × d|²` of
/// [`Sphere::roots`] (`f = o − c`, `a = d·d`, in f64) is negative, decided
/// from the same formula in f32, half the work per lane. Only certain
/// misses say so: the f32 value `Δ′` must be below `−m`, with `m` a bound
/// on `|Δ′ − Δ|`. With `u = 2⁻²⁴` (Higham, "Accuracy and Stability of
/// Numerical Algorithms", §3.1): `a·r²` has relative error ≤ 5u; each
/// component of `f × d`, from the rounded `f`, absolute error ≤ 3u·m_i with
/// `m_i = |f_j d_k| + |f_k d_j|`, so its square ≤ 6u·m_i² + O(u²), and
/// `Σ m_i² ≤ 2|f|²|d|²`; summing the squares adds 4u, the last subtraction
/// u. So `|Δ′ − Δ| ≤ 7u·a r² + 18u·|f|²|d|²` (f64's own error is 2²⁹ times
/// smaller), and `m = 32u·(a r² + |f|² a)` covers it, with
/// `f32::MIN_POSITIVE` added for results that underflow (where the relative
/// bounds fail: by less than 2⁻¹⁴⁹ per operation). A NaN or infinite value
/// anywhere gives `false`: the lane is left to the f64 test.
#[inline(always)]
pub(crate) fn sphere_misses_f32(c: [f32; 3], r: f32, o: [f32; 3], d: [f32; 3]) -> bool {
    let f = [o[0] - c[0], o[1] - c[1], o[2] - c[2]];
    let a = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    let x = [
        f[1] * d[2] - f[2] * d[1],
        f[2] * d[0] - f[0] * d[2],
        f[0] * d[1] - f[1] * d[0],
    ];
    let ff = f[0] * f[0] + f[1] * f[1] + f[2] * f[2];
    let ar2 = a * (r * r);
    let discriminant = ar2 - (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
    let margin = SPHERE_MISS_MARGIN * (ar2 + ff * a) + f32::MIN_POSITIVE;
    discriminant < -margin
}

/// For every ray of the batch, the product of the Fresnel transmittances
/// (light entering glass of index `ior` from outside, at the angle of
/// incidence) of the crossings of the sphere's surface by the ray's
/// segment, 1 where it crosses none: what [`Sphere::crossings`] hands to
/// the shadow-ray code, in the same operations and order, multiplied
/// together (multiplying by 1 is exact).
#[inline(always)]
pub fn sphere_glass_lanes(s: &Sphere, ior: f32, rays: &RayBatch, passed: &mut [f32; BATCH]) {
    let sphere = (s.center.to_array(), s.radius);
    passed.fill(1.0);
    for_groups_met(
        s,
        rays,
        #[inline(always)]
        |first| {
            // Two loops, each of which the compiler vectorises: the roots
            // (in f64), then the crossings (in f32).
            let mut roots = [(0.0, 0.0); GROUP];
            for (k, r) in roots.iter_mut().enumerate() {
                *r = sphere_roots(s, rays, first + k);
            }
            for (k, &(t0, t1)) in roots.iter().enumerate() {
                let j = first + k;
                let d = [rays.d[0][j], rays.d[1][j], rays.d[2][j]];
                let o = [rays.o[0][j], rays.o[1][j], rays.o[2][j]];
                let d_len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                let (t_min, t_max) = (rays.t_min[j], rays.t_max[j]);
                let (in0, f0) = glass_crossing(sphere, o, d, d_len, t0, t_min, t_max, ior);
                let (in1, f1) = glass_crossing(sphere, o, d, d_len, t1, t_min, t_max, ior);
                // 1·T₀ = T₀ exactly: the product as the one-ray code forms it.
                let p = if in0 { f0 } else { 1.0 };
                passed[j] = if in1 { p * f1 } else { p };
            }
        },
    );
}

/// Whether the segment `[t_min, t_max)` of the ray `o + t·d` (`d_len =
/// |d|`) contains `t`, a root of the glass sphere of centre `c` and radius
/// `radius` and index `ior`, and the Fresnel transmittance there, as
/// [`Sphere::crossings`] computes it. (The centre comes as an array: a
/// `Vec3A` loaded in the loop would keep it from being vectorised.)
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn glass_crossing(
    (c, radius): ([f32; 3], f32),
    o: [f32; 3],
    d: [f32; 3],
    d_len: f32,
    t: f32,
    t_min: f32,
    t_max: f32,
    ior: f32,
) -> (bool, f32) {
    // The unit normal there, as `(ray.at(t) − c) / r`.
    let n = [
        (o[0] + d[0] * t - c[0]) / radius,
        (o[1] + d[1] * t - c[1]) / radius,
        (o[2] + d[2] * t - c[2]) / radius,
    ];
    let cos = ((n[0] * d[0] + n[1] * d[1] + n[2] * d[2]) / d_len)
        .abs()
        .min(1.0);
    (
        contains(t, t_min, t_max),
        fresnel_transmittance_lane(cos, ior),
    )
}

/// [`fresnel_dielectric`](crate::shading::fresnel_dielectric)`(cos_i, 1,
/// eta_t).transmittance` in the same operations, its early return (total
/// internal reflection or grazing light: 0) a select.
#[inline(always)]
fn fresnel_transmittance_lane(cos_i: f32, eta_t: f32) -> f32 {
    let eta_i = 1.0f32;
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin_t = eta_i / eta_t * (1.0 - cos_i * cos_i).sqrt();
    let cos_t = (1.0 - sin_t * sin_t).sqrt();
    let (ii, tt) = (eta_i * cos_i, eta_t * cos_t);
    let (it, ti) = (eta_i * cos_t, eta_t * cos_i);
    let t_s = 2.0 * ii / (ii + tt);
    let t_p = 2.0 * ii / (ti + it);
    let t = tt / ii * 0.5 * (t_s * t_s + t_p * t_p);
    if (sin_t >= 1.0) | (cos_i == 0.0) {
        0.0
    } else {
        t
    }
}

impl Lanes for Plane {
    /// The same operations as [`Plane::intersect`].
    #[inline(always)]
    fn lane(&self, rays: &RayBatch, j: usize, t_max: f32) -> (bool, f32, u32) {
        let (p, n) = (self.point, self.normal);
        let denom = rays.d[0][j] * n.x + rays.d[1][j] * n.y + rays.d[2][j] * n.z;
        let rel = [p.x - rays.o[0][j], p.y - rays.o[1][j], p.z - rays.o[2][j]];
        let t = (rel[0] * n.x + rel[1] * n.y + rel[2] * n.z) / denom;
        ((denom != 0.0) & contains(t, rays.t_min[j], t_max), t, 0)
    }
}

impl Lanes for Cuboid {
    /// [`Cuboid::intersect`]: the slab test of [`crate::math::Aabb::slab`]
    /// with selects.
    #[inline(always)]
    fn lane(&self, rays: &RayBatch, j: usize, t_max: f32) -> (bool, f32, u32) {
        let (lo, hi) = (self.bounds.min.to_array(), self.bounds.max.to_array());
        let mut t_enter = f32::NEG_INFINITY;
        let mut t_exit = f32::INFINITY;
        let (mut axis_enter, mut axis_exit) = (0u32, 0u32);
        for i in 0..3 {
            let inv_d = 1.0 / rays.d[i][j];
            let o = rays.o[i][j];
            let (near, far) = if inv_d >= 0.0 {
                (lo[i], hi[i])
            } else {
                (hi[i], lo[i])
            };
            let t_near = (near - o) * inv_d;
            let t_far = (far - o) * inv_d;
            let enters = t_near > t_enter;
            t_enter = if enters { t_near } else { t_enter };
            axis_enter = if enters { i as u32 } else { axis_enter };
            let exits = t_far < t_exit;
            t_exit = if exits { t_far } else { t_exit };
            axis_exit = if exits { i as u32 } else { axis_exit };
        }
        let slab = (t_enter < t_exit) & (t_exit >= 0.0);
        let t_min = rays.t_min[j];
        let (enter, exit) = (
            contains(t_enter, t_min, t_max),
            contains(t_exit, t_min, t_max),
        );
        (
            slab & (enter | exit),
            if enter { t_enter } else { t_exit },
            if enter { axis_enter } else { 3 + axis_exit },
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Shape, ShapeHit, TraceCounters};
    use crate::math::Vec3;
    use crate::render::Pcg32;
    use crate::shading::fresnel_dielectric;

    /// Rays of every kind the renderer makes against the shape: from far
    /// away, from the surface (origins just off it), from inside, grazing,
    /// axis-parallel (zero direction components), and shadow segments.
    fn rays(rng: &mut Pcg32, n: usize, around: Vec3, size: f32) -> Vec<Ray> {
        let mut v = |s: f32| (rng.next_f32() * 2.0 - 1.0) * s;
        (0..n)
            .map(|k| {
                let o = around + Vec3::new(v(size * 3.0), v(size * 3.0), v(size * 3.0));
                let target = around + Vec3::new(v(size), v(size), v(size));
                let mut d = target - o;
                if k % 7 == 0 {
                    d.x = 0.0;
                }
                if k % 11 == 0 {
                    d = Vec3::new(0.0, d.y, 0.0);
                }
                if d == Vec3::ZERO {
                    d = Vec3::Y;
                }
                let mut r = Ray::new(o, d);
                if k % 3 == 0 {
                    r.t_max = v(1.0).abs() * 2.0;
                }
                if k % 5 == 0 {
                    r.t_min = v(1.0).abs();
                }
                r
            })
            .collect()
    }

    /// The f32 miss test of the sphere groups claims a miss only where the
    /// f64 discriminant of [`Sphere::roots`] is negative: on lines passing
    /// the surface at relative distances from 10⁻¹ down to 10⁻⁹ (below f32's
    /// precision), from near and far, with spheres from 10⁻¹⁵ to 10¹⁵ across
    /// and directions of any length. And it does find the clear misses.
    #[test]
    fn sphere_f32_miss_test_claims_only_certain_misses() {
        let mut rng = Pcg32::new(5, 9);
        let mut u = || rng.next_f32() * 2.0 - 1.0;
        let (mut clear, mut found) = (0, 0);
        for k in 0..400_000u32 {
            let scale = 10f32.powi((k % 31) as i32 - 15);
            let c = Vec3::new(u(), u(), u()) * scale * 4.0;
            let r = scale * (0.05 + u().abs());
            let d = Vec3::new(u(), u(), u());
            let d = if d == Vec3::ZERO { Vec3::X } else { d } * 10f32.powi((k % 5) as i32 - 2);
            let side = d.normalize().any_orthonormal_vector();
            let gap = u() * 10f32.powi(-((k % 9) as i32 + 1));
            let foot = c + side * (r * (1.0 + gap));
            let reach = if k % 2 == 0 { 100.0 * scale } else { 8.0 * r };
            let o = foot - d * (u() * reach / d.length());
            if !(o.is_finite() && d.is_finite()) {
                continue;
            }
            let sphere = Sphere::new(c, r);
            let ray = Ray::new(o, d);
            let says_miss = sphere_misses_f32(c.to_array(), r, o.to_array(), d.to_array());
            assert!(
                !says_miss || sphere.roots(&ray).is_none(),
                "claimed a miss of {sphere:?} by {ray:?} (gap {gap:e})"
            );
            // (Where the origin is far away for the sphere's size, rounding
            // `o − c` in f32 leaves too little of `|f × d|` to be sure; where
            // `a·r²` is near f32's smallest normal number, underflow does.)
            let normal = d.length_squared() * (r * r) > 1e-30;
            if gap > 1e-3 && (o - c).length() < 10.0 * r && normal {
                clear += 1;
                found += says_miss as u32;
            }
        }
        // Every line passing outside by 0.1 % or more, from within ten radii,
        // is a clear miss.
        assert!(clear > 5_000 && found == clear, "{found} of {clear}");
        let nan = [f32::NAN, 0.0, 0.0];
        assert!(!sphere_misses_f32([0.0; 3], 1.0, nan, [1.0, 0.0, 0.0]));
        let far = [0.0, f32::MAX, 0.0];
        assert!(!sphere_misses_f32([0.0; 3], 1.0, far, [f32::MAX, 0.0, 0.0]));
    }

    /// Each lane of the batch tests gives what the one-ray test gives.
    fn check(shape: &Shape, around: Vec3, size: f32) {
        let mut rng = Pcg32::new(11, 3);
        let mut counters = TraceCounters::default();
        for _ in 0..200 {
            let rs = rays(&mut rng, BATCH, around, size);
            let batch = RayBatch::new(&rs);
            let mut best = Closest::start(&batch);
            let mut any = [false; BATCH];
            let mut run = |s: &dyn Lanes| {
                closest_batch(&s, &batch, &mut best, 7);
                any_batch(&s, &batch, &mut any);
            };
            match shape {
                Shape::Sphere(s) => run(s),
                Shape::Plane(s) => run(s),
                Shape::Cuboid(s) => run(s),
                _ => unreachable!(),
            }
            for (j, r) in rs.iter().enumerate() {
                let one = shape.intersect(r, &mut counters);
                let lanes = (best.object[j] == 7).then_some(ShapeHit {
                    t: best.t[j],
                    prim: best.prim[j],
                    ..ShapeHit::default()
                });
                assert_eq!(
                    one.map(|h| (h.t.to_bits(), h.prim)),
                    lanes.map(|h| (h.t.to_bits(), h.prim)),
                    "{} {r:?}",
                    shape.name()
                );
                assert_eq!(any[j], shape.occludes(r, &mut counters), "{r:?}");
                if one.is_none() {
                    assert_eq!(best.t[j].to_bits(), r.t_max.to_bits());
                }
            }
            if let Shape::Sphere(s) = shape {
                // What a glass sphere lets through: the product of the
                // transmittances of the crossings the one-ray code finds.
                let mut passed = [0.0; BATCH];
                sphere_glass_lanes(s, 1.5, &batch, &mut passed);
                for (j, r) in rs.iter().enumerate() {
                    let mut one = 1.0f32;
                    shape.crossings(r, &mut counters, &mut |cos| {
                        one *= fresnel_dielectric(cos, 1.0, 1.5).transmittance;
                    });
                    assert_eq!(one.to_bits(), passed[j].to_bits(), "{r:?}");
                }
            }
        }
    }

    #[test]
    fn sphere_lanes_are_the_one_ray_test() {
        check(
            &Shape::Sphere(Sphere::new(Vec3::new(0.3, 1.0, -2.0), 0.85)),
            Vec3::new(0.3, 1.0, -2.0),
            1.0,
        );
        // Small in the rays' box: most groups of lanes miss it whole.
        check(
            &Shape::Sphere(Sphere::new(Vec3::new(0.3, 1.0, -2.0), 0.05)),
            Vec3::new(0.3, 1.0, -2.0),
            1.0,
        );
        // Far from the origin, small: rounding differs most there.
        check(
            &Shape::Sphere(Sphere::new(Vec3::new(1e3, -5e2, 7e2), 1e-2)),
            Vec3::new(1e3, -5e2, 7e2),
            1e-2,
        );
    }

    #[test]
    fn plane_lanes_are_the_one_ray_test() {
        check(
            &Shape::Plane(Plane::new(
                Vec3::new(0.0, -1.0, 0.0),
                Vec3::new(0.2, 1.0, 0.1),
            )),
            Vec3::ZERO,
            2.0,
        );
        check(
            &Shape::Plane(Plane::new(Vec3::ZERO, Vec3::Y)),
            Vec3::ZERO,
            2.0,
        );
    }

    #[test]
    fn box_lanes_are_the_one_ray_test() {
        let b = Cuboid::new(Vec3::new(-4.0, -0.02, -4.0), Vec3::new(4.0, 0.0, 12.0));
        check(&Shape::Cuboid(b), Vec3::new(0.0, 0.0, 4.0), 5.0);
        let b = Cuboid::new(Vec3::splat(-1.0), Vec3::splat(1.0));
        check(&Shape::Cuboid(b), Vec3::ZERO, 1.0);
    }
}
