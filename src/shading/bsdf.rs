//! The closed set of BSDFs, evaluated and sampled in the local shading frame.
//!
//! Conventions (as pbrt-v4): `wo` and `wi` both point away from the surface;
//! `z` is the shading normal, which for a dielectric points to the outside
//! (the side of index 1). [`Bsdf::eval`] is `f(ωo, ωi)` without the cosine;
//! [`Bsdf::pdf`] a density over solid angle of `ωi`. Radiance flows from
//! `ωi` to `ωo` (camera paths), so refraction scales by `1/η²`.

use super::fresnel::{fr_conductor, fr_dielectric, refract_eta, schlick};
use super::microfacet::Ggx;
use crate::math::{Color, Vec3};
use std::f32::consts::FRAC_1_PI;

/// How a conductor's reflectance depends on the angle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ConductorFresnel {
    /// The same reflectance at every angle (Whitted's mirror; `1` is the
    /// perfect conductor of white-furnace tests).
    Constant(Color),
    /// A metal of complex index `η + i·k` ([`fr_conductor`]).
    Complex { eta: Color, k: Color },
    /// Schlick's approximation from the reflectance at normal incidence.
    Schlick(Color),
}

impl ConductorFresnel {
    #[inline]
    pub fn eval(&self, cos: f32) -> Color {
        match *self {
            ConductorFresnel::Constant(r) => r,
            ConductorFresnel::Complex { eta, k } => fr_conductor(cos, eta, k),
            ConductorFresnel::Schlick(f0) => schlick(f0, cos),
        }
    }
}

/// A BSDF at a surface point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Bsdf {
    /// Lambert: `f = ρ/π` on the side the light and viewer share.
    Diffuse { albedo: Color },
    /// Reflection only, from a GGX microfacet surface (Cook–Torrance with
    /// Walter 2007's normalisation): `f = D(ωm) F(ωo·ωm) G2(ωo, ωi) /
    /// (4 |cos θo| |cos θi|)` with `ωm` the half vector; a perfect mirror
    /// (`f = F/|cos θi|` on the mirror direction) when smooth.
    Conductor { fresnel: ConductorFresnel, ggx: Ggx },
    /// An interface to a medium of relative index `eta` (inside over
    /// outside), rough after Walter et al. 2007 (reflection and refraction
    /// chosen by the Fresnel reflectance), a delta pair when smooth.
    Dielectric { eta: f32, ggx: Ggx },
    /// glTF's metallic-roughness model: a Lambertian base under a GGX
    /// dielectric coat of `F0 = ((η − 1)/(η + 1))²` (0.04 for glTF's default
    /// η = 1.5), blended towards a GGX conductor of reflectance `base` by
    /// `metallic`. The specular lobe has Schlick's Fresnel from
    /// `F0 = lerp(F0_coat, base, metallic)`; the diffuse lobe
    /// `(1 − metallic)·base/π` is weighted by `(1 − F(cos θo))(1 − F(cos θi))`
    /// with the coat's `F0`, the light the coat lets in and out (a
    /// reciprocal, energy-bounded coupling as in Ashikhmin & Shirley 2000).
    /// A lobe is sampled with probability proportional to its estimated
    /// albedo.
    ///
    /// `transmission` (`KHR_materials_transmission`) turns that part of the
    /// dielectric into glass: with `w = (1 − metallic)·transmission`,
    /// `f = (1 − w)·f_opaque + w·f_glass`, where `f_opaque` is the model
    /// above with metallic `metallic/(1 − w)` (so the metal keeps its
    /// weight) and `f_glass` the [`Bsdf::Dielectric`] of index `eta` and
    /// microfacets `glass`, its transmission tinted by `base` (glTF's
    /// `specular_btdf · baseColor`). The glass part is chosen with
    /// probability `w`.
    Principled {
        base: Color,
        metallic: f32,
        ggx: Ggx,
        transmission: f32,
        eta: f32,
        glass: Ggx,
    },
}

/// A direction sampled from a BSDF.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    /// The sampled incident direction (local frame).
    pub wi: Vec3,
    /// `f(ωo, ωi)`; for a delta lobe, the weight the delta multiplies.
    pub f: Color,
    /// The density of `wi` (solid angle); for a delta lobe, the probability
    /// of choosing it.
    pub pdf: f32,
    /// Whether `wi` came from a delta lobe (then light sampling cannot find
    /// it, and no multiple importance weight applies).
    pub delta: bool,
    /// Whether `wi` crossed the surface.
    pub transmitted: bool,
}

