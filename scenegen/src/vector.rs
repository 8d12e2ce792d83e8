//! Vector inputs: one layer of any file OGR opens (GeoPackage, SpatiaLite/SQLite, GeoJSON,
//! shapefile, FlatGeobuf …), its features' polygons reprojected to the working CRS and the
//! attributes a caller asks for. Used by vector land cover (`landcover_vector.rs`).
//!
//! Every feature is accounted for: a missing file, layer or attribute, a layer without a CRS
//! (unless the region names one), or an unprojectable geometry is an error naming the file, the
//! layer and the feature id; non-polygonal features are returned apart (`not_polygons`) for the
//! caller to refuse (land cover) or skip with a warning (buildings); an empty geometry is
//! skipped with a warning that names it; an invalid polygon (self-intersection, GEOS's
//! `IsValid`) is kept with a warning naming it (GDAL's rasteriser burns it by its rings'
//! scanline parity, so its pixels are still decided). Geometries come back as plain 2D polygons
//! or multipolygons: Z and M values are dropped and curves (`CurvePolygon`, `MultiSurface`)
//! approximated by line segments (GDAL's default step). An attribute read from OpenStreetMap's
//! `other_tags` that no feature of the layer carries is an error (a misspelt key would otherwise
//! read as null everywhere).

use std::path::Path;

use gdal::spatial_ref::{AxisMappingStrategy, CoordTransform, SpatialRef};
use gdal::vector::{FieldValue, Geometry, LayerAccess, OGRwkbGeometryType};

use crate::error::ScenegenError;
use crate::raster::WorkingFrame;

/// One feature: its id, its polygons in the working CRS, the requested attributes' values
/// (`None` = null).
pub struct VectorFeature {
    /// The layer's feature id (FID), else the feature's position in the layer.
    pub id: u64,
    /// OpenStreetMap layers: "way N" or "relation N" (GDAL's OSM driver gives no stable FIDs).
    pub osm: Option<String>,
    pub geometry: Geometry,
    pub values: Vec<Option<FieldValue>>,
}

/// A layer's features, with what identifies them in messages.
pub struct VectorLayer {
    /// "`file` layer `name`".
    pub label: String,
    pub features: Vec<VectorFeature>,
    /// Features skipped because their geometry is empty.
    pub empty: usize,
    /// Ids of features whose polygon is invalid (kept).
    pub invalid: Vec<u64>,
    /// Features whose geometry is not polygonal (id, geometry type): not in `features`.
    pub not_polygons: Vec<(u64, String)>,
}

fn bad(path: &Path, message: impl Into<String>) -> ScenegenError {
    ScenegenError::Input {
        path: path.into(),
        message: message.into(),
    }
}

/// Polygonal geometry types (2D, 2.5D, measured).
fn is_polygonal(g: &Geometry) -> bool {
    let t = gdal::vector::geometry_type_flatten(g.geometry_type());
    t == OGRwkbGeometryType::wkbPolygon
        || t == OGRwkbGeometryType::wkbMultiPolygon
        || t == OGRwkbGeometryType::wkbCurvePolygon
        || t == OGRwkbGeometryType::wkbMultiSurface
}

