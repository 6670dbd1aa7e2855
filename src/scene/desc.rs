//! The scene description: what a scene file says, as plain data that
//! serialises (serde), separate from building it.
//!
//! A [`SceneDesc`] names mesh files rather than holding their triangles, and
//! formulas rather than compiled surfaces; [`SceneDesc::build`] reads the
//! meshes, compiles the formulas and builds the BVHs into a [`Scene`]. The
//! TOML reader (`load.rs`) is one front end that makes descriptions; other
//! front ends (JSON, a Python module) can make them without TOML, and a farm
//! task can read and fingerprint a description before it pays for the build.
//!
//! `build` checks everything, whoever made the description: a description is
//! input, and input is not trusted.

use super::meshio::{Model, load_mesh_file, smooth_normals};
use super::{Camera, Light, Material, MaterialKind, Object, Scene, SceneFile, Texture};
use crate::geometry::implicit::{HEART_BOUNDS, HEART_FORMULA, torus_formula};
use crate::geometry::{Cuboid, Implicit, Mesh, MeshInstance, Plane, Shape, Sphere};
use crate::light::EnvMap;
use crate::math::{Aabb, Color, Transform, Vec3};
use crate::settings::RenderSettings;
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A scene: camera, settings, materials by name, lights and objects.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneDesc {
    pub camera: CameraDesc,
    #[serde(default)]
    pub settings: RenderSettings,
    /// Radiance of rays that leave the scene.
    #[serde(default)]
    pub background: Color,
    /// The ambient light `A` of Whitted's model.
    #[serde(default)]
    pub ambient: Color,
    /// Named materials, in order (objects refer to them by name).
    #[serde(default)]
    pub materials: Vec<NamedMaterial>,
    #[serde(default)]
    pub lights: Vec<Light>,
    #[serde(default)]
    pub objects: Vec<ObjectDesc>,
    /// An environment map instead of the background colour.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub environment: Option<EnvironmentDesc>,
}

/// The scene file's `[environment]`: an equirectangular EXR image of the
/// radiance arriving from every direction.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnvironmentDesc {
    /// The EXR file, relative to the scene's folder.
    pub map: PathBuf,
    /// A factor on every texel.
    #[serde(default = "one")]
    pub scale: f32,
    /// Degrees the map is turned about +y.
    #[serde(default)]
    pub rotate_y: f32,
}

fn one() -> f32 {
    1.0
}

/// A pinhole camera: the scene file's `[camera]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraDesc {
    pub position: Vec3,
    pub look_at: Vec3,
    pub up: Vec3,
    /// Vertical field of view, degrees, in (0, 180).
    pub fov: f32,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NamedMaterial {
    pub name: String,
    pub material: Material,
}

/// An object: a shape and the name of its material (none: the mesh file's
/// own materials, or grey).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectDesc {
    pub shape: ShapeDesc,
    #[serde(default)]
    pub material: Option<String>,
}

/// Scale (per axis), then rotate about x, then y, then z (degrees, right-hand
/// rule), then translate.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TransformDesc {
    pub scale: Vec3,
    pub rotate_deg: Vec3,
    pub translate: Vec3,
}

impl TransformDesc {
    /// The transform, or `None` if it is singular (a zero scale) or not
    /// finite.
    pub fn transform(&self) -> Option<Transform> {
        Transform::from_parts(
            self.scale.as_dvec3(),
            self.rotate_deg.as_dvec3(),
            self.translate.as_dvec3(),
        )
    }
}

