//! Linear radiance to 8-bit sRGB: the transfer function of IEC 61966-2-1,
//! and a table that gives the same bytes without a `powf` per channel (a
//! 1080p frame has six million channels; the viewer converts every frame).

use std::sync::OnceLock;

/// The sRGB transfer function: `12.92·v` below 0.0031308, else
/// `1.055·v^(1/2.4) − 0.055`; input clamped to [0, 1] (NaN gives 0).
pub fn srgb_encode(v: f32) -> f32 {
    let v = if v > 0.0 { v.min(1.0) } else { 0.0 };
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// A linear channel as an 8-bit sRGB value, rounded: the definition, one
/// `powf` per call. [`srgb8`] gives the same byte faster.
pub fn srgb8_exact(v: f32) -> u8 {
    (srgb_encode(v) * 255.0 + 0.5) as u8
}

/// Bits of an f32 dropped to find its bucket: 16 leaves the exponent and
/// the top 7 bits of the mantissa, so [0, 1] spans 16,257 buckets (a byte
/// each), none of which spans a whole code: the slope of the encoding,
/// steepest at each bucket's start, times the bucket's width stays below
/// 0.9 codes (`Table::new` checks that at most one threshold lies inside).
const BUCKET_SHIFT: u32 = 16;
const BUCKETS: usize = (1.0f32.to_bits() >> BUCKET_SHIFT) as usize + 1;

/// For [`srgb8`]: `first[b]`, the code of the smallest value of bucket `b`,
/// and `threshold[k]`, the smallest value whose code is at least `k`.
struct Table {
    first: Vec<u8>,
    threshold: [f32; 258],
}

impl Table {
    /// Built from [`srgb8_exact`], which is non-decreasing in `v`
    /// (`powf`, the products and the rounding all are): each threshold by
    /// bisection over the bit patterns of [0, 1], which order as the values
    /// do. About 12,000 calls of `powf`, once per process.
    fn new() -> Table {
        let mut threshold = [f32::INFINITY; 258];
        threshold[0] = f32::NEG_INFINITY;
        for (k, t) in threshold.iter_mut().enumerate().take(256).skip(1) {
            // The first bit pattern whose code reaches k.
            let (mut lo, mut hi) = (0u32, 1.0f32.to_bits() + 1);
            while lo < hi {
                let mid = lo + (hi - lo) / 2;
                if (srgb8_exact(f32::from_bits(mid)) as usize) < k {
                    lo = mid + 1;
                } else {
                    hi = mid;
                }
            }
            *t = f32::from_bits(lo);
        }
        let first: Vec<u8> = (0..BUCKETS)
            .map(|b| srgb8_exact(f32::from_bits((b as u32) << BUCKET_SHIFT)))
            .collect();
        // One step up at most within a bucket: the threshold after the
        // next lies past the bucket's end.
        for (b, &k) in first.iter().enumerate() {
            let end = f32::from_bits((b as u32 + 1) << BUCKET_SHIFT);
            assert!(
                threshold[k as usize + 2] >= end,
                "sRGB table: bucket {b} holds two thresholds"
            );
        }
        Table { first, threshold }
    }
}

fn table() -> &'static Table {
    static TABLE: OnceLock<Table> = OnceLock::new();
    TABLE.get_or_init(Table::new)
}

/// [`srgb8_exact`], bit for bit, by table: the clamped value's bucket gives
/// a first code, one more where the value reaches the next code's
/// threshold. No branch, no `powf`.
#[inline]
pub fn srgb8(v: f32) -> u8 {
    srgb8_with(table(), v)
}

#[inline]
fn srgb8_with(t: &Table, v: f32) -> u8 {
    // As srgb_encode clamps: NaN and negatives to 0 (+0.0, bucket 0).
    let v = if v > 0.0 { v.min(1.0) } else { 0.0 };
    let k = t.first[(v.to_bits() >> BUCKET_SHIFT) as usize] as usize;
    (k + (v >= t.threshold[k + 1]) as usize) as u8
}

/// Every channel of `pixels` as 8-bit sRGB, three bytes per pixel.
pub fn srgb8_pixels(pixels: &[crate::math::Color], out: &mut Vec<u8>) {
    let t = table();
    let start = out.len();
    out.resize(start + 3 * pixels.len(), 0);
    for (rgb, c) in out[start..].chunks_exact_mut(3).zip(pixels) {
        rgb[0] = srgb8_with(t, c.x);
        rgb[1] = srgb8_with(t, c.y);
        rgb[2] = srgb8_with(t, c.z);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encoding_matches_the_standard() {
        assert_eq!(srgb_encode(0.0), 0.0);
        assert!((srgb_encode(1.0) - 1.0).abs() < 1e-6);
        assert_eq!(srgb_encode(2.0), srgb_encode(1.0));
        assert_eq!(srgb_encode(f32::NAN), 0.0);
        assert!((srgb_encode(0.18) - 0.4613).abs() < 1e-3);
        assert!((srgb_encode(0.003) - 0.03876).abs() < 1e-4);
    }

    /// The table against the definition where it can go wrong: a few
    /// hundred bit patterns either side of every threshold, every bucket's
    /// ends, a stride through all of [0, 1], and values outside it.
    #[test]
    fn table_gives_the_exact_bytes() {
        let t = table();
        let check = |bits: u32| {
            let v = f32::from_bits(bits);
            assert_eq!(srgb8_with(t, v), srgb8_exact(v), "{v:e} ({bits:#x})");
        };
        for k in 1..256 {
            let b = t.threshold[k].to_bits();
            for bits in b.saturating_sub(300)..=b + 300 {
                check(bits.min(1.0f32.to_bits()));
            }
        }
        for b in 0..BUCKETS as u32 {
            check(b << BUCKET_SHIFT);
            check(((b + 1) << BUCKET_SHIFT) - 1);
        }
        for bits in (0..=1.0f32.to_bits()).step_by(4099) {
            check(bits);
        }
        for v in [
            -0.0,
            -1.0,
            f32::NAN,
            -f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            1.5,
            f32::MAX,
            f32::from_bits(1),
        ] {
            assert_eq!(srgb8_with(t, v), srgb8_exact(v), "{v}");
        }
        // The codes are all reached, in order.
        assert_eq!(srgb8(0.0), 0);
        assert_eq!(srgb8(1.0), 255);
        assert!(t.threshold[1..256].windows(2).all(|w| w[0] < w[1]));
    }

    /// Every f32 in [0, 1] (about a billion; seconds in release, too slow
    /// for a debug build): `cargo test --release -- --ignored srgb`.
    #[test]
    #[ignore]
    fn table_gives_the_exact_bytes_everywhere() {
        let t = table();
        for bits in 0..=1.0f32.to_bits() {
            let v = f32::from_bits(bits);
            assert_eq!(srgb8_with(t, v), srgb8_exact(v), "{v:e}");
        }
    }
}
