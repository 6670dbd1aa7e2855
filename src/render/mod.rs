//! Rendering: pixels in tiles, in parallel, deterministically.
//!
//! Each pixel's samples depend only on the pixel's coordinates (its random
//! sequence is seeded from them), tiles are independent, and their results are
//! assembled in a fixed order, so an image is the same bit for bit whatever the
//! number of threads.

mod film;
mod integrator;
mod sampler;
mod stats;

pub use film::{Image, ImageFormat, ImageWriteError, srgb_encode, write_image};
pub use integrator::{Counters, Integrator, Raycast, Whitted};
pub use sampler::{Pcg32, pixel_offset, strata};
pub use stats::{RayCounts, RenderStats, TileCounters};

use crate::math::Color;
use crate::scene::Scene;
use crate::settings::{IntegratorKind, RenderSettings};
use rayon::prelude::*;
use std::time::Instant;

/// Side of the square tiles the image is cut into, in pixels.
pub const TILE_SIZE: u32 = 16;

#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("invalid render settings: {0}")]
    Settings(String),
    #[error("cannot start {threads} render threads: {message}")]
    ThreadPool { threads: usize, message: String },
}

/// Renders `scene` with `settings`. `progress` is called (from worker threads)
/// with the number of pixels of each finished tile.
pub fn render(
    scene: &Scene,
    settings: &RenderSettings,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Image, RenderStats), RenderError> {
    match settings.integrator {
        IntegratorKind::Raycast => render_with(scene, settings, &Raycast, progress),
        IntegratorKind::Whitted => render_with(
            scene,
            settings,
            &Whitted {
                max_depth: settings.max_depth,
                min_weight: settings.min_weight,
            },
            progress,
        ),
    }
}

/// [`render`] with a given integrator.
pub fn render_with<I: Integrator>(
    scene: &Scene,
    settings: &RenderSettings,
    integrator: &I,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Image, RenderStats), RenderError> {
    settings.validate().map_err(RenderError::Settings)?;
    let start = Instant::now();
    let (image, counters, threads) = if settings.threads == 0 {
        let (image, counters) = render_tiles(scene, settings, integrator, progress);
        (image, counters, rayon::current_num_threads())
    } else {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(settings.threads)
            .build()
            .map_err(|e| RenderError::ThreadPool {
                threads: settings.threads,
                message: e.to_string(),
            })?;
        let (image, counters) =
            pool.install(|| render_tiles(scene, settings, integrator, progress));
        (image, counters, settings.threads)
    };
    let seconds_render = start.elapsed().as_secs_f64();
    let rays_total = counters.rays.total();
    let stats = RenderStats {
        width: settings.width,
        height: settings.height,
        spp: settings.spp,
        integrator: settings.integrator.name().to_string(),
        max_depth: settings.max_depth,
        threads,
        seconds_load: 0.0,
        seconds_render,
        rays: counters.rays,
        rays_total,
        rays_per_second: rays_total as f64 / seconds_render.max(1e-9),
        intersection_tests: counters.intersection_tests,
        implicit_searches: counters.implicit_searches,
        implicit_evaluations: counters.implicit_evaluations,
        implicit_evaluations_per_search: counters.implicit_evaluations as f64
            / counters.implicit_searches.max(1) as f64,
        bvh_nodes_visited: counters.bvh_nodes_visited,
        triangle_tests: counters.triangle_tests,
        bvh_nodes_visited_per_ray: counters.bvh_nodes_visited as f64 / rays_total.max(1) as f64,
        triangle_tests_per_ray: counters.triangle_tests as f64 / rays_total.max(1) as f64,
        implicit_evaluations_per_ray: counters.implicit_evaluations as f64
            / rays_total.max(1) as f64,
        nan_pixels: counters.nan_pixels,
        bad_samples: counters.bad_samples,
    };
    Ok((image, stats))
}

#[derive(Clone, Copy)]
struct Tile {
    x0: u32,
    y0: u32,
    width: u32,
    height: u32,
}

fn render_tiles<I: Integrator>(
    scene: &Scene,
    settings: &RenderSettings,
    integrator: &I,
    progress: &(dyn Fn(u64) + Sync),
) -> (Image, TileCounters) {
    let (w, h) = (settings.width, settings.height);
    let tiles: Vec<Tile> = (0..h.div_ceil(TILE_SIZE))
        .flat_map(|ty| {
            (0..w.div_ceil(TILE_SIZE)).map(move |tx| {
                let (x0, y0) = (tx * TILE_SIZE, ty * TILE_SIZE);
                Tile {
                    x0,
                    y0,
                    width: TILE_SIZE.min(w - x0),
                    height: TILE_SIZE.min(h - y0),
                }
            })
        })
        .collect();
    let rendered: Vec<(Vec<Color>, TileCounters)> = tiles
        .par_iter()
        .map(|tile| {
            let out = render_tile(scene, settings, integrator, tile);
            progress(tile.width as u64 * tile.height as u64);
            out
        })
        .collect();

    let mut image = Image::new(w, h);
    let mut total = TileCounters::default();
    for (tile, (pixels, counters)) in tiles.iter().zip(rendered) {
        for row in 0..tile.height {
            let src = &pixels[(row * tile.width) as usize..((row + 1) * tile.width) as usize];
            let start = ((tile.y0 + row) * w + tile.x0) as usize;
            image.pixels[start..start + tile.width as usize].copy_from_slice(src);
        }
        total += counters;
    }
    (image, total)
}

fn render_tile<I: Integrator>(
    scene: &Scene,
    settings: &RenderSettings,
    integrator: &I,
    tile: &Tile,
) -> (Vec<Color>, TileCounters) {
    let mut pixels = Vec::with_capacity((tile.width * tile.height) as usize);
    let mut counters = Counters::default();
    let (mut bad_samples, mut nan_pixels) = (0, 0);
    let spp = settings.spp.max(1);
    for y in tile.y0..tile.y0 + tile.height {
        for x in tile.x0..tile.x0 + tile.width {
            let mut rng = Pcg32::for_pixel(x, y);
            let mut sum = Color::ZERO;
            let mut bad = 0;
            for s in 0..spp {
                let (u, v) = pixel_offset(s, spp, &mut rng);
                let ray =
                    scene
                        .camera
                        .ray(x as f32 + u, y as f32 + v, settings.width, settings.height);
                counters.rays.camera += 1;
                let l = integrator.radiance(scene, &ray, &mut counters);
                // Guard: no NaN or infinity reaches a pixel; count them instead.
                if l.is_finite() {
                    sum += l.max(Color::ZERO);
                } else {
                    bad += 1;
                }
            }
            bad_samples += bad;
            nan_pixels += (bad > 0) as u64;
            pixels.push(sum / spp as f32);
        }
    }
    (
        pixels,
        TileCounters {
            rays: counters.rays,
            intersection_tests: counters.trace.intersection_tests,
            implicit_searches: counters.trace.implicit_searches,
            implicit_evaluations: counters.trace.implicit_evaluations,
            bvh_nodes_visited: counters.trace.bvh.nodes_visited,
            triangle_tests: counters.trace.bvh.primitive_tests,
            bad_samples,
            nan_pixels,
        },
    )
}
