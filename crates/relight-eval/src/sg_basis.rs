//! `relight eval --method sg-basis`: Green 2005, section 3.3 and Fig. 3-3 reproduced: the
//! relative L2 error of three representations of a transport function versus the number of
//! coefficients they store.
//!
//! # Representations
//! * **SG**: `N = 1..10` isotropic spherical Gaussians, counted as **7 floats per lobe** as
//!   the paper does (RGB weight, mean direction, width). The fits see the scalar function in
//!   all three channels, so the RGB weights come out equal. See "SG fitting" below.
//! * **Haar**: the non-linear approximation of Ng, Ramamoorthi & Hanrahan 2003 (Green's
//!   ref. \[22\]): non-standard orthonormal Haar on each cube face, keep the `k` largest
//!   coefficients, `k = 1..100` (`relight_sphere::haar`; coefficients of `sqrt(dA) f`, so the
//!   choice is L2-optimal in the solid-angle measure; positions of the kept coefficients are
//!   not counted, which favours Haar).
//! * **SH**: orders `n = 1..10` (`n^2` coefficients), point-rule projection on the cube map's
//!   texels with their exact solid angles (`relight_sphere::basis::ShBasis`).
//!
//! Each curve is measured on the same tabulated data with the same norm:
//! `err = sqrt(sum_i dA_i (f_i - g_i)^2 / sum_i dA_i f_i^2)` over the `6 x 64 x 64` texels
//! (exact texel solid angles `dA_i`, `g` evaluated at the texel centres).
//!
//! # Transport functions (Green eq. 1.2: `T(w) = f_r(w, v) V(w) (n . w)`, scalar)
//! Values are `Material::eval(view, w)` (which includes the cosine) times the binary
//! visibility `V`, averaged over each texel ([`SUPERSAMPLE`]^2 samples weighted by solid
//! angle, as a renderer accumulating into the cube map would produce: a lobe thinner than a
//! texel keeps its energy instead of being aliased by the texel centres); specular
//! reflectance 1, no diffuse term (Green fits the glossy part only; the diffuse part goes to
//! SH). The shading point sits at the origin on a
//! floor (normal +Y), with the local frame of `warp::Frame::from_normal(+Y)` (local x = world
//! x). Views are given by the angle from the normal, in the xy-plane on the -x side, so
//! reflections lean towards +x.
//! * **(a) small symmetric glossy lobe**: normalised Blinn-Phong, exponent 100, normal view,
//!   unoccluded. Near the peak `cos^100(theta/2) ~ exp(-12.5 theta^2)`: an almost Gaussian lobe
//!   of `sigma ~ 0.2 rad`.
//! * **(b) large lobe cut by visibility**: GGX conductor, alpha 0.5, view 45 degrees from the
//!   normal; visibility from real geometry: a 16 x 16 floor and a box
//!   `[0.4, 1.4] x [0, 0.6] x [-1, 1]` standing next to the point, traced with
//!   `accel::build_default` (Embree when built in). The box hides the reflection direction
//!   (45 degrees elevation towards +x) and everything below about 56 degrees of elevation in
//!   that half-space: a hard visibility edge across the lobe.
//! * **(c) highly specular, anisotropic lobe**: GGX conductor, alpha 0.05, grazing view 78
//!   degrees from the normal, unoccluded. Reflection turns a tilt `d` of the half vector into
//!   `2 d` of the reflected direction in the plane of incidence but only `2 d cos 78 deg`
//!   across it: a lobe about 4.8 times longer (in elevation, cut by the horizon 12 degrees
//!   below the mirror direction) than wide, its thin side (`~ 0.02 rad`) about half a texel.
//!
//! # SG fitting
//! One incremental pass builds `N = 1, 2, .., 10`: each new lobe starts at the best atom of a
//! matching pursuit on the residual (Mallat & Zhang 1993, "Matching pursuits with
//! time-frequency dictionaries": axes on the texel centres of a `6 x 8 x 8` cube plus the 16
//! texels of largest positive residual, sharpnesses `0.4 sqrt(2)^j` up to `lambda_max`, gain
//! `(sum dA g r)^2 / sum dA g^2` at a positive amplitude), then all lobes are refined jointly by
//! `relight_sphere::sg_fit::refine` (bounded Levenberg-Marquardt, analytic Jacobians, Green
//! eq. 3.1 data term, no priors). Since the new lobe lowers the error and the solver accepts
//! only decreasing steps, the error is non-increasing in `N`. `sg_fit::fit`'s own greedy start
//! (a lobe at the texel of largest residual) stalls on the hard visibility edge of (b): the
//! non-negative amplitude of a lobe centred next to an edge it overshoots is zero, and a
//! zero-amplitude lobe has a zero Jacobian for its axis and width, so lobes 3..10 added nothing
//! (38.9 % from `N = 2` on in a first, point-sampled run of (b), against 20.5 % here).
//! `lambda_max = n^2` ([`SG_LAMBDA_MAX_PER_TEXEL2`]).
//!
//! # Orientation of the cube map
//! SG and SH errors do not depend on how the cube map is oriented, Haar errors do (a lobe on a
//! face centre straddles every level's split). The tabulation frame is therefore turned
//! against the scene by a fixed, generic rotation ([`world_from_cube`]), as the transport of
//! an arbitrary vertex is in a global frame; the Haar error of the cube-aligned tabulation is
//! reported alongside as a sensitivity check.

