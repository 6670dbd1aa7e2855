//! Writes the seed corpora of the fuzz targets into `fuzz/seeds/<target>/`:
//! the repository's scenes, formulas from its documentation, and small
//! meshes in every format and variant the loaders read (generated here, so
//! no binary files live in the repository). Run by `fuzz/run.sh`.

use base64::Engine;
use std::path::{Path, PathBuf};

fn write(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) {
    std::fs::create_dir_all(dir).expect("the seeds folder is writable");
    std::fs::write(dir.join(name), bytes).expect("the seeds folder is writable");
}

const V: [[f32; 3]; 4] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, 0.0, 1.0],
];
const F: [[u32; 3]; 4] = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];

fn ply_header(format: &str, normals: bool, uvs: bool) -> String {
    let mut h = format!(
        "ply\nformat {format} 1.0\ncomment seed\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
    );
    if normals {
        h += "property float nx\nproperty float ny\nproperty float nz\n";
    }
    if uvs {
        h += "property float u\nproperty float v\n";
    }
    h + "element face 4\nproperty list uchar int vertex_indices\nend_header\n"
}

fn plys(dir: &Path) {
    for (normals, uvs) in [(false, false), (true, false), (true, true)] {
        let mut text = ply_header("ascii", normals, uvs);
        for v in V {
            text += &format!("{} {} {}", v[0], v[1], v[2]);
            if normals {
                text += " 0 0 1";
            }
            if uvs {
                text += " 0.5 0.5";
            }
            text += "\n";
        }
        for f in F {
            text += &format!("3 {} {} {}\n", f[0], f[1], f[2]);
        }
        write(dir, &format!("ascii_{normals}_{uvs}.ply"), &text);
        for big in [false, true] {
            let format = if big {
                "binary_big_endian"
            } else {
                "binary_little_endian"
            };
            let mut out = ply_header(format, normals, uvs).into_bytes();
            let float = |out: &mut Vec<u8>, x: f32| {
                out.extend(if big {
                    x.to_be_bytes()
                } else {
                    x.to_le_bytes()
                })
            };
            for v in V {
                for c in v {
                    float(&mut out, c);
                }
                if normals {
                    for c in [0.0, 0.0, 1.0] {
                        float(&mut out, c);
                    }
                }
                if uvs {
                    float(&mut out, 0.5);
                    float(&mut out, 0.5);
                }
            }
            for f in F {
                out.push(3);
                for i in f {
                    out.extend(if big {
                        (i as i32).to_be_bytes()
                    } else {
                        (i as i32).to_le_bytes()
                    });
                }
            }
            write(dir, &format!("{format}_{normals}_{uvs}.ply"), &out);
        }
    }
    // A quad and a pentagon (fans), and an extra element to skip.
    write(
        dir,
        "polygons.ply",
        "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\n\
         element face 2\nproperty list uchar int vertex_indices\nelement edge 1\nproperty int a\nproperty int b\nend_header\n\
         0 0 0\n1 0 0\n1 1 0\n0 1 0\n0.5 2 1\n4 0 1 2 3\n5 0 1 2 4 3\n0 1\n",
    );
}

fn objs(dir: &Path) {
    let mut obj = String::from("# seed\nmtllib m.mtl\no first\nusemtl red\ns 1\n");
    for v in V {
        obj += &format!("v {} {} {}\n", v[0], v[1], v[2]);
    }
    obj += "vt 0 0\nvt 1 0\nvt 0 1\nvn 0 0 1\n";
    obj += "f 1/1/1 3/2/1 2/3/1\nf 1//1 2//1 4//1\nf -4 -1 -2\ng second\nusemtl glass\nf 2/1 3/2 4/3\n";
    obj += "v 2 0 0 1\nv 3 0 0 0.5\nv 3 1 0 1 0 0\nv 2 1 0\nusemtl chrome\nf 5 6 7 8\nl 1 2\n";
    let mtl = "newmtl red\nKd 0.8 0.1 0.1\nKs 0.5\nNs 100\nillum 2\n\
               newmtl chrome\nKd 0.1 0.1 0.1\nKs 0.9 0.9 0.9\nillum 3\n\
               newmtl glass\nKd 1 1 1\nNi 1.33\nd 0.5\nillum 7\nmap_Kd tex.png\n";
    let seed = |name: &str, obj: &str, mtl: &str| {
        let mut bytes = obj.as_bytes().to_vec();
        bytes.push(0);
        bytes.extend(mtl.as_bytes());
        write(dir, name, bytes);
    };
    seed("materials.obj", &obj, mtl);
    seed("no_library.obj", &obj.replace("mtllib m.mtl\n", ""), "");
    seed(
        "continued.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 \\\n 0\nf 1 2 \\\n3\n",
        "",
    );
}

