//! Wavefront OBJ (+ MTL) reader.
//!
//! Supported: `v`, `vt`, `vn`, `f` (any polygon, fan-triangulated; `v`, `v/vt`, `v//vn`,
//! `v/vt/vn`; negative indices are relative), `usemtl`, `mtllib`, and `o` / `g` as object
//! names ([`LoadedMesh::objects`]: a new object at each `o` or `g` line followed by faces;
//! faces before any are named after the file stem). Ignored: smoothing groups, lines, points, free-form geometry. One output vertex per distinct
//! (position, uv, normal) triple used by a face, so unused vertices disappear.
//! UVs are stored as in the file (OBJ's `v` points up). If any face corner lacks a normal,
//! all normals are recomputed (angle-weighted).
//!
//! MTL: `newmtl`, `Kd`, `Ks`, `Ns`. `Kd` alone gives [`Material::Lambert`]; a non-zero `Ks`
//! with `Ns > 0` gives [`Material::BlinnPhong`] (`exponent = Ns`). A material library that
//! cannot be read (missing, outside the model's folder under the default
//! [`super::PathPolicy`], not a regular file, over [`super::files::MAX_TEXT_BYTES`]) or an
//! unknown material name gives the default material and a warning, not an error: OBJ files
//! often name libraries that were not shipped with them.
//!
//! Faces beyond [`LoadOptions::max_triangles`] triangles stop the reading with
//! [`SceneError::TooManyTriangles`] at their line.

use super::files::{self, LoadOptions};
use super::{read_bytes, LoadedMesh};
use crate::error::SceneError;
use crate::material::Material;
use crate::mesh::TriMesh;
use crate::{Vec2, Vec3};
use std::collections::HashMap;
use std::path::Path;

