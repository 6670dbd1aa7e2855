//! The TOML scene file (documented key by key in `docs/scene-format.md`).
//!
//! The file is parsed into toml's spanned document tree, then read table by
//! table. Every key is looked up by name, so every error can point at the
//! exact place: an unknown key at the key, a wrong type or value at the value,
//! a missing key at the table that lacks it.
//!
//! ```toml
//! [camera]
//! position = [0, 2.2, -7]
//! look_at = [0, 1, 0]
//!
//! [materials]
//! glass = { type = "dielectric", ior = 1.5 }
//!
//! [[light]]
//! type = "point"
//! position = [4, 9, -7]
//! intensity = 130
//!
//! [[object]]
//! shape = "sphere"
//! center = [0, 1, 0]
//! radius = 1
//! material = "glass"
//! ```

use super::Scene;
use super::desc::{
    CameraDesc, EnvironmentDesc, ImplicitFormula, NamedMaterial, NamedSurface, ObjectDesc, Place,
    SceneDesc, ShapeDesc, TransformDesc, check_camera, implicit_formula,
};
use super::files::{FileError, read_text_file};
use crate::geometry::Implicit;
use crate::geometry::implicit::ImplicitError;
use crate::math::{Aabb, Color, Transform, Vec3};
use crate::settings::{
    IntegratorKind, MAX_DEPTH, MAX_IMAGE_SIDE, MAX_LIGHT_SAMPLES, MAX_SPP, RenderSettings, Sampling,
};
use std::ops::Range;
use std::path::{Path, PathBuf};
use toml::Spanned;
use toml::de::{DeTable, DeValue};

mod materials;
use materials::{read_light, read_material};

/// The built-in scene: Whitted's spheres and checkerboard, as shipped in
/// `scenes/whitted.toml`.
pub const BUILTIN_WHITTED: &str = include_str!("../../../scenes/whitted.toml");

/// A scene file's contents: the scene and its `[render]` settings.
#[derive(Clone, Debug)]
pub struct SceneFile {
    pub scene: Scene,
    pub settings: RenderSettings,
    /// Seconds spent reading mesh files and building their BVHs.
    pub seconds_mesh_load: f64,
    pub seconds_mesh_build: f64,
    /// The mesh files' warnings (see `Model::warnings`).
    pub warnings: Vec<String>,
    /// The description the scene was built from (`None` for a scene made
    /// from a mesh file by [`super::mesh_scene`]).
    pub desc: Option<SceneDesc>,
}

/// Why a scene could not be loaded. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("cannot read scene file `{}`: {}", path.display(), reason.reason())]
    Io { path: PathBuf, reason: FileError },
    #[error("{}:{line}:{column}: {message}", path.display())]
    Parse {
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// 1-based column, in characters.
        column: usize,
        message: String,
    },
    #[error("{}: {error}", path.display())]
    Build {
        path: PathBuf,
        error: super::desc::DescError,
    },
}

/// Reads and parses the scene file at `path`: TOML, or (with the extension
/// `.json`) a [`SceneDesc`] as JSON.
pub fn load_scene_file(path: &Path) -> std::result::Result<SceneFile, SceneError> {
    let text = read_text_file(path).map_err(|reason| SceneError::Io {
        path: path.to_path_buf(),
        reason,
    })?;
    let is_json = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    if is_json {
        parse_scene_json(&text, path)
    } else {
        parse_scene(&text, path)
    }
}

/// Parses a [`SceneDesc`] written as JSON and builds it; errors name the
/// line and column (serde's), or the object, light or material at fault.
pub fn parse_scene_json(text: &str, path: &Path) -> std::result::Result<SceneFile, SceneError> {
    let desc: SceneDesc = serde_json::from_str(text).map_err(|e| SceneError::Parse {
        path: path.to_path_buf(),
        line: e.line(),
        column: e.column(),
        message: e
            .to_string()
            .split(" at line ")
            .next()
            .unwrap_or("")
            .to_string(),
    })?;
    let folder = path.parent().unwrap_or(Path::new(""));
    desc.build(folder).map_err(|e| SceneError::Build {
        path: path.to_path_buf(),
        error: e,
    })
}

