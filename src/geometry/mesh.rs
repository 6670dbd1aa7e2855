//! Triangle meshes: flat arrays owned by the mesh, indexed by its own BVH;
//! instances (a shared mesh plus a transform) are in `mesh/instance.rs`,
//! rays traced in packets in `mesh/packet.rs`.

use super::triangle::{
    LANES, RayShear, TriangleLanes, intersect_watertight, intersect_watertight_lanes,
};
use super::{ShapeHit, SurfacePoint, TraceCounters};
use crate::accel::{Bvh, Bvh8, MAX_PRIMITIVES, PrimRef};
use crate::math::{Aabb, Ray, Vec3, gamma, normalize_robust, triangle_normal};
use glam::{Vec2, Vec4};
use rayon::prelude::*;

mod instance;
mod packet;
pub use instance::MeshInstance;

/// A triangle mesh. Triangles are stored in the BVH's leaf order, so a leaf's
/// triangles are contiguous (the BVH keeps no index array).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    pub positions: Vec<glam::Vec3>,
    pub triangles: Vec<[u32; 3]>,
    /// Per-vertex normals, or empty (flat shading).
    pub normals: Vec<glam::Vec3>,
    /// Per-vertex texture coordinates, or empty.
    pub uvs: Vec<Vec2>,
    /// 8-wide BVH, collapsed from the binary SAH BVH. Where the mesh keeps
    /// [`Mesh::blocks`], each leaf names its first block rather than its
    /// first triangle (see [`Mesh::leaf_triangles`]).
    pub bvh: Bvh8,
    /// For meshes of more than [`SMALL_MESH_TRIANGLES`] triangles, where
    /// memory allows (see [`Mesh::new`]): every leaf's triangles, four to
    /// a block in structure-of-arrays form (the three vertices, as the
    /// watertight test uses them; a last block's spare lanes repeat its
    /// first triangle), the blocks of sibling leaves next to each other. A
    /// leaf is then tested without gathering its vertices through the
    /// index array (Wald et al. 2014, Embree's `Triangle4v`), and the
    /// tree's leaf words point at the blocks directly, as tinybvh's
    /// `BVH8_CPU` and Embree's BVH8 leaves do: no lookup stands between a
    /// node and its triangles.
    blocks: Vec<TriangleLanes>,
    /// For the same meshes: the triangle in lane 0 of each block (the
    /// others follow it).
    block_first: Vec<u32>,
    /// For meshes of at most [`SMALL_MESH_TRIANGLES`] triangles, instead
    /// of blocks: entry `k` holds triangles `k .. k + 4` (the last ones
    /// repeat triangle `k`), so that a leaf starting at any triangle reads
    /// its lanes directly.
    lanes: Vec<TriangleLanes>,
    /// For the same small meshes: each triangle's unit normal, computed once.
    face_normals: Vec<Vec3>,
    /// The mean area of the triangles, for [`Mesh::packet_pays`].
    mean_triangle_area: f32,
}

/// For each mask of four lanes, 1 in the lanes set and 0 in the others (a
/// compare turns it into a lane mask).
const LANE_SET: [Vec4; 1 << LANES] = {
    let mut table = [Vec4::ZERO; 1 << LANES];
    let mut m = 0;
    while m < 1 << LANES {
        table[m] = Vec4::new(
            (m & 1) as f32,
            (m >> 1 & 1) as f32,
            (m >> 2 & 1) as f32,
            (m >> 3 & 1) as f32,
        );
        m += 1;
    }
    table
};

/// Meshes up to this many triangles keep lanes per triangle and face normals
/// (160 bytes per triangle, at most 655 KB a mesh) rather than leaf blocks.
pub const SMALL_MESH_TRIANGLES: usize = 1 << 12;

/// The sizes and distances, in a mesh's own units, at which its triangles
/// are checked to render ([`intersect_watertight`]: its edge functions,
/// products of two lengths, must stay within f32's normal range; the mesh
/// tests render a closed mesh across this whole range). Outside it, some
/// or all of a mesh's triangles may be missed, so loading warns
/// ([`Mesh::scale_problem`]).
pub const CHECKED_SCALES: std::ops::RangeInclusive<f32> = 1e-16..=1e18;

