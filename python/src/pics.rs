//! PICS sweeps: one site (a table in memory, parsed once) and many acquisitions run in one call,
//! in this process, so the site's data files are read once per sweep where the simulator caches
//! them and its scene is built once; the result is the contents of `pics.nc`.

use std::path::PathBuf;

use pyo3::prelude::*;
use pyo3::types::PyDict;
use simulator::pics::{self, Acquisition};

use crate::errors::{config, simulation, SimulationError};

/// One acquisition as Python passes it: time (RFC 3339), vza, vaa, srf, sza, saa.
type Row = (String, f64, f64, String, Option<f64>, Option<f64>);

fn acquisition(k: usize, r: &Row) -> Result<Acquisition, String> {
    let (time, vza, vaa, srf, sza, saa) = r;
    let mut a = Acquisition::new(time, *vza, *vaa, srf)
        .map_err(|m| format!("acquisitions[{k}].time_utc: {m}"))?;
    a.sun = match (sza, saa) {
        (Some(z), Some(a)) => Some((*z, *a)),
        (None, None) => None,
        _ => {
            return Err(format!(
                "acquisitions[{k}]: give both sza and saa, or neither"
            ))
        }
    };
    Ok(a)
}

/// Run every acquisition at the site of TOML `site_text` (`site_path` names it in errors and
/// anchors its relative paths). `progress`: a callable `(acquisitions_done, total)`.
#[pyfunction]
#[pyo3(signature = (site_text, site_path, acquisitions, progress=None, threads=None))]
pub fn pics_sweep<'py>(
    py: Python<'py>,
    site_text: &str,
    site_path: PathBuf,
    acquisitions: Vec<Row>,
    progress: Option<&Bound<'py, PyAny>>,
    threads: Option<usize>,
) -> PyResult<Bound<'py, PyDict>> {
    let site: toml::Table = site_text
        .parse()
        .map_err(|e: toml::de::Error| config(format!("{}: {e}", site_path.display())))?;
    let site = pics::with_catalogue(site)
        .map_err(|m| config(format!("{}: `catalogue`: {m}", site_path.display())))?;
    let acqs: Vec<Acquisition> = acquisitions
        .iter()
        .enumerate()
        .map(|(k, r)| acquisition(k, r))
        .collect::<Result<_, _>>()
        .map_err(|m| config(format!("{}: {m}", site_path.display())))?;
    if acqs.is_empty() {
        return Err(config("no acquisitions to run"));
    }
    let n = acqs.len() as u64;
    let out = crate::released::run(py, progress, threads, n, |p| {
        let rows = pics::run_site(
            &site,
            &site_path,
            &acqs,
            |k| p.bar.set_position(k as u64),
            &p.cancel,
        )?;
        let Some(rows) = rows else {
            return Ok(None);
        };
        let times =
            pics::acquisition_times(&rows).map_err(|m| engine::error::ConfigError::Invalid {
                path: site_path.clone(),
                key: "acquisitions.time_utc".into(),
                message: m.to_string(),
            })?;
        Ok(Some(crate::dataset::in_memory(|f| {
            pics::fill_netcdf(f, &site_path, &rows, &times)
        })))
    })?;
    let out: Result<_, engine::error::ConfigError> = out;
    let Some(raw) = out.map_err(config)? else {
        return Err(SimulationError::new_err("the sweep was cancelled"));
    };
    crate::dataset::to_py(py, &raw.map_err(simulation)?)
}

/// The rows of an acquisitions CSV (`docs/pics.md`), checked as `simulate pics` checks them:
/// `(time_utc, vza, vaa, srf, sza, saa)`.
#[pyfunction]
pub fn read_acquisitions(path: PathBuf) -> PyResult<Vec<Row>> {
    let acqs = pics::read_acquisitions(&path).map_err(config)?;
    Ok(acqs
        .into_iter()
        .map(|a| {
            let (sza, saa) = a.sun.map_or((None, None), |(z, s)| (Some(z), Some(s)));
            (a.time_utc, a.vza, a.vaa, a.srf, sza, saa)
        })
        .collect())
}
