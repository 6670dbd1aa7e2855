//! Tests of [`super`]: the leaf blocks and their numbering.

use super::*;
use crate::geometry::testgen::torus;
use crate::render::Pcg32;

/// A mesh with leaf blocks, whose BVH leaves then name blocks.
fn blocked() -> Mesh {
    let (v, f) = torus(2.0, 0.6, 96, 48);
    let m = Mesh::new(v, f, vec![], vec![]).unwrap();
    assert!(m.triangles.len() > SMALL_MESH_TRIANGLES && !m.blocks.is_empty());
    m
}

/// The three vertices of lane `i`.
fn tri_lane(lanes: &TriangleLanes, i: usize) -> [[f32; 3]; 3] {
    std::array::from_fn(|j| std::array::from_fn(|a| lanes.v[j][a][i]))
}

#[test]
fn block_numbered_leaves_validate_and_hold_their_triangles() {
    let m = blocked();
    assert_eq!(m.validate_bvh(), Ok(()));
    // Every triangle is reached through exactly one leaf's blocks, and
    // the spare lanes of a leaf's last block repeat its lane 0 bit for bit
    // (the closest-hit visit relies on it).
    let mut seen = vec![0u32; m.triangles.len()];
    for (first, count) in m.bvh.leaves() {
        let mut j = 0;
        m.leaf_lanes::<true>(first, count, |lanes, own, at| {
            let real = (count - j * LANES as u32).min(LANES as u32) as usize;
            let base = m.leaf_triangles(at);
            j += 1;
            for i in 0..LANES {
                assert!(own & 1 << i != 0);
                if i < real {
                    seen[(base + i as u32) as usize] += 1;
                } else {
                    let lane = |i: usize| tri_lane(lanes, i).map(|v| v.map(f32::to_bits));
                    assert_eq!(lane(i), lane(0), "spare lane {i}");
                }
            }
            false
        });
    }
    assert!(seen.iter().all(|&s| s == 1));
}

#[test]
fn validation_notices_a_wrong_block() {
    let mut m = blocked();
    m.blocks.swap(3, 4);
    assert!(m.validate_bvh().is_err());
    let mut m = blocked();
    m.block_first[5] += 1;
    assert!(m.validate_bvh().is_err());
    // Out of range: an error, not a panic.
    let mut m = blocked();
    m.block_first[5] = u32::MAX - 8;
    assert!(m.validate_bvh().is_err());
    let mut m = blocked();
    let past = m.blocks.len() as u32 + 5;
    m.bvh
        .map_leaves(|first, _| if first == 7 { past } else { first });
    assert!(m.validate_bvh().is_err());
    let mut m = blocked();
    m.bvh
        .map_leaves(|first, _| if first == 7 { 8 } else { first });
    assert!(m.validate_bvh().is_err());
}

/// A mesh built without leaf blocks (as on a machine short of memory, the
/// only case left where the vertices are gathered through the index array)
/// finds the same closest hits, bit for bit, and the same occlusion as the
/// same mesh with blocks, on rays from all around and from inside the torus.
#[test]
fn gathered_vertices_give_the_hits_of_the_blocks() {
    let (v, f) = torus(2.0, 0.6, 96, 48);
    let with = Mesh::build(v.clone(), f.clone(), vec![], vec![], true).unwrap();
    let without = Mesh::build(v, f, vec![], vec![], false).unwrap();
    assert!(!with.blocks.is_empty());
    assert!(without.blocks.is_empty() && without.lanes.is_empty());
    assert_eq!(
        (with.leaf_blocks(), without.leaf_blocks()),
        (Some(true), Some(false))
    );
    let (v, f) = torus(2.0, 0.6, 16, 8);
    assert_eq!(Mesh::new(v, f, vec![], vec![]).unwrap().leaf_blocks(), None);
    assert_eq!(without.validate_bvh(), Ok(()));
    let mut rng = Pcg32::new(21, 5);
    let mut u = |s: f32| (rng.next_f32() * 2.0 - 1.0) * s;
    let mut c = TraceCounters::default();
    let (mut hits, mut blocked) = (0, 0);
    for k in 0..20_000 {
        let o = Vec3::new(u(4.0), u(2.0), u(4.0));
        let target = Vec3::new(u(2.6), u(0.6), u(2.6));
        let mut ray = Ray::new(o, target - o);
        if k % 3 == 0 {
            ray.t_max = u(1.0).abs() * 1.5;
        }
        let a = with.intersect_object(&ray, &mut c);
        let b = without.intersect_object(&ray, &mut c);
        let key = |h: ShapeHit| (h.t.to_bits(), h.prim, h.u.to_bits(), h.v.to_bits());
        assert_eq!(a.map(key), b.map(key), "{ray:?}");
        let occluded = with.occludes_object(&ray, &mut c);
        assert_eq!(occluded, without.occludes_object(&ray, &mut c), "{ray:?}");
        assert_eq!(occluded, a.is_some(), "{ray:?}");
        hits += u32::from(a.is_some());
        blocked += u32::from(occluded);
    }
    assert!(
        hits > 4_000 && blocked == hits,
        "{hits} hits, {blocked} occluded"
    );
}