/// Why a mesh could not be built from its arrays.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum MeshDataError {
    #[error("triangle {triangle} refers to vertex {vertex}, but there are only {count} vertices")]
    IndexOutOfRange {
        triangle: usize,
        vertex: u32,
        count: usize,
    },
    #[error("vertex {vertex} has a non-finite coordinate")]
    NonFinite { vertex: usize },
    #[error("{count} triangles; a mesh holds fewer than {limit}")]
    TooManyTriangles { count: usize, limit: usize },
    #[error("{what} has {found} entries for {count} vertices")]
    AttributeCount {
        what: &'static str,
        found: usize,
        count: usize,
    },
}

impl Mesh {
    /// Checks the arrays, builds the BVH (binned SAH, in parallel) and
    /// reorders the triangles into its leaf order. `normals` and `uvs` are
    /// per vertex or empty. Meshes of more than [`SMALL_MESH_TRIANGLES`]
    /// triangles keep their leaves' triangles in blocks where these take
    /// less than half the memory left, whatever the mesh's size.
    pub fn new(
        positions: Vec<glam::Vec3>,
        triangles: Vec<[u32; 3]>,
        normals: Vec<glam::Vec3>,
        uvs: Vec<Vec2>,
    ) -> Result<Mesh, MeshDataError> {
        Self::build(positions, triangles, normals, uvs, true)
    }

