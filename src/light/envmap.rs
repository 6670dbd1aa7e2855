//! An environment map: radiance from every direction at infinity, read from
//! an equirectangular (latitude–longitude) EXR image, importance-sampled
//! with a 2-D piecewise-constant distribution (pbrt-v4 §A.5.6: a marginal
//! density over rows and a conditional density within each row, weighted
//! by luminance × sin θ so that the density over directions follows the
//! radiance).

use crate::math::{Color, Vec3};
use std::f32::consts::PI;

/// A piecewise-constant density on [0, 1) with `n` equal pieces.
#[derive(Clone, Debug, PartialEq)]
pub struct Distribution1D {
    /// The pieces' weights.
    func: Vec<f32>,
    /// `cdf[i]`: the probability of the pieces before `i` (`n + 1` values).
    cdf: Vec<f32>,
    /// `∫ func` over [0, 1).
    integral: f32,
}

impl Distribution1D {
    /// The density proportional to `func` (finite, ≥ 0); uniform where all
    /// weights are zero.
    pub fn new(func: Vec<f32>) -> Self {
        let n = func.len();
        let mut cdf = vec![0f32; n + 1];
        let mut acc = 0f64;
        for (i, &f) in func.iter().enumerate() {
            acc += f as f64 / n as f64;
            cdf[i + 1] = acc as f32;
        }
        let integral = acc as f32;
        if integral > 0.0 {
            for c in &mut cdf[1..] {
                *c /= integral;
            }
        } else {
            for (i, c) in cdf.iter_mut().enumerate() {
                *c = i as f32 / n as f32;
            }
        }
        cdf[n] = 1.0;
        Distribution1D {
            func,
            cdf,
            integral,
        }
    }

    /// The density at `x` in piece `i`.
    #[inline]
    fn pdf_of(&self, i: usize) -> f32 {
        if self.integral > 0.0 {
            self.func[i] / self.integral
        } else {
            1.0
        }
    }

    /// A sample `x ∈ [0, 1)` for `u ∈ [0, 1)`: its piece and its density.
    #[inline]
    pub fn sample(&self, u: f32) -> (f32, usize, f32) {
        let n = self.func.len();
        // The last i with cdf[i] ≤ u.
        let i = self
            .cdf
            .partition_point(|&c| c <= u)
            .saturating_sub(1)
            .min(n - 1);
        let width = self.cdf[i + 1] - self.cdf[i];
        let du = if width > 0.0 {
            (u - self.cdf[i]) / width
        } else {
            0.5
        };
        let x = ((i as f32 + du.clamp(0.0, 1.0)) / n as f32).min(1.0 - f32::EPSILON / 2.0);
        (x, i, self.pdf_of(i))
    }

    /// The density at `x ∈ [0, 1)`.
    #[inline]
    pub fn pdf(&self, x: f32) -> f32 {
        let n = self.func.len();
        self.pdf_of(((x * n as f32) as usize).min(n - 1))
    }
}

/// An equirectangular environment map. Direction `d` maps to `u = (φ + π)/2π`
/// with `φ = atan2(d.x, d.z)` (after turning the map by `rotate_y`) and
/// `v = θ/π` with `θ = acos(d.y)`: the top row is straight up.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvMap {
    pub width: u32,
    pub height: u32,
    /// Row by row from the top, already multiplied by the scale.
    texels: Vec<Color>,
    /// `(cos, sin)` of the map's turn about +y.
    rotation: (f32, f32),
    rows: Distribution1D,
    columns: Vec<Distribution1D>,
}

/// The largest map accepted, in texels.
pub const MAX_TEXELS: u64 = 1 << 26;

impl EnvMap {
    /// A map of `width × height` texels (row by row from the top), scaled by
    /// `scale` and turned by `rotate_y_deg` about +y. Texels must be finite
    /// and non-negative; the error names the first that is not.
    pub fn new(
        width: u32,
        height: u32,
        texels: Vec<Color>,
        scale: f32,
        rotate_y_deg: f32,
    ) -> Result<Self, String> {
        if width == 0 || height == 0 || width as u64 * height as u64 > MAX_TEXELS {
            return Err(format!(
                "a {width}×{height} environment map is empty or larger than {MAX_TEXELS} texels"
            ));
        }
        if texels.len() != width as usize * height as usize {
            return Err("the texel count does not match the size".into());
        }
        if let Some(i) = texels
            .iter()
            .position(|t| !t.is_finite() || t.min_element() < 0.0)
        {
            return Err(format!(
                "texel ({}, {}) is {}, not a finite radiance ≥ 0",
                i % width as usize,
                i / width as usize,
                texels[i]
            ));
        }
        let texels: Vec<Color> = texels.into_iter().map(|t| t * scale).collect();
        let luminance = |c: Color| 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;
        let (w, h) = (width as usize, height as usize);
        let mut columns = Vec::with_capacity(h);
        let mut row_weights = Vec::with_capacity(h);
        for y in 0..h {
            let sin_theta = (PI * (y as f32 + 0.5) / h as f32).sin();
            let row: Vec<f32> = texels[y * w..(y + 1) * w]
                .iter()
                .map(|&t| luminance(t) * sin_theta)
                .collect();
            let d = Distribution1D::new(row);
            row_weights.push(d.integral);
            columns.push(d);
        }
        let a = rotate_y_deg.to_radians();
        Ok(EnvMap {
            width,
            height,
            texels,
            rotation: (a.cos(), a.sin()),
            rows: Distribution1D::new(row_weights),
            columns,
        })
    }

