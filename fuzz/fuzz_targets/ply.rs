//! PLY, ASCII and binary: any bytes, parsed; a mesh that parses is built
//! (BVH) and rendered small.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let path = Path::new("fuzz.ply");
    if let Ok(raw) = glint::scene::meshio::ply::parse(path, data)
        && let Ok(mesh) = raw.build(path)
    {
        let model = glint::scene::meshio::Model {
            parts: vec![glint::scene::meshio::ModelPart {
                name: String::new(),
                mesh: std::sync::Arc::new(mesh),
                transform: None,
                material: None,
            }],
            ..Default::default()
        };
        glint_fuzz::render_model(&model);
    }
});
