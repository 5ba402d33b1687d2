//! A baked scene in memory and its bundle form (tensor names and metadata: docs/BUNDLE.md).

use anyhow::{bail, Context, Result};
use glam::{Vec2, Vec3};
use relight_bake::sh::{ShTransfer, ShTransferKind};
use relight_bundle::{Bundle, Tensor};
use relight_scene::material::Material;
use relight_scene::mesh::TriMesh;
use relight_scene::scene_file::SceneDesc;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The bake settings as recorded in a bundle.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RecordedSettings {
    /// SH order.
    pub order: usize,
    /// `unshadowed`, `shadowed` or `interreflected`.
    pub transfer: String,
    /// Interreflection bounces (0 otherwise).
    pub bounces: u32,
    /// Directions per vertex.
    pub samples: u32,
    /// Seed.
    pub seed: u64,
    /// Whether the transfer is stored as f16.
    pub f16: bool,
    /// Ray-casting back-end.
    pub backend: String,
    /// Wall time of the bake, seconds.
    pub seconds: f64,
}

/// Everything an `sh` bundle holds.
pub struct ShBake {
    /// The scene the bake came from (environment and camera are defaults for rendering).
    pub scene: SceneDesc,
    /// The merged mesh.
    pub mesh: TriMesh,
    /// Materials.
    pub materials: Vec<Material>,
    /// Per-vertex diffuse albedo.
    pub albedo: Vec<Vec3>,
    /// The transfer.
    pub transfer: ShTransfer,
    /// Settings.
    pub settings: RecordedSettings,
}

fn flat3(v: &[Vec3]) -> Vec<f32> {
    v.iter().flat_map(|p| p.to_array()).collect()
}

fn unflat3(v: &[f32]) -> Vec<Vec3> {
    v.chunks_exact(3).map(Vec3::from_slice).collect()
}

impl ShBake {
    /// Build the bundle.
    pub fn to_bundle(&self) -> Result<Bundle> {
        let mut b = Bundle::new();
        let m = &self.mesh;
        let (v, t) = (m.vertex_count(), m.triangle_count());
        b.metadata.insert("method".into(), "sh".into());
        b.metadata
            .insert("relight_version".into(), env!("CARGO_PKG_VERSION").into());
        b.metadata
            .insert("settings".into(), serde_json::to_string(&self.settings)?);
        b.metadata
            .insert("scene".into(), serde_json::to_string(&self.scene)?);
        b.metadata
            .insert("materials".into(), serde_json::to_string(&self.materials)?);
        b.insert(
            "positions",
            Tensor::from_f32(vec![v, 3], &flat3(&m.positions)),
        );
        b.insert("normals", Tensor::from_f32(vec![v, 3], &flat3(&m.normals)));
        if let Some(uv) = &m.uvs {
            let f: Vec<f32> = uv.iter().flat_map(|p| p.to_array()).collect();
            b.insert("uvs", Tensor::from_f32(vec![v, 2], &f));
        }
        let idx: Vec<u32> = m.indices.iter().flatten().copied().collect();
        b.insert("indices", Tensor::from_u32(vec![t, 3], &idx));
        b.insert("material_ids", Tensor::from_u32(vec![t], &m.material_ids));
        b.insert("albedo", Tensor::from_f32(vec![v, 3], &flat3(&self.albedo)));
        let tr = &self.transfer;
        let shape = vec![tr.vertex_count, tr.coeff_count(), tr.channels];
        b.insert(
            "transfer",
            if self.settings.f16 {
                Tensor::from_f32_as_f16(shape, &tr.data)
            } else {
                Tensor::from_f32(shape, &tr.data)
            },
        );
        Ok(b)
    }

