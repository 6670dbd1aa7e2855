//! Whitted's shading of a batch of hits in SIMD lanes, for the breadth-first
//! stream ([`super::stream`]): the surface point, the local terms' shadow
//! rays and gains for point lights, and the reflected and refracted rays,
//! computed for many hits at once in structure-of-arrays form, in loops the
//! compiler vectorises (see [`crate::scene::widest`]).
//!
//! Each lane does exactly the arithmetic of the one-hit code, in the same
//! order: [`crate::scene::Scene::surface`], [`super::whitted::AtHit::new`],
//! [`super::whitted::local_terms`], `Whitted::secondaries`, with glam's
//! vector operations spelt out per component (`a·b = (a.x·b.x + a.y·b.y) +
//! a.z·b.z`, `normalize(v) = v / |v|`, `normalize_or_zero(v) = v·(1/|v|)`,
//! min and max as SSE's `a < b ? a : b`) and no fused multiply–adds. So a
//! hit gets the same rays and terms, bit for bit, either way; the stream
//! tests (`tests/stream.rs`) compare whole renders both ways.
//!
//! It takes the hits on spheres, boxes and planes whose material is
//! diffuse, a mirror or clear glass (no emission, no absorption), textured
//! by a colour or a checkerboard (solid, or planar on a box), in scenes
//! whose lights are point lights ([`Plan::new`]). Other hits are shaded
//! one by one, in their turn.

use super::columns::{Nodes, Wave};
use super::lane::{
    F, GROUP, Lane, Lane3, Mask, Z, Z3, at, blend, compress, dot, floor_lane, for_lanes,
    for_lanes_in, fresnel_lane, get, is_even_lane, neg, offset_origin, pick, put, put_if,
};
use super::whitted::highlight;
use crate::geometry::Shape;
use crate::geometry::batch::{BATCH, Closest, RayBatch};
use crate::light::Light;
use crate::math::{Color, SHADOW_EPSILON, gamma};
use crate::scene::{CheckerMode, MaterialKind, Object, Scene, Texture};

/// Most point lights the lanes take.
pub(super) const MAX_LIGHTS: usize = 4;

/// A shape the lanes take.
#[derive(Clone, Copy, Debug)]
enum Form {
    Sphere { center: [f32; 3], radius: f32 },
    Cuboid { min: [f32; 3], max: [f32; 3] },
    Plane { point: [f32; 3], normal: [f32; 3] },
}

/// A texture the lanes take.
#[derive(Clone, Copy, Debug)]
enum Paint {
    Solid([f32; 3]),
    /// A checkerboard, planar (on a box's faces) or solid.
    Checker {
        even: [f32; 3],
        odd: [f32; 3],
        scale: f32,
        planar: bool,
    },
}

const DIFFUSE: u32 = 0;
const MIRROR: u32 = 1;
const GLASS: u32 = 2;

/// What the lanes need of an object: its shape, texture and material.
#[derive(Clone, Copy, Debug)]
struct Look {
    form: Form,
    paint: Paint,
    ambient: f32,
    diffuse: f32,
    specular: f32,
    shininess: f32,
    /// [`DIFFUSE`], [`MIRROR`] or [`GLASS`].
    kind: u32,
    reflectance: [f32; 3],
    /// `reflectance.max_element()`, as glam gives it.
    reflectance_max: f32,
    ior: f32,
}

/// How the lanes shade a scene: each object's look (`None`: shaded one by
/// one) and the point lights, in the order of the delta lights.
pub(super) struct Plan {
    looks: Vec<Option<Look>>,
    lights: Vec<([f32; 3], [f32; 3])>,
    ambient: [f32; 3],
}

impl Plan {
    /// The plan for `scene`, if the lanes can shade any of its hits: its
    /// delta lights are at most [`MAX_LIGHTS`] point lights.
    pub(super) fn new(scene: &Scene) -> Option<Plan> {
        let mut lights = Vec::new();
        for &i in &scene.emitters.delta_lights {
            match scene.emitters.lights[i as usize] {
                Light::Point {
                    position,
                    intensity,
                } => lights.push((position.to_array(), intensity.to_array())),
                _ => return None,
            }
        }
        if lights.len() > MAX_LIGHTS {
            return None;
        }
        let looks: Vec<Option<Look>> = scene.objects.iter().map(|o| look(scene, o)).collect();
        looks.iter().any(Option::is_some).then(|| Plan {
            looks,
            lights,
            ambient: scene.ambient.to_array(),
        })
    }

