//! `pics.nc`: the PICS results as CF-1.10 netCDF, one entry per acquisition on the dimension
//! `acquisition`.
//!
//! * `acquisition(acquisition)`: the acquisition's 1-based row number (the dimension's
//!   coordinate variable; acquisitions may share a time, so time cannot be the dimension).
//! * `time(acquisition)`: double, `seconds since 1970-01-01T00:00:00Z`, calendar `standard`,
//!   `standard_name = "time"`, `axis = "T"`; every data variable names it in `coordinates`, so
//!   CF readers (xarray, Panoply) take it as the time coordinate.
//! * `time_utc` and `srf`: strings, the RFC 3339 UTC time and the band as in `pics.csv`.
//! * `vza, vaa, sza, saa` (degree), `earth_sun_distance` (au), `reflectance`, `radiance`,
//!   `band_irradiance` and the standard errors; `sun_angles_given` (byte flag: 1 where the CSV
//!   gave `sza`, `saa`, 0 where SPA computed them).
//!
//! Written to a temporary file and renamed.

use std::path::Path;

use super::PicsRow;
use crate::error::OutputError;
use engine::sources::sun_position::{parse_time, unix_seconds};
use engine::sources::EphemerisError;

/// A data column: name, units, long name, accessor.
type Column = (
    &'static str,
    &'static str,
    &'static str,
    fn(&PicsRow) -> f64,
);

const COLUMNS: [Column; 10] = [
    ("vza", "degree", "view zenith angle", |r| r.acquisition.vza),
    (
        "vaa",
        "degree",
        "view azimuth angle, clockwise from North (site to sensor)",
        |r| r.acquisition.vaa,
    ),
    (
        "sza",
        "degree",
        "solar zenith angle (NREL SPA, geometric, unless given)",
        |r| r.sza,
    ),
    (
        "saa",
        "degree",
        "solar azimuth angle, clockwise from North",
        |r| r.saa,
    ),
    ("earth_sun_distance", "au", "Earth-Sun distance", |r| {
        r.earth_sun_distance_au
    }),
    (
        "reflectance",
        "1",
        "band TOA reflectance pi L / (E0 cos SZA)",
        |r| r.reflectance.0,
    ),
    (
        "reflectance_stderr",
        "1",
        "standard error of reflectance",
        |r| r.reflectance.1,
    ),
    ("radiance", "W m-2 sr-1 nm-1", "band TOA radiance", |r| {
        r.radiance.0
    }),
    (
        "radiance_stderr",
        "W m-2 sr-1 nm-1",
        "standard error of radiance",
        |r| r.radiance.1,
    ),
    (
        "band_irradiance",
        "W m-2 nm-1",
        "band solar irradiance at the Earth-Sun distance",
        |r| r.band_irradiance,
    ),
];

/// The acquisition times of `rows`, seconds since 1970-01-01 UTC.
pub fn times(rows: &[PicsRow]) -> Result<Vec<f64>, EphemerisError> {
    rows.iter()
        .map(|r| parse_time(&r.acquisition.time_utc).map(|t| unix_seconds(&t)))
        .collect()
}

/// Write `pics.nc` at `path`; `site_path` is recorded as an attribute.
pub fn write_netcdf(path: &Path, site_path: &Path, rows: &[PicsRow]) -> Result<(), OutputError> {
    let times = times(rows).map_err(|e| OutputError::Io {
        path: path.to_path_buf(),
        source: std::io::Error::new(std::io::ErrorKind::InvalidData, e),
    })?;
    let tmp = crate::products::tmp_path(path);
    let _ = std::fs::remove_file(&tmp);
    let nc = |source| OutputError::Netcdf {
        path: path.to_path_buf(),
        source,
    };
    {
        let _session = engine::netcdf_session();
        let mut f = netcdf::create(&tmp).map_err(nc)?;
        fill(&mut f, site_path, rows, &times).map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            nc(e)
        })?;
    }
    std::fs::rename(&tmp, path).map_err(|source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Every dimension, variable and attribute of `pics.nc` written into an open file `f` (on disk
/// for [`write_netcdf`], diskless for the Python package); `times` from [`times`].
pub fn fill(
    f: &mut netcdf::FileMut,
    site_path: &Path,
    rows: &[PicsRow],
    times: &[f64],
) -> Result<(), netcdf::Error> {
    f.add_attribute("Conventions", "CF-1.10")?;
    f.add_attribute("title", "Simulated TOA reflectance of a calibration site")?;
    f.add_attribute("source", format!("simulator {}", crate::BUILD_ID))?;
    f.add_attribute("site_file", site_path.display().to_string())?;
    f.add_dimension("acquisition", rows.len())?;
    {
        let mut v = f.add_variable::<i32>("acquisition", &["acquisition"])?;
        v.put_attribute(
            "long_name",
            "acquisition number (row of the acquisitions file, from 1)",
        )?;
        let idx: Vec<i32> = (1..=rows.len() as i32).collect();
        v.put_values(&idx, ..)?;
    }
    {
        let mut v = f.add_variable::<f64>("time", &["acquisition"])?;
        v.put_attribute("standard_name", "time")?;
        v.put_attribute("long_name", "acquisition time")?;
        v.put_attribute("units", "seconds since 1970-01-01T00:00:00Z")?;
        v.put_attribute("calendar", "standard")?;
        v.put_attribute("axis", "T")?;
        v.put_values(times, ..)?;
    }
    {
        let mut v = f.add_string_variable("time_utc", &["acquisition"])?;
        v.put_attribute("long_name", "acquisition time, RFC 3339 UTC")?;
        for (i, r) in rows.iter().enumerate() {
            v.put_string(&r.acquisition.time_utc, [i])?;
        }
    }
    {
        let mut v = f.add_string_variable("srf", &["acquisition"])?;
        v.put_attribute("long_name", "spectral response function (name or file)")?;
        v.put_attribute("coordinates", "time")?;
        for (i, r) in rows.iter().enumerate() {
            v.put_string(&r.acquisition.srf, [i])?;
        }
    }
    {
        let mut v = f.add_variable::<i8>("sun_angles_given", &["acquisition"])?;
        v.put_attribute(
            "long_name",
            "whether sza and saa come from the acquisitions file",
        )?;
        v.put_attribute("flag_values", vec![0i8, 1])?;
        v.put_attribute("flag_meanings", "computed_by_spa given_in_csv")?;
        v.put_attribute("coordinates", "time")?;
        let given: Vec<i8> = rows
            .iter()
            .map(|r| i8::from(r.acquisition.sun.is_some()))
            .collect();
        v.put_values(&given, ..)?;
    }
    for (name, units, long, get) in COLUMNS {
        let data: Vec<f64> = rows.iter().map(get).collect();
        let mut v = f.add_variable::<f64>(name, &["acquisition"])?;
        v.put_attribute("units", units)?;
        v.put_attribute("long_name", long)?;
        v.put_attribute("coordinates", "time")?;
        v.put_values(&data, ..)?;
    }
    Ok(())
}
