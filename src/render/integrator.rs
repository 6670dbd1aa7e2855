//! Integrators: ray casting (Appel 1968) and recursive ray tracing
//! (Whitted 1979).

use super::explain::RayTree;
use super::stats::RayCounts;
use crate::math::{Color, Ray, Vec3};
use crate::scene::{
    Hit, Light, MaterialKind, Scene, SurfaceInteraction, TraceCounters, fresnel_dielectric,
    reflect, refract,
};

/// Work counters an integrator adds to while tracing.
#[derive(Clone, Copy, Debug, Default)]
pub struct Counters {
    pub rays: RayCounts,
    pub trace: TraceCounters,
    /// Camera samples whose ray tree reached [`MAX_RAY_TREE`] (Whitted).
    pub ray_trees_cut: u64,
}

/// The most secondary rays (reflected and refracted) one camera sample may
/// spawn in [`Whitted`]. Each glass hit splits a ray in two, so with a
/// `min_weight` of 0 the tree behind one pixel grows as 2^max_depth; this
/// bounds it. A full tree of the default depth 8 has 510 secondary rays, so
/// the bound binds only where depth and weight are pushed far past the
/// defaults; the rays it cuts are the last in depth-first order (reflection
/// before refraction), and the render counts the samples it cut.
pub const MAX_RAY_TREE: u32 = 1024;

/// Computes the radiance arriving along a camera ray.
pub trait Integrator: Sync {
    fn radiance(&self, scene: &Scene, ray: &Ray, counters: &mut Counters) -> Color;

    /// [`Integrator::radiance`], telling `tree` about every ray it traces
    /// (`glint explain`). Integrators that cannot tell return the radiance
    /// and leave the tree empty.
    fn radiance_explained(
        &self,
        scene: &Scene,
        ray: &Ray,
        counters: &mut Counters,
        tree: &mut RayTree,
    ) -> Color {
        let _ = tree;
        self.radiance(scene, ray, counters)
    }
}

/// What an integrator tells while it traces, for `glint explain`. The
/// methods do nothing by default; [`NoRecord`] is what a render passes, so
/// the calls vanish from rendering code.
pub trait Recorder {
    /// Whether shadow rays should find what blocks them (a second trace).
    const BLOCKERS: bool = false;
    /// A camera, reflected or refracted ray starts; `weight` is the factor
    /// its radiance is multiplied by on its way to the pixel.
    #[inline]
    fn begin(&mut self, _kind: RayKind, _ray: &Ray, _weight: Color) {}
    /// What it hit (or `None`), with the work its intersection did.
    #[inline]
    fn hit(&mut self, _scene: &Scene, _ray: &Ray, _hit: Option<&Hit>, _work: TraceCounters) {}
    /// A shadow ray to light `light`: its transmittance, where an opaque
    /// object blocked it (if asked for), and the radiance it brought (its
    /// share of the local term).
    #[inline]
    fn shadow(
        &mut self,
        _scene: &Scene,
        _light: usize,
        _ray: &Ray,
        _visibility: Color,
        _blocker: Option<&Hit>,
        _radiance: Color,
    ) {
    }
    /// The Fresnel reflectance and transmittance at a dielectric hit.
    #[inline]
    fn fresnel(&mut self, _reflectance: f32, _transmittance: f32) {}
    /// The ray ends: the local term at its hit (or the background), the
    /// absorption factor applied to everything it returns, and its radiance.
    #[inline]
    fn end(&mut self, _local: Color, _absorption: Color, _radiance: Color) {}
}

/// The recorder of an ordinary render: nothing.
pub struct NoRecord;
impl Recorder for NoRecord {}

/// Kinds of rays in a ray tree.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum RayKind {
    Camera,
    Reflection,
    Refraction,
    Shadow,
}

/// Appel's ray casting: the first hit along the eye ray, shaded by the local
/// terms of its material with a shadow ray to each light. No secondary rays.
#[derive(Clone, Copy, Debug, Default)]
pub struct Raycast;

impl Integrator for Raycast {
    fn radiance(&self, scene: &Scene, ray: &Ray, counters: &mut Counters) -> Color {
        self.trace(scene, ray, counters, &mut NoRecord)
    }

    fn radiance_explained(
        &self,
        scene: &Scene,
        ray: &Ray,
        counters: &mut Counters,
        tree: &mut RayTree,
    ) -> Color {
        self.trace(scene, ray, counters, tree)
    }
}

impl Raycast {
    fn trace<R: Recorder>(
        &self,
        scene: &Scene,
        ray: &Ray,
        counters: &mut Counters,
        rec: &mut R,
    ) -> Color {
        rec.begin(RayKind::Camera, ray, Color::ONE);
        let hit = intersect(scene, ray, counters, rec);
        let Some(hit) = hit else {
            rec.end(scene.background, Color::ONE, scene.background);
            return scene.background;
        };
        let si = scene.surface(ray, &hit);
        let wo = -ray.d.normalize();
        let n_facing = face_forward(si.ns, face_forward(si.n, wo));
        let l = local_shading(scene, &si, wo, n_facing, counters, rec);
        rec.end(l, Color::ONE, l);
        l
    }
}

