//! A region's area of interest as a polygon (`[area] polygon = "FILE"`): reading, checking and
//! reprojecting it, and the geometry the build asks of it (containment, area), with `geo`.
//!
//! Input: a WKT file (extension `.wkt`, or text starting with `POLYGON`/`MULTIPOLYGON`), or any
//! vector file GDAL/OGR opens (GeoJSON, GeoPackage, shapefile…: the polygons of every feature
//! of its first layer). Its CRS: `area.polygon_crs` when given, else the layer's own (GeoJSON:
//! WGS 84 unless declared), else WGS 84 longitude/latitude (degrees, traditional GIS axis
//! order). The polygon is reprojected vertex by vertex (edges stay straight segments in the
//! target CRS; keep edges short against the projection's curvature over large areas) first to
//! WGS 84 (to centre the default local frame on it), then to the working CRS, where areas are
//! planar (m²) and containment is tested. The file must hold a valid polygon or multipolygon
//! (closed rings, no self-intersection, holes inside: `geo`'s validation); anything else is an
//! error naming the file.

use std::path::Path;

use gdal::spatial_ref::{CoordTransform, SpatialRef};
use gdal::vector::{Geometry, LayerAccess};
use geo::{Area, BoundingRect, Contains, Coord, LineString, MultiPolygon, Point, Polygon};

use crate::error::ScenegenError;

fn bad(path: &Path, message: impl Into<String>) -> ScenegenError {
    ScenegenError::Input {
        path: path.into(),
        message: message.into(),
    }
}

/// Read the polygon file and return it in WGS 84 longitude/latitude (degrees).
pub fn read_lon_lat(path: &Path, crs: Option<&str>) -> Result<MultiPolygon<f64>, ScenegenError> {
    if !path.is_file() {
        return Err(bad(path, "polygon file not found (area.polygon)"));
    }
    let wkt_text = match std::fs::read(path) {
        Ok(bytes) => {
            let t = String::from_utf8_lossy(&bytes)
                .trim_start()
                .to_ascii_uppercase();
            let is_wkt = path
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("wkt"))
                || t.starts_with("POLYGON")
                || t.starts_with("MULTIPOLYGON");
            is_wkt.then(|| String::from_utf8_lossy(&bytes).into_owned())
        }
        Err(e) => return Err(bad(path, format!("cannot read: {e}"))),
    };
    let (geoms, layer_srs) = match wkt_text {
        Some(t) => {
            let g = Geometry::from_wkt(t.trim())
                .map_err(|e| bad(path, format!("not readable as WKT: {e}")))?;
            (vec![to_geo(path, &g)?], None)
        }
        None => {
            let ds = gdal::Dataset::open(path)
                .map_err(|e| bad(path, format!("not a vector file GDAL can open: {e}")))?;
            let mut layer = ds
                .layer(0)
                .map_err(|e| bad(path, format!("no layer: {e}")))?;
            let srs = layer.spatial_ref();
            let mut out = Vec::new();
            for f in layer.features() {
                if let Some(g) = f.geometry() {
                    out.push(to_geo(path, g)?);
                }
            }
            (out, srs)
        }
    };
    let mut polys: Vec<Polygon<f64>> = Vec::new();
    for g in geoms {
        match g {
            geo::Geometry::Polygon(p) => polys.push(p),
            geo::Geometry::MultiPolygon(m) => polys.extend(m.0),
            other => {
                return Err(bad(
                    path,
                    format!(
                        "holds a {}, not a polygon or multipolygon (area.polygon)",
                        type_name(&other)
                    ),
                ))
            }
        }
    }
    if polys.is_empty() {
        return Err(bad(path, "holds no polygon (area.polygon)"));
    }
    let mp = MultiPolygon(polys);
    if let Err(e) = geo::Validation::check_validation(&mp) {
        return Err(bad(path, format!("invalid polygon (area.polygon): {e}")));
    }
    let src = match crs {
        Some(c) => SpatialRef::from_definition(c).map_err(|e| {
            bad(
                path,
                format!("area.polygon_crs `{c}` is not a CRS GDAL reads: {e}"),
            )
        })?,
        None => match layer_srs {
            Some(s) => s,
            None => wgs84()?,
        },
    };
    reproject(path, &mp, &src, &wgs84()?)
}

fn to_geo(path: &Path, g: &Geometry) -> Result<geo::Geometry<f64>, ScenegenError> {
    geo::Geometry::try_from(g).map_err(|e| bad(path, format!("unsupported geometry: {e}")))
}

