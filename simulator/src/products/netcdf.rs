//! `results.nc`: the same data as `results.csv`, as labelled CF-1.10 variables (xarray-ready).
//!
//! Layout: a global `wavelength` coordinate (nm). Each measure `ID` has its own variables,
//! prefixed by its id:
//! * `mdistant` / `radiancemeter`: dimension `ID_direction`, coordinates `ID_vza(ID_direction)`
//!   and `ID_vaa(ID_direction)` (degrees), data `ID_brf`, `ID_brf_stderr`, `ID_brf_single`,
//!   `ID_brf_multiple`, `ID_radiance`, `ID_radiance_stderr`, `ID_n_samples`, all on
//!   `(wavelength, ID_direction)`;
//! * polarized runs add `ID_brf_q`, `ID_brf_u`, `ID_brf_v` (Stokes components normalised like
//!   the BRF, meridian frame of the view direction), `ID_dolp` and their `_stderr`;
//! * `distant_flux`: `ID_albedo`, `ID_albedo_stderr`, `ID_flux`, `ID_flux_stderr`,
//!   `ID_n_samples` on `(wavelength)`;
//! * `ortho` / `perspective` images: dimensions `ID_y`, `ID_x`; ortho images have coordinates
//!   `ID_x(ID_x)`, `ID_y(ID_y)` (pixel centres in the scene's CRS, m) and the CRS's WKT as the
//!   attribute `crs_wkt`; polarized runs add `ID_q`, `ID_u`, `ID_dolp`, `ID_dolp_stderr`; data `ID_brf`, `ID_brf_stderr`, `ID_brf_single`, `ID_brf_multiple`,
//!   `ID_radiance`, `ID_radiance_stderr` on `(wavelength, ID_y, ID_x)` (row 0 = north / top);
//!   `ID_n_samples(wavelength)` samples per pixel.
//!
//! Global attributes: `Conventions`, `title`, `source` (crate and version), `history`,
//! `seed`, `sun_zenith`, `sun_azimuth`, and `experiment` (the experiment file's text).

use std::path::Path;

use super::{tmp_path, Row};
use crate::config::resolve::Experiment;
use crate::error::OutputError;
use crate::measure::MeasureKind;

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
        let _session = crate::netcdf_session();
        let mut f = netcdf::create(&tmp).map_err(nc)?;
        write_into(&mut f, exp, rows)
            .and_then(|_| images.iter().try_for_each(|p| write_image(&mut f, p)))
            .and_then(|_| write_band(&mut f, exp, band))
            .map_err(|e| {
                let _ = std::fs::remove_file(&tmp);
                nc(e)
            })?;
    }
    std::fs::rename(&tmp, path).map_err(|source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    })
}

