//! Implicit surfaces `f(x, y, z) = 0` from a formula a user types.
//!
//! The formula is parsed ([`parse`]), compiled once into a flat instruction
//! list ([`Tape`]) and evaluated three ways: as a value, over intervals, and
//! with derivatives by forward-mode automatic differentiation. A ray finds its
//! first root with [`roots::RaySearch`], inside the object's bounds, and the
//! normal is the normalised gradient. Inside is where `f < 0`.
//!
//! Scene file:
//!
//! ```toml
//! [[object]]
//! shape = "implicit"
//! f = "(x^2 + 9/4*y^2 + z^2 - 1)^3 - x^2*z^3 - 9/80*y^2*z^3"
//! bounds = [[-1.2, -0.75, -1.05], [1.2, 0.75, 1.3]]
//! transform = { rotate_x = -90, translate = [0, 1.05, 0] }
//! ```

mod parse;
pub mod roots;
mod tape;

pub use parse::{Expr, FormulaError, parse};
pub use tape::{Dual, MAX_TAPE, Scalar, Tape};

use super::{ShapeHit, SurfacePoint, TraceCounters};
use crate::math::{Aabb, Ray, Transform, gamma};
use glam::DVec3;
use roots::{RaySearch, Root};

/// The formula of the torus with major radius `R` and minor radius `r` around
/// the z axis: `(R − √(x² + y²))² + z² − r²`.
pub fn torus_formula(major: f64, minor: f64) -> String {
    format!("({major} - sqrt(x^2 + y^2))^2 + z^2 - {minor}^2")
}

/// The heart surface `(x² + 9y²/4 + z² − 1)³ − x²z³ − 9y²z³/80` (Taubin 1994),
/// z up, and a box that holds it.
pub const HEART_FORMULA: &str = "(x^2 + 9/4*y^2 + z^2 - 1)^3 - x^2*z^3 - 9/80*y^2*z^3";
pub const HEART_BOUNDS: [[f32; 3]; 2] = [[-1.2, -0.75, -1.05], [1.2, 0.75, 1.3]];

/// The most roots of an implicit surface that a shadow ray through it
/// (a transparent one) looks for; see [`Implicit::crossings`]. Formulas such
/// as `sin(100·x)` can cross a ray thousands of times, and every root costs
/// a search; 256 crossings attenuate light by far more than any image shows.
pub const MAX_SHADOW_CROSSINGS: usize = 256;

/// Why an implicit surface could not be built.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ImplicitError {
    #[error("{0}")]
    Formula(#[from] FormulaError),
    #[error("{0}")]
    TooLong(String),
}

/// An implicit surface `f = 0` inside `bounds` (object space), placed in the
/// world by `transform`.
#[derive(Clone, Debug, PartialEq)]
pub struct Implicit {
    pub formula: String,
    tape: Tape,
    min: DVec3,
    max: DVec3,
    transform: Transform,
    world_bounds: Aabb,
}

impl Implicit {
    pub fn new(formula: &str, bounds: Aabb, transform: Transform) -> Result<Self, ImplicitError> {
        let expr = parse(formula)?;
        let tape = Tape::compile(&expr).map_err(ImplicitError::TooLong)?;
        let (min, max) = (bounds.min.as_dvec3(), bounds.max.as_dvec3());
        let mut world_bounds = Aabb::EMPTY;
        for i in 0..8 {
            let corner = DVec3::new(
                if i & 1 == 0 { min.x } else { max.x },
                if i & 2 == 0 { min.y } else { max.y },
                if i & 4 == 0 { min.z } else { max.z },
            );
            let w = transform
                .world_from_object
                .transform_point3(corner)
                .as_vec3a();
            world_bounds = world_bounds.union(&Aabb::new(w, w));
        }
        Ok(Implicit {
            formula: formula.to_string(),
            tape,
            min,
            max,
            transform,
            world_bounds,
        })
    }

