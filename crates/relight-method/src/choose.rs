//! The default method: which methods render which materials, the method `relight bake`
//! chooses from a scene's materials, and the method `relight render` shows an `sh` bake with.
//!
//! # What each method renders
//! - `sh` and `hybrid` transfer diffuse light only (Sloan et al. 2002): a material's
//!   view-dependent lobe is dropped (a GGX conductor is black, a GGX plastic shows its base).
//! - `sg` (Green et al. 2006) and `cuts` (Cheslack-Postava et al. 2008) render every material;
//!   only `cuts` applies texture and normal maps, since it evaluates materials per pixel.
//! - `vmf` (Laurijssen & Dutré 2009) renders every isotropic material; it refuses Ward, whose
//!   frame follows a tangent.
//!
//! # The rule ([`choose_bake_method`])
//! 1. A material with texture or normal maps: `cuts`, the only method that applies them.
//! 2. Every material diffuse: `sh`, the cheapest method that renders them exactly as they are.
//! 3. Otherwise (a glossy material): [`GLOSSY_DEFAULT`] (the figures that chose it are on it).
//!
//! # The render of an `sh` bake ([`choose_frame_method`])
//! Under an environment with a dominant light, `sh` rings: the truncated SH series of a sun
//! overshoots and goes negative, so the ground shows negative light. `hybrid` (Gerhards' thesis,
//! ch. 4) extracts the bright lights from the environment and renders them with shadow maps,
//! leaving a smooth SH remainder: an `sh` bake is shown with `hybrid` when the decomposition
//! extracts a light, and with `sh` otherwise (then the two are the same picture, and `sh`
//! is cheaper).

use crate::hybrid::{decompose_env, HybridSettings};
use crate::{BakeKind, Baked, MethodError, MethodKind};
use relight_scene::material::maps::SceneMaps;
use relight_scene::material::Material;
use relight_scene::scene::Environment;
use relight_scene::scene_file::{shape_label, SceneDesc};

/// The method `relight bake` chooses for a scene with a glossy material (rule 3 of the module
/// docs): `cuts`. Each method baked with its defaults and rendered with its defaults, relative
/// RMSE against `relight reference` at 256 spp (bake seconds on a loaded 2-core machine):
///
/// | scene | sg | cuts | vmf |
/// |---|---|---|---|
/// | `sky_spheres.json` (GGX conductor, sky with a sun) | 17.7 % (413 s) | 17.0 % (27 s) | 52.1 % (181 s) |
/// | `sg_conductor_stpeters.json` (GGX conductor) | 15.3 % (759 s) | 27.1 % (34 s) | 28.1 % (195 s) |
/// | `vmf_glossy.json` (Blinn-Phong, sky with a sun) | 23.1 % (93 s) | 15.1 % (5 s) | 25.8 % (37 s) |
///
/// `cuts` is closest on two scenes of three (`sg` wins the conductor under St Peter's many small
/// windows), bakes 10 to 20 times faster than `sg`, and renders every material and texture
/// map.
pub const GLOSSY_DEFAULT: MethodKind = MethodKind::Cuts;

/// A method and why it was chosen (one line for the user).
#[derive(Clone, Debug, PartialEq)]
pub struct Choice {
    /// The method.
    pub method: MethodKind,
    /// Why, in a few words.
    pub why: String,
}

impl std::fmt::Display for Choice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "method: {} ({})", self.method.name(), self.why)
    }
}

impl MethodKind {
    /// Whether this method renders `m` completely (the module docs), textures aside
    /// ([`MethodKind::renders_maps`]).
    pub fn renders(self, m: &Material) -> bool {
        match self {
            MethodKind::Sh | MethodKind::Hybrid => m.is_diffuse_only(),
            MethodKind::Sg | MethodKind::Cuts => true,
            MethodKind::Vmf => !matches!(m, Material::Ward { .. }),
        }
    }

