//! Bounding volume hierarchy: binned SAH build, parallel with rayon, flattened
//! into a compact depth-first node array; closest-hit traversal nearer child
//! first with pruning by the current closest `t`, and any-hit traversal that
//! stops at the first hit.
//!
//! Build: Wald, "On fast Construction of SAH-based Bounding Volume
//! Hierarchies" (2007): primitives are binned by centroid into `BINS` buckets
//! along the longest axis of their centroids' box, and the split minimising the surface area heuristic
//! `C = C_trav + (A_L·N_L + A_R·N_R)/A` is taken, or a leaf when that is
//! cheaper. Subtrees above `PARALLEL_THRESHOLD` primitives (and 1/32 of all) are built on both
//! sides of a `rayon::join`, and binning of large nodes is split into chunks
//! that run in parallel.

mod build;

use crate::math::{Aabb, Ray, Vec3};

const BINS: usize = 16;
/// Largest leaf.
pub(crate) const MAX_LEAF: usize = 8;
/// Cost of a traversal step relative to one primitive test.
const TRAVERSAL_COST: f64 = 1.0;
/// Depth below which splits are chosen by SAH (see `node`).
const MAX_SAH_DEPTH: usize = 40;
/// A bound on the depth of any tree, MAX_SAH_DEPTH plus log2 of the largest
/// primitive count (2^32), for the traversal stacks.
pub(crate) const MAX_DEPTH: usize = MAX_SAH_DEPTH + 33;
/// Nodes with at most this many primitives are split by a full SAH sweep.
const SWEEP_BELOW: usize = 32;
/// Nodes with more primitives than this build their children in parallel.
const PARALLEL_THRESHOLD: usize = 4096;
/// Nodes with more primitives than this bin them in parallel chunks.
const PARALLEL_BINNING: usize = 1 << 16;

/// A node of the flattened tree (32 bytes). Interior nodes (`count == 0`)
/// have their first child right after them and the second at `offset`;
/// leaves hold primitives `offset .. offset + count` of [`Bvh::indices`].
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Zeroable)]
#[repr(C)]
pub struct BvhNode {
    pub min: [f32; 3],
    pub offset: u32,
    pub max: [f32; 3],
    pub count: u32,
}

impl BvhNode {
    fn new(b: &Aabb, offset: u32, count: u32) -> Self {
        BvhNode {
            min: b.min.to_array(),
            offset,
            max: b.max.to_array(),
            count,
        }
    }

    pub fn bounds(&self) -> Aabb {
        Aabb {
            min: Vec3::from_array(self.min),
            max: Vec3::from_array(self.max),
        }
    }

    /// The slab test against this node's box, with the ray's interval
    /// `[t_min, t_max)`: the entry parameter if the box is hit.
    #[inline(always)]
    fn hit(&self, o: Vec3, inv_d: Vec3, t_min: f32, t_max: f32) -> Option<f32> {
        // `inv_d` is finite (see `safe_inv_d`), so no product is NaN.
        let t0 = (Vec3::from_array(self.min) - o) * inv_d;
        let t1 = (Vec3::from_array(self.max) - o) * inv_d;
        let near = t0.min(t1);
        let far = t0.max(t1);
        let t_enter = near.max_element().max(t_min);
        let t_exit = far.min_element().min(t_max);
        (t_enter <= t_exit).then_some(t_enter)
    }
}

/// A BVH over primitives given by their boxes.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Bvh {
    /// Depth-first, the root first. After a parallel build some slots
    /// between subtrees are unused (zeroed and never referenced).
    pub nodes: Vec<BvhNode>,
    /// Primitive indices in leaf order, or empty once the owner has
    /// reordered its primitives into leaf order (leaves then index them
    /// directly).
    pub indices: Vec<u32>,
}

/// `1/d` with infinities (zero direction components) replaced by ±1e30, so
/// that the slab test's `(plane − o)·(1/d)` is never `0·∞ = NaN` when the
/// origin lies on a slab plane; for any other origin the product is still
/// huge with the right sign, as with ∞ (obvhs `safe_inverse`). The price: a
/// ray parallel to an axis ends, for the BVH, near `t = 1e30·(distance to
/// the slab)`, far beyond any scene f32 coordinates can describe sensibly.
#[inline(always)]
fn safe_inv_d(ray: &Ray) -> Vec3 {
    ray.d.recip().clamp(Vec3::splat(-1e30), Vec3::splat(1e30))
}

/// Work done by traversals.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TraversalCounters {
    pub nodes_visited: u64,
    pub primitive_tests: u64,
}

