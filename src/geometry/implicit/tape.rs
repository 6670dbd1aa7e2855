//! A formula compiled once into a flat instruction list (a "tape"), evaluated
//! without allocation over any [`Scalar`] type: f64 values, intervals
//! (inclusion functions), and dual numbers (forward-mode automatic
//! differentiation: the gradient for normals, the derivative along a ray for
//! Newton steps and monotonicity tests).
//!
//! Compilation folds constants, shares repeated subexpressions (hash-consing),
//! turns `a*a` into `a^2` (whose interval extension is tighter: `[−1, 2]²` is
//! `[0, 4]`, `[−1, 2]·[−1, 2]` is `[−2, 4]`), and turns integer exponents into
//! `powi`, which is exact in sign for negative bases.

use super::parse::{BinOp, Expr, Func};
use crate::math::Interval;
use std::collections::HashMap;
use std::mem::MaybeUninit;

/// Longest tape accepted (instructions after sharing and folding).
pub const MAX_TAPE: usize = 512;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Op {
    Const(f64),
    Var(u8),
    Add(u16, u16),
    Sub(u16, u16),
    Mul(u16, u16),
    Div(u16, u16),
    Neg(u16),
    PowI(u16, i32),
    PowF(u16, u16),
    Call(Func, u16),
    Min(u16, u16),
    Max(u16, u16),
}

/// A compiled formula. Every instruction reads only earlier results.
#[derive(Clone, Debug, PartialEq)]
pub struct Tape {
    ops: Vec<Op>,
}

/// Hashable identity of an instruction, for sharing repeated subexpressions.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
struct Key(u8, u64, u64);

impl Op {
    fn key(&self) -> Key {
        match *self {
            Op::Const(c) => Key(0, c.to_bits(), 0),
            Op::Var(v) => Key(1, v as u64, 0),
            Op::Add(a, b) => Key(2, a.min(b) as u64, a.max(b) as u64),
            Op::Sub(a, b) => Key(3, a as u64, b as u64),
            Op::Mul(a, b) => Key(4, a.min(b) as u64, a.max(b) as u64),
            Op::Div(a, b) => Key(5, a as u64, b as u64),
            Op::Neg(a) => Key(6, a as u64, 0),
            Op::PowI(a, n) => Key(7, a as u64, n as u32 as u64),
            Op::PowF(a, b) => Key(8, a as u64, b as u64),
            Op::Call(f, a) => Key(9 + f as u8, a as u64, 0),
            Op::Min(a, b) => Key(20, a.min(b) as u64, a.max(b) as u64),
            Op::Max(a, b) => Key(21, a.min(b) as u64, a.max(b) as u64),
        }
    }
}

struct Builder {
    ops: Vec<Op>,
    seen: HashMap<Key, u16>,
}

impl Builder {
    fn constant(&self, i: u16) -> Option<f64> {
        match self.ops[i as usize] {
            Op::Const(c) => Some(c),
            _ => None,
        }
    }

    /// Appends `op` (or finds an identical earlier one), folding constants.
    fn push(&mut self, op: Op) -> Result<u16, String> {
        let folded = self.fold(op);
        let op = folded.map_or(op, Op::Const);
        if let Some(&i) = self.seen.get(&op.key()) {
            return Ok(i);
        }
        if self.ops.len() >= MAX_TAPE {
            return Err(format!(
                "the formula is too long (more than {MAX_TAPE} operations)"
            ));
        }
        let i = self.ops.len() as u16;
        self.ops.push(op);
        self.seen.insert(op.key(), i);
        Ok(i)
    }

    fn fold(&self, op: Op) -> Option<f64> {
        let c = |i: u16| self.constant(i);
        let v = match op {
            Op::Const(_) | Op::Var(_) => return None,
            Op::Add(a, b) => c(a)? + c(b)?,
            Op::Sub(a, b) => c(a)? - c(b)?,
            Op::Mul(a, b) => c(a)? * c(b)?,
            Op::Div(a, b) => c(a)? / c(b)?,
            Op::Neg(a) => -c(a)?,
            Op::PowI(a, n) => c(a)?.powi(n),
            Op::PowF(a, b) => c(a)?.powf(c(b)?),
            Op::Call(f, a) => call(f, c(a)?),
            Op::Min(a, b) => c(a)?.min(c(b)?),
            Op::Max(a, b) => c(a)?.max(c(b)?),
        };
        // Keep undefined constant subexpressions (e.g. ln(-1)) unfolded, so the
        // formula stays undefined there, as written.
        v.is_finite().then_some(v)
    }

