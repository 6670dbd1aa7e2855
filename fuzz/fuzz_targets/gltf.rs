//! glTF and GLB from a structured generator: documents whose nodes,
//! meshes, accessors, buffer views and buffers refer to each other by
//! arbitrary indices, offsets, counts and strides, with buffers in a GLB
//! chunk, in data: URIs, in files beside the model or named by hostile
//! URIs; GLB containers with arbitrary lengths; and raw bytes. What loads
//! is rendered small.
//!
//! The first byte chooses: odd, the rest drives the generator; even, the
//! rest is the file itself (a `.glb` if bit 1 is set, else a `.gltf`).
#![no_main]

use arbitrary::Arbitrary;
use base64::Engine;
use libfuzzer_sys::fuzz_target;
use serde_json::{Value, json};

#[derive(Arbitrary, Debug)]
struct Doc {
    glb: bool,
    /// (length, version) written into the GLB header instead of the true ones.
    glb_header: Option<(u32, u32)>,
    roots: Vec<u8>,
    nodes: Vec<Node>,
    meshes: Vec<Vec<Primitive>>,
    materials: Vec<Material>,
    accessors: Vec<Accessor>,
    views: Vec<View>,
    buffers: Vec<Buffer>,
    camera_fov: Option<f32>,
}

#[derive(Arbitrary, Debug)]
struct Node {
    children: Vec<u8>,
    mesh: Option<u8>,
    camera: bool,
    translation: Option<[f32; 3]>,
    scale: Option<[f32; 3]>,
    matrix: Option<[f32; 16]>,
}

#[derive(Arbitrary, Debug)]
struct Primitive {
    position: u8,
    indices: Option<u8>,
    normal: Option<u8>,
    uv: Option<u8>,
    mode: u8,
    material: Option<u8>,
}

#[derive(Arbitrary, Debug)]
struct Material {
    base: [f32; 4],
    metallic: f32,
    roughness: f32,
    transmission: Option<f32>,
    ior: Option<f32>,
}

#[derive(Arbitrary, Debug)]
struct Accessor {
    view: Option<u8>,
    offset: u16,
    count: u32,
    component: u8,
    kind: u8,
    normalized: bool,
    bounds: bool,
}

#[derive(Arbitrary, Debug)]
struct View {
    buffer: u8,
    offset: u16,
    length: u16,
    stride: Option<u8>,
}

#[derive(Arbitrary, Debug)]
enum Source {
    Bin,
    DataUri,
    File,
    Uri(String),
}

#[derive(Arbitrary, Debug)]
struct Buffer {
    source: Source,
    /// Vertices of a tetrahedron and its indices first, so that accessors
    /// can find real geometry, then these bytes.
    tetrahedron: bool,
    bytes: Vec<u8>,
    /// byteLength as declared, instead of the true one.
    declared: Option<u32>,
}

fn tetrahedron() -> Vec<u8> {
    let v: [f32; 12] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    let f: [u32; 12] = [0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3];
    let mut b: Vec<u8> = v.iter().flat_map(|c| c.to_le_bytes()).collect();
    b.extend(f.iter().flat_map(|i| i.to_le_bytes()));
    b
}

fn num(x: f32) -> Value {
    // JSON has no NaN or infinity: those become out-of-range numbers.
    if x.is_finite() {
        json!(x)
    } else {
        json!(1e300)
    }
}

