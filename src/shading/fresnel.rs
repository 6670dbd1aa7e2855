//! Fresnel equations and the directions of specular reflection and
//! refraction.
//!
//! Two forms of the dielectric equations live here: [`fresnel_dielectric`]
//! (reflectance and transmittance computed apart, from the amplitude
//! coefficients; Whitted's integrator and the shadow rays through glass use
//! it) and [`fr_dielectric`] (reflectance only, with the relative index
//! `η = η_t/η_i`, as the BSDFs use it). [`fr_conductor`] is the exact
//! equation for an absorbing medium of complex index `η + i·k`, and
//! [`schlick`] the approximation some file formats prescribe.

use crate::math::{Color, Vec3};

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

/// Fresnel reflectance of a smooth dielectric interface for unpolarised
/// light, with `eta = η_t/η_i` the index of the side the normal points away
/// from over the side it points to, and `cos_i` the cosine between the
/// incident direction and the normal (negative: the light arrives from the
/// inside, and the interface is seen with `1/η`):
/// `R = (r_∥² + r_⊥²)/2`, `r_∥ = (η cos θ_i − cos θ_t)/(η cos θ_i + cos θ_t)`,
/// `r_⊥ = (cos θ_i − η cos θ_t)/(cos θ_i + η cos θ_t)`, `R = 1` past the
/// critical angle (Hecht, "Optics", §4.6; pbrt-v4 §9.3.2).
#[inline]
pub fn fr_dielectric(cos_i: f32, eta: f32) -> f32 {
    let (cos_i, eta) = if cos_i < 0.0 {
        (-cos_i, 1.0 / eta)
    } else {
        (cos_i, eta)
    };
    let cos_i = cos_i.min(1.0);
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).max(0.0).sqrt();
    let r_par = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (r_par * r_par + r_perp * r_perp)
}

/// Refraction of `wi` (pointing away from the surface) through the
/// interface with unit normal `n`, relative index `eta = η_t/η_i` for light
/// arriving on `n`'s side: `w_t = −w_i/η + (cos θ_i/η − cos θ_t) n` (Snell).
/// From the other side the interface has index `1/η` and normal `−n`.
/// Returns the refracted direction and the relative index it crossed, or
/// `None` on total internal reflection.
#[inline]
pub fn refract_eta(wi: Vec3, n: Vec3, eta: f32) -> Option<(Vec3, f32)> {
    let mut cos_i = n.dot(wi);
    let (mut eta, mut n) = (eta, n);
    if cos_i < 0.0 {
        eta = 1.0 / eta;
        cos_i = -cos_i;
        n = -n;
    }
    let sin2_i = (1.0 - cos_i * cos_i).max(0.0);
    let sin2_t = sin2_i / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((-wi / eta + (cos_i / eta - cos_t) * n, eta))
}

/// Fresnel reflectance of a conductor of complex index `η + i·k` (per
/// channel) seen from a dielectric of index 1, at `cos θ_i` (the exact
/// equations with complex arithmetic, Born & Wolf §14.2; pbrt-v4
/// `FrComplex`): `r_∥ = (η̃ cos θ_i − cos θ_t)/(η̃ cos θ_i + cos θ_t)`,
/// `r_⊥ = (cos θ_i − η̃ cos θ_t)/(cos θ_i + η̃ cos θ_t)` with
/// `sin θ_t = sin θ_i/η̃` and `R = (|r_∥|² + |r_⊥|²)/2`.
pub fn fr_conductor(cos_i: f32, eta: Color, k: Color) -> Color {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let f = |eta: f32, k: f32| fr_complex(cos_i, Complex::new(eta, k));
    Color::new(f(eta.x, k.x), f(eta.y, k.y), f(eta.z, k.z))
}

/// Schlick's approximation `F = F0 + (1 − F0)(1 − cos θ)^5` (Schlick 1994),
/// used where a file format prescribes it (glTF's metallic-roughness model).
#[inline]
pub fn schlick(f0: Color, cos_i: f32) -> Color {
    let m = (1.0 - cos_i.clamp(0.0, 1.0)).powi(5);
    f0 + (Color::ONE - f0) * m
}

#[derive(Clone, Copy, Debug)]
struct Complex {
    re: f32,
    im: f32,
}

impl Complex {
    fn new(re: f32, im: f32) -> Self {
        Complex { re, im }
    }
    fn add(self, o: Complex) -> Complex {
        Complex::new(self.re + o.re, self.im + o.im)
    }
    fn sub(self, o: Complex) -> Complex {
        Complex::new(self.re - o.re, self.im - o.im)
    }
    fn mul(self, o: Complex) -> Complex {
        Complex::new(
            self.re * o.re - self.im * o.im,
            self.re * o.im + self.im * o.re,
        )
    }
    fn div(self, o: Complex) -> Complex {
        let s = 1.0 / (o.re * o.re + o.im * o.im);
        Complex::new(
            s * (self.re * o.re + self.im * o.im),
            s * (self.im * o.re - self.re * o.im),
        )
    }
    fn norm(self) -> f32 {
        self.re * self.re + self.im * self.im
    }
    /// The principal square root.
    fn sqrt(self) -> Complex {
        let n = self.norm().sqrt();
        if n == 0.0 {
            return Complex::new(0.0, 0.0);
        }
        let t1 = (0.5 * (n + self.re.abs())).sqrt();
        let t2 = 0.5 * self.im / t1;
        if self.re >= 0.0 {
            Complex::new(t1, t2)
        } else {
            Complex::new(t2.abs(), t1.copysign(self.im))
        }
    }
}

