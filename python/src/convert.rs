//! Python objects ↔ TOML values: an experiment, site or region given as a dict is written as
//! TOML text and parsed by the same code as a file, so its errors name the same key paths.

use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};

/// The TOML value of a Python object; `key` is its key path, named in errors. `None` values
/// of a dict are left out (an absent key).
pub fn to_toml(obj: &Bound<'_, PyAny>, key: &str) -> PyResult<toml::Value> {
    if obj.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(obj.extract()?));
    }
    if obj.is_instance_of::<PyInt>() {
        return obj.extract::<i64>().map(toml::Value::Integer).map_err(|_| {
            PyTypeError::new_err(format!("`{key}`: integer out of the 64-bit range"))
        });
    }
    if obj.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(obj.extract()?));
    }
    if obj.is_instance_of::<PyString>() {
        return Ok(toml::Value::String(obj.extract()?));
    }
    if let Ok(d) = obj.downcast::<PyDict>() {
        let mut t = toml::Table::new();
        for (k, v) in d.iter() {
            let k: String = k.extract().map_err(|_| {
                PyTypeError::new_err(format!(
                    "`{key}`: dictionary keys must be strings, found {}",
                    k.repr().map(|r| r.to_string()).unwrap_or_default()
                ))
            })?;
            if v.is_none() {
                continue;
            }
            let sub = if key.is_empty() {
                k.clone()
            } else {
                format!("{key}.{k}")
            };
            t.insert(k, to_toml(&v, &sub)?);
        }
        return Ok(toml::Value::Table(t));
    }
    if obj.is_instance_of::<PyList>() || obj.is_instance_of::<PyTuple>() {
        let mut a = Vec::new();
        for (i, v) in obj.try_iter()?.enumerate() {
            a.push(to_toml(&v?, &format!("{key}[{i}]"))?);
        }
        return Ok(toml::Value::Array(a));
    }
    // numpy scalars and arrays, pathlib paths.
    if obj.hasattr("tolist")? {
        return to_toml(&obj.call_method0("tolist")?, key);
    }
    if obj.hasattr("__fspath__")? {
        return Ok(toml::Value::String(
            obj.call_method0("__fspath__")?.extract()?,
        ));
    }
    Err(PyTypeError::new_err(format!(
        "`{key}`: a {} has no TOML value (use numbers, strings, booleans, lists and dicts)",
        obj.get_type().name()?
    )))
}

/// A TOML value as a Python object (tables as dicts, dates as strings).
pub fn from_toml<'py>(py: Python<'py>, v: &toml::Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match v {
        toml::Value::String(s) => s.into_pyobject(py)?.into_any(),
        toml::Value::Integer(i) => i.into_pyobject(py)?.into_any(),
        toml::Value::Float(f) => f.into_pyobject(py)?.into_any(),
        toml::Value::Boolean(b) => b.into_pyobject(py)?.to_owned().into_any(),
        toml::Value::Datetime(d) => d.to_string().into_pyobject(py)?.into_any(),
        toml::Value::Array(a) => {
            let l = PyList::empty(py);
            for x in a {
                l.append(from_toml(py, x)?)?;
            }
            l.into_any()
        }
        toml::Value::Table(t) => {
            let d = PyDict::new(py);
            for (k, x) in t {
                d.set_item(k, from_toml(py, x)?)?;
            }
            d.into_any()
        }
    })
}

/// The TOML text of a dict (top-level keys of an experiment, site or region file).
#[pyfunction]
pub fn dict_to_toml(obj: &Bound<'_, PyAny>) -> PyResult<String> {
    match to_toml(obj, "")? {
        toml::Value::Table(t) => {
            toml::to_string(&t).map_err(|e| PyTypeError::new_err(format!("cannot write TOML: {e}")))
        }
        _ => Err(PyTypeError::new_err(
            "expected a dict of top-level keys (as in the TOML file)",
        )),
    }
}

/// A TOML text as a dict; `name` (a file name, or `<string>`) is named in syntax errors.
#[pyfunction]
pub fn toml_to_dict<'py>(py: Python<'py>, text: &str, name: &str) -> PyResult<Bound<'py, PyAny>> {
    let t: toml::Table = text
        .parse()
        .map_err(|e: toml::de::Error| crate::errors::config(format!("{name}: {e}")))?;
    from_toml(py, &toml::Value::Table(t))
}