/// Read layer `layer` (default: the first) of `path`, features reprojected to `frame`'s CRS, with
/// the values of `attributes`. `crs` declares the layer's CRS when the file has none (or
/// overrides it).
pub fn read_layer(
    path: &Path,
    layer: Option<&str>,
    crs: Option<&str>,
    filter: Option<&str>,
    attributes: &[&str],
    frame: &WorkingFrame,
) -> Result<VectorLayer, ScenegenError> {
    if !path.exists() {
        return Err(bad(path, "no such file"));
    }
    let ds = gdal::Dataset::open_ex(
        path,
        gdal::DatasetOptions {
            open_flags: gdal::GdalOpenFlags::GDAL_OF_VECTOR | gdal::GdalOpenFlags::GDAL_OF_READONLY,
            ..Default::default()
        },
    )
    .map_err(|e| bad(path, format!("GDAL cannot open it as a vector file: {e}")))?;
    let names: Vec<String> = (0..ds.layer_count())
        .filter_map(|i| ds.layer(i).ok().map(|l| l.name()))
        .collect();
    let mut lyr = match layer {
        Some(n) => ds.layer_by_name(n).map_err(|_| {
            bad(
                path,
                format!("no layer `{n}` (layers: {})", names.join(", ")),
            )
        })?,
        None => ds
            .layer(0)
            .map_err(|_| bad(path, "the file holds no vector layer"))?,
    };
    let name = lyr.name();
    let label = format!("layer `{name}`");
    let src = match crs {
        Some(def) => SpatialRef::from_definition(def)
            .map_err(|e| bad(path, format!("{label}: GDAL cannot read CRS `{def}`: {e}")))?,
        None => lyr.spatial_ref().ok_or_else(|| {
            bad(
                path,
                format!("{label} has no CRS: declare it with `crs` (e.g. \"EPSG:28992\")"),
            )
        })?,
    };
    let mut src = src;
    src.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
    let mut dst = frame.srs.clone();
    dst.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
    let to_work = CoordTransform::new(&src, &dst).map_err(|e| {
        bad(
            path,
            format!("{label}: no transformation to the working CRS: {e}"),
        )
    })?;

    if let Some(w) = filter {
        lyr.set_attribute_filter(w)
            .map_err(|e| bad(path, format!("{label}: GDAL refuses the filter `{w}`: {e}")))?;
    }
    let fields: Vec<String> = lyr.defn().fields().map(|f| f.name()).collect();
    // OpenStreetMap (GDAL's OSM driver) keeps most keys in the `other_tags` hstore text.
    let other_tags = fields.iter().position(|f| f == "other_tags");
    let mut idx = Vec::with_capacity(attributes.len());
    for a in attributes {
        let i = match (fields.iter().position(|f| f == a), other_tags) {
            (Some(i), _) => Field::Column(i),
            (None, Some(o)) => Field::Tag(o, (*a).to_string()),
            (None, None) => {
                return Err(bad(
                    path,
                    format!(
                        "{label} has no attribute `{a}` (attributes: {})",
                        fields.join(", ")
                    ),
                ))
            }
        };
        idx.push(i);
    }

    let osm_cols = (
        fields.iter().position(|f| f == "osm_way_id"),
        fields.iter().position(|f| f == "osm_id"),
    );
    let mut out = VectorLayer {
        label: format!("{} {label}", path.display()),
        features: Vec::new(),
        empty: 0,
        invalid: Vec::new(),
        not_polygons: Vec::new(),
    };
    for (k, f) in lyr.features().enumerate() {
        let id = f.fid().unwrap_or(k as u64);
        let Some(g) = f.geometry() else {
            out.empty += 1;
            tracing::warn!("{}: feature {id} has no geometry: skipped", out.label);
            continue;
        };
        if g.is_empty() {
            out.empty += 1;
            tracing::warn!("{}: feature {id} has an empty geometry: skipped", out.label);
            continue;
        }
        if !is_polygonal(g) {
            out.not_polygons.push((id, g.geometry_name()));
            continue;
        }
        if !g.is_valid() {
            tracing::warn!(
                "{}: feature {id} is not a valid polygon (self-intersection or bad ring): kept, rasterised by scanline parity",
                out.label
            );
            out.invalid.push(id);
        }
        let mut geometry = linear(g).and_then(|l| l.transform(&to_work)).map_err(|e| {
            bad(
                path,
                format!("{label}, feature {id}: cannot transform it to the working CRS: {e}"),
            )
        })?;
        geometry.flatten_to_2d();
        let mut values = Vec::with_capacity(idx.len());
        for field in &idx {
            let (i, tag) = match field {
                Field::Column(i) => (*i, None),
                Field::Tag(o, key) => (*o, Some(key)),
            };
            let v = f.field(i).map_err(|e| {
                bad(
                    path,
                    format!(
                        "{label}, feature {id}: unreadable attribute `{}`: {e}",
                        fields[i]
                    ),
                )
            })?;
            values.push(match (tag, v) {
                (None, v) => v,
                (Some(key), Some(FieldValue::StringValue(h))) => {
                    hstore_get(&h, key).map(FieldValue::StringValue)
                }
                (Some(_), _) => None,
            });
        }
        let text = |i: Option<usize>| {
            i.and_then(|i| f.field_as_string(i).ok().flatten())
                .filter(|t| !t.is_empty())
        };
        let osm = match (text(osm_cols.0), text(osm_cols.1)) {
            (Some(w), _) => Some(format!("way {w}")),
            (None, Some(r)) if osm_cols.0.is_some() => Some(format!("relation {r}")),
            (None, Some(n)) => Some(format!("osm {n}")),
            _ => None,
        };
        out.features.push(VectorFeature {
            id,
            osm,
            geometry,
            values,
        });
    }
    for (k, field) in idx.iter().enumerate() {
        if let Field::Tag(_, key) = field {
            if !out.features.is_empty() && out.features.iter().all(|f| f.values[k].is_none()) {
                return Err(bad(
                    path,
                    format!(
                        "{label}: no feature carries the key `{key}` (neither a column, {} nor in `other_tags`)",
                        fields.join(", ")
                    ),
                ));
            }
        }
    }
    Ok(out)
}

