//! The `glint` binary: default render, overrides, output files, statistics,
//! and errors.

use std::path::Path;
use std::process::{Command, Output};

fn glint(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_glint"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("the glint binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn no_arguments_render_the_builtin_scene_to_whitted_png() {
    let dir = tempfile::tempdir().unwrap();
    let out = glint(dir.path(), &[]);
    assert!(out.status.success(), "{}", stderr(&out));
    let png = dir.path().join("whitted.png");
    let img = image::open(&png).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (800, 600));
    assert!(
        stderr(&out).contains("wrote whitted.png"),
        "{}",
        stderr(&out)
    );
    // Only the image: no temporary file left behind.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn threads_do_not_change_the_output_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let base = [
        "render", "--width", "64", "--height", "48", "--spp", "2", "-q",
    ];
    let one = glint(
        dir.path(),
        &[&base[..], &["--threads", "1", "-o", "a.png"]].concat(),
    );
    let two = glint(
        dir.path(),
        &[&base[..], &["--threads", "2", "-o", "b.png"]].concat(),
    );
    assert!(one.status.success() && two.status.success());
    let a = std::fs::read(dir.path().join("a.png")).unwrap();
    let b = std::fs::read(dir.path().join("b.png")).unwrap();
    assert_eq!(a, b);
}

#[test]
fn stats_json_has_the_documented_keys() {
    let dir = tempfile::tempdir().unwrap();
    let out = glint(
        dir.path(),
        &[
            "render",
            "--width",
            "40",
            "--height",
            "30",
            "--spp",
            "1",
            "--stats-json",
            "s.json",
            "-o",
            "x.exr",
            "-q",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(out.stderr.is_empty(), "--quiet printed {}", stderr(&out));
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("s.json")).unwrap()).unwrap();
    assert_eq!(v["width"], 40);
    assert_eq!(v["height"], 30);
    assert_eq!(v["spp"], 1);
    assert_eq!(v["sample_offset"], 0);
    assert_eq!(v["crop"], serde_json::json!([0, 40, 0, 30]));
    assert!(v["seconds_render"].as_f64().unwrap() > 0.0);
    assert!(v["seconds_load"].as_f64().is_some());
    assert_eq!(v["rays"]["camera"], 1200);
    for k in ["shadow", "reflection", "refraction"] {
        assert!(v["rays"][k].as_u64().unwrap() > 0, "{k}");
    }
    assert!(v["intersection_tests"].as_u64().unwrap() > 1200);
    assert_eq!(v["nan_pixels"], 0);
    // The EXR holds linear radiance: the top-left pixel is the sky colour.
    let exr = exr::prelude::read_first_rgba_layer_from_file(
        dir.path().join("x.exr"),
        |res, _| vec![[0f32; 3]; res.width() * res.height()],
        |px: &mut Vec<[f32; 3]>, pos, (r, g, b, _): (f32, f32, f32, f32)| {
            px[pos.y() * 40 + pos.x()] = [r, g, b]
        },
    )
    .unwrap();
    assert_eq!(exr.layer_data.channel_data.pixels[0], [0.03, 0.12, 0.6]);
}

#[test]
fn command_line_overrides_the_scene_file() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("tiny.toml"),
        "[camera]\nposition = [0, 0, -3]\nlook_at = [0, 0, 0]\n[render]\nwidth = 10\nheight = 10\nintegrator = \"whitted\"\n",
    )
    .unwrap();
    let out = glint(
        dir.path(),
        &[
            "render",
            "tiny.toml",
            "--width",
            "12",
            "--integrator",
            "raycast",
            "--stats-json",
            "s.json",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let img = image::open(dir.path().join("tiny.png")).unwrap();
    assert_eq!((img.width(), img.height()), (12, 10));
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("s.json")).unwrap()).unwrap();
    assert_eq!(v["integrator"], "raycast");
}

