//! Hostile input: files that once crashed, hung, ran out of memory, read
//! outside a model's folder or rendered NaN. Each must end in an error that
//! names the file and the element (or, where the format allows it, load).

use glint::scene::meshio::load_mesh_file;
use glint::scene::{Texture, load_scene_file};
use std::path::{Path, PathBuf};

fn write(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
    let p = dir.join(name);
    if let Some(parent) = p.parent() {
        std::fs::create_dir_all(parent).unwrap();
    }
    std::fs::write(&p, bytes).unwrap();
    p
}

/// The error of loading `path`, as text.
fn load_error(path: &Path) -> String {
    match load_mesh_file(path) {
        Ok(_) => panic!("{} loaded", path.display()),
        Err(e) => e.to_string(),
    }
}

const TETRA_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";

fn obj_with(dir: &Path, mtl: &str) -> PathBuf {
    write(dir, "m.mtl", mtl);
    write(dir, "m.obj", format!("mtllib m.mtl\nusemtl a\n{TETRA_OBJ}"))
}

#[test]
fn mtl_colours_with_one_or_two_values_follow_the_specification() {
    let dir = tempfile::tempdir().unwrap();
    for (line, expected) in [
        ("Kd 0.8", [0.8, 0.8, 0.8]),
        ("Kd 0.8 0.4", [0.8, 0.4, 0.8]),
        ("Kd 0.8 0.4 0.2", [0.8, 0.4, 0.2]),
    ] {
        let obj = obj_with(dir.path(), &format!("newmtl a\n{line}\nKs 0.5\n"));
        let model = load_mesh_file(&obj).unwrap_or_else(|e| panic!("{line}: {e}"));
        let m = model.parts[0].material.as_ref().unwrap();
        assert_eq!(
            m.texture,
            Texture::Solid(glint::math::Color::from_array(expected)),
            "{line}"
        );
        assert_eq!(m.specular, 0.5);
    }
}

#[test]
fn non_finite_or_negative_file_colours_are_errors_naming_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    for line in [
        "Kd nan 0 0",
        "Kd 1e39 1 1",
        "Ks nan 0.5 0.5",
        "Kd -1 0 0",
        "Kd inf",
        "Ns nan",
        "Ni -2",
        "d 7",
    ] {
        let obj = obj_with(dir.path(), &format!("newmtl a\n{line}\n"));
        let e = load_error(&obj);
        assert!(e.contains("m.mtl: line 2:"), "{line}: {e}");
    }
    // The same rules for glTF factors.
    for factor in [
        r#""baseColorFactor": [1e39, 1, 1, 1]"#,
        r#""baseColorFactor": [-1, 1, 1, 1]"#,
        r#""roughnessFactor": 3"#,
    ] {
        let path = write(
            dir.path(),
            "c.gltf",
            gltf(&Gltf {
                material: format!(r#"{{"pbrMetallicRoughness": {{{factor}}}}}"#),
                ..Gltf::default()
            }),
        );
        let e = load_error(&path);
        assert!(e.contains("c.gltf: material 0:"), "{factor}: {e}");
    }
    // Vertices.
    let path = write(
        dir.path(),
        "v.obj",
        TETRA_OBJ.replace("v 1 0 0", "v 1 nan 0"),
    );
    assert!(load_error(&path).contains("v.obj: line 2:"));
    let path = write(
        dir.path(),
        "w.obj",
        TETRA_OBJ.replace("v 1 0 0", "v 1 1e39 0"),
    );
    assert!(load_error(&path).contains("w.obj: line 2:"));
}

#[test]
fn a_missing_material_library_is_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let obj = write(
        dir.path(),
        "m.obj",
        format!("mtllib gone.mtl\nusemtl a\n{TETRA_OBJ}"),
    );
    let model = load_mesh_file(&obj).unwrap();
    assert!(model.parts[0].material.is_none());
    assert_eq!(model.warnings.len(), 1);
    assert!(
        model.warnings[0].contains("m.obj: material library `gone.mtl` not found")
            && model.warnings[0].contains("gone.mtl`"),
        "{:?}",
        model.warnings
    );
}

