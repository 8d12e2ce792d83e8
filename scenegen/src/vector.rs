//! Vector inputs: one layer of any file OGR opens (GeoPackage, SpatiaLite/SQLite, GeoJSON,
//! shapefile, FlatGeobuf …), its features' polygons reprojected to the working CRS and the
//! attributes a caller asks for. Used by vector land cover (`landcover_vector.rs`).
//!
//! Every feature is accounted for: a missing file, layer or attribute, a layer without a CRS
//! (unless the region names one), a non-polygonal or unprojectable geometry is an error naming
//! the file, the layer and the feature id; an empty geometry is skipped with a warning that names
//! it; an invalid polygon (self-intersection, GEOS's `IsValid`) is kept with a warning naming it
//! (GDAL's rasteriser burns it by its rings' scanline parity, so its pixels are still decided).

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

    let fields: Vec<String> = lyr.defn().fields().map(|f| f.name()).collect();
    let mut idx = Vec::with_capacity(attributes.len());
    for a in attributes {
        let i = fields.iter().position(|f| f == a).ok_or_else(|| {
            bad(
                path,
                format!(
                    "{label} has no attribute `{a}` (attributes: {})",
                    fields.join(", ")
                ),
            )
        })?;
        idx.push(i);
    }

    let mut out = VectorLayer {
        label: format!("{} {label}", path.display()),
        features: Vec::new(),
        empty: 0,
        invalid: Vec::new(),
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
            return Err(bad(
                path,
                format!(
                    "{label}, feature {id}: a {} where polygons are expected",
                    g.geometry_name()
                ),
            ));
        }
        if !g.is_valid() {
            tracing::warn!(
                "{}: feature {id} is not a valid polygon (self-intersection or bad ring): kept, rasterised by scanline parity",
                out.label
            );
            out.invalid.push(id);
        }
        let geometry = g.transform(&to_work).map_err(|e| {
            bad(
                path,
                format!("{label}, feature {id}: cannot transform it to the working CRS: {e}"),
            )
        })?;
        let mut values = Vec::with_capacity(idx.len());
        for &i in &idx {
            values.push(f.field(i).map_err(|e| {
                bad(
                    path,
                    format!(
                        "{label}, feature {id}: unreadable attribute `{}`: {e}",
                        fields[i]
                    ),
                )
            })?);
        }
        out.features.push(VectorFeature {
            id,
            geometry,
            values,
        });
    }
    Ok(out)
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
