//! Crops and sample ranges rendered apart and merged are the whole render,
//! bit for bit; `glint merge` refuses parts that do not fit, naming them.

use glint::render::parts::{Film, merge};
use glint::render::{StagedFile, read_film_exr, render_film};
use glint::scene::{BUILTIN_WHITTED, parse_scene};
use glint::settings::{Rect, RenderSettings};
use std::path::Path;
use std::process::{Command, Output};

fn whitted() -> (glint::scene::Scene, RenderSettings) {
    let file = parse_scene(BUILTIN_WHITTED, Path::new("whitted.toml")).unwrap();
    let settings = RenderSettings {
        width: 40,
        height: 30,
        spp: 4,
        ..file.settings
    };
    (file.scene, settings)
}

fn film(scene: &glint::scene::Scene, settings: &RenderSettings) -> Film {
    let options = glint::render::FilmOptions {
        keep_sums: true,
        ..Default::default()
    };
    render_film(scene, settings, &options, &|_| {}).unwrap().0
}

/// The f32 bits of every pixel, and the sums.
fn bits(f: &Film) -> (Vec<[u32; 3]>, &[glint::render::SampleSum]) {
    let px = f
        .image
        .pixels
        .iter()
        .map(|c| c.to_array().map(f32::to_bits))
        .collect();
    (px, &f.sums)
}

#[test]
fn crops_merge_into_the_whole_render_bit_for_bit() {
    let (scene, settings) = whitted();
    let whole = film(&scene, &settings);
    for (n, m) in [(2, 2), (4, 4), (3, 1)] {
        let tiles: Vec<(String, Film)> = (0..n * m)
            .map(|k| {
                let crop = Rect::tile(settings.width, settings.height, n, m, k).unwrap();
                let s = RenderSettings {
                    crop: Some(crop),
                    ..settings.clone()
                };
                (format!("tile {k}"), film(&scene, &s))
            })
            .collect();
        // Each crop is exactly its pixels of the whole render.
        for (_, t) in &tiles {
            let r = t.header.rect;
            for y in r.y0..r.y1 {
                for x in r.x0..r.x1 {
                    let a = t.image.get(x - r.x0, y - r.y0);
                    let b = whole.image.get(x, y);
                    assert_eq!(
                        a.to_array().map(f32::to_bits),
                        b.to_array().map(f32::to_bits)
                    );
                }
            }
        }
        let parts: Vec<(String, &Film)> = tiles.iter().map(|(n, f)| (n.clone(), f)).collect();
        let merged = merge(&parts).unwrap();
        assert_eq!(merged.header, whole.header, "{n}×{m}");
        assert_eq!(bits(&merged), bits(&whole), "{n}×{m}");
    }
}

#[test]
fn sample_ranges_merge_into_one_render_of_all_samples_bit_for_bit() {
    let (scene, settings) = whitted();
    let all = film(
        &scene,
        &RenderSettings {
            spp: 8,
            ..settings.clone()
        },
    );
    for split in [&[0, 4, 8][..], &[0, 1, 3, 8], &[0, 7, 8]] {
        let ranges: Vec<(String, Film)> = split
            .windows(2)
            .map(|w| {
                let s = RenderSettings {
                    spp: w[1] - w[0],
                    sample_offset: w[0],
                    ..settings.clone()
                };
                (format!("samples {}..{}", w[0], w[1]), film(&scene, &s))
            })
            .collect();
        // In any order.
        let parts: Vec<(String, &Film)> =
            ranges.iter().rev().map(|(n, f)| (n.clone(), f)).collect();
        let merged = merge(&parts).unwrap();
        assert_eq!(merged.header, all.header, "{split:?}");
        assert_eq!(bits(&merged), bits(&all), "{split:?}");
    }
    // The sampler, not the split, decides: more samples change the image.
    assert_ne!(bits(&all).0, bits(&film(&scene, &settings)).0);
}

