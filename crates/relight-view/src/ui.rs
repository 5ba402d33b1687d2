//! The viewer's window: the status bar, the control panel, the 3D view with its mouse
//! handling, the help panel, drag-and-drop and the keyboard shortcuts.

use crate::app::{App, Slot};
use crate::env::EnvSource;
use crate::orbit;
use crate::script::SplitMode;
use eframe::egui::{self, Color32, Key, Pos2, Rect, RichText, Sense, Stroke, Vec2};
use relight_method::hybrid::HybridSettings;
use relight_method::sg::SgFrameSettings;
use relight_method::sh::ShFrameSettings;
use relight_method::FrameSettings;
use relight_sphere::sh::Window;
use std::time::Instant;

/// Degrees of orbit per point of mouse drag.
const ORBIT_DEG_PER_POINT: f32 = 0.4;
/// Degrees of environment rotation per point of ctrl-drag.
const ROTATE_DEG_PER_POINT: f32 = 0.5;
/// Zoom factor per point of scroll: `exp(-scroll * this)`.
const ZOOM_PER_POINT: f32 = 0.002;

impl eframe::App for App<'_> {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        let t0 = Instant::now();
        let ctx = ui.ctx().clone();
        self.take_dropped_files(&ctx);
        self.shortcuts(&ctx);
        self.step_script(&ctx);
        egui::Panel::top("status").show(ui, |ui| self.status_bar(ui));
        egui::Panel::left("controls")
            .default_size(290.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| self.controls(ui));
            });
        egui::CentralPanel::default().show(ui, |ui| self.view(ui));
        let mut open = self.help;
        egui::Window::new("Help: shortcuts")
            .open(&mut open)
            .show(&ctx, |ui| {
                for line in crate::SHORTCUTS.lines() {
                    let (k, v) = line.split_once(": ").unwrap_or((line, ""));
                    ui.horizontal(|ui| {
                        ui.label(RichText::new(k).strong());
                        ui.label(v);
                    });
                }
            });
        self.help = open;
        self.timings.ui_ms = t0.elapsed().as_secs_f64() * 1e3;
    }
}

