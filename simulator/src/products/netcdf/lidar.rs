//! The variables of each lidar measure `ID` in `results.nc` (the same numbers as its CSV
//! products, `products/lidar.rs`), added to the file the passive products made:
//!
//! * dimensions `ID_shot`, `ID_bin`, `ID_part` (the parts of the return, named by the
//!   attribute `parts`: total, first order, multiple, first-order canopy, ground, air) and
//!   `ID_rh_percent`;
//! * coordinates `ID_time_ns(ID_bin)` (two-way delay after `2 R0 / c`), `ID_height_m(ID_bin)`
//!   (apparent height above the footprint centre), `ID_x(ID_shot)`, `ID_y(ID_shot)` (footprint
//!   centres in the experiment's coordinates), `ID_footprint_height_m(ID_shot)` and
//!   `ID_rh_percent`;
//! * `ID_energy(ID_shot, ID_part, ID_bin)` and `ID_energy_stderr`: normalised energy
//!   `E_R / (E_T A_r / (π R0²))` per bin; `ID_energy_j` (the total part in joules) and
//!   `ID_range_m(ID_shot, ID_bin)`;
//! * `ID_total(ID_shot, ID_part)` and `ID_total_stderr`: whole returns;
//! * metrics (`engine::lidar::metrics`): `ID_ground_m`, `ID_top_m`, `ID_cover` on `ID_shot`
//!   and `ID_rh_m(ID_shot, ID_rh_percent)`, each with `_stderr`; NaN for shots without a
//!   ground return.

use std::path::Path;

use engine::lidar::metrics::RH_PERCENTS;
use engine::lidar::trace::{COMP_NAMES, NCOMP, TOTAL};
use engine::lidar::C_M_PER_NS;

use crate::error::OutputError;
use engine::lidar::LidarResult;

/// Add the lidar measures' variables to the netCDF file at `path`.
pub fn append(path: &Path, lidars: &[LidarResult]) -> Result<(), OutputError> {
    if lidars.is_empty() {
        return Ok(());
    }
    let nc = |source| OutputError::Netcdf {
        path: path.to_path_buf(),
        source,
    };
    let _session = engine::netcdf_session();
    let mut f = netcdf::append(path).map_err(nc)?;
    fill(&mut f, lidars).map_err(nc)
}

/// The lidar variables written into an open file (on disk for [`append`], in memory for the
/// Python package's dataset).
pub fn fill(f: &mut netcdf::FileMut, lidars: &[LidarResult]) -> Result<(), netcdf::Error> {
    lidars.iter().try_for_each(|r| write_one(f, r))
}

