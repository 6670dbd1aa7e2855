//! `glint render`: settings from the scene file and the command line, the
//! render with a progress bar, the files written all together or not at
//! all, and the summary of what it took.

use super::{
    MeshView, count, group, load_scene, parse_grid, parse_integrator, parse_weight, peak_rss_bytes,
};
use anyhow::{Context, Result, bail};
use clap::Args;
use glint::render::{self, ImageFormat, RenderStats, StagedFile};
use glint::scene::{GeometryStats, SceneFile};
use glint::settings::{
    IntegratorKind, MAX_DEPTH, MAX_IMAGE_SIDE, MAX_LIGHT_SAMPLES, MAX_SPP, Rect,
};
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Args, Debug, Default)]
pub struct RenderArgs {
    /// Scene file (TOML, see docs/scene-format.md), or a mesh file (.ply, .obj,
    /// .gltf, .glb) to render framed by a default camera and light; the
    /// built-in Whitted scene if omitted.
    scene: Option<PathBuf>,
    /// Output image, .png (sRGB, 8-bit) or .exr (linear, 32-bit float).
    /// Default: the scene file's name with .png, in the current folder.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Image width in pixels (overrides the scene file).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=MAX_IMAGE_SIDE as i64))]
    width: Option<u32>,
    /// Image height in pixels.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=MAX_IMAGE_SIDE as i64))]
    height: Option<u32>,
    /// Samples per pixel (1: through pixel centres; more: stratified, jittered).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=MAX_SPP as i64))]
    spp: Option<u32>,
    /// Maximum recursion depth: bounces after the camera ray (−1: no limit;
    /// path tracing then ends paths by Russian roulette).
    #[arg(long, allow_hyphen_values = true, value_parser = clap::value_parser!(i32).range(-1..=MAX_DEPTH as i64))]
    max_depth: Option<i32>,
    /// Shadow rays per shading point to the area lights (Whitted and ray
    /// casting; soft shadows).
    #[arg(long, value_parser = clap::value_parser!(u32).range(0..=MAX_LIGHT_SAMPLES as i64))]
    light_samples: Option<u32>,
    /// Render progressively in passes of whole samples per pixel until this
    /// many seconds of rendering (stopping at the end of a pass; --spp, if
    /// given, is then the most samples taken). The stats and the EXR record
    /// the samples reached.
    #[arg(long, value_name = "SECONDS", value_parser = parse_seconds)]
    time: Option<f64>,
    /// Path tracing: find light by `mis` (light and BSDF sampling combined,
    /// the default), `light` or `bsdf` sampling alone.
    #[arg(long, value_parser = parse_sampling)]
    sampling: Option<glint::settings::Sampling>,
    /// Scale each sample down to at most this radiance in its largest
    /// channel (biased; off by default).
    #[arg(long, value_parser = parse_clamp)]
    clamp: Option<f32>,
    /// Rays whose weight falls below this are not traced (Whitted).
    #[arg(long, value_parser = parse_weight)]
    min_weight: Option<f32>,
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=4096))]
    threads: Option<u32>,
    /// Light transport algorithm: raycast, whitted or path.
    #[arg(long, value_parser = parse_integrator)]
    integrator: Option<IntegratorKind>,
    /// Render only the pixels x ∈ [X0, X1), y ∈ [Y0, Y1) of the frame
    /// (an EXR keeps the frame as its display window).
    #[arg(long, value_name = "X0,X1,Y0,Y1", conflicts_with = "tiles")]
    crop: Option<Rect>,
    /// Cut the frame into a grid of N×M tiles (N across, M down) and render
    /// the one given by --tile-index.
    #[arg(long, value_name = "NxM", value_parser = parse_grid, requires = "tile_index")]
    tiles: Option<(u32, u32)>,
    /// Which tile of --tiles to render, from 0 (top left), row by row.
    #[arg(long, value_name = "K", requires = "tiles")]
    tile_index: Option<u32>,
    /// The number of the first sample: render samples K .. K+spp of each
    /// pixel, to merge with renders of the other samples (glint merge).
    #[arg(long, value_name = "K")]
    sample_offset: Option<u32>,
    /// Output variables to gather, as extra EXR channels (and PNGs, see
    /// --aov-png): depth, normal, albedo, id (object), cost (BVH nodes and
    /// primitives tested), rays (by kind), evals (implicit-surface
    /// evaluations).
    #[arg(long, value_name = "NAME[,NAME…]", value_parser = glint::render::aov::parse_aovs)]
    aov: Option<std::vec::Vec<glint::render::Aov>>,
    /// Also write each AOV as a PNG beside the output (OUT.NAME.png): counts
    /// and depth as heat maps with a scale bar. Implied for a .png output.
    #[arg(long, requires = "aov")]
    aov_png: bool,
    /// Also write the statistics as JSON to this file.
    #[arg(long, value_name = "FILE")]
    stats_json: Option<PathBuf>,
    #[command(flatten)]
    mesh: MeshView,
    /// Print nothing but errors.
    #[arg(long, short)]
    quiet: bool,
}

