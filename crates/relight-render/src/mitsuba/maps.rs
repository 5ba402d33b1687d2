//! The maps of a textured material as Mitsuba `bitmap` textures (conventions in the parent
//! module's docs, "Texture and normal maps").

use super::MitsubaError;
use relight_scene::material::maps::{MaterialMaps, MIN_MAP_ALPHA};
use relight_scene::material::Material;
use relight_scene::mesh::TriMesh;
use relight_scene::texture::{Filter, Texture, UvTransform, Wrap};
use relight_scene::Vec3;
use serde_json::{json, Value};
use std::path::Path;

/// A refusal of material `index`'s `map`, with the reason.
fn refuse(index: usize, map: &'static str, reason: String) -> MitsubaError {
    MitsubaError::MapUnsupported { index, map, reason }
}

/// Write `texels` (of `t`'s size) as `tex_<index>_<kind>.exr` in `dir`; the `bitmap` entry
/// of `scene.json` naming it, with `t`'s sampler and transform where they are not the
/// defaults ([`sampling`]).
fn write_texture(
    dir: &Path,
    index: usize,
    kind: &'static str,
    t: &Texture,
    texels: &[Vec3],
) -> Result<Value, MitsubaError> {
    let mut entry = sampling(index, kind, t)?;
    let name = format!("tex_{index}_{kind}.exr");
    relight_scene::io::write_exr(&dir.join(&name), t.width(), t.height(), texels)?;
    entry["bitmap"] = json!(name);
    Ok(entry)
}

/// The sampling keys of `t`'s `bitmap` entry, each only when not the default (parent module
/// docs): `wrap_mode` (`clamp`, `mirror`), `filter_type` (`nearest`) and `to_uv` (the rows
/// of the 3 x 3 affine matrix of its `KHR_texture_transform`, which acts on Mitsuba's uv as
/// on relight's image space `(s, t)`). Refused when the two axes wrap differently (Mitsuba's
/// `wrap_mode` is one for both).
fn sampling(index: usize, kind: &'static str, t: &Texture) -> Result<Value, MitsubaError> {
    let mode = |w: Wrap| match w {
        Wrap::Repeat => "repeat",
        Wrap::ClampToEdge => "clamp",
        Wrap::MirroredRepeat => "mirror",
    };
    let s = t.sampler();
    if s.wrap_s != s.wrap_t {
        return Err(refuse(
            index,
            kind,
            format!(
                "its sampler wraps s and t differently ({:?} and {:?}) while Mitsuba's bitmap \
                 has one wrap_mode for both axes",
                s.wrap_s, s.wrap_t
            ),
        ));
    }
    let mut entry = json!({});
    if s.wrap_s != Wrap::Repeat {
        entry["wrap_mode"] = json!(mode(s.wrap_s));
    }
    if s.filter == Filter::Nearest {
        entry["filter_type"] = json!("nearest");
    }
    if let Some(x) = t.transform().filter(|x| *x != UvTransform::default()) {
        let (sin, cos) = x.rotation.sin_cos();
        entry["to_uv"] = json!([
            [cos * x.scale.x, sin * x.scale.y, x.offset.x],
            [-sin * x.scale.x, cos * x.scale.y, x.offset.y],
            [0.0, 0.0, 1.0],
        ]);
    }
    Ok(entry)
}

/// `t` scaled per channel by the constant `c` that relight multiplies its lookup by (the
/// bilinear lookup of the scaled texels is `c` times the lookup, `c` being constant).
fn scaled(
    dir: &Path,
    index: usize,
    kind: &'static str,
    t: &Texture,
    c: Vec3,
) -> Result<Value, MitsubaError> {
    let texels: Vec<Vec3> = t.texels().iter().map(|x| *x * c).collect();
    write_texture(dir, index, kind, t, &texels)
}