fn document(doc: &Doc) -> (Value, Option<Vec<u8>>) {
    const COMPONENTS: [u32; 6] = [5120, 5121, 5122, 5123, 5125, 5126];
    const KINDS: [&str; 7] = ["SCALAR", "VEC2", "VEC3", "VEC4", "MAT2", "MAT3", "MAT4"];
    let mut bin = None;
    let dir = glint_fuzz::scratch();
    let buffers: Vec<Value> = doc
        .buffers
        .iter()
        .enumerate()
        .map(|(i, b)| {
            let mut data = if b.tetrahedron {
                tetrahedron()
            } else {
                Vec::new()
            };
            data.extend(&b.bytes);
            let length = b.declared.unwrap_or(data.len() as u32);
            match &b.source {
                Source::Bin => {
                    bin = Some(data);
                    json!({"byteLength": length})
                }
                Source::DataUri => json!({
                    "byteLength": length,
                    "uri": format!("data:application/octet-stream;base64,{}",
                        base64::engine::general_purpose::STANDARD.encode(&data)),
                }),
                Source::File => {
                    let name = format!("buffer{i}.bin");
                    let _ = std::fs::write(dir.join(&name), &data);
                    json!({"byteLength": length, "uri": name})
                }
                Source::Uri(uri) => json!({"byteLength": length, "uri": uri}),
            }
        })
        .collect();
    let views: Vec<Value> = doc
        .views
        .iter()
        .map(|v| {
            let mut o = json!({"buffer": v.buffer, "byteOffset": v.offset, "byteLength": v.length});
            if let Some(s) = v.stride {
                o["byteStride"] = json!(s);
            }
            o
        })
        .collect();
    let accessors: Vec<Value> = doc
        .accessors
        .iter()
        .map(|a| {
            let mut o = json!({
                "byteOffset": a.offset,
                "count": a.count,
                "componentType": COMPONENTS[a.component as usize % COMPONENTS.len()],
                "type": KINDS[a.kind as usize % KINDS.len()],
                "normalized": a.normalized,
            });
            if let Some(v) = a.view {
                o["bufferView"] = json!(v);
            }
            // The specification requires them on POSITION accessors, and
            // the validation that precedes glint's reader checks them.
            if a.bounds {
                o["min"] = json!([0, 0, 0]);
                o["max"] = json!([1, 1, 1]);
            }
            o
        })
        .collect();
    let meshes: Vec<Value> = doc
        .meshes
        .iter()
        .map(|prims| {
            let prims: Vec<Value> = prims
                .iter()
                .map(|p| {
                    let mut attributes = json!({"POSITION": p.position});
                    if let Some(n) = p.normal {
                        attributes["NORMAL"] = json!(n);
                    }
                    if let Some(t) = p.uv {
                        attributes["TEXCOORD_0"] = json!(t);
                    }
                    let mut o = json!({"attributes": attributes, "mode": p.mode % 8});
                    if let Some(i) = p.indices {
                        o["indices"] = json!(i);
                    }
                    if let Some(m) = p.material {
                        o["material"] = json!(m);
                    }
                    o
                })
                .collect();
            json!({"primitives": prims})
        })
        .collect();
    let materials: Vec<Value> = doc
        .materials
        .iter()
        .map(|m| {
            let mut o = json!({"pbrMetallicRoughness": {
                "baseColorFactor": m.base.map(num),
                "metallicFactor": num(m.metallic),
                "roughnessFactor": num(m.roughness),
            }});
            let mut ext = json!({});
            if let Some(t) = m.transmission {
                ext["KHR_materials_transmission"] = json!({"transmissionFactor": num(t)});
            }
            if let Some(i) = m.ior {
                ext["KHR_materials_ior"] = json!({"ior": num(i)});
            }
            o["extensions"] = ext;
            o
        })
        .collect();
    let nodes: Vec<Value> = doc
        .nodes
        .iter()
        .map(|n| {
            let mut o = json!({});
            if !n.children.is_empty() {
                o["children"] = json!(n.children);
            }
            if let Some(m) = n.mesh {
                o["mesh"] = json!(m);
            }
            if n.camera {
                o["camera"] = json!(0);
            }
            if let Some(t) = n.translation {
                o["translation"] = json!(t.map(num));
            }
            if let Some(s) = n.scale {
                o["scale"] = json!(s.map(num));
            }
            if let Some(m) = n.matrix {
                o["matrix"] = json!(m.map(num));
            }
            o
        })
        .collect();
    let mut root = json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_materials_transmission", "KHR_materials_ior"],
        "scene": 0,
        "scenes": [{"nodes": doc.roots}],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "accessors": accessors,
        "bufferViews": views,
        "buffers": buffers,
    });
    if let Some(fov) = doc.camera_fov {
        root["cameras"] =
            json!([{"type": "perspective", "perspective": {"yfov": num(fov), "znear": 0.1}}]);
    }
    (root, bin)
}

fn glb(json: &[u8], bin: Option<&[u8]>, header: Option<(u32, u32)>) -> Vec<u8> {
    let mut json = json.to_vec();
    while json.len() % 4 != 0 {
        json.push(b' ');
    }
    let mut body = Vec::new();
    body.extend((json.len() as u32).to_le_bytes());
    body.extend(b"JSON");
    body.extend(&json);
    if let Some(bin) = bin {
        let mut bin = bin.to_vec();
        while bin.len() % 4 != 0 {
            bin.push(0);
        }
        body.extend((bin.len() as u32).to_le_bytes());
        body.extend(b"BIN\0");
        body.extend(&bin);
    }
    let (length, version) = header.unwrap_or((12 + body.len() as u32, 2));
    let mut out = b"glTF".to_vec();
    out.extend(version.to_le_bytes());
    out.extend(length.to_le_bytes());
    out.extend(body);
    out
}

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else {
        return;
    };
    let dir = glint_fuzz::scratch();
    let (bytes, ext) = if mode & 1 == 0 {
        (rest.to_vec(), if mode & 2 != 0 { "glb" } else { "gltf" })
    } else {
        let Ok(doc) = Doc::arbitrary_take_rest(arbitrary::Unstructured::new(rest)) else {
            return;
        };
        let (root, bin) = document(&doc);
        let text = serde_json::to_vec(&root).expect("a JSON value serialises");
        if doc.glb {
            (glb(&text, bin.as_deref(), doc.glb_header), "glb")
        } else {
            (text, "gltf")
        }
    };
    let path = dir.join(format!("model.{ext}"));
    if std::fs::write(&path, bytes).is_err() {
        return;
    }
    if let Ok(model) = glint::scene::meshio::load_mesh_file(&path) {
        glint_fuzz::render_model(&model);
    }
});