/// The implicit surfaces glint knows by name.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "surface", rename_all = "lowercase", deny_unknown_fields)]
pub enum NamedSurface {
    /// A torus about the z axis: `major_radius` from its centre to the middle
    /// of the tube, `minor_radius` the tube's.
    Torus {
        major_radius: f32,
        minor_radius: f32,
    },
    /// The heart `(x² + 9y²/4 + z² − 1)³ − x²z³ − 9y²z³/80 = 0`.
    Heart,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum ShapeDesc {
    Sphere {
        center: Vec3,
        radius: f32,
    },
    Plane {
        point: Vec3,
        normal: Vec3,
    },
    Box {
        min: Vec3,
        max: Vec3,
    },
    /// `f(x, y, z) = 0` inside `bounds` (object space), from a typed formula
    /// or a named surface (whose bounds, if not given, hold it).
    Implicit {
        formula: ImplicitFormula,
        bounds: Option<[Vec3; 2]>,
        transform: Option<TransformDesc>,
    },
    /// Every part of a mesh file (PLY, OBJ, glTF); a relative path is
    /// relative to the folder given to [`SceneDesc::build`].
    Mesh {
        file: PathBuf,
        /// Area-weighted vertex normals for meshes that have none.
        smooth: bool,
        transform: Option<TransformDesc>,
    },
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ImplicitFormula {
    Formula(String),
    Named(NamedSurface),
}

impl ShapeDesc {
    /// The shape's kind, as the scene file names it.
    pub fn kind(&self) -> &'static str {
        match self {
            ShapeDesc::Sphere { .. } => "sphere",
            ShapeDesc::Plane { .. } => "plane",
            ShapeDesc::Box { .. } => "box",
            ShapeDesc::Implicit { .. } => "implicit",
            ShapeDesc::Mesh { .. } => "mesh",
        }
    }
}

/// Where a description is wrong, and what is wrong.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{place}: {message}")]
pub struct DescError {
    pub place: Place,
    pub message: String,
}

/// A part of a description, for error messages.
#[derive(Clone, Debug, PartialEq)]
pub enum Place {
    Camera,
    Settings,
    Scene,
    Material(String),
    /// Lights and objects are numbered from 1, as in the scene file.
    Light(usize),
    Object(usize, &'static str),
    Environment,
}

impl std::fmt::Display for Place {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Place::Camera => f.write_str("the camera"),
            Place::Settings => f.write_str("the render settings"),
            Place::Scene => f.write_str("the scene"),
            Place::Material(name) => write!(f, "material `{name}`"),
            Place::Light(i) => write!(f, "light {i}"),
            Place::Object(i, kind) => write!(f, "object {i} ({kind})"),
            Place::Environment => f.write_str("the environment"),
        }
    }
}

/// A model and the indices its parts' materials got in the scene's list.
type LoadedModel = (Arc<Model>, Vec<Option<u32>>);

impl SceneDesc {
    /// Builds the scene: checks every value, reads mesh files (each once,
    /// however many objects use it; relative paths from `folder`), compiles
    /// formulas and builds the BVHs.
    pub fn build(&self, folder: &Path) -> Result<SceneFile, DescError> {
        let err = |place: Place, message: String| DescError { place, message };
        self.settings
            .validate()
            .map_err(|m| err(Place::Settings, m))?;
        let c = &self.camera;
        let camera = check_camera(c).map_err(|m| err(Place::Camera, m))?;
        for (what, v) in [("background", self.background), ("ambient", self.ambient)] {
            check_color(v).map_err(|m| err(Place::Scene, format!("`{what}`: {m}")))?;
        }

        let mut materials = vec![Material::default_diffuse()];
        let mut by_name = HashMap::new();
        for m in &self.materials {
            check_material(&m.material).map_err(|e| err(Place::Material(m.name.clone()), e))?;
            if by_name
                .insert(m.name.clone(), materials.len() as u32)
                .is_some()
            {
                return Err(err(
                    Place::Material(m.name.clone()),
                    "is defined twice".into(),
                ));
            }
            materials.push(m.material.clone());
        }
        for (i, light) in self.lights.iter().enumerate() {
            check_light(light).map_err(|m| err(Place::Light(i + 1), m))?;
        }
        let lights = self
            .lights
            .iter()
            .map(|l| match *l {
                Light::Directional {
                    direction,
                    irradiance,
                } => Light::Directional {
                    direction: direction.normalize(),
                    irradiance,
                },
                ref other => other.clone(),
            })
            .collect();

        let mut objects = Vec::new();
        let mut models: HashMap<(PathBuf, bool), LoadedModel> = HashMap::new();
        for (i, o) in self.objects.iter().enumerate() {
            let place = || Place::Object(i + 1, o.shape.kind());
            let material = match &o.material {
                None => None,
                Some(name) => Some(*by_name.get(name).ok_or_else(|| {
                    let mut names: Vec<&str> = by_name.keys().map(String::as_str).collect();
                    names.sort_unstable();
                    err(
                        place(),
                        format!(
                            "unknown material `{name}`; defined: {}",
                            if names.is_empty() {
                                "none".to_string()
                            } else {
                                names.join(", ")
                            }
                        ),
                    )
                })?),
            };
            let shapes = build_shape(&o.shape, folder, &mut materials, &mut models)
                .map_err(|m| err(place(), m))?;
            // The object's material overrides the file's; without either, grey.
            objects.extend(shapes.into_iter().map(|(shape, own)| Object {
                shape,
                material: material.or(own).unwrap_or(0),
            }));
        }
        let scene = Scene::new(
            camera,
            objects,
            materials,
            lights,
            self.background,
            self.ambient,
        )
        .map_err(|e| err(Place::Scene, e.to_string()))?;
        let scene = match &self.environment {
            None => scene,
            Some(e) => {
                let map = load_environment(e, folder).map_err(|m| err(Place::Environment, m))?;
                scene.with_environment(map)
            }
        };
        Ok(SceneFile {
            scene,
            settings: self.settings.clone(),
            // Folded from +0 (an empty f64 `sum` is −0).
            seconds_mesh_load: models.values().fold(0.0, |a, m| a + m.0.seconds_load),
            seconds_mesh_build: models.values().fold(0.0, |a, m| a + m.0.seconds_build),
            warnings: models
                .values()
                .flat_map(|m| m.0.warnings.iter().cloned())
                .collect(),
            desc: Some(self.clone()),
        })
    }
}