    pub(super) fn lights(&self) -> usize {
        self.lights.len()
    }
}

/// The look of an object the lanes can shade.
fn look(scene: &Scene, object: &Object) -> Option<Look> {
    let m = &scene.materials[object.material as usize];
    if m.is_emissive() {
        return None;
    }
    let (kind, reflectance, ior) = match m.kind {
        MaterialKind::Diffuse => (DIFFUSE, Color::ZERO, 1.0),
        MaterialKind::Mirror { reflectance } => (MIRROR, reflectance, 1.0),
        MaterialKind::Dielectric {
            ior, absorption, ..
        } if absorption == Color::ZERO => (GLASS, Color::ZERO, ior),
        _ => return None,
    };
    let form = match &object.shape {
        Shape::Sphere(s) => Form::Sphere {
            center: s.center.to_array(),
            radius: s.radius,
        },
        Shape::Cuboid(c) => Form::Cuboid {
            min: c.bounds.min.to_array(),
            max: c.bounds.max.to_array(),
        },
        Shape::Plane(p) => Form::Plane {
            point: p.point.to_array(),
            normal: p.normal.to_array(),
        },
        _ => return None,
    };
    let paint = match m.texture {
        Texture::Solid(c) => Paint::Solid(c.to_array()),
        Texture::Checker {
            even,
            odd,
            scale,
            mode,
        } => {
            let planar = mode == CheckerMode::Planar;
            // Planar on a sphere or a plane: their (u, v) are left to the
            // one-by-one code.
            if planar && !matches!(form, Form::Cuboid { .. }) {
                return None;
            }
            Paint::Checker {
                even: even.to_array(),
                odd: odd.to_array(),
                scale,
                planar,
            }
        }
    };
    Some(Look {
        form,
        paint,
        ambient: m.ambient,
        diffuse: m.diffuse,
        specular: m.specular,
        shininess: m.shininess,
        kind,
        reflectance: reflectance.to_array(),
        reflectance_max: reflectance.max_element(),
        ior,
    })
}

/// The shading of a batch's hits, lane by lane (meaningful only in lanes
/// marked `shaded`): the hits, then per light and for the secondary rays
/// (apart, so that the compiler sees that each phase's output does not
/// overlap its input).
pub(super) struct Lanes {
    hits: HitLanes,
    lights: [LightLanes; MAX_LIGHTS],
    secondaries: SecondaryLanes,
    /// Whether any lane may spawn secondary rays (else `secondaries` is
    /// not computed).
    spawns: bool,
}

/// The hits' surface, material and local term.
struct HitLanes {
    /// Whether the lane's hit was shaded here.
    shaded: Mask,
    // The surface point, its error bound, the geometric normal, the albedo
    // and the material's coefficients.
    p: Lane3,
    p_err: Lane3,
    n: Lane3,
    albedo: Lane3,
    ambient: Lane,
    diffuse: Lane,
    specular: Lane,
    shininess: Lane,
    kind: [u32; BATCH],
    reflectance: Lane3,
    reflectance_max: Lane,
    ior: Lane,
    /// The unit direction of the ray, whether it met the front, and the
    /// normal facing it.
    d: Lane3,
    front: Mask,
    n_facing: Lane3,
    /// The ambient term.
    local: Lane3,
}

/// A light's shadow rays: whether the lane has one, the ray, and its gain.
struct LightLanes {
    lit: Mask,
    o: Lane3,
    d: Lane3,
    irradiance: Lane3,
    diffuse: Lane3,
    n_dot_h: Lane,
}