    fn emit(&mut self, e: &Expr) -> Result<u16, String> {
        Ok(match e {
            Expr::Num(n) => self.push(Op::Const(*n))?,
            Expr::Var(v) => self.push(Op::Var(*v))?,
            Expr::Neg(a) => {
                let a = self.emit(a)?;
                self.push(Op::Neg(a))?
            }
            Expr::Call(f, args) => {
                let a = self.emit(&args[0])?;
                match f {
                    Func::Min => {
                        let b = self.emit(&args[1])?;
                        self.push(Op::Min(a, b))?
                    }
                    Func::Max => {
                        let b = self.emit(&args[1])?;
                        self.push(Op::Max(a, b))?
                    }
                    _ => self.push(Op::Call(*f, a))?,
                }
            }
            Expr::Binary(op, a, b) => {
                let (a, b) = (self.emit(a)?, self.emit(b)?);
                match op {
                    BinOp::Add => self.push(Op::Add(a, b))?,
                    BinOp::Sub => self.push(Op::Sub(a, b))?,
                    BinOp::Mul if a == b => self.push(Op::PowI(a, 2))?,
                    BinOp::Mul => self.push(Op::Mul(a, b))?,
                    BinOp::Div => self.push(Op::Div(a, b))?,
                    BinOp::Pow => match self.constant(b) {
                        Some(n) if n == n.round() && n.abs() <= 64.0 => {
                            self.push(Op::PowI(a, n as i32))?
                        }
                        _ => self.push(Op::PowF(a, b))?,
                    },
                }
            }
        })
    }
}

/// The instructions that `root` depends on, renumbered in order, `root` last
/// (folding leaves the operands of folded constants behind).
fn live_ops(ops: &[Op], root: u16) -> Vec<Op> {
    let mut live = vec![false; ops.len()];
    live[root as usize] = true;
    for i in (0..=root as usize).rev() {
        if !live[i] {
            continue;
        }
        let mut mark = |j: u16| live[j as usize] = true;
        match ops[i] {
            Op::Const(_) | Op::Var(_) => {}
            Op::Neg(a) | Op::PowI(a, _) | Op::Call(_, a) => mark(a),
            Op::Add(a, b)
            | Op::Sub(a, b)
            | Op::Mul(a, b)
            | Op::Div(a, b)
            | Op::PowF(a, b)
            | Op::Min(a, b)
            | Op::Max(a, b) => {
                mark(a);
                mark(b);
            }
        }
    }
    let mut index = vec![0u16; ops.len()];
    let mut out = Vec::new();
    for i in 0..=root as usize {
        if live[i] {
            index[i] = out.len() as u16;
            let m = |j: u16| index[j as usize];
            out.push(match ops[i] {
                op @ (Op::Const(_) | Op::Var(_)) => op,
                Op::Neg(a) => Op::Neg(m(a)),
                Op::PowI(a, n) => Op::PowI(m(a), n),
                Op::Call(f, a) => Op::Call(f, m(a)),
                Op::Add(a, b) => Op::Add(m(a), m(b)),
                Op::Sub(a, b) => Op::Sub(m(a), m(b)),
                Op::Mul(a, b) => Op::Mul(m(a), m(b)),
                Op::Div(a, b) => Op::Div(m(a), m(b)),
                Op::PowF(a, b) => Op::PowF(m(a), m(b)),
                Op::Min(a, b) => Op::Min(m(a), m(b)),
                Op::Max(a, b) => Op::Max(m(a), m(b)),
            });
        }
    }
    out
}

fn call(f: Func, x: f64) -> f64 {
    match f {
        Func::Sqrt => x.sqrt(),
        Func::Abs => x.abs(),
        Func::Sin => x.sin(),
        Func::Cos => x.cos(),
        Func::Exp => x.exp(),
        Func::Ln => x.ln(),
        Func::Min | Func::Max => unreachable!("min and max are binary operations"),
    }
}

impl Tape {
    /// Compiles an expression tree.
    pub fn compile(e: &Expr) -> Result<Tape, String> {
        let mut b = Builder {
            ops: Vec::new(),
            seen: HashMap::new(),
        };
        let root = b.emit(e)?;
        Ok(Tape {
            ops: live_ops(&b.ops, root),
        })
    }

    /// Number of instructions.
    pub fn len(&self) -> usize {
        self.ops.len()
    }

