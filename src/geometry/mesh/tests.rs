//! Tests of [`super`]: the leaf blocks and their numbering.

use super::*;
use crate::geometry::testgen::torus;

/// A mesh with leaf blocks, whose BVH leaves then name blocks.
fn blocked() -> Mesh {
    let (v, f) = torus(2.0, 0.6, 96, 48);
    let m = Mesh::new(v, f, vec![], vec![]).unwrap();
    assert!(m.triangles.len() > SMALL_MESH_TRIANGLES && !m.blocks.is_empty());
    m
}

#[test]
fn block_numbered_leaves_validate_and_hold_their_triangles() {
    let m = blocked();
    assert_eq!(m.validate_bvh(), Ok(()));
    // Every triangle is reached through exactly one leaf's blocks.
    let mut seen = vec![0u32; m.triangles.len()];
    for (first, count) in m.bvh.leaves() {
        m.leaf_lanes::<true>(first, count, |_, own, prims| {
            for i in 0..LANES {
                if own & 1 << i != 0 {
                    seen[prims[i] as usize] += 1;
                }
            }
            false
        });
    }
    assert!(seen.iter().all(|&s| s == 1));
}

#[test]
fn validation_notices_a_wrong_block() {
    let mut m = blocked();
    m.blocks.swap(3, 4);
    assert!(m.validate_bvh().is_err());
    let mut m = blocked();
    m.block_first[5] += 1;
    assert!(m.validate_bvh().is_err());
    // Out of range: an error, not a panic.
    let mut m = blocked();
    m.block_first[5] = u32::MAX - 8;
    assert!(m.validate_bvh().is_err());
    let mut m = blocked();
    let past = m.blocks.len() as u32 + 5;
    m.bvh
        .map_leaves(|first, _| if first == 7 { past } else { first });
    assert!(m.validate_bvh().is_err());
    let mut m = blocked();
    m.bvh
        .map_leaves(|first, _| if first == 7 { 8 } else { first });
    assert!(m.validate_bvh().is_err());
}
