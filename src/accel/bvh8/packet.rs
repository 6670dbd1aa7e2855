//! Closest and any hits of coherent rays traced together: a packet of up to
//! [`PACKET`] rays (a 4×4 block of camera rays, say) goes down the tree as
//! one, with a mask of the rays still in each subtree (Wald et al.,
//! "Interactive Rendering with Coherent Ray Tracing", 2001; with masks per
//! stack entry as Reshetov et al.'s "Multi-Level Ray Tracing", 2005).
//!
//! One AVX-512 register (or two AVX2 registers) holds a quantity for all
//! sixteen rays, so a child's box is tested against every ray of the packet
//! with the operations that test one ray against eight boxes in the
//! single-ray traversal: a node is eight such tests, whatever the number of
//! rays, and its load, its decisions and their mispredictions are paid once
//! per packet instead of once per ray. Each ray's test is the single-ray fused test (see
//! `RaySetup::new`), operation for operation, with its own constants and its
//! own `t_max`: a ray enters exactly the boxes it would enter alone. A
//! child's entry distances are kept with it on the stack, and a popped
//! entry goes on only with the rays whose closest hit so far does not lie
//! before it, so leaves are tested for a ray only where the single-ray
//! traversal would also test them, if not always in the same order (the
//! packet takes the children in the order of its first ray's octant).
//!
//! Each ray's closest `t` is therefore the single-ray traversal's; where
//! two primitives are hit at exactly that `t` (a shared edge), the one
//! returned may differ, as it may between two traversal orders. Rays that
//! the fused test does not take (and with AVX2, rays of another octant than
//! the first ray's), and packets on CPUs without AVX2, are traced one by
//! one.
//!
//! Any hits (shadow rays) go the same way without the order and the
//! distances, as the single-ray any-hit traversal does: a node's leaves are
//! tested at once for the rays that reach them, and a ray leaves the
//! packet as soon as something blocks it.

#[cfg(target_arch = "x86_64")]
use super::STACK;
use super::{Bvh8, Bvh8Node, LEAF};
use crate::accel::bvh::TraversalCounters;
use crate::math::Ray;
#[cfg(target_arch = "x86_64")]
use std::mem::MaybeUninit;

/// Rays of a packet: one AVX-512 register of f32.
pub const PACKET: usize = 16;

impl Bvh8 {
    /// The closest hit of each ray of `rays` (at most [`PACKET`]), as
    /// [`Bvh8::closest_leaves`] finds it, into `out`: `test(r, first,
    /// count, t_max)` tests ray `r` against a leaf's primitives and returns
    /// the closest hit before `t_max`, the earliest of equals. See the
    /// module documentation for what packets change and what they do not.
    pub fn closest_packet(
        &self,
        rays: &[Ray],
        counters: &mut TraversalCounters,
        mut test: impl FnMut(usize, u32, u32, f32) -> Option<(u32, f32)>,
        out: &mut [Option<(u32, f32)>],
    ) {
        assert!(rays.len() <= PACKET && rays.len() == out.len());
        out.fill(None);
        if self.nodes.is_empty() {
            return;
        }
        #[cfg(target_arch = "x86_64")]
        // SAFETY (both): the CPU has what the lanes need.
        let packed = if avx512::available() {
            unsafe { self.closest_packet_avx512(rays, counters, &mut test, out) }
        } else if avx2::available() {
            unsafe { self.closest_packet_avx2(rays, counters, &mut test, out) }
        } else {
            0
        };
        #[cfg(not(target_arch = "x86_64"))]
        let packed = 0u16;
        // The rest one by one.
        for (r, ray) in rays.iter().enumerate() {
            if packed & 1 << r == 0 {
                out[r] = self.closest_leaves(ray, counters, |first, count, t_max| {
                    test(r, first, count, t_max)
                });
            }
        }
    }

