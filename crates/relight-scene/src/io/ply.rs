//! Stanford PLY reader (ASCII, binary little and big endian) and binary PLY writer.
//!
//! Read: element `vertex` with `x y z`, optional `nx ny nz` and UVs (`u v`, `s t`,
//! `texture_u texture_v` or `texture_s texture_t`); element `face` with a list property
//! `vertex_indices` (or `vertex_index`), fan-triangulated. Other elements and properties are
//! skipped. Element counts are checked against the bytes left in the file, and against
//! [`LoadOptions::max_triangles`] (faces; vertices: three times that), before allocating.
//!
//! Write: `binary_little_endian`, `float x y z nx ny nz [u v]`, `list uchar int
//! vertex_indices` — the layout Mitsuba 3's `ply` shape reads. Material ids are not written.

use super::files::LoadOptions;
use super::{read_bytes, write_atomic, LoadedMesh};
use crate::error::SceneError;
use crate::mesh::TriMesh;
use crate::{Vec2, Vec3};
use std::path::Path;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(s: &str) -> Option<Scalar> {
        Some(match s {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }
}

#[derive(Debug)]
struct Property {
    name: String,
    /// `Some(count type)` for a list property.
    list: Option<Scalar>,
    ty: Scalar,
}

#[derive(Debug)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Property>,
}

#[derive(Clone, Copy, PartialEq)]
enum Format {
    Ascii,
    Le,
    Be,
}

