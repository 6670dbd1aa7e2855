//! Interval arithmetic with outward rounding (Moore, "Interval Analysis", 1966).
//!
//! Every operation returns an interval that contains the result of the
//! operation on every pair of points of its operands: each computed bound is
//! moved at least one ulp outwards (arithmetic is correctly rounded, so the
//! true bound lies within that ulp), twice for library functions (`exp`, `ln`,
//! `sin`, `cos`, whose results are within one ulp).
//!
//! Functions defined only on part of the reals (`sqrt`, `ln`, real powers) are
//! evaluated on the part of the interval inside their domain; an interval
//! entirely outside it gives the empty interval, which contains nothing (so a
//! root search discards it: the function has no zero where it is undefined).

/// A closed interval `[lo, hi]` of f64, possibly unbounded, or empty.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interval {
    pub lo: f64,
    pub hi: f64,
}

/// At least one ulp of `x` (`ulp(x) ≤ |x|·2⁻⁵²` for normal numbers, the
/// smallest subnormal below them), computed without branches: `next_up` and
/// `next_down` branch on sign and zero, which costs more than the arithmetic.
/// Finite for infinite `x`.
#[inline]
fn ulp_bound(x: f64) -> f64 {
    (x.abs() * f64::EPSILON).clamp(f64::from_bits(1), f64::MAX)
}

/// `x` rounded down by at least one ulp (round-to-nearest of `x − δ` with
/// `δ ≥ ulp(x)` is at most `next_down(x)`). `+∞` stays `+∞` (`δ` is at most
/// `f64::MAX`, so no `∞ − ∞` makes a NaN, the empty interval's mark).
#[inline]
fn down(x: f64) -> f64 {
    x - ulp_bound(x)
}

/// `x` rounded up by at least one ulp (`−∞` stays `−∞`).
#[inline]
fn up(x: f64) -> f64 {
    x + ulp_bound(x)
}

impl Interval {
    /// All reals.
    pub const ENTIRE: Interval = Interval {
        lo: f64::NEG_INFINITY,
        hi: f64::INFINITY,
    };
    /// The empty set (both bounds NaN; every comparison with it is false).
    pub const EMPTY: Interval = Interval {
        lo: f64::NAN,
        hi: f64::NAN,
    };

    /// `[lo, hi]`; `lo ≤ hi` is the caller's promise.
    #[inline]
    pub const fn new(lo: f64, hi: f64) -> Self {
        Interval { lo, hi }
    }

    /// The degenerate interval `[x, x]`.
    #[inline]
    pub const fn point(x: f64) -> Self {
        Interval { lo: x, hi: x }
    }

    #[inline]
    pub fn is_empty(self) -> bool {
        self.lo.is_nan() || self.hi.is_nan()
    }

    /// Whether `x` lies in the interval (false for the empty interval).
    #[inline]
    pub fn contains(self, x: f64) -> bool {
        self.lo <= x && x <= self.hi
    }

    #[inline]
    pub fn width(self) -> f64 {
        self.hi - self.lo
    }

    /// The smallest interval holding both.
    #[inline]
    pub fn hull(self, o: Interval) -> Interval {
        if self.is_empty() {
            return o;
        }
        if o.is_empty() {
            return self;
        }
        Interval::new(self.lo.min(o.lo), self.hi.max(o.hi))
    }

    /// Product: the hull of the four endpoint products, with `0·∞ = 0` (the
    /// limit of `x·y` as the zero factor is exact).
    #[inline]
    fn product(self, o: Interval) -> Interval {
        if self.is_empty() || o.is_empty() {
            return Interval::EMPTY;
        }
        let p = |a: f64, b: f64| if a == 0.0 || b == 0.0 { 0.0 } else { a * b };
        let (p1, p2, p3, p4) = (
            p(self.lo, o.lo),
            p(self.lo, o.hi),
            p(self.hi, o.lo),
            p(self.hi, o.hi),
        );
        Interval::new(
            down(p1.min(p2).min(p3).min(p4)),
            up(p1.max(p2).max(p3).max(p4)),
        )
    }

