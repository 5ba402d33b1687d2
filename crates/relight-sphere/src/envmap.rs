//! Environment maps in memory (placeholder until the spherical toolkit lands; see lib.rs).
use crate::Vec3;

/// An environment map.
#[derive(Clone, Debug)]
pub struct EnvMap {
    /// Texels.
    pub texels: Vec<Vec3>,
}

impl EnvMap {
    /// Radiance from `dir`.
    pub fn eval(&self, _dir: Vec3) -> Vec3 {
        unimplemented!("replaced by the spherical toolkit")
    }
}
