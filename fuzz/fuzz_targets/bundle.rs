//! Baked bundles, in two ways per input:
//! 1. the input as a bundle file: the container (header, checksums, tensor layout);
//! 2. the input as edits of a real `sh` bundle (baked once per process from a tiny scene)
//!    re-serialised with valid checksums, so that the loaders' content checks (shapes,
//!    ranges, indices, settings, records) see inputs past the checksums. Each edit is 4
//!    bytes: which tensor or metadata key, where, and the new byte; metadata edits replace
//!    one character.
#![no_main]
use libfuzzer_sys::fuzz_target;
use relight_bundle::Bundle;
use relight_method::sh::Sh;
use relight_method::{BakeContext, BakeInput, Method};
use std::path::Path;
use std::sync::OnceLock;

fn real() -> &'static Bundle {
    static B: OnceLock<Bundle> = OnceLock::new();
    B.get_or_init(|| {
        let origin = Path::new("<fuzz>");
        let desc = relight_scene::scene_file::SceneDesc::from_json(
            origin,
            r#"{"shapes": [{"type": "sphere", "center": [0, 0.5, 0], "radius": 0.5, "rings": 3},
                           {"type": "plane", "center": [0, 0, 0], "size": 2, "divisions": 1}],
                "environment": {"type": "constant", "radiance": [1, 1, 1]},
                "camera": {"origin": [0, 1, 3], "target": [0, 0.5, 0], "up": [0, 1, 0],
                           "fov_deg": 40, "width": 8, "height": 6}}"#,
        )
        .expect("scene JSON");
        let scene = desc.build(origin).expect("tiny scene");
        let input = BakeInput {
            desc: &desc,
            scene: &scene,
            origin,
        };
        let mut settings = <Sh as Method>::Settings::default();
        (settings.order, settings.samples) = (2, 4);
        let baked = Sh::bake(
            input,
            &settings,
            0..scene.mesh.vertex_count(),
            &BakeContext::default(),
        )
        .expect("tiny bake");
        Sh::store(&baked).expect("store")
    })
}

fuzz_target!(|data: &[u8]| {
    let path = Path::new("fuzz.relight");
    if let Ok(b) = Bundle::from_bytes(path, data) {
        let _ = relight_method::from_bundle(&b, path);
    }
    let mut b = real().clone();
    let keys: Vec<String> = b.metadata.keys().cloned().collect();
    let names: Vec<String> = b.tensors.keys().cloned().collect();
    for e in data.chunks_exact(4) {
        let (which, at, value) = (
            e[0] as usize,
            u16::from_le_bytes([e[1], e[2]]) as usize,
            e[3],
        );
        if which % 2 == 0 {
            let t = b
                .tensors
                .get_mut(&names[which / 2 % names.len()])
                .expect("tensor");
            if !t.bytes.is_empty() {
                let i = at % t.bytes.len();
                t.bytes[i] = value;
            }
        } else {
            let v = b
                .metadata
                .get_mut(&keys[which / 2 % keys.len()])
                .expect("key");
            let mut bytes = std::mem::take(v).into_bytes();
            if !bytes.is_empty() {
                let i = at % bytes.len();
                bytes[i] = value;
            }
            *v = String::from_utf8_lossy(&bytes).into_owned();
        }
    }
    if let Ok(b) = Bundle::from_bytes(path, &b.to_bytes()) {
        let _ = relight_method::from_bundle(&b, path);
    }
});
