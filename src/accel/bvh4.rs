//! A 4-wide BVH collapsed from the binary one: each node holds the boxes of up
//! to four children in structure-of-arrays form, and one ray is tested against
//! all four with 4-lane SIMD (glam's `Vec4`: SSE on x86-64, scalar elsewhere).
//! Wide nodes halve the depth of the tree and the number of nodes a ray
//! visits (Wald et al., "Getting Rid of Packets", 2008; Dammertz et al.,
//! "Shallow Bounding Volume Hierarchies", 2008).
//!
//! Collapse: a binary node's children are expanded, largest surface area
//! first, until the node has four children or only leaves are left.

use super::bvh::{Bvh, MAX_DEPTH, TraversalCounters};
use crate::math::{Aabb, Ray, Vec3};
use glam::{BVec4A, Vec4};

/// A child slot: an interior node, a leaf, or empty.
const EMPTY: u32 = u32::MAX;
/// High bit of `child` marks a leaf; the rest is its first primitive.
const LEAF: u32 = 1 << 31;

/// A node with up to four children (128 bytes, two cache lines).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct Bvh4Node {
    pub min_x: Vec4,
    pub max_x: Vec4,
    pub min_y: Vec4,
    pub max_y: Vec4,
    pub min_z: Vec4,
    pub max_z: Vec4,
    /// Interior child: its node index; leaf: `LEAF | first primitive`; `EMPTY`.
    pub child: [u32; 4],
    /// Primitives of a leaf child.
    pub count: [u32; 4],
}

impl Bvh4Node {
    const EMPTY_NODE: Bvh4Node = Bvh4Node {
        min_x: Vec4::INFINITY,
        max_x: Vec4::NEG_INFINITY,
        min_y: Vec4::INFINITY,
        max_y: Vec4::NEG_INFINITY,
        min_z: Vec4::INFINITY,
        max_z: Vec4::NEG_INFINITY,
        child: [EMPTY; 4],
        count: [0; 4],
    };

    fn set(&mut self, k: usize, b: &Aabb, child: u32, count: u32) {
        self.min_x[k] = b.min.x;
        self.min_y[k] = b.min.y;
        self.min_z[k] = b.min.z;
        self.max_x[k] = b.max.x;
        self.max_y[k] = b.max.y;
        self.max_z[k] = b.max.z;
        self.child[k] = child;
        self.count[k] = count;
    }

    pub fn child_bounds(&self, k: usize) -> Aabb {
        Aabb {
            min: Vec3::new(self.min_x[k], self.min_y[k], self.min_z[k]),
            max: Vec3::new(self.max_x[k], self.max_y[k], self.max_z[k]),
        }
    }
}

/// The ray, prepared for box tests: origin and finite inverse direction
/// splatted across lanes, and for each axis which of min/max is the near plane.
struct RayLanes {
    o: [Vec4; 3],
    inv: [Vec4; 3],
    negative: [bool; 3],
    t_min: f32,
}

impl RayLanes {
    #[inline(always)]
    fn new(ray: &Ray) -> Self {
        // Finite, so (plane − o)·inv is never 0·∞ = NaN (see `Bvh`).
        let inv = ray.d.recip().clamp(Vec3::splat(-1e30), Vec3::splat(1e30));
        RayLanes {
            o: [
                Vec4::splat(ray.o.x),
                Vec4::splat(ray.o.y),
                Vec4::splat(ray.o.z),
            ],
            inv: [Vec4::splat(inv.x), Vec4::splat(inv.y), Vec4::splat(inv.z)],
            negative: [inv.x < 0.0, inv.y < 0.0, inv.z < 0.0],
            t_min: ray.t_min,
        }
    }

    /// The slab test against the node's four boxes: entry distances and the
    /// mask of boxes hit within `[t_min, t_max]`.
    #[inline(always)]
    fn test(&self, n: &Bvh4Node, t_max: f32) -> (Vec4, BVec4A) {
        let axis = |k: usize, lo: Vec4, hi: Vec4| {
            let (near, far) = if self.negative[k] { (hi, lo) } else { (lo, hi) };
            (
                (near - self.o[k]) * self.inv[k],
                (far - self.o[k]) * self.inv[k],
            )
        };
        let (nx, fx) = axis(0, n.min_x, n.max_x);
        let (ny, fy) = axis(1, n.min_y, n.max_y);
        let (nz, fz) = axis(2, n.min_z, n.max_z);
        let t_enter = nx.max(ny).max(nz.max(Vec4::splat(self.t_min)));
        let t_exit = fx.min(fy).min(fz.min(Vec4::splat(t_max)));
        (t_enter, t_enter.cmple(t_exit))
    }
}

/// A 4-wide BVH over primitives given by leaf position (the owner keeps its
/// primitives in the order of the binary BVH it was collapsed from).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Bvh4 {
    pub nodes: Vec<Bvh4Node>,
    /// The box of everything.
    pub bounds: Option<Aabb>,
}

