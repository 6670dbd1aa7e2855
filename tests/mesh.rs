//! Triangle meshes: the BVH against brute force, watertightness at shared
//! edges and vertices, inside/outside, and instancing.

use glam::{DVec3, Vec3 as V3};
use glint::geometry::testgen::{icosphere, torus};
use glint::geometry::{
    Mesh, MeshInstance, Shape, TraceCounters, intersect_mt, intersect_watertight,
};
use glint::math::{Ray, Transform, Vec3};
use glint::render::{Pcg32, render};
use glint::scene::{Camera, Light, Material, Object, Scene};
use glint::settings::{IntegratorKind, RenderSettings};
use rayon::prelude::*;
use std::sync::Arc;

fn mesh((v, f): (Vec<V3>, Vec<[u32; 3]>)) -> Mesh {
    Mesh::new(v, f, Vec::new(), Vec::new()).unwrap()
}

fn random_in(rng: &mut Pcg32, half: f32) -> Vec3 {
    (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - Vec3::ONE) * half
}

/// Closest hit by testing every triangle: (t, triangle).
fn brute_force(m: &Mesh, ray: &Ray) -> Option<(f32, u32)> {
    let mut best: Option<(f32, u32)> = None;
    for (i, t) in m.triangles.iter().enumerate() {
        let [a, b, c] = t.map(|k| Vec3::from(m.positions[k as usize]));
        let t_max = best.map_or(ray.t_max, |b| b.0);
        if let Some((h, _)) = intersect_watertight(ray.o, ray.d, a, b, c, ray.t_min, t_max) {
            best = Some((h.t, i as u32));
        }
    }
    best
}

fn random_soup(n: usize, seed: u64) -> Mesh {
    let mut rng = Pcg32::new(seed, 4);
    let mut v = Vec::new();
    let mut f = Vec::new();
    for i in 0..n {
        let c = random_in(&mut rng, 5.0);
        for _ in 0..3 {
            v.push(V3::from(c + random_in(&mut rng, 0.4)));
        }
        f.push([3 * i as u32, 3 * i as u32 + 1, 3 * i as u32 + 2]);
    }
    mesh((v, f))
}

#[test]
fn bvh_matches_brute_force_over_100k_rays() {
    // Small meshes (lanes per triangle, batched across leaves), and two
    // larger than glint::geometry::mesh's 4,096 (leaf blocks).
    let meshes = [
        random_soup(3000, 1),
        mesh(icosphere(3, 2.0)),
        mesh(torus(2.0, 0.6, 40, 20)),
        random_soup(6000, 2),
        mesh(torus(2.0, 0.6, 96, 48)),
    ];
    for (k, m) in meshes.iter().enumerate() {
        let bvh_ok = m.validate_bvh();
        assert!(bvh_ok.is_ok(), "{bvh_ok:?}");
        let rays = match k {
            0 => 40_000,
            1 | 2 => 30_000,
            _ => 4_000,
        };
        let mismatches: usize = (0..rays)
            .into_par_iter()
            .map(|i| {
                let mut rng = Pcg32::new(i as u64, 10 + k as u64);
                let o = random_in(&mut rng, 8.0);
                let target = random_in(&mut rng, 3.0);
                let ray = Ray::new(o, target - o);
                let mut c = TraceCounters::default();
                let got = m.intersect_object(&ray, &mut c).map(|h| (h.t, h.prim));
                let want = brute_force(m, &ray);
                let occluded = m.occludes_object(&ray, &mut c);
                let same = match (got, want) {
                    (Some(g), Some(w)) => {
                        g.0 == w.0
                            && (g.1 == w.1 || {
                                // A tie at a shared edge: both triangles give this t.
                                let [a, b, cc] = m.triangles[g.1 as usize]
                                    .map(|x| Vec3::from(m.positions[x as usize]));
                                intersect_watertight(ray.o, ray.d, a, b, cc, 0.0, f32::INFINITY)
                                    .map(|h| h.0.t)
                                    == Some(w.0)
                            })
                    }
                    (None, None) => true,
                    _ => false,
                };
                (!same || occluded != want.is_some()) as usize
            })
            .sum();
        assert_eq!(
            mismatches, 0,
            "mesh {k}: {mismatches} rays differ from brute force"
        );
    }
}

