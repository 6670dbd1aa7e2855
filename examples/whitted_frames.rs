//! Renders the built-in Whitted scene at 1280×720 (1 spp, depth 8) `N`
//! times (`cargo run --release --example whitted_frames -- N`, 40 by
//! default) and prints the mean and best time per frame: a fixed amount of
//! work, to compare builds in turns on a noisy machine.

use glint::render::render;
use glint::scene::{BUILTIN_WHITTED, parse_scene};
use glint::settings::{IntegratorKind, RenderSettings};
use std::path::Path;
fn main() {
    let n: u32 = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(40);
    let file = parse_scene(BUILTIN_WHITTED, Path::new("scenes/whitted.toml")).unwrap();
    let settings = RenderSettings {
        width: 1280,
        height: 720,
        spp: 1,
        max_depth: 8,
        integrator: IntegratorKind::Whitted,
        ..file.settings.clone()
    };
    render(&file.scene, &settings, &|_| {}).unwrap();
    let mut best = f64::INFINITY;
    let t = std::time::Instant::now();
    for _ in 0..n {
        let t0 = std::time::Instant::now();
        render(&file.scene, &settings, &|_| {}).unwrap();
        best = best.min(t0.elapsed().as_secs_f64());
    }
    println!(
        "mean {:.2} ms, best {:.2} ms",
        t.elapsed().as_secs_f64() * 1e3 / n as f64,
        best * 1e3
    );
}
