//! Baked scenes in memory and their bundle form (tensor names and metadata: docs/BUNDLE.md):
//! `sh` bundles ([`ShBake`]) and `sg` bundles ([`SgBundle`]).

use anyhow::{bail, Context, Result};
use glam::{Vec2, Vec3};
use relight_bake::sg::{SgBake, SgBakeSettings, SgFitStats, SgLobes};
use relight_bake::sh::{ShTransfer, ShTransferKind};
use relight_bundle::{Bundle, Tensor};
use relight_scene::material::Material;
use relight_scene::mesh::TriMesh;
use relight_scene::scene_file::SceneDesc;
use relight_sphere::sg::SgLobe;
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

/// The mesh tensors: positions, normals, optional uvs, indices, material ids.
fn insert_mesh(b: &mut Bundle, m: &TriMesh) {
    let (v, t) = (m.vertex_count(), m.triangle_count());
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
}

/// Checked access to the tensors of a bundle read from `path` (named in every error).
struct TensorReader<'a> {
    b: &'a Bundle,
    path: &'a Path,
}

impl<'a> TensorReader<'a> {
    /// A required tensor of the expected shape.
    fn shaped(&self, name: &str, shape: &[usize]) -> Result<&'a Tensor> {
        let t = self.b.tensor(self.path, name)?;
        if t.shape != shape {
            bail!(
                "{}: tensor '{name}' has shape {:?}, expected {shape:?}",
                self.path.display(),
                t.shape
            );
        }
        Ok(t)
    }

    /// A floating-point tensor of the expected shape, every value finite.
    fn f32s(&self, name: &str, shape: &[usize]) -> Result<Vec<f32>> {
        let p = self.path.display();
        let v = self
            .shaped(name, shape)?
            .to_f32()
            .with_context(|| format!("{p}: tensor '{name}' is not floating point"))?;
        if let Some(i) = v.iter().position(|x| !x.is_finite()) {
            bail!("{p}: tensor '{name}' has a non-finite value at element {i}");
        }
        Ok(v)
    }

    /// A U32 tensor of the expected shape.
    fn u32s(&self, name: &str, shape: &[usize]) -> Result<Vec<u32>> {
        self.shaped(name, shape)?
            .to_u32()
            .with_context(|| format!("{}: tensor '{name}' is not U32", self.path.display()))
    }

    /// The mesh tensors (positions, normals, optional uvs, indices, material ids), checked
    /// against each other and against `materials` scene materials.
    fn mesh(&self, materials: usize) -> Result<TriMesh> {
        let p = self.path.display();
        let first = |name: &str| -> Result<usize> {
            Ok(self
                .b
                .tensor(self.path, name)?
                .shape
                .first()
                .copied()
                .unwrap_or(0))
        };
        let (v, t) = (first("positions")?, first("indices")?);
        let positions = unflat3(&self.f32s("positions", &[v, 3])?);
        let normals = unflat3(&self.f32s("normals", &[v, 3])?);
        let uvs = match self.b.tensors.get("uvs") {
            Some(_) => Some(
                self.f32s("uvs", &[v, 2])?
                    .chunks_exact(2)
                    .map(Vec2::from_slice)
                    .collect(),
            ),
            None => None,
        };
        let idx = self.u32s("indices", &[t, 3])?;
        if let Some(bad) = idx.iter().find(|&&i| i as usize >= v) {
            bail!("{p}: triangle index {bad} out of range ({v} vertices)");
        }
        let material_ids = self.u32s("material_ids", &[t])?;
        if let Some(bad) = material_ids.iter().find(|&&i| i as usize >= materials) {
            bail!("{p}: material id {bad} out of range ({materials} materials)");
        }
        Ok(TriMesh {
            positions,
            normals,
            uvs,
            indices: idx.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            material_ids,
        })
    }
}

