//! # relight-render: images out of scenes and bakes
//!
//! The CPU rasteriser with per-method shading, the reference path tracer, tone mapping and
//! image comparison. Conventions are those of `relight_sphere` (Mitsuba 3's, +Y up).

pub mod image;

pub use image::Image;
