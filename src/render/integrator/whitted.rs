//! Whitted's recursive ray tracing, and the local terms of its
//! illumination model (which [`super::Raycast`] shares).

use super::{Counters, MAX_RAY_TREE, RayKind, Recorder, Tracer, face_forward, intersect};
use crate::accel::PACKET;
use crate::light::Light;
use crate::math::{Color, Ray, Vec3};
use crate::render::sampler::PixelSampler;
use crate::scene::{Hit, MaterialKind, Scene, SurfaceInteraction, TraceCounters};
use crate::shading::{Bsdf, bsdf_at, fresnel_dielectric, reflect, refract};

/// Whitted's recursive ray tracing.
///
/// At each hit: the local terms (as [`Raycast`](super::Raycast)), plus for a mirror a reflected
/// ray weighted by its reflectance, and for a dielectric a reflected and a
/// refracted ray weighted by the Fresnel reflectance `R` and transmittance `T`
/// (total internal reflection: `R = 1`). Recursion ends at diffuse surfaces
/// (they spawn nothing), when a ray leaves the scene (it sees the background),
/// when a ray's weight (the product of the factors on its way to the pixel,
/// largest channel) would fall below `min_weight`, at `max_depth` bounces, or
/// when the sample has spawned [`MAX_RAY_TREE`] secondary rays.
///
/// Point and directional lights get one shadow ray each. Area lights (the
/// emissive objects) get `light_samples` shadow rays in all, to points
/// chosen by power among them and stratified over their surfaces: soft
/// shadows. Rays that hit an emitter see its emission.
#[derive(Clone, Copy, Debug)]
pub struct Whitted {
    pub max_depth: u32,
    pub min_weight: f32,
    pub light_samples: u32,
}

impl Tracer for Whitted {
    #[inline]
    fn trace<R: Recorder>(
        &self,
        scene: &Scene,
        ray: &Ray,
        sampler: &mut PixelSampler,
        counters: &mut Counters,
        rec: &mut R,
    ) -> Color {
        self.camera_ray(scene, ray, sampler, counters, rec)
    }

    #[inline]
    fn escaped(&self, scene: &Scene, ray: &Ray) -> Color {
        scene.background_le(ray.d)
    }

    fn streams(&self, scene: &Scene) -> bool {
        Whitted::streams(self, scene)
    }

    fn trace_stream(
        &self,
        scene: &Scene,
        rays: &[Ray],
        counters: &mut Counters,
        out: &mut [Color],
    ) -> bool {
        self.stream(scene, rays, counters, out)
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
        sampler: &mut PixelSampler,
        counters: &mut Counters,
        rec: &mut R,
    ) -> Color {
        rec.begin(RayKind::Camera, ray, Color::ONE);
        let hit = intersect(scene, ray, counters, rec);
        self.camera_hit(scene, ray, hit, sampler, counters, rec)
    }

    /// The radiance of a camera ray whose first hit is `hit` (the recorder
    /// told of both).
    #[inline(always)]
    pub(super) fn camera_hit<R: Recorder>(
        &self,
        scene: &Scene,
        ray: &Ray,
        hit: Option<Hit>,
        sampler: &mut PixelSampler,
        counters: &mut Counters,
        rec: &mut R,
    ) -> Color {
        let mut budget = Budget {
            left: MAX_RAY_TREE,
            cut: false,
        };
        let l = self.trace_hit(
            scene,
            ray,
            hit,
            0,
            1.0,
            Color::ONE,
            &mut budget,
            sampler,
            counters,
            rec,
        );
        counters.ray_trees_cut += budget.cut as u64;
        l
    }