#[test]
fn model_references_outside_the_folder_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "secret.mtl", "newmtl a\nKd 1 0 0\n");
    write(dir.path(), "secret.bin", [0u8; 96]);
    let model = dir.path().join("model");
    for lib in ["../secret.mtl", "/etc/passwd", "file:///etc/passwd"] {
        let obj = write(
            &model,
            "m.obj",
            format!("mtllib {lib}\nusemtl a\n{TETRA_OBJ}"),
        );
        let e = load_error(&obj);
        assert!(
            e.contains(&format!("`{lib}`")) && e.contains("own folder"),
            "{lib}: {e}"
        );
    }
    for uri in [
        "../secret.bin",
        "../../../../../../etc/passwd",
        "/etc/passwd",
        "file:///etc/passwd",
        "/dev/zero",
        "sub/../../secret.bin",
        "%2E%2E/secret.bin",
    ] {
        let path = write(
            &model,
            "t.gltf",
            gltf(&Gltf {
                buffer_uri: Some(uri.into()),
                ..Gltf::default()
            }),
        );
        let e = load_error(&path);
        assert!(
            e.contains("t.gltf: buffer 0:") && e.contains(&format!("`{uri}`")),
            "{uri}: {e}"
        );
    }
    let path = write(
        &model,
        "i.gltf",
        gltf(&Gltf {
            images: r#""images": [{"uri": "../secret.png"}],"#.into(),
            ..Gltf::default()
        }),
    );
    let e = load_error(&path);
    assert!(e.contains("i.gltf: image 0: URI `../secret.png`"), "{e}");
    #[cfg(unix)]
    {
        // A link inside the folder that leads out.
        std::os::unix::fs::symlink(dir.path().join("secret.bin"), model.join("link.bin")).unwrap();
        let path = write(
            &model,
            "l.gltf",
            gltf(&Gltf {
                buffer_uri: Some("link.bin".into()),
                ..Gltf::default()
            }),
        );
        assert!(load_error(&path).contains("outside the model's folder"));
    }
    // Inside the folder, the same file loads.
    write(&model, "data/tetra.bin", buffer());
    let path = write(
        &model,
        "ok.gltf",
        gltf(&Gltf {
            buffer_uri: Some("data/tetra.bin".into()),
            ..Gltf::default()
        }),
    );
    load_mesh_file(&path).unwrap();
}

#[cfg(unix)]
#[test]
fn special_files_are_refused_not_read() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["zero.ply", "zero.obj", "zero.gltf", "zero.glb", "zero.toml"] {
        let link = dir.path().join(name);
        std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
        let e = if name.ends_with(".toml") {
            load_scene_file(&link).unwrap_err().to_string()
        } else {
            load_error(&link)
        };
        assert!(
            e.contains(name) && e.contains("character device, not a regular file"),
            "{e}"
        );
    }
    let fifo = dir.path().join("pipe.ply");
    let made = std::process::Command::new("mkfifo").arg(&fifo).status();
    if made.is_ok_and(|s| s.success()) {
        // Opening a FIFO for reading would block until a writer comes.
        assert!(load_error(&fifo).contains("a FIFO, not a regular file"));
    }
    let e = load_error(&dir.path().join("missing.ply"));
    assert!(e.contains("missing.ply: file: not found"), "{e}");
}

#[test]
fn gltf_node_cycles_and_shared_children_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    for (nodes, roots, culprit) in [
        (r#"[{"mesh": 0, "children": [0]}]"#, "[0]", "node 0"),
        (
            r#"[{"mesh": 0, "children": [1]}, {"children": [2]}, {"children": [1]}]"#,
            "[0]",
            "node 1",
        ),
        (
            r#"[{"mesh": 0, "children": [2]}, {"children": [2]}, {"mesh": 0}]"#,
            "[0, 1]",
            "node 2",
        ),
    ] {
        let path = write(
            dir.path(),
            "cycle.gltf",
            gltf(&Gltf {
                nodes: nodes.into(),
                roots: roots.into(),
                ..Gltf::default()
            }),
        );
        let e = load_error(&path);
        assert!(
            e.contains(&format!("cycle.gltf: {culprit}: is reached a second time")),
            "{nodes}: {e}"
        );
    }
}

