//! A gridded terrain mesh (PLY) to a georeferenced DEM, so that scenegen can build a bundle from
//! it like from any DEM (`scenegen mesh-to-dem`).
//!
//! Input: a PLY file (ASCII or binary little/big endian) whose `vertex` element has `x`, `y`, `z`
//! properties (metres, any scalar type; other properties are ignored), or a Wavefront OBJ file
//! (extension `.obj`: its `v x y z` lines; here z is up, as in the PLY case), in a local frame: x east,
//! y north, z height above sea level. The vertices must form a regular grid (every (x, y) pair of
//! the distinct x and y values present exactly once, uniform spacing within 1e-6 of the step),
//! which is what terrain meshes made from rasters are, e.g. the Libya-4 site mesh
//! `shared/data/terrain/libya4_20km.ply` (200 × 200 vertices, 100 m). Faces are not needed:
//! the bundle's TIN is rebuilt from the heights. A mesh that is not such a grid is refused.
//!
//! Output: a one-band Float32 GeoTIFF whose pixel centres are the vertices, in the transverse
//! Mercator CRS centred on the site (`+proj=tmerc +lat_0=φ +lon_0=λ +k=1 +x_0=0 +y_0=0
//! +datum=WGS84 +units=m`): the mesh's (0, 0) is at (λ, φ) — the same "local" frame as a region
//! file's default working CRS. Optionally a land-cover raster of one class code on the same grid.

use std::io::Read;
use std::path::Path;

use crate::error::ScenegenError;
use crate::synth::write_geotiff;

/// Vertex positions of a terrain mesh: OBJ when the extension is `.obj`, else PLY.
pub fn read_mesh_vertices(path: &Path) -> Result<Vec<[f64; 3]>, ScenegenError> {
    let is_obj = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("obj"));
    if is_obj {
        read_obj_vertices(path)
    } else {
        read_ply_vertices(path)
    }
}

/// Vertex positions (`v x y z` lines) of a Wavefront OBJ file; faces and the rest are ignored.
pub fn read_obj_vertices(path: &Path) -> Result<Vec<[f64; 3]>, ScenegenError> {
    let bad = |m: String| ScenegenError::Input {
        path: path.into(),
        message: m,
    };
    let text = std::fs::read_to_string(path).map_err(|e| bad(format!("cannot read: {e}")))?;
    let mut v = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let mut w = line.split_whitespace();
        if w.next() != Some("v") {
            continue;
        }
        let mut p = [0.0; 3];
        for c in &mut p {
            *c = w
                .next()
                .and_then(|t| t.parse::<f64>().ok())
                .filter(|x| x.is_finite())
                .ok_or_else(|| bad(format!("line {}: `{line}` is not `v x y z`", i + 1)))?;
        }
        v.push(p);
    }
    if v.is_empty() {
        return Err(bad(
            "not an OBJ terrain mesh (no `v x y z` vertex lines)".into()
        ));
    }
    Ok(v)
}

