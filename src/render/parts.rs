//! Films that merge: a render of a crop of the frame and of a range of sample
//! numbers, with exact per-pixel sums, so that crops assemble into the frame
//! and sample ranges combine into one render of all their samples, bit for
//! bit.
//!
//! Floating-point addition is not associative: summing samples 0..32 and
//! 32..64 apart and adding the two sums rounds differently from summing
//! 0..64 in one go. So each sample's radiance is rounded once, to a multiple
//! of 2^−[`SUM_FRACTION_BITS`], and summed as a 128-bit integer, whose
//! addition is exact: any split of the samples gives the same sums, and the
//! pixel's mean is computed from them in one fixed way.

use super::film::Image;
use crate::math::Color;
use crate::settings::{MAX_IMAGE_SIDE, MAX_PIXELS, Rect, SampleRange};
use std::fmt::Write;

/// Fixed-point fraction bits of a sample in a [`SampleSum`]: samples are
/// rounded to multiples of 2^−48 ≈ 3.6·10^−15 (exact for every f32 from
/// 2^−25 ≈ 3·10^−8 up).
pub const SUM_FRACTION_BITS: u32 = 48;

/// Largest sample value a sum holds, 2^47 ≈ 1.4·10^14; larger samples are
/// clamped to it. With at most 2^32 samples per pixel (sample numbers are
/// 32-bit), a sum stays below 2^127.
pub const MAX_SAMPLE_VALUE: f32 = (1u64 << 47) as f32;

const SCALE: f64 = (1u64 << SUM_FRACTION_BITS) as f64;

/// The exact sum of a pixel's samples, per channel, in units of 2^−48.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SampleSum(pub [u128; 3]);

impl SampleSum {
    /// Adds one sample (finite, ≥ 0; anything else counts as 0). A sample
    /// adds less than 2^95, and a pixel has at most 2^32 samples, so a sum
    /// stays below 2^127 and cannot overflow.
    #[inline]
    pub fn add_sample(&mut self, c: Color) {
        for (s, v) in self.0.iter_mut().zip(c.to_array()) {
            *s = s.wrapping_add(quantise(v));
        }
    }

    /// Adds another sum (of other samples of the same pixel; together at
    /// most 2^32 samples, which [`plan_merge`] checks).
    #[inline]
    pub fn add(&mut self, other: &SampleSum) {
        for (s, o) in self.0.iter_mut().zip(other.0) {
            *s = s.wrapping_add(o);
        }
    }

    /// The mean of `count` samples: each channel's sum, converted to f64
    /// (rounded to nearest), scaled by 2^−48, divided by `count` and rounded
    /// to f32. One sample of an f32 value from 2^−25 to 2^47 gives that
    /// value back exactly.
    #[inline]
    pub fn mean(&self, count: u64) -> Color {
        // Scaling by a power of two is exact, so multiplying by 2^−48 is
        // dividing by 2^48; and dividing by 1 changes nothing (so it is not
        // done: the branch is taken once, not per channel).
        let x = self.0.map(|s| to_f64(s) * (1.0 / SCALE));
        if count <= 1 {
            Color::new(x[0] as f32, x[1] as f32, x[2] as f32)
        } else {
            let n = count as f64;
            Color::new((x[0] / n) as f32, (x[1] / n) as f32, (x[2] / n) as f32)
        }
    }

    /// What [`SampleSum::add_sample`] of `c` into an empty sum, then
    /// [`SampleSum::mean`] of 1, gives (a render of one sample per pixel
    /// that keeps no sums): each channel clamped to [0,
    /// [`MAX_SAMPLE_VALUE`]] (NaN to 0), and below 2^−25 rounded to a
    /// multiple of 2^−48. From 2^−25 up every f32 is such a multiple, so
    /// where no channel is below it (the usual case) the integers are
    /// skipped.
    #[inline]
    pub fn mean_of_one(c: Color) -> Color {
        const SMALL: f32 = 1.0 / (1u32 << 25) as f32;
        // All channels at once where none needs rounding: `max` gives its
        // second operand for NaN and for −0, so NaN and −0 become +0 as in
        // `quantise`.
        let v = c.max(Color::ZERO).min(Color::splat(MAX_SAMPLE_VALUE));
        if (v.cmpge(Color::splat(SMALL)) | v.cmpeq(Color::ZERO)).all() {
            return v;
        }
        // Values below 2^−25 (rare): through the integers.
        let mut sum = SampleSum::default();
        sum.add_sample(c);
        sum.mean(1)
    }
}