/// The reflected and refracted rays: whether traced, the ray, factor and
/// weight.
struct SecondaryLanes {
    reflected: Mask,
    reflected_o: Lane3,
    reflected_d: Lane3,
    reflected_factor: Lane3,
    reflected_weight: Lane,
    refracted: Mask,
    refracted_o: Lane3,
    refracted_d: Lane3,
    refracted_factor: Lane,
    refracted_weight: Lane,
}

impl Lanes {
    pub(super) fn new() -> Box<Lanes> {
        const LIGHT: LightLanes = LightLanes {
            lit: F,
            o: Z3,
            d: Z3,
            irradiance: Z3,
            diffuse: Z3,
            n_dot_h: Z,
        };
        Box::new(Lanes {
            hits: HitLanes {
                shaded: F,
                p: Z3,
                p_err: Z3,
                n: Z3,
                albedo: Z3,
                ambient: Z,
                diffuse: Z,
                specular: Z,
                shininess: Z,
                kind: [0; BATCH],
                reflectance: Z3,
                reflectance_max: Z,
                ior: Z,
                d: Z3,
                front: F,
                n_facing: Z3,
                local: Z3,
            },
            lights: [LIGHT; MAX_LIGHTS],
            spawns: false,
            secondaries: SecondaryLanes {
                reflected: F,
                reflected_o: Z3,
                reflected_d: Z3,
                reflected_factor: Z3,
                reflected_weight: Z,
                refracted: F,
                refracted_o: Z3,
                refracted_d: Z3,
                refracted_factor: Z,
                refracted_weight: Z,
            },
        })
    }

    /// Whether lane `j`'s hit was shaded here.
    #[inline]
    pub(super) fn shaded(&self, j: usize) -> bool {
        self.hits.shaded[j] != 0
    }

    /// Shades the hits `best` of the batch `rays` whose objects `plan`
    /// takes; `weight` is each ray's weight, and secondary rays whose
    /// weight falls below `min_weight` are not traced, nor any unless
    /// `spawn`.
    pub(super) fn shade(
        &mut self,
        plan: &Plan,
        rays: &RayBatch,
        best: &Closest,
        weight: &Lane,
        (min_weight, spawn): (f32, bool),
    ) {
        crate::scene::widest(
            #[inline(always)]
            || self.shade_in(plan, rays, best, weight, min_weight, spawn),
        )
    }

    #[inline(always)]
    fn shade_in(
        &mut self,
        plan: &Plan,
        rays: &RayBatch,
        best: &Closest,
        weight: &Lane,
        min_weight: f32,
        spawn: bool,
    ) {
        let groups = rays.groups();
        let hits = &mut self.hits;
        hits.shaded = F;
        for (i, look) in plan.looks.iter().enumerate() {
            let Some(look) = look else { continue };
            let i = i as u32;
            if !best.object[..rays.len].contains(&i) {
                continue;
            }
            for j in 0..rays.len {
                hits.shaded[j] |= u32::from(best.object[j] == i);
            }
            hits.surface(look, i, rays, best, groups);
        }
        let ambient = plan.ambient;
        for_lanes(
            groups,
            #[inline(always)]
            |j| hits.at_hit(rays, j, ambient),
        );
        let hits = &self.hits;
        for (&(position, intensity), light) in plan.lights.iter().zip(&mut self.lights) {
            for_lanes(
                groups,
                #[inline(always)]
                |j| light.light(hits, position, intensity, j),
            );
        }
        // Only mirrors and glass spawn rays.
        let mut specular = 0;
        for j in 0..BATCH {
            specular |= hits.shaded[j] & u32::from(hits.kind[j] != DIFFUSE);
        }
        self.spawns = spawn && specular != 0;
        if !self.spawns {
            return;
        }
        let secondaries = &mut self.secondaries;
        for_lanes(
            groups,
            #[inline(always)]
            |j| secondaries.secondaries(hits, weight[j], min_weight, j),
        );
    }
}