/// [`Mesh::packet_pays`] on a flat 100×100 grid of unit squares cut in
/// two (mean triangle area 1/2) under a 4×4 block of parallel rays: the
/// rays are traced together while each covers at most
/// [`PACKET_TRIANGLES_PER_RAY`] triangle areas where they meet the grid,
/// one by one beyond; a closest-hit packet that misses the bounds goes ray
/// by ray, a shadow packet that does stays a packet; and the mean area is
/// the grid's.
#[test]
fn packets_are_traced_together_while_their_rays_are_close() {
    let n = 100u32;
    let positions: Vec<glam::Vec3> = (0..=n)
        .flat_map(|y| (0..=n).map(move |x| glam::Vec3::new(x as f32, y as f32, 0.0)))
        .collect();
    let triangles: Vec<[u32; 3]> = (0..n)
        .flat_map(|y| (0..n).map(move |x| (x, y)))
        .flat_map(|(x, y)| {
            let v = y * (n + 1) + x;
            [[v, v + 1, v + n + 2], [v, v + n + 2, v + n + 1]]
        })
        .collect();
    let m = Mesh::new(positions, triangles, vec![], vec![]).unwrap();
    assert!((m.mean_triangle_area - 0.5).abs() < 1e-6);
    // Rays 1 above the grid, straight down, `step` apart.
    let block = |x0: f32, step: f32| -> Vec<Ray> {
        (0..16)
            .map(|i| {
                let (i, j) = ((i % 4) as f32, (i / 4) as f32);
                let o = Vec3::new(x0 + step * i, 50.0 + step * j, 1.0);
                Ray::new(o, Vec3::new(0.0, 0.0, -1.0))
            })
            .collect()
    };
    // The corners are 3·√2·step apart: 18·step² over 16 rays, against
    // 4 · 1/2 = 2 per ray, so the limit lies at step = 4/3.
    for (step, together) in [(0.01, true), (1.3, true), (1.4, false), (5.0, false)] {
        for closest in [true, false] {
            let rays = block(10.0, step);
            assert_eq!(m.packet_pays(&rays, closest), together, "{step}");
        }
    }
    // Beside the grid (x from 200): no corner enters the bounds.
    let past = block(200.0, 0.01);
    assert!(!m.packet_pays(&past, true));
    assert!(m.packet_pays(&past, false));
    // One corner outside, the other in: judged where that one enters.
    let mut half = block(95.0, 0.01);
    half[0].o.x = -10.0;
    assert!(!m.packet_pays(&half, true));
}

