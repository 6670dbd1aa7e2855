//! `glint view SCENE`: the scene in a window, rendered progressively (one
//! sample per pixel at once, then more added while the camera stays still),
//! with the camera under the mouse and keyboard.
//!
//! Windowing is `winit` with `softbuffer` (pure Rust; on Linux X11 is
//! loaded at run time, so building needs no system libraries). The image
//! shown is the one `glint render` writes for the same camera and samples:
//! samples are added with [`Progressive`], which is exact, and converted to
//! 8-bit sRGB as the PNG writer does.

use super::{MeshView, load_scene, parse_integrator};
use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use glint::math::Vec3;
use glint::render::ImageFormat;
use glint::render::{Image, Progressive};
use glint::scene::{Camera, Scene};
use glint::settings::{IntegratorKind, RenderSettings};
use glint::settings::{MAX_DEPTH, MAX_IMAGE_SIDE, MAX_SPP};
use std::num::NonZeroU32;
use std::path::{Path, PathBuf};
use std::rc::Rc;
use std::time::Instant;
use winit::application::ApplicationHandler;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{Key, NamedKey};
use winit::window::{Window, WindowId};

/// How the viewer starts and (for tests and scripts) when it stops.
pub struct ViewOptions {
    /// Stop after this many passes, when given.
    pub frames: Option<u32>,
    /// Where to save what the window shows when it stops (PNG).
    pub screenshot: Option<PathBuf>,
}

/// The camera as the controls move it: an eye orbiting a target.
#[derive(Clone, Copy, Debug)]
struct Orbit {
    target: Vec3,
    /// Distance from the target to the eye.
    distance: f32,
    /// Angles of the eye around the target, radians: around `up`, and
    /// above the plane perpendicular to it.
    yaw: f32,
    pitch: f32,
    up: Vec3,
    /// Two directions perpendicular to `up`, for the angles.
    base: (Vec3, Vec3),
    fov: f32,
}

impl Orbit {
    /// The orbit that reproduces `camera`, around the point at `distance`
    /// along its view.
    fn from_camera(camera: &Camera, distance: f32) -> Orbit {
        // Around the image's up direction (perpendicular to the view, so
        // the scene's camera is the orbit at pitch 0).
        let up = camera.up();
        let forward = camera.forward();
        let (b1, b2) = glint::math::orthonormal_basis(up);
        let back = -forward;
        let pitch = back.dot(up).clamp(-1.0, 1.0).asin();
        let flat = back - up * back.dot(up);
        let yaw = flat.dot(b2).atan2(flat.dot(b1));
        Orbit {
            target: camera.position + forward * distance,
            distance,
            yaw,
            pitch,
            up,
            base: (b1, b2),
            fov: camera.fov_y_deg(),
        }
    }

    fn back(&self) -> Vec3 {
        let (b1, b2) = self.base;
        (b1 * self.yaw.cos() + b2 * self.yaw.sin()) * self.pitch.cos() + self.up * self.pitch.sin()
    }

    fn camera(&self) -> Option<Camera> {
        let eye = self.target + self.back() * self.distance;
        Camera::try_new(eye, self.target, self.up, self.fov)
    }
}

struct Viewer {
    scene: Scene,
    settings: RenderSettings,
    options: ViewOptions,
    orbit: Orbit,
    /// The orbit of the scene file's camera (`r` returns to it). Until the
    /// camera moves, the scene's own camera is used as it is.
    start: Orbit,
    film: Option<Progressive>,
    window: Option<Rc<Window>>,
    surface: Option<softbuffer::Surface<Rc<Window>, Rc<Window>>>,
    passes: u32,
    cursor: (f64, f64),
    /// The buttons held, the last pressed last (it decides what a drag does).
    buttons: Vec<MouseButton>,
    error: Option<anyhow::Error>,
    /// Frames and rays since the title last changed.
    window_start: Instant,
    window_rays: u64,
    window_frames: u32,
    saved: u32,
}

