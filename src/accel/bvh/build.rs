//! The binned SAH build of [`Bvh`] (Wald 2007; the method is described in
//! [`super`]), with its parallel subtrees and parallel binning.

use super::{
    BINS, Bvh, BvhNode, MAX_LEAF, MAX_SAH_DEPTH, PARALLEL_BINNING, PARALLEL_THRESHOLD, PrimRef,
    SWEEP_BELOW, TRAVERSAL_COST,
};
use crate::math::Aabb;
use rayon::prelude::*;

#[derive(Clone, Copy)]
struct Bin {
    bounds: Aabb,
    /// Box of the doubled centroids.
    centroids: Aabb,
    count: u32,
}

const EMPTY_BIN: Bin = Bin {
    bounds: Aabb::EMPTY,
    centroids: Aabb::EMPTY,
    count: 0,
};

impl Bin {
    fn merge(&self, o: &Bin) -> Bin {
        Bin {
            bounds: self.bounds.union(&o.bounds),
            centroids: self.centroids.union(&o.centroids),
            count: self.count + o.count,
        }
    }
}

impl Bvh {
    /// Builds a BVH over primitives with the given boxes (centroids are the
    /// boxes' centres). Primitives with empty or non-finite boxes are left out.
    pub fn build(bounds: &[Aabb]) -> Bvh {
        let refs = bounds
            .par_iter()
            .enumerate()
            .filter(|(_, b)| PrimRef::valid(b))
            .map(|(i, b)| PrimRef::new(b, i as u32))
            .collect();
        Bvh::build_refs(refs)
    }

    /// Builds from primitive references (consumed: the array is reordered in
    /// place and its ids become [`Bvh::indices`]).
    pub fn build_refs(mut refs: Vec<PrimRef>) -> Bvh {
        if refs.is_empty() {
            return Bvh::default();
        }
        let (b, cb) = node_bounds(&refs);
        // A binary tree over n primitives has at most 2n − 1 nodes. Each
        // subtree is written into its own range of one array of that size:
        // no copies, no regrowing. The array is allocated zeroed, which the
        // system provides as untouched pages: pages of slots a parallel build
        // leaves unused never become memory.
        let mut nodes: Vec<BvhNode> = bytemuck::zeroed_vec(2 * refs.len() - 1);
        // Parallel subtrees down to 1/32 of the whole: enough tasks to keep
        // every core busy.
        let par = PARALLEL_THRESHOLD.max(refs.len() / 32);
        let used = node(
            Task {
                refs: &mut refs,
                first: 0,
                bounds: b,
                centroids: cb,
                depth: 0,
            },
            &mut nodes,
            0,
            par,
        );
        nodes.truncate(used);
        let indices = refs.par_iter().map(PrimRef::id).collect();
        Bvh { nodes, indices }
    }
}

/// Bins `refs` by centroid along `axis` of `cb` (the doubled centroids' box).
fn bin(refs: &[PrimRef], cb: &Aabb, axis: usize) -> [Bin; BINS] {
    let scale = BINS as f32 / (cb.max[axis] - cb.min[axis]).max(f32::MIN_POSITIVE);
    let lo = cb.min[axis];
    let one = |chunk: &[PrimRef]| {
        let mut bins = [EMPTY_BIN; BINS];
        for r in chunk {
            let c = r.centroid2();
            let k = (((c[axis] - lo) * scale) as usize).min(BINS - 1);
            let bin = &mut bins[k];
            bin.bounds = bin.bounds.union(&r.bounds());
            bin.centroids = bin.centroids.union(&Aabb { min: c, max: c });
            bin.count += 1;
        }
        bins
    };
    if refs.len() < PARALLEL_BINNING {
        return one(refs);
    }
    refs.par_chunks(PARALLEL_BINNING / 4).map(one).reduce(
        || [EMPTY_BIN; BINS],
        |mut a, b| {
            for k in 0..BINS {
                a[k] = a[k].merge(&b[k]);
            }
            a
        },
    )
}

/// The box of the primitives and the box of their doubled centroids.
fn node_bounds(refs: &[PrimRef]) -> (Aabb, Aabb) {
    let one = |chunk: &[PrimRef]| {
        chunk.iter().fold((Aabb::EMPTY, Aabb::EMPTY), |(b, c), r| {
            let cp = r.centroid2();
            (b.union(&r.bounds()), c.union(&Aabb { min: cp, max: cp }))
        })
    };
    if refs.len() < PARALLEL_BINNING {
        return one(refs);
    }
    refs.par_chunks(PARALLEL_BINNING / 4).map(one).reduce(
        || (Aabb::EMPTY, Aabb::EMPTY),
        |a, b| (a.0.union(&b.0), a.1.union(&b.1)),
    )
}