    /// [`Mesh::new`], with leaf blocks only if `blocks` (and memory)
    /// allow: the tests build meshes without them, as a machine short of
    /// memory does, to check that gathering the vertices finds the same
    /// hits.
    fn build(
        positions: Vec<glam::Vec3>,
        triangles: Vec<[u32; 3]>,
        normals: Vec<glam::Vec3>,
        uvs: Vec<Vec2>,
        blocks: bool,
    ) -> Result<Mesh, MeshDataError> {
        if triangles.len() >= MAX_PRIMITIVES {
            return Err(MeshDataError::TooManyTriangles {
                count: triangles.len(),
                limit: MAX_PRIMITIVES,
            });
        }
        let count = positions.len();
        if let Some(vertex) = positions.iter().position(|p| !p.is_finite()) {
            return Err(MeshDataError::NonFinite { vertex });
        }
        for (what, found) in [
            ("the normal array", normals.len()),
            ("the uv array", uvs.len()),
        ] {
            if found != 0 && found != count {
                return Err(MeshDataError::AttributeCount { what, found, count });
            }
        }
        if let Some((triangle, &vertex)) = triangles
            .par_iter()
            .enumerate()
            .find_map_first(|(i, t)| t.iter().find(|&&v| v as usize >= count).map(|v| (i, v)))
        {
            return Err(MeshDataError::IndexOutOfRange {
                triangle,
                vertex,
                count,
            });
        }
        let refs: Vec<PrimRef> = triangles
            .par_iter()
            .enumerate()
            .map(|(i, t)| {
                let [a, b, c] = t.map(|i| Vec3::from(positions[i as usize]));
                PrimRef::new(&Aabb::new(a.min(b).min(c), a.max(b).max(c)), i as u32)
            })
            .collect();
        let binary = Bvh::build_refs(refs);
        // Triangles in leaf order; the old order is dropped at once.
        let triangles: Vec<[u32; 3]> = binary
            .indices
            .par_iter()
            .map(|&i| triangles[i as usize])
            .collect();
        let Bvh { nodes, .. } = binary;
        let binary = Bvh {
            nodes,
            indices: Vec::new(),
        };
        let bvh = Bvh8::from_binary(&binary);
        drop(binary);
        let mut mesh = Mesh {
            positions,
            triangles,
            normals,
            uvs,
            bvh,
            blocks: Vec::new(),
            block_first: Vec::new(),
            lanes: Vec::new(),
            face_normals: Vec::new(),
            mean_triangle_area: 0.0,
        };
        let n = mesh.triangles.len();
        let area: f64 = (0..n as u32)
            .into_par_iter()
            .map(|k| {
                let (a, b, c) = mesh.vertices(k);
                f64::from((b - a).cross(c - a).length()) / 2.0
            })
            .sum();
        mesh.mean_triangle_area = (area / n.max(1) as f64) as f32;
        let leaves: Vec<(u32, u32)> = if blocks && n > SMALL_MESH_TRIANGLES {
            mesh.bvh.leaves().collect()
        } else {
            Vec::new()
        };
        let mut starts = Vec::with_capacity(leaves.len());
        let mut total = 0u32;
        for &(_, count) in &leaves {
            starts.push(total);
            total += count.div_ceil(LANES as u32);
        }
        // The blocks are an acceleration: they are left out where they would
        // take more than half the memory left (most of a ray's time then goes
        // to gathering vertices, but the mesh renders).
        let block_bytes = total as u64 * (std::mem::size_of::<TriangleLanes>() as u64 + 4);
        let room = crate::render::memory::available_bytes().is_none_or(|a| block_bytes < a / 2);
        if !leaves.is_empty() && room {
            mesh.blocks = leaves
                .par_iter()
                .flat_map_iter(|&(first, count)| {
                    (0..count.div_ceil(LANES as u32)).map(move |j| {
                        let lo = first + j * LANES as u32;
                        lo..(lo + LANES as u32).min(first + count)
                    })
                })
                .map(|prims| {
                    let ids: [u32; LANES] = std::array::from_fn(|i| prims.start + i as u32);
                    mesh.gather(&ids[..prims.len()])
                })
                .collect();
            mesh.block_first = leaves
                .iter()
                .flat_map(|&(first, count)| {
                    (0..count.div_ceil(LANES as u32)).map(move |j| first + j * LANES as u32)
                })
                .collect();
            // Blocks are numbered in the order `leaves` lists the leaves,
            // which `map_leaves` follows too.
            let mut next = starts.iter();
            mesh.bvh
                .map_leaves(|_, _| *next.next().expect("one start per leaf"));
        }
        if n <= SMALL_MESH_TRIANGLES {
            mesh.lanes = (0..n as u32)
                .map(|k| {
                    let prims: Vec<u32> = (k..(k + LANES as u32).min(n as u32)).collect();
                    mesh.gather(&prims)
                })
                .collect();
            mesh.face_normals = (0..n as u32)
                .map(|k| {
                    let (a, b, c) = mesh.vertices(k);
                    triangle_normal(a, b, c)
                })
                .collect();
        }
        Ok(mesh)
    }

    pub fn bounds(&self) -> Aabb {
        self.bvh.bounds.unwrap_or(Aabb::EMPTY)
    }

    /// What is wrong with the mesh's scale, where it lies outside
    /// [`CHECKED_SCALES`]: coordinates beyond the top of the range, or a
    /// largest extent below its bottom (a whole mesh that small).
    pub fn scale_problem(&self) -> Option<String> {
        let b = self.bvh.bounds?;
        let reach = b.min.abs().max(b.max.abs()).max_element();
        let extent = (b.max - b.min).max_element();
        let (low, high) = (*CHECKED_SCALES.start(), *CHECKED_SCALES.end());
        let what = if reach > high {
            format!("its coordinates reach {reach:.1e}")
        } else if extent < low {
            format!("it is only {extent:.1e} across")
        } else {
            return None;
        };
        Some(format!(
            "{what}; triangles are tested in f32 and are known to render at sizes and distances from {low:e} to {high:e}, so some may be missed: scale the mesh into that range"
        ))
    }

    /// How a leaf reaches its triangles: `None` for small meshes (lanes per
    /// triangle, [`SMALL_MESH_TRIANGLES`]), `Some(true)` where the mesh
    /// keeps leaf blocks, `Some(false)` where they were left out for lack
    /// of memory (every leaf test then gathers its vertices through the
    /// index array, which slows rays down).
    pub fn leaf_blocks(&self) -> Option<bool> {
        (self.triangles.len() > SMALL_MESH_TRIANGLES).then_some(!self.blocks.is_empty())
    }

