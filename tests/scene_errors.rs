//! Malformed scene files give errors that name the file, line and column, and
//! say what was expected.

use glint::scene::{SceneError, load_scene_file, parse_scene};
use std::path::Path;

const GOOD: &str = r#"[camera]
position = [0, 1, -5]
look_at = [0, 1, 0]

[materials]
red = { type = "diffuse", color = [1, 0, 0] }

[[light]]
type = "point"
position = [0, 5, -5]
intensity = 20

[[object]]
shape = "sphere"
center = [0, 1, 0]
radius = 1
material = "red"
"#;

/// Replaces `from` (which must occur once) in the good scene and parses it.
fn error_for(from: &str, to: &str) -> (usize, usize, String) {
    assert_eq!(GOOD.matches(from).count(), 1, "{from}");
    let text = GOOD.replace(from, to);
    match parse_scene(&text, Path::new("scenes/bad.toml")) {
        Ok(_) => panic!("accepted:\n{text}"),
        Err(e @ SceneError::Parse { .. }) => {
            let shown = e.to_string();
            let SceneError::Parse {
                path,
                line,
                column,
                message,
            } = e
            else {
                unreachable!()
            };
            assert_eq!(path, Path::new("scenes/bad.toml"));
            assert!(
                shown.starts_with(&format!("scenes/bad.toml:{line}:{column}: ")),
                "{shown}"
            );
            (line, column, message)
        }
        Err(e) => panic!("unexpected error {e}"),
    }
}

#[test]
fn good_scene_parses() {
    let f = parse_scene(GOOD, Path::new("good.toml")).unwrap();
    assert_eq!(f.scene.objects.len(), 1);
    assert_eq!(f.scene.lights.len(), 1);
}

#[test]
fn toml_syntax_error() {
    let (line, column, message) = error_for("look_at = [0, 1, 0]", "look_at = [0, 1 0]");
    assert_eq!((line, column), (3, 15)); // the element after which a comma is missing
    assert!(message.contains("invalid TOML"), "{message}");
}

#[test]
fn unknown_key() {
    let (line, column, message) = error_for("radius = 1", "radius = 1\nshiny = true");
    assert_eq!((line, column), (17, 1));
    assert!(message.contains("unknown key `shiny`"), "{message}");
    assert!(
        message.contains("expected one of: center, material, radius, shape"),
        "{message}"
    );
}

#[test]
fn misspelt_required_key_is_named() {
    let (line, column, message) = error_for("radius = 1", "radus = 1");
    assert_eq!((line, column), (16, 1));
    assert!(
        message.contains("unknown key `radus`") && message.contains("did you mean `radius`"),
        "{message}"
    );
}

#[test]
fn wrong_type() {
    let (line, column, message) = error_for("radius = 1", "radius = \"large\"");
    assert_eq!((line, column), (16, 10));
    assert!(
        message.contains("expected a number, found string"),
        "{message}"
    );
    let (line, column, message) = error_for("center = [0, 1, 0]", "center = [0, 1]");
    assert_eq!((line, column), (15, 10));
    assert!(message.contains("array of 3 numbers"), "{message}");
    let (line, column, _) = error_for("intensity = 20", "intensity = [1, \"2\", 3]");
    assert_eq!((line, column), (11, 17));
}

#[test]
fn missing_required_key() {
    let (line, column, message) = error_for("radius = 1\n", "");
    // Located at the table that lacks it.
    assert_eq!((line, column), (13, 1));
    assert!(
        message.contains("missing required key `radius` in object 1 (sphere)"),
        "{message}"
    );
    let (line, column, message) =
        error_for("[camera]\nposition = [0, 1, -5]\nlook_at = [0, 1, 0]\n", "");
    assert_eq!((line, column), (1, 1));
    assert!(
        message.contains("missing required key `camera`"),
        "{message}"
    );
}

#[test]
fn unknown_material_name() {
    let (line, column, message) = error_for("material = \"red\"", "material = \"blue\"");
    assert_eq!((line, column), (17, 12));
    assert!(
        message.contains("unknown material `blue`") && message.contains("red"),
        "{message}"
    );
}

