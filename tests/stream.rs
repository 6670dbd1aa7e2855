//! Whitted's integrator traces scenes of spheres, planes and boxes many
//! camera rays at a time (breadth first, in SIMD batches), and ray
//! casting their camera and shadow rays in SIMD batches too. These tests
//! render scenes both ways, the other way being the integrator one ray at
//! a time (depth first), and ask for the same image bit for bit and the
//! same counts.

use glint::math::{Color, Ray};
use glint::render::{AnyIntegrator, Counters, Integrator, PixelSampler, RenderStats, render_with};
use glint::scene::{BUILTIN_WHITTED, Scene, parse_scene};
use glint::settings::{IntegratorKind, RenderSettings};
use std::path::Path;

/// The integrator, one camera ray at a time (it never streams).
struct OneByOne(AnyIntegrator);

impl Integrator for OneByOne {
    fn radiance(
        &self,
        scene: &Scene,
        ray: &Ray,
        sampler: &mut PixelSampler,
        counters: &mut Counters,
    ) -> Color {
        self.0.radiance(scene, ray, sampler, counters)
    }

    fn escaped(&self, scene: &Scene, ray: &Ray) -> Option<Color> {
        Integrator::escaped(&self.0, scene, ray)
    }
}

/// The counts of a render, without its times.
fn counts(s: &RenderStats) -> String {
    let mut s = s.clone();
    s.seconds_render = 0.0;
    s.rays_per_second = 0.0;
    s.samples_per_second = 0.0;
    format!("{s:?}")
}

/// Renders `scene` with `integrator` (streaming where it can) and one ray
/// at a time, asks for the same image bit for bit, and returns the two
/// renders' statistics.
fn render_both_ways(
    scene: &Scene,
    settings: &RenderSettings,
    integrator: AnyIntegrator,
) -> (RenderStats, RenderStats) {
    let options = Default::default();
    let (streamed, a) =
        render_with(scene, settings, &integrator, &options, &|_| {}).expect("renders");
    let (one, b) =
        render_with(scene, settings, &OneByOne(integrator), &options, &|_| {}).expect("renders");
    let (width, height) = (settings.width, settings.height);
    for (k, (x, y)) in streamed
        .image
        .pixels
        .iter()
        .zip(&one.image.pixels)
        .enumerate()
    {
        assert_eq!(
            x.to_array().map(f32::to_bits),
            y.to_array().map(f32::to_bits),
            "pixel {k} of {width}×{height}: {x} streamed, {y} one by one"
        );
    }
    (a, b)
}

/// Renders `text` (a scene file) both ways with Whitted's integrator and
/// with ray casting (which streams such scenes in SIMD batches, shadow
/// rays too) and compares; returns whether Whitted's streamed breadth
/// first.
fn same_both_ways(text: &str, width: u32, height: u32, spp: u32, max_depth: i32) -> bool {
    let file = parse_scene(text, Path::new("stream.toml")).unwrap_or_else(|e| panic!("{e}"));
    let mut breadth_first = false;
    for kind in [IntegratorKind::Whitted, IntegratorKind::Raycast] {
        let settings = RenderSettings {
            width,
            height,
            spp,
            max_depth,
            integrator: kind,
            ..file.settings.clone()
        };
        let integrator = AnyIntegrator::new(&settings);
        match integrator {
            AnyIntegrator::Whitted(w) => {
                breadth_first = w.streams(&file.scene) && w.breadth_first(&file.scene)
            }
            AnyIntegrator::Raycast(_) => {}
            _ => unreachable!(),
        };
        let (a, b) = render_both_ways(&file.scene, &settings, integrator);
        assert_eq!(counts(&a), counts(&b), "{kind:?}");
    }
    breadth_first
}

