//! Render farms: a frame, or a sequence of frames, cut into parts that an
//! existing scheduler runs as plain `glint render` commands, then merged.
//!
//! glint has no scheduler of its own. [`SlurmJob::scripts`] writes the two
//! batch scripts of a Slurm job array (Slurm being the scheduler of most
//! render and HPC clusters): the array renders one part per task, and a
//! merge job, submitted by the array's first task with
//! `--dependency=afterok:` on the array, assembles the parts with
//! `glint merge` once every task has succeeded. A task whose part exists
//! already skips it (glint writes files atomically, so a part that exists is
//! complete), so submitting the script again redoes only the missing parts.

use std::fmt::Write;
use std::path::{Path, PathBuf};

/// What a farm job renders: one scene, or frames numbered `first..=last`
/// whose scene files are named by a printf pattern (`shot.%04d.toml`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Frames {
    One(PathBuf),
    Sequence {
        pattern: String,
        first: u32,
        last: u32,
    },
}

impl Frames {
    pub fn count(&self) -> u64 {
        match self {
            Frames::One(_) => 1,
            Frames::Sequence { first, last, .. } => (*last - *first) as u64 + 1,
        }
    }
}

/// Checks a printf pattern for frame numbers: exactly one `%d` directive,
/// optionally zero-padded to a width (`%04d`), and `%%` for a literal `%`.
pub fn check_frame_pattern(pattern: &str) -> Result<(), String> {
    let mut directives = 0;
    let mut chars = pattern.chars().peekable();
    while let Some(c) = chars.next() {
        if c != '%' {
            continue;
        }
        if chars.peek() == Some(&'%') {
            chars.next();
            continue;
        }
        let mut spec = String::new();
        while let Some(&d) = chars.peek() {
            chars.next();
            if d == 'd' {
                break;
            }
            spec.push(d);
        }
        if !spec.chars().all(|d| d.is_ascii_digit()) || spec.len() > 2 {
            return Err(format!(
                "`{pattern}` has a `%` that is not `%d`, `%0Nd` or `%%`"
            ));
        }
        directives += 1;
    }
    if directives != 1 {
        return Err(format!(
            "`{pattern}` must hold exactly one frame number, as `%d` or `%04d`"
        ));
    }
    Ok(())
}

/// `pattern` with its frame number filled in, as the shell's printf would.
pub fn frame_name(pattern: &str, frame: u32) -> String {
    let mut out = String::new();
    let mut chars = pattern.chars().peekable();
    while let Some(c) = chars.next() {
        if c != '%' {
            out.push(c);
            continue;
        }
        if chars.peek() == Some(&'%') {
            chars.next();
            out.push('%');
            continue;
        }
        let mut spec = String::new();
        for d in chars.by_ref() {
            if d == 'd' {
                break;
            }
            spec.push(d);
        }
        let width: usize = spec.parse().unwrap_or(0);
        let _ = write!(out, "{frame:0width$}");
    }
    out
}

/// The sample ranges of `chunks` chunks of `spp` samples: chunk `c` takes
/// samples `⌊c·spp/chunks⌋ .. ⌊(c+1)·spp/chunks⌋`.
pub fn sample_chunks(spp: u32, chunks: u32) -> Vec<(u32, u32)> {
    (0..chunks as u64)
        .map(|c| {
            let start = c * spp as u64 / chunks as u64;
            let end = (c + 1) * spp as u64 / chunks as u64;
            (start as u32, (end - start) as u32)
        })
        .collect()
}

