//! The textured glTF test assets made by third-party tools (relight-testdata's
//! `gltf_assets`: obj2gltf and @gltf-transform from the shared `spot.obj`, each checked by the
//! Khronos gltf-validator): what the builder promises is in each file, the validator accepts
//! every one and refuses corrupted ones, and `relight_scene::io::load_mesh` reads each with
//! the geometry of `spot.obj` and the textures, materials and objects each asset carries.

mod common;

use common::{read_png, tmpdir};
use relight_scene::io::load_mesh;
use relight_testdata::{gltf_assets, validate_gltf};
use serde_json::Value;
use std::path::Path;

/// The validator's warnings the assets may carry, each for a reason outside the builder:
/// - `IMAGE_FEATURES_UNSUPPORTED`: the shared `spot_texture.png` carries colour-space chunks;
/// - `MESH_PRIMITIVE_GENERATED_TANGENT_SPACE`: a normal texture on a primitive without
///   tangents, which glTF asks the reader to generate (MikkTSpace).
const EXPECTED_WARNINGS: &[&str] = &[
    "IMAGE_FEATURES_UNSUPPORTED",
    "MESH_PRIMITIVE_GENERATED_TANGENT_SPACE",
];

/// The JSON of a `.gltf`, or of a `.glb`'s first chunk.
fn gltf_json(path: &Path) -> Value {
    let bytes = std::fs::read(path).unwrap();
    let json = if bytes.starts_with(b"glTF") {
        let len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        assert_eq!(&bytes[16..20], b"JSON", "{}", path.display());
        &bytes[20..20 + len]
    } else {
        &bytes[..]
    };
    serde_json::from_slice(json).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Material `i` of a glTF JSON.
fn material(json: &Value, i: usize) -> &Value {
    &json["materials"][i]
}

#[test]
fn every_asset_is_built_with_what_it_promises_and_validates() {
    let Some(assets) = gltf_assets() else { return };
    for (step, ms) in &assets.timings {
        eprintln!("gltf assets: {step}: {ms:.0} ms");
    }
    // The validator's verdicts, recorded by the build, one per asset in order.
    assert_eq!(assets.verdicts.len(), assets.all().len());
    for (v, path) in assets.verdicts.iter().zip(assets.all()) {
        assert_eq!(Path::new(&v.file), path.file_name().unwrap());
        assert_eq!(v.errors, 0, "{v:?}");
        for code in &v.codes {
            assert!(EXPECTED_WARNINGS.contains(&code.as_str()), "{v:?}");
        }
    }
    // The assets with a normal texture and no tangents, and only they, get the tangent warning.
    for v in &assets.verdicts {
        let has_normal_map = matches!(v.file.as_str(), "spot_normal.glb" | "spot_external.gltf");
        let tangent = v
            .codes
            .iter()
            .any(|c| c == "MESH_PRIMITIVE_GENERATED_TANGENT_SPACE");
        assert_eq!(tangent, has_normal_map, "{v:?}");
    }

    // spot.glb: obj2gltf's one material with an embedded base-colour texture.
    let j = gltf_json(&assets.spot);
    assert_eq!(j["materials"].as_array().unwrap().len(), 1);
    let pbr = &material(&j, 0)["pbrMetallicRoughness"];
    assert!(pbr["baseColorTexture"]["index"].is_u64(), "{pbr}");
    assert!(j["images"][0]["bufferView"].is_u64(), "{}", j["images"]);

    // spot_mr.glb and spot_normal.glb: a second texture in its slot.
    let j = gltf_json(&assets.metallic_roughness);
    let pbr = &material(&j, 0)["pbrMetallicRoughness"];
    assert!(pbr["metallicRoughnessTexture"]["index"].is_u64(), "{pbr}");
    assert_eq!(j["images"].as_array().unwrap().len(), 2);
    let j = gltf_json(&assets.normal);
    assert!(material(&j, 0)["normalTexture"]["index"].is_u64(), "{j}");

    // spot_transform.glb: KHR_texture_transform on the base colour.
    let j = gltf_json(&assets.texture_transform);
    let t = &material(&j, 0)["pbrMetallicRoughness"]["baseColorTexture"]["extensions"]
        ["KHR_texture_transform"];
    let pair = |v: &Value| -> Vec<f64> {
        v.as_array()
            .map(|a| a.iter().filter_map(Value::as_f64).collect())
            .unwrap_or_default()
    };
    assert_eq!(pair(&t["scale"]), [2.0, 2.0], "{t}");
    assert_eq!(pair(&t["offset"]), [0.25, 0.0], "{t}");

    // spot_external.gltf: three textures and the buffer in separate files beside it.
    let j = gltf_json(&assets.external);
    let uris: Vec<&str> = j["images"]
        .as_array()
        .unwrap()
        .iter()
        .chain(j["buffers"].as_array().unwrap())
        .map(|x| x["uri"].as_str().expect("an external uri"))
        .collect();
    assert_eq!(uris.len(), 4, "{uris:?}");
    for u in &uris {
        assert!(assets.dir.join(u).is_file(), "{u}");
    }
    let m = material(&j, 0);
    assert!(
        m["normalTexture"].is_object()
            && m["pbrMetallicRoughness"]["metallicRoughnessTexture"].is_object()
    );

    // spot_two.glb: two named nodes, each with its own mesh and material, one metallic.
    let j = gltf_json(&assets.two_objects);
    let names: Vec<&str> = j["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["spot_plastic", "spot_metal"]);
    let metallic = |i: usize| {
        material(&j, i)["pbrMetallicRoughness"]["metallicFactor"]
            .as_f64()
            .unwrap_or(1.0) // glTF's default
    };
    assert_eq!((metallic(0), metallic(1)), (0.0, 1.0));
}

/// Axis-aligned bounds of a mesh's positions.
fn bounds(path: &Path) -> (usize, usize, glam::Vec3, glam::Vec3) {
    let m = load_mesh(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .mesh;
    let lo = m.positions.iter().fold(glam::Vec3::MAX, |a, &p| a.min(p));
    let hi = m.positions.iter().fold(glam::Vec3::MIN, |a, &p| a.max(p));
    (m.vertex_count(), m.triangle_count(), lo, hi)
}

#[test]
fn every_asset_loads_with_the_geometry_of_the_obj() {
    let Some(assets) = gltf_assets() else { return };
    // The OBJ obj2gltf read (with its mtllib line), through relight's OBJ reader.
    let (obj_v, obj_t, lo, hi) = bounds(&assets.dir.join("spot.obj"));
    // glTF stores positions as f32, as relight does: the bounds agree to float rounding of
    // coordinates of size ~1.
    let close = |a: glam::Vec3, b: glam::Vec3| (a - b).abs().max_element() < 1e-5;
    for path in assets.all() {
        let (v, t, glo, ghi) = bounds(path);
        let name = path.file_name().unwrap().to_string_lossy();
        if name == "spot_two.glb" {
            // Twice the mesh, the second copy moved along +x by 1.5 widths.
            let shift = glam::Vec3::X * 1.5 * (hi.x - lo.x);
            assert_eq!((v, t), (2 * obj_v, 2 * obj_t), "{name}");
            assert!(
                close(glo, lo) && close(ghi, hi + shift),
                "{name}: {glo} {ghi}"
            );
        } else {
            assert_eq!((v, t), (obj_v, obj_t), "{name}");
            assert!(close(glo, lo) && close(ghi, hi), "{name}: {glo} {ghi}");
        }
    }
}

/// Each asset's textures, materials and object names reach relight: the base colour as the
/// `gltf` material's diffuse map (sRGB-decoded: the texture's mean is that of spot.png
/// decoded), the metallic-roughness and normal textures in their slots, the texture transform
/// on the map, external images read from the folder, and the two-object scene's node names
/// and metallic factors.
#[test]
fn every_asset_carries_its_textures_materials_and_names() {
    use relight_scene::material::Material;
    let Some(assets) = gltf_assets() else { return };
    for path in assets.all() {
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        let m = load_mesh(path).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(
            m.materials
                .iter()
                .all(|x| matches!(x, Material::Gltf { .. })),
            "{name}: {:?}",
            m.materials
        );
        let maps = &m.maps[0];
        let base = maps
            .diffuse
            .as_ref()
            .unwrap_or_else(|| panic!("{name}: no base colour map"));
        assert!(base.width() > 1 && base.height() > 1, "{name}");
        let has = |t: &Option<relight_scene::texture::Texture>| t.is_some();
        let mr = matches!(name.as_str(), "spot_mr.glb" | "spot_external.gltf");
        let normal = matches!(name.as_str(), "spot_normal.glb" | "spot_external.gltf");
        assert_eq!(has(&maps.metallic_roughness), mr, "{name}");
        assert_eq!(has(&maps.normal), normal, "{name}");
        assert_eq!(
            base.transform().is_some(),
            name == "spot_transform.glb",
            "{name}"
        );
        let names: Vec<&str> = m.objects.iter().map(|o| o.name.as_str()).collect();
        if name == "spot_two.glb" {
            assert_eq!(names, ["spot_plastic", "spot_metal"], "{name}");
            let metallic: Vec<f32> = m
                .materials
                .iter()
                .map(|x| match x {
                    Material::Gltf { metallic, .. } => *metallic,
                    _ => unreachable!(),
                })
                .collect();
            assert_eq!(metallic, [0.0, 1.0], "{name}");
        } else {
            assert_eq!(names.len(), 1, "{name}: {names:?}");
        }
    }
}

#[test]
fn the_validator_refuses_corrupted_files() {
    let Some(assets) = gltf_assets() else { return };
    let Some(good) = validate_gltf(&assets.spot) else {
        return;
    };
    let good = good.expect("spot.glb is valid");
    assert_eq!(good.errors, 0);

    let dir = tmpdir("gltf-assets", "corrupt");
    let bytes = std::fs::read(&assets.spot).unwrap();
    // A node naming a mesh that does not exist (same length, so the GLB's sizes still hold).
    let key = b"\"mesh\":0";
    let at = bytes
        .windows(key.len())
        .position(|w| w == key)
        .expect("spot.glb's node names mesh 0");
    let mut bad_ref = bytes.clone();
    bad_ref[at + key.len() - 1] = b'7';
    // The binary chunk cut short: its header announces more bytes than the file has.
    let truncated = bytes[..bytes.len() - 1000].to_vec();
    // The first bytes are not glTF at all.
    let mut garbage = bytes.clone();
    garbage[..4].copy_from_slice(b"junk");
    for (name, data, code) in [
        ("bad_ref.glb", bad_ref, "UNRESOLVED_REFERENCE"),
        (
            "truncated.glb",
            truncated,
            "GLB_UNEXPECTED_END_OF_CHUNK_DATA",
        ),
        ("garbage.glb", garbage, "could not detect glTF format"),
    ] {
        let path = dir.join(name);
        std::fs::write(&path, data).unwrap();
        let Some(verdict) = validate_gltf(&path) else {
            return;
        };
        let msg = verdict.expect_err(name);
        assert!(msg.contains(code), "{name}: {msg}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_generated_maps_vary_as_documented() {
    let Some(assets) = gltf_assets() else { return };
    // Metallic-roughness: roughness (G) in stripes of 0.2 and 0.9, metallic (B) of 0 and 1.
    let mr = read_png(&assets.dir.join("spot_external_metallic_roughness.png"));
    assert_eq!(mr.len(), 64 * 64);
    for (i, &[r, g, b]) in mr.iter().enumerate() {
        let x = i % 64;
        assert_eq!(r, 255, "texel {i}");
        assert_eq!(g, if (8 * x / 64) % 2 == 0 { 51 } else { 230 }, "texel {i}");
        assert_eq!(b, if (4 * x / 64) % 2 == 0 { 0 } else { 255 }, "texel {i}");
    }
    // Normal map: unit tangent-space normals facing out (+z), tilted by the bumps. 8-bit
    // encoding rounds each component by at most 1/255, so |n| is 1 within ~1.5 %.
    let nm = read_png(&assets.dir.join("spot_external_normal.png"));
    assert_eq!(nm.len(), 64 * 64);
    let decode = |t: [u8; 3]| glam::Vec3::from_array(t.map(|c| f32::from(c) / 255.0 * 2.0 - 1.0));
    let mut max_tilt = 0.0f32;
    for &t in &nm {
        let n = decode(t);
        assert!((n.length() - 1.0).abs() < 0.015, "{n}");
        assert!(n.z > 0.5, "{n}");
        max_tilt = max_tilt.max(n.z.acos());
    }
    // Slope amplitude a 2 pi k = 0.02 x 2 pi x 8 ~ 1.0: at the texel centres the steepest
    // normal tilts by 0.716 rad (41 degrees); 0.6 leaves room for the 8-bit rounding.
    assert!(
        max_tilt > 0.6,
        "the bumps tilt the normals by {max_tilt} rad at most"
    );
}
