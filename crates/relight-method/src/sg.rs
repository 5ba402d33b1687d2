//! The `sg` method: view-dependent glossy PRT with spherical Gaussians (Green 2005). The bake
//! is `relight_bake::sg` (tabulation and the fit of eq. 2.2-2.6), the frame
//! `relight_render::shade_sg` (view blend per vertex, lobe blend per pixel, one prefiltered
//! fetch per lobe).

mod frame;
mod store;

pub use frame::{SgBlend, SgFrame, SgFrameSettings, SgMatch, SgViewBlend};
pub use store::SG_LOBE_FLOATS;

use crate::shard::Shard;
use crate::store::{BakeRecord, BakedScene};
use crate::{build_caster, BakeContext, BakeInput, BakeKind, Method, MethodError};
use glam::Vec3;
use relight_bake::sg::fit::PartFit;
use relight_bake::sg::{self, LobeSetting, SgBake, SgBakeSettings, SgFitStats, SgLobes, SgPart};
use relight_bake::sh::{ShTransfer, ShTransferKind};
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
        let to = crate::parse_material(to).map_err(|e| bad(format!("blend material: {e}")))?;
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

impl SgSettings {
    /// These settings with the lobes [`LobeSetting::for_materials`] chooses for `materials`
    /// and the blend's material (what `relight bake` and `relight eval` do when no lobe
    /// option is given), and the reason.
    pub fn with_lobes_for(self, materials: &[Material]) -> (SgSettings, &'static str) {
        let blend = self.blend.as_ref().map(|b| &b.to);
        let (lobes, why) = LobeSetting::for_materials(materials.iter().chain(blend));
        let settings = SgSettings {
            bake: SgBakeSettings {
                fit: self.bake.fit.with_lobes(lobes),
                ..self.bake
            },
            ..self
        };
        (settings, why)
    }
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
    /// For a part of a sharded bake ([`crate::shard`]): which vertices `bake`'s rows are.
    /// `None` for a whole bake.
    pub part: Option<SgPartRows>,
}