#[test]
fn whitted_scene_streams_to_the_same_image() {
    assert!(same_both_ways(BUILTIN_WHITTED, 96, 64, 1, 8));
    // Several samples per pixel: a tile's samples are streamed together,
    // and past 16 per pixel, a pixel's 64 at a time.
    assert!(same_both_ways(BUILTIN_WHITTED, 40, 30, 5, 8));
    assert!(same_both_ways(BUILTIN_WHITTED, 12, 8, 70, 8));
    // Depths where rays are cut by depth, and the deepest that streams.
    assert!(same_both_ways(BUILTIN_WHITTED, 48, 32, 1, 0));
    assert!(same_both_ways(BUILTIN_WHITTED, 48, 32, 1, 2));
    assert!(same_both_ways(BUILTIN_WHITTED, 48, 32, 1, 9));
    // Deeper trees may be cut by the ray budget, in depth-first order:
    // those stream only their camera rays' first hits.
    assert!(!same_both_ways(BUILTIN_WHITTED, 24, 16, 1, 10));
}

/// Every material and light kind the integrator knows, on spheres, planes
/// and boxes, with absorbing glass and the camera close to the glass.
const MIXED: &str = r#"
[camera]
position = [0.4, 1.2, -3.2]
look_at = [0, 0.6, 0]
up = [0, 1, 0]
fov = 60

[render]
width = 64
height = 48
integrator = "whitted"
max_depth = 6
min_weight = 1e-4
light_samples = 0                 # the glowing sphere is seen, not sampled
background = [0.1, 0.2, 0.5]
ambient = [0.2, 0.2, 0.2]

[materials]
checks = { type = "diffuse", texture = { checker = [[0.9, 0.9, 0.9], [0.2, 0.3, 0.8]], scale = 0.5 }, ambient = 0.1 }
mirror = { type = "mirror", reflectance = [0.9, 0.8, 0.7], specular = 0.5, shininess = 50 }
glass = { type = "dielectric", ior = 1.5, absorption = [0.5, 0.1, 0.05], specular = 0.9, shininess = 500 }
clear = { type = "dielectric", ior = 1.33 }
gold = { type = "conductor", metal = "Au", specular = 0.6, shininess = 40 }
steel = { type = "principled", color = [0.8, 0.8, 0.85], metallic = 1.0 }
pglass = { type = "principled", color = [1, 1, 1], transmission = 1.0, ior = 1.4 }
glow = { type = "diffuse", color = [1, 1, 1], emission = [2, 1.5, 1] }

[[light]]
type = "point"
position = [2, 4, -3]
intensity = 30

[[light]]
type = "directional"
direction = [-0.3, -1, 0.4]
irradiance = 0.8

[[light]]
type = "point"
position = [-2, 3, -1]
intensity = [20, 10, 5]

[[object]]
shape = "plane"
point = [0, 0, 0]
normal = [0, 1, 0]
material = "checks"

[[object]]
shape = "box"
min = [0.6, 0, 0.2]
max = [1.4, 0.8, 1.0]
material = "clear"

[[object]]
shape = "sphere"
center = [-0.8, 0.6, 0.5]
radius = 0.6
material = "mirror"

[[object]]
shape = "sphere"
center = [0.2, 0.7, -1.6]
radius = 0.7
material = "glass"

[[object]]
shape = "sphere"
center = [1.5, 0.3, -0.8]
radius = 0.3
material = "gold"

[[object]]
shape = "box"
min = [-1.8, 0, -1.5]
max = [-1.2, 0.4, -0.9]
material = "steel"

[[object]]
shape = "sphere"
center = [-0.2, 0.25, -2.2]
radius = 0.25
material = "pglass"

[[object]]
shape = "sphere"
center = [0, 2.5, 2]
radius = 0.3
material = "glow"
"#;

#[test]
fn mixed_scene_streams_to_the_same_image() {
    assert!(same_both_ways(MIXED, 64, 48, 1, 6));
    assert!(same_both_ways(MIXED, 32, 24, 3, 9));
}

/// A scene whose hits Whitted's stream shades in SIMD lanes (point lights
/// only; spheres, boxes and a plane; diffuse, mirror and clear glass;
/// solid and planar checkerboards), with two objects it shades one by one
/// among them (absorbing glass, a conductor).
const LANES: &str = r#"
[camera]
position = [0.3, 1.1, -3.0]
look_at = [0, 0.6, 0]
up = [0, 1, 0]
fov = 65

