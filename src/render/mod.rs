//! Rendering: pixels in tiles, in parallel, deterministically.
//!
//! Each sample depends only on the pixel's coordinates and the sample's
//! number (its random numbers are seeded from them), and a pixel's samples
//! are summed exactly ([`SampleSum`]), so an image is the same bit for bit
//! whatever the number of threads, and a crop or a range of samples rendered
//! apart is exactly that part of the whole render ([`parts`]).

pub mod aov;
pub mod explain;
mod film;
pub mod heatmap;
mod integrator;
pub mod memory;
pub mod parts;
mod sampler;
mod srgb;
mod stats;
mod tile;

pub use aov::{Aov, AovPixel};
pub use film::{
    FilmReadError, Image, ImageFormat, ImageWriteError, StagedFile, commit_all, png_bytes,
    read_film_exr, read_film_header, write_image,
};
pub use integrator::{
    AnyIntegrator, Counters, Integrator, MAX_RAY_TREE, NoRecord, Path, RayKind, Raycast, Recorder,
    Tracer, Whitted, transmittance,
};
pub use parts::{Film, FilmHeader, MergeError, SampleSum};
pub use sampler::{OFFSET_LANES, Pcg32, PixelSampler, PixelSamples};
pub use srgb::{srgb_encode, srgb8, srgb8_exact};
pub use stats::{RayCounts, RenderStats, TileCounters};

use crate::math::Color;
use crate::scene::Scene;
use crate::settings::RenderSettings;
use std::time::Instant;
use tile::render_tiles;

/// Side of the square tiles the image is cut into, in pixels. A tile's
/// camera rays are streamed together (up to 1024 at a time), so the
/// breadth-first Whitted waves and their shadow and secondary batches are
/// fuller than with 16-pixel tiles: the 1280×720 Whitted frame takes about
/// 4 % less time (920 tiles, still plenty to share among threads).
pub const TILE_SIZE: u32 = 32;

#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("invalid render settings: {0}")]
    Settings(String),
    #[error("cannot start {threads} render threads: {message}")]
    ThreadPool { threads: usize, message: String },
    #[error(
        "a {width}×{height} image needs {:.2} GB for its pixels, but only {:.2} GB of memory is available; render a smaller image",
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

/// Renders `scene` with `settings`: the pixels of `settings.rect()`, as an
/// image of that size. `progress` is called (from worker threads) with the
/// number of pixels of each finished tile.
pub fn render(
    scene: &Scene,
    settings: &RenderSettings,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Image, RenderStats), RenderError> {
    render_film(scene, settings, &FilmOptions::default(), progress)
        .map(|(film, stats)| (film.image, stats))
}

/// What a [`Film`] keeps besides the image.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FilmOptions {
    /// The exact per-pixel sums that merging needs (48 bytes per pixel).
    pub keep_sums: bool,
    /// Output variables to gather (60 bytes per pixel if any).
    pub aovs: Vec<Aov>,
}

/// [`render`] as a [`Film`], which also records the crop and the sample
/// range, and keeps what `options` asks for.
pub fn render_film(
    scene: &Scene,
    settings: &RenderSettings,
    options: &FilmOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Film, RenderStats), RenderError> {
    render_with(
        scene,
        settings,
        &AnyIntegrator::new(settings),
        options,
        progress,
    )
}

/// [`render_film`] with a given integrator.
pub fn render_with<I: Integrator>(
    scene: &Scene,
    settings: &RenderSettings,
    integrator: &I,
    options: &FilmOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Film, RenderStats), RenderError> {
    let (film, counters, threads, seconds) =
        render_pass(scene, settings, integrator, options, progress)?;
    Ok((film, render_stats(settings, &counters, threads, seconds)))
}

/// A film that whole samples per pixel are added to pass by pass (for
/// `--time` and the viewer): after passes of `a` and `b` samples its image
/// is, bit for bit, the render of `a + b` samples (the passes are sample
/// ranges, added into exact sums).
pub struct Progressive {
    settings: RenderSettings,
    integrator: AnyIntegrator,
    film: Film,
    done: u32,
}

impl Progressive {
    /// An empty film for `settings`, whose samples start at its
    /// `sample_offset` (its `spp` is ignored: passes say how many samples
    /// they add).
    pub fn new(settings: &RenderSettings) -> Result<Self, RenderError> {
        let settings = RenderSettings {
            spp: 1,
            ..settings.clone()
        };
        let options = FilmOptions {
            keep_sums: true,
            aovs: Vec::new(),
        };
        Ok(Progressive {
            film: new_film(&settings, &options)?,
            integrator: AnyIntegrator::new(&settings),
            settings,
            done: 0,
        })
    }