impl HitLanes {
    /// The surface point, normal, albedo and material of the lanes that hit
    /// object `i` (of look `look`): [`crate::scene::Scene::surface`] and
    /// [`crate::scene::Scene::albedo`].
    #[inline(always)]
    fn surface(&mut self, look: &Look, i: u32, rays: &RayBatch, best: &Closest, groups: usize) {
        let at = |j: usize| at(rays, best, j);
        // The groups of lanes with a hit on the object.
        let mut mine = [false; BATCH / GROUP];
        for (g, mine) in mine.iter_mut().enumerate().take(groups) {
            *mine = best.object[g * GROUP..(g + 1) * GROUP].contains(&i);
        }
        // Each lane's point, error bound and normal.
        let mut point = |j: usize, (p, p_err, n): ([f32; 3], [f32; 3], [f32; 3])| {
            let mine = best.object[j] == i;
            put_if(&mut self.p, j, mine, p);
            put_if(&mut self.p_err, j, mine, p_err);
            put_if(&mut self.n, j, mine, n);
        };
        match look.form {
            Form::Sphere { center, radius } => {
                let (g5, g2) = (gamma(5), gamma(2));
                for_lanes_in(
                    &mine,
                    #[inline(always)]
                    |j| {
                        let raw = at(j);
                        let offset = [0, 1, 2].map(|c| raw[c] - center[c]);
                        let len = dot(offset, offset).sqrt();
                        let n = if len > 0.0 {
                            offset.map(|x| x / len)
                        } else {
                            [0.0, 1.0, 0.0]
                        };
                        let local = n.map(|x| x * radius);
                        let p = [0, 1, 2].map(|c| center[c] + local[c]);
                        let p_err = [0, 1, 2].map(|c| g5 * local[c].abs() + g2 * p[c].abs());
                        point(j, (p, p_err, n));
                    },
                );
            }
            Form::Cuboid { min, max } => {
                let g5 = gamma(5);
                for_lanes_in(
                    &mine,
                    #[inline(always)]
                    |j| {
                        let prim = best.prim[j];
                        let axis = prim % 3;
                        let (dx, dy, dz) = (rays.d[0][j], rays.d[1][j], rays.d[2][j]);
                        let d_axis = if axis == 0 {
                            dx
                        } else if axis == 1 {
                            dy
                        } else {
                            dz
                        };
                        let outward_positive = if prim >= 3 {
                            d_axis > 0.0
                        } else {
                            d_axis < 0.0
                        };
                        let (face, sign) = if outward_positive {
                            (max, 1.0)
                        } else {
                            (min, -1.0)
                        };
                        let raw = at(j);
                        let on = [axis == 0, axis == 1, axis == 2];
                        let p = [0, 1, 2].map(|c| {
                            let x = if on[c] { face[c] } else { raw[c] };
                            // glam's clamp: `max(min)` then `min(max)`, as SSE.
                            let x = if x > min[c] { x } else { min[c] };
                            if x < max[c] { x } else { max[c] }
                        });
                        let n = on.map(|o| if o { sign } else { 0.0 });
                        let p_err = p.map(|x| g5 * x.abs());
                        point(j, (p, p_err, n));
                    },
                );
            }
            Form::Plane { point: q, normal } => {
                let g7 = gamma(7);
                for_lanes_in(
                    &mine,
                    #[inline(always)]
                    |j| {
                        let raw = at(j);
                        let h = dot([0, 1, 2].map(|c| raw[c] - q[c]), normal);
                        let p = [0, 1, 2].map(|c| raw[c] - h * normal[c]);
                        let p_err = [0, 1, 2].map(|c| g7 * (p[c].abs() + q[c].abs()));
                        point(j, (p, p_err, normal));
                    },
                );
            }
        }
        // The albedo. The checkerboard's cells are counted in loops of
        // their own, which the compiler vectorises (with the choice of
        // paint and the colours' selects in the same loop it kept them
        // scalar: 2–3 % of a Whitted frame).
        match look.paint {
            Paint::Solid(c) => for_lanes_in(
                &mine,
                #[inline(always)]
                |j| put_if(&mut self.albedo, j, best.object[j] == i, c),
            ),
            Paint::Checker {
                even,
                odd,
                scale,
                planar,
            } => {
                let mut cells: Lane = [0.0; BATCH];
                if planar {
                    for_lanes_in(
                        &mine,
                        #[inline(always)]
                        |j| {
                            // A box's (u, v) on the face of axis `prim % 3`.
                            let p = get(&self.p, j);
                            let axis = best.prim[j] % 3;
                            let u = if axis == 0 { p[2] } else { p[0] };
                            let v = if axis == 1 { p[2] } else { p[1] };
                            cells[j] = floor_lane(u / scale) + floor_lane(v / scale);
                        },
                    );
                } else {
                    for_lanes_in(
                        &mine,
                        #[inline(always)]
                        |j| {
                            let p = get(&self.p, j);
                            cells[j] = (floor_lane(p[0] / scale) + floor_lane(p[1] / scale))
                                + floor_lane(p[2] / scale);
                        },
                    );
                }
                for_lanes_in(
                    &mine,
                    #[inline(always)]
                    |j| {
                        let albedo = pick(is_even_lane(cells[j]), even, odd);
                        put_if(&mut self.albedo, j, best.object[j] == i, albedo);
                    },
                );
            }
        }
        for_lanes_in(
            &mine,
            #[inline(always)]
            |j| {
                let mine = best.object[j] == i;
                let set = |lane: &mut Lane, x: f32| lane[j] = if mine { x } else { lane[j] };
                set(&mut self.ambient, look.ambient);
                set(&mut self.diffuse, look.diffuse);
                set(&mut self.specular, look.specular);
                set(&mut self.shininess, look.shininess);
                set(&mut self.reflectance_max, look.reflectance_max);
                set(&mut self.ior, look.ior);
                self.kind[j] = if mine { look.kind } else { self.kind[j] };
                put_if(&mut self.reflectance, j, mine, look.reflectance);
            },
        );
    }

