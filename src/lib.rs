//! glint: a Whitted-style ray tracer.
//!
//! Load a scene ([`scene::load_scene_file`], or the built-in
//! [`scene::BUILTIN_WHITTED`] through [`scene::parse_scene`]), render it
//! ([`render::render`]) into an [`render::Image`] with [`render::RenderStats`],
//! and write it ([`render::write_image`]).
//!
//! To split a render across processes or machines, render crops
//! ([`settings::RenderSettings::crop`]) and sample ranges
//! ([`settings::RenderSettings::sample_offset`]) with
//! [`render::render_film`], and merge the films with
//! [`render::parts::merge`]: the result is the whole render, bit for bit.
//! [`farm`] writes the batch scripts that run such parts on Slurm.
//!
//! ```
//! use glint::{render, scene, settings::RenderSettings};
//! let file = scene::parse_scene(scene::BUILTIN_WHITTED, "whitted.toml".as_ref()).unwrap();
//! let settings = RenderSettings { width: 32, height: 24, spp: 1, ..file.settings };
//! let (image, stats) = render::render(&file.scene, &settings, &|_| {}).unwrap();
//! assert_eq!(image.pixels.len(), 32 * 24);
//! assert_eq!(stats.rays.camera, 32 * 24);
//! ```

pub mod accel;
pub mod farm;
pub mod geometry;
pub mod light;
pub mod math;
pub mod render;
pub mod scene;
pub mod settings;
pub mod shading;
