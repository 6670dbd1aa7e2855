//! The `glint` command line: argument parsing, progress, writing files.

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand, ValueEnum};
use glint::render::{self, ImageFormat, RenderStats, StagedFile};
use glint::scene::{self, GeometryStats, SceneFile};
use glint::settings::{
    IntegratorKind, MAX_DEPTH, MAX_IMAGE_SIDE, MAX_LIGHT_SAMPLES, MAX_SPP, Rect,
};
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[cfg(feature = "view")]
mod view;

/// glint: a Whitted-style ray tracer.
///
/// With no arguments, renders the built-in Whitted scene to `whitted.png`.
#[derive(Parser, Debug)]
#[command(version, about)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Render a scene file (or the built-in Whitted scene) to PNG or EXR.
    Render(RenderArgs),
    /// Show a scene in a window, rendered progressively: drag to orbit
    /// (left button) or pan (other buttons), scroll to zoom, W/A/S/D to
    /// move, 1/2/3 for raycast/whitted/path, +/− for the depth, R to go
    /// back to the scene's camera, P to save a PNG, Esc to quit.
    #[cfg(feature = "view")]
    View(view::ViewArgs),
    /// Load a mesh file (PLY, OBJ, glTF) and print its counts, bounds, load
    /// and BVH build time and memory.
    Info {
        /// The mesh file.
        mesh: PathBuf,
    },
    /// Trace one sample of one pixel and print its ray tree: every ray, what
    /// it hit, what it carried and what it gave the pixel.
    Explain(ExplainArgs),
    /// Write the batch scripts that render a scene (or a sequence of frames)
    /// in parts on a cluster and merge them. Nothing is submitted.
    Farm {
        #[command(subcommand)]
        engine: FarmEngine,
    },
    /// Assemble EXR parts (crops and/or sample ranges written by `glint
    /// render … -o PART.exr`) into one image, exactly as one render would
    /// have made it.
    Merge {
        /// The parts (.exr files written by glint render).
        #[arg(required = true)]
        parts: Vec<PathBuf>,
        /// The merged image, .exr (mergeable again) or .png.
        #[arg(short, long)]
        output: PathBuf,
        /// Print nothing but errors.
        #[arg(long, short)]
        quiet: bool,
    },
}

#[derive(Args, Debug, Default)]
struct RenderArgs {
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

#[derive(Args, Debug)]
struct ExplainArgs {
    /// Scene file (TOML or JSON), or a mesh file; the built-in Whitted scene
    /// if omitted.
    scene: Option<PathBuf>,
    /// The pixel: X from the left, Y from the top, from 0 (as in the image
    /// the same settings render).
    #[arg(long, value_name = "X,Y", value_parser = parse_pixel)]
    pixel: (u32, u32),
    /// Which sample of the pixel (0 goes through its centre).
    #[arg(long, default_value_t = 0)]
    sample: u32,
    /// Also write the tree as JSON to this file.
    #[arg(long, value_name = "FILE")]
    json: Option<PathBuf>,
    /// Also draw the tree as an SVG, over a faint render of the scene.
    #[arg(long, value_name = "FILE")]
    svg: Option<PathBuf>,
    /// Where the SVG looks from: `side` (across the camera ray, far enough
    /// to see every ray, as the lecture draws ray trees) or `camera` (the
    /// scene's own view).
    #[arg(long, value_enum, default_value = "side")]
    svg_view: SvgView,
    /// Image width and height the pixel refers to (overrides the scene file).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=MAX_IMAGE_SIDE as i64))]
    width: Option<u32>,
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=MAX_IMAGE_SIDE as i64))]
    height: Option<u32>,
    /// Light transport algorithm: raycast, whitted or path.
    #[arg(long, value_parser = parse_integrator)]
    integrator: Option<IntegratorKind>,
    /// Maximum recursion depth: bounces after the camera ray (−1: no limit;
    /// path tracing then ends paths by Russian roulette).
    #[arg(long, allow_hyphen_values = true, value_parser = clap::value_parser!(i32).range(-1..=MAX_DEPTH as i64))]
    max_depth: Option<i32>,
    /// Shadow rays per shading point to the area lights (Whitted and ray
    /// casting; soft shadows).
    #[arg(long, value_parser = clap::value_parser!(u32).range(0..=MAX_LIGHT_SAMPLES as i64))]
    light_samples: Option<u32>,
    /// Rays whose weight falls below this are not traced (Whitted).
    #[arg(long, value_parser = parse_weight)]
    min_weight: Option<f32>,
    #[command(flatten)]
    mesh: MeshView,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum SvgView {
    Side,
    Camera,
}

