//! Implicit surfaces against closed-form answers: the sphere, the torus (an
//! independent quartic solver written here), tangent and near-miss rays, the
//! heart without holes, and secondary rays without acne.

use glam::DVec3;
use glint::geometry::implicit::{HEART_BOUNDS, HEART_FORMULA, torus_formula};
use glint::geometry::{Implicit, ShapeHit, Sphere, TraceCounters};
use glint::math::{Aabb, Ray, Transform, Vec3};
use glint::render::Pcg32;
use glint::scene::{SceneError, load_scene_file, parse_scene};
use rayon::prelude::*;
use std::path::Path;

fn implicit(f: &str, half: f32) -> Implicit {
    Implicit::new(
        f,
        Aabb::new(Vec3::splat(-half), Vec3::splat(half)),
        Transform::IDENTITY,
    )
    .unwrap()
}

/// The f64 ray parameter of an implicit hit.
fn t64(h: &ShapeHit) -> f64 {
    h.t as f64 + h.u as f64
}

fn random_unit(rng: &mut Pcg32) -> Vec3 {
    loop {
        let v = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - Vec3::ONE;
        if v.length_squared() > 1e-4 && v.length_squared() <= 1.0 {
            return v.normalize();
        }
    }
}

#[test]
fn implicit_sphere_matches_the_analytic_sphere_over_100k_rays() {
    let shape = implicit("x^2 + y^2 + z^2 - 1", 1.5);
    let sphere = Sphere::new(Vec3::ZERO, 1.0);
    let results: Vec<(bool, bool, f64)> = (0..100_000u32)
        .into_par_iter()
        .map(|i| {
            let mut rng = Pcg32::new(i as u64, 7);
            // Origins anywhere in [−3, 3]³ (some inside the sphere), aimed at
            // points within 1.2 of the centre: many hits, many near misses.
            let o =
                (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - Vec3::ONE) * 3.0;
            let target = random_unit(&mut rng) * 1.2 * rng.next_f32();
            let ray = Ray::new(o, target - o);
            let a = sphere.intersect(&ray);
            let b = shape.intersect(&ray, &mut TraceCounters::default());
            let rel = match (a, b) {
                (Some(a), Some(b)) => {
                    let exact = sphere
                        .roots(&ray)
                        .map(|(t0, t1)| if t0 >= 0.0 { t0 } else { t1 })
                        .unwrap();
                    let _ = a;
                    (t64(&b) - exact).abs() / exact
                }
                _ => 0.0,
            };
            (a.is_some(), b.is_some(), rel)
        })
        .collect();
    let hits = results.iter().filter(|r| r.0).count();
    let disagree = results.iter().filter(|r| r.0 != r.1).count();
    let worst = results.iter().map(|r| r.2).fold(0.0, f64::max);
    assert!(hits > 30_000, "{hits} hits");
    assert_eq!(disagree, 0, "hit/miss decisions differ on {disagree} rays");
    assert!(worst < 1e-6, "worst relative error of t: {worst}");
}

/// Real roots of `c[0] t⁴ + c[1] t³ + c[2] t² + c[3] t + c[4] = 0` by Ferrari's
/// method: the depressed quartic `y⁴ + p y² + q y + r` (t = y − a/4) is split
/// into two quadratics with the resolvent cubic's largest root. When `q` is
/// nearly zero (symmetric rays) that split divides by nearly zero, so the
/// biquadratic roots (q = 0) are candidates too. Every candidate is polished
/// by Newton steps on the original polynomial and kept only if it then is a
/// root to within rounding.
fn quartic_roots(c: [f64; 5]) -> Vec<f64> {
    let (a, b, cc, d) = (c[1] / c[0], c[2] / c[0], c[3] / c[0], c[4] / c[0]);
    let p = b - 3.0 * a * a / 8.0;
    let q = cc - a * b / 2.0 + a * a * a / 8.0;
    let r = d - a * cc / 4.0 + a * a * b / 16.0 - 3.0 * a.powi(4) / 256.0;
    let mut ys = Vec::new();
    // Biquadratic: z² + p z + r = 0, y = ±√z (exact when q = 0).
    let disc = p * p - 4.0 * r;
    if disc >= 0.0 {
        for z in [(-p + disc.sqrt()) / 2.0, (-p - disc.sqrt()) / 2.0] {
            let z = z.max(0.0);
            ys.extend([z.sqrt(), -z.sqrt()]);
        }
    }
    // Resolvent cubic m³ + p m² + (p²/4 − r) m − q²/8 = 0; its largest root m ≥ 0.
    let m = largest_cubic_root(p, p * p / 4.0 - r, -q * q / 8.0);
    if m > 0.0 {
        let s = (2.0 * m).sqrt();
        for s1 in [1.0, -1.0] {
            let inner = (-(2.0 * p + 2.0 * m + s1 * 2.0 * q / s)).max(0.0);
            for s2 in [1.0, -1.0] {
                ys.push((s1 * s + s2 * inner.sqrt()) / 2.0);
            }
        }
    }
    let poly = |t: f64| (((c[0] * t + c[1]) * t + c[2]) * t + c[3]) * t + c[4];
    let dpoly = |t: f64| ((4.0 * c[0] * t + 3.0 * c[1]) * t + 2.0 * c[2]) * t + c[3];
    let scale = |t: f64| {
        c.iter()
            .enumerate()
            .map(|(i, ci)| ci.abs() * t.abs().powi(4 - i as i32))
            .sum::<f64>()
    };
    ys.into_iter()
        .filter_map(|y| {
            let mut t = y - a / 4.0;
            for _ in 0..30 {
                let d = dpoly(t);
                if d == 0.0 {
                    break;
                }
                t -= poly(t) / d;
            }
            (poly(t).abs() <= 1e-12 * scale(t)).then_some(t)
        })
        .collect()
}

