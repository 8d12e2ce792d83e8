//! `results.nc`: the same data as `results.csv` (and the images), as labelled CF-1.10 variables
//! in a netCDF-4 file (xarray-ready).
//!
//! Layout:
//! * the coordinate `wavelength` (nm);
//! * the non-image measures (`mdistant`, `radiancemeter`, `distant_flux`) as one table on the
//!   dimensions `measure` and `direction` (one entry per measure and direction, as the rows of
//!   `results.csv`), with data variables such as `brf(wavelength, direction)` (`table.rs`). With
//!   xarray, one measure: `ds.isel(direction=(ds.direction_measure_id == "toa_pp").values)`;
//! * each `ortho` / `perspective` image measure `ID` as `ID_brf(wavelength, ID_y, ID_x)` and
//!   friends, ortho images georeferenced through a CF grid-mapping variable `ID_spatial_ref`
//!   (`image.rs`, `grid_mapping.rs`);
//! * band runs: band-weighted variables `band_brf(direction)` and friends (`table.rs`).
//!
//! Global attributes: `Conventions`, `title`, `source` (crate and version), `history`, `seed`,
//! `polarized`, `sun_zenith`, `sun_azimuth`, `experiment` (the experiment file's text) and, in band
//! runs, `srf` (the band's name).
//!
//! The file is written to a temporary name in the output folder and renamed, so a failed write
//! never leaves a partial `results.nc`.

mod grid_mapping;
mod image;
pub mod lidar;
mod table;

use std::path::Path;

use super::{tmp_path, Row};
use crate::error::OutputError;
use engine::config::resolve::Experiment;

/// Write `rows` and the band-weighted `band` rows (`products::band_rows`; empty without a band).
pub fn write(
    path: &Path,
    exp: &Experiment,
    rows: &[Row],
    band: &[super::BandRow],
    images: &[super::imagery::ImageProduct],
) -> Result<(), OutputError> {
    let tmp = tmp_path(path);
    let _ = std::fs::remove_file(&tmp);
    let nc = |source| OutputError::Netcdf {
        path: path.to_path_buf(),
        source,
    };
    {
        let _session = engine::netcdf_session();
        let mut f = netcdf::create(&tmp).map_err(nc)?;
        fill(&mut f, exp, rows, band, images).map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            nc(e)
        })?;
    }
    std::fs::rename(&tmp, path).map_err(|source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Every dimension, variable and attribute of `results.nc`, written into an open file `f` (a
/// file on disk for [`write()`], or a diskless one for the Python package, which reads it back
/// into an `xarray.Dataset` without touching the disk).
pub fn fill(
    f: &mut netcdf::FileMut,
    exp: &Experiment,
    rows: &[Row],
    band: &[super::BandRow],
    images: &[super::imagery::ImageProduct],
) -> Result<(), netcdf::Error> {
    write_globals(f, exp)?;
    table::write(f, exp, rows)?;
    images.iter().try_for_each(|p| image::write(f, p))?;
    table::write_band(f, exp, band)
}

/// Global attributes and the `wavelength` coordinate.
fn write_globals(f: &mut netcdf::FileMut, exp: &Experiment) -> Result<(), netcdf::Error> {
    f.add_attribute("Conventions", "CF-1.10")?;
    f.add_attribute("title", "Monte Carlo radiative transfer simulation")?;
    f.add_attribute("source", format!("simulator {}", crate::BUILD_ID))?;
    f.add_attribute(
        "history",
        format!("created by `simulate run {}`", exp.source_path.display()),
    )?;
    f.add_attribute("seed", exp.seed as i64)?;
    f.add_attribute("polarized", if exp.polarized { "true" } else { "false" })?;
    f.add_attribute("sun_zenith", exp.sun_zenith_deg)?;
    f.add_attribute("sun_azimuth", exp.sun_azimuth_deg)?;
    if let Some(m) = &exp.moon {
        // The Moon shines beside the Sun: radiances and fluxes are the sum, BRFs stay in the
        // Sun's units.
        f.add_attribute("moon_zenith", m.zenith_deg)?;
        f.add_attribute("moon_azimuth", m.azimuth_deg)?;
        f.add_attribute("moon_irradiance", m.irradiance.clone())?;
    }
    f.add_attribute("experiment", exp.source_text.as_str())?;
    let nw = exp.wavelengths.len();
    f.add_dimension("wavelength", nw)?;
    {
        let mut v = f.add_variable::<f64>("wavelength", &["wavelength"])?;
        v.put_attribute("units", "nm")?;
        v.put_attribute("long_name", "wavelength")?;
        v.put_attribute("standard_name", "radiation_wavelength")?;
        if let Some(b) = &exp.bands {
            // Runs with sensor bands: each "wavelength" is a band, at its effective wavelength.
            v.put_attribute(
                "comment",
                "sensor bands (spectral.bands): the effective wavelength of each band, sum(S·λ)/sum(S)",
            )?;
            v.put_attribute("band_names", b.names.join(","))?;
        }
        v.put_values(&exp.wavelengths, ..)?;
    }
    if let Some(b) = &exp.bands {
        f.add_attribute("bands", b.names.join(","))?;
    }
    Ok(())
}