fn write_into(
    f: &mut netcdf::FileMut,
    exp: &Experiment,
    rows: &[Row],
) -> Result<(), netcdf::Error> {
    f.add_attribute("Conventions", "CF-1.10")?;
    f.add_attribute("title", "Monte Carlo radiative transfer simulation")?;
    f.add_attribute("source", format!("simulator {}", env!("CARGO_PKG_VERSION")))?;
    f.add_attribute(
        "history",
        format!("created by `simulate run {}`", exp.source_path.display()),
    )?;
    f.add_attribute("seed", exp.seed as i64)?;
    f.add_attribute("polarized", if exp.polarized { "true" } else { "false" })?;
    f.add_attribute("sun_zenith", exp.sun_zenith_deg)?;
    f.add_attribute("sun_azimuth", exp.sun_azimuth_deg)?;
    f.add_attribute("experiment", exp.source_text.as_str())?;
    let nw = exp.wavelengths.len();
    f.add_dimension("wavelength", nw)?;
    {
        let mut v = f.add_variable::<f64>("wavelength", &["wavelength"])?;
        v.put_attribute("units", "nm")?;
        v.put_attribute("long_name", "wavelength")?;
        v.put_attribute("standard_name", "radiation_wavelength")?;
        v.put_values(&exp.wavelengths, ..)?;
    }
    for m in &exp.measures {
        if m.is_image() {
            continue;
        }
        let id = &m.id;
        let mrows: Vec<&Row> = rows.iter().filter(|r| &r.measure == id).collect();
        let nc = m.cell_count();
        // Rows are in (wavelength, direction) order.
        let col =
            |get: &dyn Fn(&Row) -> f64| -> Vec<f64> { mrows.iter().map(|r| get(r)).collect() };
        let nan = f64::NAN;
        match m.kind {
            MeasureKind::DistantFlux { altitude } => {
                let vars: [(&str, Vec<f64>, &str, &str); 4] = [
                    (
                        "albedo",
                        col(&|r| r.albedo.map_or(nan, |p| p.0)),
                        "1",
                        "upwelling flux / (E0 cos SZA)",
                    ),
                    (
                        "albedo_stderr",
                        col(&|r| r.albedo.map_or(nan, |p| p.1)),
                        "1",
                        "standard error of albedo",
                    ),
                    (
                        "flux",
                        col(&|r| r.flux.map_or(nan, |p| p.0)),
                        "W m-2 nm-1",
                        "upwelling hemispherical flux",
                    ),
                    (
                        "flux_stderr",
                        col(&|r| r.flux.map_or(nan, |p| p.1)),
                        "W m-2 nm-1",
                        "standard error of flux",
                    ),
                ];
                for (name, data, units, long) in vars {
                    let mut v = f.add_variable::<f64>(&format!("{id}_{name}"), &["wavelength"])?;
                    v.put_attribute("units", units)?;
                    v.put_attribute("long_name", long)?;
                    v.put_attribute("altitude_m", altitude)?;
                    v.put_values(&data, ..)?;
                }
                let n: Vec<i64> = mrows.iter().map(|r| r.n_samples as i64).collect();
                let mut v = f.add_variable::<i64>(&format!("{id}_n_samples"), &["wavelength"])?;
                v.put_attribute("long_name", "Monte Carlo samples")?;
                v.put_values(&n, ..)?;
            }
            _ => {
                let dim = format!("{id}_direction");
                f.add_dimension(&dim, nc)?;
                let first: Vec<&&Row> = mrows.iter().take(nc).collect();
                for (name, get, long) in [
                    (
                        "vza",
                        (|r: &Row| r.vza.unwrap_or(f64::NAN)) as fn(&Row) -> f64,
                        "viewing zenith angle (target to sensor)",
                    ),
                    (
                        "vaa",
                        |r: &Row| r.vaa.unwrap_or(f64::NAN),
                        "viewing azimuth angle, clockwise from North (target to sensor)",
                    ),
                ] {
                    let data: Vec<f64> = first.iter().map(|r| get(r)).collect();
                    let mut v = f.add_variable::<f64>(&format!("{id}_{name}"), &[&dim])?;
                    v.put_attribute("units", "degree")?;
                    v.put_attribute("long_name", long)?;
                    v.put_values(&data, ..)?;
                }
                let coords = format!("{id}_vza {id}_vaa");
                let vars: [(&str, Vec<f64>, &str, &str); 8] = [
                    (
                        "brf",
                        col(&|r| r.brf.map_or(nan, |p| p.0)),
                        "1",
                        "bidirectional reflectance factor pi L / (E0 cos SZA)",
                    ),
                    (
                        "brf_stderr",
                        col(&|r| r.brf.map_or(nan, |p| p.1)),
                        "1",
                        "standard error of brf",
                    ),
                    (
                        "brf_single",
                        col(&|r| r.brf_single.map_or(nan, |p| p.0)),
                        "1",
                        "single-scattering part of brf",
                    ),
                    (
                        "brf_single_stderr",
                        col(&|r| r.brf_single.map_or(nan, |p| p.1)),
                        "1",
                        "standard error of brf_single",
                    ),
                    (
                        "brf_multiple",
                        col(&|r| r.brf_multiple.map_or(nan, |p| p.0)),
                        "1",
                        "multiple-scattering part of brf",
                    ),
                    (
                        "brf_multiple_stderr",
                        col(&|r| r.brf_multiple.map_or(nan, |p| p.1)),
                        "1",
                        "standard error of brf_multiple",
                    ),
                    (
                        "radiance",
                        col(&|r| r.radiance.map_or(nan, |p| p.0)),
                        "W m-2 sr-1 nm-1",
                        "radiance",
                    ),
                    (
                        "radiance_stderr",
                        col(&|r| r.radiance.map_or(nan, |p| p.1)),
                        "W m-2 sr-1 nm-1",
                        "standard error of radiance",
                    ),
                ];
                for (name, data, units, long) in vars {
                    let mut v =
                        f.add_variable::<f64>(&format!("{id}_{name}"), &["wavelength", &dim])?;
                    v.put_attribute("units", units)?;
                    v.put_attribute("long_name", long)?;
                    v.put_attribute("coordinates", coords.as_str())?;
                    v.put_values(&data, ..)?;
                }
                if mrows.first().is_some_and(|r| r.brf_q.is_some()) {
                    let pol: [(&str, Vec<f64>, &str, &str); 8] = [
                        (
                            "brf_q",
                            col(&|r| r.brf_q.map_or(nan, |p| p.0)),
                            "1",
                            "Stokes Q normalised like brf (meridian frame of the view direction)",
                        ),
                        (
                            "brf_q_stderr",
                            col(&|r| r.brf_q.map_or(nan, |p| p.1)),
                            "1",
                            "standard error of brf_q",
                        ),
                        (
                            "brf_u",
                            col(&|r| r.brf_u.map_or(nan, |p| p.0)),
                            "1",
                            "Stokes U normalised like brf (meridian frame of the view direction)",
                        ),
                        (
                            "brf_u_stderr",
                            col(&|r| r.brf_u.map_or(nan, |p| p.1)),
                            "1",
                            "standard error of brf_u",
                        ),
                        (
                            "brf_v",
                            col(&|r| r.brf_v.map_or(nan, |p| p.0)),
                            "1",
                            "Stokes V normalised like brf",
                        ),
                        (
                            "brf_v_stderr",
                            col(&|r| r.brf_v.map_or(nan, |p| p.1)),
                            "1",
                            "standard error of brf_v",
                        ),
                        (
                            "dolp",
                            col(&|r| r.dolp.map_or(nan, |p| p.0)),
                            "1",
                            "degree of linear polarization sqrt(Q^2+U^2)/I",
                        ),
                        (
                            "dolp_stderr",
                            col(&|r| r.dolp.map_or(nan, |p| p.1)),
                            "1",
                            "standard error of dolp (delta method)",
                        ),
                    ];
                    for (name, data, units, long) in pol {
                        let mut v =
                            f.add_variable::<f64>(&format!("{id}_{name}"), &["wavelength", &dim])?;
                        v.put_attribute("units", units)?;
                        v.put_attribute("long_name", long)?;
                        v.put_attribute("coordinates", coords.as_str())?;
                        v.put_values(&data, ..)?;
                    }
                }
                let n: Vec<i64> = mrows.iter().map(|r| r.n_samples as i64).collect();
                let mut v =
                    f.add_variable::<i64>(&format!("{id}_n_samples"), &["wavelength", &dim])?;
                v.put_attribute("long_name", "Monte Carlo samples")?;
                v.put_values(&n, ..)?;
            }
        }
    }
    Ok(())
}

