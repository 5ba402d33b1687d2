//! Rendering of the `sg` method: view-dependent glossy PRT with spherical Gaussians (Green
//! 2005, thesis section 2.3 and 3.2; the bake is `relight_bake::sg`).
//!
//! A frame is two passes:
//! 1. **Per vertex** ([`SgRenderer::prepare`], parallel): the view `v = normalize(eye - x)` is
//!    located on the view icosahedron ([`Icosphere::locate`]: triangle and spherical-cone
//!    barycentrics `b`, `sum b = 1`), and the lobes `k` of its three views are blended
//!    (Conventions below). The diffuse part `rho_x k_view(n_x . v) sum_i T_x,i L_i` is the SH dot
//!    product of the bake's mono transfer with the world-frame SH of the environment
//!    ([`crate::shade_sh::vertex_radiance`]) times the albedo and the material's view-side
//!    factor (`Material::diffuse_factors`).
//! 2. **Per pixel** (deferred shading on [`raster::render_deferred`]): the three vertices'
//!    blended lobes are blended again with the fragment's perspective-correct barycentrics
//!    (the per-pixel interpolation the paper calls critical, its figure 2-2) and each lobe
//!    is integrated against the lighting with one trilinear fetch of the Gaussian-prefiltered
//!    cube chain (eq. 2.7, figure 3-2's shader):
//!    `L_o = sum_k a_k unit_integral(lambda_k) P(R mu_k, lambda_k)` with `R = env_from_world`,
//!    plus the Gouraud-interpolated diffuse radiance. A bake with the GGX-shaped lobe kernel
//!    (`SgBake::kernel`, [`relight_sphere::sg_kernel`]) takes one such fetch per Gaussian term
//!    of the kernel (four), and its energies use the kernel's integral. A bake in the
//!    **half-vector domain** (`SgBake::domain`, `--lobe-domain half-vector`)
//!    has lobes `a K(1 - mu . h(w))`, `h(w) = normalize(w + v)`: each Gaussian term is
//!    integrated for the fragment's own view `v = normalize(eye - x)` with the five tabulated
//!    isotropic Gaussians of [`relight_sphere::half_vector`] (five fetches per term, twenty
//!    per GGX-kernel lobe). Its lobes are blended as others (a half-vector lobe's axis stays
//!    near the normal from view to view), then rescaled to keep the blend of the corners'
//!    integrals, each seen from the view it was fitted or blended for ([`keep_mass`]: a
//!    lobe's integral over `w` depends on the view), and its corners are blended linearly by
//!    default; two or more of its lobes are nested and blended slot by slot, unmatched
//!    ([`ShadeOptions::default_for`]).
//!
//! # Conventions
//! * Lobes are [`SgLobe`]s `a exp(lambda (mu . w - 1))` with axes in the **world** frame in
//!   the bake; [`SgRenderer::prepare`] rotates the blended axes into the **environment map's**
//!   frame (`Environment::env_from_world`), so the prefiltered chain is built once per map
//!   and a runtime rotation only re-rotates the SH of the diffuse part. Rotating a blend is
//!   the same as blending rotated axes (rotation is linear and keeps lengths).
//! * Blending ([`ShadeOptions`]): before any blend, each corner's lobes are **matched** to one
//!   reference corner's ([`match_corners`]: the thesis' correspondence, section 2.2.2 and the
//!   flipping of section 3.4, enforced at render time), across a vertex's three views and
//!   across a triangle's three corners alike. The three **views** are then blended
//!   **linearly** as the thesis does (section 2.3: axes summed and renormalised, amplitudes
//!   and sharpnesses linear, [`blend3`]), and the three **corners** of a pixel's triangle by
//!   **energy** ([`blend3_energy`]: the blend's integral `a int G` is the barycentric mean of
//!   the corners', axis and sharpness weighted by each corner's energy). Why each choice,
//!   measured on five scenes against Mitsuba (docs/RESULTS.md, section sg): without the
//!   view matching, two lobes whose slots swap between views lost 17 % of the teapot-dawn
//!   conductor's light (error 13 % -> 56 % from one lobe to two); an energy blend across
//!   views made more lobes *worse* on Fig. 3-5's shadowed highlight (28.5 / 61.9 / 45.9 % for
//!   1 / 2 / 3 lobes; linear matched views: 33.4 / 19.7 / 19.9 %); the corners' energy
//!   blend keeps a triangle's light the mean of its corners' where a corner's lobe is
//!   switched off. [`ShadeOptions::PAPER`] is the thesis' frame (linear, slot `k` with slot
//!   `k`) and [`ShadeOptions::ENERGY`] energy blends everywhere.
//!   The linear blend's energy `(sum w a) / (sum w lambda)` is a weighted mean of the
//!   corners' `a_j / lambda_j` (weights `w_j lambda_j`), dominated by the sharpest corner.
//! * Radiance: `L(w) = scale * map(env_from_world w)`, as `Environment::radiance`.
//! * Back-facing vertices keep the lobes of their view: the bake clamps views below the
//!   horizon (see `relight_bake::sg`), so silhouettes stay continuous. The diffuse view
//!   factor is evaluated at `max(n . v, 0)`.
//!
//! # Cost (`relight bench`, section "SG frame")
//! 512 x 512, a 15.4K-vertex sphere covering 60 % of the image, 1 lobe, on the shared 2-core
//! machine under a load of 4-8: 56-62 ms wall, 37-40 ms of CPU time over both threads (the
//! SH PRT frame of the same scene: 20 ms), i.e. about 20 ms (50 fps) on two idle cores. The
//! per-vertex pass takes 1-2 ms (view location walks from the previous vertex's triangle,
//! [`locate_near`]); the rasteriser's deferred pass (visibility and fragments) is about half
//! of the frame and the prefiltered fetches about a third. 2 and 3 lobes: 52-56 and 68-74 ms
//! of CPU time.

