//! Traversal of a [`Bvh8`]: the eight slab tests of a node at once (AVX
//! where the CPU has it, two 4-lane halves otherwise, the same numbers
//! either way), children taken nearest first from a fixed stack.

use super::{Bvh8, Bvh8Node, LEAF, STACK, WIDTH};
use crate::accel::bvh::TraversalCounters;
use crate::math::{Ray, Vec3};
use glam::Vec4;
use std::mem::MaybeUninit;
use std::sync::atomic::{AtomicBool, Ordering};

/// What every lane implementation needs of a ray: origin, finite inverse
/// direction, the rows of the near and far planes, and `t_min`.
struct RaySetup {
    o: Vec3,
    inv: Vec3,
    near: [usize; 3],
    far: [usize; 3],
    t_min: f32,
}

impl RaySetup {
    #[inline(always)]
    fn new(ray: &Ray) -> Self {
        // Finite, so (plane − o)·inv is never 0·∞ = NaN (see `Bvh`).
        let inv = ray.d.recip().clamp(Vec3::splat(-1e30), Vec3::splat(1e30));
        let negative = [inv.x < 0.0, inv.y < 0.0, inv.z < 0.0];
        RaySetup {
            o: ray.o,
            inv,
            near: std::array::from_fn(|a| a + 3 * negative[a] as usize),
            far: std::array::from_fn(|a| a + 3 * !negative[a] as usize),
            t_min: ray.t_min,
        }
    }
}

/// The slab tests of a ray against the eight boxes of a node: fills the entry
/// distances and returns the mask of children hit within `[t_min, t_max]`.
trait NodeTest {
    fn test(&self, n: &Bvh8Node, t_max: f32, t_enter: &mut [f32; WIDTH]) -> u32;
}

/// The eight slab tests as two 4-lane halves.
struct PortableLanes {
    o: [Vec4; 3],
    inv: [Vec4; 3],
    near: [usize; 3],
    far: [usize; 3],
    t_min: Vec4,
}

impl PortableLanes {
    #[inline(always)]
    fn new(r: &RaySetup) -> Self {
        PortableLanes {
            o: [0, 1, 2].map(|a| Vec4::splat(r.o[a])),
            inv: [0, 1, 2].map(|a| Vec4::splat(r.inv[a])),
            near: r.near,
            far: r.far,
            t_min: Vec4::splat(r.t_min),
        }
    }
}

impl NodeTest for PortableLanes {
    #[inline(always)]
    fn test(&self, n: &Bvh8Node, t_max: f32, t_enter: &mut [f32; WIDTH]) -> u32 {
        let t_max = Vec4::splat(t_max);
        let mut mask = 0;
        for half in 0..2 {
            let lanes = |row: usize| Vec4::from_slice(&n.planes[row].0[4 * half..4 * half + 4]);
            let t = |a: usize, row: usize| (lanes(row) - self.o[a]) * self.inv[a];
            let (nx, ny, nz) = (t(0, self.near[0]), t(1, self.near[1]), t(2, self.near[2]));
            let (fx, fy, fz) = (t(0, self.far[0]), t(1, self.far[1]), t(2, self.far[2]));
            let enter = nx.max(ny).max(nz.max(self.t_min));
            let exit = fx.min(fy).min(fz.min(t_max));
            enter.write_to_slice(&mut t_enter[4 * half..4 * half + 4]);
            mask |= enter.cmple(exit).bitmask() << (4 * half);
        }
        mask
    }
}

#[cfg(target_arch = "x86_64")]
mod avx {
    use super::{Bvh8Node, NodeTest, RaySetup, WIDTH};
    use std::arch::x86_64::*;

    /// The eight slab tests in one 256-bit register each. Only made where the
    /// CPU has AVX.
    pub(super) struct AvxLanes {
        o: [__m256; 3],
        inv: [__m256; 3],
        near: [usize; 3],
        far: [usize; 3],
        t_min: __m256,
    }