/// The builder's surface areas are f64 ([`crate::math::Aabb::half_area`]),
/// so a mesh scaled by a power of two gets the same tree, node for node,
/// with its boxes scaled, from 2⁻¹⁰⁰ to 2¹⁰⁰. With f32 areas the trees
/// differed from 2⁶⁰ up (area times count overflowed, and every split then
/// cost the same) and from 2⁻⁸⁰ down (the areas fell below f32's normal
/// range); they were the same from 2⁻⁶⁰ to 2⁵⁰.
#[test]
fn the_tree_is_the_same_at_every_scale_from_two_to_the_minus_100_to_the_100() {
    for (nu, nv) in [(96, 48), (16, 8)] {
        let (v, f) = torus(2.0, 0.6, nu, nv);
        let unit = Mesh::new(v.clone(), f.clone(), vec![], vec![]).unwrap();
        for e in [-100, -80, -60, -45, 45, 60, 80, 100] {
            let s = 2f32.powi(e);
            let scaled: Vec<glam::Vec3> = v.iter().map(|p| *p * s).collect();
            let m = Mesh::new(scaled, f.clone(), vec![], vec![]).unwrap();
            assert_eq!(m.triangles, unit.triangles, "2^{e}, {nu}×{nv}");
            assert_eq!(m.bvh.nodes.len(), unit.bvh.nodes.len(), "2^{e}, {nu}×{nv}");
            for (a, b) in unit.bvh.nodes.iter().zip(&m.bvh.nodes) {
                assert_eq!((a.child, a.order), (b.child, b.order), "2^{e}, {nu}×{nv}");
                for (ra, rb) in a.planes.iter().zip(&b.planes) {
                    assert_eq!(ra.0.map(|x| x * s), rb.0, "2^{e}, {nu}×{nv}");
                }
            }
        }
    }
}

/// A closed mesh scaled by a power of two gives the same hits as the mesh
/// itself, `t` scaled by the same power, from 2⁻⁵⁵ (about 3·10⁻¹⁷) to 2⁶⁰
/// (about 10¹⁸), with leaf blocks and with per-triangle lanes: the
/// watertight test takes `t` from the barycentrics. Taken as `(e0·z0 +
/// e1·z1 + e2·z2)/det`, whose numerator grows as the cube of the size, it
/// overflowed past about 10¹² and underflowed below about 10⁻¹³, and such
/// meshes rendered empty. Floating point scales exactly while no value
/// falls below the normal range: bit for bit from 2⁻⁴⁵ up; below, some
/// products in the edge functions are subnormal, and the same triangles
/// are hit at nearly the same `t`.
#[test]
fn hits_scale_with_the_mesh_from_two_to_the_minus_55_to_the_60() {
    for (nu, nv) in [(96, 48), (16, 8)] {
        let (v, f) = torus(2.0, 0.6, nu, nv);
        let unit = Mesh::new(v.clone(), f.clone(), vec![], vec![]).unwrap();
        for e in [-55, -50, -45, 45, 60] {
            let s = 2f32.powi(e);
            let scaled: Vec<glam::Vec3> = v.iter().map(|p| *p * s).collect();
            let big = Mesh::new(scaled, f.clone(), vec![], vec![]).unwrap();
            let mut rng = Pcg32::new(7, e as u64 & 0xff);
            let mut u = |r: f32| (rng.next_f32() * 2.0 - 1.0) * r;
            let mut c = TraceCounters::default();
            let mut hits = 0;
            for _ in 0..3_000 {
                let o = Vec3::new(u(4.0), u(2.0), u(4.0));
                let target = Vec3::new(u(2.6), u(0.6), u(2.6));
                let ray = Ray::new(o, target - o);
                let ray_s = Ray::new(o * s, ray.d);
                let a = unit.intersect_object(&ray, &mut c);
                let b = big.intersect_object(&ray_s, &mut c);
                // The triangle hit, by its vertices.
                let corners = |m: &Mesh, h: &ShapeHit, k: f32| {
                    m.triangles[h.prim as usize].map(|i| (m.positions[i as usize] * k).to_array())
                };
                assert_eq!(
                    a.map(|h| corners(&unit, &h, s)),
                    b.map(|h| corners(&big, &h, 1.0)),
                    "2^{e}: {ray:?}"
                );
                if let (Some(a), Some(b)) = (a, b) {
                    let t = a.t * s;
                    if e >= -45 {
                        assert_eq!((t.to_bits(), a.u, a.v), (b.t.to_bits(), b.u, b.v), "2^{e}");
                    } else {
                        assert!((b.t - t).abs() <= 1e-5 * t, "2^{e}: {} against {t}", b.t);
                    }
                }
                let blocked = big.occludes_object(&ray_s, &mut c);
                assert_eq!(blocked, b.is_some(), "2^{e}: {ray:?}");
                hits += u32::from(b.is_some());
            }
            assert!(hits > 500, "2^{e}, {nu}×{nv}: {hits} hits");
        }
    }
}
