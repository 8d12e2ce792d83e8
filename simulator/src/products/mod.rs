//! Products: turn the integrators' sums into physical quantities with standard errors, and
//! write them (CSV table, CF netCDF). Files are written atomically: to a temporary name in the
//! output folder, then renamed, so a crash or a full disk never leaves a truncated product.
//!
//! Quantities (units in `docs/conventions.md`):
//! * `brf` = π·L/(E0·cos SZA) (dimensionless), its single- and multiple-scattering parts;
//! * `radiance` L = brf·E0·cos SZA/π, W m⁻² sr⁻¹ nm⁻¹ when E0 is in W m⁻² nm⁻¹;
//! * `flux` F (W m⁻² nm⁻¹) for `distant_flux`, upwelling or downwelling, and `albedo` =
//!   F/(E0·cos SZA); `flux_direct` (the attenuated solar beam, exact: `direct_flux.rs`; 0 for
//!   upwelling flux) and `flux_diffuse` (scattered light, the Monte Carlo estimate) with
//!   `flux = flux_direct + flux_diffuse`;
//! * `hdrf` = π·L↑(v)/E↓ for `hdrf` measures (radiance and downwelling flux at the level,
//!   independent estimates: standard error by the delta method for a ratio of independent
//!   means, `σ² = (σ_L/E)² + (L·σ_E/E²)²` in normalised units); their `radiance` and `brf`
//!   columns hold the upwelling radiance at the level and π·L/(E0·cos SZA);
//! * with thermal emission (`emission = true`), `brightness_temperature` (K): the inverse Planck
//!   function (`planck.rs`) of the radiance at the wavelength (band rows: of the band radiance
//!   at the band's effective wavelength Σwλ/Σw), its standard error by the delta method
//!   σ_T = σ_L/(dB/dT). The radiance then includes the emitted radiance; without a Sun
//!   (`illumination.type = "none"`) the BRF is left empty.
//!
//! Every quantity carries the Monte Carlo standard error of its mean.

pub mod cloud_bands;
pub mod csv;
pub mod image;
pub mod imagery;
pub mod lidar;
pub mod netcdf;
pub mod output_lock;
pub mod staging;

use std::path::Path;

use crate::error::OutputError;
use engine::accum::MeasureResult;
use engine::config::resolve::Experiment;
use engine::measure::{FluxDirection, MeasureKind};

/// The step of [`write_all`] that failed: before anything was written (the staging folder),
/// while writing into the staging folder (the previous products are untouched), or while
/// moving the products in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WriteStep {
    Stage,
    Write,
    Commit,
}

/// A failure of [`write_all`] and the step it happened in (the error boxed: GDAL's and netCDF's
/// errors make `OutputError` large).
#[derive(Debug, thiserror::Error)]
#[error("{error}")]
pub struct WriteError {
    pub step: WriteStep,
    pub error: Box<OutputError>,
}

/// What [`write_all`] wrote: every product's final path, and per image (in the order of the
/// images given) the description of its quicklook.
pub struct Written {
    pub files: Vec<std::path::PathBuf>,
    pub quicklooks: Vec<String>,
}

/// Write every product of a run into `output`, the one writer the command line and the Python
/// package call: `results.csv`, `results.nc`, each image's GeoTIFFs and PNG quicklook, and
/// `results_band.csv` for band runs. Staged (`staging.rs`): all appear together or none, and a
/// failure before the commit leaves the previous products as they were.
pub fn write_all(
    output: &Path,
    exp: &Experiment,
    rows: &[Row],
    band: &[BandRow],
    images: &[imagery::ImageProduct],
    lidars: &[engine::lidar::LidarResult],
) -> Result<Written, WriteError> {
    let at = |step| {
        move |error| WriteError {
            step,
            error: Box::new(error),
        }
    };
    let mut stage = staging::Staging::new(output).map_err(at(WriteStep::Stage))?;
    let mut quicklooks = Vec::new();
    (|| -> Result<(), OutputError> {
        csv::write(&stage.path("results.csv"), rows)?;
        netcdf::write(&stage.path("results.nc"), exp, rows, band, images)?;
        for img in images {
            quicklooks.push(imagery::write_files(stage.dir(), exp, img)?.1);
        }
        if !band.is_empty() {
            csv::write_band(&stage.path("results_band.csv"), band)?;
        }
        netcdf::lidar::append(&stage.path("results.nc"), lidars)?;
        lidar::write(stage.dir(), lidars)?;
        Ok(())
    })()
    .map_err(at(WriteStep::Write))?;
    let files = stage.commit().map_err(at(WriteStep::Commit))?;
    Ok(Written { files, quicklooks })
}

