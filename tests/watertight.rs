//! No ray slips through a closed mesh: rays aimed exactly through the
//! vertices and edges of steep triangle fans (triangles 1–3° from the ray),
//! from outside and from inside, at scales 1e-3 to 1e6 and 1e6 from the
//! origin, with both traversal kernels (AVX and portable), closest hit and
//! any hit.
//!
//! This file is its own test binary because it switches the process-wide
//! kernel choice ([`glint::accel::force_portable`]).

use glam::{Quat, Vec3 as V3};
use glint::accel::force_portable;
use glint::geometry::testgen::icosphere;
use glint::geometry::{Mesh, TraceCounters};
use glint::math::{Ray, Vec3};
use glint::render::Pcg32;

/// A closed cone: apex at `(0, 0, height)`, a ring of `n` vertices of radius
/// `radius` at z = 0 and the base closed by a fan around its centre. Every
/// triangle is wound counter-clockwise seen from outside.
fn cone(n: u32, radius: f32, height: f32) -> (Vec<V3>, Vec<[u32; 3]>) {
    let mut v = vec![V3::new(0.0, 0.0, height), V3::ZERO];
    for i in 0..n {
        let a = std::f32::consts::TAU * i as f32 / n as f32;
        v.push(V3::new(radius * a.cos(), radius * a.sin(), 0.0));
    }
    let ring = |i: u32| 2 + i % n;
    let mut f = Vec::new();
    for i in 0..n {
        f.push([0, ring(i), ring(i + 1)]);
        f.push([1, ring(i + 1), ring(i)]);
    }
    (v, f)
}

/// The closed convex meshes of the probe, each placed by a random rotation,
/// then `scale`, then `offset`: needles whose side fans are 1°, 2° and 3°
/// from their axis, and an icosphere squashed to a disc 40 times thinner than
/// wide (grazing rays meet its faces at a few degrees).
fn meshes(rng: &mut Pcg32, scale: f32, offset: V3) -> Vec<(String, Vec<V3>, Vec<[u32; 3]>)> {
    let mut out = Vec::new();
    for (deg, n) in [(1.0f32, 16), (2.0, 24), (3.0, 12)] {
        let (v, f) = cone(n, deg.to_radians().tan(), 1.0);
        out.push((format!("{deg}° needle"), v, f));
    }
    let (v, f) = icosphere(2, 1.0);
    let v = v
        .into_iter()
        .map(|p| p * V3::new(1.0, 1.0, 0.025))
        .collect();
    out.push(("squashed icosphere".into(), v, f));
    for (_, v, _) in &mut out {
        let q = Quat::from_euler(
            glam::EulerRot::XYZ,
            rng.next_f32() * 6.3,
            rng.next_f32() * 6.3,
            rng.next_f32() * 6.3,
        );
        for p in v.iter_mut() {
            *p = q * *p * scale + offset;
        }
    }
    out
}

/// A random point strictly inside the convex hull of `v`: a random convex
/// combination of the vertices, pulled towards their centroid.
fn interior(rng: &mut Pcg32, v: &[V3]) -> Vec3 {
    let centroid: glam::DVec3 =
        v.iter().map(|p| p.as_dvec3()).sum::<glam::DVec3>() / v.len() as f64;
    let mut sum = glam::DVec3::ZERO;
    let mut total = 0.0;
    for p in v {
        let w = rng.next_f32() as f64;
        sum += p.as_dvec3() * w;
        total += w;
    }
    Vec3::from((sum / total * 0.5 + centroid * 0.5).as_vec3())
}

/// Points of the surface the probe aims at: every vertex, and points of every
/// edge (its midpoint and a random point of it).
fn targets(rng: &mut Pcg32, v: &[V3], f: &[[u32; 3]]) -> Vec<Vec3> {
    let mut out: Vec<Vec3> = v.iter().map(|&p| Vec3::from(p)).collect();
    for t in f {
        for k in 0..3 {
            let (a, b) = (v[t[k] as usize], v[t[(k + 1) % 3] as usize]);
            out.push(Vec3::from(a.lerp(b, 0.5)));
            out.push(Vec3::from(a.lerp(b, rng.next_f32())));
        }
    }
    out
}

/// Shoots the probe at one mesh; returns (rays, leaks) and prints the first
/// few leaks. A ray leaks if it reaches a point strictly inside the mesh
/// without a hit before it: for rays from outside, aimed at the surface
/// point `p` on the line towards an interior point `q`, the point halfway
/// from `p` to `q`; for rays from `q` itself, anywhere.
fn probe(name: &str, mesh: &Mesh, rng: &mut Pcg32, targets: &[Vec3], v: &[V3]) -> (u64, u64) {
    let (mut rays, mut leaks) = (0u64, 0u64);
    let mut counters = TraceCounters::default();
    let mut check = |ray: Ray, reach: f32, what: &str| {
        rays += 1;
        let closest = mesh.intersect_object(&ray, &mut counters);
        let closest_ok = closest.is_some_and(|h| h.t <= reach);
        let segment = Ray {
            t_max: reach,
            ..ray
        };
        let any_ok = mesh.occludes_object(&segment, &mut counters);
        if !(closest_ok && any_ok) {
            leaks += 1;
            if leaks <= 5 {
                eprintln!(
                    "{name}: {what} ray {:?} + t·{:?} leaks before t = {reach} (closest {:?}, any {any_ok})",
                    ray.o, ray.d, closest
                );
            }
        }
    };
    for &p in targets {
        for _ in 0..4 {
            let q = interior(rng, v);
            // From outside: o = p + s(p − q), so p is at t = 1 and the point
            // halfway to q at t = 1 + 1/(2s).
            let s = 0.05 + 3.0 * rng.next_f32();
            let o = p + (p - q) * s;
            check(Ray::new(o, p - o), 1.0 + 0.5 / s, "outside");
            check(Ray::new(q, p - q), f32::INFINITY, "inside");
        }
    }
    (rays, leaks)
}

#[test]
fn rays_through_vertices_and_edges_of_steep_fans_never_leak() {
    let mut total = (0u64, 0u64);
    for portable in [false, true] {
        force_portable(portable);
        let mut rng = Pcg32::new(2013, 7);
        let placements = [
            (1e-3, V3::ZERO),
            (1.0, V3::ZERO),
            (1e3, V3::ZERO),
            (1e6, V3::ZERO),
            (1e3, V3::new(1e6, -1e6, 1e6)),
            (1e4, V3::new(-1e6, 1e6, 0.0)),
        ];
        for (scale, offset) in placements {
            for (name, v, f) in meshes(&mut rng, scale, offset) {
                let targets = targets(&mut rng, &v, &f);
                let mesh = Mesh::new(v.clone(), f, Vec::new(), Vec::new()).unwrap();
                let label = format!(
                    "{name} at scale {scale:e}, offset {offset}, {} kernel",
                    if portable { "portable" } else { "default" }
                );
                let (rays, leaks) = probe(&label, &mesh, &mut rng, &targets, &v);
                if leaks > 0 {
                    eprintln!("{label}: {leaks} of {rays} rays leak");
                }
                total.0 += rays;
                total.1 += leaks;
            }
        }
    }
    force_portable(false);
    assert!(total.0 > 50_000, "only {} rays", total.0);
    assert_eq!(total.1, 0, "{} of {} rays leaked", total.1, total.0);
}
