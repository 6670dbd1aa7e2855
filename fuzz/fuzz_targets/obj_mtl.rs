//! OBJ with its MTL: the input is the OBJ's text, a NUL byte, and the text
//! of `m.mtl` written beside it (which the OBJ may name with `mtllib`, or
//! name another file, or none). What loads is rendered small.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let (obj, mtl) = match data.iter().position(|&b| b == 0) {
        Some(i) => (&data[..i], &data[i + 1..]),
        None => (data, &[][..]),
    };
    let dir = glint_fuzz::scratch();
    let path = dir.join("m.obj");
    if std::fs::write(dir.join("m.mtl"), mtl).is_err() || std::fs::write(&path, obj).is_err() {
        return;
    }
    if let Ok(model) = glint::scene::meshio::load_mesh_file(&path) {
        glint_fuzz::render_model(&model);
    }
});