/// `scene.intersect`, telling the recorder what was hit and the work done.
#[inline]
fn intersect<R: Recorder>(
    scene: &Scene,
    ray: &Ray,
    counters: &mut Counters,
    rec: &mut R,
) -> Option<Hit> {
    let before = counters.trace;
    let hit = scene.intersect(ray, &mut counters.trace);
    rec.hit(scene, ray, hit.as_ref(), counters.trace.since(&before));
    hit
}

/// Whitted's recursive ray tracing.
///
/// At each hit: the local terms (as [`Raycast`]), plus for a mirror a reflected
/// ray weighted by its reflectance, and for a dielectric a reflected and a
/// refracted ray weighted by the Fresnel reflectance `R` and transmittance `T`
/// (total internal reflection: `R = 1`). Recursion ends at diffuse surfaces
/// (they spawn nothing), when a ray leaves the scene (it sees the background),
/// when a ray's weight (the product of the factors on its way to the pixel,
/// largest channel) would fall below `min_weight`, at `max_depth` bounces, or
/// when the sample has spawned [`MAX_RAY_TREE`] secondary rays.
/// Lights are points or directions and cannot be hit by rays.
#[derive(Clone, Copy, Debug)]
pub struct Whitted {
    pub max_depth: u32,
    pub min_weight: f32,
}

impl Integrator for Whitted {
    fn radiance(&self, scene: &Scene, ray: &Ray, counters: &mut Counters) -> Color {
        self.camera_ray(scene, ray, counters, &mut NoRecord)
    }

    fn radiance_explained(
        &self,
        scene: &Scene,
        ray: &Ray,
        counters: &mut Counters,
        tree: &mut RayTree,
    ) -> Color {
        self.camera_ray(scene, ray, counters, tree)
    }
}

/// The secondary rays a camera sample may still spawn.
struct Budget {
    left: u32,
    /// Whether a ray was refused for want of budget.
    cut: bool,
}

/// Takes one ray from the sample's budget, if any is left.
#[inline]
fn spend(budget: &mut Budget) -> bool {
    if budget.left == 0 {
        budget.cut = true;
        return false;
    }
    budget.left -= 1;
    true
}

impl Whitted {
    fn camera_ray<R: Recorder>(
        &self,
        scene: &Scene,
        ray: &Ray,
        counters: &mut Counters,
        rec: &mut R,
    ) -> Color {
        let mut budget = Budget {
            left: MAX_RAY_TREE,
            cut: false,
        };
        rec.begin(RayKind::Camera, ray, Color::ONE);
        let l = self.trace(scene, ray, 0, 1.0, Color::ONE, &mut budget, counters, rec);
        counters.ray_trees_cut += budget.cut as u64;
        l
    }

