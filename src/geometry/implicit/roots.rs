//! The first root of `f(o + t·d)` on `[t0, t1]`, found without skipping any.
//!
//! 1. Interval exclusion (Mitchell, "Robust Ray Intersection with Interval
//!    Arithmetic", Graphics Interface 1990): the interval extension `F(T)` of
//!    `t ↦ f(o + t·d)` encloses every value on the piece `T`; if `0 ∉ F(T)`,
//!    `T` holds no root and is discarded. Pieces are examined depth-first from
//!    the smallest `t`, so the first root found is the first root.
//! 2. Monotonicity: the same evaluation on interval dual numbers encloses the
//!    derivative `F′(T)`. If `0 ∉ F′(T)`, `f` is strictly monotonic on `T` and
//!    has a root there iff its endpoint values differ in sign; that root is
//!    then refined by safeguarded Newton–bisection to a few ulps.
//! 3. Otherwise `T` is split at its midpoint `m`, and the interval Newton
//!    step removes a gap around `m` that provably holds no root (from a
//!    rigorous enclosure of `f(m)` and `F′(T)`), down to a width of
//!    `RELATIVE_TOLERANCE` of the search range. A piece that small on which `F` still contains 0 either
//!    shows a sign change (a root of odd multiplicity, e.g. at a singular point
//!    where the gradient vanishes: refined by bisection), or not: then `f`
//!    only touches zero there (a root of even multiplicity, a ray tangent to
//!    the surface), and its midpoint is reported.
//!
//! What is guaranteed: no root of `f` on `[t0, t1]` is skipped (the exclusion
//! and monotonicity tests are conservative, with outward rounding), so there
//! are no holes. A ray that comes within a distance δ of the surface without
//! touching it is reported as a hit only if `|f|` along it stays within the
//! rounding error of the interval evaluation on pieces of the tolerance width
//! — far below 1e-4 for formulas of ordinary size. Where `f` is undefined (e.g.
//! `sqrt` of a negative number) there is no surface; a pole of `f` (division
//! by zero) where `f` changes sign is reported as a root.

use super::tape::{Dual, Tape};
use crate::math::Interval;
use glam::DVec3;

/// Smallest piece examined, relative to the length of the search range.
pub const RELATIVE_TOLERANCE: f64 = 1e-12;

/// Deepest subdivision: `2^-MAX_DEPTH` is below `RELATIVE_TOLERANCE`.
const MAX_DEPTH: usize = 48;

/// The most interval evaluations one root search may make. A formula whose
/// enclosures stay loose over many small pieces without a root (a sum of
/// terms that cancel, oscillating thousands of times across the bounds)
/// could otherwise cost millions per ray and hold a render for hours; past
/// this the search gives up and reports no root, and the render counts it
/// (`implicit_searches_cut`). Ordinary formulas take a few to a few hundred
/// (none of the heart-and-torus scene's searches needs 256).
pub const MAX_SEARCH_EVALUATIONS: u64 = 1024;

/// A root: the ray parameter and a bound on its error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Root {
    pub t: f64,
    pub t_err: f64,
}

/// `f` along the ray `o + t·d` (object space, f64).
pub struct RaySearch<'a> {
    pub tape: &'a Tape,
    pub o: DVec3,
    pub d: DVec3,
}

