//! Reading meshes from files: PLY (our own fast reader), OBJ + MTL (`tobj`)
//! and glTF 2.0 (`gltf`). Every error names the file and the bad element.

mod gltf;
mod obj;
pub use obj::smooth_normals;
pub mod ply;

use crate::geometry::{Mesh, MeshDataError};
use crate::math::Transform;
use crate::scene::Material;
use crate::scene::files::FileError;
use glam::{Vec2, Vec3};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

/// A mesh file could not be read: the file, the element (e.g. `face 17`,
/// `header line 3`, `line 12`, `mesh 0 primitive 1`) and what is wrong.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{}: {element}: {message}", path.display())]
pub struct MeshError {
    pub path: PathBuf,
    pub element: String,
    pub message: String,
}

impl MeshError {
    pub fn new(path: &Path, element: &str, message: impl Into<String>) -> Self {
        MeshError {
            path: path.to_path_buf(),
            element: element.to_string(),
            message: message.into(),
        }
    }

    /// The mesh file itself could not be read.
    pub fn file(path: &Path, e: &FileError) -> Self {
        MeshError::new(path, "file", e.reason())
    }
}

/// Mesh arrays as read from a file, before the BVH is built.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RawMesh {
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    pub normals: Vec<Vec3>,
    pub uvs: Vec<Vec2>,
    /// Polygons of more than 3 vertices split into fans: (first triangle,
    /// face in the file, number of triangles), to name faces in errors.
    pub polygons: Vec<(u32, u32, u32)>,
}

impl RawMesh {
    /// The face of the file that triangle `t` came from.
    pub fn face_of_triangle(&self, t: usize) -> usize {
        let t = t as u32;
        let k = self.polygons.partition_point(|p| p.0 <= t);
        if k == 0 {
            return t as usize;
        }
        let (first, face, count) = self.polygons[k - 1];
        if t < first + count {
            face as usize
        } else {
            // Every polygon up to here added `count − 1` triangles beyond its face.
            let extra: u32 = self.polygons[..k].iter().map(|p| p.2 - 1).sum();
            (t - extra) as usize
        }
    }

    /// Builds the mesh and its BVH; first checks that the build fits in the
    /// memory the process may still use (see [`BUILD_BYTES_PER_TRIANGLE`]).
    pub fn build(self, path: &Path) -> Result<Mesh, MeshError> {
        let needed = self.triangles.len() as u64 * BUILD_BYTES_PER_TRIANGLE;
        if let Some(available) = crate::render::memory::available_bytes()
            && needed > available
        {
            return Err(MeshError::new(
                path,
                "file",
                format!(
                    "building the BVH of its {} triangles needs about {:.2} GB, but only {:.2} GB of memory is available",
                    self.triangles.len(),
                    needed as f64 / 1e9,
                    available as f64 / 1e9
                ),
            ));
        }
        // Moved, not copied; only the polygon table is kept to name faces.
        let polygons = RawMesh {
            polygons: self.polygons,
            ..RawMesh::default()
        };
        let face = |t: usize| format!("face {}", polygons.face_of_triangle(t));
        Mesh::new(self.positions, self.triangles, self.normals, self.uvs).map_err(|e| match e {
            MeshDataError::IndexOutOfRange { triangle, .. } => {
                MeshError::new(path, &face(triangle), e.to_string())
            }
            MeshDataError::NonFinite { vertex } => MeshError::new(
                path,
                &format!("vertex {vertex}"),
                "has a non-finite coordinate",
            ),
            other => MeshError::new(path, "mesh", other.to_string()),
        })
    }
}

/// Memory a mesh takes at the peak of its BVH build, per triangle, beyond
/// the arrays read from the file: primitive references (32 bytes), the binary
/// nodes (about 32), the reordered triangles (12) and the wide BVH, rounded
/// up (the 25.6M-triangle test mesh peaked at 93 bytes per triangle with its
/// file's data). The leaf blocks of meshes (about 50 bytes per triangle)
/// come after the binary nodes are freed, and are left out when they would
/// take more than half the memory left.
pub const BUILD_BYTES_PER_TRIANGLE: u64 = 100;

/// One mesh of a model, with its placement and material (if the file gives one).
#[derive(Clone, Debug)]
pub struct ModelPart {
    pub name: String,
    pub mesh: Arc<Mesh>,
    pub transform: Option<Transform>,
    pub material: Option<Material>,
}

/// A camera found in a file (glTF).
#[derive(Clone, Debug, PartialEq)]
pub struct FileCamera {
    pub position: Vec3,
    pub look_at: Vec3,
    pub up: Vec3,
    pub fov_y_deg: f32,
}

/// The meshes of a file, ready to render.
#[derive(Clone, Debug, Default)]
pub struct Model {
    pub parts: Vec<ModelPart>,
    pub camera: Option<FileCamera>,
    pub seconds_load: f64,
    pub seconds_build: f64,
    /// What was read in a way the file may not have meant (a missing
    /// material library, say), one message each, naming the file.
    pub warnings: Vec<String>,
}

impl Model {
    /// Triangles over all parts (instances counted once per use).
    pub fn triangles(&self) -> usize {
        self.parts.iter().map(|p| p.mesh.triangles.len()).sum()
    }
}

/// Reads a mesh file (`.ply`, `.obj`, `.gltf`, `.glb`) and builds its BVHs.
pub fn load_mesh_file(path: &Path) -> Result<Model, MeshError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    let start = Instant::now();
    let mut model = match ext.as_str() {
        "ply" => {
            let raw = ply::read(path)?;
            let seconds_load = start.elapsed().as_secs_f64();
            let build = Instant::now();
            let mesh = Arc::new(raw.build(path)?);
            Ok(Model {
                parts: vec![ModelPart {
                    name: path
                        .file_stem()
                        .map(|s| s.to_string_lossy().into_owned())
                        .unwrap_or_default(),
                    mesh,
                    transform: None,
                    material: None,
                }],
                camera: None,
                seconds_load,
                seconds_build: build.elapsed().as_secs_f64(),
                warnings: Vec::new(),
            })
        }
        "obj" => obj::read(path),
        "gltf" | "glb" => gltf::read(path),
        _ => Err(MeshError::new(
            path,
            "file",
            format!("unknown mesh format `.{ext}`; expected .ply, .obj, .gltf or .glb"),
        )),
    }?;
    // A file without triangles would render nothing and frame no camera.
    if model.triangles() == 0 {
        return Err(MeshError::new(path, "file", "holds no triangles"));
    }
    // Meshes at scales where triangles may be missed: the first few named,
    // the rest counted (a glTF file may hold thousands of parts).
    const NAMED: usize = 3;
    let problems: Vec<String> = model
        .parts
        .iter()
        .filter_map(|p| {
            let problem = p.mesh.scale_problem()?;
            Some(format!("{}: mesh `{}`: {problem}", path.display(), p.name))
        })
        .collect();
    let more = problems.len().saturating_sub(NAMED);
    model.warnings.extend(problems.into_iter().take(NAMED));
    if more > 0 {
        model.warnings.push(format!(
            "{}: {more} more meshes are outside the checked scales",
            path.display()
        ));
    }
    Ok(model)
}