/// The Mitsuba BSDF of material `index` (`material`, already known to have a Mitsuba
/// counterpart, and `bsdf` its constant description) with its `maps`, writing the textures
/// into `dir`. `frames()` is [`normal_map_frames`] for the material, asked only for a normal
/// map.
pub(super) fn textured_bsdf(
    dir: &Path,
    index: usize,
    material: &Material,
    mut bsdf: Value,
    maps: &MaterialMaps,
    frames: impl FnOnce() -> Result<f32, String>,
) -> Result<Value, MitsubaError> {
    let d = maps.diffuse.as_ref();
    let s = maps.specular.as_ref();
    match *material {
        Material::Lambert { albedo } => {
            if let Some(t) = d {
                bsdf["reflectance"] = scaled(dir, index, "diffuse", t, albedo)?;
            }
        }
        Material::GgxConductor { specular, .. } => {
            if let Some(t) = s {
                bsdf["specular_reflectance"] = scaled(dir, index, "specular", t, specular)?;
            }
            if let Some(t) = &maps.roughness {
                bsdf["alpha"] = roughness(dir, index, t)?;
            }
        }
        Material::GgxPlastic {
            diffuse, specular, ..
        } => {
            if maps.roughness.is_some() {
                return Err(refuse(
                    index,
                    "roughness",
                    "Mitsuba 3's roughplastic takes a scalar alpha only (no texture)".into(),
                ));
            }
            if let Some(t) = d {
                bsdf["diffuse_reflectance"] = scaled(dir, index, "diffuse", t, diffuse)?;
            }
            if let Some(t) = s {
                bsdf["specular_reflectance"] = scaled(dir, index, "specular", t, specular)?;
            }
        }
        Material::Gltf {
            base_color,
            metallic,
            roughness,
        } => {
            if let Some(t) = d {
                bsdf["base_color"] = scaled(dir, index, "diffuse", t, base_color)?;
            }
            if let Some(t) = &maps.metallic_roughness {
                // Blue times `metallic`, green times `roughness` (glTF's channels), each a
                // one-channel texture; the plugin squares the interpolated roughness.
                bsdf["metallic"] = channel(dir, index, "metallic", t, 2, metallic)?;
                bsdf["roughness"] = channel(dir, index, "roughness", t, 1, roughness)?;
            }
        }
        // Refused before the maps are looked at (no Mitsuba counterpart).
        Material::BlinnPhong { .. } | Material::Ward { .. } => {}
    }
    let Some(normal) = &maps.normal else {
        return Ok(bsdf);
    };
    let flip_green = frames().map_err(|reason| refuse(index, "normal", reason))? < 0.0;
    // `normal_scale` s: Mitsuba decodes `2 rgb - 1` and normalises, so the texels are written
    // as `(s x, s y, z) / k` with one constant `k = max(|s|, 1)` keeping them in range: the
    // bilinear lookup of those is the scaled lookup over `k`, the same direction.
    let s = maps.normal_scale;
    let k = s.abs().max(1.0);
    let texels: Vec<Vec3> = normal
        .texels()
        .iter()
        .map(|c| {
            let c = if flip_green {
                Vec3::new(c.x, 1.0 - c.y, c.z)
            } else {
                *c
            };
            if s == 1.0 {
                c
            } else {
                let n = (c * 2.0 - Vec3::ONE) * Vec3::new(s, s, 1.0) / k;
                (n + Vec3::ONE) * 0.5
            }
        })
        .collect();
    Ok(json!({
        "type": "normalmap",
        "normalmap": write_texture(dir, index, "normal", normal, &texels)?,
        "bsdf": bsdf,
    }))
}

/// Channel `c` of `t` times `factor`, written to all three channels of
/// `tex_<index>_<kind>.exr`, read as channel 0 (a scalar texture).
fn channel(
    dir: &Path,
    index: usize,
    kind: &'static str,
    t: &Texture,
    c: usize,
    factor: f32,
) -> Result<Value, MitsubaError> {
    let texels: Vec<Vec3> = t
        .texels()
        .iter()
        .map(|x| Vec3::splat(x[c] * factor))
        .collect();
    let mut v = write_texture(dir, index, kind, t, &texels)?;
    v["channel"] = json!(0);
    Ok(v)
}

