//! Statistical tests of the BSDFs: sampling against densities (Pearson's
//! chi-square, as pbrt's and Mitsuba's test suites do), energy, reciprocity,
//! and the agreement of `sample` with `eval` and `pdf`.

use super::*;
use crate::render::Pcg32;
use std::f64::consts::PI;

fn rough_bsdfs() -> Vec<(&'static str, Bsdf)> {
    let gold = fresnel::metal("Au").unwrap();
    vec![
        (
            "diffuse",
            Bsdf::Diffuse {
                albedo: Color::new(0.9, 0.5, 0.1),
            },
        ),
        (
            "conductor r=0.5",
            Bsdf::Conductor {
                fresnel: ConductorFresnel::Complex {
                    eta: gold.0,
                    k: gold.1,
                },
                ggx: Ggx::from_roughness(0.5, 0.0),
            },
        ),
        (
            "conductor r=0.7 anisotropic",
            Bsdf::Conductor {
                fresnel: ConductorFresnel::Constant(Color::ONE),
                ggx: Ggx::from_roughness(0.7, 0.6),
            },
        ),
        (
            "dielectric r=0.5",
            Bsdf::Dielectric {
                eta: 1.5,
                ggx: Ggx::from_roughness(0.5, 0.0),
            },
        ),
        (
            "principled plastic r=0.5",
            Bsdf::Principled {
                base: Color::new(0.9, 0.3, 0.1),
                metallic: 0.0,
                ggx: Ggx::from_roughness(0.5, 0.0),
                transmission: 0.0,
                eta: 1.5,
                glass: Ggx::from_roughness(0.5, 0.0),
            },
        ),
        (
            "principled half metal r=0.6",
            Bsdf::Principled {
                base: Color::ONE,
                metallic: 0.5,
                ggx: Ggx::from_roughness(0.6, 0.0),
                transmission: 0.0,
                eta: 1.5,
                glass: Ggx::from_roughness(0.6, 0.0),
            },
        ),
        (
            "principled transmission 0.6 r=0.4 η=1.4",
            Bsdf::Principled {
                base: Color::new(0.9, 0.6, 0.3),
                metallic: 0.2,
                ggx: Ggx::from_roughness(0.4, 0.0),
                transmission: 0.6,
                eta: 1.4,
                glass: Ggx::from_roughness(0.4, 0.0),
            },
        ),
        (
            "principled glass r=0.3",
            Bsdf::Principled {
                base: Color::ONE,
                metallic: 0.0,
                ggx: Ggx::from_roughness(0.3, 0.0),
                transmission: 1.0,
                eta: 1.5,
                glass: Ggx::from_roughness(0.3, 0.0),
            },
        ),
        (
            "dielectric r=0.8 η=1.33",
            Bsdf::Dielectric {
                eta: 1.33,
                ggx: Ggx::from_roughness(0.8, 0.0),
            },
        ),
    ]
}

fn directions() -> Vec<Vec3> {
    [
        (0.1f32, 0.3f32),
        (0.9, 1.0),
        (1.35, 2.5),
        (2.2, 0.7),
        (3.0, 4.0),
    ]
    .iter()
    .map(|&(theta, phi)| {
        Vec3::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        )
    })
    .collect()
}

fn dir(theta: f64, phi: f64) -> Vec3 {
    Vec3::new(
        (theta.sin() * phi.cos()) as f32,
        (theta.sin() * phi.sin()) as f32,
        theta.cos() as f32,
    )
}

/// Upper tail of the chi-square distribution with `k` degrees of freedom
/// (Wilson–Hilferty's normal approximation of the cube root, accurate to
/// well below the significance levels used here for `k ≥ 10`).
fn chi2_upper_tail(x: f64, k: f64) -> f64 {
    let z = ((x / k).cbrt() - (1.0 - 2.0 / (9.0 * k))) / (2.0 / (9.0 * k)).sqrt();
    0.5 * erfc(z / std::f64::consts::SQRT_2)
}

/// The complementary error function (Numerical Recipes' Chebyshev fit,
/// relative error below 1.2e-7).
fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let r = t
        * (-z * z - 1.265_512_23
            + t * (1.000_023_68
                + t * (0.374_091_96
                    + t * (0.096_784_18
                        + t * (-0.186_288_06
                            + t * (0.278_868_07
                                + t * (-1.135_203_98
                                    + t * (1.488_515_87
                                        + t * (-0.822_152_23 + t * 0.170_872_77)))))))))
            .exp();
    if x >= 0.0 { r } else { 2.0 - r }
}

