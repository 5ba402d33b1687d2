//! Issue 10: more lobes must never be worse. A small glossy scene with self-shadowing, baked
//! with 1, 2 and 3 direct lobes (the default bake and frame settings), rendered by the frame
//! and compared with relight's own path tracer (direct lighting, the reference that matches
//! Mitsuba 3 to its noise, docs/RESULTS-pathtracer.md), so no Mitsuba is needed.

use super::*;
use crate::compare;
use crate::pathtrace::{self, PtSettings};
use relight_bake::sg::{self as bake_sg, SgBakeSettings};
use relight_scene::scene::Scene;
use relight_scene::shapes;

/// A sphere on a floor, both GGX conductors (alpha 0.2 and 0.15), under a sky with two small
/// bright windows (a peaked probe like the real ones: the windows carry most of the light).
fn scene() -> Scene {
    let mut mesh = shapes::uv_sphere(Vec3::new(0.0, 0.5, 0.0), 0.5, 10, 20);
    mesh.append(&shapes::ground_plane(Vec3::ZERO, 3.0, 8), 1);
    let windows = [
        (
            Vec3::new(0.6, 0.5, -0.62).normalize(),
            Vec3::new(40.0, 36.0, 30.0),
        ),
        (
            Vec3::new(-0.7, 0.35, 0.62).normalize(),
            Vec3::new(12.0, 14.0, 18.0),
        ),
    ];
    let map = EnvMap::latlong_from_fn(128, 64, |d| {
        let sky = Vec3::new(0.25, 0.35, 0.5) * (0.6 + 0.6 * d.y.max(0.0))
            + Vec3::new(0.2, 0.17, 0.12) * (-d.y).max(0.0);
        windows.iter().fold(sky, |acc, (w, c)| {
            acc + if d.dot(*w) > 0.985 { *c } else { Vec3::ZERO }
        })
    });
    Scene {
        maps: Default::default(),
        mesh,
        materials: vec![
            Material::GgxConductor {
                specular: Vec3::new(0.9, 0.8, 0.7),
                alpha: 0.2,
            },
            Material::GgxConductor {
                specular: Vec3::new(0.6, 0.6, 0.65),
                alpha: 0.15,
            },
        ],
        env: Environment::new(map),
        camera: Camera {
            origin: [0.3, 1.3, 2.4],
            target: [0.0, 0.35, 0.0],
            up: [0.0, 1.0, 0.0],
            fov_deg: 45.0,
            width: 64,
            height: 48,
        },
    }
}

/// Relative RMSE of the frame against the path tracer for 1, 2 and 3 direct lobes baked
/// with `fit` and rendered with `shade`, and the reference's relative noise.
fn errors_by_lobes(fit: bake_sg::SgFitSettings, shade: ShadeOptions) -> (Vec<f64>, f64) {
    let scene = scene();
    let caster = relight_scene::accel::build_default(&scene.mesh);
    let (reference, variance) = pathtrace::render_with_variance(
        &scene,
        caster.as_ref(),
        &PtSettings {
            spp: 1024,
            max_depth: 2,
            seed: 7,
            show_background: false,
            ..PtSettings::default()
        },
    );
    let lighting = SgLighting::new(&scene.env, 3, 128);
    let mut errors = vec![];
    let mut mask = vec![];
    for lobes in 1..=3 {
        let settings = SgBakeSettings {
            // 16 texels per face resolve these lobes (sharpness up to 64, a GGX alpha of
            // about 0.1 seen head-on) and keep the test fast.
            direct_res: 16,
            direct_lobes: lobes,
            indirect_lobes: 0,
            diffuse_order: 3,
            fit,
            ..SgBakeSettings::default()
        };
        let bake = bake_sg::bake(
            &scene.mesh,
            &scene.materials,
            None,
            caster.as_ref(),
            &settings,
        )
        .unwrap();
        let r = SgRenderer::new(&scene.mesh, &bake).with_options(shade);
        let (img, _) = r.render(
            &lighting,
            &scene.camera,
            None,
            &RasterOptions { supersample: 4 },
        );
        if mask.is_empty() {
            mask = img.full_coverage_mask();
        }
        errors.push(compare::metrics(&img.image, &reference, Some(&mask)).rel_rmse);
    }
    // The reference's own relative noise over the same pixels (standard error of each pixel).
    let (mut var, mut sq) = (0f64, 0f64);
    for ((v, p), &m) in variance.pixels.iter().zip(&reference.pixels).zip(&mask) {
        if m {
            var += v.element_sum() as f64;
            sq += p.length_squared() as f64;
        }
    }
    (errors, (var / sq).sqrt())
}

/// The default bake and frame (energy blend, lobe matching): each added lobe is no worse
/// than one lobe fewer. Measured 2026-12-01: 0.307, 0.215, 0.189 for 1, 2, 3 lobes, reference
/// noise 0.037. The bake options tried in issue 10 fail it (nested lobes with the energy term
/// gave 0.292, 0.338, 0.273); the paper's linear blend gave 0.300, 0.299, 0.301.
#[test]
fn more_direct_lobes_are_never_worse() {
    let (errors, noise) = errors_by_lobes(Default::default(), ShadeOptions::default());
    eprintln!("relative RMSE by lobe count {errors:?}, reference noise {noise:.4}");
    // Lobes must also pay for themselves: the measured gain from one to three lobes (0.12)
    // is over three times the reference noise, so a frame that merely ties (the paper's
    // blend: 0.300 -> 0.301) fails.
    assert!(
        errors[2] < errors[0] - noise,
        "3 lobes {} not better than 1 lobe {} by the noise {noise}",
        errors[2],
        errors[0]
    );
    for k in 0..2 {
        // Both errors are measured against the same reference, so its noise moves them
        // together; a difference within one reference noise is not a measurable loss.
        assert!(
            errors[k + 1] <= errors[k] + noise,
            "{} lobes: {} > {} lobes: {} + noise {noise}",
            k + 2,
            errors[k + 1],
            k + 1,
            errors[k]
        );
    }
}

/// The same check with the lobes moved to their moments after the fit
/// (`--lobe-shape moments`, issue 10).
#[test]
fn more_moment_shaped_lobes_are_never_worse() {
    let fit = bake_sg::SgFitSettings {
        lobe_shape: bake_sg::LobeShape::Moments,
        ..Default::default()
    };
    let (errors, noise) = errors_by_lobes(fit, ShadeOptions::default());
    eprintln!("moments: relative RMSE by lobe count {errors:?}, reference noise {noise:.4}");
    for k in 0..2 {
        // As above: a difference within one reference noise is not a measurable loss.
        assert!(
            errors[k + 1] <= errors[k] + noise,
            "{} lobes: {} > {} lobes: {} + noise {noise}",
            k + 2,
            errors[k + 1],
            k + 1,
            errors[k]
        );
    }
}