impl Viewer {
    fn restart(&mut self) {
        self.film = None;
    }

    fn moved(&mut self) {
        if let Some(camera) = self.orbit.camera() {
            self.scene.camera = camera;
        }
        self.restart();
    }

    /// Adds one pass of samples (1 per pixel) and shows the result.
    fn frame(&mut self) -> Result<()> {
        if self.film.is_none() {
            self.film = Some(Progressive::new(&self.settings)?);
        }
        let film = self.film.as_mut().expect("made above");
        let (counters, _) = film.add(&self.scene, 1, &|_| {})?;
        let rays = counters.rays.total();
        self.passes += 1;
        self.window_rays += rays;
        self.window_frames += 1;
        let image = film.image();
        if let (Some(window), Some(surface)) = (&self.window, &mut self.surface) {
            let (w, h) = (image.width, image.height);
            surface
                .resize(
                    NonZeroU32::new(w).context("zero width")?,
                    NonZeroU32::new(h).context("zero height")?,
                )
                .map_err(|e| anyhow!("cannot size the window's buffer: {e}"))?;
            let mut buffer = surface
                .buffer_mut()
                .map_err(|e| anyhow!("cannot draw into the window: {e}"))?;
            for (dst, rgb) in buffer.iter_mut().zip(image.to_srgb8().chunks_exact(3)) {
                *dst = (rgb[0] as u32) << 16 | (rgb[1] as u32) << 8 | rgb[2] as u32;
            }
            buffer
                .present()
                .map_err(|e| anyhow!("cannot show the frame: {e}"))?;
            let seconds = self.window_start.elapsed().as_secs_f64();
            if seconds >= 0.5 {
                window.set_title(&format!(
                    "glint — {:.1} fps, {:.1} M rays/s — {} spp, {}, depth {}",
                    self.window_frames as f64 / seconds,
                    self.window_rays as f64 / seconds / 1e6,
                    film.samples(),
                    self.settings.integrator.name(),
                    self.settings.max_depth
                ));
                self.window_start = Instant::now();
                (self.window_rays, self.window_frames) = (0, 0);
            }
        }
        Ok(())
    }

    /// Writes what the window shows as a PNG (as `glint render` writes it).
    fn save(&self, path: &Path) -> Result<()> {
        let image: &Image = self
            .film
            .as_ref()
            .map(Progressive::image)
            .context("nothing rendered yet")?;
        Ok(glint::render::write_image(path, image)?)
    }

    fn key(&mut self, key: &Key, event_loop: &ActiveEventLoop) {
        let step = 0.05 * self.orbit.distance.max(1e-3);
        let forward = -self.orbit.back();
        let right = forward.cross(self.orbit.up).normalize_or_zero();
        match key {
            Key::Named(NamedKey::Escape) => event_loop.exit(),
            Key::Character(c) => match c.as_str() {
                "w" | "s" => {
                    let sign = if c == "w" { 1.0 } else { -1.0 };
                    self.orbit.target += forward * step * sign;
                    self.moved();
                }
                "a" | "d" => {
                    let sign = if c == "d" { 1.0 } else { -1.0 };
                    self.orbit.target += right * step * sign;
                    self.moved();
                }
                "1" | "2" | "3" => {
                    self.settings.integrator = match c.as_str() {
                        "1" => IntegratorKind::Raycast,
                        "2" => IntegratorKind::Whitted,
                        _ => IntegratorKind::Path,
                    };
                    self.restart();
                }
                "+" | "=" => {
                    self.settings.max_depth = (self.settings.max_depth + 1).min(64);
                    self.restart();
                }
                "-" => {
                    self.settings.max_depth = (self.settings.max_depth - 1).max(0);
                    self.restart();
                }
                "r" => {
                    self.orbit = self.start;
                    self.moved();
                }
                "p" => {
                    self.saved += 1;
                    let path = PathBuf::from(format!("glint-view-{}.png", self.saved));
                    match self.save(&path) {
                        Ok(()) => eprintln!("wrote {}", path.display()),
                        Err(e) => eprintln!("error: {e:#}"),
                    }
                }
                _ => {}
            },
            _ => {}
        }
    }