use crate::raster::{self, Fragment, RasterOptions, Rendered};
use crate::shade_sh;
use glam::{Mat3, Vec3, Vec3A};
use rayon::prelude::*;
use relight_bake::sg::transport::clamp_view;
use relight_bake::sg::SgBake;
use relight_bake::sg::{LobeOrder, SgDomain};
use relight_scene::camera::Camera;
use relight_scene::material::Material;
use relight_scene::mesh::TriMesh;
use relight_scene::scene::Environment;
use relight_sphere::cubemap::{self, CubeFace};
use relight_sphere::env_prefilter::{
    default_levels, prefilter_face, PrefilterLevel, PrefilterOptions, PrefilteredEnv, SourcePyramid,
};
use relight_sphere::envmap::{EnvLayout, EnvMap};
use relight_sphere::half_vector;
use relight_sphere::icosphere::Icosphere;
use relight_sphere::sg::SgLobe;
use relight_sphere::sg_kernel::LobeKernel;
use relight_sphere::sh;
use relight_sphere::sh::rotate::ShRotation;
use std::time::Instant;

mod blend;
pub use blend::{
    blend3, blend3_energy, blend3_with, keep_mass, match_corners, unit_mass, LobeBlend,
};

/// Vertices per parallel work item of the per-vertex pass.
const CHUNK: usize = 1024;

/// `int exp(lambda (mu . w - 1)) dw = 2 pi (1 - exp(-2 lambda)) / lambda` in f32 (the same
/// as `relight_sphere::sg::unit_integral`, which works in f64; beyond `lambda = 9`,
/// `exp(-2 lambda)` is below f32 rounding and is dropped).
#[inline]
pub fn unit_integral_f32(lambda: f32) -> f32 {
    const TWO_PI: f32 = 2.0 * std::f32::consts::PI;
    if lambda > 9.0 {
        TWO_PI / lambda
    } else if lambda > 1e-6 {
        -TWO_PI * (-2.0 * lambda).exp_m1() / lambda
    } else {
        2.0 * TWO_PI
    }
}

/// A cube-map copy of `map` with face size `n` (a power of two), each texel the mean of a
/// 2 x 2 grid of bilinear [`EnvMap::eval`]s: the input of the prefilter. A cube map of the
/// same size is returned as is.
pub fn to_cube(map: &EnvMap, n: usize) -> EnvMap {
    if map.layout() == EnvLayout::Cube && map.width() == n {
        return map.clone();
    }
    let mut texels = vec![Vec3::ZERO; 6 * n * n];
    texels.par_chunks_mut(n).enumerate().for_each(|(fr, row)| {
        let (face, r) = (CubeFace::from_index(fr / n), fr % n);
        for (c, t) in row.iter_mut().enumerate() {
            let mut acc = Vec3::ZERO;
            for (dy, dx) in [(0.25, 0.25), (0.25, 0.75), (0.75, 0.25), (0.75, 0.75)] {
                let st = glam::Vec2::new((c as f32 + dx) / n as f32, (r as f32 + dy) / n as f32);
                acc += map.eval(cubemap::face_st_to_dir(face, st));
            }
            *t = acc * 0.25;
        }
    });
    EnvMap::cube(n, texels)
}

/// Face size of the prefilter's source for `map`: its own for a power-of-two cube map, else
/// the power of two nearest the face size of the same texel pitch (a cube's face size; a
/// quarter of the width of a latlong or an angular probe), in `8..=512`.
pub fn source_face_size(map: &EnvMap) -> usize {
    let w = match map.layout() {
        EnvLayout::Cube if map.width().is_power_of_two() => return map.width(),
        EnvLayout::Cube => map.width(),
        EnvLayout::LatLong | EnvLayout::Probe => map.width() / 4,
    }
    .max(8);
    let up = w.next_power_of_two();
    let n = if up - w > w - up / 2 { up / 2 } else { up };
    n.clamp(8, 512)
}

/// Prefilters a power-of-two cube map into `levels`, one rayon job per `(level, face)`.
///
/// # Panics
/// As [`SourcePyramid::new`] and [`PrefilteredEnv::from_levels`].
pub fn prefilter_parallel(cube: &EnvMap, levels: &[PrefilterLevel]) -> PrefilteredEnv {
    let pyr = SourcePyramid::new(cube);
    let opts = PrefilterOptions::default();
    let data = levels
        .iter()
        .map(|l| {
            let mut v = vec![Vec3::ZERO; 6 * l.size * l.size];
            v.par_chunks_mut(l.size * l.size)
                .enumerate()
                .for_each(|(f, out)| prefilter_face(&pyr, l, &opts, CubeFace::from_index(f), out));
            v
        })
        .collect();
    PrefilteredEnv::from_levels(levels.to_vec(), data)
}

/// The shape of the prefiltered chain of an SG frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChainOptions {
    /// Face size of the finest level (a power of two; capped at the source's).
    pub face_size: usize,
    /// Levels per octave of `sigma` (1: [`default_levels`]).
    pub levels_per_octave: usize,
    /// Texels per `sigma` at a face centre (a face is 2 units wide in its tangent plane, so
    /// texel pitch `2 / n`): level `k` has face size `texels_per_sigma * 2 / sigma_k`
    /// rounded up to a power of two, within `1..=face_size` (1: [`default_levels`]).
    pub texels_per_sigma: f32,
}

impl Default for ChainOptions {
    /// [`default_levels`] of a 128-texel finest level: one level per octave, `n_k = 2 / sigma_k`.
    fn default() -> Self {
        ChainOptions {
            face_size: 128,
            levels_per_octave: 1,
            texels_per_sigma: 1.0,
        }
    }
}

