//! OpenEXR (through the `exr` crate: scanline and tiled, compressions, mip levels) as an
//! environment in each layout (the first byte picks it, the rest is the file).
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| relight_fuzz::load_env_any_layout("e.exr", data));
