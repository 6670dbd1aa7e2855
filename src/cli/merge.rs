//! `glint merge`: EXR parts (crops and sample ranges) assembled into the
//! image one render would have made.

use super::count;
use anyhow::{Context, Result, bail};
use glint::render::{self, ImageFormat, StagedFile};
use std::path::{Path, PathBuf};

/// Merges `parts` into `output`.
pub(crate) fn run(parts: &[PathBuf], output: &Path, quiet: bool) -> Result<()> {
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
