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

    /// [`Image::new`], or `None` if its pixels cannot be allocated.
    pub fn try_new(width: u32, height: u32) -> Option<Self> {
        let n = width as usize * height as usize;
        let mut pixels = Vec::new();
        pixels.try_reserve_exact(n).ok()?;
        pixels.resize(n, Color::ZERO);
        Some(Image {
            width,
            height,
            pixels,
        })
    }

    /// Bytes of the pixels of a `width × height` image.
    pub fn bytes_for(width: u32, height: u32) -> u64 {
        width as u64 * height as u64 * std::mem::size_of::<Color>() as u64
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
            .map(srgb8)
            .collect()
    }
}

/// A linear channel as an 8-bit sRGB value, rounded.
fn srgb8(v: f32) -> u8 {
    (srgb_encode(v) * 255.0 + 0.5) as u8
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

/// A file being written, all or nothing: its data go to a hidden temporary
/// file beside `path`, created at once (so a folder that cannot be written
/// is found before any work is done), and [`StagedFile::commit`] renames it
/// over `path`. Dropped uncommitted, it removes the temporary file.
#[derive(Debug)]
pub struct StagedFile {
    path: PathBuf,
    tmp: PathBuf,
    file: Option<std::fs::File>,
}

impl StagedFile {
    /// Creates the temporary file for `path`. Fails if `path` is a folder or
    /// its folder cannot be written.
    pub fn create(path: &Path) -> Result<StagedFile, ImageWriteError> {
        let error = |message: String| ImageWriteError::Write {
            path: path.to_path_buf(),
            message,
        };
        if path.is_dir() {
            return Err(error("it is a folder".into()));
        }
        let name = path
            .file_name()
            .ok_or_else(|| error("it names no file".into()))?
            .to_string_lossy();
        let tmp = path.with_file_name(format!(".{name}.{}.tmp", std::process::id()));
        let file = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&tmp)
            .map_err(|e| error(e.to_string()))?;
        Ok(StagedFile {
            path: path.to_path_buf(),
            tmp,
            file: Some(file),
        })
    }

    /// The final path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    fn error(&self, message: impl std::fmt::Display) -> ImageWriteError {
        ImageWriteError::Write {
            path: self.path.clone(),
            message: message.to_string(),
        }
    }

    /// Writes `bytes` as the file's whole content.
    pub fn write_bytes(&mut self, bytes: &[u8]) -> Result<(), ImageWriteError> {
        use std::io::Write;
        let file = self.file.as_mut().expect("open until commit");
        file.write_all(bytes).map_err(|e| self.error(e))
    }

    /// Writes `image` in the format of the final path's extension.
    pub fn write_image(&mut self, image: &Image) -> Result<(), ImageWriteError> {
        let format = ImageFormat::from_path(&self.path).ok_or_else(|| {
            ImageWriteError::UnsupportedFormat {
                path: self.path.clone(),
            }
        })?;
        let file = self.file.as_mut().expect("open until commit");
        let mut out = std::io::BufWriter::new(file);
        let written = match format {
            ImageFormat::Png => write_png(&mut out, image),
            ImageFormat::Exr => write_exr(&mut out, image),
        };
        // Flushed here, not on drop, where a failed write (a full disk)
        // would go unnoticed and a truncated file be committed.
        let flushed =
            written.and_then(|()| std::io::Write::flush(&mut out).map_err(|e| e.to_string()));
        drop(out);
        flushed.map_err(|e| self.error(e))
    }

    /// Flushes the data to disk and renames the temporary file over the
    /// final path.
    pub fn commit(mut self) -> Result<(), ImageWriteError> {
        let file = self.file.take().expect("open until commit");
        file.sync_all().map_err(|e| self.error(e))?;
        drop(file);
        std::fs::rename(&self.tmp, &self.path).map_err(|e| self.error(e))
    }
}

impl Drop for StagedFile {
    fn drop(&mut self) {
        if self.file.is_some() {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// Commits several staged files together: if one rename fails, the files
/// already renamed into place are removed again, so that either all appear
/// or (as far as the file system allows) none does.
pub fn commit_all(files: Vec<StagedFile>) -> Result<(), ImageWriteError> {
    let mut done: Vec<PathBuf> = Vec::new();
    for f in files {
        let path = f.path.clone();
        if let Err(e) = f.commit() {
            for p in done {
                let _ = std::fs::remove_file(p);
            }
            return Err(e);
        }
        done.push(path);
    }
    Ok(())
}

/// 8-bit sRGB PNG, encoded row by row (no second copy of the image).
fn write_png(out: impl std::io::Write, image: &Image) -> Result<(), String> {
    let mut encoder = png::Encoder::new(out, image.width, image.height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().map_err(|e| e.to_string())?;
    let mut stream = writer.stream_writer().map_err(|e| e.to_string())?;
    let mut row = Vec::with_capacity(image.width as usize * 3);
    for y in 0..image.height as usize {
        let w = image.width as usize;
        row.clear();
        row.extend(
            image.pixels[y * w..(y + 1) * w]
                .iter()
                .flat_map(|c| c.to_array())
                .map(srgb8),
        );
        std::io::Write::write_all(&mut stream, &row).map_err(|e| e.to_string())?;
    }
    stream.finish().map_err(|e| e.to_string())?;
    writer.finish().map_err(|e| e.to_string())
}

/// 32-bit float linear RGB OpenEXR.
fn write_exr(out: impl std::io::Write + std::io::Seek, image: &Image) -> Result<(), String> {
    use exr::prelude::*;
    let channels = SpecificChannels::rgb(|p: Vec2<usize>| {
        let c = image.get(p.x() as u32, p.y() as u32);
        (c.x, c.y, c.z)
    });
    Image::from_channels((image.width as usize, image.height as usize), channels)
        .write()
        .to_buffered(out)
        .map_err(|e| e.to_string())
}

/// Writes `image` to `path` (PNG or EXR by extension), atomically: the data go
/// to a temporary file beside it, which is renamed over `path` only once it is
/// complete.
pub fn write_image(path: &Path, image: &Image) -> Result<(), ImageWriteError> {
    if ImageFormat::from_path(path).is_none() {
        return Err(ImageWriteError::UnsupportedFormat {
            path: path.to_path_buf(),
        });
    }
    let mut file = StagedFile::create(path)?;
    file.write_image(image)?;
    file.commit()
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
