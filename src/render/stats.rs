//! Render statistics, shown after a render and written by `--stats-json`.

use serde::Serialize;

/// Rays traced, by kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct RayCounts {
    pub camera: u64,
    pub shadow: u64,
    pub reflection: u64,
    pub refraction: u64,
}

impl RayCounts {
    pub fn total(&self) -> u64 {
        self.camera + self.shadow + self.reflection + self.refraction
    }
}

/// Per-tile work counters, summed into [`RenderStats`] in tile order.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TileCounters {
    pub rays: RayCounts,
    pub intersection_tests: u64,
    pub implicit_searches: u64,
    pub implicit_evaluations: u64,
    pub bvh_nodes_visited: u64,
    pub triangle_tests: u64,
    /// Samples whose radiance was NaN or infinite (replaced by black).
    pub bad_samples: u64,
    /// Pixels with at least one such sample.
    pub nan_pixels: u64,
    /// Camera samples whose ray tree reached `MAX_RAY_TREE` secondary rays.
    pub ray_trees_cut: u64,
    /// Implicit root searches that gave up at `MAX_SEARCH_EVALUATIONS`.
    pub implicit_searches_cut: u64,
}

impl std::ops::AddAssign for TileCounters {
    fn add_assign(&mut self, o: Self) {
        self.rays.camera += o.rays.camera;
        self.rays.shadow += o.rays.shadow;
        self.rays.reflection += o.rays.reflection;
        self.rays.refraction += o.rays.refraction;
        self.intersection_tests += o.intersection_tests;
        self.implicit_searches += o.implicit_searches;
        self.implicit_evaluations += o.implicit_evaluations;
        self.bvh_nodes_visited += o.bvh_nodes_visited;
        self.triangle_tests += o.triangle_tests;
        self.bad_samples += o.bad_samples;
        self.nan_pixels += o.nan_pixels;
        self.ray_trees_cut += o.ray_trees_cut;
        self.implicit_searches_cut += o.implicit_searches_cut;
    }
}

/// What a render did and how long it took.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct RenderStats {
    /// The frame.
    pub width: u32,
    pub height: u32,
    /// The pixels rendered, `[x0, x1, y0, y1]` (the whole frame without a crop).
    pub crop: [u32; 4],
    /// Samples `sample_offset .. sample_offset + spp` of each pixel.
    pub spp: u32,
    pub sample_offset: u32,
    pub integrator: String,
    pub max_depth: i32,
    pub threads: usize,
    /// Time to read and build the scene (filled in by the caller that loaded it).
    pub seconds_load: f64,
    pub seconds_render: f64,
    pub rays: RayCounts,
    pub rays_total: u64,
    pub rays_per_second: f64,
    /// Camera samples (paths, for the path integrator) per second.
    pub samples_per_second: f64,
    /// Ray–shape intersection tests, all ray kinds.
    pub intersection_tests: u64,
    /// Root searches on implicit surfaces (rays that entered their bounds).
    pub implicit_searches: u64,
    /// Interval evaluations of implicit surfaces' formulas (root isolation).
    pub implicit_evaluations: u64,
    /// `implicit_evaluations` per root search.
    pub implicit_evaluations_per_search: f64,
    /// `implicit_evaluations` per ray (all kinds).
    pub implicit_evaluations_per_ray: f64,
    /// BVH nodes visited inside meshes, all rays.
    pub bvh_nodes_visited: u64,
    /// Ray–triangle tests, all rays.
    pub triangle_tests: u64,
    /// `bvh_nodes_visited` and `triangle_tests` per ray (all kinds).
    pub bvh_nodes_visited_per_ray: f64,
    pub triangle_tests_per_ray: f64,
    /// Pixels that had a NaN or infinite sample (each such sample counts as black).
    pub nan_pixels: u64,
    pub bad_samples: u64,
    /// Camera samples whose ray tree was cut at `MAX_RAY_TREE` secondary
    /// rays (Whitted with a large `max_depth` and a tiny `min_weight`).
    pub ray_trees_cut: u64,
    /// Implicit root searches that gave up after `MAX_SEARCH_EVALUATIONS`
    /// interval evaluations (and reported no root).
    pub implicit_searches_cut: u64,
}