impl ShBake {
    /// Build the bundle.
    pub fn to_bundle(&self) -> Result<Bundle> {
        let mut b = Bundle::new();
        let m = &self.mesh;
        let v = m.vertex_count();
        b.metadata.insert("method".into(), "sh".into());
        b.metadata
            .insert("relight_version".into(), env!("CARGO_PKG_VERSION").into());
        b.metadata
            .insert("settings".into(), serde_json::to_string(&self.settings)?);
        b.metadata
            .insert("scene".into(), serde_json::to_string(&self.scene)?);
        b.metadata
            .insert("materials".into(), serde_json::to_string(&self.materials)?);
        insert_mesh(&mut b, m);
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
        let r = TensorReader { b: &b, path };
        let mesh = r.mesh(materials.len())?;
        let v = mesh.vertex_count();
        let albedo = unflat3(&r.f32s("albedo", &[v, 3])?);
        let kind = match settings.transfer.as_str() {
            "unshadowed" => ShTransferKind::Unshadowed,
            "shadowed" => ShTransferKind::Shadowed,
            "interreflected" => ShTransferKind::Interreflected {
                bounces: settings.bounces,
            },
            k => bail!("{}: unknown transfer kind '{k}'", path.display()),
        };
        let n2 = relight_sphere::sh::sh_count(settings.order);
        let data = r.f32s("transfer", &[v, n2, kind.channels()])?;
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

// ---------------------------------------------------------------------------------------------
// `sg` bundles (Green 2005 view-dependent glossy PRT; tensor names in docs/BUNDLE.md)

/// Floats per stored lobe: axis x, y, z, sharpness, amplitude r, g, b.
pub const SG_LOBE_FLOATS: usize = 7;

/// Largest finite f16: lobe values are clamped to it when stored as f16.
const F16_MAX: f32 = 65504.0;

/// The SG bake settings as recorded in a bundle: every `SgBakeSettings` field (the fit's
/// prefixed `fit_`) plus how the bundle was made.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SgRecordedSettings {
    /// Frequency of the view icosahedron (3: 92 views).
    pub view_frequency: usize,
    /// Direct-glossy cube-map face size.
    pub direct_res: usize,
    /// Indirect-glossy cube-map face size.
    pub indirect_res: usize,
    /// Indirect paths per (vertex, view).
    pub indirect_paths: u32,
    /// Bounces of an indirect path.
    pub max_depth: u32,
    /// SH order of the diffuse part.
    pub diffuse_order: usize,
    /// View clamping elevation, degrees.
    pub horizon_deg: f32,
    /// Whether visibility was traced (`false`: `--no-visibility`).
    #[serde(default = "yes")]
    pub visibility: bool,
    /// Direct lobes.
    pub direct_lobes: usize,
    /// Indirect lobes (0: none).
    pub indirect_lobes: usize,
    /// Levenberg-Marquardt iterations.
    pub fit_max_iterations: usize,
    /// Mean-alignment weight (eq. 2.4).
    pub fit_mean_weight: f64,
    /// Width-alignment weight (eq. 2.5).
    pub fit_width_weight: f64,
    /// Spatial weight (eq. 2.6).
    pub fit_spatial_weight: f64,
    /// Relaxation sweeps.
    pub fit_relax_sweeps: usize,
    /// Flood-fill regions (0: automatic).
    pub fit_regions: usize,
    /// Amplitudes rescaled to the data's integral.
    #[serde(default = "yes")]
    pub fit_energy: bool,
    /// Seed.
    pub seed: u64,
    /// Material blend, if any (`--blend-to` / `--blend-axis`, as given).
    pub blend: Option<String>,
    /// Whether lobes and diffuse transfer are stored as f16.
    pub f16: bool,
    /// Ray-casting back-end.
    pub backend: String,
    /// Wall time of the bake, seconds.
    pub seconds: f64,
}

impl SgRecordedSettings {
    /// The record of `s` (storage fields left for the caller).
    pub fn new(s: &SgBakeSettings, view_frequency: usize) -> Self {
        SgRecordedSettings {
            view_frequency,
            direct_res: s.direct_res,
            indirect_res: s.indirect_res,
            indirect_paths: s.indirect_paths,
            max_depth: s.max_depth,
            diffuse_order: s.diffuse_order,
            horizon_deg: s.horizon_deg,
            visibility: s.visibility,
            direct_lobes: s.direct_lobes,
            indirect_lobes: s.indirect_lobes,
            fit_max_iterations: s.fit.max_iterations,
            fit_mean_weight: s.fit.mean_weight,
            fit_width_weight: s.fit.width_weight,
            fit_spatial_weight: s.fit.spatial_weight,
            fit_relax_sweeps: s.fit.relax_sweeps,
            fit_regions: s.fit.regions,
            fit_energy: s.fit.energy,
            seed: s.seed,
            blend: None,
            f16: false,
            backend: String::new(),
            seconds: 0.0,
        }
    }
}

fn yes() -> bool {
    true
}

/// `SgFitStats` as recorded in a bundle.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct RecordedStats {
    mean_relative_error: [f64; 2],
    iterations: u64,
    flips: u64,
    flips_after_relaxation: u64,
}