/// The largest real root of m³ + a m² + b m + c = 0 (Cardano, or Viète's
/// trigonometric form for three real roots).
fn largest_cubic_root(a: f64, b: f64, c: f64) -> f64 {
    let q = (a * a - 3.0 * b) / 9.0;
    let r = (2.0 * a * a * a - 9.0 * a * b + 27.0 * c) / 54.0;
    let m = if r * r < q * q * q {
        let theta = (r / q.powf(1.5)).clamp(-1.0, 1.0).acos();
        -2.0 * q.sqrt() * (theta / 3.0).cos() - a / 3.0
    } else {
        let big = -r.signum() * (r.abs() + (r * r - q * q * q).sqrt()).cbrt();
        let small = if big == 0.0 { 0.0 } else { q / big };
        big + small - a / 3.0
    };
    // One Newton polish.
    let f = ((m + a) * m + b) * m + c;
    let df = (3.0 * m + 2.0 * a) * m + b;
    if df != 0.0 { m - f / df } else { m }
}

/// The first root of the torus (R, r) around z along o + t·d, t > 0, from the
/// quartic (|p|² + R² − r²)² − 4R²(x² + y²) = 0.
fn torus_first_hit(o: DVec3, d: DVec3, big_r: f64, small_r: f64) -> Option<f64> {
    let a = d.dot(d);
    let b = 2.0 * o.dot(d);
    let c = o.dot(o) + big_r * big_r - small_r * small_r;
    let k = 4.0 * big_r * big_r;
    let coefficients = [
        a * a,
        2.0 * a * b,
        b * b + 2.0 * a * c - k * (d.x * d.x + d.y * d.y),
        2.0 * b * c - 2.0 * k * (o.x * d.x + o.y * d.y),
        c * c - k * (o.x * o.x + o.y * o.y),
    ];
    quartic_roots(coefficients)
        .into_iter()
        .filter(|&t| t > 1e-9)
        .fold(None, |best: Option<f64>, t| {
            Some(best.map_or(t, |b| b.min(t)))
        })
}

#[test]
fn torus_matches_the_closed_form_quartic() {
    let (big_r, small_r) = (1.0, 0.35);
    let shape = Implicit::new(
        &torus_formula(big_r, small_r),
        Aabb::new(Vec3::new(-1.4, -1.4, -0.4), Vec3::new(1.4, 1.4, 0.4)),
        Transform::IDENTITY,
    )
    .unwrap();
    let mut rays = Vec::new();
    let mut rng = Pcg32::new(11, 3);
    for _ in 0..20_000 {
        let o = random_unit(&mut rng) * 4.0;
        let target = Vec3::new(
            rng.next_f32() * 2.8 - 1.4,
            rng.next_f32() * 2.8 - 1.4,
            rng.next_f32() * 0.8 - 0.4,
        );
        rays.push(Ray::new(o, target - o));
    }
    // Grazing rays: parallel to the x axis at heights just inside and outside
    // the top of the tube (z = r), and along the outer rim (y = R + r).
    for k in 0..200 {
        let eps = [1e-3, 1e-4, -1e-3, -1e-4][k % 4];
        let x = -3.0 + 0.01 * k as f32;
        rays.push(Ray::new(
            Vec3::new(-4.0, x * 0.1, (small_r as f32) - eps),
            Vec3::X,
        ));
        rays.push(Ray::new(
            Vec3::new(-4.0, (big_r + small_r) as f32 - eps, x * 0.01),
            Vec3::X,
        ));
    }
    let mut hits = 0;
    for ray in &rays {
        let closed = torus_first_hit(ray.o.as_dvec3(), ray.d.as_dvec3(), big_r, small_r);
        let found = shape
            .intersect(ray, &mut TraceCounters::default())
            .map(|h| t64(&h));
        match (closed, found) {
            (Some(a), Some(b)) => {
                hits += 1;
                assert!(
                    (a - b).abs() <= 1e-6 * a.max(1.0),
                    "t {a} vs {b} for {ray:?}"
                );
            }
            (None, None) => {}
            _ => panic!("closed form {closed:?}, implicit {found:?} for {ray:?}"),
        }
    }
    assert!(hits > 5_000, "{hits} hits");
}