    /// [`super::whitted::AtHit::new`]'s direction, side and facing normal,
    /// and the ambient term of [`super::whitted::local_terms`].
    #[inline(always)]
    fn at_hit(&mut self, rays: &RayBatch, j: usize, ambient: [f32; 3]) {
        let d = [rays.d[0][j], rays.d[1][j], rays.d[2][j]];
        let len = dot(d, d).sqrt();
        let d = d.map(|x| x / len);
        let n = get(&self.n, j);
        let front = dot(d, n) < 0.0;
        let toward = pick(front, n, neg(n));
        // face_forward(ns, toward), with ns = n for these shapes.
        let n_facing = pick(dot(n, toward) < 0.0, neg(n), n);
        put(&mut self.d, j, d);
        self.front[j] = u32::from(front);
        put(&mut self.n_facing, j, n_facing);
        let (a, albedo) = (self.ambient[j], get(&self.albedo, j));
        put(
            &mut self.local,
            j,
            [0, 1, 2].map(|c| (a * albedo[c]) * ambient[c]),
        );
    }
}

impl LightLanes {
    /// Point light `k` at `position` of intensity `intensity`: its shadow
    /// ray and gain, as [`super::whitted::local_terms`] makes them.
    // `!(x <= 0)` and `!(x >= 1)`: NaN passes, as in the one-hit code's
    // early returns.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    #[inline(always)]
    fn light(&mut self, hits: &HitLanes, position: [f32; 3], intensity: [f32; 3], j: usize) {
        let (p, p_err, n) = (get(&hits.p, j), get(&hits.p_err, j), get(&hits.n, j));
        let n_facing = get(&hits.n_facing, j);
        let wo = neg(get(&hits.d, j));
        let to_light = [0, 1, 2].map(|c| position[c] - p[c]);
        let dist2 = dot(to_light, to_light);
        let dist = dist2.sqrt();
        let wi = to_light.map(|x| x / dist);
        let o = offset_origin(p, p_err, n, to_light);
        let cos = dot(n_facing, wi);
        let (kd, ks) = (hits.diffuse[j], hits.specular[j]);
        let shading = !(kd == 0.0 && ks == 0.0);
        self.lit[j] = hits.shaded[j] & u32::from(shading & (dist2 > 0.0) & !(cos <= 0.0));
        put(&mut self.o, j, o);
        put(&mut self.d, j, [0, 1, 2].map(|c| position[c] - o[c]));
        put(&mut self.irradiance, j, intensity.map(|x| x / dist2));
        let albedo = get(&hits.albedo, j);
        put(&mut self.diffuse, j, albedo.map(|a| (kd * cos) * a));
        // normalize_or_zero(wi + wo): `v·(1/|v|)` where that is finite and
        // positive, else 0.
        let h = [0, 1, 2].map(|c| wi[c] + wo[c]);
        let rcp = 1.0 / dot(h, h).sqrt();
        let h = if rcp.is_finite() && rcp > 0.0 {
            h.map(|x| x * rcp)
        } else {
            [0.0; 3]
        };
        self.n_dot_h[j] = if ks > 0.0 {
            dot(n_facing, h).max(0.0)
        } else {
            0.0
        };
    }
}

