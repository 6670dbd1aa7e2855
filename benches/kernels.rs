//! A mesh render against the raw kernels on its own rays: what a ray costs
//! outside traversal.
//!
//! For each mesh, `glint render MESH` is set up as the CLI does (the framing
//! camera and light of [`mesh_scene`], ray casting at 1920×1080, 1 spp), and
//! the rays that render traces are collected: its camera rays and, through a
//! [`Recorder`], each shadow ray it sends. Then, on both cores:
//! - `kernels/render/MESH`: the whole render (rays, shading, film);
//! - `kernels/closest/MESH`: the closest-hit kernel on its camera rays;
//! - `kernels/closest_packets/MESH`: the same rays in the packets of 16
//!   that the render traces (4×4 blocks of pixels: a tile's pixels in Z
//!   order), as it traces them (ray by ray where `Mesh::packet_pays` says
//!   packets lose);
//! - `kernels/any/MESH`: the any-hit kernel on its shadow rays;
//! - `kernels/any_packets/MESH`: the same rays in packets of 16 (the
//!   render sends the shadow rays of a packet of camera rays together,
//!   sorted by light: with one light, those of the packet's hits, at most
//!   16, so these full packets flatter the kernel a little).
//!
//! Last it prints, per mesh, the render's time over the sum of the
//! kernels' (closest and any; both in packets), medians of 15 runs each,
//! taken in turns in one process.
//!
//! Meshes: a generated bumpy icosphere of 1.31M triangles (always) and the
//! meshes of `../shared/data/` when that folder is there (it says so when it
//! is not); or, where `GLINT_KERNELS_MESHES` is set, only the files it lists
//! (separated by `:`), each as `PATH` (seen from the CLI's default view, y
//! up) or `PATH@VX,VY,VZ@UX,UY,UZ` (as `--view` and `--up`), for example
//! `GLINT_KERNELS_MESHES=/tmp/big.ply@-0.3,1,0.2@0,0,1` for the
//! 25.6M-triangle mesh of `../shared/data/gen_big.py`.

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use glint::accel::PACKET;
use glint::geometry::testgen::bumpy_icosphere;
use glint::geometry::{Mesh, Shape, TraceCounters};
use glint::math::Vec3;
use glint::math::{Color, Ray};
use glint::render::{Counters, PixelSampler, Recorder, TILE_SIZE, Tracer, render};
use glint::scene::meshio::{Model, ModelPart, load_mesh_file};
use glint::scene::{Scene, SceneFile, mesh_scene};
use glint::settings::{IntegratorKind, RenderSettings};
use rayon::prelude::*;
use std::hint::black_box;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

/// Keeps the shadow rays an integrator sends.
struct ShadowRays(Vec<Ray>);

impl Recorder for ShadowRays {
    // Blocked shadow rays are reported only when blockers are asked for.
    const BLOCKERS: bool = true;
    fn shadow(
        &mut self,
        _scene: &Scene,
        _light: usize,
        ray: &Ray,
        _visibility: Color,
        _blocker: Option<&glint::scene::Hit>,
        _radiance: Color,
    ) {
        self.0.push(*ray);
    }
}

/// The pixels of a `w`×`h` frame in the order the render traces their
/// camera rays: tile by tile ([`TILE_SIZE`]²), each tile's pixels in Z
/// order (as `render/tile.rs` orders them), so that 16 consecutive rays
/// are a 4×4 block of pixels.
fn render_order(w: u32, h: u32) -> Vec<(u32, u32)> {
    let bits = TILE_SIZE.ilog2();
    let deal = |code: u32, k: u32| (0..bits).fold(0, |v, b| v | (code >> (2 * b + k) & 1) << b);
    let mut out = Vec::with_capacity((w * h) as usize);
    for ty in (0..h).step_by(TILE_SIZE as usize) {
        for tx in (0..w).step_by(TILE_SIZE as usize) {
            for code in 0..TILE_SIZE * TILE_SIZE {
                let (x, y) = (tx + deal(code, 0), ty + deal(code, 1));
                if x < w && y < h {
                    out.push((x, y));
                }
            }
        }
    }
    out
}

