//! BVH build (M triangles/s) and traversal (M rays/s) of triangle meshes, set
//! up as `shared/anchors/embree_bench.py` does for Embree, so the two can be
//! compared on the same mesh and rays:
//! - camera (`common.camera`): box centre c, r = 0.6·(largest extent), eye at
//!   c + normalize(0.35, 0.3, 1)·r/sin(20°), vertical fov 40°, y up; point
//!   light at c + 3r(−0.5 right + 0.8 up + 0.33 back);
//! - primary: 1920×1080 rays through pixel centres, closest hit;
//! - shadow: from every hit whose viewer-facing geometric normal faces the
//!   light, origin offset by 1e-4·r along it, to 0.9999 of the way to the light.
//!
//! Meshes: a generated bumpy icosphere of 1.31M triangles (always), the meshes
//! of `../shared/data/` when that folder is there (it says so when it is not),
//! and any files listed in `GLINT_BENCH_MESHES` (colon-separated), e.g. the
//! `icosphere_8.ply` that the Embree script writes, to measure the very same file
//! (a listed file replaces a built-in mesh of the same name, and is seen
//! from the default view).

use criterion::measurement::WallTime;
use criterion::{
    BatchSize, BenchmarkGroup, BenchmarkId, Criterion, Throughput, criterion_group, criterion_main,
};
use glam::Vec3;
use glint::accel::PACKET;
use glint::geometry::testgen::bumpy_icosphere;
use glint::geometry::{Mesh, TraceCounters};
use glint::math::Ray;
use glint::scene::meshio::load_mesh_file;
use rayon::prelude::*;
use std::hint::black_box;
use std::path::Path;

const WIDTH: u32 = 1920;
const HEIGHT: u32 = 1080;

struct Rays {
    primary: Vec<Ray>,
    shadow: Vec<Ray>,
    /// The primary rays in 4×4 pixel blocks, and their shadow rays in
    /// that order (for packets).
    primary_blocks: Vec<Ray>,
    shadow_blocks: Vec<Ray>,
    hit_fraction: f64,
}

/// `common.camera` and `common.primary_rays`, then the shadow rays of
/// `embree_bench.py` from the closest hits.
fn rays(mesh: &Mesh, view: Vec3, up: Vec3) -> Rays {
    let b = mesh.bounds();
    let (lo, hi) = (b.min.as_dvec3(), b.max.as_dvec3());
    let c = (lo + hi) / 2.0;
    let r = 0.6 * (hi - lo).max_element();
    let back = view.as_dvec3().normalize();
    let right = up.as_dvec3().cross(back).normalize();
    let up = back.cross(right);
    let eye = c + back * r / 20f64.to_radians().sin();
    let light = (c + r * 3.0 * (-0.5 * right + 0.8 * up + 0.33 * back)).as_vec3a();
    let th = 20f64.to_radians().tan();
    let primary: Vec<Ray> = (0..WIDTH * HEIGHT)
        .map(|i| {
            let (x, y) = ((i % WIDTH) as f64, (i / WIDTH) as f64);
            let px = (2.0 * (x + 0.5) / WIDTH as f64 - 1.0) * th * WIDTH as f64 / HEIGHT as f64;
            let py = (1.0 - 2.0 * (y + 0.5) / HEIGHT as f64) * th;
            let d = (right * px + up * py - back).normalize();
            Ray::new(eye.as_vec3a(), d.as_vec3a())
        })
        .collect();
    // From each hit whose viewer-facing normal faces the light.
    let shadow_of = |primary: &[Ray]| -> Vec<Ray> {
        primary
            .par_iter()
            .filter_map(|ray| {
                let h = mesh.intersect_object(ray, &mut TraceCounters::default())?;
                let s = mesh.surface_object(&h);
                let p = ray.at(h.t);
                let n = if s.n.dot(ray.d) > 0.0 { -s.n } else { s.n };
                (n.dot(light - p) > 0.0).then(|| {
                    let o = p + n * (1e-4 * r as f32);
                    Ray {
                        o,
                        d: light - o,
                        t_min: 0.0,
                        t_max: 0.9999,
                    }
                })
            })
            .collect()
    };
    let shadow = shadow_of(&primary);
    // The same rays in 4×4 pixel blocks, for packets; the shadow rays of
    // their hits in that order.
    let (w, h) = (WIDTH as usize, HEIGHT as usize);
    let primary_blocks: Vec<Ray> = (0..h / 4)
        .flat_map(|by| (0..w / 4).map(move |bx| (bx, by)))
        .flat_map(|(bx, by)| (0..16).map(move |i| (4 * by + i / 4) * w + 4 * bx + i % 4))
        .map(|i| primary[i])
        .collect();
    let shadow_blocks = shadow_of(&primary_blocks);
    let hit_count = primary
        .par_iter()
        .filter(|r| mesh.occludes_object(r, &mut TraceCounters::default()))
        .count();
    Rays {
        hit_fraction: hit_count as f64 / primary.len() as f64,
        shadow,
        primary,
        primary_blocks,
        shadow_blocks,
    }
}