    fn mouse_moved(&mut self, x: f64, y: f64) {
        let (dx, dy) = ((x - self.cursor.0) as f32, (y - self.cursor.1) as f32);
        self.cursor = (x, y);
        let Some(&button) = self.buttons.last() else {
            return;
        };
        match button {
            // Orbit: a full turn across 2π·200 pixels.
            MouseButton::Left => {
                self.orbit.yaw -= dx * 0.005;
                self.orbit.pitch = (self.orbit.pitch + dy * 0.005).clamp(-1.55, 1.55);
            }
            // Pan: the target moves with the cursor.
            _ => {
                let height = self.settings.height.max(1) as f32;
                let scale =
                    2.0 * self.orbit.distance * (self.orbit.fov.to_radians() * 0.5).tan() / height;
                let forward = -self.orbit.back();
                let right = forward.cross(self.orbit.up).normalize_or_zero();
                let up = right.cross(forward);
                self.orbit.target += (-right * dx + up * dy) * scale;
            }
        }
        self.moved();
    }
}

impl ApplicationHandler for Viewer {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.window.is_some() {
            return;
        }
        let attributes = Window::default_attributes()
            .with_title("glint")
            .with_resizable(false)
            .with_inner_size(winit::dpi::PhysicalSize::new(
                self.settings.width,
                self.settings.height,
            ));
        let made = event_loop
            .create_window(attributes)
            .map_err(|e| anyhow!("cannot open a window: {e}"))
            .and_then(|window| {
                let window = Rc::new(window);
                let context = softbuffer::Context::new(window.clone())
                    .map_err(|e| anyhow!("cannot draw into a window: {e}"))?;
                let surface = softbuffer::Surface::new(&context, window.clone())
                    .map_err(|e| anyhow!("cannot draw into a window: {e}"))?;
                Ok((window, surface))
            });
        match made {
            Ok((window, surface)) => {
                window.request_redraw();
                self.window = Some(window);
                self.surface = Some(surface);
            }
            Err(e) => {
                self.error = Some(e);
                event_loop.exit();
            }
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _: WindowId, event: WindowEvent) {
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.frame() {
                    self.error = Some(e);
                    event_loop.exit();
                    return;
                }
                if self.options.frames.is_some_and(|n| self.passes >= n) {
                    if let Some(path) = &self.options.screenshot
                        && let Err(e) = self.save(path)
                    {
                        self.error = Some(e);
                    }
                    event_loop.exit();
                    return;
                }
                // Refine while still (up to a generous limit), at once after
                // a change.
                if self.film.as_ref().is_none_or(|f| f.samples() < 1 << 16)
                    && let Some(w) = &self.window
                {
                    w.request_redraw();
                }
            }
            WindowEvent::KeyboardInput { event, .. } if event.state == ElementState::Pressed => {
                self.key(&event.logical_key, event_loop);
                if let Some(w) = &self.window {
                    w.request_redraw();
                }
            }
            WindowEvent::CursorMoved { position, .. } => {
                self.mouse_moved(position.x, position.y);
                if let Some(w) = &self.window {
                    w.request_redraw();
                }
            }
            WindowEvent::MouseInput { state, button, .. } => match state {
                ElementState::Pressed => {
                    self.buttons.push(button);
                }
                ElementState::Released => {
                    self.buttons.retain(|&b| b != button);
                }
            },
            WindowEvent::MouseWheel { delta, .. } => {
                let lines = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
                };
                self.orbit.distance = (self.orbit.distance * 0.9f32.powf(lines)).max(1e-4);
                self.moved();
                if let Some(w) = &self.window {
                    w.request_redraw();
                }
            }
            _ => {}
        }
    }
}

