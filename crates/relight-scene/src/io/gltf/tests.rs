//! Tests of the glTF reader: small files built here (JSON, base64 buffers, GLB, PNGs).

use super::buffers::base64_decode;
use super::*;
use crate::io::files;
use crate::io::{load_mesh, test_util::base64_encode, test_util::temp_dir};
use std::path::PathBuf;

/// A unit quad in the z = 0 plane: 4 positions, 4 UVs, 6 u16 indices (no normals).
fn quad_bin() -> Vec<u8> {
    let mut b = Vec::new();
    for p in [[0f32, 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]] {
        p.iter().for_each(|v| b.extend_from_slice(&v.to_le_bytes()));
    }
    for t in [[0f32, 0.], [1., 0.], [1., 1.], [0., 1.]] {
        t.iter().for_each(|v| b.extend_from_slice(&v.to_le_bytes()));
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        b.extend_from_slice(&i.to_le_bytes());
    }
    b
}

fn quad_json(uri: Option<&str>, idx_count: usize) -> String {
    let uri = uri.map_or(String::new(), |u| format!("\"uri\": \"{u}\", "));
    format!(
        r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0]}}],
        "nodes": [{{"children": [1], "translation": [0, 0, 5]}}, {{"mesh": 0, "scale": [2, 2, 2]}}],
        "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0, "TEXCOORD_0": 1}}, "indices": 2, "material": 0}}]}}],
        "materials": [{{"pbrMetallicRoughness": {{"baseColorFactor": [0.5, 0.25, 1, 1], "metallicFactor": 0, "roughnessFactor": 0.5}}}}],
        "buffers": [{{{uri}"byteLength": 92}}],
        "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 48}}, {{"buffer": 0, "byteOffset": 48, "byteLength": 32}},
                        {{"buffer": 0, "byteOffset": 80, "byteLength": 12}}],
        "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"}},
                      {{"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"}},
                      {{"bufferView": 2, "componentType": 5123, "count": {idx_count}, "type": "SCALAR"}}]}}"#
    )
}

fn check_quad(m: &LoadedMesh) {
    assert_eq!(m.mesh.indices, vec![[0, 1, 2], [0, 2, 3]]);
    assert_eq!(m.mesh.positions[2], Vec3::new(2.0, 2.0, 5.0)); // scaled by 2, moved by +5 z
    assert!(m
        .mesh
        .normals
        .iter()
        .all(|n| (*n - Vec3::Z).length() < 1e-6));
    // TEXCOORD_0 (1, 1), v flipped to OBJ's upward convention.
    assert_eq!(m.mesh.uvs.as_ref().unwrap()[2], Vec2::new(1.0, 0.0));
    assert_eq!(
        m.materials,
        vec![Material::Gltf {
            base_color: Vec3::new(0.5, 0.25, 1.0),
            metallic: 0.0,
            roughness: 0.5,
        }]
    );
}

#[test]
fn embedded_base64_gltf_reads() {
    let dir = temp_dir("gltf");
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64_encode(&quad_bin())
    );
    let p = dir.join("q.gltf");
    std::fs::write(&p, quad_json(Some(&uri), 6)).unwrap();
    check_quad(&load_mesh(&p).unwrap());
}

#[test]
fn external_bin_gltf_reads() {
    let dir = temp_dir("gltfbin");
    std::fs::write(dir.join("q.bin"), quad_bin()).unwrap();
    let p = dir.join("q.gltf");
    std::fs::write(&p, quad_json(Some("q.bin"), 6)).unwrap();
    check_quad(&load_mesh(&p).unwrap());
}

fn glb(json: &str, bin: &[u8]) -> Vec<u8> {
    let mut j = json.as_bytes().to_vec();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    let mut out = b"glTF".to_vec();
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&((12 + 8 + j.len() + 8 + bin.len()) as u32).to_le_bytes());
    out.extend_from_slice(&(j.len() as u32).to_le_bytes());
    out.extend_from_slice(&0x4E4F_534Au32.to_le_bytes());
    out.extend_from_slice(&j);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(&0x004E_4942u32.to_le_bytes());
    out.extend_from_slice(bin);
    out
}