/// Pearson's chi-square test of `sample` against `pdf` on a θ×φ grid over
/// the sphere: the expected count of each cell is `n ∫ pdf dω` over it
/// (midpoint rule on a finer grid), cells expecting fewer than 5 samples are
/// pooled, and the test fails below a significance of 1e-4 (many tests run).
fn chi_square(bsdf: &Bsdf, wo: Vec3, seed: u64) -> Result<(), String> {
    chi_square_of(
        |uc, u| bsdf.sample(wo, uc, u).map(|s| s.wi),
        |wi| bsdf.pdf(wo, wi),
        seed,
        400_000,
        24,
    )
}

/// [`chi_square`] of any sampling routine against any density.
/// `n` samples; each cell's pdf integrated on a `sub × sub` grid (finer
/// for densities with sharp edges).
pub(crate) fn chi_square_of(
    sample: impl Fn(f32, (f32, f32)) -> Option<Vec3>,
    pdf: impl Fn(Vec3) -> f32,
    seed: u64,
    n: u32,
    sub: usize,
) -> Result<(), String> {
    const THETA: usize = 20;
    const PHI: usize = 40;
    let mut rng = Pcg32::new(seed, 1);
    let mut observed = vec![0f64; THETA * PHI];
    for _ in 0..n {
        let uc = rng.next_f32();
        let u = (rng.next_f32(), rng.next_f32());
        let Some(wi) = sample(uc, u) else {
            continue;
        };
        let w = wi.normalize();
        let theta = (w.z as f64).clamp(-1.0, 1.0).acos();
        let mut phi = (w.y as f64).atan2(w.x as f64);
        if phi < 0.0 {
            phi += 2.0 * PI;
        }
        let i = ((theta / PI * THETA as f64) as usize).min(THETA - 1);
        let j = ((phi / (2.0 * PI) * PHI as f64) as usize).min(PHI - 1);
        observed[i * PHI + j] += 1.0;
    }
    let mut expected = vec![0f64; THETA * PHI];
    let (dt, dp) = (PI / THETA as f64, 2.0 * PI / PHI as f64);
    for i in 0..THETA {
        for j in 0..PHI {
            let mut sum = 0.0;
            for a in 0..sub {
                for b in 0..sub {
                    let theta = (i as f64 + (a as f64 + 0.5) / sub as f64) * dt;
                    let phi = (j as f64 + (b as f64 + 0.5) / sub as f64) * dp;
                    let pdf = pdf(dir(theta, phi)) as f64;
                    sum += pdf * theta.sin();
                }
            }
            expected[i * PHI + j] = sum * dt * dp / (sub * sub) as f64 * n as f64;
        }
    }
    // Pool the cells that expect little, smallest first.
    let mut cells: Vec<(f64, f64)> = expected.into_iter().zip(observed).collect();
    cells.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (mut pooled_e, mut pooled_o) = (0.0, 0.0);
    let (mut chi2, mut dof) = (0.0, 0usize);
    // Samples in cells where the integrated pdf is 0: a cell the support
    // only grazes (thinner than the integration grid) holds a few; more
    // means samples where there is no density.
    let stray: f64 = cells.iter().filter(|c| c.0 == 0.0).map(|c| c.1).sum();
    if stray > 1e-3 * n as f64 {
        return Err(format!("{stray} samples where the pdf is 0"));
    }
    pooled_o += stray;
    for (e, o) in cells.into_iter().filter(|c| c.0 > 0.0) {
        if e < 5.0 || pooled_e > 0.0 && pooled_e < 5.0 {
            pooled_e += e;
            pooled_o += o;
            continue;
        }
        chi2 += (o - e) * (o - e) / e;
        dof += 1;
    }
    if pooled_e > 0.0 {
        chi2 += (pooled_o - pooled_e) * (pooled_o - pooled_e) / pooled_e;
        dof += 1;
    }
    let p = chi2_upper_tail(chi2, (dof - 1) as f64);
    if p < 1e-4 {
        return Err(format!("χ² = {chi2:.1} over {dof} cells, p = {p:.2e}"));
    }
    Ok(())
}

#[test]
fn sampling_matches_pdf_chi_square() {
    for (name, bsdf) in rough_bsdfs() {
        for (k, wo) in directions().into_iter().enumerate() {
            if let Err(e) = chi_square(&bsdf, wo, 10 + k as u64) {
                panic!("{name}, wo {wo}: {e}");
            }
        }
    }
}

/// The test can fail: sampling one roughness against the density of a
/// slightly different one is rejected.
#[test]
fn chi_square_rejects_a_wrong_density() {
    let conductor = |r| Bsdf::Conductor {
        fresnel: ConductorFresnel::Constant(Color::ONE),
        ggx: Ggx::from_roughness(r, 0.0),
    };
    let (a, b) = (conductor(0.5), conductor(0.55));
    let wo = directions()[1];
    assert!(
        chi_square_of(
            |uc, u| a.sample(wo, uc, u).map(|s| s.wi),
            |wi| a.pdf(wo, wi),
            1,
            400_000,
            24
        )
        .is_ok()
    );
    assert!(
        chi_square_of(
            |uc, u| a.sample(wo, uc, u).map(|s| s.wi),
            |wi| b.pdf(wo, wi),
            1,
            400_000,
            24
        )
        .is_err()
    );
}

