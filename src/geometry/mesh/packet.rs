//! Mesh rays traced in packets of up to [`PACKET`]: the packet traversal
//! of the mesh's BVH ([`Bvh8::closest_packet`](crate::accel::Bvh8::closest_packet), [`Bvh8::any_packet`](crate::accel::Bvh8::any_packet)) with
//! the leaf tests of `mesh.rs`, and the choice, packet by packet, of
//! tracing the rays together or one by one ([`Mesh::packet_pays`]).

use super::{Mesh, ShapeHit, TraceCounters};
use crate::accel::PACKET;
use crate::geometry::triangle::RayShear;
use crate::math::{Ray, Vec3};

/// A packet whose rays lie farther apart where they enter the mesh's
/// bounds than this many mean triangle areas per ray is traced one ray at a
/// time (see [`Mesh::packet_pays`]).
const PACKET_TRIANGLES_PER_RAY: f32 = 4.0;

/// The [`RayShear`] of each ray of a packet, all made at once (spare
/// slots get a fixed, unused one).
#[inline(always)]
fn packet_shears(rays: &[Ray]) -> [RayShear; PACKET] {
    std::array::from_fn(|r| match rays.get(r) {
        Some(ray) => RayShear::new(ray.o, ray.d),
        None => RayShear::new(Vec3::ZERO, Vec3::Z),
    })
}

/// The [`RayShear`] of each ray of a packet of closest-hit rays, made when
/// the ray first reaches a leaf: most rays of a camera packet that passes a
/// mesh by reach none, and a shear costs a division (made for all sixteen
/// up front, it made packets of camera rays slower than single rays on a
/// mesh that covers little of the frame). Shadow rays start on a surface
/// and nearly all reach a leaf: [`packet_shears`] makes theirs up front,
/// which takes fewer instructions (`benches/ir.py`).
struct PacketShears<'a> {
    rays: &'a [Ray],
    made: [Option<RayShear>; PACKET],
}

impl<'a> PacketShears<'a> {
    #[inline(always)]
    fn new(rays: &'a [Ray]) -> Self {
        PacketShears {
            rays,
            made: [None; PACKET],
        }
    }

    /// Ray `r`'s shear.
    #[inline(always)]
    fn get(&mut self, r: usize) -> &RayShear {
        let ray = &self.rays[r];
        self.made[r].get_or_insert_with(|| RayShear::new(ray.o, ray.d))
    }
}

impl Mesh {
    /// Whether up to [`PACKET`] coherent object-space rays are faster
    /// traced together ([`Bvh8::closest_packet`](crate::accel::Bvh8::closest_packet), [`Bvh8::any_packet`](crate::accel::Bvh8::any_packet))
    /// than one by one, judged from the first and the last ray (the
    /// corners of a block of camera rays, or of the shadow rays from their
    /// hits) where they enter the mesh's bounds: a packet pays while its
    /// rays are close together against the triangles, and loses once each
    /// ray covers more than [`PACKET_TRIANGLES_PER_RAY`] mean triangle
    /// areas there, since its rays then part near the root and the packet
    /// tests visit nodes for one or two rays each. (Rays traced in a
    /// 1080p frame, each packet timed both ways and the packets binned by
    /// that ratio: on lucy and its subdivisions to 25.6M triangles and on
    /// the bumpy icosphere, packets took 0.6–0.9 of the single rays' time
    /// below 2 triangle areas per ray, about 1.0 at 4, and 1.1–1.45 from
    /// 16 up, the same on every mesh.) A packet of closest-hit rays
    /// neither of whose corner rays enters the bounds is taken as passing
    /// the mesh by, and those rays are cheaper one by one (a miss at the
    /// root costs about 30 cycles alone; packets of such rays took 1.25×
    /// their time); packets of shadow rays that pass by that way stay
    /// packets, which took 0.6–0.7× the single rays' time.
    #[inline]
    pub(super) fn packet_pays(&self, rays: &[Ray], closest: bool) -> bool {
        let (Some(first), Some(last)) = (rays.first(), rays.last()) else {
            return false;
        };
        // Where each corner ray enters the bounds (the slab test without
        // branches; infinite where it misses them).
        let bounds = self.bounds();
        let entry = |ray: &Ray| {
            let inv = ray.d.recip();
            let (a, b) = ((bounds.min - ray.o) * inv, (bounds.max - ray.o) * inv);
            let enter = a.min(b).max_element().max(ray.t_min);
            let exit = a.max(b).min_element().min(ray.t_max);
            if enter <= exit { enter } else { f32::INFINITY }
        };
        let (t_first, t_last) = (entry(first), entry(last));
        let t = if t_first.is_finite() { t_first } else { t_last };
        if !t.is_finite() {
            return !closest;
        }
        let apart = (first.o + t * first.d).distance_squared(last.o + t * last.d);
        apart <= PACKET_TRIANGLES_PER_RAY * self.mean_triangle_area * rays.len() as f32
    }