    impl AvxLanes {
        /// The caller makes sure that the CPU has AVX.
        #[target_feature(enable = "avx")]
        #[inline]
        pub(super) fn new(r: &RaySetup) -> Self {
            AvxLanes {
                o: [0, 1, 2].map(|a| _mm256_set1_ps(r.o[a])),
                inv: [0, 1, 2].map(|a| _mm256_set1_ps(r.inv[a])),
                near: r.near,
                far: r.far,
                t_min: _mm256_set1_ps(r.t_min),
            }
        }
    }

    impl NodeTest for AvxLanes {
        /// As [`super::PortableLanes`]'s, operation for operation (max and
        /// min return their second operand for NaN in both). Inlined into the
        /// callers compiled with AVX enabled.
        #[inline(always)]
        fn test(&self, n: &Bvh8Node, t_max: f32, t_enter: &mut [f32; WIDTH]) -> u32 {
            // SAFETY (all blocks): an `AvxLanes` exists only where the CPU has
            // AVX; each row is 8 floats aligned to 32 bytes (`Lanes8`), and
            // `t_enter` holds 8 floats.
            let lanes = |row: usize| unsafe { _mm256_load_ps(n.planes[row].0.as_ptr()) };
            let t = |a: usize, row: usize| unsafe {
                _mm256_mul_ps(_mm256_sub_ps(lanes(row), self.o[a]), self.inv[a])
            };
            let (nx, ny, nz) = (t(0, self.near[0]), t(1, self.near[1]), t(2, self.near[2]));
            let (fx, fy, fz) = (t(0, self.far[0]), t(1, self.far[1]), t(2, self.far[2]));
            unsafe {
                let enter = _mm256_max_ps(_mm256_max_ps(nx, ny), _mm256_max_ps(nz, self.t_min));
                let exit = _mm256_min_ps(
                    _mm256_min_ps(fx, fy),
                    _mm256_min_ps(fz, _mm256_set1_ps(t_max)),
                );
                _mm256_storeu_ps(t_enter.as_mut_ptr(), enter);
                _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(enter, exit)) as u32
            }
        }
    }
}

/// Set by [`force_portable`]: traverse with the portable lanes even where the
/// CPU has AVX.
static FORCE_PORTABLE: AtomicBool = AtomicBool::new(false);

/// Makes every traversal in the process use the portable (SSE) node test,
/// or, with `false`, the fastest the CPU has again. The two give
/// bit-identical results; this exists so that tests (and users chasing a
/// suspected kernel bug) can run both on one machine.
pub fn force_portable(portable: bool) {
    FORCE_PORTABLE.store(portable, Ordering::Relaxed);
}

/// Whether the 256-bit lane test can run here (checked once, then cached by
/// the standard library) and is not switched off by [`force_portable`].
#[inline(always)]
fn has_avx() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        !FORCE_PORTABLE.load(Ordering::Relaxed) && std::arch::is_x86_feature_detected!("avx")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// A traversal stack that is not cleared for every ray.
struct Stack<T: Copy> {
    items: [MaybeUninit<T>; STACK],
    len: usize,
}

impl<T: Copy> Stack<T> {
    #[inline(always)]
    fn new() -> Self {
        Stack {
            items: [const { MaybeUninit::uninit() }; STACK],
            len: 0,
        }
    }

    #[inline(always)]
    fn push(&mut self, item: T) {
        // Indexing checks the bound; `STACK` covers the deepest tree.
        self.items[self.len].write(item);
        self.len += 1;
    }

    #[inline(always)]
    fn pop(&mut self) -> Option<T> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: items below `len` were written by `push`.
        Some(unsafe { self.items[self.len].assume_init() })
    }
}

