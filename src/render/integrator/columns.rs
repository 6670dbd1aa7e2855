//! The breadth-first stream's records in columns (structure of arrays):
//! the rays of a wave, the nodes of the ray trees and the shadow rays, so
//! that a batch of them is a slice of each column, and the SIMD lanes of
//! [`super::wave`] write theirs with stores at a running position, not
//! pushes (see [`Rays::room`]).

use super::whitted::LightGain;
use crate::geometry::batch::RayBatch;
use crate::math::{Color, Ray};

/// Rays `r(t) = o + t·d`, `t_min ≤ t < t_max`, by component: `len` of
/// them; the columns may be longer (room made ahead, written in place).
#[derive(Default)]
pub(super) struct Rays {
    pub len: usize,
    pub o: [Vec<f32>; 3],
    pub d: [Vec<f32>; 3],
    pub t_min: Vec<f32>,
    pub t_max: Vec<f32>,
}

impl Rays {
    /// Makes the columns long enough for `extra` rays past `len` (so that
    /// a loop may write one at `len`, then keep it or not by how far it
    /// moves on: compaction without branches).
    pub fn room(&mut self, extra: usize) {
        let n = self.len + extra;
        if self.t_min.len() < n {
            for c in self.o.iter_mut().chain(&mut self.d) {
                c.resize(n, 0.0);
            }
            self.t_min.resize(n, 0.0);
            self.t_max.resize(n, 0.0);
        }
    }

    #[inline(always)]
    pub fn set(&mut self, i: usize, o: [f32; 3], d: [f32; 3], t_min: f32, t_max: f32) {
        for c in 0..3 {
            self.o[c][i] = o[c];
            self.d[c][i] = d[c];
        }
        self.t_min[i] = t_min;
        self.t_max[i] = t_max;
    }

    #[inline(always)]
    pub fn set_ray(&mut self, i: usize, ray: &Ray) {
        self.set(i, ray.o.to_array(), ray.d.to_array(), ray.t_min, ray.t_max);
    }

    /// Rays `start..start + n` as `batch` (`n` at most a batch).
    pub fn to_batch(&self, start: usize, n: usize, batch: &mut RayBatch) {
        let end = start + n;
        batch.len = n;
        for c in 0..3 {
            batch.o[c][..n].copy_from_slice(&self.o[c][start..end]);
            batch.d[c][..n].copy_from_slice(&self.d[c][start..end]);
        }
        batch.t_min[..n].copy_from_slice(&self.t_min[start..end]);
        batch.t_max[..n].copy_from_slice(&self.t_max[start..end]);
    }
}

/// The rays of a wave, with the factor each one's parent puts on its
/// radiance and its weight (all rays of a wave have the same depth).
#[derive(Default)]
pub(super) struct Wave {
    pub rays: Rays,
    pub factor: [Vec<f32>; 3],
    pub weight: Vec<f32>,
}

impl Wave {
    pub fn len(&self) -> usize {
        self.rays.len
    }

    pub fn clear(&mut self) {
        self.rays.len = 0;
    }

    /// See [`Rays::room`].
    pub fn room(&mut self, extra: usize) {
        self.rays.room(extra);
        let n = self.rays.t_min.len();
        for c in &mut self.factor {
            c.resize(n, 0.0);
        }
        self.weight.resize(n, 0.0);
    }

    /// Makes `rays` the wave (each with factor and weight 1), column by
    /// column: per ray, seven stores to seven columns, each checked against
    /// its length, cost about 1.5 % of a Whitted frame.
    pub fn start(&mut self, rays: &[Ray]) {
        let n = rays.len();
        self.clear();
        self.room(n);
        let fill = |column: &mut Vec<f32>, get: fn(&Ray) -> f32| {
            for (x, r) in column[..n].iter_mut().zip(rays) {
                *x = get(r);
            }
        };
        let (o, d) = (&mut self.rays.o, &mut self.rays.d);
        fill(&mut o[0], |r| r.o.x);
        fill(&mut o[1], |r| r.o.y);
        fill(&mut o[2], |r| r.o.z);
        fill(&mut d[0], |r| r.d.x);
        fill(&mut d[1], |r| r.d.y);
        fill(&mut d[2], |r| r.d.z);
        fill(&mut self.rays.t_min, |r| r.t_min);
        fill(&mut self.rays.t_max, |r| r.t_max);
        for c in &mut self.factor {
            c[..n].fill(1.0);
        }
        self.weight[..n].fill(1.0);
        self.rays.len = n;
    }

