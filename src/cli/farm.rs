//! `glint farm slurm`: the batch scripts of a Slurm job array that renders
//! a scene (or a sequence of frames) in parts, and the job that merges them.

use super::parse_grid;
use anyhow::{Context, Result, bail};
use clap::{Args, Subcommand};
use glint::render::{self, ImageFormat, StagedFile};
use glint::settings::MAX_SPP;
use std::path::{Path, PathBuf};

#[derive(Subcommand, Debug)]
pub enum FarmEngine {
    /// A Slurm job array (`sbatch SCRIPT`): one task per tile and sample
    /// chunk of each frame, then a merge job that depends on the array.
    Slurm(SlurmArgs),
}

#[derive(Args, Debug)]
pub struct SlurmArgs {
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

/// `path` made absolute (the tasks run in other folders, on other machines).
fn absolute(path: &Path) -> Result<PathBuf> {
    std::path::absolute(path).with_context(|| format!("cannot resolve `{}`", path.display()))
}

/// Writes the array and merge scripts `args` describe; submits nothing.
pub(crate) fn run_slurm(args: SlurmArgs) -> Result<()> {
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