impl Bvh8 {
    /// Asks the CPU to start loading node `index` (a hint; no effect where
    /// there is no prefetch instruction).
    #[inline(always)]
    fn prefetch(&self, index: u32) {
        #[cfg(target_arch = "x86_64")]
        if let Some(node) = self.nodes.get(index as usize) {
            use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
            let p = (node as *const Bvh8Node).cast::<i8>();
            // SAFETY: prefetching is a hint that never faults; the addresses
            // lie inside the node anyway. SSE is part of x86-64.
            unsafe {
                for line in 0..4 {
                    _mm_prefetch::<_MM_HINT_T0>(p.add(64 * line));
                }
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = index;
    }

    /// Closest hit, nearer children first, pruning by the closest `t`; as
    /// [`Bvh::closest`](crate::accel::Bvh::closest).
    #[inline]
    pub fn closest(
        &self,
        ray: &Ray,
        counters: &mut TraversalCounters,
        mut test: impl FnMut(u32, f32) -> Option<f32>,
    ) -> Option<(u32, f32)> {
        self.closest_leaves(
            ray,
            counters,
            #[inline(always)]
            |leaves, mut t_max| {
                let mut best = None;
                for &(first, count) in leaves {
                    for prim in first..first + count {
                        if let Some(t) = test(prim, t_max) {
                            t_max = t;
                            best = Some((prim, t));
                        }
                    }
                }
                best
            },
        )
    }

    /// Closest hit, with the leaves of a node whose boxes the ray meets
    /// before the closest hit so far handed to `test` together, as `(first
    /// primitive, count)` in child order (for tests that take several
    /// primitives at once, with SIMD, from data laid out per leaf or per
    /// primitive): `test(leaves, t_max)` returns the closest hit among
    /// their primitives before `t_max`, the earliest of equals.
    #[inline]
    pub fn closest_leaves(
        &self,
        ray: &Ray,
        counters: &mut TraversalCounters,
        test: impl FnMut(&[(u32, u32)], f32) -> Option<(u32, f32)>,
    ) -> Option<(u32, f32)> {
        if self.nodes.is_empty() {
            return None;
        }
        let setup = RaySetup::new(ray);
        #[cfg(target_arch = "x86_64")]
        if has_avx() {
            // SAFETY: the CPU has AVX.
            return unsafe { self.closest_avx(&setup, ray.t_max, counters, test) };
        }
        self.closest_with(ray.t_max, counters, test, &PortableLanes::new(&setup))
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    fn closest_avx(
        &self,
        setup: &RaySetup,
        t_max: f32,
        counters: &mut TraversalCounters,
        test: impl FnMut(&[(u32, u32)], f32) -> Option<(u32, f32)>,
    ) -> Option<(u32, f32)> {
        self.closest_with(t_max, counters, test, &avx::AvxLanes::new(setup))
    }

    #[inline(always)]
    fn closest_with(
        &self,
        mut t_max: f32,
        counters: &mut TraversalCounters,
        mut test: impl FnMut(&[(u32, u32)], f32) -> Option<(u32, f32)>,
        lanes: &impl NodeTest,
    ) -> Option<(u32, f32)> {
        let mut best = None;
        // Children not visited yet, with their entry distances.
        let mut stack = Stack::<(u32, f32)>::new();
        let mut index = 0u32;
        let (mut visited, mut tests) = (0u64, 0u64);
        let mut t = [0f32; WIDTH];
        'visit: loop {
            let node = &self.nodes[index as usize];
            visited += 1;
            let hit = lanes.test(node, t_max, &mut t);
            // Interior children hit, sorted by descending distance: the
            // nearest is visited next without going through the stack, the
            // others are pushed farthest first. Their nodes are fetched
            // while the leaf children are tested, each pruning by the
            // closest hit so far.
            let mut inner = [(0u32, 0f32); WIDTH];
            let mut n_inner = 0;
            let mut bits = hit & !node.leaves as u32;
            while bits != 0 {
                let k = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let child = node.child[k];
                self.prefetch(child);
                let mut j = n_inner;
                while j > 0 && inner[j - 1].1 < t[k] {
                    inner[j] = inner[j - 1];
                    j -= 1;
                }
                inner[j] = (child, t[k]);
                n_inner += 1;
            }
            let mut bits = hit & node.leaves as u32;
            let mut leaves = [(0u32, 0u32); WIDTH];
            let mut n = 0;
            while bits != 0 {
                let k = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                if t[k] > t_max {
                    continue;
                }
                let count = node.count[k] as u32;
                tests += count as u64;
                leaves[n] = (node.child[k] & !LEAF, count);
                n += 1;
            }
            if n > 0
                && let Some(h) = test(&leaves[..n], t_max)
            {
                (t_max, best) = (h.1, Some(h));
            }
            if n_inner > 0 {
                for &item in &inner[..n_inner - 1] {
                    stack.push(item);
                }
                let (c, tc) = inner[n_inner - 1];
                if tc <= t_max {
                    index = c;
                    continue;
                }
            }
            // Pop, skipping nodes now beyond the closest hit.
            while let Some((c, tc)) = stack.pop() {
                if tc <= t_max {
                    index = c;
                    continue 'visit;
                }
            }
            break;
        }
        counters.nodes_visited += visited;
        counters.primitive_tests += tests;
        best
    }

    /// Any hit: stops at the first primitive for which `test(prim)` is true.
    #[inline]
    pub fn any(
        &self,
        ray: &Ray,
        counters: &mut TraversalCounters,
        mut test: impl FnMut(u32) -> bool,
    ) -> bool {
        self.any_leaves(
            ray,
            counters,
            #[inline(always)]
            |leaves| {
                leaves
                    .iter()
                    .any(|&(first, count)| (first..first + count).any(&mut test))
            },
        )
    }

    /// Any hit, with a node's leaves handed to `test` together as by
    /// [`Bvh8::closest_leaves`] (`test(leaves)`); stops when `test` returns
    /// true.
    #[inline]
    pub fn any_leaves(
        &self,
        ray: &Ray,
        counters: &mut TraversalCounters,
        test: impl FnMut(&[(u32, u32)]) -> bool,
    ) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let setup = RaySetup::new(ray);
        #[cfg(target_arch = "x86_64")]
        if has_avx() {
            // SAFETY: the CPU has AVX.
            return unsafe { self.any_avx(&setup, ray.t_max, counters, test) };
        }
        self.any_with(ray.t_max, counters, test, &PortableLanes::new(&setup))
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    fn any_avx(
        &self,
        setup: &RaySetup,
        t_max: f32,
        counters: &mut TraversalCounters,
        test: impl FnMut(&[(u32, u32)]) -> bool,
    ) -> bool {
        self.any_with(t_max, counters, test, &avx::AvxLanes::new(setup))
    }

    #[inline(always)]
    fn any_with(
        &self,
        t_max: f32,
        counters: &mut TraversalCounters,
        mut test: impl FnMut(&[(u32, u32)]) -> bool,
        lanes: &impl NodeTest,
    ) -> bool {
        let mut stack = Stack::<u32>::new();
        let mut index = 0u32;
        let (mut visited, mut tests) = (0u64, 0u64);
        let mut found = false;
        let mut t = [0f32; WIDTH];
        loop {
            let node = &self.nodes[index as usize];
            visited += 1;
            let hit = lanes.test(node, t_max, &mut t);
            // Interior children hit: the last is visited next without going
            // through the stack, the others are pushed; their nodes are
            // fetched while the leaf children are tested.
            let mut next = None;
            let mut bits = hit & !node.leaves as u32;
            while bits != 0 {
                let k = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let child = node.child[k];
                self.prefetch(child);
                if let Some(previous) = next {
                    stack.push(previous);
                }
                next = Some(child);
            }
            let mut bits = hit & node.leaves as u32;
            let mut leaves = [(0u32, 0u32); WIDTH];
            let mut n = 0;
            while bits != 0 {
                let k = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let count = node.count[k] as u32;
                tests += count as u64;
                leaves[n] = (node.child[k] & !LEAF, count);
                n += 1;
            }
            if n > 0 && test(&leaves[..n]) {
                found = true;
                break;
            }
            index = match next.or_else(|| stack.pop()) {
                Some(c) => c,
                None => break,
            };
        }
        counters.nodes_visited += visited;
        counters.primitive_tests += tests;
        found
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::bvh::Bvh;
    use crate::accel::bvh8::EMPTY;
    use crate::math::Aabb;
    use crate::render::Pcg32;

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
        for _ in 0..2000 {
            let o =
                Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 14.0 - Vec3::splat(2.0);
            let d = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - Vec3::splat(0.5);
            let ray = Ray::new(o, d);
            let inv = ray.inv_d();
            let t_of = |p: u32| {
                leaf_boxes[p as usize]
                    .slab(ray.o, inv)
                    .map(|h| h.t_enter.max(0.0))
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
            // The path taken where the CPU lacks AVX.
            let portable = PortableLanes::new(&RaySetup::new(&ray));
            let nearest = |leaves: &[(u32, u32)], t_max: f32| {
                assert!(!leaves.is_empty() && leaves.len() <= WIDTH);
                assert!(
                    leaves
                        .iter()
                        .all(|l| l.1 >= 1 && l.1 as usize <= crate::accel::bvh::MAX_LEAF)
                );
                leaves
                    .iter()
                    .flat_map(|&(first, count)| first..first + count)
                    .filter_map(|p| t_of(p).filter(|&t| t < t_max).map(|t| (p, t)))
                    .min_by(|x, y| x.1.total_cmp(&y.1))
            };
            let got = wide.closest_with(ray.t_max, &mut counters, nearest, &portable);
            assert_eq!(got.map(|g| g.1), brute.map(|b| b.1));
            let any = |leaves: &[(u32, u32)]| {
                leaves
                    .iter()
                    .flat_map(|&(first, count)| first..first + count)
                    .any(|p| t_of(p).is_some())
            };
            assert_eq!(
                wide.any_with(ray.t_max, &mut counters, any, &portable),
                brute.is_some()
            );
            // And the per-leaf entry points.
            let got = wide.closest_leaves(&ray, &mut counters, nearest);
            assert_eq!(got.map(|g| g.1), brute.map(|b| b.1));
            assert_eq!(wide.any_leaves(&ray, &mut counters, any), brute.is_some());
        }
    }

    #[test]
    fn avx_and_portable_lanes_agree_bit_for_bit() {
        let b = random_boxes(5000, 4);
        let bvh = Bvh::build(&b);
        let wide = Bvh8::from_binary(&bvh);
        let mut rng = Pcg32::new(5, 3);
        let mut compared = 0;
        for i in 0..20_000 {
            let o =
                Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 14.0 - Vec3::splat(2.0);
            let mut d =
                Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - Vec3::splat(0.5);
            // Axis-parallel directions too: 1/0 clamps to ±1e30.
            if i % 7 == 0 {
                d[i % 3] = 0.0;
            }
            let mut ray = Ray::new(o, d);
            ray.t_max = rng.next_f32() * 20.0;
            let setup = RaySetup::new(&ray);
            let portable = PortableLanes::new(&setup);
            for node in wide.nodes.iter().step_by(17) {
                let mut t_p = [0f32; WIDTH];
                let m_p = portable.test(node, ray.t_max, &mut t_p);
                #[cfg(target_arch = "x86_64")]
                if has_avx() {
                    let mut t_a = [0f32; WIDTH];
                    // SAFETY: the CPU has AVX.
                    let m_a = unsafe { avx::AvxLanes::new(&setup) }.test(node, ray.t_max, &mut t_a);
                    assert_eq!(m_a, m_p);
                    for k in 0..WIDTH {
                        if m_p & (1 << k) != 0 {
                            assert_eq!(t_a[k].to_bits(), t_p[k].to_bits());
                        }
                    }
                    compared += 1;
                }
                // The mask against the scalar slab test of each child.
                for k in 0..WIDTH {
                    if node.child[k] == EMPTY {
                        assert_eq!(m_p & (1 << k), 0);
                        continue;
                    }
                    let hit = node
                        .child_bounds(k)
                        .slab(ray.o, ray.inv_d())
                        .is_some_and(|h| h.t_enter.max(ray.t_min) <= h.t_exit.min(ray.t_max));
                    assert_eq!(m_p & (1 << k) != 0, hit, "child {k}");
                }
            }
        }
        if has_avx() {
            assert!(compared > 0);
        }
    }
}
