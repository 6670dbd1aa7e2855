//! Mesh loaders: small files written here (OBJ + MTL, PLY ASCII and binary in
//! both byte orders, glTF and GLB), loaded, and broken versions that must
//! give errors naming the file and the element.

use glint::scene::meshio::load_mesh_file;
use glint::scene::{MaterialKind, load_scene_file};
use std::path::{Path, PathBuf};

/// A unit tetrahedron: 4 vertices, 4 faces, wound outward.
const V: [[f32; 3]; 4] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, 0.0, 1.0],
];
const F: [[u32; 3]; 4] = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];

fn write(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn ply_header(format: &str, faces: usize) -> String {
    format!(
        "ply\nformat {format} 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
         property float nx\nproperty float ny\nproperty float nz\nelement face {faces}\nproperty list uchar int vertex_indices\nend_header\n"
    )
}

fn binary_ply(big: bool) -> Vec<u8> {
    let mut out = ply_header(
        if big {
            "binary_big_endian"
        } else {
            "binary_little_endian"
        },
        4,
    )
    .into_bytes();
    let f32b = |x: f32| {
        if big {
            x.to_be_bytes()
        } else {
            x.to_le_bytes()
        }
    };
    let i32b = |x: i32| {
        if big {
            x.to_be_bytes()
        } else {
            x.to_le_bytes()
        }
    };
    for v in V {
        for c in v {
            out.extend(f32b(c));
        }
        for c in [0.0, 0.0, 1.0] {
            out.extend(f32b(c));
        }
    }
    for f in F {
        out.push(3);
        for i in f {
            out.extend(i32b(i as i32));
        }
    }
    out
}

fn check_tetrahedron(path: &Path) {
    let model = load_mesh_file(path).unwrap_or_else(|e| panic!("{e}"));
    let m = &model.parts[0].mesh;
    assert_eq!(
        (m.positions.len(), m.triangles.len()),
        (4, 4),
        "{}",
        path.display()
    );
    let b = m.bounds();
    assert_eq!((b.min.to_array(), b.max.to_array()), ([0.0; 3], [1.0; 3]));
    // Closed: a point inside is inside.
    assert!(m.contains(glint::math::Vec3::splat(0.2)));
    assert!(!m.contains(glint::math::Vec3::splat(0.5)));
}

#[test]
fn ply_ascii_and_binary_both_byte_orders() {
    let dir = tempfile::tempdir().unwrap();
    let mut ascii = ply_header("ascii", 4);
    for v in V {
        ascii += &format!("{} {} {} 0 0 1\n", v[0], v[1], v[2]);
    }
    for f in F {
        ascii += &format!("3 {} {} {}\n", f[0], f[1], f[2]);
    }
    for (name, bytes) in [
        ("a.ply", ascii.into_bytes()),
        ("le.ply", binary_ply(false)),
        ("be.ply", binary_ply(true)),
    ] {
        let p = write(dir.path(), name, bytes);
        check_tetrahedron(&p);
        let model = load_mesh_file(&p).unwrap();
        assert_eq!(
            model.parts[0].mesh.normals.len(),
            4,
            "{name}: normals are read"
        );
    }
}

#[test]
fn ply_errors_name_the_element() {
    let dir = tempfile::tempdir().unwrap();
    // A face index out of range, in the binary fast path.
    let mut bad = binary_ply(false);
    let n = bad.len();
    bad[n - 4..].copy_from_slice(&9i32.to_le_bytes());
    let e = load_mesh_file(&write(dir.path(), "bad.ply", &bad))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("bad.ply: face 3: vertex index out of range"),
        "{e}"
    );
    // Truncated inside a face.
    let good = binary_ply(false);
    let e = load_mesh_file(&write(dir.path(), "cut.ply", &good[..good.len() - 5]))
        .unwrap_err()
        .to_string();
    assert!(e.contains("cut.ply: face") && e.contains("ends"), "{e}");
    // Truncated inside the vertices.
    let header = ply_header("binary_little_endian", 4).len();
    let e = load_mesh_file(&write(dir.path(), "cutv.ply", &good[..header + 30]))
        .unwrap_err()
        .to_string();
    assert!(e.contains("cutv.ply: vertex") && e.contains("ends"), "{e}");
    // A NaN coordinate.
    let mut nan = binary_ply(false);
    nan[header..header + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    let e = load_mesh_file(&write(dir.path(), "nan.ply", &nan))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("nan.ply: vertex 0") && e.contains("non-finite"),
        "{e}"
    );
    // No faces at all.
    let mut empty = ply_header("binary_little_endian", 0).into_bytes();
    empty.extend(&binary_ply(false)[header..header + 4 * 24]);
    let e = load_mesh_file(&write(dir.path(), "empty.ply", &empty))
        .unwrap_err()
        .to_string();
    assert!(e.contains("empty.ply: file: holds no triangles"), "{e}");
    // Missing file.
    let e = load_mesh_file(&dir.path().join("none.ply"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("none.ply") && e.contains("not found"), "{e}");
}

const MTL: &str = "newmtl red\nKd 0.8 0.1 0.1\nKs 0.5 0.5 0.5\nNs 100\nillum 2\n\
newmtl chrome\nKd 0.1 0.1 0.1\nKs 0.9 0.9 0.9\nillum 3\n\
newmtl glass\nKd 1 1 1\nNi 1.33\nillum 7\n";

#[test]
fn obj_with_mtl_materials_and_groups() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "m.mtl", MTL);
    let mut obj = String::from("mtllib m.mtl\n");
    for v in V {
        obj += &format!("v {} {} {}\n", v[0], v[1], v[2]);
    }
    // Two groups with different materials; the second a quad (split in two).
    obj += "o first\nusemtl red\ns 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
    obj += "v 2 0 0\nv 3 0 0\nv 3 1 0\nv 2 1 0\no second\nusemtl glass\nf 5 6 7 8\n";
    let p = write(dir.path(), "t.obj", &obj);
    let model = load_mesh_file(&p).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(model.parts.len(), 2);
    let (a, b) = (&model.parts[0], &model.parts[1]);
    assert_eq!(a.mesh.triangles.len(), 4);
    assert_eq!(b.mesh.triangles.len(), 2);
    assert_eq!(
        a.mesh.normals.len(),
        a.mesh.positions.len(),
        "smoothing groups give vertex normals"
    );
    let red = a.material.as_ref().unwrap();
    assert!(
        matches!(red.kind, MaterialKind::Diffuse) && red.specular == 0.5 && red.shininess == 100.0
    );
    assert!(
        matches!(b.material.as_ref().unwrap().kind, MaterialKind::Dielectric { ior, .. } if ior == 1.33)
    );
    let mirror_obj = obj.replace("usemtl glass", "usemtl chrome");
    let m = load_mesh_file(&write(dir.path(), "c.obj", mirror_obj)).unwrap();
    assert!(matches!(
        m.parts[1].material.as_ref().unwrap().kind,
        MaterialKind::Mirror { .. }
    ));
}

