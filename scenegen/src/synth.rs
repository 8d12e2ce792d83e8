//! Synthetic GeoTIFFs for tests and benchmarks, written through GDAL's GTiff driver (so the
//! reading side runs the same code path as for real data).
//!
//! * [`terrain_height`]: a deterministic landscape in metres — a broad plain rising to a ridge,
//!   hills and a few octaves of valleys — with slopes up to about 40°, so that the TIN has both
//!   flat and rough areas.
//! * [`landcover_code`]: CORINE grid codes in patches (arable 12, pasture 18, broad-leaved 23,
//!   coniferous 24, urban 2, water 41, bare rock 31), from smooth noise and height.

use std::path::Path;

use gdal::raster::{Buffer, GdalType};
use gdal::spatial_ref::SpatialRef;
use gdal::DriverManager;

use crate::error::{gdal_err, ScenegenError};

/// Height in metres at (x, y) metres from the scene's south-west corner.
pub fn terrain_height(x: f64, y: f64) -> f64 {
    let k = std::f64::consts::TAU;
    let ridge = 1800.0 / (1.0 + ((x - 70_000.0) / 15_000.0).powi(2));
    let mut h = 200.0 + ridge + 0.002 * y;
    let mut amp = 120.0;
    let mut wl = 9000.0;
    for o in 0..5 {
        let phase = o as f64 * 1.7;
        h += amp * (k * x / wl + phase).sin() * (k * y / (wl * 1.3) + 0.5 * phase).cos();
        amp *= 0.45;
        wl *= 0.42;
    }
    // Flat plain in the west: the TIN should need few triangles there.
    if x < 20_000.0 {
        h = 200.0 + 0.002 * y;
    }
    h
}

/// CORINE grid code at (x, y) metres from the south-west corner, given the height there.
pub fn landcover_code(x: f64, y: f64, h: f64) -> u8 {
    let n = (x / 3700.0).sin() * (y / 2900.0).cos() + 0.5 * (x / 1300.0 + y / 1700.0).sin();
    if h > 1700.0 {
        31
    } else if n > 1.1 {
        41
    } else if n > 0.6 {
        if h > 900.0 {
            24
        } else {
            23
        }
    } else if n < -1.0 {
        2
    } else if n < -0.3 {
        18
    } else {
        12
    }
}

/// Write a one-band GeoTIFF. `gt` is GDAL's geotransform; `srs` any GDAL CRS definition
/// (`None` writes no CRS, for error tests); `nodata` optional.
pub fn write_geotiff<T: GdalType + Copy>(
    path: &Path,
    width: usize,
    height: usize,
    gt: Option<[f64; 6]>,
    srs: Option<&str>,
    nodata: Option<f64>,
    data: Vec<T>,
) -> Result<(), ScenegenError> {
    // Output parents are created (a fresh tree has no `out/…` folders).
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(|source| {
            ScenegenError::Bundle(bundle::BundleError::Write {
                path: parent.to_path_buf(),
                source,
            })
        })?;
    }
    // Written beside the destination, closed, read back whole, then renamed: GDAL does not
    // always report a full disk, and a truncated GeoTIFF must never take the file's place.
    let tmp = {
        let mut t = path.as_os_str().to_owned();
        t.push(format!(".tmp-{}", std::process::id()));
        std::path::PathBuf::from(t)
    };
    let result = write_geotiff_at(&tmp, width, height, gt, srs, nodata, data)
        .and_then(|()| read_back::<T>(&tmp, width, height))
        .and_then(|()| {
            std::fs::rename(&tmp, path).map_err(|source| {
                ScenegenError::Bundle(bundle::BundleError::Write {
                    path: path.to_path_buf(),
                    source,
                })
            })
        });
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Reads every pixel of the one-band GeoTIFF `path` (`width × height`): a file cut short by a
/// full disk fails here, naming it.
fn read_back<T: GdalType + Copy>(
    path: &Path,
    width: usize,
    height: usize,
) -> Result<(), ScenegenError> {
    let what = || format!("read back {} (a full disk?)", path.display());
    let ds = gdal::Dataset::open(path).map_err(gdal_err(what()))?;
    let band = ds.rasterband(1).map_err(gdal_err(what()))?;
    if band.size() != (width, height) {
        return Err(ScenegenError::Bundle(bundle::BundleError::Write {
            path: path.to_path_buf(),
            source: std::io::Error::other("the written GeoTIFF has the wrong size"),
        }));
    }
    band.read_as::<T>((0, 0), (width, height), (width, height), None)
        .map_err(gdal_err(what()))?;
    Ok(())
}

fn write_geotiff_at<T: GdalType + Copy>(
    path: &Path,
    width: usize,
    height: usize,
    gt: Option<[f64; 6]>,
    srs: Option<&str>,
    nodata: Option<f64>,
    data: Vec<T>,
) -> Result<(), ScenegenError> {
    let drv = DriverManager::get_driver_by_name("GTiff").map_err(gdal_err("GTiff driver"))?;
    let mut opts = gdal::raster::RasterCreationOptions::new();
    opts.add_name_value("COMPRESS", "DEFLATE")
        .map_err(gdal_err("options"))?;
    opts.add_name_value("TILED", "YES")
        .map_err(gdal_err("options"))?;
    let mut ds = drv
        .create_with_band_type_with_options::<T, _>(path, width, height, 1, &opts)
        .map_err(gdal_err(format!("create {}", path.display())))?;
    if let Some(gt) = gt {
        ds.set_geo_transform(&gt)
            .map_err(gdal_err("geotransform"))?;
    }
    if let Some(s) = srs {
        let s = SpatialRef::from_definition(s).map_err(gdal_err(format!("CRS {s}")))?;
        ds.set_spatial_ref(&s).map_err(gdal_err("set CRS"))?;
    }
    let mut band = ds.rasterband(1).map_err(gdal_err("band"))?;
    if let Some(nd) = nodata {
        band.set_no_data_value(Some(nd))
            .map_err(gdal_err("nodata"))?;
    }
    let mut buf = Buffer::new((width, height), data);
    band.write((0, 0), (width, height), &mut buf)
        .map_err(gdal_err(format!("write {}", path.display())))?;

    ds.close()
        .map_err(gdal_err(format!("close {}", path.display())))?;
    Ok(())
}