/// Vertex positions of a PLY file (x, y, z as f64).
pub fn read_ply_vertices(path: &Path) -> Result<Vec<[f64; 3]>, ScenegenError> {
    let bad = |m: String| ScenegenError::Input {
        path: path.into(),
        message: m,
    };
    let mut f = std::fs::File::open(path).map_err(|e| bad(format!("cannot open: {e}")))?;
    let mut bytes = Vec::new();
    f.read_to_end(&mut bytes)
        .map_err(|e| bad(format!("cannot read: {e}")))?;
    let end = find(&bytes, b"end_header")
        .ok_or_else(|| bad("not a PLY file (no `end_header`)".into()))?;
    let header =
        std::str::from_utf8(&bytes[..end]).map_err(|_| bad("header is not text".into()))?;
    let mut body = end + "end_header".len();
    // The header ends with a newline (\n or \r\n).
    while body < bytes.len() && (bytes[body] == b'\r' || bytes[body] == b'\n') {
        body += 1;
        if bytes[body - 1] == b'\n' {
            break;
        }
    }
    let mut lines = header.lines();
    if lines.next().map(str::trim) != Some("ply") {
        return Err(bad("not a PLY file (first line is not `ply`)".into()));
    }
    let mut format = None;
    // Elements in order: (name, count, properties (name, type) or list).
    let mut elements: Vec<(String, usize, Vec<Prop>)> = Vec::new();
    for l in lines {
        let w: Vec<&str> = l.split_whitespace().collect();
        match w.first().copied() {
            Some("format") => format = w.get(1).map(|s| s.to_string()),
            Some("element") if w.len() == 3 => {
                let n = w[2]
                    .parse()
                    .map_err(|_| bad(format!("bad element count in `{l}`")))?;
                elements.push((w[1].to_string(), n, Vec::new()));
            }
            Some("property") => {
                let el = elements
                    .last_mut()
                    .ok_or_else(|| bad(format!("`{l}` before any element")))?;
                if w.get(1) == Some(&"list") && w.len() == 5 {
                    el.2.push(Prop::List(
                        scalar(w[2]).ok_or_else(|| bad(format!("unknown type in `{l}`")))?,
                        scalar(w[3]).ok_or_else(|| bad(format!("unknown type in `{l}`")))?,
                    ));
                } else if w.len() == 3 {
                    el.2.push(Prop::Scalar(
                        w[2].to_string(),
                        scalar(w[1]).ok_or_else(|| bad(format!("unknown type in `{l}`")))?,
                    ));
                } else {
                    return Err(bad(format!("cannot parse `{l}`")));
                }
            }
            _ => {}
        }
    }
    let format = format.ok_or_else(|| bad("no `format` line".into()))?;
    let (vi, (_, nv, props)) = elements
        .iter()
        .enumerate()
        .find(|(_, e)| e.0 == "vertex")
        .ok_or_else(|| bad("no `vertex` element".into()))?;
    let col = |name: &str| {
        props
            .iter()
            .position(|p| matches!(p, Prop::Scalar(n, _) if n == name))
            .ok_or_else(|| bad(format!("the vertex element has no `{name}` property")))
    };
    let (cx, cy, cz) = (col("x")?, col("y")?, col("z")?);
    if elements[..vi]
        .iter()
        .any(|e| e.2.iter().any(|p| matches!(p, Prop::List(..))))
    {
        return Err(bad(
            "elements with lists before the vertices are not supported".into(),
        ));
    }
    let mut out = Vec::with_capacity(*nv);
    if format == "ascii" {
        let text =
            std::str::from_utf8(&bytes[body..]).map_err(|_| bad("body is not text".into()))?;
        let skip: usize = elements[..vi].iter().map(|e| e.1).sum();
        let mut rows = text.lines().filter(|l| !l.trim().is_empty()).skip(skip);
        for k in 0..*nv {
            let l = rows
                .next()
                .ok_or_else(|| bad(format!("ends after {k} of {nv} vertices")))?;
            let v: Vec<f64> = l
                .split_whitespace()
                .map(|x| x.parse::<f64>())
                .collect::<Result<_, _>>()
                .map_err(|_| bad(format!("vertex {k}: `{l}` is not numbers")))?;
            if v.len() < props.len() {
                return Err(bad(format!(
                    "vertex {k}: {} values for {} properties",
                    v.len(),
                    props.len()
                )));
            }
            out.push([v[cx], v[cy], v[cz]]);
        }
    } else {
        let le = match format.as_str() {
            "binary_little_endian" => true,
            "binary_big_endian" => false,
            other => return Err(bad(format!("unknown PLY format `{other}`"))),
        };
        let mut pos = body;
        for e in &elements[..vi] {
            let size: usize = e.2.iter().map(|p| p.size().unwrap_or(0)).sum();
            pos += size * e.1;
        }
        let offsets: Vec<usize> = props
            .iter()
            .scan(0, |acc, p| {
                let o = *acc;
                *acc += p.size().unwrap_or(0);
                Some(o)
            })
            .collect();
        let stride: usize = props.iter().map(|p| p.size().unwrap_or(0)).sum();
        if bytes.len() < pos + stride * nv {
            return Err(bad(format!(
                "truncated: {} vertices of {stride} bytes need {} bytes after the header, the file has {}",
                nv,
                stride * nv,
                bytes.len().saturating_sub(pos)
            )));
        }
        let get = |at: usize, t: Scalar| t.read(&bytes[at..at + t.size()], le);
        let ty = |i: usize| match &props[i] {
            Prop::Scalar(_, t) => *t,
            Prop::List(..) => unreachable!(),
        };
        for k in 0..*nv {
            let base = pos + k * stride;
            out.push([
                get(base + offsets[cx], ty(cx)),
                get(base + offsets[cy], ty(cy)),
                get(base + offsets[cz], ty(cz)),
            ]);
        }
    }
    if let Some((k, v)) = out
        .iter()
        .enumerate()
        .find(|(_, v)| v.iter().any(|x| !x.is_finite()))
    {
        return Err(bad(format!("vertex {k} is not finite: {v:?}")));
    }
    Ok(out)
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

#[derive(Clone, Copy, Debug)]
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
    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn read(self, b: &[u8], le: bool) -> f64 {
        macro_rules! conv {
            ($t:ty, $n:expr) => {{
                let a: [u8; $n] = b.try_into().unwrap();
                (if le {
                    <$t>::from_le_bytes(a)
                } else {
                    <$t>::from_be_bytes(a)
                }) as f64
            }};
        }
        match self {
            Scalar::I8 => b[0] as i8 as f64,
            Scalar::U8 => b[0] as f64,
            Scalar::I16 => conv!(i16, 2),
            Scalar::U16 => conv!(u16, 2),
            Scalar::I32 => conv!(i32, 4),
            Scalar::U32 => conv!(u32, 4),
            Scalar::F32 => conv!(f32, 4),
            Scalar::F64 => conv!(f64, 8),
        }
    }
}