#[test]
fn obj_errors_name_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let e = load_mesh_file(&write(
        dir.path(),
        "b.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n",
    ))
    .unwrap_err()
    .to_string();
    assert!(e.contains("b.obj: line 4") && e.contains("vertex 7"), "{e}");
    let e = load_mesh_file(&write(
        dir.path(),
        "c.obj",
        "v 0 0 0\nv 1 zero 0\nv 0 1 0\nf 1 2 3\n",
    ))
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("c.obj: line 2") && e.contains("bad vertex"),
        "{e}"
    );
}

fn base64(data: &[u8]) -> String {
    const T: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in data.chunks(3) {
        let n = (c[0] as u32) << 16
            | (*c.get(1).unwrap_or(&0) as u32) << 8
            | *c.get(2).unwrap_or(&0) as u32;
        for k in 0..4 {
            if k <= c.len() {
                s.push(T[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// A glTF holding the tetrahedron mesh used by two nodes (an instance moved
/// by +5 in x inside a scaled parent), a transmissive material with an IOR,
/// and a camera.
fn gltf_json(buffer_uri: Option<&str>, length: usize) -> String {
    let uri = buffer_uri.map_or(String::new(), |u| format!("\"uri\": \"{u}\", "));
    format!(
        r#"{{
  "asset": {{"version": "2.0"}},
  "extensionsUsed": ["KHR_materials_transmission", "KHR_materials_ior"],
  "scene": 0,
  "scenes": [{{"nodes": [0, 1, 3]}}],
  "nodes": [
    {{"mesh": 0}},
    {{"scale": [2, 2, 2], "children": [2]}},
    {{"mesh": 0, "translation": [5, 0, 0]}},
    {{"camera": 0, "translation": [0, 0, 10]}}
  ],
  "cameras": [{{"type": "perspective", "perspective": {{"yfov": 0.7, "znear": 0.1}}}}],
  "materials": [{{"pbrMetallicRoughness": {{"baseColorFactor": [1, 1, 1, 1], "metallicFactor": 0, "roughnessFactor": 0}},
                 "extensions": {{"KHR_materials_transmission": {{"transmissionFactor": 1}}, "KHR_materials_ior": {{"ior": 1.7}}}}}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1, "material": 0}}]}}],
  "buffers": [{{{uri}"byteLength": {length}}}],
  "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 48}}, {{"buffer": 0, "byteOffset": 48, "byteLength": 48}}],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 1]}},
    {{"bufferView": 1, "componentType": 5125, "count": 12, "type": "SCALAR"}}
  ]
}}"#
    )
}