/// The camera rays of a 1-spp render (through pixel centres, as
/// `render_tile` makes them, in the order of [`render_order`]) and the
/// shadow rays ray casting sends from their hits.
fn render_rays(scene: &Scene, settings: &RenderSettings) -> (Vec<Ray>, Vec<Ray>) {
    let (w, h) = (settings.width, settings.height);
    let pixels = render_order(w, h);
    let camera: Vec<Ray> = pixels
        .iter()
        .map(|&(x, y)| scene.camera.ray(x as f32 + 0.5, y as f32 + 0.5, w, h))
        .collect();
    let integrator = glint::render::Raycast {
        light_samples: settings.light_samples,
    };
    let mut shadow = ShadowRays(Vec::new());
    for (ray, &(x, y)) in camera.iter().zip(&pixels) {
        let mut sampler = PixelSampler::new(x, y, 0);
        let mut counters = Counters::default();
        integrator.trace(scene, ray, &mut sampler, &mut counters, &mut shadow);
    }
    (camera, shadow.0)
}

/// `x,y,z` → a vector.
fn vec3(s: &str) -> Option<Vec3> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse().ok())
        .collect::<Option<_>>()?;
    match v[..] {
        [x, y, z] => Some(Vec3::new(x, y, z)),
        _ => None,
    }
}

/// The meshes of `GLINT_KERNELS_MESHES` (see the module's documentation).
fn listed_meshes(list: &str) -> Vec<(String, Model, Vec3, Vec3)> {
    let mut out = Vec::new();
    for entry in list.split(':').filter(|e| !e.is_empty()) {
        let mut parts = entry.split('@');
        let path = Path::new(parts.next().unwrap_or_default());
        let (view, up) = match (parts.next(), parts.next()) {
            (None, _) => (Some(Vec3::new(0.35, 0.3, 1.0)), Some(Vec3::Y)),
            (Some(v), Some(u)) => (vec3(v), vec3(u)),
            (Some(_), None) => (None, None),
        };
        let (Some(view), Some(up)) = (view, up) else {
            panic!("GLINT_KERNELS_MESHES: `{entry}` is not PATH or PATH@VX,VY,VZ@UX,UY,UZ");
        };
        let name = path
            .file_stem()
            .map_or(entry.into(), |s| s.to_string_lossy().into_owned());
        match load_mesh_file(path) {
            Ok(model) => out.push((name, model, view, up)),
            Err(e) => eprintln!("note: skipping {}: {e}", path.display()),
        }
    }
    out
}

fn meshes() -> Vec<(String, Model, Vec3, Vec3)> {
    if let Ok(list) = std::env::var("GLINT_KERNELS_MESHES") {
        return listed_meshes(&list);
    }
    let default_view = Vec3::new(0.35, 0.3, 1.0);
    let (v, f) = bumpy_icosphere(8);
    let generated = Model {
        parts: vec![ModelPart {
            name: "icosphere_8".into(),
            mesh: Arc::new(Mesh::new(v, f, Vec::new(), Vec::new()).expect("valid mesh")),
            transform: None,
            material: None,
        }],
        camera: None,
        seconds_load: 0.0,
        seconds_build: 0.0,
        warnings: Vec::new(),
    };
    let mut out = vec![(
        "icosphere_8_generated".to_string(),
        generated,
        default_view,
        Vec3::Y,
    )];
    let data = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data"));
    if !data.is_dir() {
        eprintln!(
            "note: {} is not there; benchmarking the generated mesh only",
            data.display()
        );
        return out;
    }
    for (name, view, up) in [
        ("igea_tris", default_view, Vec3::Y),
        ("stanford_bunny", default_view, Vec3::Y),
        ("lucy_100k", Vec3::new(-0.3, 1.0, 0.2), Vec3::Z),
    ] {
        let path = data.join(format!("{name}.ply"));
        match load_mesh_file(&path) {
            Ok(model) => out.push((name.to_string(), model, view, up)),
            Err(e) => eprintln!("note: skipping {}: {e}", path.display()),
        }
    }
    out
}

