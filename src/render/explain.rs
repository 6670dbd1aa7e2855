//! The ray tree of one pixel sample (`glint explain`): every ray the
//! integrator traced for it — the eye ray, the reflected and refracted rays
//! each hit spawned, the shadow rays to each light — with what each hit,
//! what it carried and what it gave the pixel.
//!
//! Contributions: a camera, reflected or refracted ray gives the pixel its
//! *throughput* (the product of the factors on its way to the pixel:
//! reflectances, Fresnel weights, absorption) times its *local* term (the
//! background where it hits nothing; otherwise the ambient term plus the
//! light its shadow rays brought). These add up to the pixel's sample. A
//! shadow ray's contribution is its part of its parent's.

use super::integrator::{Counters, Integrator, RayKind, Raycast, Recorder, Whitted};
use super::sampler::PixelSamples;
use crate::math::{Color, Ray};
use crate::scene::{Hit, Scene, TraceCounters};
use crate::settings::{IntegratorKind, RenderSettings};
use serde::Serialize;

/// What a ray hit.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HitInfo {
    /// The object, numbered from 1 in the scene's order (as the `id` AOV;
    /// each part of a mesh file is one object).
    pub object: u32,
    /// sphere, plane, box, implicit or mesh.
    pub shape: &'static str,
    /// The triangle, for a mesh.
    pub triangle: Option<u32>,
    pub t: f32,
    pub point: [f32; 3],
    /// Unit geometric normal (outward for closed shapes).
    pub normal: [f32; 3],
    /// Whether the ray met the outside of the surface.
    pub front_face: bool,
    /// The material's index in the scene.
    pub material: u32,
}

/// One ray of the tree.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RayNode {
    pub id: usize,
    pub parent: Option<usize>,
    pub kind: RayKind,
    pub origin: [f32; 3],
    pub direction: [f32; 3],
    pub t_min: f32,
    pub t_max: f32,
    /// What it hit; `None`: nothing (a camera, reflected or refracted ray
    /// then sees the background; a shadow ray reaches its light).
    pub hit: Option<HitInfo>,
    /// Shadow rays: the light (from 1, in the scene's order), the
    /// transmittance, and the opaque object (numbered as `hit.object`) that
    /// blocked the ray, if one did.
    pub light: Option<usize>,
    pub transmittance: Option<[f32; 3]>,
    pub blocked_by: Option<u32>,
    /// Dielectric hits: the Fresnel reflectance and transmittance.
    pub fresnel: Option<[f32; 2]>,
    /// The factor the ray's radiance is multiplied by on its way to the
    /// pixel (a shadow ray: its parent's, after absorption).
    pub throughput: [f32; 3],
    /// The local term at the hit (or the background); for a shadow ray, the
    /// light it brought.
    pub local: [f32; 3],
    /// `throughput × local`: what this ray alone gives the pixel.
    pub contribution: [f32; 3],
    /// What the ray returned to its parent (its subtree's radiance).
    pub radiance: [f32; 3],
    /// Work of its intersection query: BVH nodes visited and primitives
    /// tested inside meshes, shape tests, implicit-surface evaluations.
    pub bvh_nodes: u64,
    pub primitives: u64,
    pub intersection_tests: u64,
    pub implicit_evaluations: u64,
}

/// The rays of one pixel sample, parents before children (depth first).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct RayTree {
    pub nodes: Vec<RayNode>,
    /// The rays begun and not yet ended, innermost last.
    #[serde(skip)]
    open: Vec<usize>,
}

impl RayTree {
    /// The sum of the contributions of camera, reflected and refracted rays.
    pub fn total(&self) -> Color {
        self.nodes
            .iter()
            .filter(|n| n.kind != RayKind::Shadow)
            .map(|n| Color::from_array(n.contribution))
            .fold(Color::ZERO, |a, c| a + c)
    }

    /// The depth of node `i` (camera ray: 0).
    pub fn depth(&self, i: usize) -> usize {
        let mut d = 0;
        let mut p = self.nodes[i].parent;
        while let Some(j) = p {
            d += 1;
            p = self.nodes[j].parent;
        }
        d
    }

    fn new_node(&self, kind: RayKind, ray: &Ray, throughput: Color) -> RayNode {
        RayNode {
            id: self.nodes.len(),
            parent: self.open.last().copied(),
            kind,
            origin: ray.o.to_array(),
            direction: ray.d.to_array(),
            t_min: ray.t_min,
            t_max: ray.t_max,
            hit: None,
            light: None,
            transmittance: None,
            blocked_by: None,
            fresnel: None,
            throughput: throughput.to_array(),
            local: [0.0; 3],
            contribution: [0.0; 3],
            radiance: [0.0; 3],
            bvh_nodes: 0,
            primitives: 0,
            intersection_tests: 0,
            implicit_evaluations: 0,
        }
    }
}