/// Parses scene-file text and builds the scene; `path` is used in error
/// messages, and its folder is where relative mesh paths start.
pub fn parse_scene(text: &str, path: &Path) -> std::result::Result<SceneFile, SceneError> {
    let ctx = Ctx { path, text };
    let (desc, spans) = describe(&ctx)?;
    let folder = path.parent().unwrap_or(Path::new(""));
    // What only the build can find (a mesh file that cannot be read, a
    // transform made singular by a file's own) is placed at the object.
    desc.build(folder).map_err(|e| match e.place {
        Place::Object(i, _) => {
            ctx.error(spans.objects.get(i - 1).cloned().unwrap_or(0..0), e.message)
        }
        Place::Environment => ctx.error(spans.environment.clone().unwrap_or(0..0), e.to_string()),
        _ => ctx.error(0..0, e.to_string()),
    })
}

/// Parses scene-file text into a [`SceneDesc`], without reading mesh files
/// or building anything; `path` is used in error messages only. Every value
/// is checked here, where errors can point at it.
pub fn parse_scene_desc(text: &str, path: &Path) -> std::result::Result<SceneDesc, SceneError> {
    describe(&Ctx { path, text }).map(|(desc, _)| desc)
}

/// Where build errors point: each object, and the environment map's file.
struct Spans {
    objects: Vec<Range<usize>>,
    environment: Option<Range<usize>>,
}

/// The description, and the spans that build errors point at.
fn describe(ctx: &Ctx) -> Result<(SceneDesc, Spans)> {
    let doc = DeTable::parse(ctx.text).map_err(|e| {
        let span = e.span().unwrap_or(0..0);
        ctx.error(span, format!("invalid TOML: {}", e.message().trim()))
    })?;
    read_document(ctx, doc.get_ref(), doc.span())
}

type Value<'i> = Spanned<DeValue<'i>>;
type Result<T> = std::result::Result<T, SceneError>;

struct Ctx<'a> {
    path: &'a Path,
    text: &'a str,
}

impl Ctx<'_> {
    /// An error located at the start of the byte range `span`.
    fn error(&self, span: Range<usize>, message: impl Into<String>) -> SceneError {
        let offset = span.start.min(self.text.len());
        let before = &self.text[..offset];
        let line = before.matches('\n').count() + 1;
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        SceneError::Parse {
            path: self.path.to_path_buf(),
            line,
            column: before[line_start..].chars().count() + 1,
            message: message.into(),
        }
    }

    fn number(&self, v: &Value) -> Result<f32> {
        let x = match v.get_ref() {
            DeValue::Integer(i) => parse_integer(i.as_str(), i.radix()).map(|i| i as f64),
            DeValue::Float(f) => f.as_str().replace('_', "").parse::<f64>().ok(),
            other => {
                return Err(self.error(
                    v.span(),
                    format!("expected a number, found {}", other.type_str()),
                ));
            }
        };
        match x.map(|x| x as f32) {
            Some(x) if x.is_finite() => Ok(x),
            _ => Err(self.error(v.span(), "expected a finite number")),
        }
    }

    fn integer(&self, v: &Value) -> Result<i64> {
        match v.get_ref() {
            DeValue::Integer(i) => parse_integer(i.as_str(), i.radix())
                .ok_or_else(|| self.error(v.span(), "integer out of range")),
            other => Err(self.error(
                v.span(),
                format!("expected an integer, found {}", other.type_str()),
            )),
        }
    }

    fn string<'v>(&self, v: &'v Value) -> Result<&'v str> {
        match v.get_ref() {
            DeValue::String(s) => Ok(s),
            other => Err(self.error(
                v.span(),
                format!("expected a string, found {}", other.type_str()),
            )),
        }
    }

    fn boolean(&self, v: &Value) -> Result<bool> {
        match v.get_ref() {
            DeValue::Boolean(b) => Ok(*b),
            other => Err(self.error(
                v.span(),
                format!("expected true or false, found {}", other.type_str()),
            )),
        }
    }

    fn array<'v, 'i>(&self, v: &'v Value<'i>, what: &str) -> Result<&'v [Value<'i>]> {
        match v.get_ref() {
            DeValue::Array(a) => Ok(a),
            other => Err(self.error(
                v.span(),
                format!("expected {what}, found {}", other.type_str()),
            )),
        }
    }

    fn vec3(&self, v: &Value) -> Result<Vec3> {
        const WHAT: &str = "an array of 3 numbers [x, y, z]";
        let items = self.array(v, WHAT)?;
        if items.len() != 3 {
            return Err(self.error(
                v.span(),
                format!("expected {WHAT}, found {} elements", items.len()),
            ));
        }
        Ok(Vec3::new(
            self.number(&items[0])?,
            self.number(&items[1])?,
            self.number(&items[2])?,
        ))
    }

    /// A colour: `[r, g, b]`, or one number for grey; components ≥ 0.
    fn color(&self, v: &Value) -> Result<Color> {
        let c = match v.get_ref() {
            DeValue::Array(_) => self.vec3(v)?,
            DeValue::Integer(_) | DeValue::Float(_) => Color::splat(self.number(v)?),
            other => {
                return Err(self.error(
                    v.span(),
                    format!(
                        "expected a colour [r, g, b] or a number, found {}",
                        other.type_str()
                    ),
                ));
            }
        };
        if c.min_element() < 0.0 {
            return Err(self.error(v.span(), "expected colour components ≥ 0"));
        }
        Ok(c)
    }
}