    /// Whether this method applies texture and normal maps.
    pub fn renders_maps(self) -> bool {
        match self {
            MethodKind::Cuts => true,
            MethodKind::Sh | MethodKind::Hybrid | MethodKind::Sg | MethodKind::Vmf => false,
        }
    }
}

/// A label per material of the scene built from `desc` (`materials` of them), for messages:
/// the shape that carries it (`shapes[1] (sphere)`) when every shape carries one material,
/// else `material 3`.
pub fn material_labels(desc: &SceneDesc, materials: usize) -> Vec<String> {
    if desc.shapes.len() == materials {
        (desc.shapes.iter().enumerate())
            .map(|(i, s)| shape_label(i, s))
            .collect()
    } else {
        (0..materials).map(|i| format!("material {i}")).collect()
    }
}

/// The labels of the materials `method` does not render completely, with their kinds
/// (`shapes[1] (sphere) is ggx_conductor`), and of those whose maps it does not apply.
fn unrendered(
    method: MethodKind,
    desc: &SceneDesc,
    materials: &[Material],
    maps: &SceneMaps,
) -> Vec<String> {
    let labels = material_labels(desc, materials.len());
    let mut out = Vec::new();
    for (i, m) in materials.iter().enumerate() {
        if !method.renders(m) {
            out.push(format!("{} is {}", labels[i], m.kind_name()));
        } else if !method.renders_maps() && maps.of(i as u32).is_some() {
            out.push(format!("{} has texture or normal maps", labels[i]));
        }
    }
    out
}

/// The method `relight bake` uses when none is given: the rule of the module docs, with the
/// reason.
pub fn choose_bake_method(desc: &SceneDesc, materials: &[Material], maps: &SceneMaps) -> Choice {
    let labels = material_labels(desc, materials.len());
    let with_maps: Vec<&str> = (0..materials.len())
        .filter(|&i| maps.of(i as u32).is_some())
        .map(|i| labels[i].as_str())
        .collect();
    if !with_maps.is_empty() {
        return Choice {
            method: MethodKind::Cuts,
            why: format!(
                "{} {} texture or normal maps, which only cuts applies",
                with_maps.join(", "),
                if with_maps.len() == 1 { "has" } else { "have" }
            ),
        };
    }
    let glossy: Vec<String> = (materials.iter().enumerate())
        .filter(|(_, m)| !MethodKind::Sh.renders(m))
        .map(|(i, m)| format!("{} is {}", labels[i], m.kind_name()))
        .collect();
    if glossy.is_empty() {
        return Choice {
            method: MethodKind::Sh,
            why: "every material is diffuse, which sh renders".into(),
        };
    }
    Choice {
        method: GLOSSY_DEFAULT,
        why: format!(
            "{}: glossy, and sh renders diffuse light only; {} renders every material, and was the closest to the path tracer on most glossy examples at a fraction of sg's bake time",
            glossy.join(", "),
            GLOSSY_DEFAULT.name()
        ),
    }
}

/// A warning when an explicit `method` does not render some of the materials, naming the
/// objects and the methods that render them all; `None` when it renders them all.
pub fn method_warning(
    method: MethodKind,
    desc: &SceneDesc,
    materials: &[Material],
    maps: &SceneMaps,
) -> Option<String> {
    let missed = unrendered(method, desc, materials, maps);
    if missed.is_empty() {
        return None;
    }
    let can: Vec<&str> = MethodKind::ALL
        .into_iter()
        .filter(|&k| unrendered(k, desc, materials, maps).is_empty())
        .map(MethodKind::name)
        .collect();
    let what = if method.bake_kind() == BakeKind::Sh {
        "renders diffuse light only, without maps"
    } else if method.renders_maps() {
        "does not render every material"
    } else {
        "does not render every material or texture map"
    };
    Some(format!(
        "warning: --method {} {what}: {}; {} render{} the whole scene",
        method.name(),
        missed.join(", "),
        if can.is_empty() {
            "no method".to_string()
        } else {
            can.join(", ")
        },
        if can.len() == 1 { "s" } else { "" }
    ))
}

