//! `glint explain`: the ray tree of one sample of one pixel, as text, JSON
//! and an SVG drawing.

use super::{MeshView, load_scene, parse_integrator, parse_weight};
use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use glint::render::{self, StagedFile};
use glint::settings::{IntegratorKind, MAX_DEPTH, MAX_IMAGE_SIDE, MAX_LIGHT_SAMPLES};
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct ExplainArgs {
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
pub(crate) enum SvgView {
    Side,
    Camera,
}

/// `12,34` → (12, 34).
pub(crate) fn parse_pixel(s: &str) -> Result<(u32, u32), String> {
    let err = || format!("expected a pixel X,Y of whole numbers from 0, found `{s}`");
    let (x, y) = s.split_once(',').ok_or_else(err)?;
    match (x.trim().parse::<u32>(), y.trim().parse::<u32>()) {
        (Ok(x), Ok(y)) => Ok((x, y)),
        _ => Err(err()),
    }
}

/// Prints (and writes) the ray tree `args` asks for.
pub(crate) fn run(args: ExplainArgs) -> Result<()> {
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
