//! The progressive reference: relight's path tracer (`relight_render::pathtrace`, the
//! Mitsuba-matched estimator) on a background thread, a few samples per pixel per pass at a
//! reduced resolution, restarted whenever the view or the environment changes, and the GPU
//! frame's error against it.
//!
//! Pass `k` renders with seed `k`, so passes are independent estimates and their running mean
//! is the estimate at `spp = sum of the passes' spp`. A new job (camera, environment, depth,
//! background) bumps the generation: the running pass finishes (a pass is short by design)
//! and is thrown away, and accumulation restarts. The accumulated image is published after
//! every pass for the UI to read.

use glam::Vec3;
use relight_render::compare::{self, Metrics};
use relight_render::pathtrace::{self, PtSettings};
use relight_render::Image;
use relight_scene::accel::{Backend, RayCaster};
use relight_scene::camera::Camera;
use relight_scene::scene::{Environment, Scene};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError, Sender};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Most samples per pixel the reference accumulates for one view; it then idles.
pub const MAX_SPP: u32 = 4096;

/// Target duration of a pass, milliseconds: short enough that a change of view is followed
/// within about this long, long enough that the per-pass overhead (thread hand-off, image
/// copy) stays small. The samples per pass double until a pass takes this long.
pub const PASS_MS: f64 = 150.0;

/// What to path-trace.
#[derive(Clone, Debug)]
pub struct Job {
    /// The camera, at the reference's (reduced) resolution.
    pub camera: Camera,
    /// The environment (map, rotation, scale).
    pub env: Environment,
    /// Longest path, Mitsuba semantics (`-1` unlimited, 2 direct only).
    pub max_depth: i32,
    /// Whether escaping camera rays show the environment.
    pub background: bool,
}

/// The reference as accumulated so far.
#[derive(Clone, Debug, Default)]
pub struct Accumulated {
    /// The job's generation.
    pub generation: u64,
    /// Mean of the passes so far (empty before the first pass).
    pub image: Option<Image>,
    /// Samples per pixel in `image`.
    pub spp: u32,
    /// Duration of the last pass, milliseconds, and its samples per pixel.
    pub last_pass: (f64, u32),
    /// Why the reference cannot run (no ray-casting back-end for this mesh).
    pub error: Option<String>,
}

struct Shared {
    state: Mutex<Accumulated>,
    generation: AtomicU64,
    stop: AtomicBool,
}

/// The background path tracer.
pub struct Reference {
    shared: Arc<Shared>,
    jobs: Sender<(u64, Job)>,
    thread: Option<JoinHandle<()>>,
}

impl Reference {
    /// Start the thread over the scene's mesh and materials; `on_pass` is called after every
    /// published pass (the UI asks for a repaint there).
    pub fn start(
        mesh: relight_scene::mesh::TriMesh,
        materials: Vec<relight_scene::material::Material>,
        env: Environment,
        camera: Camera,
        on_pass: impl Fn() + Send + 'static,
    ) -> Reference {
        let shared = Arc::new(Shared {
            state: Mutex::new(Accumulated::default()),
            generation: AtomicU64::new(0),
            stop: AtomicBool::new(false),
        });
        let (jobs, rx) = channel();
        let sh = shared.clone();
        let thread = std::thread::Builder::new()
            .name("relight-view reference".into())
            .spawn(move || {
                let scene = Scene {
                    maps: Default::default(),
                    mesh,
                    materials,
                    env,
                    camera,
                    objects: Vec::new(),
                };
                run(scene, &sh, &rx, &on_pass)
            })
            .ok();
        Reference {
            shared,
            jobs,
            thread,
        }
    }

    /// Start path-tracing `job`, dropping what was accumulated for the previous one.
    /// Returns the job's generation.
    pub fn submit(&self, job: Job) -> u64 {
        let g = self.shared.generation.fetch_add(1, Ordering::SeqCst) + 1;
        // A send fails only when the thread has ended (it reports why in `error`).
        let _ = self.jobs.send((g, job));
        g
    }

    /// The current generation.
    pub fn generation(&self) -> u64 {
        self.shared.generation.load(Ordering::SeqCst)
    }

    /// A copy of the accumulated reference.
    pub fn snapshot(&self) -> Accumulated {
        let mut s = lock(&self.shared.state).clone();
        if s.error.is_none() && self.thread.is_none() {
            s.error = Some("the reference thread could not be started".into());
        }
        s
    }
}

impl Drop for Reference {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::SeqCst);
        // Waiting would block the window's close by up to a pass: the thread notices the
        // flag after its pass and ends on its own.
        drop(self.thread.take());
    }
}

