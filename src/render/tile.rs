//! The tiles of a render: the film cut into tiles of [`TILE_SIZE`]² in
//! bands of tile rows, rendered in parallel straight into it, and each
//! tile's pixels: their camera rays, traced many at a time where the
//! integrator can ([`Integrator::radiance_stream`]), their samples taken
//! into the film and their output variables.

use super::integrator::{Counters, Integrator};
use super::{AovPixel, Film, OFFSET_LANES, PixelSamples, SampleSum, TILE_SIZE, TileCounters, aov};
use crate::math::{Color, Ray, Vec3};
use crate::scene::Scene;
use crate::settings::RenderSettings;
use rayon::prelude::*;

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
pub(super) fn render_tiles<I: Integrator>(
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

/// The pixels of a tile in Morton (Z) order: entry `code` is `(dx, dy)`,
/// the bits of `code` dealt alternately to `dx` and `dy`.
const Z_ORDER: [(u8, u8); (TILE_SIZE * TILE_SIZE) as usize] = {
    assert!(TILE_SIZE.is_power_of_two() && TILE_SIZE <= 256);
    let mut table = [(0u8, 0u8); (TILE_SIZE * TILE_SIZE) as usize];
    let mut code = 0;
    while code < table.len() {
        let (mut x, mut y, mut bit) = (0, 0, 0);
        while 1 << bit < TILE_SIZE {
            x |= (code >> (2 * bit) & 1) << bit;
            y |= (code >> (2 * bit + 1) & 1) << bit;
            bit += 1;
        }
        table[code] = (x as u8, y as u8);
        code += 1;
    }
    table
};

/// The radiance of every sample of the tile (pixel by pixel in rows, each
/// pixel's samples in order), traced many at a time by the integrator; `None`
/// if it cannot (nothing is then counted).
///
/// In a scene whose rays are traced in packets (meshes: see
/// [`Scene::intersect_packet`]) the camera rays go to the integrator with
/// the pixels in Z order ([`Z_ORDER`]) rather than row by row, so that the
/// rays a packet takes come from a compact block of pixels: sixteen rays
/// of one sample per pixel are a 4×4 block, not a sixteen-pixel stretch of
/// a row. (`glint render` of igea, the bunny and lucy, 1080p: 0.91, 0.93
/// and 0.91 of the time in rows.) Scenes of analytic shapes, traced in
/// SIMD batches ([`Scene::batchable`]), keep rows, written straight into
/// place: in Z order the Whitted frame took 4 % longer. Each pixel's
/// radiance depends on its own samples alone, so the order changes no
/// pixel.
fn stream_tile<I: Integrator>(
    scene: &Scene,
    integrator: &I,
    tile: &Tile,
    settings: &RenderSettings,
    counters: &mut Counters,
) -> Option<Vec<Color>> {
    const CHUNK: usize = 1024;
    thread_local! {
        // The camera rays of a chunk, and their radiance (kept: a fresh
        // array per tile costs more than a Whitted tile's shading).
        static RAYS: std::cell::RefCell<(Vec<Ray>, Vec<Color>)> =
            const { std::cell::RefCell::new((Vec::new(), Vec::new())) };
    }
    let samples = settings.samples();
    let (width, height) = (settings.width, settings.height);
    let mut points = Vec::with_capacity(CHUNK);
    let blocks = !scene.batchable();
    // Where each point's radiance goes in `out` (for rays in blocks).
    let mut places = Vec::with_capacity(if blocks { CHUNK } else { 0 });
    let (w, h) = (tile.rows.first().map_or(0, |r| r.len()), tile.rows.len());
    // The last tile's array, if given back ([`recycle`]): every element is
    // written before the tile is given out, so it need not be cleared.
    let mut out = STREAMED.take();
    out.resize(w * h * samples.count as usize, Color::ZERO);
    // Rays in rows fill `out` in order; rays in blocks go to their places.
    let mut done = 0;
    let mut trace = |points: &mut Vec<(f32, f32)>, places: &mut Vec<usize>, out: &mut [Color]| {
        let n = points.len();
        RAYS.with_borrow_mut(|(rays, radiance)| {
            rays.resize(CHUNK, Ray::new(Vec3::ZERO, Vec3::X));
            scene.camera.rays(points, width, height, &mut rays[..n]);
            points.clear();
            let ok = if blocks {
                radiance.resize(CHUNK, Color::ZERO);
                let ok =
                    integrator.radiance_stream(scene, &rays[..n], counters, &mut radiance[..n]);
                for (&place, &l) in places.iter().zip(&radiance[..n]) {
                    out[place] = l;
                }
                places.clear();
                ok
            } else {
                integrator.radiance_stream(scene, &rays[..n], counters, &mut out[done..done + n])
            };
            done += n;
            ok
        })
    };
    // A pixel's samples, in both loops below (a closure called from two
    // places was not inlined, and took three times the instructions).
    macro_rules! pixel {
        ($dx:expr, $dy:expr) => {{
            let (dx, dy): (usize, usize) = ($dx, $dy);
            let (x, y) = (tile.x0 + dx as u32, tile.y0 + dy as u32);
            let mut pixel = PixelSamples::new(x, y);
            let first = (dy * w + dx) * samples.count as usize;
            let mut offsets = [(0.0f32, 0.0f32); OFFSET_LANES];
            for (k, index) in (samples.start..samples.start + samples.count).enumerate() {
                let lane = k % OFFSET_LANES;
                if lane == 0 {
                    let n = (samples.count as usize - k).min(OFFSET_LANES);
                    pixel.offsets(index, &mut offsets[..n]);
                }
                let (u, v) = offsets[lane];
                points.push((x as f32 + u, y as f32 + v));
                if blocks {
                    places.push(first + k);
                }
                if points.len() == CHUNK && !trace(&mut points, &mut places, &mut out) {
                    return None;
                }
            }
        }};
    }
    if blocks {
        for &(dx, dy) in &Z_ORDER {
            let (dx, dy) = (dx as usize, dy as usize);
            if dx < w && dy < h {
                pixel!(dx, dy);
            }
        }
    } else {
        for dy in 0..h {
            for dx in 0..w {
                pixel!(dx, dy);
            }
        }
    }
    if !points.is_empty() && !trace(&mut points, &mut places, &mut out) {
        return None;
    }
    Some(out)
}

thread_local! {
    // A streamed tile's radiance array, kept for the thread's next tile
    // (zeroing a fresh one cost about 1 % of a Whitted frame).
    static STREAMED: std::cell::Cell<Vec<Color>> = const { std::cell::Cell::new(Vec::new()) };
}

/// Gives a streamed tile's array back for the thread's next tile.
fn recycle(out: Vec<Color>) {
    STREAMED.set(out);
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
    let mut tile_streamed = if streaming && samples.count <= STREAM_SPP {
        let out = stream_tile(scene, integrator, tile, settings, &mut counters);
        streaming = out.is_some();
        out
    } else {
        None
    };
    if let Some(out) = tile_streamed.take_if(|_| plain) {
        // One sample per pixel and no sums: each straight to its pixel
        // (what the general loop below does in this case, without its
        // per-pixel sums). A rejected sample leaves the pixel 0, the mean
        // of an empty sum.
        let mut samples = out.iter();
        for row in tile.rows.iter_mut() {
            for (pixel, &l) in row.iter_mut().zip(&mut samples) {
                let bad = take_sample(l, settings.clamp, true, pixel, &mut SampleSum::default());
                if bad {
                    *pixel = SampleSum::default().mean(1);
                }
                bad_samples += bad as u64;
                nan_pixels += bad as u64;
            }
        }
        counters.rays.camera += out.len() as u64;
        recycle(out);
        return tile_counters(&counters, bad_samples, nan_pixels);
    }
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
        recycle(out);
        return tile_counters(&counters, bad_samples, nan_pixels);
    }
    // Made only here: a streamed tile needs none of them.
    let mut points = [(0.0f32, 0.0f32); RAYS];
    let mut offsets = [(0.0f32, 0.0f32); RAYS];
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
                        pixel_samples.offsets(index as u32, &mut offsets[..n]);
                        for (p, (u, v)) in points[..n].iter_mut().zip(&offsets[..n]) {
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

#[cfg(test)]
mod tests {
    use super::*;

    /// [`Z_ORDER`] lists every pixel of a tile once, and each aligned run
    /// of 4, 16 or 64 entries is a square block of pixels (2×2, 4×4, 8×8):
    /// the pixels of a packet of 16 rays at 4 and 1 samples per pixel.
    #[test]
    fn z_order_visits_every_pixel_once_in_blocks() {
        let n = TILE_SIZE as usize;
        let mut seen = vec![false; n * n];
        for &(x, y) in &Z_ORDER {
            let k = y as usize * n + x as usize;
            assert!(!seen[k], "({x}, {y}) twice");
            seen[k] = true;
        }
        assert!(seen.iter().all(|&s| s));
        for (run, side) in [(4, 2), (16, 4), (64, 8)] {
            for block in Z_ORDER.chunks(run) {
                let (x0, y0) = block[0];
                assert!((x0 as usize).is_multiple_of(side) && (y0 as usize).is_multiple_of(side));
                for &(x, y) in block {
                    assert!((x0..x0 + side as u8).contains(&x), "{block:?}");
                    assert!((y0..y0 + side as u8).contains(&y), "{block:?}");
                }
            }
        }
        // Row-major within the smallest block: (0,0), (1,0), (0,1), (1,1).
        assert_eq!(Z_ORDER[..4], [(0, 0), (1, 0), (0, 1), (1, 1)]);
    }
}