    pub fn is_empty(&self) -> bool {
        self.ops.is_empty()
    }

    /// Evaluates the formula at `(x, y, z)`.
    #[inline]
    pub fn eval<T: Scalar>(&self, x: T, y: T, z: T) -> T {
        let vars = [x, y, z];
        let mut regs = [const { MaybeUninit::<T>::uninit() }; MAX_TAPE];
        let n = self.ops.len();
        for i in 0..n {
            // SAFETY: compilation only emits operands that index earlier
            // instructions (`push` returns the index of an existing or the newly
            // appended op, and operands are emitted before their users), and
            // every instruction below `i` has been written by this loop.
            let r = |j: u16| unsafe { regs[j as usize].assume_init() };
            let v = match self.ops[i] {
                Op::Const(c) => T::constant(c),
                Op::Var(k) => vars[k as usize],
                Op::Add(a, b) => r(a).add(r(b)),
                Op::Sub(a, b) => r(a).sub(r(b)),
                Op::Mul(a, b) => r(a).mul(r(b)),
                Op::Div(a, b) => r(a).div(r(b)),
                Op::Neg(a) => r(a).neg(),
                Op::PowI(a, k) => r(a).powi(k),
                Op::PowF(a, b) => r(a).powf(r(b)),
                Op::Call(f, a) => {
                    let a = r(a);
                    match f {
                        Func::Sqrt => a.sqrt(),
                        Func::Abs => a.abs(),
                        Func::Sin => a.sin(),
                        Func::Cos => a.cos(),
                        Func::Exp => a.exp(),
                        Func::Ln => a.ln(),
                        Func::Min | Func::Max => unreachable!("emitted as Op::Min/Max"),
                    }
                }
                Op::Min(a, b) => r(a).min(r(b)),
                Op::Max(a, b) => r(a).max(r(b)),
            };
            regs[i].write(v);
        }
        // SAFETY: a compiled tape is never empty, and the loop wrote every entry.
        unsafe { regs[n - 1].assume_init() }
    }
}

/// The arithmetic a tape is evaluated in.
pub trait Scalar: Copy {
    fn constant(c: f64) -> Self;
    fn add(self, o: Self) -> Self;
    fn sub(self, o: Self) -> Self;
    fn mul(self, o: Self) -> Self;
    fn div(self, o: Self) -> Self;
    fn neg(self) -> Self;
    fn powi(self, n: i32) -> Self;
    /// `x^e` for real `e`, defined for `x ≥ 0`.
    fn powf(self, e: Self) -> Self;
    fn sqrt(self) -> Self;
    fn abs(self) -> Self;
    fn sin(self) -> Self;
    fn cos(self) -> Self;
    fn exp(self) -> Self;
    fn ln(self) -> Self;
    fn min(self, o: Self) -> Self;
    fn max(self, o: Self) -> Self;
    /// The derivative of `|x|`: −1, 0 or 1 (an interval: their hull over `x`).
    fn signum(self) -> Self;
    /// Which of `self`, `o` is the smaller: `Some(true)` self, `Some(false)`
    /// `o`, `None` either (intervals that overlap).
    fn is_smaller(self, o: Self) -> Option<bool>;
    /// The smallest value of the type holding both.
    fn hull(self, o: Self) -> Self;
    fn is_zero(self) -> bool;
}

impl Scalar for f64 {
    #[inline]
    fn constant(c: f64) -> Self {
        c
    }
    #[inline]
    fn add(self, o: Self) -> Self {
        self + o
    }
    #[inline]
    fn sub(self, o: Self) -> Self {
        self - o
    }
    #[inline]
    fn mul(self, o: Self) -> Self {
        self * o
    }
    #[inline]
    fn div(self, o: Self) -> Self {
        self / o
    }
    #[inline]
    fn neg(self) -> Self {
        -self
    }
    #[inline]
    fn powi(self, n: i32) -> Self {
        // Repeated squaring, inlined: `f64::powi` is a library call.
        let (mut base, mut k, mut acc) = (self, n.unsigned_abs(), 1.0);
        while k > 0 {
            if k & 1 == 1 {
                acc *= base;
            }
            k >>= 1;
            base *= base;
        }
        if n < 0 { 1.0 / acc } else { acc }
    }
    #[inline]
    fn powf(self, e: Self) -> Self {
        if self < 0.0 {
            f64::NAN
        } else {
            f64::powf(self, e)
        }
    }
    #[inline]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline]
    fn abs(self) -> Self {
        f64::abs(self)
    }
    #[inline]
    fn sin(self) -> Self {
        f64::sin(self)
    }
    #[inline]
    fn cos(self) -> Self {
        f64::cos(self)
    }
    #[inline]
    fn exp(self) -> Self {
        f64::exp(self)
    }
    #[inline]
    fn ln(self) -> Self {
        f64::ln(self)
    }
    #[inline]
    fn min(self, o: Self) -> Self {
        f64::min(self, o)
    }
    #[inline]
    fn max(self, o: Self) -> Self {
        f64::max(self, o)
    }
    #[inline]
    fn signum(self) -> Self {
        if self > 0.0 {
            1.0
        } else if self < 0.0 {
            -1.0
        } else {
            0.0
        }
    }
    #[inline]
    fn is_smaller(self, o: Self) -> Option<bool> {
        Some(self <= o)
    }
    #[inline]
    fn hull(self, _: Self) -> Self {
        self
    }
    #[inline]
    fn is_zero(self) -> bool {
        self == 0.0
    }
}

