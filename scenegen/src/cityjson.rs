//! City models from CityJSON (`[[city_models]]`, CityJSON 1.0–2.0): the surfaces of the chosen
//! city objects (default `Building` and `BuildingPart`) taken as they are, triangulated, and
//! placed as scene geometry with roof and wall materials. Keys: docs/region.md.
//!
//! * **Vertices**: the file's integer vertices through its `transform` (scale, translate) when
//!   it has one; horizontal coordinates reprojected from its `referenceSystem` (or the `crs` key)
//!   to the working CRS, heights kept as they are (a compound CRS's vertical datum, e.g. NAP in
//!   EPSG:7415, must be the DEM's).
//! * **Geometry**: of each object, the geometry of the highest level of detail (or `lod`);
//!   `Solid`, `MultiSolid`, `CompositeSolid`, `MultiSurface` and `CompositeSurface`. Each surface
//!   (an exterior ring and holes) is triangulated in its own plane (Newell normal, constrained
//!   Delaunay triangulation, triangles inside the rings kept); vertex indices are shared as in
//!   the file, so a watertight solid stays watertight.
//! * **Materials**: with semantics, `RoofSurface` → `roof_material`, every other surface type
//!   (walls, ground, closures) → `wall_material`; without semantics, surfaces whose normal points
//!   up (n_z > 0.5) are roofs and the rest walls.
//! * Bad input is named: unreadable JSON, a missing `CityObjects`/`vertices`, a vertex index out
//!   of range, an unknown CRS. A surface that cannot be triangulated (fewer than three distinct
//!   vertices, crossing rings), and a geometry without surfaces (`MultiPoint`,
//!   `GeometryInstance`, …), are skipped with a warning naming the object.
//! * An object whose `children` are taken too (a 3DBAG `Building` above its `BuildingPart`s) is
//!   left out: its parts carry its geometry.

pub use crate::inputs::CityModelSpec;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use gdal::spatial_ref::{AxisMappingStrategy, CoordTransform, SpatialRef};
use serde_json::Value;
use spade::{ConstrainedDelaunayTriangulation, Point2, Triangulation};

use crate::buildings::TemplateGroups;
use crate::error::ScenegenError;
use crate::raster::WorkingFrame;

/// One city object as placed.
#[derive(Clone, Debug)]
pub struct CityObjectRecord {
    pub id: String,
    /// Lowest and highest vertex heights, m.
    pub zmin: f64,
    pub zmax: f64,
    pub triangles: usize,
    /// Centre of its bounding box in the working CRS.
    pub centre: [f64; 2],
    /// Its `attributes` object as in the file.
    pub attributes: Value,
}

/// What the city-model stage produced.
#[derive(Default)]
pub struct CityModelsOutput {
    pub templates: Vec<bundle::TemplateMesh>,
    pub origins: Vec<[f64; 2]>,
    pub records: Vec<CityObjectRecord>,
    /// Surfaces skipped (object id, reason).
    pub skipped: Vec<(String, String)>,
    pub inputs: Vec<PathBuf>,
}

fn bad(path: &Path, message: impl Into<String>) -> ScenegenError {
    ScenegenError::Input {
        path: path.into(),
        message: message.into(),
    }
}

/// EPSG code of a CityJSON `referenceSystem` (1.0 URN or 1.1+ URL).
fn epsg_of(rs: &str) -> Option<u32> {
    rs.rsplit([':', '/'])
        .find(|t| !t.is_empty())
        .and_then(|t| t.parse().ok())
}

