//! The vMF transfer slices over the paper's Blinn-Phong exponents (Laurijssen & Dutré 2009,
//! Table 1: 4 to 128), on a plane with a Lambert box beside the point: the eq. 9 glossy lobe
//! of the material, the slice's class integrals, and how well one lobe per class renders a
//! vMF light compared with the slice's own samples and with three EM lobes per class.
//!
//! `cargo run --release -p relight-bake --example vmf_slice_table`

use glam::Vec3;
use relight_bake::vmf::slice::{trace_slice, SliceScene, SliceSettings, SurfacePoint};
use relight_bake::vmf::{MaterialLobes, PathClass};
use relight_scene::accel::build_default;
use relight_scene::material::Material;
use relight_scene::shapes::{aabb_box, ground_plane};
use relight_sphere::vmf::{inner_product, EmOptions, KappaEstimate, VmfLobe};
use relight_sphere::warp::Frame;
use std::time::Instant;

fn main() {
    let mut mesh = ground_plane(Vec3::ZERO, 4.0, 2);
    mesh.material_ids = vec![0; mesh.indices.len()];
    let mut b = aabb_box(Vec3::new(0.2, 0.0, -0.5), Vec3::new(0.8, 0.6, 0.5), 1);
    b.material_ids = vec![0; b.indices.len()];
    mesh.append(&b, 1);
    let caster = build_default(&mesh);
    let ambient = Vec3::splat(0.2);
    let light = VmfLobe::new(
        Vec3::new(-0.6, 0.7, 0.2).normalize(),
        20.0,
        Vec3::splat(6.0),
    );
    let radiance = |d: Vec3| ambient + light.eval(d);
    let render = |lobes: &mut dyn Iterator<Item = &VmfLobe>| -> Vec3 {
        lobes
            .map(|l| l.amplitude * ambient + inner_product(l, &light))
            .sum()
    };
    let settings = SliceSettings {
        paths: 8192,
        max_bounces: 1,
        ..Default::default()
    };
    let view_world = Vec3::new(0.6, 0.7, -0.2).normalize();
    let view = Frame::from_normal(Vec3::Y).to_local(view_world);
    println!(
        "view (world) {view_world}, light axis {}, kappa 20",
        light.axis
    );
    println!(
        "{:>4} {:>9} {:>8} | {:>7} {:>7} {:>7} | {:>8} {:>8} {:>8} | {:>7} {:>7} | {:>6}",
        "n",
        "eq9 kappa",
        "eq9 alb",
        "direct",
        "ind D",
        "ind G",
        "samples",
        "1 lobe",
        "3 lobes",
        "gap 1",
        "gap 3",
        "ms"
    );
    for n in [4.0f32, 16.0, 32.0, 64.0, 128.0] {
        let m = Material::BlinnPhong {
            diffuse: Vec3::splat(0.3),
            specular: Vec3::splat(0.6),
            exponent: n,
        };
        let mats = relight_bake::sg::transport::vertex_materials(&mesh, &[m, m]);
        let scene = SliceScene {
            mesh: &mesh,
            caster: caster.as_ref(),
            vertex_materials: &mats,
        };
        let eq9 = MaterialLobes::fit(&m, view, settings.material_samples);
        let point = SurfacePoint {
            position: Vec3::ZERO,
            normal: Vec3::Y,
            geometric_normal: Vec3::Y,
            material: m,
        };
        let t = Instant::now();
        let samples = trace_slice(&scene, &point, view, &settings, 0, 0);
        let slice = samples.estimate(KappaEstimate::Banerjee, settings.kappa_max);
        let ms = t.elapsed().as_secs_f64() * 1e3;
        let mc: Vec3 = samples
            .classes
            .iter()
            .flatten()
            .flatten()
            .map(|w| w.weight * radiance(w.dir))
            .sum();
        let one = render(&mut slice.lobes.iter().flatten());
        let fits = samples.fit_em_nested(
            3,
            &EmOptions {
                kappa_max: settings.kappa_max,
                ..Default::default()
            },
        );
        let three = render(
            &mut fits
                .iter()
                .flatten()
                .filter_map(|f| f.last())
                .flat_map(|f| f.lobes.iter()),
        );
        println!(
            "{n:>4} {:>9.1} {:>8.3} | {:>7.3} {:>7.3} {:>7.3} | {:>8.3} {:>8.3} {:>8.3} | {:>6.1}% {:>6.1}% | {ms:>6.1}",
            eq9.glossy.kappa,
            eq9.integral().x,
            slice.class_integral(PathClass::Direct).x,
            slice.class_integral(PathClass::IndirectDiffuse).x,
            slice.class_integral(PathClass::IndirectGlossy).x,
            mc.x,
            one.x,
            three.x,
            100.0 * (one.x - mc.x) / mc.x,
            100.0 * (three.x - mc.x) / mc.x,
        );
    }
}
