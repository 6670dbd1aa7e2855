//! Arbitrary output variables (AOVs): per-pixel layers besides the image —
//! what the first camera ray of a pixel hit (depth, normal, albedo, object),
//! and what the pixel cost (BVH nodes visited and primitives tested, rays
//! by kind, implicit-surface evaluations).
//!
//! A render gathers them only when asked (a branch per pixel otherwise), so
//! an ordinary render does not pay for them. The counting layers are the
//! differences of the render's own counters across each pixel, so they add
//! up exactly to the render's statistics.

use crate::math::{Color, Ray, Vec3};
use crate::scene::{Scene, TraceCounters};

/// An output variable, as named on the command line (`--aov depth,cost`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Aov {
    /// Distance from the eye to the first hit of the pixel's first camera
    /// ray, along the ray (0 where it hits nothing).
    Depth,
    /// The unit shading normal there, facing the eye (0 where nothing is hit).
    Normal,
    /// The surface colour there (the material's texture), linear RGB.
    Albedo,
    /// The index of the object hit there, from 1 (0: nothing).
    Id,
    /// BVH nodes visited and primitives (triangles) tested inside meshes, by
    /// all of the pixel's rays (the statistics' `bvh_nodes_visited` and
    /// `triangle_tests`).
    Cost,
    /// The pixel's rays by kind: camera, shadow, reflection, refraction.
    Rays,
    /// Interval evaluations of implicit surfaces' formulas by the pixel's
    /// root searches.
    Evals,
}

impl Aov {
    pub const ALL: [Aov; 7] = [
        Aov::Depth,
        Aov::Normal,
        Aov::Albedo,
        Aov::Id,
        Aov::Cost,
        Aov::Rays,
        Aov::Evals,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Aov::Depth => "depth",
            Aov::Normal => "normal",
            Aov::Albedo => "albedo",
            Aov::Id => "id",
            Aov::Cost => "cost",
            Aov::Rays => "rays",
            Aov::Evals => "evals",
        }
    }

    pub fn from_name(name: &str) -> Option<Aov> {
        Aov::ALL.into_iter().find(|a| a.name() == name)
    }

    /// Whether it is a count (summed over the pixel's samples), as opposed
    /// to a property of the first hit.
    pub fn is_count(self) -> bool {
        matches!(self, Aov::Cost | Aov::Rays | Aov::Evals)
    }

    /// The EXR channels it writes.
    pub fn channels(self) -> &'static [&'static str] {
        match self {
            Aov::Depth => &["Z"],
            Aov::Normal => &["N.X", "N.Y", "N.Z"],
            Aov::Albedo => &["albedo.R", "albedo.G", "albedo.B"],
            Aov::Id => &["id"],
            Aov::Cost => &["cost.nodes", "cost.prims"],
            Aov::Rays => &[
                "rays.camera",
                "rays.shadow",
                "rays.reflection",
                "rays.refraction",
            ],
            Aov::Evals => &["implicit.evals"],
        }
    }
}

/// Parses `depth,cost,…` (duplicates are kept once).
pub fn parse_aovs(list: &str) -> Result<Vec<Aov>, String> {
    let mut aovs = Vec::new();
    for name in list.split(',').map(str::trim).filter(|n| !n.is_empty()) {
        let aov = Aov::from_name(name).ok_or_else(|| {
            let names: Vec<&str> = Aov::ALL.iter().map(|a| a.name()).collect();
            format!(
                "unknown AOV `{name}`; expected some of: {}",
                names.join(", ")
            )
        })?;
        if !aovs.contains(&aov) {
            aovs.push(aov);
        }
    }
    if aovs.is_empty() {
        return Err("expected AOV names separated by commas".into());
    }
    Ok(aovs)
}

/// One channel's value: a float or a count.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AovValue {
    F32(f32),
    U32(u32),
}

impl AovValue {
    pub fn as_f64(self) -> f64 {
        match self {
            AovValue::F32(v) => v as f64,
            AovValue::U32(v) => v as f64,
        }
    }
}

