//! How to render: resolution, sampling, recursion, threads.
//!
//! Shared by the scene loader (the file's `[render]` table) and the renderer;
//! the command line overrides any of them.

use std::fmt;

/// Which light-transport algorithm computes a pixel's radiance.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum IntegratorKind {
    /// Appel (1968): an eye ray per sample, a shadow ray per light, local shading.
    Raycast,
    /// Whitted (1979): ray casting plus recursive reflected and refracted rays.
    #[default]
    Whitted,
}

impl IntegratorKind {
    pub const NAMES: [&'static str; 2] = ["raycast", "whitted"];

    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "raycast" => Some(IntegratorKind::Raycast),
            "whitted" => Some(IntegratorKind::Whitted),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            IntegratorKind::Raycast => "raycast",
            IntegratorKind::Whitted => "whitted",
        }
    }
}

impl fmt::Display for IntegratorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Render settings. Defaults: 640×480, 1 sample per pixel, Whitted, depth 8,
/// weight threshold 1e-3, all cores.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    /// Samples per pixel: 1 shoots through pixel centres; more are stratified
    /// and jittered.
    pub spp: u32,
    /// Deepest recursion: a camera ray has depth 0, each bounce adds 1.
    pub max_depth: u32,
    /// A secondary ray is not traced when its weight (the factor its radiance is
    /// multiplied by on the way to the pixel, largest channel) is below this.
    pub min_weight: f32,
    pub integrator: IntegratorKind,
    /// Worker threads; 0 uses every core.
    pub threads: usize,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            width: 640,
            height: 480,
            spp: 1,
            max_depth: 8,
            min_weight: 1e-3,
            integrator: IntegratorKind::Whitted,
            threads: 0,
        }
    }
}

impl RenderSettings {
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
        if self.max_depth > MAX_DEPTH {
            return Err(format!("max_depth {} is above {MAX_DEPTH}", self.max_depth));
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