/// Non-delta samples report exactly what `eval` and `pdf` say.
#[test]
fn samples_agree_with_eval_and_pdf() {
    let mut rng = Pcg32::new(5, 5);
    for (name, bsdf) in rough_bsdfs() {
        for wo in directions() {
            for _ in 0..2000 {
                let Some(s) = bsdf.sample(wo, rng.next_f32(), (rng.next_f32(), rng.next_f32()))
                else {
                    continue;
                };
                let (f, pdf) = (bsdf.eval(wo, s.wi), bsdf.pdf(wo, s.wi));
                let tol = |a: f32, b: f32| (a - b).abs() <= 2e-3 * a.abs().max(b.abs()) + 1e-6;
                assert!(
                    tol(f.x, s.f.x) && tol(f.z, s.f.z),
                    "{name}: f {f} vs {}",
                    s.f
                );
                assert!(tol(pdf, s.pdf), "{name}: pdf {pdf} vs {}", s.pdf);
            }
        }
    }
}

/// The directional albedo `∫ f |cos θi| dωi ≤ 1` for every BSDF and
/// direction, estimated two ways that must agree: by the BSDF's own samples
/// and by uniform directions over the sphere.
#[test]
fn albedo_is_at_most_one() {
    let mut all = rough_bsdfs();
    all.push(("white diffuse", Bsdf::Diffuse { albedo: Color::ONE }));
    for (name, bsdf) in all {
        // Radiance crossing into a medium of index η is η² times denser
        // (Veach 1997, §5.2): energy is the radiance weight times
        // (η_i/η_o)².
        let eta = bsdf.eta();
        let side = |w: Vec3| if w.z > 0.0 { 1.0 } else { eta };
        let energy = |wo: Vec3, wi: Vec3| (side(wi) / side(wo)).powi(2);
        for wo in directions() {
            let mut rng = Pcg32::new(7, 7);
            let n = 200_000;
            let mut by_sample = 0.0f64;
            for _ in 0..n {
                if let Some(s) = bsdf.sample(wo, rng.next_f32(), (rng.next_f32(), rng.next_f32())) {
                    by_sample += (s.weight().max_element() * energy(wo, s.wi)) as f64;
                }
            }
            // The midpoint rule on a fine θ×φ grid (the lobes are too peaked
            // for uniform Monte Carlo to be precise).
            let (nt, np) = (600, 400);
            let mut by_grid = 0.0f64;
            for i in 0..nt {
                let theta = (i as f64 + 0.5) / nt as f64 * PI;
                for j in 0..np {
                    let phi = (j as f64 + 0.5) / np as f64 * 2.0 * PI;
                    let wi = dir(theta, phi);
                    by_grid += (bsdf.eval(wo, wi).max_element() * wi.z.abs() * energy(wo, wi))
                        as f64
                        * theta.sin();
                }
            }
            by_grid *= (PI / nt as f64) * (2.0 * PI / np as f64);
            let by_uniform = by_grid * n as f64;
            let (a, b) = (by_sample / n as f64, by_uniform / n as f64);
            assert!(a <= 1.0 + 5e-3, "{name}, wo {wo}: albedo {a}");
            assert!(
                (a - b).abs() < 0.01,
                "{name}, wo {wo}: sampled {a} vs uniform {b}"
            );
        }
    }
}

/// `f(ωo, ωi)/η_o² = f(ωi, ωo)/η_i²` (Veach 1997, eq. 5.14; for reflection
/// plain symmetry), with `η` the index on each direction's side.
#[test]
fn reciprocity() {
    let mut rng = Pcg32::new(9, 9);
    for (name, bsdf) in rough_bsdfs() {
        let eta = bsdf.eta();
        let side = |w: Vec3| if w.z > 0.0 { 1.0 } else { eta };
        for _ in 0..5000 {
            let mut pick = || {
                let z = 1.0 - 2.0 * rng.next_f32();
                let r = (1.0 - z * z).max(0.0).sqrt();
                let phi = 2.0 * std::f32::consts::PI * rng.next_f32();
                Vec3::new(r * phi.cos(), r * phi.sin(), z)
            };
            let (wo, wi) = (pick(), pick());
            if wo.z.abs() < 0.05 || wi.z.abs() < 0.05 {
                continue;
            }
            let a = bsdf.eval(wo, wi) / (side(wo) * side(wo));
            let b = bsdf.eval(wi, wo) / (side(wi) * side(wi));
            let err = (a - b).abs().max_element();
            assert!(
                err <= 1e-3 * a.max_element().max(b.max_element()) + 1e-6,
                "{name}: {a} vs {b} for {wo}, {wi}"
            );
        }
    }
}

