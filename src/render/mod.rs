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
pub use sampler::{Pcg32, PixelSampler, PixelSamples};
pub use srgb::{srgb_encode, srgb8, srgb8_exact};
pub use stats::{RayCounts, RenderStats, TileCounters};

use crate::math::{Color, Ray, Vec3};
use crate::scene::Scene;
use crate::settings::RenderSettings;
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

/// A tile: its top-left pixel (in the frame) and, row by row, the slices of
/// the film it covers (so tiles are rendered in parallel straight into it).
struct Tile<'a> {
    x0: u32,
    y0: u32,
    rows: Vec<&'a mut [Color]>,
    /// The rows of sums, if the film keeps them.
    sums: Vec<&'a mut [SampleSum]>,
    /// The rows of output variables, if the film has them.
    aovs: Vec<&'a mut [AovPixel]>,
    /// Whether the first hit's variables are asked for.
    first_hit: bool,
}

/// A band of tile rows: its number, its pixels and, if kept, its sums and
/// output variables.
type Band<'a> = (
    usize,
    &'a mut [Color],
    Option<&'a mut [SampleSum]>,
    Option<&'a mut [AovPixel]>,
);

/// Renders every pixel of `film` (blank) in tiles of [`TILE_SIZE`]², in
/// parallel: bands of tile rows, each cut into its tiles.
fn render_tiles<I: Integrator>(
    scene: &Scene,
    settings: &RenderSettings,
    integrator: &I,
    progress: &(dyn Fn(u64) + Sync),
    film: &mut Film,
    accumulate: Option<u64>,
) -> TileCounters {
    let rect = film.header.rect;
    let w = rect.width() as usize;
    let band = TILE_SIZE as usize * w;
    let first_hit = film.aovs.iter().any(|a| !a.is_count());
    let bands: Vec<Band> = film
        .image
        .pixels
        .chunks_mut(band)
        .zip(optional_bands(&mut film.sums, band))
        .zip(optional_bands(&mut film.aov_pixels, band))
        .enumerate()
        .map(|(ty, ((p, s), a))| (ty, p, s, a))
        .collect();
    bands
        .into_par_iter()
        .map(|(ty, band, sums, aovs)| {
            let mut tiles: Vec<Tile> = (0..w.div_ceil(TILE_SIZE as usize))
                .map(|tx| Tile {
                    x0: rect.x0 + tx as u32 * TILE_SIZE,
                    y0: rect.y0 + ty as u32 * TILE_SIZE,
                    rows: Vec::with_capacity(TILE_SIZE as usize),
                    sums: Vec::new(),
                    aovs: Vec::new(),
                    first_hit,
                })
                .collect();
            deal(band, w, &mut tiles, |t| &mut t.rows);
            if let Some(sums) = sums {
                deal(sums, w, &mut tiles, |t| &mut t.sums);
            }
            if let Some(aovs) = aovs {
                deal(aovs, w, &mut tiles, |t| &mut t.aovs);
            }
            tiles
                .into_par_iter()
                .map(|mut tile| {
                    let counters = render_tile(scene, settings, integrator, &mut tile, accumulate);
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
        })
}

/// `data` in bands of `band` elements, or `None` for every band where it is
/// empty (a film that does not keep it).
fn optional_bands<T>(data: &mut [T], band: usize) -> impl Iterator<Item = Option<&mut [T]>> {
    let kept = (!data.is_empty()).then_some(data);
    kept.into_iter()
        .flat_map(move |d| d.chunks_mut(band))
        .map(Some)
        .chain(std::iter::repeat_with(|| None))
}

/// Cuts a band's rows (`w` wide) into the tiles' pieces, each tile's going
/// to the list `slot` picks.
fn deal<'a, T>(
    band: &'a mut [T],
    w: usize,
    tiles: &mut [Tile<'a>],
    slot: impl for<'t> Fn(&'t mut Tile<'a>) -> &'t mut Vec<&'a mut [T]>,
) {
    for row in band.chunks_mut(w) {
        for (tile, piece) in tiles.iter_mut().zip(row.chunks_mut(TILE_SIZE as usize)) {
            slot(tile).push(piece);
        }
    }
}

/// Most samples per pixel for which a tile's camera rays are traced
/// together (see [`Integrator::radiance_stream`]).
const STREAM_SPP: u32 = 16;

/// The radiance of every sample of the tile (pixel by pixel in rows, each
/// pixel's samples in order), traced many at a time by the integrator; `None`
/// if it cannot (nothing is then counted).
fn stream_tile<I: Integrator>(
    scene: &Scene,
    integrator: &I,
    tile: &Tile,
    settings: &RenderSettings,
    counters: &mut Counters,
) -> Option<Vec<Color>> {
    const CHUNK: usize = 1024;
    thread_local! {
        // The camera rays of a chunk (kept: a fresh array per tile costs
        // more than a Whitted tile's shading).
        static RAYS: std::cell::RefCell<Vec<Ray>> = const { std::cell::RefCell::new(Vec::new()) };
    }
    let samples = settings.samples();
    let (width, height) = (settings.width, settings.height);
    let mut points = Vec::with_capacity(CHUNK);
    let pixels = tile.rows.iter().map(|r| r.len()).sum::<usize>();
    let mut out = vec![Color::ZERO; pixels * samples.count as usize];
    let mut done = 0;
    let mut trace = |points: &mut Vec<(f32, f32)>, done: &mut usize| {
        let n = points.len();
        RAYS.with_borrow_mut(|rays| {
            rays.resize(CHUNK, Ray::new(Vec3::ZERO, Vec3::X));
            scene.camera.rays(points, width, height, &mut rays[..n]);
            points.clear();
            let ok =
                integrator.radiance_stream(scene, &rays[..n], counters, &mut out[*done..*done + n]);
            *done += n;
            ok
        })
    };
    for (dy, row) in tile.rows.iter().enumerate() {
        let y = tile.y0 + dy as u32;
        for dx in 0..row.len() {
            let x = tile.x0 + dx as u32;
            let mut pixel = PixelSamples::new(x, y);
            for index in samples.start..samples.start + samples.count {
                let (u, v) = pixel.offset(index);
                points.push((x as f32 + u, y as f32 + v));
                if points.len() == CHUNK && !trace(&mut points, &mut done) {
                    return None;
                }
            }
        }
    }
    if !points.is_empty() && !trace(&mut points, &mut done) {
        return None;
    }
    Some(out)
}

fn render_tile<I: Integrator>(
    scene: &Scene,
    settings: &RenderSettings,
    integrator: &I,
    tile: &mut Tile,
    accumulate: Option<u64>,
) -> TileCounters {
    let mut counters = Counters::default();
    let (mut bad_samples, mut nan_pixels) = (0, 0);
    let samples = settings.samples();
    let (width, height) = (settings.width, settings.height);
    // Camera rays are made in batches (see `Camera::rays`): a row's with one
    // sample per pixel, else a pixel's samples, up to `RAYS` at a time.
    const RAYS: usize = 64;
    const { assert!(TILE_SIZE as usize <= RAYS) };
    let single = samples.count == 1;
    // One sample per pixel written straight to a film that keeps no sums.
    let plain = single && accumulate.is_none() && tile.sums.is_empty();
    // A tile whose camera rays all miss everything is not traced (its
    // output variables, if any, are gathered the ordinary way).
    let missed = tile.aovs.is_empty() && {
        let (x1, y1) = (
            tile.x0 + tile.rows.first().map_or(0, |r| r.len()) as u32,
            tile.y0 + tile.rows.len() as u32,
        );
        scene.camera_misses(
            tile.x0 as f32,
            x1 as f32,
            tile.y0 as f32,
            y1 as f32,
            width,
            height,
        )
    };
    // Integrators that can trace many camera rays at once get the tile's
    // (with at most `STREAM_SPP` samples per pixel), else a pixel's samples
    // `RAYS` at a time; the first refusal stops the asking. Output
    // variables need each pixel's own counts: not then.
    let mut streaming = !missed && tile.aovs.is_empty() && integrator.streams(scene);
    let tile_streamed = if streaming && samples.count <= STREAM_SPP {
        let out = stream_tile(scene, integrator, tile, settings, &mut counters);
        streaming = out.is_some();
        out
    } else {
        None
    };
    if let Some(out) = tile_streamed {
        // Each pixel's samples in turn, as traced.
        let mut radiance = out.chunks_exact(samples.count as usize);
        for (dy, row) in tile.rows.iter_mut().enumerate() {
            for (dx, pixel) in row.iter_mut().enumerate() {
                let mut sum = SampleSum::default();
                let mut bad = 0;
                for &l in radiance.next().expect("a radiance per sample") {
                    bad += take_sample(l, settings.clamp, plain, pixel, &mut sum) as u64;
                }
                bad_samples += bad;
                nan_pixels += (bad > 0) as u64;
                let kept = tile.sums.get_mut(dy).map(|s| &mut s[dx]);
                finish_pixel(pixel, &sum, kept, accumulate, plain, bad, samples.count);
            }
        }
        counters.rays.camera += out.len() as u64;
        return tile_counters(&counters, bad_samples, nan_pixels);
    }
    // Made only here: a streamed tile needs none of them.
    let mut points = [(0.0f32, 0.0f32); RAYS];
    let mut rays = [Ray::new(Vec3::ZERO, Vec3::X); RAYS];
    let mut row_samples = [PixelSamples::new(0, 0); TILE_SIZE as usize];
    let mut streamed = [Color::ZERO; RAYS];
    for (dy, row) in tile.rows.iter_mut().enumerate() {
        let y = tile.y0 + dy as u32;
        if single {
            for (dx, (p, s)) in points
                .iter_mut()
                .zip(&mut row_samples[..row.len()])
                .enumerate()
            {
                let x = tile.x0 + dx as u32;
                *s = PixelSamples::new(x, y);
                let (u, v) = s.offset(samples.start);
                *p = (x as f32 + u, y as f32 + v);
            }
            let n = row.len();
            scene
                .camera
                .rays(&points[..n], width, height, &mut rays[..n]);
        }
        for (dx, pixel) in row.iter_mut().enumerate() {
            let x = tile.x0 + dx as u32;
            let mut sum = SampleSum::default();
            let mut bad = 0;
            let mut pixel_samples = if single {
                row_samples[dx]
            } else {
                PixelSamples::new(x, y)
            };
            // The counters before the pixel, for its counting AOVs.
            let before = (!tile.aovs.is_empty()).then_some(counters);
            for index in samples.start as u64..samples.end() {
                let k = (index - samples.start as u64) as usize % RAYS;
                let ray = if single {
                    rays[dx]
                } else {
                    if k == 0 {
                        let n = (samples.end() - index).min(RAYS as u64) as usize;
                        for (j, p) in points[..n].iter_mut().enumerate() {
                            let (u, v) = pixel_samples.offset(index as u32 + j as u32);
                            *p = (x as f32 + u, y as f32 + v);
                        }
                        scene
                            .camera
                            .rays(&points[..n], width, height, &mut rays[..n]);
                        if streaming {
                            streaming = integrator.radiance_stream(
                                scene,
                                &rays[..n],
                                &mut counters,
                                &mut streamed[..n],
                            );
                        }
                    }
                    rays[k]
                };
                counters.rays.camera += 1;
                let escaped = if missed {
                    integrator.escaped(scene, &ray)
                } else {
                    None
                };
                let l = escaped.unwrap_or_else(|| {
                    if streaming {
                        return streamed[k];
                    }
                    let mut sampler = pixel_samples.sampler(index as u32);
                    integrator.radiance(scene, &ray, &mut sampler, &mut counters)
                });
                bad += take_sample(l, settings.clamp, plain, pixel, &mut sum) as u64;
            }
            bad_samples += bad;
            nan_pixels += (bad > 0) as u64;
            let kept = tile.sums.get_mut(dy).map(|s| &mut s[dx]);
            finish_pixel(pixel, &sum, kept, accumulate, plain, bad, samples.count);
            if let (Some(row), Some(before)) = (tile.aovs.get_mut(dy), before) {
                let a = &mut row[dx];
                let r = &counters.rays;
                let b = &before.rays;
                a.rays = [
                    r.camera - b.camera,
                    r.shadow - b.shadow,
                    r.reflection - b.reflection,
                    r.refraction - b.refraction,
                ]
                .map(aov::count32);
                let (t, tb) = (&counters.trace, &before.trace);
                a.nodes = aov::count32(t.bvh.nodes_visited - tb.bvh.nodes_visited);
                a.prims = aov::count32(t.bvh.primitive_tests - tb.bvh.primitive_tests);
                a.evals = aov::count32(t.implicit_evaluations - tb.implicit_evaluations);
                if tile.first_hit {
                    let (u, v) = pixel_samples.offset(samples.start);
                    let ray = scene.camera.ray(
                        x as f32 + u,
                        y as f32 + v,
                        settings.width,
                        settings.height,
                    );
                    a.first_hit(scene, &ray);
                }
            }
        }
    }
    tile_counters(&counters, bad_samples, nan_pixels)
}

/// A tile's counts.
fn tile_counters(counters: &Counters, bad_samples: u64, nan_pixels: u64) -> TileCounters {
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

/// A sample's radiance `l` into its pixel: scaled down to the optional
/// `clamp` (off by default), then, unless it is NaN or infinite (returns
/// true: such samples are counted, never let through), written as the
/// pixel's value (`plain`: one sample and no sums) or added to `sum`. Sums
/// are exact and clamped, so every pixel stays finite.
#[inline(always)]
fn take_sample(
    mut l: Color,
    clamp: Option<f32>,
    plain: bool,
    pixel: &mut Color,
    sum: &mut SampleSum,
) -> bool {
    if let Some(c) = clamp {
        let m = l.max_element();
        if m > c {
            l *= c / m;
        }
    }
    if !l.is_finite() {
        return true;
    }
    if plain {
        *pixel = SampleSum::mean_of_one(l);
    } else {
        sum.add_sample(l);
    }
    false
}

/// A pixel's value after its `count` samples (`bad` of them rejected) went
/// into `sum`: with `accumulate` (the samples taken in all, earlier passes'
/// included) the mean of the film's kept sum plus this one, else this
/// sum's mean (already written where `plain` and none was rejected), kept
/// if the film keeps sums.
#[inline(always)]
fn finish_pixel(
    pixel: &mut Color,
    sum: &SampleSum,
    kept: Option<&mut SampleSum>,
    accumulate: Option<u64>,
    plain: bool,
    bad: u64,
    count: u32,
) {
    match (accumulate, kept) {
        (Some(total), Some(s)) => {
            s.add(sum);
            *pixel = s.mean(total);
        }
        (_, s) => {
            if !plain || bad > 0 {
                *pixel = sum.mean(count as u64);
            }
            if let Some(s) = s {
                *s = *sum;
            }
        }
    }
}
