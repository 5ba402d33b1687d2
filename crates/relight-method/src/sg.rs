//! The `sg` method: view-dependent glossy PRT with spherical Gaussians (Green 2005). The bake
//! is `relight_bake::sg` (tabulation and the fit of eq. 2.2-2.6), the frame
//! `relight_render::shade_sg` (view blend per vertex, lobe blend per pixel, one prefiltered
//! fetch per lobe).

mod frame;
mod store;

pub use frame::{SgFrame, SgFrameSettings};
pub use store::SG_LOBE_FLOATS;

use crate::store::{BakeRecord, BakedScene};
use crate::{build_caster, BakeContext, BakeInput, BakeKind, Method, MethodError};
use glam::Vec3;
use relight_bake::sg::{self, SgBake, SgBakeSettings};
use relight_bundle::Bundle;
use relight_scene::error::Invalid;
use relight_scene::material::Material;
use relight_scene::scene::Scene;
use serde::{Deserialize, Serialize};
use std::ops::Range;
use std::path::Path;
use std::time::Instant;

/// The `sg` method's bake verbs.
pub struct Sg;

/// A spatially varying material (thesis section 2.3.1, the paper's "bird"): the scene's one
/// material at the lowest vertex along `axis`, `to` at the highest, blended linearly.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MaterialBlend {
    /// The material at the highest vertex.
    pub to: Material,
    /// The blend axis (any length but zero).
    pub axis: Vec3,
}

impl MaterialBlend {
    /// A blend to `to` along `axis`: `to` is a material as inline JSON (starting with `{`)
    /// or the path of a `.json` file holding one (a regular file of at most 64 MiB).
    ///
    /// # Errors
    /// [`MethodError::Settings`] naming the file or the JSON and the problem.
    pub fn parse(to: &str, axis: Vec3) -> Result<MaterialBlend, MethodError> {
        let bad = |m: String| MethodError::Settings(m);
        let (text, origin) = if to.trim_start().starts_with('{') {
            (to.to_string(), "the blend material".to_string())
        } else {
            let bytes = relight_scene::io::files::read_file(
                Path::new(to),
                relight_scene::io::files::MAX_TEXT_BYTES,
                "material file",
            )
            .map_err(|e| bad(format!("blend material: not inline JSON, and {e}")))?;
            (String::from_utf8_lossy(&bytes).into_owned(), to.to_string())
        };
        let to: Material = serde_json::from_str(&text)
            .map_err(|e| bad(format!("{origin}: not a valid material: {e}")))?;
        to.validate().map_err(|e| bad(format!("{origin}: {e}")))?;
        if !(axis.is_finite() && axis != Vec3::ZERO) {
            return Err(bad(format!("blend axis {axis} has no direction")));
        }
        Ok(MaterialBlend { to, axis })
    }
}

/// The settings of an `sg` bake, as recorded in its bundle.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SgSettings {
    /// The bake's settings.
    #[serde(flatten)]
    pub bake: SgBakeSettings,
    /// A material blend across the mesh, if any.
    #[serde(default)]
    pub blend: Option<MaterialBlend>,
}

/// Everything an `sg` bundle holds.
#[derive(Clone, Debug)]
pub struct SgBaked {
    /// The scene it was baked from.
    pub scene: BakedScene,
    /// The bake: lobes, diffuse transfer, per-vertex materials, fit statistics.
    pub bake: SgBake,
    /// The settings.
    pub settings: SgSettings,
    /// How the bake ran.
    pub record: BakeRecord,
}

impl SgBaked {
    /// Bytes per vertex of the transfer (lobes of every view plus diffuse SH) as stored.
    pub fn transfer_bytes_per_vertex(&self) -> usize {
        let b = if self.record.f16 { 2 } else { 4 };
        let lobes =
            self.bake.direct.lobe_count + self.bake.indirect.as_ref().map_or(0, |l| l.lobe_count);
        b * (self.bake.direct.view_count * lobes * SG_LOBE_FLOATS + self.bake.diffuse.coeff_count())
    }

