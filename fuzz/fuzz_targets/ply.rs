//! PLY, ASCII and binary (both byte orders).
#![no_main]
use libfuzzer_sys::fuzz_target;
use relight_fuzz::with_files;

fuzz_target!(|data: &[u8]| {
    with_files(&[("m.ply", data)], |p| {
        let _ = relight_scene::io::load_mesh(p);
    });
});
