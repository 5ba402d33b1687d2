use super::*;
use crate::io::test_util::temp_dir;
use crate::scene_file::SceneDesc;
use crate::shapes::{ground_plane, uv_sphere};
use crate::texture::tests::{write_exr_raw, write_png};

fn plastic() -> Material {
    Material::GgxPlastic {
        diffuse: Vec3::new(0.8, 0.6, 0.4),
        specular: Vec3::ONE,
        alpha: 0.3,
        ior: 1.49,
    }
}

fn constant_maps(normal: Option<Vec3>) -> MaterialMaps {
    MaterialMaps {
        normal: normal.map(|c| Texture::constant(c).unwrap()),
        ..Default::default()
    }
}

#[test]
fn tangent_frames_are_orthonormal_and_follow_u() {
    let mesh = uv_sphere(Vec3::ZERO, 1.0, 16, 32);
    let tangents = vertex_tangents(&mesh).unwrap();
    let uvs = mesh.uvs.as_ref().unwrap();
    for (v, t) in tangents.iter().enumerate() {
        let n = mesh.normals[v];
        let (s, b) = tangent_frame(n, t.truncate(), t.w);
        // Orthonormal to float precision.
        assert!((s.length() - 1.0).abs() < 1e-5 && (b.length() - 1.0).abs() < 1e-5);
        assert!(s.dot(n).abs() < 1e-5 && b.dot(n).abs() < 1e-5 && s.dot(b).abs() < 1e-5);
        assert!(t.w == 1.0 || t.w == -1.0);
        // Away from the poles, u is the longitude phi: d/du of the parametrisation
        // (sin phi sin theta, cos theta, -cos phi sin theta) points along (cos phi, 0, sin phi).
        let theta = std::f32::consts::PI * uvs[v].y;
        if theta.sin() > 0.3 {
            let phi = std::f32::consts::TAU * uvs[v].x;
            let want = Vec3::new(phi.cos(), 0.0, phi.sin());
            // Interior vertices average the chords on both sides (exact up to rounding); those
            // on the seam u = 0 or 1 see one side only, whose chord turns by half a slice.
            let bound = (std::f32::consts::PI / 32.0).cos() - 1e-3;
            assert!(s.dot(want) > bound, "vertex {v}: {s} vs {want}");
            // v grows with theta, downwards: dP/dv = -Y-ish, so (T, B = sign N x T) spans
            // the surface with B along dP/dv.
            let dpdv = Vec3::new(
                phi.sin() * theta.cos(),
                -theta.sin(),
                -phi.cos() * theta.cos(),
            );
            assert!(b.dot(dpdv) > bound, "vertex {v}: bitangent {b} vs {dpdv}");
        }
    }
    // Without UVs there are no tangents.
    let mut bare = mesh.clone();
    bare.uvs = None;
    assert!(vertex_tangents(&bare).is_none());
}

#[test]
fn a_flat_normal_map_gives_exactly_the_normal() {
    let mesh = uv_sphere(Vec3::ZERO, 1.0, 8, 16);
    let materials = [plastic()];
    let maps = SceneMaps::new(
        &mesh,
        vec![Some(Arc::new(constant_maps(Some(Vec3::new(
            0.5, 0.5, 1.0,
        )))))],
    )
    .unwrap();
    for tri in [3u32, 40, 100] {
        let bary = [0.2, 0.3, 0.5];
        let n = mesh.shading_normal(tri as usize, 0.3, 0.5);
        let (m, f) = shading_at(&mesh, &materials, &maps, tri, bary, n);
        let (m0, f0) = shading_at(&mesh, &materials, &SceneMaps::default(), tri, bary, n);
        assert_eq!(m, m0);
        assert_eq!((f.s, f.t, f.n), (f0.s, f0.t, f0.n));
        assert_eq!(f.n, n);
    }
}

#[test]
fn a_tilted_normal_map_turns_the_normal_towards_the_tangent() {
    let mesh = ground_plane(Vec3::ZERO, 2.0, 2);
    let materials = [plastic()];
    // (1, 0.5, 0.5) encodes +T; (0.5, 1, 0.5) encodes +B; 45 degrees between them and N.
    for (c, want) in [
        (Vec3::new(1.0, 0.5, 0.5), Vec3::X),
        (Vec3::new(0.5, 1.0, 0.5), Vec3::Z),
        (
            Vec3::new(1.0, 0.5, 1.0),
            Vec3::new(1.0, 1.0, 0.0).normalize(),
        ),
    ] {
        let maps = SceneMaps::new(&mesh, vec![Some(Arc::new(constant_maps(Some(c))))]).unwrap();
        let (_, f) = shading_at(&mesh, &materials, &maps, 0, [0.3, 0.3, 0.4], Vec3::Y);
        // The plane's u grows along +X and v along +Z (`ground_plane`).
        assert!((f.n - want).length() < 1e-5, "{c}: {} vs {want}", f.n);
    }
}

