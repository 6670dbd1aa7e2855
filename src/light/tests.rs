use super::*;
use crate::render::Pcg32;

fn emissive(two_sided: bool) -> Material {
    Material {
        emission: Color::new(2.0, 1.0, 0.5),
        two_sided,
        ..Material::default_diffuse()
    }
}

fn lights_under_test() -> Vec<Light> {
    let m = emissive(false);
    vec![
        Light::Area(
            AreaLight::new(
                Vec3::new(-0.5, 2.0, -0.3),
                Vec3::new(0.7, 2.0, -0.3),
                Vec3::new(-0.5, 2.0, 0.6),
                true,
                &emissive(true),
            )
            .unwrap(),
        ),
        Light::Area(
            AreaLight::new(
                Vec3::new(-0.5, 1.5, 0.3),
                Vec3::new(0.2, 1.8, -0.3),
                Vec3::new(0.6, 1.4, 0.6),
                false,
                &emissive(true),
            )
            .unwrap(),
        ),
        Light::Sphere {
            center: Vec3::new(0.3, 1.2, 0.1),
            radius: 0.4,
            radiance: m.emission,
        },
        Light::Sphere {
            center: Vec3::new(30.0, 40.0, 0.0),
            radius: 0.05,
            radiance: m.emission,
        },
        Light::Environment {
            radiance: Color::ONE,
        },
    ]
}

/// Every sample's density is what `pdf_li` says for its direction, and
/// `pdf_li` integrates to 1 over the directions that reach the light
/// (Monte Carlo over the sphere of directions, with the light hit found
/// from the sampled geometry).
#[test]
fn sample_li_agrees_with_pdf_li() {
    let p = Vec3::new(0.05, 0.1, -0.02);
    let mut rng = Pcg32::new(7, 8);
    for (k, light) in lights_under_test().iter().enumerate() {
        for _ in 0..2000 {
            let u = (rng.next_f32(), rng.next_f32());
            let Some(s) = light.sample_li(p, u) else {
                continue;
            };
            assert!((s.wi.length() - 1.0).abs() < 1e-4);
            let q = s.target.unwrap_or(p + s.wi);
            let pdf = light.pdf_li(p, s.wi, q);
            assert!(
                (pdf - s.pdf).abs() <= 1e-3 * s.pdf,
                "light {k}: sample pdf {} vs pdf_li {pdf}",
                s.pdf
            );
        }
    }
}

/// The irradiance estimate `E[L cos/pdf]` matches closed forms: a sphere
/// of radiance `L` seen under half-angle `θ` along the normal gives
/// `π L sin²θ`; a polygon gives Lambert's `L/2 Σ Θ_k (n·u_k)` (the angle
/// each edge subtends times the cosine of the plane through it).
#[test]
fn irradiance_matches_closed_forms() {
    let p = Vec3::ZERO;
    let estimate = |light: &Light, n: Vec3| {
        let mut rng = Pcg32::new(9, 10);
        let count = 400_000;
        let mut sum = 0.0f64;
        for _ in 0..count {
            if let Some(s) = light.sample_li(p, (rng.next_f32(), rng.next_f32())) {
                sum += (s.li.x * n.dot(s.wi).max(0.0) / s.pdf) as f64;
            }
        }
        sum / count as f64
    };
    let sphere = Light::Sphere {
        center: Vec3::new(0.0, 3.0, 0.0),
        radius: 1.0,
        radiance: Color::ONE,
    };
    let expect = std::f64::consts::PI / 9.0;
    let got = estimate(&sphere, Vec3::Y);
    assert!(
        (got - expect).abs() < 2e-3 * expect.max(1.0),
        "{got} vs {expect}"
    );

    let corners = [
        Vec3::new(-0.5, 1.0, -0.4),
        Vec3::new(0.8, 1.0, -0.4),
        Vec3::new(0.8, 1.0, 0.7),
        Vec3::new(-0.5, 1.0, 0.7),
    ];
    let rect = Light::Area(
        AreaLight::new(corners[0], corners[3], corners[1], true, &emissive(true)).unwrap(),
    );
    let n = Vec3::new(0.3, 1.0, 0.2).normalize();
    let mut lambert = 0.0f64;
    for k in 0..4 {
        let (a, b) = (corners[k].normalize(), corners[(k + 1) % 4].normalize());
        let theta = a.dot(b).clamp(-1.0, 1.0).acos() as f64;
        let u = a.cross(b).normalize();
        lambert += theta * n.dot(u) as f64;
    }
    // The light's red radiance is 2.
    let expect = (0.5 * lambert).abs() * 2.0;
    let got = estimate(&rect, n);
    assert!((got - expect).abs() < 3e-3 * expect, "{got} vs {expect}");
}