/// Band-weighted variables `ID_band_brf`, `ID_band_radiance` (and `_stderr`; `ID_band_albedo`,
/// `ID_band_flux` for fluxes) on the measure's direction dimension, with the band's name and
/// irradiance as attributes.
fn write_band(
    f: &mut netcdf::FileMut,
    exp: &Experiment,
    band: &[super::BandRow],
) -> Result<(), netcdf::Error> {
    let Some(b) = &exp.band else { return Ok(()) };
    f.add_attribute("srf", b.name.as_str())?;
    for m in &exp.measures {
        if m.is_image() {
            continue;
        }
        let id = &m.id;
        let rows: Vec<&super::BandRow> = band.iter().filter(|r| &r.measure == id).collect();
        let dim = match m.kind {
            MeasureKind::DistantFlux { .. } => {
                let d = format!("{id}_band_cell");
                f.add_dimension(&d, 1)?;
                d
            }
            _ => format!("{id}_direction"),
        };
        let nan = f64::NAN;
        let vars: [(&str, Vec<f64>, &str); 8] = [
            (
                "band_brf",
                rows.iter().map(|r| r.brf.map_or(nan, |p| p.0)).collect(),
                "1",
            ),
            (
                "band_brf_stderr",
                rows.iter().map(|r| r.brf.map_or(nan, |p| p.1)).collect(),
                "1",
            ),
            (
                "band_radiance",
                rows.iter()
                    .map(|r| r.radiance.map_or(nan, |p| p.0))
                    .collect(),
                "W m-2 sr-1 nm-1",
            ),
            (
                "band_radiance_stderr",
                rows.iter()
                    .map(|r| r.radiance.map_or(nan, |p| p.1))
                    .collect(),
                "W m-2 sr-1 nm-1",
            ),
            (
                "band_albedo",
                rows.iter().map(|r| r.albedo.map_or(nan, |p| p.0)).collect(),
                "1",
            ),
            (
                "band_albedo_stderr",
                rows.iter().map(|r| r.albedo.map_or(nan, |p| p.1)).collect(),
                "1",
            ),
            (
                "band_flux",
                rows.iter().map(|r| r.flux.map_or(nan, |p| p.0)).collect(),
                "W m-2 nm-1",
            ),
            (
                "band_flux_stderr",
                rows.iter().map(|r| r.flux.map_or(nan, |p| p.1)).collect(),
                "W m-2 nm-1",
            ),
        ];
        for (name, data, units) in vars {
            if data.iter().all(|v| v.is_nan()) {
                continue;
            }
            let mut v = f.add_variable::<f64>(&format!("{id}_{name}"), &[&dim])?;
            v.put_attribute("units", units)?;
            v.put_attribute(
                "long_name",
                format!("{name} weighted by the spectral response {}", b.name).as_str(),
            )?;
            v.put_attribute(
                "band_irradiance",
                rows.first().map_or(nan, |r| r.irradiance),
            )?;
            v.put_values(&data, ..)?;
        }
    }
    Ok(())
}

