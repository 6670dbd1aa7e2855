//! The Trowbridge–Reitz (GGX) microfacet distribution, anisotropic, with
//! Smith's height-correlated masking-shadowing and sampling of the visible
//! normals.
//!
//! All directions are in the local shading frame (`z` = the normal).
//! References: Walter et al., "Microfacet Models for Refraction through
//! Rough Surfaces", EGSR 2007; Heitz, "Understanding the Masking-Shadowing
//! Function in Microfacet-Based BRDFs", JCGT 3(2), 2014; Heitz, "Sampling the
//! GGX Distribution of Visible Normals", JCGT 7(4), 2018.

use crate::math::Vec3;
use std::f32::consts::PI;

/// Below this `α` a surface is treated as perfectly smooth (a delta BSDF):
/// the distribution is then too narrow for f32 to evaluate.
pub const SMOOTH_ALPHA: f32 = 1e-3;

/// A GGX distribution with roughnesses `α_x`, `α_y` along the frame's axes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ggx {
    pub alpha_x: f32,
    pub alpha_y: f32,
}

impl Ggx {
    /// The distribution of a surface of perceptual `roughness` in [0, 1]
    /// (`α = roughness²`, as glTF and Disney's model define it) and
    /// `anisotropy` in (−1, 1) (`α_x = α(1 + a)`, `α_y = α(1 − a)`).
    pub fn from_roughness(roughness: f32, anisotropy: f32) -> Self {
        let alpha = roughness * roughness;
        Ggx {
            alpha_x: (alpha * (1.0 + anisotropy)).max(0.0),
            alpha_y: (alpha * (1.0 - anisotropy)).max(0.0),
        }
    }

    /// Whether the surface is a perfect mirror (or interface) for shading.
    #[inline]
    pub fn is_smooth(&self) -> bool {
        self.alpha_x.max(self.alpha_y) < SMOOTH_ALPHA
    }

    /// `D(ω_m) = 1 / (π α_x α_y cos⁴θ_m (1 + tan²θ_m (cos²φ/α_x² + sin²φ/α_y²))²)`
    /// (Walter 2007, eq. 33, anisotropic form of Heitz 2014 eq. 85).
    #[inline]
    pub fn d(&self, wm: Vec3) -> f32 {
        let cos2 = wm.z * wm.z;
        let sin2 = (1.0 - cos2).max(0.0);
        let tan2 = sin2 / cos2;
        if !tan2.is_finite() {
            return 0.0;
        }
        let cos4 = cos2 * cos2;
        let (cos2_phi, sin2_phi) = if sin2 > 0.0 {
            (wm.x * wm.x / sin2, wm.y * wm.y / sin2)
        } else {
            (1.0, 0.0)
        };
        let e = tan2
            * (cos2_phi / (self.alpha_x * self.alpha_x) + sin2_phi / (self.alpha_y * self.alpha_y));
        1.0 / (PI * self.alpha_x * self.alpha_y * cos4 * (1.0 + e) * (1.0 + e))
    }

    /// Smith's `Λ(ω) = (√(1 + α(φ)² tan²θ) − 1)/2`, with
    /// `α(φ)² = α_x² cos²φ + α_y² sin²φ` (Heitz 2014, eq. 86).
    #[inline]
    pub fn lambda(&self, w: Vec3) -> f32 {
        let cos2 = w.z * w.z;
        let sin2 = (1.0 - cos2).max(0.0);
        let tan2 = sin2 / cos2;
        if !tan2.is_finite() {
            return 0.0;
        }
        let alpha2 = if sin2 > 0.0 {
            (w.x * w.x * self.alpha_x * self.alpha_x + w.y * w.y * self.alpha_y * self.alpha_y)
                / sin2
        } else {
            self.alpha_x * self.alpha_x
        };
        0.5 * ((1.0 + alpha2 * tan2).sqrt() - 1.0)
    }