    /// Writes ray `i` (see [`Rays::room`]).
    #[inline(always)]
    pub fn set(&mut self, i: usize, ray: ([f32; 3], [f32; 3]), factor: [f32; 3], weight: f32) {
        self.rays.set(i, ray.0, ray.1, 0.0, f32::INFINITY);
        for (c, f) in self.factor.iter_mut().zip(factor) {
            c[i] = f;
        }
        self.weight[i] = weight;
    }

    pub fn push(&mut self, ray: &Ray, factor: Color, weight: f32) {
        self.room(1);
        let i = self.rays.len;
        self.rays.set_ray(i, ray);
        for (c, f) in self.factor.iter_mut().zip(factor.to_array()) {
            c[i] = f;
        }
        self.weight[i] = weight;
        self.rays.len += 1;
    }
}

/// The rays of the trees, in the order traced (children after their
/// parents): what each one's hit gives before its children's radiance
/// (`local`, with each unblocked shadow ray's term added in turn), the
/// absorption on its way (1 where none: multiplying by 1 is exact), the
/// factor its parent puts on its radiance, and its children (`children` of
/// them from `first_child`).
#[derive(Default)]
pub(super) struct Nodes {
    pub local: [Vec<f32>; 3],
    pub absorption: [Vec<f32>; 3],
    pub factor: [Vec<f32>; 3],
    pub first_child: Vec<u32>,
    pub children: Vec<u32>,
}

impl Nodes {
    pub fn len(&self) -> usize {
        self.children.len()
    }

    pub fn clear(&mut self) {
        self.grow_to(0);
    }

    /// Makes `n` nodes; the new ones with no local term, no absorption and
    /// no children.
    pub fn grow_to(&mut self, n: usize) {
        for c in 0..3 {
            self.local[c].resize(n, 0.0);
            self.absorption[c].resize(n, 1.0);
            self.factor[c].resize(n, 0.0);
        }
        self.first_child.resize(n, 0);
        self.children.resize(n, 0);
    }

    #[inline]
    pub fn set_local(&mut self, i: usize, l: Color) {
        for (c, x) in self.local.iter_mut().zip(l.to_array()) {
            c[i] = x;
        }
    }

    #[inline]
    pub fn add_local(&mut self, i: usize, l: Color) {
        for (c, x) in self.local.iter_mut().zip(l.to_array()) {
            c[i] += x;
        }
    }

    #[inline]
    pub fn set_absorption(&mut self, i: usize, a: Color) {
        for (c, x) in self.absorption.iter_mut().zip(a.to_array()) {
            c[i] = x;
        }
    }

    /// Each node's radiance into `radiance` (by component), from the last
    /// node to the first, so that children's come before their parents':
    /// `L = (local + Σ factor_c·L_c)·absorption`, the sum in children's
    /// order, as the depth-first code adds them.
    pub fn radiance(&self, radiance: &mut [Vec<f32>; 3]) {
        let n = self.len();
        for c in radiance.iter_mut() {
            c.clear();
            c.resize(n, 0.0);
        }
        for i in (0..n).rev() {
            let mut l = [self.local[0][i], self.local[1][i], self.local[2][i]];
            if self.children[i] > 0 {
                let first = self.first_child[i] as usize;
                let children = first..first + self.children[i] as usize;
                // Each component on its own: the same sums, in children's
                // order.
                for (k, l) in l.iter_mut().enumerate() {
                    let factors = &self.factor[k][children.clone()];
                    for (f, r) in factors.iter().zip(&radiance[k][children.clone()]) {
                        *l += f * r;
                    }
                }
            }
            for (k, l) in l.into_iter().enumerate() {
                radiance[k][i] = l * self.absorption[k][i];
            }
        }
    }
}

/// Shadow rays, each with its node and what it adds there if unblocked
/// (the one-by-one path's: the lanes test theirs batch by batch).
#[derive(Default)]
pub(super) struct Shadows {
    pub rays: Rays,
    pub node: Vec<u32>,
    pub gain: Vec<LightGain>,
}

impl Shadows {
    pub fn len(&self) -> usize {
        self.rays.len
    }

    pub fn clear(&mut self) {
        self.rays.len = 0;
        self.node.clear();
        self.gain.clear();
    }

    pub fn push(&mut self, ray: &Ray, node: u32, gain: LightGain) {
        self.rays.room(1);
        self.rays.set_ray(self.rays.len, ray);
        self.rays.len += 1;
        self.node.push(node);
        self.gain.push(gain);
    }
}
