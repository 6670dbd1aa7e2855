//! How to render: resolution, sampling, recursion, threads.
//!
//! Shared by the scene loader (the file's `[render]` table) and the renderer;
//! the command line overrides any of them.

use std::fmt;

/// Which light-transport algorithm computes a pixel's radiance.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum IntegratorKind {
    /// Appel (1968): an eye ray per sample, a shadow ray per light, local shading.
    Raycast,
    /// Whitted (1979): ray casting plus recursive reflected and refracted rays.
    #[default]
    Whitted,
    /// Path tracing (Kajiya 1986) with next-event estimation and multiple
    /// importance sampling: soft shadows, glossy reflection, indirect light.
    Path,
}

impl IntegratorKind {
    /// Every integrator, in the order of [`IntegratorKind::NAMES`].
    pub const ALL: [IntegratorKind; 3] = [
        IntegratorKind::Raycast,
        IntegratorKind::Whitted,
        IntegratorKind::Path,
    ];
    /// The names the scene file and the command line use.
    pub const NAMES: [&'static str; 3] = ["raycast", "whitted", "path"];

    pub fn from_name(name: &str) -> Option<Self> {
        Self::NAMES
            .iter()
            .position(|n| *n == name)
            .map(|i| Self::ALL[i])
    }

    pub fn name(self) -> &'static str {
        Self::NAMES[Self::ALL.iter().position(|k| *k == self).unwrap_or(0)]
    }
}

impl std::str::FromStr for IntegratorKind {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        Self::from_name(s).ok_or_else(|| {
            format!(
                "unknown integrator `{s}`; expected one of: {}",
                Self::NAMES.join(", ")
            )
        })
    }
}

impl fmt::Display for IntegratorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// How the path integrator finds light at a vertex.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Sampling {
    /// Light sampling and BSDF sampling, combined by multiple importance
    /// sampling (the power heuristic).
    #[default]
    Mis,
    /// Light sampling only (emitters that lights cannot sample are still
    /// found by the path).
    Light,
    /// BSDF sampling only: light is found only where paths hit emitters.
    Bsdf,
}

impl Sampling {
    pub const NAMES: [&'static str; 3] = ["mis", "light", "bsdf"];
    const ALL: [Sampling; 3] = [Sampling::Mis, Sampling::Light, Sampling::Bsdf];
}

impl std::str::FromStr for Sampling {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        Self::NAMES
            .iter()
            .position(|n| *n == s)
            .map(|i| Self::ALL[i])
            .ok_or_else(|| {
                format!(
                    "unknown sampling `{s}`; expected one of: {}",
                    Self::NAMES.join(", ")
                )
            })
    }
}

/// Render settings. Defaults: 640×480, 1 sample per pixel, Whitted, depth 8,
/// weight threshold 1e-3, all cores.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    /// Samples per pixel: 1 shoots through pixel centres; more are stratified
    /// and jittered.
    pub spp: u32,
    /// Deepest recursion: a camera ray has depth 0, each bounce adds 1;
    /// −1: no limit (the path integrator's Russian roulette ends paths;
    /// Whitted stops at [`MAX_DEPTH`]).
    pub max_depth: i32,
    /// Shadow rays to the area lights per shading point (Whitted and ray
    /// casting: soft shadows).
    pub light_samples: u32,
    /// How the path integrator finds light (see [`Sampling`]).
    pub sampling: Sampling,
    /// Each sample's radiance is scaled down to at most this in its largest
    /// channel (a biased cure for fireflies); `None`: no clamping.
    pub clamp: Option<f32>,
    /// A secondary ray is not traced when its weight (the factor its radiance is
    /// multiplied by on the way to the pixel, largest channel) is below this.
    pub min_weight: f32,
    pub integrator: IntegratorKind,
    /// Worker threads; 0 uses every core.
    pub threads: usize,
    /// The pixels to render, within the `width × height` frame; `None`: all.
    /// A crop's pixels are exactly those of the whole frame.
    pub crop: Option<Rect>,
    /// The number of the first sample: a render takes samples
    /// `sample_offset .. sample_offset + spp` of every pixel, so renders of
    /// consecutive ranges merge into one of all their samples.
    pub sample_offset: u32,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            width: 640,
            height: 480,
            spp: 1,
            max_depth: 8,
            light_samples: 16,
            sampling: Sampling::Mis,
            clamp: None,
            min_weight: 1e-3,
            integrator: IntegratorKind::Whitted,
            threads: 0,
            crop: None,
            sample_offset: 0,
        }
    }
}

impl RenderSettings {
    /// The pixels a render covers: the crop, or the whole frame.
    pub fn rect(&self) -> Rect {
        self.crop.unwrap_or(Rect::full(self.width, self.height))
    }