/// The levels of a chain of base face size `n` (the sharpest level has `sigma = 2 / n`, as
/// [`default_levels`]) down to `sigma = 2` radians, `per_octave` levels per octave of
/// `sigma`, each level's face size `texels_per_sigma * 2 / sigma` rounded up to a power of
/// two and capped at `n`. `(1, 1.0)` is [`default_levels`].
pub fn chain_levels(n: usize, per_octave: usize, texels_per_sigma: f32) -> Vec<PrefilterLevel> {
    let per_octave = per_octave.max(1);
    let octaves = n.trailing_zeros() as usize;
    (0..=octaves * per_octave)
        .map(|j| {
            let sigma = 2.0 / n as f32 * 2f32.powf(j as f32 / per_octave as f32);
            let want = (texels_per_sigma * 2.0 / sigma).ceil().max(1.0) as usize;
            PrefilterLevel {
                lambda: 1.0 / (sigma * sigma),
                size: want.next_power_of_two().min(n),
            }
        })
        .collect()
}

/// The lighting of an SG frame: the environment's Gaussian-prefiltered chain (map frame,
/// built once per map), its SH for the diffuse part, and the runtime rotation and scale.
#[derive(Clone, Debug)]
pub struct SgLighting {
    prefiltered: PrefilteredEnv,
    /// `ln lambda` of each level (sharpest first), for the trilinear fetch.
    ln_lambda: Vec<f32>,
    /// The levels' texels as 16-byte SIMD vectors (same order as the chain's).
    texels: Vec<Vec<Vec3A>>,
    /// SH of the map in its own frame, unscaled.
    map_sh: Vec<Vec3>,
    sh_order: usize,
    /// Rotation from world to map directions.
    pub env_from_world: Mat3,
    /// Radiance scale of the environment.
    pub scale: f32,
    /// SH of the lighting in the world frame, scaled: what the diffuse transfer is dotted with.
    world_sh: Vec<Vec3>,
}

impl SgLighting {
    /// Prefilters `env.map` (converted to a cube map of [`source_face_size`]) into the
    /// default chain ([`default_levels`], one level per octave of `sigma`) of base face size
    /// `min(face_size, source)` down to 1 texel, and projects it to SH of `sh_order`
    /// (the diffuse transfer's order).
    ///
    /// # Panics
    /// If `face_size` is not a power of two or `sh_order` is outside `1..=sh::MAX_ORDER`.
    pub fn new(env: &Environment, sh_order: usize, face_size: usize) -> SgLighting {
        SgLighting::with_chain(
            env,
            sh_order,
            &ChainOptions {
                face_size,
                ..ChainOptions::default()
            },
        )
    }

    /// [`SgLighting::new`] with the chain of `chain` ([`chain_levels`]).
    ///
    /// # Panics
    /// If the face size is not a power of two or `sh_order` is outside `1..=sh::MAX_ORDER`.
    pub fn with_chain(env: &Environment, sh_order: usize, chain: &ChainOptions) -> SgLighting {
        let face_size = chain.face_size;
        assert!(face_size.is_power_of_two(), "face size {face_size}");
        let src = source_face_size(&env.map);
        let cube = to_cube(&env.map, src);
        let n = face_size.min(src);
        let levels = chain_levels(n, chain.levels_per_octave, chain.texels_per_sigma);
        debug_assert!(
            chain.levels_per_octave != 1
                || chain.texels_per_sigma != 1.0
                || levels == default_levels(n, n.trailing_zeros() as usize + 1)
        );
        let pre = prefilter_parallel(&cube, &levels);
        let map_sh = sh::project_env(&env.map, sh_order);
        SgLighting::from_parts(pre, map_sh, sh_order, env)
    }

    /// Assembles the lighting from a prefiltered chain and the map's SH (`order^2`
    /// coefficients, map frame), both of `env.map`, with `env`'s rotation and scale.
    pub fn from_parts(
        prefiltered: PrefilteredEnv,
        map_sh: Vec<Vec3>,
        sh_order: usize,
        env: &Environment,
    ) -> SgLighting {
        assert_eq!(map_sh.len(), sh::sh_count(sh_order), "SH of the map");
        let ln_lambda = prefiltered.levels().iter().map(|l| l.lambda.ln()).collect();
        let texels = (0..prefiltered.levels().len())
            .map(|k| {
                prefiltered
                    .level_texels(k)
                    .iter()
                    .map(|&t| t.into())
                    .collect()
            })
            .collect();
        let mut l = SgLighting {
            prefiltered,
            ln_lambda,
            texels,
            map_sh,
            sh_order,
            env_from_world: Mat3::IDENTITY,
            scale: 1.0,
            world_sh: vec![],
        };
        l.set_rotation(env);
        l
    }

    /// Takes `env`'s rotation and scale (its map must be the one prefiltered): re-rotates the
    /// diffuse SH only, the chain stays (a runtime rotation costs microseconds).
    pub fn set_rotation(&mut self, env: &Environment) {
        self.env_from_world = env.env_from_world();
        self.scale = env.scale;
        let mut c = ShRotation::new(self.sh_order, env.world_from_env()).apply(&self.map_sh);
        c.iter_mut().for_each(|v| *v *= env.scale);
        self.world_sh = c;
    }

    /// The prefiltered chain (map frame).
    pub fn prefiltered(&self) -> &PrefilteredEnv {
        &self.prefiltered
    }

    /// The world-frame, scaled SH of the lighting.
    pub fn world_sh(&self) -> &[Vec3] {
        &self.world_sh
    }

    /// [`PrefilteredEnv::sample`] with the levels' `ln lambda` precomputed (the same
    /// trilinear fetch: bilinear in the two levels bracketing `ln lambda`, linear between).
    /// `dir` is a unit direction in the map frame.
    #[inline]
    pub fn sample(&self, dir: Vec3, lambda: f32) -> Vec3 {
        self.sample_a(dir, lambda).into()
    }