    /// The radiance along `ray` (whose start the recorder has been told).
    /// `weight` decides whether rays are worth tracing (the product of the
    /// largest channels of the factors on the way to the pixel);
    /// `throughput` is that product per channel, absorption included, for
    /// the recorder.
    #[allow(clippy::too_many_arguments)]
    fn trace<R: Recorder>(
        &self,
        scene: &Scene,
        ray: &Ray,
        depth: u32,
        weight: f32,
        throughput: Color,
        budget: &mut Budget,
        counters: &mut Counters,
        rec: &mut R,
    ) -> Color {
        let Some(hit) = intersect(scene, ray, counters, rec) else {
            rec.end(scene.background, Color::ONE, scene.background);
            return scene.background;
        };
        let si = scene.surface(ray, &hit);
        let d = ray.d.normalize();
        let wo = -d;
        let front = d.dot(si.n) < 0.0;
        // The shading normal, on the side of the geometric normal the ray came from.
        let n_facing = face_forward(si.ns, if front { si.n } else { -si.n });
        let local = local_shading(scene, &si, wo, n_facing, counters, rec);
        let mut l = local;
        let material = &scene.materials[si.material as usize];
        // Absorption inside a dielectric scales everything this ray returns.
        let absorption = if !front
            && let MaterialKind::Dielectric { absorption, .. } = material.kind
            && absorption != Color::ZERO
        {
            Some((-absorption * (hit.t * ray.d.length())).exp())
        } else {
            None
        };
        let carried = throughput * absorption.unwrap_or(Color::ONE);

        if depth < self.max_depth {
            match material.kind {
                MaterialKind::Diffuse => {}
                MaterialKind::Mirror { reflectance } => {
                    let w = weight * reflectance.max_element();
                    if w >= self.min_weight && spend(budget) {
                        counters.rays.reflection += 1;
                        let r = Ray::spawn(si.p, si.p_err, si.n, reflect(d, n_facing));
                        let t = carried * reflectance;
                        rec.begin(RayKind::Reflection, &r, t);
                        l += reflectance
                            * self.trace(scene, &r, depth + 1, w, t, budget, counters, rec);
                    }
                }
                MaterialKind::Dielectric { ior, .. } => {
                    let (eta_i, eta_t) = if front { (1.0, ior) } else { (ior, 1.0) };
                    let f = fresnel_dielectric(wo.dot(n_facing), eta_i, eta_t);
                    rec.fresnel(f.reflectance, f.transmittance);
                    let w = weight * f.reflectance;
                    if w >= self.min_weight && spend(budget) {
                        counters.rays.reflection += 1;
                        let r = Ray::spawn(si.p, si.p_err, si.n, reflect(d, n_facing));
                        let t = carried * f.reflectance;
                        rec.begin(RayKind::Reflection, &r, t);
                        l += f.reflectance
                            * self.trace(scene, &r, depth + 1, w, t, budget, counters, rec);
                    }
                    let w = weight * f.transmittance;
                    if w >= self.min_weight
                        && let Some(dir) = refract(d, n_facing, eta_i / eta_t)
                        && spend(budget)
                    {
                        counters.rays.refraction += 1;
                        let r = Ray::spawn(si.p, si.p_err, si.n, dir);
                        let t = carried * f.transmittance;
                        rec.begin(RayKind::Refraction, &r, t);
                        l += f.transmittance
                            * self.trace(scene, &r, depth + 1, w, t, budget, counters, rec);
                    }
                }
            }
        }

        // A ray that reached the back face of a dielectric travelled inside it.
        if let Some(a) = absorption {
            l *= a;
        }
        rec.end(local, absorption.unwrap_or(Color::ONE), l);
        l
    }
}

/// `n` flipped, if needed, to the side of `w`.
#[inline]
fn face_forward(n: Vec3, w: Vec3) -> Vec3 {
    if n.dot(w) < 0.0 { -n } else { n }
}

/// The local terms of Whitted's model at a hit seen from direction `wo`
/// (unit, towards the viewer), with `n_facing` the unit normal on `wo`'s side:
/// `k_a·C·A + Σ_lights V·E·(k_d·C·(N·L) + k_s·(N·H)^n)` over the lights with
/// `N·L > 0`, where `V` is the shadow ray's transmittance (1 unblocked, 0
/// blocked by an opaque object, in between through glass), `E` the light's
/// irradiance at the point (`I/r²` for a point light), and `H = (L + wo)/|L + wo|`
/// (Blinn 1977).
#[inline]
fn local_shading<R: Recorder>(
    scene: &Scene,
    si: &SurfaceInteraction,
    wo: Vec3,
    n_facing: Vec3,
    counters: &mut Counters,
    rec: &mut R,
) -> Color {
    let m = &scene.materials[si.material as usize];
    let albedo = scene.albedo(si);
    let mut l = m.ambient * albedo * scene.ambient;
    if m.diffuse == 0.0 && m.specular == 0.0 {
        return l;
    }
    for (index, light) in scene.lights.iter().enumerate() {
        let (wi, irradiance, shadow_ray) = match *light {
            Light::Point {
                position,
                intensity,
            } => {
                let to_light = position - si.p;
                let dist2 = to_light.length_squared();
                (
                    to_light / dist2.sqrt(),
                    intensity / dist2,
                    Ray::spawn_to(si.p, si.p_err, si.n, position),
                )
            }
            Light::Directional {
                direction,
                irradiance,
            } => (
                -direction,
                irradiance,
                Ray::spawn(si.p, si.p_err, si.n, -direction),
            ),
        };
        let cos = n_facing.dot(wi);
        if cos <= 0.0 {
            continue;
        }
        counters.rays.shadow += 1;
        let visibility = scene.transmittance(&shadow_ray, &mut counters.trace);
        if visibility == Color::ZERO {
            if R::BLOCKERS {
                // The nearest object on the segment; opaque, as it stopped the ray.
                let mut scratch = TraceCounters::default();
                let blocker = scene.intersect(&shadow_ray, &mut scratch);
                rec.shadow(
                    scene,
                    index,
                    &shadow_ray,
                    visibility,
                    blocker.as_ref(),
                    Color::ZERO,
                );
            }
            continue;
        }
        let mut reflected = m.diffuse * cos * albedo;
        if m.specular > 0.0 {
            let h = (wi + wo).normalize_or_zero();
            reflected += m.specular * n_facing.dot(h).max(0.0).powf(m.shininess);
        }
        let term = visibility * irradiance * reflected;
        rec.shadow(scene, index, &shadow_ray, visibility, None, term);
        l += term;
    }
    l
}