/// Everything an `sg` bundle holds.
pub struct SgBundle {
    /// The scene the bake came from (environment and camera are defaults for rendering).
    pub scene: SceneDesc,
    /// The merged mesh.
    pub mesh: TriMesh,
    /// The scene's materials (indexed by `mesh.material_ids`).
    pub materials: Vec<Material>,
    /// The bake (lobes, diffuse transfer, per-vertex materials, fit statistics).
    pub bake: SgBake,
    /// Settings.
    pub settings: SgRecordedSettings,
}

fn lobes_flat(l: &SgLobes, f16: bool) -> Vec<f32> {
    let c = |x: f32| if f16 { x.clamp(-F16_MAX, F16_MAX) } else { x };
    l.lobes
        .iter()
        .flat_map(|g| {
            let (a, m) = (g.axis, g.amplitude);
            [a.x, a.y, a.z, c(g.sharpness), c(m.x), c(m.y), c(m.z)]
        })
        .collect()
}

impl SgBundle {
    /// Bytes per vertex of the transfer (lobes of every view plus diffuse SH) as stored.
    pub fn transfer_bytes_per_vertex(&self) -> usize {
        let b = if self.settings.f16 { 2 } else { 4 };
        let lobes =
            self.bake.direct.lobe_count + self.bake.indirect.as_ref().map_or(0, |l| l.lobe_count);
        b * (self.bake.direct.view_count * lobes * SG_LOBE_FLOATS + self.bake.diffuse.coeff_count())
    }

    /// Build the bundle.
    pub fn to_bundle(&self) -> Result<Bundle> {
        let mut b = Bundle::new();
        let m = &self.mesh;
        let v = m.vertex_count();
        let meta = |b: &mut Bundle, k: &str, s: String| b.metadata.insert(k.into(), s);
        meta(&mut b, "method", "sg".into());
        meta(&mut b, "relight_version", env!("CARGO_PKG_VERSION").into());
        meta(&mut b, "settings", serde_json::to_string(&self.settings)?);
        meta(&mut b, "scene", serde_json::to_string(&self.scene)?);
        meta(&mut b, "materials", serde_json::to_string(&self.materials)?);
        let st = &self.bake.stats;
        let stats = RecordedStats {
            mean_relative_error: st.mean_relative_error,
            iterations: st.iterations,
            flips: st.flips,
            flips_after_relaxation: st.flips_after_relaxation,
        };
        meta(&mut b, "sg_stats", serde_json::to_string(&stats)?);
        // Distinct per-vertex materials (one per vertex only when blended).
        let mut palette: Vec<Material> = vec![];
        let mut index: std::collections::HashMap<String, u32> = Default::default();
        let mut ids = Vec::with_capacity(v);
        for mat in &self.bake.materials {
            let key = serde_json::to_string(mat)?;
            let id = *index.entry(key).or_insert_with(|| {
                palette.push(*mat);
                (palette.len() - 1) as u32
            });
            ids.push(id);
        }
        meta(&mut b, "sg_materials", serde_json::to_string(&palette)?);
        insert_mesh(&mut b, m);
        b.insert("sg_vertex_material", Tensor::from_u32(vec![v], &ids));
        let f16 = self.settings.f16;
        let float = |shape: Vec<usize>, data: &[f32]| {
            if f16 {
                Tensor::from_f32_as_f16(shape, data)
            } else {
                Tensor::from_f32(shape, data)
            }
        };
        for (name, l) in [
            ("sg_direct", Some(&self.bake.direct)),
            ("sg_indirect", self.bake.indirect.as_ref()),
        ] {
            if let Some(l) = l {
                let shape = vec![v, l.view_count, l.lobe_count, SG_LOBE_FLOATS];
                b.insert(name, float(shape, &lobes_flat(l, f16)));
            }
        }
        let d = &self.bake.diffuse;
        b.insert("sg_diffuse", float(vec![v, d.coeff_count(), 1], &d.data));
        Ok(b)
    }

    /// Read and check an `sg` bundle.
    pub fn read(path: &Path) -> Result<SgBundle> {
        SgBundle::from_bundle(path, &Bundle::read(path)?)
    }

