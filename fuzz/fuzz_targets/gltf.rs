//! glTF: an input starting with `glTF` is a GLB, else the part up to the first NUL is a
//! `.gltf` JSON and the rest its external buffer or image `b.bin` (a `uri` of "b.bin" reads
//! it).
#![no_main]
use libfuzzer_sys::fuzz_target;
use relight_fuzz::{split_nul, with_files};

fuzz_target!(|data: &[u8]| {
    if data.starts_with(b"glTF") {
        with_files(&[("m.glb", data)], |p| {
            let _ = relight_scene::io::load_mesh(p);
        });
    } else {
        let (json, bin) = split_nul(data);
        with_files(&[("m.gltf", json), ("b.bin", bin)], |p| {
            let _ = relight_scene::io::load_mesh(p);
        });
    }
});