/// Read an OBJ file and the MTL libraries it names (see the module docs); `opts` gives the
/// path policy for `mtllib` and the triangle limit.
pub fn read_obj(path: &Path, opts: &LoadOptions) -> Result<LoadedMesh, SceneError> {
    let text = String::from_utf8_lossy(&read_bytes(path)?).into_owned();
    let mut warnings = Vec::new();
    let (mut pos, mut tex, mut nor) = (Vec::<Vec3>::new(), Vec::<Vec2>::new(), Vec::<Vec3>::new());
    let mut mesh = TriMesh::default();
    let mut corner_map: HashMap<(u32, u32, u32), u32> = HashMap::new();
    let (mut any_missing_vt, mut any_vt, mut any_missing_vn) = (false, false, false);
    let mut library: HashMap<String, Material> = HashMap::new();
    let mut materials: Vec<Material> = Vec::new();
    let mut material_index: HashMap<String, u32> = HashMap::new();
    let mut current: Option<u32> = None;
    let stem = super::file_stem(path);
    // Objects as (name, first triangle), in order.
    let mut objects: Vec<(String, u32)> = Vec::new();
    let mut corners: Vec<u32> = Vec::new();

    for (ln, raw) in text.lines().enumerate() {
        let ln = ln + 1;
        let line = raw.split('#').next().unwrap_or("").trim();
        let mut it = line.split_whitespace();
        let Some(key) = it.next() else { continue };
        let err = |m: String| SceneError::malformed_at(path, ln, m);
        match key {
            "v" => pos.push(Vec3::from(parse_floats::<3>(&mut it).map_err(err)?)),
            "vt" => {
                let mut vals = it.map(parse_f32);
                let u = vals
                    .next()
                    .ok_or_else(|| err("vt needs a u coordinate".into()))?
                    .map_err(err)?;
                let v = vals.next().unwrap_or(Ok(0.0)).map_err(err)?;
                tex.push(Vec2::new(u, v));
            }
            "vn" => nor.push(Vec3::from(parse_floats::<3>(&mut it).map_err(err)?)),
            "f" => {
                corners.clear();
                for tok in it {
                    let mut parts = tok.split('/');
                    let v = resolve(parts.next(), pos.len(), "vertex").map_err(err)?;
                    let t = resolve(parts.next(), tex.len(), "texture coordinate").map_err(err)?;
                    let n = resolve(parts.next(), nor.len(), "normal").map_err(err)?;
                    let Some(v) = v else {
                        return Err(err(format!("face corner '{tok}' has no vertex index")));
                    };
                    any_vt |= t.is_some();
                    any_missing_vt |= t.is_none();
                    any_missing_vn |= n.is_none();
                    let key = (v, t.map_or(0, |t| t + 1), n.map_or(0, |n| n + 1));
                    let id = *corner_map.entry(key).or_insert_with(|| {
                        mesh.positions.push(pos[v as usize]);
                        mesh.normals.push(n.map_or(Vec3::ZERO, |n| nor[n as usize]));
                        mesh.uvs
                            .get_or_insert_with(Vec::new)
                            .push(t.map_or(Vec2::ZERO, |t| tex[t as usize]));
                        mesh.positions.len() as u32 - 1
                    });
                    corners.push(id);
                }
                if corners.len() < 3 {
                    return Err(err(format!(
                        "face has {} vertices (needs at least 3)",
                        corners.len()
                    )));
                }
                let mat = match current {
                    Some(m) => m,
                    None => {
                        let m = *material_index.entry(String::new()).or_insert_with(|| {
                            materials.push(Material::default());
                            materials.len() as u32 - 1
                        });
                        current = Some(m);
                        m
                    }
                };
                if objects.is_empty() {
                    objects.push((stem.clone(), 0));
                }
                let total = (mesh.indices.len() + corners.len() - 2) as u64;
                opts.check_triangles(total, true, || crate::error::Location::line(path, ln))?;
                for k in 1..corners.len() - 1 {
                    mesh.indices.push([corners[0], corners[k], corners[k + 1]]);
                    mesh.material_ids.push(mat);
                }
            }
            "o" | "g" => {
                let name = line[1..].trim();
                let name = if name.is_empty() {
                    stem.clone()
                } else {
                    name.to_string()
                };
                let start = mesh.indices.len() as u32;
                match objects.last_mut() {
                    Some((n, s)) if *s == start => *n = name,
                    _ => objects.push((name, start)),
                }
            }
            "mtllib" => {
                let name = line["mtllib".len()..].trim();
                let read =
                    files::resolve_model_ref(path, name, &opts.paths, "mtllib").and_then(|mtl| {
                        Ok((files::read_file(&mtl, files::MAX_TEXT_BYTES, "MTL")?, mtl))
                    });
                match read {
                    Ok((bytes, mtl)) => library.extend(parse_mtl(
                        &mtl,
                        &String::from_utf8_lossy(&bytes),
                        &mut warnings,
                    )?),
                    Err(e) => warnings.push(format!(
                        "{}: line {ln}: material library not read: {e}; using the default material",
                        path.display(),
                    )),
                }
            }
            "usemtl" => {
                let name = line["usemtl".len()..].trim().to_string();
                let next = materials.len() as u32;
                let m = *material_index.entry(name.clone()).or_insert(next);
                if m == next {
                    let mat = library.get(&name).copied().unwrap_or_else(|| {
                        warnings.push(format!(
                            "{}: line {ln}: material '{name}' not defined in any MTL library; using the default material",
                            path.display()
                        ));
                        Material::default()
                    });
                    materials.push(mat);
                }
                current = Some(m);
            }
            _ => {}
        }
    }
    if !any_vt || any_missing_vt {
        if any_vt {
            warnings.push(format!(
                "{}: some face corners have no texture coordinates; UVs dropped",
                path.display()
            ));
        }
        mesh.uvs = None;
    }
    if any_missing_vn {
        mesh.normals.clear(); // recomputed by `finish_mesh`
    } else {
        for (i, n) in mesh.normals.iter_mut().enumerate() {
            *n = n.try_normalize().ok_or_else(|| {
                SceneError::invalid_mesh(path, format!("vertex {i}: zero or non-finite normal"))
            })?;
        }
    }
    let end = mesh.indices.len() as u32;
    let objects = super::objects_from_starts(objects, end);
    Ok(LoadedMesh {
        maps: Vec::new(),
        objects,
        camera: None,
        mesh,
        materials,
        warnings,
    })
}

fn parse_f32(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(format!("non-finite number '{s}'")),
        Err(_) => Err(format!("bad number '{s}'")),
    }
}

fn parse_floats<'a, const N: usize>(
    it: &mut impl Iterator<Item = &'a str>,
) -> Result<[f32; N], String> {
    let mut out = [0.0; N];
    for (k, o) in out.iter_mut().enumerate() {
        *o = parse_f32(
            it.next()
                .ok_or_else(|| format!("expected {N} numbers, found {k}"))?,
        )?;
    }
    Ok(out)
}

