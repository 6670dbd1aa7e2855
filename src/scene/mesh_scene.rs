//! A scene around a mesh file, for `glint render model.ply`: a camera that
//! frames the whole model, a point light and a sky-grey fill, a white
//! Lambertian material where the file gives none, and ray casting at
//! 1920×1080 — one camera ray and one shadow ray per pixel.

use super::meshio::Model;
use super::{Camera, Light, Material, Object, Scene, SceneFile};
use crate::geometry::{MeshInstance, Shape};
use crate::math::{Aabb, Color, Vec3};
use crate::settings::{IntegratorKind, RenderSettings};

/// Why a mesh could not be framed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MeshSceneError {
    #[error("--view and --up must be non-zero and not parallel")]
    View,
    #[error("the model's bounds {min:?} .. {max:?} are too large to frame in f32")]
    TooLarge { min: [f32; 3], max: [f32; 3] },
    #[error("the file's camera is degenerate")]
    FileCamera,
}

/// The background of a mesh shown on its own: a light grey-blue sky.
const SKY: Color = Color::new(0.42, 0.5, 0.62);
/// Ambient light `A` of the scene around a mesh, so that what the point
/// light does not reach is dark grey rather than black.
const AMBIENT_FILL: f32 = 0.15;

/// Builds the scene. `view` points from the mesh's centre towards the eye,
/// `up` is the up axis (z for z-up scans).
///
/// The camera frames the whole model: it looks at the centre `c` of the
/// bounding box, from `c + vieŵ·D`, with a vertical field of view of 40° and
/// `D = 1.1·R / sin 20°`, where `R` is the radius of the sphere around the
/// box, so that the model fits in the frame whichever way it turns (with a
/// margin of a tenth). A directional light of unit irradiance from above,
/// left of and behind the eye (from `−0.5 right + 0.8 up + 0.33 back`) casts
/// the shadows — the same at every scale, where a point light's intensity
/// would have to grow as `R²` and overflow f32 for models past 1e18; a
/// sky-grey background and an ambient fill of 0.15 keep the parts it does
/// not reach readable against the background. A camera in the file (glTF) is
/// used instead when there is one.
pub fn mesh_scene(model: &Model, view: Vec3, up: Vec3) -> Result<SceneFile, MeshSceneError> {
    let mut materials = vec![Material::default_diffuse()];
    let mut objects = Vec::new();
    let mut bounds = Aabb::EMPTY;
    for part in &model.parts {
        let instance = MeshInstance::new(part.mesh.clone(), part.transform.as_ref());
        bounds = bounds.union(&instance.bounds());
        let material = match &part.material {
            Some(m) => {
                materials.push(m.clone());
                materials.len() as u32 - 1
            }
            None => 0,
        };
        objects.push(Object {
            shape: Shape::Mesh(instance),
            material,
        });
    }
    let c = (bounds.min + bounds.max) * 0.5;
    // Half the diagonal, in f64: its square overflows f32 for boxes past 1e19.
    let r = ((bounds.max - bounds.min).as_dvec3().length() * 0.5) as f32;
    // A single point or a flat model still needs a distance to look from.
    let r = if r > 0.0 {
        r
    } else {
        c.abs().max_element().max(1.0)
    };
    let back = view.try_normalize().ok_or(MeshSceneError::View)?;
    let right = up.cross(back).try_normalize().ok_or(MeshSceneError::View)?;
    let up = back.cross(right);
    let eye = c + back * (1.1 * r / 20f32.to_radians().sin());
    let too_large = || MeshSceneError::TooLarge {
        min: bounds.min.to_array(),
        max: bounds.max.to_array(),
    };
    if !(eye.is_finite() && c.is_finite() && r.is_finite()) {
        return Err(too_large());
    }
    let camera = match &model.camera {
        Some(fc) => Camera::try_new(
            fc.position.into(),
            fc.look_at.into(),
            fc.up.into(),
            fc.fov_y_deg,
        )
        .ok_or(MeshSceneError::FileCamera)?,
        None => Camera::try_new(eye, c, up, 40.0).ok_or_else(too_large)?,
    };
    let light = Light::Directional {
        direction: -(-0.5 * right + 0.8 * up + 0.33 * back).normalize(),
        irradiance: Color::ONE,
    };
    Ok(SceneFile {
        scene: Scene::new(
            camera,
            objects,
            materials,
            vec![light],
            SKY,
            Color::splat(AMBIENT_FILL),
        )
        .expect("every object's material was pushed just before it"),
        settings: RenderSettings {
            width: 1920,
            height: 1080,
            spp: 1,
            integrator: IntegratorKind::Raycast,
            ..RenderSettings::default()
        },
        seconds_mesh_load: model.seconds_load,
        seconds_mesh_build: model.seconds_build,
        warnings: model.warnings.clone(),
        desc: None,
    })
}
