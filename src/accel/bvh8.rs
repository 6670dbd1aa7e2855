//! An 8-wide BVH collapsed from the binary one: each node holds the boxes of up
//! to eight children in structure-of-arrays form, and one ray is tested
//! against all eight at once. Wide nodes cut the depth of the tree and the
//! number of nodes a ray visits to about a third of the binary tree's (Wald et
//! al., "Getting Rid of Packets", 2008; Dammertz et al., "Shallow Bounding
//! Volume Hierarchies", 2008; Embree's BVH8).
//!
//! The eight slab tests run in one 256-bit AVX register where the CPU has AVX
//! (detected at run time, so the binary runs on any x86-64), and as two 4-lane
//! halves otherwise (glam's `Vec4`: SSE2 on x86-64, scalar elsewhere). Both
//! compute exactly the same numbers, `(plane − o)·(1/d)` without fused
//! multiply-add, so images do not depend on the CPU.
//!
//! Collapse: a binary node's children are expanded, largest surface area
//! first, until the node has eight children or only leaves are left.

use super::bvh::{Bvh, MAX_DEPTH, TraversalCounters};
use crate::math::{Aabb, Ray, Vec3};
use glam::Vec4;
use rayon::prelude::*;
use std::mem::MaybeUninit;
use std::sync::atomic::{AtomicBool, Ordering};

/// Children per node.
pub const WIDTH: usize = 8;
/// A child slot: an interior node, a leaf, or empty.
const EMPTY: u32 = u32::MAX;
/// High bit of `child` marks a leaf; the rest is its first primitive.
const LEAF: u32 = 1 << 31;
/// Each visit pushes at most `WIDTH − 1` children, and no path through the
/// wide tree is longer than one through the binary tree.
const STACK: usize = (WIDTH - 1) * MAX_DEPTH + 1;

/// One coordinate of the eight children's boxes, aligned for a 256-bit load.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
pub struct Lanes8(pub [f32; WIDTH]);

/// A node with up to eight children (256 bytes, four cache lines).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct Bvh8Node {
    /// Rows `min x, min y, min z, max x, max y, max z`, one lane per child:
    /// the near plane of axis `a` for a ray with `d[a] < 0` is row `a + 3`.
    pub planes: [Lanes8; 6],
    /// Interior child: its node index; leaf: `LEAF | first primitive`; `EMPTY`.
    pub child: [u32; WIDTH],
    /// Primitives of a leaf child (at most the binary BVH's largest leaf).
    pub count: [u8; WIDTH],
    /// Bit `k` set: child `k` is a leaf.
    pub leaves: u8,
}

impl Bvh8Node {
    const EMPTY_NODE: Bvh8Node = Bvh8Node {
        planes: [
            Lanes8([f32::INFINITY; WIDTH]),
            Lanes8([f32::INFINITY; WIDTH]),
            Lanes8([f32::INFINITY; WIDTH]),
            Lanes8([f32::NEG_INFINITY; WIDTH]),
            Lanes8([f32::NEG_INFINITY; WIDTH]),
            Lanes8([f32::NEG_INFINITY; WIDTH]),
        ],
        child: [EMPTY; WIDTH],
        count: [0; WIDTH],
        leaves: 0,
    };

    fn set(&mut self, k: usize, b: &Aabb, child: u32, count: u32) {
        for a in 0..3 {
            self.planes[a].0[k] = b.min[a];
            self.planes[a + 3].0[k] = b.max[a];
        }
        self.child[k] = child;
        self.count[k] = u8::try_from(count).expect("leaves hold at most 255 primitives");
        // Leaves hold at least one primitive; interior children none (the
        // top of `from_binary` fills in their index later).
        if count > 0 {
            self.leaves |= 1 << k;
        }
    }

    pub fn child_bounds(&self, k: usize) -> Aabb {
        let p = |row: usize| self.planes[row].0[k];
        Aabb {
            min: Vec3::new(p(0), p(1), p(2)),
            max: Vec3::new(p(3), p(4), p(5)),
        }
    }
}

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

