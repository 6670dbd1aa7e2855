//! Textures: what colour a surface has at a point.

use crate::math::{Color, Vec3, floor};
use glam::Vec2;

/// Scene file: `color = [r, g, b]` or
/// `texture = { checker = [[r, g, b], [r, g, b]], scale = 1.0, mode = "planar" }`.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Texture {
    Solid(Color),
    /// Squares of side `scale` alternating between `even` and `odd`.
    Checker {
        even: Color,
        odd: Color,
        scale: f32,
        mode: CheckerMode,
    },
}

/// How a checkerboard is laid on a surface.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CheckerMode {
    /// In the surface's own (u, v) coordinates: `⌊u/s⌋ + ⌊v/s⌋` even or odd.
    Planar,
    /// A solid (3D) checkerboard in world space: `⌊x/s⌋ + ⌊y/s⌋ + ⌊z/s⌋`.
    Solid,
}

impl Texture {
    /// The colour at world point `p`; `uv` gives the surface coordinates,
    /// computed only for textures that use them. A planar checker on a
    /// surface without coordinates (`uv` gives `None`: implicit surfaces,
    /// meshes without texture coordinates) is laid as a solid one, whose
    /// cubes cut any surface in a regular pattern.
    #[inline]
    pub fn eval(&self, p: Vec3, uv: impl FnOnce() -> Option<Vec2>) -> Color {
        match *self {
            Texture::Solid(c) => c,
            Texture::Checker {
                even,
                odd,
                scale,
                mode,
            } => {
                let planar = match mode {
                    CheckerMode::Planar => uv(),
                    CheckerMode::Solid => None,
                };
                let cells = match planar {
                    Some(uv) => (uv / scale).map(floor).element_sum(),
                    None => (p / scale).map(floor).element_sum(),
                };
                if is_even(cells) { even } else { odd }
            }
        }
    }
}

/// Whether the integer-valued `cells` is even: `cells.rem_euclid(2.0) ==
/// 0.0` (true for ±0 and for every float from 2^24 on; false for ±∞ and
/// NaN), without the slow `fmodf` it calls.
#[inline]
pub fn is_even(cells: f32) -> bool {
    cells.is_finite() & (floor(cells * 0.5) * 2.0 == cells)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn is_even_is_rem_euclid_for_integer_valued_floats() {
        let mut values: Vec<f32> = (-300..300).map(|k| k as f32).collect();
        for e in 20..128 {
            let big = 2f32.powi(e);
            values.extend([big, -big, big - 1.0, -(big - 1.0), big + 1.0]);
        }
        values.extend([
            0.0,
            -0.0,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            f32::MAX,
            f32::MIN,
        ]);
        for x in values {
            assert_eq!(is_even(x), x.rem_euclid(2.0) == 0.0, "{x}");
        }
    }

    #[test]
    fn checker_alternates_per_cell() {
        let t = Texture::Checker {
            even: Color::X,
            odd: Color::Y,
            scale: 0.5,
            mode: CheckerMode::Planar,
        };
        assert_eq!(t.eval(Vec3::ZERO, || Some(Vec2::new(0.1, 0.1))), Color::X);
        assert_eq!(t.eval(Vec3::ZERO, || Some(Vec2::new(0.6, 0.1))), Color::Y);
        assert_eq!(t.eval(Vec3::ZERO, || Some(Vec2::new(-0.1, 0.1))), Color::Y);
        assert_eq!(t.eval(Vec3::ZERO, || Some(Vec2::new(-0.1, -0.1))), Color::X);
        let s = Texture::Checker {
            even: Color::X,
            odd: Color::Y,
            scale: 1.0,
            mode: CheckerMode::Solid,
        };
        assert_eq!(
            s.eval(Vec3::new(0.5, 0.5, 0.5), || Some(Vec2::ZERO)),
            Color::X
        );
        assert_eq!(
            s.eval(Vec3::new(0.5, 1.5, 0.5), || Some(Vec2::ZERO)),
            Color::Y
        );
    }

    #[test]
    fn planar_checker_without_surface_coordinates_is_solid() {
        let t = Texture::Checker {
            even: Color::X,
            odd: Color::Y,
            scale: 1.0,
            mode: CheckerMode::Planar,
        };
        assert_eq!(t.eval(Vec3::new(0.5, 0.5, 0.5), || None), Color::X);
        assert_eq!(t.eval(Vec3::new(0.5, 1.5, 0.5), || None), Color::Y);
        assert_eq!(t.eval(Vec3::new(1.5, 1.5, 0.5), || None), Color::X);
    }
}