/// Triangulate one planar polygon (rings of vertex indices into `v`); returns triangles of
/// vertex indices oriented like the exterior ring, and the polygon's Newell normal.
fn triangulate_surface(
    rings: &[Vec<u32>],
    v: &[[f64; 3]],
) -> Result<(Vec<[u32; 3]>, [f64; 3]), String> {
    let ext = rings.first().ok_or("a surface without rings")?;
    // Newell normal of the exterior ring.
    let mut n = [0.0f64; 3];
    for i in 0..ext.len() {
        let (a, b) = (v[ext[i] as usize], v[ext[(i + 1) % ext.len()] as usize]);
        n[0] += (a[1] - b[1]) * (a[2] + b[2]);
        n[1] += (a[2] - b[2]) * (a[0] + b[0]);
        n[2] += (a[0] - b[0]) * (a[1] + b[1]);
    }
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    if len.is_nan() || len <= 1e-12 {
        return Err("a degenerate surface (no area)".into());
    }
    let n = [n[0] / len, n[1] / len, n[2] / len];
    if rings.len() == 1 && ext.len() == 3 {
        return Ok((vec![[ext[0], ext[1], ext[2]]], n));
    }
    // A 2D frame in the plane: u, w with u × w = n.
    let a = if n[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let cross = |p: [f64; 3], q: [f64; 3]| {
        [
            p[1] * q[2] - p[2] * q[1],
            p[2] * q[0] - p[0] * q[2],
            p[0] * q[1] - p[1] * q[0],
        ]
    };
    let u = cross(a, n);
    let ul = (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt();
    let u = [u[0] / ul, u[1] / ul, u[2] / ul];
    let w = cross(n, u);
    let o = v[ext[0] as usize];
    let proj = |i: u32| {
        let p = v[i as usize];
        let d = [p[0] - o[0], p[1] - o[1], p[2] - o[2]];
        [
            d[0] * u[0] + d[1] * u[1] + d[2] * u[2],
            d[0] * w[0] + d[1] * w[1] + d[2] * w[2],
        ]
    };
    let mut cdt: ConstrainedDelaunayTriangulation<Point2<f64>> =
        ConstrainedDelaunayTriangulation::new();
    let mut map: BTreeMap<usize, u32> = BTreeMap::new();
    let mut polys: Vec<Vec<[f64; 2]>> = Vec::new();
    for r in rings {
        let mut hs = Vec::with_capacity(r.len());
        let mut ring2 = Vec::with_capacity(r.len());
        for &i in r {
            let p = proj(i);
            let h = cdt
                .insert(Point2::new(p[0], p[1]))
                .map_err(|e| format!("vertex {i}: {e:?}"))?;
            map.entry(h.index()).or_insert(i);
            hs.push(h);
            ring2.push(p);
        }
        for k in 0..hs.len() {
            let (p, q) = (hs[k], hs[(k + 1) % hs.len()]);
            if p != q && cdt.try_add_constraint(p, q).is_empty() && !cdt.exists_constraint(p, q) {
                return Err("its rings cross".into());
            }
        }
        polys.push(ring2);
    }
    if cdt.num_vertices() != map.len() {
        return Err("its rings cross".into());
    }
    let inside = |c: [f64; 2]| {
        polys
            .iter()
            .filter(|ring| {
                let mut odd = false;
                let m = ring.len();
                for k in 0..m {
                    let (a, b) = (ring[k], ring[(k + 1) % m]);
                    if (a[1] > c[1]) != (b[1] > c[1])
                        && c[0] < a[0] + (c[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0])
                    {
                        odd = !odd;
                    }
                }
                odd
            })
            .count()
            % 2
            == 1
    };
    let mut tris = Vec::new();
    for f in cdt.inner_faces() {
        let vs = f.vertices();
        let c = vs.iter().fold([0.0, 0.0], |acc, h| {
            let p = h.position();
            [acc[0] + p.x / 3.0, acc[1] + p.y / 3.0]
        });
        if inside(c) {
            // spade's faces are counter-clockwise in (u, w), i.e. about +n.
            tris.push(vs.map(|h| map[&h.fix().index()]));
        }
    }
    if tris.is_empty() {
        return Err("it triangulates to nothing".into());
    }
    Ok((tris, n))
}

/// Surfaces (rings of vertex indices) of a CityJSON geometry, with each surface's semantic
/// value index (if any).
/// A surface's rings (exterior first) and its semantic value index.
type Surface = (Vec<Vec<u32>>, Option<usize>);

fn surfaces(g: &Value) -> Result<Vec<Surface>, String> {
    let ty = g["type"].as_str().unwrap_or("");
    let b = &g["boundaries"];
    let sv = &g["semantics"]["values"];
    let ring = |r: &Value| -> Result<Vec<u32>, String> {
        r.as_array()
            .ok_or("a ring is not an array")?
            .iter()
            .map(|i| {
                i.as_u64()
                    .and_then(|i| u32::try_from(i).ok())
                    .ok_or_else(|| "a vertex index is not an integer below 2³²".to_string())
            })
            .collect()
    };
    let surface = |s: &Value| -> Result<Vec<Vec<u32>>, String> {
        s.as_array()
            .ok_or("a surface is not an array")?
            .iter()
            .map(ring)
            .collect()
    };
    let arr = |x: &Value| x.as_array().cloned().unwrap_or_default();
    let mut out = Vec::new();
    match ty {
        "MultiSurface" | "CompositeSurface" => {
            for (k, s) in arr(b).iter().enumerate() {
                out.push((surface(s)?, sv[k].as_u64().map(|x| x as usize)));
            }
        }
        "Solid" => {
            for (i, shell) in arr(b).iter().enumerate() {
                for (k, s) in arr(shell).iter().enumerate() {
                    out.push((surface(s)?, sv[i][k].as_u64().map(|x| x as usize)));
                }
            }
        }
        "MultiSolid" | "CompositeSolid" => {
            for (j, solid) in arr(b).iter().enumerate() {
                for (i, shell) in arr(solid).iter().enumerate() {
                    for (k, s) in arr(shell).iter().enumerate() {
                        out.push((surface(s)?, sv[j][i][k].as_u64().map(|x| x as usize)));
                    }
                }
            }
        }
        other => return Err(format!("geometry type `{other}` has no surfaces")),
    }
    Ok(out)
}

fn lod_of(g: &Value) -> String {
    match &g["lod"] {
        Value::String(s) => s.clone(),
        Value::Number(n) => n.to_string(),
        _ => String::new(),
    }
}

/// Read every `[[city_models]]` file into templates (one per square of `tile_m`).
pub fn build(
    specs: &[CityModelSpec],
    frame: &WorkingFrame,
    tile_m: f64,
    mut material: impl FnMut(&str) -> Result<u8, ScenegenError>,
) -> Result<CityModelsOutput, ScenegenError> {
    let mut out = CityModelsOutput::default();
    let mut groups = TemplateGroups::new(tile_m);
    for spec in specs {
        let path = &spec.file;
        let (roof_m, wall_m) = (
            material(&spec.roof_material)?,
            material(&spec.wall_material)?,
        );
        let text = std::fs::read_to_string(path)
            .map_err(|e| bad(path, format!("cannot read the city model: {e}")))?;
        let doc: Value =
            serde_json::from_str(&text).map_err(|e| bad(path, format!("not valid JSON: {e}")))?;
        if doc["type"].as_str() != Some("CityJSON") {
            return Err(bad(
                path,
                "not a CityJSON file (`type` is not \"CityJSON\")",
            ));
        }
        let objects = doc["CityObjects"]
            .as_object()
            .ok_or_else(|| bad(path, "no `CityObjects` object"))?;
        let raw = doc["vertices"]
            .as_array()
            .ok_or_else(|| bad(path, "no `vertices` array"))?;
        let (scale, translate) = match doc.get("transform") {
            Some(t) => {
                let f = |k: &str| -> Result<[f64; 3], ScenegenError> {
                    let a = t[k].as_array().filter(|a| a.len() == 3).ok_or_else(|| {
                        bad(path, format!("`transform.{k}` must be three numbers"))
                    })?;
                    Ok([0, 1, 2].map(|i| a[i].as_f64().unwrap_or(f64::NAN)))
                };
                (f("scale")?, f("translate")?)
            }
            None => ([1.0; 3], [0.0; 3]),
        };
        let mut v: Vec<[f64; 3]> = Vec::with_capacity(raw.len());
        for (k, p) in raw.iter().enumerate() {
            let c = p
                .as_array()
                .filter(|a| a.len() == 3)
                .ok_or_else(|| bad(path, format!("vertex {k} is not three numbers")))?;
            let q = [0, 1, 2].map(|i| c[i].as_f64().unwrap_or(f64::NAN) * scale[i] + translate[i]);
            if !q.iter().all(|x| x.is_finite()) {
                return Err(bad(path, format!("vertex {k} is not finite")));
            }
            v.push(q);
        }
        // Horizontal reprojection.
        let mut src = match &spec.crs {
            Some(def) => SpatialRef::from_definition(def)
                .map_err(|e| bad(path, format!("GDAL cannot read CRS `{def}`: {e}")))?,
            None => {
                let rs = doc["metadata"]["referenceSystem"].as_str().ok_or_else(|| {
                    bad(
                        path,
                        "the city model declares no `metadata.referenceSystem`: give `crs`",
                    )
                })?;
                let code = epsg_of(rs).ok_or_else(|| {
                    bad(
                        path,
                        format!("cannot read an EPSG code from referenceSystem `{rs}`: give `crs`"),
                    )
                })?;
                SpatialRef::from_epsg(code).map_err(|e| bad(path, format!("EPSG:{code}: {e}")))?
            }
        };
        src.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
        let mut dst = frame.srs.clone();
        dst.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
        let t = CoordTransform::new(&src, &dst)
            .map_err(|e| bad(path, format!("no transformation to the working CRS: {e}")))?;
        let mut xs: Vec<f64> = v.iter().map(|p| p[0]).collect();
        let mut ys: Vec<f64> = v.iter().map(|p| p[1]).collect();
        t.transform_coords(&mut xs, &mut ys, &mut [])
            .map_err(|e| bad(path, format!("cannot transform its vertices: {e}")))?;
        for (k, p) in v.iter_mut().enumerate() {
            p[0] = xs[k];
            p[1] = ys[k];
        }
        let label = format!("{}", path.display());
        let mut taken = 0;
        for (id, o) in objects {
            let ty = o["type"].as_str().unwrap_or("");
            if !spec.types.iter().any(|t| t == ty) {
                continue;
            }
            // A parent whose parts are taken too (3DBAG: a Building's LoD0 outline above its
            // BuildingParts' solids) would be placed twice.
            let taken_child = o["children"].as_array().is_some_and(|c| {
                c.iter().filter_map(Value::as_str).any(|k| {
                    objects
                        .get(k)
                        .and_then(|x| x["type"].as_str())
                        .is_some_and(|t| spec.types.iter().any(|s| s == t))
                })
            });
            if taken_child {
                continue;
            }
            let geoms = o["geometry"].as_array().cloned().unwrap_or_default();
            let g = match &spec.lod {
                Some(l) => geoms.iter().find(|g| lod_of(g) == *l),
                None => geoms.iter().max_by(|a, b| {
                    lod_of(a)
                        .parse::<f64>()
                        .unwrap_or(0.0)
                        .total_cmp(&lod_of(b).parse::<f64>().unwrap_or(0.0))
                }),
            };
            let Some(g) = g else {
                tracing::warn!(
                    "{label}: city object {id} has no geometry{}: skipped",
                    spec.lod
                        .as_ref()
                        .map(|l| format!(" of lod {l}"))
                        .unwrap_or_default()
                );
                out.skipped.push((id.clone(), "no geometry".into()));
                continue;
            };
            let surfs = match surfaces(g) {
                Ok(s) => s,
                Err(e) if e.contains("has no surfaces") => {
                    tracing::warn!("{label}: city object {id}: skipped: {e}");
                    out.skipped.push((id.clone(), e));
                    continue;
                }
                Err(e) => return Err(bad(path, format!("city object {id}: {e}"))),
            };
            let sem = g["semantics"]["surfaces"]
                .as_array()
                .cloned()
                .unwrap_or_default();
            // Local vertex table of this object.
            let mut local: BTreeMap<u32, u32> = BTreeMap::new();
            let mut pos: Vec<[f64; 3]> = Vec::new();
            let (mut tris, mut mats) = (Vec::new(), Vec::new());
            for (k, (rings, sv)) in surfs.iter().enumerate() {
                for r in rings {
                    if let Some(&i) = r.iter().find(|&&i| i as usize >= v.len()) {
                        return Err(bad(
                            path,
                            format!(
                                "city object {id}, surface {k}: vertex index {i} ≥ {} vertices",
                                v.len()
                            ),
                        ));
                    }
                }
                let (tt, n) = match triangulate_surface(rings, &v) {
                    Ok(x) => x,
                    Err(why) => {
                        tracing::warn!("{label}: city object {id}, surface {k}: skipped: {why}");
                        out.skipped
                            .push((id.clone(), format!("surface {k}: {why}")));
                        continue;
                    }
                };
                let roof = match sv.and_then(|i| sem.get(i)) {
                    Some(s) => s["type"].as_str() == Some("RoofSurface"),
                    None => n[2] > 0.5,
                };
                for tri in tt {
                    tris.push(tri.map(|i| {
                        *local.entry(i).or_insert_with(|| {
                            pos.push(v[i as usize]);
                            (pos.len() - 1) as u32
                        })
                    }));
                    mats.push(if roof { roof_m } else { wall_m });
                }
            }
            if tris.is_empty() {
                continue;
            }
            let (mut bb, mut zmin, mut zmax) =
                ([f64::MAX, f64::MAX, f64::MIN, f64::MIN], f64::MAX, f64::MIN);
            for p in &pos {
                bb = [
                    bb[0].min(p[0]),
                    bb[1].min(p[1]),
                    bb[2].max(p[0]),
                    bb[3].max(p[1]),
                ];
                zmin = zmin.min(p[2]);
                zmax = zmax.max(p[2]);
            }
            let centre = [0.5 * (bb[0] + bb[2]), 0.5 * (bb[1] + bb[3])];
            groups.add(centre, &pos, &tris, &mats, &label);
            out.records.push(CityObjectRecord {
                id: id.clone(),
                zmin,
                zmax,
                triangles: tris.len(),
                centre,
                attributes: o["attributes"].clone(),
            });
            taken += 1;
        }
        tracing::info!(
            "city model {label}: {taken} objects of types {:?} placed",
            spec.types
        );
        out.inputs.push(path.clone());
    }
    (out.templates, out.origins) = groups.finish("city");
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_systems_give_their_code() {
        assert_eq!(epsg_of("urn:ogc:def:crs:EPSG::7415"), Some(7415));
        assert_eq!(
            epsg_of("https://www.opengis.net/def/crs/EPSG/0/28992"),
            Some(28992)
        );
        assert_eq!(epsg_of("nonsense"), None);
    }

    #[test]
    fn a_square_with_a_hole_triangulates_inside_the_rings() {
        let v = vec![
            [0.0, 0.0, 5.0],
            [10.0, 0.0, 5.0],
            [10.0, 10.0, 5.0],
            [0.0, 10.0, 5.0],
            [4.0, 4.0, 5.0],
            [4.0, 6.0, 5.0],
            [6.0, 6.0, 5.0],
            [6.0, 4.0, 5.0],
        ];
        let (t, n) = triangulate_surface(&[vec![0, 1, 2, 3], vec![4, 5, 6, 7]], &v).unwrap();
        assert!((n[2] - 1.0).abs() < 1e-12);
        let area: f64 = t
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| v[i as usize]);
                0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]))
            })
            .sum();
        assert!((area - 96.0).abs() < 1e-9, "area {area}, oriented up");
        // A vertical wall facing −y.
        let w = vec![
            [0.0, 0.0, 0.0],
            [10.0, 0.0, 0.0],
            [10.0, 0.0, 3.0],
            [0.0, 0.0, 3.0],
        ];
        let (t, n) = triangulate_surface(&[vec![0, 1, 2, 3]], &w).unwrap();
        assert_eq!(t.len(), 2);
        assert!((n[1] + 1.0).abs() < 1e-12, "{n:?}");
    }
}