/// `v` rounded to the nearest multiple of 2^−48 (halves up), as an
/// integer; `v` clamped to [0, [`MAX_SAMPLE_VALUE`]] first (NaN counts as
/// 0). Conversions between floats and 128-bit integers are slow software
/// routines, so values below 2^16 (all but the brightest) go through `u64`.
#[inline]
fn quantise(v: f32) -> u128 {
    let v = if v > 0.0 {
        v.min(MAX_SAMPLE_VALUE)
    } else {
        0.0
    };
    // Exact: an f32 times a power of two fits an f64.
    let x = v as f64 * SCALE;
    const TWO_52: f64 = (1u64 << 52) as f64;
    const TWO_64: f64 = 18_446_744_073_709_551_616.0;
    if x < TWO_52 {
        // x + 0.5 is exact here, and truncation rounds it down. Through
        // `i64` (it fits): one instruction, where `u64` takes a branch.
        (x + 0.5) as i64 as u64 as u128
    } else if x < TWO_64 {
        // From 2^52 up, every f64 is a whole number.
        x as u64 as u128
    } else {
        x as u128
    }
}

/// `s` as an f64: exact to nearest below 2^64, where it goes through `u64`
/// (a sum of samples below 2^16 each); above, as `hi·2^64 + lo` (two
/// roundings, still one fixed function of `s`). Conversions from 128-bit
/// integers are slow software routines, which this avoids.
#[inline]
fn to_f64(s: u128) -> f64 {
    let (hi, lo) = ((s >> 64) as u64, s as u64);
    if s < 1 << 63 {
        // Through `i64`: one instruction, where `u64` takes a branch.
        lo as i64 as f64
    } else if hi == 0 {
        lo as f64
    } else {
        hi as f64 * 18_446_744_073_709_551_616.0 + lo as f64
    }
}

/// What a film covers: the frame it belongs to, its pixels, its samples, and
/// a fingerprint of the scene and settings that made it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FilmHeader {
    /// The whole frame (the EXR display window).
    pub width: u32,
    pub height: u32,
    /// The pixels held (the EXR data window).
    pub rect: Rect,
    pub samples: SampleRange,
    /// Identifies the scene and the settings that change pixels; parts with
    /// different fingerprints belong to different renders. Empty if unknown.
    pub fingerprint: String,
}

/// A rendered crop: its pixels' means and, for merging, their exact sums.
#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    pub header: FilmHeader,
    /// The means, `rect.width() × rect.height()`, row by row.
    pub image: Image,
    /// The sums, in the same order; empty if the render did not keep them.
    pub sums: Vec<SampleSum>,
    /// The output variables asked for, and every pixel's (in the same order;
    /// empty without AOVs). Merging keeps the AOVs every part has.
    pub aovs: Vec<super::aov::Aov>,
    pub aov_pixels: Vec<super::aov::AovPixel>,
}

/// Why parts cannot be merged. The message names the files.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct MergeError(pub String);