impl Bvh4 {
    /// Collapses a binary BVH. Leaves keep their primitive ranges, so the
    /// primitives stay in `bvh`'s leaf order. Sequential: it is memory-bound,
    /// and per-thread arrays would cost more in fresh pages than they save.
    pub fn from_binary(bvh: &Bvh) -> Bvh4 {
        let Some(root) = bvh.nodes.first() else {
            return Bvh4::default();
        };
        let bounds = Some(root.bounds());
        if root.count > 0 {
            // A single leaf: one node with one child.
            let mut n = Bvh4Node::EMPTY_NODE;
            n.set(0, &root.bounds(), LEAF | root.offset, root.count);
            return Bvh4 {
                nodes: vec![n],
                bounds,
            };
        }
        // About a third of the binary nodes become wide nodes.
        let mut nodes = Vec::with_capacity(bvh.nodes.len() / 3 + 1);
        nodes.push(Bvh4Node::EMPTY_NODE);
        // (binary node's subtree range, wide node to fill)
        let mut todo = vec![((0usize, bvh.nodes.len()), 0usize)];
        while let Some((range, w)) = todo.pop() {
            let (children, len) = collapse(bvh, range);
            let mut node = Bvh4Node::EMPTY_NODE;
            for (k, &(c, end)) in children[..len].iter().enumerate() {
                let child = &bvh.nodes[c];
                if child.count > 0 {
                    node.set(k, &child.bounds(), LEAF | child.offset, child.count);
                } else {
                    let index = nodes.len();
                    nodes.push(Bvh4Node::EMPTY_NODE);
                    node.set(k, &child.bounds(), index as u32, 0);
                    todo.push(((c, end), index));
                }
            }
            nodes[w] = node;
        }
        Bvh4 { nodes, bounds }
    }

    /// Bytes of nodes.
    pub fn bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<Bvh4Node>()
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
        if self.nodes.is_empty() {
            return None;
        }
        let lanes = RayLanes::new(ray);
        let mut t_max = ray.t_max;
        let mut best = None;
        // Stack of (node, entry distance) for children not visited yet.
        // Each visit pushes at most three: 3 per level.
        let mut stack = [(0u32, 0f32); 3 * MAX_DEPTH + 2];
        let mut len = 0;
        let mut index = 0u32;
        let (mut visited, mut tests) = (0u64, 0u64);
        'visit: loop {
            let node = &self.nodes[index as usize];
            visited += 1;
            let (t, mask) = lanes.test(node, t_max);
            // Leaf children first, each pruning by the closest hit so far;
            // then the nearest interior child is visited next without going
            // through the stack, and the others are pushed. One interior child
            // hit (the common case deep in the tree) costs no stack traffic.
            let mut bits = mask.bitmask();
            let mut next: Option<(u32, f32)> = None;
            while bits != 0 {
                let k = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let child = node.child[k];
                if child & LEAF != 0 {
                    let first = child & !LEAF;
                    for prim in first..first + node.count[k] {
                        tests += 1;
                        if let Some(th) = test(prim, t_max) {
                            t_max = th;
                            best = Some((prim, th));
                        }
                    }
                } else {
                    let tc = t[k];
                    match next {
                        None => next = Some((child, tc)),
                        Some((c, tn)) if tc < tn => {
                            stack[len] = (c, tn);
                            len += 1;
                            next = Some((child, tc));
                        }
                        Some(_) => {
                            stack[len] = (child, tc);
                            len += 1;
                        }
                    }
                }
            }
            if let Some((c, tc)) = next
                && tc <= t_max
            {
                index = c;
                continue;
            }
            // Pop, skipping nodes now beyond the closest hit.
            while len > 0 {
                len -= 1;
                let (c, tc) = stack[len];
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
        if self.nodes.is_empty() {
            return false;
        }
        let lanes = RayLanes::new(ray);
        let mut stack = [0u32; 3 * MAX_DEPTH + 2];
        let mut len = 0;
        let mut index = 0u32;
        let (mut visited, mut tests) = (0u64, 0u64);
        let mut found = false;
        'visit: loop {
            let node = &self.nodes[index as usize];
            visited += 1;
            let (_, mask) = lanes.test(node, ray.t_max);
            let mut bits = mask.bitmask();
            // Leaves at once; of the interior children, the last is visited
            // next without going through the stack, the others are pushed.
            let mut next = None;
            while bits != 0 {
                let k = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let child = node.child[k];
                if child & LEAF != 0 {
                    let first = child & !LEAF;
                    for prim in first..first + node.count[k] {
                        tests += 1;
                        if test(prim) {
                            found = true;
                            break 'visit;
                        }
                    }
                } else {
                    if let Some(previous) = next {
                        stack[len] = previous;
                        len += 1;
                    }
                    next = Some(child);
                }
            }
            index = match next {
                Some(c) => c,
                None if len > 0 => {
                    len -= 1;
                    stack[len]
                }
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
            for k in 0..4 {
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

/// Up to four descendants of binary node `range.0` that together cover it,
/// each with the end of its subtree's node range: its children, with the
/// interior one of largest surface area replaced by its own children while
/// there is room.
fn collapse(bvh: &Bvh, range: (usize, usize)) -> ([(usize, usize); 4], usize) {
    let (b, end) = range;
    let right = bvh.nodes[b].offset as usize;
    let mut children = [(b + 1, right), (right, end), (0, 0), (0, 0)];
    let mut len = 2;
    let area = |i: usize| {
        let e = (bvh.nodes[i].bounds().max - bvh.nodes[i].bounds().min).max(Vec3::ZERO);
        e.x * e.y + e.y * e.z + e.z * e.x
    };
    while len < 4 {
        let Some(k) = (0..len)
            .filter(|&k| bvh.nodes[children[k].0].count == 0)
            .max_by(|&x, &y| area(children[x].0).total_cmp(&area(children[y].0)))
        else {
            break;
        };
        let (c, c_end) = children[k];
        let c_right = bvh.nodes[c].offset as usize;
        children[k] = (c + 1, c_right);
        children[len] = (c_right, c_end);
        len += 1;
    }
    (children, len)
}