/// A conductor's roughness map: the first channel (written to all three, the script reads
/// channel 0). Refused when a texel is below [`MIN_MAP_ALPHA`]: relight raises the
/// *interpolated* alpha to it, Mitsuba would interpolate raised texels, which differ between
/// texel centres.
fn roughness(dir: &Path, index: usize, t: &Texture) -> Result<Value, MitsubaError> {
    if let Some(i) = t.texels().iter().position(|c| c.x < MIN_MAP_ALPHA) {
        return Err(refuse(
            index,
            "roughness",
            format!(
                "texel ({}, {}) is {} < {MIN_MAP_ALPHA}: relight raises the interpolated alpha \
                 to {MIN_MAP_ALPHA}, Mitsuba would interpolate the texels as they are",
                i % t.width(),
                i / t.width(),
                t.texels()[i].x
            ),
        ));
    }
    let texels: Vec<Vec3> = t.texels().iter().map(|c| Vec3::splat(c.x)).collect();
    let mut v = write_texture(dir, index, "roughness", t, &texels)?;
    v["channel"] = json!(0);
    Ok(v)
}

/// Largest `1 - cos` between a corner's normal and the face normal, or its tangent and the
/// triangle's `dp/du` direction, for which the two normal-map frames count as the same
/// (about 0.08 degrees: rounding on a planar quad is ~1e-7).
const SAME_DIRECTION: f32 = 1e-6;

/// Whether relight's normal-map frame (per-vertex tangents `tangents`,
/// [`relight_scene::material::maps::vertex_tangents`]) is Mitsuba's on every triangle of
/// material `m` of `mesh` (parent module docs): every corner's normal is the face normal and
/// its tangent the triangle's `dp/du` direction, and all corners share one handedness,
/// which is returned. Otherwise the reason, naming the first triangle that differs.
pub(super) fn normal_map_frames(
    mesh: &TriMesh,
    tangents: &[glam::Vec4],
    m: u32,
) -> Result<f32, String> {
    let uvs = mesh.uvs.as_deref().unwrap_or(&[]);
    let mut sign = None;
    for (t, (tri, id)) in mesh.indices.iter().zip(&mesh.material_ids).enumerate() {
        if *id != m {
            continue;
        }
        let [a, b, c] = tri.map(|v| v as usize);
        let (Some(ua), Some(ub), Some(uc)) = (uvs.get(a), uvs.get(b), uvs.get(c)) else {
            return Err("the mesh has no texture coordinates".into());
        };
        let (e1, e2) = (
            mesh.positions[b] - mesh.positions[a],
            mesh.positions[c] - mesh.positions[a],
        );
        let (d1, d2) = (*ub - *ua, *uc - *ua);
        // dp/du up to its positive length 1 / |det| (Mitsuba's `v' = 1 - v` leaves it alone).
        let det = d1.x * d2.y - d2.x * d1.y;
        let dp_du = ((e1 * d2.y - e2 * d1.y) * det.signum()).normalize_or_zero();
        let ng = mesh.geometric_normal(t);
        if dp_du == Vec3::ZERO || ng == Vec3::ZERO || det.abs() < 1e-20 {
            return Err(format!(
                "triangle {t} has degenerate positions or texture coordinates"
            ));
        }
        for v in [a, b, c] {
            let Some(tv) = tangents.get(v) else {
                return Err("no per-vertex tangents".into());
            };
            let w = if tv.w < 0.0 { -1.0 } else { 1.0 };
            if *sign.get_or_insert(w) != w {
                return Err(
                    "its texture coordinates are mirrored on some triangles and not on others \
                     (mixed tangent handedness), while Mitsuba's normalmap takes the bitangent \
                     as n x dp/du on every triangle"
                        .into(),
                );
            }
            let n_off = 1.0 - mesh.normals[v].dot(ng);
            let t_off = 1.0
                - tv.truncate()
                    .dot((dp_du - ng * ng.dot(dp_du)).normalize_or_zero());
            if !(n_off <= SAME_DIRECTION && t_off <= SAME_DIRECTION) {
                return Err(format!(
                    "on triangle {t} (vertex {v}) the vertex normal or the per-vertex tangent \
                     differs from the face normal or the triangle's dp/du (1 - cos = {n_off:.2e}, \
                     {t_off:.2e}): Mitsuba's normalmap frame is per triangle, relight's \
                     interpolated per vertex, so only flat triangles with affine UVs \
                     (e.g. planar quads) render alike"
                ));
            }
        }
    }
    sign.ok_or_else(|| "no triangles".into())
}

