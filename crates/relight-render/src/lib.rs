//! # relight-render: images out of scenes and bakes
//!
//! The CPU rasteriser with per-method shading, the reference path tracer, tone mapping and
//! image comparison. Conventions are those of `relight_sphere` (Mitsuba 3's, +Y up).

pub mod compare;
pub mod decompose_picture;
pub mod hybrid;
pub mod image;
pub mod light;
pub mod mapped;
pub mod mitsuba;
pub mod pathtrace;
pub mod plot;
pub mod raster;
pub mod shade_cuts;
pub mod shade_local;
pub mod shade_sg;
pub mod shade_sh;
pub mod shade_vmf;
pub mod shadowmap;
pub mod text;
pub mod tonemap;

pub use image::{read_image, write_image, Image, ImageError, ImageFormat};