#[test]
fn one_sided_lights_emit_on_their_normal_side() {
    let a = AreaLight::new(Vec3::ZERO, Vec3::X, Vec3::Y, false, &emissive(false)).unwrap();
    assert_eq!(a.n, Vec3::Z);
    let light = Light::Area(a);
    assert!(
        light
            .sample_li(Vec3::new(0.2, 0.2, 1.0), (0.3, 0.3))
            .is_some()
    );
    assert!(
        light
            .sample_li(Vec3::new(0.2, 0.2, -1.0), (0.3, 0.3))
            .is_none()
    );
    assert_eq!(light.le(Vec3::Z, -Vec3::Z), Color::ZERO);
    assert_ne!(light.le(Vec3::Z, Vec3::Z), Color::ZERO);
}

#[test]
fn box_faces_point_out_and_match_hits() {
    let c = crate::geometry::Cuboid::new(Vec3::new(-1.0, -2.0, -3.0), Vec3::new(1.0, 2.0, 3.0));
    for face in 0..6 {
        let [p0, p1, p2] = c.face_corners(face);
        let n = triangle_normal(p0, p1, p2);
        let centre = p0 + 0.5 * ((p1 - p0) + (p2 - p0));
        assert!(n.dot(centre) > 0.0, "face {face} normal {n}");
        assert_eq!(crate::geometry::Cuboid::face_of(n), face as u32);
    }
}

/// Pearson's chi-square test of each finite light's directions against
/// `pdf_li` (the light's point along a direction found by intersecting it).
#[test]
fn sample_li_chi_square() {
    let p = Vec3::new(0.05, 0.1, -0.02);
    for (k, light) in lights_under_test().iter().enumerate() {
        if let Light::Sphere { radius, .. } = light
            && *radius < 0.1
        {
            continue; // Too small a cone for a 20×40 grid.
        }
        let hit = |wi: Vec3| -> Option<Vec3> {
            match light {
                Light::Area(a) => {
                    let denom = a.n.dot(wi);
                    if denom == 0.0 {
                        return None;
                    }
                    let t = a.n.dot(a.p0 - p) / denom;
                    let q = p + wi * t;
                    // Barycentric-style coordinates in the (e1, e2) basis.
                    let d = q - a.p0;
                    let (e11, e12, e22) = (a.e1.dot(a.e1), a.e1.dot(a.e2), a.e2.dot(a.e2));
                    let (d1, d2) = (d.dot(a.e1), d.dot(a.e2));
                    let det = e11 * e22 - e12 * e12;
                    let u = (e22 * d1 - e12 * d2) / det;
                    let v = (e11 * d2 - e12 * d1) / det;
                    let inside = u >= 0.0
                        && v >= 0.0
                        && if a.parallelogram {
                            u <= 1.0 && v <= 1.0
                        } else {
                            u + v <= 1.0
                        };
                    (t > 0.0 && inside).then_some(q)
                }
                Light::Sphere { center, radius, .. } => {
                    let oc = p - *center;
                    let b = oc.dot(wi);
                    let c = oc.length_squared() - radius * radius;
                    let disc = b * b - c;
                    let t = -b - disc.max(0.0).sqrt();
                    (disc >= 0.0 && t > 0.0).then(|| p + wi * t)
                }
                _ => Some(p + wi),
            }
        };
        let result = crate::shading::tests::chi_square_of(
            |_, u| light.sample_li(p, u).map(|s| s.wi),
            |wi| hit(wi).map_or(0.0, |q| light.pdf_li(p, wi, q)),
            20 + k as u64,
            100_000,
            96,
        );
        assert!(result.is_ok(), "light {k}: {result:?}");
    }
}

