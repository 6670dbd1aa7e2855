//! Lights: what the integrators sample to find light.
//!
//! [`Light`] is the closed set of emitters: point and directional lights
//! (delta distributions, reached only by shadow rays), area lights (the
//! triangles, parallelograms and spheres of emissive objects, which rays
//! can also hit) and the constant environment. [`LightSet`] holds a scene's
//! lights with the tables that choose among them by power (Walker's alias
//! method, so a shading point never loops over thousands of emitters).

mod alias;
pub mod envmap;

pub use alias::AliasTable;
pub use envmap::EnvMap;

use crate::geometry::Shape;
use crate::math::{Aabb, Color, Vec3, triangle_normal};
use crate::scene::{Light as LightDesc, Material, Object};
use std::f32::consts::PI;

/// A light source.
#[derive(Clone, Debug, PartialEq)]
pub enum Light {
    /// Radiant intensity `intensity` from a point; irradiance `I/r²`.
    Point { position: Vec3, intensity: Color },
    /// Light from infinitely far along the unit `direction`, of irradiance
    /// `irradiance` on a surface facing it.
    Directional { direction: Vec3, irradiance: Color },
    /// An emitting triangle (`parallelogram`: the parallelogram) `p0 + u·e1
    /// + v·e2`, sampled uniformly by area.
    Area(AreaLight),
    /// An emitting sphere, sampled uniformly in the cone of directions it
    /// subtends (pbrt-v4 §6.2.4).
    Sphere {
        center: Vec3,
        radius: f32,
        radiance: Color,
    },
    /// Radiance `radiance` from every direction at infinity.
    Environment { radiance: Color },
    /// Radiance from an environment map, importance-sampled.
    EnvMap(std::sync::Arc<EnvMap>),
}

/// A flat emitter: a triangle or a parallelogram.
#[derive(Clone, Debug, PartialEq)]
pub struct AreaLight {
    pub p0: Vec3,
    pub e1: Vec3,
    pub e2: Vec3,
    /// Unit normal `e1 × e2/|…|`: the emitting side of a one-sided light.
    pub n: Vec3,
    pub area: f32,
    pub radiance: Color,
    pub two_sided: bool,
    pub parallelogram: bool,
}

/// Light arriving at a point from a sampled point (or direction) of a light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSample {
    /// Unit direction from the shading point towards the light.
    pub wi: Vec3,
    /// Radiance arriving along `wi` (for a delta light: the irradiance it
    /// delivers on a surface facing it).
    pub li: Color,
    /// Density of `wi` over solid angle; 1 for delta lights.
    pub pdf: f32,
    /// The point sampled on the light; `None` for lights at infinity.
    pub target: Option<Vec3>,
    pub delta: bool,
}

impl AreaLight {
    fn new(p0: Vec3, p1: Vec3, p2: Vec3, parallelogram: bool, m: &Material) -> Option<Self> {
        let (e1, e2) = (p1 - p0, p2 - p0);
        let n = triangle_normal(p0, p1, p2);
        let area = e1.cross(e2).length() * if parallelogram { 1.0 } else { 0.5 };
        (n != Vec3::ZERO && area > 0.0 && area.is_finite()).then_some(AreaLight {
            p0,
            e1,
            e2,
            n,
            area,
            radiance: m.emission,
            two_sided: m.two_sided,
            parallelogram,
        })
    }

    /// Radiance leaving towards `w` (unit, away from the light).
    #[inline]
    fn emitted(&self, w: Vec3) -> Color {
        if self.two_sided || self.n.dot(w) > 0.0 {
            self.radiance
        } else {
            Color::ZERO
        }
    }
}