/// The camera, or what is wrong with it.
pub fn check_camera(c: &CameraDesc) -> Result<Camera, String> {
    if !(c.position.is_finite() && c.look_at.is_finite() && c.up.is_finite()) {
        return Err("its vectors must be finite".into());
    }
    if !(c.fov > 0.0 && c.fov < 180.0) {
        return Err(format!(
            "fov {} is not a vertical field of view in degrees, between 0 and 180",
            c.fov
        ));
    }
    Camera::try_new(c.position, c.look_at, c.up, c.fov).ok_or_else(|| {
        "degenerate camera: `look_at` must differ from `position`, and `up` must not be parallel to the view direction".into()
    })
}

fn check_color(c: Color) -> Result<(), String> {
    if c.is_finite() && c.min_element() >= 0.0 {
        Ok(())
    } else {
        Err(format!(
            "colour {:?} must be finite and ≥ 0 in every channel",
            c.to_array()
        ))
    }
}

fn check_material(m: &Material) -> Result<(), String> {
    match &m.texture {
        Texture::Solid(c) => check_color(*c)?,
        Texture::Checker {
            even, odd, scale, ..
        } => {
            check_color(*even)?;
            check_color(*odd)?;
            if !(*scale > 0.0 && scale.is_finite()) {
                return Err(format!("checker scale {scale} must be positive"));
            }
        }
    }
    for (name, v) in [
        ("ambient", m.ambient),
        ("diffuse", m.diffuse),
        ("specular", m.specular),
    ] {
        if !(v >= 0.0 && v.is_finite()) {
            return Err(format!("`{name}` {v} must be a number ≥ 0"));
        }
    }
    if !(m.shininess > 0.0 && m.shininess.is_finite()) {
        return Err(format!("`shininess` {} must be positive", m.shininess));
    }
    match m.kind {
        MaterialKind::Diffuse => Ok(()),
        MaterialKind::Mirror { reflectance } => check_color(reflectance),
        MaterialKind::Dielectric {
            ior,
            absorption,
            roughness,
        } => {
            if !(ior > 0.0 && ior.is_finite()) {
                return Err(format!("`ior` {ior} must be positive"));
            }
            check_unit("roughness", roughness)?;
            check_color(absorption)
        }
        MaterialKind::Conductor {
            complex_ior,
            roughness,
            anisotropy,
        } => {
            check_unit("roughness", roughness)?;
            if !(anisotropy > -1.0 && anisotropy < 1.0) {
                return Err(format!("`anisotropy` {anisotropy} must lie in (−1, 1)"));
            }
            if let Some((eta, k)) = complex_ior {
                if !(eta.min_element() > 0.0 && eta.is_finite()) {
                    return Err(format!("`eta` {eta} must be positive"));
                }
                check_color(k)?;
            }
            Ok(())
        }
        MaterialKind::Principled {
            metallic,
            roughness,
            transmission,
            ior,
        } => {
            check_unit("metallic", metallic)?;
            check_unit("roughness", roughness)?;
            check_unit("transmission", transmission)?;
            if !(1.0..1e6).contains(&ior) {
                return Err(format!("`ior` {ior} must be from 1 to 1e6"));
            }
            Ok(())
        }
    }?;
    check_color(m.emission)
}

