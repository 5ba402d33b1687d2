//! The reference path tracer: unidirectional path tracing under the scene's environment, with
//! environment importance sampling, BSDF sampling and multiple importance sampling (power
//! heuristic, Veach 1997, ch. 9), written to agree with Mitsuba 3's `path` integrator.
//!
//! Semantics shared with Mitsuba 3 (`path` integrator, `box` reconstruction filter):
//! * `max_depth`: 1 = only the directly visible environment, 2 = direct lighting only, 3 = one
//!   indirect bounce, ..., -1 = unlimited; 0 renders black.
//! * Russian roulette from depth 5 on (Mitsuba's default `rr_depth = 5`): the path survives
//!   with probability `min(max_channel(throughput), 0.95)`. It never triggers at
//!   `max_depth <= 5`, where the estimator is the same as Mitsuba's.
//! * Pixel `(x, y)` averages `spp` radiance samples through uniformly jittered points of the
//!   pixel square (a box filter of one pixel, Mitsuba's `<rfilter type="box"/>`).
//! * Materials are one-sided and are evaluated in the shading frame of the interpolated vertex
//!   normal, or of the normal map's normal; texture maps set the material's parameters at the
//!   hit (`relight_scene::material::maps::shading_at`, shared with the cuts renderer). A
//!   direction (towards the viewer or the light) whose side of the *geometric* normal
//!   disagrees with its side of the shading normal ends the path / contributes nothing (no
//!   light leaks through shading-normal interpolation).
//! * The environment is visible to camera rays when `show_background` (Mitsuba's
//!   `hide_emitters = false`).
//! * Point and spot lights ([`crate::light`], [`render_with_lights`]) are delta lights: reached
//!   by next-event estimation only (one shadow ray per light and path vertex, no MIS: BSDF
//!   sampling can never hit them), at the same path vertices as the environment's, so
//!   `max_depth 2` is their direct light and `3` adds one indirect bounce, as in Mitsuba.
//!
//! Determinism: pixel `p = y * width + x` draws all its random numbers from its own stream
//! `Rng::new(seed, p)`, so the image depends on the seed only, not on the thread count or
//! scheduling.

use crate::image::Image;
use crate::light::PointLight;
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use relight_scene::accel::{offset_ray_origin, Ray, RayCaster};
use relight_scene::material::{power_heuristic, Material};
use relight_scene::scene::Scene;
use relight_scene::{Mat3, Vec3};
use relight_sphere::env_sampler::EnvSampler;
use relight_sphere::warp::Rng;

/// Depth from which Russian roulette may end paths (Mitsuba 3's default `rr_depth`).
pub const RR_DEPTH: u32 = 5;

/// Settings of a path-traced render.
#[derive(Clone, Debug, PartialEq)]
pub struct PtSettings {
    /// Samples per pixel.
    pub spp: u32,
    /// Longest path in segments, Mitsuba semantics (2 = direct only, -1 = unlimited).
    pub max_depth: i32,
    /// Seed of all random streams.
    pub seed: u64,
    /// Worker threads (`None`: rayon's global pool).
    pub threads: Option<usize>,
    /// Whether camera rays that escape show the environment.
    pub show_background: bool,
    /// Show an indicatif progress bar on stderr.
    pub progress: bool,
}

impl Default for PtSettings {
    fn default() -> Self {
        PtSettings {
            spp: 64,
            max_depth: -1,
            seed: 0,
            threads: None,
            show_background: true,
            progress: false,
        }
    }
}

impl PtSettings {
    /// Check user input: `spp` in `1..=max_spp`, `max_depth` -1 (unlimited) or >= 0.
    ///
    /// # Errors
    /// A message naming the option (`--spp`, `--max-depth`) and its range.
    pub fn validate(&self, max_spp: u32) -> Result<(), String> {
        if !(1..=max_spp).contains(&self.spp) {
            return Err(format!("--spp {} is not in 1..={max_spp}", self.spp));
        }
        if self.max_depth < -1 {
            return Err(format!(
                "--max-depth {} is not -1 (unlimited) or >= 0",
                self.max_depth
            ));
        }
        Ok(())
    }
}