    /// Read and check an `sh` bundle.
    pub fn read(path: &Path) -> Result<ShBake> {
        let b = Bundle::read(path)?;
        let method = b.meta(path, "method")?;
        if method != "sh" {
            bail!("{}: bundle method '{method}' is not 'sh'", path.display());
        }
        let ctx = |what: &str| format!("{}: metadata '{what}' is not valid", path.display());
        let settings: RecordedSettings =
            serde_json::from_str(b.meta(path, "settings")?).with_context(|| ctx("settings"))?;
        let scene: SceneDesc =
            serde_json::from_str(b.meta(path, "scene")?).with_context(|| ctx("scene"))?;
        let materials: Vec<Material> =
            serde_json::from_str(b.meta(path, "materials")?).with_context(|| ctx("materials"))?;
        // A required tensor of the expected shape.
        let shaped = |name: &str, shape: &[usize]| -> Result<&Tensor> {
            let t = b.tensor(path, name)?;
            if t.shape != shape {
                bail!(
                    "{}: tensor '{name}' has shape {:?}, expected {:?}",
                    path.display(),
                    t.shape,
                    shape
                );
            }
            Ok(t)
        };
        let f32s = |name: &str, shape: &[usize]| -> Result<Vec<f32>> {
            shaped(name, shape)?.to_f32().with_context(|| {
                format!("{}: tensor '{name}' is not floating point", path.display())
            })
        };
        let u32s = |name: &str, shape: &[usize]| -> Result<Vec<u32>> {
            shaped(name, shape)?
                .to_u32()
                .with_context(|| format!("{}: tensor '{name}' is not U32", path.display()))
        };
        let v = b
            .tensor(path, "positions")?
            .shape
            .first()
            .copied()
            .unwrap_or(0);
        let t = b
            .tensor(path, "indices")?
            .shape
            .first()
            .copied()
            .unwrap_or(0);
        let positions = unflat3(&f32s("positions", &[v, 3])?);
        let normals = unflat3(&f32s("normals", &[v, 3])?);
        let uvs = match b.tensors.get("uvs") {
            Some(_) => Some(
                f32s("uvs", &[v, 2])?
                    .chunks_exact(2)
                    .map(Vec2::from_slice)
                    .collect(),
            ),
            None => None,
        };
        let idx = u32s("indices", &[t, 3])?;
        if let Some(bad) = idx.iter().find(|&&i| i as usize >= v) {
            bail!(
                "{}: triangle index {bad} out of range ({v} vertices)",
                path.display()
            );
        }
        let material_ids = u32s("material_ids", &[t])?;
        if let Some(bad) = material_ids
            .iter()
            .find(|&&i| i as usize >= materials.len())
        {
            bail!(
                "{}: material id {bad} out of range ({} materials)",
                path.display(),
                materials.len()
            );
        }
        let albedo = unflat3(&f32s("albedo", &[v, 3])?);
        let kind = match settings.transfer.as_str() {
            "unshadowed" => ShTransferKind::Unshadowed,
            "shadowed" => ShTransferKind::Shadowed,
            "interreflected" => ShTransferKind::Interreflected {
                bounces: settings.bounces,
            },
            k => bail!("{}: unknown transfer kind '{k}'", path.display()),
        };
        let n2 = relight_sphere::sh::sh_count(settings.order);
        let data = f32s("transfer", &[v, n2, kind.channels()])?;
        let transfer = ShTransfer {
            order: settings.order,
            kind,
            vertex_count: v,
            channels: kind.channels(),
            data,
        };
        transfer
            .validate()
            .map_err(|e| anyhow::anyhow!("{}: transfer: {e}", path.display()))?;
        let mesh = TriMesh {
            positions,
            normals,
            uvs,
            indices: idx.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            material_ids,
        };
        Ok(ShBake {
            scene,
            mesh,
            materials,
            albedo,
            transfer,
            settings,
        })
    }
}

/// Name of a transfer kind in settings and on the command line.
pub fn kind_name(k: ShTransferKind) -> &'static str {
    match k {
        ShTransferKind::Unshadowed => "unshadowed",
        ShTransferKind::Shadowed => "shadowed",
        ShTransferKind::Interreflected { .. } => "interreflected",
    }
}