#[cfg(test)]
mod tests {
    use super::super::{export_mitsuba, MitsubaError};
    use relight_scene::camera::Camera;
    use relight_scene::io::files::LoadOptions;
    use relight_scene::material::maps::{MaterialMaps, SceneMaps};
    use relight_scene::material::Material;
    use relight_scene::scene::{Environment, Scene};
    use relight_scene::shapes::{ground_plane, uv_sphere};
    use relight_scene::texture::{Filter, Texture, UvTransform, Wrap};
    use relight_scene::Vec3;
    use relight_sphere::envmap::EnvMap;
    use serde_json::Value;
    use std::sync::Arc;

    /// A 3 x 2 texture whose texel `(x, y)` is `(x / 4, y / 2, 0.75)`.
    fn ramp() -> Texture {
        let texels = (0..6)
            .map(|i| Vec3::new((i % 3) as f32 / 4.0, (i / 3) as f32 / 2.0, 0.75))
            .collect();
        Texture::new(3, 2, texels).unwrap()
    }

    /// A ground plane (material 0) and a sphere (material 1) with `maps` on `materials`.
    fn scene(materials: Vec<Material>, maps: Vec<Option<MaterialMaps>>) -> Scene {
        let mut mesh = ground_plane(Vec3::ZERO, 4.0, 2);
        mesh.append(&uv_sphere(Vec3::Y, 1.0, 6, 12), 1);
        let maps = SceneMaps::new(&mesh, maps.into_iter().map(|m| m.map(Arc::new)).collect());
        Scene {
            maps: maps.unwrap(),
            mesh,
            materials,
            env: Environment::new(EnvMap::constant(Vec3::ONE)),
            camera: Camera::look_at([0.0, 1.0, 5.0], [0.0, 1.0, 0.0], 40.0, 8, 6),
            objects: Vec::new(),
        }
    }

    fn tmp(name: &str) -> std::path::PathBuf {
        std::env::temp_dir().join(format!(
            "relight-mitsuba-maps-{name}-{}",
            std::process::id()
        ))
    }