/// Render the scene's camera view; see the module docs for the estimator.
pub fn render(scene: &Scene, caster: &dyn RayCaster, s: &PtSettings) -> Image {
    render_with_variance(scene, caster, s).0
}

/// Render, and also return per pixel and channel the estimated variance **of the mean** (sample
/// variance over `spp`, divided by `spp`): the squared standard error of each pixel value,
/// which tests use as the image's noise floor.
pub fn render_with_variance(
    scene: &Scene,
    caster: &dyn RayCaster,
    s: &PtSettings,
) -> (Image, Image) {
    render_with_lights(scene, caster, s, &[])
}

/// [`render_with_variance`] with point and spot `lights` besides the environment (module
/// docs; the lights are used as given: check them with [`PointLight::validated`]).
pub fn render_with_lights(
    scene: &Scene,
    caster: &dyn RayCaster,
    s: &PtSettings,
    lights: &[PointLight],
) -> (Image, Image) {
    match s.threads {
        Some(n) => match rayon::ThreadPoolBuilder::new()
            .num_threads(n.max(1))
            .build()
        {
            Ok(pool) => pool.install(|| render_inner(scene, caster, s, lights)),
            Err(_) => render_inner(scene, caster, s, lights),
        },
        None => render_inner(scene, caster, s, lights),
    }
}

/// Everything a path needs that is the same for all pixels.
struct Ctx<'a> {
    scene: &'a Scene,
    caster: &'a dyn RayCaster,
    sampler: EnvSampler,
    env_from_world: Mat3,
    world_from_env: Mat3,
    max_depth: u32,
    show_background: bool,
    lights: &'a [PointLight],
}

fn render_inner(
    scene: &Scene,
    caster: &dyn RayCaster,
    s: &PtSettings,
    lights: &[PointLight],
) -> (Image, Image) {
    let frame = scene.camera.frame();
    let (w, h) = (scene.camera.width as usize, scene.camera.height as usize);
    let ctx = Ctx {
        scene,
        caster,
        sampler: EnvSampler::new(&scene.env.map),
        env_from_world: scene.env.env_from_world(),
        world_from_env: scene.env.world_from_env(),
        max_depth: if s.max_depth < 0 {
            u32::MAX
        } else {
            s.max_depth as u32
        },
        show_background: s.show_background,
        lights,
    };
    let bar = if s.progress {
        let b = ProgressBar::new(h as u64);
        if let Ok(style) =
            ProgressStyle::with_template("path tracing {bar:40} {pos}/{len} rows {elapsed}<{eta}")
        {
            b.set_style(style);
        }
        b
    } else {
        ProgressBar::hidden()
    };
    let spp = s.spp.max(1);
    let rows: Vec<Vec<(Vec3, Vec3)>> = (0..h)
        .into_par_iter()
        .map(|y| {
            let row = (0..w)
                .map(|x| {
                    let mut rng = Rng::new(s.seed, (y * w + x) as u64);
                    let (mut sum, mut sum2) = ([0.0f64; 3], [0.0f64; 3]);
                    for _ in 0..spp {
                        let j = rng.next_vec2();
                        let dir = frame.dir_at(x as f32 + j.x, y as f32 + j.y);
                        let l =
                            ctx.radiance(Ray::new(frame.origin, dir, 0.0, f32::INFINITY), &mut rng);
                        for c in 0..3 {
                            sum[c] += l[c] as f64;
                            sum2[c] += (l[c] as f64) * (l[c] as f64);
                        }
                    }
                    let n = spp as f64;
                    let mean: [f64; 3] = std::array::from_fn(|c| sum[c] / n);
                    let var: [f64; 3] = std::array::from_fn(|c| {
                        if spp < 2 {
                            0.0
                        } else {
                            ((sum2[c] - n * mean[c] * mean[c]) / (n - 1.0)).max(0.0) / n
                        }
                    });
                    (
                        Vec3::from(mean.map(|v| v as f32)),
                        Vec3::from(var.map(|v| v as f32)),
                    )
                })
                .collect();
            bar.inc(1);
            row
        })
        .collect();
    bar.finish_and_clear();
    let mut img = Image::new(w, h);
    let mut var = Image::new(w, h);
    for (y, row) in rows.into_iter().enumerate() {
        for (x, (m, v)) in row.into_iter().enumerate() {
            img.set(x, y, m);
            var.set(x, y, v);
        }
    }
    (img, var)
}