[render]
integrator = "whitted"
min_weight = 1e-4
background = [0.1, 0.2, 0.5]
ambient = [0.2, 0.25, 0.3]

[materials]
floor = { type = "diffuse", texture = { checker = [[0.9, 0.9, 0.9], [0.2, 0.3, 0.8]], scale = 0.5, mode = "solid" }, ambient = 0.1, specular = 0.3, shininess = 20 }
tiles = { type = "diffuse", texture = { checker = [[0.8, 0.2, 0.1], [0.9, 0.8, 0.1]], scale = 0.15 }, ambient = 0.2 }
cubes = { type = "diffuse", texture = { checker = [[0.1, 0.7, 0.2], [0.9, 0.9, 0.9]], scale = 0.2, mode = "solid" }, specular = 0.6, shininess = 80 }
mirror = { type = "mirror", reflectance = [0.9, 0.8, 0.7], color = [0.3, 0.3, 0.3], diffuse = 0.2, specular = 0.5, shininess = 50 }
glass = { type = "dielectric", ior = 1.5, specular = 0.9, shininess = 500 }
water = { type = "dielectric", ior = 1.33 }
tinted = { type = "dielectric", ior = 1.4, absorption = [0.5, 0.1, 0.05] }
gold = { type = "conductor", metal = "Au", specular = 0.6, shininess = 40 }

[[light]]
type = "point"
position = [2, 4, -3]
intensity = 30

[[light]]
type = "point"
position = [-2, 3, -1]
intensity = [20, 10, 5]

[[object]]
shape = "plane"
point = [0, 0, 0]
normal = [0, 1, 0]
material = "floor"

[[object]]
shape = "box"
min = [-1.9, 0, -0.2]
max = [-1.1, 0.5, 0.6]
material = "tiles"

[[object]]
shape = "box"
min = [0.6, 0, 0.2]
max = [1.4, 0.8, 1.0]
material = "water"

[[object]]
shape = "sphere"
center = [-0.8, 0.6, 0.9]
radius = 0.6
material = "mirror"

[[object]]
shape = "sphere"
center = [0.25, 0.45, -1.3]
radius = 0.45
material = "glass"

[[object]]
shape = "sphere"
center = [1.3, 0.35, -0.5]
radius = 0.35
material = "tinted"

[[object]]
shape = "sphere"
center = [-0.9, 0.25, -1.2]
radius = 0.25
material = "gold"

[[object]]
shape = "sphere"
center = [0.3, 0.3, 1.4]
radius = 0.3
material = "cubes"
"#;

#[test]
fn scene_shaded_in_lanes_streams_to_the_same_image() {
    assert!(same_both_ways(LANES, 64, 48, 1, 8));
    assert!(same_both_ways(LANES, 32, 24, 2, 3));
}

#[test]
fn scenes_it_cannot_stream_are_traced_one_by_one() {
    // Area lights sampled with random numbers: not streamed, the same image.
    let area = MIXED.replace("light_samples = 0", "light_samples = 4");
    assert!(!same_both_ways(&area, 32, 24, 1, 4));
}

