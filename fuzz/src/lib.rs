//! What the fuzz targets share: a scratch folder for files that loaders
//! must read from disk, and a small render that checks every pixel.

use glint::render::render;
use glint::scene::{SceneFile, mesh_scene, meshio::Model};
use glint::settings::RenderSettings;
use std::path::PathBuf;

/// A folder of this process's own under the system's temporary folder
/// (libFuzzer may run several processes at once).
pub fn scratch() -> PathBuf {
    let dir = std::env::temp_dir().join(format!("glint-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("the temporary folder is writable");
    dir
}

/// Renders the scene at 6×4, one sample, recursion cut to 4, one thread,
/// and checks that no pixel is NaN or infinite.
pub fn render_small(file: &SceneFile) {
    let settings = RenderSettings {
        width: 6,
        height: 4,
        spp: 1,
        max_depth: file.settings.max_depth.min(4),
        threads: 1,
        ..file.settings.clone()
    };
    if let Ok((image, _)) = render(&file.scene, &settings, &|_| {}) {
        assert!(
            image.pixels.iter().all(|c| c.is_finite()),
            "a pixel is NaN or infinite"
        );
    }
}

/// Renders a loaded mesh file as `glint render MESH` would, but small.
pub fn render_model(model: &Model) {
    let up = glint::math::Vec3::Y;
    if let Ok(file) = mesh_scene(model, glint::math::Vec3::new(0.35, 0.3, 1.0), up) {
        render_small(&file);
    }
}
