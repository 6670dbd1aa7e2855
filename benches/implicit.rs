//! Renders of implicit surfaces at 512×512, 1 spp: the whole of
//! `scenes/implicit.toml` (the POV-Ray comparison scene: torus, heart, glass
//! sphere over the checkerboard), and the heart and the torus alone over the
//! checkerboard. Prints the interval evaluations per ray of each.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glint::geometry::Shape;
use glint::render::render;
use glint::scene::{Scene, load_scene_file};
use glint::settings::RenderSettings;
use std::hint::black_box;
use std::path::Path;

fn frames(c: &mut Criterion) {
    let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/implicit.toml"));
    let file = load_scene_file(path).expect("scenes/implicit.toml loads");
    let settings = RenderSettings {
        width: 512,
        height: 512,
        spp: 1,
        ..file.settings.clone()
    };
    let s = &file.scene;
    // Keep the ground plane and the implicit object whose formula contains `pick`.
    let only = |pick: &str| {
        let objects = s
            .objects
            .iter()
            .filter(|o| match &o.shape {
                Shape::Implicit(i) => i.formula.contains(pick),
                _ => true,
            })
            .cloned()
            .collect();
        Scene::new(
            s.camera.clone(),
            objects,
            s.materials.clone(),
            s.lights.clone(),
            s.background,
            s.ambient,
        )
        .expect("the objects keep their valid material indices")
    };
    let scenes = [
        ("implicit_scene_512x512", s.clone()),
        ("heart_512x512", only("9/80")),
        ("torus_512x512", only("sqrt(x^2 + y^2)")),
    ];
    let mut group = c.benchmark_group("implicit");
    group.sample_size(10);
    for (name, scene) in &scenes {
        assert!(scene.objects.len() >= 2, "{name}");
        let (_, stats) = render(scene, &settings, &|_| {}).expect("renders");
        eprintln!(
            "{name}: {} rays, {:.2} interval evaluations per ray, {:.2} per root search ({} searches)",
            stats.rays_total,
            stats.implicit_evaluations_per_ray,
            stats.implicit_evaluations_per_search,
            stats.implicit_searches
        );
        group.throughput(Throughput::Elements(stats.rays_total));
        group.bench_function(*name, |b| {
            b.iter(|| render(black_box(scene), black_box(&settings), &|_| {}).expect("renders"))
        });
    }
    group.finish();
}

criterion_group!(benches, frames);
criterion_main!(benches);