    pub fn bounds(&self) -> Aabb {
        self.world_bounds
    }

    pub fn tape(&self) -> &Tape {
        &self.tape
    }

    fn object_ray(&self, ray: &Ray) -> RaySearch<'_> {
        let m = &self.transform.object_from_world;
        RaySearch {
            tape: &self.tape,
            o: m.transform_point3(ray.o.as_dvec3()),
            d: m.transform_vector3(ray.d.as_dvec3()),
        }
    }

    /// The part of `[t_min, t_max)` inside the bounds (slab test in f64).
    fn clip(&self, s: &RaySearch, t_min: f64, t_max: f64) -> Option<(f64, f64)> {
        let (mut t0, mut t1) = (t_min, t_max);
        for k in 0..3 {
            let inv = 1.0 / s.d[k];
            let (near, far) = if inv >= 0.0 {
                (self.min[k], self.max[k])
            } else {
                (self.max[k], self.min[k])
            };
            let (tn, tf) = ((near - s.o[k]) * inv, (far - s.o[k]) * inv);
            if tn > t0 {
                t0 = tn;
            }
            if tf < t1 {
                t1 = tf;
            }
        }
        (t0 <= t1).then_some((t0, t1))
    }

    /// The first root in `[t_min, t_max)`. `ShapeHit::u` carries the part of
    /// the f64 root lost in rounding `t` to f32, so that [`Implicit::surface`]
    /// can rebuild the point to f64 precision.
    // Out of line: keeps the dispatch of the cheap shapes small in the hot loop.
    #[inline(never)]
    pub fn intersect(&self, ray: &Ray, counters: &mut TraceCounters) -> Option<ShapeHit> {
        if !self.world_bounds.hit_by(ray, ray.inv_d()) {
            return None;
        }
        let s = self.object_ray(ray);
        let (t0, t1) = self.clip(&s, ray.t_min as f64, ray.t_max as f64)?;
        counters.implicit_searches += 1;
        let before = counters.implicit_evaluations;
        let root = s.first_root(t0, t1, &mut counters.implicit_evaluations);
        counters.note_cut(before);
        let Root { t, .. } = root?;
        let t32 = t as f32;
        ray.contains(t32).then_some(ShapeHit {
            t: t32,
            prim: 0,
            u: (t - t32 as f64) as f32,
            v: 0.0,
        })
    }

    /// Whether anything of the surface lies on the ray's segment (any-hit, for
    /// shadow rays: no refinement of the root).
    // Out of line: keeps the dispatch of the cheap shapes small in the hot loop.
    #[inline(never)]
    pub fn occludes(&self, ray: &Ray, counters: &mut TraceCounters) -> bool {
        if !self.world_bounds.hit_by(ray, ray.inv_d()) {
            return false;
        }
        let s = self.object_ray(ray);
        // The f32 segment end, as an f64 bound that excludes t_max itself.
        let t_max = (ray.t_max as f64).next_down();
        match self.clip(&s, ray.t_min as f64, t_max) {
            Some((t0, t1)) => {
                counters.implicit_searches += 1;
                let before = counters.implicit_evaluations;
                let hit = s.has_root(t0, t1, &mut counters.implicit_evaluations);
                counters.note_cut(before);
                hit
            }
            None => false,
        }
    }

    /// The point, rebuilt from the f64 root, and the normal: the gradient of
    /// `f` by automatic differentiation, taken to world space by the inverse
    /// transpose. Where the gradient vanishes (the heart's cusps and the curve
    /// along its "equator", where `f = g³` near the surface), it gives no
    /// direction; the normal is then that of the plane through the hit and two
    /// nearby hits of rays parallel to this one (see `Implicit::fallback_normal`).
    // Out of line: keeps the dispatch of the cheap shapes small in the hot loop.
    #[inline(never)]
    pub fn surface(&self, ray: &Ray, hit: &ShapeHit) -> SurfacePoint {
        let s = self.object_ray(ray);
        let t = hit.t as f64 + hit.u as f64;
        let p_object = s.o + s.d * t;
        let g = self.gradient(p_object);
        let n_world = (self.transform.normal_to_world * g).normalize_or_zero();
        let n_world = if n_world != DVec3::ZERO && n_world.is_finite() {
            n_world
        } else {
            self.fallback_normal(&s, t)
        };
        let p = self.transform.world_from_object.transform_point3(p_object);
        let p32 = p.as_vec3a();
        // Rounding the f64 point to f32, plus the f32 ray parameter's share.
        let p_err = gamma(4) * (p32.abs() + (ray.d * hit.t).abs());
        SurfacePoint {
            p: p32,
            p_err,
            n: n_world.as_vec3a(),
            ns: n_world.as_vec3a(),
        }
    }

    /// ∇f at an object-space point, by forward-mode automatic differentiation.
    pub fn gradient(&self, p: DVec3) -> DVec3 {
        let g = self.tape.eval(
            Dual::new(p.x, [1.0, 0.0, 0.0]),
            Dual::new(p.y, [0.0, 1.0, 0.0]),
            Dual::new(p.z, [0.0, 0.0, 1.0]),
        );
        DVec3::from_array(g.d)
    }

    /// The normal at a point where ∇f = 0: two rays parallel to the original,
    /// offset by a millionth of the bounds' size across it, are intersected
    /// near the hit; the normal of the plane through the three hit points
    /// (oriented against the ray) is the surface's normal to within that
    /// distance. If they miss, the normal faces the ray.
    fn fallback_normal(&self, s: &RaySearch, t: f64) -> DVec3 {
        let facing = -(self.transform.normal_to_world * s.d).normalize_or(DVec3::Y);
        let size = (self.max - self.min).length();
        let delta = 1e-6 * size;
        let window = 1e-3 * size / s.d.length();
        let p0 = s.o + s.d * t;
        let (u, v) = s.d.normalize().any_orthonormal_pair();
        let nearby = |offset: DVec3| -> Option<DVec3> {
            let aux = RaySearch {
                tape: s.tape,
                o: s.o + offset,
                d: s.d,
            };
            let root = aux.first_root(t - window, t + window, &mut 0)?;
            Some(aux.o + aux.d * root.t - p0)
        };
        let side = |axis: DVec3| nearby(axis * delta).or_else(|| nearby(-axis * delta));
        let (Some(a), Some(b)) = (side(u), side(v)) else {
            return facing;
        };
        let n_object = a.cross(b);
        let n = (self.transform.normal_to_world * n_object).normalize_or_zero();
        if n == DVec3::ZERO {
            facing
        } else if n.dot(facing) < 0.0 {
            -n
        } else {
            n
        }
    }

    /// Calls `crossing` with `|cos θ|` at every root on the ray's segment, in
    /// `t` order, and returns the length of the segment inside (`f < 0`,
    /// judged between consecutive roots by the sign of `f` midway, so a
    /// segment that starts inside is measured right). At most
    /// [`MAX_SHADOW_CROSSINGS`] roots are searched for (each search costs an
    /// interval subdivision); past them the rest of the segment counts as
    /// one gap, and no more Fresnel factors are applied.
    // Out of line: keeps the dispatch of the cheap shapes small in the hot loop.
    #[inline(never)]
    pub fn crossings(
        &self,
        ray: &Ray,
        counters: &mut TraceCounters,
        crossing: &mut impl FnMut(f32),
    ) -> f32 {
        if !self.world_bounds.hit_by(ray, ray.inv_d()) {
            return 0.0;
        }
        let s = self.object_ray(ray);
        let Some((t0, t1)) = self.clip(&s, ray.t_min as f64, ray.t_max as f64) else {
            return 0.0;
        };
        counters.implicit_searches += 1;
        let d_world = ray.d.as_dvec3();
        let step = roots::RELATIVE_TOLERANCE * (t1 - t0).max(1e-300) * 4.0;
        let (mut start, mut previous, mut inside) = (t0, t0, 0.0);
        let mut count = 0;
        let mut add_gap = |a: f64, b: f64| {
            if s.f(0.5 * (a + b)) < 0.0 {
                inside += b - a;
            }
        };
        while count < MAX_SHADOW_CROSSINGS
            && let Some(r) = {
                let before = counters.implicit_evaluations;
                let root = s.first_root(start, t1, &mut counters.implicit_evaluations);
                counters.note_cut(before);
                root
            }
        {
            let n = self.transform.normal_to_world * self.gradient(s.o + s.d * r.t);
            let cos = n.normalize_or_zero().dot(d_world.normalize()).abs();
            crossing(cos as f32);
            add_gap(previous, r.t);
            previous = r.t;
            start = r.t + r.t_err.max(step);
            count += 1;
        }
        add_gap(previous, t1);
        (inside * d_world.length()) as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;

    fn unit_sphere() -> Implicit {
        Implicit::new(
            "x^2 + y^2 + z^2 - 1",
            Aabb::new(Vec3::splat(-1.5), Vec3::splat(1.5)),
            Transform::IDENTITY,
        )
        .unwrap()
    }

    #[test]
    fn sphere_hit_and_normal() {
        let s = unit_sphere();
        let r = Ray::new(Vec3::new(0.3, 0.2, -5.0), Vec3::Z);
        let h = s.intersect(&r, &mut TraceCounters::default()).unwrap();
        let (x, y) = (0.3f32 as f64, 0.2f32 as f64);
        let expected = 5.0 - (1.0 - x * x - y * y).sqrt();
        assert!(((h.t as f64 + h.u as f64) - expected).abs() < 1e-12);
        let sp = s.surface(&r, &h);
        assert!((sp.n - sp.p.normalize()).length() < 1e-6);
    }

    #[test]
    fn transformed_heart_is_hit_from_above() {
        let t = Transform::from_parts(
            DVec3::ONE,
            DVec3::new(-90.0, 0.0, 0.0),
            DVec3::new(0.0, 1.05, 0.0),
        )
        .unwrap();
        let heart = Implicit::new(
            HEART_FORMULA,
            Aabb::new(
                Vec3::from_array(HEART_BOUNDS[0]),
                Vec3::from_array(HEART_BOUNDS[1]),
            ),
            t,
        )
        .unwrap();
        // Straight down through the heart's top dimple region (x = 0.5 of a lobe).
        let r = Ray::new(Vec3::new(0.5, 5.0, 0.0), -Vec3::Y);
        let h = heart.intersect(&r, &mut TraceCounters::default()).unwrap();
        let sp = heart.surface(&r, &h);
        assert!(sp.p.y > 1.05 && sp.p.y < 1.05 + 1.3, "{:?}", sp.p);
        assert!(sp.n.y > 0.0, "{:?}", sp.n);
    }

    #[test]
    fn vanishing_gradient_uses_the_geometric_fallback() {
        // f = (x² + y² + z² − 1)³ has ∇f = 0 everywhere on its surface.
        let cube = Implicit::new(
            "(x^2 + y^2 + z^2 - 1)^3",
            Aabb::new(Vec3::splat(-1.5), Vec3::splat(1.5)),
            Transform::IDENTITY,
        )
        .unwrap();
        let r = Ray::new(Vec3::new(0.3, 0.4, -5.0), Vec3::Z);
        let h = cube.intersect(&r, &mut TraceCounters::default()).unwrap();
        let sp = cube.surface(&r, &h);
        assert!(
            (sp.n - sp.p.normalize()).length() < 1e-4,
            "{:?} vs {:?}",
            sp.n,
            sp.p.normalize()
        );
    }
}