/// Every output variable of one pixel. Counts above 2^32 − 1 saturate.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AovPixel {
    pub depth: f32,
    pub normal: [f32; 3],
    pub albedo: [f32; 3],
    pub id: u32,
    pub nodes: u32,
    pub prims: u32,
    /// Camera, shadow, reflection, refraction.
    pub rays: [u32; 4],
    pub evals: u32,
}

impl AovPixel {
    /// Channel `k` of `aov` (in the order of [`Aov::channels`]).
    pub fn value(&self, aov: Aov, k: usize) -> AovValue {
        match aov {
            Aov::Depth => AovValue::F32(self.depth),
            Aov::Normal => AovValue::F32(self.normal[k]),
            Aov::Albedo => AovValue::F32(self.albedo[k]),
            Aov::Id => AovValue::U32(self.id),
            Aov::Cost => AovValue::U32([self.nodes, self.prims][k]),
            Aov::Rays => AovValue::U32(self.rays[k]),
            Aov::Evals => AovValue::U32(self.evals),
        }
    }

    /// Sets channel `k` of `aov` (the inverse of [`AovPixel::value`]; a value
    /// of the wrong kind is converted).
    pub fn set(&mut self, aov: Aov, k: usize, v: AovValue) {
        let f = || match v {
            AovValue::F32(x) => x,
            AovValue::U32(x) => x as f32,
        };
        let u = || match v {
            AovValue::U32(x) => x,
            AovValue::F32(x) => x as u32,
        };
        match aov {
            Aov::Depth => self.depth = f(),
            Aov::Normal => self.normal[k] = f(),
            Aov::Albedo => self.albedo[k] = f(),
            Aov::Id => self.id = u(),
            Aov::Cost => *[&mut self.nodes, &mut self.prims][k] = u(),
            Aov::Rays => self.rays[k] = u(),
            Aov::Evals => self.evals = u(),
        }
    }

    /// Merges another part's pixel: counts add (saturating); with `first`
    /// (the other holds the pixel's first sample), the first hit's layers
    /// are taken from it.
    pub fn merge(&mut self, other: &AovPixel, first: bool) {
        self.nodes = self.nodes.saturating_add(other.nodes);
        self.prims = self.prims.saturating_add(other.prims);
        self.evals = self.evals.saturating_add(other.evals);
        for (a, b) in self.rays.iter_mut().zip(other.rays) {
            *a = a.saturating_add(b);
        }
        if first {
            self.depth = other.depth;
            self.normal = other.normal;
            self.albedo = other.albedo;
            self.id = other.id;
        }
    }

    /// What the first hit of `ray` (the pixel's first camera ray) shows:
    /// traced again with counters of its own, so the counting layers stay
    /// those of the render.
    pub fn first_hit(&mut self, scene: &Scene, ray: &Ray) {
        let mut scratch = TraceCounters::default();
        let Some(hit) = scene.intersect(ray, &mut scratch) else {
            return;
        };
        let si = scene.surface(ray, &hit);
        let d = ray.d;
        self.depth = finite_or_zero(hit.t * d.length());
        let n = if si.ns.dot(d) > 0.0 { -si.ns } else { si.ns };
        self.normal = n.to_array().map(finite_or_zero);
        let albedo: Color = scene.albedo(&si);
        self.albedo = albedo.to_array().map(finite_or_zero);
        self.id = si.object.saturating_add(1);
    }
}

fn finite_or_zero(v: f32) -> f32 {
    if v.is_finite() { v } else { 0.0 }
}

/// A count as a channel value, saturating.
#[inline]
pub fn count32(v: u64) -> u32 {
    v.min(u32::MAX as u64) as u32
}

/// A unit vector's colour in a normal map: `(n + 1) / 2` per channel.
pub fn normal_color(n: [f32; 3]) -> Color {
    if n == [0.0; 3] {
        return Color::ZERO;
    }
    Vec3::from_array(n) * 0.5 + Vec3::splat(0.5)
}