/// `12,34` → (12, 34).
fn parse_pixel(s: &str) -> Result<(u32, u32), String> {
    let err = || format!("expected a pixel X,Y of whole numbers from 0, found `{s}`");
    let (x, y) = s.split_once(',').ok_or_else(err)?;
    match (x.trim().parse::<u32>(), y.trim().parse::<u32>()) {
        (Ok(x), Ok(y)) => Ok((x, y)),
        _ => Err(err()),
    }
}

#[derive(Subcommand, Debug)]
enum FarmEngine {
    /// A Slurm job array (`sbatch SCRIPT`): one task per tile and sample
    /// chunk of each frame, then a merge job that depends on the array.
    Slurm(SlurmArgs),
}

#[derive(Args, Debug)]
struct SlurmArgs {
    /// The scene file (or mesh file) to render.
    #[arg(required_unless_present = "frames", conflicts_with = "frames")]
    scene: Option<PathBuf>,
    /// Render a sequence of frames instead: scene files named by a printf
    /// pattern and a range of frame numbers, as `shot.%04d.toml 1-240`.
    #[arg(long, num_args = 2, value_names = ["PATTERN", "FIRST-LAST"])]
    frames: Option<Vec<String>>,
    /// Cut each frame into N×M tiles (N across, M down).
    #[arg(long, value_name = "NxM", value_parser = parse_grid, default_value = "1x1")]
    tiles: (u32, u32),
    /// Samples per pixel of the whole render (default: the scene's).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=MAX_SPP as i64))]
    spp: Option<u32>,
    /// Cut each tile's samples into this many sample ranges (needs --spp).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=MAX_SPP as i64))]
    spp_chunks: u32,
    /// CPUs of each task (its render threads).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=4096))]
    cpus_per_task: u32,
    /// The merged image, .png or .exr (for --frames, a pattern such as
    /// `shot.%04d.png`). Default: the scene's name with .png.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// The folder for parts and logs. Default: the output's name with
    /// `.parts`.
    #[arg(long)]
    parts: Option<PathBuf>,
    /// The array script to write. Default: the output's name with
    /// `.slurm.sh`; the merge script goes beside it as `.merge.sh`.
    #[arg(long)]
    script: Option<PathBuf>,
    /// More arguments for every `glint render`, after `--` (for example
    /// `-- --width 1920 --height 1080`).
    #[arg(last = true)]
    render_args: Vec<String>,
}

/// How a mesh file given as SCENE is framed (see `glint render --help`).
#[derive(Args, Debug, Clone, Copy)]
struct MeshView {
    /// For a mesh file as SCENE: direction from the mesh's centre to the eye.
    #[arg(long, value_parser = parse_vec3, default_value = "0.35,0.3,1", allow_hyphen_values = true)]
    view: glint::math::Vec3,
    /// For a mesh file as SCENE: the up axis (0,0,1 for z-up scans).
    #[arg(long, value_parser = parse_vec3, default_value = "0,1,0", allow_hyphen_values = true)]
    up: glint::math::Vec3,
}

impl Default for MeshView {
    fn default() -> Self {
        MeshView {
            view: glint::math::Vec3::new(0.35, 0.3, 1.0),
            up: glint::math::Vec3::Y,
        }
    }
}

