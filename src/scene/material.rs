//! Materials: what a scene file says about a surface. The optics they imply
//! live in [`crate::shading`] (which maps a material to a BSDF).
//!
//! Every material has the local (Phong-style) terms of Whitted's illumination
//! model, `I = k_a·C·A + Σ_lights V·(k_d·C·max(0, N·L) + k_s·(N·H)^n)·E`,
//! with `C` the texture colour, `A` the ambient light, `E` the light's
//! irradiance and `V` its shadow-ray transmittance. What a material adds on top
//! is its [`MaterialKind`]: nothing (diffuse: recursion ends), a reflected ray
//! (mirror), or a Fresnel-weighted reflected and refracted ray (dielectric).
//! The `path` integrator uses the BSDF [`crate::shading::bsdf_at`] makes of
//! it, and its `emission`.

use super::Texture;
use crate::math::Color;

#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Material {
    /// Surface colour `C`, scaling the ambient and diffuse terms.
    pub texture: Texture,
    /// Ambient coefficient `k_a`.
    pub ambient: f32,
    /// Lambert coefficient `k_d`.
    pub diffuse: f32,
    /// Blinn–Phong highlight coefficient `k_s` (a white highlight).
    pub specular: f32,
    /// Blinn–Phong exponent `n`.
    pub shininess: f32,
    pub kind: MaterialKind,
    /// Radiance emitted by the surface (zero: none); any shape with such a
    /// material is an area light.
    #[serde(default)]
    pub emission: Color,
    /// Whether it emits from both sides (else only on its normal's side).
    #[serde(default)]
    pub two_sided: bool,
}

#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "type", rename_all = "lowercase")]
pub enum MaterialKind {
    /// Local shading only; rays that hit it end here.
    Diffuse,
    /// Perfect reflection, tinted by `reflectance` (per channel, in [0, 1]).
    Mirror { reflectance: Color },
    /// A smooth interface into a medium of index of refraction `ior` (outside:
    /// 1). Reflected and refracted rays are weighted by the exact Fresnel
    /// equations. Light travelling a distance `s` inside is attenuated by
    /// `exp(−absorption·s)` (Beer–Lambert), which tints thick glass.
    ///
    /// `roughness` (perceptual, `α = roughness²`) makes the interface a GGX
    /// microfacet surface for the `path` integrator (Walter et al. 2007);
    /// Whitted's integrator treats it as smooth.
    Dielectric {
        ior: f32,
        absorption: Color,
        #[serde(default)]
        roughness: f32,
    },
    /// A metal: GGX microfacets of `roughness` (perceptual, `α =
    /// roughness²`) and `anisotropy` in (−1, 1), with the Fresnel equations
    /// of the complex index `(η, k)` per channel, or, without one, a
    /// constant reflectance (the material's colour). Whitted's integrator
    /// treats it as a smooth mirror.
    Conductor {
        complex_ior: Option<(Color, Color)>,
        #[serde(default)]
        roughness: f32,
        #[serde(default)]
        anisotropy: f32,
    },
    /// The neutral material of model files (glTF's metallic-roughness
    /// model; the colour is the base colour): for the `path` integrator a
    /// diffuse base under a GGX coat of index `ior`, blended to a metal by
    /// `metallic`, with the fraction `transmission` of the non-metal part
    /// glass of index `ior` (see [`crate::shading::Bsdf::Principled`]).
    /// Whitted's integrator shades it as diffuse, as a mirror of the base
    /// colour when `metallic ≥ 0.5`, or as smooth glass when it is mostly
    /// glass (see [`Material::glass`]).
    Principled {
        metallic: f32,
        roughness: f32,
        #[serde(default)]
        transmission: f32,
        #[serde(default = "default_ior")]
        ior: f32,
    },
}

/// glTF's default index of refraction.
fn default_ior() -> f32 {
    1.5
}

impl Material {
    /// A grey Lambertian surface: what objects without a material get.
    pub fn default_diffuse() -> Self {
        Material {
            texture: Texture::Solid(Color::splat(0.8)),
            ambient: 1.0,
            diffuse: 1.0,
            specular: 0.0,
            shininess: 64.0,
            kind: MaterialKind::Diffuse,
            emission: Color::ZERO,
            two_sided: false,
        }
    }

    /// Whether shadow rays stop at this material (everything but glass).
    pub fn is_opaque(&self) -> bool {
        self.glass().is_none()
    }

    /// The index of refraction and absorption of a material that Whitted's
    /// integrator (and its light shadows) treat as smooth glass:
    /// dielectrics, and principled materials whose glass part
    /// `(1 − metallic)·transmission` is at least one half.
    pub fn glass(&self) -> Option<(f32, Color)> {
        match self.kind {
            MaterialKind::Dielectric {
                ior, absorption, ..
            } => Some((ior, absorption)),
            MaterialKind::Principled {
                metallic,
                transmission,
                ior,
                ..
            } if (1.0 - metallic) * transmission >= 0.5 => Some((ior, Color::ZERO)),
            _ => None,
        }
    }

    /// Whether the surface emits light.
    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }
}
