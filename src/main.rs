//! The `glint` command line: argument parsing, progress, writing files.
//! Each subcommand lives in its own module under `cli/`.

use clap::{Parser, Subcommand};
use std::path::PathBuf;

mod cli;

use cli::{explain::ExplainArgs, farm::FarmEngine, render::RenderArgs};

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
    View(cli::view::ViewArgs),
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

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Some(Command::Render(args)) => cli::render::run(args),
        #[cfg(feature = "view")]
        Some(Command::View(args)) => cli::view::run_view(args),
        Some(Command::Info { mesh }) => cli::info::run(&mesh),
        Some(Command::Explain(args)) => cli::explain::run(args),
        Some(Command::Farm {
            engine: FarmEngine::Slurm(args),
        }) => cli::farm::run_slurm(args),
        Some(Command::Merge {
            parts,
            output,
            quiet,
        }) => cli::merge::run(&parts, &output, quiet),
        None => cli::render::run(RenderArgs::default()),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