    /// Adds `count` samples per pixel (the next ones in each pixel's
    /// sequence), calling `progress` with pixels done; returns the work done
    /// and the threads that did it.
    pub fn add(
        &mut self,
        scene: &Scene,
        count: u32,
        progress: &(dyn Fn(u64) + Sync),
    ) -> Result<(TileCounters, usize), RenderError> {
        let pass = RenderSettings {
            spp: count.max(1),
            sample_offset: self.settings.sample_offset + self.done,
            ..self.settings.clone()
        };
        let total = (self.done + pass.spp) as u64;
        let done = run_tiles(
            scene,
            &pass,
            &self.integrator,
            progress,
            &mut self.film,
            Some(total),
        )?;
        self.done += pass.spp;
        self.film.header.samples.count = self.done;
        Ok(done)
    }

    /// The mean of the samples so far.
    pub fn image(&self) -> &Image {
        &self.film.image
    }

    /// Samples per pixel so far.
    pub fn samples(&self) -> u32 {
        self.done
    }

    /// The film so far.
    pub fn into_film(self) -> Film {
        self.film
    }
}

/// Renders `settings` in passes of whole samples per pixel (1, 1, 2, 4, 8,
/// then the largest power of two, else multiple of 4, that the time left
/// affords) until `settings.spp` are done or the next pass would
/// end after `seconds` (at least one pass is rendered). Passes are exact
/// sample ranges merged exactly, so the result is the render of the samples
/// reached (`film.header.samples` and `stats.spp` say how many), bit for bit.
pub fn render_timed(
    scene: &Scene,
    settings: &RenderSettings,
    options: &FilmOptions,
    seconds: f64,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Film, RenderStats), RenderError> {
    settings.validate().map_err(RenderError::Settings)?;
    let integrator = AnyIntegrator::new(settings);
    let start = Instant::now();
    let in_place = options.aovs.is_empty();
    let pass_options = FilmOptions {
        keep_sums: true,
        ..options.clone()
    };
    // Without AOVs the passes add into one film; with them each pass has a
    // film of its own, merged (AOVs of several passes need merging rules).
    let mut film = if in_place {
        Some(Progressive::new(settings)?)
    } else {
        None
    };
    let mut merger: Option<parts::Merger> = None;
    let mut total = TileCounters::default();
    let mut threads = 1;
    let mut done = 0u32;
    let mut pass = 1u32;
    while done < settings.spp {
        let count = pass.min(settings.spp - done);
        let pass_settings = RenderSettings {
            spp: count,
            sample_offset: settings.sample_offset + done,
            ..settings.clone()
        };
        // Progress in pixel-samples.
        let scaled = |n: u64| progress(n * count as u64);
        let counters = match &mut film {
            Some(film) => {
                let (counters, t) = film.add(scene, count, &scaled)?;
                threads = t;
                counters
            }
            None => {
                let (part, counters, t, _) =
                    render_pass(scene, &pass_settings, &integrator, &pass_options, &scaled)?;
                threads = t;
                merger
                    .get_or_insert_with(|| {
                        let mut header = part.header.clone();
                        header.samples = settings.samples();
                        parts::Merger::new(header).expect("the film of one pass was allocated")
                    })
                    .add(&part);
                counters
            }
        };
        total += counters;
        done += count;
        // The next pass: up to 16 samples, double them (cheap passes that
        // measure the speed); then reach the largest power of two that the
        // time left affords (power-of-two prefixes are the best
        // stratified), else add what it affords in multiples of 4.
        let elapsed = start.elapsed().as_secs_f64();
        let per_sample = elapsed / done as f64;
        let affordable = ((seconds - elapsed) / per_sample)
            .max(0.0)
            .min(u32::MAX as f64) as u32;
        let left = settings.spp - done;
        let next = if done < 16 {
            done
        } else {
            let power = (done + affordable.min(left))
                .checked_next_power_of_two()
                .map_or(0, |p| {
                    if p > done + affordable.min(left) {
                        p / 2
                    } else {
                        p
                    }
                });
            if power > done {
                power - done
            } else {
                affordable.min(left) / 4 * 4
            }
        };
        if next == 0 || elapsed + per_sample * next.min(left) as f64 > seconds {
            break;
        }
        pass = next;
    }
    let seconds_render = start.elapsed().as_secs_f64();
    let mut film = match film {
        Some(film) => film.into_film(),
        None => {
            let mut merger = merger.expect("at least one pass is rendered");
            merger.set_sample_count(done);
            merger.finish()
        }
    };
    if !options.keep_sums {
        film.sums = Vec::new();
    }
    let reached = RenderSettings {
        spp: done,
        ..settings.clone()
    };
    Ok((
        film,
        render_stats(&reached, &total, threads, seconds_render),
    ))
}