impl BsdfSample {
    /// The factor this sample multiplies a path's throughput by:
    /// `f |cos θi| / pdf`.
    #[inline]
    pub fn weight(&self) -> Color {
        self.f * (self.wi.z.abs() / self.pdf)
    }
}

/// `w` mirrored below the surface when `flip`.
#[inline]
fn flip_z(w: Vec3, flip: bool) -> Vec3 {
    if flip { Vec3::new(w.x, w.y, -w.z) } else { w }
}

/// A cosine-weighted direction on the upper hemisphere (Malley's method:
/// a uniform point of the unit disc, lifted), density `cos θ/π`.
#[inline]
pub fn cosine_hemisphere(u: (f32, f32)) -> Vec3 {
    let r = u.0.sqrt();
    let (sin_p, cos_p) = crate::math::sin_cos_turns(u.1);
    // z = √(1 − r²) from u directly, beside r rather than after it.
    Vec3::new(r * cos_p, r * sin_p, (1.0 - u.0).max(0.0).sqrt())
}

impl Bsdf {
    /// Whether every lobe is a delta (smooth mirror or glass): such a BSDF
    /// is never sampled by lights.
    #[inline]
    pub fn is_delta(&self) -> bool {
        match self {
            Bsdf::Diffuse { .. } => false,
            // Only smooth glass is left when its weight is 1.
            Bsdf::Principled {
                metallic,
                transmission,
                glass,
                ..
            } => glass_weight(*metallic, *transmission) >= 1.0 && glass.is_smooth(),
            Bsdf::Conductor { ggx, .. } | Bsdf::Dielectric { ggx, .. } => ggx.is_smooth(),
        }
    }

    /// Whether [`Bsdf::sample`] chooses between lobes (uses its `uc`).
    #[inline]
    pub fn has_lobes(&self) -> bool {
        matches!(self, Bsdf::Dielectric { .. } | Bsdf::Principled { .. })
    }

    /// Whether light can pass through the surface.
    #[inline]
    pub fn transmits(&self) -> bool {
        match self {
            Bsdf::Dielectric { .. } => true,
            Bsdf::Principled {
                metallic,
                transmission,
                ..
            } => glass_weight(*metallic, *transmission) > 0.0,
            _ => false,
        }
    }

    /// The relative index of refraction (inside over outside) of light
    /// that crosses the surface; 1 where none does.
    #[inline]
    pub fn eta(&self) -> f32 {
        match *self {
            Bsdf::Dielectric { eta, .. } => eta,
            Bsdf::Principled { eta, .. } if self.transmits() => eta,
            _ => 1.0,
        }
    }

    /// `f(ωo, ωi)` (zero for delta lobes).
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Color {
        match *self {
            Bsdf::Diffuse { albedo } => {
                if wo.z * wi.z > 0.0 {
                    albedo * FRAC_1_PI
                } else {
                    Color::ZERO
                }
            }
            Bsdf::Conductor { fresnel, ggx } => {
                if ggx.is_smooth() || wo.z * wi.z <= 0.0 {
                    return Color::ZERO;
                }
                let flip = wo.z < 0.0;
                let (wo, wi) = (flip_z(wo, flip), flip_z(wi, flip));
                let Some(wm) = (wo + wi).try_normalize() else {
                    return Color::ZERO;
                };
                let f = fresnel.eval(wo.dot(wm).abs());
                f * (ggx.d(wm) * ggx.g(wo, wi) / (4.0 * wo.z * wi.z))
            }
            Bsdf::Dielectric { eta, ggx } => {
                if ggx.is_smooth() {
                    return Color::ZERO;
                }
                Color::splat(dielectric_eval(eta, &ggx, wo, wi))
            }
            Bsdf::Principled {
                base,
                metallic,
                ggx,
                transmission,
                eta,
                glass,
            } => {
                let w = glass_weight(metallic, transmission);
                let mut f = Color::ZERO;
                if w < 1.0 && wo.z * wi.z > 0.0 {
                    let metallic = opaque_metallic(metallic, w);
                    let f0 = coat_f0(eta);
                    let flip = wo.z < 0.0;
                    let (wo, wi) = (flip_z(wo, flip), flip_z(wi, flip));
                    f = (principled_diffuse(base, metallic, f0, wo, wi)
                        + principled_specular(base, metallic, f0, &ggx, wo, wi))
                        * (1.0 - w);
                }
                if w > 0.0 && !glass.is_smooth() {
                    let tint = if wo.z * wi.z < 0.0 { base } else { Color::ONE };
                    f += tint * (w * dielectric_eval(eta, &glass, wo, wi));
                }
                f
            }
        }
    }