    /// Bytes of vertex, index and BVH data.
    pub fn bytes(&self) -> usize {
        (self.blocks.len() + self.lanes.len()) * std::mem::size_of::<TriangleLanes>()
            + self.block_first.len() * 4
            + self.face_normals.len() * std::mem::size_of::<Vec3>()
            + self.positions.len() * 12
            + self.triangles.len() * 12
            + self.normals.len() * 12
            + self.uvs.len() * 8
            + self.bvh.bytes()
    }

    #[inline(always)]
    fn vertices(&self, prim: u32) -> (Vec3, Vec3, Vec3) {
        let [a, b, c] = self.triangles[prim as usize];
        let p = &self.positions;
        (
            p[a as usize].into(),
            p[b as usize].into(),
            p[c as usize].into(),
        )
    }

    /// The first triangle of the leaf whose BVH word holds `first`: its
    /// first block's lane 0 where the mesh keeps [`Mesh::blocks`], else
    /// `first` itself. The leaf's `count` triangles follow it. Likewise,
    /// for any block `first`, its lane 0 (as [`Mesh::leaf_lanes`] names
    /// the blocks it hands over).
    #[inline(always)]
    fn leaf_triangles(&self, first: u32) -> u32 {
        if self.blocks.is_empty() {
            first
        } else {
            self.block_first[first as usize]
        }
    }

    /// Checks the BVH as [`Bvh8::validate`] does against the triangles'
    /// boxes, with block-numbered leaves (see [`Mesh::bvh`]) read as the
    /// triangles they hold, and checks that each block holds its leaf's
    /// triangles.
    pub fn validate_bvh(&self) -> Result<(), String> {
        let bounds: Vec<Aabb> = (0..self.triangles.len() as u32)
            .map(|k| {
                let (a, b, c) = self.vertices(k);
                Aabb::new(a.min(b).min(c), a.max(b).max(c))
            })
            .collect();
        let mut bvh = self.bvh.clone();
        let mut bad = None;
        bvh.map_leaves(|first, count| {
            if self.blocks.is_empty() {
                return first;
            }
            let Some(&start) = self.block_first.get(first as usize) else {
                bad.get_or_insert(format!("leaf names block {first}, past the last"));
                return first;
            };
            let n = self.triangles.len() as u32;
            if start.checked_add(count).is_none_or(|end| end > n) {
                bad.get_or_insert(format!("leaf at block {first} starts at triangle {start}"));
                return first;
            }
            for j in 0..count.div_ceil(LANES as u32) {
                let base = start + j * LANES as u32;
                let end = (base + LANES as u32).min(start + count);
                let prims: Vec<u32> = (base..end).collect();
                let k = (first + j) as usize;
                if end > n
                    || self.block_first.get(k) != Some(&base)
                    || self.blocks.get(k) != Some(&self.gather(&prims))
                {
                    bad.get_or_insert(format!("block {k} of the leaf at block {first}"));
                }
            }
            start
        });
        match bad {
            Some(e) => Err(e),
            None => bvh.validate(&bounds),
        }
    }

