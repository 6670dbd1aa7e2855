//! Pictures of AOV layers: false-colour heat maps with a scale bar whose
//! numbers can be read, normal maps, albedo and object ids, as 8-bit RGB.

use super::aov::{Aov, AovPixel, normal_color};
use super::srgb::srgb8;

/// An 8-bit RGB picture, row-major.
pub struct Picture {
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<u8>,
}

/// Control points of the colour scale, evenly spaced from low to high: a
/// perceptually ordered black–purple–red–orange–yellow ramp (after the
/// shape of matplotlib's "inferno"), readable in grey print too.
const RAMP: [[f32; 3]; 8] = [
    [0.0, 0.0, 4.0],
    [40.0, 11.0, 84.0],
    [101.0, 21.0, 110.0],
    [159.0, 42.0, 99.0],
    [212.0, 72.0, 66.0],
    [245.0, 125.0, 21.0],
    [250.0, 193.0, 39.0],
    [252.0, 255.0, 164.0],
];

/// The colour of `t ∈ [0, 1]` on the ramp (linear between control points).
pub fn heat_color(t: f64) -> [u8; 3] {
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let x = t * (RAMP.len() - 1) as f64;
    let i = (x.floor() as usize).min(RAMP.len() - 2);
    let f = (x - i as f64) as f32;
    let (a, b) = (RAMP[i], RAMP[i + 1]);
    [0, 1, 2].map(|k| (a[k] + (b[k] - a[k]) * f).round() as u8)
}

/// 3×5 bitmaps of the characters a scale label needs, row by row (bit 2 is
/// the left column).
fn glyph(c: char) -> Option<[u8; 5]> {
    Some(match c {
        '0' => [0b111, 0b101, 0b101, 0b101, 0b111],
        '1' => [0b010, 0b110, 0b010, 0b010, 0b111],
        '2' => [0b111, 0b001, 0b111, 0b100, 0b111],
        '3' => [0b111, 0b001, 0b111, 0b001, 0b111],
        '4' => [0b101, 0b101, 0b111, 0b001, 0b001],
        '5' => [0b111, 0b100, 0b111, 0b001, 0b111],
        '6' => [0b111, 0b100, 0b111, 0b101, 0b111],
        '7' => [0b111, 0b001, 0b010, 0b010, 0b010],
        '8' => [0b111, 0b101, 0b111, 0b101, 0b111],
        '9' => [0b111, 0b101, 0b111, 0b001, 0b111],
        '.' => [0b000, 0b000, 0b000, 0b000, 0b010],
        '-' => [0b000, 0b000, 0b111, 0b000, 0b000],
        'e' => [0b000, 0b111, 0b111, 0b100, 0b111],
        _ => return None,
    })
}

/// Pixels per font dot.
const DOT: u32 = 2;
/// Height of the scale bar's area below the picture.
const BAR_AREA: u32 = 12 + 5 * DOT + 8;

impl Picture {
    fn new(width: u32, height: u32) -> Picture {
        Picture {
            width,
            height,
            rgb: vec![255; width as usize * height as usize * 3],
        }
    }

    fn set(&mut self, x: u32, y: u32, c: [u8; 3]) {
        if x < self.width && y < self.height {
            let i = (y as usize * self.width as usize + x as usize) * 3;
            self.rgb[i..i + 3].copy_from_slice(&c);
        }
    }

    /// Writes `text` with its top-left corner at `(x, y)`.
    fn text(&mut self, x: u32, y: u32, text: &str) {
        for (i, c) in text.chars().enumerate() {
            let Some(rows) = glyph(c) else { continue };
            let x0 = x + i as u32 * 4 * DOT;
            for (r, bits) in rows.iter().enumerate() {
                for col in 0..3 {
                    if bits >> (2 - col) & 1 == 1 {
                        for dy in 0..DOT {
                            for dx in 0..DOT {
                                self.set(x0 + col * DOT + dx, y + r as u32 * DOT + dy, [0; 3]);
                            }
                        }
                    }
                }
            }
        }
    }

    fn text_width(text: &str) -> u32 {
        (text.chars().count() as u32 * 4).saturating_sub(1) * DOT
    }
}

/// A number as a short label: whole numbers as they are, others with three
/// significant digits.
pub fn label(v: f64) -> String {
    if v == v.round() && v.abs() < 1e9 {
        format!("{}", v as i64)
    } else if v.abs() >= 0.01 && v.abs() < 1e5 {
        let digits = (2 - v.abs().log10().floor() as i32).max(0) as usize;
        format!("{v:.digits$}")
    } else {
        format!("{v:.2e}")
    }
}

/// `values` (row-major, `width × height`) in false colour from 0 to their
/// maximum, above a scale bar labelled 0, half the maximum and the maximum.
pub fn heat_map(values: &[f64], width: u32, height: u32) -> Picture {
    let max = values
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0f64, f64::max);
    let mut p = Picture::new(width, height + BAR_AREA);
    for (i, &v) in values.iter().enumerate() {
        let t = if max > 0.0 { v / max } else { 0.0 };
        p.set(i as u32 % width, i as u32 / width, heat_color(t));
    }
    // The bar: the ramp across the width, 12 px high, 4 px below the picture.
    let bar_top = height + 4;
    let inner = width.saturating_sub(2).max(1);
    for x in 0..width {
        let t = x.saturating_sub(1) as f64 / (inner - 1).max(1) as f64;
        for y in bar_top..bar_top + 8 {
            p.set(x, y, heat_color(t));
        }
    }
    let y = bar_top + 10;
    let (lo, mid, hi) = (label(0.0), label(max / 2.0), label(max));
    p.text(1, y, &lo);
    let mid_w = Picture::text_width(&mid);
    if width > 3 * mid_w {
        p.text(width / 2 - mid_w / 2, y, &mid);
    }
    let hi_w = Picture::text_width(&hi);
    p.text(width.saturating_sub(hi_w + 1), y, &hi);
    p
}

