//! `glint explain`: the ray tree of a pixel sample adds up to the pixel,
//! shows Whitted's rays, and names what blocks a shadow ray.

use glint::render::explain::explain;
use glint::render::{Aov, FilmOptions, RayKind, render_film};
use glint::scene::{BUILTIN_WHITTED, parse_scene};
use glint::settings::{IntegratorKind, Rect, RenderSettings};
use std::path::Path;

fn whitted(width: u32, height: u32) -> (glint::scene::Scene, RenderSettings) {
    let file = parse_scene(BUILTIN_WHITTED, Path::new("whitted.toml")).unwrap();
    let settings = RenderSettings {
        width,
        height,
        spp: 1,
        ..file.settings
    };
    (file.scene, settings)
}

fn close(a: [f32; 3], b: [f32; 3]) -> bool {
    a.iter()
        .zip(b)
        .all(|(x, y)| (x - y).abs() <= 1e-5 * x.abs().max(y.abs()).max(1e-3))
}

#[test]
fn every_pixels_tree_adds_up_to_the_rendered_pixel() {
    let (scene, settings) = whitted(32, 24);
    for integrator in [
        IntegratorKind::Whitted,
        IntegratorKind::Raycast,
        IntegratorKind::Path,
    ] {
        for sample in [0, 5] {
            let s = RenderSettings {
                integrator,
                sample_offset: sample,
                ..settings.clone()
            };
            let (image, _) = glint::render::render(&scene, &s, &|_| {}).unwrap();
            for y in 0..24 {
                for x in 0..32 {
                    let e = explain(&scene, &s, x, y, sample).unwrap();
                    let pixel = image.get(x, y).to_array();
                    // Exactly the pixel, but for values below 2^−25, which
                    // the film rounds to multiples of 2^−48.
                    if e.radiance.iter().all(|&c| c == 0.0 || c >= 3e-8) {
                        assert_eq!(e.radiance, pixel, "({x}, {y}) sample {sample}");
                    }
                    assert!(
                        close(e.total, pixel),
                        "({x}, {y}): {:?} vs {pixel:?}",
                        e.total
                    );
                    if integrator == IntegratorKind::Raycast {
                        assert!(e.rays.nodes[1..].iter().all(|n| n.kind == RayKind::Shadow));
                    }
                }
            }
        }
    }
}

#[test]
fn a_glass_pixel_has_reflection_refraction_and_shadow_rays() {
    let (scene, settings) = whitted(80, 60);
    let options = FilmOptions {
        keep_sums: false,
        aovs: vec![Aov::Id],
    };
    let film = render_film(&scene, &settings, &options, &|_| {}).unwrap().0;
    // The glass sphere is the third object.
    let i = film.aov_pixels.iter().position(|p| p.id == 3).unwrap();
    let (x, y) = (i as u32 % 80, i as u32 / 80);
    let e = explain(&scene, &settings, x, y, 0).unwrap();
    let root = &e.rays.nodes[0];
    assert_eq!(root.kind, RayKind::Camera);
    let hit = root.hit.as_ref().unwrap();
    assert_eq!((hit.object, hit.shape, hit.front_face), (3, "sphere", true));
    let children: Vec<RayKind> = e
        .rays
        .nodes
        .iter()
        .filter(|n| n.parent == Some(0))
        .map(|n| n.kind)
        .collect();
    for kind in [RayKind::Shadow, RayKind::Reflection, RayKind::Refraction] {
        assert!(children.contains(&kind), "{children:?}");
    }
    let [r, t] = root.fresnel.unwrap();
    assert!((r + t - 1.0).abs() < 1e-6);
    // The sample's value, rendered alone.
    let one = RenderSettings {
        crop: Some(Rect {
            x0: x,
            x1: x + 1,
            y0: y,
            y1: y + 1,
        }),
        ..settings.clone()
    };
    let (pixel, _) = glint::render::render(&scene, &one, &|_| {}).unwrap();
    assert!(close(e.total, pixel.pixels[0].to_array()));
}