    /// Whether each ray of `rays` (at most [`PACKET`]) meets a primitive,
    /// as [`Bvh8::any_leaves`] finds it, into `out`: `test(r, first,
    /// count)` says whether ray `r` meets one of a leaf's primitives.
    pub fn any_packet(
        &self,
        rays: &[Ray],
        counters: &mut TraversalCounters,
        mut test: impl FnMut(usize, u32, u32) -> bool,
        out: &mut [bool],
    ) {
        assert!(rays.len() <= PACKET && rays.len() == out.len());
        out.fill(false);
        if self.nodes.is_empty() {
            return;
        }
        #[cfg(target_arch = "x86_64")]
        // SAFETY (both): the CPU has what the lanes need.
        let packed = if avx512::available() {
            unsafe { self.any_packet_avx512(rays, counters, &mut test, out) }
        } else if avx2::available() {
            unsafe { self.any_packet_avx2(rays, counters, &mut test, out) }
        } else {
            0
        };
        #[cfg(not(target_arch = "x86_64"))]
        let packed = 0u16;
        for (r, ray) in rays.iter().enumerate() {
            if packed & 1 << r == 0 {
                out[r] = self.any_leaves(ray, counters, |first, count| test(r, first, count));
            }
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,fma,popcnt,bmi1")]
    fn closest_packet_avx512(
        &self,
        rays: &[Ray],
        counters: &mut TraversalCounters,
        test: &mut impl FnMut(usize, u32, u32, f32) -> Option<(u32, f32)>,
        out: &mut [Option<(u32, f32)>],
    ) -> u16 {
        let lanes = avx512::Lanes16::new(rays, &self.root());
        self.closest_lanes(&lanes, rays, counters, test, out)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,popcnt,bmi1")]
    fn closest_packet_avx2(
        &self,
        rays: &[Ray],
        counters: &mut TraversalCounters,
        test: &mut impl FnMut(usize, u32, u32, f32) -> Option<(u32, f32)>,
        out: &mut [Option<(u32, f32)>],
    ) -> u16 {
        let lanes = avx2::Lanes16::new(rays, &self.root());
        self.closest_lanes(&lanes, rays, counters, test, out)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,fma,popcnt,bmi1")]
    fn any_packet_avx512(
        &self,
        rays: &[Ray],
        counters: &mut TraversalCounters,
        test: &mut impl FnMut(usize, u32, u32) -> bool,
        out: &mut [bool],
    ) -> u16 {
        let lanes = avx512::Lanes16::new(rays, &self.root());
        self.any_lanes(&lanes, rays, counters, test, out)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,popcnt,bmi1")]
    fn any_packet_avx2(
        &self,
        rays: &[Ray],
        counters: &mut TraversalCounters,
        test: &mut impl FnMut(usize, u32, u32) -> bool,
        out: &mut [bool],
    ) -> u16 {
        let lanes = avx2::Lanes16::new(rays, &self.root());
        self.any_lanes(&lanes, rays, counters, test, out)
    }

    /// The closest hits of the rays of `rays` that `lanes` takes, into
    /// `out`; returns the mask of those rays. Inlined into the callers
    /// compiled for the lanes' instructions.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn closest_lanes<L: Lanes>(
        &self,
        lanes: &L,
        rays: &[Ray],
        counters: &mut TraversalCounters,
        test: &mut impl FnMut(usize, u32, u32, f32) -> Option<(u32, f32)>,
        out: &mut [Option<(u32, f32)>],
    ) -> u16 {
        let active = lanes.active();
        if active == 0 {
            return 0;
        }
        let shift = 3 * lanes.octant();
        let mut t_max: [f32; PACKET] =
            std::array::from_fn(|r| rays.get(r).map_or(f32::INFINITY, |ray| ray.t_max));
        let mut bound = lanes.widen(&t_max);
        let mut hull = reach(&t_max, active);
        let mut best = [None; PACKET];
        // The stack: entries, their rays, their rays' entry distances.
        let mut stack = Stack::new();
        let (mut visited, mut tests) = (0u64, 0u64);
        let (mut entry, mut mask) = (0u32, active);
        'visit: loop {
            if entry & LEAF == 0 {
                visited += u64::from(mask.count_ones());
                let node = &self.nodes[entry as usize];
                // Each child against every ray of the mask.
                let mut hit = [0u16; 8];
                let mut enter = [lanes.zero(); 8];
                let maybe = lanes.cull(node, hull);
                for k in 0..8 {
                    if maybe & 1 << k != 0 && node.child[k] != super::EMPTY {
                        (hit[k], enter[k]) = lanes.test(node, k, mask, bound);
                    }
                }
                // Nearest first for the packet's octant: push the others
                // farthest first.
                let mut next = None;
                for j in (0..8).rev() {
                    let k = (node.order[j] >> shift & 7) as usize;
                    if hit[k] != 0
                        && let Some(previous) = next.replace(k)
                    {
                        stack.push(node.child[previous], hit[previous], enter[previous]);
                    }
                }
                if let Some(k) = next {
                    (entry, mask) = (node.child[k], hit[k]);
                    continue;
                }
            } else {
                let (first, count) = Bvh8Node::leaf_range(entry);
                let mut rays_left = mask;
                let mut changed = false;
                while rays_left != 0 {
                    let r = rays_left.trailing_zeros() as usize;
                    rays_left &= rays_left - 1;
                    tests += u64::from(count);
                    if let Some(h) = test(r, first, count, t_max[r]) {
                        (t_max[r], best[r]) = (h.1, Some(h));
                        changed = true;
                    }
                }
                if changed {
                    bound = lanes.widen(&t_max);
                    hull = reach(&t_max, active);
                }
            }
            // Entries go on with the rays whose closest hit so far is not
            // before them.
            while let Some((e, m, d)) = stack.pop() {
                let m = lanes.le(m, d, bound);
                if m != 0 {
                    (entry, mask) = (e, m);
                    continue 'visit;
                }
            }
            break;
        }
        counters.nodes_visited += visited;
        counters.primitive_tests += tests;
        for (r, o) in out.iter_mut().enumerate() {
            if active & 1 << r != 0 {
                *o = best[r];
            }
        }
        active
    }

    /// The any hits of the rays of `rays` that `lanes` takes, into `out`;
    /// returns the mask of those rays.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn any_lanes<L: Lanes>(
        &self,
        lanes: &L,
        rays: &[Ray],
        counters: &mut TraversalCounters,
        test: &mut impl FnMut(usize, u32, u32) -> bool,
        out: &mut [bool],
    ) -> u16 {
        let active = lanes.active();
        if active == 0 {
            return 0;
        }
        let t_max: [f32; PACKET] =
            std::array::from_fn(|r| rays.get(r).map_or(f32::INFINITY, |ray| ray.t_max));
        let bound = lanes.widen(&t_max);
        let hull = reach(&t_max, active);
        // Only nodes go through the stack (distances unused).
        let mut stack = Stack::new();
        let (mut visited, mut tests) = (0u64, 0u64);
        let mut blocked = 0u16;
        let (mut entry, mut mask) = (0u32, active);
        'visit: loop {
            visited += u64::from(mask.count_ones());
            let node = &self.nodes[entry as usize];
            let mut next = None;
            let maybe = lanes.cull(node, hull);
            for k in (0..8).rev() {
                let child = node.child[k];
                if maybe & 1 << k == 0 || child == super::EMPTY {
                    continue;
                }
                let (hit, _) = lanes.test(node, k, mask & !blocked, bound);
                if hit == 0 {
                    continue;
                }
                if child & LEAF == 0 {
                    if let Some((c, m)) = next.replace((child, hit)) {
                        stack.push(c, m, lanes.zero());
                    }
                    continue;
                }
                let (first, count) = Bvh8Node::leaf_range(child);
                let mut rays_left = hit & !blocked;
                while rays_left != 0 {
                    let r = rays_left.trailing_zeros() as usize;
                    rays_left &= rays_left - 1;
                    tests += u64::from(count);
                    if test(r, first, count) {
                        blocked |= 1 << r;
                    }
                }
                if blocked == active {
                    break 'visit;
                }
            }
            if let Some((c, m)) = next
                && m & !blocked != 0
            {
                (entry, mask) = (c, m & !blocked);
                continue;
            }
            while let Some((e, m, _)) = stack.pop() {
                if m & !blocked != 0 {
                    (entry, mask) = (e, m & !blocked);
                    continue 'visit;
                }
            }
            break;
        }
        counters.nodes_visited += visited;
        counters.primitive_tests += tests;
        for (r, o) in out.iter_mut().enumerate() {
            if active & 1 << r != 0 {
                *o = blocked & 1 << r != 0;
            }
        }
        active
    }
}

/// The greatest `t_max` of the rays of `rays` (a mask).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn reach(t_max: &[f32; PACKET], mut rays: u16) -> f32 {
    let mut far = f32::NEG_INFINITY;
    while rays != 0 {
        far = far.max(t_max[rays.trailing_zeros() as usize]);
        rays &= rays - 1;
    }
    far
}

