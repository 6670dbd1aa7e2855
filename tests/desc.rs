//! The scene description: TOML → description → scene, the description as
//! JSON, built without TOML, and checked whoever made it.

use glint::math::{Color, Vec3};
use glint::render::render;
use glint::scene::desc::{
    CameraDesc, ImplicitFormula, NamedMaterial, NamedSurface, ObjectDesc, Place, ShapeDesc,
    TransformDesc,
};
use glint::scene::{
    BUILTIN_WHITTED, Light, Material, MaterialKind, SceneDesc, Texture, parse_scene,
    parse_scene_desc,
};
use glint::settings::RenderSettings;
use std::path::Path;

fn small(settings: &RenderSettings) -> RenderSettings {
    RenderSettings {
        width: 40,
        height: 30,
        spp: 2,
        ..settings.clone()
    }
}

fn bits(image: &glint::render::Image) -> Vec<[u32; 3]> {
    image
        .pixels
        .iter()
        .map(|c| c.to_array().map(f32::to_bits))
        .collect()
}

#[test]
fn a_description_round_trips_through_json_and_builds_the_same_scene() {
    let desc = parse_scene_desc(BUILTIN_WHITTED, Path::new("whitted.toml")).unwrap();
    let json = serde_json::to_string_pretty(&desc).unwrap();
    let back: SceneDesc = serde_json::from_str(&json).unwrap();
    assert_eq!(back, desc);
    let from_toml = parse_scene(BUILTIN_WHITTED, Path::new("whitted.toml")).unwrap();
    let built = back.build(Path::new(".")).unwrap();
    let s = small(&from_toml.settings);
    let a = render(&from_toml.scene, &s, &|_| {}).unwrap().0;
    let b = render(&built.scene, &s, &|_| {}).unwrap().0;
    assert_eq!(bits(&a), bits(&b));
    assert_eq!(built.desc.as_ref(), Some(&desc));
    // The JSON reads as the scene file does.
    assert!(json.contains("\"kind\": \"sphere\""), "{json}");
    assert!(json.contains("\"type\": \"dielectric\""), "{json}");
    // Unknown fields are refused, as in scene files.
    let typo = json.replacen("\"radius\"", "\"radus\"", 1);
    let e = serde_json::from_str::<SceneDesc>(&typo)
        .unwrap_err()
        .to_string();
    assert!(e.contains("unknown field `radus`"), "{e}");
}

fn lit_scene(objects: Vec<ObjectDesc>) -> SceneDesc {
    SceneDesc {
        camera: CameraDesc {
            position: Vec3::new(0.0, 1.0, -6.0),
            look_at: Vec3::ZERO,
            up: Vec3::Y,
            fov: 45.0,
        },
        settings: RenderSettings {
            width: 32,
            height: 24,
            ..Default::default()
        },
        background: Color::new(0.1, 0.1, 0.2),
        ambient: Color::splat(0.1),
        materials: vec![NamedMaterial {
            name: "red".into(),
            material: Material {
                texture: Texture::Solid(Color::new(0.9, 0.1, 0.1)),
                ..Material::default_diffuse()
            },
        }],
        lights: vec![Light::Directional {
            direction: Vec3::new(1.0, -2.0, 1.0),
            irradiance: Color::ONE,
        }],
        objects,
        environment: None,
    }
}

fn sphere(center: Vec3, radius: f32) -> ObjectDesc {
    ObjectDesc {
        shape: ShapeDesc::Sphere { center, radius },
        material: Some("red".into()),
    }
}