    /// A human description (one line each) and the same figures as JSON: views, lobes,
    /// stored bytes per vertex, distinct materials and the fit's statistics (what `relight
    /// bake` and `relight info` print).
    pub fn describe(&self) -> (Vec<String>, serde_json::Value) {
        let (s, k, st) = (&self.settings.bake, &self.bake, &self.bake.stats);
        let distinct = k
            .materials
            .iter()
            .map(|m| format!("{m:?}"))
            .collect::<std::collections::BTreeSet<_>>()
            .len();
        let blend = self.settings.blend.as_ref().map_or(String::new(), |b| {
            format!(" (blend to {:?} along {})", b.to, b.axis)
        });
        let lines = vec![
            format!(
                "SG (Green 2005): {} views (icosahedron frequency {}), {} direct + {} indirect lobes per vertex and view, diffuse SH order {}",
                k.direct.view_count, k.view_frequency, s.direct_lobes, s.indirect_lobes, s.diffuse_order
            ),
            format!(
                "transfer: {} bytes per vertex as {}; {distinct} distinct per-vertex materials{blend}",
                self.transfer_bytes_per_vertex(),
                if self.record.f16 { "f16" } else { "f32" },
            ),
            format!(
                "fit: mean relative L2 error {:.4} direct, {:.4} indirect; {} LM iterations; flips {} -> {} after relaxation",
                st.mean_relative_error[0], st.mean_relative_error[1], st.iterations, st.flips, st.flips_after_relaxation
            ),
        ];
        let json = serde_json::json!({
            "views": k.direct.view_count,
            "direct_lobes": s.direct_lobes,
            "indirect_lobes": s.indirect_lobes,
            "transfer_bytes_per_vertex": self.transfer_bytes_per_vertex(),
            "distinct_materials": distinct,
            "fit_mean_relative_error": st.mean_relative_error,
            "fit_iterations": st.iterations,
            "flips": st.flips,
            "flips_after_relaxation": st.flips_after_relaxation,
        });
        (lines, json)
    }

    /// Check every invariant of the contents: lobe arrays of the right sizes, unit axes,
    /// positive sharpness, finite non-negative amplitudes, one valid material per vertex,
    /// the diffuse transfer's layout.
    ///
    /// # Errors
    /// A message naming the first violation.
    pub fn validate(&self) -> Result<(), Invalid> {
        self.validate_msg().map_err(Invalid)
    }

    fn validate_msg(&self) -> Result<(), String> {
        let v = self.scene.mesh.vertex_count();
        let k = &self.bake;
        let views = 10 * k.view_frequency * k.view_frequency + 2;
        let s = &self.settings.bake;
        let comps = [
            ("sg_direct", Some(&k.direct), s.direct_lobes),
            ("sg_indirect", k.indirect.as_ref(), s.indirect_lobes),
        ];
        for (name, lobes, count) in comps {
            let Some(l) = lobes else {
                if count > 0 {
                    return Err(format!("{name}: missing ({count} lobes in the settings)"));
                }
                continue;
            };
            if l.view_count != views || l.lobe_count != count || l.lobes.len() != v * views * count
            {
                return Err(format!(
                    "{name}: {} lobes of {} views x {} per vertex for {v} vertices, expected {views} views x {count}",
                    l.lobes.len(),
                    l.view_count,
                    l.lobe_count
                ));
            }
            for (i, g) in l.lobes.iter().enumerate() {
                let len = g.axis.length();
                let amp_ok = g.amplitude.is_finite() && g.amplitude.min_element() >= 0.0;
                if !((len - 1.0).abs() <= 1e-2
                    && g.sharpness.is_finite()
                    && g.sharpness > 0.0
                    && amp_ok)
                {
                    return Err(format!(
                        "{name}: lobe {i} has axis length {len}, sharpness {} and amplitude {} (expected a unit axis, a positive sharpness and non-negative amplitudes)",
                        g.sharpness, g.amplitude
                    ));
                }
            }
        }
        if k.materials.len() != v {
            return Err(format!(
                "{} vertex materials for {v} vertices",
                k.materials.len()
            ));
        }
        for m in &k.materials {
            m.validate()
                .map_err(|e| format!("vertex material {m:?}: {e}"))?;
        }
        if k.diffuse.vertex_count != v || k.diffuse.order != s.diffuse_order {
            return Err(format!(
                "diffuse transfer of {} vertices and order {} for {v} vertices and order {}",
                k.diffuse.vertex_count, k.diffuse.order, s.diffuse_order
            ));
        }
        k.diffuse
            .validate()
            .map_err(|e| format!("diffuse transfer: {e}"))
    }
}

