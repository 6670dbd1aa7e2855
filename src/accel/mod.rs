//! Acceleration structures. The BVH sees boxes only, never shapes: the same
//! code serves a mesh's triangles and the scene's objects.

mod bvh;
mod bvh8;

pub use bvh::{Bvh, BvhNode, PrimRef, TraversalCounters};
pub use bvh8::{Bvh8, Bvh8Node, force_portable};
