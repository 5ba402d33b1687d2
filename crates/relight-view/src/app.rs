//! The viewer's state and what changes it: the GPU frame (re-created, re-prepared and
//! re-rendered only for what changed), the environment, the camera, the reference, the
//! scripted actions and the screenshots. The panels and the 3D view's mouse handling are in
//! `ui.rs`.

mod runner;
use runner::Runner;

use crate::env::{self, EnvSource};
use crate::orbit;
use crate::reference::{self, Comparison, Job, Reference};
use crate::script::{Script, SplitMode};
use crate::ViewArgs;
use eframe::egui::{self, ColorImage, TextureHandle, TextureOptions};
use relight_gpu::{frame_of_path, Gpu, GpuFrame, GpuOutput};
use relight_method::{Baked, FrameOptions, FrameSettings, MethodKind};
use relight_render::tonemap::ToneMap;
use relight_render::Image;
use relight_scene::camera::Camera;
use relight_scene::scene::Environment;
use std::cell::RefCell;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::rc::Rc;

use std::time::Instant;

/// The errors shown during a run, shared with [`crate::run`] (the app is dropped by eframe).
#[derive(Clone, Default)]
pub struct Outcome(Rc<RefCell<Vec<String>>>);

impl Outcome {
    /// Every distinct error shown, in order.
    pub fn errors(&self) -> Vec<String> {
        self.0.borrow().clone()
    }

    fn record(&self, e: &str) {
        let mut v = self.0.borrow_mut();
        if !v.iter().any(|x| x == e) {
            println!("relight view: shown in the window: {e}");
            v.push(e.to_string());
        }
    }
}

/// What an error is about: fixing that thing clears it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Slot {
    /// The bundle could not be read.
    Bundle,
    /// The method cannot render this bundle (or its settings are refused).
    Method,
    /// The environment could not be loaded or prepared.
    Env,
    /// The frame could not be rendered.
    Render,
    /// The reference path tracer.
    Reference,
    /// A screenshot could not be written.
    Screenshot,
    /// A scripted action failed.
    Script,
}

/// What must be redone before the next frame is shown.
#[derive(Clone, Copy, Debug, Default)]
pub struct Dirty {
    /// Re-create the GPU frame (method or settings changed).
    pub frame: bool,
    /// Rebuild the environment's map (source changed).
    pub env_map: bool,
    /// Prepare the environment again (map, rotation).
    pub env: bool,
    /// Render again (camera, size, options).
    pub render: bool,
    /// Tone-map again (exposure).
    pub tonemap: bool,
}

impl Dirty {
    fn any(&self) -> bool {
        self.frame || self.env_map || self.env || self.render || self.tonemap
    }
}

/// Timings shown on screen, milliseconds.
#[derive(Clone, Copy, Debug, Default)]
pub struct Timings {
    /// The GPU frame: CPU-side work before the GPU commands (relight-gpu's `cpu_ms`).
    pub frame_cpu_ms: f64,
    /// The GPU frame: submit to image read back (relight-gpu's `total_ms`).
    pub frame_total_ms: f64,
    /// Tone mapping and texture upload of the frame.
    pub upload_ms: f64,
    /// Preparing the environment: CPU part, GPU part.
    pub prepare_ms: (f64, f64),
    /// The whole UI update, frame rendering included.
    pub ui_ms: f64,
}

/// The viewer.
pub struct App<'a> {
    pub(crate) gpu: &'a Gpu,
    pub(crate) baked: Option<&'a Baked>,
    pub(crate) bundle: PathBuf,
    pub(crate) settings: FrameSettings,
    frame: Option<Box<dyn GpuFrame + 'a>>,
    prepared: bool,
    pub(crate) env_source: EnvSource,
    env_map: Option<Environment>,
    pub(crate) env_path_text: String,
    pub(crate) rotate_deg: f32,
    env_scale: f32,
    pub(crate) exposure_ev: f32,
    /// The automatic exposure of the first frame (`relight render`'s rule), which
    /// `exposure_ev` multiplies by `2^EV`.
    auto_exposure: Option<ToneMap>,
    pub(crate) camera: Camera,
    pub(crate) bundle_camera: Camera,
    pub(crate) opts: FrameOptions,
    pub(crate) view_size: (u32, u32),
    output: Option<GpuOutput>,
    pub(crate) texture: Option<TextureHandle>,
    pub(crate) ref_texture: Option<TextureHandle>,
    pub(crate) heat_texture: Option<TextureHandle>,
    pub(crate) timings: Timings,
    reference: Option<Reference>,
    pub(crate) split: SplitMode,
    pub(crate) split_at: f32,
    /// The reference's pixels are this many frame pixels across.
    pub(crate) ref_factor: usize,
    pub(crate) max_depth: i32,
    ref_generation: u64,
    pub(crate) ref_shown: (u64, u32),
    pub(crate) ref_image: Option<Image>,
    pub(crate) ref_pass: (f64, u32),
    pub(crate) comparison: Option<Comparison>,
    pub(crate) dirty: Dirty,
    pub(crate) errors: BTreeMap<Slot, String>,
    outcome: Outcome,
    pub(crate) help: bool,
    runner: Option<Runner>,
    screenshots: u32,
    pub(crate) summary: String,
}

