//! OBJ + MTL: the input up to its first NUL is `m.obj`, the rest `m.mtl` (which the OBJ
//! may name with `mtllib m.mtl`).
#![no_main]
use libfuzzer_sys::fuzz_target;
use relight_fuzz::{split_nul, with_files};

fuzz_target!(|data: &[u8]| {
    let (obj, mtl) = split_nul(data);
    with_files(&[("m.obj", obj), ("m.mtl", mtl)], |p| {
        let _ = relight_scene::io::load_mesh(p);
    });
});