/// A primitive as the builder sees it: its box and its index, 32 bytes.
/// The builder partitions an array of these in place, so binning and
/// partitioning stream through memory instead of gathering boxes through an
/// index array (as Embree's `PrimRef`).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct PrimRef {
    /// Box minimum; the fourth lane holds the id's bits.
    lo: glam::Vec4,
    /// Box maximum (fourth lane unused).
    hi: glam::Vec4,
}

impl PrimRef {
    pub fn new(b: &Aabb, id: u32) -> Self {
        PrimRef {
            lo: b.min.extend(f32::from_bits(id)),
            hi: b.max.extend(0.0),
        }
    }

    pub fn id(&self) -> u32 {
        self.lo.w.to_bits()
    }

    /// The box: the vectors as they are, no shuffling (the fourth lane is
    /// ignored by every `Vec3A` operation that matters here).
    #[inline(always)]
    fn bounds(&self) -> Aabb {
        Aabb {
            min: Vec3::from_vec4(self.lo),
            max: Vec3::from_vec4(self.hi),
        }
    }

    /// Twice the centroid (the factor ½ cancels in every use).
    #[inline(always)]
    fn centroid2(&self) -> Vec3 {
        Vec3::from_vec4(self.lo) + Vec3::from_vec4(self.hi)
    }

    fn valid(b: &Aabb) -> bool {
        b.min.is_finite() && b.max.is_finite() && b.min.cmple(b.max).all()
    }
}

impl Bvh {
    /// The primitive at leaf position `k`.
    #[inline(always)]
    fn prim(&self, k: u32) -> u32 {
        if self.indices.is_empty() {
            k
        } else {
            self.indices[k as usize]
        }
    }

    /// The root's box (empty for an empty tree).
    pub fn bounds(&self) -> Aabb {
        self.nodes.first().map_or(Aabb::EMPTY, BvhNode::bounds)
    }

    /// Nodes in the tree (`nodes.len()` also counts the slots a parallel
    /// build left unused).
    pub fn node_count(&self) -> usize {
        let mut count = 0;
        let mut stack = if self.nodes.is_empty() {
            vec![]
        } else {
            vec![0usize]
        };
        while let Some(i) = stack.pop() {
            count += 1;
            let n = &self.nodes[i];
            if n.count == 0 {
                stack.extend([i + 1, n.offset as usize]);
            }
        }
        count
    }