    /// The radiance along `ray` (whose start the recorder has been told).
    /// `weight` decides whether rays are worth tracing (the product of the
    /// largest channels of the factors on the way to the pixel);
    /// `throughput` is that product per channel, absorption included, for
    /// the recorder.
    #[allow(clippy::too_many_arguments)]
    fn trace_ray<R: Recorder>(
        &self,
        scene: &Scene,
        ray: &Ray,
        depth: u32,
        weight: f32,
        throughput: Color,
        budget: &mut Budget,
        sampler: &mut PixelSampler,
        counters: &mut Counters,
        rec: &mut R,
    ) -> Color {
        let hit = intersect(scene, ray, counters, rec);
        self.trace_hit(
            scene, ray, hit, depth, weight, throughput, budget, sampler, counters, rec,
        )
    }

    /// [`Whitted::trace_ray`] given the ray's first hit.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn trace_hit<R: Recorder>(
        &self,
        scene: &Scene,
        ray: &Ray,
        hit: Option<Hit>,
        depth: u32,
        weight: f32,
        throughput: Color,
        budget: &mut Budget,
        sampler: &mut PixelSampler,
        counters: &mut Counters,
        rec: &mut R,
    ) -> Color {
        let Some(hit) = hit else {
            // Any ray of the tree that escapes, as a camera ray does.
            let background = Tracer::escaped(self, scene, ray);
            rec.end(background, Color::ONE, background);
            return background;
        };
        let at = AtHit::new(scene, ray, &hit);
        let area = area_rotation(scene, self.light_samples, sampler);
        let local = local_shading(scene, &at.si, at.wo, at.n_facing, area, counters, rec);
        let mut l = local;
        let absorption = at.absorption(hit.t * ray.d.length());
        let carried = throughput * absorption.unwrap_or(Color::ONE);

        if depth < self.max_depth {
            // By reference: moving the array into an iterator copies it.
            let secondaries = self.secondaries(scene, &at, weight, rec);
            for s in secondaries.iter().flatten() {
                if !spend(budget) {
                    continue;
                }
                s.count(counters);
                let t = carried * s.factor;
                rec.begin(s.kind, &s.ray, t);
                l += s.factor
                    * self.trace_ray(
                        scene,
                        &s.ray,
                        depth + 1,
                        s.weight,
                        t,
                        budget,
                        sampler,
                        counters,
                        rec,
                    );
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

/// A reflected or refracted ray that a hit spawns: the factor its radiance
/// is multiplied by, and its weight (see [`Whitted::trace_ray`]).
pub(super) struct Secondary {
    kind: RayKind,
    pub factor: Color,
    pub ray: Ray,
    pub weight: f32,
}

impl Secondary {
    #[inline]
    pub(super) fn count(&self, counters: &mut Counters) {
        match self.kind {
            RayKind::Refraction => counters.rays.refraction += 1,
            _ => counters.rays.reflection += 1,
        }
    }
}

impl Whitted {
    /// The rays a hit (reached with weight `weight`) spawns, in the order
    /// they are traced, if their weight reaches `min_weight`: a mirror's
    /// reflection (a conductor's, of its Fresnel reflectance), or a
    /// dielectric's reflection and refraction weighted by Fresnel's `R` and
    /// `T` (none refracted at total internal reflection).
    #[inline(never)]
    pub(super) fn secondaries<R: Recorder>(
        &self,
        scene: &Scene,
        at: &AtHit,
        weight: f32,
        rec: &mut R,
    ) -> [Option<Secondary>; 2] {
        let (si, d, wo, n_facing) = (&at.si, at.d, at.wo, at.n_facing);
        let material = &scene.materials[si.material as usize];
        // A conductor is a mirror here, of its Fresnel reflectance.
        let mirror = match material.kind {
            _ if at.glass.is_some() => None,
            MaterialKind::Mirror { reflectance } => Some(reflectance),
            MaterialKind::Conductor { .. } => match bsdf_at(material, scene.albedo(si)) {
                Bsdf::Conductor { fresnel, .. } => Some(fresnel.eval(wo.dot(n_facing))),
                _ => None,
            },
            MaterialKind::Principled { metallic, .. } if metallic >= 0.5 => Some(scene.albedo(si)),
            _ => None,
        };
        let reflected = |factor: Color, w: f32| {
            (w >= self.min_weight).then(|| Secondary {
                kind: RayKind::Reflection,
                factor,
                ray: Ray::spawn(si.p, si.p_err, si.n, reflect(d, n_facing)),
                weight: w,
            })
        };
        match (mirror, at.glass) {
            (None, None) => [None, None],
            (Some(reflectance), _) => [
                reflected(reflectance, weight * reflectance.max_element()),
                None,
            ],
            (None, Some((ior, _))) => {
                let (eta_i, eta_t) = if at.front { (1.0, ior) } else { (ior, 1.0) };
                let f = fresnel_dielectric(wo.dot(n_facing), eta_i, eta_t);
                rec.fresnel(f.reflectance, f.transmittance);
                let w = weight * f.transmittance;
                let refracted = if w >= self.min_weight
                    && let Some(dir) = refract(d, n_facing, eta_i / eta_t)
                {
                    Some(Secondary {
                        kind: RayKind::Refraction,
                        factor: Color::splat(f.transmittance),
                        ray: Ray::spawn(si.p, si.p_err, si.n, dir),
                        weight: w,
                    })
                } else {
                    None
                };
                [
                    reflected(Color::splat(f.reflectance), weight * f.reflectance),
                    refracted,
                ]
            }
        }
    }
}

/// A ray's hit as shading sees it.
pub(super) struct AtHit {
    pub si: SurfaceInteraction,
    /// The ray's unit direction.
    pub d: Vec3,
    /// `−d`: towards where the ray came from.
    pub wo: Vec3,
    /// Whether the ray met the front of the surface (against its normal).
    pub front: bool,
    /// The shading normal, on the side of the geometric normal the ray came from.
    pub n_facing: Vec3,
    /// The material's index of refraction and absorption, if Whitted's
    /// model treats it as glass.
    pub glass: Option<(f32, Color)>,
}

impl AtHit {
    #[inline]
    pub fn new(scene: &Scene, ray: &Ray, hit: &Hit) -> AtHit {
        let si = scene.surface(ray, hit);
        let d = ray.d.normalize();
        let front = d.dot(si.n) < 0.0;
        AtHit {
            glass: scene.materials[si.material as usize].glass(),
            n_facing: face_forward(si.ns, if front { si.n } else { -si.n }),
            si,
            d,
            wo: -d,
            front,
        }
    }

    /// The attenuation of light that travelled `length` inside an absorbing
    /// dielectric to reach this back face, `exp(−σ·length)`; `None` where
    /// nothing is absorbed.
    #[inline]
    pub(super) fn absorption(&self, length: f32) -> Option<Color> {
        match self.glass {
            Some((_, absorption)) if !self.front && absorption != Color::ZERO => {
                Some((-absorption * length).exp())
            }
            _ => None,
        }
    }
}

/// The local terms of Whitted's model at a hit seen from direction `wo`
/// (unit, towards the viewer), with `n_facing` the unit normal on `wo`'s side:
/// `k_a·C·A + Σ_lights V·E·(k_d·C·(N·L) + k_s·(N·H)^n)` over the lights with
/// `N·L > 0`, where `V` is the shadow ray's transmittance (1 unblocked, 0
/// blocked by an opaque object, in between through glass), `E` the light's
/// irradiance at the point (`I/r²` for a point light), and `H = (L + wo)/|L + wo|`
/// (Blinn 1977).
///
/// An area light contributes `(1/N) Σ_j V_j·L_j/p_j·(k_d·C·(N·L_j) + k_s·(N·H_j)^n)`
/// over `N = light_samples` points chosen by power among the area lights
/// (`p_j` the density of the direction, over solid angle, times the
/// probability of the light), stratified by a rank-1 lattice rotated per
/// sample (see [`lattice_point`]). For a small light of radiance
/// `L` and area `A` this is the point light of intensity `L·A`. An emitting
/// surface adds its own emission.
#[inline]
pub(super) fn local_shading<R: Recorder>(
    scene: &Scene,
    si: &SurfaceInteraction,
    wo: Vec3,
    n_facing: Vec3,
    area: Option<(u32, [f32; 3])>,
    counters: &mut Counters,
    rec: &mut R,
) -> Color {
    local_terms(scene, si, wo, n_facing, area, |l, term| {
        counters.rays.shadow += 1;
        let visibility = transmittance(scene, &term.ray, &mut counters.trace);
        if visibility == Color::ZERO {
            if R::BLOCKERS {
                // The nearest object on the segment; opaque, as it stopped the ray.
                let mut scratch = TraceCounters::default();
                let blocker = scene.intersect(&term.ray, &mut scratch);
                rec.shadow(
                    scene,
                    term.light,
                    &term.ray,
                    visibility,
                    blocker.as_ref(),
                    Color::ZERO,
                );
            }
            return;
        }
        let radiance = term.gain.radiance(visibility);
        rec.shadow(scene, term.light, &term.ray, visibility, None, radiance);
        *l += radiance;
    })
}

/// Whether shading samples area lights (`light_samples` of them per hit),
/// which draws random numbers (see [`area_rotation`]).
#[inline]
pub(super) fn samples_area_lights(scene: &Scene, light_samples: u32) -> bool {
    light_samples > 0 && !scene.emitters.area_select.is_empty()
}

/// The random rotation of the area lights' lattice for a sample, if it
/// has area lights to sample (see [`local_shading`]).
#[inline]
pub(super) fn area_rotation(
    scene: &Scene,
    light_samples: u32,
    sampler: &mut PixelSampler,
) -> Option<(u32, [f32; 3])> {
    samples_area_lights(scene, light_samples).then(|| {
        let (r0, r1) = sampler.next_2d();
        (light_samples, [r0, r1, sampler.next_1d()])
    })
}

/// One shadow ray of the local terms, with what it brings if unblocked.
pub(super) struct LightTerm {
    pub light: usize,
    pub ray: Ray,
    pub gain: LightGain,
}

/// What a light sample brings through its shadow ray (see
/// [`LightGain::radiance`]).
#[derive(Clone, Copy, Debug)]
pub(super) struct LightGain {
    pub irradiance: Color,
    /// `k_d·C·(N·L)`.
    pub diffuse: Color,
    /// `k_s`, `N·H` (clamped to 0) and `n` of the highlight, raised to the
    /// power only for unblocked shadow rays (`powf` is the costly part).
    pub specular: f32,
    pub n_dot_h: f32,
    pub shininess: f32,
}

impl LightGain {
    /// The term's radiance through the shadow ray's transmittance
    /// `visibility`: `V·E·(k_d·C·(N·L) + k_s·(N·H)^n)`.
    #[inline]
    pub fn radiance(&self, visibility: Color) -> Color {
        let mut reflected = self.diffuse;
        if self.specular > 0.0 {
            reflected += self.specular * highlight(self.n_dot_h, self.shininess);
        }
        visibility * self.irradiance * reflected
    }
}

/// [`local_shading`] up to the shadow rays: returns the terms that need no
/// shadow ray (ambient and emission), and calls `each(l, term)` with the
/// light samples that face the surface, in order, for the caller to trace
/// their shadow rays and add their radiance to `l`. `area` is the count
/// of area-light samples and the lattice rotation (see [`area_rotation`]).
#[inline(always)]
pub(super) fn local_terms(
    scene: &Scene,
    si: &SurfaceInteraction,
    wo: Vec3,
    n_facing: Vec3,
    area: Option<(u32, [f32; 3])>,
    mut each: impl FnMut(&mut Color, LightTerm),
) -> Color {
    let m = &scene.materials[si.material as usize];
    let albedo = scene.albedo(si);
    let mut l = m.ambient * albedo * scene.ambient;
    if m.is_emissive() && (m.two_sided || si.n.dot(wo) > 0.0) {
        l += m.emission;
    }
    if m.diffuse == 0.0 && m.specular == 0.0 {
        return l;
    }
    let emitters = &scene.emitters;
    // One light sample: its shadow ray and gain handed to `each`, if it
    // faces the surface.
    let mut term = |l: &mut Color, index: usize, scale: f32, u: (f32, f32)| {
        let light = &emitters.lights[index];
        let Some(ls) = light.sample_li(si.p, u) else {
            return;
        };
        let wi = ls.wi;
        let (irradiance, shadow_ray) = match ls.target {
            Some(target) if ls.delta => (ls.li, Ray::spawn_to(si.p, si.p_err, si.n, target)),
            Some(target) => (
                ls.li / (ls.pdf * scale),
                Ray::spawn_to(si.p, si.p_err, si.n, target),
            ),
            None => (ls.li, Ray::spawn(si.p, si.p_err, si.n, wi)),
        };
        if let Light::Area(_) | Light::Sphere { .. } = light
            && !irradiance.is_finite()
        {
            return;
        }
        let cos = n_facing.dot(wi);
        if cos <= 0.0 {
            return;
        }
        let n_dot_h = if m.specular > 0.0 {
            let h = (wi + wo).normalize_or_zero();
            n_facing.dot(h).max(0.0)
        } else {
            0.0
        };
        each(
            l,
            LightTerm {
                light: index,
                ray: shadow_ray,
                gain: LightGain {
                    irradiance,
                    diffuse: m.diffuse * cos * albedo,
                    specular: m.specular,
                    n_dot_h,
                    shininess: m.shininess,
                },
            },
        );
    };
    // The point and directional lights, then the area-light samples (a
    // plain loop each: most scenes have no area lights to sample).
    for &i in &emitters.delta_lights {
        term(&mut l, i as usize, 1.0, (0.5, 0.5));
    }
    if let Some((n, rot)) = area {
        for j in 0..n {
            let (u0, u1, u2) = lattice_point(j, n, rot);
            if let Some((k, pmf)) = emitters.area_select.sample(u0) {
                term(
                    &mut l,
                    emitters.area_lights[k] as usize,
                    pmf * n as f32,
                    (u1, u2),
                );
            }
        }
    }
    l
}

/// Blinn–Phong's highlight `c^n` for `c = N·H ≥ 0` and `n > 0`: `c.powf(n)`,
/// bit for bit, without the call where the result is certainly 0. A sharp
/// highlight (`n` in the hundreds) underflows over most of a surface, and
/// glibc's `powf` takes a slow path there.
///
/// With `c = 2^e·(1 + m)`, `m ∈ [0, 1)`, the bits of `c` read as an integer
/// give `e + m` (scaled by 2²³), and `log2(c) = e + log2(1 + m) ≤ e + m +
/// 0.0861`. Where `n` times that bound is below −160, `c^n < 2^−160`, far
/// below half the smallest subnormal (2^−150), and `powf` returns +0.
#[inline]
pub(super) fn highlight(c: f32, n: f32) -> f32 {
    let log2_bound =
        (c.to_bits() as i32 - 1.0f32.to_bits() as i32) as f32 * (1.0 / 8_388_608.0) + 0.09;
    if n * log2_bound < -160.0 {
        return 0.0;
    }
    c.powf(n)
}

/// Point `j` of an `n`-point rank-1 lattice in [0, 1)³ shifted modulo 1 by
/// the uniform `rot` (Cranley–Patterson rotation, which makes each point
/// uniform and the set stratified): `(j + ½)/n` chooses the light, and the
/// R2 sequence `{j·(1/ρ, 1/ρ²)}` (ρ the plastic number; Roberts 2018) the
/// point on it.
#[inline]
fn lattice_point(j: u32, n: u32, rot: [f32; 3]) -> (f32, f32, f32) {
    const A1: f64 = 0.754_877_666_246_692_7;
    const A2: f64 = 0.569_840_290_998_053_2;
    let wrap = |x: f32| {
        let f = x - x.floor();
        if f >= 1.0 { 0.0 } else { f }
    };
    let a = (j as f32 + 0.5) / n as f32;
    let b = (j as f64 * A1).fract() as f32;
    let c = (j as f64 * A2).fract() as f32;
    (wrap(a + rot[0]), wrap(b + rot[1]), wrap(c + rot[2]))
}

/// The fraction of light that passes along a shadow ray's segment, for
/// Whitted's model.
///
/// Opaque objects block it (black at the first one found). Dielectrics let
/// it through straight, without bending it: each crossing of their surface
/// passes the Fresnel transmittance for light entering the medium at that
/// angle, and the path inside is attenuated by the material's absorption. So
/// glass casts a light, coloured shadow that darkens towards its rim; the
/// focusing of light by glass (caustics) is not rendered, as in Whitted's
/// ray tracer.
pub fn transmittance(scene: &Scene, ray: &Ray, counters: &mut TraceCounters) -> Color {
    let mut tr = Color::ONE;
    let blocked = scene.visit_segment(ray, counters, |i, counters| {
        if scene.is_opaque(i) {
            return scene.objects[i as usize].shape.occludes(ray, counters);
        }
        through_glass(scene, i, ray, counters, &mut tr);
        false
    });
    if blocked { Color::ZERO } else { tr }
}

/// [`transmittance`] for each of up to [`PACKET`] shadow rays, into `out`:
/// the same values, and the same counts of object tests; meshes are
/// tested for the rays together ([`Scene::segments_packet`]).
pub fn transmittance_packet(
    scene: &Scene,
    rays: &[Ray],
    counters: &mut TraceCounters,
    out: &mut [Color],
) {
    let n = rays.len();
    assert!(n <= PACKET && out.len() == n);
    let mut blocked = [false; PACKET];
    out.fill(Color::ONE);
    scene.segments_packet(rays, counters, &mut blocked[..n], |i, j, counters| {
        through_glass(scene, i, &rays[j], counters, &mut out[j]);
    });
    for (tr, &b) in out.iter_mut().zip(&blocked[..n]) {
        if b {
            *tr = Color::ZERO;
        }
    }
}

/// [`transmittance`]'s factors for object `i`, a dielectric the shadow ray
/// passes through: `tr` is multiplied by the Fresnel transmittance of each
/// crossing (together), then by the absorption inside.
#[inline]
pub(super) fn through_glass(
    scene: &Scene,
    i: u32,
    ray: &Ray,
    counters: &mut TraceCounters,
    tr: &mut Color,
) {
    let object = &scene.objects[i as usize];
    if let Some((ior, absorption)) = scene.materials[object.material as usize].glass() {
        let mut passed = 1.0f32;
        let inside = object.shape.crossings(ray, counters, &mut |cos| {
            passed *= fresnel_dielectric(cos, 1.0, ior).transmittance;
        });
        *tr *= passed;
        if inside > 0.0 && absorption != Color::ZERO {
            *tr *= (-absorption * inside).exp();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::highlight;
    use proptest::prelude::*;

    #[test]
    fn highlight_is_powf_bit_for_bit() {
        // Exponents from scene files, OBJ and glTF (1 to 10⁴), and c over
        // (0, 1] by bit patterns, with the ends.
        for n in [0.5, 1.0, 2.0, 10.0, 64.0, 200.0, 1000.0, 4321.5, 1e4] {
            for bits in (0..=1.0f32.to_bits())
                .step_by(65_537)
                .chain([1, 0x3f7f_ffff])
            {
                let c = f32::from_bits(bits);
                assert_eq!(highlight(c, n).to_bits(), c.powf(n).to_bits(), "{c:e}^{n}");
            }
        }
    }

    proptest! {
        #[test]
        fn highlight_matches_powf(c in 0.0f32..=1.0, n in 0.01f32..1e4) {
            prop_assert_eq!(highlight(c, n).to_bits(), c.powf(n).to_bits());
        }
    }
}
