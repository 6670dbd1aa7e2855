//! Wavefront OBJ with MTL materials, read by `tobj` (triangulated, one index
//! per vertex). One part per object/group. MTL materials map to ours:
//! `Kd` diffuse colour, `Ks`/`Ns` Blinn–Phong highlight, `illum 3` mirror
//! (reflectance `Ks`), `illum 4, 6, 7` or `d < 1` glass with `Ni` as the index
//! of refraction. Objects without normals get smooth vertex normals when the
//! file turns smoothing groups on (`s 1`), flat shading otherwise.
//!
//! Both files are read and checked here first, line by line, and `tobj` is
//! given a clean copy: every statement it parses in the form it expects,
//! with every number finite and every face index in range. So a malformed
//! file is an error that names its line, never a panic inside `tobj`, and
//! what the formats allow but `tobj` does not take (`Kd 0.8` with g and b
//! defaulting to r, `vt u` without v, line continuations) is accepted.
//! Material libraries are read only from the OBJ's folder (see
//! [`resolve_inside`]); a missing one is a warning, and its objects get the
//! default material. MTL colours must be finite and non-negative, as in
//! scene files: anything else is an error naming the MTL file and line.

use super::{MeshError, Model, ModelPart, RawMesh};
use crate::math::Color;
use crate::scene::files::{FileError, read_text_file, resolve_inside};
use crate::scene::{Material, MaterialKind, Texture};
use glam::{Vec2, Vec3};
use std::cell::RefCell;
use std::fmt::Write;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

pub fn read(path: &Path) -> Result<Model, MeshError> {
    let start = Instant::now();
    let text = read_text_file(path).map_err(|e| MeshError::file(path, &e))?;
    let clean = clean_obj(path, &text)?;
    let folder = path.parent().unwrap_or(Path::new(""));
    // What the material loader found, kept here: tobj passes on only its own
    // error codes.
    let problem: RefCell<Option<MeshError>> = RefCell::new(None);
    let warnings: RefCell<Vec<String>> = RefCell::new(Vec::new());
    let (models, materials) = tobj::load_obj_buf(
        &mut clean.text.as_bytes(),
        &tobj::GPU_LOAD_OPTIONS,
        |library| {
            let name = library.to_string_lossy();
            match load_library(folder, &name) {
                Ok(text) => tobj::load_mtl_buf(&mut text.as_bytes()),
                Err(Library::Missing(tried)) => {
                    warnings.borrow_mut().push(format!(
                        "{}: material library `{name}` not found (tried `{}`); its materials are replaced by the default",
                        path.display(),
                        tried.display()
                    ));
                    Err(tobj::LoadError::OpenFileFailed)
                }
                Err(Library::Error(e)) => {
                    problem.borrow_mut().get_or_insert(e);
                    Err(tobj::LoadError::OpenFileFailed)
                }
            }
        },
    )
    .map_err(|e| MeshError::new(path, "file", format!("cannot read it as OBJ ({e})")))?;
    if let Some(e) = problem.into_inner() {
        return Err(e);
    }
    // Only libraries that failed (reported above) give an error here.
    let materials = materials.unwrap_or_default();
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
        if raw.normals.is_empty() && clean.smoothing {
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
        warnings: warnings.into_inner(),
    })
}

/// An OBJ file checked and rewritten for `tobj`.
struct CleanObj {
    text: String,
    /// Whether any `s` statement turns smoothing groups on.
    smoothing: bool,
}

/// One statement of an OBJ or MTL file: its 1-based line number, the whole
/// logical line, its keyword and the words after it.
struct Statement<'a> {
    number: usize,
    line: &'a str,
    keyword: &'a str,
    rest: Vec<&'a str>,
}

impl Statement<'_> {
    /// Where it is, for messages: `line N`.
    fn at(&self) -> String {
        format!("line {}", self.number)
    }

    /// The text after the keyword, trimmed (names may hold spaces).
    fn tail(&self) -> &str {
        self.line.trim_start()[self.keyword.len()..].trim()
    }
}