/// What a part of a sharded `sg` bake holds besides its rows: which vertices they are (those
/// of its flood-fill regions, ascending) and the fit errors the merge's statistics need.
#[derive(Clone, Debug, PartialEq)]
pub struct SgPartRows {
    /// The vertices of the rows, ascending.
    pub vertices: Vec<u32>,
    /// Per component (direct, then indirect): relative L2 error per row and view (negative:
    /// no data).
    pub errors: Vec<Vec<f32>>,
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
                "SG (Green 2005): {} views (icosahedron frequency {}), {} direct + {} indirect lobes per vertex and view ({}), diffuse SH order {}",
                k.direct.view_count, k.view_frequency, s.direct_lobes, s.indirect_lobes, s.fit.lobes().describe(), s.diffuse_order
            ),
            format!(
                "transfer: {} bytes per vertex as {}; {distinct} distinct per-vertex materials{blend}",
                self.transfer_bytes_per_vertex(),
                if self.record.f16 { "f16" } else { "f32" },
            ),
            match &self.part {
                None => format!(
                    "fit: mean relative L2 error {:.4} direct, {:.4} indirect; {} LM iterations; flips {} -> {} after relaxation",
                    st.mean_relative_error[0], st.mean_relative_error[1], st.iterations, st.flips, st.flips_after_relaxation
                ),
                Some(p) => format!(
                    "fit of a part ({} vertices): {} LM iterations; errors and flips are counted by the merge",
                    p.vertices.len(),
                    st.iterations
                ),
            },
        ];
        let json = serde_json::json!({
            "views": k.direct.view_count,
            "direct_lobes": s.direct_lobes,
            "indirect_lobes": s.indirect_lobes,
            "lobes": s.fit.lobes().describe(),
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
        let k = &self.bake;
        let views = 10 * k.view_frequency * k.view_frequency + 2;
        let v = match &self.part {
            None => self.scene.mesh.vertex_count(),
            Some(p) => {
                p.validate(self.scene.mesh.vertex_count(), views, k.indirect.is_some())?;
                p.vertices.len()
            }
        };
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
    const PART_UNIT: &'static str = "flood-fill region";

    fn validate(s: &SgSettings) -> Result<(), MethodError> {
        Ok(s.bake.validate()?)
    }

    fn bake(
        input: BakeInput,
        settings: &SgSettings,
        range: Range<usize>,
        ctx: &BakeContext,
    ) -> Result<SgBaked, MethodError> {
        let n = input.scene.mesh.vertex_count();
        if range != (0..n) {
            // The flood fill couples neighbouring vertices (eq. 2.6) and aligns whole regions
            // afterwards: a part is a set of regions (`bake_shard`), not a vertex range.
            return Err(MethodError::Settings(format!(
                "sg bakes the whole mesh or whole flood-fill regions (a --shard), not vertices {}..{} of {n}: its flood fill couples neighbouring vertices",
                range.start, range.end
            )));
        }
        run(input, settings, ctx, |scene, blended, caster, s| {
            let bake = sg::bake(&scene.mesh, &scene.materials, blended, caster, s)?;
            Ok((bake, None))
        })
    }

    /// Lobes of every view (each `SgLobe` 28 bytes), the diffuse SH, the fit errors.
    fn row_bytes(_: BakeInput, s: &SgSettings) -> u64 {
        let views = 10 * sg::VIEW_FREQUENCY.pow(2) as u64 + 2;
        let b = &s.bake;
        let lobes = (b.direct_lobes + b.indirect_lobes) as u64;
        let comps = 1 + u64::from(b.indirect_lobes > 0);
        views * lobes * 28
            + relight_sphere::sh::sh_count(b.diffuse_order) as u64 * 4
            + comps * views * 4
    }

    fn settings_line(s: &SgSettings) -> String {
        let b = &s.bake;
        format!(
            "SG, {} views, {} direct + {} indirect lobes ({}), cube maps 6x{r}x{r} / 6x{q}x{q}, diffuse SH order {}",
            10 * relight_bake::sg::VIEW_FREQUENCY.pow(2) + 2,
            b.direct_lobes,
            b.indirect_lobes,
            b.fit.lobes().describe(),
            b.diffuse_order,
            r = b.direct_res,
            q = b.indirect_res,
        )
    }

    fn streams(_: &SgSettings) -> Option<&'static str> {
        Some("the sg merge aligns flood-fill regions over the whole mesh")
    }

    /// One part per flood-fill region at most.
    fn max_parts(input: BakeInput, settings: &SgSettings) -> usize {
        sg::region_plan(&input.scene.mesh, &settings.bake).region_count()
    }

    /// Part `shard` is the flood-fill regions `shard.range(R)` of the mesh's `R` regions
    /// ([`relight_bake::sg::region_plan`]), fitted as the whole bake fits them.
    fn bake_shard(
        input: BakeInput,
        settings: &SgSettings,
        shard: Shard,
        ctx: &BakeContext,
    ) -> Result<SgBaked, MethodError> {
        run(input, settings, ctx, |scene, blended, caster, s| {
            let plan = sg::region_plan(&scene.mesh, s);
            let r = plan.region_count();
            if shard.count > r {
                return Err(MethodError::Settings(format!(
                    "--shard {}/{}: the mesh has {r} flood-fill regions, the unit an sg bake splits; use at most {r} parts, or more regions (--regions, up to {})",
                    shard.index,
                    shard.count,
                    relight_bake::sg::MAX_REGIONS
                )));
            }
            let part = sg::bake_regions(
                &scene.mesh,
                &scene.materials,
                blended,
                caster,
                s,
                &plan,
                shard.range(r),
            )?;
            let (bake, rows) = from_part(part, s);
            Ok((bake, Some(rows)))
        })
    }

    fn store(b: &SgBaked) -> Result<Bundle, MethodError> {
        store::store(b)
    }

    fn load(bundle: &Bundle, path: &Path) -> Result<SgBaked, MethodError> {
        store::load(bundle, path)
    }
}