    /// Calls `visit(lanes, own, at)` for the `count` triangles of the
    /// leaf whose BVH word holds `first` (see [`Mesh::leaf_triangles`]),
    /// four at a time: lane `i` holds triangle `leaf_triangles(at) + i`
    /// where bit `i` of `own` is set (`at` names the block where the mesh
    /// keeps blocks, so that a visit looks its triangle up only for a
    /// hit), and a lane whose bit is clear holds a triangle that is not
    /// the leaf's: the visit must ignore it. Stops when `visit`
    /// returns true, and returns whether it did. Small meshes take the
    /// lanes from [`Mesh::lanes`], larger ones from [`Mesh::blocks`] where
    /// they keep them, else gather the vertices.
    ///
    /// The spare lanes of a block or of gathered lanes repeat lane 0, the
    /// same triangle bit for bit: they hit where lane 0 does, at the same
    /// `t`, so they are handed over as the block's own (all bits set), and
    /// the visits' "first of equals" picks lane 0 over them. Only the lanes
    /// of small meshes, which run on into the next leaf's triangles, are
    /// masked.
    ///
    /// `BLOCKS` says whether the mesh keeps blocks; the callers choose it
    /// once per ray (or packet), outside the traversal, so that a kernel
    /// carries only one way to reach a leaf's triangles: with all three
    /// inlined, the any-hit kernel kept its next node and the bounds of the
    /// other arrays in memory, not registers.
    #[inline(always)]
    fn leaf_lanes<const BLOCKS: bool>(
        &self,
        first: u32,
        count: u32,
        mut visit: impl FnMut(&TriangleLanes, u32, u32) -> bool,
    ) -> bool {
        debug_assert_eq!(BLOCKS, !self.blocks.is_empty());
        const ALL: u32 = (1 << LANES) - 1;
        let blocks = count.div_ceil(LANES as u32);
        if BLOCKS {
            // `first` is the leaf's first block.
            let leaf = &self.blocks[first as usize..(first + blocks) as usize];
            for (lanes, at) in leaf.iter().zip(first..) {
                if visit(lanes, ALL, at) {
                    return true;
                }
            }
            return false;
        }
        if !self.lanes.is_empty() {
            for j in 0..blocks {
                let base = first + j * LANES as u32;
                let left = count - j * LANES as u32;
                let own = if left >= LANES as u32 {
                    ALL
                } else {
                    (1u32 << left) - 1
                };
                if visit(&self.lanes[base as usize], own, base) {
                    return true;
                }
            }
            return false;
        }
        for j in 0..blocks {
            let base = first + j * LANES as u32;
            let n = (count - j * LANES as u32).min(LANES as u32);
            let prims: [u32; LANES] = std::array::from_fn(|i| base + i as u32);
            if visit(&self.gather(&prims[..n as usize]), ALL, base) {
                return true;
            }
        }
        false
    }

    /// Up to [`LANES`] triangles, one per lane; lanes past `prims.len()`
    /// repeat the first triangle.
    #[inline(always)]
    fn gather(&self, prims: &[u32]) -> TriangleLanes {
        let vertex = |i: usize, j: usize| {
            let prim = *prims.get(i).unwrap_or(&prims[0]);
            self.positions[self.triangles[prim as usize][j] as usize]
        };
        let v = |j: usize| {
            let p: [glam::Vec3; LANES] = std::array::from_fn(|i| vertex(i, j));
            [
                Vec4::new(p[0].x, p[1].x, p[2].x, p[3].x),
                Vec4::new(p[0].y, p[1].y, p[2].y, p[3].y),
                Vec4::new(p[0].z, p[1].z, p[2].z, p[3].z),
            ]
        };
        TriangleLanes::new([v(0), v(1), v(2)])
    }

    /// Closest hit of an object-space ray: `(prim, t, b1, b2)`. Triangles
    /// are tested four at a time with the watertight test
    /// ([`intersect_watertight_lanes`]).
    #[inline]
    pub fn intersect_object(&self, ray: &Ray, counters: &mut TraceCounters) -> Option<ShapeHit> {
        if self.blocks.is_empty() {
            self.intersect_in::<false>(ray, counters)
        } else {
            self.intersect_in::<true>(ray, counters)
        }
    }

    /// [`Mesh::intersect_object`] with the leaves reached as `BLOCKS` says
    /// (see [`Mesh::leaf_lanes`]).
    #[inline(always)]
    fn intersect_in<const BLOCKS: bool>(
        &self,
        ray: &Ray,
        counters: &mut TraceCounters,
    ) -> Option<ShapeHit> {
        let mut bary = (0.0, 0.0);
        // Made once the ray enters the tree: most rays past a mesh do not.
        let (prim, t) = self.bvh.closest_leaves_with(
            ray,
            &mut counters.bvh,
            || RayShear::new(ray.o, ray.d),
            #[inline(always)]
            |shear, first, count, t_max| {
                self.leaf_closest::<BLOCKS>(shear, ray.t_min, first, count, t_max, &mut bary)
            },
        )?;
        Some(ShapeHit {
            t,
            prim,
            u: bary.0,
            v: bary.1,
        })
    }