/// Rays from outside aimed exactly at shared edges (midpoints and points a
/// third of the way along) and at shared vertices of closed meshes, from
/// directions near the surface normal there (so every triangle around the
/// target faces the ray: at a silhouette a ray through an edge only grazes the
/// surface, and a miss is right). Every ray must hit one of the triangles
/// around its target: none may slip between them.
#[test]
fn no_leaks_at_shared_edges_and_vertices() {
    for (name, m) in [
        ("icosphere", mesh(icosphere(4, 1.0))),
        ("torus", mesh(torus(1.0, 0.35, 64, 32))),
    ] {
        let p = |i: u32| Vec3::from(m.positions[i as usize]);
        let normal = |t: &[u32; 3]| (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0])).normalize();
        let mut by_edge: std::collections::HashMap<(u32, u32), Vec<usize>> = Default::default();
        let mut by_vertex: Vec<Vec<usize>> = vec![Vec::new(); m.positions.len()];
        for (i, t) in m.triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                by_edge.entry((a.min(b), a.max(b))).or_default().push(i);
                by_vertex[a as usize].push(i);
            }
        }
        // (target point, triangles around it)
        let mut targets: Vec<(Vec3, &[usize])> = Vec::new();
        for (&(a, b), tris) in &by_edge {
            assert_eq!(
                tris.len(),
                2,
                "{name}: edge {a}-{b} is not shared by two triangles"
            );
            targets.push(((p(a) + p(b)) * 0.5, tris));
            targets.push((p(a) + (p(b) - p(a)) / 3.0, tris));
        }
        for (v, tris) in by_vertex.iter().enumerate() {
            targets.push((p(v as u32), tris));
        }
        let mut rng = Pcg32::new(77, 1);
        let (mut leaks_mt, mut leaks_wt) = (0, 0);
        for &(target, tris) in &targets {
            let n: Vec3 = tris
                .iter()
                .map(|&i| normal(&m.triangles[i]))
                .sum::<Vec3>()
                .normalize();
            let o = target + (n + random_in(&mut rng, 0.15)) * (1.0 + 3.0 * rng.next_f32());
            let d = target - o;
            assert!(
                tris.iter().all(|&i| normal(&m.triangles[i]).dot(d) < 0.0),
                "{name}: a triangle faces away"
            );
            let hits = |test: &dyn Fn(Vec3, Vec3, Vec3) -> bool| {
                tris.iter().any(|&i| {
                    let [a, b, c] = m.triangles[i].map(p);
                    test(a, b, c)
                })
            };
            if !hits(&|a, b, c| intersect_mt(o, d, a, b, c, 0.0, f32::INFINITY).is_some()) {
                leaks_mt += 1;
            }
            if !hits(&|a, b, c| intersect_watertight(o, d, a, b, c, 0.0, f32::INFINITY).is_some()) {
                leaks_wt += 1;
            }
        }
        assert!(targets.len() > 5000, "{name}: {}", targets.len());
        assert_eq!(
            (leaks_mt, leaks_wt),
            (0, 0),
            "{name}: leaks of {} rays (Möller–Trumbore, watertight)",
            targets.len()
        );
    }
}

#[test]
fn contains_matches_analytic_inside_outside() {
    let sphere = mesh(icosphere(4, 1.0));
    let (big_r, small_r) = (1.0f32, 0.4f32);
    let ring = mesh(torus(big_r, small_r, 96, 48));
    let mut rng = Pcg32::new(5, 9);
    let mut checked = 0;
    for _ in 0..4000 {
        let p = random_in(&mut rng, 1.6);
        // Facets lie inside the analytic surface by at most ~0.5% here: skip a band.
        let r = p.length();
        if (r - 1.0).abs() > 0.02 {
            assert_eq!(sphere.contains(p), r < 1.0, "sphere at {p:?}");
            checked += 1;
        }
        let q = ((p.x * p.x + p.y * p.y).sqrt() - big_r).hypot(p.z);
        if (q - small_r).abs() > 0.02 {
            assert_eq!(ring.contains(p), q < small_r, "torus at {p:?}");
            checked += 1;
        }
    }
    assert!(checked > 7000);
    // Points exactly on axes and planes of symmetry, where a ray along a
    // coordinate direction would graze edges and vertices.
    assert!(sphere.contains(Vec3::ZERO));
    assert!(!ring.contains(Vec3::ZERO));
    assert!(ring.contains(Vec3::new(1.0, 0.0, 0.0)));
}