/// The parts of [`Sg::bake`] and [`Sg::bake_shard`] around the bake itself: settings
/// checked, materials blended, caster built, settings and record made.
fn run(
    input: BakeInput,
    settings: &SgSettings,
    ctx: &BakeContext,
    bake: impl FnOnce(
        &Scene,
        Option<&[Material]>,
        &dyn relight_scene::accel::RayCaster,
        &SgBakeSettings,
    ) -> Result<(SgBake, Option<SgPartRows>), MethodError>,
) -> Result<SgBaked, MethodError> {
    Sg::validate(settings)?;
    let scene = input.scene;
    let n = scene.mesh.vertex_count();
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
    let (bake, part) = bake(scene, blended.as_deref(), caster.as_ref(), &bake_settings)?;
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
            &(0..n),
            n,
        ),
        part,
    })
}

/// A part's fit as rows of a bake and the part's extra data.
fn from_part(p: SgPart, s: &SgBakeSettings) -> (SgBake, SgPartRows) {
    let views = relight_sphere::icosphere::Icosphere::new(sg::VIEW_FREQUENCY)
        .vertices()
        .len();
    let n = p.fit.vertices.len();
    let mut lobes = p.fit.lobes.into_iter();
    let mut comp = |count: usize| {
        lobes.next().map(|l| SgLobes {
            lobe_count: count,
            view_count: views,
            lobes: l,
        })
    };
    let direct = comp(s.direct_lobes).unwrap_or(SgLobes {
        lobe_count: s.direct_lobes,
        view_count: views,
        lobes: vec![],
    });
    let indirect = comp(s.indirect_lobes);
    let bake = SgBake {
        view_frequency: sg::VIEW_FREQUENCY,
        direct,
        indirect,
        diffuse: ShTransfer {
            order: s.diffuse_order,
            kind: ShTransferKind::Shadowed,
            vertex_count: n,
            channels: 1,
            data: p.fit.diffuse_sh,
        },
        materials: p.materials,
        stats: SgFitStats {
            iterations: p.fit.iterations,
            ..SgFitStats::default()
        },
        kernel: s.fit.lobe_kernel.kernel(),
        domain: s.fit.lobe_domain,
        horizon_deg: s.horizon_deg,
        lobe_order: s.fit.lobe_order,
    };
    let rows = SgPartRows {
        vertices: p.fit.vertices,
        errors: p.fit.errors,
    };
    (bake, rows)
}

/// The inverse of [`from_part`].
pub(crate) fn to_part(b: SgBake, rows: SgPartRows) -> SgPart {
    let stride = b.diffuse.coeff_count();
    let mut lobes = vec![b.direct.lobes];
    lobes.extend(b.indirect.map(|l| l.lobes));
    SgPart {
        fit: PartFit {
            vertices: rows.vertices,
            lobes,
            errors: rows.errors,
            diffuse_sh: b.diffuse.data,
            diffuse_stride: stride,
            iterations: b.stats.iterations,
        },
        materials: b.materials,
    }
}

impl SgPartRows {
    /// Vertices ascending and below `mesh_vertices`; one error per view and row of each
    /// component.
    fn validate(&self, mesh_vertices: usize, views: usize, indirect: bool) -> Result<(), String> {
        if self.vertices.windows(2).any(|w| w[0] >= w[1])
            || self
                .vertices
                .last()
                .is_some_and(|&x| x as usize >= mesh_vertices)
        {
            return Err(format!(
                "part vertices are not ascending vertices of the mesh's {mesh_vertices}"
            ));
        }
        let comps = 1 + indirect as usize;
        let want = self.vertices.len() * views;
        if self.errors.len() != comps || self.errors.iter().any(|e| e.len() != want) {
            return Err(format!(
                "part errors: {:?} values per component, expected {comps} components of {want}",
                self.errors.iter().map(Vec::len).collect::<Vec<_>>()
            ));
        }
        if self.errors.iter().flatten().any(|e| !e.is_finite()) {
            return Err("part errors are not all finite".into());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
