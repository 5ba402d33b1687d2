//! Radiance HDR (flat and RLE scanlines) as an environment in each layout (the first byte
//! picks it, the rest is the file).
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| relight_fuzz::load_env_any_layout("e.hdr", data));
