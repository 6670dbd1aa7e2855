//! Integrators, one per file: ray casting (Appel 1968), recursive ray
//! tracing (Whitted 1979) and unidirectional path tracing (Kajiya 1986,
//! with Veach's multiple importance sampling). [`IntegratorKind`] names
//! them; [`AnyIntegrator::new`] makes the one the settings name.

mod columns;
mod lane;
mod path;
mod raycast;
mod stream;
mod wave;
mod whitted;

pub use path::Path;
pub use raycast::Raycast;
pub use whitted::{Whitted, transmittance};

use super::explain::RayTree;
use super::sampler::PixelSampler;
use super::stats::RayCounts;
use crate::accel::PACKET;
use crate::math::{Color, Ray, Vec3};
use crate::scene::{Hit, Scene, TraceCounters};
use crate::settings::{IntegratorKind, RenderSettings};

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

/// Computes the radiance arriving along a camera ray. `sampler` gives the
/// sample's random numbers after the pixel position.
pub trait Integrator: Sync {
    fn radiance(
        &self,
        scene: &Scene,
        ray: &Ray,
        sampler: &mut PixelSampler,
        counters: &mut Counters,
    ) -> Color;

    /// What [`Integrator::radiance`] returns for a camera ray that hits
    /// nothing, for rays the renderer knows to miss (see
    /// [`Scene::camera_misses`]); `None` (the default) if the integrator
    /// cannot say, and the ray is then traced.
    fn escaped(&self, scene: &Scene, ray: &Ray) -> Option<Color> {
        let _ = (scene, ray);
        None
    }

    /// Whether [`Integrator::radiance_stream`] traces `scene`'s camera rays
    /// (false by default).
    fn streams(&self, scene: &Scene) -> bool {
        let _ = scene;
        false
    }

    /// The radiance of each camera ray of `rays` into `out`, exactly as
    /// [`Integrator::radiance`] gives it, for integrators that can trace
    /// many rays at once in `scene` (without random numbers); returns false,
    /// having done nothing, where they cannot (the default). Returning true,
    /// it has written every element of `out` (which may hold old values).
    fn radiance_stream(
        &self,
        scene: &Scene,
        rays: &[Ray],
        counters: &mut Counters,
        out: &mut [Color],
    ) -> bool {
        let _ = (scene, rays, counters, out);
        false
    }

    /// [`Integrator::radiance`], telling `tree` about every ray it traces
    /// (`glint explain`). Integrators that cannot tell return the radiance
    /// and leave the tree empty.
    fn radiance_explained(
        &self,
        scene: &Scene,
        ray: &Ray,
        sampler: &mut PixelSampler,
        counters: &mut Counters,
        tree: &mut RayTree,
    ) -> Color {
        let _ = tree;
        self.radiance(scene, ray, sampler, counters)
    }
}

/// An integrator written once for any [`Recorder`]; [`Integrator`] follows
/// from it (a render passes [`NoRecord`], whose calls vanish, and `glint
/// explain` a [`RayTree`]).
pub trait Tracer: Sync {
    /// The radiance along the camera ray `ray`, telling `rec` what is traced.
    fn trace<R: Recorder>(
        &self,
        scene: &Scene,
        ray: &Ray,
        sampler: &mut PixelSampler,
        counters: &mut Counters,
        rec: &mut R,
    ) -> Color;

    /// The radiance of a camera ray that hits nothing: what
    /// [`Tracer::trace`] returns for it, computed by the same code.
    fn escaped(&self, scene: &Scene, ray: &Ray) -> Color;

    /// See [`Integrator::streams`].
    fn streams(&self, scene: &Scene) -> bool {
        let _ = scene;
        false
    }

    /// See [`Integrator::radiance_stream`].
    fn trace_stream(
        &self,
        scene: &Scene,
        rays: &[Ray],
        counters: &mut Counters,
        out: &mut [Color],
    ) -> bool {
        let _ = (scene, rays, counters, out);
        false
    }
}

impl<T: Tracer> Integrator for T {
    #[inline]
    fn escaped(&self, scene: &Scene, ray: &Ray) -> Option<Color> {
        Some(Tracer::escaped(self, scene, ray))
    }

    #[inline]
    fn radiance(
        &self,
        scene: &Scene,
        ray: &Ray,
        sampler: &mut PixelSampler,
        counters: &mut Counters,
    ) -> Color {
        self.trace(scene, ray, sampler, counters, &mut NoRecord)
    }

    fn radiance_explained(
        &self,
        scene: &Scene,
        ray: &Ray,
        sampler: &mut PixelSampler,
        counters: &mut Counters,
        tree: &mut RayTree,
    ) -> Color {
        self.trace(scene, ray, sampler, counters, tree)
    }