fn lock(m: &Mutex<Accumulated>) -> std::sync::MutexGuard<'_, Accumulated> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// The thread: build the ray caster, then accumulate passes of the latest job.
fn run(mut scene: Scene, shared: &Shared, rx: &Receiver<(u64, Job)>, on_pass: &dyn Fn()) {
    let caster = match build_caster(&scene) {
        Ok(c) => c,
        Err(e) => {
            lock(&shared.state).error = Some(e);
            on_pass();
            return;
        }
    };
    let mut current: Option<(u64, Job)> = None;
    let (mut sum, mut spp, mut pass, mut pass_spp) = (Vec::<Vec3>::new(), 0u32, 0u64, 1u32);
    while !shared.stop.load(Ordering::SeqCst) {
        // Take the newest job; block while there is nothing (left) to do.
        let idle = current.as_ref().is_none_or(|_| spp >= MAX_SPP);
        let next = if idle {
            match rx.recv_timeout(Duration::from_millis(200)) {
                Ok(j) => Some(j),
                Err(RecvTimeoutError::Timeout) => continue,
                Err(RecvTimeoutError::Disconnected) => return,
            }
        } else {
            rx.try_recv().ok()
        };
        if let Some(mut j) = next {
            while let Ok(newer) = rx.try_recv() {
                j = newer;
            }
            scene.camera = j.1.camera;
            scene.env = j.1.env.clone();
            let n = (scene.camera.width * scene.camera.height) as usize;
            sum = vec![Vec3::ZERO; n];
            (spp, pass, pass_spp) = (0, 0, 1);
            current = Some(j);
        }
        let Some((generation, job)) = &current else {
            continue;
        };
        let t0 = Instant::now();
        let s = PtSettings {
            spp: pass_spp,
            max_depth: job.max_depth,
            seed: pass,
            threads: None,
            show_background: job.background,
            progress: false,
        };
        let img = pathtrace::render(&scene, caster.as_ref(), &s);
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        if shared.generation.load(Ordering::SeqCst) != *generation {
            continue; // cancelled: a newer job is waiting
        }
        accumulate(&mut sum, spp, &img.pixels, pass_spp);
        spp += pass_spp;
        pass += 1;
        {
            let mut st = lock(&shared.state);
            st.generation = *generation;
            st.image = Some(Image {
                width: img.width,
                height: img.height,
                pixels: sum.clone(),
            });
            st.spp = spp;
            st.last_pass = (ms, pass_spp);
        }
        on_pass();
        if ms < PASS_MS {
            pass_spp = (pass_spp * 2).min(64);
        }
        pass_spp = pass_spp.min(MAX_SPP - spp.min(MAX_SPP)).max(1);
    }
}

/// Fold a pass of `n` samples per pixel into the running mean `mean` of `m` samples:
/// `mean' = (m mean + n pass) / (m + n)`.
pub fn accumulate(mean: &mut [Vec3], m: u32, pass: &[Vec3], n: u32) {
    let (wm, wn) = (m as f32 / (m + n) as f32, n as f32 / (m + n) as f32);
    for (a, &b) in mean.iter_mut().zip(pass) {
        *a = *a * wm + b * wn;
    }
}

fn build_caster(scene: &Scene) -> Result<Box<dyn RayCaster>, String> {
    let mut last = String::from("no ray-casting back-end is compiled in");
    for &b in Backend::available() {
        match relight_scene::accel::build(&scene.mesh, b) {
            Ok(c) => return Ok(c),
            Err(e) => last = e.to_string(),
        }
    }
    Err(format!("the reference path tracer cannot run: {last}"))
}

/// `image` box-filtered down by `factor` in each direction (`factor x factor` pixels to one);
/// the size is the floor of the division.
pub fn downsample(image: &Image, factor: usize) -> Image {
    let f = factor.max(1);
    let (w, h) = (image.width / f, image.height / f);
    let mut out = Image::new(w, h);
    let norm = 1.0 / (f * f) as f32;
    for y in 0..h {
        for x in 0..w {
            let mut s = Vec3::ZERO;
            for dy in 0..f {
                for dx in 0..f {
                    s += image.get(x * f + dx, y * f + dy);
                }
            }
            out.set(x, y, s * norm);
        }
    }
    out
}

/// The GPU frame's error against the reference, both at the reference's resolution.
#[derive(Clone, Debug)]
pub struct Comparison {
    /// relight-render's metrics over the covered pixels (relative RMSE, ...).
    pub metrics: Metrics,
    /// The luminance-error heat map (`relight_render::compare::heatmap`), 8-bit sRGB.
    pub heatmap: Vec<[u8; 3]>,
}