/// Levenshtein distance between two short strings.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diagonal = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let substitute = diagonal + usize::from(ca != cb);
            diagonal = row[j + 1];
            row[j + 1] = substitute.min(row[j] + 1).min(row[j + 1] + 1);
        }
    }
    row[b.len()]
}

/// The value of a TOML integer's text in `radix`, or `None` where it is not
/// one (out of range, or no digits: the reader hands over `0b` as an empty
/// text, which must not be sliced).
fn parse_integer(digits: &str, radix: u32) -> Option<i64> {
    let digits = digits.replace('_', "");
    let digits = match radix {
        10 => digits.as_str(),
        _ => ["0x", "0o", "0b"]
            .iter()
            .find_map(|p| digits.strip_prefix(p))
            .unwrap_or(&digits),
    };
    i64::from_str_radix(digits, radix).ok()
}

/// Reads the keys of one table, remembering which were asked for, so that
/// [`Fields::finish`] can reject the others as unknown.
struct Fields<'c, 'i> {
    ctx: &'c Ctx<'c>,
    table: &'c DeTable<'i>,
    span: Range<usize>,
    /// How the table is named in messages, e.g. "[camera]" or "object 2 (sphere)".
    what: String,
    known: Vec<&'static str>,
}

impl<'c, 'i> Fields<'c, 'i> {
    fn new(ctx: &'c Ctx<'c>, table: &'c DeTable<'i>, span: Range<usize>, what: String) -> Self {
        Fields {
            ctx,
            table,
            span,
            what,
            known: Vec::new(),
        }
    }

    /// A table value, or an error naming `what` it should have been.
    fn of(ctx: &'c Ctx<'c>, v: &'c Value<'i>, what: String) -> Result<Self> {
        match v.get_ref() {
            DeValue::Table(t) => Ok(Fields::new(ctx, t, v.span(), what)),
            other => Err(ctx.error(
                v.span(),
                format!("expected a table for {what}, found {}", other.type_str()),
            )),
        }
    }

    fn get(&mut self, key: &'static str) -> Option<&'c Value<'i>> {
        self.known.push(key);
        self.table.get(key)
    }

    /// A key that must be present. When it is missing and an unknown key in
    /// the table is a likely misspelling of it, that key is reported instead.
    fn require(&mut self, key: &'static str) -> Result<&'c Value<'i>> {
        if let Some(v) = self.get(key) {
            return Ok(v);
        }
        let typo = self.table.iter().map(|(k, _)| k).find(|k| {
            let k = k.get_ref().as_ref();
            !self.known.contains(&k) && edit_distance(k, key) <= 2
        });
        Err(match typo {
            Some(k) => self.ctx.error(
                k.span(),
                format!(
                    "unknown key `{}` in {}; did you mean `{key}`?",
                    k.get_ref(),
                    self.what
                ),
            ),
            None => self.ctx.error(
                self.span.clone(),
                format!("missing required key `{key}` in {}", self.what),
            ),
        })
    }

