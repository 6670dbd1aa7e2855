//! The rendered image and writing it: sRGB 8-bit PNG or linear EXR, chosen by
//! the file extension, written to a temporary file and renamed into place so
//! that a failed or interrupted write never leaves a partial image.

use super::parts::{Film, FilmHeader, SampleSum, check_header};
use super::srgb::srgb8_pixels;
use crate::math::Color;
use crate::settings::{Rect, SampleRange};
use rayon::prelude::*;
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
        let mut pixels: Vec<Color> = Vec::new();
        pixels.try_reserve_exact(n).ok()?;
        // Zeroed on all threads: a 1280×720 film is 15 MB, whose clearing
        // by the calling thread alone, while the others wait, took 3% of a
        // Whitted frame.
        pixels.spare_capacity_mut()[..n]
            .par_chunks_mut(1 << 15)
            .for_each(|chunk| chunk.fill(std::mem::MaybeUninit::new(Color::ZERO)));
        // SAFETY: the capacity holds `n` elements, all written just above.
        unsafe { pixels.set_len(n) };
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
        let mut out = Vec::with_capacity(self.pixels.len() * 3);
        srgb8_pixels(&self.pixels, &mut out);
        out
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

    /// Writes `image` in the format of the final path's extension (an EXR
    /// as a whole frame without sums).
    pub fn write_image(&mut self, image: &Image) -> Result<(), ImageWriteError> {
        self.write_film(&Film {
            header: FilmHeader {
                width: image.width,
                height: image.height,
                rect: Rect::full(image.width, image.height),
                samples: SampleRange { start: 0, count: 1 },
                fingerprint: String::new(),
            },
            image: image.clone(),
            sums: Vec::new(),
            aovs: Vec::new(),
            aov_pixels: Vec::new(),
        })
    }

    /// Writes `film` in the format of the final path's extension: a PNG of
    /// its pixels, or an EXR with its frame as display window, its crop as
    /// data window, and its sample range, fingerprint and sums (see
    /// `write_film_exr`).
    pub fn write_film(&mut self, film: &Film) -> Result<(), ImageWriteError> {
        let image = &film.image;
        let format = ImageFormat::from_path(&self.path).ok_or_else(|| {
            ImageWriteError::UnsupportedFormat {
                path: self.path.clone(),
            }
        })?;
        let file = self.file.as_mut().expect("open until commit");
        let mut out = std::io::BufWriter::new(file);
        let written = match format {
            ImageFormat::Png => write_png(&mut out, image),
            ImageFormat::Exr => write_film_exr(&mut out, film),
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

/// An 8-bit RGB picture (row-major, three bytes per pixel) as PNG bytes.
pub fn png_bytes(width: u32, height: u32, rgb: &[u8]) -> Result<Vec<u8>, String> {
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().map_err(|e| e.to_string())?;
    writer.write_image_data(rgb).map_err(|e| e.to_string())?;
    writer.finish().map_err(|e| e.to_string())?;
    Ok(out)
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
        srgb8_pixels(&image.pixels[y * w..(y + 1) * w], &mut row);
        std::io::Write::write_all(&mut stream, &row).map_err(|e| e.to_string())?;
    }
    stream.finish().map_err(|e| e.to_string())?;
    writer.finish().map_err(|e| e.to_string())
}

/// The EXR header attribute (a text vector of `key=value` entries) that
/// says which part of which render a file holds. One attribute, because the
/// `exr` crate writes several in a random order, and the same render must
/// give the same file.
const ATTR_PART: &str = "glint.part";
const KEY_FINGERPRINT: &str = "fingerprint";
const KEY_SAMPLE_START: &str = "sampleStart";
const KEY_SAMPLE_COUNT: &str = "sampleCount";

/// The name of the 32-bit word `word` (0 the lowest) of channel `c`'s sums.
fn sum_channel(c: &str, word: usize) -> String {
    format!("glint.sum.{c}.{word}")
}

/// 32-bit float linear RGB OpenEXR of a film (the OpenEXR convention for a
/// crop: the display window is the frame, the data window the crop), with
/// its sample range and fingerprint as text attributes and, if it has them,
/// its exact sums as twelve 32-bit unsigned channels (`glint.sum.R.0` …
/// `glint.sum.B.3`, four words of each 128-bit sum, lowest first).
fn write_film_exr(out: impl std::io::Write + std::io::Seek, film: &Film) -> Result<(), String> {
    use exr::prelude::*;
    let h = &film.header;
    let pixels = &film.image.pixels;
    let mut channels: Vec<AnyChannel<FlatSamples>> = ["R", "G", "B"]
        .iter()
        .enumerate()
        .map(|(k, name)| {
            AnyChannel::new(
                *name,
                FlatSamples::F32(pixels.iter().map(|c| c.to_array()[k]).collect()),
            )
        })
        .collect();
    if !film.sums.is_empty() {
        for (k, name) in ["R", "G", "B"].iter().enumerate() {
            for word in 0..4 {
                let words = film.sums.iter().map(|s| (s.0[k] >> (32 * word)) as u32);
                let mut channel = AnyChannel::new(
                    sum_channel(name, word).as_str(),
                    FlatSamples::U32(words.collect()),
                );
                channel.quantize_linearly = true;
                channels.push(channel);
            }
        }
    }
    for &aov in &film.aovs {
        for (k, name) in aov.channels().iter().enumerate() {
            let values = film.aov_pixels.iter().map(|p| p.value(aov, k));
            let samples = match film.aov_pixels.first().map(|p| p.value(aov, k)) {
                Some(super::aov::AovValue::U32(_)) => FlatSamples::U32(
                    values
                        .map(|v| match v {
                            super::aov::AovValue::U32(x) => x,
                            super::aov::AovValue::F32(x) => x as u32,
                        })
                        .collect(),
                ),
                _ => FlatSamples::F32(values.map(|v| v.as_f64() as f32).collect()),
            };
            channels.push(AnyChannel::new(*name, samples));
        }
    }
    let mut attributes = LayerAttributes {
        layer_position: Vec2(h.rect.x0 as i32, h.rect.y0 as i32),
        ..Default::default()
    };
    let entries = [
        format!("{KEY_FINGERPRINT}={}", h.fingerprint),
        format!("{KEY_SAMPLE_START}={}", h.samples.start),
        format!("{KEY_SAMPLE_COUNT}={}", h.samples.count),
    ];
    attributes.other.insert(
        Text::from(ATTR_PART),
        AttributeValue::TextVector(entries.iter().map(|e| Text::from(e.as_str())).collect()),
    );
    let layer = Layer::new(
        (h.rect.width() as usize, h.rect.height() as usize),
        attributes,
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(channels.into()),
    );
    let display = IntegerBounds::new((0, 0), (h.width as usize, h.height as usize));
    Image::new(ImageAttributes::new(display), layer)
        .write()
        .to_buffered(out)
        .map_err(|e| e.to_string())
}

/// Why an EXR part could not be read.
#[derive(Debug, thiserror::Error)]
pub enum FilmReadError {
    #[error("cannot read `{}`: {reason}", path.display())]
    Io { path: PathBuf, reason: String },
    #[error("`{}` is not a glint part: {reason}", path.display())]
    NotAPart { path: PathBuf, reason: String },
}

/// Reads the header of an EXR written by glint (see `write_film_exr`),
/// without its pixels.
pub fn read_film_header(path: &Path) -> Result<FilmHeader, FilmReadError> {
    let bytes = read_part_file(path)?;
    header_from_bytes(path, &bytes)
}

/// The whole file, if it is a regular file (a FIFO or device is refused
/// before it is opened).
fn read_part_file(path: &Path) -> Result<Vec<u8>, FilmReadError> {
    crate::scene::files::read_regular_file(path).map_err(|e| FilmReadError::Io {
        path: path.to_path_buf(),
        reason: e.reason(),
    })
}

fn header_from_bytes(path: &Path, bytes: &[u8]) -> Result<FilmHeader, FilmReadError> {
    let meta =
        exr::meta::MetaData::read_from_buffered(bytes, false).map_err(|e| FilmReadError::Io {
            path: path.to_path_buf(),
            reason: exr_reason(e),
        })?;
    let not_a_part = |reason: String| FilmReadError::NotAPart {
        path: path.to_path_buf(),
        reason,
    };
    let [header] = &meta.headers[..] else {
        return Err(not_a_part(format!(
            "it has {} layers, not one",
            meta.headers.len()
        )));
    };
    header_of(
        &header.shared_attributes.display_window,
        header.own_attributes.layer_position,
        header.layer_size,
        &header.own_attributes.other,
    )
    .map_err(not_a_part)
}

/// The film header that a layer's attributes describe.
fn header_of(
    display: &exr::meta::attribute::IntegerBounds,
    position: exr::math::Vec2<i32>,
    size: exr::math::Vec2<usize>,
    other: &std::collections::HashMap<
        exr::meta::attribute::Text,
        exr::meta::attribute::AttributeValue,
    >,
) -> Result<FilmHeader, String> {
    use exr::meta::attribute::AttributeValue;
    let Some(AttributeValue::TextVector(entries)) =
        other.get(&exr::meta::attribute::Text::from(ATTR_PART))
    else {
        return Err(format!("it has no `{ATTR_PART}` attribute"));
    };
    let entries: Vec<String> = entries.iter().map(|t| t.to_string()).collect();
    let text = |key: &str| -> Result<String, String> {
        entries
            .iter()
            .find_map(|e| e.strip_prefix(key)?.strip_prefix('=').map(str::to_string))
            .ok_or_else(|| format!("its `{ATTR_PART}` attribute has no `{key}`"))
    };
    let number = |key: &str| -> Result<u32, String> {
        let t = text(key)?;
        t.parse()
            .map_err(|_| format!("its `{key}`, `{t}`, is not a whole number from 0 to 2^32 − 1"))
    };
    if display.position.x() != 0 || display.position.y() != 0 {
        return Err("its display window does not start at (0, 0)".into());
    }
    let side = |v: usize| u32::try_from(v).unwrap_or(u32::MAX);
    let corner = |v: i32| {
        u32::try_from(v)
            .map_err(|_| "its data window starts left of or above its display window".to_string())
    };
    let (x0, y0) = (corner(position.x())?, corner(position.y())?);
    let header = FilmHeader {
        width: side(display.size.x()),
        height: side(display.size.y()),
        rect: Rect {
            x0,
            x1: x0.saturating_add(side(size.x())),
            y0,
            y1: y0.saturating_add(side(size.y())),
        },
        samples: SampleRange {
            start: number(KEY_SAMPLE_START)?,
            count: number(KEY_SAMPLE_COUNT)?,
        },
        fingerprint: text(KEY_FINGERPRINT)?,
    };
    check_header(&header)?;
    Ok(header)
}

/// The message of an EXR error, without its kind's prefix.
fn exr_reason(e: exr::error::Error) -> String {
    match e {
        exr::error::Error::Io(io) => io.to_string(),
        other => format!("it is not an OpenEXR file glint can read ({other})"),
    }
}

/// Reads a film written by glint to EXR, with its sums (it is refused if it
/// has none). The header is read and checked first, so a hostile file
/// cannot make the pixels' allocation huge.
pub fn read_film_exr(path: &Path) -> Result<Film, FilmReadError> {
    use exr::prelude::*;
    let bytes = read_part_file(path)?;
    let header = header_from_bytes(path, &bytes)?;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_buffered(std::io::Cursor::new(&bytes))
        .map_err(|e| FilmReadError::Io {
            path: path.to_path_buf(),
            reason: exr_reason(e),
        })?;
    let not_a_part = |reason: String| FilmReadError::NotAPart {
        path: path.to_path_buf(),
        reason,
    };
    let n = header.rect.area() as usize;
    let channels = &image.layer_data.channel_data.list;
    let find = |name: &str| channels.iter().find(|c| c.name == *name);
    let mut rgb: [&[f32]; 3] = [&[]; 3];
    for (k, name) in ["R", "G", "B"].iter().enumerate() {
        match find(name).map(|c| &c.sample_data) {
            Some(FlatSamples::F32(v)) if v.len() == n => rgb[k] = v,
            _ => {
                return Err(not_a_part(format!(
                    "it has no 32-bit float channel `{name}`"
                )));
            }
        }
    }
    let mut sums = vec![SampleSum::default(); n];
    for (k, name) in ["R", "G", "B"].iter().enumerate() {
        for word in 0..4 {
            let channel = sum_channel(name, word);
            match find(&channel).map(|c| &c.sample_data) {
                Some(FlatSamples::U32(v)) if v.len() == n => {
                    for (s, &w) in sums.iter_mut().zip(v) {
                        s.0[k] |= (w as u128) << (32 * word);
                    }
                }
                _ => {
                    return Err(not_a_part(format!(
                        "it has no 32-bit unsigned channel `{channel}` (render parts to .exr with glint render to merge them)"
                    )));
                }
            }
        }
    }
    if sums.iter().any(|s| s.0.iter().any(|&c| c >= 1 << 127)) {
        return Err(not_a_part("its sums are out of range".into()));
    }
    // Output variables whose channels are all there, of the right kind.
    use super::aov::{Aov, AovPixel, AovValue};
    let mut aovs = Vec::new();
    let mut aov_pixels: Vec<AovPixel> = Vec::new();
    for aov in Aov::ALL {
        let data: Option<Vec<&FlatSamples>> = aov
            .channels()
            .iter()
            .map(|name| find(name).map(|c| &c.sample_data))
            .collect();
        let Some(data) = data else { continue };
        let fits = data.iter().all(|d| match d {
            FlatSamples::F32(v) => v.len() == n && !aov.is_count() && aov != Aov::Id,
            FlatSamples::U32(v) => v.len() == n && (aov.is_count() || aov == Aov::Id),
            FlatSamples::F16(_) => false,
        });
        if !fits {
            continue;
        }
        if aov_pixels.is_empty() {
            aov_pixels = vec![AovPixel::default(); n];
        }
        for (k, d) in data.iter().enumerate() {
            for (i, p) in aov_pixels.iter_mut().enumerate() {
                let v = match d {
                    // Nothing that is not finite passes through.
                    FlatSamples::F32(v) => AovValue::F32(if v[i].is_finite() { v[i] } else { 0.0 }),
                    FlatSamples::U32(v) => AovValue::U32(v[i]),
                    FlatSamples::F16(_) => continue,
                };
                p.set(aov, k, v);
            }
        }
        aovs.push(aov);
    }
    let pixels = (0..n)
        .map(|i| Color::new(rgb[0][i], rgb[1][i], rgb[2][i]))
        .collect();
    Ok(Film {
        image: self::Image {
            width: header.rect.width(),
            height: header.rect.height(),
            pixels,
        },
        header,
        sums,
        aovs,
        aov_pixels,
    })
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