#[test]
fn tangent_rays_hit_and_near_misses_do_not() {
    let sphere = implicit("x^2 + y^2 + z^2 - 1", 1.5);
    let torus = Implicit::new(
        &torus_formula(1.0, 0.25),
        Aabb::new(Vec3::new(-1.3, -1.3, -0.3), Vec3::new(1.3, 1.3, 0.3)),
        Transform::IDENTITY,
    )
    .unwrap();
    let c = &mut TraceCounters::default();
    // Touching the sphere at (0, 1, 0), and the torus's top at (±1, 0, 0.25).
    let touch = sphere
        .intersect(&Ray::new(Vec3::new(-5.0, 1.0, 0.0), Vec3::X), c)
        .unwrap();
    assert!((t64(&touch) - 5.0).abs() < 1e-5, "{touch:?}");
    let touch = torus
        .intersect(&Ray::new(Vec3::new(-5.0, 0.0, 0.25), Vec3::X), c)
        .unwrap();
    assert!((t64(&touch) - 4.0).abs() < 1e-4, "{touch:?}");
    // The torus's outer rim at (0, 1.25, 0), along x.
    let touch = torus
        .intersect(&Ray::new(Vec3::new(-5.0, 1.25, 0.0), Vec3::X), c)
        .unwrap();
    assert!((t64(&touch) - 5.0).abs() < 1e-4, "{touch:?}");
    // Passing 1e-4 away: no hit.
    for ray in [
        Ray::new(Vec3::new(-5.0, 1.0 + 1e-4, 0.0), Vec3::X),
        Ray::new(Vec3::new(-5.0, 0.0, 1.0 + 1e-4), Vec3::X),
    ] {
        assert!(sphere.intersect(&ray, c).is_none(), "{ray:?}");
    }
    assert!(
        torus
            .intersect(&Ray::new(Vec3::new(-5.0, 0.0, 0.25 + 1e-4), Vec3::X), c)
            .is_none()
    );
    assert!(
        torus
            .intersect(&Ray::new(Vec3::new(-5.0, 1.25 + 1e-4, 0.0), Vec3::X), c)
            .is_none()
    );
    assert!(
        torus
            .intersect(&Ray::new(Vec3::new(-5.0, 0.0, -0.25 - 1e-4), Vec3::X), c)
            .is_none()
    );
}

/// The heart of `scenes/implicit.toml` seen by its camera at 256×256: every
/// pixel whose 4×4 sub-pixel rays all hit the heart is itself hit (no holes),
/// also along the "equator" where ∇f vanishes, where POV-Ray's polynomial
/// solver leaves speckles.
#[test]
fn heart_has_no_holes() {
    let heart = Implicit::new(
        HEART_FORMULA,
        Aabb::new(
            Vec3::from_array(HEART_BOUNDS[0]),
            Vec3::from_array(HEART_BOUNDS[1]),
        ),
        Transform::from_parts(
            DVec3::ONE,
            DVec3::new(-90.0, 0.0, 0.0),
            DVec3::new(0.0, 1.05, 0.0),
        )
        .unwrap(),
    )
    .unwrap();
    // Framed on the heart: it fills most of the image.
    let camera = glint::scene::Camera::try_new(
        Vec3::new(0.0, 1.6, -4.5),
        Vec3::new(0.0, 1.1, 0.0),
        Vec3::Y,
        40.0,
    )
    .unwrap();
    let size = 256u32;
    let hit = |x: f32, y: f32| {
        heart
            .intersect(&camera.ray(x, y, size, size), &mut TraceCounters::default())
            .is_some()
    };
    let (holes, covered, hits): (u32, u32, u32) = (0..size * size)
        .into_par_iter()
        .map(|i| {
            let (px, py) = ((i % size) as f32, (i / size) as f32);
            let centre = hit(px + 0.5, py + 0.5);
            let all = (0..16).all(|k| {
                hit(
                    px + 0.125 + 0.25 * (k % 4) as f32,
                    py + 0.125 + 0.25 * (k / 4) as f32,
                )
            });
            ((all && !centre) as u32, all as u32, centre as u32)
        })
        .reduce(|| (0, 0, 0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2));
    assert!(covered > 15_000, "the heart covers only {covered} pixels");
    assert_eq!(holes, 0, "{holes} holes among {hits} hit pixels");
}