    #[inline]
    fn sample_a(&self, dir: Vec3, lambda: f32) -> Vec3A {
        // The face and face coordinates are shared by both levels (one projection per fetch).
        let (face, st) = cubemap::dir_to_face_st(dir);
        let x = lambda.max(1e-30).ln();
        let ln = &self.ln_lambda;
        let last = ln.len() - 1;
        if x >= ln[0] {
            return self.level_eval(0, face, st);
        }
        if x <= ln[last] {
            return self.level_eval(last, face, st);
        }
        let mut k = 0;
        while ln[k + 1] >= x {
            k += 1;
        }
        let t = (ln[k] - x) / (ln[k] - ln[k + 1]);
        self.level_eval(k, face, st) * (1.0 - t) + self.level_eval(k + 1, face, st) * t
    }

    /// Bilinear fetch in level `k` at face coordinates `st` (as `cubemap::bilinear`: texel
    /// centres at `(i + 0.5) / n`, clamped at the face's edges).
    #[inline]
    fn level_eval(&self, k: usize, face: CubeFace, st: glam::Vec2) -> Vec3A {
        let texels = &self.texels[k];
        let n = self.prefiltered.levels()[k].size;
        let x = (st.x * n as f32 - 0.5).clamp(0.0, (n - 1) as f32);
        let y = (st.y * n as f32 - 0.5).clamp(0.0, (n - 1) as f32);
        let c0 = (x as usize).min(n.saturating_sub(2));
        let r0 = (y as usize).min(n.saturating_sub(2));
        let fx = (x - c0 as f32).min(1.0);
        let fy = (y - r0 as f32).min(1.0);
        let (c1, r1) = ((c0 + 1).min(n - 1), (r0 + 1).min(n - 1));
        let base = face.index() * n * n;
        let at = |r: usize, c: usize| texels[base + r * n + c];
        (at(r0, c0) * (1.0 - fx) + at(r0, c1) * fx) * (1.0 - fy)
            + (at(r1, c0) * (1.0 - fx) + at(r1, c1) * fx) * fy
    }

    /// `int a K(w) L(w) dw` of a lobe of kernel `kernel` whose axis is in the map frame: one
    /// [`SgLighting::integrate`] per Gaussian term ([`relight_sphere::sg_kernel`]).
    #[inline]
    pub fn integrate_kernel(&self, kernel: LobeKernel, lobe_in_map: &SgLobe) -> Vec3 {
        kernel.integrate_with(lobe_in_map, |g| self.integrate(g))
    }

    /// `int G(w) L(w) dw` of a lobe whose axis is in the map frame (eq. 2.7, one lobe):
    /// `scale a unit_integral(lambda) P(mu, lambda)`.
    #[inline]
    pub fn integrate(&self, lobe_in_map: &SgLobe) -> Vec3 {
        let p = self.sample_a(lobe_in_map.axis, lobe_in_map.sharpness);
        Vec3::from(Vec3A::from(lobe_in_map.amplitude) * p)
            * (self.scale * unit_integral_f32(lobe_in_map.sharpness))
    }
}

/// The per-vertex state of one frame (output of [`SgRenderer::prepare`]).
#[derive(Clone, Debug, Default)]
pub struct SgFrame {
    /// Lobes per vertex (direct then indirect).
    pub lobe_count: usize,
    /// `lobes[x * lobe_count + k]`: view-blended lobes, axes in the map frame.
    pub lobes: Vec<SgLobe>,
    /// Diffuse radiance per vertex (albedo and view factor applied).
    pub diffuse: Vec<Vec3>,
    /// The eye (world), for the per-pixel view of half-vector-domain lobes.
    pub eye: Vec3,
    /// The lighting's `env_from_world` (the lobes' axes are in the map frame; so is the view
    /// a half-vector lobe is integrated for).
    pub env_from_world: Mat3,
    /// Half-vector bakes: `masses[x * lobe_count + k]`, the [`unit_mass`] of lobe `k` of
    /// vertex `x` seen from the view it was blended for ([`SgRenderer::vertex_masses`]):
    /// what the corner blend keeps ([`keep_mass`]). Empty for light-domain bakes.
    pub masses: Vec<f32>,
}

/// Where the time of one SG frame goes.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SgTimes {
    /// Per-vertex pass: view location and blending, diffuse SH dot products.
    pub vertex_ms: f64,
    /// Rasterisation and per-pixel lobe blending and fetches.
    pub pixel_ms: f64,
}

/// How the frame interpolates lobes ([`LobeBlend`], [`match_corners`]): across the three
/// nearest views at a vertex, and across a triangle's three corners at a pixel. The default
/// (chosen by the figures of docs/RESULTS.md, section sg; module docs) matches lobes
/// everywhere, blends views linearly and corners by energy (a half-vector bake's corners
/// linearly: [`ShadeOptions::default_for`]);
/// [`ShadeOptions::PAPER`] is the thesis' plain barycentric blend of slot `k` with slot `k`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShadeOptions {
    /// The blend of a vertex's three nearest views, of each component's first slot.
    pub views: LobeBlend,
    /// The blend of a vertex's three nearest views, of the later slots (equal to `views`
    /// except for additive lobes, [`Self::ADDITIVE_HALF_VECTOR`]).
    pub later_views: LobeBlend,
    /// Permute each view's lobes to the reference view's before they are blended (two or
    /// more lobes per component).
    pub match_views: bool,
    /// The blend of a triangle's three corners at a pixel.
    pub corners: LobeBlend,
    /// Permute each corner's lobes to the reference corner's before they are blended.
    pub match_corners: bool,
}