/// The method that shows `baked` under `env` when none is given: the bake's own, except that
/// an `sh` bake is shown with `hybrid` when the environment has a light the decomposition
/// extracts (module docs). `window`: the user windows the lighting's SH, which only `sh`
/// applies, so an `sh` bake stays `sh` (without decomposing the environment).
///
/// # Errors
/// [`MethodError::Environment`] when the decomposition refuses the map.
pub fn choose_frame_method(
    baked: &Baked,
    env: &Environment,
    window: bool,
) -> Result<Choice, MethodError> {
    let own = baked.kind().methods()[0];
    let Baked::Sh(sh) = baked else {
        return Ok(Choice {
            method: own,
            why: format!("the bundle holds a {} bake", baked.kind().name()),
        });
    };
    if window {
        return Ok(Choice {
            method: MethodKind::Sh,
            why: "an sh bake, and a window of the lighting's SH applies to sh".into(),
        });
    }
    let (d, _) = HybridSettings::default().resolve(sh.transfer.order)?;
    let dec = decompose_env(env, &d)?;
    if dec.lights.is_empty() {
        return Ok(Choice {
            method: MethodKind::Sh,
            why: "an sh bake, and no light stands out of the environment".into(),
        });
    }
    // Lights are sorted by luminance, descending.
    let top = dec.lights[0].luminance / dec.total_luminance.max(f32::MIN_POSITIVE);
    let n = dec.lights.len();
    Ok(Choice {
        method: MethodKind::Hybrid,
        why: format!(
            "an sh bake under an environment with {n} bright light{} (the brightest {:.0} % of its power): hybrid renders {} with shadow maps, without the negative light of the SH series; --method sh shows the bake alone",
            if n == 1 { "" } else { "s" },
            100.0 * top,
            if n == 1 { "it" } else { "them" }
        ),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sh::Sh;
    use crate::test_scene::with_input;
    use crate::{BakeContext, Method};
    use glam::Vec3;
    use relight_bake::sh::ShBakeSettings;
    use relight_scene::scene::Scene;

    /// A sphere of `sphere` material on a Lambert plane.
    fn scene(sphere: &str) -> (SceneDesc, Scene) {
        let d: SceneDesc = serde_json::from_str(&format!(
            r#"{{"shapes": [
                  {{"type": "sphere", "center": [0, 0.6, 0], "radius": 0.5, "rings": 8,
                   "material": {sphere}}},
                  {{"type": "plane", "center": [0, 0, 0], "size": 3, "divisions": 2,
                   "material": {{"type": "lambert", "albedo": [0.5, 0.5, 0.5]}}}}],
                "environment": {{"type": "constant", "radiance": [1, 1, 1]}},
                "camera": {{"origin": [0, 1.5, 3], "target": [0, 0.4, 0], "up": [0, 1, 0],
                           "fov_deg": 40, "width": 24, "height": 16}}}}"#
        ))
        .unwrap();
        let s = d.build(std::path::Path::new("<test>")).unwrap();
        (d, s)
    }

    const CONDUCTOR: &str =
        r#"{"type": "ggx_conductor", "specular": [0.9, 0.9, 0.9], "alpha": 0.2}"#;
    const WARD: &str = r#"{"type": "ward", "diffuse": [0.2, 0.2, 0.2], "specular": [0.3, 0.3, 0.3], "alpha_x": 0.1, "alpha_y": 0.3}"#;

    #[test]
    fn diffuse_scenes_bake_sh_and_glossy_ones_a_method_that_renders_them() {
        let (d, s) = scene(r#"{"type": "lambert", "albedo": [0.8, 0.3, 0.2]}"#);
        let c = choose_bake_method(&d, &s.materials, &s.maps);
        assert_eq!(c.method, MethodKind::Sh, "{c}");
        assert_eq!(
            method_warning(MethodKind::Sh, &d, &s.materials, &s.maps),
            None
        );
        for glossy in [CONDUCTOR, WARD] {
            let (d, s) = scene(glossy);
            let c = choose_bake_method(&d, &s.materials, &s.maps);
            assert_eq!(c.method, GLOSSY_DEFAULT, "{c}");
            assert!(c.method.renders(&s.materials[0]));
            // The reason names the object and its material.
            assert!(c.why.contains("shapes[0] (sphere) is "), "{c}");
            assert!(!c.why.contains("shapes[1]"), "{c}");
        }
    }

    #[test]
    fn an_explicit_method_that_drops_a_material_warns_by_object_and_names_the_others() {
        let (d, s) = scene(CONDUCTOR);
        let w = method_warning(MethodKind::Sh, &d, &s.materials, &s.maps).unwrap();
        assert!(
            w.contains("shapes[0] (sphere) is ggx_conductor") && w.contains("sg, cuts, vmf render"),
            "{w}"
        );
        assert!(!w.contains("shapes[1]"), "{w}");
        for m in [MethodKind::Sg, MethodKind::Cuts, MethodKind::Vmf] {
            assert_eq!(method_warning(m, &d, &s.materials, &s.maps), None, "{m:?}");
        }
        // Ward: vmf refuses it; sg and cuts render it.
        let (d, s) = scene(WARD);
        let w = method_warning(MethodKind::Vmf, &d, &s.materials, &s.maps).unwrap();
        assert!(
            w.contains("is ward") && w.contains("sg, cuts render "),
            "{w}"
        );
    }

    #[test]
    fn a_material_with_maps_is_baked_with_cuts() {
        let dir = std::env::temp_dir().join(format!("relight-choose-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // A 2 x 2 texture beside the scene file.
        let tex = dir.join("t.png");
        relight_scene::io::image::write_png_srgb8(&tex, 2, 2, &[[200, 10, 10]; 4]).unwrap();
        let json = r#"{"shapes": [{"type": "plane", "center": [0, 0, 0], "size": 3, "divisions": 2,
                 "material": {"type": "lambert", "albedo": [1, 1, 1],
                               "maps": {"diffuse": "t.png"}}}],
               "environment": {"type": "constant", "radiance": [1, 1, 1]},
               "camera": {"origin": [0, 1.5, 3], "target": [0, 0, 0], "up": [0, 1, 0],
                          "fov_deg": 40, "width": 8, "height": 8}}"#;
        let d: SceneDesc = serde_json::from_str(json).unwrap();
        let s = d.build(&dir.join("scene.json")).unwrap();
        let c = choose_bake_method(&d, &s.materials, &s.maps);
        assert_eq!(c.method, MethodKind::Cuts, "{c}");
        let w = method_warning(MethodKind::Sh, &d, &s.materials, &s.maps).unwrap();
        assert!(
            w.contains("has texture or normal maps") && w.contains("cuts renders"),
            "{w}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn an_sh_bake_is_shown_with_hybrid_under_a_sun_and_with_sh_under_a_flat_sky() {
        let baked = with_input(0.5, |input| {
            let s = ShBakeSettings {
                order: 3,
                samples: 32,
                ..Default::default()
            };
            Sh::bake(
                input,
                &s,
                0..input.scene.mesh.vertex_count(),
                &BakeContext::default(),
            )
            .unwrap()
        });
        let baked = Baked::Sh(baked);
        let flat = Environment::new(relight_sphere::EnvMap::constant(Vec3::ONE));
        let c = choose_frame_method(&baked, &flat, false).unwrap();
        assert_eq!(c.method, MethodKind::Sh, "{c}");
        let sun = Vec3::new(0.3, 0.8, 0.2).normalize();
        let sky = Environment::new(relight_sphere::decompose::sky_with_discs(
            32,
            &[(sun, 2.0, Vec3::splat(300.0))],
        ));
        let c = choose_frame_method(&baked, &sky, false).unwrap();
        assert_eq!(c.method, MethodKind::Hybrid, "{c}");
        assert!(c.why.contains("1 bright light"), "{c}");
    }
}