#[test]
fn a_description_made_in_code_builds_meshes_formulas_and_shapes() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("tri.obj"),
        "v -1 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    let desc = lit_scene(vec![
        sphere(Vec3::new(-1.5, 0.0, 0.0), 0.7),
        ObjectDesc {
            shape: ShapeDesc::Implicit {
                formula: ImplicitFormula::Named(NamedSurface::Torus {
                    major_radius: 0.6,
                    minor_radius: 0.2,
                }),
                bounds: None,
                transform: Some(TransformDesc {
                    scale: Vec3::ONE,
                    rotate_deg: Vec3::new(90.0, 0.0, 0.0),
                    translate: Vec3::new(1.5, 0.0, 0.0),
                }),
            },
            material: None,
        },
        ObjectDesc {
            shape: ShapeDesc::Mesh {
                file: "tri.obj".into(),
                smooth: false,
                transform: None,
            },
            material: Some("red".into()),
        },
        ObjectDesc {
            shape: ShapeDesc::Plane {
                point: Vec3::new(0.0, -1.0, 0.0),
                normal: Vec3::Y,
            },
            material: None,
        },
    ]);
    let file = desc.build(dir.path()).unwrap();
    assert_eq!(file.scene.objects.len(), 4);
    assert_eq!(file.scene.geometry_stats().triangles, 1);
    let (image, stats) = render(&file.scene, &file.settings, &|_| {}).unwrap();
    assert_eq!(stats.nan_pixels, 0);
    // The middle pixel sees the red triangle: red dominates.
    let c = image.get(16, 11);
    assert!(c.x > 2.0 * c.y && c.x > 2.0 * c.z, "{c:?}");
}

#[test]
fn every_value_is_checked_whoever_made_the_description() {
    let dir = tempfile::tempdir().unwrap();
    let err = |d: &SceneDesc| d.build(dir.path()).expect_err("refused").to_string();
    let ok = lit_scene(vec![sphere(Vec3::ZERO, 1.0)]);
    assert!(ok.build(dir.path()).is_ok());

    let mut d = ok.clone();
    d.objects[0] = sphere(Vec3::ZERO, -1.0);
    assert_eq!(err(&d), "object 1 (sphere): radius -1 must be positive");
    d.objects[0] = sphere(Vec3::new(f32::NAN, 0.0, 0.0), 1.0);
    assert_eq!(err(&d), "object 1 (sphere): `center` must be finite");
    d.objects[0] = ObjectDesc {
        material: Some("blue".into()),
        ..sphere(Vec3::ZERO, 1.0)
    };
    assert_eq!(
        err(&d),
        "object 1 (sphere): unknown material `blue`; defined: red"
    );

    let mut d = ok.clone();
    d.camera.look_at = d.camera.position;
    assert!(
        err(&d).starts_with("the camera: degenerate camera"),
        "{}",
        err(&d)
    );
    let mut d = ok.clone();
    d.camera.fov = 180.0;
    assert!(err(&d).contains("fov 180"), "{}", err(&d));

    let mut d = ok.clone();
    d.materials.push(d.materials[0].clone());
    assert_eq!(err(&d), "material `red`: is defined twice");
    let mut d = ok.clone();
    d.materials[0].material.kind = MaterialKind::Dielectric {
        ior: 0.0,
        absorption: Color::ZERO,
        roughness: 0.0,
    };
    assert_eq!(err(&d), "material `red`: `ior` 0 must be positive");
    let mut d = ok.clone();
    d.materials[0].material.texture = Texture::Solid(Color::new(-1.0, 0.0, 0.0));
    assert!(err(&d).contains("must be finite and ≥ 0"), "{}", err(&d));

    let mut d = ok.clone();
    d.lights[0] = Light::Directional {
        direction: Vec3::ZERO,
        irradiance: Color::ONE,
    };
    assert_eq!(
        err(&d),
        "light 1: its direction must be non-zero and finite"
    );
    let mut d = ok.clone();
    d.background = Color::splat(f32::INFINITY);
    assert!(
        err(&d).starts_with("the scene: `background`"),
        "{}",
        err(&d)
    );
    let mut d = ok.clone();
    d.settings.width = 0;
    assert!(
        err(&d).starts_with("the render settings: image size 0×24"),
        "{}",
        err(&d)
    );

    let mut d = ok.clone();
    d.objects.push(ObjectDesc {
        shape: ShapeDesc::Implicit {
            formula: ImplicitFormula::Formula("x*x + y*y + z*z - ".into()),
            bounds: Some([Vec3::splat(-1.0), Vec3::ONE]),
            transform: None,
        },
        material: None,
    });
    assert!(
        err(&d).starts_with("object 2 (implicit): in its formula"),
        "{}",
        err(&d)
    );
    d.objects[1].shape = ShapeDesc::Implicit {
        formula: ImplicitFormula::Formula("x*x + y*y + z*z - 1".into()),
        bounds: None,
        transform: None,
    };
    assert_eq!(err(&d), "object 2 (implicit): a formula needs `bounds`");
    d.objects[1].shape = ShapeDesc::Mesh {
        file: "gone.ply".into(),
        smooth: false,
        transform: Some(TransformDesc {
            scale: Vec3::ZERO,
            rotate_deg: Vec3::ZERO,
            translate: Vec3::ZERO,
        }),
    };
    assert!(
        err(&d).contains("object 2 (mesh): the transform is singular"),
        "{}",
        err(&d)
    );
    if let ShapeDesc::Mesh { transform, .. } = &mut d.objects[1].shape {
        *transform = None;
    }
    let e = d.build(dir.path()).unwrap_err();
    assert_eq!(e.place, Place::Object(2, "mesh"));
    assert!(e.message.starts_with("cannot load mesh `gone.ply`"), "{e}");
}

