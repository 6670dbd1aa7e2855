//! Acceleration structures. The BVH sees boxes only, never shapes: the same
//! code serves a mesh's triangles and the scene's objects.

mod bvh;

pub use bvh::{Bvh, BvhNode, TraversalCounters};