impl Light {
    /// Samples light arriving at `p` with `u ∈ [0, 1)²`. `None` where the
    /// sample carries nothing (the back of a one-sided light, a point inside
    /// a sphere light's surface).
    #[inline(always)]
    pub fn sample_li(&self, p: Vec3, u: (f32, f32)) -> Option<LightSample> {
        match self {
            Light::Point {
                position,
                intensity,
            } => {
                let to_light = *position - p;
                let dist2 = to_light.length_squared();
                (dist2 > 0.0).then(|| LightSample {
                    wi: to_light / dist2.sqrt(),
                    li: *intensity / dist2,
                    pdf: 1.0,
                    target: Some(*position),
                    delta: true,
                })
            }
            Light::Directional {
                direction,
                irradiance,
            } => Some(LightSample {
                wi: -*direction,
                li: *irradiance,
                pdf: 1.0,
                target: None,
                delta: true,
            }),
            Light::Area(a) => {
                // Uniform by area: a parallelogram directly; a triangle by
                // folding the square (u1 + u2 > 1 maps to 1 − u).
                let (mut u1, mut u2) = u;
                if !a.parallelogram && u1 + u2 > 1.0 {
                    (u1, u2) = (1.0 - u1, 1.0 - u2);
                }
                let q = a.p0 + a.e1 * u1 + a.e2 * u2;
                let d = q - p;
                let dist2 = d.length_squared();
                let wi = d / dist2.sqrt();
                let cos_l = a.n.dot(wi).abs();
                let li = a.emitted(-wi);
                if li == Color::ZERO || cos_l == 0.0 || dist2.is_nan() || dist2 <= 0.0 {
                    return None;
                }
                let pdf = dist2 / (cos_l * a.area);
                pdf.is_finite().then_some(LightSample {
                    wi,
                    li,
                    pdf,
                    target: Some(q),
                    delta: false,
                })
            }
            Light::Sphere {
                center,
                radius,
                radiance,
            } => {
                let dc = *center - p;
                let dist2 = dc.length_squared();
                let r2 = radius * radius;
                if dist2 <= r2 * 1.0001 {
                    return None;
                }
                let sin2_max = r2 / dist2;
                let cos_max = (1.0 - sin2_max).max(0.0).sqrt();
                // 1 − cos θ_max without cancellation for small cones.
                let one_minus = sin2_max / (1.0 + cos_max);
                let cos_t = 1.0 - u.0 * one_minus;
                let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
                let (sin_p, cos_p) = crate::math::sin_cos_turns(u.1);
                let dist = dist2.sqrt();
                let axis = dc / dist;
                let frame = crate::shading::Frame::from_z(axis);
                let wi = frame
                    .to_world(Vec3::new(sin_t * cos_p, sin_t * sin_p, cos_t))
                    .normalize();
                // Distance to the near side along wi (tangent point if the
                // rounded ray misses).
                let b = dist * cos_t;
                let disc = (r2 - (dist2 - b * b)).max(0.0);
                let t = b - disc.sqrt();
                Some(LightSample {
                    wi,
                    li: *radiance,
                    pdf: 1.0 / (2.0 * PI * one_minus),
                    target: Some(p + wi * t),
                    delta: false,
                })
            }
            Light::EnvMap(map) => {
                let (wi, pdf, li) = map.sample(u)?;
                (li != Color::ZERO).then_some(LightSample {
                    wi,
                    li,
                    pdf,
                    target: None,
                    delta: false,
                })
            }
            Light::Environment { radiance } => {
                // Uniform over the sphere.
                let z = 1.0 - 2.0 * u.0;
                let r = (1.0 - z * z).max(0.0).sqrt();
                let (sin_p, cos_p) = crate::math::sin_cos_turns(u.1);
                Some(LightSample {
                    wi: Vec3::new(r * cos_p, r * sin_p, z),
                    li: *radiance,
                    pdf: 1.0 / (4.0 * PI),
                    target: None,
                    delta: false,
                })
            }
        }
    }

    /// The density (solid angle, at `p`) with which [`Light::sample_li`]
    /// picks direction `wi`, given that `wi` meets the light at `q` (unused
    /// for lights at infinity). Zero for delta lights.
    #[inline]
    pub fn pdf_li(&self, p: Vec3, wi: Vec3, q: Vec3) -> f32 {
        match self {
            Light::Point { .. } | Light::Directional { .. } => 0.0,
            Light::Area(a) => {
                let cos_l = a.n.dot(wi).abs();
                let dist2 = (q - p).length_squared();
                // A degenerate triangle's slot (never chosen) has no density.
                if cos_l == 0.0 || a.area == 0.0 {
                    return 0.0;
                }
                dist2 / (cos_l * a.area)
            }
            Light::Sphere { center, radius, .. } => {
                let dist2 = (*center - p).length_squared();
                let r2 = radius * radius;
                if dist2 <= r2 * 1.0001 {
                    return 0.0;
                }
                let sin2_max = r2 / dist2;
                let cos_max = (1.0 - sin2_max).max(0.0).sqrt();
                1.0 / (2.0 * PI * sin2_max / (1.0 + cos_max))
            }
            Light::Environment { .. } => 1.0 / (4.0 * PI),
            Light::EnvMap(map) => map.pdf(wi),
        }
    }

