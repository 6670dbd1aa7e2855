//! What splitting a render costs: the built-in Whitted scene at its own
//! settings (800×600, 4 spp) rendered whole, as 16 crops of a 4×4 grid, and
//! as 4 sample ranges of 1 sample, one after another in one process (so
//! process start-up and scene loading, which a farm pays per task, are not
//! counted; `glint render --stats-json` reports them as `seconds_load`); and
//! merging the 16 crops in memory.

use criterion::{Criterion, criterion_group, criterion_main};
use glint::render::parts::merge;
use glint::render::{Film, render_film};
use glint::scene::{BUILTIN_WHITTED, parse_scene};
use glint::settings::{Rect, RenderSettings};
use std::hint::black_box;
use std::path::Path;

fn split(c: &mut Criterion) {
    let file = parse_scene(BUILTIN_WHITTED, Path::new("scenes/whitted.toml"))
        .expect("the built-in scene parses");
    let scene = &file.scene;
    let settings = file.settings.clone();
    let render = |s: &RenderSettings| -> Film {
        let options = glint::render::FilmOptions {
            keep_sums: true,
            ..Default::default()
        };
        render_film(black_box(scene), black_box(s), &options, &|_| {})
            .expect("renders")
            .0
    };
    let crops: Vec<RenderSettings> = (0..16)
        .map(|k| RenderSettings {
            crop: Rect::tile(settings.width, settings.height, 4, 4, k),
            ..settings.clone()
        })
        .collect();
    let ranges: Vec<RenderSettings> = (0..settings.spp)
        .map(|k| RenderSettings {
            spp: 1,
            sample_offset: k,
            ..settings.clone()
        })
        .collect();

    let mut group = c.benchmark_group("split_whitted_800x600_4spp");
    group.sample_size(10);
    group.bench_function("whole", |b| b.iter(|| render(&settings)));
    group.bench_function("16_crops", |b| {
        b.iter(|| crops.iter().map(render).collect::<Vec<_>>())
    });
    group.bench_function("4_sample_ranges", |b| {
        b.iter(|| ranges.iter().map(render).collect::<Vec<_>>())
    });
    let films: Vec<(String, Film)> = crops
        .iter()
        .enumerate()
        .map(|(k, s)| (format!("crop {k}"), render(s)))
        .collect();
    let parts: Vec<(String, &Film)> = films.iter().map(|(n, f)| (n.clone(), f)).collect();
    group.bench_function("merge_16_crops", |b| {
        b.iter(|| merge(black_box(&parts)).expect("merges"))
    });
    group.finish();
}

criterion_group!(benches, split);
criterion_main!(benches);