fn parse_sampling(s: &str) -> Result<glint::settings::Sampling, String> {
    s.parse()
}

fn parse_seconds(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(x) if x > 0.0 && x <= 1e7 => Ok(x),
        _ => Err(format!("`{s}` is not a number of seconds above 0")),
    }
}

fn parse_clamp(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(x) if x > 0.0 && x.is_finite() => Ok(x),
        _ => Err(format!("`{s}` is not a positive number")),
    }
}

/// Renders a scene (or the built-in Whitted scene) as `args` say.
pub(crate) fn run(args: RenderArgs) -> Result<()> {
    let output = match &args.output {
        Some(o) => o.clone(),
        None => {
            let stem = args
                .scene
                .as_deref()
                .and_then(Path::file_stem)
                .map_or("whitted".into(), |s| s.to_string_lossy().into_owned());
            PathBuf::from(format!("{stem}.png"))
        }
    };
    if ImageFormat::from_path(&output).is_none() {
        bail!(
            "cannot write `{}`: unsupported file extension (use .png or .exr)",
            output.display()
        );
    }

    // Every output is created (as a temporary file beside it) before any
    // work, so that a path that cannot be written fails at once; all of them
    // are renamed into place together at the end, or none is.
    let stage = |path: &Path| -> Result<StagedFile> {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty())
            && !dir.is_dir()
        {
            bail!(
                "cannot write `{}`: folder `{}` does not exist",
                path.display(),
                dir.display()
            );
        }
        Ok(StagedFile::create(path)?)
    };
    let mut image_file = stage(&output)?;
    let mut stats_file = args.stats_json.as_deref().map(stage).transpose()?;
    let aovs = args.aov.clone().unwrap_or_default();
    let aov_pngs = !aovs.is_empty()
        && (args.aov_png || ImageFormat::from_path(&output) == Some(ImageFormat::Png));
    let mut aov_files = Vec::new();
    if aov_pngs {
        let stem = output.with_extension("");
        for &aov in &aovs {
            for (k, name) in render::heatmap::picture_names(aov).iter().enumerate() {
                let path = PathBuf::from(format!("{}.{name}.png", stem.display()));
                aov_files.push((aov, k, stage(&path)?));
            }
        }
    }

    let load_start = Instant::now();
    // `source` is what the scene came from, for the parts' fingerprint.
    let (
        SceneFile {
            scene,
            mut settings,
            seconds_mesh_load,
            seconds_mesh_build,
            warnings,
            desc,
        },
        scene_name,
        source,
    ) = load_scene(args.scene.as_deref(), args.mesh)?;
    // A scene file is fingerprinted by its description (not its text, so
    // comments and layout do not count), without its render settings: the
    // ones that change pixels are added below, after the command line's.
    let source = match desc {
        Some(mut d) => {
            d.settings = Default::default();
            serde_json::to_vec(&d).context("serialising the scene description")?
        }
        None => source,
    };
    if !args.quiet {
        for w in &warnings {
            eprintln!("warning: {w}");
        }
    }
    // Reading files and parsing vs. building BVHs (mesh BVHs are built while
    // the scene loads; the top-level BVH with the scene).
    let seconds_total = load_start.elapsed().as_secs_f64();
    let seconds_build = seconds_mesh_build;
    let seconds_load = (seconds_total - seconds_build).max(seconds_mesh_load);

    if let Some(w) = args.width {
        settings.width = w;
    }
    if let Some(h) = args.height {
        settings.height = h;
    }
    if let Some(s) = args.spp {
        settings.spp = s;
    }
    if let Some(d) = args.max_depth {
        settings.max_depth = d;
    }
    if let Some(w) = args.min_weight {
        settings.min_weight = w;
    }
    if let Some(t) = args.threads {
        settings.threads = t as usize;
    }
    if let Some(i) = args.integrator {
        settings.integrator = i;
    }
    if let Some(n) = args.light_samples {
        settings.light_samples = n;
    }
    if let Some(m) = args.sampling {
        settings.sampling = m;
    }
    if let Some(c) = args.clamp {
        settings.clamp = Some(c);
    }
    if args.time.is_some() && args.spp.is_none() {
        settings.spp = MAX_SPP;
    }
    settings.crop = args.crop;
    if let (Some((n, m)), Some(k)) = (args.tiles, args.tile_index) {
        let tile = Rect::tile(settings.width, settings.height, n, m, k);
        settings.crop = Some(tile.ok_or_else(|| {
            if k as u64 >= n as u64 * m as u64 {
                anyhow::anyhow!("--tile-index {k} is past the last of {n}×{m} tiles, {}", n as u64 * m as u64 - 1)
            } else {
                anyhow::anyhow!(
                    "a {}×{} frame cannot be cut into {n}×{m} tiles (more tiles than pixels across or down)",
                    settings.width,
                    settings.height
                )
            }
        })?);
    }
    if let Some(k) = args.sample_offset {
        settings.sample_offset = k;
    }
    settings
        .validate()
        .map_err(|e| anyhow::anyhow!("invalid render settings: {e}"))?;
    // The settings that change pixels (not the crop, the samples or the
    // threads, which parts differ in), the scene's source, and what it
    // built into.
    let fingerprint = render::parts::fingerprint(&[
        concat!("glint ", env!("CARGO_PKG_VERSION")).as_bytes(),
        &source,
        format!(
            "{}x{} {} depth {} weight {:08x}",
            settings.width,
            settings.height,
            settings.integrator,
            settings.max_depth,
            settings.min_weight.to_bits()
        )
        .as_bytes(),
        format!(
            "{:?} {:?} {:?} {:?}",
            scene.geometry_stats(),
            scene.camera,
            scene.lights,
            scene.materials
        )
        .as_bytes(),
    ]);

    let pixels = settings.rect().area();
    let bar = if !args.quiet && std::io::stderr().is_terminal() {
        let bar = ProgressBar::new(pixels);
        bar.set_style(
            ProgressStyle::with_template(
                "{spinner} rendering [{bar:40}] {percent:>3}%  {elapsed_precise} elapsed, ETA {eta}",
            )
            .expect("the template is a valid constant")
            .progress_chars("=> "),
        );
        bar
    } else {
        ProgressBar::hidden()
    };
    // An EXR keeps the exact sums, so that it can be merged with others.
    let options = render::FilmOptions {
        keep_sums: ImageFormat::from_path(&output) == Some(ImageFormat::Exr),
        aovs,
    };
    let (mut film, mut stats) = match args.time {
        Some(seconds) => {
            bar.set_length(pixels * settings.spp as u64);
            render::render_timed(&scene, &settings, &options, seconds, &|n| bar.inc(n))?
        }
        None => render::render_film(&scene, &settings, &options, &|n| bar.inc(n))?,
    };
    bar.finish_and_clear();
    stats.seconds_load = seconds_load;
    film.header.fingerprint = fingerprint;

    image_file.write_film(&film)?;
    let mut outputs = vec![image_file];
    let (w, h) = (film.image.width, film.image.height);
    for (aov, k, mut file) in aov_files {
        let picture = render::heatmap::aov_pictures(aov, &film.aov_pixels, w, h).swap_remove(k);
        let bytes = render::png_bytes(picture.width, picture.height, &picture.rgb)
            .map_err(|e| anyhow::anyhow!("cannot encode `{}`: {e}", file.path().display()))?;
        file.write_bytes(&bytes)?;
        outputs.push(file);
    }
    drop(film);
    let report = Report::new(stats, scene.geometry_stats(), seconds_build);
    if let Some(mut file) = stats_file.take() {
        let json = serde_json::to_string_pretty(&report).context("serialising statistics")?;
        file.write_bytes((json + "\n").as_bytes())?;
        outputs.push(file);
    }
    render::commit_all(outputs)?;
    if !args.quiet {
        eprintln!("{}", summary(&scene_name, &report));
        eprintln!("wrote {}", output.display());
    }
    Ok(())
}

