//! Issue 10: more lobes must never be worse. A small glossy scene with self-shadowing, baked
//! with 1, 2 and 3 direct lobes (the default bake and frame settings), rendered by the frame
//! and compared with relight's own path tracer (direct lighting, the reference that matches
//! Mitsuba 3 to its noise, docs/RESULTS-pathtracer.md), so no Mitsuba is needed.

use super::*;
use crate::compare;
use crate::pathtrace::{self, PtSettings};
use crate::Image;
use relight_bake::sg::{self as bake_sg, SgBakeSettings};
use relight_scene::scene::Scene;
use relight_scene::shapes;

/// A sphere on a floor, both GGX conductors (alpha 0.2 and 0.15), under a sky with two small
/// bright windows (a peaked probe like the real ones: the windows carry most of the light).
fn sphere_scene() -> Scene {
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
        objects: Vec::new(),
    }
}

/// Fig. 3-5 in small: a Lambert box standing between a bright window low in the sky and a
/// glossy GGX conductor floor (alpha 0.2, which the test's 16-texel cube faces resolve;
/// triangles a sixth of the box, about as Fig. 3-5's floor is to its teapot), seen from the
/// other side, so the window's reflection on the floor is cut by the box's shadow.
fn shadowed_highlight_scene() -> Scene {
    let mut mesh = shapes::aabb_box(Vec3::new(-0.3, 0.0, -0.3), Vec3::new(0.3, 0.5, 0.3), 4);
    mesh.append(&shapes::ground_plane(Vec3::ZERO, 2.4, 24), 1);
    let window = Vec3::new(0.0, 0.3, -1.0).normalize();
    let map = EnvMap::latlong_from_fn(128, 64, |d| {
        let sky = Vec3::new(0.3, 0.35, 0.45) * (0.4 + 0.6 * d.y.max(0.0))
            + Vec3::new(0.15, 0.13, 0.1) * (-d.y).max(0.0);
        sky + if d.dot(window) > 0.98 {
            Vec3::new(30.0, 28.0, 24.0)
        } else {
            Vec3::ZERO
        }
    });
    Scene {
        maps: Default::default(),
        mesh,
        materials: vec![
            Material::Lambert {
                albedo: Vec3::splat(0.7),
            },
            Material::GgxConductor {
                specular: Vec3::new(0.6, 0.6, 0.65),
                alpha: 0.2,
            },
        ],
        env: Environment::new(map),
        camera: Camera {
            origin: [0.2, 1.0, 2.6],
            target: [0.0, 0.1, 0.0],
            up: [0.0, 1.0, 0.0],
            fov_deg: 45.0,
            width: 64,
            height: 48,
        },
        objects: Vec::new(),
    }
}

/// Relative RMSE of the frame against the path tracer for 1 to `most` direct lobes baked
/// with `fit`, each bake rendered with every one of `shades` (`errors[s][lobes - 1]`), and
/// the reference's relative noise.
fn errors_by_lobes(
    scene: &Scene,
    fit: bake_sg::SgFitSettings,
    shades: &[ShadeOptions],
    most: usize,
) -> (Vec<Vec<f64>>, f64) {
    let caster = relight_scene::accel::build_default(&scene.mesh);
    let (reference, variance) = reference(scene, caster.as_ref());
    let lighting = SgLighting::new(&scene.env, 3, 128);
    let mut errors = vec![vec![]; shades.len()];
    let mut mask = vec![];
    for lobes in 1..=most {
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
        for (e, &shade) in errors.iter_mut().zip(shades) {
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
            e.push(compare::metrics(&img.image, &reference, Some(&mask)).rel_rmse);
        }
    }
    (errors, noise(&reference, &variance, &mask))
}

/// relight's path tracer, direct light (1,024 spp), and its per-pixel variance.
fn reference(scene: &Scene, caster: &dyn relight_scene::accel::RayCaster) -> (Image, Image) {
    pathtrace::render_with_variance(
        scene,
        caster,
        &PtSettings {
            spp: 1024,
            max_depth: 2,
            seed: 7,
            show_background: false,
            ..PtSettings::default()
        },
    )
}

/// The reference's own relative noise over the masked pixels (standard error of each pixel).
fn noise(reference: &Image, variance: &Image, mask: &[bool]) -> f64 {
    let (mut var, mut sq) = (0f64, 0f64);
    for ((v, p), &m) in variance.pixels.iter().zip(&reference.pixels).zip(mask) {
        if m {
            var += v.element_sum() as f64;
            sq += p.length_squared() as f64;
        }
    }
    (var / sq).sqrt()
}