fn gltf_buffer() -> Vec<u8> {
    let mut b = Vec::new();
    for v in V {
        for c in v {
            b.extend(c.to_le_bytes());
        }
    }
    for f in F {
        for i in f {
            b.extend(i.to_le_bytes());
        }
    }
    b
}

#[test]
fn gltf_and_glb_with_instances_materials_and_camera() {
    let dir = tempfile::tempdir().unwrap();
    let buf = gltf_buffer();
    let uri = format!("data:application/octet-stream;base64,{}", base64(&buf));
    let gltf = write(dir.path(), "t.gltf", gltf_json(Some(&uri), buf.len()));
    // GLB: header, JSON chunk (padded with spaces), BIN chunk.
    let mut json = gltf_json(None, buf.len()).into_bytes();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut glb = Vec::new();
    let total = 12 + 8 + json.len() + 8 + buf.len();
    glb.extend(b"glTF");
    glb.extend(2u32.to_le_bytes());
    glb.extend((total as u32).to_le_bytes());
    glb.extend((json.len() as u32).to_le_bytes());
    glb.extend(b"JSON");
    glb.extend(&json);
    glb.extend((buf.len() as u32).to_le_bytes());
    glb.extend(b"BIN\0");
    glb.extend(&buf);
    let glb = write(dir.path(), "t.glb", glb);
    for path in [gltf, glb] {
        let model = load_mesh_file(&path).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(model.parts.len(), 2, "{}", path.display());
        assert!(
            std::sync::Arc::ptr_eq(&model.parts[0].mesh, &model.parts[1].mesh),
            "one mesh, two instances"
        );
        let mut xs: Vec<f32> = model
            .parts
            .iter()
            .map(|p| {
                glint::geometry::MeshInstance::new(p.mesh.clone(), p.transform.as_ref())
                    .bounds()
                    .max
                    .x
            })
            .collect();
        xs.sort_by(f32::total_cmp);
        // 1 untransformed; (5 + 1)·2 = 12 under the parent's scale.
        assert!(
            (xs[0] - 1.0).abs() < 1e-5 && (xs[1] - 12.0).abs() < 1e-4,
            "{xs:?}"
        );
        // The neutral material as the file gives it (shading makes it glass).
        let m = model.parts[0].material.as_ref().unwrap();
        assert!(
            matches!(m.kind, MaterialKind::Principled { ior, transmission, .. } if (ior - 1.7).abs() < 1e-6 && transmission == 1.0),
            "{:?}",
            m.kind
        );
        assert_eq!(m.glass(), Some((1.7, glint::math::Color::ZERO)));
        let cam = model.camera.as_ref().unwrap();
        assert_eq!(cam.position.to_array(), [0.0, 0.0, 10.0]);
        assert!((cam.fov_y_deg - 0.7f32.to_degrees()).abs() < 1e-4);
    }
    let e = load_mesh_file(&write(dir.path(), "broken.gltf", "{\"asset\": "))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("broken.gltf: file: cannot read it as glTF"),
        "{e}"
    );
    // Indices beyond the vertices.
    let mut bad = gltf_buffer();
    let n = bad.len();
    bad[n - 4..].copy_from_slice(&7u32.to_le_bytes());
    let uri = format!("data:application/octet-stream;base64,{}", base64(&bad));
    let e = load_mesh_file(&write(
        dir.path(),
        "idx.gltf",
        gltf_json(Some(&uri), bad.len()),
    ))
    .unwrap_err()
    .to_string();
    assert!(e.contains("idx.gltf: mesh 0 primitive 0, face 3"), "{e}");
}