    #[inline]
    fn streams(&self, scene: &Scene) -> bool {
        Tracer::streams(self, scene)
    }

    #[inline]
    fn radiance_stream(
        &self,
        scene: &Scene,
        rays: &[Ray],
        counters: &mut Counters,
        out: &mut [Color],
    ) -> bool {
        self.trace_stream(scene, rays, counters, out)
    }
}

/// The integrator the settings name.
#[derive(Clone, Copy, Debug)]
pub enum AnyIntegrator {
    Raycast(Raycast),
    Whitted(Whitted),
    Path(Path),
}

impl AnyIntegrator {
    pub fn new(settings: &RenderSettings) -> Self {
        match settings.integrator {
            IntegratorKind::Raycast => AnyIntegrator::Raycast(Raycast {
                light_samples: settings.light_samples,
            }),
            IntegratorKind::Whitted => AnyIntegrator::Whitted(Whitted {
                max_depth: settings.depth_limit(),
                min_weight: settings.min_weight,
                light_samples: settings.light_samples,
            }),
            IntegratorKind::Path => AnyIntegrator::Path(Path {
                max_depth: settings.depth_limit(),
                rr_depth: 5,
                sampling: settings.sampling,
            }),
        }
    }
}

impl Tracer for AnyIntegrator {
    #[inline]
    fn trace<R: Recorder>(
        &self,
        scene: &Scene,
        ray: &Ray,
        sampler: &mut PixelSampler,
        counters: &mut Counters,
        rec: &mut R,
    ) -> Color {
        match self {
            AnyIntegrator::Raycast(i) => i.trace(scene, ray, sampler, counters, rec),
            AnyIntegrator::Whitted(i) => i.trace(scene, ray, sampler, counters, rec),
            AnyIntegrator::Path(i) => i.trace(scene, ray, sampler, counters, rec),
        }
    }

    #[inline]
    fn escaped(&self, scene: &Scene, ray: &Ray) -> Color {
        match self {
            AnyIntegrator::Raycast(i) => Tracer::escaped(i, scene, ray),
            AnyIntegrator::Whitted(i) => Tracer::escaped(i, scene, ray),
            AnyIntegrator::Path(i) => Tracer::escaped(i, scene, ray),
        }
    }

    fn streams(&self, scene: &Scene) -> bool {
        match self {
            AnyIntegrator::Raycast(i) => Tracer::streams(i, scene),
            AnyIntegrator::Whitted(i) => i.streams(scene),
            _ => false,
        }
    }

    fn trace_stream(
        &self,
        scene: &Scene,
        rays: &[Ray],
        counters: &mut Counters,
        out: &mut [Color],
    ) -> bool {
        match self {
            AnyIntegrator::Raycast(i) => i.trace_stream(scene, rays, counters, out),
            AnyIntegrator::Whitted(i) => i.stream(scene, rays, counters, out),
            _ => false,
        }
    }
}

/// What an integrator tells while it traces, for `glint explain`. The
/// methods do nothing by default; [`NoRecord`] is what a render passes, so
/// the calls vanish from rendering code.
pub trait Recorder {
    /// Whether shadow rays should find what blocks them (a second trace).
    const BLOCKERS: bool = false;
    /// Whether anything is recorded (integrators may keep extra books then).
    const RECORDS: bool = false;
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

/// `scene.intersect`, telling the recorder what was hit and the work done.
#[inline]
pub(super) fn intersect<R: Recorder>(
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

/// The radiance of each camera ray of `rays` into `out`: their first hits
/// found [`PACKET`] rays at a time ([`Scene::intersect_packet`]: coherent
/// neighbours go through a mesh's tree together), then `radiance(ray, hit,
/// counters)` for each, in order.
#[inline(always)]
pub(super) fn from_first_hits(
    scene: &Scene,
    rays: &[Ray],
    counters: &mut Counters,
    out: &mut [Color],
    mut radiance: impl FnMut(&Ray, Option<Hit>, &mut Counters) -> Color,
) {
    let mut hits = [None; PACKET];
    for (rays, out) in rays.chunks(PACKET).zip(out.chunks_mut(PACKET)) {
        let hits = &mut hits[..rays.len()];
        scene.intersect_packet(rays, &mut counters.trace, hits);
        for ((ray, hit), out) in rays.iter().zip(hits.iter()).zip(out) {
            *out = radiance(ray, *hit, counters);
        }
    }
}

/// `n` flipped, if needed, to the side of `w`.
#[inline]
pub(super) fn face_forward(n: Vec3, w: Vec3) -> Vec3 {
    if n.dot(w) < 0.0 { -n } else { n }
}