    /// [`Mesh::intersect_object`] for up to [`PACKET`] coherent rays at
    /// once ([`Bvh8::closest_packet`](crate::accel::Bvh8::closest_packet), or one by one where
    /// [`Mesh::packet_pays`] says so: the same `t` for every ray; where
    /// two triangles are hit at exactly that `t`, either may be returned).
    pub fn intersect_packet(
        &self,
        rays: &[Ray],
        counters: &mut TraceCounters,
        out: &mut [Option<ShapeHit>],
    ) {
        assert!(rays.len() <= PACKET && out.len() == rays.len());
        if self.packet_pays(rays, true) {
            self.intersect_as_packet(rays, counters, out);
        } else {
            for (o, ray) in out.iter_mut().zip(rays) {
                *o = self.intersect_object(ray, counters);
            }
        }
    }

    /// [`Mesh::intersect_packet`] always as one packet, whatever
    /// [`Mesh::packet_pays`] would say (for the tests and benchmarks of
    /// the packet traversal).
    pub fn intersect_as_packet(
        &self,
        rays: &[Ray],
        counters: &mut TraceCounters,
        out: &mut [Option<ShapeHit>],
    ) {
        if self.blocks.is_empty() {
            self.intersect_packet_in::<false>(rays, counters, out)
        } else {
            self.intersect_packet_in::<true>(rays, counters, out)
        }
    }

    /// [`Mesh::intersect_packet`] with the leaves reached as `BLOCKS` says.
    #[inline(always)]
    fn intersect_packet_in<const BLOCKS: bool>(
        &self,
        rays: &[Ray],
        counters: &mut TraceCounters,
        out: &mut [Option<ShapeHit>],
    ) {
        assert!(rays.len() <= PACKET && out.len() == rays.len());
        let mut bary = [(0.0, 0.0); PACKET];
        let mut hits = [None; PACKET];
        let mut shears = PacketShears::new(rays);
        self.bvh.closest_packet(
            rays,
            &mut counters.bvh,
            #[inline(always)]
            |r, first, count, t_max| {
                let t_min = rays[r].t_min;
                let shear = shears.get(r);
                self.leaf_closest::<BLOCKS>(shear, t_min, first, count, t_max, &mut bary[r])
            },
            &mut hits[..rays.len()],
        );
        for (r, o) in out.iter_mut().enumerate() {
            *o = hits[r].map(|(prim, t)| ShapeHit {
                t,
                prim,
                u: bary[r].0,
                v: bary[r].1,
            });
        }
    }

    /// [`Mesh::occludes_object`] for up to [`PACKET`] coherent rays at once
    /// ([`Bvh8::any_packet`](crate::accel::Bvh8::any_packet), or one by one where [`Mesh::packet_pays`]
    /// says so): the same answers.
    pub fn occludes_packet(&self, rays: &[Ray], counters: &mut TraceCounters, out: &mut [bool]) {
        assert!(rays.len() <= PACKET && out.len() == rays.len());
        if self.packet_pays(rays, false) {
            self.occludes_as_packet(rays, counters, out);
        } else {
            for (o, ray) in out.iter_mut().zip(rays) {
                *o = self.occludes_object(ray, counters);
            }
        }
    }

    /// [`Mesh::occludes_packet`] always as one packet (for the tests and
    /// benchmarks of the packet traversal).
    pub fn occludes_as_packet(&self, rays: &[Ray], counters: &mut TraceCounters, out: &mut [bool]) {
        if self.blocks.is_empty() {
            self.occludes_packet_in::<false>(rays, counters, out)
        } else {
            self.occludes_packet_in::<true>(rays, counters, out)
        }
    }

    /// [`Mesh::occludes_packet`] with the leaves reached as `BLOCKS` says.
    #[inline(always)]
    fn occludes_packet_in<const BLOCKS: bool>(
        &self,
        rays: &[Ray],
        counters: &mut TraceCounters,
        out: &mut [bool],
    ) {
        let shears = packet_shears(rays);
        self.bvh.any_packet(
            rays,
            &mut counters.bvh,
            #[inline(always)]
            |r, first, count| self.leaf_occludes::<BLOCKS>(&shears[r], &rays[r], first, count),
            out,
        );
    }
}