use crate::{output, Result};
use rayon::prelude::*;
use relight_render::plot::{self, Chart, Series, YScale};
use relight_scene::accel::{self, Ray};
use relight_scene::material::Material;
use relight_scene::shapes;
use relight_sphere::basis::{ShBasis, SphericalBasis};
use relight_sphere::haar::{truncation_errors, HaarBasis};
use relight_sphere::sg_fit::{refine, FitOptions, FitTarget};
use relight_sphere::warp::Frame;
use relight_sphere::{cubemap, sg, EnvMap, Mat3, Vec3};
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

/// Samples per texel side when tabulating (texel averages; module docs).
pub const SUPERSAMPLE: usize = 4;

/// SG sharpness bound in units of `n^2` (`n` the face size): `lambda_max = n^2`, i.e.
/// `sigma >= 1 / n` rad, half the angle of a face-centre texel.
pub const SG_LAMBDA_MAX_PER_TEXEL2: f32 = 1.0;

/// Floats per Gaussian lobe in Green's count (RGB weight, mean direction, width).
pub const FLOATS_PER_LOBE: usize = 7;

/// One of the three transport functions (module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Transport {
    /// (a) Blinn-Phong exponent 100 at normal view, unoccluded.
    SmallGlossy,
    /// (b) GGX alpha 0.5 at 45 degrees, cut by a box.
    LargeOccluded,
    /// (c) GGX alpha 0.05 at 78 degrees (grazing), unoccluded.
    SharpAnisotropic,
}

impl Transport {
    /// All three, in the paper's order.
    pub const ALL: [Transport; 3] = [
        Transport::SmallGlossy,
        Transport::LargeOccluded,
        Transport::SharpAnisotropic,
    ];

    /// Short tag (CSV, plot titles).
    pub fn tag(self) -> &'static str {
        match self {
            Transport::SmallGlossy => "a",
            Transport::LargeOccluded => "b",
            Transport::SharpAnisotropic => "c",
        }
    }

    /// Human-readable description.
    pub fn describe(self) -> &'static str {
        match self {
            Transport::SmallGlossy => "small symmetric glossy lobe (Blinn-Phong 100, normal view)",
            Transport::LargeOccluded => "large lobe cut by visibility (GGX 0.5, 45 deg, box)",
            Transport::SharpAnisotropic => "sharp anisotropic lobe (GGX 0.05, 78 deg view)",
        }
    }

    fn material_and_view(self) -> (Material, f32) {
        let spec = Vec3::ONE;
        match self {
            Transport::SmallGlossy => (
                Material::BlinnPhong {
                    diffuse: Vec3::ZERO,
                    specular: spec,
                    exponent: 100.0,
                },
                0.0,
            ),
            Transport::LargeOccluded => (
                Material::GgxConductor {
                    specular: spec,
                    alpha: 0.5,
                },
                45.0,
            ),
            Transport::SharpAnisotropic => (
                Material::GgxConductor {
                    specular: spec,
                    alpha: 0.05,
                },
                78.0,
            ),
        }
    }
}

/// The fixed generic rotation from the cube map's frame to the scene's (module docs): 0.5 rad
/// about `(1, 2, 3) / sqrt 14`.
pub fn world_from_cube() -> Mat3 {
    Mat3::from_axis_angle(Vec3::new(1.0, 2.0, 3.0).normalize(), 0.5)
}