#[test]
fn glb_reads() {
    let dir = temp_dir("glb");
    let p = dir.join("q.glb");
    std::fs::write(&p, glb(&quad_json(None, 6), &quad_bin())).unwrap();
    check_quad(&load_mesh(&p).unwrap());
}

#[test]
fn malformed_gltf_json_names_the_line() {
    let dir = temp_dir("gltfbad");
    let p = dir.join("bad.gltf");
    std::fs::write(
        &p,
        "{\n\"asset\": {\"version\": \"2.0\"},\n\"nodes\": [ {\"mesh\": } ]\n}",
    )
    .unwrap();
    let e = load_mesh(&p).unwrap_err().to_string();
    assert!(e.contains("bad.gltf: line 3"), "{e}");
}

/// A POSITION attribute naming an accessor the file does not have is an error, not a panic
/// in the `gltf` crate's validation (found by the fuzzer).
#[test]
fn an_attribute_naming_a_missing_accessor_is_an_error() {
    let dir = temp_dir("gltfacc");
    let p = dir.join("a.gltf");
    std::fs::write(
        &p,
        r#"{"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
            "nodes": [{"mesh": 0}], "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}]}"#,
    )
    .unwrap();
    let e = load_mesh(&p).unwrap_err().to_string();
    assert!(e.contains("a.gltf") && e.contains("accessor 0"), "{e}");
}

#[test]
fn truncated_gltf_is_an_error() {
    let dir = temp_dir("gltftrunc");
    let p = dir.join("t.gltf");
    let json = quad_json(Some("q.bin"), 6);
    std::fs::write(&p, &json[..json.len() / 2]).unwrap();
    let e = load_mesh(&p).unwrap_err().to_string();
    assert!(e.contains("t.gltf: line") && e.contains("EOF"), "{e}");
}

#[test]
fn accessor_beyond_buffer_is_refused() {
    let dir = temp_dir("gltfhuge");
    std::fs::write(dir.join("q.bin"), quad_bin()).unwrap();
    let p = dir.join("q.gltf");
    std::fs::write(&p, quad_json(Some("q.bin"), 4_000_000_000)).unwrap();
    let e = load_mesh(&p).unwrap_err();
    assert!(matches!(e, SceneError::TooLarge { .. }), "{e}");
}

#[test]
fn malformed_and_truncated_glb_are_errors() {
    let dir = temp_dir("glbbad");
    let p = dir.join("bad.glb");
    let good = glb(&quad_json(None, 6), &quad_bin());
    std::fs::write(&p, &good[..good.len() - 20]).unwrap();
    let e = load_mesh(&p).unwrap_err().to_string();
    assert!(e.contains("bad.glb") && e.contains("truncated"), "{e}");
    let mut bad = good.clone();
    bad[0] = b'x';
    std::fs::write(&p, &bad).unwrap();
    assert!(load_mesh(&p).unwrap_err().to_string().contains("magic"));
    std::fs::write(&p, b"glTF").unwrap();
    assert!(load_mesh(&p).is_err());
}

#[test]
fn missing_external_buffer_is_an_io_error() {
    let dir = temp_dir("gltfmiss");
    let p = dir.join("q.gltf");
    std::fs::write(&p, quad_json(Some("gone.bin"), 6)).unwrap();
    let e = load_mesh(&p).unwrap_err();
    assert!(
        matches!(e, SceneError::Io { .. }) && e.to_string().contains("gone.bin"),
        "{e}"
    );
}

#[test]
fn cyclic_node_graph_is_refused() {
    let dir = temp_dir("gltfcycle");
    std::fs::write(dir.join("q.bin"), quad_bin()).unwrap();
    let p = dir.join("c.gltf");
    let json = quad_json(Some("q.bin"), 6).replace(
        r#"{"mesh": 0, "scale": [2, 2, 2]}"#,
        r#"{"mesh": 0, "children": [0]}"#,
    );
    std::fs::write(&p, json).unwrap();
    assert!(load_mesh(&p)
        .unwrap_err()
        .to_string()
        .contains("not a tree"));
}