#[test]
fn tiles_of_sample_ranges_merge_and_merge_again() {
    let (scene, settings) = whitted();
    let whole = film(&scene, &settings);
    let mut parts = Vec::new();
    for k in 0..4 {
        for (offset, spp) in [(0, 1), (1, 3)] {
            let s = RenderSettings {
                crop: Rect::tile(40, 30, 2, 2, k),
                spp,
                sample_offset: offset,
                ..settings.clone()
            };
            parts.push((format!("tile {k} samples {offset}"), film(&scene, &s)));
        }
    }
    let all: Vec<(String, &Film)> = parts.iter().map(|(n, f)| (n.clone(), f)).collect();
    assert_eq!(bits(&merge(&all).unwrap()), bits(&whole));
    // Merge each tile's ranges first, then the tiles.
    let per_tile: Vec<(String, Film)> = all
        .chunks(2)
        .map(|c| (c[0].0.clone(), merge(c).unwrap()))
        .collect();
    let tiles: Vec<(String, &Film)> = per_tile.iter().map(|(n, f)| (n.clone(), f)).collect();
    assert_eq!(bits(&merge(&tiles).unwrap()), bits(&whole));
}

#[test]
fn an_exr_part_reads_back_as_written() {
    let (scene, settings) = whitted();
    let dir = tempfile::tempdir().unwrap();
    let s = RenderSettings {
        crop: Some(Rect {
            x0: 3,
            x1: 29,
            y0: 7,
            y1: 8,
        }),
        sample_offset: 4_000_000_000,
        ..settings
    };
    let mut f = film(&scene, &s);
    f.header.fingerprint = "0123456789abcdef".into();
    let path = dir.path().join("p.exr");
    let mut file = StagedFile::create(&path).unwrap();
    file.write_film(&f).unwrap();
    file.commit().unwrap();
    assert_eq!(read_film_exr(&path).unwrap(), f);
    // The display window is the frame, the data window the crop.
    let meta = exr::meta::MetaData::read_from_file(&path, false).unwrap();
    let h = &meta.headers[0];
    assert_eq!(h.shared_attributes.display_window.size.x(), 40);
    assert_eq!(h.shared_attributes.display_window.size.y(), 30);
    assert_eq!(h.own_attributes.layer_position.x(), 3);
    assert_eq!(h.own_attributes.layer_position.y(), 7);
    assert_eq!(h.layer_size.x(), 26);
}

fn glint(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_glint"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("the glint binary runs")
}

