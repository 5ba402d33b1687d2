//! Tests of textures, materials, objects, cameras, refusals and warnings of the glTF reader.

use super::*;
use crate::io::load_mesh;

/// A 2 x 2 RGB PNG: red, green / blue, white.
fn png_2x2(dir: &Path) -> Vec<u8> {
    let p = dir.join("tmp-2x2.png");
    crate::texture::tests::write_png(
        &p,
        2,
        2,
        3,
        &[255, 0, 0, 0, 255, 0, 0, 0, 255, 255, 255, 255],
    );
    let b = std::fs::read(&p).unwrap();
    std::fs::remove_file(&p).unwrap();
    b
}

fn data_uri(mime: &str, b: &[u8]) -> String {
    format!("data:{mime};base64,{}", base64_encode(b))
}

/// The quad of [`quad_json`] (embedded buffer) with `material`, `images` and top-level
/// `extra` JSON (each spliced in as written), one texture of image 0 with a sampler that
/// clamps `s`, mirrors `t` and magnifies to the nearest texel.
fn textured_json(material: &str, images: &str, extra: &str) -> String {
    let buffer = data_uri("application/octet-stream", &quad_bin());
    format!(
        r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0]}}],
        "nodes": [{{"mesh": 0, "name": "quad"}}],
        "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0, "TEXCOORD_0": 1}}, "indices": 2, "material": 0}}]}}],
        "materials": [{material}],
        "textures": [{{"source": 0, "sampler": 0}}],
        "samplers": [{{"wrapS": 33071, "wrapT": 33648, "magFilter": 9728}}],
        "images": [{images}],
        "buffers": [{{"uri": "{buffer}", "byteLength": 92}}],
        "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 48}}, {{"buffer": 0, "byteOffset": 48, "byteLength": 32}},
                        {{"buffer": 0, "byteOffset": 80, "byteLength": 12}}],
        "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"}},
                      {{"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"}},
                      {{"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}}]{extra}}}"#
    )
}