#[test]
fn maps_multiply_colours_and_replace_roughness() {
    let d = Texture::constant(Vec3::new(0.5, 0.25, 1.0)).unwrap();
    let r = Texture::constant(Vec3::splat(0.1234)).unwrap();
    let maps = MaterialMaps {
        diffuse: Some(d.clone()),
        specular: Some(d),
        roughness: Some(r),
        ..Default::default()
    };
    let uv = Vec2::new(0.3, 0.7);
    match maps.apply(plastic(), uv) {
        Material::GgxPlastic {
            diffuse,
            specular,
            alpha,
            ior,
        } => {
            assert!((diffuse - Vec3::new(0.4, 0.15, 0.4)).length() < 1e-6);
            assert!((specular - Vec3::new(0.5, 0.25, 1.0)).length() < 1e-6);
            // Rounded to a multiple of 1/256 for the plastic's tables.
            assert_eq!(alpha, (0.1234f32 * 256.0).round() / 256.0);
            assert_eq!(ior, 1.49);
        }
        m => panic!("{m:?}"),
    }
    let cond = Material::GgxConductor {
        specular: Vec3::ONE,
        alpha: 0.5,
    };
    assert!(matches!(
        maps.apply(cond, uv),
        Material::GgxConductor { alpha, .. } if alpha == 0.1234
    ));
    // A texel of 0 is as smooth as allowed, and valid.
    let smooth = MaterialMaps {
        roughness: Some(Texture::constant(Vec3::ZERO).unwrap()),
        ..Default::default()
    };
    let m = smooth.apply(cond, uv);
    assert!(matches!(m, Material::GgxConductor { alpha, .. } if alpha == MIN_MAP_ALPHA));
    assert!(m.validate().is_ok());
}

/// On a glTF material the diffuse map multiplies `base_color`, the metallic-roughness map's
/// green multiplies `roughness` and its blue `metallic` (glTF's channels); the result is valid.
#[test]
fn gltf_maps_multiply_base_colour_metallic_and_roughness() {
    let maps = MaterialMaps {
        diffuse: Some(Texture::constant(Vec3::new(0.5, 0.25, 1.0)).unwrap()),
        metallic_roughness: Some(Texture::constant(Vec3::new(0.9, 0.5, 0.25)).unwrap()),
        ..Default::default()
    };
    let m = Material::Gltf {
        base_color: Vec3::new(0.8, 0.6, 0.4),
        metallic: 0.8,
        roughness: 0.6,
    };
    let got = maps.apply(m, Vec2::new(0.2, 0.9));
    let Material::Gltf {
        base_color,
        metallic,
        roughness,
    } = got
    else {
        panic!("{got:?}")
    };
    assert!((base_color - Vec3::new(0.4, 0.15, 0.4)).length() < 1e-6);
    assert!((metallic - 0.2).abs() < 1e-6 && (roughness - 0.3).abs() < 1e-6);
    assert!(got.validate().is_ok());
    // Specular and roughness maps are refused on it, by name; metallic_roughness elsewhere too.
    for which in ["specular", "roughness"] {
        let e = check_applies(&m, which).unwrap_err();
        assert!(
            e.contains(&format!("a {which} map on a gltf material")),
            "{e}"
        );
    }
    assert!(check_applies(&m, "metallic_roughness").is_ok());
    assert!(check_applies(&plastic(), "metallic_roughness").is_err());
}

/// `normal_scale` scales the decoded normal's `x` and `y` before normalising (glTF's
/// `normalTexture.scale`): scale 0 gives the normal, scale 2 on `(1, 0.5, 0.75)` tilts to
/// `normalize(2, 0, 0.5)`.
#[test]
fn normal_scale_scales_the_tangent_components() {
    let mesh = ground_plane(Vec3::ZERO, 2.0, 2);
    let materials = [plastic()];
    for (scale, want) in [
        (0.0f32, Vec3::Y),
        (1.0, Vec3::new(1.0, 0.5, 0.0).normalize()),
        (2.0, Vec3::new(2.0, 0.5, 0.0).normalize()),
    ] {
        let mm = MaterialMaps {
            normal_scale: scale,
            ..constant_maps(Some(Vec3::new(1.0, 0.5, 0.75)))
        };
        let maps = SceneMaps::new(&mesh, vec![Some(Arc::new(mm))]).unwrap();
        let (_, f) = shading_at(&mesh, &materials, &maps, 0, [0.3, 0.3, 0.4], Vec3::Y);
        assert!((f.n - want).length() < 1e-5, "{scale}: {} vs {want}", f.n);
    }
    let desc: MapsDesc = serde_json::from_str(r#"{"normal": "n.png"}"#).unwrap();
    assert_eq!(desc.normal_scale, 1.0);
    let desc: MapsDesc = serde_json::from_str(
        r#"{"normal": "n.png", "normal_scale": 0.5, "metallic_roughness": "mr.png"}"#,
    )
    .unwrap();
    assert_eq!(desc.normal_scale, 0.5);
    assert_eq!(desc.metallic_roughness.as_deref(), Some("mr.png"));
}

/// A scene with one shape in `dir`, its material naming `maps` (JSON), built.
fn build(dir: &Path, shape: &str, maps: &str) -> Result<crate::scene::Scene, SceneError> {
    let text = format!(
        r#"{{"shapes": [{shape_open}, "material": {{"type": "ggx_plastic", "diffuse": [1, 1, 1], "specular": [1, 1, 1], "alpha": 0.2, "ior": 1.5, "maps": {maps}}}}}],
        "environment": {{"type": "constant", "radiance": [1, 1, 1]}},
        "camera": {{"origin": [0, 1, 4], "target": [0, 0, 0], "up": [0, 1, 0], "fov_deg": 40, "width": 8, "height": 8}}}}"#,
        shape_open = shape.trim_end_matches('}')
    );
    let origin = dir.join("scene.json");
    std::fs::write(&origin, &text).unwrap();
    SceneDesc::read(&origin)?.build(&origin)
}