    fn opt<T>(
        &mut self,
        key: &'static str,
        read: impl FnOnce(&'c Ctx<'c>, &'c Value<'i>) -> Result<T>,
    ) -> Result<Option<T>> {
        match self.get(key) {
            Some(v) => read(self.ctx, v).map(Some),
            None => Ok(None),
        }
    }

    fn req<T>(
        &mut self,
        key: &'static str,
        read: impl FnOnce(&'c Ctx<'c>, &'c Value<'i>) -> Result<T>,
    ) -> Result<T> {
        let v = self.require(key)?;
        read(self.ctx, v)
    }

    /// A number that must satisfy `ok`; `expected` says what was expected.
    fn checked(
        &mut self,
        key: &'static str,
        default: Option<f32>,
        ok: impl Fn(f32) -> bool,
        expected: &str,
    ) -> Result<f32> {
        let v = match (self.get(key), default) {
            (Some(v), _) => v,
            (None, Some(d)) => return Ok(d),
            (None, None) => return self.require(key).map(|_| 0.0),
        };
        let x = self.ctx.number(v)?;
        if !ok(x) {
            return Err(self.ctx.error(
                v.span(),
                format!("expected {expected} for `{key}`, found {x}"),
            ));
        }
        Ok(x)
    }

    /// An integer in `range`, or `default` if absent.
    fn int_in(&mut self, key: &'static str, default: i64, range: Range<i64>) -> Result<i64> {
        let Some(v) = self.get(key) else {
            return Ok(default);
        };
        let x = self.ctx.integer(v)?;
        if !range.contains(&x) {
            return Err(self.ctx.error(
                v.span(),
                format!(
                    "expected an integer from {} to {} for `{key}`, found {x}",
                    range.start,
                    range.end - 1
                ),
            ));
        }
        Ok(x)
    }