    /// Whether the ray's segment meets one of a leaf's triangles.
    #[inline(always)]
    fn leaf_occludes<const BLOCKS: bool>(
        &self,
        shear: &RayShear,
        ray: &Ray,
        first: u32,
        count: u32,
    ) -> bool {
        self.leaf_lanes::<BLOCKS>(
            first,
            count,
            #[inline(always)]
            |lanes, own, _| {
                let h = intersect_watertight_lanes(shear, lanes, ray.t_min, ray.t_max);
                h.mask & own != 0
            },
        )
    }

    /// The closest hit before `t_max` among a leaf's triangles, the first
    /// of equals, with its barycentrics put in `bary`.
    #[inline(always)]
    fn leaf_closest<const BLOCKS: bool>(
        &self,
        shear: &RayShear,
        t_min: f32,
        first: u32,
        count: u32,
        mut t_max: f32,
        bary: &mut (f32, f32),
    ) -> Option<(u32, f32)> {
        let mut best = None;
        self.leaf_lanes::<BLOCKS>(
            first,
            count,
            #[inline(always)]
            |lanes, own, at| {
                let h = intersect_watertight_lanes(shear, lanes, t_min, t_max);
                // Every lane hit is nearer than `t_max`; the nearest, the
                // first of equals, found in registers: the least `t` of
                // the lanes hit, then the first lane that has it.
                let mask = h.mask & own;
                if mask != 0 {
                    let hit = LANE_SET[mask as usize].cmpne(Vec4::ZERO);
                    let t = Vec4::select(hit, h.t, Vec4::INFINITY);
                    let near = t.min_element();
                    let i = t.cmpeq(Vec4::splat(near)).bitmask().trailing_zeros();
                    let (b1, b2) = (h.b1.to_array(), h.b2.to_array());
                    t_max = near;
                    *bary = (b1[i as usize], b2[i as usize]);
                    best = Some((self.leaf_triangles(at) + i, t_max));
                }
                false
            },
        );
        best
    }

    /// Whether an object-space ray's segment meets the mesh (any hit).
    #[inline]
    pub fn occludes_object(&self, ray: &Ray, counters: &mut TraceCounters) -> bool {
        if self.blocks.is_empty() {
            self.occludes_in::<false>(ray, counters)
        } else {
            self.occludes_in::<true>(ray, counters)
        }
    }

    /// [`Mesh::occludes_object`] with the leaves reached as `BLOCKS` says.
    #[inline(always)]
    fn occludes_in<const BLOCKS: bool>(&self, ray: &Ray, counters: &mut TraceCounters) -> bool {
        self.bvh.any_leaves_with(
            ray,
            &mut counters.bvh,
            || RayShear::new(ray.o, ray.d),
            #[inline(always)]
            |shear, first, count| self.leaf_occludes::<BLOCKS>(shear, ray, first, count),
        )
    }

    /// Calls `hit(t, cos θ)` for every triangle the object-space ray's segment
    /// crosses (watertight test), in no particular order; the second value says
    /// whether a hit lies exactly on an edge or vertex.
    fn all_hits(
        &self,
        ray: &Ray,
        counters: &mut TraceCounters,
        mut hit: impl FnMut(f32, f32, bool),
    ) {
        let d_len = ray.d.length();
        self.bvh.any_leaves(ray, &mut counters.bvh, |first, count| {
            let first = self.leaf_triangles(first);
            for prim in first..first + count {
                let (v0, v1, v2) = self.vertices(prim);
                if let Some((h, on_edge)) =
                    intersect_watertight(ray.o, ray.d, v0, v1, v2, ray.t_min, ray.t_max)
                {
                    let n = triangle_normal(v0, v1, v2);
                    hit(h.t, (n.dot(ray.d) / d_len).abs(), on_edge);
                }
            }
            false
        });
    }