#[test]
fn a_shadowed_pixel_names_its_blocker() {
    let (scene, settings) = whitted(80, 60);
    // Somewhere on the board, a shadow ray is stopped by the mirror sphere
    // (object 2); the glass sphere lets light through and blocks nothing.
    let mut found = false;
    'search: for y in 30..60 {
        for x in 0..80 {
            let e = explain(&scene, &settings, x, y, 0).unwrap();
            for n in &e.rays.nodes {
                if n.kind == RayKind::Shadow && n.blocked_by.is_some() {
                    assert_eq!(n.blocked_by, Some(2), "({x}, {y})");
                    assert_eq!(n.transmittance, Some([0.0; 3]));
                    assert_eq!(n.contribution, [0.0; 3]);
                    found = true;
                    break 'search;
                }
            }
        }
    }
    assert!(found);
    let e = explain(&scene, &settings, 80, 0, 0).unwrap_err();
    assert_eq!(
        e,
        "pixel (80, 0) is outside the 80×60 image (x from 0 to 79, y from 0 to 59)"
    );
}

#[test]
fn the_command_line_prints_and_writes_the_tree() {
    let dir = tempfile::tempdir().unwrap();
    let run = |args: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_glint"))
            .args(args)
            .current_dir(dir.path())
            .output()
            .unwrap()
    };
    let out = run(&["explain", "--pixel", "420,260", "--json", "t.json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(
        text.starts_with("Pixel (420, 260), sample 0, whitted integrator"),
        "{text}"
    );
    assert!(text.contains("camera ray from"), "{text}");
    assert!(text.contains("material `glass`"), "{text}");
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("t.json")).unwrap()).unwrap();
    assert_eq!(v["pixel"], serde_json::json!([420, 260]));
    let nodes = v["rays"]["nodes"].as_array().unwrap();
    assert_eq!(nodes[0]["kind"], "camera");
    assert!(nodes.iter().any(|n| n["kind"] == "refraction"));
    for key in [
        "origin",
        "direction",
        "throughput",
        "contribution",
        "bvh_nodes",
    ] {
        assert!(nodes[0].get(key).is_some(), "{key}");
    }
    // The SVG: side view by default, the eye ringed, a line per drawn ray.
    let out = run(&[
        "explain", "--pixel", "430,180", "--svg", "t.svg", "--width", "160", "--height", "120",
    ]);
    assert!(
        !out.status.success(),
        "430 is outside a 160-pixel-wide image"
    );
    let out = run(&[
        "explain", "--pixel", "86,36", "--svg", "t.svg", "--width", "160", "--height", "120",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let svg = std::fs::read_to_string(dir.path().join("t.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    assert!(svg.contains("data:image/png;base64,"));
    assert!(svg.contains("<title>the eye</title>"), "{svg}");
    assert!(svg.matches("<line").count() >= 3, "{svg}");
    let out = run(&[
        "explain",
        "--pixel",
        "86,36",
        "--svg",
        "c.svg",
        "--svg-view",
        "camera",
        "--width",
        "160",
        "--height",
        "120",
    ]);
    assert!(out.status.success());
    let svg = std::fs::read_to_string(dir.path().join("c.svg")).unwrap();
    assert!(
        svg.contains("pixel (86, 36): the camera ray, end on"),
        "{svg}"
    );

    let out = run(&["explain", "--pixel", "800,10"]);
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        e.contains("pixel (800, 10) is outside the 800×600 image"),
        "{e}"
    );
    let out = run(&["explain", "--pixel", "8"]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("expected a pixel X,Y"));
}

#[test]
fn the_side_view_frames_the_eye_and_every_hit() {
    let (scene, settings) = whitted(160, 120);
    let e = explain(&scene, &settings, 86, 36, 0).unwrap();
    let side = glint::render::explain::side_camera(&e, &scene).unwrap();
    let mut points = vec![scene.camera.position];
    points.extend(e.rays.nodes.iter().filter_map(|n| {
        n.hit
            .as_ref()
            .map(|h| glint::math::Vec3::from_array(h.point))
    }));
    assert!(points.len() >= 3);
    for p in points {
        let (x, y) = side
            .project(p, 160, 120)
            .expect("in front of the side camera");
        assert!(
            (0.0..160.0).contains(&x) && (0.0..120.0).contains(&y),
            "{p:?} → {x}, {y}"
        );
    }
}