/// Reads and checks the environment map `e` names (relative to `folder`).
fn load_environment(e: &EnvironmentDesc, folder: &Path) -> Result<EnvMap, String> {
    if !(e.scale >= 0.0 && e.scale.is_finite()) {
        return Err(format!("`scale` {} must be a number ≥ 0", e.scale));
    }
    if !e.rotate_y.is_finite() {
        return Err("`rotate_y` must be finite".into());
    }
    let path = folder.join(&e.map);
    let bytes = super::files::read_regular_file(&path)
        .map_err(|r| format!("cannot read `{}`: {}", path.display(), r.reason()))?;
    let (w, h, texels) =
        crate::light::envmap::read_exr(&bytes).map_err(|m| format!("`{}`: {m}", path.display()))?;
    EnvMap::new(w, h, texels, e.scale, e.rotate_y).map_err(|m| format!("`{}`: {m}", path.display()))
}

/// A number in [0, 1].
fn check_unit(name: &str, x: f32) -> Result<(), String> {
    if (0.0..=1.0).contains(&x) {
        Ok(())
    } else {
        Err(format!("`{name}` {x} must lie in [0, 1]"))
    }
}

fn check_light(l: &Light) -> Result<(), String> {
    match *l {
        Light::Point {
            position,
            intensity,
        } => {
            if !position.is_finite() {
                return Err("its position must be finite".into());
            }
            check_color(intensity)
        }
        Light::Directional {
            direction,
            irradiance,
        } => {
            if direction.try_normalize().is_none() {
                return Err("its direction must be non-zero and finite".into());
            }
            check_color(irradiance)
        }
    }
}

/// A shape's parts (a mesh file has several), each with its file material.
fn build_shape(
    shape: &ShapeDesc,
    folder: &Path,
    materials: &mut Vec<Material>,
    models: &mut HashMap<(PathBuf, bool), LoadedModel>,
) -> Result<Vec<(Shape, Option<u32>)>, String> {
    let finite = |v: Vec3, what: &str| {
        if v.is_finite() {
            Ok(v)
        } else {
            Err(format!("`{what}` must be finite"))
        }
    };
    let one = |shape| Ok(vec![(shape, None)]);
    match shape {
        ShapeDesc::Sphere { center, radius } => {
            finite(*center, "center")?;
            if !(*radius > 0.0 && radius.is_finite()) {
                return Err(format!("radius {radius} must be positive"));
            }
            one(Shape::Sphere(Sphere::new(*center, *radius)))
        }
        ShapeDesc::Plane { point, normal } => {
            finite(*point, "point")?;
            let n = normal.try_normalize().ok_or("expected a non-zero normal")?;
            one(Shape::Plane(Plane::new(*point, n)))
        }
        ShapeDesc::Box { min, max } => {
            finite(*min, "min")?;
            finite(*max, "max")?;
            if !min.cmplt(*max).all() {
                return Err("expected `max` greater than `min` in every coordinate".into());
            }
            one(Shape::Cuboid(Cuboid::new(*min, *max)))
        }
        ShapeDesc::Implicit {
            formula,
            bounds,
            transform,
        } => {
            let (text, default_bounds) = implicit_formula(formula)?;
            let [min, max] = match (bounds, default_bounds) {
                (Some(b), _) => *b,
                (None, Some(b)) => [b.min, b.max],
                (None, None) => return Err("a formula needs `bounds`".into()),
            };
            finite(min, "bounds")?;
            finite(max, "bounds")?;
            if !min.cmplt(max).all() {
                return Err(
                    "expected the second corner of `bounds` greater than the first in every coordinate"
                        .into(),
                );
            }
            let transform = match transform {
                None => Transform::IDENTITY,
                Some(t) => t.transform().ok_or(SINGULAR)?,
            };
            let implicit = Implicit::new(&text, Aabb::new(min, max), transform)
                .map_err(|e| format!("in its formula: {e}"))?;
            one(Shape::Implicit(Box::new(implicit)))
        }
        ShapeDesc::Mesh {
            file,
            smooth,
            transform,
        } => {
            let transform = match transform {
                None => None,
                Some(t) => Some(t.transform().ok_or(SINGULAR)?),
            };
            let path = folder.join(file);
            let key = (path.clone(), *smooth);
            let (model, ids) = match models.get(&key) {
                Some(entry) => entry.clone(),
                None => {
                    let model = load_model(&path, *smooth).map_err(|e| {
                        // The mesh error names the full path that was tried.
                        format!("cannot load mesh `{}`: {e}", file.display())
                    })?;
                    let ids = model
                        .parts
                        .iter()
                        .map(|part| {
                            part.material.clone().map(|m| {
                                materials.push(m);
                                materials.len() as u32 - 1
                            })
                        })
                        .collect();
                    let entry = (Arc::new(model), ids);
                    models.insert(key, entry.clone());
                    entry
                }
            };
            model
                .parts
                .iter()
                .zip(ids)
                .map(|(part, material)| {
                    let world = match (&transform, &part.transform) {
                        (None, None) => None,
                        (Some(t), None) | (None, Some(t)) => Some(t.clone()),
                        (Some(outer), Some(inner)) => Some(
                            Transform::from_affine(
                                outer.world_from_object * inner.world_from_object,
                            )
                            .ok_or("the combined transform is singular")?,
                        ),
                    };
                    Ok((
                        Shape::Mesh(MeshInstance::new(part.mesh.clone(), world.as_ref())),
                        material,
                    ))
                })
                .collect()
        }
    }
}