/// `root/model/q.gltf` whose buffer `uri` is `uri`, and the buffer at `root/outside/q.bin`.
fn model_and_outside_buffer(tag: &str, uri: impl Fn(&Path) -> String) -> PathBuf {
    let root = temp_dir(tag);
    std::fs::create_dir_all(root.join("model")).unwrap();
    std::fs::create_dir_all(root.join("outside")).unwrap();
    std::fs::write(root.join("outside/q.bin"), quad_bin()).unwrap();
    let p = root.join("model/q.gltf");
    std::fs::write(&p, quad_json(Some(&uri(&root)), 6)).unwrap();
    p
}

fn allow_outside() -> LoadOptions {
    LoadOptions {
        paths: files::PathPolicy {
            allow_outside: true,
        },
        ..LoadOptions::default()
    }
}

#[test]
fn buffer_uri_climbing_out_of_the_folder_is_refused_unless_allowed() {
    let p = model_and_outside_buffer("gltfdotdot", |_| "../outside/q.bin".into());
    let e = load_mesh(&p).unwrap_err();
    assert!(matches!(e, SceneError::OutsideFolder { .. }), "{e}");
    assert!(
        e.to_string().contains("buffer 0 uri '../outside/q.bin'")
            && e.to_string().contains("--allow-outside-paths"),
        "{e}"
    );
    // Percent-encoded dots climb out the same way.
    let p2 = p.with_file_name("enc.gltf");
    std::fs::write(&p2, quad_json(Some("%2e%2e/outside/q.bin"), 6)).unwrap();
    assert!(matches!(
        load_mesh(&p2).unwrap_err(),
        SceneError::OutsideFolder { .. }
    ));
    // The opt-in reads it.
    check_quad(&crate::io::load_mesh_with(&p, &allow_outside()).unwrap());
    // Deep climbs towards system files are refused without touching them.
    let p3 = p.with_file_name("passwd.gltf");
    let deep = "../".repeat(40) + "etc/passwd";
    std::fs::write(&p3, quad_json(Some(&deep), 6)).unwrap();
    assert!(matches!(
        load_mesh(&p3).unwrap_err(),
        SceneError::OutsideFolder { .. }
    ));
}

#[test]
fn absolute_buffer_uri_is_refused_unless_allowed() {
    let p = model_and_outside_buffer("gltfabs", |root| {
        root.join("outside/q.bin").display().to_string()
    });
    let e = load_mesh(&p).unwrap_err();
    assert!(matches!(e, SceneError::OutsideFolder { .. }), "{e}");
    check_quad(&crate::io::load_mesh_with(&p, &allow_outside()).unwrap());
    // A URI with a scheme is refused either way.
    let p2 = p.with_file_name("file.gltf");
    std::fs::write(&p2, quad_json(Some("file:///etc/passwd"), 6)).unwrap();
    for opts in [LoadOptions::default(), allow_outside()] {
        let e = crate::io::load_mesh_with(&p2, &opts).unwrap_err();
        assert!(matches!(e, SceneError::Unsupported { .. }), "{e}");
    }
}

#[cfg(unix)]
#[test]
fn symlink_out_of_the_folder_is_refused_unless_allowed() {
    let p = model_and_outside_buffer("gltflink", |_| "link.bin".into());
    let root = p.parent().unwrap().parent().unwrap().to_path_buf();
    std::os::unix::fs::symlink(root.join("outside/q.bin"), root.join("model/link.bin")).unwrap();
    let e = load_mesh(&p).unwrap_err();
    assert!(matches!(e, SceneError::OutsideFolder { .. }), "{e}");
    check_quad(&crate::io::load_mesh_with(&p, &allow_outside()).unwrap());
    // A symlinked folder inside the model's folder leads out the same way.
    std::os::unix::fs::symlink(root.join("outside"), root.join("model/sub")).unwrap();
    let p2 = p.with_file_name("sub.gltf");
    std::fs::write(&p2, quad_json(Some("sub/q.bin"), 6)).unwrap();
    assert!(matches!(
        load_mesh(&p2).unwrap_err(),
        SceneError::OutsideFolder { .. }
    ));
    // A symlink that stays inside is fine.
    std::fs::copy(root.join("outside/q.bin"), root.join("model/real.bin")).unwrap();
    std::os::unix::fs::symlink("real.bin", root.join("model/inside.bin")).unwrap();
    let p3 = p.with_file_name("inside.gltf");
    std::fs::write(&p3, quad_json(Some("inside.bin"), 6)).unwrap();
    check_quad(&load_mesh(&p3).unwrap());
}

