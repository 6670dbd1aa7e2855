//! Tests of [`super`]: traversals against brute force, the AVX2 and
//! portable visits against each other bit for bit.

use super::*;
use crate::accel::bvh::Bvh;
use crate::accel::bvh8::EMPTY;
use crate::math::{Aabb, Vec3};
use crate::render::Pcg32;

thread_local! {
    /// Set in a test thread to make the kernels skip their AVX-512VL
    /// copies (see [`super::has_avx512vl`]), so that the AVX2 copies are
    /// tested on CPUs that have both.
    pub(super) static AVX2_ONLY: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

fn random_boxes(n: usize, seed: u64) -> Vec<Aabb> {
    let mut rng = Pcg32::new(seed, 1);
    (0..n)
        .map(|_| {
            let c = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 10.0;
            let e = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 0.3;
            Aabb::new(c - e, c + e)
        })
        .collect()
}

#[test]
fn traversal_matches_brute_force_and_tree_is_valid() {
    let b = random_boxes(20_000, 3);
    let bvh = Bvh::build(&b);
    let wide = Bvh8::from_binary(&bvh);
    // The wide tree refers to primitives by leaf position.
    let leaf_boxes: Vec<Aabb> = bvh.indices.iter().map(|&i| b[i as usize]).collect();
    wide.validate(&leaf_boxes).unwrap();
    assert!(
        wide.nodes.len() * 5 < bvh.nodes.len(),
        "collapse fills nodes"
    );
    let mut rng = Pcg32::new(9, 2);
    for i in 0..3000 {
        let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 14.0 - Vec3::splat(2.0);
        let d = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - Vec3::splat(0.5);
        let mut ray = Ray::new(o, d);
        // A third of the rays start further on, as shadow rays do: boxes
        // met only before `t_min` are not hits (the any-hit visits take
        // them from 0, and the leaf test must refuse them).
        if i % 3 == 1 {
            ray.t_min = rng.next_f32() * 8.0;
        }
        let inv = ray.inv_d();
        let t_of = |p: u32| {
            leaf_boxes[p as usize]
                .slab(ray.o, inv)
                .filter(|h| h.t_exit >= ray.t_min)
                .map(|h| h.t_enter.max(ray.t_min))
        };
        let brute = (0..leaf_boxes.len() as u32)
            .filter_map(|p| t_of(p).map(|t| (p, t)))
            .min_by(|x, y| x.1.total_cmp(&y.1).then(x.0.cmp(&y.0)));
        let mut counters = TraversalCounters::default();
        let got = wide.closest(&ray, &mut counters, |p, t_max| {
            t_of(p).filter(|&t| t < t_max)
        });
        assert_eq!(got.map(|g| g.1), brute.map(|b| b.1));
        assert_eq!(
            wide.any(&ray, &mut counters, |p| t_of(p).is_some()),
            brute.is_some()
        );
        // The path taken where the CPU lacks AVX2.
        let portable = PortableLanes::new(&RaySetup::new(&ray, &wide.root()));
        let nearest = |first: u32, count: u32, t_max: f32| {
            assert!(count >= 1 && count as usize <= crate::accel::bvh::MAX_LEAF);
            (first..first + count)
                .filter_map(|p| t_of(p).filter(|&t| t < t_max).map(|t| (p, t)))
                .min_by(|x, y| x.1.total_cmp(&y.1))
        };
        let leaf = |_: &(), first, count, t_max| nearest(first, count, t_max);
        let got = wide.closest_with(ray.t_max, &mut counters, || (), leaf, &portable);
        assert_eq!(got.map(|g| g.1), brute.map(|b| b.1));
        let any = |first: u32, count: u32| (first..first + count).any(|p| t_of(p).is_some());
        assert_eq!(
            wide.any_with(
                ray.t_max,
                &mut counters,
                (|| (), |_: &(), f, c| any(f, c)),
                &portable
            ),
            brute.is_some()
        );
        // And the per-leaf entry points.
        let got = wide.closest_leaves(&ray, &mut counters, nearest);
        assert_eq!(got.map(|g| g.1), brute.map(|b| b.1));
        // Per-ray constants: made at most once, before the first leaf (and
        // not for rays that miss the root's children); every leaf gets them.
        let (mut made, mut leaves) = (0, 0);
        let got = wide.closest_leaves_with(
            &ray,
            &mut counters,
            || {
                made += 1;
                ray.o.x + 1.0
            },
            |&p: &f32, first, count, t_max| {
                assert_eq!(p, ray.o.x + 1.0);
                leaves += 1;
                nearest(first, count, t_max)
            },
        );
        assert_eq!(got.map(|g| g.1), brute.map(|b| b.1));
        assert!(made <= 1 && (leaves == 0 || made == 1), "{made} {leaves}");
        let mut enter = [0.0; WIDTH];
        let root_hit = portable.test(
            &wide.nodes[0],
            portable.t_min,
            portable.bound(ray.t_max),
            &mut enter,
        );
        if root_hit == 0 {
            assert_eq!(made, 0);
        }
        assert_eq!(wide.any_leaves(&ray, &mut counters, any), brute.is_some());
        let (mut made, mut leaves) = (0, 0);
        let found = wide.any_leaves_with(
            &ray,
            &mut counters,
            || {
                made += 1;
                ray.o.y - 1.0
            },
            |&p: &f32, first, count| {
                assert_eq!(p, ray.o.y - 1.0);
                leaves += 1;
                any(first, count)
            },
        );
        assert_eq!(found, brute.is_some());
        assert!(made <= 1 && (leaves == 0 || made == 1), "{made} {leaves}");
        // Any hits test the root from 0 where the test is fused (see
        // `NodeVisit::visit_any`).
        let t_min = if portable.fused {
            Vec4::ZERO
        } else {
            portable.t_min
        };
        let root_hit = portable.test(&wide.nodes[0], t_min, portable.bound(ray.t_max), &mut enter);
        if root_hit == 0 {
            assert_eq!(made, 0);
        }
    }
}

/// One node visit through the AVX2 lanes of the ray's octant, for closest
/// (`ANY` false) or any hits: the child returned, the leaves set apart
/// (always 0 for closest hits), and the stack's entries with their
/// distances as bits (0 for any hits, which push none).
#[cfg(target_arch = "x86_64")]
fn visit_avx2<const ANY: bool>(
    setup: &RaySetup,
    node: &Bvh8Node,
    t_max: f32,
) -> (Option<u32>, u32, Vec<(u32, u32)>) {
    fn run<const OCT: u32, const ANY: bool>(
        setup: &RaySetup,
        node: &Bvh8Node,
        t_max: f32,
        stack: &mut Stack,
    ) -> (Option<u32>, u32) {
        // SAFETY: called only where the CPU has AVX2.
        let lanes = unsafe { avx2::Avx2Lanes::<OCT>::new(setup) };
        if ANY {
            lanes.visit_any(node, t_max, stack)
        } else {
            (lanes.visit(node, t_max, stack), 0)
        }
    }
    let mut stack = Stack::new();
    let (next, leaves) =
        by_octant!(setup.octant, OCT => run::<OCT, ANY>(setup, node, t_max, &mut stack));
    let drained = if ANY {
        drain_entries(&mut stack)
    } else {
        drain(&mut stack)
    };
    (next, leaves, drained)
}

fn drain_entries(stack: &mut Stack) -> Vec<(u32, u32)> {
    std::iter::from_fn(|| stack.pop_entry())
        .map(|c| (c, 0))
        .collect()
}

fn drain(stack: &mut Stack) -> Vec<(u32, u32)> {
    let mut items = Vec::new();
    while let Some((c, d)) = stack.pop() {
        items.push((c, d.to_bits()));
    }
    items
}

#[test]
fn avx2_and_portable_visits_agree_bit_for_bit() {
    let b = random_boxes(5000, 4);
    let bvh = Bvh::build(&b);
    let wide = Bvh8::from_binary(&bvh);
    let mut rng = Pcg32::new(5, 3);
    let mut compared = 0;
    let mut pushed = 0;
    // Children tested by plain and by fused rays; those only the fused
    // test takes.
    let (mut tested, mut extra) = ([0usize; 2], 0);
    // Children the any-hit visit takes from 0 that the ray's own interval
    // does not (rays with t_min > 0).
    let mut extra_any = 0;
    for i in 0..20_000 {
        let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 14.0 - Vec3::splat(2.0);
        let mut d = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - Vec3::splat(0.5);
        // Axis-parallel directions too: 1/0 clamps to ±1e30.
        if i % 7 == 0 {
            d[i % 3] = 0.0;
        }
        let mut ray = Ray::new(o, d);
        ray.t_max = rng.next_f32() * 20.0;
        // Some rays take the plain test (the fused one needs t_min ≥ 0;
        // an exit in [t_min, 0) would take a child the scalar test,
        // which wants exits ≥ 0, does not).
        if i % 5 == 1 {
            ray.t_min = -f32::MIN_POSITIVE;
        }
        // Some start further on (fused, as shadow rays).
        if i % 5 == 2 {
            ray.t_min = rng.next_f32() * ray.t_max;
        }
        let setup = RaySetup::new(&ray, &wide.root());
        let portable = PortableLanes::new(&setup);
        // The any-hit visit tests fused rays from 0 (see
        // `NodeVisit::visit_any`): the children the closest-hit visit
        // takes for the same ray from 0.
        let from_zero = PortableLanes::new(&RaySetup::new(
            &Ray {
                t_min: if setup.fused { 0.0 } else { ray.t_min },
                ..ray
            },
            &wide.root(),
        ));
        // The visits take t_max widened as traversal gives it.
        let bound = portable.bound(ray.t_max);
        for node in wide.nodes.iter().step_by(17) {
            let mut t_p = [0f32; WIDTH];
            let m_p = portable.test(node, portable.t_min, bound, &mut t_p);
            let mut stack = Stack::new();
            let next_p = portable.visit(node, bound, &mut stack);
            let stack_p = drain(&mut stack);
            pushed += stack_p.len();
            let (next_l, leaves_l) = portable.visit_any(node, bound, &mut stack);
            let stack_l = drain_entries(&mut stack);
            #[cfg(target_arch = "x86_64")]
            if has_avx2() && setup.fused {
                assert_eq!(
                    visit_avx2::<false>(&setup, node, bound),
                    (next_p, 0, stack_p.clone())
                );
                assert_eq!(
                    visit_avx2::<true>(&setup, node, bound),
                    (next_l, leaves_l, stack_l.clone())
                );
                compared += 1;
            }
            // Any hit: the same children, the leaves named by the mask and
            // the others in lane order.
            let is_leaf = |c: u32| c & LEAF != 0;
            let lane = |c: u32| (0..WIDTH).position(|k| node.child[k] == c);
            let next_z = from_zero.visit(node, bound, &mut stack);
            let mut all: Vec<u32> = next_z.into_iter().collect();
            all.extend(drain(&mut stack).iter().map(|e| e.0));
            // Every child the ray's own interval takes, and maybe more.
            let own = next_p.iter().chain(stack_p.iter().map(|e| &e.0));
            assert!(own.clone().all(|c| all.contains(c)));
            extra_any += all.len() - own.count();
            all.sort_by_key(|&c| lane(c));
            let mut inner: Vec<u32> = next_l.into_iter().collect();
            inner.extend(stack_l.iter().map(|e| e.0));
            let all_inner: Vec<u32> = all.iter().copied().filter(|&c| !is_leaf(c)).collect();
            assert_eq!(inner, all_inner);
            let named: Vec<u32> = (0..WIDTH)
                .filter(|&k| leaves_l & (1 << k) != 0)
                .map(|k| node.child[k])
                .collect();
            let apart: Vec<u32> = all.iter().copied().filter(|&c| is_leaf(c)).collect();
            assert_eq!(named, apart);
            // The mask against the scalar slab test of each child (the
            // plain test gives the same; the fused one every child it
            // gives, and a few more), and the children taken: those hit,
            // in the node's order.
            let mut hit = Vec::new();
            for k in 0..WIDTH {
                let taken = m_p & (1 << k) != 0;
                if node.child[k] == EMPTY {
                    assert!(!taken);
                    continue;
                }
                let slab = node
                    .child_bounds(k)
                    .slab(ray.o, ray.inv_d())
                    .is_some_and(|h| h.t_enter.max(ray.t_min) <= h.t_exit.min(ray.t_max));
                if setup.fused {
                    assert!(taken || !slab, "child {k} missed by the fused test");
                    tested[1] += 1;
                    extra += (taken && !slab) as usize;
                } else {
                    assert_eq!(taken, slab, "child {k}");
                    tested[0] += 1;
                }
                if taken {
                    hit.push(k);
                }
            }
            let rank = |k: usize| {
                (0..WIDTH)
                    .position(|j| (node.order[j] >> (3 * setup.octant) & 7) as usize == k)
                    .unwrap()
            };
            hit.sort_by_key(|&k| rank(k));
            let want: Vec<u32> = hit.iter().map(|&k| node.child[k]).collect();
            let mut got: Vec<u32> = next_p.into_iter().collect();
            got.extend(stack_p.iter().map(|e| e.0));
            assert_eq!(got, want);
            for &(c, d) in &stack_p {
                let k = (0..WIDTH).find(|&k| node.child[k] == c).unwrap();
                assert_eq!(d, t_p[k].to_bits());
            }
        }
    }
    assert!(pushed > 1000, "visits with several children hit: {pushed}");
    assert!(tested[0] > 10_000 && tested[1] > 100_000, "{tested:?}");
    assert!(
        extra * 10_000 < tested[1],
        "{extra} of {} widened in",
        tested[1]
    );
    assert!(
        extra_any > 100,
        "any-hit visits from 0 took {extra_any} more"
    );
    if has_avx2() {
        assert!(compared > 0);
    }
}

#[test]
fn whole_traversals_agree_with_and_without_avx2() {
    let b = random_boxes(20_000, 8);
    let bvh = Bvh::build(&b);
    let wide = Bvh8::from_binary(&bvh);
    let leaf_boxes: Vec<Aabb> = bvh.indices.iter().map(|&i| b[i as usize]).collect();
    // Pass 0: the fastest kernels the CPU has (AVX-512VL where present);
    // 1: the AVX2 copies; 2: the portable visit.
    let mut results = [Vec::new(), Vec::new(), Vec::new()];
    for (pass, out) in results.iter_mut().enumerate() {
        AVX2_ONLY.with(|only| only.set(pass == 1));
        let mut rng = Pcg32::new(12, 4);
        let setups: Vec<Ray> = (0..3000)
            .map(|_| {
                let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 14.0
                    - Vec3::splat(2.0);
                let d =
                    Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - Vec3::splat(0.5);
                Ray::new(o, d)
            })
            .collect();
        for mut ray in setups {
            let inv = ray.inv_d();
            let t_of = |p: u32| {
                leaf_boxes[p as usize]
                    .slab(ray.o, inv)
                    .map(|h| h.t_enter.max(0.0))
            };
            let mut c = TraversalCounters::default();
            let mut order = Vec::new();
            let mut leaf = |first: u32, count: u32, t_max: f32| {
                order.push(first);
                (first..first + count)
                    .filter_map(|p| t_of(p).filter(|&t| t < t_max).map(|t| (p, t)))
                    .min_by(|x, y| x.1.total_cmp(&y.1))
            };
            let hit = if pass < 2 {
                wide.closest_leaves(&ray, &mut c, &mut leaf)
            } else {
                let portable = PortableLanes::new(&RaySetup::new(&ray, &wide.root()));
                let leaf = |_: &(), first, count, t_max| leaf(first, count, t_max);
                wide.closest_with(ray.t_max, &mut c, || (), leaf, &portable)
            };
            // Any hit on the segment up to the middle of the closest hit.
            ray.t_max = hit.map_or(5.0, |h| h.1 * 0.5);
            let inv = ray.inv_d();
            let mut any_order = Vec::new();
            let mut any_leaf = |first: u32, count: u32| {
                any_order.push(first);
                (first..first + count).any(|p| {
                    leaf_boxes[p as usize]
                        .slab(ray.o, inv)
                        .is_some_and(|h| h.t_enter.max(0.0) < ray.t_max)
                })
            };
            let mut any_c = TraversalCounters::default();
            let blocked = if pass < 2 {
                wide.any_leaves(&ray, &mut any_c, &mut any_leaf)
            } else {
                let portable = PortableLanes::new(&RaySetup::new(&ray, &wide.root()));
                wide.any_with(
                    ray.t_max,
                    &mut any_c,
                    (|| (), |_: &(), f, c| any_leaf(f, c)),
                    &portable,
                )
            };
            out.push((
                hit.map(|h| (h.0, h.1.to_bits())),
                order,
                c.nodes_visited,
                blocked,
                any_order,
                any_c.nodes_visited,
            ));
        }
    }
    AVX2_ONLY.with(|only| only.set(false));
    assert_eq!(results[0], results[1]);
    assert_eq!(results[0], results[2]);
    // Rays that miss the root's children and rays that do not, both.
    let root_only = results[0].iter().filter(|r| r.2 == 1).count();
    assert!(root_only > 100 && root_only < 2900, "{root_only}");
}

/// The fused slab test takes every child the plain one takes, and keeps
/// every entry the plain one keeps, on rays aimed at the corners and edges
/// of boxes (where the two roundings disagree most), nearly parallel to an
/// axis or exactly so, at scales 1e-3 to 1e6 and up to 1e6 from the
/// origin, with `t_max` at the plain test's own entry distances.
#[test]
fn fused_test_takes_every_child_the_plain_one_takes() {
    let mut rng = Pcg32::new(31, 7);
    let (mut checked, mut widened) = (0usize, 0usize);
    for (scale, offset) in [
        (1e-3f32, 0.0f32),
        (1.0, 0.0),
        (1.0, 1e3),
        (1e3, 1e6),
        (1e6, 1e6),
    ] {
        let boxes: Vec<Aabb> = (0..300)
            .map(|_| {
                let c = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 10.0 * scale
                    + Vec3::splat(offset);
                let e = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * scale;
                Aabb::new(c - e, c + e)
            })
            .collect();
        let wide = Bvh8::from_binary(&Bvh::build(&boxes));
        for i in 0..3000 {
            let target = &boxes[i % boxes.len()];
            // A corner, or a point on an edge.
            let mut pick = |a: usize| {
                if rng.next_f32() < 0.5 {
                    target.min[a]
                } else {
                    target.max[a]
                }
            };
            let mut aim = Vec3::new(pick(0), pick(1), pick(2));
            if i % 2 == 1 {
                let a = i % 3;
                aim[a] = target.min[a] + (target.max[a] - target.min[a]) * rng.next_f32();
            }
            let o = Vec3::splat(offset)
                + (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 30.0
                    - Vec3::splat(10.0))
                    * scale;
            let mut d = aim - o;
            match i % 10 {
                0 => d[i % 3] *= 1e-4,
                5 => d[i % 3] = 0.0,
                _ => {}
            }
            if d == Vec3::ZERO {
                continue;
            }
            let mut ray = Ray::new(o, d);
            for t_max in [f32::INFINITY, 0.0, 1.0] {
                ray.t_max = t_max;
                let setup = RaySetup::new(&ray, &wide.root());
                if !setup.fused {
                    // Parallel to an axis with the origin past 10⁶.
                    assert!(offset >= 1e6 && d.abs().min_element() == 0.0, "{ray:?}");
                    continue;
                }
                let mut plain = RaySetup::new(&ray, &wide.root());
                plain.fused = false;
                let (plain, fused) = (PortableLanes::new(&plain), PortableLanes::new(&setup));
                for node in &wide.nodes {
                    let (mut tp, mut tf) = ([0f32; WIDTH], [0f32; WIDTH]);
                    let mp = plain.test(node, plain.t_min, t_max, &mut tp);
                    let mf = fused.test(node, fused.t_min, fused.bound(t_max), &mut tf);
                    assert_eq!(mp & !mf, 0, "{ray:?}: plain {mp:08b}, fused {mf:08b}");
                    checked += mp.count_ones() as usize;
                    widened += (mf & !mp).count_ones() as usize;
                    // With t_max at each child's plain entry: still taken,
                    // and the entry kept by the pruning bound.
                    for k in (0..WIDTH).filter(|&k| mp & (1 << k) != 0) {
                        let t = tp[k];
                        let (mut up, mut uf) = ([0f32; WIDTH], [0f32; WIDTH]);
                        let mp = plain.test(node, plain.t_min, t, &mut up);
                        let mf = fused.test(node, fused.t_min, fused.bound(t), &mut uf);
                        assert_eq!(mp & !mf, 0, "{ray:?} to {t}");
                        assert!(mp & (1 << k) != 0, "{ray:?}: child {k} at its own entry");
                        assert!(uf[k] <= fused.bound(t), "{ray:?} pruned at {t}");
                    }
                }
            }
        }
    }
    assert!(checked > 10_000, "children taken: {checked}");
    assert!(
        widened < checked / 10,
        "{widened} widened in, {checked} taken"
    );
}
