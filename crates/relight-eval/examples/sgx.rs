//! Scratch experiments (issue 10): render an sg bundle with frame variants against a Mitsuba
//! reference folder. Not part of the project; deleted before merging.

use glam::Vec3;
use relight_eval::reference::{coverage_mask, mean_image};
use relight_method::Baked;
use relight_render::compare;
use relight_render::raster::RasterOptions;
use relight_render::shade_sg::{LobeBlend, SgLighting, SgRenderer, ShadeOptions};
use relight_scene::scene_file::SceneDesc;
use std::path::PathBuf;

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let scene_path = PathBuf::from(&a[1]);
    let bundle = PathBuf::from(&a[2]);
    let refdir = PathBuf::from(&a[3]);
    let refname = a.get(4).cloned().unwrap_or("mitsuba".into());
    let desc = SceneDesc::read(&scene_path).unwrap();
    let scene = desc.build(&scene_path).unwrap();
    let Baked::Sg(sg) = relight_method::read_any(&bundle).unwrap() else {
        panic!()
    };
    let r1 = relight_render::read_image(&refdir.join(format!("{refname}_s1.exr"))).unwrap();
    let r2 = relight_render::read_image(&refdir.join(format!("{refname}_s2.exr"))).unwrap();
    let reference = mean_image(&r1, &r2);
    let mask = coverage_mask(&scene);
    let noise = compare::metrics(&r1, &r2, Some(&mask)).rel_rmse / 2.0;
    println!("reference noise {:.2} %", 100.0 * noise);
    let bake = &sg.bake;
    println!(
        "flips {} fit error {:?}",
        bake.stats.flips, bake.stats.mean_relative_error
    );
    // Lobe statistics of the direct component.
    let d = &bake.direct;
    if d.lobe_count > 1 {
        let n = d.lobe_count;
        let mut share = vec![0f64; n];
        let mut cnt = 0usize;
        let mut weak = 0usize;
        let mut at_max = vec![0usize; n];
        for c in d.lobes.chunks_exact(n) {
            let e: Vec<f32> = c
                .iter()
                .map(|l| l.amplitude.element_sum() * relight_sphere::sg::unit_integral(l.sharpness))
                .collect();
            let t: f32 = e.iter().sum();
            if t <= 0.0 {
                continue;
            }
            cnt += 1;
            for k in 0..n {
                share[k] += (e[k] / t) as f64;
                if c[k].sharpness > 255.0 {
                    at_max[k] += 1;
                }
            }
            if e.iter().cloned().fold(f32::MAX, f32::min) < 0.05 * t {
                weak += 1;
            }
        }
        println!(
            "lobe energy shares {:?}; weakest lobe < 5 %: {:.1} %; at lambda_max {:?}",
            share.iter().map(|s| s / cnt as f64).collect::<Vec<_>>(),
            100.0 * weak as f64 / cnt as f64,
            at_max
        );
    }
    let variants: Vec<&str> = a[5..].iter().map(|s| s.as_str()).collect();
    let order = bake.diffuse.order;
    let eye = Vec3::from(scene.camera.origin);
    let _ = eye;
    for v in variants {
        let mut opts = ShadeOptions::default();
        let mut size = 128;
        for part in v.split('+') {
            match part {
                "energy" => opts.blend = LobeBlend::Energy,
                "match" => opts.match_lobes = true,
                "p256" => size = 256,
                "base" => {}
                x => panic!("{x}"),
            }
        }
        let lighting = SgLighting::new(&scene.env, order, size);
        let r = SgRenderer::new(&scene.mesh, bake).with_options(opts);
        let t = std::time::Instant::now();
        let (img, _) = r.render(
            &lighting,
            &scene.camera,
            None,
            &RasterOptions { supersample: 4 },
        );
        let m = compare::metrics(&img.image, &reference, Some(&mask));
        println!(
            "{v:24} rel RMSE {:6.2} %  mean abs lum {:.4}  ({:.0} ms)",
            100.0 * m.rel_rmse,
            m.mean_abs_lum_err,
            t.elapsed().as_secs_f64() * 1e3
        );
        let out = bundle.with_extension(format!("{}.exr", v.replace('+', "_")));
        relight_render::write_image(
            &out,
            &img.image,
            &relight_render::tonemap::ToneMap::Linear { exposure: 1.0 },
        )
        .unwrap();
    }
}
