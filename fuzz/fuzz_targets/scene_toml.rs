//! The scene file: any text, parsed; what parses is rendered small.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let path = glint_fuzz::scratch().join("fuzz.toml");
    if let Ok(file) = glint::scene::parse_scene(&text, &path) {
        glint_fuzz::render_small(&file);
    }
});