#[test]
fn unknown_names_of_kinds() {
    let (line, column, message) = error_for("shape = \"sphere\"", "shape = \"cube\"");
    assert_eq!((line, column), (14, 9));
    assert!(
        message.contains("expected one of: sphere, plane, box"),
        "{message}"
    );
    let (_, _, message) = error_for("type = \"diffuse\"", "type = \"velvet\"");
    assert!(
        message.contains("unknown material type `velvet`"),
        "{message}"
    );
    let (_, _, message) = error_for("type = \"point\"", "type = \"spot\"");
    assert!(message.contains("unknown light type `spot`"), "{message}");
}

#[test]
fn values_out_of_range() {
    let (line, column, message) = error_for("radius = 1", "radius = -1");
    assert_eq!((line, column), (16, 10));
    assert!(message.contains("positive radius"), "{message}");
    let (_, _, message) = error_for("[camera]", "[render]\nwidth = 0\n\n[camera]");
    assert!(message.contains("width"), "{message}");
    let (_, _, message) = error_for("radius = 1", "radius = nan");
    assert!(message.contains("finite"), "{message}");
    let (_, _, message) = error_for("color = [1, 0, 0]", "color = [1, -0.5, 0]");
    assert!(message.contains("≥ 0"), "{message}");
    let (_, _, message) = error_for("look_at = [0, 1, 0]", "look_at = [0, 1, -5]");
    assert!(message.contains("degenerate [camera]"), "{message}");
}

#[test]
fn missing_file_names_the_path() {
    let e = load_scene_file(Path::new("no/such/scene.toml")).unwrap_err();
    assert!(matches!(e, SceneError::Io { .. }));
    assert!(e.to_string().contains("no/such/scene.toml"), "{e}");
}

/// Every shipped scene loads. Scenes that use the meshes of
/// `../shared/data/` (not part of the repository) load when that folder is
/// there, and otherwise fail saying which file they looked for.
#[test]
fn shipped_scenes_parse() {
    let data = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data"));
    for entry in std::fs::read_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        let uses_shared_data = std::fs::read_to_string(&path)
            .unwrap()
            .contains("shared/data/");
        match load_scene_file(&path) {
            Ok(_) => {}
            Err(e) if uses_shared_data && !data.is_dir() => {
                let message = e.to_string();
                assert!(
                    message.contains("cannot load mesh")
                        && message.contains("shared/data/")
                        && message.contains("not found"),
                    "{message}"
                );
            }
            Err(e) => panic!("{e}"),
        }
    }
}

#[test]
fn documented_example_parses() {
    let doc = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/scene-format.md"))
        .unwrap();
    let start = doc
        .find("```toml\n")
        .expect("docs/scene-format.md has an example")
        + 8;
    let end = start + doc[start..].find("```").unwrap();
    let f = parse_scene(&doc[start..end], Path::new("docs/scene-format.md"))
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(f.scene.objects.len(), 2);
}

#[test]
fn an_unknown_texture_kind_is_named_as_an_unknown_key() {
    let text = "[camera]\nposition = [0, 0, -5]\nlook_at = [0, 0, 0]\n\n[materials]\nm = { type = \"diffuse\", texture = { image = \"x.png\" } }\n";
    let e = glint::scene::parse_scene(text, Path::new("t.toml"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("t.toml:6:37: unknown key `image` in the texture of material `m`; expected one of: checker, mode, scale"),
        "{e}"
    );
}

/// Integers with a radix prefix and no digits (`0b`, `0x`, `0o`, found by
/// the scene fuzzer, which panicked on them) and other malformed integers
/// are errors at their place, never a panic.
#[test]
fn radix_prefixes_without_digits_are_errors() {
    for bad in ["0b", "0x", "0o", "0x_", "0b2", "0xg"] {
        let text = GOOD.replace("radius = 1", &format!("radius = {bad}"));
        // The TOML reader may reject it itself; either way, an error.
        match parse_scene(&text, Path::new("scenes/bad.toml")) {
            Err(SceneError::Parse { line, .. }) => assert_eq!(line, 16, "{bad}"),
            other => panic!("{bad}: {:?}", other.map(|_| ())),
        }
    }
    // Good prefixed integers still read.
    for (good, r) in [("0x2", 2.0), ("0o10", 8.0), ("0b11", 3.0)] {
        let text = GOOD.replace("radius = 1", &format!("radius = {good}"));
        let f = parse_scene(&text, Path::new("good.toml")).unwrap();
        let shown = format!("{:?}", f.scene.objects[0]);
        assert!(shown.contains(&format!("{r:?}")), "{good}: {shown}");
    }
}