/// Whether each added lobe is no worse than one lobe fewer: both errors are measured
/// against the same reference, so its noise moves them together; a difference within one
/// reference noise is not a measurable loss.
fn monotone(errors: &[f64], noise: f64) -> bool {
    errors.windows(2).all(|w| w[1] <= w[0] + noise)
}

/// The default bake and frame (lobes matched, views blended linearly, corners by energy):
/// each added lobe is no worse than one lobe fewer. Measured 2026-12-02: 0.305, 0.214, 0.185
/// for 1, 2, 3 lobes, reference noise 0.037; 2026-12-03, after the fitter's Jacobian was
/// written per kernel (same formulas, other rounding, so other flood-fill paths): 0.305,
/// 0.214, 0.210 (the energy frame of 2026-12-01, `ShadeOptions::ENERGY`:
/// 0.307, 0.215, 0.189). The bake options tried in issue 10 fail it (nested lobes with the energy term
/// gave 0.292, 0.338, 0.273); the paper's linear blend gave 0.300, 0.299, 0.301.
#[test]
fn more_direct_lobes_are_never_worse() {
    let (errors, noise) = errors_by_lobes(
        &sphere_scene(),
        Default::default(),
        &[ShadeOptions::default()],
        3,
    );
    let errors = &errors[0];
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
    assert!(monotone(errors, noise), "{errors:?} (noise {noise})");
}

/// The same check with the lobes moved to their moments after the fit
/// (`--lobe-shape moments`, issue 10).
#[test]
fn more_moment_shaped_lobes_are_never_worse() {
    let fit = bake_sg::SgFitSettings {
        lobe_shape: bake_sg::LobeShape::Moments,
        ..Default::default()
    };
    let (errors, noise) = errors_by_lobes(&sphere_scene(), fit, &[ShadeOptions::default()], 3);
    let errors = &errors[0];
    eprintln!("moments: relative RMSE by lobe count {errors:?}, reference noise {noise:.4}");
    assert!(monotone(errors, noise), "{errors:?} (noise {noise})");
}

/// Fig. 3-5 in small ([`shadowed_highlight_scene`]): with the default frame each added lobe
/// is no worse than one fewer. Measured 2026-12-02: 0.366, 0.332, 0.230 for 1, 2, 3 lobes,
/// reference noise 0.036. This small scene does **not** reproduce Fig. 3-5's failure of the
/// energy frame (`ShadeOptions::ENERGY`: 0.351, 0.322, 0.238 here, monotone; 28.5, 61.9,
/// 45.9 % on Fig. 3-5, whose alpha 0.1 floor needs the bake's full 32-texel faces, too slow
/// for a test): it checks monotonicity where a shadow cuts a highlight; the evaluation
/// (`relight eval --method sg`) checks the real scenes.
#[test]
fn shadowed_highlight_more_lobes_are_never_worse() {
    let (errors, noise) = errors_by_lobes(
        &shadowed_highlight_scene(),
        Default::default(),
        &[ShadeOptions::default()],
        3,
    );
    eprintln!(
        "relative RMSE by lobe count {:?}, reference noise {noise:.4}",
        errors[0]
    );
    assert!(
        monotone(&errors[0], noise),
        "default frame: {:?} (noise {noise})",
        errors[0]
    );
}

/// GGX-kernel lobes in the half-vector domain, nested (`--lobe-order nested`, not the
/// default), through their default frame (`ShadeOptions::default_for`: one lobe blended
/// linearly; two or more views by energy, corners linear, unmatched): each added lobe, up to
/// four, is no worse than one fewer within the reference's noise, on both small scenes.
/// Measured 2026-12-04: sphere 0.0750, 0.0808, 0.1070, 0.1249 (noise 0.0368), shadowed
/// highlight 0.2102, 0.2143, 0.2239, 0.2516 (noise 0.0363). Each step is within one noise,
/// **but the trend is upward**: four nested lobes are 1.4 and 1.1 noises worse than one, so
/// they fail the end-to-end bound (four lobes within one noise of one) that the default order
/// meets ([`default_half_vector_lobes_are_never_worse`]); that drift is why nested is not the
/// default. The cause (the joint refinement moves the first lobe) is in
/// docs/notes/2026-11-to-12-development-log.md §8, session 32.
#[test]
fn nested_half_vector_lobes_step_within_the_noise() {
    half_vector_lobes_are_never_worse(bake_sg::LobeOrder::Nested, false);
}