impl SecondaryLanes {
    /// `Whitted::secondaries`: a mirror's reflected ray, or a dielectric's
    /// reflected and refracted rays, each if its weight reaches `min_weight`.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    #[inline(always)]
    fn secondaries(&mut self, hits: &HitLanes, weight: f32, min_weight: f32, j: usize) {
        let (p, p_err, n) = (get(&hits.p, j), get(&hits.p_err, j), get(&hits.n, j));
        let (d, n_facing) = (get(&hits.d, j), get(&hits.n_facing, j));
        let kind = hits.kind[j];
        let shaded = hits.shaded[j];
        // reflect(d, n) = d − (2·(d·n))·n.
        let d_dot_n = dot(d, n_facing);
        let k = 2.0 * d_dot_n;
        let reflected = [0, 1, 2].map(|c| d[c] - k * n_facing[c]);
        // The dielectric's Fresnel terms and refracted direction.
        let ior = hits.ior[j];
        let front = hits.front[j] != 0;
        let (eta_i, eta_t) = if front { (1.0, ior) } else { (ior, 1.0) };
        let wo = neg(d);
        let f = fresnel_lane(dot(wo, n_facing), eta_i, eta_t);
        let eta = eta_i / eta_t;
        let cos_i = -d_dot_n;
        let sin2_t = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
        let cos_t = (1.0 - sin2_t).sqrt();
        let a = eta * cos_i - cos_t;
        let refracted = [0, 1, 2].map(|c| eta * d[c] + a * n_facing[c]);
        let glass = kind == GLASS;
        let (factor, w) = if kind == MIRROR {
            (get(&hits.reflectance, j), weight * hits.reflectance_max[j])
        } else {
            ([f.reflectance; 3], weight * f.reflectance)
        };
        self.reflected[j] = shaded & u32::from((kind != DIFFUSE) & (w >= min_weight));
        put(
            &mut self.reflected_o,
            j,
            offset_origin(p, p_err, n, reflected),
        );
        put(&mut self.reflected_d, j, reflected);
        put(&mut self.reflected_factor, j, factor);
        self.reflected_weight[j] = w;
        let w = weight * f.transmittance;
        self.refracted[j] = shaded & u32::from(glass & (w >= min_weight) & !(sin2_t >= 1.0));
        put(
            &mut self.refracted_o,
            j,
            offset_origin(p, p_err, n, refracted),
        );
        put(&mut self.refracted_d, j, refracted);
        self.refracted_factor[j] = f.transmittance;
        self.refracted_weight[j] = w;
    }
}

impl Lanes {
    /// The ambient terms of lanes `..n` into nodes `first..`, where shaded.
    pub(super) fn write_locals(&self, n: usize, first: usize, nodes: &mut Nodes) {
        let hits = &self.hits;
        for (local, lane) in nodes.local.iter_mut().zip(&hits.local) {
            for (j, l) in local[first..first + n].iter_mut().enumerate() {
                *l = blend(hits.shaded[j] != 0, lane[j], *l);
            }
        }
    }