/// Compare `frame` (downsampled to the reference's size) with `reference` over the pixels the
/// frame's geometry covers (`coverage`, per frame pixel, averaged the same way, > 0), or over
/// every pixel when `background` (the environment is part of both images then). `None` when
/// the sizes do not match (a pass of an older view) or nothing is covered.
pub fn compare(
    frame: &Image,
    coverage: &[f32],
    factor: usize,
    reference: &Image,
    background: bool,
) -> Option<Comparison> {
    let a = downsample(frame, factor);
    if (a.width, a.height) != (reference.width, reference.height) {
        return None;
    }
    let mask: Vec<bool> = (0..a.width * a.height)
        .map(|i| {
            if background {
                return true;
            }
            let (x, y) = (i % a.width, i / a.width);
            (0..factor * factor).any(|k| {
                let (px, py) = (x * factor + k % factor, y * factor + k / factor);
                coverage
                    .get(py * frame.width + px)
                    .is_some_and(|&c| c > 0.0)
            })
        })
        .collect();
    let metrics = compare::metrics(&a, reference, Some(&mask));
    if metrics.pixels == 0 {
        return None;
    }
    Some(Comparison {
        metrics,
        heatmap: compare::heatmap(&a, reference),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use relight_sphere::envmap::EnvMap;

    #[test]
    fn accumulating_passes_is_the_mean_of_all_samples() {
        let passes: [(&[f32], u32); 3] = [(&[1.0, 4.0], 1), (&[2.0, 0.0], 2), (&[7.0, 1.0], 4)];
        let mut mean = vec![Vec3::ZERO; 2];
        let mut m = 0;
        for (p, n) in passes {
            let px: Vec<Vec3> = p.iter().map(|&v| Vec3::splat(v)).collect();
            accumulate(&mut mean, m, &px, n);
            m += n;
        }
        // (1*1 + 2*2 + 7*4) / 7 and (4*1 + 0*2 + 1*4) / 7.
        assert!((mean[0].x - 33.0 / 7.0).abs() < 1e-6);
        assert!((mean[1].x - 8.0 / 7.0).abs() < 1e-6);
    }

    #[test]
    fn downsampling_is_a_box_filter() {
        let mut img = Image::new(4, 2);
        for (i, p) in img.pixels.iter_mut().enumerate() {
            *p = Vec3::splat(i as f32);
        }
        let d = downsample(&img, 2);
        assert_eq!((d.width, d.height), (2, 1));
        assert_eq!(d.pixels[0].x, (0.0 + 1.0 + 4.0 + 5.0) / 4.0);
        assert_eq!(d.pixels[1].x, (2.0 + 3.0 + 6.0 + 7.0) / 4.0);
    }

    #[test]
    fn comparison_counts_covered_pixels_only_and_is_zero_for_the_same_image() {
        let mut frame = Image::new(4, 4);
        let mut cov = vec![0.0; 16];
        for y in 0..2 {
            for x in 0..4 {
                frame.set(x, y, Vec3::splat(1.0));
                cov[y * 4 + x] = 1.0;
            }
        }
        let reference = downsample(&frame, 2);
        let c = compare(&frame, &cov, 2, &reference, false).unwrap();
        assert_eq!(c.metrics.pixels, 2, "the top row of the 2x2 reference");
        assert_eq!(c.metrics.rel_rmse, 0.0);
        let mut off = reference.clone();
        off.pixels[0] = Vec3::splat(2.0);
        let c = compare(&frame, &cov, 2, &off, false).unwrap();
        // a = (1, 1), b = (2, 1): rmse = sqrt(1/2), rms(b) = sqrt(5/2).
        assert!((c.metrics.rel_rmse - (1.0f64 / 5.0).sqrt()).abs() < 1e-6);
        assert!(
            compare(&frame, &cov, 1, &reference, false).is_none(),
            "size mismatch"
        );
    }

    /// The thread path-traces a unit sphere under a constant white environment: a white
    /// Lambertian sphere there has radiance exactly 1 everywhere (the furnace test), so the
    /// accumulated reference converges to 1 on the sphere and a new job restarts it.
    #[test]
    fn the_thread_accumulates_and_restarts_on_a_new_job() {
        let mesh = relight_scene::shapes::uv_sphere(Vec3::ZERO, 1.0, 12, 24);
        let materials = vec![relight_scene::material::Material::Lambert { albedo: Vec3::ONE }];
        let env = Environment::new(EnvMap::constant(Vec3::ONE));
        let camera = Camera::look_at([0.0, 0.0, 4.0], [0.0; 3], 30.0, 16, 16);
        let r = Reference::start(mesh, materials, env.clone(), camera, || {});
        let job = Job {
            camera,
            env,
            max_depth: -1,
            background: false,
        };
        let g = r.submit(job.clone());
        let t0 = Instant::now();
        let s = loop {
            let s = r.snapshot();
            assert!(s.error.is_none(), "{:?}", s.error);
            if s.generation == g && s.spp >= 16 {
                break s;
            }
            assert!(t0.elapsed().as_secs() < 60, "no progress: {} spp", s.spp);
            std::thread::sleep(Duration::from_millis(5));
        };
        let img = s.image.unwrap();
        // The centre pixel sees the sphere: 1 up to the path tracer's Russian roulette noise
        // (white furnace: every path carries exactly 1 until roulette, which only adds
        // variance); 16+ spp keep it within 0.25 with a wide margin.
        let c = img.get(8, 8);
        assert!((c.x - 1.0).abs() < 0.25, "{c}");
        let g2 = r.submit(Job {
            background: true,
            ..job
        });
        assert!(g2 > g);
        let t0 = Instant::now();
        loop {
            let s = r.snapshot();
            if s.generation == g2 {
                assert!(s.spp < MAX_SPP);
                // The background now shows the white environment in the corner.
                assert!((s.image.unwrap().get(0, 0).x - 1.0).abs() < 1e-5);
                break;
            }
            assert!(t0.elapsed().as_secs() < 60, "no restart");
            std::thread::sleep(Duration::from_millis(5));
        }
    }
}