impl Scalar for Interval {
    #[inline]
    fn constant(c: f64) -> Self {
        Interval::point(c)
    }
    #[inline]
    fn add(self, o: Self) -> Self {
        self + o
    }
    #[inline]
    fn sub(self, o: Self) -> Self {
        self - o
    }
    #[inline]
    fn mul(self, o: Self) -> Self {
        self * o
    }
    #[inline]
    fn div(self, o: Self) -> Self {
        self / o
    }
    #[inline]
    fn neg(self) -> Self {
        -self
    }
    #[inline]
    fn powi(self, n: i32) -> Self {
        Interval::powi(self, n)
    }
    #[inline]
    fn powf(self, e: Self) -> Self {
        Interval::powf(self, e)
    }
    #[inline]
    fn sqrt(self) -> Self {
        Interval::sqrt(self)
    }
    #[inline]
    fn abs(self) -> Self {
        Interval::abs(self)
    }
    #[inline]
    fn sin(self) -> Self {
        Interval::sin(self)
    }
    #[inline]
    fn cos(self) -> Self {
        Interval::cos(self)
    }
    #[inline]
    fn exp(self) -> Self {
        Interval::exp(self)
    }
    #[inline]
    fn ln(self) -> Self {
        Interval::ln(self)
    }
    #[inline]
    fn min(self, o: Self) -> Self {
        Interval::min(self, o)
    }
    #[inline]
    fn max(self, o: Self) -> Self {
        Interval::max(self, o)
    }
    #[inline]
    fn signum(self) -> Self {
        if self.lo > 0.0 {
            Interval::point(1.0)
        } else if self.hi < 0.0 {
            Interval::point(-1.0)
        } else if self.is_empty() {
            self
        } else {
            Interval::new(-1.0, 1.0)
        }
    }
    #[inline]
    fn is_smaller(self, o: Self) -> Option<bool> {
        if self.hi < o.lo {
            Some(true)
        } else if o.hi < self.lo {
            Some(false)
        } else {
            None
        }
    }
    #[inline]
    fn hull(self, o: Self) -> Self {
        Interval::hull(self, o)
    }
    #[inline]
    fn is_zero(self) -> bool {
        self.lo == 0.0 && self.hi == 0.0
    }
}

/// A dual number `v + Σ dᵢ εᵢ` (εᵢ εⱼ = 0): evaluating a formula on duals
/// carries the value and its `N` partial derivatives together (forward-mode
/// automatic differentiation). Over [`Interval`] it encloses the derivative
/// over a whole interval.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dual<S, const N: usize> {
    pub v: S,
    pub d: [S; N],
}

impl<S: Scalar, const N: usize> Dual<S, N> {
    /// A variable with value `v` and derivatives `d`.
    #[inline]
    pub fn new(v: S, d: [S; N]) -> Self {
        Dual { v, d }
    }

    /// Applies the chain rule: value `v`, derivative `f′ · self.d`.
    #[inline]
    fn chain(self, v: S, f_prime: S) -> Self {
        Dual {
            v,
            d: self.d.map(|d| f_prime.mul(d)),
        }
    }

    #[inline]
    fn zip(self, o: Self, f: impl Fn(S, S) -> S) -> [S; N] {
        std::array::from_fn(|i| f(self.d[i], o.d[i]))
    }
}

