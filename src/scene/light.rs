//! Point and directional lights.

use crate::math::{Color, Vec3};

/// A light source. Lights are not geometry: camera and reflected rays never
/// hit them; they are reached only by shadow rays.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "type", rename_all = "lowercase")]
pub enum Light {
    /// Point light of radiant intensity `intensity` (per colour channel); the
    /// irradiance at distance `r` falls off as `intensity / r²`.
    Point { position: Vec3, intensity: Color },
    /// Light from infinitely far away, travelling along the unit vector
    /// `direction`, with irradiance `irradiance` on a surface facing it.
    Directional { direction: Vec3, irradiance: Color },
}
