//! Plausibility of DEM heights, checked on the source pixels that cover the area before they are
//! warped (bilinear resampling would smear a bad pixel over its neighbours and hide its origin).
//!
//! Refused, with the file, the source pixel (column, row) and the value:
//! * non-finite heights (`inf`, or NaN when NaN is not the band's no-data value);
//! * heights outside [`MIN_HEIGHT_M`, `MAX_HEIGHT_M`] after the band's scale, offset and unit
//!   (a 1e30 spike; the deepest ocean trench is −10 935 m, Everest 8 849 m);
//! * void sentinels (−32768, −32767, −9999) in a band with no no-data tag: the file almost
//!   surely marks voids with them, and reading them as heights would dig pits. The message says
//!   how to tag them (`gdal_edit.py -a_nodata`).
//!
//! Pixels equal to the band's no-data value are skipped (holes are handled by the hole filler).
//! The window is read in strips of rows, so memory stays bounded for any DEM size.

use std::path::Path;

use gdal::Dataset;

use crate::error::{input, ScenegenError};

/// Lowest accepted height, metres (below the deepest ocean trench).
pub const MIN_HEIGHT_M: f64 = -12_000.0;
/// Highest accepted height, metres (above the highest summit).
pub const MAX_HEIGHT_M: f64 = 9_000.0;
/// Values that mark voids in common DEM products (SRTM, ASTER, many national DEMs).
const VOID_SENTINELS: [f64; 3] = [-32768.0, -32767.0, -9999.0];
/// Rows per strip read.
const STRIP_ROWS: usize = 256;

/// Check band 1 of `ds` over the source-CRS bounds `window` (xmin, ymin, xmax, ymax); `to_m`
/// converts a raw value to metres.
pub fn check(
    ds: &Dataset,
    path: &Path,
    window: [f64; 4],
    to_m: impl Fn(f64) -> f64,
) -> Result<(), ScenegenError> {
    let gt = ds.geo_transform().map_err(|e| input(path, e.to_string()))?;
    let (w, h) = ds.raster_size();
    let (c0, c1, r0, r1) = if gt[2] == 0.0 && gt[4] == 0.0 && gt[1] != 0.0 && gt[5] != 0.0 {
        let col = |x: f64| (x - gt[0]) / gt[1];
        let row = |y: f64| (y - gt[3]) / gt[5];
        let (ca, cb) = (col(window[0]), col(window[2]));
        let (ra, rb) = (row(window[1]), row(window[3]));
        let clamp = |v: f64, n: usize| v.clamp(0.0, n as f64) as usize;
        (
            clamp(ca.min(cb).floor() - 1.0, w),
            clamp(ca.max(cb).ceil() + 1.0, w),
            clamp(ra.min(rb).floor() - 1.0, h),
            clamp(ra.max(rb).ceil() + 1.0, h),
        )
    } else {
        (0, w, 0, h)
    };
    if c1 <= c0 || r1 <= r0 {
        return Ok(());
    }
    let band = ds.rasterband(1).map_err(|e| input(path, e.to_string()))?;
    let nodata = band.no_data_value();
    let is_nodata = |v: f64| match nodata {
        Some(n) if n.is_nan() => v.is_nan(),
        Some(n) => v == n,
        None => false,
    };
    let mut r = r0;
    while r < r1 {
        let rows = STRIP_ROWS.min(r1 - r);
        let buf = band
            .read_as::<f64>(
                (c0 as isize, r as isize),
                (c1 - c0, rows),
                (c1 - c0, rows),
                None,
            )
            .map_err(|e| input(path, format!("cannot read DEM rows {r}..{}: {e}", r + rows)))?;
        for (k, &v) in buf.data().iter().enumerate() {
            if is_nodata(v) {
                continue;
            }
            let (col, row) = (c0 + k % (c1 - c0), r + k / (c1 - c0));
            if nodata.is_none() && VOID_SENTINELS.contains(&v) {
                return Err(input(
                    path,
                    format!(
                        "pixel (column {col}, row {row}) holds {}, a void marker, but the band has no no-data value; tag it (`gdal_edit.py -a_nodata {} FILE`) so voids are filled instead of read as heights",
                        num(v),
                        num(v)
                    ),
                ));
            }
            let m = to_m(v);
            if !m.is_finite() || !(MIN_HEIGHT_M..=MAX_HEIGHT_M).contains(&m) {
                return Err(input(
                    path,
                    format!(
                        "pixel (column {col}, row {row}) has height {} m (raw value {}); heights must be finite and within [{MIN_HEIGHT_M}, {MAX_HEIGHT_M}] m (a damaged or mis-scaled DEM, or voids without a no-data tag)",
                        num(m),
                        num(v)
                    ),
                ));
            }
        }
        r += rows;
    }
    Ok(())
}

/// A value as a person reads it: plain below a million, else in scientific notation.
fn num(v: f64) -> String {
    if v.is_finite() && v.abs() >= 1e6 {
        format!("{v:.3e}")
    } else {
        format!("{v}")
    }
}