/// The names of `aov`'s pictures (`OUT.NAME.png`), in the order of
/// [`aov_pictures`].
pub fn picture_names(aov: Aov) -> &'static [&'static str] {
    match aov {
        Aov::Depth => &["depth"],
        Aov::Normal => &["normal"],
        Aov::Albedo => &["albedo"],
        Aov::Id => &["id"],
        Aov::Cost => &["cost-nodes", "cost-prims"],
        Aov::Rays => &["rays"],
        Aov::Evals => &["evals"],
    }
}

/// The pictures of `aov` over `pixels` (`width × height`), one for each of
/// its [`picture_names`]. Counts and depth are heat maps; normals are
/// `(n + 1)/2` as colours; albedo is sRGB; ids get a colour each.
pub fn aov_pictures(aov: Aov, pixels: &[AovPixel], width: u32, height: u32) -> Vec<Picture> {
    let heat = |f: &dyn Fn(&AovPixel) -> f64| {
        let v: Vec<f64> = pixels.iter().map(f).collect();
        heat_map(&v, width, height)
    };
    let colors = |f: &dyn Fn(&AovPixel) -> [u8; 3]| {
        let mut p = Picture::new(width, height);
        for (i, px) in pixels.iter().enumerate() {
            p.set(i as u32 % width, i as u32 / width, f(px));
        }
        p
    };
    let srgb = |c: [f32; 3]| c.map(srgb8);
    match aov {
        Aov::Depth => vec![heat(&|p| p.depth as f64)],
        Aov::Normal => vec![colors(&|p| {
            normal_color(p.normal)
                .to_array()
                .map(|v| (v * 255.0 + 0.5) as u8)
        })],
        Aov::Albedo => vec![colors(&|p| srgb(p.albedo))],
        Aov::Id => vec![colors(&|p| {
            if p.id == 0 {
                return [0; 3];
            }
            // A well-spread hue per id (golden-ratio steps), bright.
            let h = (p.id as f64 * 0.618_033_988_75).fract();
            let c = [0.0, 1.0 / 3.0, 2.0 / 3.0]
                .map(|o| 0.55 + 0.45 * (std::f64::consts::TAU * (h + o)).cos());
            c.map(|v| (v * 255.0) as u8)
        })],
        Aov::Cost => vec![heat(&|p| p.nodes as f64), heat(&|p| p.prims as f64)],
        Aov::Rays => vec![heat(&|p| p.rays.iter().map(|&r| r as f64).sum())],
        Aov::Evals => vec![heat(&|p| p.evals as f64)],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ramp_runs_dark_to_light() {
        assert_eq!(heat_color(0.0), [0, 0, 4]);
        assert_eq!(heat_color(1.0), [252, 255, 164]);
        assert_eq!(heat_color(f64::NAN), [0, 0, 4]);
        let luma = |c: [u8; 3]| 0.3 * c[0] as f64 + 0.59 * c[1] as f64 + 0.11 * c[2] as f64;
        for i in 0..100 {
            let (a, b) = (
                heat_color(i as f64 / 100.0),
                heat_color((i + 1) as f64 / 100.0),
            );
            assert!(luma(b) >= luma(a) - 1.0, "{i}: {a:?} {b:?}");
        }
    }

    #[test]
    fn every_aov_has_a_picture_per_name() {
        for aov in Aov::ALL {
            let pictures = aov_pictures(aov, &[AovPixel::default(); 6], 3, 2);
            assert_eq!(pictures.len(), picture_names(aov).len(), "{aov:?}");
        }
    }

    #[test]
    fn labels_are_short_and_drawable() {
        assert_eq!(label(0.0), "0");
        assert_eq!(label(1234.0), "1234");
        assert_eq!(label(6.25), "6.25");
        assert_eq!(label(12.345), "12.3");
        assert_eq!(label(0.5), "0.500");
        for v in [0.0, 1.5, 123.0, 1e-7, 3.3e12, 0.123] {
            assert!(label(v).chars().all(|c| glyph(c).is_some()), "{}", label(v));
        }
    }

    #[test]
    fn a_heat_map_has_its_bar_and_numbers() {
        let values: Vec<f64> = (0..64 * 8).map(|i| (i % 64) as f64).collect();
        let p = heat_map(&values, 64, 8);
        assert_eq!((p.width, p.height), (64, 8 + BAR_AREA));
        let at = |x: u32, y: u32| {
            let i = ((y * p.width + x) * 3) as usize;
            [p.rgb[i], p.rgb[i + 1], p.rgb[i + 2]]
        };
        assert_eq!(at(0, 0), heat_color(0.0));
        assert_eq!(at(63, 0), heat_color(1.0));
        // Black dots of the labels under the bar.
        let dark = (8 + 14..p.height)
            .flat_map(|y| (0..64).map(move |x| (x, y)))
            .filter(|&(x, y)| at(x, y) == [0; 3])
            .count();
        assert!(dark > 20, "{dark}");
    }
}
