//! glTF 2.0 (`.gltf` with its buffers, or `.glb`). The `gltf` crate parses
//! and validates the JSON document; everything that reaches for bytes is
//! done here, checked before use:
//!
//! - the GLB container (header, chunk lengths) is read here, so that no
//!   length in the file sizes an allocation before it is checked against
//!   the file's own size;
//! - buffers are the GLB's binary chunk, base64 `data:` URIs, or regular
//!   files inside the model's folder ([`resolve_inside`]); any other URI is
//!   an error naming it, and image URIs must obey the same rule (images are
//!   not read);
//! - accessors are read with every offset, stride and count checked against
//!   their buffer view and buffer;
//! - the node hierarchy must be a forest: a node that is its own ancestor
//!   (a cycle) or the child of two parents is an error naming it.
//!
//! The default scene's nodes are walked with their transforms; each
//! triangle primitive becomes a mesh, shared by every node that uses it (an
//! instance). Materials: base colour, metallic, roughness,
//! `KHR_materials_transmission` and `KHR_materials_ior` (default 1.5)
//! become a `principled` material as they are, which shading maps to a BSDF
//! (Whitted: diffuse, a mirror tinted by the base colour when metallic ≥
//! 0.5, smooth glass when mostly transmissive); roughness also sets
//! Whitted's highlight. Their factors must be finite and in the ranges the
//! specification gives. The first valid perspective camera found, if any,
//! is returned.

use super::{FileCamera, MeshError, Model, ModelPart, RawMesh};
use crate::math::{Color, Transform};
use crate::scene::files::{FileError, read_regular_file, resolve_inside};
use crate::scene::{Material, MaterialKind, Texture};
use ::gltf::accessor::{DataType, Dimensions};
use base64::Engine;
use glam::{DAffine3, DMat4, Vec2, Vec3};
use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

pub fn read(path: &Path) -> Result<Model, MeshError> {
    let start = Instant::now();
    let err = |element: &str, message: String| MeshError::new(path, element, message);
    let data = read_regular_file(path).map_err(|e| MeshError::file(path, &e))?;
    let (json, blob) = if data.starts_with(b"glTF") {
        let glb = parse_glb(&data).map_err(|m| err("GLB header", m))?;
        (glb.json, glb.bin)
    } else {
        (&data[..], None)
    };
    let root = ::gltf::json::Root::from_slice(json)
        .map_err(|e| err("file", format!("cannot read it as glTF: {e}")))?;
    check_position_accessors(&root).map_err(|(element, m)| err(&element, m))?;
    let doc =
        ::gltf::Document::from_json(root).map_err(|e| err("file", format!("invalid glTF: {e}")))?;
    let folder = path.parent().unwrap_or(Path::new(""));
    check_images(&doc, folder).map_err(|(element, m)| err(&element, m))?;
    let buffers = load_buffers(&doc, folder, blob).map_err(|(element, m)| err(&element, m))?;

    let mut raws: HashMap<(usize, usize), RawMesh> = HashMap::new();
    let mut uses: Vec<(usize, usize, String, DMat4, Option<Material>)> = Vec::new();
    let mut camera = None;
    let mut warnings = Vec::new();
    let scene = doc
        .default_scene()
        .or_else(|| doc.scenes().next())
        .ok_or_else(|| err("file", "holds no scene".into()))?;
    let mut materials: HashMap<Option<usize>, Material> = HashMap::new();
    let mut reached = vec![false; doc.nodes().len()];
    let mut stack: Vec<(::gltf::Node, DMat4)> = Vec::new();
    for node in scene.nodes() {
        if std::mem::replace(&mut reached[node.index()], true) {
            return Err(err(
                &format!("node {}", node.index()),
                "is listed twice among the scene's root nodes".into(),
            ));
        }
        stack.push((node, DMat4::IDENTITY));
    }
    while let Some((node, parent)) = stack.pop() {
        let element = format!("node {}", node.index());
        let local = DMat4::from_cols_array_2d(&node.transform().matrix().map(|c| c.map(f64::from)));
        if !local.is_finite() {
            return Err(err(&element, "has a non-finite transform".into()));
        }
        let world = parent * local;
        if let Some(cam) = node.camera()
            && camera.is_none()
            && let ::gltf::camera::Projection::Perspective(p) = cam.projection()
        {
            let c = FileCamera {
                position: world.transform_point3(glam::DVec3::ZERO).as_vec3(),
                look_at: world.transform_point3(glam::DVec3::NEG_Z).as_vec3(),
                up: world.transform_vector3(glam::DVec3::Y).as_vec3(),
                fov_y_deg: p.yfov().to_degrees(),
            };
            let usable = crate::scene::Camera::try_new(
                c.position.into(),
                c.look_at.into(),
                c.up.into(),
                c.fov_y_deg,
            )
            .is_some();
            if usable {
                camera = Some(c);
            } else {
                warnings.push(format!(
                    "{}: {element}: camera {} is degenerate (field of view {}°, or a singular transform); ignored",
                    path.display(),
                    cam.index(),
                    c.fov_y_deg
                ));
            }
        }
        if let Some(mesh) = node.mesh() {
            for prim in mesh.primitives() {
                if prim.mode() != ::gltf::mesh::Mode::Triangles {
                    continue;
                }
                let key = (mesh.index(), prim.index());
                let element = format!("mesh {} primitive {}", mesh.index(), prim.index());
                if let std::collections::hash_map::Entry::Vacant(slot) = raws.entry(key) {
                    slot.insert(read_primitive(&prim, &buffers).map_err(|m| err(&element, m))?);
                }
                let material = prim.material();
                let material = match materials.entry(material.index()) {
                    std::collections::hash_map::Entry::Occupied(m) => m.get().clone(),
                    std::collections::hash_map::Entry::Vacant(slot) => {
                        let what = match material.index() {
                            Some(i) => format!("material {i}"),
                            None => "the default material".into(),
                        };
                        slot.insert(map_material(&material).map_err(|m| err(&what, m))?)
                            .clone()
                    }
                };
                let name = mesh.name().map_or(element.clone(), str::to_string);
                uses.push((key.0, key.1, name, world, Some(material)));
            }
        }
        for child in node.children() {
            let seen = std::mem::replace(&mut reached[child.index()], true);
            if seen {
                return Err(err(
                    &format!("node {}", child.index()),
                    format!(
                        "is reached a second time, as a child of node {}: the node hierarchy has a cycle or a node with two parents (glTF requires a tree)",
                        node.index()
                    ),
                ));
            }
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
        warnings,
    })
}