    /// Check and convert a bundle read from `path` (named in errors).
    pub fn from_bundle(path: &Path, b: &Bundle) -> Result<SgBundle> {
        let p = path.display();
        let method = b.meta(path, "method")?;
        if method != "sg" {
            bail!("{p}: bundle method '{method}' is not 'sg' (bake with --method sg)");
        }
        let ctx = |what: &str| format!("{p}: metadata '{what}' is not valid");
        let json = |k: &str| -> Result<&str> { Ok(b.meta(path, k)?) };
        let settings: SgRecordedSettings =
            serde_json::from_str(json("settings")?).with_context(|| ctx("settings"))?;
        let scene: SceneDesc =
            serde_json::from_str(json("scene")?).with_context(|| ctx("scene"))?;
        let materials: Vec<Material> =
            serde_json::from_str(json("materials")?).with_context(|| ctx("materials"))?;
        let palette: Vec<Material> =
            serde_json::from_str(json("sg_materials")?).with_context(|| ctx("sg_materials"))?;
        let stats: RecordedStats =
            serde_json::from_str(json("sg_stats")?).with_context(|| ctx("sg_stats"))?;
        for m in palette.iter().chain(&materials) {
            m.validate()
                .map_err(|e| anyhow::anyhow!("{p}: material {m:?}: {e}"))?;
        }
        let r = TensorReader { b, path };
        let mesh = r.mesh(materials.len())?;
        let v = mesh.vertex_count();
        let (f32s, u32s) = (
            |n: &str, sh: &[usize]| r.f32s(n, sh),
            |n: &str, sh: &[usize]| r.u32s(n, sh),
        );
        let vertex_materials = u32s("sg_vertex_material", &[v])?
            .iter()
            .map(|&i| {
                palette.get(i as usize).copied().with_context(|| {
                    format!(
                        "{p}: vertex material {i} out of range ({} in sg_materials)",
                        palette.len()
                    )
                })
            })
            .collect::<Result<Vec<_>>>()?;
        if settings.view_frequency == 0 || settings.view_frequency > 64 {
            bail!(
                "{p}: view frequency {} is not in 1..=64",
                settings.view_frequency
            );
        }
        let f = settings.view_frequency;
        let views = 10 * f * f + 2;
        let lobes = |name: &str, count: usize| -> Result<SgLobes> {
            let tensor = b.tensor(path, name)?;
            let raw = f32s(name, &[v, views, count, SG_LOBE_FLOATS])?;
            let renormalise = tensor.dtype == relight_bundle::DType::F16;
            let lobes = raw
                .chunks_exact(SG_LOBE_FLOATS)
                .enumerate()
                .map(|(i, c)| {
                    let axis = Vec3::new(c[0], c[1], c[2]);
                    let len = axis.length();
                    if (len - 1.0).abs() > 1e-2 || c[3] <= 0.0 {
                        bail!(
                            "{p}: tensor '{name}': lobe {i} has axis length {len} or sharpness {} (expected a unit axis and a positive sharpness)",
                            c[3]
                        );
                    }
                    Ok(SgLobe {
                        axis: if renormalise { axis / len } else { axis },
                        sharpness: c[3],
                        amplitude: Vec3::new(c[4], c[5], c[6]),
                    })
                })
                .collect::<Result<Vec<_>>>()?;
            Ok(SgLobes {
                lobe_count: count,
                view_count: views,
                lobes,
            })
        };
        let direct = lobes("sg_direct", settings.direct_lobes)?;
        let indirect = match settings.indirect_lobes {
            0 => None,
            n => Some(lobes("sg_indirect", n)?),
        };
        let order = settings.diffuse_order;
        if !(1..=relight_sphere::sh::MAX_ORDER).contains(&order) {
            bail!("{p}: diffuse SH order {order} is out of range");
        }
        let n2 = relight_sphere::sh::sh_count(order);
        let diffuse = ShTransfer {
            order,
            kind: ShTransferKind::Shadowed,
            vertex_count: v,
            channels: 1,
            data: f32s("sg_diffuse", &[v, n2, 1])?,
        };
        diffuse
            .validate()
            .map_err(|e| anyhow::anyhow!("{p}: diffuse transfer: {e}"))?;
        let bake = SgBake {
            view_frequency: f,
            direct,
            indirect,
            diffuse,
            materials: vertex_materials,
            stats: SgFitStats {
                mean_relative_error: stats.mean_relative_error,
                iterations: stats.iterations,
                flips: stats.flips,
                flips_after_relaxation: stats.flips_after_relaxation,
            },
        };
        Ok(SgBundle {
            scene,
            mesh,
            materials,
            bake,
            settings,
        })
    }
}

#[cfg(test)]
#[path = "store_sg_tests.rs"]
mod sg_tests;
