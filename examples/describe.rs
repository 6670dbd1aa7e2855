//! Prints a scene file's description as JSON (the form `glint render` also
//! reads, and that other front ends can write):
//! `cargo run --example describe -- scenes/whitted.toml > whitted.json`.

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args()
        .nth(1)
        .ok_or("usage: describe SCENE.toml")?;
    let path = std::path::Path::new(&path);
    let text = std::fs::read_to_string(path)?;
    let desc = glint::scene::parse_scene_desc(&text, path)?;
    println!("{}", serde_json::to_string_pretty(&desc)?);
    Ok(())
}