/// Tabulates `t` on a cube map with `n x n` faces whose directions map to the scene by
/// `world_from_cube`: texel values in cube texel order.
pub fn tabulate(t: Transport, n: usize, world_from_cube: Mat3) -> Vec<f64> {
    let (material, view_deg) = t.material_and_view();
    let normal = Vec3::Y;
    let frame = Frame::from_normal(normal);
    let th = view_deg.to_radians();
    let view_local = frame.to_local(Vec3::new(-th.sin(), th.cos(), 0.0));
    let caster = (t == Transport::LargeOccluded).then(|| {
        let mut mesh = shapes::ground_plane(Vec3::ZERO, 16.0, 1);
        let b = shapes::aabb_box(Vec3::new(0.4, 0.0, -1.0), Vec3::new(1.4, 0.6, 1.0), 1);
        mesh.append(&b, 0);
        accel::build_default(&mesh)
    });
    let value = |w: Vec3| -> f64 {
        let v = material.eval(view_local, frame.to_local(w)).x as f64;
        if v == 0.0 {
            return 0.0;
        }
        if let Some(rc) = &caster {
            let o = accel::offset_ray_origin(Vec3::ZERO, normal, w);
            if rc.occluded(&Ray::new(o, w, 0.0, f32::INFINITY)) {
                return 0.0;
            }
        }
        v
    };
    (0..6 * n * n)
        .into_par_iter()
        .map(|i| {
            // Texel average over a SUPERSAMPLE^2 grid in the face plane, each sample weighted
            // by the solid angle it covers, (1 + x^2 + y^2)^(-3/2) dx dy.
            let (face, r, c) = cubemap::texel_coords(n, i);
            let (mut acc, mut wsum) = (0.0, 0.0);
            for sy in 0..SUPERSAMPLE {
                for sx in 0..SUPERSAMPLE {
                    let x =
                        2.0 * (c as f32 + (sx as f32 + 0.5) / SUPERSAMPLE as f32) / n as f32 - 1.0;
                    let y =
                        2.0 * (r as f32 + (sy as f32 + 0.5) / SUPERSAMPLE as f32) / n as f32 - 1.0;
                    let jac = (1.0 + x * x + y * y).powf(-1.5) as f64;
                    let d = face.plane_point(x, y).normalize();
                    acc += jac * value((world_from_cube * d).normalize());
                    wsum += jac;
                }
            }
            acc / wsum
        })
        .collect()
}

/// Solid angles and directions of the texels of an `n x n`-face cube map.
fn texel_geometry(n: usize) -> (Vec<f64>, Vec<Vec3>) {
    (0..6 * n * n)
        .map(|i| {
            let (face, r, c) = cubemap::texel_coords(n, i);
            (
                cubemap::texel_solid_angle(n, r, c),
                cubemap::texel_dir(n, face, r, c),
            )
        })
        .unzip()
}

/// `sqrt(sum dA (f - g)^2 / sum dA f^2)`.
fn relative_l2(da: &[f64], f: &[f64], g: impl Fn(usize) -> f64) -> f64 {
    let (mut e, mut t) = (0.0, 0.0);
    for (i, (&w, &v)) in da.iter().zip(f).enumerate() {
        e += w * (v - g(i)).powi(2);
        t += w * v * v;
    }
    if t > 0.0 {
        (e / t).sqrt()
    } else {
        0.0
    }
}

/// The error curves of one transport function.
#[derive(Clone, Debug)]
pub struct Curves {
    /// Which function.
    pub transport: Transport,
    /// SG error for `N = 1, 2, ..` lobes (`7 N` coefficients).
    pub sg: Vec<f64>,
    /// Haar error for `k = 0, 1, ..` kept coefficients (index = `k`).
    pub haar: Vec<f64>,
    /// Haar error of the cube-aligned tabulation, same indexing.
    pub haar_aligned: Vec<f64>,
    /// SH error for orders `n = 1, 2, ..` (`n^2` coefficients).
    pub sh: Vec<f64>,
    /// Seconds spent fitting the SGs.
    pub sg_seconds: f64,
}

/// Sizes of the experiment.
#[derive(Clone, Copy, Debug)]
pub struct Config {
    /// Cube face size (a power of two).
    pub face: usize,
    /// Largest SG count.
    pub max_lobes: usize,
    /// Largest SH order.
    pub max_sh_order: usize,
    /// Largest number of Haar coefficients.
    pub max_haar: usize,
}