fn scalar(t: &str) -> Option<Scalar> {
    Some(match t {
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

#[derive(Clone, Debug)]
enum Prop {
    Scalar(String, Scalar),
    #[allow(dead_code)]
    List(Scalar, Scalar),
}

impl Prop {
    fn size(&self) -> Option<usize> {
        match self {
            Prop::Scalar(_, t) => Some(t.size()),
            Prop::List(..) => None,
        }
    }
}

/// A regular grid of heights: row 0 at the north, column 0 at the west.
#[derive(Clone, Debug)]
pub struct HeightGrid {
    pub width: usize,
    pub height: usize,
    /// Centre of the north-west node, m.
    pub x0: f64,
    pub y0: f64,
    pub dx: f64,
    pub dy: f64,
    /// Heights, row-major from the north.
    pub z: Vec<f32>,
}

/// Arrange grid vertices into rows and columns; refuses anything but a complete regular grid.
pub fn to_grid(path: &Path, v: &[[f64; 3]]) -> Result<HeightGrid, ScenegenError> {
    let bad = |m: String| ScenegenError::Input {
        path: path.into(),
        message: m,
    };
    let distinct = |k: usize| {
        let mut a: Vec<f64> = v.iter().map(|p| p[k]).collect();
        a.sort_by(f64::total_cmp);
        a.dedup_by(|x, y| (*x - *y).abs() < 1e-6);
        a
    };
    let (xs, ys) = (distinct(0), distinct(1));
    let (w, h) = (xs.len(), ys.len());
    if w < 2 || h < 2 || w * h != v.len() {
        return Err(bad(format!(
            "the {} vertices are not a regular grid ({w} distinct x × {h} distinct y); only gridded terrain meshes can become a DEM",
            v.len()
        )));
    }
    let step = |a: &[f64], name: &str| -> Result<f64, ScenegenError> {
        let d = (a[a.len() - 1] - a[0]) / (a.len() - 1) as f64;
        if let Some(i) = (1..a.len()).find(|&i| ((a[i] - a[i - 1]) - d).abs() > 1e-6 * d.max(1.0)) {
            return Err(bad(format!(
                "{name} spacing is not uniform: {} m between {} and {} (step {d} m)",
                a[i] - a[i - 1],
                a[i - 1],
                a[i]
            )));
        }
        Ok(d)
    };
    let (dx, dy) = (step(&xs, "x")?, step(&ys, "y")?);
    let mut z = vec![f32::NAN; w * h];
    for p in v {
        let c = ((p[0] - xs[0]) / dx).round() as usize;
        let r = ((ys[h - 1] - p[1]) / dy).round() as usize;
        let cell = &mut z[r * w + c];
        if !cell.is_nan() {
            return Err(bad(format!("two vertices at x = {}, y = {}", p[0], p[1])));
        }
        *cell = p[2] as f32;
    }
    Ok(HeightGrid {
        width: w,
        height: h,
        x0: xs[0],
        y0: ys[h - 1],
        dx,
        dy,
        z,
    })
}

/// The local transverse Mercator CRS centred on (lon, lat).
pub fn local_crs(lon: f64, lat: f64) -> String {
    format!(
        "+proj=tmerc +lat_0={lat} +lon_0={lon} +k=1 +x_0=0 +y_0=0 +datum=WGS84 +units=m +no_defs"
    )
}

/// `scenegen mesh-to-dem`: write the DEM (and optionally a one-class land cover) of a gridded
/// mesh whose origin is at (lon, lat). Returns the grid.
pub fn mesh_to_dem(
    mesh: &Path,
    lon: f64,
    lat: f64,
    dem_out: &Path,
    landcover: Option<(u8, &Path)>,
) -> Result<HeightGrid, ScenegenError> {
    if !(lat.abs() < 89.0 && lon.abs() <= 180.0) {
        return Err(ScenegenError::Input {
            path: mesh.into(),
            message: format!("centre ({lon}, {lat}) is not a longitude in [-180, 180] and a latitude in (-89, 89)"),
        });
    }
    let v = read_mesh_vertices(mesh)?;
    let g = to_grid(mesh, &v)?;
    let gt = [g.x0 - 0.5 * g.dx, g.dx, 0.0, g.y0 + 0.5 * g.dy, 0.0, -g.dy];
    let crs = local_crs(lon, lat);
    write_geotiff(
        dem_out,
        g.width,
        g.height,
        Some(gt),
        Some(&crs),
        None,
        g.z.clone(),
    )?;
    if let Some((code, path)) = landcover {
        write_geotiff(
            path,
            g.width,
            g.height,
            Some(gt),
            Some(&crs),
            None,
            vec![code; g.width * g.height],
        )?;
    }
    Ok(g)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write_ascii(path: &Path, verts: &[[f64; 3]]) {
        let mut s = format!(
            "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n",
            verts.len()
        );
        for v in verts {
            s += &format!("{} {} {}\n", v[0], v[1], v[2]);
        }
        std::fs::write(path, s).unwrap();
    }

    /// A 3 × 2 ASCII grid becomes a DEM whose pixel centres are the vertices (read back with
    /// GDAL: heights, geotransform, CRS); a missing vertex and uneven spacing are refused.
    #[test]
    fn ascii_grid_to_dem_and_refusals() {
        let dir = std::env::temp_dir().join(format!("mesh_dem_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("g.ply");
        let verts: Vec<[f64; 3]> = [
            (-50.0, -25.0),
            (50.0, -25.0),
            (150.0, -25.0),
            (-50.0, 75.0),
            (50.0, 75.0),
            (150.0, 75.0),
        ]
        .iter()
        .enumerate()
        .map(|(i, &(x, y))| [x, y, 100.0 + i as f64])
        .collect();
        write_ascii(&p, &verts);
        let dem = dir.join("dem.tif");
        let lc = dir.join("lc.tif");
        let g = mesh_to_dem(&p, 23.39, 28.55, &dem, Some((60, &lc))).unwrap();
        assert_eq!((g.width, g.height, g.dx, g.dy), (3, 2, 100.0, 100.0));
        let ds = gdal::Dataset::open(&dem).unwrap();
        assert_eq!(
            ds.geo_transform().unwrap(),
            [-100.0, 100.0, 0.0, 125.0, 0.0, -100.0]
        );
        assert!(ds
            .spatial_ref()
            .unwrap()
            .to_proj4()
            .unwrap()
            .contains("+lat_0=28.55"));
        let b = ds.rasterband(1).unwrap();
        let z = b.read_as::<f32>((0, 0), (3, 2), (3, 2), None).unwrap();
        // Row 0 is the north (y = 75): vertices 3, 4, 5.
        assert_eq!(z.data(), &[103.0, 104.0, 105.0, 100.0, 101.0, 102.0]);
        let l = gdal::Dataset::open(&lc).unwrap();
        let c = l
            .rasterband(1)
            .unwrap()
            .read_as::<u8>((0, 0), (3, 2), (3, 2), None)
            .unwrap();
        assert!(c.data().iter().all(|&v| v == 60));

        write_ascii(&p, &verts[..5]);
        let e = mesh_to_dem(&p, 23.39, 28.55, &dem, None)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("g.ply") && e.contains("not a regular grid"),
            "{e}"
        );
        let mut uneven = verts.clone();
        for v in uneven.iter_mut().filter(|v| v[0] == 150.0) {
            v[0] = 170.0;
        }
        write_ascii(&p, &uneven);
        let e = mesh_to_dem(&p, 23.39, 28.55, &dem, None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("not uniform"), "{e}");
        std::fs::write(&p, "not a ply").unwrap();
        let e = mesh_to_dem(&p, 23.39, 28.55, &dem, None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a PLY"), "{e}");
        // The same grid as OBJ `v` lines gives the same DEM.
        let obj = dir.join("g.obj");
        let text: String = verts
            .iter()
            .map(|v| format!("v {} {} {}\n", v[0], v[1], v[2]))
            .collect();
        std::fs::write(&obj, format!("# grid\n{text}f 1 2 5\n")).unwrap();
        let g = mesh_to_dem(&obj, 23.39, 28.55, &dem, None).unwrap();
        assert_eq!((g.width, g.height), (3, 2));
        assert_eq!(g.z, vec![103.0, 104.0, 105.0, 100.0, 101.0, 102.0]);
        std::fs::write(&obj, "v 1 2\n").unwrap();
        let e = mesh_to_dem(&obj, 23.39, 28.55, &dem, None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("g.obj") && e.contains("line 1"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// The shared Libya-4 mesh (binary little endian, with extra s, t properties and faces):
    /// 200 × 200 nodes at 100 m, x, y in [−9950, 9950] m, heights 97.8–156.0 m (MANIFEST).
    #[test]
    fn libya4_mesh() {
        let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../shared/data/terrain/libya4_20km.ply");
        if !p.exists() {
            eprintln!("skipped: {} is absent", p.display());
            return;
        }
        let v = read_ply_vertices(&p).unwrap();
        let g = to_grid(&p, &v).unwrap();
        assert_eq!((g.width, g.height), (200, 200));
        assert_eq!((g.dx, g.dy), (100.0, 100.0));
        assert_eq!((g.x0, g.y0), (-9950.0, 9950.0));
        let (lo, hi) =
            g.z.iter()
                .fold((f32::MAX, f32::MIN), |(a, b), &z| (a.min(z), b.max(z)));
        assert!(
            (lo - 97.8).abs() < 0.1 && (hi - 156.0).abs() < 0.1,
            "{lo} {hi}"
        );
    }
}