    /// The density with which [`Bsdf::sample`] picks `wi` (zero for delta
    /// lobes).
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        match *self {
            Bsdf::Diffuse { .. } => {
                if wo.z * wi.z > 0.0 {
                    wi.z.abs() * FRAC_1_PI
                } else {
                    0.0
                }
            }
            Bsdf::Conductor { ggx, .. } => {
                if ggx.is_smooth() || wo.z * wi.z <= 0.0 {
                    return 0.0;
                }
                let flip = wo.z < 0.0;
                let (wo, wi) = (flip_z(wo, flip), flip_z(wi, flip));
                let Some(wm) = (wo + wi).try_normalize() else {
                    return 0.0;
                };
                // Reflection maps ωm to ωi with Jacobian 1/(4 |ωo·ωm|).
                ggx.d_visible(wo, wm) / (4.0 * wo.dot(wm).abs())
            }
            Bsdf::Dielectric { eta, ggx } => {
                if ggx.is_smooth() {
                    return 0.0;
                }
                dielectric_pdf(eta, &ggx, wo, wi)
            }
            Bsdf::Principled {
                base,
                metallic,
                ggx,
                transmission,
                eta,
                glass,
            } => {
                let w = glass_weight(metallic, transmission);
                let mut pdf = 0.0;
                if w < 1.0 && wo.z * wi.z > 0.0 {
                    let metallic = opaque_metallic(metallic, w);
                    let f0 = coat_f0(eta);
                    let flip = wo.z < 0.0;
                    let (wo, wi) = (flip_z(wo, flip), flip_z(wi, flip));
                    let p_spec = principled_specular_probability(base, metallic, f0, wo);
                    let diffuse = wi.z * FRAC_1_PI;
                    let specular = match (wo + wi).try_normalize() {
                        Some(wm) if !ggx.is_smooth() => ggx.d_visible(wo, wm) / (4.0 * wo.dot(wm)),
                        _ => 0.0,
                    };
                    pdf = (1.0 - w) * (p_spec * specular + (1.0 - p_spec) * diffuse);
                }
                if w > 0.0 && !glass.is_smooth() {
                    pdf += w * dielectric_pdf(eta, &glass, wo, wi);
                }
                pdf
            }
        }
    }

    /// Samples `wi` given `wo`, with `uc` choosing a lobe and `u` a
    /// direction within it. `None` where no direction carries light (the
    /// sampled microfacet sends it below the surface, say).
    pub fn sample(&self, wo: Vec3, uc: f32, u: (f32, f32)) -> Option<BsdfSample> {
        if wo.z == 0.0 {
            return None;
        }
        match *self {
            Bsdf::Diffuse { albedo } => {
                let wi = flip_z(cosine_hemisphere(u), wo.z < 0.0);
                let pdf = wi.z.abs() * FRAC_1_PI;
                (pdf > 0.0).then_some(BsdfSample {
                    wi,
                    f: albedo * FRAC_1_PI,
                    pdf,
                    delta: false,
                    transmitted: false,
                })
            }
            Bsdf::Conductor { fresnel, ggx } => {
                let flip = wo.z < 0.0;
                let wo = flip_z(wo, flip);
                if ggx.is_smooth() {
                    let wi = Vec3::new(-wo.x, -wo.y, wo.z);
                    return Some(BsdfSample {
                        wi: flip_z(wi, flip),
                        f: fresnel.eval(wo.z) / wo.z,
                        pdf: 1.0,
                        delta: true,
                        transmitted: false,
                    });
                }
                let wm = ggx.sample_visible(wo, u);
                let wi = 2.0 * wo.dot(wm) * wm - wo;
                if wi.z <= 0.0 {
                    return None;
                }
                let pdf = ggx.d_visible(wo, wm) / (4.0 * wo.dot(wm).abs());
                let f = fresnel.eval(wo.dot(wm).abs())
                    * (ggx.d(wm) * ggx.g(wo, wi) / (4.0 * wo.z * wi.z));
                (pdf > 0.0 && pdf.is_finite()).then_some(BsdfSample {
                    wi: flip_z(wi, flip),
                    f,
                    pdf,
                    delta: false,
                    transmitted: false,
                })
            }
            Bsdf::Dielectric { eta, ggx } => dielectric_sample(eta, &ggx, wo, uc, u),
            Bsdf::Principled {
                base,
                metallic,
                ggx,
                transmission,
                eta,
                glass,
            } => {
                let w = glass_weight(metallic, transmission);
                // The glass part with probability w (uc rescaled for its
                // own lobe choice), else the opaque part.
                if uc < w {
                    let s = dielectric_sample(eta, &glass, wo, uc / w, u)?;
                    let tint = if s.transmitted { base } else { Color::ONE };
                    if s.delta {
                        return Some(BsdfSample {
                            f: s.f * tint * w,
                            pdf: s.pdf * w,
                            ..s
                        });
                    }
                    let pdf = self.pdf(wo, s.wi);
                    return (pdf > 0.0 && pdf.is_finite()).then(|| BsdfSample {
                        f: self.eval(wo, s.wi),
                        pdf,
                        ..s
                    });
                }
                let metallic = opaque_metallic(metallic, w);
                let flip = wo.z < 0.0;
                let wo_up = flip_z(wo, flip);
                let p_spec = principled_specular_probability(base, metallic, coat_f0(eta), wo_up);
                let uc = if w > 0.0 { (uc - w) / (1.0 - w) } else { uc };
                let wi = if uc < p_spec {
                    let wm = ggx.sample_visible(wo_up, u);
                    2.0 * wo_up.dot(wm) * wm - wo_up
                } else {
                    cosine_hemisphere(u)
                };
                if wi.z <= 0.0 {
                    return None;
                }
                let wi = flip_z(wi, flip);
                let pdf = self.pdf(wo, wi);
                (pdf > 0.0 && pdf.is_finite()).then(|| BsdfSample {
                    wi,
                    f: self.eval(wo, wi),
                    pdf,
                    delta: false,
                    transmitted: false,
                })
            }
        }
    }
}