/// Half-vector GGX lobes fitted in `order`, 1-4 of them, on both small scenes through their
/// default frame (`ShadeOptions::default_for`: one lobe the paper's, two or more the nested
/// frame): each added lobe no worse than one fewer within the reference's noise. Every lobe
/// count is printed through both frames.
/// With `bound_drift`, four lobes are also no worse than one by more than the noise.
fn half_vector_lobes_are_never_worse(order: bake_sg::LobeOrder, bound_drift: bool) {
    let fit = bake_sg::SgFitSettings {
        lobe_kernel: bake_sg::SgKernel::Ggx,
        lobe_domain: bake_sg::SgDomain::HalfVector,
        lobe_order: order,
        ..Default::default()
    };
    let frame = |lobes| ShadeOptions::default_for(bake_sg::SgDomain::HalfVector, order, lobes);
    assert_eq!(frame(1), ShadeOptions::PAPER);
    let more = frame(2);
    assert_eq!((frame(3), frame(4)), (more, more));
    for (name, scene) in [
        ("sphere", sphere_scene()),
        ("shadowed highlight", shadowed_highlight_scene()),
    ] {
        let (errors, noise) = errors_by_lobes(&scene, fit, &[ShadeOptions::PAPER, more], 4);
        let default = [errors[0][0], errors[1][1], errors[1][2], errors[1][3]];
        eprintln!(
            "{name}, {order:?}: relative RMSE by lobe count, default frame {default:?}; linear {:?}, the frame of two or more {:?}; reference noise {noise:.4}",
            errors[0], errors[1]
        );
        assert!(
            monotone(&default, noise),
            "{name}: {default:?} (noise {noise})"
        );
        // Steps each within the noise may still add up: the last count no worse than one
        // lobe by more than one noise either (nested lobes fail this, see
        // `nested_half_vector_lobes_step_within_the_noise`).
        assert!(
            !bound_drift || default[3] <= default[0] + noise,
            "{name}: four lobes {} drift above one lobe {} by more than the noise {noise}: {default:?}",
            default[3],
            default[0]
        );
    }
}

/// The default half-vector lobes ([`bake_sg::LobeSetting::HALF_VECTOR_GGX`], additive: each
/// further lobe fitted alone to what the earlier ones leave, which stay put), through their
/// default frame (`ShadeOptions::ADDITIVE_HALF_VECTOR` from two lobes): each added lobe, up to four, no worse than one fewer within the reference's noise, on
/// both small scenes. Measured 2026-12-05: sphere 0.0750, 0.0753, 0.0734, 0.0733 (noise
/// 0.0368; nested: up to 0.1249), shadowed highlight 0.2102, 0.2179, 0.2198, 0.2204 (noise
/// 0.0363; nested: 0.2143, 0.2239, 0.2516): after the second lobe flat, where nested lobes
/// keep drifting upward. Session 36's additive fit (the residual of slot 1 before its
/// peak was bounded, no gate) through the nested frame gave 0.2292, 0.2313, 0.2320 on the
/// shadowed highlight (docs/notes/2026-11-to-12-development-log.md §8, session 37).
/// Also asserted: four lobes no worse than one by more than the noise (measured 2026-12-07 as
/// above: 0.0733 and 0.2204 against 0.0750 and 0.2102).
#[test]
fn default_half_vector_lobes_are_never_worse() {
    let default = bake_sg::LobeSetting::HALF_VECTOR_GGX;
    assert_eq!(default.order, bake_sg::LobeOrder::Additive);
    half_vector_lobes_are_never_worse(default.order, true);
}

/// Issue 10 item 3: one lobe of the GGX-shaped kernel (`--lobe-kernel ggx`,
/// `relight_sphere::sg_kernel`) on the GGX sphere scene, against one Gaussian lobe: no worse
/// by more than the reference's noise. Measured 2026-12-03: 0.317 against 0.305, noise 0.037.
/// The kernel does not win here: this 16-texel scene's lobes sit at the sharpness bound
/// (median 64), so the lobe's tails are not what limits it. The shape's gain is tested on the
/// fit itself (`relight_sphere::sg_fit` tests,
/// `one_ggx_kernel_lobe_fits_a_ggx_lobe_better_than_one_gaussian`) and measured on the
/// evaluation's scenes (docs/notes/2026-11-to-12-development-log.md §8). A frame that read the kernel's lobes wrongly
/// (as Gaussians, or with the Gaussian's integral) is several noises off.
#[test]
fn one_ggx_kernel_lobe_is_no_worse_than_one_gaussian() {
    let scene = sphere_scene();
    let caster = relight_scene::accel::build_default(&scene.mesh);
    let (reference, variance) = reference(&scene, caster.as_ref());
    let lighting = SgLighting::new(&scene.env, 3, 128);
    let render = |kernel: bake_sg::SgKernel| {
        let bake = one_lobe_bake(
            &scene,
            caster.as_ref(),
            bake_sg::SgFitSettings {
                lobe_kernel: kernel,
                ..Default::default()
            },
        );
        let (img, _) = SgRenderer::new(&scene.mesh, &bake).render(
            &lighting,
            &scene.camera,
            None,
            &RasterOptions { supersample: 4 },
        );
        (img, bake)
    };
    let (gauss, _) = render(bake_sg::SgKernel::Gaussian);
    let mask = gauss.full_coverage_mask();
    let err = |img: &Rendered| compare::metrics(&img.image, &reference, Some(&mask)).rel_rmse;
    let (ggx, mut bake) = render(bake_sg::SgKernel::Ggx);
    let noise = noise(&reference, &variance, &mask);
    let (eg, ek) = (err(&gauss), err(&ggx));
    eprintln!("one lobe: gaussian {eg:.4}, ggx kernel {ek:.4}, reference noise {noise:.4}");
    assert!(
        ek <= eg + noise,
        "ggx kernel {ek} gaussian {eg} noise {noise}"
    );
    // Control: the same lobes read as Gaussians.
    bake.kernel = relight_sphere::sg_kernel::LobeKernel::Gaussian;
    let (wrong, _) = SgRenderer::new(&scene.mesh, &bake).render(
        &lighting,
        &scene.camera,
        None,
        &RasterOptions { supersample: 4 },
    );
    let ew = err(&wrong);
    eprintln!("control, the kernel's lobes read as Gaussians: {ew:.4}");
    assert!(
        ew > ek + noise,
        "control {ew} not off by the noise {noise} ({ek})"
    );
}

