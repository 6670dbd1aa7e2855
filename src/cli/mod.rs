//! The subcommands of `glint` (one module each) and what they share:
//! loading the scene to show, the framing of a mesh file, argument parsers,
//! and number formatting.

use anyhow::{Context, Result};
use clap::Args;
use glint::scene::{self, SceneFile};
use glint::settings::IntegratorKind;
use std::path::Path;

pub mod explain;
pub mod farm;
pub mod info;
pub mod merge;
pub mod render;
#[cfg(feature = "view")]
pub mod view;

/// How a mesh file given as SCENE is framed (see `glint render --help`).
#[derive(Args, Debug, Clone, Copy)]
pub(crate) struct MeshView {
    /// For a mesh file as SCENE: direction from the mesh's centre to the eye.
    #[arg(long, value_parser = parse_vec3, default_value = "0.35,0.3,1", allow_hyphen_values = true)]
    pub(crate) view: glint::math::Vec3,
    /// For a mesh file as SCENE: the up axis (0,0,1 for z-up scans).
    #[arg(long, value_parser = parse_vec3, default_value = "0,1,0", allow_hyphen_values = true)]
    pub(crate) up: glint::math::Vec3,
}

impl Default for MeshView {
    fn default() -> Self {
        MeshView {
            view: glint::math::Vec3::new(0.35, 0.3, 1.0),
            up: glint::math::Vec3::Y,
        }
    }
}

pub(crate) fn parse_integrator(s: &str) -> Result<IntegratorKind, String> {
    s.parse()
}

/// Whether SCENE names a mesh file rather than a scene file.
pub(crate) fn is_mesh_file(path: &Path) -> bool {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    matches!(ext.as_deref(), Some("ply" | "obj" | "gltf" | "glb"))
}

pub(crate) fn parse_vec3(s: &str) -> Result<glint::math::Vec3, String> {
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
pub(crate) fn parse_grid(s: &str) -> Result<(u32, u32), String> {
    let err = || format!("expected a grid NxM of whole numbers from 1, found `{s}`");
    let (n, m) = s.split_once(['x', 'X']).ok_or_else(err)?;
    match (n.trim().parse::<u32>(), m.trim().parse::<u32>()) {
        (Ok(n), Ok(m)) if n > 0 && m > 0 => Ok((n, m)),
        _ => Err(err()),
    }
}

pub(crate) fn parse_weight(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(x) if (0.0..=1.0).contains(&x) => Ok(x),
        _ => Err(format!("expected a number from 0 to 1, found `{s}`")),
    }
}

/// The scene to render, explain or view: a scene file, a mesh file framed
/// by a default camera and light (seen from `mesh.view`, with `mesh.up` up), or the
/// built-in Whitted scene; with a name for messages and the bytes that
/// fingerprint where it came from.
pub(crate) fn load_scene(
    scene: Option<&Path>,
    mesh: MeshView,
) -> Result<(SceneFile, String, Vec<u8>)> {
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

/// `VmHWM` of /proc/self/status: the peak resident set size.
pub(crate) fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// `n` and the noun in the right number: `1 thread`, `2 threads`,
/// `1,024 meshes`.
pub(crate) fn count(n: u64, one: &str, many: &str) -> String {
    format!("{} {}", group(n), if n == 1 { one } else { many })
}

/// `1234567` → `1,234,567`.
pub(crate) fn group(n: u64) -> String {
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