/// A benchmark mesh: name, vertices, triangles, view direction and up axis.
type BenchMesh = (String, Vec<Vec3>, Vec<[u32; 3]>, Vec3, Vec3);

fn meshes() -> Vec<BenchMesh> {
    let default_view = Vec3::new(0.35, 0.3, 1.0);
    let (v, f) = bumpy_icosphere(8);
    let mut out = vec![(
        "icosphere_8_generated".to_string(),
        v,
        f,
        default_view,
        Vec3::Y,
    )];
    let mut files: Vec<(String, Vec3, Vec3)> = Vec::new();
    let data = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data"));
    if data.is_dir() {
        for name in ["stanford_bunny.ply", "igea_tris.ply"] {
            files.push((data.join(name).display().to_string(), default_view, Vec3::Y));
        }
        files.push((
            data.join("lucy_100k.ply").display().to_string(),
            Vec3::new(-0.3, 1.0, 0.2),
            Vec3::Z,
        ));
    } else {
        eprintln!(
            "note: {} is not there; benchmarking the generated mesh only",
            data.display()
        );
    }
    if let Ok(list) = std::env::var("GLINT_BENCH_MESHES") {
        let stem = |p: &str| Path::new(p).file_stem().map(|s| s.to_os_string());
        for p in list.split(':').filter(|p| !p.is_empty()) {
            // A listed file replaces a built-in one of the same name (with
            // the default view, as the anchors' scripts use for every
            // mesh), rather than adding a second benchmark of that name.
            files.retain(|(q, _, _)| stem(q) != stem(p));
            files.push((p.to_string(), default_view, Vec3::Y));
        }
    }
    for (path, view, up) in files {
        match load_mesh_file(Path::new(&path)) {
            Ok(model) => {
                let m = &model.parts[0].mesh;
                let name = Path::new(&path)
                    .file_stem()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or(path.clone());
                out.push((name, m.positions.clone(), m.triangles.clone(), view, up));
            }
            Err(e) => eprintln!("note: skipping {path}: {e}"),
        }
    }
    out
}

/// Prints the work per ray (nodes visited, triangle tests), then times
/// tracing all `rays` on both cores.
fn trace_rays(
    g: &mut BenchmarkGroup<WallTime>,
    kind: &str,
    name: &str,
    rays: &[Ray],
    trace: impl Fn(&Ray, &mut TraceCounters) -> bool + Sync,
) {
    let mut c = TraceCounters::default();
    for r in rays {
        trace(r, &mut c);
    }
    let n = rays.len().max(1) as f64;
    eprintln!(
        "  {kind}: {:.1} nodes visited, {:.1} triangle tests per ray",
        c.bvh.nodes_visited as f64 / n,
        c.bvh.primitive_tests as f64 / n
    );
    g.throughput(Throughput::Elements(rays.len() as u64));
    g.bench_function(BenchmarkId::new(kind, name), |b| {
        b.iter(|| {
            rays.par_chunks(4096)
                .map(|chunk| {
                    let mut c = TraceCounters::default();
                    chunk.iter().filter(|r| trace(r, &mut c)).count()
                })
                .sum::<usize>()
        })
    });
}

/// A packet benchmark: its name, its rays, how to trace a chunk of them
/// (returning the hits) and how to trace one alone (whether it hits).
type PacketCase<'a> = (
    &'a str,
    &'a [Ray],
    &'a (dyn Fn(&[Ray], &mut TraceCounters) -> usize + Sync),
    &'a dyn Fn(&Ray) -> bool,
);