/// Runs `f` `n` times and returns the median of its times in seconds.
fn median_seconds(n: usize, mut f: impl FnMut()) -> f64 {
    let mut times: Vec<f64> = (0..n)
        .map(|_| {
            let start = Instant::now();
            f();
            start.elapsed().as_secs_f64()
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[n / 2]
}

fn bench(c: &mut Criterion) {
    let mut ratios = Vec::new();
    for (name, model, view, up) in meshes() {
        let SceneFile {
            scene, settings, ..
        } = mesh_scene(&model, view, up).expect("the mesh can be framed");
        assert_eq!(settings.integrator, IntegratorKind::Raycast);
        let settings = RenderSettings { spp: 1, ..settings };
        if scene.objects.len() != 1 {
            eprintln!("note: skipping {name}: it has more than one part");
            continue;
        }
        let Shape::Mesh(instance) = &scene.objects[0].shape else {
            unreachable!("a mesh scene's objects are meshes")
        };
        let (camera, shadow) = render_rays(&scene, &settings);
        let (_, stats) = render(&scene, &settings, &|_| {}).expect("renders");
        // The collected rays are the render's: the same counts.
        assert_eq!(stats.rays.camera, camera.len() as u64);
        assert_eq!(stats.rays.shadow, shadow.len() as u64);
        eprintln!(
            "{name}: {} camera rays, {} shadow rays",
            camera.len(),
            shadow.len()
        );
        let closest = || {
            camera
                .par_chunks(4096)
                .map(|chunk| {
                    let mut c = TraceCounters::default();
                    chunk
                        .iter()
                        .filter(|r| instance.intersect(r, &mut c).is_some())
                        .count()
                })
                .sum::<usize>()
        };
        let closest_packets = || {
            camera
                .par_chunks(4096)
                .map(|chunk| {
                    let mut c = TraceCounters::default();
                    let mut hits = [None; PACKET];
                    chunk
                        .chunks(PACKET)
                        .map(|p| {
                            let hits = &mut hits[..p.len()];
                            instance.intersect_packet(p, &mut c, hits);
                            hits.iter().filter(|h| h.is_some()).count()
                        })
                        .sum::<usize>()
                })
                .sum::<usize>()
        };
        assert_eq!(closest(), closest_packets(), "packets hit as often");
        let any = || {
            shadow
                .par_chunks(4096)
                .map(|chunk| {
                    let mut c = TraceCounters::default();
                    chunk
                        .iter()
                        .filter(|r| instance.occludes(r, &mut c))
                        .count()
                })
                .sum::<usize>()
        };
        let any_packets = || {
            shadow
                .par_chunks(4096)
                .map(|chunk| {
                    let mut c = TraceCounters::default();
                    let mut blocked = [false; PACKET];
                    chunk
                        .chunks(PACKET)
                        .map(|p| {
                            let blocked = &mut blocked[..p.len()];
                            instance.occludes_packet(p, &mut c, blocked);
                            blocked.iter().filter(|&&b| b).count()
                        })
                        .sum::<usize>()
                })
                .sum::<usize>()
        };
        assert_eq!(any(), any_packets(), "packets blocked as often");
        let whole = || render(black_box(&scene), black_box(&settings), &|_| {}).expect("renders");
        let mut g = c.benchmark_group("kernels");
        g.sample_size(15);
        g.throughput(Throughput::Elements(stats.rays_total));
        g.bench_function(BenchmarkId::new("render", &name), |b| b.iter(whole));
        g.throughput(Throughput::Elements(camera.len() as u64));
        g.bench_function(BenchmarkId::new("closest", &name), |b| b.iter(closest));
        g.bench_function(BenchmarkId::new("closest_packets", &name), |b| {
            b.iter(closest_packets)
        });
        g.throughput(Throughput::Elements(shadow.len() as u64));
        g.bench_function(BenchmarkId::new("any", &name), |b| b.iter(any));
        g.bench_function(BenchmarkId::new("any_packets", &name), |b| {
            b.iter(any_packets)
        });
        g.finish();
        // Side by side, in turns.
        let mut t = [Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new()];
        for _ in 0..5 {
            t[0].push(median_seconds(3, || {
                black_box(whole());
            }));
            t[1].push(median_seconds(3, || {
                black_box(closest());
            }));
            t[2].push(median_seconds(3, || {
                black_box(any());
            }));
            t[3].push(median_seconds(3, || {
                black_box(closest_packets());
            }));
            t[4].push(median_seconds(3, || {
                black_box(any_packets());
            }));
        }
        let [r, k1, k2, k3, k4] = t.map(|mut v| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        });
        ratios.push(format!(
            "{name}: render {:.1} ms, kernels {:.1} ms (closest {:.1} + any {:.1}): render / kernels = {:.2}; \
             in packets (closest {:.1} + any {:.1} ms): {:.2}",
            r * 1e3,
            (k1 + k2) * 1e3,
            k1 * 1e3,
            k2 * 1e3,
            r / (k1 + k2),
            k3 * 1e3,
            k4 * 1e3,
            r / (k3 + k4)
        ));
    }
    for line in ratios {
        eprintln!("{line}");
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
