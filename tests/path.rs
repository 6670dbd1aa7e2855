//! The path integrator against what must hold: white furnaces, the Cornell
//! box's mean (Mitsuba 3's 16,384-spp reference), error falling with the
//! sample count, the three sampling strategies agreeing (and MIS winning on
//! Veach's plates), area lights in Whitted's integrator, and exact
//! progressive passes.

use glint::render::{FilmOptions, Image, render, render_film, render_timed};
use glint::scene::{SceneFile, load_scene_file, parse_scene};
use glint::settings::{IntegratorKind, RenderSettings, Sampling};
use std::path::Path;

fn scene(text: &str) -> SceneFile {
    parse_scene(text, Path::new("test.toml")).unwrap()
}

fn repo_scene(name: &str) -> SceneFile {
    load_scene_file(
        &Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenes")
            .join(name),
    )
    .unwrap()
}

fn mean(image: &Image) -> [f64; 3] {
    let mut m = [0.0; 3];
    for p in &image.pixels {
        for c in 0..3 {
            m[c] += p[c] as f64;
        }
    }
    m.map(|x| x / image.pixels.len() as f64)
}

fn rmse(a: &Image, b: &Image) -> f64 {
    let sum: f64 = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .map(|(x, y)| ((*x - *y) * (*x - *y)).element_sum() as f64)
        .sum();
    (sum / (3 * a.pixels.len()) as f64).sqrt()
}

fn furnace(material: &str) -> SceneFile {
    scene(&format!(
        r#"
[camera]
position = [0, 0, -4]
look_at = [0, 0, 0]
fov = 30
[render]
width = 32
height = 32
spp = 16
integrator = "path"
max_depth = -1
background = [1, 1, 1]
[materials]
m = {material}
[[object]]
shape = "sphere"
center = [0, 0, 0]
radius = 1
material = "m"
"#
    ))
}

/// A sphere that absorbs nothing, in a uniform environment of radiance 1,
/// is invisible: every pixel is 1 (±1% here) for a white Lambertian, a
/// rough perfect conductor (F = 1), rough glass and smooth glass (as
/// dielectrics, and as glTF's principled material with transmission 1).
/// Single-scattering GGX loses energy at grazing angles (1.1% of the
/// sphere's mean at α = 0.09; there is no multiple-scattering compensation
/// yet), so the rough surfaces use roughness 0.2 (α = 0.04) for the
/// conductor and 0.1 for glass (whose rim loses 1.2% at 0.2).
#[test]
fn white_furnace() {
    for material in [
        r#"{ type = "diffuse", color = [1, 1, 1] }"#,
        r#"{ type = "conductor", color = [1, 1, 1], roughness = 0.2 }"#,
        r#"{ type = "dielectric", ior = 1.5, roughness = 0.1 }"#,
        r#"{ type = "dielectric", ior = 1.5 }"#,
        // glTF's transmission: all glass, rough and smooth, with a white
        // base (which tints only transmitted light).
        r#"{ type = "principled", color = [1, 1, 1], transmission = 1, roughness = 0.1 }"#,
        r#"{ type = "principled", color = [1, 1, 1], transmission = 1, roughness = 0 }"#,
    ] {
        let file = furnace(material);
        let (image, stats) = render(&file.scene, &file.settings, &|_| {}).unwrap();
        assert_eq!(stats.nan_pixels, 0);
        // The centre 16×16 pixels all see the sphere.
        let mut sum = 0.0f64;
        for y in 8..24 {
            for x in 8..24 {
                sum += image.pixels[y * 32 + x].element_sum() as f64 / 3.0;
            }
        }
        let centre = sum / 256.0;
        assert!((centre - 1.0).abs() < 0.01, "{material}: {centre}");
        let all = mean(&image);
        assert!(
            all.iter().all(|m| (m - 1.0).abs() < 0.01),
            "{material}: {all:?}"
        );
    }
}