    /// Quotient. A divisor containing zero gives all reals (the quotient is
    /// unbounded near the zero), except a divisor of exactly `[0, 0]`, where the
    /// quotient is undefined (empty).
    ///
    /// An infinite bound stands for values past `f64::MAX` (an overflow, as
    /// in f64 arithmetic: `[∞, ∞]` is what overflowed upwards), so
    /// `±∞/±∞` is any quotient of that sign, from 0 to ∞: both enter the
    /// hull (IEEE's NaN there would make the result empty).
    #[inline]
    fn quotient(self, o: Interval) -> Interval {
        if self.is_empty() || o.is_empty() || (o.lo == 0.0 && o.hi == 0.0) {
            return Interval::EMPTY;
        }
        if o.lo <= 0.0 && o.hi >= 0.0 {
            return Interval::ENTIRE;
        }
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for (a, b) in [
            (self.lo, o.lo),
            (self.lo, o.hi),
            (self.hi, o.lo),
            (self.hi, o.hi),
        ] {
            let q = a / b;
            let (q_lo, q_hi) = if q.is_nan() {
                let signed = (a.signum() * b.signum()) * f64::INFINITY;
                (signed.min(0.0), signed.max(0.0))
            } else {
                (q, q)
            };
            lo = lo.min(q_lo);
            hi = hi.max(q_hi);
        }
        Interval::new(down(lo), up(hi))
    }

    /// `x^n` for an integer `n`. Even powers of an interval containing zero
    /// start at zero (`[−1, 2]² = [0, 4]`, not `[−2, 4]`); negative powers are
    /// `1/x^|n|`.
    pub fn powi(self, n: i32) -> Interval {
        if self.is_empty() {
            return self;
        }
        if n < 0 {
            return Interval::point(1.0) / self.powi(-n);
        }
        if n == 0 {
            return Interval::point(1.0);
        }
        let n = n as u32;
        if n % 2 == 1 {
            // Odd: monotonic increasing.
            return Interval::new(pow_signed(self.lo, n, false), pow_signed(self.hi, n, true));
        }
        let (a, b) = (self.lo.abs(), self.hi.abs());
        if self.lo <= 0.0 && self.hi >= 0.0 {
            Interval::new(0.0, pow_abs(a.max(b), n, true))
        } else {
            Interval::new(pow_abs(a.min(b), n, false), pow_abs(a.max(b), n, true))
        }
    }

    /// `√x` on the part of the interval where `x ≥ 0`.
    #[inline]
    pub fn sqrt(self) -> Interval {
        if self.hi < 0.0 || self.is_empty() {
            return Interval::EMPTY;
        }
        // sqrt is correctly rounded.
        Interval::new(down(self.lo.max(0.0).sqrt()).max(0.0), up(self.hi.sqrt()))
    }

    #[inline]
    pub fn abs(self) -> Interval {
        if self.lo >= 0.0 {
            self
        } else if self.hi <= 0.0 {
            -self
        } else if self.is_empty() {
            self
        } else {
            Interval::new(0.0, (-self.lo).max(self.hi))
        }
    }

    #[inline]
    pub fn exp(self) -> Interval {
        if self.is_empty() {
            return self;
        }
        Interval::new(down(down(self.lo.exp())).max(0.0), up(up(self.hi.exp())))
    }

    /// Natural logarithm on the part of the interval where `x > 0`.
    #[inline]
    pub fn ln(self) -> Interval {
        if self.hi <= 0.0 || self.is_empty() {
            return Interval::EMPTY;
        }
        let lo = if self.lo <= 0.0 {
            f64::NEG_INFINITY
        } else {
            down(down(self.lo.ln()))
        };
        Interval::new(lo, up(up(self.hi.ln())))
    }

    /// `x^e = exp(e·ln x)` on the part where `x ≥ 0` (with `0^e = 0` for `e > 0`).
    pub fn powf(self, e: Interval) -> Interval {
        if self.hi < 0.0 || self.is_empty() || e.is_empty() {
            return Interval::EMPTY;
        }
        let positive = Interval::new(
            self.lo.max(f64::MIN_POSITIVE),
            self.hi.max(f64::MIN_POSITIVE),
        );
        let r = (e * positive.ln()).exp();
        if self.lo <= 0.0 {
            // x = 0 is in the domain: 0^e is 0 for e > 0, 1 for e = 0, ∞ for e < 0.
            let at_zero = if e.lo > 0.0 {
                Interval::point(0.0)
            } else {
                Interval::new(0.0, f64::INFINITY)
            };
            r.hull(at_zero)
        } else {
            r
        }
    }

    /// Sine: the endpoints' values, widened to ±1 where the interval contains
    /// a crest or trough `π/2 + kπ`.
    pub fn sin(self) -> Interval {
        self.periodic(f64::sin, std::f64::consts::FRAC_PI_2)
    }

