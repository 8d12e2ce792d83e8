//! Spatially varying reflectance textures on the terrain.
//!
//! A texture is a georeferenced raster (any GDAL format, e.g. GeoTIFF) in the bundle's CRS whose
//! pixels are the Lambertian reflectance of one material: band k holds the reflectance at
//! `wavelengths_nm[k]` (linear interpolation between bands, constant beyond the ends; a single
//! band applies at every wavelength). A terrain hit whose material (from the material raster) is
//! textured takes its reflectance from the texture's pixel under the hit (nearest); outside the
//! texture, or on a nodata pixel, the material's own reflectance applies (the number of such
//! pixels is logged at load). Only Lambertian materials can be textured.
//!
//! Errors name the file and, for bad values, the pixel (row, column, band). The georeferenced
//! reading is [`GeoRaster`], shared with land-surface-temperature maps ([`TemperatureMap`]: one
//! band of kinetic temperatures, read by `emission.rs`).

use std::path::Path;

use gdal::Dataset;

use super::error::SceneError;

/// A north-up georeferenced raster in the bundle's CRS, moved into the scene's local frame:
/// what reflectance textures and land-surface-temperature maps (`emission.rs`) share.
#[derive(Clone, Debug)]
pub struct GeoRaster {
    pub width: usize,
    pub height: usize,
    /// GDAL geotransform in the local frame (north-up only).
    pub geotransform: [f64; 6],
    /// `[band][row * width + col]`, NaN where nodata.
    pub bands: Vec<Vec<f32>>,
}

impl GeoRaster {
    /// Read every band of `path` (`what` names it in errors); `wkt` is the bundle's CRS,
    /// `origin` its local-frame origin (working-CRS coordinates). Nodata pixels become NaN
    /// (their count is logged).
    pub fn read(
        path: &Path,
        what: &'static str,
        wkt: &str,
        origin: [f64; 2],
    ) -> Result<GeoRaster, SceneError> {
        let name = path.display();
        let p = || path.to_path_buf();
        if !path.is_file() {
            return Err(SceneError::RasterNotFound { what, path: p() });
        }
        let ds = Dataset::open(path).map_err(|source| SceneError::RasterOpen {
            what,
            path: p(),
            source,
        })?;
        let (width, height) = ds.raster_size();
        let nb = ds.raster_count();
        if nb == 0 || width == 0 || height == 0 {
            return Err(SceneError::RasterEmpty { what, path: p() });
        }
        let gt = ds
            .geo_transform()
            .map_err(|source| SceneError::RasterGeotransform {
                what,
                path: p(),
                source,
            })?;
        if gt[2] != 0.0 || gt[4] != 0.0 || gt[1] <= 0.0 || gt[5] >= 0.0 {
            return Err(SceneError::RasterRotated {
                what,
                path: p(),
                geotransform: gt,
            });
        }
        let srs = ds.spatial_ref().map_err(|source| SceneError::RasterNoCrs {
            what,
            path: p(),
            source,
        })?;
        if !wkt.is_empty() {
            let bundle = gdal::spatial_ref::SpatialRef::from_wkt(wkt)
                .map_err(|source| SceneError::BundleCrs { source })?;
            if srs != bundle {
                return Err(SceneError::RasterCrs {
                    what,
                    path: p(),
                    target: bundle
                        .to_proj4()
                        .unwrap_or_else(|_| "the bundle's WKT".into()),
                });
            }
        }
        let mut bands = Vec::with_capacity(nb);
        let mut nodata_count = 0usize;
        for b in 1..=nb {
            let band = ds.rasterband(b).map_err(|source| SceneError::RasterBand {
                what,
                path: p(),
                band: b,
                source,
            })?;
            let nodata = band.no_data_value();
            let buf = band
                .read_band_as::<f64>()
                .map_err(|source| SceneError::RasterRead {
                    what,
                    path: p(),
                    band: b,
                    source,
                })?;
            let mut v = Vec::with_capacity(width * height);
            for &x in buf.data() {
                if nodata.is_some_and(|nd| x == nd || (nd.is_nan() && x.is_nan())) || x.is_nan() {
                    nodata_count += 1;
                    v.push(f32::NAN);
                } else {
                    v.push(x as f32);
                }
            }
            bands.push(v);
        }
        if nodata_count > 0 {
            tracing::warn!(
                "{what} {name}: {nodata_count} nodata pixel-band(s) use the material's own value"
            );
        }
        Ok(GeoRaster {
            width,
            height,
            geotransform: [gt[0] - origin[0], gt[1], 0.0, gt[3] - origin[1], 0.0, gt[5]],
            bands,
        })
    }

    /// The pixel index (row · width + column) under local (x, y); `None` outside.
    #[inline]
    pub fn pixel(&self, x: f64, y: f64) -> Option<usize> {
        let g = &self.geotransform;
        let col = ((x - g[0]) / g[1]).floor();
        let row = ((y - g[3]) / g[5]).floor();
        if col < 0.0 || row < 0.0 || col >= self.width as f64 || row >= self.height as f64 {
            return None;
        }
        Some(row as usize * self.width + col as usize)
    }
}