/// The primary and shadow rays again, traced as packets of 16 rays
/// (`Mesh::intersect_packet`, `Mesh::occludes_packet`, as the renderer
/// traces them: ray by ray where their spacing against the triangles
/// makes packets lose, see `Mesh::packet_pays`): the primary rays of 4×4
/// pixel blocks, the shadow rays of their hits in that order.
/// `bvh/primary_packets/MESH` and `bvh/shadow_packets/MESH`, in rays per
/// second like the single-ray figures, after checking that the packets
/// hit as often as single rays.
fn trace_packets(g: &mut BenchmarkGroup<WallTime>, name: &str, mesh: &Mesh, rays: &Rays) {
    let closest = |chunk: &[Ray], c: &mut TraceCounters| {
        let mut hits = [None; PACKET];
        chunk
            .chunks(PACKET)
            .map(|p| {
                mesh.intersect_packet(p, c, &mut hits[..p.len()]);
                hits[..p.len()].iter().filter(|h| h.is_some()).count()
            })
            .sum::<usize>()
    };
    let any = |chunk: &[Ray], c: &mut TraceCounters| {
        let mut blocked = [false; PACKET];
        chunk
            .chunks(PACKET)
            .map(|p| {
                mesh.occludes_packet(p, c, &mut blocked[..p.len()]);
                blocked[..p.len()].iter().filter(|&&b| b).count()
            })
            .sum::<usize>()
    };
    let cases: [PacketCase; 2] = [
        ("primary_packets", &rays.primary_blocks, &closest, &|r| {
            mesh.intersect_object(r, &mut TraceCounters::default())
                .is_some()
        }),
        ("shadow_packets", &rays.shadow_blocks, &any, &|r| {
            mesh.occludes_object(r, &mut TraceCounters::default())
        }),
    ];
    for (kind, list, trace, single) in cases {
        let mut c = TraceCounters::default();
        let hits = trace(list, &mut c);
        let want = list.iter().filter(|r| single(r)).count();
        assert_eq!(hits, want, "{kind}: packets and single rays hit as often");
        let n = list.len().max(1) as f64;
        eprintln!(
            "  {kind}: {:.1} node visits, {:.1} triangle tests per ray",
            c.bvh.nodes_visited as f64 / n,
            c.bvh.primitive_tests as f64 / n
        );
        g.throughput(Throughput::Elements(list.len() as u64));
        g.bench_function(BenchmarkId::new(kind, name), |b| {
            b.iter(|| {
                list.par_chunks(4096)
                    .map(|chunk| trace(chunk, &mut TraceCounters::default()))
                    .sum::<usize>()
            })
        });
    }
}

fn bench(c: &mut Criterion) {
    for (name, v, f, view, up) in meshes() {
        let mesh = Mesh::new(v.clone(), f.clone(), Vec::new(), Vec::new()).expect("valid mesh");
        let rays = rays(&mesh, view, up);
        eprintln!(
            "{name}: {} triangles, {} BVH nodes ({:.1} bytes/triangle); {} primary rays ({:.1}% hit), {} shadow rays",
            f.len(),
            mesh.bvh.nodes.len(),
            mesh.bvh.bytes() as f64 / f.len() as f64,
            rays.primary.len(),
            100.0 * rays.hit_fraction,
            rays.shadow.len()
        );
        let mut g = c.benchmark_group("bvh");
        g.sample_size(10);
        g.throughput(Throughput::Elements(f.len() as u64));
        // Mesh::new takes the arrays; copying them is set-up, not timed (as
        // Embree's commit, which the anchors time apart from the upload).
        g.bench_function(BenchmarkId::new("build", &name), |b| {
            b.iter_batched(
                || (v.clone(), f.clone()),
                |(v, f)| {
                    Mesh::new(black_box(v), black_box(f), Vec::new(), Vec::new())
                        .expect("valid mesh")
                },
                BatchSize::LargeInput,
            )
        });
        trace_rays(&mut g, "primary", &name, &rays.primary, |r, c| {
            mesh.intersect_object(r, c).is_some()
        });
        trace_rays(&mut g, "shadow", &name, &rays.shadow, |r, c| {
            mesh.occludes_object(r, c)
        });
        trace_packets(&mut g, &name, &mesh, &rays);
        g.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