#[test]
fn errors_are_clear_and_leave_no_file() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("bad.toml"),
        "[camera]\nposition = [0, 0]\nlook_at = [0, 0, 1]\n",
    )
    .unwrap();
    let out = glint(dir.path(), &["render", "bad.toml"]);
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("bad.toml:2:12: expected an array of 3 numbers"),
        "{}",
        stderr(&out)
    );

    let out = glint(dir.path(), &["render", "missing.toml"]);
    assert!(
        stderr(&out).contains("cannot read scene file `missing.toml`"),
        "{}",
        stderr(&out)
    );

    let out = glint(dir.path(), &["render", "-o", "picture.jpg"]);
    assert!(
        stderr(&out).contains("unsupported file extension"),
        "{}",
        stderr(&out)
    );

    let out = glint(dir.path(), &["render", "--spp", "0"]);
    assert!(!out.status.success());

    let out = glint(dir.path(), &["render", "-o", "nowhere/x.png"]);
    assert!(
        stderr(&out).contains("folder `nowhere` does not exist"),
        "{}",
        stderr(&out)
    );

    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, vec![std::ffi::OsString::from("bad.toml")]);
}

/// An ASCII PLY octahedron.
const OCTAHEDRON: &str = "ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\nproperty float y\nproperty float z\n\
element face 8\nproperty list uchar int vertex_indices\nend_header\n\
1 0 0\n-1 0 0\n0 1 0\n0 -1 0\n0 0 1\n0 0 -1\n\
3 0 2 4\n3 2 1 4\n3 1 3 4\n3 3 0 4\n3 2 0 5\n3 1 2 5\n3 3 1 5\n3 0 3 5\n";

#[test]
fn info_and_rendering_a_mesh_file() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("oct.ply"), OCTAHEDRON).unwrap();
    let out = glint(dir.path(), &["info", "oct.ply"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("triangles    8") && text.contains("vertices     6"),
        "{text}"
    );
    assert!(text.contains("bytes per triangle"), "{text}");

    let out = glint(
        dir.path(),
        &[
            "render",
            "oct.ply",
            "--width",
            "48",
            "--height",
            "32",
            "--view=-0.3,1,0.2",
            "--up",
            "0,0,1",
            "--stats-json",
            "s.json",
            "-q",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let img = image::open(dir.path().join("oct.png")).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (48, 32));
    assert!(img.pixels().any(|p| p[0] > 50), "the mesh is lit");
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("s.json")).unwrap()).unwrap();
    assert_eq!(v["triangles"], 8);
    assert_eq!(v["instances"], 1);
    for k in [
        "seconds_load",
        "seconds_build",
        "bvh_bytes",
        "bvh_nodes_visited",
        "bytes_per_triangle",
    ] {
        assert!(v[k].as_f64().is_some(), "{k}");
    }
    assert!(v["peak_rss_bytes"].as_u64().unwrap_or(1) > 0);

    std::fs::write(
        dir.path().join("bad.ply"),
        OCTAHEDRON.replace("3 0 3 5", "3 0 3 9"),
    )
    .unwrap();
    let out = glint(dir.path(), &["info", "bad.ply"]);
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("bad.ply: face 7: vertex index out of range"),
        "{}",
        stderr(&out)
    );
    let out = glint(
        dir.path(),
        &["render", "oct.ply", "--view", "0,1,0", "--up", "0,2,0"],
    );
    assert!(
        stderr(&out).contains("must be non-zero and not parallel"),
        "{}",
        stderr(&out)
    );
}

/// Output paths are checked before any work, and the outputs appear all
/// together or not at all.
#[test]
fn unwritable_outputs_fail_before_rendering_and_leave_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let small = ["render", "--width", "32", "--height", "24"];
    let out = glint(dir.path(), &[&small[..], &["-o", "/proc/x.png"]].concat());
    assert!(!out.status.success());
    let err = stderr(&out);
    assert!(err.contains("cannot write `/proc/x.png`"), "{err}");
    assert!(!err.contains("Rendered"), "it rendered first: {err}");

    let out = glint(
        dir.path(),
        &[
            &small[..],
            &["-o", "ok.png", "--stats-json", "/proc/x.json"],
        ]
        .concat(),
    );
    assert!(!out.status.success());
    let err = stderr(&out);
    assert!(err.contains("cannot write `/proc/x.json`"), "{err}");
    assert!(!err.contains("Rendered"), "{err}");
    // Neither the image nor any temporary file.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);

    std::fs::create_dir(dir.path().join("folder.png")).unwrap();
    let out = glint(dir.path(), &[&small[..], &["-o", "folder.png"]].concat());
    assert!(stderr(&out).contains("it is a folder"), "{}", stderr(&out));

    let out = glint(
        dir.path(),
        &[&small[..], &["-o", "a.exr", "--stats-json", "a.json"]].concat(),
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let mut names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    names.sort();
    assert_eq!(names, ["a.exr", "a.json", "folder.png"]);
}