fn parse_integrator(s: &str) -> Result<IntegratorKind, String> {
    s.parse()
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

/// Whether SCENE names a mesh file rather than a scene file.
fn is_mesh_file(path: &Path) -> bool {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    matches!(ext.as_deref(), Some("ply" | "obj" | "gltf" | "glb"))
}

fn parse_vec3(s: &str) -> Result<glint::math::Vec3, String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("expected three numbers x,y,z, found `{s}`"))?;
    match v.as_slice() {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(glint::math::Vec3::new(*x, *y, *z)),
        _ => Err(format!("expected three numbers x,y,z, found `{s}`")),
    }
}

/// `4x4` → (4, 4): columns across, rows down.
fn parse_grid(s: &str) -> Result<(u32, u32), String> {
    let err = || format!("expected a grid NxM of whole numbers from 1, found `{s}`");
    let (n, m) = s.split_once(['x', 'X']).ok_or_else(err)?;
    match (n.trim().parse::<u32>(), m.trim().parse::<u32>()) {
        (Ok(n), Ok(m)) if n > 0 && m > 0 => Ok((n, m)),
        _ => Err(err()),
    }
}

fn parse_weight(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(x) if (0.0..=1.0).contains(&x) => Ok(x),
        _ => Err(format!("expected a number from 0 to 1, found `{s}`")),
    }
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Some(Command::Render(args)) => run_render(args),
        #[cfg(feature = "view")]
        Some(Command::View(args)) => view::run_view(args),
        Some(Command::Info { mesh }) => run_info(&mesh),
        Some(Command::Explain(args)) => run_explain(args),
        Some(Command::Farm {
            engine: FarmEngine::Slurm(args),
        }) => run_farm_slurm(args),
        Some(Command::Merge {
            parts,
            output,
            quiet,
        }) => run_merge(&parts, &output, quiet),
        None => run_render(RenderArgs::default()),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

/// The scene to render, explain or view: a scene file, a mesh file framed
/// by a default camera and light (seen from `mesh.view`, with `mesh.up` up), or the
/// built-in Whitted scene; with a name for messages and the bytes that
/// fingerprint where it came from.
fn load_scene(scene: Option<&Path>, mesh: MeshView) -> Result<(SceneFile, String, Vec<u8>)> {
    let MeshView { view, up } = mesh;
    Ok(match scene {
        Some(path) if is_mesh_file(path) => {
            let model = scene::meshio::load_mesh_file(path)?;
            let file = scene::mesh_scene(&model, view, up)
                .with_context(|| format!("cannot show `{}`", path.display()))?;
            let source = format!("mesh {:?} view {} up {}", path.file_name(), view, up);
            (file, path.display().to_string(), source.into_bytes())
        }
        Some(path) => (
            scene::load_scene_file(path)?,
            path.display().to_string(),
            Vec::new(),
        ),
        None => (
            scene::parse_scene(
                scene::BUILTIN_WHITTED,
                Path::new("scenes/whitted.toml (built in)"),
            )?,
            "the built-in Whitted scene".to_string(),
            Vec::new(),
        ),
    })
}

