//! Acceleration structures. The BVH sees boxes only, never shapes: the same
//! code serves a mesh's triangles and the scene's objects.

mod bvh;
mod bvh4;

pub use bvh::{Bvh, BvhNode, PrimRef, TraversalCounters};
pub use bvh4::{Bvh4, Bvh4Node};
