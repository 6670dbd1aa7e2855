//! Textures: what colour a surface has at a point.

use crate::math::{Color, Vec3};
use glam::Vec2;

/// Scene file: `color = [r, g, b]` or
/// `texture = { checker = [[r, g, b], [r, g, b]], scale = 1.0, mode = "planar" }`.
#[derive(Clone, Debug, PartialEq)]
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
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CheckerMode {
    /// In the surface's own (u, v) coordinates: `⌊u/s⌋ + ⌊v/s⌋` even or odd.
    Planar,
    /// A solid (3D) checkerboard in world space: `⌊x/s⌋ + ⌊y/s⌋ + ⌊z/s⌋`.
    Solid,
}

impl Texture {
    /// The colour at world point `p`; `uv` gives the surface coordinates,
    /// computed only for textures that use them.
    #[inline]
    pub fn eval(&self, p: Vec3, uv: impl FnOnce() -> Vec2) -> Color {
        match *self {
            Texture::Solid(c) => c,
            Texture::Checker {
                even,
                odd,
                scale,
                mode,
            } => {
                let cells = match mode {
                    CheckerMode::Planar => (uv() / scale).floor().element_sum(),
                    CheckerMode::Solid => (p / scale).floor().element_sum(),
                };
                if cells.rem_euclid(2.0) == 0.0 {
                    even
                } else {
                    odd
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checker_alternates_per_cell() {
        let t = Texture::Checker {
            even: Color::X,
            odd: Color::Y,
            scale: 0.5,
            mode: CheckerMode::Planar,
        };
        assert_eq!(t.eval(Vec3::ZERO, || Vec2::new(0.1, 0.1)), Color::X);
        assert_eq!(t.eval(Vec3::ZERO, || Vec2::new(0.6, 0.1)), Color::Y);
        assert_eq!(t.eval(Vec3::ZERO, || Vec2::new(-0.1, 0.1)), Color::Y);
        assert_eq!(t.eval(Vec3::ZERO, || Vec2::new(-0.1, -0.1)), Color::X);
        let s = Texture::Checker {
            even: Color::X,
            odd: Color::Y,
            scale: 1.0,
            mode: CheckerMode::Solid,
        };
        assert_eq!(s.eval(Vec3::new(0.5, 0.5, 0.5), || Vec2::ZERO), Color::X);
        assert_eq!(s.eval(Vec3::new(0.5, 1.5, 0.5), || Vec2::ZERO), Color::Y);
    }
}