    /// One of `names`, as a string.
    fn choice(&mut self, key: &'static str, names: &[&str]) -> Result<Option<&'c str>> {
        let Some(v) = self.get(key) else {
            return Ok(None);
        };
        let s = self.ctx.string(v)?;
        if !names.contains(&s) {
            return Err(self.ctx.error(
                v.span(),
                format!("unknown {key} `{s}`; expected one of: {}", names.join(", ")),
            ));
        }
        Ok(Some(s))
    }

    /// Rejects any key that was never asked for.
    fn finish(&self) -> Result<()> {
        for (key, _) in self.table.iter() {
            if !self.known.contains(&key.get_ref().as_ref()) {
                let mut known = self.known.clone();
                known.sort_unstable();
                known.dedup();
                return Err(self.ctx.error(
                    key.span(),
                    format!(
                        "unknown key `{}` in {}; expected one of: {}",
                        key.get_ref(),
                        self.what,
                        known.join(", ")
                    ),
                ));
            }
        }
        Ok(())
    }
}

fn read_document(ctx: &Ctx, doc: &DeTable, span: Range<usize>) -> Result<(SceneDesc, Spans)> {
    let mut top = Fields::new(ctx, doc, span.start..span.start, "the scene file".into());

    let camera = read_camera(ctx, top.require("camera")?)?;

    let mut settings = RenderSettings::default();
    let (mut background, mut ambient) = (Color::ZERO, Color::ZERO);
    if let Some(v) = top.get("render") {
        let mut f = Fields::of(ctx, v, "[render]".into())?;
        settings.width =
            f.int_in("width", settings.width as i64, 1..MAX_IMAGE_SIDE as i64 + 1)? as u32;
        settings.height = f.int_in(
            "height",
            settings.height as i64,
            1..MAX_IMAGE_SIDE as i64 + 1,
        )? as u32;
        settings.spp = f.int_in("spp", settings.spp as i64, 1..MAX_SPP as i64 + 1)? as u32;
        settings.max_depth = f.int_in(
            "max_depth",
            settings.max_depth as i64,
            -1..MAX_DEPTH as i64 + 1,
        )? as i32;
        settings.light_samples = f.int_in(
            "light_samples",
            settings.light_samples as i64,
            0..MAX_LIGHT_SAMPLES as i64 + 1,
        )? as u32;
        settings.min_weight = f.checked(
            "min_weight",
            Some(settings.min_weight),
            |x| (0.0..=1.0).contains(&x),
            "a number from 0 to 1",
        )?;
        if let Some(name) = f.choice("integrator", &IntegratorKind::NAMES)? {
            settings.integrator = IntegratorKind::from_name(name).unwrap_or_default();
        }
        if let Some(name) = f.choice("sampling", &Sampling::NAMES)? {
            settings.sampling = name.parse().unwrap_or_default();
        }
        if let Some(c) = f.opt("clamp", Ctx::number)? {
            if !(c > 0.0 && c.is_finite()) {
                return Err(ctx.error(
                    f.table.get("clamp").map_or(0..0, |v| v.span()),
                    format!("expected a positive number for `clamp`, found {c}"),
                ));
            }
            settings.clamp = Some(c);
        }
        background = f.opt("background", Ctx::color)?.unwrap_or(background);
        ambient = f.opt("ambient", Ctx::color)?.unwrap_or(ambient);
        f.finish()?;
    }

    let mut materials = Vec::new();
    if let Some(v) = top.get("materials") {
        let f = Fields::of(ctx, v, "[materials]".into())?;
        for (name, value) in f.table.iter() {
            let name = name.get_ref().as_ref();
            materials.push(NamedMaterial {
                name: name.to_string(),
                material: read_material(ctx, name, value)?,
            });
        }
    }

    let mut lights = Vec::new();
    if let Some(v) = top.get("light") {
        for (i, item) in ctx
            .array(v, "an array of [[light]] tables")?
            .iter()
            .enumerate()
        {
            lights.push(read_light(ctx, item, i + 1)?);
        }
    }

    let mut objects = Vec::new();
    let mut spans = Vec::new();
    if let Some(v) = top.get("object") {
        let names: Vec<&str> = materials.iter().map(|m| m.name.as_str()).collect();
        for (i, item) in ctx
            .array(v, "an array of [[object]] tables")?
            .iter()
            .enumerate()
        {
            let (object, span) = read_object(ctx, item, i + 1, &names)?;
            objects.push(object);
            spans.push(span);
        }
    }
    let mut environment_span = None;
    let environment = match top.get("environment") {
        None => None,
        Some(v) => {
            let mut f = Fields::of(ctx, v, "[environment]".into())?;
            let map_value = f.require("map")?;
            environment_span = Some(map_value.span());
            let map = PathBuf::from(ctx.string(map_value)?);
            let scale = f.checked(
                "scale",
                Some(1.0),
                |x| x >= 0.0 && x.is_finite(),
                "a number ≥ 0",
            )?;
            let rotate_y =
                f.checked("rotate_y", Some(0.0), f32::is_finite, "an angle in degrees")?;
            f.finish()?;
            Some(EnvironmentDesc {
                map,
                scale,
                rotate_y,
            })
        }
    };
    top.finish()?;

    let desc = SceneDesc {
        camera,
        settings,
        background,
        ambient,
        materials,
        lights,
        objects,
        environment,
    };
    Ok((
        desc,
        Spans {
            objects: spans,
            environment: environment_span,
        },
    ))
}

fn read_camera(ctx: &Ctx, v: &Value) -> Result<CameraDesc> {
    let mut f = Fields::of(ctx, v, "[camera]".into())?;
    let position = f.req("position", Ctx::vec3)?;
    let look_at = f.req("look_at", Ctx::vec3)?;
    let up = f.opt("up", Ctx::vec3)?.unwrap_or(Vec3::Y);
    let fov = f.checked(
        "fov",
        Some(40.0),
        |x| x > 0.0 && x < 180.0,
        "a vertical field of view in degrees, between 0 and 180",
    )?;
    let span = f.span.clone();
    f.finish()?;
    let camera = CameraDesc {
        position,
        look_at,
        up,
        fov,
    };
    match check_camera(&camera) {
        Ok(_) => Ok(camera),
        Err(_) => Err(ctx.error(
            span,
            "degenerate [camera]: `look_at` must differ from `position`, and `up` must not be parallel to the view direction",
        )),
    }
}

/// `bounds = [[x, y, z], [x, y, z]]`, min then max.
fn read_bounds(ctx: &Ctx, v: &Value) -> Result<[Vec3; 2]> {
    const WHAT: &str = "[[min x, y, z], [max x, y, z]]";
    let corners = ctx.array(v, WHAT)?;
    if corners.len() != 2 {
        return Err(ctx.error(
            v.span(),
            format!("expected {WHAT}, found {} elements", corners.len()),
        ));
    }
    let (min, max) = (ctx.vec3(&corners[0])?, ctx.vec3(&corners[1])?);
    if !min.cmplt(max).all() {
        return Err(ctx.error(
            corners[1].span(),
            "expected the second corner greater than the first in every coordinate",
        ));
    }
    Ok([min, max])
}

/// `transform = { scale = s | [sx, sy, sz], rotate_x = deg, rotate_y = deg,
/// rotate_z = deg, translate = [x, y, z] }`: scale, then rotate about x, y, z,
/// then translate.
fn read_transform(ctx: &Ctx, v: &Value) -> Result<TransformDesc> {
    let mut f = Fields::of(ctx, v, "the transform".into())?;
    let scale = match f.get("scale") {
        None => Vec3::ONE,
        Some(s) => match s.get_ref() {
            DeValue::Array(_) => ctx.vec3(s)?,
            _ => Vec3::splat(ctx.number(s)?),
        },
    };
    let any = |_: f32| true;
    let rotate_deg = Vec3::new(
        f.checked("rotate_x", Some(0.0), any, "an angle in degrees")?,
        f.checked("rotate_y", Some(0.0), any, "an angle in degrees")?,
        f.checked("rotate_z", Some(0.0), any, "an angle in degrees")?,
    );
    let translate = f.opt("translate", Ctx::vec3)?.unwrap_or(Vec3::ZERO);
    f.finish()?;
    let desc = TransformDesc {
        scale,
        rotate_deg,
        translate,
    };
    match desc.transform() {
        Some(_) => Ok(desc),
        None => Err(ctx.error(v.span(), "the transform is singular (a scale is zero)")),
    }
}

/// An implicit surface: `f = "formula"` with `bounds`, or a named `surface`
/// (`"torus"` with `major_radius` and `minor_radius`, or `"heart"`), whose
/// bounds default to a box that holds it.
fn read_implicit(ctx: &Ctx, f: &mut Fields) -> Result<ShapeDesc> {
    let surface = f.choice("surface", &["torus", "heart"])?;
    let formula_value = f.get("f");
    let formula = match (surface, formula_value) {
        (Some(_), Some(v)) => {
            return Err(ctx.error(
                v.span(),
                format!("{} has both `f` and `surface`; give one", f.what),
            ));
        }
        (None, None) => return Err(f.require("f").map(|_| ()).unwrap_err()),
        (None, Some(v)) => ImplicitFormula::Formula(ctx.string(v)?.to_string()),
        (Some("torus"), None) => ImplicitFormula::Named(NamedSurface::Torus {
            major_radius: f.checked("major_radius", None, |x| x > 0.0, "a positive radius")?,
            minor_radius: f.checked("minor_radius", None, |x| x > 0.0, "a positive radius")?,
        }),
        (Some(_), None) => ImplicitFormula::Named(NamedSurface::Heart),
    };
    let (text, default_bounds) =
        implicit_formula(&formula).map_err(|m| ctx.error(f.span.clone(), m))?;
    let bounds = f.opt("bounds", read_bounds)?;
    let aabb = match (bounds, default_bounds) {
        (Some([min, max]), _) => Aabb::new(min, max),
        (None, Some(b)) => b,
        (None, None) => return Err(f.require("bounds").map(|_| ()).unwrap_err()),
    };
    let transform = f.opt("transform", read_transform)?;
    // Compiled here (and again by the build) so that a formula's errors
    // point at their column in the file.
    let checked = transform
        .as_ref()
        .and_then(TransformDesc::transform)
        .unwrap_or(Transform::IDENTITY);
    if let Err(e) = Implicit::new(&text, aabb, checked) {
        return Err(match (e, formula_value) {
            (ImplicitError::Formula(e), Some(v)) => {
                formula_error(ctx, v, &text, e.column, &e.message)
            }
            (e, _) => ctx.error(f.span.clone(), format!("in the formula of {}: {e}", f.what)),
        });
    }
    Ok(ShapeDesc::Implicit {
        formula,
        bounds,
        transform,
    })
}

/// Locates an error at `column` (1-based, in characters) of the formula in the
/// string value `v`: exactly, when the string is written without escapes;
/// otherwise at the string, naming the column.
fn formula_error(ctx: &Ctx, v: &Value, formula: &str, column: usize, message: &str) -> SceneError {
    let span = v.span();
    let raw = &ctx.text[span.clone()];
    let quote = if raw.starts_with("\"\"\"") || raw.starts_with("'''") {
        3
    } else {
        1
    };
    let body = raw.get(quote..).unwrap_or("");
    if body.starts_with(formula) {
        let offset = formula
            .char_indices()
            .nth(column - 1)
            .map_or(formula.len(), |(i, _)| i);
        let at = span.start + quote + offset;
        ctx.error(at..at, format!("in formula: {message}"))
    } else {
        ctx.error(span, format!("in formula, column {column}: {message}"))
    }
}

/// An object, and where the build's errors about it point (a mesh's file).
fn read_object(
    ctx: &Ctx,
    v: &Value,
    index: usize,
    materials: &[&str],
) -> Result<(ObjectDesc, Range<usize>)> {
    let mut f = Fields::of(ctx, v, format!("object {index}"))?;
    let kind = f.require("shape")?;
    let kind_name = ctx.string(kind)?;
    f.what = format!("object {index} ({kind_name})");
    let mut span = f.span.clone();
    let shape = match kind_name {
        "sphere" => ShapeDesc::Sphere {
            center: f.req("center", Ctx::vec3)?,
            radius: f.checked("radius", None, |x| x > 0.0, "a positive radius")?,
        },
        "plane" => {
            let point = f.opt("point", Ctx::vec3)?.unwrap_or(Vec3::ZERO);
            let normal = match f.get("normal") {
                Some(n) => ctx
                    .vec3(n)?
                    .try_normalize()
                    .ok_or_else(|| ctx.error(n.span(), "expected a non-zero normal"))?,
                None => Vec3::Y,
            };
            ShapeDesc::Plane { point, normal }
        }
        "box" => {
            let min = f.req("min", Ctx::vec3)?;
            let max_value = f.require("max")?;
            let max = ctx.vec3(max_value)?;
            if !min.cmplt(max).all() {
                return Err(ctx.error(
                    max_value.span(),
                    "expected `max` greater than `min` in every coordinate",
                ));
            }
            ShapeDesc::Box { min, max }
        }
        "implicit" => read_implicit(ctx, &mut f)?,
        "mesh" => {
            let file = f.require("file")?;
            span = file.span();
            ShapeDesc::Mesh {
                file: PathBuf::from(ctx.string(file)?),
                smooth: f.opt("smooth", |ctx, v| ctx.boolean(v))?.unwrap_or(false),
                transform: f.opt("transform", read_transform)?,
            }
        }
        other => {
            return Err(ctx.error(
                kind.span(),
                format!(
                    "unknown shape `{other}`; expected one of: sphere, plane, box, implicit, mesh"
                ),
            ));
        }
    };
    let material = match f.get("material") {
        None => None,
        Some(m) => {
            let name = ctx.string(m)?;
            if !materials.contains(&name) {
                let mut names = materials.to_vec();
                names.sort_unstable();
                return Err(ctx.error(
                    m.span(),
                    format!(
                        "unknown material `{name}`; defined in [materials]: {}",
                        if names.is_empty() {
                            "none".to_string()
                        } else {
                            names.join(", ")
                        }
                    ),
                ));
            }
            Some(name.to_string())
        }
    };
    f.finish()?;
    Ok((ObjectDesc { shape, material }, span))
}