impl<S: Scalar, const N: usize> Scalar for Dual<S, N> {
    #[inline]
    fn constant(c: f64) -> Self {
        Dual {
            v: S::constant(c),
            d: [S::constant(0.0); N],
        }
    }
    #[inline]
    fn add(self, o: Self) -> Self {
        Dual {
            v: self.v.add(o.v),
            d: self.zip(o, S::add),
        }
    }
    #[inline]
    fn sub(self, o: Self) -> Self {
        Dual {
            v: self.v.sub(o.v),
            d: self.zip(o, S::sub),
        }
    }
    #[inline]
    fn mul(self, o: Self) -> Self {
        let (a, b) = (self.v, o.v);
        Dual {
            v: a.mul(b),
            d: self.zip(o, |da, db| a.mul(db).add(b.mul(da))),
        }
    }
    #[inline]
    fn div(self, o: Self) -> Self {
        // (a/b)′ = (a′ − (a/b)·b′)/b
        let q = self.v.div(o.v);
        Dual {
            v: q,
            d: self.zip(o, |da, db| da.sub(q.mul(db)).div(o.v)),
        }
    }
    #[inline]
    fn neg(self) -> Self {
        Dual {
            v: self.v.neg(),
            d: self.d.map(S::neg),
        }
    }
    #[inline]
    fn powi(self, n: i32) -> Self {
        if n == 0 {
            return Self::constant(1.0);
        }
        let f_prime = S::constant(n as f64).mul(self.v.powi(n - 1));
        self.chain(self.v.powi(n), f_prime)
    }
    #[inline]
    fn powf(self, e: Self) -> Self {
        // (u^e)′ = e·u^(e−1)·u′ + u^e·ln(u)·e′
        let v = self.v.powf(e.v);
        let d_base = e.v.mul(self.v.powf(e.v.sub(S::constant(1.0))));
        let constant_exponent = e.d.iter().all(|d| d.is_zero());
        let ln_u = self.v.ln();
        Dual {
            v,
            d: std::array::from_fn(|i| {
                let from_base = d_base.mul(self.d[i]);
                if constant_exponent {
                    from_base
                } else {
                    from_base.add(v.mul(ln_u).mul(e.d[i]))
                }
            }),
        }
    }
    #[inline]
    fn sqrt(self) -> Self {
        let s = self.v.sqrt();
        self.chain(s, S::constant(0.5).div(s))
    }
    #[inline]
    fn abs(self) -> Self {
        self.chain(self.v.abs(), self.v.signum())
    }
    #[inline]
    fn sin(self) -> Self {
        self.chain(self.v.sin(), self.v.cos())
    }
    #[inline]
    fn cos(self) -> Self {
        self.chain(self.v.cos(), self.v.sin().neg())
    }
    #[inline]
    fn exp(self) -> Self {
        let e = self.v.exp();
        self.chain(e, e)
    }
    #[inline]
    fn ln(self) -> Self {
        self.chain(self.v.ln(), S::constant(1.0).div(self.v))
    }
    #[inline]
    fn min(self, o: Self) -> Self {
        match self.v.is_smaller(o.v) {
            Some(true) => self,
            Some(false) => o,
            None => Dual {
                v: self.v.min(o.v),
                d: self.zip(o, S::hull),
            },
        }
    }
    #[inline]
    fn max(self, o: Self) -> Self {
        match self.v.is_smaller(o.v) {
            Some(true) => o,
            Some(false) => self,
            None => Dual {
                v: self.v.max(o.v),
                d: self.zip(o, S::hull),
            },
        }
    }
    #[inline]
    fn signum(self) -> Self {
        Dual {
            v: self.v.signum(),
            d: [S::constant(0.0); N],
        }
    }
    #[inline]
    fn is_smaller(self, o: Self) -> Option<bool> {
        self.v.is_smaller(o.v)
    }
    #[inline]
    fn hull(self, o: Self) -> Self {
        Dual {
            v: self.v.hull(o.v),
            d: self.zip(o, S::hull),
        }
    }
    #[inline]
    fn is_zero(self) -> bool {
        self.v.is_zero() && self.d.iter().all(|d| d.is_zero())
    }
}

#[cfg(test)]
mod tests {
    use super::super::parse::parse;
    use super::*;

    fn tape(s: &str) -> Tape {
        Tape::compile(&parse(s).unwrap()).unwrap()
    }