impl Ctx<'_> {
    /// Radiance arriving along `ray` (from its far end towards the origin).
    fn radiance(&self, mut ray: Ray, rng: &mut Rng) -> Vec3 {
        let mesh = &self.scene.mesh;
        let env = &self.scene.env;
        let mut result = Vec3::ZERO;
        let mut throughput = Vec3::ONE;
        // Density of the BSDF sample that produced `ray` (`None`: camera ray).
        let mut prev_bsdf_pdf: Option<f32> = None;
        let mut depth: u32 = 0;
        if self.max_depth == 0 {
            return result;
        }
        loop {
            let Some(hit) = self.caster.intersect(&ray) else {
                // Escaped: environment, MIS-weighted against environment sampling.
                let d = ray.dir.normalize();
                let weight = match prev_bsdf_pdf {
                    None if !self.show_background => 0.0,
                    None => 1.0,
                    Some(p) => power_heuristic(p, self.sampler.pdf(self.env_from_world * d)),
                };
                if weight > 0.0 {
                    result += throughput * env.radiance(d) * weight;
                }
                break;
            };
            // Mitsuba: no emitter sampling nor continuation once depth + 1 reaches max_depth.
            if depth.saturating_add(1) >= self.max_depth {
                break;
            }
            let tri = hit.tri as usize;
            let p = ray.at(hit.t);
            let ng = mesh.geometric_normal(tri);
            // The material and frame at the hit, texture and normal maps applied: the lookup
            // the cuts renderer shares (`relight_scene::material::maps::shading_at`).
            let n = mesh.shading_normal(tri, hit.u, hit.v);
            let valid = mesh
                .material_ids
                .get(tri)
                .is_some_and(|&m| (m as usize) < self.scene.materials.len());
            let (material, shading) = if valid {
                self.scene
                    .shading_at(hit.tri, [1.0 - hit.u - hit.v, hit.u, hit.v], n)
            } else {
                debug_assert!(false, "triangle {tri} has no valid material");
                let m = Material::default();
                (m, m.shading_frame(n))
            };
            let wi_world = -ray.dir.normalize();
            let wi = shading.to_local(wi_world);
            // One-sided materials see nothing from below; reject inconsistent sides.
            if wi.z <= 0.0 || wi_world.dot(ng) * wi.z <= 0.0 {
                break;
            }

            // Environment sampling (next-event estimation), MIS-weighted against BSDF sampling.
            let (d_env, pdf_env) = self.sampler.sample(rng.next_vec2());
            if pdf_env > 0.0 {
                let d = (self.world_from_env * d_env).normalize();
                let wo = shading.to_local(d);
                if wo.z > 0.0 && d.dot(ng) > 0.0 {
                    let f = material.eval(wi, wo);
                    if f.max_element() > 0.0 {
                        let shadow = Ray::new(offset_ray_origin(p, ng, d), d, 0.0, f32::INFINITY);
                        if !self.caster.occluded(&shadow) {
                            let le = env.map.eval(d_env) * env.scale;
                            let w = power_heuristic(pdf_env, material.pdf(wi, wo));
                            result += throughput * f * le * (w / pdf_env);
                        }
                    }
                }
            }

            // Point and spot lights (delta: no MIS).
            for light in self.lights {
                let Some((e, d, dist)) = light.irradiance(p, ng) else {
                    continue;
                };
                let wo = shading.to_local(d);
                if wo.z <= 0.0 {
                    continue;
                }
                let f = material.eval(wi, wo);
                if f.max_element() > 0.0 {
                    let shadow = Ray::new(offset_ray_origin(p, ng, d), d, 0.0, dist);
                    if !self.caster.occluded(&shadow) {
                        // eval includes the shading cosine; e holds the geometric one.
                        let cos_g = ng.dot(d);
                        result += throughput * f * (e / cos_g);
                    }
                }
            }

            // BSDF sampling: continue the path.
            let Some(bs) = material.sample(wi, rng.next_vec2(), rng.next_f32()) else {
                break;
            };
            let d = shading.to_world(bs.wo).normalize();
            if d.dot(ng) * bs.wo.z <= 0.0 {
                break;
            }
            throughput *= bs.weight;
            prev_bsdf_pdf = Some(bs.pdf);
            ray = Ray::new(offset_ray_origin(p, ng, d), d, 0.0, f32::INFINITY);
            depth += 1;

            // Russian roulette (Mitsuba's rule and default depth).
            let tmax = throughput.max_element();
            // Zero or NaN throughput ends the path.
            if tmax.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                break;
            }
            if depth >= RR_DEPTH {
                let q = tmax.min(0.95);
                if rng.next_f32() >= q {
                    break;
                }
                throughput /= q;
            }
        }
        result
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use relight_scene::accel::build_default;
    use relight_scene::camera::Camera;
    use relight_scene::scene::Environment;
    use relight_scene::shapes::uv_sphere;
    use relight_sphere::envmap::EnvMap;

    fn sphere_scene(material: Material, env: EnvMap) -> Scene {
        let mut mesh = uv_sphere(Vec3::ZERO, 1.0, 24, 48);
        mesh.material_ids = vec![0; mesh.indices.len()];
        Scene {
            maps: Default::default(),
            mesh,
            materials: vec![material],
            env: Environment::new(env),
            camera: Camera::look_at([0.0, 0.0, 4.0], [0.0; 3], 40.0, 24, 16),
            objects: Vec::new(),
        }
    }

    #[test]
    fn deterministic_for_a_seed_regardless_of_threads() {
        let scene = sphere_scene(
            Material::GgxPlastic {
                diffuse: Vec3::splat(0.5),
                specular: Vec3::ONE,
                alpha: 0.2,
                ior: 1.49,
            },
            EnvMap::latlong_from_fn(32, 16, |d| Vec3::new(1.0 + d.x, 1.0 + d.y, 1.0 - d.z)),
        );
        let caster = build_default(&scene.mesh);
        let s = PtSettings {
            spp: 4,
            max_depth: 4,
            seed: 3,
            ..Default::default()
        };
        let a = render(
            &scene,
            caster.as_ref(),
            &PtSettings {
                threads: Some(1),
                ..s.clone()
            },
        );
        let b = render(
            &scene,
            caster.as_ref(),
            &PtSettings {
                threads: Some(2),
                ..s.clone()
            },
        );
        assert_eq!(a, b);
        let c = render(&scene, caster.as_ref(), &PtSettings { seed: 4, ..s });
        assert_ne!(a, c);
    }

    #[test]
    fn background_and_depth_semantics() {
        let scene = sphere_scene(
            Material::Lambert {
                albedo: Vec3::splat(0.5),
            },
            EnvMap::constant(Vec3::splat(2.0)),
        );
        let caster = build_default(&scene.mesh);
        let s = PtSettings {
            spp: 2,
            max_depth: 1,
            ..Default::default()
        };
        let img = render(&scene, caster.as_ref(), &s);
        // Corner: environment; centre: the sphere, black at max_depth 1.
        assert!((img.get(0, 0) - Vec3::splat(2.0)).abs().max_element() < 1e-6);
        assert_eq!(img.get(12, 8), Vec3::ZERO);
        let hidden = render(
            &scene,
            caster.as_ref(),
            &PtSettings {
                show_background: false,
                max_depth: 2,
                ..s.clone()
            },
        );
        assert_eq!(hidden.get(0, 0), Vec3::ZERO);
        assert!(hidden.get(12, 8).x > 0.5);
        let none = render(&scene, caster.as_ref(), &PtSettings { max_depth: 0, ..s });
        assert!(none.pixels.iter().all(|p| *p == Vec3::ZERO));
    }

    #[test]
    fn variance_shrinks_with_spp() {
        let scene = sphere_scene(
            Material::Lambert {
                albedo: Vec3::splat(0.8),
            },
            EnvMap::latlong_from_fn(32, 16, |d| Vec3::splat(if d.y > 0.7 { 20.0 } else { 0.1 })),
        );
        let caster = build_default(&scene.mesh);
        let mean_var = |spp| {
            let (_, v) = render_with_variance(
                &scene,
                caster.as_ref(),
                &PtSettings {
                    spp,
                    max_depth: 2,
                    ..Default::default()
                },
            );
            v.pixels.iter().map(|p| p.x as f64).sum::<f64>() / v.pixels.len() as f64
        };
        let (v8, v32) = (mean_var(8), mean_var(32));
        // Variance of the mean scales as 1/spp: 4x fewer, within sampling error of the estimate.
        assert!(v8 > 0.0 && (v8 / v32 - 4.0).abs() < 1.5, "{v8} {v32}");
    }

    #[test]
    fn head_on_pixel_under_constant_light_is_the_directional_albedo() {
        // A convex sphere under a constant environment L, direct lighting only: the pixel at
        // the centre of a very narrow view sees the sphere at normal incidence (within 0.7
        // degrees), so its value is L x albedo(normal incidence) of the material, computed
        // independently by averaging `sample` weights. Checks MIS and the estimator for every
        // material, Blinn-Phong included (which Mitsuba cannot check).
        let l = 1.7f32;
        let mats = [
            Material::Lambert {
                albedo: Vec3::new(0.9, 0.5, 0.2),
            },
            Material::BlinnPhong {
                diffuse: Vec3::splat(0.3),
                specular: Vec3::splat(0.6),
                exponent: 50.0,
            },
            Material::GgxConductor {
                specular: Vec3::new(0.9, 0.7, 0.4),
                alpha: 0.3,
            },
            Material::GgxPlastic {
                diffuse: Vec3::new(0.2, 0.5, 0.8),
                specular: Vec3::ONE,
                alpha: 0.2,
                ior: 1.49,
            },
        ];
        for m in mats {
            let mut scene = sphere_scene(m, EnvMap::constant(Vec3::splat(l)));
            scene.camera = Camera {
                fov_deg: 1.0,
                width: 1,
                height: 1,
                ..scene.camera
            };
            let caster = build_default(&scene.mesh);
            let s = PtSettings {
                spp: 40_000,
                max_depth: 2,
                seed: 5,
                ..Default::default()
            };
            let (img, var) = render_with_variance(&scene, caster.as_ref(), &s);
            let mut rng = Rng::new(99, 0);
            let n = 400_000;
            let mut albedo = Vec3::ZERO;
            for _ in 0..n {
                if let Some(b) = m.sample(Vec3::Z, rng.next_vec2(), rng.next_f32()) {
                    albedo += b.weight / n as f32;
                }
            }
            let want = albedo * l;
            let got = img.get(0, 0);
            // Path tracer's standard error plus a generous allowance for the albedo estimate
            // (importance sampled, relative error well below 0.5%) and the 0.7 degree spread.
            let tol = var.get(0, 0).powf(0.5) * 4.0 + want * 0.01;
            assert!(
                ((got - want).abs() - tol).max_element() <= 0.0,
                "{m:?}: {got} vs {want} +- {tol}"
            );
        }
    }
}
