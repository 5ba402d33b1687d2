//! The small scene the sharding and checkpoint tests bake: a Lambert sphere of `radius` (8
//! rings) on a plane, under a constant environment.

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

/// Run `f` with the bake input of the scene with `radius`.
pub fn with_input<T>(radius: f32, f: impl FnOnce(BakeInput) -> T) -> T {
    let d = desc(radius);
    let origin = Path::new("<test>");
    let scene = d.build(origin).expect("test scene");
    f(BakeInput {
        desc: &d,
        scene: &scene,
        origin,
    })
}