/// One output row: one measure, wavelength and direction.
#[derive(Clone, Debug, Default)]
pub struct Row {
    pub measure: String,
    pub kind: &'static str,
    pub method: &'static str,
    pub wavelength_nm: f64,
    /// Zenith and azimuth (degrees) of the direction from the target towards the sensor.
    pub vza: Option<f64>,
    pub vaa: Option<f64>,
    pub radiance: Option<(f64, f64)>,
    pub brf: Option<(f64, f64)>,
    pub brf_single: Option<(f64, f64)>,
    pub brf_multiple: Option<(f64, f64)>,
    pub albedo: Option<(f64, f64)>,
    pub flux: Option<(f64, f64)>,
    /// Flux measures: the direct solar beam's and the scattered light's parts of `flux`.
    pub flux_direct: Option<(f64, f64)>,
    pub flux_diffuse: Option<(f64, f64)>,
    /// `hdrf` measures: the hemispherical–directional reflectance factor.
    pub hdrf: Option<(f64, f64)>,
    /// Polarized runs: BRF-normalised Stokes Q, U, V (π·Q/(E0 cos SZA), meridian frame of the
    /// view direction) and the degree of linear polarization √(Q²+U²)/I.
    pub brf_q: Option<(f64, f64)>,
    pub brf_u: Option<(f64, f64)>,
    pub brf_v: Option<(f64, f64)>,
    pub dolp: Option<(f64, f64)>,
    /// Thermal runs: brightness temperature of the radiance (K).
    pub brightness_temperature: Option<(f64, f64)>,
    pub n_samples: u64,
}

/// Degree of linear polarization and its standard error (delta method with the estimated
/// covariances of the means of I, Q, U).
pub(crate) fn dolp(acc: &engine::integrator::Accum, c: usize) -> (f64, f64) {
    use engine::integrator::{Q, TOTAL, U};
    let (i, ei) = acc.mean_stderr(c, TOTAL);
    let (q, eq) = acc.mean_stderr(c, Q);
    let (u, eu) = acc.mean_stderr(c, U);
    let pl = (q * q + u * u).sqrt();
    if i.is_nan() || i <= 0.0 {
        return (f64::NAN, f64::NAN);
    }
    let p = pl / i;
    if pl == 0.0 {
        return (0.0, ((eq * eq + eu * eu) / 2.0).sqrt() / i);
    }
    // Gradient of √(Q²+U²)/I with respect to (I, Q, U).
    let (gi, gq, gu) = (-p / i, q / (pl * i), u / (pl * i));
    let var = gi * gi * ei * ei
        + gq * gq * eq * eq
        + gu * gu * eu * eu
        + 2.0
            * (gi * gq * acc.cov_of_means(c, 0)
                + gi * gu * acc.cov_of_means(c, 1)
                + gq * gu * acc.cov_of_means(c, 2));
    (p, var.max(0.0).sqrt())
}

