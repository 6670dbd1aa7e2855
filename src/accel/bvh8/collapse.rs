//! Collapsing a binary [`Bvh`] into a [`Bvh8`] (the method is described in
//! [`super`]).

use super::{Bvh8, Bvh8Node, WIDTH};
use crate::accel::bvh::Bvh;
use rayon::prelude::*;
use std::mem::MaybeUninit;

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
            n.set(0, &root.bounds(), first, count);
            n.order_children();
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
                    node.set(k, &child.bounds(), first, count);
                } else if end - c > split {
                    node.set(k, &child.bounds(), top.len() as u32, 0);
                    todo.push(((c, end), top.len()));
                    top.push(Bvh8Node::EMPTY_NODE);
                } else {
                    // The index is set once the subtree has its place (0,
                    // the root, is no one's child, and not an empty slot).
                    node.set(k, &child.bounds(), 0, 0);
                    tasks.push(((c, end), w, k));
                }
            }
            node.order_children();
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
}

/// Up to eight descendants of binary node `range.0` that together cover it:
/// its children, with the interior one of largest surface area replaced by
/// its own children while there is room (subtrees small enough to become
/// leaves are not expanded).
///
/// A *bottom* subtree, one that makes at most eight wide leaves, is never
/// split part way: it is either replaced by all its leaves, where they fit,
/// or kept whole, to become one node of only leaves. Split one level at a
/// time, as larger subtrees are, the bottom of the tree was mostly nodes of
/// two leaves (44–63 % of all nodes on igea and a bumpy icosphere), each
/// a visit that tested two boxes; kept whole, such a subtree is one node
/// that tests all its leaves' boxes in one visit.
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
            bvh.nodes[i].bounds().half_area()
        };
        (Child { node: i, end, leaf }, area)
    };
    let mut children = [Child {
        node: 0,
        end: 0,
        leaf: None,
    }; WIDTH];
    let mut areas = [0f64; WIDTH];
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
        if let Some((leaves, count)) = bottom_leaves(bvh, c, c_end) {
            if len - 1 + count <= WIDTH {
                children[k] = leaves[0];
                areas[k] = -1.0;
                for &leaf in &leaves[1..count] {
                    children[len] = leaf;
                    areas[len] = -1.0;
                    len += 1;
                }
            } else {
                // Kept whole: it becomes a node of leaves.
                areas[k] = -1.0;
            }
            continue;
        }
        let c_right = bvh.nodes[c].offset as usize;
        (children[k], areas[k]) = child(c + 1, c_right);
        (children[len], areas[len]) = child(c_right, c_end);
        len += 1;
    }
    (children, len)
}

/// The wide leaves of the binary subtree `c` (its node range ending at
/// `end`), leftmost first, if it makes at most [`WIDTH`] of them.
fn bottom_leaves(bvh: &Bvh, c: usize, end: usize) -> Option<([Child; WIDTH], usize)> {
    let mut leaves = [Child {
        node: 0,
        end: 0,
        leaf: None,
    }; WIDTH];
    let mut count = 0;
    // Binary subtrees still to split; a subtree of more than WIDTH of them
    // is given up on before the stack can hold more than WIDTH + 1.
    let mut stack = [(0usize, 0usize); WIDTH + 2];
    let mut len = 1;
    stack[0] = (c, end);
    while len > 0 {
        len -= 1;
        let (i, i_end) = stack[len];
        if let Some(range) = leaf_range(bvh, i) {
            if count == WIDTH {
                return None;
            }
            leaves[count] = Child {
                node: i,
                end: i_end,
                leaf: Some(range),
            };
            count += 1;
        } else {
            if count + len + 2 > WIDTH {
                return None;
            }
            let right = bvh.nodes[i].offset as usize;
            // The left child is taken first.
            stack[len] = (right, i_end);
            stack[len + 1] = (i + 1, right);
            len += 2;
        }
    }
    Some((leaves, count))
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
                node.set(k, &child.bounds(), first, count);
            } else {
                node.set(k, &child.bounds(), (base + next) as u32, 0);
                todo.push(((c, end), next));
                next += 1;
            }
        }
        node.order_children();
        // Slot `w` was handed out once, from `next`: each is written once.
        out[w].write(node);
    }
    next
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::testgen::bumpy_icosphere;
    use crate::math::{Aabb, Vec3};

    /// The bottom of the tree is made of full nodes of leaves, not of
    /// nodes of two leaves each (which the collapse made of bottom
    /// subtrees split one level at a time: 1,745 of its 2,631 nodes).
    #[test]
    fn bottom_subtrees_become_whole_nodes_of_leaves() {
        let (v, f) = bumpy_icosphere(5);
        let boxes: Vec<Aabb> = f
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| Vec3::from(v[i as usize]));
                Aabb::new(a.min(b).min(c), a.max(b).max(c))
            })
            .collect();
        let bvh = Bvh::build(&boxes);
        let wide = Bvh8::from_binary(&bvh);
        let leaf_boxes: Vec<Aabb> = bvh.indices.iter().map(|&i| boxes[i as usize]).collect();
        wide.validate(&leaf_boxes).unwrap();
        let children = |n: &Bvh8Node| {
            (0..WIDTH)
                .filter(|&k| n.child[k] != super::super::EMPTY)
                .count()
        };
        let all_leaves =
            |n: &Bvh8Node| (0..WIDTH).all(|k| n.child[k] == super::super::EMPTY || n.is_leaf(k));
        let pairs = wide
            .nodes
            .iter()
            .filter(|n| children(n) == 2 && all_leaves(n))
            .count();
        let mean = wide.nodes.iter().map(children).sum::<usize>() as f64 / wide.nodes.len() as f64;
        eprintln!(
            "{} nodes, {pairs} of two leaves, {mean:.2} children on average",
            wide.nodes.len()
        );
        assert!(pairs * 20 < wide.nodes.len(), "{pairs} nodes of two leaves");
        assert!(mean > 5.0, "{mean} children per node");
    }
}
