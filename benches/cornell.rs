//! The path integrator on the Cornell box (`scenes/cornell.toml`, the
//! anchors' scene): 512×512 at 4 samples per pixel, unbounded depth with
//! Russian roulette. Throughput is in samples (paths) per second; compare
//! with Mitsuba 3's `llvm_ad_rgb` figures from
//! `../shared/anchors/cornell/mitsuba_cornell.py` run in the same session.
//! A second case renders Veach's MIS scene at 384×256, 4 spp.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glint::render::render;
use glint::scene::load_scene_file;
use glint::settings::RenderSettings;
use std::hint::black_box;
use std::path::Path;

fn path_tracing(c: &mut Criterion) {
    let mut group = c.benchmark_group("path");
    group.sample_size(10);
    for (name, file, width, height) in [
        ("cornell_512x512_4spp", "scenes/cornell.toml", 512, 512),
        ("veach_mis_384x256_4spp", "scenes/veach-mis.toml", 384, 256),
    ] {
        let scene = load_scene_file(Path::new(file)).expect("the scene loads");
        let settings = RenderSettings {
            width,
            height,
            spp: 4,
            ..scene.settings.clone()
        };
        group.throughput(Throughput::Elements(width as u64 * height as u64 * 4));
        group.bench_function(name, |b| {
            b.iter(|| {
                render(black_box(&scene.scene), black_box(&settings), &|_| {}).expect("renders")
            })
        });
    }
    group.finish();
}

criterion_group!(benches, path_tracing);
criterion_main!(benches);