/// The rays of a packet in SIMD lanes, one quantity of all sixteen rays
/// per [`Lanes::Wide`]: what the packet traversals need of an instruction
/// set. A value exists only where the CPU has its instructions, so its
/// methods, inlined into functions compiled for them, may use them.
#[cfg(target_arch = "x86_64")]
trait Lanes {
    /// Sixteen `f32`, one per ray.
    type Wide: Copy;

    /// The rays that take the packet test (the others are traced alone).
    fn active(&self) -> u16;

    /// The octant whose child order the packet follows.
    fn octant(&self) -> u32;

    /// Child `k` of `node` against the rays of `mask` whose intervals end
    /// at `bound` (widened): the rays that enter its box (a subset of
    /// `mask`), and the entry distances (lanes outside `mask` unspecified).
    fn test(&self, node: &Bvh8Node, k: usize, mask: u16, bound: Self::Wide) -> (u16, Self::Wide);

    /// The children of `node` that a ray of the packet whose `t_max` is at
    /// most `t_max` may enter, as a mask: at least those its per-ray
    /// [`Lanes::test`] takes, from one test of the eight boxes against the
    /// packet's interval (Boulos et al., "Geometric and Arithmetic Culling
    /// Methods for Entire Ray Packets", 2006), so that boxes no ray enters
    /// cost one 8-wide test instead of one per ray.
    fn cull(&self, node: &Bvh8Node, t_max: f32) -> u32;