    /// Radiance leaving a point of the light with geometric normal `n`
    /// towards `w` (unit, away from the light).
    #[inline]
    pub fn le(&self, n: Vec3, w: Vec3) -> Color {
        match self {
            Light::Area(a) => a.emitted(w),
            Light::Sphere { radiance, .. } => {
                if n.dot(w) > 0.0 {
                    *radiance
                } else {
                    Color::ZERO
                }
            }
            Light::Environment { radiance } => *radiance,
            Light::EnvMap(map) => map.le(-w),
            Light::Point { .. } | Light::Directional { .. } => Color::ZERO,
        }
    }

    /// Whether the light is a delta distribution (point or directional).
    #[inline]
    pub fn is_delta(&self) -> bool {
        matches!(self, Light::Point { .. } | Light::Directional { .. })
    }

    /// Emitted power (average over channels), for choosing lights; lights at
    /// infinity count what falls on a disc of the scene's radius.
    pub fn power(&self, scene_radius: f32) -> f64 {
        let avg = |c: Color| ((c.x + c.y + c.z) / 3.0) as f64;
        let pi = std::f64::consts::PI;
        let r2 = (scene_radius as f64).powi(2);
        match self {
            Light::Point { intensity, .. } => 4.0 * pi * avg(*intensity),
            Light::Directional { irradiance, .. } => pi * r2 * avg(*irradiance),
            Light::Area(a) => {
                pi * a.area as f64 * avg(a.radiance) * if a.two_sided { 2.0 } else { 1.0 }
            }
            Light::Sphere {
                radius, radiance, ..
            } => pi * 4.0 * pi * (*radius as f64).powi(2) * avg(*radiance),
            Light::Environment { radiance } => 4.0 * pi * pi * r2 * avg(*radiance),
            Light::EnvMap(map) => 4.0 * pi * pi * r2 * avg(map.mean_radiance()),
        }
    }
}

/// The most area lights a scene may have (one per emissive triangle or box
/// face; about 100 bytes each, so 400 MB at most).
pub const MAX_AREA_LIGHTS: u64 = 1 << 22;

/// How many area lights [`LightSet::build`] would make of `objects`.
pub fn area_light_count(objects: &[Object], materials: &[Material]) -> u64 {
    objects
        .iter()
        .filter(|o| materials[o.material as usize].is_emissive())
        .map(|o| match &o.shape {
            Shape::Sphere(_) => 1,
            Shape::Mesh(m) => m.mesh.triangles.len() as u64,
            Shape::Cuboid(_) => 6,
            Shape::Plane(_) | Shape::Implicit(_) => 0,
        })
        .sum()
}

/// Marks objects without lights in [`LightSet::object_lights`].
pub const NO_LIGHT: u32 = u32::MAX;

/// A scene's lights and the tables that choose among them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LightSet {
    pub lights: Vec<Light>,
    /// Every light, chosen by power (the `path` integrator's choice).
    pub select: AliasTable,
    /// The area lights (triangles, parallelograms, spheres), chosen by
    /// power: what Whitted's soft shadows sample.
    pub area_select: AliasTable,
    /// Indices into `lights` of `area_select`'s entries.
    pub area_lights: Vec<u32>,
    /// The delta lights, in the order of the scene file.
    pub delta_lights: Vec<u32>,
    /// Per object, its first light (a mesh's triangle `k` is light
    /// `first + k`), or [`NO_LIGHT`] for objects that do not emit or whose
    /// shape cannot be sampled (planes, implicit surfaces: their light is
    /// found only by rays that hit them).
    pub object_lights: Vec<u32>,
    /// The environment light: the map if there is one, else the background
    /// colour if it is not black.
    pub environment: Option<u32>,
}