/// Checks that `parts` (a name for messages, and a header each) fit together
/// into one film, and returns that film's header.
///
/// Refused: no parts; different frames or fingerprints; two parts holding
/// the same sample of the same pixel (overlapping crops, duplicated sample
/// ranges, a file given twice); and pixels that lack samples that others have
/// (missing parts, gaps between ranges). The merged film holds the common
/// crop if every part has the same one, otherwise the whole frame.
pub fn plan_merge(parts: &[(String, FilmHeader)]) -> Result<FilmHeader, MergeError> {
    let Some((first_name, first)) = parts.first() else {
        return Err(MergeError("no parts to merge".into()));
    };
    for (name, h) in &parts[1..] {
        if (h.width, h.height) != (first.width, first.height) {
            return Err(MergeError(format!(
                "`{name}` is part of a {}×{} frame, but `{first_name}` of a {}×{} one",
                h.width, h.height, first.width, first.height
            )));
        }
        if h.fingerprint != first.fingerprint {
            return Err(MergeError(format!(
                "`{name}` and `{first_name}` come from different scenes or settings (fingerprints {} and {})",
                h.fingerprint, first.fingerprint
            )));
        }
    }
    for (i, (a_name, a)) in parts.iter().enumerate() {
        for (b_name, b) in &parts[i + 1..] {
            if let Some(common) = a.rect.intersect(&b.rect)
                && a.samples.overlaps(&b.samples)
            {
                let what = if a.samples == b.samples && a.rect == b.rect {
                    "the same pixels and samples (a part given twice?)".to_string()
                } else if a.samples == b.samples {
                    format!("overlapping crops ({common})")
                } else {
                    format!(
                        "overlapping sample ranges ({} and {}) of pixels {common}",
                        a.samples, b.samples
                    )
                };
                return Err(MergeError(format!("`{a_name}` and `{b_name}` hold {what}")));
            }
        }
    }

    let rect = if parts.iter().all(|(_, h)| h.rect == first.rect) {
        first.rect
    } else {
        Rect::full(first.width, first.height)
    };
    let start = parts
        .iter()
        .map(|(_, h)| h.samples.start)
        .min()
        .unwrap_or(0);
    let end = parts
        .iter()
        .map(|(_, h)| h.samples.end())
        .max()
        .unwrap_or(0);
    let total = end - start as u64;
    let count = u32::try_from(total).map_err(|_| {
        MergeError(format!(
            "the parts' samples {start}..{end} are more than 2^32 − 1 in all"
        ))
    })?;
    let span = SampleRange { start, count };

    // Every pixel must have every sample of the span: as no two parts share
    // a sample of a pixel, that holds where a pixel's counts add up to it.
    let mut counts: Vec<u64> = Vec::new();
    counts
        .try_reserve_exact(rect.area() as usize)
        .map_err(|_| MergeError(format!("not enough memory to check {rect}")))?;
    counts.resize(rect.area() as usize, 0);
    let w = rect.width() as usize;
    for (_, h) in parts {
        for y in h.rect.y0..h.rect.y1 {
            let row = (y - rect.y0) as usize * w;
            let (a, b) = (
                row + (h.rect.x0 - rect.x0) as usize,
                row + (h.rect.x1 - rect.x0) as usize,
            );
            for c in &mut counts[a..b] {
                *c += h.samples.count as u64;
            }
        }
    }
    if let Some(i) = counts.iter().position(|&c| c != total) {
        let (x, y) = (rect.x0 + (i % w) as u32, rect.y0 + (i / w) as u32);
        let mut holders = String::new();
        for (name, h) in parts {
            if (h.rect.x0..h.rect.x1).contains(&x) && (h.rect.y0..h.rect.y1).contains(&y) {
                let sep = if holders.is_empty() { "" } else { ", " };
                let _ = write!(holders, "{sep}{} in `{name}`", h.samples);
            }
        }
        if holders.is_empty() {
            holders = "no part covers it".into();
        }
        return Err(MergeError(format!(
            "parts are missing: pixel ({x}, {y}) has {} of the samples {span} ({holders})",
            counts[i]
        )));
    }
    Ok(FilmHeader {
        width: first.width,
        height: first.height,
        rect,
        samples: span,
        fingerprint: first.fingerprint.clone(),
    })
}

/// Adds parts' sums into a film, then computes its means. Output variables
/// that every part has are merged too: counts add, and the first hit's
/// layers come from the part that holds each pixel's first sample.
pub struct Merger {
    header: FilmHeader,
    sums: Vec<SampleSum>,
    /// The AOVs every part added so far has (`None` before the first).
    aovs: Option<Vec<super::aov::Aov>>,
    aov_pixels: Vec<super::aov::AovPixel>,
}