/// An 8-wide BVH over primitives given by leaf position (the owner keeps its
/// primitives in the order of the binary BVH it was collapsed from).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Bvh8 {
    pub nodes: Vec<Bvh8Node>,
    /// The box of everything.
    pub bounds: Option<Aabb>,
}

impl Bvh8 {
    /// Collapses a binary BVH. Leaves keep their primitive ranges, so the
    /// primitives stay in `bvh`'s leaf order.
    ///
    /// The top of the tree is collapsed first, down to subtrees of about
    /// 1/64 of the binary nodes; those are then counted and collapsed in
    /// parallel, each straight into its own range of the final array (the
    /// array is allocated once and every page is written once: on a
    /// 25M-triangle mesh it is over a gigabyte, and first touches of fresh
    /// pages are much of the cost).
    pub fn from_binary(bvh: &Bvh) -> Bvh8 {
        let Some(root) = bvh.nodes.first() else {
            return Bvh8::default();
        };
        let bounds = Some(root.bounds());
        if let Some((first, count)) = leaf_range(bvh, 0) {
            // A single leaf: one node with one child.
            let mut n = Bvh8Node::EMPTY_NODE;
            n.set(0, &root.bounds(), LEAF | first, count);
            return Bvh8 {
                nodes: vec![n],
                bounds,
            };
        }
        let split = (bvh.nodes.len() / 64).max(1 << 12);
        // The top: wide nodes whose binary subtrees are larger than `split`.
        let mut top = vec![Bvh8Node::EMPTY_NODE];
        // Subtrees left for the parallel phase: (binary range, parent, slot).
        let mut tasks: Vec<((usize, usize), usize, usize)> = Vec::new();
        let mut todo = vec![((0usize, bvh.nodes.len()), 0usize)];
        while let Some((range, w)) = todo.pop() {
            let (children, len) = collapse(bvh, range);
            let mut node = Bvh8Node::EMPTY_NODE;
            for (k, &Child { node: c, end, leaf }) in children[..len].iter().enumerate() {
                let child = &bvh.nodes[c];
                if let Some((first, count)) = leaf {
                    node.set(k, &child.bounds(), LEAF | first, count);
                } else if end - c > split {
                    node.set(k, &child.bounds(), top.len() as u32, 0);
                    todo.push(((c, end), top.len()));
                    top.push(Bvh8Node::EMPTY_NODE);
                } else {
                    // The index is set once the subtree has its place.
                    node.set(k, &child.bounds(), EMPTY, 0);
                    tasks.push(((c, end), w, k));
                }
            }
            top[w] = node;
        }
        let counts: Vec<usize> = tasks
            .par_iter()
            .map(|&(range, _, _)| subtree_size(bvh, range))
            .collect();
        // Every slot is written below by exactly one thread, in place: no
        // zeroing pass (64-byte alignment would make the allocator clear the
        // whole array on one thread first).
        let total = top.len() + counts.iter().sum::<usize>();
        let mut nodes: Vec<Bvh8Node> = Vec::with_capacity(total);
        let (head, mut rest) = nodes.spare_capacity_mut()[..total].split_at_mut(top.len());
        let mut base = top.len();
        let mut jobs = Vec::with_capacity(tasks.len());
        for (&(range, w, k), &count) in tasks.iter().zip(&counts) {
            let (slice, tail) = rest.split_at_mut(count);
            top[w].child[k] = base as u32;
            jobs.push((range, slice, base));
            rest = tail;
            base += count;
        }
        for (slot, node) in head.iter_mut().zip(&top) {
            slot.write(*node);
        }
        let written: usize = jobs
            .into_par_iter()
            .map(|(range, out, base)| collapse_into(bvh, range, out, base))
            .sum();
        assert_eq!(top.len() + written, total, "wide node count");
        // SAFETY: slots 0..top.len() were written just above, and each task
        // wrote all slots of its range (`collapse_into` returns how many it
        // wrote, at most its range's length, and the sum is checked).
        unsafe { nodes.set_len(total) };
        Bvh8 { nodes, bounds }
    }

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