/// An instance with a transform renders the same image as the mesh with the
/// transform baked into its vertices.
#[test]
fn instance_renders_like_the_baked_mesh() {
    let (v, f) = torus(1.0, 0.35, 48, 24);
    let t = Transform::from_parts(
        DVec3::new(1.0, 1.5, 0.8),
        DVec3::new(-60.0, 20.0, 10.0),
        DVec3::new(0.3, 1.0, -0.5),
    )
    .unwrap();
    let baked: Vec<V3> = v
        .iter()
        .map(|p| t.world_from_object.transform_point3(p.as_dvec3()).as_vec3())
        .collect();
    let instance = Shape::Mesh(MeshInstance::new(Arc::new(mesh((v, f.clone()))), Some(&t)));
    let plain = Shape::Mesh(MeshInstance::new(Arc::new(mesh((baked, f))), None));
    let scene = |shape: Shape| {
        Scene::new(
            Camera::try_new(
                Vec3::new(0.0, 1.5, -3.5),
                Vec3::new(0.3, 1.0, -0.5),
                Vec3::Y,
                40.0,
            )
            .unwrap(),
            vec![Object { shape, material: 0 }],
            vec![Material::default_diffuse()],
            vec![Light::Point {
                position: Vec3::new(3.0, 6.0, -4.0),
                intensity: glint::math::Color::splat(40.0),
            }],
            glint::math::Color::ZERO,
            glint::math::Color::ZERO,
        )
        .unwrap()
    };
    let settings = RenderSettings {
        width: 96,
        height: 72,
        spp: 1,
        integrator: IntegratorKind::Raycast,
        ..Default::default()
    };
    let (a, _) = render(&scene(instance), &settings, &|_| {}).unwrap();
    let (b, _) = render(&scene(plain), &settings, &|_| {}).unwrap();
    let lit = a.pixels.iter().filter(|c| c.x > 0.0).count();
    let differ = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .filter(|(x, y)| (**x - **y).abs().max_element() > 1e-3)
        .count();
    assert!(lit > 1000, "{lit} lit pixels");
    // Silhouette pixels may flip where a ray grazes an edge to within rounding.
    assert!(differ <= lit / 200, "{differ} of {lit} pixels differ");
}

/// A PLY file of a generated mesh, written with the binary little-endian layout.
fn write_ply(path: &std::path::Path, (v, f): &(Vec<V3>, Vec<[u32; 3]>)) {
    let mut out = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        v.len(),
        f.len()
    )
    .into_bytes();
    for p in v {
        for c in p.to_array() {
            out.extend(c.to_le_bytes());
        }
    }
    for t in f {
        out.push(3);
        for i in t {
            out.extend(i.to_le_bytes());
        }
    }
    std::fs::write(path, out).unwrap();
}