/// `gltf-json`'s validation indexes the accessor of every primitive's
/// POSITION attribute without checking it (a panic for an index out of
/// range), so that index is checked here first.
fn check_position_accessors(root: &::gltf::json::Root) -> Result<(), (String, String)> {
    use ::gltf::json::mesh::Semantic;
    use ::gltf::json::validation::Checked;
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            if let Some(i) = prim.attributes.get(&Checked::Valid(Semantic::Positions))
                && i.value() >= root.accessors.len()
            {
                return Err((
                    format!("mesh {m} primitive {p}"),
                    format!(
                        "its POSITION is accessor {}, but the file has {} accessors",
                        i.value(),
                        root.accessors.len()
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// The chunks of a GLB file.
struct Glb<'a> {
    json: &'a [u8],
    bin: Option<&'a [u8]>,
}

/// Reads the GLB container (glTF 2.0 §4.4): a 12-byte header (`glTF`,
/// version 2, total length equal to the file's), then a JSON chunk and
/// optionally a BIN chunk, each an 8-byte header (length, type) and that
/// many bytes inside the file. Nothing is allocated.
fn parse_glb(data: &[u8]) -> Result<Glb<'_>, String> {
    let u32_at = |at: usize| -> Option<u32> {
        data.get(at..at + 4)
            .map(|b| u32::from_le_bytes(b.try_into().expect("4 bytes")))
    };
    let (Some(version), Some(length)) = (u32_at(4), u32_at(8)) else {
        return Err(format!(
            "the file has {} bytes, less than the 12 of a GLB header",
            data.len()
        ));
    };
    if version != 2 {
        return Err(format!("version {version}; only glTF 2 is supported"));
    }
    if length as usize != data.len() {
        return Err(format!(
            "the header gives a length of {length} bytes, but the file has {}",
            data.len()
        ));
    }
    let mut at = 12;
    let mut chunks = Vec::new();
    while at < data.len() {
        let (Some(chunk_length), Some(kind)) = (u32_at(at), u32_at(at + 4)) else {
            return Err(format!("chunk at byte {at} has a truncated header"));
        };
        let begin = at + 8;
        let end = begin
            .checked_add(chunk_length as usize)
            .filter(|&e| e <= data.len())
            .ok_or_else(|| {
                format!("chunk at byte {at} is {chunk_length} bytes long, past the end of the file")
            })?;
        chunks.push((kind, &data[begin..end]));
        // Chunks are 4-byte aligned.
        at = end.next_multiple_of(4);
    }
    const JSON: u32 = 0x4E4F_534A;
    const BIN: u32 = 0x004E_4942;
    match chunks.as_slice() {
        [(JSON, json), rest @ ..] => Ok(Glb {
            json,
            bin: rest.iter().find(|(k, _)| *k == BIN).map(|(_, b)| *b),
        }),
        _ => Err("the first chunk is not JSON".into()),
    }
}

/// Decodes a `data:` URI (RFC 2397) with base64 content; `None` if `uri` is
/// not a `data:` URI.
fn data_uri(uri: &str) -> Option<Result<Vec<u8>, String>> {
    let rest = uri.strip_prefix("data:")?;
    Some(match rest.split_once(',') {
        Some((meta, payload)) if meta.ends_with(";base64") => {
            base64::engine::general_purpose::STANDARD
                .decode(payload.trim_end())
                .map_err(|e| format!("its data: URI is not valid base64 ({e})"))
        }
        Some(_) => Err("its data: URI is not base64-encoded".into()),
        None => Err("its data: URI has no `,`".into()),
    })
}

/// Decodes the %XX escapes of a relative URI reference into a path.
fn percent_decode(uri: &str) -> Result<String, FileError> {
    let bad = |why: &str| FileError::Outside {
        reference: uri.to_string(),
        why: why.to_string(),
    };
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = uri
                .get(i + 1..i + 3)
                .and_then(|h| u8::from_str_radix(h, 16).ok())
                .ok_or_else(|| bad("a URI with a bad %-escape"))?;
            out.push(hex);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).map_err(|_| bad("a URI that is not UTF-8 once decoded"))
}

/// The file a relative URI names, inside `folder`.
fn uri_path(folder: &Path, uri: &str) -> Result<std::path::PathBuf, FileError> {
    resolve_inside(folder, &percent_decode(uri)?)
}

/// What is wrong with the URI `uri`, for a message.
fn uri_message(uri: &str, e: FileError) -> String {
    match e {
        FileError::Outside { why, .. } => format!(
            "URI `{uri}` is {why}; a model may refer only to files in its own folder or data: URIs"
        ),
        e => format!("URI `{uri}`: {e}"),
    }
}

/// Every buffer's bytes, at least as many as its `byteLength`.
fn load_buffers(
    doc: &::gltf::Document,
    folder: &Path,
    blob: Option<&[u8]>,
) -> Result<Vec<Vec<u8>>, (String, String)> {
    let mut out = Vec::new();
    for buffer in doc.buffers() {
        let element = format!("buffer {}", buffer.index());
        let fail = |m: String| (element.clone(), m);
        let data = match buffer.source() {
            ::gltf::buffer::Source::Bin => blob
                .ok_or_else(|| fail("refers to the GLB binary chunk, which the file lacks".into()))?
                .to_vec(),
            ::gltf::buffer::Source::Uri(uri) => match data_uri(uri) {
                Some(decoded) => decoded.map_err(fail)?,
                None => {
                    let file = uri_path(folder, uri).map_err(|e| fail(uri_message(uri, e)))?;
                    read_regular_file(&file).map_err(|e| fail(uri_message(uri, e)))?
                }
            },
        };
        if data.len() < buffer.length() {
            return Err(fail(format!(
                "has {} bytes, fewer than its byteLength {}",
                data.len(),
                buffer.length()
            )));
        }
        out.push(data);
    }
    Ok(out)
}

/// Images are not read, but their URIs must follow the rule for buffers.
fn check_images(doc: &::gltf::Document, folder: &Path) -> Result<(), (String, String)> {
    for image in doc.images() {
        if let ::gltf::image::Source::Uri { uri, .. } = image.source()
            && !uri.starts_with("data:")
        {
            match uri_path(folder, uri) {
                // A missing texture does not matter: glint does not use it.
                Ok(_) | Err(FileError::NotFound { .. }) => {}
                Err(e) => return Err((format!("image {}", image.index()), uri_message(uri, e))),
            }
        }
    }
    Ok(())
}

/// The bytes of accessor `accessor`, checked: `N` components per element
/// (`what` names the attribute in messages), not sparse, and every element
/// inside its buffer view and buffer. Returns the bytes from the first
/// element on, the stride between elements and the component size.
fn accessor_bytes<'b>(
    accessor: &::gltf::Accessor,
    buffers: &'b [Vec<u8>],
    components: usize,
    what: &str,
) -> Result<(&'b [u8], usize, usize), String> {
    let element = format!("its {what} (accessor {})", accessor.index());
    let dims = match accessor.dimensions() {
        Dimensions::Scalar => 1,
        Dimensions::Vec2 => 2,
        Dimensions::Vec3 => 3,
        Dimensions::Vec4 => 4,
        other => return Err(format!("{element} has type {other:?}")),
    };
    if dims != components {
        return Err(format!(
            "{element} has {dims} components; expected {components}"
        ));
    }
    if accessor.sparse().is_some() {
        return Err(format!("{element} is sparse, which is not supported"));
    }
    let count = accessor.count();
    if count == 0 {
        return Ok((&[], 0, 1));
    }
    let view = accessor
        .view()
        .ok_or_else(|| format!("{element} has no buffer view"))?;
    let size = match accessor.data_type() {
        DataType::I8 | DataType::U8 => 1,
        DataType::I16 | DataType::U16 => 2,
        DataType::U32 | DataType::F32 => 4,
    };
    let element_size = size * components;
    let stride = view.stride().unwrap_or(element_size);
    if stride < element_size {
        return Err(format!(
            "{element}: byteStride {stride} is less than its elements' {element_size} bytes"
        ));
    }
    let data = &buffers[view.buffer().index()];
    let view_end = view
        .offset()
        .checked_add(view.length())
        .filter(|&e| e <= data.len())
        .ok_or_else(|| {
            format!(
                "{element}: buffer view {} ends past the end of buffer {}",
                view.index(),
                view.buffer().index()
            )
        })?;
    let view_data = &data[view.offset()..view_end];
    let end = (count - 1)
        .checked_mul(stride)
        .and_then(|x| x.checked_add(accessor.offset()))
        .and_then(|x| x.checked_add(element_size))
        .filter(|&e| e <= view_data.len())
        .ok_or_else(|| {
            format!(
                "{element}: {count} elements from byte {} overrun buffer view {} ({} bytes)",
                accessor.offset(),
                view.index(),
                view_data.len()
            )
        })?;
    Ok((&view_data[accessor.offset()..end], stride, size))
}

/// Accessor `accessor` as `N`-component f32 elements; integer components
/// are converted, scaled to [0, 1] or [−1, 1] where normalised (glTF 2.0
/// §3.11).
fn read_accessor<const N: usize>(
    accessor: &::gltf::Accessor,
    buffers: &[Vec<u8>],
    what: &str,
) -> Result<Vec<[f32; N]>, String> {
    let (bytes, stride, size) = accessor_bytes(accessor, buffers, N, what)?;
    let (ty, normalized) = (accessor.data_type(), accessor.normalized());
    let component = |b: &[u8]| -> f32 {
        match ty {
            DataType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            DataType::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32,
            DataType::U8 if normalized => b[0] as f32 / 255.0,
            DataType::U8 => b[0] as f32,
            DataType::I8 if normalized => (b[0] as i8 as f32 / 127.0).max(-1.0),
            DataType::I8 => b[0] as i8 as f32,
            DataType::U16 if normalized => u16::from_le_bytes([b[0], b[1]]) as f32 / 65535.0,
            DataType::U16 => u16::from_le_bytes([b[0], b[1]]) as f32,
            DataType::I16 if normalized => {
                (i16::from_le_bytes([b[0], b[1]]) as f32 / 32767.0).max(-1.0)
            }
            DataType::I16 => i16::from_le_bytes([b[0], b[1]]) as f32,
        }
    };
    Ok((0..accessor.count())
        .map(|i| std::array::from_fn(|k| component(&bytes[i * stride + k * size..])))
        .collect())
}

/// Indices, exactly (u32 indices above 2^24 must not pass through f32).
fn read_indices(accessor: &::gltf::Accessor, buffers: &[Vec<u8>]) -> Result<Vec<u32>, String> {
    let (bytes, stride, _) = accessor_bytes(accessor, buffers, 1, "indices")?;
    let index: fn(&[u8]) -> u32 = match accessor.data_type() {
        DataType::U8 => |b| b[0] as u32,
        DataType::U16 => |b| u16::from_le_bytes([b[0], b[1]]) as u32,
        DataType::U32 => |b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
        other => {
            return Err(format!(
                "its indices (accessor {}) are {other:?}; expected unsigned integers",
                accessor.index()
            ));
        }
    };
    Ok((0..accessor.count())
        .map(|i| index(&bytes[i * stride..]))
        .collect())
}

fn read_primitive(prim: &::gltf::Primitive, buffers: &[Vec<u8>]) -> Result<RawMesh, String> {
    use ::gltf::Semantic;
    let positions: Vec<Vec3> = read_accessor::<3>(
        &prim.get(&Semantic::Positions).ok_or("has no positions")?,
        buffers,
        "positions",
    )?
    .into_iter()
    .map(Vec3::from)
    .collect();
    let indices = match prim.indices() {
        Some(a) => read_indices(&a, buffers)?,
        None => (0..positions.len() as u32).collect(),
    };
    if !indices.len().is_multiple_of(3) {
        return Err(format!("{} indices is not a multiple of 3", indices.len()));
    }
    let normals = match prim.get(&Semantic::Normals) {
        Some(a) => read_accessor::<3>(&a, buffers, "normals")?
            .into_iter()
            .map(Vec3::from)
            .collect(),
        None => Vec::new(),
    };
    let uvs = match prim.get(&Semantic::TexCoords(0)) {
        Some(a) => read_accessor::<2>(&a, buffers, "texture coordinates")?
            .into_iter()
            .map(Vec2::from)
            .collect(),
        None => Vec::new(),
    };
    Ok(RawMesh {
        triangles: indices
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect(),
        normals,
        uvs,
        positions,
        polygons: Vec::new(),
    })
}

/// Our material for a glTF material; its factors must be finite and within
/// the specification's ranges (base colour, metallic, roughness and
/// transmission in [0, 1], IOR ≥ 1), as values in scene files must.
fn map_material(m: &::gltf::Material) -> Result<Material, String> {
    let pbr = m.pbr_metallic_roughness();
    let unit = |name: &str, x: f32| {
        if (0.0..=1.0).contains(&x) {
            Ok(x)
        } else {
            Err(format!("{name} {x} is not a number from 0 to 1"))
        }
    };
    let [r, g, b, _] = pbr.base_color_factor();
    let base = Color::new(
        unit("baseColorFactor", r)?,
        unit("baseColorFactor", g)?,
        unit("baseColorFactor", b)?,
    );
    let roughness = unit("roughnessFactor", pbr.roughness_factor())?;
    let metallic = unit("metallicFactor", pbr.metallic_factor())?;
    // Blinn–Phong exponent of the same lobe width as GGX α = roughness²
    // (Walter et al. 2007: n = 2/α² − 2).
    let alpha = (roughness * roughness).max(1e-3);
    let shininess = (2.0 / (alpha * alpha) - 2.0).clamp(1.0, 1e4);
    let specular = 0.5 * (1.0 - roughness) * (1.0 - roughness);
    let transmission = unit(
        "transmissionFactor",
        m.transmission().map_or(0.0, |t| t.transmission_factor()),
    )?;
    let ior = m.ior().unwrap_or(1.5);
    // glTF allows an IOR of 0 too, meaning "no refraction"; glint has no such
    // medium, so it is read as the default.
    let ior = match ior {
        0.0 => 1.5,
        x if (1.0..1e6).contains(&x) => x,
        x => return Err(format!("ior {x} is not 0 or a number ≥ 1")),
    };
    // Emitted radiance: emissiveFactor × KHR_materials_emissive_strength.
    let strength = m.emissive_strength().unwrap_or(1.0);
    if !(strength >= 0.0 && strength.is_finite()) {
        return Err(format!("emissiveStrength {strength} is not a number ≥ 0"));
    }
    let [er, eg, eb] = m.emissive_factor();
    let emission = Color::new(
        unit("emissiveFactor", er)?,
        unit("emissiveFactor", eg)?,
        unit("emissiveFactor", eb)?,
    ) * strength;
    let mut material = Material {
        texture: Texture::Solid(base),
        ambient: 1.0,
        diffuse: 1.0,
        specular,
        shininess,
        kind: MaterialKind::Diffuse,
        emission,
        two_sided: m.double_sided(),
    };
    // glTF's metallic-roughness model, as it is: shading maps it to a BSDF
    // (for Whitted: diffuse, a mirror of the base colour when mostly metal,
    // glass when mostly transmissive).
    material.kind = MaterialKind::Principled {
        metallic,
        roughness,
        transmission,
        ior,
    };
    if metallic >= 0.5 || material.glass().is_some() {
        material.diffuse = 0.0;
        material.ambient = 0.0;
    }
    Ok(material)
}