/// One render of `settings`: the film, the work done, the threads used and
/// the seconds it took.
fn render_pass<I: Integrator>(
    scene: &Scene,
    settings: &RenderSettings,
    integrator: &I,
    options: &FilmOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Film, TileCounters, usize, f64), RenderError> {
    let mut film = new_film(settings, options)?;
    let start = Instant::now();
    let (counters, threads) = run_tiles(scene, settings, integrator, progress, &mut film, None)?;
    Ok((film, counters, threads, start.elapsed().as_secs_f64()))
}

/// A blank film for `settings`, keeping what `options` asks for; refused
/// (not aborted) where memory is short.
fn new_film(settings: &RenderSettings, options: &FilmOptions) -> Result<Film, RenderError> {
    settings.validate().map_err(RenderError::Settings)?;
    let keep_sums = options.keep_sums;
    let keep_aovs = !options.aovs.is_empty();
    let rect = settings.rect();
    let (width, height) = (rect.width(), rect.height());
    let per_pixel = std::mem::size_of::<Color>() as u64
        + if keep_sums {
            std::mem::size_of::<SampleSum>() as u64
        } else {
            0
        }
        + if keep_aovs {
            std::mem::size_of::<AovPixel>() as u64
        } else {
            0
        };
    let needed = rect.area() * per_pixel;
    let memory_error = |available| RenderError::Memory {
        width,
        height,
        needed,
        available,
    };
    // Refused up front where the system says how much it has; allocated
    // fallibly in any case.
    if let Some(available) = memory::available_bytes()
        && needed > available
    {
        return Err(memory_error(available));
    }
    let image = Image::try_new(width, height).ok_or_else(|| memory_error(0))?;
    let mut sums = Vec::new();
    if keep_sums {
        sums.try_reserve_exact(rect.area() as usize)
            .map_err(|_| memory_error(0))?;
        sums.resize(rect.area() as usize, SampleSum::default());
    }
    let mut aov_pixels = Vec::new();
    if keep_aovs {
        aov_pixels
            .try_reserve_exact(rect.area() as usize)
            .map_err(|_| memory_error(0))?;
        aov_pixels.resize(rect.area() as usize, AovPixel::default());
    }
    Ok(Film {
        header: FilmHeader {
            width: settings.width,
            height: settings.height,
            rect,
            samples: settings.samples(),
            fingerprint: String::new(),
        },
        image,
        sums,
        aovs: options.aovs.clone(),
        aov_pixels,
    })
}

/// Renders the samples of `settings` into `film`, on the settings' threads;
/// with `accumulate = Some(n)`, adds them to the film's sums (which then
/// hold `n` samples per pixel) instead of replacing them. Returns the work
/// done and the threads used.
fn run_tiles<I: Integrator>(
    scene: &Scene,
    settings: &RenderSettings,
    integrator: &I,
    progress: &(dyn Fn(u64) + Sync),
    film: &mut Film,
    accumulate: Option<u64>,
) -> Result<(TileCounters, usize), RenderError> {
    if settings.threads == 0 {
        let counters = render_tiles(scene, settings, integrator, progress, film, accumulate);
        return Ok((counters, rayon::current_num_threads()));
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(settings.threads)
        .build()
        .map_err(|e| RenderError::ThreadPool {
            threads: settings.threads,
            message: e.to_string(),
        })?;
    let counters =
        pool.install(|| render_tiles(scene, settings, integrator, progress, film, accumulate));
    Ok((counters, settings.threads))
}

/// The statistics of a render of `settings` that did the work `counters`.
fn render_stats(
    settings: &RenderSettings,
    counters: &TileCounters,
    threads: usize,
    seconds_render: f64,
) -> RenderStats {
    let rect = settings.rect();
    let rays_total = counters.rays.total();
    RenderStats {
        width: settings.width,
        height: settings.height,
        crop: [rect.x0, rect.x1, rect.y0, rect.y1],
        spp: settings.spp,
        sample_offset: settings.sample_offset,
        integrator: settings.integrator.name().to_string(),
        max_depth: settings.max_depth,
        threads,
        seconds_load: 0.0,
        seconds_render,
        rays: counters.rays,
        rays_total,
        rays_per_second: rays_total as f64 / seconds_render.max(1e-9),
        samples_per_second: counters.rays.camera as f64 / seconds_render.max(1e-9),
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
    }
}