/// 1,000 instances of one 20,480-triangle mesh in a scene file: the mesh is
/// read and stored once, and every instance renders.
#[test]
fn thousand_instances_share_one_mesh() {
    let dir = tempfile::tempdir().unwrap();
    write_ply(&dir.path().join("ball.ply"), &icosphere(5, 0.4));
    let mut scene = String::from(
        "[camera]\nposition = [4.5, 4.5, -14]\nlook_at = [4.5, 4.5, 4.5]\n[render]\nwidth = 64\nheight = 48\nintegrator = \"raycast\"\n\
         [[light]]\ntype = \"directional\"\ndirection = [0.3, -1, 0.5]\nirradiance = 1\n",
    );
    for i in 0..1000 {
        let (x, y, z) = (i % 10, i / 10 % 10, i / 100);
        scene += &format!(
            "[[object]]\nshape = \"mesh\"\nfile = \"ball.ply\"\ntransform = {{ scale = [1, {}, 1], rotate_y = {}, translate = [{x}, {y}, {z}] }}\n",
            1.0 + 0.1 * (i % 3) as f32,
            i % 90
        );
    }
    std::fs::write(dir.path().join("s.toml"), scene).unwrap();
    let file =
        glint::scene::load_scene_file(&dir.path().join("s.toml")).unwrap_or_else(|e| panic!("{e}"));
    let g = file.scene.geometry_stats();
    assert_eq!(
        (g.meshes, g.instances, g.triangles, g.triangles_instanced),
        (1, 1000, 20_480, 20_480_000)
    );
    // The memory of one mesh (about 100 bytes per triangle with its leaf
    // blocks), not a thousand.
    assert!(g.mesh_bytes < 20_480 * 128, "{} bytes", g.mesh_bytes);
    let (image, stats) = render(&file.scene, &file.settings, &|_| {}).unwrap();
    let lit = image.pixels.iter().filter(|c| c.x > 0.0).count();
    assert!(lit > 64 * 48 / 5, "{lit} lit pixels");
    // The top-level BVH culls: far fewer than 1,000 object tests per ray.
    assert!(
        stats.intersection_tests < stats.rays_total * 40,
        "{} tests for {} rays",
        stats.intersection_tests,
        stats.rays_total
    );
}

/// Rays spawned from hits on transformed instances (non-uniform scale,
/// rotation, translation) towards a light never hit the same instance again
/// at t ≈ 0: the error bound covers the rounding of taking the ray back into
/// the instance's object space. (The instances of
/// `thousand_instances_share_one_mesh`, whose render showed shadow acne
/// before that term was added.)
#[test]
fn spawned_rays_leave_transformed_instances() {
    let ball = Arc::new(mesh(icosphere(5, 0.4)));
    let light = -Vec3::new(0.3, -1.0, 0.5).normalize();
    let mut rng = Pcg32::new(3, 3);
    let (mut tested, mut rehits) = (0, 0);
    for i in 0..1000 {
        let (x, y, z) = ((i % 10) as f64, (i / 10 % 10) as f64, (i / 100) as f64);
        let t = Transform::from_parts(
            DVec3::new(1.0, 1.0 + 0.1 * (i % 3) as f64, 1.0),
            DVec3::new(0.0, (i % 90) as f64, 0.0),
            DVec3::new(x, y, z),
        )
        .unwrap();
        let inst = MeshInstance::new(ball.clone(), Some(&t));
        let centre = Vec3::new(x as f32, y as f32, z as f32);
        for _ in 0..40 {
            let o = centre + Vec3::new(0.0, 0.0, -3.0) + random_in(&mut rng, 0.5);
            let ray = Ray::new(o, centre + random_in(&mut rng, 0.4) - o);
            let mut c = TraceCounters::default();
            let Some(h) = inst.intersect(&ray, &mut c) else {
                continue;
            };
            let s = inst.surface(&ray, &h);
            if s.n.dot(light) <= 0.0 {
                continue;
            }
            tested += 1;
            let out = Ray::spawn(s.p, s.p_err, s.n, light);
            if inst
                .intersect(&out, &mut c)
                .is_some_and(|again| again.t < 1e-3)
            {
                rehits += 1;
            }
        }
    }
    assert!(tested > 10_000, "{tested}");
    assert_eq!(
        rehits, 0,
        "{rehits} of {tested} shadow rays hit their own surface again"
    );
}

