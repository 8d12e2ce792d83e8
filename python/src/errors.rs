//! The package's exceptions and the conversion of the crates' errors into them. The Python
//! layer (`eosim/_errors.py`) replaces the one-line docstrings below with full numpydoc ones.

use pyo3::create_exception;
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::PyErr;

create_exception!(
    eosim,
    ConfigError,
    PyValueError,
    "An invalid experiment, site, region or acquisition: the message names the file (or \
     `<dict>`/`<string>`) and the key path, as the command-line tools do."
);
create_exception!(
    eosim,
    SimulationError,
    PyRuntimeError,
    "A failure while running or writing (an output folder, a netCDF file, a bundle)."
);

/// A configuration error (its `Display` names the file and the key path).
pub fn config(e: impl std::fmt::Display) -> PyErr {
    ConfigError::new_err(e.to_string())
}

/// Any other error, with its chain of causes.
pub fn simulation(e: impl std::error::Error) -> PyErr {
    let mut msg = e.to_string();
    let mut src = e.source();
    while let Some(s) = src {
        let t = s.to_string();
        if !msg.contains(&t) {
            msg.push_str(": ");
            msg.push_str(&t);
        }
        src = s.source();
    }
    SimulationError::new_err(msg)
}
