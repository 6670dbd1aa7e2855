//! The formula language: any text, parsed and compiled; then evaluated at a
//! point and over a box holding it, where the interval result must enclose
//! the point's value (the root finder's guarantee rests on it), and with
//! derivatives.
#![no_main]

use glint::geometry::implicit::{Dual, Tape, parse};
use glint::math::Interval;
use libfuzzer_sys::fuzz_target;

/// The input: three pairs of box ends (i16, in thousandths), where the point
/// lies in the box (three u16 fractions), then the formula's text.
const HEAD: usize = 18;

fuzz_target!(|data: &[u8]| {
    if data.len() < HEAD {
        return;
    }
    let word = |k: usize| [data[2 * k], data[2 * k + 1]];
    let formula = String::from_utf8_lossy(&data[HEAD..]);
    let Ok(expr) = parse(&formula) else {
        return;
    };
    let Ok(tape) = Tape::compile(&expr) else {
        return;
    };
    let mut boxes = [Interval::new(0.0, 0.0); 3];
    let mut point = [0.0f64; 3];
    for k in 0..3 {
        let a = i16::from_le_bytes(word(2 * k)) as f64 / 1000.0;
        let b = i16::from_le_bytes(word(2 * k + 1)) as f64 / 1000.0;
        let (lo, hi) = (a.min(b), a.max(b));
        boxes[k] = Interval::new(lo, hi);
        let s = u16::from_le_bytes(word(6 + k)) as f64 / u16::MAX as f64;
        point[k] = (lo + (hi - lo) * s).clamp(lo, hi);
    }
    // Where the formula is defined at the point (its interval evaluation
    // there is not empty: no division by zero, no root of a negative), the
    // interval over the box holds the point's f64 value: the root finder
    // rests on it. Where it is undefined, f64 may still give a number
    // (9/0·y^0 = inf^0 = 1), which the root finder rightly ignores. (The
    // point's own interval is no reference: where an operation overflows,
    // [inf, inf] makes it looser than the box's.)
    let value = tape.eval(point[0], point[1], point[2]);
    let at_point = tape.eval(
        Interval::point(point[0]),
        Interval::point(point[1]),
        Interval::point(point[2]),
    );
    let range = tape.eval(boxes[0], boxes[1], boxes[2]);
    if !at_point.is_empty() && value.is_finite() {
        assert!(
            range.contains(value),
            "f{point:?} = {value} is outside the interval {range:?} over {boxes:?}"
        );
    }
    let _ = tape.eval(
        Dual::new(point[0], [1.0, 0.0, 0.0]),
        Dual::new(point[1], [0.0, 1.0, 0.0]),
        Dual::new(point[2], [0.0, 0.0, 1.0]),
    );
});