    /// The depth an integrator stops at: `max_depth`, or for −1 no limit
    /// (`u32::MAX`) for path tracing and [`MAX_DEPTH`] for the others.
    pub fn depth_limit(&self) -> u32 {
        match (self.max_depth, self.integrator) {
            (d, _) if d >= 0 => d as u32,
            (_, IntegratorKind::Path) => u32::MAX,
            _ => MAX_DEPTH,
        }
    }

    /// The samples a render takes of each pixel.
    pub fn samples(&self) -> SampleRange {
        SampleRange {
            start: self.sample_offset,
            count: self.spp,
        }
    }

    /// Checks the settings a render depends on; the error says what is wrong.
    pub fn validate(&self) -> Result<(), String> {
        let side = 1..=MAX_IMAGE_SIDE;
        if !side.contains(&self.width) || !side.contains(&self.height) {
            return Err(format!(
                "image size {}×{} is out of range (each side from 1 to {MAX_IMAGE_SIDE})",
                self.width, self.height
            ));
        }
        let pixels = self.width as u64 * self.height as u64;
        if pixels > MAX_PIXELS {
            return Err(format!(
                "image size {}×{} has {pixels} pixels, more than the limit of {MAX_PIXELS}",
                self.width, self.height
            ));
        }
        if !(1..=MAX_SPP).contains(&self.spp) {
            return Err(format!("spp {} is out of range (1 to {MAX_SPP})", self.spp));
        }
        if self.sample_offset as u64 + self.spp as u64 > 1 << 32 {
            return Err(format!(
                "samples {}..{} go past the last sample number, 2^32 − 1",
                self.sample_offset,
                self.sample_offset as u64 + self.spp as u64
            ));
        }
        if let Some(crop) = self.crop {
            let frame = Rect::full(self.width, self.height);
            if crop.is_empty() || crop.intersect(&frame) != Some(crop) {
                return Err(format!(
                    "crop {crop} is not a non-empty part of the {}×{} frame",
                    self.width, self.height
                ));
            }
        }
        if !(-1..=MAX_DEPTH as i32).contains(&self.max_depth) {
            return Err(format!(
                "max_depth {} is not −1 (no limit) or 0 to {MAX_DEPTH}",
                self.max_depth
            ));
        }
        if let Some(c) = self.clamp
            && !(c > 0.0 && c.is_finite())
        {
            return Err(format!("clamp {c} is not a positive number"));
        }
        if self.light_samples > MAX_LIGHT_SAMPLES {
            return Err(format!(
                "light_samples {} is above {MAX_LIGHT_SAMPLES}",
                self.light_samples
            ));
        }
        if !(0.0..=1.0).contains(&self.min_weight) {
            return Err(format!("min_weight {} is not in [0, 1]", self.min_weight));
        }
        Ok(())
    }
}

/// Largest accepted number of pixels (the film holds 16 bytes per pixel).
pub const MAX_PIXELS: u64 = 1 << 27;
/// Largest accepted image side, in pixels.
pub const MAX_IMAGE_SIDE: u32 = 1 << 15;
/// Largest accepted sample count per pixel.
pub const MAX_SPP: u32 = 1 << 16;
/// Largest accepted recursion depth.
pub const MAX_DEPTH: u32 = 1024;
/// Largest accepted number of shadow rays per area-light evaluation.
pub const MAX_LIGHT_SAMPLES: u32 = 4096;

/// A rectangle of pixels, `x ∈ [x0, x1)`, `y ∈ [y0, y1)`, in the frame's
/// coordinates (origin top left, y down).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub struct Rect {
    pub x0: u32,
    pub x1: u32,
    pub y0: u32,
    pub y1: u32,
}

impl Rect {
    /// The whole `width × height` frame.
    pub fn full(width: u32, height: u32) -> Rect {
        Rect {
            x0: 0,
            x1: width,
            y0: 0,
            y1: height,
        }
    }

    pub fn width(&self) -> u32 {
        self.x1.saturating_sub(self.x0)
    }

    pub fn height(&self) -> u32 {
        self.y1.saturating_sub(self.y0)
    }

    pub fn area(&self) -> u64 {
        self.width() as u64 * self.height() as u64
    }

    pub fn is_empty(&self) -> bool {
        self.area() == 0
    }

    /// The common pixels, if any.
    pub fn intersect(&self, other: &Rect) -> Option<Rect> {
        let r = Rect {
            x0: self.x0.max(other.x0),
            x1: self.x1.min(other.x1),
            y0: self.y0.max(other.y0),
            y1: self.y1.min(other.y1),
        };
        (!r.is_empty()).then_some(r)
    }

    /// The smallest rectangle holding both.
    pub fn union(&self, other: &Rect) -> Rect {
        Rect {
            x0: self.x0.min(other.x0),
            x1: self.x1.max(other.x1),
            y0: self.y0.min(other.y0),
            y1: self.y1.max(other.y1),
        }
    }