/// `smooth = true` gives a mesh file without normals area-weighted vertex
/// normals (on a sphere: nearly radial), shared by the objects that ask for
/// them; the same file without it stays flat; a non-boolean is an error.
#[test]
fn smooth_option_makes_vertex_normals() {
    let dir = tempfile::tempdir().unwrap();
    write_ply(&dir.path().join("ball.ply"), &icosphere(3, 1.0));
    let head = "[camera]\nposition = [0, 0, -5]\nlook_at = [0, 0, 0]\n";
    let object =
        |extra: &str| format!("[[object]]\nshape = \"mesh\"\nfile = \"ball.ply\"\n{extra}");
    let scene = format!(
        "{head}{}{}{}",
        object("smooth = true\n"),
        object("smooth = true\ntransform = { translate = [3, 0, 0] }\n"),
        object("")
    );
    std::fs::write(dir.path().join("s.toml"), scene).unwrap();
    let file =
        glint::scene::load_scene_file(&dir.path().join("s.toml")).unwrap_or_else(|e| panic!("{e}"));
    let meshes: Vec<&Arc<Mesh>> = file
        .scene
        .objects
        .iter()
        .map(|o| match &o.shape {
            Shape::Mesh(m) => &m.mesh,
            other => panic!("not a mesh: {other:?}"),
        })
        .collect();
    let (smooth, flat) = (meshes[0], meshes[2]);
    assert!(
        Arc::ptr_eq(meshes[0], meshes[1]),
        "one smoothed mesh, shared"
    );
    assert!(flat.normals.is_empty());
    assert_eq!(smooth.normals.len(), smooth.positions.len());
    for (p, n) in smooth.positions.iter().zip(&smooth.normals) {
        assert!(n.dot(p.normalize()) > 0.99, "normal {n} at {p}");
    }
    std::fs::write(
        dir.path().join("bad.toml"),
        format!("{head}{}", object("smooth = \"yes\"\n")),
    )
    .unwrap();
    let Err(err) = glint::scene::load_scene_file(&dir.path().join("bad.toml")) else {
        panic!("a string is not a boolean");
    };
    let err = err.to_string();
    assert!(
        err.contains("bad.toml:7:10") && err.contains("expected true or false"),
        "{err}"
    );
}

/// The same mesh scene written at scales from 1e-30 to 1e30 (vertices
/// scaled, not placed with a transform), framed by `mesh_scene`: a diffuse
/// icosphere, a mirror torus and a glass sphere lit by its light. From
/// 1e-9 to 1e9 the image is that of scale 1 (to f32 rounding, at a few
/// silhouette pixels at most), and at every scale no sample is NaN or
/// infinite and the diffuse mesh is lit. (Before normals were computed in
/// f64, meshes at 1e±10 lost them: diffuse went unlit, mirrors see-through
/// and glass gave NaN.)
#[test]
fn meshes_far_from_unit_size_render_the_same_image() {
    use glint::scene::meshio::{Model, ModelPart};
    use glint::scene::{MaterialKind, mesh_scene};
    let render_at = |scale: f32| {
        let part = |(v, f): (Vec<V3>, Vec<[u32; 3]>), at: V3, material: Material| {
            let v = v.into_iter().map(|p| (p + at) * scale).collect();
            ModelPart {
                name: String::new(),
                mesh: Arc::new(mesh((v, f))),
                transform: None,
                material: Some(material),
            }
        };
        let mirror = Material {
            kind: MaterialKind::Mirror {
                reflectance: Vec3::splat(0.9),
            },
            diffuse: 0.0,
            ambient: 0.0,
            ..Material::default_diffuse()
        };
        let glass = Material {
            kind: MaterialKind::Dielectric {
                ior: 1.5,
                absorption: Vec3::ZERO,
                roughness: 0.0,
            },
            diffuse: 0.0,
            ambient: 0.0,
            ..Material::default_diffuse()
        };
        let model = Model {
            parts: vec![
                part(
                    icosphere(3, 1.0),
                    V3::new(-1.2, 0.0, 0.0),
                    Material::default_diffuse(),
                ),
                part(torus(0.8, 0.25, 48, 24), V3::new(1.2, 0.0, 0.0), mirror),
                part(icosphere(3, 0.6), V3::new(0.0, 0.8, 1.2), glass),
            ],
            ..Model::default()
        };
        let file = mesh_scene(&model, V3::new(0.35, 0.3, 1.0).into(), Vec3::Y).unwrap();
        let settings = RenderSettings {
            width: 128,
            height: 72,
            integrator: IntegratorKind::Whitted,
            max_depth: 6,
            ..RenderSettings::default()
        };
        render(&file.scene, &settings, &|_| {}).unwrap()
    };
    let (reference, _) = render_at(1.0);
    // Pixels of the diffuse sphere facing the light are brighter than the
    // sky and anything else in the picture.
    let lit = |image: &glint::render::Image| {
        image
            .pixels
            .iter()
            .filter(|c| c.min_element() > 0.7)
            .count()
    };
    assert!(
        lit(&reference) > 40,
        "only {} lit pixels at scale 1",
        lit(&reference)
    );
    for exponent in [-30, -20, -16, -12, -9, -6, -3, 3, 6, 9, 12, 16, 18, 20, 30] {
        let scale = 10f32.powi(exponent);
        let (image, stats) = render_at(scale);
        assert_eq!(
            stats.bad_samples, 0,
            "NaN or infinite samples at 1e{exponent}"
        );
        if !(-16..=18).contains(&exponent) {
            // Beyond, the triangle test's edge functions (products of two
            // lengths) leave f32's normal range and the mesh may vanish,
            // but nothing is NaN.
            continue;
        }
        let lit_here = lit(&image);
        assert!(lit_here > 40, "only {lit_here} lit pixels at 1e{exponent}");
        if exponent.abs() <= 9 {
            let differing = image
                .pixels
                .iter()
                .zip(&reference.pixels)
                .filter(|(a, b)| (**a - **b).abs().max_element() > 1e-3)
                .count();
            assert!(
                differing <= 8,
                "{differing} pixels differ from scale 1 at 1e{exponent}"
            );
        }
    }
}