/// A bake of `scene` with one direct lobe (16 x 16 faces, no indirect lobe, SH order 3) and
/// the fit settings `fit`.
fn one_lobe_bake(
    scene: &Scene,
    caster: &dyn relight_scene::accel::RayCaster,
    fit: bake_sg::SgFitSettings,
) -> SgBake {
    let settings = SgBakeSettings {
        direct_res: 16,
        direct_lobes: 1,
        indirect_lobes: 0,
        diffuse_order: 3,
        fit,
        ..SgBakeSettings::default()
    };
    bake_sg::bake(&scene.mesh, &scene.materials, None, caster, &settings).unwrap()
}

/// Issue 10 item 3: one GGX-kernel lobe in the half-vector domain (`--lobe-domain
/// half-vector`) against one in the light domain, both through the frame (prefiltered chain,
/// the tabulated Gaussians of `relight_sphere::half_vector` for the former). Control: the
/// half-vector bake's lobes read as light-domain lobes.
#[test]
fn one_half_vector_lobe_is_no_worse_than_one_light_domain_lobe() {
    let scene = sphere_scene();
    let caster = relight_scene::accel::build_default(&scene.mesh);
    let (reference, variance) = reference(&scene, caster.as_ref());
    let lighting = SgLighting::new(&scene.env, 3, 128);
    let opts = RasterOptions { supersample: 4 };
    let render = |domain: bake_sg::SgDomain| {
        let bake = one_lobe_bake(
            &scene,
            caster.as_ref(),
            bake_sg::SgFitSettings {
                lobe_kernel: bake_sg::SgKernel::Ggx,
                lobe_domain: domain,
                ..Default::default()
            },
        );
        let (img, _) =
            SgRenderer::new(&scene.mesh, &bake).render(&lighting, &scene.camera, None, &opts);
        (img, bake)
    };
    let (light, _) = render(bake_sg::SgDomain::Light);
    let mask = light.full_coverage_mask();
    let err = |img: &Rendered| compare::metrics(&img.image, &reference, Some(&mask)).rel_rmse;
    let (half, mut bake) = render(bake_sg::SgDomain::HalfVector);
    let noise = noise(&reference, &variance, &mask);
    let (el, eh) = (err(&light), err(&half));
    eprintln!("one ggx-kernel lobe: light domain {el:.4}, half-vector domain {eh:.4}, reference noise {noise:.4}");
    assert!(
        eh <= el + noise,
        "half-vector {eh} light {el} noise {noise}"
    );
    // The fast path against the slow reference of the same lobes (each term summed over the
    // map's texels): the tabulated Gaussians and the prefiltered chain.
    let slow = SgRenderer::new(&scene.mesh, &bake).render_reference(
        &lighting,
        &scene.env,
        &scene.camera,
        &opts,
    );
    let es = compare::metrics(&half.image, &slow.image, Some(&mask)).rel_rmse;
    eprintln!("half-vector frame against its texel-sum reference: {es:.4}");
    assert!(es < 0.05, "{es}");
    bake.domain = bake_sg::SgDomain::Light;
    let (wrong, _) =
        SgRenderer::new(&scene.mesh, &bake).render(&lighting, &scene.camera, None, &opts);
    let ew = err(&wrong);
    eprintln!("control, the half-vector lobes read in the light domain: {ew:.4}");
    assert!(
        ew > eh + noise,
        "control {ew} not off by the noise {noise} ({eh})"
    );
}