/// The primitives of one subtree under construction and where it goes.
struct Task<'a> {
    refs: &'a mut [PrimRef],
    /// Position of `refs[0]` in the whole array.
    first: usize,
    /// Boxes of the primitives and of their doubled centroids.
    bounds: Aabb,
    centroids: Aabb,
    depth: usize,
}

/// Writes the subtree of `task` (its primitives reordered in place into leaf
/// order) depth-first into the start of `out`, whose first slot is node
/// `base` of the whole array; returns the number of slots used. `out` must
/// hold `2·n − 1` slots for `n` primitives. Subtrees of more than `par`
/// primitives are built in parallel.
fn node(task: Task, out: &mut [BvhNode], base: usize, par: usize) -> usize {
    let Task {
        refs,
        first,
        bounds: b,
        centroids: cb,
        depth,
    } = task;
    let n = refs.len();
    let leaf = |out: &mut [BvhNode]| {
        out[0] = BvhNode::new(&b, first as u32, n as u32);
        1
    };
    if n <= 2 || (cb.max.cmple(cb.min).all() && n <= MAX_LEAF) {
        return leaf(out);
    }
    // Past MAX_SAH_DEPTH only median splits: the depth of any tree stays
    // below MAX_SAH_DEPTH + log2(n), which bounds the builder's recursion and
    // the traversal stacks whatever the input.
    if depth >= MAX_SAH_DEPTH {
        return halves(refs, first, b, depth, out, base, par);
    }
    let axis = (cb.max - cb.min).max_position();
    if n <= SWEEP_BELOW {
        return small(refs, first, b, depth, axis, out, base, par);
    }
    // Binned along the longest axis of the centroids' box only (Wald 2007);
    // the bins merged on each side give the children's boxes.
    let mut best: Option<(f64, usize, Bin, Bin)> = None;
    if cb.max[axis] > cb.min[axis] {
        let bins = bin(refs, &cb, axis);
        let mut right = [EMPTY_BIN; BINS];
        let mut acc = EMPTY_BIN;
        for k in (1..BINS).rev() {
            acc = acc.merge(&bins[k]);
            right[k] = acc;
        }
        let mut left = EMPTY_BIN;
        for k in 1..BINS {
            left = left.merge(&bins[k - 1]);
            let r = &right[k];
            if left.count == 0 || r.count == 0 {
                continue;
            }
            let cost =
                left.bounds.half_area() * left.count as f64 + r.bounds.half_area() * r.count as f64;
            if best.as_ref().is_none_or(|b| cost < b.0) {
                best = Some((cost, k, left, *r));
            }
        }
    }
    let split_cost = best.as_ref().map_or(f64::INFINITY, |b| {
        TRAVERSAL_COST
            + b.0
                / b.2
                    .bounds
                    .union(&b.3.bounds)
                    .half_area()
                    .max(f64::MIN_POSITIVE)
    });
    match best {
        Some((_, k, lb, rb)) if split_cost < n as f64 || n > MAX_LEAF => {
            let scale = BINS as f32 / (cb.max[axis] - cb.min[axis]);
            let lo = cb.min[axis];
            let mid = partition(refs, |r| {
                (((r.centroid2()[axis] - lo) * scale) as usize).min(BINS - 1) < k
            });
            if mid == 0 || mid == n {
                // Rounding put every centroid on one side: split the list.
                return halves(refs, first, b, depth, out, base, par);
            }
            children(
                refs,
                first,
                b,
                depth,
                mid,
                [(lb.bounds, lb.centroids), (rb.bounds, rb.centroids)],
                out,
                base,
                par,
            )
        }
        _ if n <= MAX_LEAF => leaf(out),
        // No useful SAH split (e.g. all centroids equal): split the list in half.
        _ => halves(refs, first, b, depth, out, base, par),
    }
}

