//! `eosim._native`: the Rust side of the Python package `eosim` (`python/eosim/`).
//!
//! Modules: [`convert`] (Python objects ↔ TOML values), [`dataset`] (a netCDF file written in
//! memory by the simulator's own writers, read back as plain arrays and attributes for
//! xarray), [`released`] (runs with the GIL released: progress, Ctrl-C, thread count),
//! [`experiment`] (experiments and runs), [`pics`] (PICS sweeps), [`bundles`] (scene bundles).
//! Every error crosses into Python as an exception (`ConfigError` for input that names a key
//! path, `SimulationError` for everything else); nothing panics across the boundary.

pub mod bundles;
pub mod convert;
pub mod dataset;
pub mod errors;
pub mod experiment;
pub mod pics;
pub mod released;

use pyo3::prelude::*;

/// The native module.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("ConfigError", py.get_type::<errors::ConfigError>())?;
    m.add("SimulationError", py.get_type::<errors::SimulationError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<experiment::Experiment>()?;
    m.add_function(wrap_pyfunction!(experiment::load_experiment, m)?)?;
    m.add_function(wrap_pyfunction!(convert::dict_to_toml, m)?)?;
    m.add_function(wrap_pyfunction!(convert::toml_to_dict, m)?)?;
    m.add_function(wrap_pyfunction!(pics::pics_sweep, m)?)?;
    m.add_function(wrap_pyfunction!(pics::read_acquisitions, m)?)?;
    m.add_function(wrap_pyfunction!(bundles::build_bundle, m)?)?;
    m.add_function(wrap_pyfunction!(bundles::open_bundle, m)?)?;
    Ok(())
}