impl ShadeOptions {
    /// The thesis' interpolation (section 2.3): linear parameters, slot `k` with slot `k`.
    pub const PAPER: ShadeOptions = ShadeOptions {
        views: LobeBlend::Linear,
        later_views: LobeBlend::Linear,
        match_views: false,
        corners: LobeBlend::Linear,
        match_corners: false,
    };
    /// Energy blends of matched lobes across views and corners.
    pub const ENERGY: ShadeOptions = ShadeOptions {
        views: LobeBlend::Energy,
        later_views: LobeBlend::Energy,
        match_views: true,
        corners: LobeBlend::Energy,
        match_corners: true,
    };
    /// Two or more nested half-vector lobes ([`Self::default_for`]): views by energy, corners
    /// linear, slot by slot.
    pub const NESTED_HALF_VECTOR: ShadeOptions = ShadeOptions {
        views: LobeBlend::Energy,
        later_views: LobeBlend::Energy,
        match_views: false,
        corners: LobeBlend::Linear,
        match_corners: false,
    };
    /// Two or more additive half-vector lobes ([`Self::default_for`]): slot 1, which is the
    /// one-lobe fit, blended as one lobe is ([`Self::PAPER`]); the later slots, each fitted
    /// to what the earlier ones leave, with the views by energy; corners linear, slot by
    /// slot. So an `N + 1`-lobe frame is the `N`-lobe frame plus one residual lobe (up to
    /// the common energy factor of the bake).
    pub const ADDITIVE_HALF_VECTOR: ShadeOptions = ShadeOptions {
        views: LobeBlend::Linear,
        later_views: LobeBlend::Energy,
        match_views: false,
        corners: LobeBlend::Linear,
        match_corners: false,
    };

    /// The view blend of slot `k` (from 0) of a component.
    #[inline]
    pub fn view_blend(&self, k: usize) -> LobeBlend {
        if k == 0 {
            self.views
        } else {
            self.later_views
        }
    }

    /// The default interpolation of a bake whose lobes are in `domain`, ordered by `order`:
    /// [`Self::default`] for light-domain lobes. Half-vector lobes keep their integrals
    /// across both blends ([`keep_mass`]), so the corners' energy blend only weights their
    /// shapes by energy; blending them linearly instead measured better on all five scenes
    /// of the evaluation, by 0 to 1.7 points (docs/RESULTS.md, section sg: the Spot
    /// conductor 10.9 -> 9.2 %). Half-vector bakes of two or more lobes are nested or
    /// additive (the settings refuse others): slot 1 is fitted first at every (vertex,
    /// view) and slot `k` is the `k`-th lobe found, so the slots already correspond and
    /// re-matching them by axis distance can only pair a residual lobe with a main one:
    /// they are blended slot by slot. With one lobe (`lobes`, the most of either component)
    /// every blend is linear. With two or more, a residual lobe blended linearly across
    /// views has its axis averaged with the next view's at full weight however little
    /// energy it carries (St Peter's conductor, nested: 16.3 and 12.4 % at two and three
    /// lobes against 8.1 % for one), so the later slots' views are blended by energy (8.1
    /// and 8.3 %). Nested lobes blend slot 1 by energy too ([`Self::NESTED_HALF_VECTOR`]):
    /// their joint refinement moves it away from the one-lobe fit, and blended linearly it
    /// brought St Peter's blotches back (10.97 % at two lobes). Additive lobes keep slot 1
    /// the one-lobe fit, so it is blended as one lobe is ([`Self::ADDITIVE_HALF_VECTOR`]).
    /// Matching as well (the energy frame) broke the small sphere test (13.0 % at two lobes
    /// against 7.5 % at one).
    pub fn default_for(domain: SgDomain, order: LobeOrder, lobes: usize) -> ShadeOptions {
        match (domain, order) {
            (SgDomain::Light, _) => ShadeOptions::default(),
            (SgDomain::HalfVector, LobeOrder::Joint) => ShadeOptions {
                corners: LobeBlend::Linear,
                ..ShadeOptions::default()
            },
            (SgDomain::HalfVector, LobeOrder::Nested | LobeOrder::Additive) if lobes <= 1 => {
                ShadeOptions::PAPER
            }
            (SgDomain::HalfVector, LobeOrder::Nested) => ShadeOptions::NESTED_HALF_VECTOR,
            (SgDomain::HalfVector, LobeOrder::Additive) => ShadeOptions::ADDITIVE_HALF_VECTOR,
        }
    }

    /// [`Self::default_for`] of `bake`'s domain, order and lobe count.
    pub fn for_bake(bake: &SgBake) -> ShadeOptions {
        let lobes = bake
            .direct
            .lobe_count
            .max(bake.indirect.as_ref().map_or(0, |l| l.lobe_count));
        ShadeOptions::default_for(bake.domain, bake.lobe_order, lobes)
    }
}

impl Default for ShadeOptions {
    /// Matched lobes, views blended linearly, corners by energy (module docs).
    fn default() -> Self {
        ShadeOptions {
            views: LobeBlend::Linear,
            later_views: LobeBlend::Linear,
            match_views: true,
            corners: LobeBlend::Energy,
            match_corners: true,
        }
    }
}

/// [`unit_integral_f32`] of a kernel's unit lobe, `sum_j w_j I(c_j lambda)`
/// ([`relight_sphere::sg_kernel`]).
#[inline]
pub fn kernel_integral_f32(kernel: LobeKernel, lambda: f32) -> f32 {
    match kernel {
        LobeKernel::Gaussian => unit_integral_f32(lambda),
        _ => kernel
            .terms()
            .iter()
            .map(|&(c, w)| w * unit_integral_f32(c * lambda))
            .sum(),
    }
}

/// Renders an [`SgBake`] of a mesh (module docs).
#[derive(Clone, Debug)]
pub struct SgRenderer<'a> {
    mesh: &'a TriMesh,
    bake: &'a SgBake,
    options: ShadeOptions,
    views: Icosphere,
    /// Diffuse albedo of each vertex's material.
    albedo: Vec<Vec3>,
    /// View-factor tables of the distinct materials, and each vertex's table.
    view_tables: Vec<[f32; VIEW_TABLE]>,
    view_index: Vec<u32>,
    /// Sine and cosine of the bake's `horizon_deg` (half-vector bakes: the view each lobe
    /// was fitted for, [`relight_bake::sg::transport::clamp_view`]).
    horizon: (f32, f32),
}

