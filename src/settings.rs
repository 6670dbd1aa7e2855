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

/// Largest accepted image side, in pixels.
pub const MAX_IMAGE_SIDE: u32 = 1 << 15;
/// Largest accepted sample count per pixel.
pub const MAX_SPP: u32 = 1 << 16;
/// Largest accepted recursion depth.
pub const MAX_DEPTH: u32 = 1024;
