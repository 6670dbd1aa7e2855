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

mod collapse;
mod traverse;

pub use traverse::force_portable;

use super::bvh::MAX_DEPTH;
use crate::math::{Aabb, Vec3};

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

    /// Every leaf as `(first primitive, count)`, node by node (siblings
    /// together, as traversal meets them).
    pub fn leaves(&self) -> impl Iterator<Item = (u32, u32)> + '_ {
        self.nodes.iter().flat_map(|node| {
            (0..WIDTH)
                .filter(|&k| node.leaves & (1 << k) != 0)
                .map(|k| (node.child[k] & !LEAF, node.count[k] as u32))
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