/// Resolve a 1-based (or negative, relative) OBJ index against `count` items.
fn resolve(tok: Option<&str>, count: usize, what: &str) -> Result<Option<u32>, String> {
    let Some(tok) = tok.filter(|t| !t.is_empty()) else {
        return Ok(None);
    };
    let i: i64 = tok
        .parse()
        .map_err(|_| format!("bad {what} index '{tok}'"))?;
    let idx = if i > 0 { i - 1 } else { count as i64 + i };
    if i == 0 || idx < 0 || idx >= count as i64 {
        let plural = if what == "vertex" {
            "vertices".to_string()
        } else {
            format!("{what}s")
        };
        return Err(format!("face index {i} out of range ({count} {plural})"));
    }
    Ok(Some(idx as u32))
}

/// Parse an MTL library into named materials.
fn parse_mtl(
    path: &Path,
    text: &str,
    warnings: &mut Vec<String>,
) -> Result<HashMap<String, Material>, SceneError> {
    struct Raw {
        kd: Vec3,
        ks: Vec3,
        ns: f32,
        line: usize,
    }
    // Build and check a material; an invalid one (a negative or > 1 coefficient, NaN) is an
    // error at its `newmtl` line. Kd + Ks above 1 (common in exported files) is rescaled to
    // conserve energy, with a warning naming the line.
    let mut finish = |name: &str, r: &Raw| {
        let m = if r.ks.max_element() > 0.0 && r.ns > 0.0 {
            let sum = (r.kd + r.ks).max_element();
            let k = if sum > 1.0 && r.kd.max_element() <= 1.0 && r.ks.max_element() <= 1.0 {
                warnings.push(format!(
                    "{}: line {}: material '{name}': Kd + Ks = {sum} exceeds 1; both scaled by {:.4} to conserve energy",
                    path.display(),
                    r.line,
                    1.0 / sum
                ));
                1.0 / sum
            } else {
                1.0
            };
            Material::BlinnPhong {
                diffuse: r.kd * k,
                specular: r.ks * k,
                exponent: r.ns,
            }
        } else {
            Material::Lambert { albedo: r.kd }
        };
        m.validate()
            .map(|()| m)
            .map_err(|e| SceneError::malformed_at(path, r.line, format!("material '{name}': {e}")))
    };
    let mut out = HashMap::new();
    let mut cur: Option<(String, Raw)> = None;
    for (ln, raw) in text.lines().enumerate() {
        let line = raw.split('#').next().unwrap_or("").trim();
        let mut it = line.split_whitespace();
        let Some(key) = it.next() else { continue };
        let err = |m: String| SceneError::malformed_at(path, ln + 1, m);
        match key {
            "newmtl" => {
                if let Some((n, r)) = cur.take() {
                    let m = finish(&n, &r)?;
                    out.insert(n, m);
                }
                let name = line["newmtl".len()..].trim().to_string();
                cur = Some((
                    name,
                    Raw {
                        kd: Vec3::splat(0.8),
                        ks: Vec3::ZERO,
                        ns: 0.0,
                        line: ln + 1,
                    },
                ));
            }
            "Kd" | "Ks" | "Ns" => {
                let Some((_, r)) = cur.as_mut() else {
                    return Err(err(format!("'{key}' before any newmtl")));
                };
                if key == "Ns" {
                    r.ns = parse_floats::<1>(&mut it).map_err(err)?[0];
                } else {
                    let v = Vec3::from(parse_floats::<3>(&mut it).map_err(err)?);
                    if v.min_element() < 0.0 {
                        return Err(err(format!("negative reflectance {v}")));
                    }
                    if key == "Kd" {
                        r.kd = v
                    } else {
                        r.ks = v
                    }
                }
            }
            _ => {}
        }
    }
    if let Some((n, r)) = cur.take() {
        let m = finish(&n, &r)?;
        out.insert(n, m);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::{load_mesh, test_util::temp_dir};
    use relight_testdata::shared_file;

    fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    const QUAD: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";

    #[test]
    fn quads_fan_triangulate_and_materials_follow_usemtl() {
        let dir = temp_dir("obj");
        write(
            &dir,
            "m.mtl",
            "newmtl red\nKd 1 0 0\nnewmtl shiny\nKd 0.2 0.2 0.2\nKs 0.5 0.5 0.5\nNs 40\n",
        );
        let text = format!("mtllib m.mtl\n{QUAD}usemtl red\nf 1 2 3 4\nusemtl shiny\nf -4 -2 -1\nusemtl red\nf 1 2 3\n");
        let m = load_mesh(&write(&dir, "q.obj", &text)).unwrap();
        assert_eq!(m.mesh.triangle_count(), 4);
        assert_eq!(m.mesh.material_ids, vec![0, 0, 1, 0]);
        assert_eq!(m.materials[0], Material::Lambert { albedo: Vec3::X });
        assert!(matches!(
            m.materials[1],
            Material::BlinnPhong { exponent: 40.0, .. }
        ));
        assert!(m.warnings.is_empty(), "{:?}", m.warnings);
        // Computed normals of the z = 0 quad face +Z.
        assert!(m
            .mesh
            .normals
            .iter()
            .all(|n| (*n - Vec3::Z).length() < 1e-6));
    }

    #[test]
    fn invalid_mtl_material_is_an_error_at_its_line() {
        let dir = temp_dir("objmtlbad");
        write(
            &dir,
            "m.mtl",
            "# lib\nnewmtl hot\nKd 1.5 0.9 0.9\nKs 0.5 0.5 0.5\nNs 10\n",
        );
        let e = load_mesh(&write(
            &dir,
            "q.obj",
            &format!("mtllib m.mtl\n{QUAD}usemtl hot\nf 1 2 3\n"),
        ))
        .unwrap_err();
        assert!(
            e.to_string().contains("m.mtl: line 2: material 'hot'"),
            "{e}"
        );
    }

    #[test]
    fn mtl_above_unit_energy_is_rescaled_with_a_warning() {
        let dir = temp_dir("objmtlhot");
        write(
            &dir,
            "m.mtl",
            "# lib\nnewmtl hot\nKd 0.9 0.9 0.9\nKs 0.5 0.5 0.5\nNs 10\n",
        );
        let m = load_mesh(&write(
            &dir,
            "q.obj",
            &format!("mtllib m.mtl\n{QUAD}usemtl hot\nf 1 2 3\n"),
        ))
        .unwrap();
        assert!(
            m.warnings
                .iter()
                .any(|w| w.contains("m.mtl: line 2") && w.contains("exceeds 1")),
            "{:?}",
            m.warnings
        );
        match m.materials[0] {
            Material::BlinnPhong {
                diffuse, specular, ..
            } => {
                assert!(((diffuse + specular).max_element() - 1.0).abs() < 1e-6);
                assert!((diffuse.x / specular.x - 0.9 / 0.5).abs() < 1e-5);
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn missing_mtl_is_a_warning() {
        let dir = temp_dir("objmtl");
        let m = load_mesh(&write(
            &dir,
            "q.obj",
            &format!("mtllib gone.mtl\n{QUAD}usemtl x\nf 1 2 3\n"),
        ))
        .unwrap();
        assert_eq!(m.materials, vec![Material::default()]);
        assert!(
            m.warnings.iter().any(|w| w.contains("gone.mtl")),
            "{:?}",
            m.warnings
        );
    }

    #[test]
    fn index_out_of_range_names_file_and_line() {
        let dir = temp_dir("objbad");
        let e = load_mesh(&write(&dir, "bad.obj", &format!("{QUAD}f 1 2 900\n"))).unwrap_err();
        assert_eq!(
            e.to_string(),
            format!(
                "{}: line 5: face index 900 out of range (4 vertices)",
                dir.join("bad.obj").display()
            )
        );
    }

    #[test]
    fn malformed_number_is_an_error() {
        let dir = temp_dir("objnum");
        let e = load_mesh(&write(&dir, "n.obj", "v 0 0 zero\n")).unwrap_err();
        assert!(e.to_string().contains("line 1: bad number 'zero'"), "{e}");
        let e = load_mesh(&write(&dir, "t.obj", "v 0 0\n")).unwrap_err(); // truncated vertex
        assert!(e.to_string().contains("line 1"), "{e}");
        let e = load_mesh(&write(&dir, "f.obj", &format!("{QUAD}f 1 2\n"))).unwrap_err();
        assert!(e.to_string().contains("line 5"), "{e}");
    }

    #[test]
    fn triangle_limit_stops_reading_at_the_line() {
        let dir = temp_dir("objlimit");
        let p = write(&dir, "l.obj", &format!("{QUAD}f 1 2 3\nf 1 2 3 4\n"));
        let opts = |n| LoadOptions {
            max_triangles: n,
            ..LoadOptions::default()
        };
        let e = crate::io::load_mesh_with(&p, &opts(2)).unwrap_err();
        assert!(
            matches!(
                e,
                SceneError::TooManyTriangles {
                    count: 3,
                    at_least: true,
                    limit: 2,
                    ..
                }
            ),
            "{e}"
        );
        assert!(
            e.to_string()
                .contains("l.obj: line 6: at least 3 triangles"),
            "{e}"
        );
        assert_eq!(
            crate::io::load_mesh_with(&p, &opts(3))
                .unwrap()
                .mesh
                .triangle_count(),
            3
        );
    }

    #[test]
    fn empty_and_all_degenerate_meshes_are_rejected() {
        let dir = temp_dir("objempty");
        let e = load_mesh(&write(&dir, "e.obj", QUAD)).unwrap_err();
        assert!(e.to_string().contains("empty mesh"), "{e}");
        let e = load_mesh(&write(&dir, "d.obj", &format!("{QUAD}f 1 1 2\nf 1 2 2\n"))).unwrap_err();
        assert!(e.to_string().contains("empty mesh"), "{e}");
    }

    #[test]
    fn degenerate_triangles_are_reported() {
        let dir = temp_dir("objdeg");
        let m = load_mesh(&write(
            &dir,
            "d.obj",
            &format!("{QUAD}f 1 2 3\nf 1 1 2\nv 2 0 0\nf 1 2 5\n"),
        ))
        .unwrap();
        assert_eq!(m.mesh.triangle_count(), 1);
        assert!(
            m.warnings
                .iter()
                .any(|w| w.contains("dropped 2 degenerate")),
            "{:?}",
            m.warnings
        );
    }

    /// Triangle and vertex counts of SOURCES.md (vertices: used ones; spot splits at UV seams).
    #[test]
    fn shared_meshes_load_with_published_counts() {
        for (name, tris, verts) in [
            ("bunny.obj", 69_451, 35_947 - 1_113),
            ("bunny_watertight.obj", 59_664, 29_834),
            ("teapot.obj", 6_320, 3_644),
            ("dragon.obj", 100_000, 50_000),
            ("armadillo.obj", 29_170, 14_587),
            ("spot.obj", 5_856, 0),
        ] {
            let Some(p) = shared_file(&format!("data/meshes/{name}")) else {
                return;
            };
            let m = load_mesh(&p).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(m.mesh.triangle_count(), tris, "{name}: {:?}", m.warnings);
            if verts > 0 {
                assert_eq!(m.mesh.vertex_count(), verts, "{name}");
            } else {
                assert!(m.mesh.uvs.is_some(), "{name} has UVs");
            }
        }
    }

    #[test]
    fn teapot_welds_to_published_count() {
        let Some(p) = shared_file("data/meshes/teapot.obj") else {
            return;
        };
        let m = load_mesh(&p).unwrap();
        // SOURCES.md: welding at 1e-4 leaves 3,241 vertices.
        assert_eq!(crate::meshops::weld(&m.mesh, 1e-4).vertex_count(), 3_241);
    }

    #[test]
    fn objects_follow_o_and_g_lines_and_default_to_the_file_stem() {
        let dir = temp_dir("objnames");
        // Faces before any name, then `o a`, an empty `g` (the stem), `g a` again, and a
        // name with no face after it.
        let text =
            format!("{QUAD}f 1 2 3\no a\nf 1 3 4\nf 1 2 4\ng\nf 2 3 4\ng a\nf 1 2 3\no unused\n");
        let m = load_mesh(&write(&dir, "thing.obj", &text)).unwrap();
        let got: Vec<(&str, std::ops::Range<u32>)> = m
            .objects
            .iter()
            .map(|o| (o.name.as_str(), o.triangles.clone()))
            .collect();
        assert_eq!(
            got,
            [
                ("thing", 0..1),
                ("a", 1..3),
                ("thing.1", 3..4),
                ("a.1", 4..5)
            ]
        );
        // Without names: one object named after the file.
        let m = load_mesh(&write(&dir, "plain.obj", &format!("{QUAD}f 1 2 3 4\n"))).unwrap();
        assert_eq!(m.objects.len(), 1);
        assert_eq!(
            (m.objects[0].name.as_str(), m.objects[0].triangles.clone()),
            ("plain", 0..2)
        );
        assert_eq!(m.maps.len(), m.materials.len());
        // A degenerate triangle dropped on load shifts the ranges after it.
        let text = format!("{QUAD}o x\nf 1 2 3\nf 1 1 2\no y\nf 1 3 4\n");
        let m = load_mesh(&write(&dir, "degen.obj", &text)).unwrap();
        let got: Vec<_> = m.objects.iter().map(|o| o.triangles.clone()).collect();
        assert_eq!(got, [0..1, 1..2]);
    }
}