/// The coat's reflectance at normal incidence for index `eta`:
/// `((η − 1)/(η + 1))²`, 0.04 for glass of 1.5.
#[inline]
fn coat_f0(eta: f32) -> f32 {
    ((eta - 1.0) / (eta + 1.0)).powi(2)
}

/// The weight of [`Bsdf::Principled`]'s glass part.
#[inline]
fn glass_weight(metallic: f32, transmission: f32) -> f32 {
    (1.0 - metallic) * transmission
}

/// The metallic of [`Bsdf::Principled`]'s opaque part (weight `1 − w`)
/// that keeps the metal's weight `metallic` in the whole.
#[inline]
fn opaque_metallic(metallic: f32, w: f32) -> f32 {
    if w > 0.0 {
        (metallic / (1.0 - w)).min(1.0)
    } else {
        metallic
    }
}

/// [`Bsdf::Principled`]'s diffuse lobe (both directions above).
#[inline]
fn principled_diffuse(base: Color, metallic: f32, f0: f32, wo: Vec3, wi: Vec3) -> Color {
    let coat = |c: f32| 1.0 - schlick(Color::splat(f0), c).x;
    base * ((1.0 - metallic) * FRAC_1_PI * coat(wo.z) * coat(wi.z))
}

/// [`Bsdf::Principled`]'s specular lobe (both directions above).
#[inline]
fn principled_specular(
    base: Color,
    metallic: f32,
    f0: f32,
    ggx: &Ggx,
    wo: Vec3,
    wi: Vec3,
) -> Color {
    if ggx.is_smooth() {
        return Color::ZERO;
    }
    let Some(wm) = (wo + wi).try_normalize() else {
        return Color::ZERO;
    };
    let f0 = Color::splat(f0).lerp(base, metallic);
    schlick(f0, wo.dot(wm)) * (ggx.d(wm) * ggx.g(wo, wi) / (4.0 * wo.z * wi.z))
}

/// The probability of sampling [`Bsdf::Principled`]'s specular lobe seen
/// from `wo`: its Fresnel weight against the diffuse lobe's albedo.
#[inline]
fn principled_specular_probability(base: Color, metallic: f32, f0: f32, wo: Vec3) -> f32 {
    let coat = Color::splat(f0);
    let spec = schlick(coat.lerp(base, metallic), wo.z).max_element();
    let diffuse = (1.0 - metallic) * base.max_element() * (1.0 - schlick(coat, wo.z).x);
    if spec + diffuse <= 0.0 {
        return 0.5;
    }
    (spec / (spec + diffuse)).clamp(0.05, 0.95)
}

/// The generalised half vector of Walter et al. 2007 (eq. 16) for `wo`,
/// `wi`, oriented to `+z`, with the relative index `η'` of the crossing
/// (`1` for reflection). `None` for degenerate configurations and for
/// microfacets seen from behind by either direction.
#[inline]
fn half_vector(eta: f32, wo: Vec3, wi: Vec3) -> Option<(Vec3, f32, bool)> {
    let (cos_o, cos_i) = (wo.z, wi.z);
    if cos_o == 0.0 || cos_i == 0.0 {
        return None;
    }
    let reflect = cos_o * cos_i > 0.0;
    let etap = if reflect {
        1.0
    } else if cos_o > 0.0 {
        eta
    } else {
        1.0 / eta
    };
    let wm = (wi * etap + wo).try_normalize()?;
    let wm = if wm.z < 0.0 { -wm } else { wm };
    // Both directions must see the microfacet from its own side.
    if wm.dot(wi) * cos_i < 0.0 || wm.dot(wo) * cos_o < 0.0 {
        return None;
    }
    Some((wm, etap, reflect))
}