impl<'a> SgRenderer<'a> {
    /// A renderer of `bake`, made of `mesh`.
    ///
    /// # Panics
    /// If the bake's arrays do not match the mesh or each other (a loaded bundle is checked
    /// by its reader first).
    pub fn new(mesh: &'a TriMesh, bake: &'a SgBake) -> SgRenderer<'a> {
        let v = mesh.vertex_count();
        let views = Icosphere::new(bake.view_frequency);
        let nv = views.vertices().len();
        for l in std::iter::once(&bake.direct).chain(bake.indirect.as_ref()) {
            assert_eq!(l.view_count, nv, "views of the bake");
            assert_eq!(l.lobes.len(), v * nv * l.lobe_count, "lobes of the bake");
        }
        assert_eq!(bake.materials.len(), v, "one material per vertex");
        assert_eq!(bake.diffuse.vertex_count, v, "diffuse transfer per vertex");
        assert_eq!(bake.diffuse.channels, 1, "mono diffuse transfer");
        // Distinct materials (a blended bake may have one per vertex).
        let mut palette: std::collections::HashMap<String, u32> = Default::default();
        let mut view_tables = vec![];
        let mut albedo = Vec::with_capacity(v);
        let mut albedos = vec![];
        let view_index = bake
            .materials
            .iter()
            .map(|m| {
                let i = *palette.entry(format!("{m:?}")).or_insert_with(|| {
                    view_tables.push(view_table(m));
                    albedos.push(m.diffuse_albedo());
                    (view_tables.len() - 1) as u32
                });
                albedo.push(albedos[i as usize]);
                i
            })
            .collect();
        SgRenderer {
            mesh,
            bake,
            options: ShadeOptions::for_bake(bake),
            views,
            albedo,
            view_tables,
            view_index,
            horizon: bake.horizon_deg.to_radians().sin_cos(),
        }
    }

    /// The renderer with interpolation `options`.
    pub fn with_options(self, options: ShadeOptions) -> Self {
        SgRenderer { options, ..self }
    }

    /// The interpolation options.
    pub fn options(&self) -> ShadeOptions {
        self.options
    }

    /// The components' lobe counts: direct, then indirect (0 without).
    fn component_lobes(&self) -> [usize; 2] {
        [
            self.bake.direct.lobe_count,
            self.bake.indirect.as_ref().map_or(0, |l| l.lobe_count),
        ]
    }

    /// The view icosahedron.
    pub fn views(&self) -> &Icosphere {
        &self.views
    }

    /// Lobes per vertex: direct plus indirect.
    pub fn lobe_count(&self) -> usize {
        let [d, i] = self.component_lobes();
        d + i
    }

    /// The lobes of vertex `x` for world view direction `v` (unit, towards the viewer),
    /// blended over the three nearest views, world frame, into `out` (`lobe_count` entries).
    pub fn view_lobes(&self, x: usize, v: Vec3, out: &mut [SgLobe]) {
        let (t, b) = self.views.locate(v);
        self.blend_views(x, t, b, v, out);
    }

    /// Half-vector bakes: [`SgFrame::masses`] of `frame`'s lobes (map frame, eye
    /// `frame.eye`), each seen from the view its vertex's lobes were blended for (the
    /// vertex's view, clamped as the bake clamps it). Empty for light-domain bakes.
    /// [`SgRenderer::prepare`] fills them; a frame built by hand calls this.
    pub fn vertex_masses(&self, frame: &SgFrame) -> Vec<f32> {
        if self.bake.domain != SgDomain::HalfVector {
            return vec![];
        }
        let n = frame.lobe_count.max(1);
        let r = frame.env_from_world;
        frame
            .lobes
            .par_chunks(n)
            .enumerate()
            .flat_map_iter(|(x, lobes)| {
                let to_eye =
                    (frame.eye - self.mesh.positions[x]).normalize_or(self.mesh.normals[x]);
                let v = r * self.fitted_view(x, to_eye);
                lobes.iter().map(move |l| unit_mass(self.bake.kernel, l, v))
            })
            .collect()
    }

    /// The direction vertex `x`'s lobes for world view `v` were fitted for: `v`, or `v`
    /// clamped above the vertex's shading horizon as the bake clamps it.
    #[inline]
    fn fitted_view(&self, x: usize, v: Vec3) -> Vec3 {
        match self.mesh.normals[x].try_normalize() {
            Some(n) => clamp_view(n, v, self.horizon.0, self.horizon.1).0,
            None => v,
        }
    }

    /// Blend the lobes of vertex `x` over the views of triangle `t` with weights `b`, for the
    /// world view `v` (used by half-vector bakes only: [`blend::keep_mass`]).
    #[inline]
    fn blend_views(&self, x: usize, t: usize, b: [f32; 3], v: Vec3, out: &mut [SgLobe]) {
        let ids = self.views.triangles()[t].map(|j| j as usize);
        let half = self.bake.domain == SgDomain::HalfVector;
        let (src, dst) = if half {
            (
                ids.map(|j| self.fitted_view(x, self.views.vertices()[j])),
                self.fitted_view(x, v),
            )
        } else {
            ([Vec3::ZERO; 3], Vec3::ZERO)
        };
        let mut o = out.iter_mut();
        for lobes in std::iter::once(&self.bake.direct).chain(self.bake.indirect.as_ref()) {
            let l = ids.map(|j| lobes.get(x, j));
            let p = self.permutations(self.options.match_views, ids, l);
            for k in 0..lobes.lobe_count {
                let corners = [0, 1, 2].map(|c| &l[c][p[c][k] as usize]);
                let blend = self.options.view_blend(k);
                let mut lobe = blend3_with(blend, self.bake.kernel, corners, b);
                if half {
                    let mass = [0, 1, 2].map(|c| unit_mass(self.bake.kernel, corners[c], src[c]));
                    lobe = keep_mass(self.bake.kernel, lobe, corners, mass, b, dst);
                }
                *o.next().expect("out holds lobe_count lobes") = lobe;
            }
        }
    }

    /// Per corner, the permutation of its lobes that matches the corner of lowest `id`
    /// (identities when `on` is false or there is one lobe).
    #[inline]
    fn permutations(
        &self,
        on: bool,
        id: [usize; 3],
        l: [&[SgLobe]; 3],
    ) -> [[u8; blend::MAX_MATCH]; 3] {
        let identity = std::array::from_fn(|k| k as u8);
        let mut p = [identity; 3];
        if on && l[0].len() > 1 {
            let r = (0..3).min_by_key(|&c| id[c]).unwrap_or(0);
            for c in (0..3).filter(|&c| c != r) {
                p[c] = match_corners(l[r], l[c]);
            }
        }
        p
    }

    /// The per-vertex pass for an eye at `eye` (world) under `lighting`.
    pub fn prepare(&self, lighting: &SgLighting, eye: Vec3) -> SgFrame {
        let n = self.lobe_count();
        let vc = self.mesh.vertex_count();
        let mut diffuse = vec![Vec3::ZERO; vc];
        shade_sh::vertex_radiance(&self.bake.diffuse, None, lighting.world_sh(), &mut diffuse);
        let mut lobes = vec![
            SgLobe {
                axis: Vec3::Z,
                sharpness: 1.0,
                amplitude: Vec3::ZERO
            };
            vc * n
        ];
        let r = lighting.env_from_world;
        lobes
            .par_chunks_mut(CHUNK * n.max(1))
            .zip(diffuse.par_chunks_mut(CHUNK))
            .enumerate()
            .for_each(|(c, (lobes, diffuse))| {
                // Neighbouring vertices (in index order) mostly see nearby views: start each
                // view location from the previous vertex's triangle.
                let mut hint = None;
                for (i, d) in diffuse.iter_mut().enumerate() {
                    let x = c * CHUNK + i;
                    let v = (eye - self.mesh.positions[x]).normalize_or(self.mesh.normals[x]);
                    let out = &mut lobes[i * n..(i + 1) * n];
                    let (t, b) = locate_near(&self.views, hint, v);
                    hint = Some(t);
                    self.blend_views(x, t, b, v, out);
                    for l in out.iter_mut() {
                        l.axis = r * l.axis;
                    }
                    let cos_i = self.mesh.normals[x].dot(v).clamp(0.0, 1.0);
                    let table = &self.view_tables[self.view_index[x] as usize];
                    *d *= self.albedo[x] * view_factor(table, cos_i);
                }
            });
        let mut frame = SgFrame {
            lobe_count: n,
            lobes,
            diffuse,
            eye,
            env_from_world: r,
            masses: vec![],
        };
        frame.masses = self.vertex_masses(&frame);
        frame
    }

    /// Radiance of a fragment: per-pixel blend of its triangle's vertex lobes, each
    /// integrated by `lobe_integral(lobe, v)` (axis and the fragment's view `v` in the map
    /// frame), plus the interpolated diffuse part.
    #[inline]
    fn shade(
        &self,
        frame: &SgFrame,
        f: &Fragment,
        lobe_integral: impl Fn(&SgLobe, Vec3) -> Vec3,
    ) -> Vec3 {
        let n = frame.lobe_count;
        let id = self.mesh.indices[f.tri as usize].map(|i| i as usize);
        let mut sum = f.interpolate(self.mesh, &frame.diffuse);
        // The fragment's own view (map frame), needed by half-vector lobes only.
        let half = self.bake.domain == SgDomain::HalfVector;
        let v = if half {
            frame.env_from_world * (frame.eye - f.position).normalize_or(f.shading_normal)
        } else {
            Vec3::ZERO
        };
        let mut start = 0;
        for count in self.component_lobes() {
            let first = start;
            let l = id.map(|x| &frame.lobes[x * n + first..x * n + first + count]);
            start += count;
            let p = self.permutations(self.options.match_corners, id, l);
            for k in 0..count {
                let slot = p.map(|pc| pc[k] as usize);
                let corners = [0, 1, 2].map(|c| &l[c][slot[c]]);
                let mut lobe = blend3_with(self.options.corners, self.bake.kernel, corners, f.bary);
                if half {
                    let mass = [0, 1, 2].map(|c| frame.masses[id[c] * n + first + slot[c]]);
                    lobe = keep_mass(self.bake.kernel, lobe, corners, mass, f.bary, v);
                }
                if lobe.amplitude != Vec3::ZERO && lobe.sharpness > 0.0 {
                    sum += lobe_integral(&lobe, v);
                }
            }
        }
        sum
    }

    /// `int a K L` of one blended lobe seen from `v` (map frame) through a Gaussian
    /// integrator `gauss` (`int G L` of a Gaussian, axis in the map frame): one call per
    /// Gaussian term of the kernel in the light domain; in the half-vector domain
    /// ([`SgDomain::HalfVector`]) five per term, the tabulated Gaussians of
    /// [`relight_sphere::half_vector`].
    #[inline]
    fn integrate_lobe(&self, lobe: &SgLobe, v: Vec3, gauss: impl Fn(&SgLobe) -> Vec3) -> Vec3 {
        let kernel = self.bake.kernel;
        match self.bake.domain {
            SgDomain::Light => kernel.integrate_with(lobe, gauss),
            SgDomain::HalfVector => kernel
                .split(lobe)
                .map(|t| half_vector::integrate_term(&t, v, &gauss))
                .sum(),
        }
    }

    /// One frame: [`SgRenderer::prepare`], then deferred per-pixel shading with prefiltered
    /// fetches ([`SgLighting::integrate`]).
    pub fn render(
        &self,
        lighting: &SgLighting,
        camera: &Camera,
        background: Option<&Environment>,
        opts: &RasterOptions,
    ) -> (Rendered, SgTimes) {
        let t0 = Instant::now();
        let frame = self.prepare(lighting, Vec3::from(camera.origin));
        let t1 = Instant::now();
        let img = raster::render_deferred(self.mesh, camera, background, opts, |f| {
            self.shade(&frame, f, |l, v| {
                self.integrate_lobe(l, v, |g| lighting.integrate(g))
            })
        });
        let t2 = Instant::now();
        let times = SgTimes {
            vertex_ms: (t1 - t0).as_secs_f64() * 1e3,
            pixel_ms: (t2 - t1).as_secs_f64() * 1e3,
        };
        (img, times)
    }

    /// Deferred per-pixel shading of `frame` (from [`SgRenderer::prepare`], or built by hand
    /// with lobes per vertex in the map frame) with `integrate` for each Gaussian term of each
    /// blended lobe (one per lobe for Gaussian bakes, [`relight_sphere::sg_kernel`]): the
    /// second pass of [`SgRenderer::render`] with any integrator (the error budget swaps the
    /// prefiltered fetch for a finer one, and the bake's lobes for exact-view fits).
    ///
    /// # Panics
    /// If `frame` does not hold `lobe_count` lobes and one diffuse value per vertex.
    pub fn render_frame(
        &self,
        frame: &SgFrame,
        camera: &Camera,
        opts: &RasterOptions,
        integrate: impl Fn(&SgLobe) -> Vec3 + Sync,
    ) -> Rendered {
        let vc = self.mesh.vertex_count();
        assert_eq!(frame.lobe_count, self.lobe_count(), "lobes per vertex");
        assert_eq!(frame.lobes.len(), vc * frame.lobe_count, "lobes per vertex");
        assert_eq!(frame.diffuse.len(), vc, "diffuse per vertex");
        if self.bake.domain == SgDomain::HalfVector {
            assert_eq!(frame.masses.len(), frame.lobes.len(), "masses per lobe");
        }
        raster::render_deferred(self.mesh, camera, None, opts, |f| {
            self.shade(frame, f, |l, v| self.integrate_lobe(l, v, &integrate))
        })
    }

    /// The slow reference of [`SgRenderer::render`]: the same blended lobes, each integrated
    /// numerically against every texel of `env.map` with its exact solid angle
    /// (`relight_sphere::sg::integrate_with_env`), times `env.scale`. `O(texels)` per lobe and
    /// sample: for tests on small images and maps. `lighting` supplies the rotation and the
    /// diffuse SH (shared with the fast path).
    pub fn render_reference(
        &self,
        lighting: &SgLighting,
        env: &Environment,
        camera: &Camera,
        opts: &RasterOptions,
    ) -> Rendered {
        let frame = self.prepare(lighting, Vec3::from(camera.origin));
        match self.bake.domain {
            SgDomain::Light => self.render_frame(&frame, camera, opts, |l| {
                relight_sphere::sg::integrate_with_env(std::slice::from_ref(l), &env.map)
                    * env.scale
            }),
            SgDomain::HalfVector => {
                // Each term `exp(s (m . h(w) - 1))` summed over the map's texels, exactly.
                let texels: Vec<_> = env.map.texel_iter().collect();
                let kernel = self.bake.kernel;
                raster::render_deferred(self.mesh, camera, None, opts, |f| {
                    self.shade(&frame, f, |l, v| {
                        let mut acc = Vec3::ZERO;
                        for t in &texels {
                            let h = (t.dir + v).normalize_or_zero();
                            acc +=
                                t.value * (kernel.unit(l.sharpness, l.axis.dot(h)) * t.solid_angle);
                        }
                        acc * l.amplitude * env.scale
                    })
                })
            }
        }
    }
}

