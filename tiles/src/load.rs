//! Mesh files to templates: OBJ through `tobj` (triangulated), PLY (ASCII or binary
//! little-endian, vertex x/y/z and a face list; polygons fanned; our own small reader, as in
//! the RAMI scene files), glTF and GLB through `gltf`
//! (every triangle primitive of the default scene, node transforms applied; textures are
//! not read).
//!
//! Normalisation into the template frame: positions × `unit_m` (metres per file unit), then the
//! up axis is turned to +z: a y-up file (glTF's convention: +y up, +z towards the viewer,
//! right-handed) is rotated +90° about x, (x, y, z) → (x, −z, y), which keeps handedness and
//! winding. Materials keep the file's names (`unnamed` when none; a PLY file's one material is
//! named after the file stem, e.g. `foliage`).

use std::path::Path;

use serde::Deserialize;

use crate::{Template, TileError};

/// Up axis of a mesh file.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum UpAxis {
    Y,
    Z,
}

/// Load `path` by its extension (obj, gltf, glb) and normalise it.
pub fn load_mesh(path: &Path, unit_m: f64, up: UpAxis) -> Result<Template, TileError> {
    if !path.exists() {
        return Err(TileError::Mesh {
            path: path.into(),
            message: "file not found".into(),
        });
    }
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    let mut t = match ext.as_str() {
        "obj" => load_obj(path)?,
        "gltf" | "glb" => load_gltf(path)?,
        "ply" => load_ply(path)?,
        _ => {
            return Err(TileError::Mesh {
                path: path.into(),
                message: format!(
                    "unknown mesh format `.{ext}` (expected .obj, .ply, .gltf or .glb)"
                ),
            })
        }
    };
    if t.indices.is_empty() {
        return Err(TileError::Mesh {
            path: path.into(),
            message: "no triangles".into(),
        });
    }
    if let Some(p) = t
        .positions
        .iter()
        .find(|p| p.iter().any(|c| !c.is_finite()))
    {
        return Err(TileError::Mesh {
            path: path.into(),
            message: format!("non-finite vertex {p:?}"),
        });
    }
    for p in &mut t.positions {
        let s = unit_m as f32;
        let q = [p[0] * s, p[1] * s, p[2] * s];
        *p = match up {
            UpAxis::Z => q,
            UpAxis::Y => [q[0], -q[2], q[1]],
        };
    }
    t.source = path.display().to_string();
    Ok(t)
}