/// The variables of one image measure.
fn write_image(
    f: &mut netcdf::FileMut,
    p: &super::imagery::ImageProduct,
) -> Result<(), netcdf::Error> {
    let id = &p.id;
    let (dy, dx) = (format!("{id}_y"), format!("{id}_x"));
    f.add_dimension(&dy, p.height)?;
    f.add_dimension(&dx, p.width)?;
    if let Some(gt) = p.geotransform {
        let xs: Vec<f64> = (0..p.width)
            .map(|c| gt[0] + (c as f64 + 0.5) * gt[1])
            .collect();
        let ys: Vec<f64> = (0..p.height)
            .map(|r| gt[3] + (r as f64 + 0.5) * gt[5])
            .collect();
        for (name, dim, data, long) in [
            (&dx, &dx, xs, "easting of pixel centres"),
            (&dy, &dy, ys, "northing of pixel centres"),
        ] {
            let mut v = f.add_variable::<f64>(name, &[dim])?;
            v.put_attribute("units", "m")?;
            v.put_attribute("long_name", long)?;
            v.put_values(&data, ..)?;
        }
    }
    let mut sets: Vec<(&str, &Vec<Vec<f64>>, &str, &str)> = vec![
        (
            "brf",
            &p.brf,
            "1",
            "bidirectional reflectance factor pi L / (E0 cos SZA)",
        ),
        ("brf_stderr", &p.brf_stderr, "1", "standard error of brf"),
        (
            "brf_single",
            &p.brf_single,
            "1",
            "single-scattering part of brf",
        ),
        (
            "brf_multiple",
            &p.brf_multiple,
            "1",
            "multiple-scattering part of brf",
        ),
        ("radiance", &p.radiance, "W m-2 sr-1 nm-1", "radiance"),
        (
            "radiance_stderr",
            &p.radiance_stderr,
            "W m-2 sr-1 nm-1",
            "standard error of radiance",
        ),
    ];
    if let Some(st) = &p.stokes {
        sets.extend([
            (
                "q",
                &st.q,
                "1",
                "Stokes Q pi Q / (E0 cos SZA), meridian frame of the view",
            ),
            (
                "u",
                &st.u,
                "1",
                "Stokes U pi U / (E0 cos SZA), meridian frame of the view",
            ),
            ("dolp", &st.dolp, "1", "degree of linear polarization"),
            (
                "dolp_stderr",
                &st.dolp_stderr,
                "1",
                "standard error of dolp",
            ),
        ]);
    }
    for (name, data, units, long) in sets {
        let flat: Vec<f64> = data.iter().flatten().copied().collect();
        let mut v = f.add_variable::<f64>(&format!("{id}_{name}"), &["wavelength", &dy, &dx])?;
        v.put_attribute("units", units)?;
        v.put_attribute("long_name", long)?;
        if !p.wkt.is_empty() {
            v.put_attribute("crs_wkt", p.wkt.as_str())?;
        }
        if let Some((vza, vaa)) = p.view {
            v.put_attribute("vza", vza)?;
            v.put_attribute("vaa", vaa)?;
        }
        v.put_values(&flat, ..)?;
    }
    let n: Vec<i64> = p.n_samples.iter().map(|&x| x as i64).collect();
    let mut v = f.add_variable::<i64>(&format!("{id}_n_samples"), &["wavelength"])?;
    v.put_attribute("long_name", "Monte Carlo samples per pixel")?;
    v.put_values(&n, ..)?;
    Ok(())
}