/// Ray casting and Whitted's integrator stream camera rays through meshes
/// as packets (`Scene::intersect_packet`), and ray casting its shadow rays
/// too (`Scene::segments_packet`). A scene of a transformed torus
/// instance, a bumpy icosphere, a mirror sphere and a tinted glass sphere
/// in the light's way, rendered both ways: the same image bit for bit,
/// the same rays and object tests. (The packets may take a node's
/// children in another order than a single ray, so the counts of BVH nodes
/// and triangle tests are not compared; a pixel whose ray hits two
/// triangles at exactly the same `t` could also differ, and this scene has
/// none.)
#[test]
fn raycast_streams_meshes_as_packets_to_the_same_image() {
    use glam::DVec3;
    use glint::geometry::testgen::{bumpy_icosphere, torus};
    use glint::geometry::{Mesh, MeshInstance, Shape, Sphere};
    use glint::math::{Transform, Vec3};
    use glint::scene::{Camera, Light, Material, Object};
    use std::sync::Arc;
    let mesh = |(v, f)| Arc::new(Mesh::new(v, f, Vec::new(), Vec::new()).unwrap());
    let t = Transform::from_parts(
        DVec3::new(1.0, 1.5, 0.8),
        DVec3::new(-60.0, 20.0, 10.0),
        DVec3::new(0.3, 1.0, -0.5),
    )
    .unwrap();
    let torus = Object {
        shape: Shape::Mesh(MeshInstance::new(mesh(torus(1.0, 0.35, 48, 24)), Some(&t))),
        material: 0,
    };
    let ball = Object {
        shape: Shape::Mesh(MeshInstance::new(mesh(bumpy_icosphere(4)), None)),
        material: 0,
    };
    // Partly behind the ball: hits on objects met later must not win. A
    // mirror, for Whitted's ray trees.
    let sphere = Object {
        shape: Shape::Sphere(Sphere::new(Vec3::new(0.8, 0.6, 1.8), 0.6)),
        material: 1,
    };
    let mirror = Material {
        kind: glint::scene::MaterialKind::Mirror {
            reflectance: Color::splat(0.8),
        },
        ..Material::default_diffuse()
    };
    // Glass on the way from the ball to the light: shadow rays pass
    // through it (Fresnel at each crossing, and absorption inside).
    let glass = Object {
        shape: Shape::Sphere(Sphere::new(Vec3::new(1.2, 3.0, -1.6), 0.5)),
        material: 2,
    };
    let tinted = Material {
        kind: glint::scene::MaterialKind::Dielectric {
            ior: 1.5,
            absorption: Color::new(0.2, 0.5, 0.9),
            roughness: 0.0,
        },
        ..Material::default_diffuse()
    };
    let scene = |objects| {
        Scene::new(
            Camera::try_new(
                Vec3::new(0.0, 1.5, -4.5),
                Vec3::new(0.0, 0.5, 0.0),
                Vec3::Y,
                45.0,
            )
            .unwrap(),
            objects,
            vec![Material::default_diffuse(), mirror.clone(), tinted.clone()],
            vec![Light::Point {
                position: Vec3::new(3.0, 6.0, -4.0),
                intensity: Color::splat(40.0),
            }],
            Color::splat(0.1),
            Color::ZERO,
        )
        .unwrap()
    };
    // One mesh and a sphere (tested in turn), and two meshes (merged into
    // one, with the sphere in a top-level BVH).
    let scenes = [
        (
            scene(vec![ball.clone(), glass.clone(), sphere.clone()]),
            (96, 72, 1),
        ),
        (
            scene(vec![torus.clone(), ball.clone(), sphere.clone(), glass]),
            (96, 72, 1),
        ),
        (scene(vec![torus, ball, sphere]), (40, 30, 3)),
    ];
    let cases = [IntegratorKind::Raycast, IntegratorKind::Whitted]
        .into_iter()
        .flat_map(|i| scenes.iter().map(move |s| (i, s)));
    for (integrator, (scene, (width, height, spp))) in cases {
        let (width, height, spp) = (*width, *height, *spp);
        let settings = RenderSettings {
            width,
            height,
            spp,
            integrator,
            ..Default::default()
        };
        let integrator = AnyIntegrator::new(&settings);
        assert!(integrator.streams(scene));
        let (a, b) = render_both_ways(scene, &settings, integrator);
        let lit = (a.rays.shadow as f64) / (a.rays.camera as f64);
        assert!(lit > 0.1, "shadow rays per camera ray {lit}");
        assert_eq!(
            (a.rays, a.intersection_tests),
            (b.rays, b.intersection_tests)
        );
        if settings.integrator == IntegratorKind::Whitted {
            assert!(a.rays.reflection > 20, "{:?}", a.rays);
        }
    }
}
