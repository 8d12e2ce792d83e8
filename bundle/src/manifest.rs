//! The bundle manifest (`manifest.toml`): serde types, one per table, with units in the field
//! docs. Unknown keys are refused (`deny_unknown_fields`) so that a reader never silently ignores
//! something a newer writer meant.

use serde::{Deserialize, Serialize};

use crate::brdf::BrdfSpec;

/// Top level of `manifest.toml`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// Always [`super::FORMAT_NAME`].
    pub format: String,
    /// [`super::FORMAT_VERSION`] of the writer.
    pub format_version: u32,
    pub crs: Crs,
    pub frame: LocalFrame,
    pub extent: Extent,
    pub terrain: Terrain,
    pub material_raster: MaterialRaster,
    /// Material table; the material raster and template triangles hold its entries' `index`.
    pub materials: Vec<Material>,
    #[serde(default)]
    pub templates: Vec<Template>,
    pub instances: Instances,
    pub provenance: Provenance,
    /// The area of interest as a polygon, when the region file gave one (`[area] polygon`);
    /// the extent is then its bounding box.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub area: Option<AreaPolygon>,
}

/// A polygonal area of interest, in the working CRS.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AreaPolygon {
    /// OGC WKT `MULTIPOLYGON` in working-CRS metres (the same coordinates as `extent`).
    pub wkt: String,
    /// Planar area in the working CRS, m².
    pub area_m2: f64,
    /// The polygon file named by the region file.
    pub source: String,
}

/// Rings (exterior first, then holes) of points (x, y).
pub type PolygonRings = Vec<Vec<[f64; 2]>>;

impl AreaPolygon {
    /// The polygons of `wkt` (`MULTIPOLYGON (((x y, …), (…)), ((…)))` as scenegen writes it, or
    /// a `POLYGON`): each a list of closed rings of at least 4 points.
    pub fn polygons(&self) -> Result<Vec<PolygonRings>, String> {
        let t = self.wkt.trim();
        let upper = t.to_ascii_uppercase();
        let (body, multi) = if let Some(r) = upper.strip_prefix("MULTIPOLYGON") {
            (&t[t.len() - r.len()..], true)
        } else if let Some(r) = upper.strip_prefix("POLYGON") {
            (&t[t.len() - r.len()..], false)
        } else {
            return Err("not a WKT POLYGON or MULTIPOLYGON".into());
        };
        // Nesting depth of a ring's points: 3 in a multipolygon, 2 in a polygon.
        let ring_depth = if multi { 3 } else { 2 };
        let (mut depth, mut polys, mut cur, mut text) = (0, Vec::new(), Vec::new(), String::new());
        for ch in body.trim().chars() {
            match ch {
                '(' => depth += 1,
                ')' => {
                    if depth == ring_depth {
                        let ring: Result<Vec<[f64; 2]>, String> = text
                            .split(',')
                            .map(|p| {
                                let v: Vec<f64> = p
                                    .split_whitespace()
                                    .map(|w| {
                                        w.parse::<f64>().map_err(|_| format!("bad number `{w}`"))
                                    })
                                    .collect::<Result<_, _>>()?;
                                match v[..] {
                                    [x, y, ..] if x.is_finite() && y.is_finite() => Ok([x, y]),
                                    _ => Err(format!("bad point `{}`", p.trim())),
                                }
                            })
                            .collect();
                        let ring = ring?;
                        if ring.len() < 4 || ring[0] != ring[ring.len() - 1] {
                            return Err("a ring must be closed and have at least 4 points".into());
                        }
                        cur.push(ring);
                        text.clear();
                    } else if depth == ring_depth - 1 {
                        polys.push(std::mem::take(&mut cur));
                    }
                    depth -= 1;
                }
                c if depth == ring_depth => text.push(c),
                c if c.is_whitespace() || c == ',' => {}
                c => return Err(format!("unexpected `{c}`")),
            }
            if depth < 0 || depth > ring_depth {
                return Err("unbalanced parentheses".into());
            }
        }
        if depth != 0 || polys.is_empty() {
            return Err("unbalanced parentheses or no polygon".into());
        }
        Ok(polys)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rationale: what scenegen writes reads back; broken text is an error, not a panic.
    #[test]
    fn area_polygon_wkt_round_trip() {
        let a = |wkt: &str| AreaPolygon {
            wkt: wkt.into(),
            area_m2: 0.0,
            source: String::new(),
        };
        let p = a("MULTIPOLYGON (((0 0, 10 0, 10 10, 0 0), (1 1, 2 1, 2 2, 1 1)), ((20 0, 30 0, 30 5, 20 0)))")
            .polygons()
            .unwrap();
        assert_eq!(p.len(), 2);
        assert_eq!(p[0].len(), 2);
        assert_eq!(p[1][0][2], [30.0, 5.0]);
        assert_eq!(
            a("POLYGON ((0 0, 1 0, 1 1, 0 0))")
                .polygons()
                .unwrap()
                .len(),
            1
        );
        for bad in [
            "LINESTRING (0 0, 1 1)",
            "MULTIPOLYGON (((0 0, 1 0, 1 1)))",
            "POLYGON ((0 0, x 0, 1 1, 0 0))",
            "POLYGON ((0 0, 1 0, 1 1, 0 0)",
        ] {
            assert!(a(bad).polygons().is_err(), "{bad}");
        }
    }
}

/// The working (projected, metric) CRS.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Crs {
    /// OGC WKT of the working CRS.
    pub wkt: String,
    /// EPSG code where the CRS has one.
    #[serde(default)]
    pub epsg: Option<u32>,
    /// PROJ definition where the CRS was built from one (the default local frame).
    #[serde(default)]
    pub proj: Option<String>,
}