fn type_name(g: &geo::Geometry<f64>) -> &'static str {
    match g {
        geo::Geometry::Point(_) => "Point",
        geo::Geometry::Line(_) => "Line",
        geo::Geometry::LineString(_) => "LineString",
        geo::Geometry::MultiPoint(_) => "MultiPoint",
        geo::Geometry::MultiLineString(_) => "MultiLineString",
        geo::Geometry::GeometryCollection(_) => "GeometryCollection",
        geo::Geometry::Rect(_) => "Rect",
        geo::Geometry::Triangle(_) => "Triangle",
        geo::Geometry::Polygon(_) | geo::Geometry::MultiPolygon(_) => "polygon",
    }
}

/// WGS 84 with longitude first.
pub fn wgs84() -> Result<SpatialRef, ScenegenError> {
    let mut s = SpatialRef::from_epsg(4326).map_err(crate::error::gdal_err("EPSG:4326"))?;
    s.set_axis_mapping_strategy(gdal::spatial_ref::AxisMappingStrategy::TraditionalGisOrder);
    Ok(s)
}

/// The polygon's vertices from `src` to `dst` (both in traditional GIS axis order).
pub fn reproject(
    path: &Path,
    mp: &MultiPolygon<f64>,
    src: &SpatialRef,
    dst: &SpatialRef,
) -> Result<MultiPolygon<f64>, ScenegenError> {
    let mut src = src.clone();
    src.set_axis_mapping_strategy(gdal::spatial_ref::AxisMappingStrategy::TraditionalGisOrder);
    let t = CoordTransform::new(&src, dst)
        .map_err(|e| bad(path, format!("cannot reproject the polygon: {e}")))?;
    let ring = |l: &LineString<f64>| -> Result<LineString<f64>, ScenegenError> {
        let (mut xs, mut ys): (Vec<f64>, Vec<f64>) = l.0.iter().map(|c| (c.x, c.y)).unzip();
        t.transform_coords(&mut xs, &mut ys, &mut [])
            .map_err(|e| bad(path, format!("cannot reproject the polygon: {e}")))?;
        Ok(LineString(
            xs.into_iter()
                .zip(ys)
                .map(|(x, y)| Coord { x, y })
                .collect(),
        ))
    };
    let mut out = Vec::with_capacity(mp.0.len());
    for p in &mp.0 {
        let inner: Result<Vec<_>, _> = p.interiors().iter().map(ring).collect();
        out.push(Polygon::new(ring(p.exterior())?, inner?));
    }
    Ok(MultiPolygon(out))
}

/// West, south, east, north of a polygon (in its own coordinates).
pub fn bbox(mp: &MultiPolygon<f64>) -> [f64; 4] {
    match mp.bounding_rect() {
        Some(r) => [r.min().x, r.min().y, r.max().x, r.max().y],
        None => [0.0; 4],
    }
}

/// Planar area of a polygon in a metric CRS, m².
pub fn area_m2(mp: &MultiPolygon<f64>) -> f64 {
    mp.unsigned_area()
}

/// A polygon in the working CRS with its bounding box, for fast containment tests.
#[derive(Clone, Debug)]
pub struct Mask {
    pub polygon: MultiPolygon<f64>,
    pub bbox: [f64; 4],
}

impl Mask {
    pub fn new(polygon: MultiPolygon<f64>) -> Mask {
        let bbox = bbox(&polygon);
        Mask { polygon, bbox }
    }

    /// Whether the working-CRS point (x, y) lies inside the polygon (boundary excluded).
    pub fn contains(&self, x: f64, y: f64) -> bool {
        let b = self.bbox;
        x >= b[0] && x <= b[2] && y >= b[1] && y <= b[3] && self.polygon.contains(&Point::new(x, y))
    }

    /// The polygon as OGC WKT (for the bundle manifest).
    pub fn wkt(&self) -> String {
        let ring = |l: &LineString<f64>| {
            let pts: Vec<String> = l.0.iter().map(|c| format!("{} {}", c.x, c.y)).collect();
            format!("({})", pts.join(", "))
        };
        let polys: Vec<String> = self
            .polygon
            .0
            .iter()
            .map(|p| {
                let rings: Vec<String> = std::iter::once(p.exterior())
                    .chain(p.interiors())
                    .map(ring)
                    .collect();
                format!("({})", rings.join(", "))
            })
            .collect();
        format!("MULTIPOLYGON ({})", polys.join(", "))
    }
}
