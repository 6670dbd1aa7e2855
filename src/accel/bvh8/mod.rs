//! An 8-wide BVH collapsed from the binary one: each node holds the boxes of up
//! to eight children in structure-of-arrays form, and one ray is tested
//! against all eight at once. Wide nodes cut the depth of the tree and the
//! number of nodes a ray visits to about a third of the binary tree's (Wald et
//! al., "Getting Rid of Packets", 2008; Dammertz et al., "Shallow Bounding
//! Volume Hierarchies", 2008; Embree's BVH8).
//!
//! The eight slab tests run in one 256-bit register where the CPU has AVX2
//! and FMA (detected at run time, so the binary runs on any x86-64), and as
//! two 4-lane halves otherwise (glam's `Vec4`: SSE2 on x86-64, scalar
//! elsewhere). Both compute exactly the same numbers (a fused multiply-add
//! per plane, with constants that make the test take every box the plain
//! `(plane − o)·(1/d)` takes, see `traverse`; `f32::mul_add` where the
//! portable path needs it) and visit children in the same order, so images
//! do not depend on the CPU.
//!
//! Collapse: a binary node's children are expanded, largest surface area
//! first, until the node has eight children or only leaves are left; a
//! subtree of at most eight leaves is expanded into all of them at once
//! where they fit, and otherwise kept whole as one node of leaves (see
//! `collapse`). Each node then gets its children's visiting order for each
//! octant of ray directions, so that traversal orders them without sorting.

mod collapse;
mod packet;
mod traverse;

pub use packet::PACKET;
pub use traverse::force_portable;

use super::bvh::{MAX_DEPTH, MAX_LEAF};
use crate::math::{Aabb, Vec3};

/// Children per node.
pub const WIDTH: usize = 8;
/// A child slot: an interior node, a leaf, or empty.
const EMPTY: u32 = u32::MAX;
/// High bit of `child` marks a leaf (or, with every other bit set, an empty
/// slot); the next three hold its primitive count less one, the rest its
/// first primitive.
const LEAF: u32 = 1 << 31;
/// Bits of a leaf's first primitive: a tree holds fewer primitives than this.
const LEAF_FIRST_BITS: u32 = 28;
/// The limit on a tree's primitives (2^28) that the leaf words set.
pub const MAX_PRIMITIVES: usize = 1 << LEAF_FIRST_BITS;
/// Each visit pushes at most `WIDTH − 1` children, and no path through the
/// wide tree is longer than one through the binary tree; a visit writes all
/// `WIDTH` lanes at the top, so the array has `WIDTH` spare slots.
const STACK: usize = (WIDTH - 1) * MAX_DEPTH + 1 + WIDTH;

/// One coordinate of the eight children's boxes, aligned for a 256-bit load.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
pub struct Lanes8(pub [f32; WIDTH]);