/// The local frame: world (working CRS) coordinates = `origin` + local coordinates.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LocalFrame {
    /// How the frame relates to the CRS: "projected_enu" (x = easting, y = northing, z = height,
    /// metres; Earth curvature is that of the map projection, i.e. none).
    pub kind: String,
    /// Working-CRS coordinates of the local origin, metres.
    pub origin: [f64; 3],
    /// Longitude, latitude of the area's centre, degrees (WGS 84).
    pub centre_lon_lat: [f64; 2],
    /// Vertical datum of z, as given by the DEM (e.g. "EGM2008 geoid" or "unknown").
    #[serde(default)]
    pub vertical_datum: String,
}

/// Extent of the scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Extent {
    /// Working-CRS minimum x, y, metres.
    pub min: [f64; 2],
    /// Working-CRS maximum x, y, metres.
    pub max: [f64; 2],
    /// Lowest and highest terrain height, metres.
    pub height_range: [f64; 2],
    /// West, south, east, north, degrees (WGS 84) of the area of interest.
    pub lon_lat_bbox: [f64; 4],
}

/// Terrain: a TIN split into tiles; every tile's vertices are in its own local f32 frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Terrain {
    /// Binary file, relative to the bundle.
    pub file: String,
    /// Maximum vertical error of the triangulated surface at every DEM sample, metres.
    pub tolerance_m: f64,
    /// Spacing of the working DEM grid, metres.
    pub dem_spacing_m: f64,
    /// DEM samples in the working grid.
    pub dem_samples: u64,
    pub vertex_count: u64,
    pub triangle_count: u64,
    pub tiles: Vec<TerrainTileInfo>,
}

/// One terrain tile's place in `terrain.bin`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TerrainTileInfo {
    /// Column, row of the tile (row 0 is the southernmost).
    pub id: [u32; 2],
    /// Working-CRS coordinates of the tile's local origin, metres.
    pub origin: [f64; 3],
    /// Byte offset of `vertex_count` × [f32; 3] positions (local, metres).
    pub positions_offset: u64,
    /// Byte offset of `vertex_count` × [f32; 2] texture coordinates into the material raster
    /// (u to the east, v to the south, both in [0, 1] over the raster).
    pub uvs_offset: u64,
    /// Byte offset of `triangle_count` × [u32; 3] vertex indices, counter-clockwise seen from above.
    pub indices_offset: u64,
    pub vertex_count: u64,
    pub triangle_count: u64,
}

/// The material-index raster.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialRaster {
    pub file: String,
    pub width: u32,
    pub height: u32,
    /// GDAL-order geotransform in the working CRS: x = gt\[0\] + col·gt\[1\] + row·gt\[2\],
    /// y = gt\[3\] + col·gt\[4\] + row·gt\[5\] (for the pixel corner; gt\[5\] < 0, row 0 is the north).
    pub geotransform: [f64; 6],
    /// How the land cover was resampled onto this grid ("mode" or "nearest").
    pub resampling: String,
    /// Pixels per material id (the raster's value, a material's `index`; entry 255 counts cells
    /// without a material), for summaries.
    pub histogram: Vec<u64>,
}

/// A material: its place in the table, its BRDF, where it came from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Material {
    /// The material id used by the raster and template triangles: unique, 0..=254, not
    /// necessarily contiguous or in list order.
    pub index: u8,
    pub name: String,
    pub brdf: BrdfSpec,
    /// Land-cover class codes mapped to it (empty for template materials).
    #[serde(default)]
    pub class_codes: Vec<u32>,
    /// Where the parameters come from.
    #[serde(default)]
    pub source: String,
    /// The radiometry solver of the material (absent: the default `generic` solver).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub solver: Option<crate::SolverSpec>,
    /// Kinetic temperature of the material, K, for thermal emission (`emission = true`;
    /// absent: give it in the experiment's `[scene.temperatures]`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub temperature: Option<f64>,
}

/// A template mesh stored once in `templates.bin`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Template {
    pub id: u32,
    pub name: String,
    /// File or generator it came from.
    pub source: String,
    /// Byte offset of `vertex_count` × [f32; 3] positions (template frame: metres, z up, origin
    /// at the centre of the footprint on the ground).
    pub positions_offset: u64,
    /// Byte offset of `triangle_count` × [u32; 3] indices.
    pub indices_offset: u64,
    /// Byte offset of `triangle_count` × u8 material ids (the `index` of a manifest material).
    pub materials_offset: u64,
    pub vertex_count: u64,
    pub triangle_count: u64,
    /// Axis-aligned bounds in the template frame, metres.
    pub bounds_min: [f32; 3],
    pub bounds_max: [f32; 3],
    /// Lamps every instance of the template carries (streetlights): `[[lights]]` tables of an
    /// experiment (docs/experiment.md) with `position_m` and `direction` in the template frame;
    /// used when an experiment sets `scene.lamps = true`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub lamps: Vec<toml::Table>,
}

/// Where the instance records are.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Instances {
    pub file: String,
    pub count: u64,
    /// Instances per template id.
    #[serde(default)]
    pub per_template: Vec<u64>,
}

/// Where the bundle came from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Provenance {
    pub generator: String,
    pub generator_version: String,
    pub seed: u64,
    /// The region file's text.
    pub region_toml: String,
    pub inputs: Vec<InputFile>,
    /// SHA-256 of every binary file of the bundle, in the order terrain, templates, instances,
    /// materials (hex), each also listed in `files`.
    pub files: Vec<FileDigest>,
}

/// An input file and its checksum.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InputFile {
    pub role: String,
    pub path: String,
    pub bytes: u64,
    pub sha256: String,
}

/// A bundle file and its checksum.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FileDigest {
    pub file: String,
    pub bytes: u64,
    pub sha256: String,
}
