//! A scene around a mesh file, for `glint render model.ply`: the camera and
//! light that `shared/anchors/common.py` uses for the peers' benchmarks, a
//! white Lambertian material where the file gives none, and ray casting at
//! 1920×1080 — one camera ray and one shadow ray per pixel, the same work as
//! Mitsuba's `direct` integrator in `mitsuba_bench.py`.

use super::meshio::Model;
use super::{Camera, Light, Material, Object, Scene, SceneFile};
use crate::geometry::{MeshInstance, Shape};
use crate::math::{Aabb, Color, Vec3};
use crate::settings::{IntegratorKind, RenderSettings};

/// Builds the scene. `view` points from the mesh's centre towards the eye,
/// `up` is the up axis (z for z-up scans). With the bounding box's centre `c`
/// and `r = 0.6·(largest extent)`, the eye is at `c + vieŵ·r/sin 20°` and the
/// vertical field of view is 40°, so a sphere of radius `r` fills the frame's
/// height; the point light is at `c + 3r(−0.5 right + 0.8 up + 0.33 back)`
/// with intensity `9r²` (about unit irradiance at the mesh). A camera in the
/// file (glTF) is used instead when there is one.
///
/// Returns `None` if `view` and `up` are parallel or zero.
pub fn mesh_scene(model: &Model, view: Vec3, up: Vec3) -> Option<SceneFile> {
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
    let r = 0.6 * (bounds.max - bounds.min).max_element();
    let back = view.try_normalize()?;
    let right = up.cross(back).try_normalize()?;
    let up = back.cross(right);
    let eye = c + back * r / 20f32.to_radians().sin();
    let camera = match &model.camera {
        Some(fc) => Camera::try_new(
            fc.position.into(),
            fc.look_at.into(),
            fc.up.into(),
            fc.fov_y_deg,
        )?,
        None => Camera::try_new(eye, c, up, 40.0)?,
    };
    let light = Light::Point {
        position: c + r * 3.0 * (-0.5 * right + 0.8 * up + 0.33 * back),
        intensity: Color::splat(9.0 * r * r),
    };
    Some(SceneFile {
        scene: Scene::new(
            camera,
            objects,
            materials,
            vec![light],
            Color::ZERO,
            Color::ZERO,
        ),
        settings: RenderSettings {
            width: 1920,
            height: 1080,
            spp: 1,
            integrator: IntegratorKind::Raycast,
            ..RenderSettings::default()
        },
        seconds_mesh_load: model.seconds_load,
        seconds_mesh_build: model.seconds_build,
    })
}