/// Read a PLY file (see the module docs); `opts` gives the triangle limit.
pub fn read_ply(path: &Path, opts: &LoadOptions) -> Result<LoadedMesh, SceneError> {
    let bytes = read_bytes(path)?;
    let (format, elements, body_start, header_lines) = parse_header(path, &bytes)?;
    let body = &bytes[body_start..];
    // Refuse counts the remaining bytes cannot hold (ASCII: >= 2 bytes per property).
    for e in &elements {
        let min = match format {
            Format::Ascii => 2 * e.props.len().max(1),
            _ => e
                .props
                .iter()
                .map(|p| p.list.unwrap_or(p.ty).size())
                .sum::<usize>()
                .max(1),
        };
        if e.count > body.len() / min {
            return Err(SceneError::too_large(
                path,
                format!(
                    "element '{}' count {} exceeds what the {} remaining bytes can hold",
                    e.name,
                    e.count,
                    body.len()
                ),
            ));
        }
        // Every face gives at least one triangle; more vertices than three per triangle
        // would be unused.
        let loc = || crate::error::Location::file(path);
        match e.name.as_str() {
            "face" => opts.check_triangles(e.count as u64, true, loc)?,
            "vertex" if e.count as u64 > 3 * opts.max_triangles as u64 => {
                return Err(SceneError::too_large(
                    path,
                    format!(
                        "{} vertices exceed three times the triangle limit of {}; raise it with --max-triangles (LoadOptions::max_triangles) if this is intended",
                        e.count, opts.max_triangles
                    ),
                ))
            }
            _ => {}
        }
    }
    let mut reader = Reader {
        path,
        format,
        body,
        pos: 0,
        line: header_lines,
        tokens: Vec::new(),
        tok: 0,
    };
    let mut mesh = TriMesh::default();
    let mut has_n = false;
    for e in &elements {
        let find = |names: &[&str]| {
            e.props
                .iter()
                .position(|p| p.list.is_none() && names.contains(&p.name.as_str()))
        };
        match e.name.as_str() {
            "vertex" => {
                let xyz = [find(&["x"]), find(&["y"]), find(&["z"])];
                let [Some(x), Some(y), Some(z)] = xyz else {
                    return Err(SceneError::malformed(
                        path,
                        "vertex element lacks x, y or z",
                    ));
                };
                let n = [find(&["nx"]), find(&["ny"]), find(&["nz"])];
                let uv = [
                    find(&["u", "s", "texture_u", "texture_s"]),
                    find(&["v", "t", "texture_v", "texture_t"]),
                ];
                has_n = n.iter().all(Option::is_some);
                let has_uv = uv.iter().all(Option::is_some);
                let mut vals = vec![0f64; e.props.len()];
                mesh.positions.reserve(e.count);
                for _ in 0..e.count {
                    reader.begin_record()?;
                    for (k, p) in e.props.iter().enumerate() {
                        vals[k] = match p.list {
                            None => reader.scalar(p.ty)?,
                            Some(ct) => {
                                let c = reader.count(ct)?;
                                for _ in 0..c {
                                    reader.scalar(p.ty)?;
                                }
                                0.0
                            }
                        };
                    }
                    let p = Vec3::new(vals[x] as f32, vals[y] as f32, vals[z] as f32);
                    if !p.is_finite() {
                        return Err(
                            reader.error(format!("vertex {} is not finite", mesh.positions.len()))
                        );
                    }
                    mesh.positions.push(p);
                    if has_n {
                        let v = |o: Option<usize>| o.map_or(0.0, |i| vals[i] as f32);
                        mesh.normals.push(Vec3::new(v(n[0]), v(n[1]), v(n[2])));
                    }
                    if has_uv {
                        let v = |o: Option<usize>| o.map_or(0.0, |i| vals[i] as f32);
                        mesh.uvs
                            .get_or_insert_with(Vec::new)
                            .push(Vec2::new(v(uv[0]), v(uv[1])));
                    }
                }
            }
            "face" => {
                let li = e.props.iter().position(|p| {
                    p.list.is_some() && (p.name == "vertex_indices" || p.name == "vertex_index")
                });
                let Some(li) = li else {
                    return Err(SceneError::malformed(
                        path,
                        "face element lacks a vertex_indices list",
                    ));
                };
                let mut poly = Vec::new();
                for _ in 0..e.count {
                    reader.begin_record()?;
                    for (k, p) in e.props.iter().enumerate() {
                        match p.list {
                            None => {
                                reader.scalar(p.ty)?;
                            }
                            Some(ct) => {
                                let c = reader.count(ct)?;
                                poly.clear();
                                for _ in 0..c {
                                    let v = reader.scalar(p.ty)?;
                                    if k == li {
                                        poly.push(v);
                                    }
                                }
                            }
                        }
                    }
                    if poly.len() < 3 {
                        return Err(reader.error(format!(
                            "face {} has {} vertices (needs 3)",
                            mesh.indices.len(),
                            poly.len()
                        )));
                    }
                    let nv = mesh.positions.len();
                    let idx = |v: f64| -> Result<u32, SceneError> {
                        if v >= 0.0 && v < nv as f64 && v.fract() == 0.0 {
                            Ok(v as u32)
                        } else {
                            Err(reader
                                .error(format!("face index {v} out of range ({nv} vertices)")))
                        }
                    };
                    let total = (mesh.indices.len() + poly.len() - 2) as u64;
                    opts.check_triangles(total, true, || crate::error::Location::file(path))?;
                    let first = idx(poly[0])?;
                    for k in 1..poly.len() - 1 {
                        mesh.indices.push([first, idx(poly[k])?, idx(poly[k + 1])?]);
                    }
                }
            }
            _ => {
                for _ in 0..e.count {
                    reader.begin_record()?;
                    for p in &e.props {
                        let c = match p.list {
                            Some(ct) => reader.count(ct)?,
                            None => 1,
                        };
                        for _ in 0..c {
                            reader.scalar(p.ty)?;
                        }
                    }
                }
            }
        }
    }
    if has_n {
        for (i, n) in mesh.normals.iter_mut().enumerate() {
            // Keep unit normals bit-exact (round trips); normalise the others.
            if (n.length_squared() - 1.0).abs() <= 1e-6 {
                continue;
            }
            *n = n.try_normalize().ok_or_else(|| {
                SceneError::invalid_mesh(path, format!("vertex {i}: zero or non-finite normal"))
            })?;
        }
    }
    mesh.material_ids = vec![0; mesh.indices.len()];
    let objects = vec![super::MeshObject {
        name: super::file_stem(path),
        triangles: 0..mesh.indices.len() as u32,
    }];
    Ok(LoadedMesh {
        mesh,
        materials: vec![Default::default()],
        maps: Vec::new(),
        objects,
        camera: None,
        warnings: Vec::new(),
    })
}

