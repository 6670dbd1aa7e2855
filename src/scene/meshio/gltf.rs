//! glTF 2.0 (`.gltf` with its buffers, or `.glb`), read with the `gltf` crate.
//! The default scene's node hierarchy is walked with its transforms; each
//! triangle primitive becomes a mesh, shared by every node that uses it (an
//! instance). Materials: base colour; metallic ≥ 0.5 a mirror tinted by the
//! base colour; `KHR_materials_transmission` > 0 glass with
//! `KHR_materials_ior` (default 1.5); roughness sets the highlight. The first
//! camera found, if any, is returned.

use super::{FileCamera, MeshError, Model, ModelPart, RawMesh};
use crate::math::{Color, Transform};
use crate::scene::{Material, MaterialKind, Texture};
use glam::{DAffine3, DMat4, Vec2, Vec3};
use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

pub fn read(path: &Path) -> Result<Model, MeshError> {
    let start = Instant::now();
    let (doc, buffers, _images) = ::gltf::import(path)
        .map_err(|e| MeshError::new(path, "file", format!("cannot read it as glTF: {e}")))?;
    let mut raws: HashMap<(usize, usize), RawMesh> = HashMap::new();
    let mut uses: Vec<(usize, usize, String, DMat4, Option<Material>)> = Vec::new();
    let mut camera = None;
    let scene = doc
        .default_scene()
        .or_else(|| doc.scenes().next())
        .ok_or_else(|| MeshError::new(path, "file", "holds no scene"))?;
    let mut stack: Vec<(::gltf::Node, DMat4)> =
        scene.nodes().map(|n| (n, DMat4::IDENTITY)).collect();
    while let Some((node, parent)) = stack.pop() {
        let local = DMat4::from_cols_array_2d(&node.transform().matrix().map(|c| c.map(f64::from)));
        let world = parent * local;
        if let Some(cam) = node.camera()
            && camera.is_none()
            && let ::gltf::camera::Projection::Perspective(p) = cam.projection()
        {
            let position = world.transform_point3(glam::DVec3::ZERO);
            camera = Some(FileCamera {
                position: position.as_vec3(),
                look_at: world.transform_point3(glam::DVec3::NEG_Z).as_vec3(),
                up: world.transform_vector3(glam::DVec3::Y).as_vec3(),
                fov_y_deg: p.yfov().to_degrees(),
            });
        }
        if let Some(mesh) = node.mesh() {
            for prim in mesh.primitives() {
                let key = (mesh.index(), prim.index());
                let element = format!("mesh {} primitive {}", mesh.index(), prim.index());
                if prim.mode() != ::gltf::mesh::Mode::Triangles {
                    continue;
                }
                if let std::collections::hash_map::Entry::Vacant(slot) = raws.entry(key) {
                    let reader = prim.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
                    let positions: Vec<Vec3> = reader
                        .read_positions()
                        .ok_or_else(|| MeshError::new(path, &element, "has no positions"))?
                        .map(Vec3::from)
                        .collect();
                    let indices: Vec<u32> = match reader.read_indices() {
                        Some(ix) => ix.into_u32().collect(),
                        None => (0..positions.len() as u32).collect(),
                    };
                    if !indices.len().is_multiple_of(3) {
                        return Err(MeshError::new(
                            path,
                            &element,
                            format!("{} indices is not a multiple of 3", indices.len()),
                        ));
                    }
                    let raw = RawMesh {
                        triangles: indices
                            .chunks_exact(3)
                            .map(|t| [t[0], t[1], t[2]])
                            .collect(),
                        normals: reader
                            .read_normals()
                            .map(|n| n.map(Vec3::from).collect())
                            .unwrap_or_default(),
                        uvs: reader
                            .read_tex_coords(0)
                            .map(|t| t.into_f32().map(Vec2::from).collect())
                            .unwrap_or_default(),
                        positions,
                        polygons: Vec::new(),
                    };
                    slot.insert(raw);
                }
                let name = mesh.name().map_or(element.clone(), str::to_string);
                uses.push((
                    key.0,
                    key.1,
                    name,
                    world,
                    Some(map_material(&prim.material())),
                ));
            }
        }
        for child in node.children() {
            stack.push((child, world));
        }
    }
    let seconds_load = start.elapsed().as_secs_f64();
    let build = Instant::now();
    let mut meshes = HashMap::new();
    for (key, raw) in raws {
        let element = format!("mesh {} primitive {}", key.0, key.1);
        let mesh = raw
            .build(path)
            .map_err(|e| MeshError::new(path, &format!("{element}, {}", e.element), e.message))?;
        meshes.insert(key, Arc::new(mesh));
    }
    let mut parts = Vec::new();
    for (m, p, name, world, material) in uses {
        let affine = DAffine3::from_mat4(world);
        let transform = if affine == DAffine3::IDENTITY {
            None
        } else {
            Some(
                Transform::from_affine(affine)
                    .ok_or_else(|| MeshError::new(path, &name, "has a singular node transform"))?,
            )
        };
        parts.push(ModelPart {
            name,
            mesh: meshes[&(m, p)].clone(),
            transform,
            material,
        });
    }
    if parts.is_empty() {
        return Err(MeshError::new(path, "file", "holds no triangle meshes"));
    }
    Ok(Model {
        parts,
        camera,
        seconds_load,
        seconds_build: build.elapsed().as_secs_f64(),
    })
}

fn map_material(m: &::gltf::Material) -> Material {
    let pbr = m.pbr_metallic_roughness();
    let [r, g, b, _] = pbr.base_color_factor();
    let base = Color::new(r, g, b);
    let roughness = pbr.roughness_factor().clamp(0.0, 1.0);
    // Blinn–Phong exponent of the same lobe width as GGX α = roughness²
    // (Walter et al. 2007: n = 2/α² − 2).
    let alpha = (roughness * roughness).max(1e-3);
    let shininess = (2.0 / (alpha * alpha) - 2.0).clamp(1.0, 1e4);
    let specular = 0.5 * (1.0 - roughness) * (1.0 - roughness);
    let transmission = m.transmission().map_or(0.0, |t| t.transmission_factor());
    let mut material = Material {
        texture: Texture::Solid(base),
        ambient: 1.0,
        diffuse: 1.0,
        specular,
        shininess,
        kind: MaterialKind::Diffuse,
    };
    if transmission > 0.0 {
        material.kind = MaterialKind::Dielectric {
            ior: m.ior().unwrap_or(1.5),
            absorption: Color::ZERO,
        };
        material.diffuse = 1.0 - transmission;
        material.ambient = 0.0;
    } else if pbr.metallic_factor() >= 0.5 {
        material.kind = MaterialKind::Mirror { reflectance: base };
        material.diffuse = 0.0;
        material.ambient = 0.0;
    }
    material
}