fn run_render(args: RenderArgs) -> Result<()> {
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

/// `VmHWM` of /proc/self/status: the peak resident set size.
fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

fn run_explain(args: ExplainArgs) -> Result<()> {
    use glint::render::explain::Explained;
    let (file, _, _) = load_scene(args.scene.as_deref(), args.mesh)?;
    let mut settings = file.settings.clone();
    if let Some(w) = args.width {
        settings.width = w;
    }
    if let Some(h) = args.height {
        settings.height = h;
    }
    if let Some(d) = args.max_depth {
        settings.max_depth = d;
    }
    if let Some(w) = args.min_weight {
        settings.min_weight = w;
    }
    if let Some(i) = args.integrator {
        settings.integrator = i;
    }
    if let Some(n) = args.light_samples {
        settings.light_samples = n;
    }
    let mut json_file = args.json.as_deref().map(StagedFile::create).transpose()?;
    let mut svg_file = args.svg.as_deref().map(StagedFile::create).transpose()?;
    let (x, y) = args.pixel;
    let e: Explained = render::explain::explain(&file.scene, &settings, x, y, args.sample)
        .map_err(|m| anyhow::anyhow!("{m}"))?;
    // Names: materials from the description where there is one.
    let material_name = |m: u32| -> String {
        match (&file.desc, m) {
            (_, 0) => "the default grey".into(),
            (Some(d), m) if (m as usize) <= d.materials.len() => {
                format!("`{}`", d.materials[m as usize - 1].name)
            }
            _ => format!("{m} (from the mesh file)"),
        }
    };
    print!("{}", e.text(material_name));
    let mut outputs = Vec::new();
    if let Some(mut f) = json_file.take() {
        let json = serde_json::to_string_pretty(&e).context("serialising the ray tree")?;
        f.write_bytes((json + "\n").as_bytes())?;
        outputs.push(f);
    }
    if let Some(mut f) = svg_file.take() {
        let view = match args.svg_view {
            SvgView::Camera => file.scene.camera.clone(),
            SvgView::Side => render::explain::side_camera(&e, &file.scene)
                .context("cannot place a camera beside the ray tree")?,
        };
        // The faint background: the frame, seen from there, at one sample
        // per pixel.
        let quick = glint::settings::RenderSettings {
            spp: 1,
            sample_offset: 0,
            crop: None,
            ..settings.clone()
        };
        let mut seen = file.scene.clone();
        seen.camera = view.clone();
        let (image, _) = render::render(&seen, &quick, &|_| {})?;
        drop(seen);
        let png = render::png_bytes(image.width, image.height, &image.to_srgb8())
            .map_err(|m| anyhow::anyhow!("cannot encode the background: {m}"))?;
        let svg = render::explain::svg(&e, &file.scene, &view, &settings, Some(&png));
        f.write_bytes(svg.as_bytes())?;
        outputs.push(f);
    }
    render::commit_all(outputs)?;
    Ok(())
}

/// `path` made absolute (the tasks run in other folders, on other machines).
fn absolute(path: &Path) -> Result<PathBuf> {
    std::path::absolute(path).with_context(|| format!("cannot resolve `{}`", path.display()))
}

fn run_farm_slurm(args: SlurmArgs) -> Result<()> {
    use glint::farm::{Frames, SlurmJob, check_frame_pattern, frame_name};
    let frames = match (&args.scene, &args.frames) {
        (Some(scene), _) => {
            if !scene.is_file() {
                bail!("scene `{}` does not exist", scene.display());
            }
            Frames::One(absolute(scene)?)
        }
        (None, Some(f)) => {
            let (pattern, range) = (&f[0], &f[1]);
            check_frame_pattern(pattern).map_err(|e| anyhow::anyhow!("--frames: {e}"))?;
            let numbers = range.split_once('-').and_then(|(a, b)| {
                Some((a.trim().parse::<u32>().ok()?, b.trim().parse::<u32>().ok()?))
            });
            let Some((first, last)) = numbers else {
                bail!("--frames: expected a range of frame numbers FIRST-LAST, found `{range}`");
            };
            let pattern = absolute(Path::new(pattern))?.to_string_lossy().into_owned();
            if first <= last {
                for frame in first..=last {
                    let name = frame_name(&pattern, frame);
                    if !Path::new(&name).is_file() {
                        bail!("--frames: frame {frame}'s scene `{name}` does not exist");
                    }
                }
            }
            Frames::Sequence {
                pattern,
                first,
                last,
            }
        }
        (None, None) => bail!("give a scene or --frames"),
    };
    for a in &args.render_args {
        if matches!(
            a.as_str(),
            "-o" | "--output" | "--crop" | "--tiles" | "--tile-index" | "--spp" | "--sample-offset"
        ) || a.starts_with("--output=")
            || a.starts_with("--spp=")
        {
            bail!(
                "`{a}` after `--` would clash with the parts the farm sets; give it to glint farm instead (--tiles, --spp, -o)"
            );
        }
    }
    // Default names: from the scene's name (`shot.%04d.toml` → `shot`).
    let (stem, default_output) = match &frames {
        Frames::One(scene) => {
            let stem = scene
                .file_stem()
                .map_or("render".into(), |s| s.to_string_lossy().into_owned());
            (stem.clone(), format!("{stem}.png"))
        }
        Frames::Sequence { pattern, .. } => {
            let file = Path::new(pattern)
                .file_name()
                .map_or("frame.%04d".into(), |s| s.to_string_lossy().into_owned());
            let stem = file
                .split('%')
                .next()
                .unwrap_or("")
                .trim_end_matches(['.', '_', '-']);
            let stem = if stem.is_empty() { "frames" } else { stem }.to_string();
            let output = Path::new(&file)
                .with_extension("png")
                .to_string_lossy()
                .into_owned();
            (stem, output)
        }
    };
    let output = absolute(&args.output.clone().unwrap_or_else(|| default_output.into()))?;
    if ImageFormat::from_path(&output).is_none() {
        bail!(
            "cannot write `{}`: unsupported file extension (use .png or .exr)",
            output.display()
        );
    }
    let folder = output.parent().map(Path::to_path_buf).unwrap_or_default();
    let parts = match &args.parts {
        Some(p) => absolute(p)?,
        None => folder.join(format!("{stem}.parts")),
    };
    let script = match &args.script {
        Some(p) => absolute(p)?,
        None => folder.join(format!("{stem}.slurm.sh")),
    };
    let merge_script = script.with_extension("").with_extension("merge.sh");
    let name: String = stem
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    let job = SlurmJob {
        name,
        glint: std::env::current_exe().context("cannot find the glint binary's path")?,
        frames,
        tiles: args.tiles,
        spp: args.spp,
        spp_chunks: args.spp_chunks,
        cpus_per_task: args.cpus_per_task,
        parts: parts.clone(),
        output,
        merge_script: merge_script.clone(),
        render_args: args.render_args,
    };
    job.check().map_err(|e| anyhow::anyhow!(e))?;
    std::fs::create_dir_all(&parts)
        .with_context(|| format!("cannot create the parts folder `{}`", parts.display()))?;
    let (array, merge) = job.scripts();
    let mut files = Vec::new();
    for (path, text) in [(&script, array), (&merge_script, merge)] {
        let mut f = StagedFile::create(path)?;
        f.write_bytes(text.as_bytes())?;
        files.push(f);
    }
    render::commit_all(files)?;
    for path in [&script, &merge_script] {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o755))
            .with_context(|| format!("cannot make `{}` executable", path.display()))?;
    }
    if job.tasks() > glint::farm::SLURM_DEFAULT_MAX_ARRAY_SIZE {
        eprintln!(
            "warning: the array has {} tasks; Slurm's default MaxArraySize allows {} (ask for it to be raised, or use fewer tiles or chunks)",
            job.tasks(),
            glint::farm::SLURM_DEFAULT_MAX_ARRAY_SIZE
        );
    }
    eprintln!(
        "{} tasks; parts go to {}, the merge script is {}. Submit with: sbatch {}",
        job.tasks(),
        parts.display(),
        merge_script.display(),
        script.display()
    );
    println!("{}", script.display());
    Ok(())
}