/// Per-vertex materials of a blend over `scene` (which must use one material).
///
/// # Errors
/// [`MethodError::Settings`] for a scene of several materials, a zero axis or materials of
/// different kinds.
pub fn blend_materials(scene: &Scene, blend: &MaterialBlend) -> Result<Vec<Material>, MethodError> {
    let mut used = scene.mesh.material_ids.clone();
    used.sort_unstable();
    used.dedup();
    let [only] = used[..] else {
        return Err(MethodError::Settings(format!(
            "a material blend needs a scene with one material (this one uses {})",
            used.len()
        )));
    };
    blend
        .to
        .validate()
        .map_err(|e| MethodError::Settings(format!("blend material: {e}")))?;
    let a = scene.materials[only as usize];
    sg::transport::blend_along_axis(&scene.mesh, &a, &blend.to, blend.axis)
        .map_err(|e| MethodError::Settings(format!("material blend: {e}")))
}

impl Method for Sg {
    const KIND: BakeKind = BakeKind::Sg;
    type Settings = SgSettings;
    type Baked = SgBaked;

    fn validate(s: &SgSettings) -> Result<(), MethodError> {
        Ok(s.bake.validate()?)
    }

    fn bake(
        input: BakeInput,
        settings: &SgSettings,
        range: Range<usize>,
        ctx: &BakeContext,
    ) -> Result<SgBaked, MethodError> {
        Sg::validate(settings)?;
        let scene = input.scene;
        let n = scene.mesh.vertex_count();
        if range != (0..n) {
            // The flood fill couples neighbouring vertices (eq. 2.6) and aligns whole regions
            // afterwards, so a vertex range alone is not a well-defined part of the bake.
            return Err(MethodError::Settings(format!(
                "sg bakes the whole mesh at once (vertices 0..{n}, asked {}..{}): its flood fill couples neighbouring vertices",
                range.start, range.end
            )));
        }
        let blended = settings
            .blend
            .as_ref()
            .map(|b| blend_materials(scene, b))
            .transpose()?;
        let t0 = Instant::now();
        let caster = build_caster(&input, ctx)?;
        let bake_settings = SgBakeSettings {
            progress: ctx.progress,
            ..settings.bake
        };
        let bake = sg::bake(
            &scene.mesh,
            &scene.materials,
            blended.as_deref(),
            caster.as_ref(),
            &bake_settings,
        )?;
        Ok(SgBaked {
            scene: BakedScene::of(&input),
            bake,
            settings: SgSettings {
                bake: SgBakeSettings {
                    progress: false,
                    threads: None,
                    ..settings.bake
                },
                blend: settings.blend,
            },
            record: BakeRecord::new(
                caster.name(),
                t0.elapsed().as_secs_f64(),
                ctx.f16,
                &range,
                n,
            ),
        })
    }

    fn store(b: &SgBaked) -> Result<Bundle, MethodError> {
        store::store(b)
    }

    fn load(bundle: &Bundle, path: &Path) -> Result<SgBaked, MethodError> {
        store::load(bundle, path)
    }
}

#[cfg(test)]
mod tests;
