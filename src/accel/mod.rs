//! Acceleration structures. The BVH sees boxes only, never shapes: the same
//! code serves a mesh's triangles and the scene's objects.
//!
//! - `bvh`: the binary BVH, its node layout and traversal; `bvh/build.rs`
//!   its binned SAH build;
//! - `bvh8`: the 8-wide BVH's node layout; `bvh8/collapse.rs` makes it
//!   from a binary one, `bvh8/traverse.rs` traverses it (AVX2 or portable);
//! - `tlas` ([`Tlas`]): the top level over a scene's objects.

mod bvh;
mod bvh8;
mod tlas;

pub use bvh::{Bvh, BvhNode, PrimRef, TraversalCounters};
pub use bvh8::{Bvh8, Bvh8Node, MAX_PRIMITIVES, PACKET, force_portable};
pub use tlas::Tlas;