/// Rows for every result, in (wavelength, measure, direction) order.
pub fn rows(exp: &Experiment, results: &[MeasureResult]) -> Vec<Row> {
    let mu_s = exp.mu_norm();
    let sun_up = exp.sun_up();
    let mut out = Vec::new();
    for r in results {
        let m = &exp.measures[r.measure];
        if m.is_image() {
            // Images have their own products (`products::image`, image variables in netCDF).
            continue;
        }
        let e0 = exp.optics[r.wavelength].irradiance;
        let to_rad = e0 * mu_s / std::f64::consts::PI;
        // The direct beam's downwelling flux at an altitude, exact, in the tally's units
        // (E0·cos SZA); none without a Sun.
        let opt = &exp.optics[r.wavelength];
        let direct_at = |z: f64| {
            let sun = if sun_up {
                engine::measure::direct_flux::direct_transmittance(opt, exp.sun_dir, z)
            } else {
                0.0
            };
            // The Moon's beam beside the Sun's, in the Sun's units (E_moon·μ_moon/(E0·μ)).
            let moon = exp.moon.as_ref().map_or(0.0, |m| {
                engine::measure::direct_flux::direct_transmittance(opt, m.dir, z)
                    * exp.moon_ratio(r.wavelength)
                    * m.dir.z.max(0.0)
                    / mu_s
            });
            sun + moon
        };
        // An HDRF's downwelling flux at its level, from its last cell and the direct beam.
        let hdrf_flux = match &m.kind {
            MeasureKind::Hdrf {
                directions,
                altitude,
                ..
            } => {
                let (d, de) = r.acc.mean_stderr(directions.len(), 0);
                Some((d + direct_at(*altitude), de))
            }
            MeasureKind::Distant { .. }
            | MeasureKind::Radiancemeter { .. }
            | MeasureKind::DistantFlux { .. }
            | MeasureKind::Ortho(_)
            | MeasureKind::Perspective(_) => None,
        };
        for c in 0..m.row_count() {
            let (t, te) = r.acc.mean_stderr(c, 0);
            let single = r.acc.mean_stderr(c, 1);
            let multiple = r.acc.mean_stderr(c, 2);
            let mut row = Row {
                measure: m.id.clone(),
                kind: m.type_name(),
                method: r.method.name(),
                wavelength_nm: exp.wavelengths[r.wavelength],
                n_samples: r.acc.n[c],
                ..Row::default()
            };
            if r.acc.is_polarized() && !m.is_flux() {
                use engine::integrator::{Q, U, V};
                row.brf_q = Some(r.acc.mean_stderr(c, Q));
                row.brf_u = Some(r.acc.mean_stderr(c, U));
                row.brf_v = Some(r.acc.mean_stderr(c, V));
                row.dolp = Some(dolp(&r.acc, c));
            }
            if let Some((z, a)) = m.view_angles(c) {
                row.vza = Some(z);
                row.vaa = Some(a);
            }
            if let MeasureKind::DistantFlux {
                altitude,
                direction,
            } = m.kind
            {
                // The walks estimate the scattered light; a downwelling flux adds the direct beam.
                let direct = match direction {
                    FluxDirection::Down => direct_at(altitude),
                    FluxDirection::Up => 0.0,
                };
                if sun_up {
                    row.albedo = Some((t + direct, te));
                }
                let k = e0 * mu_s;
                row.flux = Some(((t + direct) * k, te * k));
                row.flux_direct = Some((direct * k, 0.0));
                row.flux_diffuse = Some((t * k, te * k));
            } else {
                if sun_up {
                    row.brf = Some((t, te));
                    row.brf_single = Some(single);
                    row.brf_multiple = Some(multiple);
                }
                row.radiance = Some((t * to_rad, te * to_rad));
                if let Some((e, ee)) = hdrf_flux {
                    let h = t / e;
                    row.hdrf = Some((h, ((te / e).powi(2) + (h * ee / e).powi(2)).sqrt()));
                }
                if exp.emission {
                    row.brightness_temperature =
                        Some(engine::sources::planck::brightness_temperature_stderr(
                            row.wavelength_nm,
                            t * to_rad,
                            te * to_rad,
                        ));
                }
            }
            out.push(row);
        }
    }
    out
}

/// Write `bytes` to `path` atomically (temporary file in the same folder, then rename).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    let tmp = tmp_path(path);
    let io = |source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    };
    std::fs::write(&tmp, bytes).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        io(e)
    })?;
    std::fs::rename(&tmp, path).map_err(io)
}