fn run_merge(parts: &[PathBuf], output: &Path, quiet: bool) -> Result<()> {
    if ImageFormat::from_path(output).is_none() {
        bail!(
            "cannot write `{}`: unsupported file extension (use .png or .exr)",
            output.display()
        );
    }
    let mut out = StagedFile::create(output)?;
    let mut headers = Vec::with_capacity(parts.len());
    for p in parts {
        headers.push((p.display().to_string(), render::read_film_header(p)?));
    }
    let header = render::parts::plan_merge(&headers)?;
    let mut merger = render::parts::Merger::new(header.clone())
        .context("not enough memory for the merged image")?;
    for (p, (name, planned)) in parts.iter().zip(&headers) {
        let film = render::read_film_exr(p)?;
        if &film.header != planned {
            bail!("`{name}` changed while it was being merged");
        }
        merger.add(&film);
    }
    let film = merger.finish();
    out.write_film(&film)?;
    out.commit()?;
    if !quiet {
        eprintln!(
            "Merged {} into {}: {}×{} frame, pixels {}, samples {}.",
            count(parts.len() as u64, "part", "parts"),
            output.display(),
            header.width,
            header.height,
            header.rect,
            header.samples
        );
    }
    Ok(())
}

fn run_info(path: &Path) -> Result<()> {
    let model = scene::meshio::load_mesh_file(path)?;
    for w in &model.warnings {
        eprintln!("warning: {w}");
    }
    let mut bounds = glint::math::Aabb::EMPTY;
    let (mut vertices, mut triangles, mut nodes, mut bvh_bytes, mut bytes) = (0, 0, 0, 0, 0);
    let mut seen = std::collections::HashSet::new();
    // Distinct meshes large enough for leaf blocks, and those left without.
    let (mut large, mut gathering) = (0u64, 0u64);
    for part in &model.parts {
        let instance =
            glint::geometry::MeshInstance::new(part.mesh.clone(), part.transform.as_ref());
        bounds = bounds.union(&instance.bounds());
        if seen.insert(std::sync::Arc::as_ptr(&part.mesh)) {
            if let Some(kept) = part.mesh.leaf_blocks() {
                large += 1;
                gathering += u64::from(!kept);
            }
            vertices += part.mesh.positions.len();
            triangles += part.mesh.triangles.len();
            nodes += part.mesh.bvh.nodes.len();
            bvh_bytes += part.mesh.bvh.bytes();
            bytes += part.mesh.bytes();
        }
    }
    let per = |b: usize| b as f64 / triangles.max(1) as f64;
    println!("{}", path.display());
    println!(
        "  parts        {} ({})",
        model.parts.len(),
        count(seen.len() as u64, "distinct mesh", "distinct meshes")
    );
    println!("  vertices     {}", group(vertices as u64));
    println!("  triangles    {}", group(triangles as u64));
    println!(
        "  bounds       {:?} .. {:?}",
        bounds.min.to_array(),
        bounds.max.to_array()
    );
    println!(
        "  load         {:.3} s ({:.1} M triangles/s)",
        model.seconds_load,
        triangles as f64 / model.seconds_load.max(1e-9) / 1e6
    );
    println!(
        "  BVH build    {:.3} s ({:.1} M triangles/s), {} nodes",
        model.seconds_build,
        triangles as f64 / model.seconds_build.max(1e-9) / 1e6,
        group(nodes as u64)
    );
    println!(
        "  memory       {:.1} MB in all, {:.1} bytes per triangle ({:.1} of them BVH)",
        bytes as f64 / 1e6,
        per(bytes),
        per(bvh_bytes)
    );
    if gathering > 0 {
        println!(
            "  leaf blocks  left out of {gathering} of {} for lack of memory: their leaf tests gather vertices (slower rays)",
            count(large, "large mesh", "large meshes")
        );
    } else if large > 0 {
        println!(
            "  leaf blocks  kept ({}: each leaf's triangles stored as the test reads them)",
            count(large, "large mesh", "large meshes")
        );
    }
    if let Some(peak) = peak_rss_bytes() {
        println!("  peak RSS     {:.1} MB", peak as f64 / 1e6);
    }
    if let Some(c) = &model.camera {
        println!(
            "  camera       at {:?} looking at {:?}, fov {:.1}°",
            c.position.to_array(),
            c.look_at.to_array(),
            c.fov_y_deg
        );
    }
    Ok(())
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

/// `n` and the noun in the right number: `1 thread`, `2 threads`,
/// `1,024 meshes`.
fn count(n: u64, one: &str, many: &str) -> String {
    format!("{} {}", group(n), if n == 1 { one } else { many })
}

/// `1234567` → `1,234,567`.
fn group(n: u64) -> String {
    let digits = n.to_string();
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}
