//! Rendering: pixels in tiles, in parallel, deterministically.
//!
//! Each pixel's samples depend only on the pixel's coordinates (its random
//! sequence is seeded from them), tiles are independent, and their results are
//! assembled in a fixed order, so an image is the same bit for bit whatever the
//! number of threads.

mod film;
mod integrator;
pub mod memory;
mod sampler;
mod stats;

pub use film::{
    Image, ImageFormat, ImageWriteError, StagedFile, commit_all, srgb_encode, write_image,
};
pub use integrator::{Counters, Integrator, MAX_RAY_TREE, Raycast, Whitted};
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
    #[error(
        "a {width}×{height} image needs {:.2} GB for its pixels (16 bytes each), but only {:.2} GB of memory is available; render a smaller image",
        *needed as f64 / 1e9,
        *available as f64 / 1e9
    )]
    Memory {
        width: u32,
        height: u32,
        needed: u64,
        available: u64,
    },
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
    let (width, height) = (settings.width, settings.height);
    let memory_error = |available| RenderError::Memory {
        width,
        height,
        needed: Image::bytes_for(width, height),
        available,
    };
    // Refused up front where the system says how much it has; allocated
    // fallibly in any case.
    if let Some(available) = memory::available_bytes()
        && Image::bytes_for(width, height) > available
    {
        return Err(memory_error(available));
    }
    let image = Image::try_new(width, height).ok_or_else(|| memory_error(0))?;
    let start = Instant::now();
    let (image, counters, threads) = if settings.threads == 0 {
        let (image, counters) = render_tiles(scene, settings, integrator, progress, image);
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
            pool.install(|| render_tiles(scene, settings, integrator, progress, image));
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
        ray_trees_cut: counters.ray_trees_cut,
        implicit_searches_cut: counters.implicit_searches_cut,
    };
    Ok((image, stats))
}

/// A tile: its top-left pixel and, row by row, the slices of the image it
/// covers (so tiles are rendered in parallel straight into the image).
struct Tile<'a> {
    x0: u32,
    y0: u32,
    rows: Vec<&'a mut [Color]>,
}

/// Renders every pixel of `image` (blank, `settings.width × settings.height`)
/// in tiles of [`TILE_SIZE`]², in parallel.
fn render_tiles<I: Integrator>(
    scene: &Scene,
    settings: &RenderSettings,
    integrator: &I,
    progress: &(dyn Fn(u64) + Sync),
    mut image: Image,
) -> (Image, TileCounters) {
    let w = settings.width as usize;
    let band = TILE_SIZE as usize * w;
    let total = image
        .pixels
        .par_chunks_mut(band)
        .enumerate()
        .map(|(ty, band)| {
            // The band's rows, cut into the tiles' pieces.
            let mut tiles: Vec<Tile> = (0..w.div_ceil(TILE_SIZE as usize))
                .map(|tx| Tile {
                    x0: tx as u32 * TILE_SIZE,
                    y0: ty as u32 * TILE_SIZE,
                    rows: Vec::with_capacity(TILE_SIZE as usize),
                })
                .collect();
            for row in band.chunks_mut(w) {
                for (tile, piece) in tiles.iter_mut().zip(row.chunks_mut(TILE_SIZE as usize)) {
                    tile.rows.push(piece);
                }
            }
            tiles
                .into_par_iter()
                .map(|mut tile| {
                    let counters = render_tile(scene, settings, integrator, &mut tile);
                    progress(tile.rows.iter().map(|r| r.len() as u64).sum());
                    counters
                })
                .reduce(TileCounters::default, |mut a, b| {
                    a += b;
                    a
                })
        })
        .reduce(TileCounters::default, |mut a, b| {
            a += b;
            a
        });
    (image, total)
}

fn render_tile<I: Integrator>(
    scene: &Scene,
    settings: &RenderSettings,
    integrator: &I,
    tile: &mut Tile,
) -> TileCounters {
    let mut counters = Counters::default();
    let (mut bad_samples, mut nan_pixels) = (0, 0);
    let spp = settings.spp.max(1);
    for (dy, row) in tile.rows.iter_mut().enumerate() {
        let y = tile.y0 + dy as u32;
        for (dx, pixel) in row.iter_mut().enumerate() {
            let x = tile.x0 + dx as u32;
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
            // A sum of huge finite samples can overflow: clamp, as every
            // pixel must stay finite.
            *pixel = (sum / spp as f32).min(Color::splat(f32::MAX));
        }
    }
    TileCounters {
        rays: counters.rays,
        intersection_tests: counters.trace.intersection_tests,
        implicit_searches: counters.trace.implicit_searches,
        implicit_evaluations: counters.trace.implicit_evaluations,
        bvh_nodes_visited: counters.trace.bvh.nodes_visited,
        triangle_tests: counters.trace.bvh.primitive_tests,
        bad_samples,
        nan_pixels,
        ray_trees_cut: counters.ray_trees_cut,
        implicit_searches_cut: counters.trace.implicit_searches_cut,
    }
}
