//! The `--script` runner of the viewer ([`crate::script`]'s actions): one action per UI
//! update once the frame of the previous one is shown, with waits for frames, for the
//! reference's samples and for window screenshots.

use super::{App, Slot};
use crate::env::EnvSource;
use crate::orbit;
use crate::script::{Action, Script, SplitMode, WAIT_REFERENCE_SECONDS};
use eframe::egui::{self, ColorImage};
use relight_method::MethodKind;
use std::path::PathBuf;
use std::sync::mpsc::Receiver;
use std::sync::Arc;
use std::time::Instant;

/// A scripted run in progress.
pub(super) struct Runner {
    actions: Vec<(usize, Action)>,
    next: usize,
    wait_frames: u32,
    wait_reference: Option<(u32, Instant)>,
    window_shot: Option<(PathBuf, Receiver<Arc<ColorImage>>, Instant)>,
    line: usize,
}

impl Runner {
    /// A run of `s` from its first action.
    pub(super) fn new(s: Script) -> Runner {
        Runner {
            actions: s.actions,
            next: 0,
            wait_frames: 0,
            wait_reference: None,
            window_shot: None,
            line: 0,
        }
    }
}

impl App<'_> {
    /// Run the script's next action(s), unless it waits. Returns whether a script is running.
    pub(crate) fn step_script(&mut self, ctx: &egui::Context) -> bool {
        let Some(mut r) = self.runner.take() else {
            return false;
        };
        // Wait for the frame of the previous action before taking the next.
        let running = if self.dirty.any() {
            true
        } else {
            self.step_runner(ctx, &mut r)
        };
        if running {
            self.runner = Some(r);
            ctx.request_repaint();
        }
        running
    }

    fn step_runner(&mut self, ctx: &egui::Context, r: &mut Runner) -> bool {
        if r.wait_frames > 0 {
            r.wait_frames -= 1;
            return true;
        }
        if let Some((spp, since)) = r.wait_reference {
            if self.reference_spp() >= spp || self.errors.contains_key(&Slot::Reference) {
                r.wait_reference = None;
            } else if since.elapsed().as_secs() > WAIT_REFERENCE_SECONDS {
                r.wait_reference = None;
                self.set_error(
                    Slot::Script,
                    format!("script line {}: wait-reference {spp}: only {} spp after {WAIT_REFERENCE_SECONDS} s", r.line, self.reference_spp()),
                );
            } else {
                return true;
            }
        }
        if let Some((path, rx, since)) = r.window_shot.take() {
            match rx.try_recv() {
                Ok(img) => {
                    let px: Vec<[u8; 3]> =
                        img.pixels.iter().map(|c| [c.r(), c.g(), c.b()]).collect();
                    if let Err(e) = relight_scene::io::image::write_png_srgb8(
                        &path,
                        img.width(),
                        img.height(),
                        &px,
                    ) {
                        self.set_error(Slot::Screenshot, format!("script line {}: {e}", r.line));
                    }
                }
                Err(_) if since.elapsed().as_secs() < 30 => {
                    r.window_shot = Some((path, rx, since));
                    return true;
                }
                Err(_) => self.set_error(
                    Slot::Screenshot,
                    format!(
                        "script line {}: the window screenshot {} never arrived",
                        r.line,
                        path.display()
                    ),
                ),
            }
        }
        let Some((line, action)) = r.actions.get(r.next).cloned() else {
            return false;
        };
        r.next += 1;
        r.line = line;
        self.apply(ctx, r, line, action);
        true
    }

    fn apply(&mut self, ctx: &egui::Context, r: &mut Runner, line: usize, action: Action) {
        match action {
            Action::WaitFrames(n) => r.wait_frames = n,
            Action::WaitReference(spp) => {
                if self.split == SplitMode::Off {
                    self.set_split(SplitMode::Reference);
                }
                r.wait_reference = Some((spp, Instant::now()));
            }
            Action::Orbit(y, p) => self.set_camera(orbit::orbit(&self.camera, y, p)),
            Action::Pan(x, y) => self.set_camera(orbit::pan(&self.camera, x, y)),
            Action::Zoom(f) => self.set_camera(orbit::zoom(&self.camera, f)),
            Action::ResetCamera => self.reset_camera(),
            Action::BundleCamera => self.set_camera(self.bundle_camera),
            Action::RotateEnv(d) => self.rotate_env(d),
            Action::Exposure(ev) => {
                self.exposure_ev = ev;
                self.dirty.tonemap = true;
            }
            Action::Sky(e, a) => self.set_env_source(EnvSource::Sky {
                elevation_deg: e,
                azimuth_deg: a,
                turbidity: 3.0,
            }),
            Action::Env(p) => self.set_env_source(EnvSource::File(p)),
            Action::BundleEnv => self.set_env_source(EnvSource::Bundle),
            Action::Method(name) => match MethodKind::ALL.iter().find(|m| m.name() == name) {
                Some(&m) if self.methods().contains(&m) => self.set_method(m),
                _ => self.set_error(
                    Slot::Script,
                    format!(
                        "script line {line}: method {name}: this bundle's methods are {:?}",
                        self.methods().iter().map(|m| m.name()).collect::<Vec<_>>()
                    ),
                ),
            },
            Action::Background(b) => {
                self.opts.background = b;
                self.dirty.render = true;
            }
            Action::Split(m) => self.set_split(m),
            Action::SplitAt(f) => self.split_at = f,
            Action::Screenshot(p) => match self.screenshot(&p) {
                Ok(()) => println!("relight view: wrote {}", p.display()),
                Err(e) => self.set_error(Slot::Screenshot, format!("script line {line}: {e}")),
            },
            Action::ScreenshotWindow(p) => {
                let (tx, rx) = std::sync::mpsc::channel();
                ctx.send_viewport_cmd(egui::ViewportCommand::Screenshot(
                    egui::ScreenshotCallback::new(move |img| {
                        let _ = tx.send(img);
                    }),
                ));
                r.window_shot = Some((p, rx, Instant::now()));
            }
            Action::PrintState => println!("relight view: {}", self.state_line()),
            Action::Quit => {
                r.next = r.actions.len();
                ctx.send_viewport_cmd(egui::ViewportCommand::Close);
            }
        }
    }
}