/// Opens the window and runs until it is closed (or `options.frames`
/// passes are done).
pub fn run(scene: Scene, settings: RenderSettings, options: ViewOptions) -> Result<()> {
    // Orbit around the point the camera looks at, at the scene's distance.
    let bounds = scene
        .objects
        .iter()
        .map(|o| o.shape.bounds())
        .filter(|b| b.min.is_finite() && b.max.is_finite())
        .fold(glint::math::Aabb::EMPTY, |a, b| a.union(&b));
    let distance = if bounds.min.is_finite() && bounds.max.is_finite() {
        let centre = (bounds.min + bounds.max) * 0.5;
        (centre - scene.camera.position)
            .dot(scene.camera.forward())
            .max(1e-3)
    } else {
        5.0
    };
    let orbit = Orbit::from_camera(&scene.camera, distance);
    let event_loop = EventLoop::new().map_err(|e| {
        anyhow!("cannot open a window (is there a display? on Linux, X11 and $DISPLAY): {e}")
    })?;
    let mut viewer = Viewer {
        scene,
        settings,
        options,
        orbit,
        start: orbit,
        film: None,
        window: None,
        surface: None,
        passes: 0,
        cursor: (0.0, 0.0),
        buttons: Vec::new(),
        error: None,
        window_start: Instant::now(),
        window_rays: 0,
        window_frames: 0,
        saved: 0,
    };
    event_loop
        .run_app(&mut viewer)
        .map_err(|e| anyhow!("the window's event loop failed: {e}"))?;
    match viewer.error {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

/// What `glint view` takes.
#[derive(Args, Debug)]
pub struct ViewArgs {
    /// Scene file, or mesh file (as for `glint render`); the built-in
    /// Whitted scene if omitted.
    scene: Option<PathBuf>,
    /// Window width in pixels (default: the scene's image width).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=MAX_IMAGE_SIDE as i64))]
    width: Option<u32>,
    /// Window height in pixels.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=MAX_IMAGE_SIDE as i64))]
    height: Option<u32>,
    /// raycast, whitted or path (default: the scene's).
    #[arg(long, value_parser = parse_integrator)]
    integrator: Option<IntegratorKind>,
    /// Maximum recursion depth.
    #[arg(long, allow_hyphen_values = true, value_parser = clap::value_parser!(i32).range(-1..=MAX_DEPTH as i64))]
    max_depth: Option<i32>,
    /// Render threads (0: all cores).
    #[arg(long)]
    threads: Option<u32>,
    /// Close the window after this many passes (one sample per pixel each);
    /// for scripts and tests.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=MAX_SPP as i64))]
    frames: Option<u32>,
    /// On closing, save what the window shows to this PNG.
    #[arg(long, value_name = "FILE.png")]
    screenshot: Option<PathBuf>,
    #[command(flatten)]
    mesh: MeshView,
}

pub fn run_view(args: ViewArgs) -> Result<()> {
    if let Some(path) = &args.screenshot
        && ImageFormat::from_path(path) != Some(ImageFormat::Png)
    {
        bail!("cannot write `{}`: a screenshot is a .png", path.display());
    }
    let (file, _, _) = load_scene(args.scene.as_deref(), args.mesh)?;
    for w in &file.warnings {
        eprintln!("warning: {w}");
    }
    let mut settings = file.settings;
    if let Some(w) = args.width {
        settings.width = w;
    }
    if let Some(h) = args.height {
        settings.height = h;
    }
    if let Some(i) = args.integrator {
        settings.integrator = i;
    }
    if let Some(d) = args.max_depth {
        settings.max_depth = d;
    }
    if let Some(t) = args.threads {
        settings.threads = t as usize;
    }
    settings.validate().map_err(|e| anyhow::anyhow!("{e}"))?;
    run(
        file.scene,
        settings,
        ViewOptions {
            frames: args.frames,
            screenshot: args.screenshot,
        },
    )
}
