//! Output variables: what they hold, that the counting ones add up to the
//! render's statistics, that they leave the image alone, and the files.

use glint::render::{Aov, FilmOptions, render_film};
use glint::settings::RenderSettings;
use std::path::Path;

/// A scene with a mesh (a 20×20 grid of triangle pairs, written here), an
/// implicit torus, a sphere, a mirror and a glass ball.
fn scene(dir: &Path) -> glint::scene::SceneFile {
    let mut obj = String::new();
    for j in 0..=20 {
        for i in 0..=20 {
            obj += &format!("v {} {} 3\n", i as f32 * 0.2 - 2.0, j as f32 * 0.2 - 2.0);
        }
    }
    for j in 0..20 {
        for i in 0..20 {
            let v = |i: usize, j: usize| j * 21 + i + 1;
            obj += &format!("f {} {} {}\n", v(i, j), v(i + 1, j), v(i + 1, j + 1));
            obj += &format!("f {} {} {}\n", v(i, j), v(i + 1, j + 1), v(i, j + 1));
        }
    }
    std::fs::write(dir.join("grid.obj"), obj).unwrap();
    let toml = r#"
[camera]
position = [0, 0, -5]
look_at = [0, 0, 0]
fov = 50
[render]
width = 33
height = 25
spp = 3
background = [0.1, 0.2, 0.3]
ambient = 0.1
[materials]
red = { type = "diffuse", color = [0.8, 0.1, 0.1] }
glass = { type = "dielectric", ior = 1.5 }
mirror = { type = "mirror" }
[[light]]
type = "point"
position = [3, 4, -6]
intensity = 60
[[object]]
shape = "mesh"
file = "grid.obj"
material = "red"
[[object]]
shape = "sphere"
center = [0, 0, 0]
radius = 1
material = "glass"
[[object]]
shape = "implicit"
surface = "torus"
major_radius = 0.6
minor_radius = 0.2
transform = { translate = [1.4, 1.2, 0] }
material = "mirror"
"#;
    let path = dir.join("s.toml");
    std::fs::write(&path, toml).unwrap();
    glint::scene::load_scene_file(&path).unwrap()
}

#[test]
fn counting_layers_add_up_to_the_statistics_and_leave_the_image_alone() {
    let dir = tempfile::tempdir().unwrap();
    let file = scene(dir.path());
    let plain = render_film(
        &file.scene,
        &file.settings,
        &FilmOptions::default(),
        &|_| {},
    )
    .unwrap()
    .0;
    let options = FilmOptions {
        keep_sums: false,
        aovs: Aov::ALL.to_vec(),
    };
    let (film, stats) = render_film(&file.scene, &file.settings, &options, &|_| {}).unwrap();
    assert_eq!(film.image, plain.image);
    assert!(plain.aov_pixels.is_empty());
    let sum = |f: &dyn Fn(&glint::render::AovPixel) -> u32| -> u64 {
        film.aov_pixels.iter().map(|p| f(p) as u64).sum()
    };
    assert!(stats.bvh_nodes_visited > 0 && stats.implicit_evaluations > 0);
    assert_eq!(sum(&|p| p.nodes), stats.bvh_nodes_visited);
    assert_eq!(sum(&|p| p.prims), stats.triangle_tests);
    assert_eq!(sum(&|p| p.evals), stats.implicit_evaluations);
    assert_eq!(sum(&|p| p.rays[0]), stats.rays.camera);
    assert_eq!(sum(&|p| p.rays[1]), stats.rays.shadow);
    assert_eq!(sum(&|p| p.rays[2]), stats.rays.reflection);
    assert_eq!(sum(&|p| p.rays[3]), stats.rays.refraction);
    // Every pixel shot its three camera rays.
    assert!(film.aov_pixels.iter().all(|p| p.rays[0] == 3));
}

#[test]
fn first_hit_layers_match_the_geometry() {
    let dir = tempfile::tempdir().unwrap();
    let file = scene(dir.path());
    let settings = RenderSettings {
        spp: 1,
        ..file.settings.clone()
    };
    let options = FilmOptions {
        keep_sums: false,
        aovs: vec![Aov::Depth, Aov::Normal, Aov::Id, Aov::Albedo],
    };
    let film = render_film(&file.scene, &settings, &options, &|_| {})
        .unwrap()
        .0;
    let at = |x: u32, y: u32| film.aov_pixels[(y * 33 + x) as usize];
    // The centre pixel's ray runs down +z through the sphere's centre: it
    // meets the sphere (object 2) 4 units away, facing straight back.
    let c = at(16, 12);
    assert!((c.depth - 4.0).abs() < 1e-5, "{c:?}");
    assert_eq!(c.id, 2);
    for (n, want) in c.normal.iter().zip([0.0, 0.0, -1.0]) {
        assert!((n - want).abs() < 1e-5, "{c:?}");
    }
    assert_eq!(c.albedo, [1.0; 3]);
    // Just inside the grid's corner: the mesh (object 1), red, depth > 8,
    // its normal facing the eye.
    let g = at(11, 18);
    assert_eq!(g.id, 1, "{g:?}");
    assert!(g.depth > 8.0, "{g:?}");
    assert_eq!(g.albedo, [0.8, 0.1, 0.1]);
    assert!(g.normal[2] < -0.99, "{g:?}");
    // The corner pixel sees only the background.
    let m = at(0, 0);
    assert_eq!((m.depth, m.id, m.normal), (0.0, 0, [0.0; 3]));
    // The torus is object 3.
    assert!(film.aov_pixels.iter().any(|p| p.id == 3));
}