fn load_obj(path: &Path) -> Result<Template, TileError> {
    let opts = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let (models, mats) = tobj::load_obj(path, &opts).map_err(|e| TileError::Mesh {
        path: path.into(),
        message: e.to_string(),
    })?;
    // A missing .mtl is not fatal: the materials keep their indices and get generic names.
    let mat_names: Vec<String> = mats
        .map(|m| m.into_iter().map(|m| m.name).collect())
        .unwrap_or_default();
    let mut t = Template {
        name: String::new(),
        source: String::new(),
        positions: vec![],
        indices: vec![],
        triangle_materials: vec![],
        material_names: vec![],
    };
    for m in models {
        let base = t.positions.len() as u32;
        let mesh = &m.mesh;
        t.positions
            .extend(mesh.positions.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
        let name = match mesh.material_id {
            Some(i) => mat_names
                .get(i)
                .cloned()
                .unwrap_or_else(|| format!("material{i}")),
            None => "unnamed".to_string(),
        };
        let mi = material_slot(&mut t.material_names, name);
        for c in mesh.indices.chunks_exact(3) {
            t.indices.push([base + c[0], base + c[1], base + c[2]]);
            t.triangle_materials.push(mi);
        }
    }
    Ok(t)
}

/// Reads one little-endian scalar from the start of a slice.
type ScalarReader = fn(&[u8]) -> f64;

/// Size in bytes and reader of a PLY scalar type.
fn ply_scalar(ty: &str) -> Option<(usize, ScalarReader)> {
    Some(match ty {
        "char" | "int8" => (1, |b| b[0] as i8 as f64),
        "uchar" | "uint8" => (1, |b| b[0] as f64),
        "short" | "int16" => (2, |b| i16::from_le_bytes([b[0], b[1]]) as f64),
        "ushort" | "uint16" => (2, |b| u16::from_le_bytes([b[0], b[1]]) as f64),
        "int" | "int32" => (4, |b| i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64),
        "uint" | "uint32" => (4, |b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64),
        "float" | "float32" => (4, |b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64),
        "double" | "float64" => (8, |b| f64::from_le_bytes(b[..8].try_into().unwrap())),
        _ => return None,
    })
}

/// PLY: `element vertex` with float x, y, z (other properties skipped) and `element face`
/// with one list property of indices; other elements are refused.
fn load_ply(path: &Path) -> Result<Template, TileError> {
    let err = |m: String| TileError::Mesh {
        path: path.into(),
        message: m,
    };
    let bytes = std::fs::read(path).map_err(|e| err(e.to_string()))?;
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .ok_or_else(|| err("no `end_header` line".into()))?;
    let header =
        std::str::from_utf8(&bytes[..end]).map_err(|_| err("header is not text".into()))?;
    let mut body = &bytes[end + 11..];
    let mut lines = header.lines();
    if lines.next().map(str::trim) != Some("ply") {
        return Err(err("not a PLY file (no `ply` magic)".into()));
    }
    let mut binary = false;
    // (element name, count, properties: (name, scalar type or list (count type, item type)))
    type Prop = (String, String, Option<String>);
    let mut elements: Vec<(String, usize, Vec<Prop>)> = Vec::new();
    for line in lines {
        let w: Vec<&str> = line.split_whitespace().collect();
        match w.as_slice() {
            ["format", "ascii", _] => binary = false,
            ["format", "binary_little_endian", _] => binary = true,
            ["format", f, _] => {
                return Err(err(format!(
                    "PLY format `{f}` is not supported (ascii, binary_little_endian)"
                )))
            }
            ["element", name, n] => elements.push((
                name.to_string(),
                n.parse()
                    .map_err(|_| err(format!("bad count in `{line}`")))?,
                vec![],
            )),
            ["property", "list", ct, it, name] => elements
                .last_mut()
                .ok_or_else(|| err("property before element".into()))?
                .2
                .push((name.to_string(), ct.to_string(), Some(it.to_string()))),
            ["property", ty, name] => elements
                .last_mut()
                .ok_or_else(|| err("property before element".into()))?
                .2
                .push((name.to_string(), ty.to_string(), None)),
            ["comment", ..] | ["obj_info", ..] | [] => {}
            _ => return Err(err(format!("unsupported header line `{line}`"))),
        }
    }
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "unnamed".into());
    let mut t = Template {
        name: String::new(),
        source: String::new(),
        positions: vec![],
        indices: vec![],
        triangle_materials: vec![],
        material_names: vec![name],
    };
    let text = if binary {
        String::new()
    } else {
        String::from_utf8_lossy(body).into_owned()
    };
    let mut tokens = text.split_whitespace();
    let mut next_value = |ty: &str, body: &mut &[u8]| -> Result<f64, TileError> {
        if binary {
            let (n, read) =
                ply_scalar(ty).ok_or_else(|| err(format!("unknown PLY type `{ty}`")))?;
            if body.len() < n {
                return Err(err("file ends inside the data".into()));
            }
            let v = read(&body[..n]);
            *body = &body[n..];
            Ok(v)
        } else {
            tokens
                .next()
                .and_then(|s| s.parse().ok())
                .ok_or_else(|| err("file ends inside the data or a value is not a number".into()))
        }
    };
    for (ename, count, props) in &elements {
        match ename.as_str() {
            "vertex" => {
                let idx = |n: &str| props.iter().position(|p| p.0 == n);
                let (Some(ix), Some(iy), Some(iz)) = (idx("x"), idx("y"), idx("z")) else {
                    return Err(err("vertex element without x, y, z".into()));
                };
                let mut vals = vec![0.0; props.len()];
                for _ in 0..*count {
                    for (k, p) in props.iter().enumerate() {
                        if p.2.is_some() {
                            return Err(err("list property in vertex element".into()));
                        }
                        vals[k] = next_value(&p.1, &mut body)?;
                    }
                    t.positions
                        .push([vals[ix] as f32, vals[iy] as f32, vals[iz] as f32]);
                }
            }
            "face" => {
                for _ in 0..*count {
                    let mut poly: Vec<u32> = Vec::new();
                    for p in props {
                        match &p.2 {
                            Some(it) => {
                                let n = next_value(&p.1, &mut body)? as usize;
                                poly.clear();
                                for _ in 0..n {
                                    poly.push(next_value(it, &mut body)? as u32);
                                }
                            }
                            None => {
                                next_value(&p.1, &mut body)?;
                            }
                        }
                    }
                    for k in 1..poly.len().saturating_sub(1) {
                        t.indices.push([poly[0], poly[k], poly[k + 1]]);
                        t.triangle_materials.push(0);
                    }
                }
            }
            other => {
                return Err(err(format!(
                    "PLY element `{other}` is not supported (vertex, face)"
                )))
            }
        }
    }
    let n = t.positions.len() as u32;
    if let Some(bad) = t.indices.iter().flatten().find(|&&i| i >= n) {
        return Err(err(format!("face index {bad} past {n} vertices")));
    }
    Ok(t)
}