/// Runs glint, which must succeed.
fn ok(dir: &Path, args: &str) {
    let out = glint(dir, &args.split_whitespace().collect::<Vec<_>>());
    assert!(
        out.status.success(),
        "glint {args}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Runs glint, which must fail, and returns its error.
fn fails(dir: &Path, args: &str) -> String {
    let out = glint(dir, &args.split_whitespace().collect::<Vec<_>>());
    assert!(!out.status.success(), "glint {args} succeeded");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn the_command_line_renders_parts_and_merges_them() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let base = "render --width 48 --height 32 -q";
    ok(d, &format!("{base} --spp 4 -o whole.exr"));
    ok(d, &format!("{base} --spp 4 -o whole.png"));
    for k in 0..4 {
        ok(
            d,
            &format!("{base} --spp 4 --tiles 2x2 --tile-index {k} -o t{k}.exr"),
        );
    }
    ok(d, &format!("{base} --spp 1 -o s0.exr"));
    ok(d, &format!("{base} --spp 3 --sample-offset 1 -o s1.exr"));
    ok(d, "merge t0.exr t1.exr t2.exr t3.exr -o tiles.exr -q");
    ok(d, "merge s1.exr s0.exr -o samples.exr -q");
    ok(d, "merge s1.exr s0.exr -o samples.png -q");
    // The same render gives the same file, byte for byte.
    let whole = std::fs::read(d.join("whole.exr")).unwrap();
    assert_eq!(std::fs::read(d.join("tiles.exr")).unwrap(), whole);
    assert_eq!(std::fs::read(d.join("samples.exr")).unwrap(), whole);
    assert_eq!(
        std::fs::read(d.join("samples.png")).unwrap(),
        std::fs::read(d.join("whole.png")).unwrap()
    );

    // Refusals name the files and leave no output.
    let e = fails(d, "merge t0.exr t1.exr t2.exr -o x.exr");
    assert!(e.contains("parts are missing: pixel (24, 16)"), "{e}");
    let e = fails(d, "merge t0.exr t1.exr t2.exr t3.exr t3.exr -o x.exr");
    assert!(
        e.contains("`t3.exr` and `t3.exr` hold the same pixels and samples"),
        "{e}"
    );
    let e = fails(d, "merge whole.exr t0.exr -o x.exr");
    assert!(
        e.contains("`whole.exr` and `t0.exr` hold overlapping crops"),
        "{e}"
    );
    let e = fails(d, "merge whole.exr s1.exr -o x.exr");
    assert!(
        e.contains("overlapping sample ranges (0..4 and 1..4)"),
        "{e}"
    );
    ok(d, &format!("{base} --spp 2 --sample-offset 5 -o s5.exr"));
    let e = fails(d, "merge s0.exr s5.exr -o x.exr");
    assert!(
        e.contains("has 3 of the samples 0..7 (0..1 in `s0.exr`, 5..7 in `s5.exr`)"),
        "{e}"
    );
    ok(
        d,
        &format!("{base} --spp 3 --sample-offset 1 --max-depth 2 -o d.exr"),
    );
    let e = fails(d, "merge s0.exr d.exr -o x.exr");
    assert!(
        e.contains("`d.exr` and `s0.exr` come from different scenes or settings"),
        "{e}"
    );
    ok(
        d,
        "render --width 40 --height 32 --spp 3 --sample-offset 1 -q -o w.exr",
    );
    let e = fails(d, "merge s0.exr w.exr -o x.exr");
    assert!(
        e.contains("`w.exr` is part of a 40×32 frame, but `s0.exr` of a 48×32 one"),
        "{e}"
    );
    let e = fails(d, "merge whole.png -o x.exr");
    assert!(e.contains("`whole.png`: it is not an OpenEXR file"), "{e}");
    let e = fails(d, "merge gone.exr -o x.exr");
    assert!(e.contains("`gone.exr`: not found"), "{e}");
    assert!(!d.join("x.exr").exists());
    // A plain EXR without glint's header is not a part.
    let img = exr::prelude::Image::from_channels(
        (2, 2),
        exr::prelude::SpecificChannels::rgb(|_| (0.5f32, 0.5f32, 0.5f32)),
    );
    exr::prelude::WritableImage::write(&img)
        .to_file(d.join("plain.exr"))
        .unwrap();
    let e = fails(d, "merge plain.exr -o x.exr");
    assert!(
        e.contains("`plain.exr` is not a glint part: it has no `glint.part` attribute"),
        "{e}"
    );
    // Bad crops and tiles.
    let e = fails(d, &format!("{base} --tiles 2x2 --tile-index 4 -o x.exr"));
    assert!(
        e.contains("--tile-index 4 is past the last of 2×2 tiles"),
        "{e}"
    );
    let e = fails(d, &format!("{base} --tiles 49x1 --tile-index 0 -o x.exr"));
    assert!(e.contains("cannot be cut into 49×1 tiles"), "{e}");
    let e = fails(d, &format!("{base} --crop 0,49,0,2 -o x.exr"));
    assert!(
        e.contains("crop x 0..49, y 0..2 is not a non-empty part of the 48×32 frame"),
        "{e}"
    );
    let e = fails(d, &format!("{base} --crop 4,4,0,2 -o x.exr"));
    assert!(e.contains("is empty"), "{e}");
    let e = fails(d, &format!("{base} --tiles 2y2 --tile-index 0 -o x.exr"));
    assert!(e.contains("expected a grid NxM"), "{e}");
    let e = fails(
        d,
        &format!("{base} --spp 4 --sample-offset 4294967293 -o x.exr"),
    );
    assert!(e.contains("go past the last sample number"), "{e}");
    assert!(!d.join("x.exr").exists());
}

/// Runs every task of a farm's array script with bash, as Slurm would (a
/// stand-in `sbatch` on the PATH takes the merge job's submission), then the
/// merge script: the plain shell loop of the README's recipes.
fn run_farm_locally(dir: &Path, script: &Path, tasks: u32) {
    let bin = dir.join("bin");
    std::fs::create_dir_all(&bin).unwrap();
    let sbatch = bin.join("sbatch");
    std::fs::write(&sbatch, "#!/bin/sh\necho 42\n").unwrap();
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&sbatch, std::fs::Permissions::from_mode(0o755)).unwrap();
    let path = format!(
        "{}:{}",
        bin.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    for task in 0..tasks {
        let out = Command::new("bash")
            .arg(script)
            .env("SLURM_ARRAY_TASK_ID", task.to_string())
            .env("SLURM_ARRAY_JOB_ID", "41")
            .env("SLURM_CPUS_PER_TASK", "1")
            .env("PATH", &path)
            .current_dir(dir)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "task {task}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let merge = script.with_extension("").with_extension("merge.sh");
    let out = Command::new("bash")
        .arg(&merge)
        .current_dir(dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "merge: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn farm_scripts_render_and_merge_a_frame_and_a_sequence() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("w.toml"), BUILTIN_WHITTED).unwrap();
    let out = glint(
        d,
        &[
            "farm",
            "slurm",
            "w.toml",
            "--tiles",
            "3x2",
            "--spp",
            "3",
            "--spp-chunks",
            "2",
            "-o",
            "w.exr",
            "--",
            "--width",
            "30",
            "--height",
            "20",
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let script = std::path::PathBuf::from(String::from_utf8(out.stdout).unwrap().trim());
    assert_eq!(script, d.canonicalize().unwrap().join("w.slurm.sh"));
    let text = std::fs::read_to_string(&script).unwrap();
    assert!(text.contains("#SBATCH --array=0-11\n"), "{text}");
    run_farm_locally(d, &script, 12);
    ok(
        d,
        "render w.toml --width 30 --height 20 --spp 3 -q -o whole.exr",
    );
    assert_eq!(
        std::fs::read(d.join("w.exr")).unwrap(),
        std::fs::read(d.join("whole.exr")).unwrap()
    );
    assert_eq!(
        std::fs::read_to_string(d.join("w.parts/merge.jobid")).unwrap(),
        "42\n"
    );

    // A sequence: two frames with different cameras, one tile grid each.
    for (frame, z) in [(7, "-6"), (8, "-5")] {
        let scene = BUILTIN_WHITTED.replace(
            "position = [0, 2.2, -7]",
            &format!("position = [0, 2.2, {z}]"),
        );
        assert_ne!(scene, BUILTIN_WHITTED);
        std::fs::write(d.join(format!("shot.{frame:04}.toml")), scene).unwrap();
    }
    let out = glint(
        d,
        &[
            "farm",
            "slurm",
            "--frames",
            "shot.%04d.toml",
            "7-8",
            "--tiles",
            "2x1",
            "--",
            "--width",
            "24",
            "--height",
            "16",
            "--spp",
            "2",
        ],
    );
    assert!(!out.status.success(), "--spp after -- is refused");
    let out = glint(
        d,
        &[
            "farm",
            "slurm",
            "--frames",
            "shot.%04d.toml",
            "7-8",
            "--tiles",
            "2x1",
            "--spp",
            "2",
            "--",
            "--width",
            "24",
            "--height",
            "16",
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let script = std::path::PathBuf::from(String::from_utf8(out.stdout).unwrap().trim());
    run_farm_locally(d, &script, 4);
    for frame in [7, 8] {
        ok(
            d,
            &format!(
                "render shot.{frame:04}.toml --width 24 --height 16 --spp 2 -q -o f{frame}.png"
            ),
        );
        assert_eq!(
            std::fs::read(d.join(format!("shot.{frame:04}.png"))).unwrap(),
            std::fs::read(d.join(format!("f{frame}.png"))).unwrap(),
            "frame {frame}"
        );
    }
    assert_ne!(
        std::fs::read(d.join("f7.png")).unwrap(),
        std::fs::read(d.join("f8.png")).unwrap()
    );

    // Errors.
    let e = fails(d, "farm slurm --frames shot.%04d.toml 7-9");
    assert!(e.contains("frame 9's scene"), "{e}");
    let e = fails(d, "farm slurm --frames shot.toml 7-8");
    assert!(e.contains("exactly one frame number"), "{e}");
    let e = fails(d, "farm slurm w.toml --spp-chunks 2");
    assert!(e.contains("--spp-chunks needs --spp"), "{e}");
    let e = fails(d, "farm slurm gone.toml");
    assert!(e.contains("scene `gone.toml` does not exist"), "{e}");
    let e = fails(d, "farm slurm w.toml -- -o x.png");
    assert!(e.contains("`-o` after `--` would clash"), "{e}");
}