#[test]
fn dev_zero_buffer_with_the_opt_in_fails_without_reading_it() {
    if !Path::new("/dev/zero").exists() {
        relight_testdata::skip_platform("dev-zero", "no /dev/zero");
        return;
    }
    let dir = temp_dir("gltfzero");
    let p = dir.join("z.gltf");
    // A byteLength as large as a real buffer may be: still not read from a device.
    let json = quad_json(Some("/dev/zero"), 6)
        .replace(r#""byteLength": 92}]"#, r#""byteLength": 4000000000}]"#);
    std::fs::write(&p, json).unwrap();
    let e = crate::io::test_util::within_seconds(10, move || {
        crate::io::load_mesh_with(&p, &allow_outside()).unwrap_err()
    });
    assert!(matches!(e, SceneError::NotRegularFile { .. }), "{e}");
    assert!(e.to_string().contains("/dev/zero"), "{e}");
}

/// 1000 nodes, each instancing one mesh of 1000 primitives that share one 300-vertex
/// accessor: 1e8 triangles (3e8 vertices) from about 50 KB of JSON.
fn instancing_bomb() -> String {
    let mut bin = Vec::new();
    for i in 0..300u32 {
        let v = [(i % 3) as f32, (i / 3 % 2) as f32, (i / 6) as f32];
        v.iter()
            .for_each(|x| bin.extend_from_slice(&x.to_le_bytes()));
    }
    let prims = vec![r#"{"attributes": {"POSITION": 0}}"#; 1000].join(",");
    let nodes = vec![r#"{"mesh": 0}"#; 1000].join(",");
    let roots: Vec<String> = (0..1000).map(|i| i.to_string()).collect();
    format!(
        r#"{{"asset": {{"version": "2.0"}}, "scenes": [{{"nodes": [{}]}}], "nodes": [{nodes}],
        "meshes": [{{"primitives": [{prims}]}}],
        "buffers": [{{"uri": "data:application/octet-stream;base64,{}", "byteLength": 3600}}],
        "bufferViews": [{{"buffer": 0, "byteLength": 3600}}],
        "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 300, "type": "VEC3"}}]}}"#,
        roots.join(","),
        base64_encode(&bin)
    )
}

#[test]
fn instancing_bomb_is_refused_before_expanding() {
    let dir = temp_dir("gltfbomb");
    let p = dir.join("bomb.gltf");
    let json = instancing_bomb();
    assert!(json.len() < 60_000);
    std::fs::write(&p, &json).unwrap();
    let e = crate::io::test_util::within_seconds(20, move || load_mesh(&p).unwrap_err());
    assert!(
        matches!(
            e,
            SceneError::TooManyTriangles {
                count: 100_000_000,
                limit: 50_000_000,
                ..
            }
        ),
        "{e}"
    );
    let s = e.to_string();
    assert!(
        s.contains("bomb.gltf") && s.contains("50000000") && s.contains("--max-triangles"),
        "{s}"
    );
}

#[test]
fn triangle_limit_applies_to_a_small_gltf() {
    let dir = temp_dir("gltflimit");
    std::fs::write(dir.join("q.bin"), quad_bin()).unwrap();
    let p = dir.join("q.gltf");
    std::fs::write(&p, quad_json(Some("q.bin"), 6)).unwrap();
    let one = LoadOptions {
        max_triangles: 1,
        ..LoadOptions::default()
    };
    let e = crate::io::load_mesh_with(&p, &one).unwrap_err();
    assert!(
        matches!(
            e,
            SceneError::TooManyTriangles {
                count: 2,
                limit: 1,
                ..
            }
        ),
        "{e}"
    );
    let two = LoadOptions {
        max_triangles: 2,
        ..LoadOptions::default()
    };
    check_quad(&crate::io::load_mesh_with(&p, &two).unwrap());
}

#[test]
fn base64_round_trip() {
    let data: Vec<u8> = (0..=255u8).collect();
    for n in [0, 1, 2, 3, 100, 256] {
        assert_eq!(
            base64_decode(&base64_encode(&data[..n])).unwrap(),
            &data[..n]
        );
    }
    assert!(base64_decode("ab$c").is_err());
}

mod textures;