impl Merger {
    /// An empty film for `header` (from [`plan_merge`]); `None` if its sums
    /// cannot be allocated.
    pub fn new(header: FilmHeader) -> Option<Merger> {
        let n = header.rect.area() as usize;
        let mut sums = Vec::new();
        sums.try_reserve_exact(n).ok()?;
        sums.resize(n, SampleSum::default());
        Some(Merger {
            header,
            sums,
            aovs: None,
            aov_pixels: Vec::new(),
        })
    }

    /// Adds `part`'s sums, pixel by pixel. The part must be one of those
    /// planned (inside the merged rectangle, with sums).
    pub fn add(&mut self, part: &Film) {
        let (r, w) = (part.header.rect, self.header.rect.width() as usize);
        let pw = r.width() as usize;
        for y in r.y0..r.y1 {
            let row =
                (y - self.header.rect.y0) as usize * w + (r.x0 - self.header.rect.x0) as usize;
            let src = &part.sums[(y - r.y0) as usize * pw..][..pw];
            for (dst, s) in self.sums[row..row + pw].iter_mut().zip(src) {
                dst.add(s);
            }
        }
        let kept = self.aovs.get_or_insert_with(|| part.aovs.clone());
        kept.retain(|a| part.aovs.contains(a));
        if kept.is_empty() || part.aov_pixels.len() != pw * r.height() as usize {
            kept.clear();
            return;
        }
        if self.aov_pixels.is_empty() {
            let n = self.header.rect.area() as usize;
            if self.aov_pixels.try_reserve_exact(n).is_err() {
                kept.clear();
                return;
            }
            self.aov_pixels.resize(n, Default::default());
        }
        let first = part.header.samples.start == self.header.samples.start;
        for y in r.y0..r.y1 {
            let row =
                (y - self.header.rect.y0) as usize * w + (r.x0 - self.header.rect.x0) as usize;
            let src = &part.aov_pixels[(y - r.y0) as usize * pw..][..pw];
            for (dst, s) in self.aov_pixels[row..row + pw].iter_mut().zip(src) {
                dst.merge(s, first);
            }
        }
    }

    /// Declares that the merged samples are the first `count` of the planned
    /// range (a progressive render that stopped early).
    pub fn set_sample_count(&mut self, count: u32) {
        self.header.samples.count = count;
    }

    /// The merged film; its means computed from the summed sums.
    pub fn finish(self) -> Film {
        let count = self.header.samples.count as u64;
        let mut image = Image::new(self.header.rect.width(), self.header.rect.height());
        for (p, s) in image.pixels.iter_mut().zip(&self.sums) {
            *p = s.mean(count);
        }
        let aovs = self.aovs.unwrap_or_default();
        let aov_pixels = if aovs.is_empty() {
            Vec::new()
        } else {
            self.aov_pixels
        };
        Film {
            header: self.header,
            image,
            sums: self.sums,
            aovs,
            aov_pixels,
        }
    }
}

/// Merges films in memory (see [`plan_merge`]); each must have its sums.
pub fn merge(parts: &[(String, &Film)]) -> Result<Film, MergeError> {
    for (name, f) in parts {
        if f.sums.len() as u64 != f.header.rect.area() {
            return Err(MergeError(format!("`{name}` has no sample sums to merge")));
        }
    }
    let headers: Vec<(String, FilmHeader)> = parts
        .iter()
        .map(|(n, f)| (n.clone(), f.header.clone()))
        .collect();
    let header = plan_merge(&headers)?;
    let mut merger = Merger::new(header)
        .ok_or_else(|| MergeError("not enough memory for the merged film".into()))?;
    for (_, f) in parts {
        merger.add(f);
    }
    Ok(merger.finish())
}