/// The principled material's glass part is the dielectric: all glass
/// (transmission 1, no metal), it evaluates, weighs and samples as
/// [`Bsdf::Dielectric`] does, except that its base colour tints the light it
/// transmits; half glass over smooth microfacets is a delta lobe of half
/// the weight beside a rough opaque part.
#[test]
fn principled_glass_part_is_the_dielectric() {
    let tint = Color::new(0.9, 0.5, 0.25);
    for roughness in [0.0, 0.3] {
        let glass = Bsdf::Dielectric {
            eta: 1.5,
            ggx: Ggx::from_roughness(roughness, 0.0),
        };
        let principled = |transmission: f32| Bsdf::Principled {
            base: tint,
            metallic: 0.0,
            ggx: Ggx::from_roughness(roughness.max(0.05), 0.0),
            transmission,
            eta: 1.5,
            glass: Ggx::from_roughness(roughness, 0.0),
        };
        let all = principled(1.0);
        assert!(all.transmits() && all.eta() == 1.5);
        assert_eq!(all.is_delta(), roughness == 0.0);
        let mut rng = Pcg32::new(3, 4);
        for _ in 0..2000 {
            let wo = dir(rng.next_f32() as f64 * PI, rng.next_f32() as f64 * 2.0 * PI);
            let (uc, u) = (rng.next_f32(), (rng.next_f32(), rng.next_f32()));
            let (Some(a), Some(b)) = (glass.sample(wo, uc, u), all.sample(wo, uc, u)) else {
                assert_eq!(glass.sample(wo, uc, u), None);
                continue;
            };
            assert_eq!(
                (a.wi, a.delta, a.transmitted),
                (b.wi, b.delta, b.transmitted)
            );
            let tinted = if a.transmitted { a.f * tint } else { a.f };
            assert!((tinted - b.f).abs().max_element() <= 1e-5 * a.f.max_element());
            assert!((a.pdf - b.pdf).abs() <= 1e-5 * a.pdf);
            let (fa, fb) = (glass.eval(wo, a.wi), all.eval(wo, a.wi));
            let fa = if a.transmitted { fa * tint } else { fa };
            assert!((fa - fb).abs().max_element() <= 1e-5 * fa.max_element().max(1e-6));
        }
        // Half glass: smooth glass samples carry half the probability (and
        // half the weight, so the throughput is as for glass).
        let half = principled(0.5);
        assert!(!half.is_delta() && half.transmits());
        if roughness == 0.0 {
            let wo = Vec3::new(0.6, 0.0, 0.8);
            let s = half.sample(wo, 0.45, (0.3, 0.7)).unwrap();
            let g = glass.sample(wo, 0.9, (0.3, 0.7)).unwrap();
            assert!(s.delta && s.transmitted && g.transmitted);
            assert!((s.pdf - 0.5 * g.pdf).abs() < 1e-6);
            assert!((s.weight() - g.weight() * tint).abs().max_element() < 1e-5);
            let opaque = half.sample(wo, 0.75, (0.3, 0.7)).unwrap();
            assert!(!opaque.delta && !opaque.transmitted);
        }
    }
}

/// Smooth glass picks reflection with probability `R` and conserves energy
/// (each sample's weight is 1 in expectation per lobe chosen: R/R, T/T, with
/// the 1/η² of radiance); a smooth mirror reflects about the normal.
#[test]
fn delta_lobes() {
    let glass = Bsdf::Dielectric {
        eta: 1.5,
        ggx: Ggx::from_roughness(0.0, 0.0),
    };
    assert!(glass.is_delta());
    let wo = Vec3::new(0.6, 0.0, 0.8);
    let r = fresnel::fr_dielectric(0.8, 1.5);
    let mut reflected = 0;
    let n = 100_000;
    for k in 0..n {
        let s = glass
            .sample(wo, (k as f32 + 0.5) / n as f32, (0.5, 0.5))
            .unwrap();
        assert!(s.delta);
        if s.transmitted {
            assert!(s.wi.z < 0.0);
            let w = s.weight().x;
            assert!((w - 1.0 / 2.25).abs() < 1e-4, "{w}");
        } else {
            reflected += 1;
            assert!((s.wi - Vec3::new(-0.6, 0.0, 0.8)).length() < 1e-6);
            assert!((s.weight().x - 1.0).abs() < 1e-4);
        }
    }
    assert!((reflected as f32 / n as f32 - r).abs() < 1e-3);
    assert_eq!(glass.eval(wo, Vec3::new(-0.6, 0.0, 0.8)), Color::ZERO);
    assert_eq!(glass.pdf(wo, Vec3::new(-0.6, 0.0, 0.8)), 0.0);
}