    /// Masking `G1(ω) = 1/(1 + Λ(ω))`.
    #[inline]
    pub fn g1(&self, w: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(w))
    }

    /// Height-correlated masking-shadowing
    /// `G2(ω_o, ω_i) = 1/(1 + Λ(ω_o) + Λ(ω_i))` (Heitz 2014, eq. 99).
    #[inline]
    pub fn g(&self, wo: Vec3, wi: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(wo) + self.lambda(wi))
    }

    /// The density of visible normals seen from `w`:
    /// `D_ω(ω_m) = G1(ω)/|cos θ| · D(ω_m) · |ω·ω_m|` (Heitz 2014, eq. 16),
    /// a density over solid angle of `ω_m`.
    /// Zero for normals facing away from `w` (for a `w` below the surface,
    /// those facing away from `−w`).
    #[inline]
    pub fn d_visible(&self, w: Vec3, wm: Vec3) -> f32 {
        let cos = w.dot(wm);
        if cos * w.z <= 0.0 {
            return 0.0;
        }
        self.g1(w) / w.z.abs() * self.d(wm) * cos.abs()
    }

    /// Samples a normal (`z > 0`) from [`Ggx::d_visible`] for `w`, by Heitz
    /// 2018's method. A `w` below the surface is taken as `−w`, which has the
    /// same density of visible normals (it depends on `|ω·ωm|` only). Stretch `w` to the configuration of roughness 1, pick
    /// a point on the projected hemisphere (a disc with its far half
    /// squashed by `(1 + cos θ)/2`), lift it to the hemisphere, and unstretch
    /// the normal.
    #[inline]
    pub fn sample_visible(&self, w: Vec3, u: (f32, f32)) -> Vec3 {
        let mut wh = Vec3::new(self.alpha_x * w.x, self.alpha_y * w.y, w.z).normalize();
        if wh.z < 0.0 {
            wh = -wh;
        }
        let t1 = if wh.z < 0.99999 {
            Vec3::Z.cross(wh).normalize()
        } else {
            Vec3::X
        };
        let t2 = wh.cross(t1);
        // A uniform point on the unit disc (polar mapping).
        let r = u.0.sqrt();
        let (sin_p, cos_p) = crate::math::sin_cos_turns(u.1);
        let (px, mut py) = (r * cos_p, r * sin_p);
        let h = (1.0 - px * px).max(0.0).sqrt();
        let s = 0.5 * (1.0 + wh.z);
        py = (1.0 - s) * h + s * py;
        let pz = (1.0 - px * px - py * py).max(0.0).sqrt();
        let nh = px * t1 + py * t2 + pz * wh;
        Vec3::new(self.alpha_x * nh.x, self.alpha_y * nh.y, nh.z.max(1e-6)).normalize()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::Pcg32;

    fn uniform_sphere(rng: &mut Pcg32) -> Vec3 {
        let z = 1.0 - 2.0 * rng.next_f32();
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = 2.0 * PI * rng.next_f32();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }

    /// `∫ D(ω_m) cos θ_m dω_m = 1`: the projected microfacet area is the
    /// macro surface's (Monte Carlo over the sphere, uniform directions).
    #[test]
    fn projected_area_is_one() {
        for (ax, ay) in [(0.5, 0.5), (0.2, 0.6), (0.9, 0.3)] {
            let ggx = Ggx {
                alpha_x: ax,
                alpha_y: ay,
            };
            let mut rng = Pcg32::new(1, 2);
            let n = 400_000;
            let mut sum = 0.0f64;
            for _ in 0..n {
                let w = uniform_sphere(&mut rng);
                if w.z > 0.0 {
                    sum += (ggx.d(w) * w.z) as f64;
                }
            }
            let integral = sum * 4.0 * std::f64::consts::PI / n as f64;
            assert!((integral - 1.0).abs() < 0.03, "α {ax},{ay}: {integral}");
        }
    }

    /// `∫ D_ω(ω_m) dω_m = 1` for every `ω` (visible normals are a
    /// density), which is also Smith's `G1` being the right normalisation.
    #[test]
    fn visible_normals_integrate_to_one() {
        let ggx = Ggx {
            alpha_x: 0.4,
            alpha_y: 0.25,
        };
        for theta in [0.1f32, 0.8, 1.3] {
            let w = Vec3::new(theta.sin() * 0.6, theta.sin() * 0.8, theta.cos());
            let mut rng = Pcg32::new(3, 4);
            let n = 400_000;
            let mut sum = 0.0f64;
            for _ in 0..n {
                let m = uniform_sphere(&mut rng);
                if m.z > 0.0 {
                    sum += ggx.d_visible(w, m) as f64;
                }
            }
            let integral = sum * 4.0 * std::f64::consts::PI / n as f64;
            assert!((integral - 1.0).abs() < 0.03, "θ {theta}: {integral}");
        }
    }

    #[test]
    fn isotropic_lambda_matches_closed_form() {
        let ggx = Ggx::from_roughness(0.5, 0.0);
        let a = ggx.alpha_x;
        for theta in [0.2f32, 0.7, 1.2, 1.5] {
            let w = Vec3::new(theta.sin(), 0.0, theta.cos());
            let expect = 0.5 * ((1.0 + a * a * theta.tan().powi(2)).sqrt() - 1.0);
            let rotated = Vec3::new(0.0, theta.sin(), theta.cos());
            assert!((ggx.lambda(w) - expect).abs() < 1e-5);
            assert!((ggx.lambda(rotated) - expect).abs() < 1e-5);
        }
    }

    #[test]
    fn sampled_normals_face_the_viewer_side() {
        let ggx = Ggx::from_roughness(0.7, 0.3);
        let mut rng = Pcg32::new(5, 6);
        for _ in 0..10_000 {
            let mut w = uniform_sphere(&mut rng);
            if w.z.abs() < 1e-3 {
                continue;
            }
            let m = ggx.sample_visible(w, (rng.next_f32(), rng.next_f32()));
            assert!(m.z > 0.0 && (m.length() - 1.0).abs() < 1e-4);
            if w.z < 0.0 {
                w = -w;
            }
            // Visible normals face the (mirrored) viewer.
            assert!(w.dot(m) > -1e-4, "{w} {m}");
        }
    }
}