/// Rough dielectric `f` (Walter et al. 2007, eqs. 20 and 21):
/// reflection `D F G2 / (4 |cos θo cos θi|)`, transmission
/// `D (1 − F) G2 |ωi·ωm| |ωo·ωm| / (|cos θo cos θi| (ωi·ωm + ωo·ωm/η')²) / η'²`.
fn dielectric_eval(eta: f32, ggx: &Ggx, wo: Vec3, wi: Vec3) -> f32 {
    let Some((wm, etap, reflect)) = half_vector(eta, wo, wi) else {
        return 0.0;
    };
    let f = fr_dielectric(wo.dot(wm), eta);
    let (cos_o, cos_i) = (wo.z, wi.z);
    if reflect {
        return ggx.d(wm) * ggx.g(wo, wi) * f / (4.0 * cos_o * cos_i).abs();
    }
    let denom = (wi.dot(wm) + wo.dot(wm) / etap).powi(2) * cos_i * cos_o;
    let ft = ggx.d(wm) * (1.0 - f) * ggx.g(wo, wi) * (wi.dot(wm) * wo.dot(wm) / denom).abs();
    ft / (etap * etap)
}

/// The density of [`dielectric_sample`]: the visible-normal density times
/// the Jacobian of reflection (`1/(4|ωo·ωm|)`) or refraction
/// (`|ωi·ωm|/(ωi·ωm + ωo·ωm/η')²`), times the probability of the lobe.
fn dielectric_pdf(eta: f32, ggx: &Ggx, wo: Vec3, wi: Vec3) -> f32 {
    let Some((wm, etap, reflect)) = half_vector(eta, wo, wi) else {
        return 0.0;
    };
    let r = fr_dielectric(wo.dot(wm), eta);
    let t = 1.0 - r;
    if reflect {
        ggx.d_visible(wo, wm) / (4.0 * wo.dot(wm).abs()) * r
    } else {
        let denom = (wi.dot(wm) + wo.dot(wm) / etap).powi(2);
        ggx.d_visible(wo, wm) * wi.dot(wm).abs() / denom * t
    }
}

fn dielectric_sample(eta: f32, ggx: &Ggx, wo: Vec3, uc: f32, u: (f32, f32)) -> Option<BsdfSample> {
    if ggx.is_smooth() {
        let r = fr_dielectric(wo.z, eta);
        let t = 1.0 - r;
        if uc < r {
            let wi = Vec3::new(-wo.x, -wo.y, wo.z);
            return Some(BsdfSample {
                wi,
                f: Color::splat(r / wi.z.abs()),
                pdf: r,
                delta: true,
                transmitted: false,
            });
        }
        let (wi, etap) = refract_eta(wo, Vec3::Z, eta)?;
        if wi.z == 0.0 {
            return None;
        }
        return Some(BsdfSample {
            wi,
            f: Color::splat(t / wi.z.abs() / (etap * etap)),
            pdf: t,
            delta: true,
            transmitted: true,
        });
    }
    // A visible microfacet normal (z > 0; for wo inside, one seen from
    // the inside). Fresnel and refraction take the side from wo·ωm.
    let wm = ggx.sample_visible(wo, u);
    let r = fr_dielectric(wo.dot(wm), eta);
    if uc < r {
        let wi = 2.0 * wo.dot(wm) * wm - wo;
        if wo.z * wi.z <= 0.0 {
            return None;
        }
        let pdf = dielectric_pdf(eta, ggx, wo, wi);
        let f = dielectric_eval(eta, ggx, wo, wi);
        return (pdf > 0.0).then_some(BsdfSample {
            wi,
            f: Color::splat(f),
            pdf,
            delta: false,
            transmitted: false,
        });
    }
    let (wi, _) = refract_eta(wo, wm, eta)?;
    if wo.z * wi.z >= 0.0 || wi.z == 0.0 {
        return None;
    }
    let pdf = dielectric_pdf(eta, ggx, wo, wi);
    let f = dielectric_eval(eta, ggx, wo, wi);
    (pdf > 0.0).then_some(BsdfSample {
        wi,
        f: Color::splat(f),
        pdf,
        delta: false,
        transmitted: true,
    })
}