/// The statements of `lines` (from [`logical_lines`]), blank lines left out.
fn statements(lines: &[(usize, String)]) -> impl Iterator<Item = Statement<'_>> {
    lines.iter().filter_map(|(number, line)| {
        let mut words = line.split_whitespace();
        let keyword = words.next()?;
        Some(Statement {
            number: *number,
            line,
            keyword,
            rest: words.collect(),
        })
    })
}

/// The logical lines of an OBJ or MTL file with their 1-based numbers: a
/// line ending in `\` continues on the next.
fn logical_lines(text: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let mut pending: Option<(usize, String)> = None;
    for (i, line) in text.lines().enumerate() {
        let (number, mut joined) = pending.take().unwrap_or((i + 1, String::new()));
        match line.trim_end().strip_suffix('\\') {
            Some(head) => {
                joined.push_str(head);
                joined.push(' ');
                pending = Some((number, joined));
            }
            None => {
                joined.push_str(line);
                out.push((number, joined));
            }
        }
    }
    out.extend(pending);
    out
}

/// Checks every statement glint reads and writes it out in the one form
/// `tobj` parses: `v x y z` (a `w` divided out, vertex colours dropped),
/// `vt u v`, `vn x y z`, faces of at least three corners with absolute
/// indices that exist, and `o`, `g`, `s`, `usemtl`, `mtllib` as they are.
/// Other statements (lines, points, free-form geometry) are left out.
fn clean_obj(path: &Path, text: &str) -> Result<CleanObj, MeshError> {
    let mut out = String::with_capacity(text.len());
    let mut smoothing = false;
    let (mut v, mut vt, mut vn) = (0usize, 0usize, 0usize);
    let lines = logical_lines(text);
    for st in statements(&lines) {
        let (line, keyword, rest) = (st.line, st.keyword, &st.rest);
        let at = || st.at();
        let numbers = |what: &str| -> Result<Vec<f32>, MeshError> {
            rest.iter()
                .map(|w| match w.parse::<f32>() {
                    Ok(x) if x.is_finite() => Ok(x),
                    Ok(_) => Err(MeshError::new(
                        path,
                        &at(),
                        format!("{what} has a non-finite value `{w}`"),
                    )),
                    Err(_) => Err(MeshError::new(
                        path,
                        &at(),
                        format!("bad {what} `{}`: `{w}` is not a number", line.trim()),
                    )),
                })
                .collect()
        };
        match keyword {
            "v" => {
                let x = numbers("vertex")?;
                let p = match x.as_slice() {
                    [x, y, z] | [x, y, z, _, _, _] => Vec3::new(*x, *y, *z),
                    [x, y, z, w] if *w != 0.0 => Vec3::new(*x, *y, *z) / *w,
                    [_, _, _, _] => {
                        return Err(MeshError::new(path, &at(), "vertex has weight w = 0"));
                    }
                    _ => {
                        return Err(MeshError::new(
                            path,
                            &at(),
                            format!(
                                "bad vertex `{}`: expected x y z, with an optional w or r g b",
                                line.trim()
                            ),
                        ));
                    }
                };
                if !p.is_finite() {
                    return Err(MeshError::new(path, &at(), "vertex is not finite"));
                }
                v += 1;
                let _ = writeln!(out, "v {} {} {}", p.x, p.y, p.z);
            }
            "vt" => {
                let t = numbers("texture coordinate")?;
                if !(1..=3).contains(&t.len()) {
                    return Err(MeshError::new(
                        path,
                        &at(),
                        format!(
                            "bad texture coordinate `{}`: expected u [v [w]]",
                            line.trim()
                        ),
                    ));
                }
                vt += 1;
                let _ = writeln!(out, "vt {} {}", t[0], t.get(1).copied().unwrap_or(0.0));
            }
            "vn" => {
                let n = numbers("normal")?;
                if n.len() != 3 {
                    return Err(MeshError::new(
                        path,
                        &at(),
                        format!("bad normal `{}`: expected x y z", line.trim()),
                    ));
                }
                vn += 1;
                let _ = writeln!(out, "vn {} {} {}", n[0], n[1], n[2]);
            }
            "f" => {
                if rest.len() < 3 {
                    return Err(MeshError::new(
                        path,
                        &at(),
                        format!("face with {} vertices; a face needs at least 3", rest.len()),
                    ));
                }
                out.push('f');
                for corner in rest {
                    out.push(' ');
                    let fields: Vec<&str> = corner.split('/').collect();
                    if fields.len() > 3 || fields[0].is_empty() {
                        return Err(MeshError::new(
                            path,
                            &at(),
                            format!(
                                "bad face corner `{corner}`: expected v, v/vt, v//vn or v/vt/vn"
                            ),
                        ));
                    }
                    for (k, field) in fields.iter().enumerate() {
                        if k > 0 {
                            out.push('/');
                        }
                        if field.is_empty() {
                            continue;
                        }
                        let (what, count) =
                            [("vertex", v), ("texture coordinate", vt), ("normal", vn)][k];
                        let index = field.parse::<i64>().map_err(|_| {
                            MeshError::new(path, &at(), format!("bad face `{}`", line.trim()))
                        })?;
                        // 1-based, or negative: counted back from the last one defined.
                        let absolute = if index < 0 {
                            count as i64 + 1 + index
                        } else {
                            index
                        };
                        if absolute < 1 || absolute > count as i64 {
                            return Err(MeshError::new(
                                path,
                                &at(),
                                format!(
                                    "face refers to {what} {index}, but only {count} are defined so far"
                                ),
                            ));
                        }
                        let _ = write!(out, "{absolute}");
                    }
                }
                out.push('\n');
            }
            "s" => {
                smoothing |= !matches!(rest.first(), Some(&"off") | Some(&"0") | None);
                let _ = writeln!(out, "s {}", rest.join(" "));
            }
            "o" | "g" | "usemtl" => {
                let _ = writeln!(out, "{keyword} {}", rest.join(" "));
            }
            "mtllib" => {
                let name = st.tail();
                if !name.is_empty() {
                    let _ = writeln!(out, "mtllib {name}");
                }
            }
            _ => {}
        }
    }
    Ok(CleanObj {
        text: out,
        smoothing,
    })
}