    /// `t_max` widened as the fused test widens it (`NodeVisit::bound`).
    fn widen(&self, t_max: &[f32; PACKET]) -> Self::Wide;

    /// The rays of `mask` whose `d` is at most `bound`.
    fn le(&self, mask: u16, d: Self::Wide, bound: Self::Wide) -> u16;

    /// Zeros.
    fn zero(&self) -> Self::Wide;
}

/// The rays of a packet as columns: lane `r` of each holds ray `r`'s value,
/// lanes from `rays.len()` on repeat the last ray's.
#[cfg(target_arch = "x86_64")]
struct Columns {
    o: [[f32; PACKET]; 3],
    d: [[f32; PACKET]; 3],
    t_min: [f32; PACKET],
}

#[cfg(target_arch = "x86_64")]
impl Columns {
    #[inline(always)]
    fn new(rays: &[Ray]) -> Columns {
        let mut c = Columns {
            o: [[0.0; PACKET]; 3],
            d: [[0.0; PACKET]; 3],
            t_min: [0.0; PACKET],
        };
        if let Some(last) = rays.last() {
            for r in 0..PACKET {
                let ray = rays.get(r).unwrap_or(last);
                for a in 0..3 {
                    c.o[a][r] = ray.o[a];
                    c.d[a][r] = ray.d[a];
                }
                c.t_min[r] = ray.t_min;
            }
        }
        c
    }
}

/// The packets' stack: entries, their rays, and their rays' entry
/// distances. Not initialised (zeroing 33 kB would cost more than a
/// packet's traversal): an entry is read only after it is written.
#[cfg(target_arch = "x86_64")]
struct Stack<W> {
    entries: [MaybeUninit<u32>; STACK],
    masks: [MaybeUninit<u16>; STACK],
    dists: [MaybeUninit<W>; STACK],
    len: usize,
}

#[cfg(target_arch = "x86_64")]
impl<W: Copy> Stack<W> {
    #[inline(always)]
    fn new() -> Self {
        Stack {
            entries: [const { MaybeUninit::uninit() }; STACK],
            masks: [const { MaybeUninit::uninit() }; STACK],
            dists: [const { MaybeUninit::uninit() }; STACK],
            len: 0,
        }
    }

    /// Pushes an entry (indexing checks the bound; `STACK` covers the
    /// deepest tree, as for single rays).
    #[inline(always)]
    fn push(&mut self, entry: u32, mask: u16, dist: W) {
        self.entries[self.len].write(entry);
        self.masks[self.len].write(mask);
        self.dists[self.len].write(dist);
        self.len += 1;
    }

    #[inline(always)]
    fn pop(&mut self) -> Option<(u32, u16, W)> {
        self.len = self.len.checked_sub(1)?;
        // SAFETY: entries below the old `len` were written.
        unsafe {
            Some((
                self.entries[self.len].assume_init(),
                self.masks[self.len].assume_init(),
                self.dists[self.len].assume_init(),
            ))
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod avx512;

#[cfg(target_arch = "x86_64")]
mod avx2;