/// A map with a bright sun, a gradient sky and a dark ground.
fn test_map(rotate: f32) -> EnvMap {
    let (w, h) = (64u32, 32u32);
    let texels = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            if (20..23).contains(&x) && (8..10).contains(&y) {
                Color::new(200.0, 180.0, 150.0)
            } else if y < h / 2 {
                Color::new(0.3, 0.5, 1.0) * (1.0 - y as f32 / h as f32)
            } else {
                Color::splat(0.05)
            }
        })
        .collect();
    EnvMap::new(w, h, texels, 1.0, rotate).unwrap()
}

/// The map's directions follow its density (chi-square), each sample's
/// radiance is the map's in its direction, and the density integrates to 1.
#[test]
fn environment_map_sampling_matches_its_pdf() {
    for rotate in [0.0, 70.0] {
        let map = test_map(rotate);
        let light = Light::EnvMap(std::sync::Arc::new(map.clone()));
        let result = crate::shading::tests::chi_square_of(
            |_, u| light.sample_li(Vec3::ZERO, u).map(|s| s.wi),
            |wi| light.pdf_li(Vec3::ZERO, wi, wi),
            31,
            200_000,
            48,
        );
        assert!(result.is_ok(), "rotate {rotate}: {result:?}");
        let mut rng = Pcg32::new(4, 4);
        for _ in 0..1000 {
            let s = light
                .sample_li(Vec3::ZERO, (rng.next_f32(), rng.next_f32()))
                .unwrap();
            assert_eq!(s.li, map.le(s.wi));
            assert!((s.pdf - map.pdf(s.wi)).abs() <= 1e-3 * s.pdf);
        }
    }
}

/// Irradiance on an upward surface: the importance-sampled estimate equals
/// the integral of the map's radiance times cos θ over the upper hemisphere
/// (midpoint rule on a fine grid).
#[test]
fn environment_map_irradiance() {
    let map = test_map(30.0);
    let light = Light::EnvMap(std::sync::Arc::new(map.clone()));
    let mut rng = Pcg32::new(6, 6);
    let n = 400_000;
    let mut estimate = 0.0f64;
    for _ in 0..n {
        if let Some(s) = light.sample_li(Vec3::ZERO, (rng.next_f32(), rng.next_f32())) {
            estimate += (s.li.x * s.wi.y.max(0.0) / s.pdf) as f64;
        }
    }
    estimate /= n as f64;
    let (nt, np) = (512, 1024);
    let mut exact = 0.0f64;
    for i in 0..nt {
        let theta = (i as f64 + 0.5) / nt as f64 * std::f64::consts::FRAC_PI_2;
        for j in 0..np {
            let phi = (j as f64 + 0.5) / np as f64 * 2.0 * std::f64::consts::PI;
            let d = Vec3::new(
                (theta.sin() * phi.cos()) as f32,
                theta.cos() as f32,
                (theta.sin() * phi.sin()) as f32,
            );
            exact += map.le(d).x as f64 * theta.cos() * theta.sin();
        }
    }
    exact *= (std::f64::consts::FRAC_PI_2 / nt as f64) * (2.0 * std::f64::consts::PI / np as f64);
    assert!(
        (estimate - exact).abs() < 0.01 * exact,
        "{estimate} vs {exact}"
    );
}

#[test]
fn environment_map_rejects_bad_texels() {
    let bad = vec![Color::new(1.0, f32::NAN, 0.0); 8];
    let e = EnvMap::new(4, 2, bad, 1.0, 0.0).unwrap_err();
    assert!(e.contains("texel (0, 0)"), "{e}");
    let neg = vec![Color::splat(-1.0); 8];
    assert!(EnvMap::new(4, 2, neg, 1.0, 0.0).is_err());
    assert!(EnvMap::new(0, 2, vec![], 1.0, 0.0).is_err());
}