    /// Light `k`'s shadow rays of lanes `..n` (those that have one),
    /// gathered into `batch` in lane order; `lane[q]` is ray `q`'s lane.
    pub(super) fn shadow_batch(&self, k: usize, n: usize, batch: &mut RayBatch, lane: &mut Mask) {
        let light = &self.lights[k];
        // Lane numbers as bit patterns: the compress moves bits.
        const LANE: Mask = {
            let mut lanes = [0; BATCH];
            let mut j = 0;
            while j < BATCH {
                lanes[j] = j as u32;
                j += 1;
            }
            lanes
        };
        let [ox, oy, oz] = &mut batch.o;
        let [dx, dy, dz] = &mut batch.d;
        let (o, d) = (&light.o, &light.d);
        let at = compress(
            &light.lit,
            n,
            [
                &o[0],
                &o[1],
                &o[2],
                &d[0],
                &d[1],
                &d[2],
                bytemuck::cast_ref(&LANE),
            ],
            [ox, oy, oz, dx, dy, dz, bytemuck::cast_mut(lane)],
        );
        batch.t_min[..at].fill(0.0);
        batch.t_max[..at].fill(1.0 - SHADOW_EPSILON);
        batch.len = at;
    }

    /// Adds light `k`'s terms to the nodes (lane `j`'s is `first + j`)
    /// of lanes `..n`, through the transmittance `visibility(q)` of each
    /// shadow ray `q` of [`Lanes::shadow_batch`] (of lane `lane[q]`): `V·E·
    /// (k_d·C·(N·L) + k_s·(N·H)^n)`, as [`super::whitted::LightGain::radiance`]
    /// makes it,
    /// where `V` is not 0.
    pub(super) fn add_light(
        &self,
        (k, n): (usize, usize),
        lane: &[u32],
        visibility: impl Fn(usize) -> Color,
        first: usize,
        nodes: &mut Nodes,
    ) {
        let (light, hits) = (&self.lights[k], &self.hits);
        // The transmittance by lane (0 without a shadow ray), and the
        // reflected part, with its highlight where there is one (`powf`
        // one by one).
        let mut v = Z3;
        let mut open = F;
        let mut reflected = light.diffuse;
        for (q, &j) in lane.iter().enumerate() {
            let (j, vis) = (j as usize, visibility(q));
            put(&mut v, j, vis.to_array());
            open[j] = u32::from(vis != Color::ZERO);
            let ks = hits.specular[j];
            if ks > 0.0 && vis != Color::ZERO {
                let h = ks * highlight(light.n_dot_h[j], hits.shininess[j]);
                let r = get(&reflected, j).map(|r| r + h);
                put(&mut reflected, j, r);
            }
        }
        for c in 0..3 {
            let (v, e, r) = (&v[c], &light.irradiance[c], &reflected[c]);
            let local = &mut nodes.local[c][first..first + n];
            for (j, l) in local.iter_mut().enumerate() {
                *l = blend(open[j] != 0, *l + (v[j] * e[j]) * r[j], *l);
            }
        }
    }

    /// The reflected and refracted rays of lanes `..n` (nodes `first..`),
    /// put after `next`'s in lane order (each node's reflected ray first),
    /// and the nodes' children (the rays of `next` are nodes from
    /// `next_base`); returns how many were reflected and refracted.
    pub(super) fn write_secondaries(
        &self,
        n: usize,
        first: usize,
        next_base: usize,
        nodes: &mut Nodes,
        next: &mut Wave,
    ) -> (u64, u64) {
        if !self.spawns {
            return (0, 0);
        }
        let s = &self.secondaries;
        next.room(2 * n);
        let mut at = next.len();
        let (mut reflected, mut refracted) = (0, 0);
        for j in 0..n {
            let (r, t) = (s.reflected[j], s.refracted[j]);
            // The nodes were made without children.
            if r + t == 0 {
                continue;
            }
            nodes.first_child[first + j] = (next_base + at) as u32;
            nodes.children[first + j] = r + t;
            let ray = (get(&s.reflected_o, j), get(&s.reflected_d, j));
            next.set(at, ray, get(&s.reflected_factor, j), s.reflected_weight[j]);
            at += r as usize;
            let ray = (get(&s.refracted_o, j), get(&s.refracted_d, j));
            next.set(at, ray, [s.refracted_factor[j]; 3], s.refracted_weight[j]);
            at += t as usize;
            reflected += u64::from(r);
            refracted += u64::from(t);
        }
        next.rays.len = at;
        (reflected, refracted)
    }
}