impl App<'_> {
    /// An `.hdr` / `.exr` dropped on the window becomes the environment.
    fn take_dropped_files(&mut self, ctx: &egui::Context) {
        let dropped = ctx.input(|i| i.raw.dropped_files.clone());
        if let Some(f) = dropped.last() {
            self.set_env_source(EnvSource::File(f.path().to_path_buf()));
        }
    }

    fn shortcuts(&mut self, ctx: &egui::Context) {
        if ctx.egui_wants_keyboard_input() {
            return;
        }
        let pressed = |k: Key| ctx.input(|i| i.key_pressed(k));
        if pressed(Key::R) {
            self.reset_camera();
        }
        if pressed(Key::C) {
            self.set_camera(self.bundle_camera);
        }
        if pressed(Key::M) {
            self.next_method();
        }
        if pressed(Key::S) {
            self.set_split(match self.split {
                SplitMode::Off => SplitMode::Reference,
                SplitMode::Reference => SplitMode::Heatmap,
                SplitMode::Heatmap => SplitMode::Off,
            });
        }
        if pressed(Key::G) {
            self.opts.background = !self.opts.background;
            self.dirty.render = true;
        }
        if pressed(Key::OpenBracket) {
            self.rotate_env(-15.0);
        }
        if pressed(Key::CloseBracket) {
            self.rotate_env(15.0);
        }
        if pressed(Key::Minus) {
            self.exposure_ev -= 0.5;
            self.dirty.tonemap = true;
        }
        if pressed(Key::Equals) || pressed(Key::Plus) {
            self.exposure_ev += 0.5;
            self.dirty.tonemap = true;
        }
        if pressed(Key::P) {
            self.screenshot_numbered();
        }
        if pressed(Key::H) || pressed(Key::F1) {
            self.help = !self.help;
        }
        if pressed(Key::Q) || pressed(Key::Escape) {
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
        }
    }

    /// Two lines of fixed height (each truncated to the window's width), so that the 3D
    /// view below keeps its size, and so its frame, whatever the text.
    fn status_bar(&mut self, ui: &mut egui::Ui) {
        let t = &self.timings;
        let line = format!(
            "{} | {}x{} | frame {:.1} ms (CPU {:.2} ms, GPU + read-back {:.1} ms) | tone map + upload {:.1} ms | UI {:.1} ms | {}",
            self.settings.method().name(),
            self.view_size.0,
            self.view_size.1,
            t.frame_total_ms + t.upload_ms,
            t.frame_cpu_ms,
            t.frame_total_ms - t.frame_cpu_ms,
            t.upload_ms,
            t.ui_ms,
            self.gpu.adapter_name()
        );
        ui.add(egui::Label::new(line).truncate());
        let reference = if self.split == SplitMode::Off {
            "reference: off (S: split against the path tracer)".to_string()
        } else {
            let rmse = self
                .comparison
                .as_ref()
                .map_or("-".into(), |c| format!("{:.4}", c.metrics.rel_rmse));
            format!(
                "reference {} spp ({:.0} ms for the last {} spp) | relative RMSE {rmse}",
                self.reference_spp(),
                self.ref_pass.0,
                self.ref_pass.1
            )
        };
        ui.horizontal(|ui| {
            if ui.button("Help (H)").clicked() {
                self.help = !self.help;
            }
            ui.add(egui::Label::new(RichText::new(reference).strong()).truncate());
        });
    }

    fn controls(&mut self, ui: &mut egui::Ui) {
        ui.heading("Bundle");
        ui.label(self.bundle.display().to_string());
        if !self.summary.is_empty() {
            ui.label(RichText::new(&self.summary).small());
        }
        self.method_controls(ui);
        ui.separator();
        self.env_controls(ui);
        ui.separator();
        ui.heading("Camera");
        ui.horizontal(|ui| {
            if ui.button("Reset (R)").clicked() {
                self.reset_camera();
            }
            if ui.button("Bundle camera (C)").clicked() {
                self.set_camera(self.bundle_camera);
            }
        });
        let mut fov = self.camera.fov_deg;
        if ui
            .add(egui::Slider::new(&mut fov, 5.0..=120.0).text("field of view"))
            .changed()
        {
            let c = relight_scene::camera::Camera {
                fov_deg: fov,
                ..self.camera
            };
            self.set_camera(c);
        }
        let mut ss = self.opts.supersample;
        if ui
            .add(egui::Slider::new(&mut ss, 1..=4).text("samples per pixel axis"))
            .changed()
        {
            self.opts.supersample = ss;
            self.dirty.render = true;
        }
        ui.separator();
        ui.heading("Reference");
        ui.horizontal(|ui| {
            for m in [SplitMode::Off, SplitMode::Reference, SplitMode::Heatmap] {
                if ui.selectable_label(self.split == m, m.name()).clicked() {
                    self.set_split(m);
                }
            }
        });
        ui.add(egui::Slider::new(&mut self.split_at, 0.0..=1.0).text("split"));
        let mut depth = self.max_depth;
        if ui
            .add(egui::Slider::new(&mut depth, -1..=16).text("max depth (-1: unlimited)"))
            .changed()
        {
            self.max_depth = depth;
            self.submit_reference();
        }
        let mut f = self.ref_factor;
        if ui
            .add(egui::Slider::new(&mut f, 1..=8).text("reference pixel size"))
            .changed()
        {
            self.ref_factor = f;
            self.dirty.render = true;
        }
        if let Some(c) = &self.comparison {
            ui.label(format!(
                "relative RMSE {:.4}, PSNR {:.1} dB over {} pixels",
                c.metrics.rel_rmse, c.metrics.psnr, c.metrics.pixels
            ));
        }
        ui.separator();
        if ui.button("Screenshot (P)").clicked() {
            self.screenshot_numbered();
        }
    }

    fn method_controls(&mut self, ui: &mut egui::Ui) {
        let methods = self.methods();
        let mut method = self.settings.method();
        if methods.len() > 1 {
            ui.horizontal(|ui| {
                ui.label("Method (M)");
                for m in &methods {
                    ui.selectable_value(&mut method, *m, m.name());
                }
            });
            self.set_method(method);
        } else if let Some(m) = methods.first() {
            ui.label(format!("Method: {}", m.name()));
        }
        let bake_order = self.bake_sh_order().unwrap_or(1);
        let mut s = self.settings.clone();
        match &mut s {
            FrameSettings::Sh(ShFrameSettings { window, sh_order }) => {
                order_slider(ui, sh_order, bake_order);
                window_combo(ui, window);
            }
            FrameSettings::Hybrid(h) => hybrid_controls(ui, h, bake_order),
            FrameSettings::Sg(SgFrameSettings { prefilter_size, .. }) => {
                egui::ComboBox::from_label("prefilter size")
                    .selected_text(prefilter_size.to_string())
                    .show_ui(ui, |ui| {
                        for n in [16, 32, 64, 128, 256, 512, 1024] {
                            ui.selectable_value(prefilter_size, n, n.to_string());
                        }
                    });
                if let Some((lines, _)) = self.baked.and_then(|b| b.describe()) {
                    for l in lines {
                        ui.label(RichText::new(l).small());
                    }
                }
            }
            FrameSettings::Cuts(_) | FrameSettings::Vmf(_) => {}
        }
        if s != self.settings {
            self.settings = s;
            self.dirty.frame = true;
        }
    }

    fn env_controls(&mut self, ui: &mut egui::Ui) {
        ui.heading("Environment");
        ui.label(self.env_source.label());
        ui.horizontal(|ui| {
            ui.label("file");
            ui.text_edit_singleline(&mut self.env_path_text);
            if ui.button("Open").clicked() {
                let p = std::path::PathBuf::from(self.env_path_text.trim());
                self.set_env_source(EnvSource::File(p));
            }
        });
        ui.label(RichText::new("or drop an .hdr / .exr on the window").small());
        ui.horizontal(|ui| {
            if ui.button("Bundle's").clicked() {
                self.set_env_source(EnvSource::Bundle);
            }
            if ui.button("Procedural sky").clicked()
                && !matches!(self.env_source, EnvSource::Sky { .. })
            {
                self.set_env_source(EnvSource::Sky {
                    elevation_deg: 30.0,
                    azimuth_deg: 90.0,
                    turbidity: 3.0,
                });
            }
        });
        if let EnvSource::Sky {
            elevation_deg,
            azimuth_deg,
            turbidity,
        } = self.env_source.clone()
        {
            let (mut e, mut a, mut t) = (elevation_deg, azimuth_deg, turbidity);
            sun_pad(ui, &mut e, &mut a);
            ui.add(egui::Slider::new(&mut e, 0.0..=90.0).text("sun elevation"));
            ui.add(egui::Slider::new(&mut a, 0.0..=360.0).text("sun azimuth"));
            ui.add(egui::Slider::new(&mut t, 2.0..=10.0).text("turbidity"));
            if (e, a, t) != (elevation_deg, azimuth_deg, turbidity) {
                self.set_env_source(EnvSource::Sky {
                    elevation_deg: e,
                    azimuth_deg: a,
                    turbidity: t,
                });
            }
        }
        let mut r = self.rotate_deg;
        if ui
            .add(egui::Slider::new(&mut r, -180.0..=180.0).text("rotation ([ ])"))
            .changed()
        {
            self.rotate_env(r - self.rotate_deg);
        }
        if ui
            .add(egui::Slider::new(&mut self.exposure_ev, -10.0..=10.0).text("exposure EV (- =)"))
            .changed()
        {
            self.dirty.tonemap = true;
        }
        let mut bg = self.opts.background;
        if ui
            .checkbox(&mut bg, "environment as background (G)")
            .changed()
        {
            self.opts.background = bg;
            self.dirty.render = true;
        }
    }

    /// The central panel: the 3D view (frame, split, reference or heat map), the errors, and
    /// the mouse.
    fn view(&mut self, ui: &mut egui::Ui) {
        for e in self.errors.values() {
            ui.label(
                RichText::new(e)
                    .color(Color32::from_rgb(255, 110, 100))
                    .strong(),
            );
        }
        let avail = ui.available_rect_before_wrap();
        let ppp = ui.ctx().pixels_per_point();
        // Physical pixels, a multiple of the reference's pixel size.
        let f = self.ref_factor as u32;
        let w = (((avail.width() * ppp) as u32 / f) * f).clamp(f, 4096);
        let h = (((avail.height() * ppp) as u32 / f) * f).clamp(f, 4096);
        if (w, h) != self.view_size {
            self.view_size = (w, h);
            self.dirty.render = true;
        }
        let ctx = ui.ctx().clone();
        self.refresh(&ctx);
        let rect = Rect::from_min_size(avail.min, Vec2::new(w as f32, h as f32) / ppp);
        let resp = ui.allocate_rect(rect, Sense::click_and_drag());
        let painter = ui.painter_at(rect);
        let full = Rect::from_min_max(Pos2::ZERO, Pos2::new(1.0, 1.0));
        if let Some(t) = &self.texture {
            painter.image(t.id(), rect, full, Color32::WHITE);
        }
        let right = match self.split {
            SplitMode::Off => None,
            SplitMode::Reference => self.ref_texture.as_ref(),
            SplitMode::Heatmap => self.heat_texture.as_ref(),
        };
        if self.split != SplitMode::Off {
            let x = rect.left() + self.split_at * rect.width();
            if let Some(t) = right {
                let r = Rect::from_min_max(Pos2::new(x, rect.top()), rect.max);
                let uv = Rect::from_min_max(Pos2::new(self.split_at, 0.0), Pos2::new(1.0, 1.0));
                painter.image(t.id(), r, uv, Color32::WHITE);
            }
            painter.line_segment(
                [Pos2::new(x, rect.top()), Pos2::new(x, rect.bottom())],
                Stroke::new(1.5, Color32::WHITE),
            );
        }
        self.mouse(ui, &resp, rect);
    }

    fn mouse(&mut self, ui: &egui::Ui, resp: &egui::Response, rect: Rect) {
        let (mods, scroll) = ui.ctx().input(|i| (i.modifiers, i.smooth_scroll_delta.y));
        let d = resp.drag_delta();
        if d != Vec2::ZERO {
            if resp.dragged_by(egui::PointerButton::Secondary)
                || (resp.dragged_by(egui::PointerButton::Primary) && mods.shift)
            {
                let c = orbit::pan(&self.camera, -d.x / rect.width(), d.y / rect.height());
                self.set_camera(c);
            } else if resp.dragged_by(egui::PointerButton::Primary) && mods.ctrl {
                self.rotate_env(d.x * ROTATE_DEG_PER_POINT);
            } else if resp.dragged_by(egui::PointerButton::Primary) {
                let c = orbit::orbit(
                    &self.camera,
                    -d.x * ORBIT_DEG_PER_POINT,
                    d.y * ORBIT_DEG_PER_POINT,
                );
                self.set_camera(c);
            }
        }
        if resp.hovered() && scroll != 0.0 {
            let c = orbit::zoom(&self.camera, (-scroll * ZOOM_PER_POINT).exp());
            self.set_camera(c);
        }
        if self.errors.contains_key(&Slot::Bundle) && self.texture.is_none() {
            ui.painter().text(
                rect.center(),
                egui::Align2::CENTER_CENTER,
                "no bundle loaded",
                egui::FontId::proportional(18.0),
                Color32::GRAY,
            );
        }
    }
}