#[test]
fn glb_lengths_are_checked_before_anything_is_allocated() {
    let dir = tempfile::tempdir().unwrap();
    let mut header = b"glTF".to_vec();
    header.extend(2u32.to_le_bytes());
    header.extend(4u32.to_le_bytes());
    let e = load_error(&write(dir.path(), "short.glb", &header));
    assert!(
        e.contains(
            "short.glb: GLB header: the header gives a length of 4 bytes, but the file has 12"
        ),
        "{e}"
    );
    // A chunk claiming 4 GiB.
    let mut glb = b"glTF".to_vec();
    glb.extend(2u32.to_le_bytes());
    glb.extend(20u32.to_le_bytes());
    glb.extend(u32::MAX.to_le_bytes());
    glb.extend(b"JSON");
    let e = load_error(&write(dir.path(), "huge.glb", &glb));
    assert!(e.contains("huge.glb: GLB header: chunk at byte 12"), "{e}");
    let e = load_error(&write(dir.path(), "tiny.glb", b"glTF"));
    assert!(e.contains("less than the 12 of a GLB header"), "{e}");
    // An accessor that claims more than its buffer holds.
    let path = write(
        dir.path(),
        "acc.gltf",
        gltf(&Gltf {
            position_count: 4_000_000_000,
            ..Gltf::default()
        }),
    );
    let e = load_error(&path);
    assert!(
        e.contains("acc.gltf: mesh 0 primitive 0: its positions (accessor 0)"),
        "{e}"
    );
}

#[test]
fn ply_elements_without_properties_do_not_loop() {
    let dir = tempfile::tempdir().unwrap();
    let ply = "ply\nformat ascii 1.0\nelement nothing 1000000000000000000\n\
               element vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
               element face 1\nproperty list uchar int vertex_indices\nend_header\n\
               0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    let model = load_mesh_file(&write(dir.path(), "p.ply", ply)).unwrap();
    assert_eq!(model.triangles(), 1);
}

#[test]
fn formulas_nested_ten_thousand_deep_are_located_errors() {
    let dir = tempfile::tempdir().unwrap();
    let deep = format!("{}x{}", "(".repeat(10_000), ")".repeat(10_000));
    let scene = format!(
        "[camera]\nposition = [0, 0, -5]\nlook_at = [0, 0, 0]\n\n[[object]]\nshape = \"implicit\"\nf = \"{deep}\"\nbounds = [[-1, -1, -1], [1, 1, 1]]\n"
    );
    let e = load_scene_file(&write(dir.path(), "deep.toml", scene))
        .unwrap_err()
        .to_string();
    // Line 7, at the 101st `(` (after `f = "`).
    assert!(
        e.contains("deep.toml:7:107: in formula:") && e.contains("100 levels deep"),
        "{e}"
    );
}

#[test]
fn scene_new_reports_a_bad_material_index() {
    use glint::scene::{Camera, Object, Scene};
    let camera = Camera::try_new(
        glint::math::Vec3::Z,
        glint::math::Vec3::ZERO,
        glint::math::Vec3::Y,
        40.0,
    )
    .unwrap();
    let object = Object {
        shape: glint::geometry::Shape::Sphere(glint::geometry::Sphere::new(
            glint::math::Vec3::ZERO,
            1.0,
        )),
        material: 3,
    };
    let e = Scene::new(
        camera,
        vec![object],
        vec![glint::scene::Material::default_diffuse()],
        Vec::new(),
        glint::math::Color::ZERO,
        glint::math::Color::ZERO,
    )
    .unwrap_err();
    assert_eq!(
        e.to_string(),
        "object 0 has material 3, but there are only 1 materials"
    );
}

/// An emissive mesh instanced 256 times would make 5 million area
/// lights (half a gigabyte): refused with a clear error before any is made.
#[test]
fn too_many_emissive_triangles_is_an_error() {
    use glint::geometry::{Mesh, MeshInstance, Shape, testgen::icosphere};
    use glint::scene::{Camera, Material, Object, Scene};
    use std::sync::Arc;
    let (positions, triangles) = icosphere(5, 1.0);
    let mesh = Arc::new(Mesh::new(positions, triangles, Vec::new(), Vec::new()).unwrap());
    let count = mesh.triangles.len();
    let lamp = Material {
        emission: glint::math::Color::ONE,
        ..Material::default_diffuse()
    };
    let objects: Vec<Object> = (0..256)
        .map(|_| Object {
            shape: Shape::Mesh(MeshInstance::new(mesh.clone(), None)),
            material: 0,
        })
        .collect();
    let camera = Camera::try_new(
        glint::math::Vec3::Z,
        glint::math::Vec3::ZERO,
        glint::math::Vec3::Y,
        40.0,
    )
    .unwrap();
    let e = Scene::new(
        camera,
        objects,
        vec![lamp],
        Vec::new(),
        glint::math::Color::ZERO,
        glint::math::Color::ZERO,
    )
    .unwrap_err();
    assert!(
        e.to_string()
            .contains(&format!("{} emissive triangles", 256 * count)),
        "{e}"
    );
}