    /// Whether `p` lies inside the closed mesh, by the parity of the number of
    /// triangles a ray from `p` crosses (Jordan curve theorem in 3D). Crossings
    /// are counted with the watertight test; if a ray passes exactly through an
    /// edge or vertex (where it might count one crossing twice or a touching
    /// one once), it is recast in another direction. The answer is meaningless
    /// for a mesh that is not closed.
    pub fn contains(&self, p: Vec3) -> bool {
        // Directions with irrational-looking components: no axis-aligned
        // grazing of axis-aligned geometry.
        const DIRECTIONS: [[f32; 3]; 6] = [
            [0.5377, 0.8244, 0.1768],
            [-0.3123, 0.4417, -0.8411],
            [0.7072, -0.6124, 0.3535],
            [-0.8660, -0.1729, 0.4692],
            [0.1209, -0.9103, -0.3958],
            [0.6305, 0.2112, -0.7470],
        ];
        let mut votes = 0;
        for d in DIRECTIONS {
            let ray = Ray::new(p, Vec3::from_array(d));
            let (mut count, mut ambiguous) = (0u32, false);
            self.all_hits(&ray, &mut TraceCounters::default(), |_, _, on_edge| {
                count += 1;
                ambiguous |= on_edge;
            });
            if !ambiguous {
                return count % 2 == 1;
            }
            votes += (count % 2) as i32 * 2 - 1;
        }
        votes > 0
    }

    /// Surface at an object-space hit: the point rebuilt from barycentrics
    /// (error bound γ(7)·Σ|bᵢvᵢ|, pbrt-v4 §6.8.4), the geometric normal
    /// `(v1 − v0) × (v2 − v0)` (outward for counter-clockwise winding), and the
    /// shading normal interpolated from vertex normals when the mesh has them.
    pub fn surface_object(&self, hit: &ShapeHit) -> SurfacePoint {
        let (v0, v1, v2) = self.vertices(hit.prim);
        let (b1, b2) = (hit.u, hit.v);
        let b0 = (1.0 - b1 - b2).max(0.0);
        let p = b0 * v0 + b1 * v1 + b2 * v2;
        let p_err = gamma(7) * ((b0 * v0).abs() + (b1 * v1).abs() + (b2 * v2).abs());
        let n = match self.face_normals.get(hit.prim as usize) {
            Some(&n) => n,
            None => triangle_normal(v0, v1, v2),
        };
        let ns = if self.normals.is_empty() {
            n
        } else {
            let [a, b, c] = self.triangles[hit.prim as usize];
            let nm = &self.normals;
            let s = Vec3::from(nm[a as usize]) * b0
                + Vec3::from(nm[b as usize]) * b1
                + Vec3::from(nm[c as usize]) * b2;
            let ns = normalize_robust(s);
            if ns == Vec3::ZERO { n } else { ns }
        };
        SurfacePoint { p, p_err, n, ns }
    }

    /// Texture coordinates at an object-space point of triangle `prim`,
    /// interpolated from the mesh's uvs; `None` if the mesh has none.
    pub fn uv_object(&self, p: Vec3, prim: u32) -> Option<Vec2> {
        if self.uvs.is_empty() {
            return None;
        }
        // In f64: |n|² is a fourth power of the triangle's size, which f32
        // cannot hold for meshes written at scales past 1e±9.
        let (v0, v1, v2) = self.vertices(prim);
        let (v0, v1, v2, p) = (v0.as_dvec3(), v1.as_dvec3(), v2.as_dvec3(), p.as_dvec3());
        let n = (v1 - v0).cross(v2 - v0);
        let area = n.length_squared();
        let [a, b, c] = self.triangles[prim as usize];
        if area == 0.0 {
            return Some(self.uvs[a as usize]);
        }
        let b1 = ((p - v0).cross(v2 - v0).dot(n) / area) as f32;
        let b2 = ((v1 - v0).cross(p - v0).dot(n) / area) as f32;
        Some(
            self.uvs[a as usize] * (1.0 - b1 - b2)
                + self.uvs[b as usize] * b1
                + self.uvs[c as usize] * b2,
        )
    }
}

#[cfg(test)]
mod tests;