    #[test]
    fn evaluates_values() {
        let t = tape("(x^2 + 9/4*y^2 + z^2 - 1)^3 - x^2*z^3 - 9/80*y^2*z^3");
        let (x, y, z) = (0.3, -0.2, 0.9);
        let g: f64 = x * x + 2.25 * y * y + z * z - 1.0;
        let expected = g.powi(3) - x * x * z * z * z - 0.1125 * y * y * z * z * z;
        assert!((t.eval(x, y, z) - expected).abs() < 1e-15);
        assert_eq!(tape("min(x, y) + max(x, y)").eval(1.0, 2.0, 0.0), 3.0);
        assert!(
            (tape("sqrt(abs(x)) + exp(ln(2)) + sin(pi/2) + cos(0)").eval(-4.0, 0.0, 0.0) - 6.0)
                .abs()
                < 1e-12
        );
        assert!((tape("x^0.5").eval(2.0, 0.0, 0.0) - 2f64.sqrt()).abs() < 1e-15);
        assert!(tape("x^0.5").eval(-2.0, 0.0, 0.0).is_nan());
        assert_eq!(tape("x^-2").eval(2.0, 0.0, 0.0), 0.25);
    }

    #[test]
    fn constants_fold_and_subexpressions_are_shared() {
        assert_eq!(tape("1 + 2*3").len(), 1);
        // x, x^2 (from x*x, shared with x^2), the sum.
        assert_eq!(tape("x*x + x^2").len(), 3);
        assert_eq!(tape("sin(x) + sin(x)").len(), 3);
    }

    #[test]
    fn gradient_by_automatic_differentiation() {
        let t = tape("x^2*y + sin(z)*x");
        let (x, y, z) = (0.7, -1.3, 0.4);
        let g = t.eval(
            Dual::new(x, [1.0, 0.0, 0.0]),
            Dual::new(y, [0.0, 1.0, 0.0]),
            Dual::new(z, [0.0, 0.0, 1.0]),
        );
        let expected = [2.0 * x * y + z.sin(), x * x, z.cos() * x];
        for (got, want) in g.d.iter().zip(expected) {
            assert!((got - want).abs() < 1e-14, "{got} vs {want}");
        }
    }

    #[test]
    fn interval_evaluation_encloses_the_range() {
        let t = tape("(2 - sqrt(x^2 + y^2))^2 + z^2 - 0.25");
        let i = t.eval(
            Interval::new(-0.1, 0.1),
            Interval::new(1.9, 2.1),
            Interval::new(-0.1, 0.1),
        );
        // Points of the box give values in [−0.25, ~−0.23]; 0 lies outside.
        assert!(i.hi < 0.0 && i.lo <= -0.25, "{i:?}");
        for (x, y, z) in [(0.0, 2.0, 0.0), (0.1, 2.1, 0.1), (-0.1, 1.9, 0.05)] {
            assert!(i.contains(t.eval(x, y, z)));
        }
    }

    #[test]
    fn overflowing_terms_still_enclose_the_range() {
        // Found by the fuzzer: 333e3333 is ∞, z^33333 overflows over the
        // box, and their quotient was NaN (read as "undefined everywhere").
        let t = tape("(x^3 − -  1)^3 - x^1*z^33333/333e3333 - 2*z^3");
        let b = Interval::new(-1.5, 1.5);
        let range = t.eval(b, b, b);
        let p = -1.5 + 3.0 * 32768.0 / 65535.0;
        let value = t.eval(p, p, p);
        assert!(
            value.is_finite() && range.contains(value),
            "{value} ∉ {range:?}"
        );
    }

    #[test]
    fn interval_derivative_encloses_point_derivatives() {
        let t = tape("(x^2 + 9/4*y^2 + z^2 - 1)^3 - x^2*z^3 - 9/80*y^2*z^3");
        let (o, d) = ([0.2, -0.4, -2.0], [0.1, 0.3, 1.0]);
        let (t0, t1) = (1.0, 1.5);
        let ray = |k: usize| {
            Dual::new(
                Interval::point(o[k]) + Interval::new(t0, t1) * Interval::point(d[k]),
                [Interval::point(d[k])],
            )
        };
        let enclosure = t.eval(ray(0), ray(1), ray(2));
        for s in 0..=20 {
            let tt = t0 + (t1 - t0) * s as f64 / 20.0;
            let p = |k: usize| Dual::new(o[k] + tt * d[k], [d[k]]);
            let v = t.eval(p(0), p(1), p(2));
            assert!(
                enclosure.v.contains(v.v) && enclosure.d[0].contains(v.d[0]),
                "t = {tt}"
            );
        }
    }
}