/// The parts of a one-mesh glTF that tests vary.
struct Gltf {
    buffer_uri: Option<String>,
    nodes: String,
    roots: String,
    material: String,
    images: String,
    position_count: u64,
}

impl Default for Gltf {
    fn default() -> Self {
        Gltf {
            buffer_uri: None,
            nodes: r#"[{"mesh": 0}]"#.into(),
            roots: "[0]".into(),
            material: r#"{"pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1]}}"#.into(),
            images: String::new(),
            position_count: 4,
        }
    }
}

/// A tetrahedron: 4 float vertices, then 12 u32 indices.
fn buffer() -> Vec<u8> {
    let v: [[f32; 3]; 4] = [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let f: [u32; 12] = [0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3];
    let mut b: Vec<u8> = v.iter().flatten().flat_map(|c| c.to_le_bytes()).collect();
    b.extend(f.iter().flat_map(|i| i.to_le_bytes()));
    b
}

fn gltf(g: &Gltf) -> String {
    use base64::Engine;
    let uri = g.buffer_uri.clone().unwrap_or_else(|| {
        format!(
            "data:application/octet-stream;base64,{}",
            base64::engine::general_purpose::STANDARD.encode(buffer())
        )
    });
    format!(
        r#"{{
  "asset": {{"version": "2.0"}},
  "scene": 0,
  "scenes": [{{"nodes": {roots}}}],
  "nodes": {nodes},
  "materials": [{material}],
  {images}
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1, "material": 0}}]}}],
  "buffers": [{{"uri": "{uri}", "byteLength": 96}}],
  "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 48}}, {{"buffer": 0, "byteOffset": 48, "byteLength": 48}}],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": {count}, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 1]}},
    {{"bufferView": 1, "componentType": 5125, "count": 12, "type": "SCALAR"}}
  ]
}}"#,
        roots = g.roots,
        nodes = g.nodes,
        material = g.material,
        images = g.images,
        count = g.position_count,
    )
}

/// Found by fuzzing: gltf-json's validation indexed a POSITION accessor
/// without checking it.
#[test]
fn a_position_accessor_out_of_range_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let text = gltf(&Gltf::default()).replace(r#""POSITION": 0"#, r#""POSITION": 255"#);
    let e = load_error(&write(dir.path(), "p.gltf", text));
    assert!(
        e.contains("p.gltf: mesh 0 primitive 0: its POSITION is accessor 255"),
        "{e}"
    );
}

/// Found by fuzzing: a binary list whose length type is float could claim
/// a length whose size in bytes overflows.
#[test]
fn a_ply_list_length_must_be_an_integer_type() {
    let dir = tempfile::tempdir().unwrap();
    let mut ply = b"ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n\
element face 1\nproperty list float int vertex_indices\nend_header\n"
        .to_vec();
    ply.extend([0u8; 12]);
    ply.extend(1e30f32.to_le_bytes());
    let e = load_error(&write(dir.path(), "f.ply", &ply));
    assert!(
        e.contains("f.ply: header line 8: a list's length must be an integer type"),
        "{e}"
    );
    // An integer length past the end of the file.
    let mut ply = b"ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n\
element face 1\nproperty list uint int vertex_indices\nend_header\n"
        .to_vec();
    ply.extend([0u8; 12]);
    ply.extend(u32::MAX.to_le_bytes());
    let e = load_error(&write(dir.path(), "g.ply", &ply));
    assert!(e.contains("g.ply: face 0: file ends inside it"), "{e}");
}

/// Found by fuzzing: a second, empty `vertex` element made records of zero
/// bytes.
#[test]
fn a_second_vertex_element_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let ply = "ply\nformat binary_little_endian 1.0\nelement vertex 0\nelement vertex 1\n\
               property float x\nproperty float y\nproperty float z\nend_header\n";
    let e = load_error(&write(dir.path(), "v.ply", ply));
    assert!(
        e.contains("v.ply: header line 4: a second `vertex` element"),
        "{e}"
    );
}