const SINGULAR: &str = "the transform is singular (a scale is zero) or not finite";

/// A formula's text, and for a named surface the bounds that hold it.
pub fn implicit_formula(f: &ImplicitFormula) -> Result<(String, Option<Aabb>), String> {
    Ok(match f {
        ImplicitFormula::Formula(text) => (text.clone(), None),
        ImplicitFormula::Named(NamedSurface::Torus {
            major_radius,
            minor_radius,
        }) => {
            let (major, minor) = (*major_radius, *minor_radius);
            if !(major > 0.0 && minor > 0.0 && major.is_finite() && minor.is_finite()) {
                return Err("a torus needs positive radii".into());
            }
            let (a, b) = (major + minor, minor);
            (
                torus_formula(major as f64, minor as f64),
                Some(Aabb::new(Vec3::new(-a, -a, -b), Vec3::new(a, a, b))),
            )
        }
        ImplicitFormula::Named(NamedSurface::Heart) => (
            HEART_FORMULA.to_string(),
            Some(Aabb::new(
                Vec3::from_array(HEART_BOUNDS[0]),
                Vec3::from_array(HEART_BOUNDS[1]),
            )),
        ),
    })
}

/// Reads a mesh file; with `smooth`, gives parts without normals
/// area-weighted vertex normals: in place where a mesh has one user (fresh
/// from the file), once per mesh where parts share it (glTF nodes).
fn load_model(path: &Path, smooth: bool) -> Result<Model, super::meshio::MeshError> {
    let mut model = load_mesh_file(path)?;
    if smooth {
        let mut shared: HashMap<*const Mesh, Arc<Mesh>> = HashMap::new();
        for part in &mut model.parts {
            if !part.mesh.normals.is_empty() {
                continue;
            }
            if let Some(mesh) = Arc::get_mut(&mut part.mesh) {
                mesh.normals = smooth_normals(&mesh.positions, &mesh.triangles);
                continue;
            }
            let original = &part.mesh;
            part.mesh = shared
                .entry(Arc::as_ptr(original))
                .or_insert_with(|| {
                    let mut mesh = (**original).clone();
                    mesh.normals = smooth_normals(&mesh.positions, &mesh.triangles);
                    Arc::new(mesh)
                })
                .clone();
        }
    }
    Ok(model)
}