    /// Bytes of nodes and indices.
    pub fn bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<BvhNode>() + self.indices.len() * 4
    }

    /// Closest hit: visits leaves front to back; `test(prim, t_max)` returns
    /// the hit's `t` if the primitive is hit before `t_max`. Returns the
    /// closest `(prim, t)`.
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
        let inv_d = safe_inv_d(ray);
        let mut t_max = ray.t_max;
        let mut best = None;
        let mut stack = [0u32; MAX_DEPTH + 1];
        let mut len = 0;
        let mut node = 0usize;
        let (mut visited, mut tests) = (1u64, 0u64);
        if self.nodes[0].hit(ray.o, inv_d, ray.t_min, t_max).is_none() {
            counters.nodes_visited += 1;
            return None;
        }
        loop {
            let n = &self.nodes[node];
            if n.count > 0 {
                for k in n.offset..n.offset + n.count {
                    let prim = self.prim(k);
                    tests += 1;
                    if let Some(t) = test(prim, t_max) {
                        t_max = t;
                        best = Some((prim, t));
                    }
                }
            } else {
                let (a, b) = (node + 1, n.offset as usize);
                visited += 2;
                let ha = self.nodes[a].hit(ray.o, inv_d, ray.t_min, t_max);
                let hb = self.nodes[b].hit(ray.o, inv_d, ray.t_min, t_max);
                match (ha, hb) {
                    (Some(ta), Some(tb)) => {
                        let (near, far) = if ta <= tb { (a, b) } else { (b, a) };
                        stack[len] = far as u32;
                        len += 1;
                        node = near;
                        continue;
                    }
                    (Some(_), None) => {
                        node = a;
                        continue;
                    }
                    (None, Some(_)) => {
                        node = b;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            // Pop, skipping nodes now beyond the closest hit.
            loop {
                if len == 0 {
                    counters.nodes_visited += visited;
                    counters.primitive_tests += tests;
                    return best;
                }
                len -= 1;
                node = stack[len] as usize;
                if self.nodes[node]
                    .hit(ray.o, inv_d, ray.t_min, t_max)
                    .is_some()
                {
                    break;
                }
            }
        }
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
        let inv_d = safe_inv_d(ray);
        // Each visit pops one node and pushes two.
        let mut stack = [0u32; MAX_DEPTH + 2];
        let mut len = 1;
        let (mut visited, mut tests) = (0u64, 0u64);
        let mut found = false;
        'outer: while len > 0 {
            len -= 1;
            let node = stack[len] as usize;
            let n = &self.nodes[node];
            visited += 1;
            if n.hit(ray.o, inv_d, ray.t_min, ray.t_max).is_none() {
                continue;
            }
            if n.count > 0 {
                for k in n.offset..n.offset + n.count {
                    let prim = self.prim(k);
                    tests += 1;
                    if test(prim) {
                        found = true;
                        break 'outer;
                    }
                }
            } else {
                stack[len] = n.offset;
                stack[len + 1] = node as u32 + 1;
                len += 2;
            }
        }
        counters.nodes_visited += visited;
        counters.primitive_tests += tests;
        found
    }

    /// Checks the structural invariants: children inside parents, every
    /// primitive in exactly one leaf, inside its leaf's box. Returns a
    /// description of the first violation.
    pub fn validate(&self, bounds: &[Aabb]) -> Result<(), String> {
        if self.nodes.is_empty() {
            return if self.indices.is_empty() {
                Ok(())
            } else {
                Err("indices without nodes".into())
            };
        }
        let mut seen = vec![false; bounds.len()];
        let mut stack = vec![0usize];
        let contains = |outer: &Aabb, inner: &Aabb| {
            inner.min.cmpge(outer.min).all() && inner.max.cmple(outer.max).all()
        };
        while let Some(i) = stack.pop() {
            let n = self.nodes.get(i).ok_or(format!("node {i} out of range"))?;
            let b = n.bounds();
            if n.count > 0 {
                let end = (n.offset + n.count) as usize;
                if end
                    > if self.indices.is_empty() {
                        bounds.len()
                    } else {
                        self.indices.len()
                    }
                {
                    return Err(format!("leaf {i} out of range"));
                }
                for k in n.offset..n.offset + n.count {
                    let p = self.prim(k) as usize;
                    if std::mem::replace(&mut seen[p], true) {
                        return Err(format!("primitive {p} in two leaves"));
                    }
                    if !contains(&b, &bounds[p]) {
                        return Err(format!("primitive {p} outside leaf {i}"));
                    }
                }
            } else {
                for c in [i + 1, n.offset as usize] {
                    let child = self
                        .nodes
                        .get(c)
                        .ok_or(format!("child {c} of {i} out of range"))?;
                    if c <= i || !contains(&b, &child.bounds()) {
                        return Err(format!("child {c} of node {i} misplaced or outside it"));
                    }
                    stack.push(c);
                }
            }
        }
        let valid = bounds
            .iter()
            .filter(|b| b.min.is_finite() && b.max.is_finite() && b.min.cmple(b.max).all())
            .count();
        if seen.iter().filter(|&&s| s).count() != valid {
            return Err("some primitives are in no leaf".into());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn boxes(n: usize, seed: u64) -> Vec<Aabb> {
        let mut rng = crate::render::Pcg32::new(seed, 1);
        let mut b = Vec::new();
        for _ in 0..n {
            let c = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 10.0;
            let e = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 0.3;
            b.push(Aabb::new(c - e, c + e));
        }
        b
    }

    #[test]
    fn empty_and_single_primitive() {
        let bvh = Bvh::build(&[]);
        assert!(bvh.nodes.is_empty());
        assert!(
            bvh.closest(
                &Ray::new(Vec3::ZERO, Vec3::X),
                &mut Default::default(),
                |_, _| Some(1.0)
            )
            .is_none()
        );
        let b = [Aabb::new(Vec3::ONE, Vec3::splat(2.0))];
        let bvh = Bvh::build(&b);
        assert_eq!(bvh.nodes.len(), 1);
        bvh.validate(&b).unwrap();
    }

    #[test]
    fn ray_on_a_slab_plane_with_zero_direction_component() {
        let b = [Aabb::new(Vec3::ZERO, Vec3::ONE)];
        let bvh = Bvh::build(&b);
        // Origin on the plane x = 0, moving along z: the boundary counts as inside.
        let ray = Ray::new(Vec3::new(0.0, 0.5, -1.0), Vec3::Z);
        assert!(bvh.any(&ray, &mut Default::default(), |_| true));
        let ray = Ray::new(Vec3::new(-1e-3, 0.5, -1.0), Vec3::Z);
        assert!(!bvh.any(&ray, &mut Default::default(), |_| true));
    }

    fn depth(bvh: &Bvh) -> usize {
        let mut deepest = 0;
        let mut stack = vec![(0usize, 1usize)];
        while let Some((i, d)) = stack.pop() {
            deepest = deepest.max(d);
            let n = &bvh.nodes[i];
            if n.count == 0 {
                stack.push((i + 1, d + 1));
                stack.push((n.offset as usize, d + 1));
            }
        }
        deepest
    }

    #[test]
    fn skewed_distributions_keep_the_tree_shallow() {
        // Centroids at 1.6^i: at every level all but the largest few fall
        // into the first of the 16 bins. (Up to 1.6^139 ≈ 2e28: rays reach
        // t ≈ 5e29 along axes they are parallel to, see `safe_inv_d`.)
        let b: Vec<Aabb> = (0..140)
            .map(|i| {
                let x = 1.6f32.powi(i);
                Aabb::new(Vec3::new(x, 0.0, 0.0), Vec3::new(x * 1.25, 1.0, 1.0))
            })
            .collect();
        let bvh = Bvh::build(&b);
        bvh.validate(&b).unwrap();
        let d = depth(&bvh);
        assert!(d <= MAX_DEPTH, "depth {d}");
        // Traversal along the row of boxes visits the deepest paths.
        let ray = Ray::new(Vec3::new(-1.0, 0.5, 0.5), Vec3::X);
        let inv = ray.inv_d();
        let t_of = |p: u32| b[p as usize].slab(ray.o, inv).map(|h| h.t_enter.max(0.0));
        let hit = bvh.closest(&ray, &mut TraversalCounters::default(), |p, t_max| {
            t_of(p).filter(|&t| t < t_max)
        });
        let brute = (0..b.len() as u32)
            .filter_map(t_of)
            .fold(f32::INFINITY, f32::min);
        assert_eq!(hit.map(|h| h.1), Some(brute));
        assert!(bvh.any(&ray, &mut TraversalCounters::default(), |p| p == 139));
        let wide = super::super::Bvh8::from_binary(&bvh);
        assert!(
            wide.any(&ray, &mut TraversalCounters::default(), |p| bvh.indices
                [p as usize]
                == 139)
        );
    }

    #[test]
    fn all_centroids_equal_still_builds_small_leaves() {
        let b = vec![Aabb::new(Vec3::ZERO, Vec3::ONE); 1000];
        let bvh = Bvh::build(&b);
        bvh.validate(&b).unwrap();
        assert!(bvh.nodes.iter().all(|n| n.count as usize <= MAX_LEAF));
    }

    #[test]
    fn non_finite_boxes_are_left_out() {
        let mut b = vec![Aabb::new(Vec3::ZERO, Vec3::ONE); 10];
        b[3] = Aabb {
            min: Vec3::splat(f32::NAN),
            max: Vec3::ONE,
        };
        b[5] = Aabb::EMPTY;
        let bvh = Bvh::build(&b);
        bvh.validate(&b).unwrap();
        assert_eq!(bvh.indices.len(), 8);
    }

    #[test]
    fn large_random_build_is_valid_and_traversal_matches_brute_force() {
        let b = boxes(20_000, 3);
        let bvh = Bvh::build(&b);
        bvh.validate(&b).unwrap();
        // Built in parallel (above PARALLEL_THRESHOLD): the array has unused
        // slots, the tree itself 2·leaves − 1 nodes.
        let leaves = bvh.nodes.iter().filter(|n| n.count > 0).count();
        assert_eq!(bvh.node_count(), 2 * leaves - 1);
        assert!(bvh.nodes.len() > bvh.node_count());
        let mut rng = crate::render::Pcg32::new(9, 2);
        for _ in 0..2000 {
            let o =
                Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 14.0 - Vec3::splat(2.0);
            let d = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - Vec3::splat(0.5);
            let ray = Ray::new(o, d);
            let inv = ray.inv_d();
            // "Hit" = the ray's entry into the primitive's box.
            let t_of = |p: u32| b[p as usize].slab(ray.o, inv).map(|h| h.t_enter.max(0.0));
            let brute = (0..b.len() as u32)
                .filter_map(|p| t_of(p).map(|t| (p, t)))
                .min_by(|x, y| x.1.total_cmp(&y.1).then(x.0.cmp(&y.0)));
            let mut counters = TraversalCounters::default();
            let got = bvh.closest(&ray, &mut counters, |p, t_max| {
                t_of(p).filter(|&t| t < t_max)
            });
            assert_eq!(got.map(|g| g.1), brute.map(|b| b.1));
            assert_eq!(
                bvh.any(&ray, &mut counters, |p| t_of(p).is_some()),
                brute.is_some()
            );
        }
    }
}