/// sin² + cos² − 0.999 is 0.001 everywhere, but its interval enclosure holds
/// 0 over every piece wider than about 1e-6: without a budget, one root
/// search made 40,000 evaluations and a 640×480 render took half an hour.
#[test]
fn root_searches_on_loose_formulas_are_bounded() {
    use glint::geometry::implicit::roots::MAX_SEARCH_EVALUATIONS;
    let text = "[camera]\nposition = [0, 0, -5]\nlook_at = [0, 0, 0]\n\n[[object]]\nshape = \"implicit\"\n\
                f = \"sin(1000*x)^2 + cos(1000*x)^2 - 0.999\"\nbounds = [[-1.5, -1.5, -1.5], [1.5, 1.5, 1.5]]\n";
    let file = glint::scene::parse_scene(text, Path::new("loose.toml")).unwrap();
    let settings = glint::settings::RenderSettings {
        width: 8,
        height: 6,
        ..file.settings
    };
    let (image, stats) = glint::render::render(&file.scene, &settings, &|_| {}).unwrap();
    assert!(stats.implicit_searches_cut > 0);
    assert!(
        stats.implicit_evaluations <= stats.implicit_searches * (MAX_SEARCH_EVALUATIONS + 1),
        "{} evaluations in {} searches",
        stats.implicit_evaluations,
        stats.implicit_searches
    );
    // No surface there: every ray sees the background.
    assert!(image.pixels.iter().all(|c| *c == file.scene.background));
}

/// A mesh too large or too small for the f32 triangle test (see
/// `glint::geometry::CHECKED_SCALES`) loads with a warning that names the
/// file and the mesh; one at either end of the range loads without.
#[test]
fn meshes_outside_the_checked_scales_are_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let faces = "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
    // A tetrahedron of size `k` with its corner at `at`.
    let tetra = |at: f32, k: f32| {
        let v = |x: f32, y: f32, z: f32| format!("v {} {} {}\n", at + x, y, z);
        format!(
            "{}{}{}{}{faces}",
            v(0.0, 0.0, 0.0),
            v(k, 0.0, 0.0),
            v(0.0, k, 0.0),
            v(0.0, 0.0, k)
        )
    };
    for (at, k, warning) in [
        (0.0, 1.0, None),
        (0.0, 1e18, None),
        (0.0, 2e-16, None),
        (0.0, 1e20, Some("its coordinates reach 1.0e20")),
        (1e19, 1e19, Some("its coordinates reach 2.0e19")),
        (0.0, 1e-18, Some("it is only 1.0e-18 across")),
    ] {
        let path = write(dir.path(), "t.obj", tetra(at, k));
        let model = load_mesh_file(&path).unwrap();
        match warning {
            None => assert!(model.warnings.is_empty(), "{k}: {:?}", model.warnings),
            Some(w) => {
                assert_eq!(model.warnings.len(), 1, "{k}: {:?}", model.warnings);
                let text = &model.warnings[0];
                assert!(
                    text.contains("t.obj: mesh `")
                        && text.contains(w)
                        && text.contains("from 1e-16 to 1e18"),
                    "{text}"
                );
            }
        }
    }
    // A file of many meshes: six too large and one in range, in between.
    // The first three too large are named, in the file's order, and the
    // other three counted.
    let mut obj = String::new();
    for (i, name) in ["a", "b", "c", "ok", "d", "e", "f"].iter().enumerate() {
        let k = if *name == "ok" { 1.0 } else { 1e20 };
        let base = 4 * i;
        obj += &format!("o {name}\n");
        for (x, y, z) in [(0.0, 0.0, 0.0), (k, 0.0, 0.0), (0.0, k, 0.0), (0.0, 0.0, k)] {
            obj += &format!("v {x} {y} {z}\n");
        }
        for f in [[1, 3, 2], [1, 2, 4], [1, 4, 3], [2, 3, 4]] {
            let [a, b, c] = f.map(|v| v + base);
            obj += &format!("f {a} {b} {c}\n");
        }
    }
    let path = write(dir.path(), "many.obj", obj);
    let model = load_mesh_file(&path).unwrap();
    assert_eq!(model.parts.len(), 7);
    let w = &model.warnings;
    assert_eq!(w.len(), 4, "{w:?}");
    for (text, name) in w.iter().zip(["a", "b", "c"]) {
        assert!(
            text.contains(&format!(
                "many.obj: mesh `{name}`: its coordinates reach 1.0e20"
            )),
            "{text}"
        );
    }
    assert!(
        w[3].contains("many.obj: 3 more meshes are outside the checked scales"),
        "{}",
        w[3]
    );
}
