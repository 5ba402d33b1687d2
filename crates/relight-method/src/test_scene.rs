//! The small scenes the method tests bake: a Lambert sphere of `radius` (8 rings) on a plane
//! under a constant environment (the sharding and checkpoint tests), and a lone sphere.

use crate::BakeInput;
use relight_scene::scene_file::SceneDesc;
use std::path::Path;

/// The description.
pub fn desc(radius: f32) -> SceneDesc {
    serde_json::from_str(&format!(
        r#"{{"shapes": [
              {{"type": "sphere", "center": [0, 0.6, 0], "radius": {radius}, "rings": 8,
               "material": {{"type": "lambert", "albedo": [0.8, 0.3, 0.2]}}}},
              {{"type": "plane", "center": [0, 0, 0], "size": 3, "divisions": 4}}],
            "environment": {{"type": "constant", "radiance": [1, 1, 1]}},
            "camera": {{"origin": [0, 1.5, 3], "target": [0, 0.4, 0], "up": [0, 1, 0],
                       "fov_deg": 40, "width": 24, "height": 16}}}}"#
    ))
    .expect("test scene")
}

/// Albedo of [`lone_sphere`].
pub const LONE_ALBEDO: [f32; 3] = [0.8, 0.3, 0.2];

/// A lone Lambert sphere of albedo [`LONE_ALBEDO`] (radius 1, 12 rings) under constant radiance
/// 1, seen head-on from `(0, 0, 4)` (24 x 18 pixels, 40 degrees across): convex, so every point
/// sees its whole upper hemisphere unoccluded and reflects exactly its albedo. Its disc is
/// centred on the image, 8.5 pixels in radius.
pub fn lone_sphere() -> SceneDesc {
    serde_json::from_str(
        r#"{"shapes": [
              {"type": "sphere", "center": [0, 0, 0], "radius": 1, "rings": 12,
               "material": {"type": "lambert", "albedo": [0.8, 0.3, 0.2]}}],
            "environment": {"type": "constant", "radiance": [1, 1, 1]},
            "camera": {"origin": [0, 0, 4], "target": [0, 0, 0], "up": [0, 1, 0],
                       "fov_deg": 40, "width": 24, "height": 18}}"#,
    )
    .expect("lone sphere")
}

/// Run `f` with the bake input of the scene with `radius`.
pub fn with_input<T>(radius: f32, f: impl FnOnce(BakeInput) -> T) -> T {
    with_desc(desc(radius), f)
}

/// Run `f` with the bake input of scene `d`.
pub fn with_desc<T>(d: SceneDesc, f: impl FnOnce(BakeInput) -> T) -> T {
    let origin = Path::new("<test>");
    let scene = d.build(origin).expect("test scene");
    f(BakeInput {
        desc: &d,
        scene: &scene,
        origin,
    })
}
