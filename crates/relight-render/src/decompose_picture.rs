//! The picture of an environment decomposition (`relight decompose -o`): four latlong panels
//! stacked, the environment, its SH part, the residual (environment - SH, negative parts
//! black) and SH + lights drawn as caps with their outlines, each labelled.

use crate::text::draw_label;
use crate::tonemap::ToneMap;
use relight_sphere::decompose::Decomposition;
use relight_sphere::{latlong, sh, EnvMap, Vec2};

/// Reinhard with the exposure that maps the map's mean luminance to 0.5.
pub fn auto_tonemap(map: &EnvMap) -> ToneMap {
    let mean = map.average_luminance();
    ToneMap::Reinhard {
        exposure: if mean > 0.0 { 1.0 / mean } else { 1.0 },
    }
}

/// The picture, `w` pixels wide (each panel `w x w/2`). Returns the sRGB pixels, row-major,
/// `w` wide and `2 w` high.
pub fn picture(map: &EnvMap, d: &Decomposition, w: usize, tm: &ToneMap) -> Vec<[u8; 3]> {
    let h = w / 2;
    let mut px = vec![[0u8; 3]; w * 4 * h];
    let pixel_angle = std::f32::consts::PI / h as f32;
    let labels = [
        "environment",
        "SH part",
        "residual (environment - SH)",
        "SH part + lights",
    ];
    for j in 0..h {
        for i in 0..w {
            let uv = Vec2::new((i as f32 + 0.5) / w as f32, (j as f32 + 0.5) / h as f32);
            let dir = latlong::uv_to_dir(uv);
            let env = map.eval(dir);
            let shv = sh::eval_rgb(&d.sh, dir);
            let panels = [env, shv, env - shv, d.radiance(dir)];
            for (k, v) in panels.iter().enumerate() {
                px[(k * h + j) * w + i] = tm.pixel_srgb8(*v);
            }
            // Cap outlines and centres on the last panel.
            for l in &d.lights {
                let a = l.dir.dot(dir).clamp(-1.0, 1.0).acos();
                if (a - l.cap_radius).abs() < pixel_angle || a < 1.5 * pixel_angle {
                    px[(3 * h + j) * w + i] = [255, 0, 255];
                }
            }
        }
    }
    for (k, text) in labels.iter().enumerate() {
        draw_label(&mut px, w, 4, k * h + 4, 1 + w / 512, text);
    }
    px
}

#[cfg(test)]
mod tests {
    use super::*;
    use relight_sphere::decompose::{sky_with_discs, DecomposeSettings, Decomposer};
    use relight_sphere::Vec3;

    #[test]
    fn the_light_is_outlined_on_the_last_panel_only() {
        // Low in the sky (20 degrees), away from the panels' labels in their top-left corner.
        let sun = Vec3::new(0.3, 0.35, -0.8).normalize();
        let map = sky_with_discs(32, &[(sun, 3.0, Vec3::splat(300.0))]);
        let s = DecomposeSettings::default();
        let d = Decomposer::new(&s, map.layout(), map.width(), map.height())
            .unwrap()
            .run(&map)
            .unwrap();
        assert_eq!(d.lights.len(), 1);
        let w = 128;
        let px = picture(&map, &d, w, &auto_tonemap(&map));
        assert_eq!(px.len(), w * 2 * w);
        let magenta = |k: usize| {
            (k * w * w / 2..(k + 1) * w * w / 2)
                .filter(|&i| px[i] == [255, 0, 255])
                .count()
        };
        assert!(magenta(3) > 10, "{}", magenta(3));
        assert_eq!(magenta(0) + magenta(1) + magenta(2), 0);
    }
}