/// Whitted with every glass hit split in two down to depth 1024: the ray
/// tree of each sample is bounded, and the summary says it was cut.
#[test]
fn runaway_ray_trees_are_bounded() {
    let dir = tempfile::tempdir().unwrap();
    let out = glint(
        dir.path(),
        &[
            "render",
            "--width",
            "32",
            "--height",
            "24",
            "--max-depth",
            "1024",
            "--min-weight",
            "0",
            "--stats-json",
            "s.json",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let stats: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("s.json")).unwrap()).unwrap();
    let camera = stats["rays"]["camera"].as_u64().unwrap();
    let secondary = stats["rays"]["reflection"].as_u64().unwrap()
        + stats["rays"]["refraction"].as_u64().unwrap();
    assert!(secondary <= camera * glint::render::MAX_RAY_TREE as u64);
    assert!(stats["ray_trees_cut"].as_u64().unwrap() > 0);
    assert!(
        stderr(&out).contains("secondary rays per sample"),
        "{}",
        stderr(&out)
    );
}

/// `glint ARGS` in `dir` under an address-space limit of `kb` kilobytes.
#[cfg(target_os = "linux")]
fn glint_under_limit(dir: &Path, kb: u64, args: &str) -> Output {
    Command::new("sh")
        .arg("-c")
        .arg(format!(
            "ulimit -v {kb} && exec '{}' {args}",
            env!("CARGO_BIN_EXE_glint")
        ))
        .current_dir(dir)
        .output()
        .expect("sh runs")
}

/// A film larger than the memory the process may use is refused with a
/// message, not an abort (here under a 2 GB address-space limit).
#[cfg(target_os = "linux")]
#[test]
fn a_film_too_large_for_memory_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let out = glint_under_limit(
        dir.path(),
        2_000_000,
        "render --width 32768 --height 4096 -o big.png",
    );
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("a 32768×4096 image needs 2.15 GB for its pixels"),
        "{err}"
    );
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

/// A mesh whose BVH build would not fit in memory is refused before the
/// build (here a binary PLY of 4M triangles under a 300 MB limit).
#[cfg(target_os = "linux")]
#[test]
fn a_mesh_too_large_for_memory_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let n = 4_000_000u32;
    let mut ply = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
         element face {n}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    .into_bytes();
    for v in [[0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
        ply.extend(v.iter().flat_map(|c| c.to_le_bytes()));
    }
    for _ in 0..n {
        ply.push(3);
        ply.extend([0i32, 1, 2].iter().flat_map(|i| i.to_le_bytes()));
    }
    std::fs::write(dir.path().join("big.ply"), ply).unwrap();
    let out = glint_under_limit(dir.path(), 300_000, "info big.ply");
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains(
            "big.ply: file: building the BVH of its 4000000 triangles needs about 0.40 GB"
        ),
        "{err}"
    );
}

/// `glint info` says whether a large mesh keeps its leaf blocks (here, a
/// grid of 7,200 triangles, above the 4,096 of a small mesh, on a machine
/// with memory to spare); a small mesh gets no such line.
#[test]
fn info_reports_leaf_blocks_of_a_large_mesh() {
    let n = 60;
    let mut ply = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        (n + 1) * (n + 1),
        2 * n * n
    );
    for j in 0..=n {
        for i in 0..=n {
            ply += &format!("{i} {j} {}\n", (i * j) % 7);
        }
    }
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i;
            ply += &format!(
                "3 {a} {} {}\n3 {a} {} {}\n",
                a + 1,
                a + n + 2,
                a + n + 2,
                a + n + 1
            );
        }
    }
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("grid.ply"), ply).unwrap();
    std::fs::write(dir.path().join("oct.ply"), OCTAHEDRON).unwrap();
    let out = glint(dir.path(), &["info", "grid.ply"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("triangles    7,200"), "{text}");
    assert!(text.contains("leaf blocks  kept (1 large mesh"), "{text}");
    let out = glint(dir.path(), &["info", "oct.ply"]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(!String::from_utf8_lossy(&out.stdout).contains("leaf blocks"));
}
