//! The scene file's `[materials]` (with textures) and `[[light]]` tables.

use super::{Ctx, Fields, Result, Value};
use crate::math::Color;
use crate::scene::{CheckerMode, Light, Material, MaterialKind, Texture};

fn read_texture(ctx: &Ctx, v: &Value, what: &str) -> Result<Texture> {
    let mut f = Fields::of(ctx, v, format!("the texture of {what}"))?;
    // The only kind of texture: a table without `checker` most likely asks
    // for another kind (`image = …`), which is better named as unknown.
    if f.table.get("checker").is_none() {
        f.known.extend(["checker", "scale", "mode"]);
        f.finish()?;
    }
    let checker = f.require("checker")?;
    let pair = ctx.array(checker, "two colours [[r, g, b], [r, g, b]]")?;
    if pair.len() != 2 {
        return Err(ctx.error(
            checker.span(),
            format!(
                "expected two colours [[r, g, b], [r, g, b]], found {} elements",
                pair.len()
            ),
        ));
    }
    let (even, odd) = (ctx.color(&pair[0])?, ctx.color(&pair[1])?);
    let scale = f.checked("scale", Some(1.0), |x| x > 0.0, "a positive cell size")?;
    let mode = match f.choice("mode", &["planar", "solid"])? {
        Some("solid") => CheckerMode::Solid,
        _ => CheckerMode::Planar,
    };
    f.finish()?;
    Ok(Texture::Checker {
        even,
        odd,
        scale,
        mode,
    })
}

pub(super) fn read_material(ctx: &Ctx, name: &str, v: &Value) -> Result<Material> {
    let what = format!("material `{name}`");
    let mut f = Fields::of(ctx, v, what.clone())?;
    let kind = f.require("type")?;
    let kind_name = ctx.string(kind)?;
    let is_diffuse = kind_name == "diffuse";
    let base = if is_diffuse { 1.0 } else { 0.0 };
    let unit = |x: f32| (0.0..=1.0).contains(&x);
    let kind = match kind_name {
        "diffuse" => MaterialKind::Diffuse,
        "mirror" => MaterialKind::Mirror {
            reflectance: f.opt("reflectance", Ctx::color)?.unwrap_or(Color::ONE),
        },
        "dielectric" => MaterialKind::Dielectric {
            ior: f.checked(
                "ior",
                Some(1.5),
                |x| x > 0.0,
                "a positive index of refraction",
            )?,
            absorption: f.opt("absorption", Ctx::color)?.unwrap_or(Color::ZERO),
            roughness: f.checked("roughness", Some(0.0), unit, "a number from 0 to 1")?,
        },
        "principled" => MaterialKind::Principled {
            metallic: f.checked("metallic", Some(0.0), unit, "a number from 0 to 1")?,
            roughness: f.checked("roughness", Some(0.5), unit, "a number from 0 to 1")?,
            transmission: f.checked("transmission", Some(0.0), unit, "a number from 0 to 1")?,
            ior: f.checked("ior", Some(1.5), |x| x >= 1.0, "an index of refraction ≥ 1")?,
        },
        "conductor" => MaterialKind::Conductor {
            complex_ior: read_complex_ior(ctx, &mut f)?,
            roughness: f.checked("roughness", Some(0.0), unit, "a number from 0 to 1")?,
            anisotropy: f.checked(
                "anisotropy",
                Some(0.0),
                |a| a > -1.0 && a < 1.0,
                "a number between −1 and 1",
            )?,
        },
        other => {
            return Err(ctx.error(
                kind.span(),
                format!(
                    "unknown material type `{other}`; expected one of: diffuse, mirror, dielectric, conductor, principled"
                ),
            ));
        }
    };
    let color = f.opt("color", Ctx::color)?;
    let texture = match (color, f.get("texture")) {
        (Some(_), Some(t)) => {
            return Err(ctx.error(
                t.span(),
                format!("{what} has both `color` and `texture`; give one"),
            ));
        }
        (_, Some(t)) => read_texture(ctx, t, &what)?,
        (Some(c), None) => Texture::Solid(c),
        (None, None) => Texture::Solid(if is_diffuse {
            Color::splat(0.8)
        } else {
            Color::ONE
        }),
    };
    let nonneg = |x: f32| x >= 0.0;
    let material = Material {
        texture,
        ambient: f.checked("ambient", Some(base), nonneg, "a number ≥ 0")?,
        diffuse: f.checked("diffuse", Some(base), nonneg, "a number ≥ 0")?,
        specular: f.checked("specular", Some(0.0), nonneg, "a number ≥ 0")?,
        shininess: f.checked("shininess", Some(64.0), |x| x > 0.0, "a positive exponent")?,
        kind,
        emission: f.opt("emission", Ctx::color)?.unwrap_or(Color::ZERO),
        two_sided: f.opt("two_sided", Ctx::boolean)?.unwrap_or(false),
    };
    f.finish()?;
    Ok(material)
}

/// A conductor's complex index: `metal = "Au"` (see
/// [`crate::shading::fresnel::METALS`]), or `eta` and `k`, or neither (a
/// constant reflectance, the material's colour).
fn read_complex_ior(ctx: &Ctx, f: &mut Fields) -> Result<Option<(Color, Color)>> {
    let metal = f.get("metal");
    let eta = f.opt("eta", Ctx::color)?;
    let k = f.opt("k", Ctx::color)?;
    match (metal, eta, k) {
        (Some(m), None, None) => {
            let name = ctx.string(m)?;
            crate::shading::fresnel::metal(name)
                .map(Some)
                .ok_or_else(|| {
                    let names: Vec<&str> = crate::shading::fresnel::METALS
                        .iter()
                        .map(|(n, _, _)| *n)
                        .collect();
                    ctx.error(
                        m.span(),
                        format!(
                            "unknown metal `{name}`; expected one of: {}",
                            names.join(", ")
                        ),
                    )
                })
        }
        (Some(m), _, _) => Err(ctx.error(
            m.span(),
            "give either `metal` or `eta` and `k`, not both".to_string(),
        )),
        (None, Some(eta), Some(k)) => {
            if eta.min_element() <= 0.0 {
                return Err(ctx.error(f.span.clone(), "`eta` must be positive".to_string()));
            }
            Ok(Some((eta, k)))
        }
        (None, None, None) => Ok(None),
        (None, _, _) => Err(ctx.error(
            f.span.clone(),
            "a conductor needs both `eta` and `k` (or `metal`)".to_string(),
        )),
    }
}

pub(super) fn read_light(ctx: &Ctx, v: &Value, index: usize) -> Result<Light> {
    let mut f = Fields::of(ctx, v, format!("light {index}"))?;
    let kind = f.require("type")?;
    let light = match ctx.string(kind)? {
        "point" => Light::Point {
            position: f.req("position", Ctx::vec3)?,
            intensity: f.req("intensity", Ctx::color)?,
        },
        "directional" => {
            let d = f.require("direction")?;
            let direction = ctx
                .vec3(d)?
                .try_normalize()
                .ok_or_else(|| ctx.error(d.span(), "expected a non-zero direction"))?;
            Light::Directional {
                direction,
                irradiance: f.req("irradiance", Ctx::color)?,
            }
        }
        other => {
            return Err(ctx.error(
                kind.span(),
                format!("unknown light type `{other}`; expected one of: point, directional"),
            ));
        }
    };
    f.finish()?;
    Ok(light)
}