impl Default for Config {
    fn default() -> Self {
        Config {
            face: 64,
            max_lobes: 10,
            max_sh_order: 10,
            max_haar: 100,
        }
    }
}

/// Candidate axes of the matching pursuit: the texel centres of a `6 x 8 x 8` cube.
const PURSUIT_GRID: usize = 8;
/// Candidate sharpnesses of the matching pursuit: `2^(j/2)`, `j = 0..`, up to `lambda_max`.
const PURSUIT_SHARPNESS_STEP: f64 = std::f64::consts::SQRT_2;

/// Errors of `N = 1..=max_lobes` SGs fitted to the texel values `f` (module docs, "SG
/// fitting"): each new lobe starts at the best matching-pursuit atom for the residual, then
/// every lobe is refined jointly by `sg_fit::refine`.
fn fit_sg_incremental(
    f: &[f64],
    da: &[f64],
    dirs: &[Vec3],
    n: usize,
    max_lobes: usize,
) -> Vec<f64> {
    let w32: Vec<f32> = da.iter().map(|&w| w as f32).collect();
    let vals: Vec<Vec3> = f.iter().map(|&v| Vec3::splat(v as f32)).collect();
    let target = FitTarget::new(dirs, &w32, &vals);
    let opts = FitOptions {
        // sigma down to half a face-centre texel (1 / n rad): the thin side of lobe (c) is
        // about that wide. sg_fit's advice, (n / 2)^2, would forbid the data's own width.
        lambda_max: SG_LAMBDA_MAX_PER_TEXEL2 * (n * n) as f32,
        // Errors are reported to 3 digits: stop refining at 1e-4 relative progress.
        tolerance: 1e-4,
        max_iterations: 30,
        ..FitOptions::default()
    };
    let lambdas: Vec<f64> = std::iter::successors(Some(opts.lambda_min as f64 * 8.0), |l| {
        Some(l * PURSUIT_SHARPNESS_STEP)
    })
    .take_while(|&l| l <= opts.lambda_max as f64 * 1.0001)
    .collect();
    let (m, grid) = (PURSUIT_GRID, PURSUIT_GRID * PURSUIT_GRID);
    let mut lobes: Vec<sg::SgLobe> = Vec::new();
    let mut errors = Vec::with_capacity(max_lobes);
    for _ in 0..max_lobes {
        let model: Vec<f64> = dirs
            .iter()
            .map(|&d| sg::eval_mixture(&lobes, d).x as f64)
            .collect();
        let res: Vec<f64> = f.iter().zip(&model).map(|(a, b)| a - b).collect();
        // Candidate axes: a coarse grid plus the 16 texels of largest positive residual.
        let mut by_res: Vec<usize> = (0..res.len()).filter(|&i| res[i] > 0.0).collect();
        by_res.sort_unstable_by(|&a, &b| res[b].total_cmp(&res[a]).then(a.cmp(&b)));
        let axes: Vec<Vec3> = (0..6 * grid)
            .map(|i| {
                let (face, r, c) = cubemap::texel_coords(m, i);
                cubemap::texel_dir(m, face, r, c)
            })
            .chain(by_res.iter().take(16).map(|&i| dirs[i]))
            .collect();
        // Matching pursuit: the atom exp(lambda (mu . w - 1)) with the largest energy gain
        // (sum dA g r)^2 / sum dA g^2 at a positive amplitude.
        let best = axes
            .par_iter()
            .map(|&mu| {
                let dots: Vec<f64> = dirs.iter().map(|&d| mu.dot(d) as f64 - 1.0).collect();
                let mut best = (0.0f64, 1.0f64, 0.0f64);
                for &lam in &lambdas {
                    let (mut num, mut den) = (0.0, 0.0);
                    for i in 0..dots.len() {
                        // exp(-30) is below f32 resolution of any amplitude: skip those texels.
                        if lam * dots[i] > -30.0 {
                            let g = (lam * dots[i]).exp();
                            num += da[i] * g * res[i];
                            den += da[i] * g * g;
                        }
                    }
                    if num > 0.0 && den > 0.0 && num * num / den > best.0 {
                        best = (num * num / den, lam, num / den);
                    }
                }
                (best, mu)
            })
            .reduce(
                || ((0.0, 1.0, 0.0), Vec3::Y),
                |a, b| if b.0 .0 > a.0 .0 { b } else { a },
            );
        let ((_, lam, amp), mu) = best;
        lobes.push(sg::SgLobe::new(mu, lam as f32, Vec3::splat(amp as f32)));
        lobes = refine(&target, &lobes, &opts, None).lobes;
        errors.push(relative_l2(da, f, |i| {
            sg::eval_mixture(&lobes, dirs[i]).x as f64
        }));
    }
    errors
}

