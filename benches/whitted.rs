//! Whole frames of the built-in Whitted scene at 512×512, 1 spp, max depth 8 —
//! the setting of the POV-Ray comparison in `shared/anchors` (`bench_pov.py`,
//! case `whitted_d8`) — with ray casting beside it, and at 1280×720 (the
//! real-time target: 1/30 s). Throughput is reported in rays (all kinds)
//! per second. Last, the 512×512 frame with every AOV gathered.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glint::render::{Aov, FilmOptions, render, render_film};
use glint::scene::{BUILTIN_WHITTED, parse_scene};
use glint::settings::{IntegratorKind, RenderSettings};
use std::hint::black_box;
use std::path::Path;

fn frames(c: &mut Criterion) {
    let file = parse_scene(BUILTIN_WHITTED, Path::new("scenes/whitted.toml"))
        .expect("the built-in scene parses");
    let mut group = c.benchmark_group("whitted_scene");
    group.sample_size(30);
    for (name, integrator, width, height) in [
        ("whitted_512x512", IntegratorKind::Whitted, 512, 512),
        ("raycast_512x512", IntegratorKind::Raycast, 512, 512),
        ("whitted_1280x720", IntegratorKind::Whitted, 1280, 720),
    ] {
        let settings = RenderSettings {
            width,
            height,
            spp: 1,
            max_depth: 8,
            integrator,
            ..file.settings.clone()
        };
        let (_, stats) = render(&file.scene, &settings, &|_| {}).expect("renders");
        group.throughput(Throughput::Elements(stats.rays_total));
        group.bench_function(name, |b| {
            b.iter(|| {
                render(black_box(&file.scene), black_box(&settings), &|_| {}).expect("renders")
            })
        });
    }
    // The same frame with every output variable gathered: what AOVs cost
    // (off, they cost a branch per pixel: compare whitted_512x512).
    let settings = RenderSettings {
        width: 512,
        height: 512,
        spp: 1,
        max_depth: 8,
        ..file.settings.clone()
    };
    let options = FilmOptions {
        keep_sums: false,
        aovs: Aov::ALL.to_vec(),
    };
    group.bench_function("whitted_512x512_all_aovs", |b| {
        b.iter(|| {
            render_film(
                black_box(&file.scene),
                black_box(&settings),
                &options,
                &|_| {},
            )
            .expect("renders")
        })
    });
    group.finish();
}

criterion_group!(benches, frames);
criterion_main!(benches);
