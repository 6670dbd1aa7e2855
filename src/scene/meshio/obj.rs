//! Wavefront OBJ with MTL materials, read by `tobj` (triangulated, one index
//! per vertex). One part per object/group. MTL materials map to ours:
//! `Kd` diffuse colour, `Ks`/`Ns` Blinn–Phong highlight, `illum 3` mirror
//! (reflectance `Ks`), `illum 4, 6, 7` or `d < 1` glass with `Ni` as the index
//! of refraction. Objects without normals get smooth vertex normals when the
//! file turns smoothing groups on (`s 1`), flat shading otherwise.

use super::{MeshError, Model, ModelPart, RawMesh};
use crate::math::Color;
use crate::scene::{Material, MaterialKind, Texture};
use glam::{Vec2, Vec3};
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

pub fn read(path: &Path) -> Result<Model, MeshError> {
    let start = Instant::now();
    let (models, materials) =
        tobj::load_obj(path, &tobj::GPU_LOAD_OPTIONS).map_err(|e| locate(path, e))?;
    let materials =
        materials.map_err(|e| MeshError::new(path, "material library", e.to_string()))?;
    let text = std::fs::read_to_string(path).unwrap_or_default();
    let smoothing = text.lines().any(|l| {
        let mut w = l.split_whitespace();
        w.next() == Some("s") && !matches!(w.next(), Some("off") | Some("0") | None)
    });
    let mut raws = Vec::new();
    for (k, m) in models.into_iter().enumerate() {
        let mesh = &m.mesh;
        let mut raw = RawMesh {
            positions: mesh
                .positions
                .chunks_exact(3)
                .map(|p| Vec3::new(p[0], p[1], p[2]))
                .collect(),
            triangles: mesh
                .indices
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]])
                .collect(),
            normals: mesh
                .normals
                .chunks_exact(3)
                .map(|n| Vec3::new(n[0], n[1], n[2]))
                .collect(),
            uvs: mesh
                .texcoords
                .chunks_exact(2)
                .map(|t| Vec2::new(t[0], t[1]))
                .collect(),
            polygons: Vec::new(),
        };
        if raw.normals.is_empty() && smoothing {
            raw.normals = smooth_normals(&raw.positions, &raw.triangles);
        }
        let material = mesh
            .material_id
            .and_then(|i| materials.get(i))
            .map(map_material);
        let name = if m.name.is_empty() {
            format!("object {k}")
        } else {
            m.name.clone()
        };
        raws.push((name, raw, material));
    }
    let seconds_load = start.elapsed().as_secs_f64();
    let build = Instant::now();
    let mut parts = Vec::new();
    for (name, raw, material) in raws {
        if raw.triangles.is_empty() {
            continue;
        }
        parts.push(ModelPart {
            mesh: Arc::new(
                raw.build(path)
                    .map_err(|e| MeshError::new(path, &format!("object `{name}`"), e.message))?,
            ),
            name,
            transform: None,
            material,
        });
    }
    if parts.is_empty() {
        return Err(MeshError::new(path, "file", "holds no faces"));
    }
    Ok(Model {
        parts,
        camera: None,
        seconds_load,
        seconds_build: build.elapsed().as_secs_f64(),
    })
}

/// Area-weighted vertex normals, summed in f64 (the area of a triangle
/// written at a scale of 1e±10 is out of f32's reach).
pub fn smooth_normals(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
    let mut n = vec![glam::DVec3::ZERO; positions.len()];
    for t in triangles {
        let [a, b, c] = t.map(|i| positions[i as usize].as_dvec3());
        let face = (b - a).cross(c - a);
        for &i in t {
            n[i as usize] += face;
        }
    }
    n.into_iter()
        .map(|v| v.normalize_or_zero().as_vec3())
        .collect()
}

fn map_material(m: &tobj::Material) -> Material {
    let kd = m.diffuse.map_or(Color::splat(0.8), Color::from);
    let ks = m.specular.map_or(Color::ZERO, Color::from);
    let mut material = Material {
        texture: Texture::Solid(kd),
        ambient: 1.0,
        diffuse: 1.0,
        specular: ks.max_element(),
        shininess: m.shininess.filter(|&s| s > 0.0).unwrap_or(64.0),
        kind: MaterialKind::Diffuse,
    };
    let glass =
        matches!(m.illumination_model, Some(4 | 6 | 7)) || m.dissolve.is_some_and(|d| d < 1.0);
    if glass {
        material.kind = MaterialKind::Dielectric {
            ior: m.optical_density.filter(|&n| n > 0.0).unwrap_or(1.5),
            absorption: Color::ZERO,
        };
        material.diffuse = 0.0;
        material.ambient = 0.0;
    } else if m.illumination_model == Some(3) {
        material.kind = MaterialKind::Mirror {
            reflectance: if ks == Color::ZERO { Color::ONE } else { ks },
        };
    }
    material
}

/// tobj's errors say what failed but not where: find the first line that
/// shows the problem, so the message can name it.
fn locate(path: &Path, e: tobj::LoadError) -> MeshError {
    use tobj::LoadError::*;
    if matches!(e, OpenFileFailed | ReadError) {
        return MeshError::new(path, "file", format!("cannot read it ({e})"));
    }
    let Ok(text) = std::fs::read_to_string(path) else {
        return MeshError::new(path, "file", e.to_string());
    };
    let (mut v, mut vt, mut vn) = (0i64, 0i64, 0i64);
    for (i, line) in text.lines().enumerate() {
        let mut w = line.split_whitespace();
        let at = format!("line {}", i + 1);
        let numbers =
            |w: std::str::SplitWhitespace| w.map(str::parse::<f32>).collect::<Result<Vec<_>, _>>();
        match w.next() {
            Some("v") => {
                v += 1;
                if numbers(w).map_or(true, |n| n.len() < 3) {
                    return MeshError::new(path, &at, format!("bad vertex `{}`", line.trim()));
                }
            }
            Some("vt") => vt += 1,
            Some("vn") => vn += 1,
            Some("f") => {
                let corners: Vec<&str> = w.collect();
                if corners.len() < 3 {
                    return MeshError::new(
                        path,
                        &at,
                        format!("face with {} vertices", corners.len()),
                    );
                }
                for c in corners {
                    for (k, field) in c.split('/').enumerate() {
                        if field.is_empty() && k > 0 {
                            continue;
                        }
                        let count = [v, vt, vn][k.min(2)];
                        match field.parse::<i64>() {
                            Ok(idx) if idx != 0 && idx.abs() <= count => {}
                            Ok(idx) => {
                                return MeshError::new(
                                    path,
                                    &at,
                                    format!(
                                        "face refers to {} {idx}, but only {count} are defined so far",
                                        ["vertex", "texture coordinate", "normal"][k.min(2)]
                                    ),
                                );
                            }
                            Err(_) => {
                                return MeshError::new(
                                    path,
                                    &at,
                                    format!("bad face `{}`", line.trim()),
                                );
                            }
                        }
                    }
                }
            }
            _ => {}
        }
    }
    MeshError::new(path, "file", e.to_string())
}