/// A Slurm job array that renders frames in parts and merges them.
#[derive(Clone, Debug)]
pub struct SlurmJob {
    /// A name for the job (Slurm's `--job-name` is `glint-NAME`).
    pub name: String,
    /// The glint binary the tasks run (an absolute path, on a file system
    /// the compute nodes share).
    pub glint: PathBuf,
    pub frames: Frames,
    /// Columns and rows of tiles each frame is cut into.
    pub tiles: (u32, u32),
    /// Samples per pixel of the whole render, and into how many sample
    /// ranges each tile's samples are cut; `None` keeps the scene's spp
    /// (with one chunk only).
    pub spp: Option<u32>,
    pub spp_chunks: u32,
    pub cpus_per_task: u32,
    /// Where the parts, the logs and the merge job's id go (absolute).
    pub parts: PathBuf,
    /// The merged image (for a sequence, a printf pattern like the scenes').
    pub output: PathBuf,
    /// Where the merge script is written (the array script calls it).
    pub merge_script: PathBuf,
    /// More `glint render` arguments, passed to every task.
    pub render_args: Vec<String>,
}

/// Slurm's default `MaxArraySize`: array indices must stay below it.
pub const SLURM_DEFAULT_MAX_ARRAY_SIZE: u64 = 1001;

/// A word quoted for bash: in single quotes, with each `'` as `'\''`.
pub fn shell_quote(s: &str) -> String {
    format!("'{}'", s.replace('\'', r"'\''"))
}

fn quote_path(p: &Path) -> String {
    shell_quote(&p.to_string_lossy())
}

impl SlurmJob {
    /// Tasks per frame: tiles times sample chunks.
    pub fn tasks_per_frame(&self) -> u64 {
        self.tiles.0 as u64 * self.tiles.1 as u64 * self.spp_chunks as u64
    }

    /// Tasks in the array.
    pub fn tasks(&self) -> u64 {
        self.tasks_per_frame() * self.frames.count()
    }

    /// Checks what the scripts cannot: a grid and chunk counts that make
    /// sense.
    pub fn check(&self) -> Result<(), String> {
        if self.tiles.0 == 0 || self.tiles.1 == 0 {
            return Err("the tile grid needs at least one tile".into());
        }
        if self.spp_chunks == 0 {
            return Err("--spp-chunks must be at least 1".into());
        }
        match self.spp {
            None if self.spp_chunks > 1 => {
                Err("--spp-chunks needs --spp: the samples to cut into chunks".into())
            }
            Some(spp) if self.spp_chunks > spp => Err(format!(
                "{} sample chunks of {spp} samples would leave some empty",
                self.spp_chunks
            )),
            _ => Ok(()),
        }?;
        if let Frames::Sequence {
            pattern,
            first,
            last,
        } = &self.frames
        {
            check_frame_pattern(pattern)?;
            check_frame_pattern(&self.output.to_string_lossy())
                .map_err(|e| format!("the output of a sequence of frames is a pattern too: {e}"))?;
            if first > last {
                return Err(format!(
                    "frames {first}-{last}: the first is after the last"
                ));
            }
        }
        Ok(())
    }

