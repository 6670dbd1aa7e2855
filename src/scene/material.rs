//! Materials and the optics of Whitted's model: reflection, Snell refraction,
//! and the exact dielectric Fresnel equations.
//!
//! Every material has the local (Phong-style) terms of Whitted's illumination
//! model, `I = k_a·C·A + Σ_lights V·(k_d·C·max(0, N·L) + k_s·(N·H)^n)·E`,
//! with `C` the texture colour, `A` the ambient light, `E` the light's
//! irradiance and `V` its shadow-ray transmittance. What a material adds on top
//! is its [`MaterialKind`]: nothing (diffuse: recursion ends), a reflected ray
//! (mirror), or a Fresnel-weighted reflected and refracted ray (dielectric).

use super::Texture;
use crate::math::{Color, Vec3};

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
    Dielectric { ior: f32, absorption: Color },
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
        }
    }

    /// Whether shadow rays stop at this material (everything but dielectrics).
    pub fn is_opaque(&self) -> bool {
        !matches!(self.kind, MaterialKind::Dielectric { .. })
    }
}

/// Mirror reflection of `d` about the unit normal `n`: `d − 2 (d·n) n`.
#[inline]
pub fn reflect(d: Vec3, n: Vec3) -> Vec3 {
    d - 2.0 * d.dot(n) * n
}

/// Refraction of the unit direction `d` at a surface with unit normal `n`
/// facing against `d` (`d·n < 0`), by Snell's law `η_i sin θ_i = η_t sin θ_t`,
/// with `eta = η_i / η_t`:
/// `t = η d + (η cos θ_i − cos θ_t) n`, `cos θ_t = √(1 − η²(1 − cos² θ_i))`.
/// Returns `None` on total internal reflection (`η sin θ_i > 1`).
#[inline]
pub fn refract(d: Vec3, n: Vec3, eta: f32) -> Option<Vec3> {
    let cos_i = -d.dot(n);
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some(eta * d + (eta * cos_i - cos_t) * n)
}

/// Fractions of the power of unpolarised light reflected and transmitted at a
/// smooth dielectric interface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fresnel {
    pub reflectance: f32,
    pub transmittance: f32,
}

/// The exact Fresnel equations for a dielectric interface (Hecht, "Optics",
/// §4.6), light going from index `eta_i` into `eta_t` at `cos θ_i = cos_i`:
///
/// - amplitude reflection `r_s = (η_i cos θ_i − η_t cos θ_t)/(η_i cos θ_i + η_t cos θ_t)`,
///   `r_p = (η_t cos θ_i − η_i cos θ_t)/(η_t cos θ_i + η_i cos θ_t)`;
/// - amplitude transmission `t_s = 2 η_i cos θ_i/(η_i cos θ_i + η_t cos θ_t)`,
///   `t_p = 2 η_i cos θ_i/(η_t cos θ_i + η_i cos θ_t)`;
/// - `R = (r_s² + r_p²)/2`, `T = (η_t cos θ_t)/(η_i cos θ_i)·(t_s² + t_p²)/2`.
///
/// `R` and `T` are computed independently, so `R + T = 1` is a check of the
/// formulas, not an identity of the code. Past the critical angle (total
/// internal reflection) `R = 1`, `T = 0`. `cos_i` is clamped to [0, 1].
pub fn fresnel_dielectric(cos_i: f32, eta_i: f32, eta_t: f32) -> Fresnel {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin_t = eta_i / eta_t * (1.0 - cos_i * cos_i).sqrt();
    if sin_t >= 1.0 || cos_i == 0.0 {
        return Fresnel {
            reflectance: 1.0,
            transmittance: 0.0,
        };
    }
    let cos_t = (1.0 - sin_t * sin_t).sqrt();
    let (ii, tt) = (eta_i * cos_i, eta_t * cos_t);
    let (it, ti) = (eta_i * cos_t, eta_t * cos_i);
    let r_s = (ii - tt) / (ii + tt);
    let r_p = (ti - it) / (ti + it);
    let t_s = 2.0 * ii / (ii + tt);
    let t_p = 2.0 * ii / (ti + it);
    Fresnel {
        reflectance: 0.5 * (r_s * r_s + r_p * r_p),
        transmittance: tt / ii * 0.5 * (t_s * t_s + t_p * t_p),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn normal_incidence_glass_reflects_four_percent() {
        let f = fresnel_dielectric(1.0, 1.0, 1.5);
        assert!((f.reflectance - 0.04).abs() < 1e-6);
        assert!((f.transmittance - 0.96).abs() < 1e-6);
        // Symmetric from inside at normal incidence.
        let g = fresnel_dielectric(1.0, 1.5, 1.0);
        assert!((g.reflectance - 0.04).abs() < 1e-6);
    }

    #[test]
    fn brewster_angle_has_no_p_reflection() {
        // At Brewster's angle tan θ = η_t/η_i, r_p = 0 and R = r_s²/2.
        let theta = 1.5f32.atan();
        let f = fresnel_dielectric(theta.cos(), 1.0, 1.5);
        let cos_t = (1.0 - (theta.sin() / 1.5).powi(2)).sqrt();
        let r_s = (theta.cos() - 1.5 * cos_t) / (theta.cos() + 1.5 * cos_t);
        assert!((f.reflectance - 0.5 * r_s * r_s).abs() < 1e-6);
    }

    #[test]
    fn total_internal_reflection_past_the_critical_angle() {
        let critical = (1.0f32 / 1.5).asin();
        let past = fresnel_dielectric((critical + 0.01).cos(), 1.5, 1.0);
        assert_eq!((past.reflectance, past.transmittance), (1.0, 0.0));
        let before = fresnel_dielectric((critical - 0.01).cos(), 1.5, 1.0);
        assert!(before.transmittance > 0.0 && before.reflectance < 1.0);
        let d = Vec3::new((critical + 0.01).sin(), -(critical + 0.01).cos(), 0.0);
        assert!(refract(d, Vec3::Y, 1.5).is_none());
        let d = Vec3::new((critical - 0.01).sin(), -(critical - 0.01).cos(), 0.0);
        assert!(refract(d, Vec3::Y, 1.5).is_some());
    }

    #[test]
    fn reflect_mirrors_about_the_normal() {
        assert_eq!(
            reflect(Vec3::new(1.0, -1.0, 0.0), Vec3::Y),
            Vec3::new(1.0, 1.0, 0.0)
        );
    }

    proptest! {
        /// R + T = 1 for every angle and pair of indices, and below the
        /// critical angle Snell's law holds for the refracted direction.
        #[test]
        fn fresnel_conserves_energy_and_snell_holds(theta in 0.0f32..std::f32::consts::FRAC_PI_2, eta_i in 1.0f32..2.5, eta_t in 1.0f32..2.5) {
            let f = fresnel_dielectric(theta.cos(), eta_i, eta_t);
            prop_assert!((f.reflectance + f.transmittance - 1.0).abs() < 1e-4, "{:?}", f);
            prop_assert!((0.0..=1.0).contains(&f.reflectance));
            let d = Vec3::new(theta.sin(), -theta.cos(), 0.0);
            match refract(d, Vec3::Y, eta_i / eta_t) {
                Some(t) => {
                    prop_assert!((t.length() - 1.0).abs() < 1e-4);
                    prop_assert!((eta_i * theta.sin() - eta_t * t.x).abs() < 1e-4);
                    prop_assert!(t.y < 0.0);
                }
                None => prop_assert!(eta_i * theta.sin() > eta_t * 0.9999 && f.reflectance == 1.0),
            }
        }
    }
}
