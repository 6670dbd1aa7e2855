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

use super::integrator::{AnyIntegrator, Counters, Integrator, RayKind, Recorder};
use super::sampler::PixelSamples;
use crate::math::{Color, Ray, Vec3};
use crate::scene::{Hit, Scene, TraceCounters};
use crate::settings::RenderSettings;
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
    /// then sees the background). For a shadow ray: the opaque object that
    /// blocked it, if one did.
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
    const RECORDS: bool = true;

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
        scene: &Scene,
        light: usize,
        ray: &Ray,
        visibility: Color,
        blocker: Option<&Hit>,
        radiance: Color,
    ) {
        let mut node = self.new_node(RayKind::Shadow, ray, Color::ZERO);
        node.light = Some(light + 1);
        node.transmittance = Some(visibility.to_array());
        node.hit = blocker.map(|h| hit_info(scene, ray, h));
        node.blocked_by = node.hit.as_ref().map(|h| h.object);
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

/// `(x, y, z)` to four decimals.
fn v3(a: [f32; 3]) -> String {
    format!("({:.4}, {:.4}, {:.4})", a[0], a[1], a[2])
}

impl RayNode {
    /// One line: the ray, what it hit or what became of it, and what it
    /// carried and gave; `material_name` names a material by its index.
    pub fn describe(&self, material_name: &dyn Fn(u32) -> String) -> String {
        let mut s = match self.kind {
            RayKind::Shadow => format!("shadow ray to light {}", self.light.unwrap_or(0)),
            kind => format!("{} ray", kind_name(kind)),
        };
        s += &format!(" from {} along {}", v3(self.origin), v3(self.direction));
        if self.kind == RayKind::Shadow {
            match (&self.hit, self.transmittance) {
                (Some(h), _) => s += &format!(": blocked by object {} ({})", h.object, h.shape),
                (None, Some(t)) if t == [0.0; 3] => s += ": blocked",
                (None, Some(t)) if t == [1.0; 3] => {
                    s += &format!(": reaches the light, brings {}", v3(self.local))
                }
                (None, Some(t)) => {
                    s += &format!(
                        ": through glass (transmittance {}), brings {}",
                        v3(t),
                        v3(self.local)
                    )
                }
                (None, None) => {}
            }
            return s;
        }
        match &self.hit {
            None => s += &format!(": hits nothing, sees the background {}", v3(self.local)),
            Some(h) => {
                s += &format!(
                    ": hits object {} ({}{}) at t = {:.4}, point {}, {} face, material {}",
                    h.object,
                    h.shape,
                    h.triangle
                        .map(|t| format!(", triangle {t}"))
                        .unwrap_or_default(),
                    h.t,
                    v3(h.point),
                    if h.front_face { "front" } else { "back" },
                    material_name(h.material)
                );
                if let Some([r, t]) = self.fresnel {
                    s += &format!("; Fresnel R = {r:.4}, T = {t:.4}");
                }
                s += &format!("; local term {}", v3(self.local));
            }
        }
        s + &format!(
            "; throughput {}, contribution {} [{} BVH nodes, {} primitives, {} shape tests]",
            v3(self.throughput),
            v3(self.contribution),
            self.bvh_nodes,
            self.primitives,
            self.intersection_tests
        )
    }
}

impl Explained {
    /// The tree as text: a heading, a line per ray indented by its depth,
    /// and the sum of the contributions.
    pub fn text(&self, material_name: impl Fn(u32) -> String) -> String {
        let mut s = format!(
            "Pixel ({}, {}), sample {}, {} integrator: radiance {}.\n",
            self.pixel[0],
            self.pixel[1],
            self.sample,
            self.integrator,
            v3(self.radiance)
        );
        for (i, n) in self.rays.nodes.iter().enumerate() {
            s += &"  ".repeat(self.rays.depth(i) + 1);
            s += &n.describe(&material_name);
            s.push('\n');
        }
        s + &format!(
            "{} rays; the contributions of camera, reflection and refraction rays add up to {}.\n",
            self.rays.nodes.len(),
            v3(self.total)
        )
    }
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
    let mut sampler = PixelSamples::new(x, y).sampler(sample);
    let radiance = AnyIntegrator::new(settings).radiance_explained(
        scene,
        &ray,
        &mut sampler,
        &mut counters,
        &mut tree,
    );
    Ok(Explained {
        pixel: [x, y],
        sample,
        integrator: settings.integrator.name(),
        radiance: radiance.to_array(),
        total: tree.total().to_array(),
        rays: tree,
    })
}

/// How far to draw rays that hit nothing: twice the first hit's distance
/// from the eye.
fn far(e: &Explained, scene: &Scene) -> f32 {
    let first = e.rays.nodes.first().and_then(|n| n.hit.as_ref());
    first.map_or(10.0, |h| {
        2.0 * (Vec3::from_array(h.point) - scene.camera.position).length()
    })
}

/// Where ray `n` is drawn to: its hit, its light, or far along it.
fn ray_end(n: &RayNode, far: f32) -> Vec3 {
    let (o, d) = (Vec3::from_array(n.origin), Vec3::from_array(n.direction));
    match (&n.hit, n.kind) {
        (Some(hit), _) => Vec3::from_array(hit.point),
        (None, RayKind::Shadow) if n.t_max.is_finite() => o + d * n.t_max,
        (None, _) => o + d.normalize_or_zero() * far,
    }
}

/// A camera that sees the tree from the side (the lecture's view of a ray
/// diagram): looking across the camera ray, from far enough that the eye and
/// every hit fit in its field of view.
pub fn side_camera(e: &Explained, scene: &Scene) -> Option<crate::scene::Camera> {
    // Framed on the eye and the hits; rays that leave run off the picture.
    let mut points = vec![scene.camera.position];
    points.extend(
        e.rays
            .nodes
            .iter()
            .filter_map(|n| n.hit.as_ref().map(|h| Vec3::from_array(h.point))),
    );
    let center = points.iter().fold(Vec3::ZERO, |a, &p| a + p) / points.len() as f32;
    let radius = points
        .iter()
        .map(|&p| (p - center).length())
        .fold(0.0f32, f32::max)
        .max(1e-3);
    let forward = scene.camera.forward();
    let up = if forward.cross(Vec3::Y).length() > 1e-3 {
        Vec3::Y
    } else {
        Vec3::Z
    };
    let side = forward.cross(up).normalize();
    let fov = 40.0f32;
    let distance = 1.15 * radius / (fov.to_radians() * 0.5).sin();
    crate::scene::Camera::try_new(center + side * distance, center, up, fov)
}

/// The ray tree drawn over a faint picture of the scene as `view` sees it
/// (an SVG document): each ray a line from its origin to its hit (or, if it
/// hits nothing, far along it), coloured by kind; hits as dots; the pixel
/// (where the scene's camera sees its camera ray end on) as a ring when
/// `view` is that camera, else the eye as a ring. `background` is a PNG of
/// the frame seen by `view`, drawn at 35% opacity.
pub fn svg(
    e: &Explained,
    scene: &Scene,
    view: &crate::scene::Camera,
    settings: &RenderSettings,
    background: Option<&[u8]>,
) -> String {
    use std::fmt::Write;
    let (w, h) = (settings.width, settings.height);
    let cam = view;
    let far = far(e, scene);
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}">"#
    );
    let _ = writeln!(s, r#"<rect width="{w}" height="{h}" fill="black"/>"#);
    if let Some(png) = background {
        use base64::Engine;
        let data = base64::engine::general_purpose::STANDARD.encode(png);
        let _ = writeln!(
            s,
            r#"<image width="{w}" height="{h}" opacity="0.35" href="data:image/png;base64,{data}"/>"#
        );
    }
    for n in &e.rays.nodes {
        let o = Vec3::from_array(n.origin);
        let end = ray_end(n, far);
        let (color, dash) = match n.kind {
            RayKind::Camera => ("white", ""),
            RayKind::Reflection => ("#4aa8ff", ""),
            RayKind::Refraction => ("#5fe36a", ""),
            RayKind::Shadow if n.blocked_by.is_some() => ("#ff4d4d", r#" stroke-dasharray="6 4""#),
            RayKind::Shadow => ("#ffd84a", r#" stroke-dasharray="6 4""#),
        };
        if let Some(((x0, y0), (x1, y1))) = project_segment(cam, o, end, w, h) {
            let _ = writeln!(
                s,
                r#"<line x1="{x0:.2}" y1="{y0:.2}" x2="{x1:.2}" y2="{y1:.2}" stroke="{color}" stroke-width="2"{dash}><title>{} ray {}</title></line>"#,
                kind_name(n.kind),
                n.id
            );
        }
        if let Some(hit) = &n.hit
            && let Some((x, y)) = cam.project(Vec3::from_array(hit.point), w, h)
        {
            let _ = writeln!(
                s,
                r#"<circle cx="{x:.2}" cy="{y:.2}" r="3" fill="{color}"><title>object {} ({}), t = {}</title></circle>"#,
                hit.object, hit.shape, hit.t
            );
        }
    }
    let (ring, title) = if *view == scene.camera {
        (
            Some((e.pixel[0] as f32 + 0.5, e.pixel[1] as f32 + 0.5)),
            format!(
                "pixel ({}, {}): the camera ray, end on",
                e.pixel[0], e.pixel[1]
            ),
        )
    } else {
        (
            view.project(scene.camera.position, w, h),
            "the eye".to_string(),
        )
    };
    if let Some((px, py)) = ring {
        let _ = writeln!(
            s,
            r#"<circle cx="{px:.2}" cy="{py:.2}" r="7" fill="none" stroke="white" stroke-width="2"><title>{title}</title></circle>"#
        );
    }
    let legend = [
        ("white", "camera"),
        ("#4aa8ff", "reflection"),
        ("#5fe36a", "refraction"),
        ("#ffd84a", "shadow"),
        ("#ff4d4d", "shadow, blocked"),
    ];
    for (i, (color, name)) in legend.iter().enumerate() {
        let y = 16 + 16 * i;
        let _ = writeln!(
            s,
            r#"<text x="8" y="{y}" fill="{color}" font-family="sans-serif" font-size="12">{name}</text>"#
        );
    }
    s += "</svg>\n";
    s
}

fn kind_name(k: RayKind) -> &'static str {
    match k {
        RayKind::Camera => "camera",
        RayKind::Reflection => "reflection",
        RayKind::Refraction => "refraction",
        RayKind::Shadow => "shadow",
    }
}

/// The segment `a`–`b` on the film, cut where it passes behind the camera.
fn project_segment(
    cam: &crate::scene::Camera,
    a: Vec3,
    b: Vec3,
    w: u32,
    h: u32,
) -> Option<((f32, f32), (f32, f32))> {
    let near = 1e-3;
    let depth = |p: Vec3| (p - cam.position).dot(cam.forward());
    let (za, zb) = (depth(a), depth(b));
    if za < near && zb < near {
        return None;
    }
    let cut = |p: Vec3, q: Vec3, zp: f32, zq: f32| p + (q - p) * ((near - zp) / (zq - zp));
    let (a, b) = if za < near {
        (cut(a, b, za, zb), b)
    } else if zb < near {
        (a, cut(b, a, zb, za))
    } else {
        (a, b)
    };
    Some((cam.project(a, w, h)?, cam.project(b, w, h)?))
}
