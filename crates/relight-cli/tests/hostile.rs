//! Hostile command lines: every value that drives an allocation or a computation is
//! checked before any work, and nonsense is refused with the option named (no abort, no
//! black image with exit 0, no partial output).

use std::path::Path;
mod common;
use common::{assert_clean_failure, relight, stderr, tmpdir};

fn scene(dir: &Path) -> std::path::PathBuf {
    let p = dir.join("s.json");
    std::fs::write(
        &p,
        r#"{"shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "rings": 8}],
            "environment": {"type": "constant", "radiance": [1, 1, 1]},
            "camera": {"origin": [0, 0, 4], "target": [0, 0, 0], "up": [0, 1, 0],
                       "fov_deg": 40, "width": 16, "height": 12}}"#,
    )
    .unwrap();
    p
}

#[test]
fn sizes_and_values_are_refused_with_the_option_named() {
    let d = tmpdir("hostile", "values");
    let sc = scene(&d);
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let b = d.join("b.relight");
    let o = relight(&["bake", &s(&sc), "-o", &s(&b), "--samples", "16"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let never_b = d.join("never.relight");
    let never = d.join("never.exr");
    // {s} the scene, {b} the bundle, {nb} a bundle and {ne} an image never to be written.
    let cases: [(&str, &str, &Path); 10] = [
        (
            "bake {s} -o {nb} --samples 4000000000",
            "samples 4000000000",
            &never_b,
        ),
        ("bake {s} -o {nb} --threads 0", "--threads 0", &never_b),
        (
            "bake {s} -o {nb} --threads 20000",
            "--threads 20000",
            &never_b,
        ),
        (
            "render {b} -o {ne} --width 16384 --height 16384",
            "16384 x 16384",
            &never,
        ),
        (
            "render {b} -o {ne} --env-scale -1",
            "--env-scale -1",
            &never,
        ),
        (
            "render {b} -o {ne} --env-scale inf",
            "--env-scale inf",
            &never,
        ),
        (
            "render {b} -o {ne} --rotate-env NaN",
            "--rotate-env NaN",
            &never,
        ),
        ("render {b} -o {ne} --window sloan:inf", "sloan:inf", &never),
        (
            "render {b} -o {ne} --supersample 0",
            "supersample 0",
            &never,
        ),
        ("reference {s} -o {ne} --spp 0", "--spp 0", &never),
    ];
    for (line, want, out) in cases {
        let args: Vec<String> = line
            .split(' ')
            .map(|w| match w {
                "{s}" => s(&sc),
                "{b}" => s(&b),
                "{nb}" => s(&never_b),
                "{ne}" => s(&never),
                w => w.to_string(),
            })
            .collect();
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        assert_clean_failure(&relight(&args), want, out);
    }
}

#[test]
fn huge_but_legal_radiance_is_refused_not_printed_as_inf() {
    let d = tmpdir("hostile", "huge");
    let env = d.join("huge.exr");
    // 3.4e38 everywhere: finite, but its SH projection and the decomposition overflow.
    relight_scene::io::image::write_exr(&env, 8, 4, &[glam::Vec3::splat(3.4e38); 32]).unwrap();
    let o = relight(&["project", env.to_str().unwrap()]);
    assert!(
        !o.status.success() && stderr(&o).contains("not finite"),
        "{}",
        stderr(&o)
    );
    let o = relight(&["decompose", env.to_str().unwrap()]);
    assert!(
        !o.status.success() && stderr(&o).contains("huge.exr"),
        "{}",
        stderr(&o)
    );
    // compare with a NaN pixel: refused, not "RMSE NaN".
    let (a, b) = (d.join("a.exr"), d.join("b.exr"));
    let mut px = vec![glam::Vec3::ONE; 16];
    relight_scene::io::image::write_exr(&b, 4, 4, &px).unwrap();
    px[5] = glam::Vec3::new(f32::NAN, 1.0, 1.0);
    exr::prelude::write_rgb_file(&a, 4, 4, |x, y| {
        let c = px[y * 4 + x];
        (c.x, c.y, c.z)
    })
    .unwrap();
    let o = relight(&["compare", a.to_str().unwrap(), b.to_str().unwrap()]);
    assert!(
        !o.status.success() && stderr(&o).contains("not finite"),
        "{}",
        stderr(&o)
    );
}