/// Measures the three representations on `t`.
pub fn measure(t: Transport, cfg: &Config) -> Curves {
    let n = cfg.face;
    let (da, dirs) = texel_geometry(n);
    let f = tabulate(t, n, world_from_cube());
    // Haar: one transform, every k at once.
    let haar = HaarBasis::new(n);
    let haar_err = truncation_errors(&haar.project_values(&f), cfg.max_haar);
    let aligned = tabulate(t, n, Mat3::IDENTITY);
    let haar_aligned = truncation_errors(&haar.project_values(&aligned), cfg.max_haar);
    // SH: project at each order, reconstruct at the texel centres.
    let map = EnvMap::cube(n, f.iter().map(|&v| Vec3::splat(v as f32)).collect());
    let sh: Vec<f64> = (1..=cfg.max_sh_order)
        .into_par_iter()
        .map(|order| {
            let c: Vec<f32> = ShBasis::new(order)
                .project_env(&map)
                .iter()
                .map(|v| v.x)
                .collect();
            relative_l2(&da, &f, |i| {
                relight_sphere::sh::eval_scalar(&c, dirs[i]) as f64
            })
        })
        .collect();
    // SG: one incremental pass, N = 1..max (module docs, "SG fitting").
    let start = Instant::now();
    let sg_err = fit_sg_incremental(&f, &da, &dirs, n, cfg.max_lobes);
    Curves {
        transport: t,
        sg: sg_err,
        haar: haar_err,
        haar_aligned,
        sh,
        sg_seconds: start.elapsed().as_secs_f64(),
    }
}

/// Percent with three significant digits.
fn pct(e: f64) -> String {
    let p = 100.0 * e;
    if p >= 10.0 {
        format!("{p:.1}")
    } else if p >= 1.0 {
        format!("{p:.2}")
    } else {
        format!("{p:.3}")
    }
}

/// The CSV (`function,representation,parameter,coefficients,relative_l2_error`).
pub fn csv(curves: &[Curves]) -> String {
    let mut s = String::from("function,representation,parameter,coefficients,relative_l2_error\n");
    for c in curves {
        let tag = c.transport.tag();
        for (i, e) in c.sg.iter().enumerate() {
            let _ = writeln!(
                s,
                "{tag},sg,{},{},{e:.6e}",
                i + 1,
                FLOATS_PER_LOBE * (i + 1)
            );
        }
        for (k, e) in c.haar.iter().enumerate().skip(1) {
            let _ = writeln!(s, "{tag},haar,{k},{k},{e:.6e}");
        }
        for (k, e) in c.haar_aligned.iter().enumerate().skip(1) {
            let _ = writeln!(s, "{tag},haar-aligned,{k},{k},{e:.6e}");
        }
        for (i, e) in c.sh.iter().enumerate() {
            let n = i + 1;
            let _ = writeln!(s, "{tag},sh,{n},{},{e:.6e}", n * n);
        }
    }
    s
}