/// `dir/.name.PID.partial`: where a product is written before the rename (unique per
/// process, so two writers never share a temporary).
pub fn tmp_path(path: &Path) -> std::path::PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.{}.partial", std::process::id()))
}

/// A band-weighted row (see `srf.rs` for the weighting): one per measure and direction.
#[derive(Clone, Debug)]
pub struct BandRow {
    pub measure: String,
    pub kind: &'static str,
    pub band: String,
    pub vza: Option<f64>,
    pub vaa: Option<f64>,
    /// Band radiance (W m⁻² sr⁻¹ nm⁻¹) or flux (W m⁻² nm⁻¹), and its standard error.
    pub radiance: Option<(f64, f64)>,
    pub flux: Option<(f64, f64)>,
    /// Flux measures: the band's direct and diffuse parts of `flux`.
    pub flux_direct: Option<(f64, f64)>,
    pub flux_diffuse: Option<(f64, f64)>,
    /// Band BRF or albedo, and its standard error.
    pub brf: Option<(f64, f64)>,
    pub albedo: Option<(f64, f64)>,
    /// Band irradiance E0_b (W m⁻² nm⁻¹).
    pub irradiance: f64,
    /// Thermal runs: brightness temperature of the band radiance at the band's effective
    /// wavelength (K).
    pub brightness_temperature: Option<(f64, f64)>,
}

/// Band-weighted rows from per-wavelength rows (empty unless `spectral.srf` was given).
pub fn band_rows(exp: &Experiment, rows: &[Row]) -> Vec<BandRow> {
    let Some(band) = &exp.band else {
        return Vec::new();
    };
    let wsum: f64 = band.weights.iter().sum();
    let e0: Vec<f64> = exp.optics.iter().map(|o| o.irradiance).collect();
    let e0_b = band
        .weights
        .iter()
        .zip(&e0)
        .map(|(w, e)| w * e)
        .sum::<f64>()
        / wsum;
    let wl_eff = band
        .weights
        .iter()
        .zip(&exp.wavelengths)
        .map(|(w, l)| w * l)
        .sum::<f64>()
        / wsum;
    let mut out = Vec::new();
    for m in &exp.measures {
        for c in 0..m.row_count() {
            // Rows of this measure and cell, one per wavelength, in wavelength order.
            let cells: Vec<&Row> = rows
                .iter()
                .filter(|r| r.measure == m.id)
                .skip(c)
                .step_by(m.row_count())
                .collect();
            if cells.is_empty() {
                // Image measures have no rows (their band images: `imagery.rs`).
                continue;
            }
            let combine =
                |get: &dyn Fn(&Row) -> Option<(f64, f64)>, by_e0: bool| -> Option<(f64, f64)> {
                    let mut num = 0.0;
                    let mut var = 0.0;
                    let mut den = 0.0;
                    for (k, r) in cells.iter().enumerate() {
                        let (v, e) = get(r)?;
                        let w = band.weights[k] * if by_e0 { e0[k] } else { 1.0 };
                        num += w * v;
                        var += (w * e).powi(2);
                        den += w;
                    }
                    Some((num / den, var.sqrt() / den))
                };
            let radiance = combine(&|r| r.radiance, false);
            let brightness_temperature = radiance
                .filter(|_| exp.emission && !m.is_flux())
                .map(|(l, e)| engine::sources::planck::brightness_temperature_stderr(wl_eff, l, e));
            out.push(BandRow {
                measure: m.id.clone(),
                kind: m.type_name(),
                band: band.name.clone(),
                vza: cells[0].vza,
                vaa: cells[0].vaa,
                radiance,
                brightness_temperature,
                flux: combine(&|r| r.flux, false),
                flux_direct: combine(&|r| r.flux_direct, false),
                flux_diffuse: combine(&|r| r.flux_diffuse, false),
                brf: combine(&|r| r.brf, true),
                albedo: combine(&|r| r.albedo, true),
                irradiance: e0_b,
            });
        }
    }
    out
}