/// `g` with its curves replaced by line segments (a copy of `g` when it has none).
fn linear(g: &Geometry) -> gdal::errors::Result<Geometry> {
    let t = gdal::vector::geometry_type_flatten(g.geometry_type());
    if t == OGRwkbGeometryType::wkbPolygon || t == OGRwkbGeometryType::wkbMultiPolygon {
        return Ok(g.clone());
    }
    // SAFETY: `g` is a valid geometry; the linear copy is owned here, exported to WKB and
    // destroyed before returning.
    unsafe {
        let h = gdal_sys::OGR_G_GetLinearGeometry(g.c_geometry(), 0.0, std::ptr::null_mut());
        if h.is_null() {
            return Err(gdal::errors::GdalError::BadArgument(
                "GDAL cannot approximate its curves".into(),
            ));
        }
        let n = gdal_sys::OGR_G_WkbSize(h).max(0) as usize;
        let mut buf = vec![0u8; n];
        gdal_sys::OGR_G_ExportToWkb(h, gdal_sys::OGRwkbByteOrder::wkbNDR, buf.as_mut_ptr());
        gdal_sys::OGR_G_DestroyGeometry(h);
        Geometry::from_wkb(&buf)
    }
}

/// Where an attribute is read: a column, or a key of the `other_tags` hstore column.
enum Field {
    Column(usize),
    Tag(usize, String),
}

/// The value of `key` in an hstore text (`"k"=>"v","k2"=>"v2"`, as GDAL's OSM driver writes
/// `other_tags`).
pub fn hstore_get(h: &str, key: &str) -> Option<String> {
    let mut rest = h;
    while let Some(start) = rest.find('"') {
        let (k, after) = quoted(&rest[start..])?;
        let after = after.trim_start().strip_prefix("=>")?.trim_start();
        let (v, tail) = quoted(after)?;
        if k == key {
            return Some(v);
        }
        rest = tail.trim_start().strip_prefix(',').unwrap_or(tail);
    }
    None
}

/// A leading `"…"` string (backslash escapes) and what follows it.
fn quoted(s: &str) -> Option<(String, &str)> {
    let s = s.strip_prefix('"')?;
    let mut out = String::new();
    let mut chars = s.char_indices();
    while let Some((i, c)) = chars.next() {
        match c {
            '\\' => out.push(chars.next()?.1),
            '"' => return Some((out, &s[i + 1..])),
            c => out.push(c),
        }
    }
    None
}

/// A field value as an integer class code, if it is one (integers, integral reals, or text
/// holding an integer).
pub fn as_code(v: &FieldValue) -> Option<i64> {
    match v {
        FieldValue::IntegerValue(i) => Some(*i as i64),
        FieldValue::Integer64Value(i) => Some(*i),
        FieldValue::RealValue(x) if x.fract() == 0.0 && x.abs() < 2f64.powi(53) => Some(*x as i64),
        FieldValue::StringValue(s) => s.trim().parse().ok(),
        _ => None,
    }
}

/// A field value as a number (integers, reals, text holding a number).
pub fn as_f64(v: &FieldValue) -> Option<f64> {
    match v {
        FieldValue::IntegerValue(i) => Some(*i as f64),
        FieldValue::Integer64Value(i) => Some(*i as f64),
        FieldValue::RealValue(x) => Some(*x),
        FieldValue::StringValue(s) => s.trim().parse().ok(),
        _ => None,
    }
    .filter(|x: &f64| x.is_finite())
}

/// A field value as text, as a user would write it in a TOML table.
pub fn as_text(v: &FieldValue) -> String {
    match v {
        FieldValue::StringValue(s) => s.clone(),
        FieldValue::IntegerValue(i) => i.to_string(),
        FieldValue::Integer64Value(i) => i.to_string(),
        FieldValue::RealValue(x) => x.to_string(),
        other => format!("{other:?}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn osm_other_tags_are_read() {
        let h = r#""building:levels"=>"6","height"=>"17.5","name"=>"Caf\"e, \\ bar""#;
        assert_eq!(hstore_get(h, "building:levels").as_deref(), Some("6"));
        assert_eq!(hstore_get(h, "height").as_deref(), Some("17.5"));
        assert_eq!(hstore_get(h, "name").as_deref(), Some("Caf\"e, \\ bar"));
        assert_eq!(hstore_get(h, "roof:shape"), None);
        assert_eq!(hstore_get("", "x"), None);
    }
}