    /// World direction → map direction (undo the turn).
    #[inline]
    fn to_map(&self, d: Vec3) -> Vec3 {
        let (c, s) = self.rotation;
        Vec3::new(c * d.x - s * d.z, d.y, s * d.x + c * d.z)
    }

    #[inline]
    fn to_world(&self, d: Vec3) -> Vec3 {
        let (c, s) = self.rotation;
        Vec3::new(c * d.x + s * d.z, d.y, -s * d.x + c * d.z)
    }

    /// `(u, v)` of a unit world direction.
    #[inline]
    fn uv(&self, d: Vec3) -> (f32, f32) {
        let m = self.to_map(d);
        let u = (m.x.atan2(m.z) + PI) / (2.0 * PI);
        let v = m.y.clamp(-1.0, 1.0).acos() / PI;
        (
            u.clamp(0.0, 1.0 - f32::EPSILON / 2.0),
            v.clamp(0.0, 1.0 - f32::EPSILON / 2.0),
        )
    }

    /// Radiance arriving from infinitely far along `-d` (that is, seen
    /// looking in direction `d`, unit): the texel under `d`.
    #[inline]
    pub fn le(&self, d: Vec3) -> Color {
        let (u, v) = self.uv(d);
        let x = ((u * self.width as f32) as usize).min(self.width as usize - 1);
        let y = ((v * self.height as f32) as usize).min(self.height as usize - 1);
        self.texels[y * self.width as usize + x]
    }

    /// A direction for `u ∈ [0, 1)²` with its density over solid angle
    /// (`p(u, v) / (2π² sin θ)`), and the radiance from it.
    #[inline]
    pub fn sample(&self, u: (f32, f32)) -> Option<(Vec3, f32, Color)> {
        let (v, row, pdf_v) = self.rows.sample(u.0);
        let (uu, _, pdf_u) = self.columns[row].sample(u.1);
        let theta = v * PI;
        let phi = uu * 2.0 * PI - PI;
        let sin_theta = theta.sin();
        if sin_theta <= 0.0 || pdf_u * pdf_v == 0.0 {
            return None;
        }
        let m = Vec3::new(sin_theta * phi.sin(), theta.cos(), sin_theta * phi.cos());
        let pdf = pdf_u * pdf_v / (2.0 * PI * PI * sin_theta);
        let d = self.to_world(m);
        Some((d, pdf, self.le(d)))
    }

    /// The density with which [`EnvMap::sample`] picks the unit direction `d`.
    #[inline]
    pub fn pdf(&self, d: Vec3) -> f32 {
        let (u, v) = self.uv(d);
        let sin_theta = (v * PI).sin();
        if sin_theta <= 0.0 {
            return 0.0;
        }
        let row = ((v * self.height as f32) as usize).min(self.height as usize - 1);
        self.rows.pdf(v) * self.columns[row].pdf(u) / (2.0 * PI * PI * sin_theta)
    }

    /// The map's mean radiance over directions (for choosing lights by power).
    pub fn mean_radiance(&self) -> Color {
        let (w, h) = (self.width as usize, self.height as usize);
        let mut sum = Color::ZERO;
        let mut weight = 0.0;
        for y in 0..h {
            let s = (PI * (y as f32 + 0.5) / h as f32).sin();
            for x in 0..w {
                sum += self.texels[y * w + x] * s;
            }
            weight += s * w as f32;
        }
        sum / weight.max(f32::MIN_POSITIVE)
    }
}

/// Reads an environment map from the bytes of an RGB(A) EXR file.
pub fn read_exr(bytes: &[u8]) -> Result<(u32, u32, Vec<Color>), String> {
    use exr::prelude::*;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            |res, _| {
                let (w, h) = (res.width(), res.height());
                let n = if (w as u64) * (h as u64) <= MAX_TEXELS {
                    w * h
                } else {
                    0
                };
                (w, h, vec![Color::ZERO; n])
            },
            |(w, _, px): &mut (usize, usize, Vec<Color>),
             pos,
             (r, g, b, _a): (f32, f32, f32, f32)| {
                if let Some(t) = px.get_mut(pos.y() * *w + pos.x()) {
                    *t = Color::new(r, g, b);
                }
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_buffered(std::io::Cursor::new(bytes))
        .map_err(|e| format!("not a readable RGB EXR image: {e}"))?;
    let (w, h, texels) = image.layer_data.channel_data.pixels;
    if texels.is_empty() {
        return Err(format!(
            "a {w}×{h} environment map is larger than {MAX_TEXELS} texels"
        ));
    }
    Ok((w as u32, h as u32, texels))
}