fn parse_header(
    path: &Path,
    bytes: &[u8],
) -> Result<(Format, Vec<Element>, usize, usize), SceneError> {
    let mut pos = 0;
    let mut ln = 0;
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        let rest = &bytes[pos..];
        let Some(end) = rest.iter().position(|&b| b == b'\n') else {
            return Err(SceneError::malformed(
                path,
                "truncated header (no end_header)",
            ));
        };
        ln += 1;
        let line = String::from_utf8_lossy(&rest[..end]).trim().to_string();
        pos += end + 1;
        let err = |m: String| SceneError::malformed_at(path, ln, m);
        let t: Vec<&str> = line.split_whitespace().collect();
        if ln == 1 {
            if line != "ply" {
                return Err(err("not a PLY file (first line is not 'ply')".into()));
            }
            continue;
        }
        match t.first().copied() {
            Some("format") => {
                format = Some(match t.get(1).copied() {
                    Some("ascii") => Format::Ascii,
                    Some("binary_little_endian") => Format::Le,
                    Some("binary_big_endian") => Format::Be,
                    other => return Err(err(format!("unknown format {other:?}"))),
                })
            }
            Some("element") => {
                let (Some(name), Some(count)) = (t.get(1), t.get(2)) else {
                    return Err(err("element needs a name and a count".into()));
                };
                let count: u64 = count
                    .parse()
                    .map_err(|_| err(format!("bad element count '{count}'")))?;
                let count = usize::try_from(count)
                    .ok()
                    .filter(|&c| c <= u32::MAX as usize)
                    .ok_or_else(|| SceneError::TooLarge {
                        at: crate::error::Location::line(path, ln),
                        msg: format!("element count {count}"),
                    })?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    props: Vec::new(),
                });
            }
            Some("property") => {
                let Some(e) = elements.last_mut() else {
                    return Err(err("property before any element".into()));
                };
                let ty = |s: Option<&&str>| {
                    s.and_then(|s| Scalar::parse(s))
                        .ok_or_else(|| err(format!("bad property type in '{line}'")))
                };
                let p = if t.get(1) == Some(&"list") {
                    let ct = ty(t.get(2))?;
                    if matches!(ct, Scalar::F32 | Scalar::F64) {
                        return Err(err("list count type must be an integer".into()));
                    }
                    Property {
                        list: Some(ct),
                        ty: ty(t.get(3))?,
                        name: t.get(4).unwrap_or(&"").to_string(),
                    }
                } else {
                    Property {
                        list: None,
                        ty: ty(t.get(1))?,
                        name: t.get(2).unwrap_or(&"").to_string(),
                    }
                };
                e.props.push(p);
            }
            Some("end_header") => break,
            Some("comment") | Some("obj_info") | None => {}
            Some(other) => return Err(err(format!("unknown header keyword '{other}'"))),
        }
    }
    let format = format.ok_or_else(|| SceneError::malformed(path, "header has no format line"))?;
    Ok((format, elements, pos, ln))
}

/// Body reader: binary scalars, or ASCII tokens one record (line) at a time.
struct Reader<'a> {
    path: &'a Path,
    format: Format,
    body: &'a [u8],
    pos: usize,
    line: usize,
    tokens: Vec<String>,
    tok: usize,
}

impl Reader<'_> {
    fn error(&self, msg: String) -> SceneError {
        match self.format {
            Format::Ascii => SceneError::malformed_at(self.path, self.line, msg),
            _ => SceneError::malformed(self.path, format!("byte {}: {msg}", self.pos)),
        }
    }

    /// ASCII: load the next non-empty line. Binary: nothing.
    fn begin_record(&mut self) -> Result<(), SceneError> {
        if self.format != Format::Ascii {
            return Ok(());
        }
        loop {
            if self.pos >= self.body.len() {
                self.line += 1;
                return Err(self.error("truncated: file ends before all elements".into()));
            }
            let rest = &self.body[self.pos..];
            let end = rest.iter().position(|&b| b == b'\n').unwrap_or(rest.len());
            self.line += 1;
            self.pos += (end + 1).min(rest.len());
            let s = String::from_utf8_lossy(&rest[..end]);
            self.tokens = s.split_whitespace().map(str::to_string).collect();
            self.tok = 0;
            if !self.tokens.is_empty() {
                return Ok(());
            }
        }
    }

    fn scalar(&mut self, ty: Scalar) -> Result<f64, SceneError> {
        if self.format == Format::Ascii {
            let Some(t) = self.tokens.get(self.tok) else {
                return Err(self.error("too few values on the line".into()));
            };
            let v: f64 = t
                .parse()
                .map_err(|_| self.error(format!("bad number '{t}'")))?;
            self.tok += 1;
            return Ok(v);
        }
        let n = ty.size();
        let Some(b) = self.body.get(self.pos..self.pos + n) else {
            return Err(self.error("truncated: file ends before all elements".into()));
        };
        let mut a = [0u8; 8];
        a[..n].copy_from_slice(b);
        if self.format == Format::Be {
            a[..n].reverse();
        }
        self.pos += n;
        Ok(match ty {
            Scalar::I8 => a[0] as i8 as f64,
            Scalar::U8 => a[0] as f64,
            Scalar::I16 => i16::from_le_bytes([a[0], a[1]]) as f64,
            Scalar::U16 => u16::from_le_bytes([a[0], a[1]]) as f64,
            Scalar::I32 => i32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Scalar::U32 => u32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Scalar::F32 => f32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Scalar::F64 => f64::from_le_bytes(a),
        })
    }

    fn count(&mut self, ty: Scalar) -> Result<usize, SceneError> {
        let v = self.scalar(ty)?;
        // A list longer than the remaining bytes (or tokens) is corrupt; refuse before looping.
        let left = match self.format {
            Format::Ascii => self.tokens.len() - self.tok.min(self.tokens.len()),
            _ => self.body.len() - self.pos.min(self.body.len()),
        };
        if v < 0.0 || v.fract() != 0.0 || v > left as f64 {
            return Err(self.error(format!("bad list length {v}")));
        }
        Ok(v as usize)
    }
}