    /// Cosine: as [`Interval::sin`], with crests and troughs at `kπ`.
    pub fn cos(self) -> Interval {
        self.periodic(f64::cos, 0.0)
    }

    /// For sin and cos: `extremum` is the position of a maximum; minima lie π
    /// further. The test for "contains an extremum" is made on a slightly
    /// widened interval so that rounding cannot hide one.
    fn periodic(self, f: fn(f64) -> f64, extremum: f64) -> Interval {
        use std::f64::consts::{PI, TAU};
        if self.is_empty() {
            return self;
        }
        // Also where a bound is infinite (an overflow; [∞, ∞] has a NaN width).
        if self.width() >= TAU || self.lo.is_infinite() || self.hi.is_infinite() {
            return Interval::new(-1.0, 1.0);
        }
        let (fa, fb) = (f(self.lo), f(self.hi));
        let mut lo = down(down(fa.min(fb)));
        let mut hi = up(up(fa.max(fb)));
        let slack = 1e-12 * (1.0 + self.lo.abs().max(self.hi.abs()));
        let contains = |c: f64| {
            let k = ((self.lo - slack - c) / TAU).ceil();
            c + k * TAU <= self.hi + slack
        };
        if contains(extremum) {
            hi = 1.0;
        }
        if contains(extremum + PI) {
            lo = -1.0;
        }
        Interval::new(lo.max(-1.0), hi.min(1.0))
    }

    #[inline]
    pub fn min(self, o: Interval) -> Interval {
        if self.is_empty() || o.is_empty() {
            return Interval::EMPTY;
        }
        Interval::new(self.lo.min(o.lo), self.hi.min(o.hi))
    }

    #[inline]
    pub fn max(self, o: Interval) -> Interval {
        if self.is_empty() || o.is_empty() {
            return Interval::EMPTY;
        }
        Interval::new(self.lo.max(o.lo), self.hi.max(o.hi))
    }
}

impl std::ops::Add for Interval {
    type Output = Interval;
    #[inline]
    fn add(self, o: Interval) -> Interval {
        let (lo, hi) = (self.lo + o.lo, self.hi + o.hi);
        // One test for both (also true for [−∞, ∞], which the slow path
        // gets right too).
        if (lo + hi).is_nan() {
            return overflowed_or_empty(lo, hi, self, o);
        }
        Interval::new(down(lo), up(hi))
    }
}

impl std::ops::Sub for Interval {
    type Output = Interval;
    #[inline]
    fn sub(self, o: Interval) -> Interval {
        let (lo, hi) = (self.lo - o.hi, self.hi - o.lo);
        if (lo + hi).is_nan() {
            return overflowed_or_empty(lo, hi, self, o);
        }
        Interval::new(down(lo), up(hi))
    }
}

impl std::ops::Neg for Interval {
    type Output = Interval;
    #[inline]
    fn neg(self) -> Interval {
        Interval::new(-self.hi, -self.lo)
    }
}

impl std::ops::Mul for Interval {
    type Output = Interval;
    #[inline]
    fn mul(self, o: Interval) -> Interval {
        self.product(o)
    }
}

impl std::ops::Div for Interval {
    type Output = Interval;
    #[inline]
    fn div(self, o: Interval) -> Interval {
        self.quotient(o)
    }
}

/// A sum or difference whose bound `lo` or `hi` came out NaN: from an
/// empty operand (the result is empty), or from `∞ − ∞`, two overflowed
/// bounds whose difference may be anything (that bound is unbounded).
#[cold]
fn overflowed_or_empty(lo: f64, hi: f64, a: Interval, b: Interval) -> Interval {
    if a.is_empty() || b.is_empty() {
        return Interval::EMPTY;
    }
    let lo = if lo.is_nan() {
        f64::NEG_INFINITY
    } else {
        down(lo)
    };
    let hi = if hi.is_nan() { f64::INFINITY } else { up(hi) };
    Interval::new(lo, hi)
}

/// `|x|^n`, rounded down or up at every multiplication (exponentiation by
/// squaring on a non-negative base keeps the direction of rounding valid).
fn pow_abs(x: f64, n: u32, round_up: bool) -> f64 {
    let step = |v: f64| if round_up { up(v) } else { down(v).max(0.0) };
    let (mut base, mut n, mut acc) = (x.abs(), n, 1.0f64);
    while n > 0 {
        if n & 1 == 1 {
            acc = step(acc * base);
        }
        n >>= 1;
        if n > 0 {
            base = step(base * base);
        }
    }
    acc
}