impl<'a> App<'a> {
    /// The viewer over `baked` (or its loading error), starting as `args` says.
    pub fn new(
        cc: &eframe::CreationContext<'_>,
        gpu: &'a Gpu,
        baked: Result<&'a Baked, String>,
        args: &ViewArgs,
        script: Option<Script>,
        outcome: Outcome,
    ) -> App<'a> {
        let (baked, load_error) = match baked {
            Ok(b) => (Some(b), None),
            Err(e) => (None, Some(e)),
        };
        let camera = baked
            .map(|b| b.scene().desc.camera)
            .unwrap_or_else(|| Camera::look_at([0.0, 1.0, 4.0], [0.0; 3], 40.0, 64, 64));
        let method = baked.map_or(MethodKind::Sh, |b| b.kind().methods()[0]);
        let (rotate_deg, env_scale) = baked
            .map(|b| env::bundle_rotation_and_scale(&b.scene().desc))
            .unwrap_or((0.0, 1.0));
        let env_source = match &args.env {
            Some(p) => EnvSource::File(p.clone()),
            None => EnvSource::Bundle,
        };
        let runner = script.map(Runner::new);
        let reference = baked.map(|b| {
            let s = b.scene();
            let ctx = cc.egui_ctx.clone();
            Reference::start(
                s.mesh.clone(),
                s.materials.clone(),
                Environment::new(relight_sphere::EnvMap::constant(glam::Vec3::ZERO)),
                camera,
                move || ctx.request_repaint(),
            )
        });
        let mut app = App {
            gpu,
            baked,
            bundle: args.bundle.clone(),
            settings: FrameSettings::default_for(method),
            frame: None,
            prepared: false,
            env_path_text: args
                .env
                .as_ref()
                .map(|p| p.display().to_string())
                .unwrap_or_default(),
            env_source,
            env_map: None,
            rotate_deg: if args.env.is_some() { 0.0 } else { rotate_deg },
            env_scale: if args.env.is_some() { 1.0 } else { env_scale },
            exposure_ev: 0.0,
            auto_exposure: None,
            camera,
            bundle_camera: camera,
            opts: FrameOptions::default(),
            view_size: (camera.width, camera.height),
            output: None,
            texture: None,
            ref_texture: None,
            heat_texture: None,
            timings: Timings::default(),
            reference,
            split: SplitMode::Off,
            split_at: 0.5,
            ref_factor: 2,
            max_depth: -1,
            ref_generation: 0,
            ref_shown: (0, 0),
            ref_image: None,
            ref_pass: (0.0, 0),
            comparison: None,
            dirty: Dirty {
                frame: true,
                env_map: true,
                env: true,
                render: true,
                tonemap: true,
            },
            errors: BTreeMap::new(),
            outcome,
            help: false,
            runner,
            screenshots: 0,
            summary: String::new(),
        };
        if let Some(e) = load_error {
            app.set_error(Slot::Bundle, e);
        }
        app
    }

    /// Show `msg` in the window (and record it).
    pub(crate) fn set_error(&mut self, slot: Slot, msg: String) {
        self.outcome.record(&msg);
        self.errors.insert(slot, msg);
    }

    fn clear_error(&mut self, slot: Slot) {
        self.errors.remove(&slot);
    }

    /// The methods of the loaded bake.
    pub(crate) fn methods(&self) -> Vec<MethodKind> {
        self.baked.map(|b| b.kind().methods()).unwrap_or_default()
    }

    /// The bake's SH order (`sh` bakes).
    pub(crate) fn bake_sh_order(&self) -> Option<usize> {
        match self.baked {
            Some(Baked::Sh(b)) => Some(b.settings.order),
            _ => None,
        }
    }

    /// Switch to `method` with its default settings.
    pub(crate) fn set_method(&mut self, method: MethodKind) {
        if self.settings.method() != method {
            self.settings = FrameSettings::default_for(method);
            self.dirty.frame = true;
        }
    }

    /// The next method of the bake, cyclically.
    pub(crate) fn next_method(&mut self) {
        let ms = self.methods();
        if let Some(i) = ms.iter().position(|&m| m == self.settings.method()) {
            self.set_method(ms[(i + 1) % ms.len()]);
        }
    }

    /// Use `source` for the environment (its map is built before the next frame).
    pub(crate) fn set_env_source(&mut self, source: EnvSource) {
        if let EnvSource::File(p) = &source {
            self.env_path_text = p.display().to_string();
        }
        self.env_source = source;
        self.dirty.env_map = true;
    }

    /// Move the camera (orbit, pan, zoom or a new one).
    pub(crate) fn set_camera(&mut self, c: Camera) {
        if c.validate().is_ok() && c != self.camera {
            self.camera = c;
            self.dirty.render = true;
        }
    }

    /// The view reset: the whole scene framed from the bundle camera's direction.
    pub(crate) fn reset_camera(&mut self) {
        if let Some(b) = self.baked {
            let c = orbit::frame_all(&self.bundle_camera, &b.scene().mesh.positions);
            self.set_camera(c);
        }
    }

    /// Rotate the environment by `deg` (wrapped to `(-180, 180]`).
    pub(crate) fn rotate_env(&mut self, deg: f32) {
        let r = (self.rotate_deg + deg + 180.0).rem_euclid(360.0) - 180.0;
        self.rotate_deg = if r == -180.0 { 180.0 } else { r };
        self.dirty.env = true;
    }

    /// The display tone map: `relight render`'s automatic exposure of the first frame
    /// ([`ToneMap::auto`]) with gain `2^EV`.
    pub(crate) fn tonemap(&self) -> ToneMap {
        self.auto_exposure
            .unwrap_or_default()
            .with_gain(self.exposure_ev.exp2())
    }

    /// The environment as prepared (map, rotation, scale).
    fn environment(&self) -> Option<Environment> {
        self.env_map.as_ref().map(|e| Environment {
            rotate_y_deg: self.rotate_deg,
            scale: self.env_scale,
            ..e.clone()
        })
    }

    /// The frame's camera at the view's size.
    fn view_camera(&self) -> Camera {
        Camera {
            width: self.view_size.0,
            height: self.view_size.1,
            ..self.camera
        }
    }

    /// Redo what changed: re-create the frame, rebuild or re-prepare the environment,
    /// render, tone-map and upload; start the reference on the new view.
    pub(crate) fn refresh(&mut self, ctx: &egui::Context) {
        let Some(baked) = self.baked else {
            self.dirty = Dirty::default();
            return;
        };
        if self.dirty.env_map {
            self.dirty.env_map = false;
            match self
                .env_source
                .build(Some(&baked.scene().desc), &self.bundle)
            {
                Ok(e) => {
                    if self.env_source == EnvSource::Bundle {
                        (self.rotate_deg, self.env_scale) =
                            env::bundle_rotation_and_scale(&baked.scene().desc);
                    } else {
                        self.env_scale = 1.0;
                    }
                    self.env_map = Some(e);
                    self.clear_error(Slot::Env);
                    self.dirty.env = true;
                }
                Err(e) => self.set_error(Slot::Env, e),
            }
        }
        if self.dirty.frame {
            self.dirty.frame = false;
            self.frame = None;
            self.prepared = false;
            let method = self.settings.method();
            match frame_of_path(self.gpu, baked, &self.settings, &self.bundle) {
                Ok(f) => {
                    self.summary = f.summary();
                    self.frame = Some(f);
                    self.clear_error(Slot::Method);
                    self.dirty.env = true;
                }
                Err(e) => {
                    let msg = format!(
                        "{}: the viewer cannot show this {} bundle with --method {}: {e}",
                        self.bundle.display(),
                        baked.kind().name(),
                        method.name()
                    );
                    self.set_error(Slot::Method, msg);
                    self.output = None;
                }
            }
        }
        if self.dirty.env {
            self.dirty.env = false;
            let env = self.environment();
            if let (Some(f), Some(env)) = (self.frame.as_mut(), env) {
                let r = f.set_environment(&env).map(|p| (p, f.summary()));
                match r {
                    Ok((p, summary)) => {
                        self.timings.prepare_ms = (p.environment_ms, p.gpu_ms);
                        self.summary = summary;
                        self.prepared = true;
                        self.clear_error(Slot::Env);
                        self.dirty.render = true;
                    }
                    Err(e) => {
                        self.prepared = false;
                        let msg = format!("environment {}: {e}", self.env_source.label());
                        self.set_error(Slot::Env, msg);
                    }
                }
            }
        }
        if self.dirty.render {
            self.dirty.render = false;
            self.render_frame();
            self.submit_reference();
        }
        if self.dirty.tonemap {
            self.dirty.tonemap = false;
            self.upload(ctx);
            self.ref_shown = (0, 0); // re-tone-map the reference too
        }
        self.poll_reference(ctx);
    }

    fn render_frame(&mut self) {
        let camera = self.view_camera();
        let (Some(f), true) = (self.frame.as_mut(), self.prepared) else {
            return;
        };
        let r = f.render(&camera, &self.opts);
        match r {
            Ok(out) => {
                if self.auto_exposure.is_none() {
                    self.auto_exposure = Some(ToneMap::auto(&out.image));
                }
                self.timings.frame_cpu_ms = out.stats.cpu_ms;
                self.timings.frame_total_ms = out.stats.total_ms;
                self.output = Some(out);
                self.clear_error(Slot::Render);
                self.dirty.tonemap = true;
            }
            Err(e) => self.set_error(Slot::Render, format!("rendering the frame: {e}")),
        }
    }

    fn upload(&mut self, ctx: &egui::Context) {
        let t0 = Instant::now();
        let Some(out) = &self.output else {
            return;
        };
        let img = color_image(&out.image, &self.tonemap().to_srgb8(&out.image));
        set_texture(ctx, &mut self.texture, "frame", img);
        self.timings.upload_ms = t0.elapsed().as_secs_f64() * 1e3;
    }

    /// The reference's camera: the view's at `1 / ref_factor` of its size.
    fn reference_camera(&self) -> Camera {
        let f = self.ref_factor as u32;
        Camera {
            width: (self.view_size.0 / f).max(1),
            height: (self.view_size.1 / f).max(1),
            ..self.camera
        }
    }

    /// Restart the reference on the current view (when the split shows it).
    pub(crate) fn submit_reference(&mut self) {
        if self.split == SplitMode::Off {
            return;
        }
        let (Some(r), Some(env)) = (&self.reference, self.environment()) else {
            return;
        };
        self.ref_generation = r.submit(Job {
            camera: self.reference_camera(),
            env,
            max_depth: self.max_depth,
            background: self.opts.background,
        });
        self.ref_image = None;
        self.comparison = None;
        self.ref_shown = (0, 0);
    }

    /// Take the reference's latest pass: its texture, the heat map and the error.
    fn poll_reference(&mut self, ctx: &egui::Context) {
        if self.split == SplitMode::Off {
            return;
        }
        let Some(r) = &self.reference else {
            return;
        };
        let s = r.snapshot();
        if let Some(e) = s.error {
            self.set_error(Slot::Reference, e);
            return;
        }
        if s.generation != self.ref_generation || (s.generation, s.spp) == self.ref_shown {
            return;
        }
        let Some(img) = s.image else {
            return;
        };
        self.ref_shown = (s.generation, s.spp);
        self.ref_pass = s.last_pass;
        let tm = self.tonemap();
        set_texture(
            ctx,
            &mut self.ref_texture,
            "reference",
            color_image(&img, &tm.to_srgb8(&img)),
        );
        self.comparison = self.output.as_ref().and_then(|o| {
            reference::compare(
                &o.image,
                &o.coverage,
                self.ref_factor,
                &img,
                self.opts.background,
            )
        });
        if let Some(c) = &self.comparison {
            set_texture(
                ctx,
                &mut self.heat_texture,
                "heatmap",
                color_image(&img, &c.heatmap),
            );
        }
        self.ref_image = Some(img);
    }

    /// The reference's samples per pixel for the current view (0 before its first pass).
    pub(crate) fn reference_spp(&self) -> u32 {
        if self.ref_shown.0 == self.ref_generation {
            self.ref_shown.1
        } else {
            0
        }
    }

    /// Set the split mode (starting the reference when it is turned on).
    pub(crate) fn set_split(&mut self, mode: SplitMode) {
        let was_off = self.split == SplitMode::Off;
        self.split = mode;
        if was_off && mode != SplitMode::Off {
            self.submit_reference();
        }
    }

    /// The 3D view as shown: the frame, and right of the split the reference or the heat map
    /// (nearest-neighbour upsampled); 8-bit sRGB for PNG and linear radiance for EXR (the
    /// heat map side holds the reference's radiance there).
    fn composite(&self) -> Option<(Image, Vec<[u8; 3]>)> {
        let out = self.output.as_ref()?;
        let tm = self.tonemap();
        let mut lin = out.image.clone();
        let mut srgb = tm.to_srgb8(&out.image);
        if let (Some(r), true) = (&self.ref_image, self.split != SplitMode::Off) {
            let f = self.ref_factor;
            let x0 = (self.split_at * lin.width as f32).round() as usize;
            for y in 0..lin.height {
                for x in x0..lin.width {
                    let (rx, ry) = ((x / f).min(r.width - 1), (y / f).min(r.height - 1));
                    let v = r.get(rx, ry);
                    lin.set(x, y, v);
                    srgb[y * lin.width + x] = match (&self.comparison, self.split) {
                        (Some(c), SplitMode::Heatmap) => c.heatmap[ry * r.width + rx],
                        _ => tm.pixel_srgb8(v),
                    };
                }
            }
        }
        Some((lin, srgb))
    }

    /// Write the 3D view to `path` (`.png` as displayed, `.exr` linear), via a temporary file
    /// renamed into place.
    pub(crate) fn screenshot(&mut self, path: &Path) -> Result<(), String> {
        let (lin, srgb) = self
            .composite()
            .ok_or_else(|| format!("screenshot {}: no frame is shown", path.display()))?;
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("")
            .to_ascii_lowercase();
        let r = match ext.as_str() {
            "exr" => relight_scene::io::image::write_exr(path, lin.width, lin.height, &lin.pixels),
            _ => relight_scene::io::image::write_png_srgb8(path, lin.width, lin.height, &srgb),
        };
        r.map_err(|e| format!("screenshot: {e}"))
    }

    /// The `P` shortcut: `relight-view-N.png` and `.exr` in the current folder.
    pub(crate) fn screenshot_numbered(&mut self) {
        loop {
            self.screenshots += 1;
            let base = format!("relight-view-{}", self.screenshots);
            let (png, exr) = (
                PathBuf::from(format!("{base}.png")),
                PathBuf::from(format!("{base}.exr")),
            );
            if png.exists() || exr.exists() {
                continue;
            }
            match self.screenshot(&png).and_then(|_| self.screenshot(&exr)) {
                Ok(()) => self.clear_error(Slot::Screenshot),
                Err(e) => self.set_error(Slot::Screenshot, e),
            }
            return;
        }
    }

    /// One line of state for `print-state`.
    pub(crate) fn state_line(&self) -> String {
        let c = &self.camera;
        let rmse = self
            .comparison
            .as_ref()
            .map_or("none".to_string(), |c| format!("{:.4}", c.metrics.rel_rmse));
        let errors: Vec<&str> = self.errors.values().map(String::as_str).collect();
        format!(
            "state: method={} env=\"{}\" rotate_env={:.1} exposure={:.2} background={} camera={:?}/{:?} view={}x{} split={} reference_spp={} rel_rmse={} frame_ms={:.1} errors={:?}",
            self.settings.method().name(),
            self.env_source.label(),
            self.rotate_deg,
            self.exposure_ev,
            self.opts.background,
            c.origin,
            c.target,
            self.view_size.0,
            self.view_size.1,
            self.split.name(),
            self.reference_spp(),
            rmse,
            self.timings.frame_total_ms,
            errors
        )
    }
}

/// An egui image of `img`'s size from 8-bit sRGB pixels.
fn color_image(img: &Image, px: &[[u8; 3]]) -> ColorImage {
    let flat: Vec<u8> = px.iter().flatten().copied().collect();
    ColorImage::from_rgb([img.width, img.height], &flat)
}

fn set_texture(ctx: &egui::Context, slot: &mut Option<TextureHandle>, name: &str, img: ColorImage) {
    match slot {
        Some(t) => t.set(img, TextureOptions::LINEAR),
        None => *slot = Some(ctx.load_texture(name, img, TextureOptions::LINEAR)),
    }
}