/// Everything `--stats-json` writes: the render's figures, the geometry's,
/// and the process's peak memory.
#[derive(Serialize)]
struct Report {
    #[serde(flatten)]
    render: RenderStats,
    #[serde(flatten)]
    geometry: GeometryStats,
    seconds_build: f64,
    /// BVH bytes per distinct triangle (0 without meshes).
    bvh_bytes_per_triangle: f64,
    /// Mesh bytes (vertices, indices, BVH) per distinct triangle.
    bytes_per_triangle: f64,
    /// Peak resident memory of the process (Linux; null elsewhere).
    peak_rss_bytes: Option<u64>,
}

impl Report {
    fn new(render: RenderStats, geometry: GeometryStats, seconds_build: f64) -> Self {
        let per = |bytes: u64| {
            if geometry.triangles > 0 {
                bytes as f64 / geometry.triangles as f64
            } else {
                0.0
            }
        };
        Report {
            render,
            geometry,
            seconds_build,
            bvh_bytes_per_triangle: per(geometry.bvh_bytes),
            bytes_per_triangle: per(geometry.mesh_bytes),
            peak_rss_bytes: peak_rss_bytes(),
        }
    }
}

fn summary(scene_name: &str, report: &Report) -> String {
    let s = &report.render;
    let g = &report.geometry;
    let nan = if s.nan_pixels > 0 {
        format!(
            " {} pixels had NaN or infinite samples ({} samples, rendered as black).",
            group(s.nan_pixels),
            group(s.bad_samples)
        )
    } else {
        " No NaN or infinite samples.".to_string()
    };
    let implicit = if s.implicit_evaluations > 0 {
        format!(
            ", {} interval evaluations of implicit surfaces ({:.1} per ray, {:.1} per root search)",
            group(s.implicit_evaluations),
            s.implicit_evaluations_per_ray,
            s.implicit_evaluations_per_search
        )
    } else {
        String::new()
    };
    let meshes = if g.instances > 0 {
        format!(
            " {} in {}, {} ({} instanced); BVH {} nodes, {:.1} bytes per triangle, built in {:.3} s; {:.1} BVH nodes and {:.1} triangle tests per ray.",
            count(g.triangles, "triangle", "triangles"),
            count(g.meshes, "mesh", "meshes"),
            count(g.instances, "instance", "instances"),
            group(g.triangles_instanced),
            group(g.bvh_nodes),
            report.bvh_bytes_per_triangle,
            report.seconds_build,
            s.bvh_nodes_visited_per_ray,
            s.triangle_tests_per_ray
        )
    } else {
        String::new()
    };
    // Work that a limit cut short.
    let mut cut = String::new();
    if s.ray_trees_cut > 0 {
        cut += &format!(
            " {} camera samples reached the limit of {} secondary rays per sample, and their deepest rays were not traced (raise min_weight or lower max_depth).",
            group(s.ray_trees_cut),
            render::MAX_RAY_TREE
        );
    }
    if s.implicit_searches_cut > 0 {
        cut += &format!(
            " {} implicit-surface root searches gave up after {} interval evaluations and reported no hit (the formula's enclosures stay loose: simplify it or shrink its bounds).",
            group(s.implicit_searches_cut),
            glint::geometry::implicit::roots::MAX_SEARCH_EVALUATIONS
        );
    }
    let [x0, x1, y0, y1] = s.crop;
    let part = if [x0, x1, y0, y1] != [0, s.width, 0, s.height] {
        format!(" (pixels x {x0}..{x1}, y {y0}..{y1})")
    } else {
        String::new()
    };
    let samples = if s.sample_offset > 0 {
        format!(
            "samples {}..{}",
            s.sample_offset,
            s.sample_offset as u64 + s.spp as u64
        )
    } else {
        format!("{} spp", s.spp)
    };
    format!(
        "Rendered {scene_name} at {}×{}{part}, {samples}, {} integrator (max depth {}), {}. \
         Load {:.1} ms, render {:.1} ms. Rays: {} camera, {} shadow, {} reflection, {} refraction \
         ({} in all, {:.1} M rays/s, {:.2} M samples/s). {} intersection tests{implicit}.{nan}{cut}{meshes}",
        s.width,
        s.height,
        s.integrator,
        s.max_depth,
        count(s.threads as u64, "thread", "threads"),
        s.seconds_load * 1e3,
        s.seconds_render * 1e3,
        group(s.rays.camera),
        group(s.rays.shadow),
        group(s.rays.reflection),
        group(s.rays.refraction),
        group(s.rays_total),
        s.rays_per_second / 1e6,
        s.samples_per_second / 1e6,
        group(s.intersection_tests),
    )
}