/// One material's reflectance texture, georeferenced in the scene's local frame.
#[derive(Clone, Debug)]
pub struct Texture {
    pub material: u16,
    pub raster: GeoRaster,
    /// nm, one per band (ascending).
    pub wavelengths: Vec<f64>,
}

impl Texture {
    /// Read `path` for `material`; `wkt` is the bundle's CRS, `origin` its local-frame origin
    /// (working-CRS coordinates).
    pub fn read(
        path: &Path,
        material: u16,
        wavelengths: &[f64],
        wkt: &str,
        origin: [f64; 2],
    ) -> Result<Texture, SceneError> {
        let raster = GeoRaster::read(path, "texture", wkt, origin)?;
        let nb = raster.bands.len();
        if wavelengths.len() != nb {
            return Err(SceneError::TextureBands {
                path: path.to_path_buf(),
                bands: nb,
                wavelengths: wavelengths.len(),
            });
        }
        if wavelengths.windows(2).any(|w| w[1] <= w[0]) {
            return Err(SceneError::TextureWavelengths {
                path: path.to_path_buf(),
            });
        }
        for (b, band) in raster.bands.iter().enumerate() {
            for (k, &x) in band.iter().enumerate() {
                if !x.is_nan() && !(0.0..=1.0).contains(&x) {
                    return Err(SceneError::TexturePixel {
                        path: path.to_path_buf(),
                        row: k / raster.width,
                        column: k % raster.width,
                        band: b + 1,
                        value: x,
                    });
                }
            }
        }
        Ok(Texture {
            material,
            raster,
            wavelengths: wavelengths.to_vec(),
        })
    }

    /// Memory of the texture, bytes.
    pub fn memory_bytes(&self) -> usize {
        self.raster.bands.len() * self.raster.width * self.raster.height * 4
    }

    /// Reflectance at local (x, y) and `wavelength_nm`; `None` outside the texture or on nodata.
    #[inline]
    pub fn reflectance(&self, x: f64, y: f64, wavelength_nm: f64) -> Option<f64> {
        let k = self.raster.pixel(x, y)?;
        let bands = &self.raster.bands;
        let w = &self.wavelengths;
        let v = if w.len() == 1 || wavelength_nm <= w[0] {
            bands[0][k]
        } else if wavelength_nm >= w[w.len() - 1] {
            bands[w.len() - 1][k]
        } else {
            let i = w.partition_point(|&x| x <= wavelength_nm) - 1;
            let t = ((wavelength_nm - w[i]) / (w[i + 1] - w[i])) as f32;
            bands[i][k] + t * (bands[i + 1][k] - bands[i][k])
        };
        (!v.is_nan()).then_some(v as f64)
    }
}

/// A land-surface-temperature raster: one band of kinetic temperatures (K) in the bundle's CRS,
/// applied to terrain hits (nearest pixel); outside it or on nodata the material's temperature
/// applies.
#[derive(Clone, Debug)]
pub struct TemperatureMap {
    raster: GeoRaster,
}

impl TemperatureMap {
    /// Read `path` (`wkt`: the bundle's CRS, `origin`: its local-frame origin); errors name the
    /// file and, for a bad value, the pixel.
    pub fn read(path: &Path, wkt: &str, origin: [f64; 2]) -> Result<Self, SceneError> {
        let raster = GeoRaster::read(path, "land-surface temperature", wkt, origin)?;
        if raster.bands.len() != 1 {
            return Err(SceneError::TemperatureBands {
                path: path.to_path_buf(),
                bands: raster.bands.len(),
            });
        }
        for (k, &v) in raster.bands[0].iter().enumerate() {
            if !(v.is_nan() || (v > 0.0 && v <= 10_000.0)) {
                return Err(SceneError::TemperaturePixel {
                    path: path.to_path_buf(),
                    row: k / raster.width,
                    column: k % raster.width,
                    value: v,
                });
            }
        }
        Ok(TemperatureMap { raster })
    }

    /// Temperature (K) at local (x, y); `None` outside or on nodata.
    pub fn at(&self, x: f64, y: f64) -> Option<f64> {
        let k = self.raster.pixel(x, y)?;
        let v = self.raster.bands[0][k];
        (!v.is_nan()).then_some(v as f64)
    }

    /// Memory of the raster, bytes.
    pub fn memory_bytes(&self) -> usize {
        self.raster.bands.iter().map(|b| b.len() * 4).sum()
    }

    /// The coldest pixel (K) and its (row, column), nodata skipped.
    pub fn coldest(&self) -> Option<(f64, usize, usize)> {
        let w = self.raster.width;
        self.raster.bands[0]
            .iter()
            .enumerate()
            .filter(|(_, v)| !v.is_nan())
            .min_by(|a, b| a.1.total_cmp(b.1))
            .map(|(k, v)| (f64::from(*v), k / w, k % w))
    }
}
