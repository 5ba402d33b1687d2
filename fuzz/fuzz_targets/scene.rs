//! Scene description JSON: parsed, validated and built (procedural shapes, skies, constant
//! environments; a mesh or map it names is looked for beside it and is absent).
#![no_main]
use libfuzzer_sys::fuzz_target;
use relight_fuzz::with_files;
use relight_scene::scene_file::SceneDesc;

fuzz_target!(|data: &[u8]| {
    with_files(&[("s.json", data)], |p| {
        if let Ok(desc) = SceneDesc::read(p) {
            let _ = desc.build(p);
        }
    });
});