/// 40 cubes of side 0.2 in one mesh, along x, 0.5 apart, and a ray down
/// their row: 80 crossings (once, only 32 were kept, in BVH order), an
/// inside length of exactly 40·0.2, and from the centre of the first cube
/// (a segment that starts inside) 0.1 + 39·0.2.
#[test]
fn crossings_of_many_surfaces_and_from_inside() {
    let mut v: Vec<V3> = Vec::new();
    let mut f: Vec<[u32; 3]> = Vec::new();
    for k in 0..40 {
        let c = V3::new(0.5 * k as f32, 0.0, 0.0);
        let base = v.len() as u32;
        for i in 0..8 {
            let corner = V3::new(
                if i & 1 == 0 { -0.1 } else { 0.1 },
                if i & 2 == 0 { -0.1 } else { 0.1 },
                if i & 4 == 0 { -0.1 } else { 0.1 },
            );
            v.push(c + corner);
        }
        for q in [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ] {
            f.push([base + q[0], base + q[1], base + q[2]]);
            f.push([base + q[0], base + q[2], base + q[3]]);
        }
    }
    let instance = MeshInstance::new(Arc::new(mesh((v, f))), None);
    let mut counters = TraceCounters::default();
    let mut crossings = 0;
    let ray = Ray::new(Vec3::new(-1.0, 0.013, 0.021), Vec3::X);
    let inside = instance.crossings(&ray, &mut counters, &mut |cos| {
        assert!((cos - 1.0).abs() < 1e-6);
        crossings += 1;
    });
    assert_eq!(crossings, 80);
    assert!((inside - 8.0).abs() < 1e-4, "{inside}");
    // From inside the first cube, to a point inside the 21st (x = 10.05).
    let ray = Ray {
        t_max: 10.05,
        ..Ray::new(Vec3::new(0.0, 0.013, 0.021), Vec3::X)
    };
    let mut crossings = 0;
    let inside = instance.crossings(&ray, &mut counters, &mut |_| crossings += 1);
    assert_eq!(crossings, 1 + 2 * 19 + 1);
    let expected = 0.1 + 19.0 * 0.2 + 0.15;
    assert!((inside - expected).abs() < 1e-4, "{inside} vs {expected}");
}