fn order_slider(ui: &mut egui::Ui, order: &mut Option<usize>, bake_order: usize) {
    let mut n = order.unwrap_or(bake_order);
    if ui
        .add(egui::Slider::new(&mut n, 1..=bake_order.max(1)).text("SH order"))
        .changed()
    {
        *order = Some(n);
    }
}

fn window_combo(ui: &mut egui::Ui, w: &mut Window) {
    let name = match w {
        Window::None => "none",
        Window::Hann => "hann",
        Window::Lanczos => "lanczos",
        Window::Sloan { .. } => "sloan",
    };
    egui::ComboBox::from_label("SH window")
        .selected_text(name)
        .show_ui(ui, |ui| {
            ui.selectable_value(w, Window::None, "none");
            ui.selectable_value(w, Window::Hann, "hann");
            ui.selectable_value(w, Window::Lanczos, "lanczos");
            if ui
                .selectable_label(matches!(w, Window::Sloan { .. }), "sloan")
                .clicked()
            {
                *w = Window::Sloan { lambda: 0.01 };
            }
        });
    if let Window::Sloan { lambda } = w {
        ui.add(egui::Slider::new(lambda, 0.0..=0.1).text("lambda"));
    }
}

fn hybrid_controls(ui: &mut egui::Ui, h: &mut HybridSettings, bake_order: usize) {
    order_slider(ui, &mut h.sh_order, bake_order);
    let l = &mut h.lights;
    ui.add(egui::Slider::new(&mut l.max_lights, 0..=32).text("lights at most"));
    ui.add(egui::Slider::new(&mut l.threshold, 0.0..=0.2).text("elbow threshold"));
    ui.add(egui::Slider::new(&mut l.light_radius, 0.5..=30.0).text("light radius (deg)"));
    ui.add(egui::Slider::new(&mut l.kernel_deg, 0.5..=10.0).text("smoothing kernel (deg)"));
    egui::ComboBox::from_label("shadow map size")
        .selected_text(h.shadow_map_size.to_string())
        .show_ui(ui, |ui| {
            for n in [256, 512, 1024, 2048, 4096] {
                ui.selectable_value(&mut h.shadow_map_size, n, n.to_string());
            }
        });
    ui.add(egui::Slider::new(&mut h.pcf, 1..=9).text("PCF width (texels)"));
    ui.checkbox(&mut h.thesis, "the thesis' point lights");
}

/// The sun pad: azimuth across (0 to 360 degrees), elevation up (0 at the bottom edge, 90 at
/// the top); drag the sun.
fn sun_pad(ui: &mut egui::Ui, elevation: &mut f32, azimuth: &mut f32) {
    let (resp, painter) = ui.allocate_painter(Vec2::new(240.0, 80.0), Sense::click_and_drag());
    let r = resp.rect;
    painter.rect_filled(r, 2.0, Color32::from_rgb(70, 110, 170));
    if let Some(p) = resp.interact_pointer_pos() {
        let p = r.clamp(p);
        *azimuth = 360.0 * (p.x - r.left()) / r.width();
        *elevation = 90.0 * (r.bottom() - p.y) / r.height();
    }
    let sun = Pos2::new(
        r.left() + r.width() * (*azimuth / 360.0),
        r.bottom() - r.height() * (*elevation / 90.0),
    );
    painter.circle_filled(sun, 6.0, Color32::from_rgb(255, 230, 150));
    painter.text(
        r.left_top() + Vec2::new(4.0, 2.0),
        egui::Align2::LEFT_TOP,
        "drag the sun",
        egui::FontId::proportional(11.0),
        Color32::WHITE,
    );
}