    /// Bytes of nodes.
    pub fn bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<Bvh8Node>()
    }

    /// Every leaf as `(first primitive, count)`, node by node (siblings
    /// together, as traversal meets them).
    pub fn leaves(&self) -> impl Iterator<Item = (u32, u32)> + '_ {
        self.nodes.iter().flat_map(|node| {
            (0..WIDTH)
                .filter(|&k| node.leaves & (1 << k) != 0)
                .map(|k| (node.child[k] & !LEAF, node.count[k] as u32))
        })
    }

    /// Closest hit, nearer children first, pruning by the closest `t`; as
    /// [`Bvh::closest`].
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

    /// Structural checks as [`Bvh::validate`]: children inside parents, every
    /// primitive (by leaf position, `0..n`) in exactly one leaf inside its box.
    pub fn validate(&self, bounds: &[Aabb]) -> Result<(), String> {
        let mut seen = vec![false; bounds.len()];
        let contains = |outer: &Aabb, inner: &Aabb| {
            inner.min.cmpge(outer.min).all() && inner.max.cmple(outer.max).all()
        };
        let mut stack = if self.nodes.is_empty() {
            vec![]
        } else {
            vec![(0usize, None::<Aabb>)]
        };
        while let Some((i, parent)) = stack.pop() {
            let node = self.nodes.get(i).ok_or(format!("node {i} out of range"))?;
            for k in 0..WIDTH {
                let child = node.child[k];
                if child == EMPTY {
                    continue;
                }
                if (child & LEAF != 0) != (node.leaves & (1 << k) != 0) {
                    return Err(format!("leaf mask of node {i} wrong for child {k}"));
                }
                let b = node.child_bounds(k);
                if let Some(p) = parent
                    && !contains(&p, &b)
                {
                    return Err(format!("child {k} of node {i} outside its parent"));
                }
                if child & LEAF != 0 {
                    let first = (child & !LEAF) as usize;
                    let end = first + node.count[k] as usize;
                    let (Some(leaf_bounds), Some(leaf_seen)) =
                        (bounds.get(first..end), seen.get_mut(first..end))
                    else {
                        return Err(format!("leaf primitives {first}..{end} out of range"));
                    };
                    for (j, (pb, was)) in leaf_bounds.iter().zip(leaf_seen).enumerate() {
                        let p = first + j;
                        if std::mem::replace(was, true) {
                            return Err(format!("primitive {p} in two leaves"));
                        }
                        if !contains(&b, pb) {
                            return Err(format!("primitive {p} outside its leaf"));
                        }
                    }
                } else {
                    if child as usize <= i {
                        return Err(format!("child {child} of node {i} precedes it"));
                    }
                    stack.push((child as usize, Some(b)));
                }
            }
        }
        if seen.iter().any(|s| !s) {
            return Err("some primitives are in no leaf".into());
        }
        Ok(())
    }
}

/// Up to eight descendants of binary node `range.0` that together cover it:
/// its children, with the interior one of largest surface area replaced by
/// its own children while there is room (subtrees small enough to become
/// leaves are not expanded).
fn collapse(bvh: &Bvh, range: (usize, usize)) -> ([Child; WIDTH], usize) {
    let (b, end) = range;
    let right = bvh.nodes[b].offset as usize;
    // With the surface area of interior children, −1 for leaves (never
    // expanded).
    let child = |i: usize, end: usize| {
        let leaf = leaf_range(bvh, i);
        let area = if leaf.is_some() {
            -1.0
        } else {
            let n = &bvh.nodes[i];
            let e = (n.bounds().max - n.bounds().min).max(Vec3::ZERO);
            e.x * e.y + e.y * e.z + e.z * e.x
        };
        (Child { node: i, end, leaf }, area)
    };
    let mut children = [Child {
        node: 0,
        end: 0,
        leaf: None,
    }; WIDTH];
    let mut areas = [0f32; WIDTH];
    (children[0], areas[0]) = child(b + 1, right);
    (children[1], areas[1]) = child(right, end);
    let mut len = 2;
    while len < WIDTH {
        // The largest interior child (first of equals).
        let mut k = 0;
        for j in 1..len {
            if areas[j] > areas[k] {
                k = j;
            }
        }
        if areas[k] < 0.0 {
            break;
        }
        let Child {
            node: c,
            end: c_end,
            ..
        } = children[k];
        let c_right = bvh.nodes[c].offset as usize;
        (children[k], areas[k]) = child(c + 1, c_right);
        (children[len], areas[len]) = child(c_right, c_end);
        len += 1;
    }
    (children, len)
}