/// The furnace can fail: a sphere of albedo 0.8 is visibly darker.
#[test]
fn grey_sphere_is_not_white_in_the_furnace() {
    let file = furnace(r#"{ type = "diffuse", color = [0.8, 0.8, 0.8] }"#);
    let (image, _) = render(&file.scene, &file.settings, &|_| {}).unwrap();
    let centre = image.pixels[16 * 32 + 16].x;
    assert!((centre - 0.8).abs() < 0.03, "{centre}");
}

/// Mean per channel of Mitsuba 3's 16,384-spp reference of the Cornell box
/// (../shared/anchors/cornell/results.md).
const CORNELL_MEAN: [f64; 3] = [0.24444, 0.14142, 0.06001];

/// The Cornell box's image mean is within 1% of Mitsuba 3's reference per
/// channel (a 64×64 image has the same mean as the 512×512 one).
#[test]
fn cornell_box_mean_matches_mitsuba() {
    let file = repo_scene("cornell.toml");
    let settings = RenderSettings {
        width: 64,
        height: 64,
        spp: 16,
        ..file.settings.clone()
    };
    let (image, stats) = render(&file.scene, &settings, &|_| {}).unwrap();
    assert_eq!(stats.nan_pixels, 0);
    let m = mean(&image);
    for c in 0..3 {
        let rel = (m[c] - CORNELL_MEAN[c]).abs() / CORNELL_MEAN[c];
        assert!(rel < 0.01, "channel {c}: {} vs {}", m[c], CORNELL_MEAN[c]);
    }
}

/// The error against a converged image falls at least as 1/√spp (the
/// progressive Sobol samples do better than that).
#[test]
fn cornell_error_falls_with_samples() {
    let file = repo_scene("cornell.toml");
    let at = |spp, offset| {
        let settings = RenderSettings {
            width: 24,
            height: 24,
            spp,
            sample_offset: offset,
            ..file.settings.clone()
        };
        render(&file.scene, &settings, &|_| {}).unwrap().0
    };
    // The reference takes samples the others do not.
    let reference = at(512, 1024);
    let (e4, e16) = (rmse(&at(4, 0), &reference), rmse(&at(16, 0), &reference));
    assert!(e4 / e16 > 1.8, "RMSE 4 spp {e4}, 16 spp {e16}");
}

/// Light sampling, BSDF sampling and MIS converge to the same image mean
/// within their standard errors (each estimated from 8 independent sample
/// ranges); on Veach's plates MIS has the lowest error of the three at equal
/// samples.
#[test]
fn sampling_strategies_agree_and_mis_wins() {
    let file = repo_scene("veach-mis.toml");
    let with = |sampling, spp, offset| {
        let settings = RenderSettings {
            width: 48,
            height: 32,
            spp,
            sample_offset: offset,
            sampling,
            ..file.settings.clone()
        };
        render(&file.scene, &settings, &|_| {}).unwrap().0
    };
    let reference = with(Sampling::Mis, 1024, 1 << 16);
    // Per strategy: the mean of the image's mean over 8 ranges of 32
    // samples, its standard error, and the 256-sample image.
    let estimate = |sampling| {
        let parts: Vec<Image> = (0..8).map(|k| with(sampling, 32, 32 * k)).collect();
        let means: Vec<f64> = parts
            .iter()
            .map(|p| mean(p).iter().sum::<f64>() / 3.0)
            .collect();
        let m = means.iter().sum::<f64>() / 8.0;
        let var = means.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / 7.0;
        let mut image = parts[0].clone();
        for (k, p) in image.pixels.iter_mut().enumerate() {
            *p = parts
                .iter()
                .map(|q| q.pixels[k])
                .sum::<glint::math::Color>()
                / 8.0;
        }
        (m, (var / 8.0).sqrt(), image)
    };
    let results: Vec<_> = [Sampling::Mis, Sampling::Light, Sampling::Bsdf]
        .into_iter()
        .map(|s| (s, estimate(s)))
        .collect();
    let (m_mis, se_mis, _) = &results[0].1;
    for (s, (m, se, _)) in &results[1..] {
        let bound = 4.0 * (se * se + se_mis * se_mis).sqrt();
        assert!(
            (m - m_mis).abs() < bound,
            "{s:?}: mean {m} ± {se} vs MIS {m_mis} ± {se_mis}"
        );
    }
    let errors: Vec<(Sampling, f64)> = results
        .iter()
        .map(|(s, (_, _, image))| (*s, rmse(image, &reference)))
        .collect();
    assert!(
        errors[1..].iter().all(|&(_, e)| errors[0].1 < e),
        "RMSE: {errors:?}"
    );
}

/// Whitted's integrator with an area light: soft shadows. A sphere above a
/// floor, lit from the side by an emissive square; the floor's visibility of
/// the light (the image over the image without the sphere) goes from
/// shadow through a penumbra to full light. A point light of the same power
/// casts a hard shadow: visibility 0 or 1 only.
#[test]
fn whitted_area_light_casts_soft_shadows() {
    let scene_with = |light: &str, sphere: bool| {
        scene(&format!(
            r#"
[camera]
position = [0, 6, 0.01]
look_at = [0, 0, 0]
fov = 60
[render]
width = 48
height = 48
spp = 1
integrator = "whitted"
light_samples = 256
ambient = [0, 0, 0]
[materials]
floor = {{ type = "diffuse", color = [1, 1, 1] }}
lamp = {{ type = "diffuse", color = [0, 0, 0], ambient = 0, emission = [20, 20, 20], two_sided = true }}
{light}
[[object]]
shape = "box"
min = [-10, -1, -10]
max = [10, 0, 10]
material = "floor"
{}
"#,
            if sphere {
                "[[object]]\nshape = \"sphere\"\ncenter = [0, 1, 0]\nradius = 0.5\nmaterial = \"floor\""
            } else {
                ""
            }
        ))
    };
    let area = r#"
[[object]]
shape = "box"
min = [-3.5, 5, -0.5]
max = [-2.5, 5.01, 0.5]
material = "lamp""#;
    let point = r#"
[[light]]
type = "point"
position = [-3, 5, 0]
intensity = 20"#;
    let visibility = |light: &str| {
        let lit = scene_with(light, false);
        let shadowed = scene_with(light, true);
        let (a, _) = render(&lit.scene, &lit.settings, &|_| {}).unwrap();
        let (b, _) = render(&shadowed.scene, &shadowed.settings, &|_| {}).unwrap();
        // The floor right of the sphere, along the row through its centre.
        (28..48)
            .map(|x| b.pixels[24 * 48 + x].x / a.pixels[24 * 48 + x].x)
            .collect::<Vec<f32>>()
    };
    let soft = visibility(area);
    assert!(soft.iter().any(|&v| v < 0.5), "no shadow: {soft:?}");
    assert!(soft.iter().any(|&v| v > 0.99), "no light: {soft:?}");
    let penumbra = soft.iter().filter(|&&v| v > 0.1 && v < 0.9).count();
    assert!(penumbra >= 2, "no penumbra: {soft:?}");
    let hard = visibility(point);
    assert!(hard.iter().any(|&v| v < 0.01), "no shadow: {hard:?}");
    assert!(
        hard.iter().all(|&v| !(0.01..0.99).contains(&v)),
        "a point light's shadow has no penumbra: {hard:?}"
    );
}

/// A progressive render stops at a pass boundary and is exactly the render
/// of the samples it reached; so is a prefix of the samples.
#[test]
fn progressive_passes_are_exact() {
    let file = repo_scene("cornell.toml");
    let settings = RenderSettings {
        width: 16,
        height: 16,
        spp: 12,
        ..file.settings.clone()
    };
    let (timed, stats) = render_timed(
        &file.scene,
        &settings,
        &FilmOptions::default(),
        1e6,
        &|_| {},
    )
    .unwrap();
    assert_eq!(stats.spp, 12);
    assert_eq!(timed.header.samples.count, 12);
    let (whole, _) = render_film(&file.scene, &settings, &FilmOptions::default(), &|_| {}).unwrap();
    assert_eq!(timed.image.pixels, whole.image.pixels);
    // A tiny time budget still renders one pass, and says so.
    let (short, stats) = render_timed(
        &file.scene,
        &settings,
        &FilmOptions::default(),
        1e-9,
        &|_| {},
    )
    .unwrap();
    assert_eq!(stats.spp, 1);
    let one = RenderSettings {
        spp: 1,
        ..settings.clone()
    };
    let (first, _) = render_film(&file.scene, &one, &FilmOptions::default(), &|_| {}).unwrap();
    assert_eq!(short.image.pixels, first.image.pixels);
}

/// The same image for any number of threads.
#[test]
fn path_tracing_is_deterministic_across_threads() {
    let file = repo_scene("cornell.toml");
    let images: Vec<Image> = [1, 2, 3]
        .iter()
        .map(|&threads| {
            let settings = RenderSettings {
                width: 32,
                height: 24,
                spp: 4,
                threads,
                ..file.settings.clone()
            };
            render(&file.scene, &settings, &|_| {}).unwrap().0
        })
        .collect();
    assert_eq!(images[0].pixels, images[1].pixels);
    assert_eq!(images[0].pixels, images[2].pixels);
}

/// Every integrator renders every shipped scene without a bad sample.
#[test]
fn integrators_render_the_new_scenes() {
    for name in ["cornell.toml", "veach-mis.toml"] {
        let file = repo_scene(name);
        for integrator in IntegratorKind::ALL {
            let settings = RenderSettings {
                width: 16,
                height: 12,
                spp: 2,
                integrator,
                ..file.settings.clone()
            };
            let (_, stats) = render(&file.scene, &settings, &|_| {}).unwrap();
            assert_eq!(stats.bad_samples, 0, "{name} {integrator}");
        }
    }
}

/// An environment map from an EXR file: a white sphere in a map of radiance
/// 1 everywhere vanishes (the map is importance-sampled as a light), and a
/// map that is not there is an error naming the path tried.
#[test]
fn environment_map_furnace_and_errors() {
    let dir = tempfile::tempdir().unwrap();
    exr::prelude::write_rgb_file(dir.path().join("white.exr"), 32, 16, |_, _| {
        (1.0f32, 1.0f32, 1.0f32)
    })
    .unwrap();
    let text = r#"
[camera]
position = [0, 0, -4]
look_at = [0, 0, 0]
fov = 30
[render]
width = 32
height = 32
spp = 16
integrator = "path"
max_depth = -1
[environment]
map = "white.exr"
rotate_y = 40
[materials]
m = { type = "diffuse", color = [1, 1, 1] }
[[object]]
shape = "sphere"
center = [0, 0, 0]
radius = 1
material = "m"
"#;
    let file = parse_scene(text, &dir.path().join("scene.toml")).unwrap();
    let (image, _) = render(&file.scene, &file.settings, &|_| {}).unwrap();
    let m = mean(&image);
    assert!(m.iter().all(|c| (c - 1.0).abs() < 0.01), "{m:?}");
    // Whitted sees the map where rays leave the scene.
    let whitted = RenderSettings {
        integrator: IntegratorKind::Whitted,
        ..file.settings.clone()
    };
    let (image, _) = render(&file.scene, &whitted, &|_| {}).unwrap();
    assert_eq!(image.pixels[0], glint::math::Color::ONE);

    let missing = parse_scene(
        &text.replace("white.exr", "nowhere.exr"),
        &dir.path().join("scene.toml"),
    )
    .unwrap_err()
    .to_string();
    // It points at the `map` value.
    let line = text.lines().position(|l| l.starts_with("map =")).unwrap() + 1;
    assert!(
        missing.contains(&format!("scene.toml:{line}:7:"))
            && missing.contains("the environment")
            && missing.contains("nowhere.exr"),
        "{missing}"
    );
}