fn gltf_json(uri: Option<&str>) -> String {
    let buffer = match uri {
        Some(u) => format!(r#"{{"uri": "{u}", "byteLength": 96}}"#),
        None => r#"{"byteLength": 96}"#.to_string(),
    };
    format!(
        r#"{{"asset": {{"version": "2.0"}}, "extensionsUsed": ["KHR_materials_transmission", "KHR_materials_ior"],
 "scene": 0, "scenes": [{{"nodes": [0, 1, 3]}}],
 "nodes": [{{"mesh": 0}}, {{"scale": [2, 2, 2], "children": [2]}}, {{"mesh": 0, "translation": [5, 0, 0]}},
           {{"camera": 0, "translation": [0, 0, 10]}}],
 "cameras": [{{"type": "perspective", "perspective": {{"yfov": 0.7, "znear": 0.1}}}}],
 "materials": [{{"pbrMetallicRoughness": {{"baseColorFactor": [1, 1, 1, 1], "metallicFactor": 0, "roughnessFactor": 0}},
   "extensions": {{"KHR_materials_transmission": {{"transmissionFactor": 1}}, "KHR_materials_ior": {{"ior": 1.7}}}}}}],
 "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1, "material": 0}}]}}],
 "buffers": [{buffer}],
 "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 48}}, {{"buffer": 0, "byteOffset": 48, "byteLength": 48}}],
 "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 1]}},
               {{"bufferView": 1, "componentType": 5125, "count": 12, "type": "SCALAR"}}]}}"#
    )
}

fn gltfs(dir: &Path) {
    let mut buffer: Vec<u8> = V.iter().flatten().flat_map(|c| c.to_le_bytes()).collect();
    buffer.extend(F.iter().flatten().flat_map(|i| i.to_le_bytes()));
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&buffer)
    );
    // Mode byte 0: the rest is a .gltf file.
    let mut gltf = vec![0u8];
    gltf.extend(gltf_json(Some(&uri)).as_bytes());
    write(dir, "data_uri.gltf.seed", gltf);
    let mut file_uri = vec![0u8];
    file_uri.extend(gltf_json(Some("buffer0.bin")).as_bytes());
    write(dir, "file_uri.gltf.seed", file_uri);
    // Mode byte 2: a .glb file.
    let mut json = gltf_json(None).into_bytes();
    while json.len() % 4 != 0 {
        json.push(b' ');
    }
    let mut glb = vec![2u8];
    glb.extend(b"glTF");
    glb.extend(2u32.to_le_bytes());
    glb.extend(((12 + 8 + json.len() + 8 + buffer.len()) as u32).to_le_bytes());
    glb.extend((json.len() as u32).to_le_bytes());
    glb.extend(b"JSON");
    glb.extend(&json);
    glb.extend((buffer.len() as u32).to_le_bytes());
    glb.extend(b"BIN\0");
    glb.extend(&buffer);
    write(dir, "bin_chunk.glb.seed", glb);
    // Mode byte 1: the structured generator, from a few bytes.
    write(
        dir,
        "structured.seed",
        [1u8, 1, 3, 0, 0, 2, 1, 0, 1, 4, 0, 0, 0, 5, 2],
    );
}

fn formulas(dir: &Path, repo: &Path) {
    let mut texts: Vec<String> = vec![
        "x^2 + y^2 + z^2 - 1".into(),
        "(x^2 + 9/4*y^2 + z^2 - 1)^3 - x^2*z^3 - 9/80*y^2*z^3".into(),
        "(1 - sqrt(x^2 + y^2))^2 + z^2 - 0.3^2".into(),
        "min(x, max(y, z)) - sin(x)*cos(y) + exp(-z) - ln(abs(x) + 1)".into(),
        "x^-2 + 2^x + x^0.5 - pi*e − y".into(),
        "(x^2 + y^2 + z^2 - 1)^3".into(),
    ];
    // The formulas of the shipped scenes.
    for entry in std::fs::read_dir(repo.join("scenes"))
        .into_iter()
        .flatten()
        .flatten()
    {
        let text = std::fs::read_to_string(entry.path()).unwrap_or_default();
        for line in text.lines() {
            if let Some(f) = line.trim().strip_prefix("f = \"") {
                texts.push(f.trim_end_matches('"').to_string());
            }
        }
    }
    for (i, t) in texts.iter().enumerate() {
        // Box [-1.5, 1.5]³ and its centre, then the formula.
        let mut bytes = Vec::new();
        for _ in 0..3 {
            bytes.extend((-1500i16).to_le_bytes());
            bytes.extend(1500i16.to_le_bytes());
        }
        for _ in 0..3 {
            bytes.extend(32768u16.to_le_bytes());
        }
        bytes.extend(t.as_bytes());
        write(dir, &format!("formula{i}"), bytes);
    }
}

fn scenes(dir: &Path, repo: &Path) {
    for entry in std::fs::read_dir(repo.join("scenes"))
        .into_iter()
        .flatten()
        .flatten()
    {
        let path = entry.path();
        if path.extension().is_some_and(|e| e == "toml") {
            let name = path
                .file_name()
                .expect("a file")
                .to_string_lossy()
                .into_owned();
            write(dir, &name, std::fs::read(&path).expect("a readable scene"));
        }
    }
}

fn main() {
    let fuzz = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let repo = fuzz
        .parent()
        .expect("fuzz/ is inside the repository")
        .to_path_buf();
    let out = fuzz.join("seeds");
    scenes(&out.join("scene_toml"), &repo);
    formulas(&out.join("formula"), &repo);
    plys(&out.join("ply"));
    objs(&out.join("obj_mtl"));
    gltfs(&out.join("gltf"));
    println!("seeds written to {}", out.display());
}
