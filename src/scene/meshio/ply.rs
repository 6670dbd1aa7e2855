//! PLY (Turk, "The PLY Polygon File Format", 1994): ASCII and binary, little
//! and big endian. Vertices `x y z` with optional normals `nx ny nz` and
//! texture coordinates (`u v`, `s t` or `texture_u texture_v`); faces as a
//! list property `vertex_indices` (or `vertex_index`), polygons split into
//! triangle fans; other elements and properties are skipped.
//!
//! The file is read into memory once and parsed without allocating per
//! element. In binary files whose vertex records and triangle records have a
//! fixed size (the common case), the records are decoded in parallel.

use super::{MeshError, RawMesh};
use crate::scene::files::read_regular_file;
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::path::Path;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Format {
    Ascii,
    Little,
    Big,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Type {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Type {
    fn parse(s: &str) -> Option<Type> {
        Some(match s {
            "char" | "int8" => Type::I8,
            "uchar" | "uint8" => Type::U8,
            "short" | "int16" => Type::I16,
            "ushort" | "uint16" => Type::U16,
            "int" | "int32" => Type::I32,
            "uint" | "uint32" => Type::U32,
            "float" | "float32" => Type::F32,
            "double" | "float64" => Type::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Type::I8 | Type::U8 => 1,
            Type::I16 | Type::U16 => 2,
            Type::I32 | Type::U32 | Type::F32 => 4,
            Type::F64 => 8,
        }
    }

    /// Decodes a value from the first `size()` bytes of `b`.
    #[inline(always)]
    fn read(self, b: &[u8], big: bool) -> f64 {
        macro_rules! get {
            ($t:ty, $n:expr) => {{
                let a: [u8; $n] = b[..$n].try_into().expect("slice has the type's size");
                if big {
                    <$t>::from_be_bytes(a) as f64
                } else {
                    <$t>::from_le_bytes(a) as f64
                }
            }};
        }
        match self {
            Type::I8 => b[0] as i8 as f64,
            Type::U8 => b[0] as f64,
            Type::I16 => get!(i16, 2),
            Type::U16 => get!(u16, 2),
            Type::I32 => get!(i32, 4),
            Type::U32 => get!(u32, 4),
            Type::F32 => get!(f32, 4),
            Type::F64 => get!(f64, 8),
        }
    }
}

#[derive(Clone, Debug)]
enum Property {
    Scalar {
        name: String,
        ty: Type,
    },
    List {
        name: String,
        count: Type,
        item: Type,
    },
}

#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: usize,
    properties: Vec<Property>,
}

impl Element {
    /// Size of a record if every property is a scalar.
    fn fixed_size(&self) -> Option<usize> {
        self.properties
            .iter()
            .map(|p| match p {
                Property::Scalar { ty, .. } => Some(ty.size()),
                Property::List { .. } => None,
            })
            .sum()
    }

    /// Index and byte offset (in a fixed-size record) of a scalar property.
    fn scalar(&self, names: &[&str]) -> Option<(usize, usize, Type)> {
        let mut offset = 0;
        for (i, p) in self.properties.iter().enumerate() {
            match p {
                Property::Scalar { name, ty } => {
                    if names.contains(&name.as_str()) {
                        return Some((i, offset, *ty));
                    }
                    offset += ty.size();
                }
                Property::List { .. } => return None,
            }
        }
        None
    }
}

/// Reads a PLY file.
pub fn read(path: &Path) -> Result<RawMesh, MeshError> {
    let data = read_regular_file(path).map_err(|e| MeshError::file(path, &e))?;
    parse(path, &data)
}

/// Parses PLY data; `path` names the file in errors.
pub fn parse(path: &Path, data: &[u8]) -> Result<RawMesh, MeshError> {
    let err = |element: String, message: String| MeshError::new(path, &element, message);
    let header_end = find(data, b"end_header")
        .ok_or_else(|| err("header".into(), "no `end_header` line".into()))?;
    let mut body = header_end + b"end_header".len();
    // The header ends with the newline after `end_header` (LF or CRLF).
    if data.get(body) == Some(&b'\r') {
        body += 1;
    }
    if data.get(body) == Some(&b'\n') {
        body += 1;
    }
    let header = std::str::from_utf8(&data[..header_end])
        .map_err(|_| err("header".into(), "not ASCII text".into()))?;
    let mut lines = header.lines().enumerate();
    if lines.next().map(|(_, l)| l.trim()) != Some("ply") {
        return Err(err(
            "header line 1".into(),
            "expected `ply` (not a PLY file)".into(),
        ));
    }
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    for (i, line) in lines {
        let at = || format!("header line {}", i + 1);
        let words: Vec<&str> = line.split_ascii_whitespace().collect();
        match words.as_slice() {
            [] | ["comment", ..] | ["obj_info", ..] => {}
            ["format", f, _version] => {
                format = Some(match *f {
                    "ascii" => Format::Ascii,
                    "binary_little_endian" => Format::Little,
                    "binary_big_endian" => Format::Big,
                    other => return Err(err(at(), format!("unknown format `{other}`"))),
                })
            }
            ["element", name, count] => {
                // Vertices and faces are read by name: a second element of
                // either name would be ambiguous.
                if matches!(*name, "vertex" | "face") && elements.iter().any(|e| e.name == *name) {
                    return Err(err(at(), format!("a second `{name}` element")));
                }
                elements.push(Element {
                    name: name.to_string(),
                    count: count
                        .parse()
                        .map_err(|_| err(at(), format!("bad element count `{count}`")))?,
                    properties: Vec::new(),
                })
            }
            ["property", "list", count, item, name] => {
                let (Some(count), Some(item)) = (Type::parse(count), Type::parse(item)) else {
                    return Err(err(at(), format!("unknown list types `{count} {item}`")));
                };
                if matches!(count, Type::F32 | Type::F64) {
                    return Err(err(
                        at(),
                        "a list's length must be an integer type, not float or double".into(),
                    ));
                }
                elements
                    .last_mut()
                    .ok_or_else(|| err(at(), "property before any element".into()))?
                    .properties
                    .push(Property::List {
                        name: name.to_string(),
                        count,
                        item,
                    });
            }
            ["property", ty, name] => {
                let ty = Type::parse(ty)
                    .ok_or_else(|| err(at(), format!("unknown property type `{ty}`")))?;
                elements
                    .last_mut()
                    .ok_or_else(|| err(at(), "property before any element".into()))?
                    .properties
                    .push(Property::Scalar {
                        name: name.to_string(),
                        ty,
                    });
            }
            _ => return Err(err(at(), format!("cannot read `{}`", line.trim()))),
        }
    }
    let format = format.ok_or_else(|| err("header".into(), "no `format` line".into()))?;
    let vertex = elements
        .iter()
        .position(|e| e.name == "vertex")
        .ok_or_else(|| err("header".into(), "no `vertex` element".into()))?;
    for axis in ["x", "y", "z"] {
        if !elements[vertex]
            .properties
            .iter()
            .any(|p| matches!(p, Property::Scalar { name, .. } if name == axis))
        {
            return Err(err(
                "header".into(),
                format!("the vertex element has no property `{axis}`"),
            ));
        }
    }
    let mut mesh = RawMesh::default();
    let body = &data[body..];
    match format {
        Format::Ascii => {
            let text = std::str::from_utf8(body)
                .map_err(|_| err("body".into(), "not ASCII text".into()))?;
            ascii(&elements, text, &mut mesh, &err)?;
        }
        Format::Little | Format::Big => {
            binary(&elements, body, format == Format::Big, &mut mesh, &err)?
        }
    }
    let n = mesh.positions.len();
    if let Some(face) = mesh
        .triangles
        .par_iter()
        .position_first(|t| t.iter().any(|&v| v as usize >= n))
    {
        return Err(err(
            format!("face {}", mesh.face_of_triangle(face)),
            format!(
                "vertex index out of range ({} vertices)",
                mesh.positions.len()
            ),
        ));
    }
    Ok(mesh)
}

fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    haystack.windows(needle.len()).position(|w| w == needle)
}

/// Names of the attributes read from vertices, by role.
const X: &[&str] = &["x"];
const Y: &[&str] = &["y"];
const Z: &[&str] = &["z"];
const NX: &[&str] = &["nx"];
const NY: &[&str] = &["ny"];
const NZ: &[&str] = &["nz"];
const U: &[&str] = &["u", "s", "texture_u"];
const V: &[&str] = &["v", "t", "texture_v"];

fn role(name: &str) -> Option<usize> {
    [X, Y, Z, NX, NY, NZ, U, V]
        .iter()
        .position(|names| names.contains(&name))
}

type ErrFn<'a> = dyn Fn(String, String) -> MeshError + 'a;

/// Stores the 8 vertex attributes (x y z nx ny nz u v) of vertex `i`.
fn store(mesh: &mut RawMesh, has_normals: bool, has_uvs: bool, a: &[f32; 8]) {
    mesh.positions.push(Vec3::new(a[0], a[1], a[2]));
    if has_normals {
        mesh.normals.push(Vec3::new(a[3], a[4], a[5]));
    }
    if has_uvs {
        mesh.uvs.push(Vec2::new(a[6], a[7]));
    }
}

fn vertex_roles(e: &Element) -> (Vec<Option<usize>>, bool, bool) {
    let roles: Vec<Option<usize>> = e
        .properties
        .iter()
        .map(|p| match p {
            Property::Scalar { name, .. } => role(name),
            Property::List { .. } => None,
        })
        .collect();
    let has = |r: usize| roles.contains(&Some(r));
    (roles.clone(), has(3) && has(4) && has(5), has(6) && has(7))
}

/// Appends the triangles of a polygon as a fan.
fn push_polygon(
    mesh: &mut RawMesh,
    face: usize,
    indices: &[u32],
    err: &ErrFn,
) -> Result<(), MeshError> {
    if indices.len() < 3 {
        return Err(err(
            format!("face {face}"),
            format!("has {} vertices; a face needs at least 3", indices.len()),
        ));
    }
    if indices.len() > 3 {
        mesh.polygons.push((
            mesh.triangles.len() as u32,
            face as u32,
            indices.len() as u32 - 2,
        ));
    }
    for k in 1..indices.len() - 1 {
        mesh.triangles
            .push([indices[0], indices[k], indices[k + 1]]);
    }
    Ok(())
}

fn face_list(e: &Element) -> Option<usize> {
    e.properties
        .iter()
        .position(|p| matches!(p, Property::List { name, .. } if name == "vertex_indices" || name == "vertex_index"))
}

fn ascii(
    elements: &[Element],
    text: &str,
    mesh: &mut RawMesh,
    err: &ErrFn,
) -> Result<(), MeshError> {
    let mut tokens = text.split_ascii_whitespace();
    let mut polygon: Vec<u32> = Vec::new();
    for e in elements {
        // Records without properties take no text: nothing to read, however
        // many the header declares (a count of 10^18 must not loop).
        if e.properties.is_empty() {
            continue;
        }
        let (roles, has_normals, has_uvs) = vertex_roles(e);
        let list = face_list(e);
        for i in 0..e.count {
            let at = || format!("{} {i}", e.name);
            let mut next = |what: &str| -> Result<f64, MeshError> {
                let tok = tokens
                    .next()
                    .ok_or_else(|| err(at(), format!("file ends before its {what}")))?;
                tok.parse::<f64>()
                    .map_err(|_| err(at(), format!("`{tok}` is not a number ({what})")))
            };
            let mut attributes = [0f32; 8];
            for (k, p) in e.properties.iter().enumerate() {
                match p {
                    Property::Scalar { name, .. } => {
                        let v = next(name)?;
                        if e.name == "vertex"
                            && let Some(r) = roles[k]
                        {
                            attributes[r] = v as f32;
                        }
                    }
                    Property::List { name, .. } => {
                        let n = next(name)?;
                        if !(n >= 0.0 && n == n.round()) {
                            return Err(err(at(), format!("bad list length `{n}`")));
                        }
                        polygon.clear();
                        for _ in 0..n as usize {
                            let v = next(name)?;
                            if Some(k) == list {
                                if !(v >= 0.0 && v == v.round() && v < u32::MAX as f64) {
                                    return Err(err(at(), format!("bad vertex index `{v}`")));
                                }
                                polygon.push(v as u32);
                            }
                        }
                        if Some(k) == list && e.name == "face" {
                            push_polygon(mesh, i, &polygon, err)?;
                        }
                    }
                }
            }
            if e.name == "vertex" {
                store(mesh, has_normals, has_uvs, &attributes);
            }
        }
    }
    Ok(())
}

fn binary(
    elements: &[Element],
    mut body: &[u8],
    big: bool,
    mesh: &mut RawMesh,
    err: &ErrFn,
) -> Result<(), MeshError> {
    for e in elements {
        let is_vertex = e.name == "vertex";
        let is_face = e.name == "face";
        if let Some(size) = e.fixed_size() {
            let bytes = size
                .checked_mul(e.count)
                .filter(|&n| n <= body.len())
                .ok_or_else(|| {
                    err(
                        format!("{} {}", e.name, body.len() / size.max(1)),
                        "file ends inside it".into(),
                    )
                })?;
            if is_vertex {
                vertices_fixed(e, &body[..bytes], size, big, mesh);
            }
            body = &body[bytes..];
            continue;
        }
        if is_face && let Some(consumed) = triangles_fixed(e, body, big, mesh) {
            body = &body[consumed..];
            continue;
        }
        // General records: walk them one by one.
        let (roles, has_normals, has_uvs) = vertex_roles(e);
        let list = face_list(e);
        let mut polygon: Vec<u32> = Vec::new();
        let mut pos = 0usize;
        for i in 0..e.count {
            let at = || format!("{} {i}", e.name);
            let mut attributes = [0f32; 8];
            for (k, p) in e.properties.iter().enumerate() {
                match p {
                    Property::Scalar { ty, .. } => {
                        let b = body
                            .get(pos..pos + ty.size())
                            .ok_or_else(|| err(at(), "file ends inside it".into()))?;
                        if is_vertex && let Some(r) = roles[k] {
                            attributes[r] = ty.read(b, big) as f32;
                        }
                        pos += ty.size();
                    }
                    Property::List { count, item, .. } => {
                        let b = body
                            .get(pos..pos + count.size())
                            .ok_or_else(|| err(at(), "file ends inside it".into()))?;
                        let n = count.read(b, big);
                        if n.is_nan() || n < 0.0 {
                            return Err(err(at(), format!("bad list length {n}")));
                        }
                        pos += count.size();
                        // Checked: a length past the file must not wrap around.
                        let items = (n as usize)
                            .checked_mul(item.size())
                            .and_then(|len| Some(pos..pos.checked_add(len)?))
                            .and_then(|range| body.get(range))
                            .ok_or_else(|| err(at(), "file ends inside it".into()))?;
                        let len = items.len();
                        if Some(k) == list && is_face {
                            polygon.clear();
                            for c in items.chunks_exact(item.size()) {
                                let v = item.read(c, big);
                                if !(v >= 0.0 && v < u32::MAX as f64) {
                                    return Err(err(at(), format!("bad vertex index {v}")));
                                }
                                polygon.push(v as u32);
                            }
                            push_polygon(mesh, i, &polygon, err)?;
                        }
                        pos += len;
                    }
                }
            }
            if is_vertex {
                store(mesh, has_normals, has_uvs, &attributes);
            }
        }
        body = &body[pos..];
    }
    Ok(())
}

/// Fixed-size vertex records, decoded in parallel.
fn vertices_fixed(e: &Element, data: &[u8], size: usize, big: bool, mesh: &mut RawMesh) {
    let field = |names: &[&str]| e.scalar(names).map(|(_, offset, ty)| (offset, ty));
    let get = |record: &[u8], f: Option<(usize, Type)>| {
        f.map_or(0.0, |(o, ty)| ty.read(&record[o..], big) as f32)
    };
    let (x, y, z) = (field(X), field(Y), field(Z));
    let (nx, ny, nz) = (field(NX), field(NY), field(NZ));
    let (u, v) = (field(U), field(V));
    mesh.positions = data
        .par_chunks_exact(size)
        .map(|r| Vec3::new(get(r, x), get(r, y), get(r, z)))
        .collect();
    if nx.is_some() && ny.is_some() && nz.is_some() {
        mesh.normals = data
            .par_chunks_exact(size)
            .map(|r| Vec3::new(get(r, nx), get(r, ny), get(r, nz)))
            .collect();
    }
    if u.is_some() && v.is_some() {
        mesh.uvs = data
            .par_chunks_exact(size)
            .map(|r| Vec2::new(get(r, u), get(r, v)))
            .collect();
    }
}

/// Faces that are all triangles with only the index list: fixed-size
/// records, checked and decoded in parallel. Returns the bytes consumed, or
/// `None` if the records are not all like that (then the general path runs).
fn triangles_fixed(e: &Element, body: &[u8], big: bool, mesh: &mut RawMesh) -> Option<usize> {
    let [Property::List { count, item, .. }] = e.properties.as_slice() else {
        return None;
    };
    face_list(e)?;
    let size = count.size() + 3 * item.size();
    let bytes = size.checked_mul(e.count).filter(|&n| n <= body.len())?;
    let data = &body[..bytes];
    let all_triangles = data
        .par_chunks_exact(size)
        .all(|r| count.read(r, big) == 3.0);
    if !all_triangles {
        return None;
    }
    let (c, s) = (count.size(), item.size());
    let index = |r: &[u8], k: usize| {
        let v = item.read(&r[c + k * s..], big);
        if v >= 0.0 && v < u32::MAX as f64 {
            v as u32
        } else {
            u32::MAX
        }
    };
    mesh.triangles = data
        .par_chunks_exact(size)
        .map(|r| [index(r, 0), index(r, 1), index(r, 2)])
        .collect();
    Some(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ascii_cube_face() -> String {
        "ply\nformat ascii 1.0\ncomment test\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
         element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n"
            .to_string()
    }

    #[test]
    fn ascii_quad_becomes_two_triangles() {
        let m = parse(Path::new("q.ply"), ascii_cube_face().as_bytes()).unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    }

    #[test]
    fn errors_name_the_element() {
        let bad = ascii_cube_face().replace("4 0 1 2 3", "4 0 1 2 9");
        let e = parse(Path::new("q.ply"), bad.as_bytes())
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("q.ply: face 0: vertex index out of range"),
            "{e}"
        );
        let bad = ascii_cube_face().replace("1 1 0\n", "1 one 0\n");
        let e = parse(Path::new("q.ply"), bad.as_bytes())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("vertex 2") && e.contains("`one` is not a number"),
            "{e}"
        );
        let bad = ascii_cube_face().replace("4 0 1 2 3\n", "");
        let e = parse(Path::new("q.ply"), bad.as_bytes())
            .unwrap_err()
            .to_string();
        assert!(e.contains("face 0") && e.contains("file ends"), "{e}");
        let e = parse(Path::new("q.ply"), b"plx\nformat ascii 1.0\nend_header\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a PLY file"), "{e}");
        let bad = ascii_cube_face().replace("format ascii", "format binary_middle_endian");
        assert!(
            parse(Path::new("q.ply"), bad.as_bytes())
                .unwrap_err()
                .to_string()
                .contains("header line 2")
        );
    }
}