/// The markdown table: one row per coefficient count that some representation uses
/// (`7 N` for SG, `n^2` for SH; Haar at every count), errors in percent.
pub fn markdown(curves: &[Curves]) -> String {
    let mut counts: Vec<usize> = Vec::new();
    if let Some(c) = curves.first() {
        counts.extend((1..=c.sg.len()).map(|n| FLOATS_PER_LOBE * n));
        counts.extend((1..=c.sh.len()).map(|n| n * n));
        counts.retain(|&k| k < c.haar.len());
    }
    counts.sort_unstable();
    counts.dedup();
    let mut s =
        String::from("Relative L2 error (%) versus stored coefficients.\n\n| coefficients |");
    for c in curves {
        let t = c.transport.tag();
        let _ = write!(s, " ({t}) SG | ({t}) Haar | ({t}) SH |");
    }
    s.push_str("\n|---:|");
    s.push_str(&"---:|".repeat(3 * curves.len()));
    s.push('\n');
    for &k in &counts {
        let _ = write!(s, "| {k} |");
        for c in curves {
            let sg = (k % FLOATS_PER_LOBE == 0)
                .then(|| c.sg.get(k / FLOATS_PER_LOBE - 1))
                .flatten();
            let n = (k as f64).sqrt().round() as usize;
            let sh = (n * n == k).then(|| c.sh.get(n - 1)).flatten();
            let cell = |e: Option<&f64>, label: String| {
                e.map_or(String::new(), |e| format!("{} ({label})", pct(*e)))
            };
            let _ = write!(
                s,
                " {} | {} | {} |",
                cell(sg, format!("N={}", k / FLOATS_PER_LOBE)),
                pct(c.haar[k]),
                cell(sh, format!("order {n}"))
            );
        }
        s.push('\n');
    }
    s.push_str("\nFunctions:\n");
    for c in curves {
        let _ = writeln!(
            s,
            "* ({}) {}; Haar with the cube map aligned to the scene: {} / {} / {} % at k = 7 / 35 / 70.",
            c.transport.tag(),
            c.transport.describe(),
            pct(c.haar_aligned[7.min(c.haar_aligned.len() - 1)]),
            pct(c.haar_aligned[35.min(c.haar_aligned.len() - 1)]),
            pct(c.haar_aligned[70.min(c.haar_aligned.len() - 1)]),
        );
    }
    s
}

/// The three panels of the figure.
pub fn charts(curves: &[Curves]) -> Vec<Chart> {
    curves
        .iter()
        .map(|c| Chart {
            title: format!(
                "({}) {}",
                c.transport.tag(),
                match c.transport {
                    Transport::SmallGlossy => "SMALL GLOSSY LOBE",
                    Transport::LargeOccluded => "LARGE LOBE + VISIBILITY",
                    Transport::SharpAnisotropic => "SHARP ANISOTROPIC LOBE",
                }
            ),
            x_label: "COEFFICIENTS".into(),
            y_label: "RELATIVE L2 ERROR".into(),
            y_scale: YScale::LogPercent,
            series: vec![
                Series {
                    name: "SG (7/LOBE)".into(),
                    points: (c.sg.iter().enumerate())
                        .map(|(i, e)| ((FLOATS_PER_LOBE * (i + 1)) as f64, *e))
                        .collect(),
                    markers: true,
                },
                Series {
                    name: "HAAR (K LARGEST)".into(),
                    points: (c.haar.iter().enumerate().skip(1))
                        .map(|(k, e)| (k as f64, *e))
                        .collect(),
                    markers: false,
                },
                Series {
                    name: "SH ORDER N".into(),
                    points: (c.sh.iter().enumerate())
                        .map(|(i, e)| (((i + 1) * (i + 1)) as f64, *e))
                        .collect(),
                    markers: true,
                },
            ],
        })
        .collect()
}

/// Runs the experiment and writes `fig3-3.csv`, `fig3-3.md` and `fig3-3.png` into `out`.
///
/// # Errors
/// A write error naming the file.
pub fn run(out: &Path) -> Result<()> {
    output::create_dir(out)?;
    let cfg = Config::default();
    let start = Instant::now();
    eprintln!(
        "eval sg-basis: 3 transport functions on 6 x {0} x {0} cube maps, in parallel",
        cfg.face
    );
    // The SG fits dominate and are single-threaded: one function per worker.
    let curves: Vec<Curves> = Transport::ALL
        .par_iter()
        .map(|&t| {
            let c = measure(t, &cfg);
            eprintln!(
                "eval sg-basis: ({}) {}: 7 coefficients: SG {} %, Haar {} %, SH order 3 {} % \
                 (SG fits {:.1} s)",
                t.tag(),
                t.describe(),
                pct(c.sg[0]),
                pct(c.haar[7]),
                pct(c.sh[2]),
                c.sg_seconds
            );
            c
        })
        .collect();
    let md = markdown(&curves);
    relight_bundle::write_atomic(&out.join("fig3-3.csv"), csv(&curves).as_bytes())?;
    relight_bundle::write_atomic(&out.join("fig3-3.md"), md.as_bytes())?;
    plot::write_png(&out.join("fig3-3.png"), &charts(&curves), 700, 500)?;
    eprintln!(
        "eval sg-basis: wrote {}/fig3-3.{{csv,md,png}} in {:.1} s",
        out.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

#[cfg(test)]
mod tests;