    /// The array script (submitted with `sbatch`) and the merge script
    /// (submitted by the array's task 0).
    pub fn scripts(&self) -> (String, String) {
        let q = quote_path;
        let (columns, rows) = self.tiles;
        let chunks = sample_chunks(self.spp.unwrap_or(1), self.spp_chunks);
        let mut s = String::new();
        let _ = writeln!(s, "#!/bin/bash");
        let _ = writeln!(
            s,
            "# glint render farm `{}`, written by `glint farm slurm`. Submit it with",
            self.name
        );
        let _ = writeln!(s, "#   sbatch THIS_SCRIPT");
        let _ = writeln!(
            s,
            "# Each of its {} tasks renders one part: a {columns}×{rows} tile grid, {} sample chunk{} per tile, {} frame{}.",
            self.tasks(),
            self.spp_chunks,
            if self.spp_chunks == 1 { "" } else { "s" },
            self.frames.count(),
            if self.frames.count() == 1 { "" } else { "s" }
        );
        let _ = writeln!(
            s,
            "# A task whose part exists skips it, so submitting again redoes only missing parts."
        );
        let _ = writeln!(
            s,
            "# Task 0 submits the merge job ({}), which runs once all tasks succeed.",
            self.merge_script.display()
        );
        let _ = writeln!(s, "#SBATCH --job-name=glint-{}", self.name);
        let _ = writeln!(s, "#SBATCH --array=0-{}", self.tasks() - 1);
        let _ = writeln!(s, "#SBATCH --cpus-per-task={}", self.cpus_per_task);
        let _ = writeln!(
            s,
            "#SBATCH --output={}/slurm-%A_%a.out",
            self.parts.display()
        );
        let _ = writeln!(s, "set -euo pipefail");
        let _ = writeln!(s, "glint={}", q(&self.glint));
        let _ = writeln!(s, "parts={}", q(&self.parts));
        let _ = writeln!(
            s,
            "task=\"${{SLURM_ARRAY_TASK_ID:?submit this script with sbatch}}\""
        );
        let _ = writeln!(
            s,
            "export RAYON_NUM_THREADS=\"${{SLURM_CPUS_PER_TASK:-1}}\""
        );
        let _ = writeln!(s, "if [ \"$task\" -eq 0 ]; then");
        let _ = writeln!(
            s,
            "  sbatch --parsable --dependency=afterok:\"$SLURM_ARRAY_JOB_ID\" {} > \"$parts/merge.jobid\"",
            q(&self.merge_script)
        );
        let _ = writeln!(
            s,
            "  echo \"merge job $(cat \"$parts/merge.jobid\") submitted\""
        );
        let _ = writeln!(s, "fi");
        let per_frame = self.tasks_per_frame();
        let _ = writeln!(s, "frame_task=$(( task % {per_frame} ))");
        let _ = writeln!(s, "tile=$(( frame_task / {} ))", self.spp_chunks);
        let _ = writeln!(s, "chunk=$(( frame_task % {} ))", self.spp_chunks);
        match &self.frames {
            Frames::One(scene) => {
                let _ = writeln!(s, "scene={}", q(scene));
                let _ = writeln!(
                    s,
                    "part=\"$parts/$(printf 't%04d-s%04d' \"$tile\" \"$chunk\").exr\""
                );
            }
            Frames::Sequence { pattern, first, .. } => {
                let _ = writeln!(s, "frame=$(( {first} + task / {per_frame} ))");
                let _ = writeln!(s, "scene=$(printf {} \"$frame\")", shell_quote(pattern));
                let _ = writeln!(
                    s,
                    "part=\"$parts/$(printf 'f%08d-t%04d-s%04d' \"$frame\" \"$tile\" \"$chunk\").exr\""
                );
            }
        }
        let mut samples = String::new();
        if self.spp.is_some() {
            let _ = writeln!(s, "case \"$chunk\" in");
            for (c, (start, count)) in chunks.iter().enumerate() {
                let _ = writeln!(s, "  {c}) offset={start}; spp={count} ;;");
            }
            let _ = writeln!(s, "esac");
            samples = " --spp \"$spp\" --sample-offset \"$offset\"".into();
        }
        let _ = writeln!(s, "if [ -s \"$part\" ]; then");
        let _ = writeln!(s, "  echo \"$part exists: skipping\"");
        let _ = writeln!(s, "  exit 0");
        let _ = writeln!(s, "fi");
        let extra: String = self
            .render_args
            .iter()
            .map(|a| format!(" {}", shell_quote(a)))
            .collect();
        let _ = writeln!(
            s,
            "\"$glint\" render \"$scene\" --tiles {columns}x{rows} --tile-index \"$tile\"{samples}{extra} -o \"$part\""
        );

        let mut m = String::new();
        let _ = writeln!(m, "#!/bin/bash");
        let _ = writeln!(
            m,
            "# Merges the parts of glint render farm `{}`; submitted by its array's task 0.",
            self.name
        );
        let _ = writeln!(m, "#SBATCH --job-name=glint-{}-merge", self.name);
        let _ = writeln!(m, "#SBATCH --cpus-per-task=1");
        let _ = writeln!(
            m,
            "#SBATCH --output={}/slurm-merge-%j.out",
            self.parts.display()
        );
        let _ = writeln!(m, "set -euo pipefail");
        let _ = writeln!(m, "glint={}", q(&self.glint));
        let _ = writeln!(m, "parts={}", q(&self.parts));
        match &self.frames {
            Frames::One(_) => {
                let _ = writeln!(
                    m,
                    "\"$glint\" merge \"$parts\"/t*-s*.exr -o {}",
                    q(&self.output)
                );
            }
            Frames::Sequence { first, last, .. } => {
                let _ = writeln!(m, "for frame in $(seq {first} {last}); do");
                let _ = writeln!(
                    m,
                    "  \"$glint\" merge \"$parts\"/\"$(printf 'f%08d' \"$frame\")\"-t*-s*.exr -o \"$(printf {} \"$frame\")\"",
                    q(&self.output)
                );
                let _ = writeln!(m, "done");
            }
        }
        (s, m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_patterns_are_printf_patterns() {
        assert_eq!(frame_name("shot.%04d.toml", 7), "shot.0007.toml");
        assert_eq!(frame_name("a%%b%dc", 12), "a%b12c");
        assert!(check_frame_pattern("shot.%04d.toml").is_ok());
        assert!(check_frame_pattern("shot.toml").is_err());
        assert!(check_frame_pattern("%d%d").is_err());
        assert!(check_frame_pattern("%s").is_err());
        assert!(check_frame_pattern("100%%-%d").is_ok());
    }

    #[test]
    fn sample_chunks_cover_the_samples() {
        assert_eq!(sample_chunks(8, 2), [(0, 4), (4, 4)]);
        assert_eq!(sample_chunks(10, 3), [(0, 3), (3, 3), (6, 4)]);
        assert_eq!(sample_chunks(1, 1), [(0, 1)]);
    }

    #[test]
    fn quoting_survives_quotes() {
        assert_eq!(shell_quote("a b"), "'a b'");
        assert_eq!(shell_quote("it's"), r"'it'\''s'");
    }

    #[test]
    fn the_array_has_one_task_per_part() {
        let job = SlurmJob {
            name: "w".into(),
            glint: "/bin/glint".into(),
            frames: Frames::Sequence {
                pattern: "s.%03d.toml".into(),
                first: 5,
                last: 7,
            },
            tiles: (2, 3),
            spp: Some(16),
            spp_chunks: 2,
            cpus_per_task: 4,
            parts: "/p".into(),
            output: "/o/s.%03d.png".into(),
            merge_script: "/p/merge.sh".into(),
            render_args: vec!["--width".into(), "64".into()],
        };
        assert!(job.check().is_ok());
        let (array, merge) = job.scripts();
        assert!(array.contains("#SBATCH --array=0-35\n"), "{array}");
        assert!(array.contains("#SBATCH --cpus-per-task=4\n"));
        assert!(array.contains("  1) offset=8; spp=8 ;;"));
        assert!(array.contains("--tiles 2x3 --tile-index \"$tile\" --spp \"$spp\" --sample-offset \"$offset\" '--width' '64' -o \"$part\""));
        assert!(array.contains("--dependency=afterok:\"$SLURM_ARRAY_JOB_ID\" '/p/merge.sh'"));
        assert!(merge.contains("for frame in $(seq 5 7); do"));
        let bad = SlurmJob {
            spp_chunks: 17,
            ..job.clone()
        };
        assert!(bad.check().unwrap_err().contains("17 sample chunks of 16"));
        let bad = SlurmJob {
            output: "/o/s.png".into(),
            ..job
        };
        assert!(bad.check().unwrap_err().contains("pattern too"));
    }
}