/// A small node: the primitives sorted by centroid along `axis` and every
/// split between neighbours evaluated with the SAH (a full sweep, MacDonald
/// and Booth 1990). Exact where binning approximates, and cheaper for a few
/// primitives than clearing and sweeping the bins; most nodes are small.
#[allow(clippy::too_many_arguments)]
fn small(
    refs: &mut [PrimRef],
    first: usize,
    b: Aabb,
    depth: usize,
    axis: usize,
    out: &mut [BvhNode],
    base: usize,
    par: usize,
) -> usize {
    let n = refs.len();
    // Insertion sort: stable, in place, fast for so few.
    for i in 1..n {
        let mut j = i;
        while j > 0 && refs[j - 1].centroid2()[axis] > refs[j].centroid2()[axis] {
            refs.swap(j - 1, j);
            j -= 1;
        }
    }
    let point = |r: &PrimRef| {
        let c = r.centroid2();
        Aabb { min: c, max: c }
    };
    // Boxes and centroid boxes of refs[i..].
    let mut suffix = [(Aabb::EMPTY, Aabb::EMPTY); SWEEP_BELOW + 1];
    for i in (0..n).rev() {
        suffix[i] = (
            suffix[i + 1].0.union(&refs[i].bounds()),
            suffix[i + 1].1.union(&point(&refs[i])),
        );
    }
    let mut left = (Aabb::EMPTY, Aabb::EMPTY);
    let mut best: Option<(f64, usize, (Aabb, Aabb))> = None;
    for i in 1..n {
        left = (
            left.0.union(&refs[i - 1].bounds()),
            left.1.union(&point(&refs[i - 1])),
        );
        let cost = left.0.half_area() * i as f64 + suffix[i].0.half_area() * (n - i) as f64;
        if best.as_ref().is_none_or(|x| cost < x.0) {
            best = Some((cost, i, left));
        }
    }
    match best {
        Some((cost, mid, left))
            if TRAVERSAL_COST + cost / b.half_area().max(f64::MIN_POSITIVE) < n as f64
                || n > MAX_LEAF =>
        {
            children(
                refs,
                first,
                b,
                depth,
                mid,
                [left, suffix[mid]],
                out,
                base,
                par,
            )
        }
        _ => {
            out[0] = BvhNode::new(&b, first as u32, n as u32);
            1
        }
    }
}

fn halves(
    refs: &mut [PrimRef],
    first: usize,
    b: Aabb,
    depth: usize,
    out: &mut [BvhNode],
    base: usize,
    par: usize,
) -> usize {
    let mid = refs.len() / 2;
    let sides = [node_bounds(&refs[..mid]), node_bounds(&refs[mid..])];
    children(refs, first, b, depth, mid, sides, out, base, par)
}

/// The node over `refs` with children over `refs[..mid]` and `refs[mid..]`
/// (`sides`: their boxes and centroid boxes), written as [`node`] does.
/// Large ones build the two subtrees in parallel, each in its own range of
/// `out` (the left one's sized for the most nodes it can have); small ones
/// put the right subtree right after the left one.
#[allow(clippy::too_many_arguments)]
fn children(
    refs: &mut [PrimRef],
    first: usize,
    b: Aabb,
    depth: usize,
    mid: usize,
    sides: [(Aabb, Aabb); 2],
    out: &mut [BvhNode],
    base: usize,
    par: usize,
) -> usize {
    let parallel = refs.len() > par;
    let (left_refs, right_refs) = refs.split_at_mut(mid);
    let [(lb, lc), (rb, rc)] = sides;
    let left = Task {
        refs: left_refs,
        first,
        bounds: lb,
        centroids: lc,
        depth: depth + 1,
    };
    let right = Task {
        refs: right_refs,
        first: first + mid,
        bounds: rb,
        centroids: rc,
        depth: depth + 1,
    };
    let (right_start, right_used) = if parallel {
        let (left_out, right_out) = out[1..].split_at_mut(2 * mid - 1);
        let right_start = 1 + left_out.len();
        let ((), right_used) = rayon::join(
            || {
                node(left, left_out, base + 1, par);
            },
            || node(right, right_out, base + right_start, par),
        );
        (right_start, right_used)
    } else {
        let right_start = 1 + node(left, &mut out[1..], base + 1, par);
        let right_used = node(right, &mut out[right_start..], base + right_start, par);
        (right_start, right_used)
    };
    out[0] = BvhNode::new(&b, (base + right_start) as u32, 0);
    right_start + right_used
}

/// Moves the elements satisfying `left` to the front; returns their count.
fn partition(v: &mut [PrimRef], left: impl Fn(&PrimRef) -> bool) -> usize {
    let (mut i, mut j) = (0, v.len());
    loop {
        while i < j && left(&v[i]) {
            i += 1;
        }
        while i < j && !left(&v[j - 1]) {
            j -= 1;
        }
        if i >= j {
            return i;
        }
        v.swap(i, j - 1);
        i += 1;
        j -= 1;
    }
}