impl RaySearch<'_> {
    /// `f(o + t·d)`.
    #[inline]
    pub fn f(&self, t: f64) -> f64 {
        let p = self.o + self.d * t;
        self.tape.eval(p.x, p.y, p.z)
    }

    /// `f` and `df/dt` at `t`.
    #[inline]
    fn f_dt(&self, t: f64) -> (f64, f64) {
        let p = self.o + self.d * t;
        let v = |k: usize| Dual::new(p[k], [self.d[k]]);
        let r = self.tape.eval(v(0), v(1), v(2));
        (r.v, r.d[0])
    }

    /// Enclosures of `f` and `df/dt` over `t ∈ [a, b]`.
    #[inline]
    fn enclose(&self, a: f64, b: f64) -> (Interval, Interval) {
        let t = Interval::new(a, b);
        let v = |k: usize| {
            let x = Interval::point(self.o[k]) + t * Interval::point(self.d[k]);
            Dual::new(x, [Interval::point(self.d[k])])
        };
        let r = self.tape.eval(v(0), v(1), v(2));
        (r.v, r.d[0])
    }

    /// A rigorous enclosure of `f(o + t·d)` at the single parameter `t`
    /// (the point itself is enclosed with outward rounding).
    #[inline]
    fn enclose_at(&self, t: f64) -> Interval {
        let t = Interval::point(t);
        let v = |k: usize| Interval::point(self.o[k]) + t * Interval::point(self.d[k]);
        self.tape.eval(v(0), v(1), v(2))
    }

    /// The smallest root in `[t0, t1]`; `evaluations` counts the interval
    /// evaluations. `None` also if the search made
    /// [`MAX_SEARCH_EVALUATIONS`] (the caller tells by the count).
    pub fn first_root(&self, t0: f64, t1: f64, evaluations: &mut u64) -> Option<Root> {
        self.search(t0, t1, evaluations, true)
    }

    /// Whether `[t0, t1]` holds a root (for shadow rays): the same search,
    /// stopped as soon as a piece is known to hold one, without refining it.
    pub fn has_root(&self, t0: f64, t1: f64, evaluations: &mut u64) -> bool {
        self.search(t0, t1, evaluations, false).is_some()
    }

    /// With `refine == false`, the root returned is only known to lie in
    /// `[t, t + t_err]`.
    fn search(&self, t0: f64, t1: f64, evaluations: &mut u64, refine: bool) -> Option<Root> {
        if t0 > t1 || t0.is_nan() || t1.is_nan() {
            return None;
        }
        let tolerance = RELATIVE_TOLERANCE * (t1 - t0).max(t0.abs().max(t1.abs()) * 1e-3);
        let mut stack = [(0.0, 0.0); MAX_DEPTH * 2 + 2];
        stack[0] = (t0, t1);
        let mut len = 1;
        let budget_end = *evaluations + MAX_SEARCH_EVALUATIONS;
        while len > 0 {
            if *evaluations >= budget_end {
                return None;
            }
            len -= 1;
            let (a, b) = stack[len];
            *evaluations += 1;
            let (f, df) = self.enclose(a, b);
            if !f.contains(0.0) {
                continue;
            }
            if !df.contains(0.0) && !df.is_empty() {
                // Strictly monotonic: a root iff the endpoint values differ in sign.
                let (fa, fb) = (self.f(a), self.f(b));
                if fa == 0.0 {
                    return Some(Root { t: a, t_err: 0.0 });
                }
                if fa.signum() != fb.signum() && !fb.is_nan() {
                    return Some(if refine {
                        self.refine(a, b, fa)
                    } else {
                        Root { t: a, t_err: b - a }
                    });
                }
                continue;
            }
            let m = 0.5 * (a + b);
            if b - a <= tolerance || len + 2 > stack.len() || m <= a || m >= b {
                let (fa, fm, fb) = (self.f(a), self.f(m), self.f(b));
                if fa == 0.0 {
                    return Some(Root { t: a, t_err: 0.0 });
                }
                if fa * fm < 0.0 {
                    return Some(self.refine(a, m, fa));
                }
                if fm * fb < 0.0 {
                    return Some(self.refine(m, b, fm));
                }
                // No sign change on a piece this small on which F holds zero:
                // f touches zero (a root of even multiplicity).
                return Some(Root { t: m, t_err: b - a });
            }
            // Interval Newton with extended division (Hansen, "Global
            // Optimization Using Interval Analysis", §9.6): every t with
            // f(t) = 0 satisfies f(m) + (t − m)·f′(ξ) = 0 for some ξ ∈ [a, b],
            // so with f(m) ≥ v > 0 and F′ = [d₋, d₊] a root lies left of m only
            // if t ≤ m − v/d₊ (d₊ > 0), right of m only if t ≥ m + v/(−d₋)
            // (d₋ < 0); symmetrically for f(m) < 0. The gap around m holds no
            // root. With v = 0 (or F(m) ∋ 0) this is plain bisection.
            *evaluations += 1;
            let fm = self.enclose_at(m);
            let (mut left_end, mut right_start) = (m, m);
            if fm.lo > 0.0 || fm.hi < 0.0 {
                let (v, d_left, d_right) = if fm.lo > 0.0 {
                    (fm.lo, df.hi, -df.lo)
                } else {
                    (-fm.hi, -df.lo, df.hi)
                };
                // Rounded towards m, so the gap is never too wide.
                left_end = if d_left > 0.0 {
                    (m - v / d_left).next_up()
                } else {
                    a
                };
                right_start = if d_right > 0.0 {
                    (m + v / d_right).next_down()
                } else {
                    b
                };
            }
            if right_start < b {
                stack[len] = (right_start.max(a), b);
                len += 1;
            }
            if left_end > a {
                stack[len] = (a, left_end.min(b));
                len += 1;
            }
        }
        None
    }

    /// Safeguarded Newton–Raphson on a bracket `[a, b]` with `f(a) = fa` and
    /// `f(b)` of the opposite sign (`rtsafe`, Press et al., "Numerical
    /// Recipes", §9.4): a Newton step when it lands inside the bracket and at
    /// least halves the previous step (quadratic convergence near a simple
    /// root), a bisection otherwise (linear, guaranteed, also at multiple
    /// roots). Every evaluation shrinks the bracket. Stops when a step is a few
    /// ulps of `t`; the error bound is that step, or the bracket if smaller.
    fn refine(&self, mut a: f64, mut b: f64, fa: f64) -> Root {
        let a_negative = fa < 0.0;
        let mut t = 0.5 * (a + b);
        let mut step = b - a;
        let mut last_step = step;
        for _ in 0..200 {
            let (ft, dft) = self.f_dt(t);
            if ft == 0.0 {
                return Root { t, t_err: 0.0 };
            }
            if (ft < 0.0) == a_negative {
                a = t;
            } else {
                b = t;
            }
            let newton = t - ft / dft;
            let previous = last_step;
            last_step = step;
            if newton > a && newton < b && (newton - t).abs() * 2.0 <= previous.abs() {
                step = newton - t;
                t = newton;
            } else {
                step = 0.5 * (b - a);
                t = a + step;
            }
            let tolerance = 4.0 * f64::EPSILON * t.abs();
            if step.abs() <= tolerance || b - a <= tolerance || step.is_nan() {
                break;
            }
        }
        Root {
            t,
            t_err: (2.0 * step.abs()).min(b - a),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::parse::parse;
    use super::*;

    fn search(f: &str) -> Tape {
        Tape::compile(&parse(f).unwrap()).unwrap()
    }

    fn first(tape: &Tape, o: [f64; 3], d: [f64; 3], t0: f64, t1: f64) -> Option<Root> {
        let s = RaySearch {
            tape,
            o: DVec3::from(o),
            d: DVec3::from(d),
        };
        s.first_root(t0, t1, &mut 0)
    }

    #[test]
    fn finds_the_near_side_of_a_sphere() {
        let t = search("x^2 + y^2 + z^2 - 1");
        let r = first(&t, [0.0, 0.0, -5.0], [0.0, 0.0, 1.0], 0.0, 10.0).unwrap();
        assert!((r.t - 4.0).abs() < 1e-14, "{r:?}");
        let r = first(&t, [0.0, 0.0, 0.0], [0.0, 0.0, 1.0], 0.0, 10.0).unwrap();
        assert!((r.t - 1.0).abs() < 1e-14, "{r:?}");
        assert!(first(&t, [0.0, 1.01, -5.0], [0.0, 0.0, 1.0], 0.0, 10.0).is_none());
    }

    #[test]
    fn finds_a_tangent_root() {
        let t = search("x^2 + y^2 + z^2 - 1");
        let r = first(&t, [0.0, 1.0, -5.0], [0.0, 0.0, 1.0], 0.0, 10.0).unwrap();
        assert!((r.t - 5.0).abs() < 1e-6, "{r:?}");
        assert!(first(&t, [0.0, 1.0 + 1e-4, -5.0], [0.0, 0.0, 1.0], 0.0, 10.0).is_none());
    }

    #[test]
    fn finds_a_triple_root() {
        // (x − 1)³ changes sign at x = 1, where its derivative vanishes too.
        let t = search("(x - 1)^3");
        let r = first(&t, [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], 0.0, 3.0).unwrap();
        assert!((r.t - 1.0).abs() < 1e-12, "{r:?}");
    }

    #[test]
    fn undefined_regions_have_no_surface() {
        // sqrt(x) − 1 is undefined for x < 0 and zero at x = 1.
        let t = search("sqrt(x) - 1");
        let r = first(&t, [-3.0, 0.0, 0.0], [1.0, 0.0, 0.0], 0.0, 10.0).unwrap();
        assert!((r.t - 4.0).abs() < 1e-12, "{r:?}");
    }

    #[test]
    fn two_close_roots_are_not_merged() {
        // Roots at t = 1 and t = 1 + 1e-9: the first is found.
        let t = search("(x - 1) * (x - 1 - 1e-9)");
        let r = first(&t, [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], 0.0, 2.0).unwrap();
        assert!((r.t - 1.0).abs() < 5e-10, "{r:?}");
        let r = first(&t, [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], 1.0 + 5e-10, 2.0).unwrap();
        assert!((r.t - (1.0 + 1e-9)).abs() < 1e-12, "{r:?}");
    }

    #[test]
    fn high_frequency_oscillation_does_not_skip_roots() {
        // sin(50 x) has roots every π/50; the first after x = 0.01 is at π/50.
        let t = search("sin(50*x)");
        let r = first(&t, [0.01, 0.0, 0.0], [1.0, 0.0, 0.0], 0.0, 3.0).unwrap();
        assert!(
            (r.t + 0.01 - std::f64::consts::PI / 50.0).abs() < 1e-12,
            "{r:?}"
        );
    }
}