/// Checks a header read from a file: a frame within the size limits, and a
/// crop and sample range inside it.
pub fn check_header(h: &FilmHeader) -> Result<(), String> {
    let side = 1..=MAX_IMAGE_SIDE;
    if !side.contains(&h.width)
        || !side.contains(&h.height)
        || h.width as u64 * h.height as u64 > MAX_PIXELS
    {
        return Err(format!(
            "its frame, {}×{}, is outside glint's limits",
            h.width, h.height
        ));
    }
    if h.rect.is_empty() || h.rect.intersect(&Rect::full(h.width, h.height)) != Some(h.rect) {
        return Err(format!(
            "its pixels ({}) are not inside its {}×{} frame",
            h.rect, h.width, h.height
        ));
    }
    if h.samples.count == 0 || h.samples.end() > 1 << 32 {
        return Err(format!(
            "its sample range {} is empty or too long",
            h.samples
        ));
    }
    Ok(())
}

/// A fingerprint of a render's inputs: FNV-1a (Fowler, Noll, Vo), 64-bit,
/// over `pieces`, each preceded by its length (so that pieces cannot run
/// into each other), as 16 hexadecimal digits. Not cryptographic: it tells
/// apart parts of different renders, it does not guard against forgery.
pub fn fingerprint(pieces: &[&[u8]]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h ^= b as u64;
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    };
    for p in pieces {
        eat(&(p.len() as u64).to_le_bytes());
        eat(p);
    }
    format!("{h:016x}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fingerprints_tell_inputs_apart() {
        assert_eq!(fingerprint(&[]), "cbf29ce484222325");
        assert_eq!(fingerprint(&[b"a"]), fingerprint(&[b"a"]));
        assert_ne!(fingerprint(&[b"ab", b"c"]), fingerprint(&[b"a", b"bc"]));
        assert_ne!(
            fingerprint(&[b"scene", b"640"]),
            fingerprint(&[b"scene", b"641"])
        );
    }

    #[test]
    fn one_sample_comes_back_exactly() {
        // Every value from 2^−25 (≈ 3·10^−8) to 2^47.
        for v in [0.0f32, 1.0, 0.1, 0.7354, 1.2e-7, 123456.78, 1.0e14] {
            let mut s = SampleSum::default();
            s.add_sample(Color::new(v, v * 0.5, v * 0.25));
            assert_eq!(s.mean(1), Color::new(v, v * 0.5, v * 0.25), "{v}");
        }
    }

    #[test]
    fn the_mean_of_one_sample_is_the_sums_bit_for_bit() {
        let mut rng = crate::render::Pcg32::new(3, 9);
        let mut values = vec![
            0.0f32,
            -0.0,
            -1.0,
            f32::NAN,
            f32::INFINITY,
            f32::MAX,
            MAX_SAMPLE_VALUE,
            1.0 / (1u32 << 25) as f32,
            f32::MIN_POSITIVE,
            1e-45,
            1.5 / (1u64 << 48) as f32,
            2.5 / (1u64 << 48) as f32,
        ];
        // Every binade that matters, with random mantissas.
        for e in -60..50 {
            for _ in 0..40 {
                values.push((1.0 + rng.next_f32()) * 2f32.powi(e));
            }
        }
        for v in values {
            let c = Color::new(v, v * 0.75, -v);
            let mut s = SampleSum::default();
            s.add_sample(c);
            assert_eq!(
                SampleSum::mean_of_one(c).to_array().map(f32::to_bits),
                s.mean(1).to_array().map(f32::to_bits),
                "{v:e}"
            );
        }
    }

    #[test]
    fn sums_are_clamped_and_exact_under_any_split() {
        let mut s = SampleSum::default();
        s.add_sample(Color::new(f32::MAX, -1.0, f32::NAN));
        assert_eq!(s.mean(1), Color::new(MAX_SAMPLE_VALUE, 0.0, 0.0));
        let samples: Vec<Color> = (0..64)
            .map(|i| Color::splat((i as f32 * 0.37).sin().abs() * 10f32.powi(i % 9 - 4)))
            .collect();
        let sum = |r: std::ops::Range<usize>| {
            let mut s = SampleSum::default();
            samples[r].iter().for_each(|&c| s.add_sample(c));
            s
        };
        let whole = sum(0..64);
        // The fast paths agree with the plain conversions.
        for v in [
            0.0f32, 1e-20, 3.0e-15, 0.3, 15.99, 16.0, 31.5, 65535.9, 65536.0, 1e9, 1.4e14,
        ] {
            let plain = (v.min(MAX_SAMPLE_VALUE) as f64 * SCALE).round() as u128;
            assert_eq!(quantise(v), plain, "{v}");
            if plain >> 64 == 0 {
                assert_eq!(to_f64(plain), plain as f64);
            }
        }
        let big = (1u128 << 100) + 12345;
        assert!((to_f64(big) / big as f64 - 1.0).abs() < 1e-15);
        for k in [1, 17, 32, 63] {
            let mut a = sum(0..k);
            a.add(&sum(k..64));
            assert_eq!(a, whole);
            assert_eq!(
                a.mean(64).to_array().map(f32::to_bits),
                whole.mean(64).to_array().map(f32::to_bits)
            );
        }
    }

    fn header(rect: Rect, start: u32, count: u32) -> FilmHeader {
        FilmHeader {
            width: 8,
            height: 6,
            rect,
            samples: SampleRange { start, count },
            fingerprint: "f".into(),
        }
    }

    fn plan(parts: &[FilmHeader]) -> Result<FilmHeader, MergeError> {
        let named: Vec<(String, FilmHeader)> = parts
            .iter()
            .enumerate()
            .map(|(i, h)| (format!("p{i}"), h.clone()))
            .collect();
        plan_merge(&named)
    }

    #[test]
    fn merge_plans_accept_tilings_and_ranges() {
        let tiles: Vec<FilmHeader> = (0..6)
            .map(|k| header(Rect::tile(8, 6, 3, 2, k).unwrap(), 0, 4))
            .collect();
        let h = plan(&tiles).unwrap();
        assert_eq!(
            (h.rect, h.samples),
            (Rect::full(8, 6), SampleRange { start: 0, count: 4 })
        );
        let crop = Rect {
            x0: 1,
            x1: 3,
            y0: 2,
            y1: 5,
        };
        let h = plan(&[header(crop, 8, 8), header(crop, 0, 8)]).unwrap();
        assert_eq!(
            (h.rect, h.samples),
            (
                crop,
                SampleRange {
                    start: 0,
                    count: 16
                }
            )
        );
    }

    #[test]
    fn merge_plans_refuse_what_does_not_fit() {
        let t = |k| Rect::tile(8, 6, 2, 2, k).unwrap();
        let err = |parts: &[FilmHeader]| plan(parts).unwrap_err().0;
        assert!(err(&[]).contains("no parts"));
        let mut other = header(t(1), 0, 4);
        other.fingerprint = "g".into();
        assert!(err(&[header(t(0), 0, 4), other]).contains("different scenes"));
        let mut other = header(t(1), 0, 4);
        other.width = 9;
        assert!(err(&[header(t(0), 0, 4), other]).contains("9×6 frame"));
        assert!(err(&[header(t(0), 0, 4), header(t(0), 0, 4)]).contains("given twice"));
        let wide = Rect {
            x0: 0,
            x1: 5,
            y0: 0,
            y1: 3,
        };
        assert!(err(&[header(t(0), 0, 4), header(wide, 0, 4)]).contains("overlapping crops"));
        assert!(
            err(&[header(t(0), 0, 4), header(t(0), 2, 4)])
                .contains("overlapping sample ranges (0..4 and 2..6)")
        );
        let missing = err(&[header(t(0), 0, 4), header(t(1), 0, 4), header(t(2), 0, 4)]);
        assert!(
            missing.contains("pixel (4, 3) has 0 of the samples 0..4 (no part covers it)"),
            "{missing}"
        );
        let gap = err(&[header(t(0), 0, 4), header(t(0), 8, 4)]);
        assert!(
            gap.contains("has 8 of the samples 0..12 (0..4 in `p0`, 8..12 in `p1`)"),
            "{gap}"
        );
    }
}
