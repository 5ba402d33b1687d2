use super::*;
use crate::io::test_util::{make_fifo, temp_dir, within_seconds};
use crate::io::{load_env, load_mesh, load_mesh_with, read_image};
use crate::scene_file::SceneDesc;

const QUAD_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";

fn allow_outside() -> LoadOptions {
    LoadOptions {
        paths: PathPolicy {
            allow_outside: true,
        },
        ..LoadOptions::default()
    }
}

#[test]
fn fifos_are_refused_without_blocking() {
    let dir = temp_dir("fifo");
    for name in ["scene.json", "m.obj", "m.ply", "m.gltf", "e.hdr", "e.exr"] {
        if !make_fifo(&dir.join(name)) {
            return;
        }
    }
    let d = dir.clone();
    let errors = within_seconds(10, move || {
        vec![
            SceneDesc::read(&d.join("scene.json")).unwrap_err(),
            load_mesh(&d.join("m.obj")).unwrap_err(),
            load_mesh(&d.join("m.ply")).unwrap_err(),
            load_mesh(&d.join("m.gltf")).unwrap_err(),
            read_image(&d.join("e.hdr")).unwrap_err(),
            load_env(&d.join("e.exr"), None).unwrap_err(),
        ]
    });
    for e in errors {
        assert!(matches!(e, SceneError::NotRegularFile { .. }), "{e}");
        assert!(e.to_string().contains("FIFO"), "{e}");
    }
    // A FIFO as a glTF buffer and as an MTL library, inside the model's folder.
    make_fifo(&dir.join("q.bin"));
    make_fifo(&dir.join("m.mtl"));
    std::fs::write(
        dir.join("b.gltf"),
        r#"{"asset": {"version": "2.0"}, "buffers": [{"uri": "q.bin", "byteLength": 92}]}"#,
    )
    .unwrap();
    std::fs::write(dir.join("mtl.obj"), format!("mtllib m.mtl\n{QUAD_OBJ}")).unwrap();
    let d = dir.clone();
    let (e, loaded) = within_seconds(10, move || {
        (
            load_mesh(&d.join("b.gltf")).unwrap_err(),
            load_mesh(&d.join("mtl.obj")).unwrap(),
        )
    });
    assert!(matches!(e, SceneError::NotRegularFile { .. }), "{e}");
    // A library that cannot be read is a warning (the default material), as a missing one.
    assert!(
        loaded
            .warnings
            .iter()
            .any(|w| w.contains("m.mtl") && w.contains("FIFO")),
        "{:?}",
        loaded.warnings
    );
}

#[test]
fn devices_are_refused_even_with_the_opt_in() {
    if !Path::new("/dev/zero").exists() {
        relight_testdata::skip_platform("dev-zero", "no /dev/zero");
        return;
    }
    let dir = temp_dir("devzero");
    std::fs::write(dir.join("m.obj"), format!("mtllib /dev/zero\n{QUAD_OBJ}")).unwrap();
    let d = dir.clone();
    let (scene, obj, mesh, image) = within_seconds(10, move || {
        (
            SceneDesc::read(Path::new("/dev/zero")).unwrap_err(),
            load_mesh_with(&d.join("m.obj"), &allow_outside()).unwrap(),
            load_mesh(Path::new("/dev/zero")).unwrap_err(),
            read_image(Path::new("/dev/zero.hdr")).unwrap_err(),
        )
    });
    assert!(
        matches!(scene, SceneError::NotRegularFile { .. }),
        "{scene}"
    );
    assert!(scene.to_string().contains("character device"), "{scene}");
    assert!(
        obj.warnings.iter().any(|w| w.contains("/dev/zero")),
        "{:?}",
        obj.warnings
    );
    assert!(matches!(mesh, SceneError::Unsupported { .. }), "{mesh}"); // no extension
    assert!(matches!(image, SceneError::Io { .. }), "{image}"); // does not exist
    let e = read_file(Path::new("/dev/zero"), MAX_FILE_BYTES, "mesh").unwrap_err();
    assert!(matches!(e, SceneError::NotRegularFile { .. }), "{e}");
}

#[test]
fn directories_are_refused() {
    let dir = temp_dir("dirread");
    let sub = dir.join("d.obj");
    std::fs::create_dir_all(&sub).unwrap();
    let e = load_mesh(&sub).unwrap_err();
    assert!(
        matches!(e, SceneError::NotRegularFile { .. }) && e.to_string().contains("directory"),
        "{e}"
    );
}

#[test]
fn files_over_their_cap_are_refused_before_reading() {
    let dir = temp_dir("cap");
    let p = dir.join("big.json");
    std::fs::write(&p, vec![b' '; 1000]).unwrap();
    let e = read_file(&p, 999, "scene description").unwrap_err();
    assert!(matches!(e, SceneError::TooLarge { .. }), "{e}");
    assert!(e.to_string().contains("999"), "{e}");
    assert_eq!(
        read_file(&p, 1000, "scene description").unwrap().len(),
        1000
    );
    assert_eq!(read_prefix(&p, 10).unwrap().len(), 10);
    assert_eq!(read_prefix(&p, 5000).unwrap().len(), 1000);
}

#[test]
fn mtllib_outside_the_folder_is_not_read_unless_allowed() {
    let root = temp_dir("mtlout");
    std::fs::create_dir_all(root.join("model")).unwrap();
    std::fs::write(root.join("red.mtl"), "newmtl red\nKd 1 0 0\n").unwrap();
    let p = root.join("model/m.obj");
    std::fs::write(
        &p,
        "mtllib ../red.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nusemtl red\nf 1 2 3\n",
    )
    .unwrap();
    let m = load_mesh(&p).unwrap();
    assert_eq!(m.materials, vec![crate::material::Material::default()]);
    assert!(
        m.warnings
            .iter()
            .any(|w| w.contains("../red.mtl") && w.contains("outside the model's folder")),
        "{:?}",
        m.warnings
    );
    let m = load_mesh_with(&p, &allow_outside()).unwrap();
    assert_eq!(
        m.materials,
        vec![crate::material::Material::Lambert {
            albedo: crate::Vec3::X
        }]
    );
}

#[test]
fn model_references_resolve_inside_the_folder() {
    let dir = temp_dir("resolve");
    std::fs::create_dir_all(dir.join("a/b")).unwrap();
    std::fs::write(dir.join("a/x.bin"), b"x").unwrap();
    let model = dir.join("a/b/../m.gltf");
    let p = PathPolicy::default();
    // `..` that stays inside the folder is fine; leaving it is not.
    assert!(resolve_model_ref(&dir.join("a/m.gltf"), "b/../x.bin", &p, "uri").is_ok());
    assert!(resolve_model_ref(&model, "../x.bin", &p, "uri").is_err());
    assert!(resolve_model_ref(&dir.join("a/m.gltf"), "/x.bin", &p, "uri").is_err());
    // A missing file inside the folder resolves (reading it then names it).
    assert!(resolve_model_ref(&dir.join("a/m.gltf"), "gone.bin", &p, "uri").is_ok());
    // A bare file name as the model resolves against the current folder.
    assert_eq!(
        resolve_model_ref(Path::new("m.gltf"), "x.bin", &p, "uri").unwrap(),
        Path::new("./x.bin")
    );
}

#[test]
fn percent_decoding() {
    assert_eq!(percent_decode("a%20b.bin"), "a b.bin");
    assert_eq!(percent_decode("%2E%2e/x"), "../x");
    assert_eq!(percent_decode("100%"), "100%");
    assert_eq!(percent_decode("%zz%4"), "%zz%4");
}
