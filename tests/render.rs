//! Image-level tests of the renderer on small scenes with known answers.

use glint::math::{Color, Ray, Vec3};
use glint::render::{Counters, Integrator, PixelSampler, render, render_with};
use glint::scene::{BUILTIN_WHITTED, Scene, SceneFile, TraceCounters, parse_scene};
use glint::settings::{IntegratorKind, RenderSettings};
use std::path::Path;

fn scene(text: &str) -> SceneFile {
    parse_scene(text, Path::new("test.toml")).unwrap_or_else(|e| panic!("{e}"))
}

fn whitted(width: u32, height: u32) -> (SceneFile, RenderSettings) {
    let file = scene(BUILTIN_WHITTED);
    let settings = RenderSettings {
        width,
        height,
        spp: 1,
        ..file.settings.clone()
    };
    (file, settings)
}

#[test]
fn default_scene_renders_without_nan() {
    let (file, settings) = whitted(64, 48);
    let (image, stats) = render(&file.scene, &settings, &|_| {}).unwrap();
    assert_eq!(stats.nan_pixels, 0);
    assert!(
        image
            .pixels
            .iter()
            .all(|c| c.is_finite() && c.min_element() >= 0.0)
    );
    // The picture is not blank: sky, checks and spheres give many colours.
    let mut distinct: Vec<[u8; 3]> = image
        .to_srgb8()
        .chunks(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    distinct.sort_unstable();
    distinct.dedup();
    assert!(distinct.len() > 100, "{} colours", distinct.len());
    // The top row is sky: the background colour exactly.
    assert_eq!(image.get(0, 0), file.scene.background);
}

#[test]
fn thread_count_does_not_change_a_single_bit() {
    let (file, mut settings) = whitted(67, 45); // not a multiple of the tile size
    settings.spp = 3;
    settings.threads = 1;
    let (one, s1) = render(&file.scene, &settings, &|_| {}).unwrap();
    settings.threads = 2;
    let (two, s2) = render(&file.scene, &settings, &|_| {}).unwrap();
    settings.threads = 5;
    let (five, _) = render(&file.scene, &settings, &|_| {}).unwrap();
    let bits = |img: &glint::render::Image| -> Vec<u32> {
        img.pixels
            .iter()
            .flat_map(|c| c.to_array().map(f32::to_bits))
            .collect()
    };
    assert_eq!(bits(&one), bits(&two));
    assert_eq!(bits(&one), bits(&five));
    assert_eq!(s1.rays, s2.rays);
    assert_eq!(s1.intersection_tests, s2.intersection_tests);
}

#[test]
fn raycast_traces_no_secondary_rays_and_whitted_does() {
    let (file, mut settings) = whitted(48, 36);
    settings.integrator = IntegratorKind::Raycast;
    let (_, ray) = render(&file.scene, &settings, &|_| {}).unwrap();
    assert_eq!(ray.rays.reflection, 0);
    assert_eq!(ray.rays.refraction, 0);
    assert_eq!(ray.rays.camera, 48 * 36);
    assert!(ray.rays.shadow > 0);
    settings.integrator = IntegratorKind::Whitted;
    let (_, wh) = render(&file.scene, &settings, &|_| {}).unwrap();
    assert!(wh.rays.reflection > 0 && wh.rays.refraction > 0);
    assert_eq!(wh.rays.camera, ray.rays.camera);
}

#[test]
fn max_depth_zero_is_ray_casting() {
    let (file, mut settings) = whitted(40, 30);
    settings.max_depth = 0;
    let (a, sa) = render(&file.scene, &settings, &|_| {}).unwrap();
    settings.integrator = IntegratorKind::Raycast;
    let (b, _) = render(&file.scene, &settings, &|_| {}).unwrap();
    assert_eq!(sa.rays.reflection + sa.rays.refraction, 0);
    assert_eq!(a, b);
}

#[test]
fn min_weight_prunes_secondary_rays() {
    let (file, mut settings) = whitted(48, 36);
    let (_, all) = render(&file.scene, &settings, &|_| {}).unwrap();
    settings.min_weight = 0.5;
    let (_, pruned) = render(&file.scene, &settings, &|_| {}).unwrap();
    // Fresnel reflection off glass (R ≈ 0.04 … 1) is mostly below 0.5.
    assert!(pruned.rays.reflection < all.rays.reflection / 2);
    assert!(pruned.rays.refraction > 0);
}

/// A red Lambertian wall at z = 4 lit head-on by a point light, seen through a
/// glass sphere: the centre ray crosses the sphere at normal incidence, so it
/// sees the wall scaled by the Fresnel transmittance (1 − 0.04)² = 0.9216,
/// plus light reflected inside the sphere twice or more (≤ R² ≈ 0.2%).
const GLASS_IN_FRONT_OF_WALL: &str = r#"
[camera]
position = [0, 0, -5]
look_at = [0, 0, 0]
fov = 30

[render]
background = [0, 0, 0]

[materials]
glass = { type = "dielectric", ior = 1.5 }
wall = { type = "diffuse", color = [0.8, 0.1, 0.1] }

[[light]]
type = "point"
position = [0, 3, 1]
intensity = 10

[[object]]
shape = "sphere"
center = [0, 0, 0]
radius = 1
material = "glass"

[[object]]
shape = "plane"
point = [0, 0, 4]
normal = [0, 0, -1]
material = "wall"
"#;

#[test]
fn ray_through_glass_centre_sees_the_wall_behind() {
    let file = scene(GLASS_IN_FRONT_OF_WALL);
    let s = &file.scene;
    let integrator = glint::render::Whitted {
        max_depth: 8,
        min_weight: 1e-6,
        light_samples: 16,
    };
    let mut counters = Counters::default();
    let through = integrator.radiance(
        s,
        &Ray::new(Vec3::new(0.0, 0.0, -5.0), Vec3::Z),
        &mut PixelSampler::new(0, 0, 0),
        &mut counters,
    );
    // The wall point (0, 0, 4): light at (0, 3, 1) → L = (0, 3, −3)/√18,
    // N·L = 3/√18, irradiance 10/18; the shadow ray misses the sphere.
    let cos = 3.0 / 18f32.sqrt();
    let wall = Color::new(0.8, 0.1, 0.1) * cos * 10.0 / 18.0;
    let expected = wall * 0.96 * 0.96;
    assert!(through.x > 0.1, "black: {through:?}");
    let rel = (through - expected).abs() / expected;
    assert!(rel.max_element() < 0.003, "{through:?} vs {expected:?}");
    // Into the sphere and out again at least.
    assert!(counters.rays.refraction >= 2);
}

#[test]
fn shadow_through_glass_is_filtered_and_opaque_is_black() {
    let file = scene(GLASS_IN_FRONT_OF_WALL);
    let s = &file.scene;
    let mut c = TraceCounters::default();
    // Straight through the centre: two crossings at normal incidence.
    let through = Ray::spawn_to(
        Vec3::new(0.0, 0.0, -3.0),
        Vec3::ZERO,
        -Vec3::Z,
        Vec3::new(0.0, 0.0, 3.0),
    );
    let t = glint::render::transmittance(s, &through, &mut c);
    assert!(
        (t - Color::splat(0.9216)).abs().max_element() < 1e-4,
        "{t:?}"
    );
    // Missing the sphere: fully lit.
    let beside = Ray::spawn_to(
        Vec3::new(2.0, 0.0, -3.0),
        Vec3::ZERO,
        -Vec3::Z,
        Vec3::new(2.0, 0.0, 3.0),
    );
    assert_eq!(glint::render::transmittance(s, &beside, &mut c), Color::ONE);
    // The wall is opaque.
    let into_wall = Ray::spawn_to(
        Vec3::new(2.0, 0.0, 3.0),
        Vec3::ZERO,
        -Vec3::Z,
        Vec3::new(2.0, 0.0, 5.0),
    );
    assert_eq!(
        glint::render::transmittance(s, &into_wall, &mut c),
        Color::ZERO
    );
    assert!(s.occluded(&into_wall, &mut c));
}

/// Ray casting of a Lambertian plane under a directional light: every pixel
/// that sees the plane has radiance `albedo · cos θ · E` exactly, with no
/// dependence on distance.
#[test]
fn lambertian_plane_under_directional_light_matches_closed_form() {
    let file = scene(
        r#"
[camera]
position = [0, 2, -4]
look_at = [0, 1.5, 0]

[render]
width = 24
height = 16
integrator = "raycast"
background = [0, 0, 1]
ambient = [0.1, 0.1, 0.1]

[materials]
grey = { type = "diffuse", color = [0.5, 0.25, 1.0], ambient = 0.5 }

[[light]]
type = "directional"
direction = [1, -2, 0]
irradiance = 2

[[object]]
shape = "plane"
material = "grey"
"#,
    );
    let (image, _) = render(&file.scene, &file.settings, &|_| {}).unwrap();
    let cos = 2.0 / 5f32.sqrt();
    let albedo = Color::new(0.5, 0.25, 1.0);
    let expected = albedo * cos * 2.0 + albedo * 0.5 * 0.1;
    let (mut plane, mut sky) = (0, 0);
    for c in &image.pixels {
        if *c == Color::new(0.0, 0.0, 1.0) {
            sky += 1;
        } else {
            plane += 1;
            assert!(
                (*c - expected).abs().max_element() < 1e-5,
                "{c:?} vs {expected:?}"
            );
        }
    }
    assert!(plane > 100 && sky > 50, "{plane} plane, {sky} sky pixels");
}

/// A mirror tints what it reflects: a camera looking down at a mirror floor
/// sees the sky (background) scaled by the reflectance.
#[test]
fn mirror_reflects_the_background_tinted() {
    let file = scene(
        r#"
[camera]
position = [0, 1, 0]
look_at = [0, 0, 0.001]
fov = 10

[render]
width = 8
height = 8
background = [0.2, 0.4, 0.8]

[materials]
m = { type = "mirror", reflectance = [0.5, 1, 0.25] }

[[object]]
shape = "plane"
material = "m"
"#,
    );
    let (image, stats) = render(&file.scene, &file.settings, &|_| {}).unwrap();
    let expected = Color::new(0.1, 0.4, 0.2);
    for c in &image.pixels {
        assert!((*c - expected).abs().max_element() < 1e-6, "{c:?}");
    }
    assert_eq!(stats.rays.reflection, 64);
}

/// An integrator that returns NaN and infinity for some rays: the renderer
/// must count them and keep every pixel finite.
struct Broken;

impl Integrator for Broken {
    fn radiance(&self, _: &Scene, ray: &Ray, _: &mut PixelSampler, _: &mut Counters) -> Color {
        if ray.d.x > 0.2 {
            Color::splat(f32::NAN)
        } else if ray.d.x < -0.2 {
            Color::new(f32::INFINITY, 0.0, 0.0)
        } else {
            Color::ONE
        }
    }
}

#[test]
fn nan_and_infinity_never_reach_a_pixel() {
    let (file, mut settings) = whitted(32, 16);
    settings.spp = 4;
    let (film, stats) = render_with(
        &file.scene,
        &settings,
        &Broken,
        &Default::default(),
        &|_| {},
    )
    .unwrap();
    let image = film.image;
    assert!(image.pixels.iter().all(|c| c.is_finite()));
    assert!(stats.nan_pixels > 0 && stats.nan_pixels < 32 * 16);
    assert!(stats.bad_samples >= stats.nan_pixels);
}

#[test]
fn more_samples_converge_towards_the_same_image() {
    // Stratified supersampling: 16 spp differs from 64 spp less than 1 spp does.
    let (file, mut settings) = whitted(32, 24);
    let mut run = |spp| {
        settings.spp = spp;
        render(&file.scene, &settings, &|_| {}).unwrap().0
    };
    let (one, sixteen, many) = (run(1), run(16), run(64));
    let diff = |a: &glint::render::Image, b: &glint::render::Image| -> f32 {
        a.pixels
            .iter()
            .zip(&b.pixels)
            .map(|(x, y)| (*x - *y).abs().element_sum())
            .sum()
    };
    assert!(diff(&sixteen, &many) < 0.5 * diff(&one, &many));
}

#[test]
fn absorbing_glass_attenuates_by_beer_lambert() {
    // The centre ray travels 2 units inside the sphere.
    let clear = scene(GLASS_IN_FRONT_OF_WALL);
    let tinted = scene(&GLASS_IN_FRONT_OF_WALL.replace(
        "glass = { type = \"dielectric\", ior = 1.5 }",
        "glass = { type = \"dielectric\", ior = 1.5, absorption = [0.1, 0.5, 1.0] }",
    ));
    let integrator = glint::render::Whitted {
        max_depth: 8,
        min_weight: 1e-6,
        light_samples: 16,
    };
    let ray = Ray::new(Vec3::new(0.0, 0.0, -5.0), Vec3::Z);
    let mut c = Counters::default();
    let a = integrator.radiance(&clear.scene, &ray, &mut PixelSampler::new(0, 0, 0), &mut c);
    let b = integrator.radiance(&tinted.scene, &ray, &mut PixelSampler::new(0, 0, 0), &mut c);
    let ratio = b.x / a.x;
    assert!((ratio - (-0.2f32).exp()).abs() < 2e-3, "{ratio}");
    // Shadow rays through it are tinted the same way.
    let shadow = Ray::spawn_to(
        Vec3::new(0.0, 0.0, -3.0),
        Vec3::ZERO,
        -Vec3::Z,
        Vec3::new(0.0, 0.0, 3.0),
    );
    let t = glint::render::transmittance(&tinted.scene, &shadow, &mut TraceCounters::default());
    let expected = 0.9216 * (-Color::new(0.1, 0.5, 1.0) * 2.0).exp();
    assert!(
        (t - expected).abs().max_element() < 1e-4,
        "{t:?} vs {expected:?}"
    );
}

#[test]
fn solid_checker_alternates_in_world_space() {
    // A camera looking straight down at a plane with a solid checker of 1-unit
    // cubes: the colour changes across x = 0 and z = 0.
    let file = scene(
        r#"
[camera]
position = [0, 5, 0]
look_at = [0, 0, 0]
up = [0, 0, 1]
fov = 30

[render]
width = 20
height = 20
integrator = "raycast"
ambient = 1

[materials]
c = { type = "diffuse", texture = { checker = [[1, 0, 0], [0, 0, 1]], scale = 1, mode = "solid" }, diffuse = 0 }

[[object]]
shape = "plane"
point = [0, 0.5, 0]
material = "c"
"#,
    );
    let (image, _) = render(&file.scene, &file.settings, &|_| {}).unwrap();
    let (a, b) = (image.get(4, 4), image.get(15, 4));
    assert!(a == Color::X || a == Color::Z);
    assert!(b == Color::X || b == Color::Z);
    assert_ne!(a, b);
    assert_eq!(image.get(4, 4), image.get(15, 15));
}

#[test]
fn invalid_settings_are_errors_not_panics() {
    let (file, mut settings) = whitted(0, 10);
    assert!(render(&file.scene, &settings, &|_| {}).is_err());
    settings.width = 30000;
    settings.height = 30000;
    let e = render(&file.scene, &settings, &|_| {}).unwrap_err();
    assert!(e.to_string().contains("more than the limit"), "{e}");
    settings.width = 8;
    settings.height = 8;
    settings.min_weight = f32::NAN;
    assert!(render(&file.scene, &settings, &|_| {}).is_err());
}

/// A glass and a diffuse sphere in one corner of the frame, lit, under a
/// coloured sky (for the path integrator, a constant environment light):
/// most tiles of the image see only the sky.
const SPHERES_IN_A_CORNER: &str = r#"
[camera]
position = [0, 0, -6]
look_at = [0, 0, 0]
fov = 40

[render]
background = [0.2, 0.3, 0.45]

[materials]
glass = { type = "dielectric", ior = 1.5 }
matte = { type = "diffuse", color = [0.7, 0.6, 0.2] }

[[light]]
type = "point"
position = [2, 3, -3]
intensity = 20

[[object]]
shape = "sphere"
center = [-1.2, 1.0, 0]
radius = 0.4
material = "glass"

[[object]]
shape = "sphere"
center = [-1.5, 0.6, 1]
radius = 0.5
material = "matte"
"#;

#[test]
fn tiles_known_to_miss_render_as_if_traced_bit_for_bit() {
    use glint::render::{AnyIntegrator, PixelSamples, SampleSum};
    let file = scene(SPHERES_IN_A_CORNER);
    let (w, h) = (80, 48);
    for integrator in [
        IntegratorKind::Raycast,
        IntegratorKind::Whitted,
        IntegratorKind::Path,
    ] {
        for spp in [1, 3] {
            let settings = RenderSettings {
                width: w,
                height: h,
                spp,
                integrator,
                ..file.settings.clone()
            };
            let (image, stats) = render(&file.scene, &settings, &|_| {}).unwrap();
            // Every pixel traced one by one, as the renderer would without
            // culling.
            let tracer = AnyIntegrator::new(&settings);
            let mut traced_rays = 0;
            for y in 0..h {
                for x in 0..w {
                    let mut samples = PixelSamples::new(x, y);
                    let mut sum = SampleSum::default();
                    let mut counters = Counters::default();
                    for i in 0..spp {
                        let (u, v) = samples.offset(i);
                        let ray = file.scene.camera.ray(x as f32 + u, y as f32 + v, w, h);
                        let mut sampler = samples.sampler(i);
                        sum.add_sample(tracer.radiance(
                            &file.scene,
                            &ray,
                            &mut sampler,
                            &mut counters,
                        ));
                    }
                    traced_rays += counters.trace.intersection_tests;
                    let expected = sum.mean(spp as u64);
                    let got = image.pixels[(y * w + x) as usize];
                    assert_eq!(
                        got.to_array().map(f32::to_bits),
                        expected.to_array().map(f32::to_bits),
                        "{integrator:?} {spp} spp, pixel ({x}, {y}): {got:?} against {expected:?}"
                    );
                }
            }
            // Tiles were culled: fewer objects tested than tracing every ray.
            assert!(
                stats.intersection_tests < traced_rays,
                "{integrator:?}: {} tests, {traced_rays} when every ray is traced",
                stats.intersection_tests
            );
        }
    }
}

#[test]
fn a_tile_is_culled_only_if_its_rays_miss_everything() {
    let file = scene(SPHERES_IN_A_CORNER);
    let s = &file.scene;
    let (w, h) = (640, 480);
    let mut rng = glint::render::Pcg32::new(11, 5);
    let (mut culled, mut kept) = (0, 0);
    for _ in 0..400 {
        let (x0, y0) = (rng.next_f32() * w as f32, rng.next_f32() * h as f32);
        let size = 1.0 + rng.next_f32() * 64.0;
        let (x1, y1) = (x0 + size, y0 + size * (0.5 + rng.next_f32()));
        if !s.camera_misses(x0, x1, y0, y1, w, h) {
            kept += 1;
            continue;
        }
        culled += 1;
        // Rays through a grid over the rectangle, its edges and corners
        // included, all miss.
        for i in 0..=8 {
            for j in 0..=8 {
                let x = x0 + (x1 - x0) * i as f32 / 8.0;
                let y = y0 + (y1 - y0) * j as f32 / 8.0;
                let ray = s.camera.ray(x, y, w, h);
                assert!(
                    s.intersect(&ray, &mut TraceCounters::default()).is_none(),
                    "({x}, {y}) in [{x0}, {x1}] × [{y0}, {y1}] hits"
                );
            }
        }
    }
    assert!(culled > 50 && kept > 50, "{culled} culled, {kept} kept");
    // A rectangle over the spheres is never culled, and a scene with a
    // plane (unbounded) never is.
    let (px, py) = s
        .camera
        .project(Vec3::new(-1.2, 1.0, 0.0), w, h)
        .expect("in front");
    assert!(!s.camera_misses(px - 1.0, px + 1.0, py - 1.0, py + 1.0, w, h));
    let wall = scene(GLASS_IN_FRONT_OF_WALL);
    assert!(!wall.scene.camera_misses(0.0, 8.0, 0.0, 8.0, w, h));
    // The built-in Whitted scene (a box and two spheres) culls its sky.
    let whitted = scene(BUILTIN_WHITTED);
    assert!(whitted.scene.camera_misses(0.0, 8.0, 0.0, 8.0, w, h));
}
