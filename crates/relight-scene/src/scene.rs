//! A scene in memory: one merged triangle mesh, its materials, the environment and a camera.

use crate::camera::Camera;
use crate::material::maps::{self, SceneMaps};
use crate::material::Material;
use crate::mesh::TriMesh;
use crate::{Mat3, Vec3};
use relight_sphere::envmap::EnvMap;
use relight_sphere::warp::Frame;

/// Distant environment lighting: an environment map, a scale and a rotation about +Y.
///
/// Matches Mitsuba 3's `envmap` emitter with `scale` and
/// `to_world = rotate(axis=[0, 1, 0], angle=rotate_y_deg)`: the radiance arriving from world
/// direction `d` is `scale * map(env_from_world * d)`.
#[derive(Clone, Debug)]
pub struct Environment {
    /// The map, in its own layout.
    pub map: EnvMap,
    /// Radiance multiplier.
    pub scale: f32,
    /// Rotation of the map about world +Y, degrees (right-handed).
    pub rotate_y_deg: f32,
}

impl Environment {
    /// An unrotated environment of scale 1.
    pub fn new(map: EnvMap) -> Self {
        Environment {
            map,
            scale: 1.0,
            rotate_y_deg: 0.0,
        }
    }

    /// Rotation taking world directions to the map's own frame.
    pub fn env_from_world(&self) -> Mat3 {
        Mat3::from_rotation_y(-self.rotate_y_deg.to_radians())
    }

    /// Rotation taking the map's directions to world directions.
    pub fn world_from_env(&self) -> Mat3 {
        Mat3::from_rotation_y(self.rotate_y_deg.to_radians())
    }

    /// Radiance arriving from world direction `dir` (unit).
    #[inline]
    pub fn radiance(&self, dir: Vec3) -> Vec3 {
        self.map.eval(self.env_from_world() * dir) * self.scale
    }
}

/// A complete scene: geometry with per-triangle material ids, materials, lighting, camera.
#[derive(Clone, Debug)]
pub struct Scene {
    /// All shapes merged into one mesh (`material_ids` index `materials`).
    pub mesh: TriMesh,
    /// Materials (their constant parameters).
    pub materials: Vec<Material>,
    /// The materials' texture and normal maps (`SceneMaps::default()`: none).
    pub maps: SceneMaps,
    /// Distant lighting.
    pub env: Environment,
    /// The camera.
    pub camera: Camera,
    /// Named objects: contiguous triangle ranges in order covering every triangle, with
    /// unique names ([`SceneObject`]); empty for a scene built in code without names.
    pub objects: Vec<SceneObject>,
}

/// A named part of a scene: a range of the merged mesh's triangles.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct SceneObject {
    /// Unique within the scene.
    pub name: String,
    /// Its triangles (indices into `mesh.indices`).
    pub triangles: std::ops::Range<u32>,
}

/// Check that `objects` are contiguous ranges in order covering triangles `0..triangles`
/// exactly, each non-empty, with unique non-empty names; the message names the first
/// object that breaks a rule.
pub fn validate_objects(objects: &[SceneObject], triangles: u32) -> Result<(), String> {
    let mut next = 0u32;
    let mut seen = std::collections::HashSet::new();
    for o in objects {
        if o.name.is_empty() {
            return Err(format!("object {:?}: an empty name", o.triangles));
        }
        if !seen.insert(o.name.as_str()) {
            return Err(format!("object {:?}: the name is given twice", o.name));
        }
        if o.triangles.start != next || o.triangles.end <= o.triangles.start {
            return Err(format!(
                "object {:?}: triangles {}..{} do not follow on from {next} (objects must cover the triangles in order, each at least one)",
                o.name, o.triangles.start, o.triangles.end
            ));
        }
        next = o.triangles.end;
    }
    if next != triangles {
        return Err(format!(
            "the objects cover triangles 0..{next} of {triangles}"
        ));
    }
    Ok(())
}

impl Scene {
    /// The material and shading frame at barycentrics `bary` of triangle `tri`, whose
    /// interpolated shading normal is `n` ([`maps::shading_at`]).
    #[inline]
    pub fn shading_at(&self, tri: u32, bary: [f32; 3], n: Vec3) -> (Material, Frame) {
        maps::shading_at(&self.mesh, &self.materials, &self.maps, tri, bary, n)
    }
}