/// Rays leaving a hit point of the torus or the heart, in any direction into
/// the outside, never hit the same surface again at t ≈ 0; a ray leaving
/// inwards finds the other side.
#[test]
fn secondary_rays_do_not_reintersect() {
    let torus = Implicit::new(
        &torus_formula(1.0, 0.3),
        Aabb::new(Vec3::new(-1.4, -1.4, -0.4), Vec3::new(1.4, 1.4, 0.4)),
        Transform::IDENTITY,
    )
    .unwrap();
    let heart = implicit(HEART_FORMULA, 1.5);
    let mut rng = Pcg32::new(5, 5);
    let mut tested = 0;
    for shape in [&torus, &heart] {
        for _ in 0..3000 {
            let o = random_unit(&mut rng) * 4.0;
            let ray = Ray::new(o, random_unit(&mut rng) * 0.8 - o);
            let c = &mut TraceCounters::default();
            let Some(h) = shape.intersect(&ray, c) else {
                continue;
            };
            let sp = shape.surface(&ray, &h);
            let w = random_unit(&mut rng);
            let w = if w.dot(sp.n) < 0.0 { -w } else { w };
            if w.dot(sp.n) < 1e-3 {
                continue;
            }
            tested += 1;
            let out = Ray::spawn(sp.p, sp.p_err, sp.n, w);
            if let Some(again) = shape.intersect(&out, c) {
                assert!(again.t > 1e-4, "re-hit at t = {} from {:?}", again.t, sp.p);
            }
            let inward = Ray::spawn(sp.p, sp.p_err, sp.n, -sp.n);
            let other = shape
                .intersect(&inward, c)
                .expect("a ray into a closed surface leaves it");
            assert!(other.t > 1e-4, "inward re-hit at t = {}", other.t);
        }
    }
    assert!(tested > 2000, "{tested}");
}

#[test]
fn formula_errors_point_at_the_scene_file() {
    let scene = |f: &str| {
        format!(
            "[camera]\nposition = [0, 0, -5]\nlook_at = [0, 0, 0]\n\n[[object]]\nshape = \"implicit\"\nf = \"{f}\"\nbounds = [[-1, -1, -1], [1, 1, 1]]\n"
        )
    };
    for (formula, column, needle) in [
        ("x^2 + y^2 + w^2 - 1", 13, "unknown name `w`"),
        ("x^2 + * y", 7, "expected a number"),
        ("(x + y", 7, "expected `)`"),
        ("2x + y", 2, "`2*x`"),
        ("min(x) + 1", 1, "takes 2 arguments"),
        ("sqrt(x", 7, "expected `,` or `)`"),
    ] {
        match parse_scene(&scene(formula), Path::new("f.toml")) {
            Err(SceneError::Parse {
                line,
                column: col,
                message,
                ..
            }) => {
                assert_eq!(line, 7, "{formula}: {message}");
                // The formula starts after `f = "`, at column 6.
                assert_eq!(col, 5 + column, "{formula}: {message}");
                assert!(message.contains(needle), "{formula}: {message}");
            }
            other => panic!("{formula}: {other:?}"),
        }
    }
    let missing = parse_scene(
        &scene("x").replace("bounds = [[-1, -1, -1], [1, 1, 1]]\n", ""),
        Path::new("f.toml"),
    );
    assert!(
        missing
            .unwrap_err()
            .to_string()
            .contains("missing required key `bounds`")
    );
}

#[test]
fn shipped_implicit_scene_renders_without_nan() {
    let file = load_scene_file(Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/implicit.toml"
    )))
    .unwrap();
    let settings = glint::settings::RenderSettings {
        width: 48,
        height: 36,
        spp: 1,
        ..file.settings
    };
    let (image, stats) = glint::render::render(&file.scene, &settings, &|_| {}).unwrap();
    assert_eq!(stats.nan_pixels, 0);
    assert!(stats.implicit_evaluations > 0);
    // The heart is red in the middle of the picture.
    let c = image.get(24, 20);
    assert!(c.x > 2.0 * c.y && c.x > 2.0 * c.z, "{c:?}");
}
