//! `glint info`: a mesh file's counts, bounds, load and build times and
//! memory.

use super::{count, group, peak_rss_bytes};
use anyhow::Result;
use glint::scene;
use std::path::Path;

/// Loads the mesh file at `path` and prints what it holds and cost.
pub(crate) fn run(path: &Path) -> Result<()> {
    let model = scene::meshio::load_mesh_file(path)?;
    for w in &model.warnings {
        eprintln!("warning: {w}");
    }
    let mut bounds = glint::math::Aabb::EMPTY;
    let (mut vertices, mut triangles, mut nodes, mut bvh_bytes, mut bytes) = (0, 0, 0, 0, 0);
    let mut seen = std::collections::HashSet::new();
    // Distinct meshes large enough for leaf blocks, and those left without.
    let (mut large, mut gathering) = (0u64, 0u64);
    for part in &model.parts {
        let instance =
            glint::geometry::MeshInstance::new(part.mesh.clone(), part.transform.as_ref());
        bounds = bounds.union(&instance.bounds());
        if seen.insert(std::sync::Arc::as_ptr(&part.mesh)) {
            if let Some(kept) = part.mesh.leaf_blocks() {
                large += 1;
                gathering += u64::from(!kept);
            }
            vertices += part.mesh.positions.len();
            triangles += part.mesh.triangles.len();
            nodes += part.mesh.bvh.nodes.len();
            bvh_bytes += part.mesh.bvh.bytes();
            bytes += part.mesh.bytes();
        }
    }
    let per = |b: usize| b as f64 / triangles.max(1) as f64;
    println!("{}", path.display());
    println!(
        "  parts        {} ({})",
        model.parts.len(),
        count(seen.len() as u64, "distinct mesh", "distinct meshes")
    );
    println!("  vertices     {}", group(vertices as u64));
    println!("  triangles    {}", group(triangles as u64));
    println!(
        "  bounds       {:?} .. {:?}",
        bounds.min.to_array(),
        bounds.max.to_array()
    );
    println!(
        "  load         {:.3} s ({:.1} M triangles/s)",
        model.seconds_load,
        triangles as f64 / model.seconds_load.max(1e-9) / 1e6
    );
    println!(
        "  BVH build    {:.3} s ({:.1} M triangles/s), {} nodes",
        model.seconds_build,
        triangles as f64 / model.seconds_build.max(1e-9) / 1e6,
        group(nodes as u64)
    );
    println!(
        "  memory       {:.1} MB in all, {:.1} bytes per triangle ({:.1} of them BVH)",
        bytes as f64 / 1e6,
        per(bytes),
        per(bvh_bytes)
    );
    if gathering > 0 {
        println!(
            "  leaf blocks  left out of {gathering} of {} for lack of memory: their leaf tests gather vertices (slower rays)",
            count(large, "large mesh", "large meshes")
        );
    } else if large > 0 {
        println!(
            "  leaf blocks  kept ({}: each leaf's triangles stored as the test reads them)",
            count(large, "large mesh", "large meshes")
        );
    }
    if let Some(peak) = peak_rss_bytes() {
        println!("  peak RSS     {:.1} MB", peak as f64 / 1e6);
    }
    if let Some(c) = &model.camera {
        println!(
            "  camera       at {:?} looking at {:?}, fov {:.1}°",
            c.position.to_array(),
            c.look_at.to_array(),
            c.fov_y_deg
        );
    }
    Ok(())
}
