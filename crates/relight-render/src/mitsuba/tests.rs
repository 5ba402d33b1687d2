//! Tests of the export's files and refusals (the maps' in `maps.rs`).

use super::*;
use relight_scene::camera::Camera;
use relight_scene::scene::Environment;
use relight_scene::shapes::{ground_plane, uv_sphere};
use relight_scene::Vec3;

#[test]
fn export_writes_one_ply_per_used_material_and_a_complete_json() {
    let mut mesh = uv_sphere(Vec3::Y, 1.0, 8, 16);
    let ground = ground_plane(Vec3::ZERO, 6.0, 2);
    mesh.append(&ground, 2);
    let scene = Scene {
        maps: Default::default(),
        mesh,
        materials: vec![
            Material::Lambert {
                albedo: Vec3::splat(0.5),
            },
            Material::BlinnPhong {
                diffuse: Vec3::ZERO,
                specular: Vec3::ONE,
                exponent: 9.0,
            }, // unused
            Material::GgxPlastic {
                diffuse: Vec3::splat(0.3),
                specular: Vec3::ONE,
                alpha: 0.2,
                ior: 1.5,
            },
        ],
        env: Environment {
            rotate_y_deg: 30.0,
            scale: 2.0,
            ..Environment::new(EnvMap::constant(Vec3::ONE))
        },
        camera: Camera::look_at([0.0, 1.0, 5.0], [0.0, 1.0, 0.0], 40.0, 8, 6),
        objects: Vec::new(),
    };
    let dir = std::env::temp_dir().join(format!("relight-mitsuba-export-{}", std::process::id()));
    let json_path = export_mitsuba(&scene, &dir, 16, 3).unwrap();
    let doc: Value = serde_json::from_str(&std::fs::read_to_string(&json_path).unwrap()).unwrap();
    let shapes = doc["shapes"].as_array().unwrap();
    assert_eq!(shapes.len(), 2);
    assert_eq!(shapes[0]["bsdf"]["type"], "diffuse");
    assert_eq!(shapes[1]["bsdf"]["type"], "roughplastic");
    assert_eq!(shapes[1]["bsdf"]["ext_ior"], 1.0);
    assert_eq!(doc["env"]["rotate_y_deg"], 30.0);
    assert_eq!(doc["max_depth"], 3);
    assert!(dir.join("shape_0.ply").is_file() && dir.join("shape_2.ply").is_file());
    assert!(!dir.join("shape_1.ply").exists());
    let (w, h, px) = relight_scene::io::image::read_exr(&dir.join("env.exr")).unwrap();
    assert_eq!((w, h), (scene.env.map.width(), scene.env.map.height()));
    assert!(px.iter().all(|p| *p == Vec3::ONE));
    // A textured material is exported with its map (the maps module's tests check the
    // details).
    let mut textured = scene.clone();
    let maps = relight_scene::material::maps::MaterialMaps {
        diffuse: Some(relight_scene::texture::Texture::constant(Vec3::splat(0.5)).unwrap()),
        ..Default::default()
    };
    textured.maps = relight_scene::material::maps::SceneMaps::new(
        &textured.mesh,
        vec![None, None, Some(std::sync::Arc::new(maps))],
    )
    .unwrap();
    let json_path = export_mitsuba(&textured, &dir, 16, 3).unwrap();
    let doc: Value = serde_json::from_str(&std::fs::read_to_string(&json_path).unwrap()).unwrap();
    assert_eq!(
        doc["shapes"][1]["bsdf"]["diffuse_reflectance"]["bitmap"],
        "tex_2_diffuse.exr"
    );
    assert!(dir.join("tex_2_diffuse.exr").is_file());
    // Blinn-Phong in use is refused.
    let mut bp = scene.clone();
    bp.mesh.material_ids.iter_mut().for_each(|m| *m = 1);
    let e = export_mitsuba(&bp, &dir, 16, 3).unwrap_err();
    assert!(
        matches!(
            e,
            MitsubaError::Unsupported {
                index: 1,
                model: "Blinn-Phong"
            }
        ),
        "{e:?}"
    );
    assert_eq!(
        e.to_string(),
        "material 1: Mitsuba 3 has no Blinn-Phong BSDF"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