/// `x^n` for odd `n`, rounded down (`round_up = false`) or up.
fn pow_signed(x: f64, n: u32, round_up: bool) -> f64 {
    if x >= 0.0 {
        pow_abs(x, n, round_up)
    } else {
        -pow_abs(x, n, !round_up)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn iv(lo: f64, hi: f64) -> Interval {
        Interval::new(lo, hi)
    }

    #[test]
    fn even_power_of_interval_through_zero_starts_at_zero() {
        let r = iv(-1.0, 2.0).powi(2);
        assert_eq!(r.lo, 0.0);
        assert!(r.hi >= 4.0 && r.hi < 4.0 + 1e-12);
        let r = iv(-3.0, -2.0).powi(2);
        assert!(r.lo <= 4.0 && r.lo > 3.99 && r.hi >= 9.0);
        let r = iv(-2.0, 1.0).powi(3);
        assert!(r.lo <= -8.0 && r.hi >= 1.0 && r.hi < 1.01);
    }

    #[test]
    fn outward_rounding_moves_at_least_one_ulp() {
        for x in [
            1.0,
            -1.0,
            0.0,
            -0.0,
            3.0e-310,
            -3.0e-310,
            1e300,
            -1e300,
            0.1,
            -7.0,
            2.0,
            -2.0,
            f64::MIN_POSITIVE,
        ] {
            assert!(up(x) >= x.next_up(), "{x}");
            assert!(down(x) <= x.next_down(), "{x}");
        }
        assert_eq!(up(f64::INFINITY), f64::INFINITY);
        assert_eq!(down(f64::NEG_INFINITY), f64::NEG_INFINITY);
    }

    #[test]
    fn division_by_interval_containing_zero_is_unbounded() {
        assert_eq!(iv(1.0, 2.0) / iv(-1.0, 1.0), Interval::ENTIRE);
        assert_eq!(iv(1.0, 2.0) / iv(0.0, 1.0), Interval::ENTIRE);
        assert!((iv(1.0, 2.0) / iv(0.0, 0.0)).is_empty());
        let q = iv(1.0, 2.0) / iv(4.0, 8.0);
        assert!(q.lo <= 0.125 && q.hi >= 0.5);
    }

    #[test]
    fn sqrt_and_ln_clip_to_their_domain() {
        assert!(iv(-2.0, -1.0).sqrt().is_empty());
        let s = iv(-1.0, 4.0).sqrt();
        assert_eq!(s.lo, 0.0);
        assert!(s.hi >= 2.0);
        assert!(iv(-2.0, 0.0).ln().is_empty());
        assert_eq!(iv(-1.0, 1.0).ln().lo, f64::NEG_INFINITY);
        assert!(!Interval::EMPTY.contains(0.0));
    }

    #[test]
    fn zero_times_infinity_is_zero() {
        let r = iv(0.0, 0.0) * Interval::ENTIRE;
        assert!(r.contains(0.0) && r.width() < 1e-300, "{r:?}");
        let r = iv(0.0, 1.0) * iv(1.0, f64::INFINITY);
        assert!(
            r.contains(0.0) && r.lo > -1e-300 && r.hi == f64::INFINITY,
            "{r:?}"
        );
    }

    #[test]
    fn sine_interval_covers_crests() {
        let r = iv(1.0, 2.0).sin();
        assert_eq!(r.hi, 1.0);
        assert!(r.lo <= 1.0f64.sin());
        let r = iv(4.0, 5.0).sin();
        assert_eq!(r.lo, -1.0);
        let r = iv(-0.1, 0.1).cos();
        assert_eq!(r.hi, 1.0);
        assert!(r.lo <= 0.1f64.cos());
    }

    #[test]
    fn overflowed_bounds_never_make_an_interval_empty() {
        // [∞, ∞] stands for values past f64::MAX: 333e3333 in a formula, or
        // a power that overflowed. Found by the fuzzer: x·z^33333/333e3333
        // over a box was [−∞, ∞]/[∞, ∞], NaN in IEEE, the empty interval.
        let inf = iv(f64::INFINITY, f64::INFINITY);
        let q = Interval::ENTIRE / inf;
        assert!(q.contains(0.0), "{q:?}");
        let q = inf / inf;
        assert!(q.contains(0.0) && q.hi == f64::INFINITY, "{q:?}");
        let q = iv(-f64::INFINITY, -1.0) / inf;
        assert!(
            q.contains(-1e300) && q.contains(0.0) && q.hi < 1e-300,
            "{q:?}"
        );
        let s = inf - inf;
        assert_eq!(s, Interval::ENTIRE);
        let s = Interval::ENTIRE + inf;
        assert!(s.lo == f64::NEG_INFINITY && s.hi == f64::INFINITY, "{s:?}");
        let p = iv(1e200, 1e200) * iv(1e200, 1e200);
        assert_eq!(p, inf);
        assert_eq!(inf.sin(), iv(-1.0, 1.0));
        assert_eq!(iv(1e300, 1e301).exp().hi, f64::INFINITY);
        assert!(!iv(1e300, 1e301).exp().is_empty());
        // Emptiness itself still propagates.
        assert!((Interval::EMPTY + inf).is_empty());
        assert!((inf - Interval::EMPTY).is_empty());
        assert!((Interval::EMPTY / inf).is_empty());
    }

    /// Bounds anywhere in f64, overflowed ones (±∞) included.
    fn wide_bound() -> impl Strategy<Value = f64> {
        prop_oneof![
            Just(f64::INFINITY),
            Just(f64::NEG_INFINITY),
            Just(f64::MAX),
            Just(0.0),
            (-1.0f64..1.0, -320i32..309).prop_map(|(m, e)| m * 10f64.powi(e)),
        ]
    }

    fn wide_interval() -> impl Strategy<Value = Interval> {
        (wide_bound(), wide_bound()).prop_map(|(a, b)| iv(a.min(b), a.max(b)))
    }

    fn interval() -> impl Strategy<Value = Interval> {
        (-5.0f64..5.0, 0.0f64..3.0).prop_map(|(a, w)| iv(a, a + w))
    }

    fn inside(i: Interval, s: f64) -> f64 {
        i.lo + (i.hi - i.lo) * s
    }

    proptest! {
        /// The inclusion property: f(x, y) ∈ F(X, Y) for every x ∈ X, y ∈ Y.
        #[test]
        fn operations_enclose_point_results(a in interval(), b in interval(), s in 0.0f64..=1.0, u in 0.0f64..=1.0, n in -4i32..7) {
            let (x, y) = (inside(a, s), inside(b, u));
            let check = |r: Interval, v: f64, name: &str| {
                if v.is_finite() {
                    assert!(r.contains(v), "{name}: {v} ∉ {r:?} (x = {x}, y = {y}, n = {n})");
                }
            };
            check(a + b, x + y, "add");
            check(a - b, x - y, "sub");
            check(a * b, x * y, "mul");
            if y != 0.0 { check(a / b, x / y, "div"); }
            check(a.powi(n), x.powi(n), "powi");
            if x >= 0.0 { check(a.sqrt(), x.sqrt(), "sqrt"); }
            if x > 0.0 { check(a.ln(), x.ln(), "ln"); check(a.powf(b), x.powf(y), "powf"); }
            check(a.exp(), x.exp(), "exp");
            check(a.sin(), x.sin(), "sin");
            check(a.cos(), x.cos(), "cos");
            check(a.abs(), x.abs(), "abs");
            check(a.min(b), x.min(y), "min");
            check(a.max(b), x.max(y), "max");
            check(-a, -x, "neg");
        }

        /// Operations defined everywhere never turn non-empty operands,
        /// however large, into the empty interval (which a root search
        /// reads as "undefined here" and skips).
        #[test]
        fn total_operations_stay_non_empty(a in wide_interval(), b in wide_interval(), n in -4i32..7) {
            let all = [
                ("add", a + b), ("sub", a - b), ("mul", a * b), ("powi", a.powi(n)),
                ("exp", a.exp()), ("sin", a.sin()), ("cos", a.cos()), ("abs", a.abs()),
                ("min", a.min(b)), ("max", a.max(b)), ("neg", -a),
            ];
            for (name, r) in all {
                assert!(!r.is_empty() && r.lo <= r.hi, "{name}: {a:?}, {b:?} (n = {n}) gave {r:?}");
            }
            if !(b.lo == 0.0 && b.hi == 0.0) {
                let r = a / b;
                assert!(!r.is_empty() && r.lo <= r.hi, "div: {a:?} / {b:?} gave {r:?}");
            }
        }
    }
}