#[test]
fn a_scene_file_describes_without_reading_its_meshes() {
    let text = BUILTIN_WHITTED.to_string()
        + "\n[[object]]\nshape = \"mesh\"\nfile = \"meshes/big.ply\"\nsmooth = true\n";
    let desc = parse_scene_desc(&text, Path::new("s.toml")).unwrap();
    assert_eq!(
        desc.objects.last().unwrap().shape,
        ShapeDesc::Mesh {
            file: "meshes/big.ply".into(),
            smooth: true,
            transform: None
        }
    );
    // Building it reads the file, and says where the file was looked for.
    let e = parse_scene(&text, Path::new("s.toml"))
        .unwrap_err()
        .to_string();
    let line = BUILTIN_WHITTED.lines().count() + 4;
    assert!(
        e.contains(&format!(
            "s.toml:{line}:8: cannot load mesh `meshes/big.ply`"
        )),
        "{e}"
    );
}

#[test]
fn glint_renders_a_json_description() {
    let dir = tempfile::tempdir().unwrap();
    let desc = parse_scene_desc(BUILTIN_WHITTED, Path::new("whitted.toml")).unwrap();
    let json = serde_json::to_string_pretty(&desc).unwrap();
    std::fs::write(dir.path().join("w.json"), &json).unwrap();
    std::fs::write(dir.path().join("w.toml"), BUILTIN_WHITTED).unwrap();
    let run = |args: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_glint"))
            .args(args)
            .current_dir(dir.path())
            .output()
            .unwrap()
    };
    let base = ["render", "--width", "32", "--height", "24", "-q", "-o"];
    assert!(
        run(&[&base[..], &["a.exr", "w.json"]].concat())
            .status
            .success()
    );
    assert!(
        run(&[&base[..], &["b.exr", "w.toml"]].concat())
            .status
            .success()
    );
    // The same scene, the same fingerprint: the same file.
    assert_eq!(
        std::fs::read(dir.path().join("a.exr")).unwrap(),
        std::fs::read(dir.path().join("b.exr")).unwrap()
    );
    // A malformed description names the file, line and column.
    let typo = json.replacen("\"fov\"", "\"fvo\"", 1);
    let line = typo.lines().position(|l| l.contains("fvo")).unwrap() + 1;
    std::fs::write(dir.path().join("bad.json"), typo).unwrap();
    let out = run(&[&base[..], &["c.png", "bad.json"]].concat());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        e.contains(&format!("bad.json:{line}:")) && e.contains("unknown field `fvo`"),
        "{e}"
    );
    let bad = json.replacen("\"radius\": 1.0", "\"radius\": -1.0", 1);
    assert_ne!(bad, json);
    std::fs::write(dir.path().join("neg.json"), bad).unwrap();
    let out = run(&[&base[..], &["c.png", "neg.json"]].concat());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        e.contains("neg.json: object 2 (sphere): radius -1 must be positive"),
        "{e}"
    );
}
