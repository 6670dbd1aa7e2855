//! The rendered image and writing it: sRGB 8-bit PNG or linear EXR, chosen by
//! the file extension, written to a temporary file and renamed into place so
//! that a failed or interrupted write never leaves a partial image.

use crate::math::Color;
use std::path::{Path, PathBuf};

/// Linear-RGB radiance per pixel, row-major from the top-left.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Color>,
}

impl Image {
    pub fn new(width: u32, height: u32) -> Self {
        Image {
            width,
            height,
            pixels: vec![Color::ZERO; width as usize * height as usize],
        }
    }

    pub fn get(&self, x: u32, y: u32) -> Color {
        self.pixels[(y * self.width + x) as usize]
    }

    /// 8-bit sRGB, three bytes per pixel: each channel clamped to [0, 1],
    /// encoded with the sRGB transfer function (IEC 61966-2-1) and rounded.
    pub fn to_srgb8(&self) -> Vec<u8> {
        self.pixels
            .iter()
            .flat_map(|c| c.to_array())
            .map(|v| (srgb_encode(v) * 255.0 + 0.5) as u8)
            .collect()
    }
}

/// The sRGB transfer function: `12.92·v` below 0.0031308, else
/// `1.055·v^(1/2.4) − 0.055`; input clamped to [0, 1] (NaN gives 0).
pub fn srgb_encode(v: f32) -> f32 {
    let v = if v > 0.0 { v.min(1.0) } else { 0.0 };
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// Output formats, by file extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    Png,
    Exr,
}

impl ImageFormat {
    /// The format for `path`'s extension (case-insensitive), if supported.
    pub fn from_path(path: &Path) -> Option<Self> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "png" => Some(ImageFormat::Png),
            "exr" => Some(ImageFormat::Exr),
            _ => None,
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum ImageWriteError {
    #[error("cannot write `{}`: unsupported file extension (use .png or .exr)", path.display())]
    UnsupportedFormat { path: PathBuf },
    #[error("cannot write `{}`: {message}", path.display())]
    Write { path: PathBuf, message: String },
}

/// Writes `image` to `path` (PNG or EXR by extension), atomically: the data go
/// to a temporary file beside it, which is renamed over `path` only once it is
/// complete.
pub fn write_image(path: &Path, image: &Image) -> Result<(), ImageWriteError> {
    let format =
        ImageFormat::from_path(path).ok_or_else(|| ImageWriteError::UnsupportedFormat {
            path: path.to_path_buf(),
        })?;
    let file_name = path
        .file_name()
        .map(|n| n.to_string_lossy())
        .unwrap_or_default();
    let tmp = path.with_file_name(format!(".{file_name}.{}.tmp", std::process::id()));
    let error = |message: String| ImageWriteError::Write {
        path: path.to_path_buf(),
        message,
    };
    let written = match format {
        ImageFormat::Png => image::save_buffer_with_format(
            &tmp,
            &image.to_srgb8(),
            image.width,
            image.height,
            image::ExtendedColorType::Rgb8,
            image::ImageFormat::Png,
        )
        .map_err(|e| e.to_string()),
        ImageFormat::Exr => exr::prelude::write_rgb_file(
            &tmp,
            image.width as usize,
            image.height as usize,
            |x, y| {
                let c = image.get(x as u32, y as u32);
                (c.x, c.y, c.z)
            },
        )
        .map_err(|e| e.to_string()),
    };
    if let Err(message) = written {
        let _ = std::fs::remove_file(&tmp);
        return Err(error(message));
    }
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        error(e.to_string())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_encoding_matches_the_standard() {
        assert_eq!(srgb_encode(0.0), 0.0);
        assert!((srgb_encode(1.0) - 1.0).abs() < 1e-6);
        assert_eq!(srgb_encode(2.0), srgb_encode(1.0));
        assert_eq!(srgb_encode(f32::NAN), 0.0);
        assert!((srgb_encode(0.18) - 0.4613).abs() < 1e-3);
        assert!((srgb_encode(0.003) - 0.03876).abs() < 1e-4);
    }

    #[test]
    fn format_follows_extension() {
        assert_eq!(
            ImageFormat::from_path(Path::new("a.PNG")),
            Some(ImageFormat::Png)
        );
        assert_eq!(
            ImageFormat::from_path(Path::new("dir/a.exr")),
            Some(ImageFormat::Exr)
        );
        assert_eq!(ImageFormat::from_path(Path::new("a.jpg")), None);
        assert_eq!(ImageFormat::from_path(Path::new("a")), None);
    }
}