const SPHERE: &str = r#"{"type": "sphere", "center": [0, 0, 0], "radius": 1, "rings": 4}"#;

#[test]
fn scene_files_load_maps_and_refuse_bad_ones_naming_the_file() {
    let root = temp_dir("maps-scene");
    let dir = root.join("scene");
    std::fs::create_dir_all(&dir).unwrap();
    write_png(&dir.join("d.png"), 2, 2, 3, &[255; 12]);
    write_png(&dir.join("n.png"), 1, 1, 3, &[128, 128, 255]);
    write_png(&root.join("outside.png"), 1, 1, 3, &[0, 0, 0]);
    write_exr_raw(&dir.join("nan.exr"), 1, 1, &[Vec3::new(0.1, f32::NAN, 0.1)]);
    std::fs::write(dir.join("d.bmp"), b"BM").unwrap();
    // Good: loaded, one map set for the one material, tangents for the normal map.
    let s = build(&dir, SPHERE, r#"{"diffuse": "d.png", "normal": "n.png"}"#).unwrap();
    let m = s.maps.of(0).expect("maps of material 0");
    assert!(m.diffuse.is_some() && m.normal.is_some() && m.roughness.is_none());
    for (maps, want) in [
        (r#"{"diffuse": "missing.png"}"#, "missing.png"),
        (r#"{"diffuse": "../outside.png"}"#, "outside.png"),
        (r#"{"diffuse": "d.bmp"}"#, "expected png or exr"),
        (r#"{"roughness": "nan.exr"}"#, "NaN"),
        (r#"{"diffuse": "d.png", "bump": "d.png"}"#, "bump"),
    ] {
        let e = build(&dir, SPHERE, maps)
            .map(|_| ())
            .unwrap_err()
            .to_string();
        assert!(e.contains(want), "{maps}: {e}");
    }
    // Outside the folder names the folder rule.
    let e = build(&dir, SPHERE, r#"{"diffuse": "../outside.png"}"#)
        .map(|_| ())
        .unwrap_err()
        .to_string();
    assert!(e.contains("outside"), "{e}");
    // A map on a material without such a parameter.
    let text = std::fs::read_to_string(dir.join("scene.json")).unwrap();
    let lambert = text.replace(
        r#""type": "ggx_plastic", "diffuse": [1, 1, 1], "specular": [1, 1, 1], "alpha": 0.2, "ior": 1.5"#,
        r#""type": "lambert", "albedo": [1, 1, 1]"#,
    );
    let lambert = lambert
        .replace("../outside.png", "d.png")
        .replace("diffuse", "roughness");
    std::fs::write(dir.join("lambert.json"), &lambert).unwrap();
    let origin = dir.join("lambert.json");
    let e = SceneDesc::read(&origin)
        .unwrap()
        .build(&origin)
        .map(|_| ())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("lambert.json") && e.contains("roughness map on a lambert material"),
        "{e}"
    );
    // A map on a mesh without texture coordinates.
    std::fs::write(dir.join("tri.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let e = build(
        &dir,
        r#"{"type": "mesh", "file": "tri.obj"}"#,
        r#"{"diffuse": "d.png"}"#,
    )
    .map(|_| ())
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("tri.obj") && e.contains("no texture coordinates"),
        "{e}"
    );
}

#[test]
fn material_desc_reads_plain_materials_and_maps() {
    let plain: MaterialDesc =
        serde_json::from_str(r#"{"type": "lambert", "albedo": [0.5, 0.5, 0.5]}"#).unwrap();
    assert_eq!(plain.maps, None);
    let mapped: MaterialDesc = serde_json::from_str(
        r#"{"type": "ggx_conductor", "specular": [1, 1, 1], "alpha": 0.1, "maps": {"roughness": "r.exr"}}"#,
    )
    .unwrap();
    assert_eq!(mapped.maps.unwrap().roughness.as_deref(), Some("r.exr"));
    // Round trip without maps writes no "maps".
    let text = serde_json::to_string(&plain).unwrap();
    assert!(!text.contains("maps"), "{text}");
}