/// A node with up to eight children (256 bytes, four cache lines), laid out
/// as Fuetterling et al. ("Accelerated Single Ray Tracing for Wide Vector
/// Units", HPG 2017) and tinybvh's `BVH8_CPU` do: the boxes as rows, the
/// children, and for each of the eight octants of ray directions the order
/// in which to visit them.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct Bvh8Node {
    /// Rows `min x, min y, min z, max x, max y, max z`, one lane per child:
    /// the near plane of axis `a` for a ray with `d[a] < 0` is row `a + 3`.
    pub planes: [Lanes8; 6],
    /// Interior child: its node index (below `LEAF`); leaf: `LEAF | (count
    /// − 1) << 28 | first primitive`, at most 8 primitives (`MAX_LEAF`);
    /// `EMPTY`.
    pub child: [u32; WIDTH],
    /// Bits `3q .. 3q + 3` of lane `j`: the child visited `j`-th by rays of
    /// octant `q` (bit `a` of `q` set where `d[a] ≥ 0`), nearest first by the
    /// distance of its near corner along the octant's diagonal; empty slots
    /// last.
    pub order: [u32; WIDTH],
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
        order: [0; WIDTH],
    };

    /// Sets child `k`: an interior node (`count` 0; its index may be filled
    /// in later) or the leaf of primitives `first .. first + count`.
    fn set(&mut self, k: usize, b: &Aabb, child: u32, count: u32) {
        for a in 0..3 {
            self.planes[a].0[k] = b.min[a];
            self.planes[a + 3].0[k] = b.max[a];
        }
        self.child[k] = if count > 0 {
            // Then the word is never EMPTY, which would take count 8 and
            // first 2^28 − 1.
            assert!(
                count as usize <= MAX_LEAF && child + count < 1 << LEAF_FIRST_BITS,
                "leaf of {count} primitives from {child}"
            );
            LEAF | (count - 1) << LEAF_FIRST_BITS | child
        } else {
            child
        };
    }

    /// Fills in [`Bvh8Node::order`] from the boxes (after every `set`).
    fn order_children(&mut self) {
        for q in 0..8 {
            let diagonal = Vec3::new(
                if q & 1 != 0 { 1.0 } else { -1.0 },
                if q & 2 != 0 { 1.0 } else { -1.0 },
                if q & 4 != 0 { 1.0 } else { -1.0 },
            );
            let distance: [f32; WIDTH] = std::array::from_fn(|k| {
                if self.child[k] == EMPTY {
                    return f32::INFINITY;
                }
                let b = self.child_bounds(k);
                let near = Vec3::select(diagonal.cmpgt(Vec3::ZERO), b.min, b.max);
                diagonal.dot(near)
            });
            let mut lanes: [usize; WIDTH] = std::array::from_fn(|k| k);
            lanes.sort_by(|&i, &j| distance[i].total_cmp(&distance[j]).then(i.cmp(&j)));
            for (j, &k) in lanes.iter().enumerate() {
                self.order[j] &= !(7 << (3 * q));
                self.order[j] |= (k as u32) << (3 * q);
            }
        }
    }

    /// Whether child `k` is a leaf.
    #[inline(always)]
    pub fn is_leaf(&self, k: usize) -> bool {
        self.child[k] & LEAF != 0 && self.child[k] != EMPTY
    }

    /// The primitives `(first, count)` of a leaf child's entry.
    #[inline(always)]
    fn leaf_range(child: u32) -> (u32, u32) {
        let mask = (1 << LEAF_FIRST_BITS) - 1;
        (child & mask, ((child & !LEAF) >> LEAF_FIRST_BITS) + 1)
    }

    pub fn child_bounds(&self, k: usize) -> Aabb {
        let p = |row: usize| self.planes[row].0[k];
        Aabb {
            min: Vec3::new(p(0), p(1), p(2)),
            max: Vec3::new(p(3), p(4), p(5)),
        }
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
    /// Bytes of nodes.
    pub fn bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<Bvh8Node>()
    }

    /// Rewrites every leaf's first primitive as `f(first, count)` (which must
    /// stay below [`MAX_PRIMITIVES`]); the count is kept.
    pub fn map_leaves(&mut self, mut f: impl FnMut(u32, u32) -> u32) {
        for node in &mut self.nodes {
            for k in 0..WIDTH {
                if node.is_leaf(k) {
                    let (first, count) = Bvh8Node::leaf_range(node.child[k]);
                    let new = f(first, count);
                    assert!(new < 1 << LEAF_FIRST_BITS, "leaf start {new}");
                    node.child[k] = LEAF | (count - 1) << LEAF_FIRST_BITS | new;
                }
            }
        }
    }

    /// Every leaf as `(first primitive, count)`, node by node (siblings
    /// together, as traversal meets them).
    pub fn leaves(&self) -> impl Iterator<Item = (u32, u32)> + '_ {
        self.nodes.iter().flat_map(|node| {
            (0..WIDTH)
                .filter(|&k| node.is_leaf(k))
                .map(|k| Bvh8Node::leaf_range(node.child[k]))
        })
    }

    /// Structural checks as [`Bvh::validate`](crate::accel::Bvh::validate): children inside parents, every
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
            for q in 0..8 {
                let lanes: Vec<usize> = node
                    .order
                    .iter()
                    .map(|&o| (o >> (3 * q) & 7) as usize)
                    .collect();
                let mut sorted = lanes.clone();
                sorted.sort();
                let empties_last = lanes
                    .iter()
                    .skip_while(|&&k| node.child[k] != EMPTY)
                    .all(|&k| node.child[k] == EMPTY);
                if sorted != (0..WIDTH).collect::<Vec<_>>() || !empties_last {
                    return Err(format!("order of node {i} for octant {q} is {lanes:?}"));
                }
            }
            for k in 0..WIDTH {
                let child = node.child[k];
                if child == EMPTY {
                    continue;
                }
                let b = node.child_bounds(k);
                if let Some(p) = parent
                    && !contains(&p, &b)
                {
                    return Err(format!("child {k} of node {i} outside its parent"));
                }
                if node.is_leaf(k) {
                    let (first, count) = Bvh8Node::leaf_range(child);
                    let (first, end) = (first as usize, (first + count) as usize);
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