/// Write `mesh` as binary little-endian PLY with normals (and UVs if present), atomically.
pub fn write_ply(path: &Path, mesh: &TriMesh) -> Result<(), SceneError> {
    crate::meshops::validate(mesh).map_err(|m| SceneError::invalid_mesh(path, m))?;
    let uv = mesh.uvs.as_ref();
    let mut out = Vec::with_capacity(mesh.positions.len() * 32 + mesh.indices.len() * 13 + 256);
    let mut header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment written by relight\nelement vertex {}\n\
         property float x\nproperty float y\nproperty float z\n\
         property float nx\nproperty float ny\nproperty float nz\n",
        mesh.positions.len()
    );
    if uv.is_some() {
        header += "property float u\nproperty float v\n";
    }
    header += &format!(
        "element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mesh.indices.len()
    );
    out.extend_from_slice(header.as_bytes());
    for i in 0..mesh.positions.len() {
        let (p, n) = (mesh.positions[i], mesh.normals[i]);
        for v in [p.x, p.y, p.z, n.x, n.y, n.z] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        if let Some(uv) = uv {
            out.extend_from_slice(&uv[i].x.to_le_bytes());
            out.extend_from_slice(&uv[i].y.to_le_bytes());
        }
    }
    for t in &mesh.indices {
        out.push(3);
        for &i in t {
            out.extend_from_slice(&(i as i32).to_le_bytes());
        }
    }
    write_atomic(path, |tmp| {
        std::fs::write(tmp, &out).map_err(|e| SceneError::io(path, e))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::{load_mesh, load_mesh_with, test_util::temp_dir};

    fn tetra() -> TriMesh {
        let positions = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
        let indices = vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
        let mut m = TriMesh {
            positions,
            indices,
            material_ids: vec![0; 4],
            ..Default::default()
        };
        m.normals = crate::meshops::smooth_normals(&m, crate::meshops::NormalWeighting::Area);
        m.uvs = Some(vec![
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(0.0, 1.0),
            Vec2::new(0.5, 0.25),
        ]);
        m
    }

    #[test]
    fn binary_round_trip_is_identical() {
        let dir = temp_dir("ply");
        let m = tetra();
        let p = dir.join("t.ply");
        write_ply(&p, &m).unwrap();
        let loaded = load_mesh(&p).unwrap();
        // One object, named after the file.
        let n = m.indices.len() as u32;
        assert_eq!(
            loaded.objects,
            [crate::io::MeshObject {
                name: "t".into(),
                triangles: 0..n
            }]
        );
        let back = loaded.mesh;
        assert_eq!(back.positions, m.positions);
        assert_eq!(back.normals, m.normals);
        assert_eq!(back.uvs, m.uvs);
        assert_eq!(back.indices, m.indices);
    }

    const ASCII: &str = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
        element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n";

    #[test]
    fn ascii_quad_reads() {
        let dir = temp_dir("plya");
        let p = dir.join("a.ply");
        std::fs::write(&p, ASCII).unwrap();
        let m = load_mesh(&p).unwrap().mesh;
        assert_eq!(m.indices, vec![[0, 1, 2], [0, 2, 3]]);
        assert!(m.normals.iter().all(|n| (*n - Vec3::Z).length() < 1e-6));
    }

    #[test]
    fn big_endian_reads() {
        let dir = temp_dir("plybe");
        let mut b = b"ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty double x\nproperty double y\nproperty double z\n\
            element face 1\nproperty list uchar ushort vertex_indices\nend_header\n".to_vec();
        for v in [0.0f64, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
            b.extend_from_slice(&v.to_be_bytes());
        }
        b.push(3);
        for i in [0u16, 1, 2] {
            b.extend_from_slice(&i.to_be_bytes());
        }
        let p = dir.join("be.ply");
        std::fs::write(&p, &b).unwrap();
        let m = load_mesh(&p).unwrap().mesh;
        assert_eq!(m.positions[1], Vec3::X);
        assert_eq!(m.indices, vec![[0, 1, 2]]);
    }

    #[test]
    fn ascii_malformed_names_the_line() {
        let dir = temp_dir("plybad");
        let p = dir.join("bad.ply");
        std::fs::write(&p, ASCII.replace("1 1 0", "1 one 0")).unwrap();
        let e = load_mesh(&p).unwrap_err().to_string();
        assert!(e.contains("bad.ply: line 12: bad number 'one'"), "{e}");
        std::fs::write(&p, ASCII.replace("4 0 1 2 3", "3 0 1 7")).unwrap();
        let e = load_mesh(&p).unwrap_err().to_string();
        assert!(
            e.contains("line 14: face index 7 out of range (4 vertices)"),
            "{e}"
        );
        std::fs::write(&p, &ASCII[..ASCII.len() - 10]).unwrap();
        assert!(load_mesh(&p).unwrap_err().to_string().contains("bad.ply"));
    }

    #[test]
    fn binary_truncated_and_malformed_are_errors() {
        let dir = temp_dir("plybin");
        let p = dir.join("t.ply");
        write_ply(&p, &tetra()).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        std::fs::write(&p, &bytes[..bytes.len() - 7]).unwrap();
        let e = load_mesh(&p).unwrap_err().to_string();
        assert!(e.contains("t.ply") && e.contains("truncated"), "{e}");
        // Corrupt a face's list length.
        let mut bad = bytes.clone();
        let face0 = bad.len() - 4 * 13;
        bad[face0] = 200;
        std::fs::write(&p, &bad).unwrap();
        assert!(load_mesh(&p).is_err());
        std::fs::write(&p, b"ply\nformat binary_middle_endian 1.0\nend_header\n").unwrap();
        assert!(load_mesh(&p).unwrap_err().to_string().contains("line 2"));
    }

    #[test]
    fn triangle_limit_is_checked_on_the_header_and_while_triangulating() {
        let dir = temp_dir("plylimit");
        let p = dir.join("a.ply");
        // One pentagon: five vertices, one face, three triangles.
        let pentagon = ASCII
            .replace("element vertex 4", "element vertex 5")
            .replace("0 1 0\n4 0 1 2 3", "0 1 0\n-1 0.5 0\n5 0 1 2 3 4");
        std::fs::write(&p, pentagon).unwrap();
        let opts = |n| LoadOptions {
            max_triangles: n,
            ..LoadOptions::default()
        };
        assert_eq!(
            load_mesh_with(&p, &opts(3)).unwrap().mesh.triangle_count(),
            3
        );
        // Header within the limit (1 face, 5 <= 6 vertices), triangulation beyond it.
        let e = load_mesh_with(&p, &opts(2)).unwrap_err();
        assert!(
            matches!(
                e,
                SceneError::TooManyTriangles {
                    count: 3,
                    limit: 2,
                    ..
                }
            ),
            "{e}"
        );
        // The header alone is enough to refuse: more than three vertices per allowed
        // triangle, or more faces.
        let e = load_mesh_with(&p, &opts(1)).unwrap_err();
        assert!(
            matches!(e, SceneError::TooLarge { .. }) && e.to_string().contains("5 vertices"),
            "{e}"
        );
        let two_faces = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
            element face 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n1 1 0\n3 0 1 2\n3 0 2 1\n";
        std::fs::write(&p, two_faces).unwrap();
        let e = load_mesh_with(&p, &opts(1)).unwrap_err();
        assert!(
            matches!(
                e,
                SceneError::TooManyTriangles {
                    count: 2,
                    limit: 1,
                    at_least: true,
                    ..
                }
            ),
            "{e}"
        );
    }

    #[test]
    fn absurd_element_count_is_refused() {
        let dir = temp_dir("plyhuge");
        let p = dir.join("huge.ply");
        std::fs::write(&p, "ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000\nproperty float x\nend_header\n").unwrap();
        let e = load_mesh(&p).unwrap_err();
        assert!(matches!(e, SceneError::TooLarge { .. }), "{e}");
        std::fs::write(&p, "ply\nformat binary_little_endian 1.0\nelement vertex 100000000\nproperty float x\nend_header\n").unwrap();
        assert!(matches!(
            load_mesh(&p).unwrap_err(),
            SceneError::TooLarge { .. }
        ));
    }
}
