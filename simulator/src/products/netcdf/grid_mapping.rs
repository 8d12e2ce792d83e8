//! The CF grid-mapping variable of an ortho image in `results.nc` (CF-1.10 §5.6), written so that
//! GDAL's netCDF driver and rioxarray find the image's CRS and geotransform.
//!
//! For an ortho measure `ID` in a scene with a CRS, the scalar variable `ID_spatial_ref` carries:
//! * `crs_wkt` (CF) and `spatial_ref` (the name GDAL and rioxarray also read): the CRS's WKT;
//! * `GeoTransform`: the pixel-corner geotransform as GDAL writes it, six numbers separated by
//!   spaces in GDAL order `x0 dx rx y0 ry dy`;
//! * `grid_mapping_name` and the CF parameters when the projection is known here:
//!   `transverse_mercator` (UTM included) and `latitude_longitude`; other projections carry the
//!   WKT only, which GDAL and rioxarray read first anyway;
//! * `semi_major_axis` and `inverse_flattening` (m, —) of the ellipsoid.
//!
//! The image variables name it in their `grid_mapping` attribute. One variable per measure (and
//! not one `spatial_ref` for the file) because each ortho window has its own geotransform.

use std::ffi::CString;

use gdal::spatial_ref::SpatialRef;

/// The CF `grid_mapping_name` and its numeric parameters, when known.
fn cf_projection(srs: &SpatialRef) -> Option<(&'static str, Vec<(&'static str, f64)>)> {
    if srs.is_geographic() {
        return Some(("latitude_longitude", Vec::new()));
    }
    if !srs.is_projected() {
        return None;
    }
    let proj = srs.get_attr_value("PROJECTION", 0).ok().flatten()?;
    if !proj.eq_ignore_ascii_case("Transverse_Mercator") {
        return None;
    }
    let parm = |name: &str, default: f64| -> f64 {
        let Ok(c) = CString::new(name) else {
            return default;
        };
        let mut err = 0;
        // SAFETY: a valid spatial reference handle owned by `srs`, a NUL-terminated name and a
        // writable error slot; OSRGetProjParm only reads the handle.
        let v = unsafe { gdal_sys::OSRGetProjParm(srs.to_c_hsrs(), c.as_ptr(), default, &mut err) };
        if err == 0 {
            v
        } else {
            default
        }
    };
    Some((
        "transverse_mercator",
        vec![
            (
                "scale_factor_at_central_meridian",
                parm("scale_factor", 1.0),
            ),
            (
                "longitude_of_central_meridian",
                parm("central_meridian", 0.0),
            ),
            (
                "latitude_of_projection_origin",
                parm("latitude_of_origin", 0.0),
            ),
            ("false_easting", parm("false_easting", 0.0)),
            ("false_northing", parm("false_northing", 0.0)),
        ],
    ))
}

/// `gt` as GDAL writes the `GeoTransform` attribute: six numbers separated by spaces.
pub(super) fn geotransform_attribute(gt: &[f64; 6]) -> String {
    gt.iter()
        .map(|v| format!("{v}"))
        .collect::<Vec<_>>()
        .join(" ")
}

/// Write the scalar grid-mapping variable `name` for the CRS `wkt` and the geotransform `gt`.
pub(super) fn write(
    f: &mut netcdf::FileMut,
    name: &str,
    wkt: &str,
    gt: &[f64; 6],
) -> Result<(), netcdf::Error> {
    let mut v = f.add_variable::<i32>(name, &[])?;
    v.put_attribute("long_name", "coordinate reference system of the image")?;
    v.put_attribute("crs_wkt", wkt)?;
    v.put_attribute("spatial_ref", wkt)?;
    v.put_attribute("GeoTransform", geotransform_attribute(gt).as_str())?;
    if let Ok(srs) = SpatialRef::from_wkt(wkt) {
        if let Some((mapping, params)) = cf_projection(&srs) {
            v.put_attribute("grid_mapping_name", mapping)?;
            for (k, x) in params {
                v.put_attribute(k, x)?;
            }
        }
        if let (Ok(a), Ok(b)) = (srs.semi_major(), srs.semi_minor()) {
            v.put_attribute("semi_major_axis", a)?;
            if a > b {
                v.put_attribute("inverse_flattening", a / (a - b))?;
            }
        }
    }
    v.put_value(0i32, ..)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn utm_is_transverse_mercator() {
        let srs = SpatialRef::from_epsg(32631).unwrap();
        let (name, p) = cf_projection(&srs).unwrap();
        assert_eq!(name, "transverse_mercator");
        let get = |k: &str| p.iter().find(|(n, _)| *n == k).unwrap().1;
        assert_eq!(get("longitude_of_central_meridian"), 3.0);
        assert_eq!(get("scale_factor_at_central_meridian"), 0.9996);
        assert_eq!(get("false_easting"), 500_000.0);
        assert_eq!(
            cf_projection(&SpatialRef::from_epsg(4326).unwrap())
                .unwrap()
                .0,
            "latitude_longitude"
        );
        assert_eq!(
            geotransform_attribute(&[499_700.0, 150.0, 0.0, 4_000_300.5, 0.0, -150.0]),
            "499700 150 0 4000300.5 0 -150"
        );
    }
}