/// [`Icosphere::locate`] started from triangle `hint`: walk across the edge opposite the
/// most negative barycentric until all are non-negative (a few steps for a nearby
/// direction); the global search if there is no hint or the walk does not arrive in 8 steps.
/// Only triangles facing `dir` count, whose cone barycentrics are meaningful.
#[inline]
pub fn locate_near(views: &Icosphere, hint: Option<usize>, dir: Vec3) -> (usize, [f32; 3]) {
    if let Some(mut t) = hint {
        for _ in 0..8 {
            let [a, b, c] = views.triangles()[t].map(|j| views.vertices()[j as usize]);
            if dir.dot(a + b + c) <= 0.0 {
                break;
            }
            let w = views.barycentrics(t, dir);
            let k = if w[0] <= w[1] && w[0] <= w[2] {
                0
            } else if w[1] <= w[2] {
                1
            } else {
                2
            };
            if w[k] >= -1e-6 {
                return (t, w);
            }
            t = views.triangle_neighbours(t)[k] as usize;
        }
    }
    views.locate(dir)
}

/// Samples of the view-side diffuse factor over `cos_i` in `[0, 1]`.
const VIEW_TABLE: usize = 33;

/// The material's view-side diffuse factor (`Material::diffuse_factors`: 1 for Lambert,
/// Blinn-Phong and the GGX conductor, the rough interface's transmittance `t(cos_i)` for GGX
/// plastic) tabulated at `VIEW_TABLE` cosines, so a frame needs no table look-up per vertex.
fn view_table(m: &Material) -> [f32; VIEW_TABLE] {
    std::array::from_fn(|i| m.diffuse_factors(i as f32 / (VIEW_TABLE - 1) as f32, 1.0).0)
}

/// Linear interpolation in a [`view_table`] at `cos_i` in `[0, 1]`.
#[inline]
fn view_factor(table: &[f32; VIEW_TABLE], cos_i: f32) -> f32 {
    let x = cos_i.clamp(0.0, 1.0) * (VIEW_TABLE - 1) as f32;
    let i = (x as usize).min(VIEW_TABLE - 2);
    let f = x - i as f32;
    table[i] * (1.0 - f) + table[i + 1] * f
}

#[cfg(test)]
mod tests;

#[cfg(test)]
mod lobe_tests;