#[test]
fn scene_file_meshes_with_override_and_missing_file() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("meshes")).unwrap();
    write(&dir.path().join("meshes"), "m.mtl", MTL);
    let mut obj = String::from("mtllib m.mtl\nusemtl red\n");
    for v in V {
        obj += &format!("v {} {} {}\n", v[0], v[1], v[2]);
    }
    obj += "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
    write(&dir.path().join("meshes"), "t.obj", obj);
    let scene = |extra: &str, file: &str| {
        format!(
            "[camera]\nposition = [0.3, 0.3, -3]\nlook_at = [0.3, 0.3, 0]\n[materials]\nblue = {{ type = \"diffuse\", color = [0, 0, 1] }}\n\
             [[object]]\nshape = \"mesh\"\nfile = \"{file}\"\n{extra}\n\
             [[object]]\nshape = \"mesh\"\nfile = \"{file}\"\ntransform = {{ translate = [3, 0, 0] }}\n"
        )
    };
    let p = write(dir.path(), "s.toml", scene("", "meshes/t.obj"));
    let f = load_scene_file(&p).unwrap_or_else(|e| panic!("{e}"));
    let g = f.scene.geometry_stats();
    assert_eq!(
        (g.meshes, g.instances, g.triangles, g.triangles_instanced),
        (1, 2, 4, 8)
    );
    // The file's material is used, then overridden by the object's.
    let m = &f.scene.materials[f.scene.objects[0].material as usize];
    assert_eq!(
        m.texture,
        glint::scene::Texture::Solid(glint::math::Color::new(0.8, 0.1, 0.1))
    );
    let p = write(
        dir.path(),
        "o.toml",
        scene("material = \"blue\"", "meshes/t.obj"),
    );
    let f = load_scene_file(&p).unwrap();
    assert_eq!(
        f.scene.materials[f.scene.objects[0].material as usize].texture,
        glint::scene::Texture::Solid(glint::math::Color::Z)
    );
    let p = write(dir.path(), "x.toml", scene("", "meshes/nothere.ply"));
    let e = load_scene_file(&p).unwrap_err().to_string();
    assert!(
        e.contains("x.toml:8:8: cannot load mesh `meshes/nothere.ply`")
            && e.contains("meshes/nothere.ply: file: not found"),
        "{e}"
    );
}