fn fr_complex(cos_i: f32, eta: Complex) -> f32 {
    let cos_i = Complex::new(cos_i, 0.0);
    let one = Complex::new(1.0, 0.0);
    let sin2_i = one.sub(cos_i.mul(cos_i));
    let sin2_t = sin2_i.div(eta.mul(eta));
    let cos_t = one.sub(sin2_t).sqrt();
    let r_par = eta.mul(cos_i).sub(cos_t).div(eta.mul(cos_i).add(cos_t));
    let r_perp = cos_i.sub(eta.mul(cos_t)).div(cos_i.add(eta.mul(cos_t)));
    0.5 * (r_par.norm() + r_perp.norm())
}

/// Complex indices of refraction of common metals, as RGB (the spectral
/// data of Palik's handbook reduced to sRGB primaries, as shipped with
/// pbrt-v3's and Mitsuba's example scenes): `(name, η, k)`.
pub const METALS: [(&str, [f32; 3], [f32; 3]); 4] = [
    (
        "Au",
        [0.143_119, 0.374_957, 1.442_48],
        [3.983_16, 2.385_72, 1.603_22],
    ),
    (
        "Ag",
        [0.155_265, 0.116_723, 0.138_342],
        [4.828_35, 3.122_25, 2.146_96],
    ),
    (
        "Cu",
        [0.200_438, 0.924_033, 1.102_21],
        [3.912_95, 2.452_85, 2.142_19],
    ),
    (
        "Al",
        [1.657_46, 0.880_369, 0.521_229],
        [9.223_87, 6.269_52, 4.837],
    ),
];

/// The complex index `(η, k)` of a metal named in [`METALS`].
pub fn metal(name: &str) -> Option<(Color, Color)> {
    METALS
        .iter()
        .find(|(n, _, _)| n.eq_ignore_ascii_case(name))
        .map(|(_, eta, k)| (Color::from(*eta), Color::from(*k)))
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

    #[test]
    fn both_dielectric_forms_agree() {
        for i in 0..=100 {
            let cos = i as f32 / 100.0;
            let a = fresnel_dielectric(cos, 1.0, 1.5).reflectance;
            assert!((fr_dielectric(cos, 1.5) - a).abs() < 1e-5, "{cos}");
            let b = fresnel_dielectric(cos, 1.5, 1.0).reflectance;
            assert!((fr_dielectric(-cos, 1.5) - b).abs() < 1e-5, "{cos}");
        }
    }

    #[test]
    fn conductor_with_no_absorption_is_a_dielectric() {
        for i in 1..=20 {
            let cos = i as f32 / 20.0;
            let c = fr_conductor(cos, Color::splat(1.5), Color::ZERO);
            assert!((c.x - fr_dielectric(cos, 1.5)).abs() < 1e-5, "{cos}: {c}");
        }
    }

    #[test]
    fn conductor_at_normal_incidence() {
        // R = ((η − 1)² + k²)/((η + 1)² + k²) at normal incidence.
        let (eta, k) = metal("au").unwrap();
        let r = fr_conductor(1.0, eta, k);
        let expect = ((eta - Color::ONE) * (eta - Color::ONE) + k * k)
            / ((eta + Color::ONE) * (eta + Color::ONE) + k * k);
        assert!((r - expect).abs().max_element() < 1e-5, "{r} vs {expect}");
        // Gold reflects red more than blue; everything goes to 1 at grazing.
        assert!(r.x > r.z);
        assert!(fr_conductor(1e-4, eta, k).min_element() > 0.99);
    }

    #[test]
    fn refract_eta_obeys_snell_from_both_sides() {
        let wi = Vec3::new(0.6, 0.0, 0.8);
        let (wt, eta) = refract_eta(wi, Vec3::Z, 1.5).unwrap();
        assert_eq!(eta, 1.5);
        assert!((0.6 - 1.5 * -wt.x).abs() < 1e-6 && wt.z < 0.0);
        // Back from the inside (wt points away from the surface, inwards):
        // the light leaves along wi.
        let (back, eta) = refract_eta(wt, Vec3::Z, 1.5).unwrap();
        assert!((eta - 1.0 / 1.5).abs() < 1e-7);
        assert!((back - wi).length() < 1e-5, "{back}");
        assert!(refract_eta(Vec3::new(0.9, 0.0, -0.435_889_9), Vec3::Z, 1.5).is_none());
    }

    #[test]
    fn schlick_ends() {
        let f0 = Color::splat(0.04);
        assert_eq!(schlick(f0, 1.0), f0);
        assert_eq!(schlick(f0, 0.0), Color::ONE);
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