/// Why a material library could not be used.
enum Library {
    /// Not there (a warning: downloaded models often lack theirs).
    Missing(std::path::PathBuf),
    Error(MeshError),
}

/// Reads the material library `name` from the OBJ's `folder`, checks it and
/// rewrites it for `tobj` (see [`clean_mtl`]).
fn load_library(folder: &Path, name: &str) -> Result<String, Library> {
    let path = folder.join(name);
    let real = resolve_inside(folder, name).map_err(|e| match e {
        FileError::NotFound { path } => Library::Missing(path),
        e => Library::Error(MeshError::new(&path, "file", e.to_string())),
    })?;
    let text = read_text_file(&real).map_err(|e| Library::Error(MeshError::file(&path, &e)))?;
    clean_mtl(&path, &text).map_err(Library::Error)
}

/// Checks an MTL file and writes out what glint reads from it in the form
/// `tobj` parses: `newmtl`, colours `Ka Kd Ks Ke` as three numbers (one or
/// two numbers mean g and b equal to r, as the MTL specification says),
/// `Ns`, `Ni`, `d` and `illum`. Colours must be finite and ≥ 0, `Ns` and
/// `Ni` finite and ≥ 0, `d` finite in [0, 1], `illum` an integer. Colours
/// given as `spectral` curves or `xyz` are not supported and left out
/// (the material keeps the default for them); texture maps and other
/// statements are left out.
fn clean_mtl(path: &Path, text: &str) -> Result<String, MeshError> {
    let mut out = String::with_capacity(text.len());
    let lines = logical_lines(text);
    for st in statements(&lines) {
        let (line, keyword, rest) = (st.line, st.keyword, &st.rest);
        let at = || st.at();
        let number = |w: &str| -> Result<f32, MeshError> {
            match w.parse::<f32>() {
                Ok(x) if x.is_finite() => Ok(x),
                _ => Err(MeshError::new(
                    path,
                    &at(),
                    format!("`{keyword}` expects finite numbers, found `{w}`"),
                )),
            }
        };
        match keyword {
            "newmtl" => {
                let name = st.tail();
                if name.is_empty() {
                    return Err(MeshError::new(path, &at(), "`newmtl` without a name"));
                }
                let _ = writeln!(out, "newmtl {name}");
            }
            "Ka" | "Kd" | "Ks" | "Ke" => {
                if matches!(rest.first(), Some(&"spectral") | Some(&"xyz")) {
                    continue;
                }
                if !(1..=3).contains(&rest.len()) {
                    return Err(MeshError::new(
                        path,
                        &at(),
                        format!("`{keyword}` expects r [g [b]], found {} values", rest.len()),
                    ));
                }
                let r = number(rest[0])?;
                let g = rest.get(1).map_or(Ok(r), |w| number(w))?;
                let b = rest.get(2).map_or(Ok(r), |w| number(w))?;
                if r < 0.0 || g < 0.0 || b < 0.0 {
                    return Err(MeshError::new(
                        path,
                        &at(),
                        format!("`{keyword}` expects colour components ≥ 0, found {r} {g} {b}"),
                    ));
                }
                let _ = writeln!(out, "{keyword} {r} {g} {b}");
            }
            "Ns" | "Ni" | "d" => {
                let Some(first) = rest.first() else {
                    return Err(MeshError::new(
                        path,
                        &at(),
                        format!("`{keyword}` without a value"),
                    ));
                };
                let x = number(first)?;
                let ok = match keyword {
                    "d" => (0.0..=1.0).contains(&x),
                    _ => x >= 0.0,
                };
                if !ok {
                    return Err(MeshError::new(
                        path,
                        &at(),
                        format!(
                            "`{keyword}` expects {}, found {x}",
                            if keyword == "d" {
                                "a number from 0 to 1"
                            } else {
                                "a number ≥ 0"
                            }
                        ),
                    ));
                }
                let _ = writeln!(out, "{keyword} {x}");
            }
            "illum" => {
                let model = rest
                    .first()
                    .and_then(|w| w.parse::<u8>().ok())
                    .ok_or_else(|| {
                        MeshError::new(
                            path,
                            &at(),
                            format!("bad `{}`: expected an integer", line.trim()),
                        )
                    })?;
                let _ = writeln!(out, "illum {model}");
            }
            _ => {}
        }
    }
    Ok(out)
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

/// MTL `Ke r g b` (emitted radiance), which tobj leaves among the unknown
/// parameters; black where absent or not three finite numbers ≥ 0.
fn emission(m: &tobj::Material) -> Color {
    let Some(text) = m.unknown_param.get("Ke") else {
        return Color::ZERO;
    };
    let v: Vec<f32> = text
        .split_whitespace()
        .filter_map(|x| x.parse().ok())
        .collect();
    match v[..] {
        [r, g, b] if [r, g, b].iter().all(|x| x.is_finite() && *x >= 0.0) => Color::new(r, g, b),
        [x] if x.is_finite() && x >= 0.0 => Color::splat(x),
        _ => Color::ZERO,
    }
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
        emission: emission(m),
        two_sided: false,
    };
    let glass =
        matches!(m.illumination_model, Some(4 | 6 | 7)) || m.dissolve.is_some_and(|d| d < 1.0);
    if glass {
        material.kind = MaterialKind::Dielectric {
            ior: m.optical_density.filter(|&n| n > 0.0).unwrap_or(1.5),
            absorption: Color::ZERO,
            roughness: 0.0,
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