#[test]
fn the_command_line_writes_aov_channels_and_pictures() {
    let dir = tempfile::tempdir().unwrap();
    scene(dir.path());
    let run = |args: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_glint"))
            .args(args)
            .current_dir(dir.path())
            .output()
            .unwrap()
    };
    let out = run(&[
        "render",
        "s.toml",
        "--aov",
        "cost,depth,id",
        "--aov-png",
        "-o",
        "a.exr",
        "-q",
        "--stats-json",
        "s.json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let image = exr::prelude::read_all_flat_layers_from_file(dir.path().join("a.exr")).unwrap();
    let channels = &image.layer_data[0].channel_data.list;
    let find = |name: &str| {
        channels
            .iter()
            .find(|c| c.name == *name)
            .unwrap_or_else(|| panic!("no channel {name}"))
    };
    let nodes: u64 = match &find("cost.nodes").sample_data {
        exr::prelude::FlatSamples::U32(v) => v.iter().map(|&x| x as u64).sum(),
        other => panic!("cost.nodes is {other:?}"),
    };
    let stats: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("s.json")).unwrap()).unwrap();
    assert_eq!(nodes, stats["bvh_nodes_visited"].as_u64().unwrap());
    find("Z");
    find("id");
    find("cost.prims");
    for name in [
        "a.cost-nodes.png",
        "a.cost-prims.png",
        "a.depth.png",
        "a.id.png",
    ] {
        let png = image::open(dir.path().join(name)).unwrap();
        assert_eq!(png.width(), 33, "{name}");
        assert!(png.height() >= 25, "{name}");
    }
    // The merge of a part with AOVs keeps the image.
    let out = run(&["merge", "a.exr", "-o", "m.exr", "-q"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    let out = run(&["render", "s.toml", "--aov", "depth,speed", "-o", "b.png"]);
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        e.contains("unknown AOV `speed`; expected some of: depth, normal"),
        "{e}"
    );
}

/// The channels of an EXR, by name: f32 values as their bits, u32 as they are.
fn channels(path: &Path) -> std::collections::BTreeMap<String, Vec<u32>> {
    let image = exr::prelude::read_all_flat_layers_from_file(path).unwrap();
    image.layer_data[0]
        .channel_data
        .list
        .iter()
        .map(|c| {
            let v = match &c.sample_data {
                exr::prelude::FlatSamples::U32(v) => v.clone(),
                exr::prelude::FlatSamples::F32(v) => v.iter().map(|x| x.to_bits()).collect(),
                exr::prelude::FlatSamples::F16(v) => v.iter().map(|x| x.to_bits() as u32).collect(),
            };
            (c.name.to_string(), v)
        })
        .collect()
}

#[test]
fn merged_parts_keep_their_aovs() {
    let dir = tempfile::tempdir().unwrap();
    scene(dir.path());
    let run = |args: &str| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_glint"))
            .args(args.split_whitespace())
            .current_dir(dir.path())
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{args}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    let base = "render s.toml -q --aov cost,rays,evals,id,depth,normal,albedo";
    run(&format!("{base} -o whole.exr"));
    for k in 0..4 {
        run(&format!("{base} --tiles 2x2 --tile-index {k} -o t{k}.exr"));
    }
    run(&format!("{base} --spp 1 -o r0.exr"));
    run(&format!("{base} --spp 2 --sample-offset 1 -o r1.exr"));
    // One part without AOVs: the merge keeps the image only.
    run("render s.toml -q --spp 2 --sample-offset 1 -o plain.exr");
    run("merge t0.exr t1.exr t2.exr t3.exr -o tiles.exr -q");
    run("merge r1.exr r0.exr -o ranges.exr -q");
    run("merge r0.exr plain.exr -o mixed.exr -q");
    let whole = channels(&dir.path().join("whole.exr"));
    assert!(whole.contains_key("cost.nodes") && whole.contains_key("N.Y"));
    assert_eq!(channels(&dir.path().join("tiles.exr")), whole);
    assert_eq!(channels(&dir.path().join("ranges.exr")), whole);
    let mixed = channels(&dir.path().join("mixed.exr"));
    assert!(!mixed.contains_key("cost.nodes") && !mixed.contains_key("Z"));
    assert_eq!(mixed["R"], whole["R"]);
}
