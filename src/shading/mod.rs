//! Shading: how surfaces scatter light.
//!
//! [`Bsdf`] is the closed set of scattering models, evaluated and sampled in
//! a local [`Frame`]; [`fresnel`] holds the Fresnel equations and
//! [`microfacet`] the GGX distribution. [`bsdf_at`] maps a scene material
//! (what a file says) to the BSDF at a hit point: this is the one place that
//! knows how file materials become optics.

mod bsdf;
pub mod fresnel;
pub mod microfacet;
#[cfg(test)]
pub(crate) mod tests;

pub use bsdf::{Bsdf, BsdfSample, ConductorFresnel, cosine_hemisphere};
pub use fresnel::{Fresnel, fresnel_dielectric, reflect, refract};
pub use microfacet::Ggx;

use crate::math::{Color, Vec3, orthonormal_basis};
use crate::scene::{Material, MaterialKind};

/// An orthonormal frame `(s, t, n)`: world ↔ local shading coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    pub s: Vec3,
    pub t: Vec3,
    pub n: Vec3,
}

impl Frame {
    /// A frame around the unit vector `n` (Duff et al. 2017's basis).
    #[inline]
    pub fn from_z(n: Vec3) -> Self {
        let (s, t) = orthonormal_basis(n);
        Frame { s, t, n }
    }

    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }

    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.s * v.x + self.t * v.y + self.n * v.z
    }
}

/// The BSDF of `material` at a point whose texture colour is `albedo`.
///
/// - `diffuse`: Lambert with albedo `k_d·C`, each channel at most 1 (the
///   Blinn–Phong highlight and the ambient term belong to Whitted's model
///   only, as they do not conserve energy);
/// - `mirror`: a smooth conductor of constant reflectance `reflectance`;
/// - `conductor`: GGX, Fresnel from the complex index if given, else the
///   constant reflectance `C` (1 by default: the perfect conductor);
/// - `dielectric`: smooth or rough glass of index `ior`;
/// - `principled`: glTF's metallic-roughness model, [`Bsdf::Principled`].
pub fn bsdf_at(material: &Material, albedo: Color) -> Bsdf {
    match material.kind {
        MaterialKind::Diffuse => Bsdf::Diffuse {
            albedo: (material.diffuse * albedo).clamp(Color::ZERO, Color::ONE),
        },
        MaterialKind::Mirror { reflectance } => Bsdf::Conductor {
            fresnel: ConductorFresnel::Constant(reflectance),
            ggx: Ggx::from_roughness(0.0, 0.0),
        },
        MaterialKind::Conductor {
            complex_ior,
            roughness,
            anisotropy,
        } => Bsdf::Conductor {
            fresnel: match complex_ior {
                Some((eta, k)) => ConductorFresnel::Complex { eta, k },
                None => ConductorFresnel::Constant(albedo.clamp(Color::ZERO, Color::ONE)),
            },
            ggx: Ggx::from_roughness(roughness, anisotropy),
        },
        MaterialKind::Dielectric { ior, roughness, .. } => Bsdf::Dielectric {
            eta: ior,
            ggx: Ggx::from_roughness(roughness, 0.0),
        },
        // Roughness 0.05 at least for the opaque part: its blend of lobes
        // has no delta limit; the glass part may be smooth.
        MaterialKind::Principled {
            metallic,
            roughness,
            transmission,
            ior,
        } => Bsdf::Principled {
            base: albedo.clamp(Color::ZERO, Color::ONE),
            metallic,
            ggx: Ggx::from_roughness(roughness.max(0.05), 0.0),
            transmission,
            eta: ior,
            glass: Ggx::from_roughness(roughness, 0.0),
        },
    }
}