    /// Tile `index` of a grid of `columns × rows` tiles over a
    /// `width × height` frame, counted row by row from the top left. Tile
    /// edges lie at `⌊i·width/columns⌋` and `⌊j·height/rows⌋`, so the tiles
    /// cover the frame exactly. `None` if the index or the grid does not fit.
    pub fn tile(width: u32, height: u32, columns: u32, rows: u32, index: u32) -> Option<Rect> {
        if columns == 0 || rows == 0 || columns > width || rows > height {
            return None;
        }
        if index as u64 >= columns as u64 * rows as u64 {
            return None;
        }
        let (i, j) = ((index % columns) as u64, (index / columns) as u64);
        let edge = |k: u64, side: u32, n: u32| (k * side as u64 / n as u64) as u32;
        Some(Rect {
            x0: edge(i, width, columns),
            x1: edge(i + 1, width, columns),
            y0: edge(j, height, rows),
            y1: edge(j + 1, height, rows),
        })
    }
}

impl fmt::Display for Rect {
    /// `x 0..64, y 32..48`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "x {}..{}, y {}..{}", self.x0, self.x1, self.y0, self.y1)
    }
}

impl std::str::FromStr for Rect {
    type Err = String;

    /// `X0,X1,Y0,Y1`: the pixels `x ∈ [X0, X1)`, `y ∈ [Y0, Y1)`.
    fn from_str(s: &str) -> Result<Rect, String> {
        let v: Vec<u32> = s
            .split(',')
            .map(|x| x.trim().parse::<u32>())
            .collect::<Result<_, _>>()
            .map_err(|_| format!("expected four whole numbers X0,X1,Y0,Y1, found `{s}`"))?;
        let [x0, x1, y0, y1] = v[..] else {
            return Err(format!(
                "expected four whole numbers X0,X1,Y0,Y1, found `{s}`"
            ));
        };
        if x0 >= x1 || y0 >= y1 {
            return Err(format!("crop `{s}` is empty: it needs X0 < X1 and Y0 < Y1"));
        }
        Ok(Rect { x0, x1, y0, y1 })
    }
}

/// Samples `start .. start + count` of every pixel (see [`RenderSettings::sample_offset`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct SampleRange {
    pub start: u32,
    pub count: u32,
}

impl SampleRange {
    /// One past the last sample's number.
    pub fn end(&self) -> u64 {
        self.start as u64 + self.count as u64
    }

    /// Whether the two ranges share a sample.
    pub fn overlaps(&self, other: &SampleRange) -> bool {
        (self.start as u64) < other.end() && (other.start as u64) < self.end()
    }
}

impl fmt::Display for SampleRange {
    /// `32..64`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}..{}", self.start, self.end())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_cover_the_frame_exactly() {
        for (w, h, c, r) in [
            (640, 480, 4, 4),
            (17, 9, 3, 2),
            (5, 5, 5, 5),
            (100, 1, 7, 1),
        ] {
            let mut count = vec![0u32; (w * h) as usize];
            for k in 0..c * r {
                let t = Rect::tile(w, h, c, r, k).unwrap();
                assert!(!t.is_empty());
                for y in t.y0..t.y1 {
                    for x in t.x0..t.x1 {
                        count[(y * w + x) as usize] += 1;
                    }
                }
            }
            assert!(count.iter().all(|&n| n == 1), "{w}×{h} in {c}×{r}");
            assert_eq!(Rect::tile(w, h, c, r, c * r), None);
        }
        assert_eq!(Rect::tile(4, 4, 5, 1, 0), None);
        assert_eq!(Rect::tile(4, 4, 0, 1, 0), None);
    }

    #[test]
    fn crops_parse_and_are_checked() {
        assert_eq!(
            "1,5,2,3".parse::<Rect>(),
            Ok(Rect {
                x0: 1,
                x1: 5,
                y0: 2,
                y1: 3
            })
        );
        assert!("1,5,2".parse::<Rect>().is_err());
        assert!("5,1,2,3".parse::<Rect>().is_err());
        assert!("1,5,-2,3".parse::<Rect>().is_err());
        let mut s = RenderSettings {
            width: 10,
            height: 10,
            crop: Some("2,11,0,1".parse().unwrap()),
            ..Default::default()
        };
        assert!(s.validate().unwrap_err().contains("crop x 2..11, y 0..1"));
        s.crop = Some("2,10,0,1".parse().unwrap());
        assert!(s.validate().is_ok());
        s.sample_offset = u32::MAX;
        s.spp = 2;
        assert!(s.validate().unwrap_err().contains("last sample"));
        s.spp = 1;
        assert!(s.validate().is_ok());
    }

    #[test]
    fn sample_ranges_overlap_when_they_share_a_sample() {
        let r = |start, count| SampleRange { start, count };
        assert!(!r(0, 32).overlaps(&r(32, 32)));
        assert!(r(0, 33).overlaps(&r(32, 32)));
        assert!(r(40, 1).overlaps(&r(32, 32)));
        assert_eq!(r(u32::MAX, 1).end(), 1 << 32);
    }
}