    #[test]
    fn maps_are_written_premultiplied_with_v_flipped_and_green_flipped_when_mirrored() {
        let lambert = Material::Lambert {
            albedo: Vec3::new(0.5, 1.0, 0.8),
        };
        let conductor = Material::GgxConductor {
            specular: Vec3::splat(0.5),
            alpha: 0.3,
        };
        let s = scene(
            vec![lambert, conductor],
            vec![
                Some(MaterialMaps {
                    diffuse: Some(ramp()),
                    normal: Some(ramp()),
                    ..Default::default()
                }),
                Some(MaterialMaps {
                    specular: Some(ramp()),
                    roughness: Some(Texture::constant(Vec3::new(0.25, 0.0, 0.0)).unwrap()),
                    ..Default::default()
                }),
            ],
        );
        let dir = tmp("written");
        let json = export_mitsuba(&s, &dir, 4, 2).unwrap();
        let doc: Value = serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap();
        // Lambert with a normal map: a normalmap around a diffuse with a bitmap reflectance.
        let b0 = &doc["shapes"][0]["bsdf"];
        assert_eq!(b0["type"], "normalmap");
        assert_eq!(b0["normalmap"]["bitmap"], "tex_0_normal.exr");
        assert_eq!(b0["bsdf"]["type"], "diffuse");
        assert_eq!(b0["bsdf"]["reflectance"]["bitmap"], "tex_0_diffuse.exr");
        let b1 = &doc["shapes"][1]["bsdf"];
        assert_eq!(b1["specular_reflectance"]["bitmap"], "tex_1_specular.exr");
        assert_eq!(b1["alpha"]["bitmap"], "tex_1_roughness.exr");
        assert_eq!(b1["alpha"]["channel"], 0);
        let read = |f: &str| relight_scene::io::image::read_exr(&dir.join(f)).unwrap();
        // Texels in relight's order (row 0 at the top), times the constant.
        let (w, h, px) = read("tex_0_diffuse.exr");
        assert_eq!((w, h), (3, 2));
        for (a, b) in px.iter().zip(ramp().texels()) {
            assert_eq!(*a, *b * Vec3::new(0.5, 1.0, 0.8));
        }
        // The ground plane's UVs are mirrored (sign -1 everywhere): green flipped.
        let (_, _, px) = read("tex_0_normal.exr");
        for (a, b) in px.iter().zip(ramp().texels()) {
            assert_eq!(*a, Vec3::new(b.x, 1.0 - b.y, b.z));
        }
        assert_eq!(read("tex_1_roughness.exr").2, vec![Vec3::splat(0.25)]);
        // The PLY holds (u, 1 - v).
        let ply =
            relight_scene::io::ply::read_ply(&dir.join("shape_0.ply"), &LoadOptions::default())
                .unwrap()
                .mesh;
        let (uvs, ours) = (ply.uvs.unwrap(), s.mesh.uvs.as_ref().unwrap());
        assert_eq!(ply.positions.len(), 9);
        for (i, uv) in uvs.iter().enumerate() {
            // The export renumbers vertices in order of first use: match by position.
            let j = s
                .mesh
                .positions
                .iter()
                .position(|p| *p == ply.positions[i])
                .unwrap();
            assert_eq!((uv.x, uv.y), (ours[j].x, 1.0 - ours[j].y), "vertex {i}");
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn maps_mitsuba_cannot_express_are_refused_by_material_and_map() {
        let plastic = Material::GgxPlastic {
            diffuse: Vec3::splat(0.5),
            specular: Vec3::ONE,
            alpha: 0.2,
            ior: 1.5,
        };
        let conductor = Material::GgxConductor {
            specular: Vec3::ONE,
            alpha: 0.2,
        };
        let rough = |v: f32| MaterialMaps {
            roughness: Some(Texture::constant(Vec3::splat(v)).unwrap()),
            ..Default::default()
        };
        let dir = tmp("refused");
        let cases = [
            (
                scene(vec![conductor, plastic], vec![None, Some(rough(0.3))]),
                1,
                "roughness",
                "roughplastic takes a scalar alpha only",
            ),
            (
                scene(vec![conductor, conductor], vec![Some(rough(0.0)), None]),
                0,
                "roughness",
                "texel (0, 0) is 0 < 0.001",
            ),
        ];
        for (s, index, map, why) in cases {
            let e = export_mitsuba(&s, &dir, 4, 2).unwrap_err();
            assert!(
                matches!(&e, MitsubaError::MapUnsupported { index: i, map: m, .. } if *i == index && *m == map),
                "{e:?}"
            );
            let msg = e.to_string();
            assert!(
                msg.starts_with(&format!(
                    "material {index}: its {map} map cannot be exported"
                )) && msg.contains(why),
                "{msg}"
            );
        }
        // A normal map over mixed handedness: the plane (mirrored UVs) and the sphere (not)
        // share material 0.
        let mut s = scene(vec![plastic, plastic], vec![None, None]);
        s.mesh.material_ids.iter_mut().for_each(|m| *m = 0);
        let normal = MaterialMaps {
            normal: Some(ramp()),
            ..Default::default()
        };
        s.maps = SceneMaps::new(&s.mesh, vec![Some(Arc::new(normal)), None]).unwrap();
        let e = export_mitsuba(&s, &dir, 4, 2).unwrap_err();
        assert!(e.to_string().contains("mixed tangent handedness"), "{e}");
        // A normal map on the (curved) sphere alone: per-vertex frames are not per-triangle.
        let s = scene(
            vec![plastic, plastic],
            vec![
                None,
                Some(MaterialMaps {
                    normal: Some(ramp()),
                    ..Default::default()
                }),
            ],
        );
        let e = export_mitsuba(&s, &dir, 4, 2).unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.starts_with("material 1: its normal map cannot be exported")
                && msg.contains("differs from the face normal or the triangle's dp/du"),
            "{msg}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// A sampler and transform become `wrap_mode`, `filter_type` and `to_uv` (absent while
    /// they are the defaults); a texture wrapping its two axes differently is refused.
    #[test]
    fn samplers_and_transforms_are_written_and_per_axis_wraps_refused() {
        use relight_scene::texture::Sampler;
        let lambert = Material::Lambert {
            albedo: Vec3::splat(0.5),
        };
        let sampled = |wrap_s, wrap_t| {
            ramp()
                .with_sampler(Sampler {
                    wrap_s,
                    wrap_t,
                    filter: Filter::Nearest,
                })
                .with_transform(Some(UvTransform {
                    offset: glam::Vec2::new(0.25, -0.5),
                    rotation: std::f32::consts::FRAC_PI_2,
                    scale: glam::Vec2::new(2.0, 3.0),
                }))
        };
        let diffuse = |t| {
            Some(MaterialMaps {
                diffuse: Some(t),
                ..Default::default()
            })
        };
        let s = scene(
            vec![lambert, lambert],
            vec![
                diffuse(sampled(Wrap::ClampToEdge, Wrap::ClampToEdge)),
                diffuse(ramp()),
            ],
        );
        let dir = tmp("sampling");
        let json = export_mitsuba(&s, &dir, 4, 2).unwrap();
        let doc: Value = serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap();
        let t0 = &doc["shapes"][0]["bsdf"]["reflectance"];
        assert_eq!(t0["bitmap"], "tex_0_diffuse.exr");
        assert_eq!(t0["wrap_mode"], "clamp");
        assert_eq!(t0["filter_type"], "nearest");
        // T(offset) R(pi / 2) S(scale): s' = 0.25 + 3 t, t' = -0.5 - 2 s.
        let m: Vec<Vec<f32>> = serde_json::from_value(t0["to_uv"].clone()).unwrap();
        let want = [[0.0, 3.0, 0.25], [-2.0, 0.0, -0.5], [0.0, 0.0, 1.0]];
        for (row, w) in m.iter().zip(want) {
            for (a, b) in row.iter().zip(w) {
                assert!((a - b).abs() < 1e-6, "{m:?}");
            }
        }
        let t1 = &doc["shapes"][1]["bsdf"]["reflectance"];
        assert_eq!(t1.as_object().unwrap().len(), 1, "{t1}");
        let s = scene(
            vec![lambert, lambert],
            vec![None, diffuse(sampled(Wrap::Repeat, Wrap::MirroredRepeat))],
        );
        let e = export_mitsuba(&s, &dir, 4, 2).unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.starts_with("material 1: its diffuse map cannot be exported")
                && msg.contains("one wrap_mode for both axes"),
            "{msg}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