impl LightSet {
    /// The lights of a scene: its point and directional lights, one area
    /// light per triangle of an emissive mesh, per face of an emissive box,
    /// one per emissive sphere, and the environment: `environment`'s map,
    /// or else the colour `background` if it is not black.
    pub fn build(
        objects: &[Object],
        materials: &[Material],
        descs: &[LightDesc],
        background: Color,
        environment: Option<&std::sync::Arc<EnvMap>>,
    ) -> Self {
        let mut lights = Vec::new();
        for d in descs {
            lights.push(match *d {
                LightDesc::Point {
                    position,
                    intensity,
                } => Light::Point {
                    position,
                    intensity,
                },
                LightDesc::Directional {
                    direction,
                    irradiance,
                } => Light::Directional {
                    direction,
                    irradiance,
                },
            });
        }
        let delta_lights = (0..lights.len() as u32).collect();
        let mut object_lights = vec![NO_LIGHT; objects.len()];
        for (i, o) in objects.iter().enumerate() {
            let m = &materials[o.material as usize];
            // Face k of a box: see `Cuboid::face_corners`.
            if !m.is_emissive() {
                continue;
            }
            let first = lights.len() as u32;
            match &o.shape {
                Shape::Sphere(s) => lights.push(Light::Sphere {
                    center: s.center,
                    radius: s.radius,
                    radiance: m.emission,
                }),
                Shape::Mesh(mesh) => {
                    for prim in 0..mesh.mesh.triangles.len() as u32 {
                        let [a, b, c] = mesh.world_triangle(prim);
                        // Degenerate triangles keep their slot (a black
                        // light, never chosen) so that `first + prim` holds.
                        let light = AreaLight::new(a, b, c, false, m).unwrap_or(AreaLight {
                            p0: a,
                            e1: Vec3::ZERO,
                            e2: Vec3::ZERO,
                            n: Vec3::Z,
                            area: 0.0,
                            radiance: Color::ZERO,
                            two_sided: false,
                            parallelogram: false,
                        });
                        lights.push(Light::Area(light));
                    }
                }
                Shape::Cuboid(c) => {
                    for face in 0..6 {
                        let [p0, p1, p2] = c.face_corners(face);
                        if let Some(l) = AreaLight::new(p0, p1, p2, true, m) {
                            lights.push(Light::Area(l));
                        }
                    }
                    if lights.len() as u32 - first != 6 {
                        lights.truncate(first as usize);
                        continue;
                    }
                }
                Shape::Plane(_) | Shape::Implicit(_) => continue,
            }
            object_lights[i] = first;
        }
        let environment = match environment {
            Some(map) => {
                lights.push(Light::EnvMap(map.clone()));
                Some(lights.len() as u32 - 1)
            }
            None => (background.max_element() > 0.0).then(|| {
                lights.push(Light::Environment {
                    radiance: background,
                });
                lights.len() as u32 - 1
            }),
        };
        // The radius of the finite objects' bounds, for lights at infinity.
        let bounds = objects
            .iter()
            .map(|o| o.shape.bounds())
            .filter(|b| b.min.is_finite() && b.max.is_finite())
            .fold(Aabb::EMPTY, |a, b| a.union(&b));
        let radius = if bounds.min.is_finite() && bounds.max.is_finite() {
            0.5 * (bounds.max - bounds.min).length()
        } else {
            1.0
        }
        .max(1e-3);
        let powers: Vec<f64> = lights.iter().map(|l| l.power(radius)).collect();
        let area_lights: Vec<u32> = (0..lights.len() as u32)
            .filter(|&i| matches!(lights[i as usize], Light::Area(_) | Light::Sphere { .. }))
            .collect();
        let area_powers: Vec<f64> = area_lights.iter().map(|&i| powers[i as usize]).collect();
        LightSet {
            select: AliasTable::new(&powers),
            area_select: AliasTable::new(&area_powers),
            area_lights,
            delta_lights,
            object_lights,
            environment,
            lights,
        }
    }

    /// The light of `object`'s part `prim` (outward geometric normal `n`),
    /// if it is a sampled light.
    #[inline]
    pub fn light_of(&self, object: u32, prim: u32, n: Vec3, shape: &Shape) -> Option<u32> {
        let first = *self.object_lights.get(object as usize)?;
        if first == NO_LIGHT {
            return None;
        }
        Some(match shape {
            Shape::Sphere(_) => first,
            Shape::Cuboid(_) => first + crate::geometry::Cuboid::face_of(n),
            _ => first + prim,
        })
    }
}

#[cfg(test)]
mod tests;