impl Recorder for RayTree {
    const BLOCKERS: bool = true;

    fn begin(&mut self, kind: RayKind, ray: &Ray, weight: Color) {
        let node = self.new_node(kind, ray, weight);
        self.open.push(node.id);
        self.nodes.push(node);
    }

    fn hit(&mut self, scene: &Scene, ray: &Ray, hit: Option<&Hit>, work: TraceCounters) {
        let Some(&i) = self.open.last() else { return };
        let node = &mut self.nodes[i];
        node.bvh_nodes = work.bvh.nodes_visited;
        node.primitives = work.bvh.primitive_tests;
        node.intersection_tests = work.intersection_tests;
        node.implicit_evaluations = work.implicit_evaluations;
        node.hit = hit.map(|h| hit_info(scene, ray, h));
    }

    fn shadow(
        &mut self,
        light: usize,
        ray: &Ray,
        visibility: Color,
        blocker: Option<u32>,
        radiance: Color,
    ) {
        let mut node = self.new_node(RayKind::Shadow, ray, Color::ZERO);
        node.light = Some(light + 1);
        node.transmittance = Some(visibility.to_array());
        node.blocked_by = blocker.map(|b| b + 1);
        node.local = radiance.to_array();
        self.nodes.push(node);
    }

    fn fresnel(&mut self, reflectance: f32, transmittance: f32) {
        if let Some(&i) = self.open.last() {
            self.nodes[i].fresnel = Some([reflectance, transmittance]);
        }
    }

    fn end(&mut self, local: Color, absorption: Color, radiance: Color) {
        let Some(i) = self.open.pop() else { return };
        let throughput = Color::from_array(self.nodes[i].throughput) * absorption;
        let node = &mut self.nodes[i];
        node.local = local.to_array();
        node.radiance = radiance.to_array();
        node.contribution = (throughput * local).to_array();
        // Its shadow rays share its throughput, after absorption.
        for child in &mut self.nodes[i + 1..] {
            if child.parent == Some(i) && child.kind == RayKind::Shadow {
                child.throughput = throughput.to_array();
                child.contribution = (throughput * Color::from_array(child.local)).to_array();
            }
        }
    }
}

fn hit_info(scene: &Scene, ray: &Ray, hit: &Hit) -> HitInfo {
    let si = scene.surface(ray, hit);
    let shape = &scene.objects[hit.object as usize].shape;
    let triangle = matches!(shape, crate::geometry::Shape::Mesh(_)).then_some(si.prim);
    HitInfo {
        object: hit.object + 1,
        shape: shape.name(),
        triangle,
        t: hit.t,
        point: si.p.to_array(),
        normal: si.n.to_array(),
        front_face: ray.d.dot(si.n) < 0.0,
        material: si.material,
    }
}

/// One pixel sample, explained.
#[derive(Clone, Debug, Serialize)]
pub struct Explained {
    pub pixel: [u32; 2],
    pub sample: u32,
    pub integrator: &'static str,
    /// The sample's radiance, as the integrator returned it.
    pub radiance: [f32; 3],
    /// The sum of the tree's contributions (equal to `radiance` up to
    /// rounding: the integrator adds in another order).
    pub total: [f32; 3],
    pub rays: RayTree,
}

/// Traces sample `sample` of pixel `(x, y)` of the frame of `settings` with
/// its integrator, recording the ray tree.
pub fn explain(
    scene: &Scene,
    settings: &RenderSettings,
    x: u32,
    y: u32,
    sample: u32,
) -> Result<Explained, String> {
    if x >= settings.width || y >= settings.height {
        return Err(format!(
            "pixel ({x}, {y}) is outside the {}×{} image (x from 0 to {}, y from 0 to {})",
            settings.width,
            settings.height,
            settings.width.saturating_sub(1),
            settings.height.saturating_sub(1)
        ));
    }
    let (u, v) = PixelSamples::new(x, y).offset(sample);
    let ray = scene
        .camera
        .ray(x as f32 + u, y as f32 + v, settings.width, settings.height);
    let mut counters = Counters::default();
    let mut tree = RayTree::default();
    let radiance = match settings.integrator {
        IntegratorKind::Raycast => {
            Raycast.radiance_explained(scene, &ray, &mut counters, &mut tree)
        }
        IntegratorKind::Whitted => Whitted {
            max_depth: settings.max_depth,
            min_weight: settings.min_weight,
        }
        .radiance_explained(scene, &ray, &mut counters, &mut tree),
    };
    Ok(Explained {
        pixel: [x, y],
        sample,
        integrator: settings.integrator.name(),
        radiance: radiance.to_array(),
        total: tree.total().to_array(),
        rays: tree,
    })
}
