//! `results.csv`: one row per measure, wavelength and direction.
//!
//! Columns: `measure,type,method,wavelength_nm,vza,vaa,radiance,radiance_stderr,brf,brf_stderr,
//! brf_single,brf_single_stderr,brf_multiple,brf_multiple_stderr,albedo,albedo_stderr,flux,
//! flux_stderr,n_samples,brf_q,brf_q_stderr,brf_u,brf_u_stderr,brf_v,brf_v_stderr,dolp,dolp_stderr,
//! brightness_temperature,brightness_temperature_stderr,flux_direct,flux_direct_stderr,
//! flux_diffuse,flux_diffuse_stderr,hdrf,hdrf_stderr`
//! (the last two for `hdrf` measures only, π·L↑/E↓ at their level; the four before them
//! for `distant_flux` measures only: the direct solar beam's part of
//! `flux`, exact, and the scattered light's part; the two before them
//! in thermal runs only, `emission = true`, in K; the eight before those
//! in polarized runs only: Stokes Q, U, V normalised like the BRF, in the
//! meridian frame of the view direction, and the degree of linear polarization). Angles in degrees (`vaa` clockwise from North, direction from the
//! target to the sensor); empty cells where a quantity does not apply to the measure type.

use std::fmt::Write;
use std::path::Path;

use super::{write_atomic, Row};
use crate::error::OutputError;

pub const HEADER: &str = "measure,type,method,wavelength_nm,vza,vaa,radiance,radiance_stderr,brf,brf_stderr,\
brf_single,brf_single_stderr,brf_multiple,brf_multiple_stderr,albedo,albedo_stderr,flux,flux_stderr,n_samples,\
brf_q,brf_q_stderr,brf_u,brf_u_stderr,brf_v,brf_v_stderr,dolp,dolp_stderr,\
brightness_temperature,brightness_temperature_stderr,flux_direct,flux_direct_stderr,flux_diffuse,flux_diffuse_stderr,\
hdrf,hdrf_stderr";

fn opt(x: Option<f64>) -> String {
    x.map(|v| format!("{v:.10e}")).unwrap_or_default()
}

fn pair(p: Option<(f64, f64)>) -> String {
    match p {
        Some((a, b)) => format!("{},{}", opt(Some(a)), opt(Some(b))),
        None => ",".into(),
    }
}

pub fn to_string(rows: &[Row]) -> String {
    let mut s = String::from(HEADER);
    s.push('\n');
    for r in rows {
        let angle = |x: Option<f64>| x.map(|v| format!("{v:.6}")).unwrap_or_default();
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            r.measure,
            r.kind,
            r.method,
            r.wavelength_nm,
            angle(r.vza),
            angle(r.vaa),
            pair(r.radiance),
            pair(r.brf),
            pair(r.brf_single),
            pair(r.brf_multiple),
            pair(r.albedo),
            pair(r.flux),
            r.n_samples,
            pair(r.brf_q),
            pair(r.brf_u),
            pair(r.brf_v),
            pair(r.dolp),
            pair(r.brightness_temperature),
            pair(r.flux_direct),
            pair(r.flux_diffuse),
            pair(r.hdrf)
        );
    }
    s
}

pub fn write(path: &Path, rows: &[Row]) -> Result<(), OutputError> {
    write_atomic(path, to_string(rows).as_bytes())
}

pub const BAND_HEADER: &str =
    "measure,type,band,vza,vaa,radiance,radiance_stderr,brf,brf_stderr,flux,flux_stderr,albedo,albedo_stderr,band_irradiance,brightness_temperature,brightness_temperature_stderr,flux_direct,flux_direct_stderr,flux_diffuse,flux_diffuse_stderr";

/// `results_band.csv`: band-weighted quantities (runs with `spectral.srf`).
pub fn band_to_string(rows: &[super::BandRow]) -> String {
    let mut s = String::from(BAND_HEADER);
    s.push('\n');
    for r in rows {
        let angle = |x: Option<f64>| x.map(|v| format!("{v:.6}")).unwrap_or_default();
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{:.10e},{},{},{}",
            r.measure,
            r.kind,
            r.band,
            angle(r.vza),
            angle(r.vaa),
            pair(r.radiance),
            pair(r.brf),
            pair(r.flux),
            pair(r.albedo),
            r.irradiance,
            pair(r.brightness_temperature),
            pair(r.flux_direct),
            pair(r.flux_diffuse)
        );
    }
    s
}

pub fn write_band(path: &Path, rows: &[super::BandRow]) -> Result<(), OutputError> {
    write_atomic(path, band_to_string(rows).as_bytes())
}