fn material_slot(names: &mut Vec<String>, name: String) -> u16 {
    match names.iter().position(|n| *n == name) {
        Some(i) => i as u16,
        None => {
            names.push(name);
            (names.len() - 1) as u16
        }
    }
}

fn load_gltf(path: &Path) -> Result<Template, TileError> {
    // Buffers only: textures are not needed (materials come from the library), and game assets
    // often name texture files that are not shipped beside them.
    let gltf::Gltf {
        document: doc,
        blob,
    } = gltf::Gltf::open(path).map_err(|e| TileError::Mesh {
        path: path.into(),
        message: e.to_string(),
    })?;
    let buffers = gltf::import_buffers(&doc, path.parent(), blob).map_err(|e| TileError::Mesh {
        path: path.into(),
        message: format!("buffers: {e}"),
    })?;
    let mut t = Template {
        name: String::new(),
        source: String::new(),
        positions: vec![],
        indices: vec![],
        triangle_materials: vec![],
        material_names: vec![],
    };
    let scene = doc
        .default_scene()
        .or_else(|| doc.scenes().next())
        .ok_or_else(|| TileError::Mesh {
            path: path.into(),
            message: "no scene".into(),
        })?;
    fn visit(
        node: gltf::Node,
        parent: glam::Mat4,
        buffers: &[gltf::buffer::Data],
        t: &mut Template,
        path: &Path,
    ) -> Result<(), TileError> {
        let m = parent * glam::Mat4::from_cols_array_2d(&node.transform().matrix());
        if let Some(mesh) = node.mesh() {
            for prim in mesh.primitives() {
                if prim.mode() != gltf::mesh::Mode::Triangles {
                    continue;
                }
                let reader = prim.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
                let Some(pos) = reader.read_positions() else {
                    continue;
                };
                let base = t.positions.len() as u32;
                t.positions
                    .extend(pos.map(|p| m.transform_point3(glam::Vec3::from(p)).to_array()));
                let n = t.positions.len() as u32 - base;
                let idx: Vec<u32> = match reader.read_indices() {
                    Some(i) => i.into_u32().collect(),
                    None => (0..n).collect(),
                };
                if let Some(bad) = idx.iter().find(|&&i| i >= n) {
                    return Err(TileError::Mesh {
                        path: path.into(),
                        message: format!("index {bad} past {n} vertices in mesh {:?}", mesh.name()),
                    });
                }
                let name = prim
                    .material()
                    .name()
                    .map(str::to_string)
                    .unwrap_or_else(|| match prim.material().index() {
                        Some(i) => format!("material{i}"),
                        None => "unnamed".into(),
                    });
                let mi = material_slot(&mut t.material_names, name);
                // A mirroring node transform flips the winding; undo it so fronts stay fronts.
                let flip = m.determinant() < 0.0;
                for c in idx.chunks_exact(3) {
                    let tri = if flip {
                        [base + c[0], base + c[2], base + c[1]]
                    } else {
                        [base + c[0], base + c[1], base + c[2]]
                    };
                    t.indices.push(tri);
                    t.triangle_materials.push(mi);
                }
            }
        }
        for child in node.children() {
            visit(child, m, buffers, t, path)?;
        }
        Ok(())
    }
    for node in scene.nodes() {
        visit(node, glam::Mat4::IDENTITY, &buffers, &mut t, path)?;
    }
    Ok(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fixture(name: &str) -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/fixtures")
            .join(name)
    }

    /// Rationale: an OBJ written y-up in centimetres must come out in metres, z up, with its
    /// material names and counter-clockwise-from-outside winding kept.
    #[test]
    fn obj_is_scaled_and_turned_z_up() {
        let t = load_mesh(&fixture("pyramid_cm_yup.obj"), 0.01, UpAxis::Y).unwrap();
        assert_eq!(t.indices.len(), 6);
        let (lo, hi) = t.bounds();
        assert!(
            (hi[2] - 2.0).abs() < 1e-6 && lo[2].abs() < 1e-6,
            "apex 200 cm up in y becomes z = 2 m: {lo:?} {hi:?}"
        );
        assert!((hi[0] - 1.0).abs() < 1e-6 && (lo[1] + 1.0).abs() < 1e-6);
        assert!(
            t.material_names.contains(&"stone".to_string()),
            "{:?}",
            t.material_names
        );
    }

    /// Rationale: an ASCII PLY quad is read and fanned into two triangles named after the file;
    /// a face index past the vertices is an error naming the file.
    #[test]
    fn ply_ascii_and_bad_index() {
        let dir = std::env::temp_dir().join(format!("ply-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("quad.ply");
        let head = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
        std::fs::write(&p, format!("{head}0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n")).unwrap();
        let t = load_mesh(&p, 1.0, UpAxis::Z).unwrap();
        assert_eq!(t.indices, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(t.material_names, vec!["quad".to_string()]);
        std::fs::write(&p, format!("{head}0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 9\n")).unwrap();
        let e = load_mesh(&p, 1.0, UpAxis::Z).unwrap_err().to_string();
        assert!(e.contains("quad.ply") && e.contains("index 9"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Rationale: the RAMI-V citrus tree (binary PLY foliage and trunk, metres, z up) loads
    /// with every face, when the shared data folder is beside the repository.
    #[test]
    fn rami_citrus_tree_loads() {
        let d = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../shared/data/meshes/rami5_wellington_citrus_orchard/CISI1");
        if !d.is_dir() {
            eprintln!("shared data not found at {}; skipped", d.display());
            return;
        }
        let f = load_mesh(&d.join("foliage.ply"), 1.0, UpAxis::Z).unwrap();
        let t = load_mesh(&d.join("trunk.ply"), 1.0, UpAxis::Z).unwrap();
        assert_eq!((f.positions.len(), f.indices.len()), (29445, 22044));
        assert_eq!((t.positions.len(), t.indices.len()), (9832, 17206));
        let (lo, hi) = f.bounds();
        assert!(
            hi[2] - lo[2] > 1.0 && hi[2] - lo[2] < 10.0,
            "a citrus crown of a few metres: {lo:?} {hi:?}"
        );
    }

    /// Rationale: a real glTF binary (Kenney city builder, CC0) loads with positions and
    /// materials; a broken file gives an error naming it.
    #[test]
    fn glb_loads_and_broken_files_are_named() {
        let t = load_mesh(&fixture("building-garage.glb"), 10.0, UpAxis::Y).unwrap();
        assert!(t.indices.len() > 10 && !t.material_names.is_empty());
        let (lo, hi) = t.bounds();
        assert!(
            hi[2] - lo[2] > 1.0 && hi[2] - lo[2] < 30.0,
            "a garage of a few metres: {lo:?} {hi:?}"
        );
        let bad = std::env::temp_dir().join(format!("broken-{}.glb", std::process::id()));
        std::fs::write(&bad, b"glTF not really").unwrap();
        let e = load_mesh(&bad, 1.0, UpAxis::Y).unwrap_err();
        assert!(e.to_string().contains(&bad.display().to_string()), "{e}");
        std::fs::remove_file(&bad).unwrap();
        let e = load_mesh(Path::new("/nonexistent/x.obj"), 1.0, UpAxis::Y).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/x.obj"), "{e}");
    }
}