const BASE_TEX: &str = r#"{"name": "paint", "pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1], "metallicFactor": 0, "roughnessFactor": 0.5, "baseColorTexture": {"index": 0}}}"#;

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn base_colour_texture_reads_with_its_sampler_from_a_data_uri() {
    let dir = temp_dir("gltftex");
    let img = format!(r#"{{"uri": "{}"}}"#, data_uri("image/png", &png_2x2(&dir)));
    let m = load_mesh(&write(&dir, "t.gltf", &textured_json(BASE_TEX, &img, ""))).unwrap();
    assert!(matches!(m.materials[0], Material::Gltf { metallic, .. } if metallic == 0.0));
    let tex = m.maps[0]
        .diffuse
        .as_ref()
        .expect("base colour as the diffuse map");
    assert_eq!(
        tex.sampler(),
        crate::texture::Sampler {
            wrap_s: crate::texture::Wrap::ClampToEdge,
            wrap_t: crate::texture::Wrap::MirroredRepeat,
            filter: crate::texture::Filter::Nearest,
        }
    );
    // sRGB 255 decodes to 1: the top-left texel (red) sits at mesh uv (0.25, 0.75).
    assert_eq!(tex.lookup(Vec2::new(0.25, 0.75)), Vec3::X);
    assert_eq!(tex.lookup(Vec2::new(0.25, 0.25)), Vec3::Z);
    assert_eq!(m.maps.len(), m.materials.len());
}

#[test]
fn images_in_a_glb_buffer_view_and_in_an_external_file_read() {
    let dir = temp_dir("gltfteximg");
    let png = png_2x2(&dir);
    // External file next to the model.
    std::fs::write(dir.join("albedo.png"), &png).unwrap();
    let p = write(
        &dir,
        "ext.gltf",
        &textured_json(BASE_TEX, r#"{"uri": "albedo.png"}"#, ""),
    );
    let ext = load_mesh(&p).unwrap();
    // GLB: the image in a buffer view of the BIN chunk after the geometry.
    let mut bin = quad_bin();
    let off = bin.len();
    bin.extend_from_slice(&png);
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let json = textured_json(
        BASE_TEX,
        r#"{"bufferView": 3, "mimeType": "image/png"}"#,
        "",
    )
    .replace(
        &format!(
            r#""uri": "{}", "byteLength": 92"#,
            data_uri("application/octet-stream", &quad_bin())
        ),
        &format!(r#""byteLength": {}"#, bin.len()),
    )
    .replace(
        r#"{"buffer": 0, "byteOffset": 80, "byteLength": 12}]"#,
        &format!(
            r#"{{"buffer": 0, "byteOffset": 80, "byteLength": 12}}, {{"buffer": 0, "byteOffset": {off}, "byteLength": {}}}]"#,
            png.len()
        ),
    );
    let g = dir.join("t.glb");
    std::fs::write(&g, glb(&json, &bin)).unwrap();
    let glb_mesh = load_mesh(&g).unwrap();
    assert_eq!(glb_mesh.maps[0].diffuse, ext.maps[0].diffuse);
    assert!(ext.maps[0].diffuse.is_some());
}

#[test]
fn bad_images_are_refused_naming_the_file_and_the_image() {
    let dir = temp_dir("gltfbadimg");
    std::fs::create_dir_all(dir.join("m")).unwrap();
    std::fs::write(dir.join("out.png"), png_2x2(&dir)).unwrap();
    let cases = [
        (r#"{"uri": "../out.png"}"#, "outside"),
        (r#"{"uri": "gone.png"}"#, "gone.png"),
        (r#"{"uri": "tex.ktx2", "mimeType": "image/ktx2"}"#, "KTX2"),
        (
            &*format!(
                r#"{{"uri": "{}"}}"#,
                data_uri("image/png", b"\x89PNG\r\n\x1a\nxx")
            ),
            "PNG",
        ),
        (
            &*format!(r#"{{"uri": "{}"}}"#, data_uri("image/gif", b"GIF89a")),
            "not a PNG or JPEG",
        ),
    ];
    for (img, want) in cases {
        let p = write(&dir.join("m"), "b.gltf", &textured_json(BASE_TEX, img, ""));
        let e = load_mesh(&p).unwrap_err().to_string();
        assert!(e.contains("b.gltf") || e.contains("gone.png"), "{e}");
        // A missing file is an IO error naming that file; the others name the image.
        assert!(
            e.contains(want) && (e.contains("image 0") || want == "gone.png"),
            "{want}: {e}"
        );
    }
    // Oversized: 16385 texels wide.
    let big = dir.join("big.png");
    crate::texture::tests::write_png(&big, 16385, 1, 1, &vec![0; 16385]);
    let img = format!(
        r#"{{"uri": "{}"}}"#,
        data_uri("image/png", &std::fs::read(&big).unwrap())
    );
    let p = write(&dir, "big.gltf", &textured_json(BASE_TEX, &img, ""));
    let e = load_mesh(&p).unwrap_err();
    assert!(matches!(e, SceneError::TooLarge { .. }), "{e}");
}

#[test]
fn extensions_emission_and_factors_are_refused_by_name() {
    let dir = temp_dir("gltfrefuse");
    let img = format!(r#"{{"uri": "{}"}}"#, data_uri("image/png", &png_2x2(&dir)));
    let cases = [
        (
            BASE_TEX.to_string(),
            r#", "extensionsUsed": ["KHR_materials_volume"], "extensionsRequired": ["KHR_materials_volume"]"#,
            "required glTF extension KHR_materials_volume (supported: KHR_texture_transform)",
        ),
        (
            BASE_TEX.to_string(),
            r#", "extensionsUsed": ["KHR_draco_mesh_compression"]"#,
            "KHR_draco_mesh_compression",
        ),
        (
            BASE_TEX.to_string(),
            r#", "extensionsUsed": ["EXT_meshopt_compression"]"#,
            "EXT_meshopt_compression",
        ),
        (
            BASE_TEX.to_string(),
            r#", "extensionsUsed": ["KHR_texture_basisu"]"#,
            "KHR_texture_basisu",
        ),
        (
            BASE_TEX.to_string(),
            r#", "extensionsUsed": ["EXT_texture_webp"]"#,
            "EXT_texture_webp",
        ),
        (
            BASE_TEX.to_string(),
            r#", "extensionsUsed": ["KHR_materials_emissive_strength"]"#,
            "KHR_materials_emissive_strength: relight's methods carry no emission",
        ),
        (
            BASE_TEX.replace(
                r#""name": "paint","#,
                r#""name": "paint", "emissiveFactor": [1, 0, 0],"#,
            ),
            "",
            "emissiveFactor",
        ),
        (
            // The material extension without its declaration is refused the same way.
            BASE_TEX.replace(
                r#""name": "paint","#,
                r#""name": "paint", "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 2}},"#,
            ),
            "",
            "KHR_materials_emissive_strength: relight's methods carry no emission",
        ),
        (
            BASE_TEX.replace(
                r#""name": "paint","#,
                r#""name": "paint", "emissiveTexture": {"index": 0},"#,
            ),
            "",
            "emissiveTexture: relight's methods carry no emission",
        ),
        (
            BASE_TEX.replace(r#""roughnessFactor": 0.5"#, r#""roughnessFactor": 1.5"#),
            "",
            "roughnessFactor 1.5 is not in [0, 1]",
        ),
        (
            BASE_TEX.replace(r#""metallicFactor": 0"#, r#""metallicFactor": -0.5"#),
            "",
            "metallicFactor -0.5 is not in [0, 1]",
        ),
        (
            BASE_TEX.replace("[1, 1, 1, 1]", "[1, 2, 1, 1]"),
            "",
            "baseColorFactor 2 is not in [0, 1]",
        ),
    ];
    for (mat, extra, want) in cases {
        let p = write(&dir, "r.gltf", &textured_json(&mat, &img, extra));
        let e = load_mesh(&p).unwrap_err().to_string();
        assert!(e.contains("r.gltf") && e.contains(want), "{want}: {e}");
    }
    // A textured material on a primitive without TEXCOORD_0.
    let json = textured_json(BASE_TEX, &img, "")
        .replace(r#""POSITION": 0, "TEXCOORD_0": 1"#, r#""POSITION": 0"#);
    let e = load_mesh(&write(&dir, "nouv.gltf", &json))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("nouv.gltf") && e.contains("no TEXCOORD_0"),
        "{e}"
    );
}

#[test]
fn alpha_modes_and_a_second_uv_set_warn_once_naming_the_material() {
    let dir = temp_dir("gltfwarn");
    let img = format!(r#"{{"uri": "{}"}}"#, data_uri("image/png", &png_2x2(&dir)));
    let mat = BASE_TEX
        .replace(r#""name": "paint","#, r#""name": "paint", "alphaMode": "BLEND","#)
        .replace(
            r#""baseColorTexture": {"index": 0}"#,
            r#""baseColorTexture": {"index": 0, "texCoord": 1}, "metallicRoughnessTexture": {"index": 0, "texCoord": 1}"#,
        );
    let m = load_mesh(&write(&dir, "w.gltf", &textured_json(&mat, &img, ""))).unwrap();
    let blend: Vec<_> = m.warnings.iter().filter(|w| w.contains("Blend")).collect();
    let uv1: Vec<_> = m
        .warnings
        .iter()
        .filter(|w| w.contains("TEXCOORD_1"))
        .collect();
    assert_eq!(blend.len(), 1, "{:?}", m.warnings);
    assert_eq!(uv1.len(), 1, "{:?}", m.warnings);
    assert!(blend[0].contains("'paint'") && uv1[0].contains("'paint'"));
}

#[test]
fn texture_transform_metallic_roughness_and_normal_maps_are_carried() {
    let dir = temp_dir("gltfmr");
    let img = format!(r#"{{"uri": "{}"}}"#, data_uri("image/png", &png_2x2(&dir)));
    let mat = r#"{"pbrMetallicRoughness": {"metallicFactor": 1, "roughnessFactor": 0.5,
        "baseColorTexture": {"index": 0, "extensions": {"KHR_texture_transform": {"offset": [0.5, 0], "rotation": 0.25, "scale": [2, 3]}}},
        "metallicRoughnessTexture": {"index": 0}}, "normalTexture": {"index": 0, "scale": 0.5, "extensions": {"KHR_texture_transform": {"rotation": 1.5}}}}"#;
    let extra = r#", "extensionsUsed": ["KHR_texture_transform"], "extensionsRequired": ["KHR_texture_transform"]"#;
    let m = load_mesh(&write(&dir, "mr.gltf", &textured_json(mat, &img, extra))).unwrap();
    assert_eq!(
        m.materials[0],
        Material::Gltf {
            base_color: Vec3::ONE,
            metallic: 1.0,
            roughness: 0.5
        }
    );
    let maps = &m.maps[0];
    let base = maps
        .diffuse
        .as_ref()
        .expect("base colour as the diffuse map");
    assert_eq!(
        base.transform(),
        Some(crate::texture::UvTransform {
            offset: Vec2::new(0.5, 0.0),
            rotation: 0.25,
            scale: Vec2::new(2.0, 3.0),
        })
    );
    // The metallic-roughness texture as it is (linear): the green texel (top right) has
    // G = 1, the red one G = 0; the map multiplies the factors at shading time.
    let mr = maps.metallic_roughness.as_ref().unwrap();
    assert_eq!(mr.lookup(Vec2::new(0.75, 0.75)), Vec3::Y);
    assert_eq!(mr.lookup(Vec2::new(0.25, 0.75)), Vec3::X);
    // The normal texture as it is, with its scale beside it.
    assert_eq!(maps.normal_scale, 0.5);
    let normal = maps.normal.as_ref().unwrap();
    let rotated = crate::texture::UvTransform {
        rotation: 1.5,
        ..Default::default()
    };
    assert_eq!(normal.transform(), Some(rotated));
    let n = normal
        .clone()
        .with_transform(None)
        .lookup(Vec2::new(0.25, 0.75));
    assert_eq!(n, Vec3::X);
}

/// Three nodes (two named the same, one unnamed instancing an unnamed mesh... and one of a
/// named mesh), and a camera.
#[test]
fn objects_are_named_and_the_first_camera_is_read() {
    let dir = temp_dir("gltfobj");
    let json = quad_json(
        Some(&data_uri("application/octet-stream", &quad_bin())),
        6,
    )
    .replace(
        r#""nodes": [{"children": [1], "translation": [0, 0, 5]}, {"mesh": 0, "scale": [2, 2, 2]}]"#,
        r#""nodes": [{"children": [1, 2, 3, 4], "translation": [0, 0, 5]}, {"mesh": 0, "name": "a"}, {"mesh": 0, "name": "a"}, {"mesh": 0},
                     {"camera": 0, "translation": [1, 2, 3], "rotation": [0, 0.7071068, 0, 0.7071068]}],
            "cameras": [{"type": "perspective", "perspective": {"yfov": 0.5, "aspectRatio": 2.0, "znear": 0.1}}]"#,
    );
    let m = load_mesh(&write(&dir, "o.gltf", &json)).unwrap();
    let names: Vec<&str> = m.objects.iter().map(|o| o.name.as_str()).collect();
    assert_eq!(names, ["a", "a.1", "mesh0"]);
    let ranges: Vec<_> = m.objects.iter().map(|o| o.triangles.clone()).collect();
    assert_eq!(ranges, [0..2, 2..4, 4..6]);
    let cam = m.camera.expect("camera");
    // Node at (1, 2, 3) + parent (0, 0, 5), turned 90 degrees about +Y: -Z becomes -X.
    assert_eq!(cam.origin, [1.0, 2.0, 8.0]);
    let t = Vec3::from(cam.target) - Vec3::from(cam.origin);
    assert!((t - Vec3::NEG_X).length() < 1e-5, "{t}");
    assert!((Vec3::from(cam.up) - Vec3::Y).length() < 1e-5);
    let fov = 2.0 * (0.25f32.tan() * 2.0).atan().to_degrees();
    assert!((cam.fov_deg - fov).abs() < 1e-4, "{}", cam.fov_deg);
    assert_eq!((cam.width, cam.height), (640, 320));
    // An orthographic camera is ignored with a warning.
    let ortho = json.replace(
        r#"{"type": "perspective", "perspective": {"yfov": 0.5, "aspectRatio": 2.0, "znear": 0.1}}"#,
        r#"{"type": "orthographic", "orthographic": {"xmag": 1, "ymag": 1, "znear": 0.1, "zfar": 10}}"#,
    );
    let m = load_mesh(&write(&dir, "ortho.gltf", &ortho)).unwrap();
    assert!(m.camera.is_none());
    assert!(m.warnings.iter().any(|w| w.contains("orthographic")));
}

/// A scene file's mesh shape keeps a glTF's maps unless it overrides the material.
#[test]
fn a_scene_file_uses_the_maps_of_a_gltf_mesh_without_a_material() {
    let dir = temp_dir("gltfscene");
    let img = format!(r#"{{"uri": "{}"}}"#, data_uri("image/png", &png_2x2(&dir)));
    write(&dir, "t.gltf", &textured_json(BASE_TEX, &img, ""));
    let scene = |shape: &str| {
        let text = format!(
            r#"{{"shapes": [{shape}], "environment": {{"type": "constant", "radiance": [1, 1, 1]}},
            "camera": {{"origin": [0, 0, 3], "target": [0, 0, 0], "up": [0, 1, 0], "fov_deg": 40, "width": 8, "height": 8}}}}"#
        );
        let origin = write(&dir, "s.json", &text);
        crate::scene_file::SceneDesc::read(&origin)
            .unwrap()
            .build(&origin)
            .unwrap()
    };
    let own = scene(r#"{"type": "mesh", "file": "t.gltf"}"#);
    assert!(!own.maps.is_empty());
    let overridden = scene(
        r#"{"type": "mesh", "file": "t.gltf", "material": {"type": "lambert", "albedo": [0.5, 0.5, 0.5]}}"#,
    );
    assert!(overridden.maps.is_empty());
}