/// Packets of up to 16 rays (`Mesh::intersect_packet` and
/// `Mesh::occludes_packet`, and the same always traced as packets,
/// `Mesh::intersect_as_packet` and `Mesh::occludes_as_packet`, since the
/// first may trace a packet ray by ray) against the same rays one by one:
/// coherent 4×4 blocks of camera rays, incoherent rays of
/// mixed octants, segments cut short, and rays that the packet hands to the
/// single-ray traversal (`t_min < 0`). Each ray must get the same `t`, bit
/// for bit, and the same triangle or another one hit at exactly that `t`;
/// and the same answer to whether anything blocks its segment.
#[test]
fn packets_match_single_rays() {
    let meshes = [
        mesh(icosphere(3, 2.0)),
        mesh(torus(2.0, 0.6, 40, 20)),
        random_soup(3000, 5),
        mesh(torus(2.0, 0.6, 96, 48)),
    ];
    for (k, m) in meshes.iter().enumerate() {
        let mut rng = Pcg32::new(7, 20 + k as u64);
        for p in 0..600 {
            let n = 1 + rng.next_u32() as usize % 16;
            let rays: Vec<Ray> = match p % 3 {
                // A 4×4 block of a pinhole camera's rays.
                0 => {
                    let eye = random_in(&mut rng, 1.0) + Vec3::new(0.0, 0.0, 7.0);
                    let (cx, cy) = (rng.next_f32() * 2.0 - 1.0, rng.next_f32() * 2.0 - 1.0);
                    let step = 0.002 + 0.02 * rng.next_f32();
                    (0..n)
                        .map(|i| {
                            let (x, y) = ((i % 4) as f32, (i / 4) as f32);
                            let d = Vec3::new(cx + step * x, cy + step * y, -2.5);
                            Ray::new(eye, d)
                        })
                        .collect()
                }
                // Incoherent: every octant.
                1 => (0..n)
                    .map(|_| {
                        let o = random_in(&mut rng, 8.0);
                        Ray::new(o, random_in(&mut rng, 3.0) - o)
                    })
                    .collect(),
                // Shared origin, cut short, some with t_min < 0.
                _ => {
                    let o = random_in(&mut rng, 6.0);
                    (0..n)
                        .map(|_| {
                            let mut r = Ray::new(o, random_in(&mut rng, 2.5) - o);
                            r.t_max = 0.3 + rng.next_f32();
                            if rng.next_u32().is_multiple_of(4) {
                                r.t_min = -1.0;
                            }
                            r
                        })
                        .collect()
                }
            };
            let (mut got, mut got_as) = (vec![None; n], vec![None; n]);
            let mut c = TraceCounters::default();
            m.intersect_packet(&rays, &mut c, &mut got);
            m.intersect_as_packet(&rays, &mut c, &mut got_as);
            let (mut blocked, mut blocked_as) = (vec![false; n], vec![false; n]);
            m.occludes_packet(&rays, &mut c, &mut blocked);
            m.occludes_as_packet(&rays, &mut c, &mut blocked_as);
            for (ray, b) in rays.iter().cycle().zip(blocked.iter().chain(&blocked_as)) {
                assert_eq!(*b, m.occludes_object(ray, &mut c), "mesh {k}, packet {p}");
            }
            for (ray, g) in rays.iter().cycle().zip(got.iter().chain(&got_as)) {
                let want = m.intersect_object(ray, &mut c);
                match (g, want) {
                    (Some(g), Some(w)) => {
                        assert_eq!(g.t.to_bits(), w.t.to_bits(), "mesh {k}, packet {p}");
                        if g.prim != w.prim {
                            let [a, b, cc] = m.triangles[g.prim as usize]
                                .map(|x| Vec3::from(m.positions[x as usize]));
                            let t =
                                intersect_watertight(ray.o, ray.d, a, b, cc, ray.t_min, ray.t_max);
                            assert_eq!(t.map(|h| h.0.t), Some(w.t), "mesh {k}, packet {p}");
                        } else {
                            assert_eq!((g.u, g.v), (w.u, w.v), "mesh {k}, packet {p}");
                        }
                    }
                    (None, None) => {}
                    _ => panic!("mesh {k}, packet {p}: {g:?} vs {want:?}"),
                }
            }
        }
    }
}