/// A child of a wide node under construction: a binary node, the end of its
/// subtree's node range, and its primitives if it becomes a leaf.
#[derive(Clone, Copy)]
struct Child {
    node: usize,
    end: usize,
    leaf: Option<(u32, u32)>,
}

/// Binary subtrees of at most this many primitives become one leaf of the
/// wide tree: its triangles are tested in one batch of SIMD lanes, which
/// costs less than visiting a node for them.
const MERGE: u32 = 4;

/// The primitives `(first, count)` of binary node `i` if it becomes a leaf of
/// the wide tree: a leaf, or a subtree of at most [`MERGE`] primitives (a
/// subtree's primitives are contiguous in leaf order).
#[inline]
fn leaf_range(bvh: &Bvh, i: usize) -> Option<(u32, u32)> {
    let n = &bvh.nodes[i];
    if n.count > 0 {
        return Some((n.offset, n.count));
    }
    // Depth-first, leftmost leaf first; every split leaves at least one
    // primitive on each side, so a small subtree is also shallow.
    let mut stack = [(0usize, 0u32); MERGE as usize + 1];
    let (mut len, mut first, mut count) = (1, None, 0);
    stack[0] = (i, 0);
    while len > 0 {
        len -= 1;
        let (j, depth) = stack[len];
        let n = &bvh.nodes[j];
        if n.count > 0 {
            first.get_or_insert(n.offset);
            count += n.count;
            if count > MERGE {
                return None;
            }
        } else {
            if depth + 1 >= MERGE || len + 2 > stack.len() {
                return None;
            }
            stack[len] = (n.offset as usize, depth + 1);
            stack[len + 1] = (j + 1, depth + 1);
            len += 2;
        }
    }
    first.map(|f| (f, count))
}

/// The number of wide nodes [`collapse_into`] makes of a binary subtree.
fn subtree_size(bvh: &Bvh, range: (usize, usize)) -> usize {
    let mut size = 0;
    let mut todo = vec![range];
    while let Some(range) = todo.pop() {
        size += 1;
        let (children, len) = collapse(bvh, range);
        todo.extend(
            children[..len]
                .iter()
                .filter(|c| c.leaf.is_none())
                .map(|c| (c.node, c.end)),
        );
    }
    size
}

/// Collapses the binary subtree `range` (an interior node) into `out`, whose
/// first slot is node `base` of the whole array and which holds
/// [`subtree_size`] slots; returns the number of slots written, each once,
/// from the first on.
fn collapse_into(
    bvh: &Bvh,
    range: (usize, usize),
    out: &mut [MaybeUninit<Bvh8Node>],
    base: usize,
) -> usize {
    let mut next = 1;
    let mut todo = vec![(range, 0usize)];
    while let Some((range, w)) = todo.pop() {
        let (children, len) = collapse(bvh, range);
        let mut node = Bvh8Node::EMPTY_NODE;
        for (k, &Child { node: c, end, leaf }) in children[..len].iter().enumerate() {
            let child = &bvh.nodes[c];
            if let Some((first, count)) = leaf {
                node.set(k, &child.bounds(), LEAF | first, count);
            } else {
                node.set(k, &child.bounds(), (base + next) as u32, 0);
                todo.push(((c, end), next));
                next += 1;
            }
        }
        // Slot `w` was handed out once, from `next`: each is written once.
        out[w].write(node);
    }
    next
}

#[cfg(test)]
mod tests {
    use super::*;
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
                        .all(|l| l.1 >= 1 && l.1 as usize <= super::super::bvh::MAX_LEAF)
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
}