fn write_one(f: &mut netcdf::FileMut, r: &LidarResult) -> Result<(), netcdf::Error> {
    let l = &r.lidar;
    let id = &l.id;
    let (ds, db, dp, dr) = (
        format!("{id}_shot"),
        format!("{id}_bin"),
        format!("{id}_part"),
        format!("{id}_rh_percent"),
    );
    let (ns, nb) = (r.shots.len(), l.bins.count);
    f.add_dimension(&ds, ns)?;
    f.add_dimension(&db, nb)?;
    f.add_dimension(&dp, NCOMP)?;
    f.add_dimension(&dr, RH_PERCENTS.len())?;

    let times: Vec<f64> = (0..nb).map(|k| l.bins.centre_ns(k)).collect();
    let coord = |f: &mut netcdf::FileMut,
                 name: &str,
                 dim: &str,
                 units: &str,
                 long: &str,
                 data: &[f64]|
     -> Result<(), netcdf::Error> {
        let mut v = f.add_variable::<f64>(name, &[dim])?;
        v.put_attribute("units", units)?;
        v.put_attribute("long_name", long)?;
        v.put_values(data, ..)?;
        Ok(())
    };
    coord(
        f,
        &format!("{id}_time_ns"),
        &db,
        "ns",
        "two-way delay of the bin centre after 2 R0 / c",
        &times,
    )?;
    let heights: Vec<f64> = times.iter().map(|t| -0.5 * C_M_PER_NS * t).collect();
    coord(
        f,
        &format!("{id}_height_m"),
        &db,
        "m",
        "apparent height of the bin centre above the footprint centre (-c t / 2)",
        &heights,
    )?;
    let xs: Vec<f64> = l.shots_given.iter().map(|s| s[0]).collect();
    let ys: Vec<f64> = l.shots_given.iter().map(|s| s[1]).collect();
    let zs: Vec<f64> = l.shots.iter().map(|c| c.z).collect();
    coord(
        f,
        &format!("{id}_x"),
        &ds,
        "m",
        "footprint centre x (experiment coordinates)",
        &xs,
    )?;
    coord(
        f,
        &format!("{id}_y"),
        &ds,
        "m",
        "footprint centre y (experiment coordinates)",
        &ys,
    )?;
    coord(
        f,
        &format!("{id}_footprint_height_m"),
        &ds,
        "m",
        "height of the footprint centre",
        &zs,
    )?;
    coord(
        f,
        &format!("{id}_rh_percent"),
        &dr,
        "percent",
        "energy percentile of the relative-height metrics",
        &RH_PERCENTS,
    )?;

    let mut energy = Vec::with_capacity(ns * NCOMP * nb);
    let mut stderr = Vec::with_capacity(ns * NCOMP * nb);
    for w in &r.shots {
        for c in 0..NCOMP {
            for b in &w.bins {
                energy.push(b[c].mean);
                stderr.push(b[c].stderr);
            }
        }
    }
    let parts = COMP_NAMES.join(" ");
    for (name, data, long) in [
        (
            "energy",
            &energy,
            "normalised energy E_R / (E_T A_r / (pi R0^2)) per bin",
        ),
        ("energy_stderr", &stderr, "standard error of energy"),
    ] {
        let mut v = f.add_variable::<f64>(&format!("{id}_{name}"), &[&ds, &dp, &db])?;
        v.put_attribute("units", "1")?;
        v.put_attribute("long_name", long)?;
        v.put_attribute("parts", parts.as_str())?;
        v.put_values(data, ..)?;
    }
    let mut joules = Vec::with_capacity(ns * nb);
    let mut joules_err = Vec::with_capacity(ns * nb);
    let mut range = Vec::with_capacity(ns * nb);
    for (k, w) in r.shots.iter().enumerate() {
        let scale = l.pulse_energy_j * l.energy_scale(l.shots[k]);
        let r0 = l.range0(l.shots[k]);
        for (b, t) in w.bins.iter().zip(&times) {
            joules.push(b[TOTAL].mean * scale);
            joules_err.push(b[TOTAL].stderr * scale);
            range.push(r0 + 0.5 * C_M_PER_NS * t);
        }
    }
    for (name, data, units, long) in [
        (
            "energy_j",
            &joules,
            "J",
            "received energy per bin, all orders",
        ),
        (
            "energy_j_stderr",
            &joules_err,
            "J",
            "standard error of energy_j",
        ),
        (
            "range_m",
            &range,
            "m",
            "range of the bin centre from the sensor (R0 + c t / 2)",
        ),
    ] {
        let mut v = f.add_variable::<f64>(&format!("{id}_{name}"), &[&ds, &db])?;
        v.put_attribute("units", units)?;
        v.put_attribute("long_name", long)?;
        v.put_values(data, ..)?;
    }
    let tot: Vec<f64> = r
        .shots
        .iter()
        .flat_map(|w| w.totals.map(|s| s.mean))
        .collect();
    let tot_err: Vec<f64> = r
        .shots
        .iter()
        .flat_map(|w| w.totals.map(|s| s.stderr))
        .collect();
    for (name, data) in [("total", &tot), ("total_stderr", &tot_err)] {
        let mut v = f.add_variable::<f64>(&format!("{id}_{name}"), &[&ds, &dp])?;
        v.put_attribute("units", "1")?;
        v.put_attribute(
            "long_name",
            "normalised energy of the whole return (every delay)",
        )?;
        v.put_attribute("parts", parts.as_str())?;
        v.put_values(data, ..)?;
    }

    // Metrics (NaN for shots without a ground return).
    let get = |pick: &dyn Fn(&engine::lidar::metrics::Metrics) -> f64, err: bool| -> Vec<f64> {
        r.shots
            .iter()
            .map(|w| match &w.metrics {
                Some((m, e)) => pick(if err { e } else { m }),
                None => f64::NAN,
            })
            .collect()
    };
    type Pick = fn(&engine::lidar::metrics::Metrics) -> f64;
    let picks: [(&str, Pick, &str); 3] = [
        (
            "ground_m",
            |m| m.ground,
            "centre of gravity of the first-order ground return above the footprint centre",
        ),
        ("top_m", |m| m.top, "RH 99.9 above the ground"),
        (
            "cover",
            |m| m.cover,
            "canopy cover Ec / (Ec + Eg rho_v / rho_g)",
        ),
    ];
    for (name, pick, long) in picks {
        for err in [false, true] {
            let n = if err {
                format!("{id}_{name}_stderr")
            } else {
                format!("{id}_{name}")
            };
            let mut v = f.add_variable::<f64>(&n, &[&ds])?;
            v.put_attribute("units", if name == "cover" { "1" } else { "m" })?;
            v.put_attribute("long_name", long)?;
            v.put_values(&get(&pick, err), ..)?;
        }
    }
    for err in [false, true] {
        let data: Vec<f64> = r
            .shots
            .iter()
            .flat_map(|w| match &w.metrics {
                Some((m, e)) => (if err { e } else { m }).rh.clone(),
                None => vec![f64::NAN; RH_PERCENTS.len()],
            })
            .collect();
        let n = if err {
            format!("{id}_rh_m_stderr")
        } else {
            format!("{id}_rh_m")
        };
        let mut v = f.add_variable::<f64>(&n, &[&ds, &dr])?;
        v.put_attribute("units", "m")?;
        v.put_attribute(
            "long_name",
            "relative height above the ground below which the percentile of the energy lies",
        )?;
        v.put_values(&data, ..)?;
    }
    // What the measure was.
    let mut v = f.add_variable::<i32>(&format!("{id}_lidar"), &[])?;
    v.put_attribute("long_name", "lidar measure settings")?;
    v.put_attribute("wavelength_nm", l.wavelength)?;
    v.put_attribute("altitude_m", l.altitude)?;
    v.put_attribute("zenith_deg", l.zenith_deg)?;
    v.put_attribute("azimuth_deg", l.azimuth_deg)?;
    v.put_attribute("pulse_sigma_ns", l.pulse_sigma_ns)?;
    v.put_attribute("pulse_energy_j", l.pulse_energy_j)?;
    v.put_attribute("receiver_area_m2", l.receiver_area_m2)?;
    v.put_attribute("fov_half_angle_rad", l.fov_half_angle)?;
    v.put_attribute(
        "photon_paths_per_shot",
        r.shots.first().map_or(0, |w| w.photons) as f64,
    )?;
    Ok(())
}
