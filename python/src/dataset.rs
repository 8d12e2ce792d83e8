//! A netCDF file written **in memory** (netCDF-4, diskless, never persisted) by the simulator's
//! own writers (`products::netcdf::fill`, `pics::fill_netcdf`) and read back as plain arrays and
//! attributes: the Python layer builds an `xarray.Dataset` from them and decodes it as
//! `xarray.open_dataset` decodes the file on disk, so both hold the same variables,
//! coordinates, units and attributes by construction.

use std::sync::atomic::{AtomicU64, Ordering};

use netcdf::types::{FloatType, IntType, NcVariableType};
use netcdf::AttributeValue;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList, PyTuple};

/// An attribute's value.
pub enum Attr {
    Str(String),
    Strs(Vec<String>),
    /// Numbers: numpy dtype, native-endian bytes, whether a single value.
    Num {
        dtype: &'static str,
        bytes: Vec<u8>,
        scalar: bool,
    },
}

/// A variable's values.
pub enum Data {
    Num { dtype: &'static str, bytes: Vec<u8> },
    Strs(Vec<String>),
}

pub struct Var {
    pub name: String,
    pub dims: Vec<String>,
    pub shape: Vec<usize>,
    pub data: Data,
    pub attrs: Vec<(String, Attr)>,
}

/// A whole file: global attributes and variables (dimensions without a variable are implied by
/// the variables' dimension names and shapes).
pub struct Raw {
    pub attrs: Vec<(String, Attr)>,
    pub vars: Vec<Var>,
}

fn bytes_of<T: Copy>(v: &[T]) -> Vec<u8> {
    // Safety: plain numbers (no padding), read as bytes.
    let n = std::mem::size_of_val(v);
    unsafe { std::slice::from_raw_parts(v.as_ptr().cast::<u8>(), n) }.to_vec()
}

fn num<T: Copy>(dtype: &'static str, v: &[T], scalar: bool) -> Attr {
    Attr::Num {
        dtype,
        bytes: bytes_of(v),
        scalar,
    }
}

fn attr(v: AttributeValue) -> Attr {
    use AttributeValue as A;
    match v {
        A::Str(s) => Attr::Str(s),
        A::Strs(s) => Attr::Strs(s),
        A::Uchar(x) => num("=u1", &[x], true),
        A::Uchars(x) => num("=u1", &x, false),
        A::Schar(x) => num("=i1", &[x], true),
        A::Schars(x) => num("=i1", &x, false),
        A::Ushort(x) => num("=u2", &[x], true),
        A::Ushorts(x) => num("=u2", &x, false),
        A::Short(x) => num("=i2", &[x], true),
        A::Shorts(x) => num("=i2", &x, false),
        A::Uint(x) => num("=u4", &[x], true),
        A::Uints(x) => num("=u4", &x, false),
        A::Int(x) => num("=i4", &[x], true),
        A::Ints(x) => num("=i4", &x, false),
        A::Ulonglong(x) => num("=u8", &[x], true),
        A::Ulonglongs(x) => num("=u8", &x, false),
        A::Longlong(x) => num("=i8", &[x], true),
        A::Longlongs(x) => num("=i8", &x, false),
        A::Float(x) => num("=f4", &[x], true),
        A::Floats(x) => num("=f4", &x, false),
        A::Double(x) => num("=f8", &[x], true),
        A::Doubles(x) => num("=f8", &x, false),
    }
}

fn dtype(t: &NcVariableType) -> Option<&'static str> {
    Some(match t {
        NcVariableType::Int(IntType::U8) => "=u1",
        NcVariableType::Int(IntType::I8) => "=i1",
        NcVariableType::Int(IntType::U16) => "=u2",
        NcVariableType::Int(IntType::I16) => "=i2",
        NcVariableType::Int(IntType::U32) => "=u4",
        NcVariableType::Int(IntType::I32) => "=i4",
        NcVariableType::Int(IntType::U64) => "=u8",
        NcVariableType::Int(IntType::I64) => "=i8",
        NcVariableType::Float(FloatType::F32) => "=f4",
        NcVariableType::Float(FloatType::F64) => "=f8",
        _ => return None,
    })
}

fn attrs<'a>(
    it: impl Iterator<Item = netcdf::Attribute<'a>>,
) -> netcdf::Result<Vec<(String, Attr)>> {
    it.map(|a| Ok((a.name().to_string(), attr(a.value()?))))
        .collect()
}

fn read(f: &netcdf::File) -> netcdf::Result<Raw> {
    let mut vars = Vec::new();
    for v in f.variables() {
        let dims: Vec<String> = v.dimensions().iter().map(|d| d.name()).collect();
        let shape: Vec<usize> = v.dimensions().iter().map(|d| d.len()).collect();
        let t = v.vartype();
        let data = match (&t, dtype(&t)) {
            (NcVariableType::String, _) => {
                let n: usize = shape.iter().product();
                let mut s = Vec::with_capacity(n);
                for i in 0..n {
                    // Strings are 0- or 1-dimensional in the simulator's files.
                    s.push(if shape.is_empty() {
                        v.get_string(..)?
                    } else {
                        v.get_string([i])?
                    });
                }
                Data::Strs(s)
            }
            (_, Some(dt)) => Data::Num {
                dtype: dt,
                bytes: v.get_raw_values(..)?,
            },
            _ => {
                return Err(netcdf::Error::Str(format!(
                    "variable {}: type {t:?} is not supported by the Python package",
                    v.name()
                )))
            }
        };
        vars.push(Var {
            name: v.name(),
            dims,
            shape,
            data,
            attrs: attrs(v.attributes())?,
        });
    }
    Ok(Raw {
        attrs: attrs(f.attributes())?,
        vars,
    })
}

/// Create a diskless netCDF-4 file, let `fill` write it, and read it back.
pub fn in_memory(
    fill: impl FnOnce(&mut netcdf::FileMut) -> netcdf::Result<()>,
) -> netcdf::Result<Raw> {
    static COUNT: AtomicU64 = AtomicU64::new(0);
    let _session = engine::netcdf_session();
    // The name is never created on disk (diskless, not persisted); unique all the same.
    let name = std::env::temp_dir().join(format!(
        "eosim-in-memory-{}-{}.nc",
        std::process::id(),
        COUNT.fetch_add(1, Ordering::Relaxed)
    ));
    let mut f = netcdf::create_with(&name, netcdf::Options::NETCDF4 | netcdf::Options::DISKLESS)?;
    fill(&mut f)?;
    read(&f)
}

fn attr_py<'py>(py: Python<'py>, a: &Attr) -> PyResult<Bound<'py, PyAny>> {
    Ok(match a {
        Attr::Str(s) => s.into_pyobject(py)?.into_any(),
        Attr::Strs(s) => PyList::new(py, s)?.into_any(),
        Attr::Num {
            dtype,
            bytes,
            scalar,
        } => PyTuple::new(
            py,
            [
                "__num__".into_pyobject(py)?.into_any(),
                dtype.into_pyobject(py)?.into_any(),
                PyBytes::new(py, bytes).into_any(),
                scalar.into_pyobject(py)?.to_owned().into_any(),
            ],
        )?
        .into_any(),
    })
}

fn attrs_py<'py>(py: Python<'py>, a: &[(String, Attr)]) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (k, v) in a {
        d.set_item(k, attr_py(py, v)?)?;
    }
    Ok(d)
}

/// `{"attrs": {...}, "variables": [(name, dims, shape, dtype, data, attrs), ...]}`: numeric
/// data as bytes with a numpy dtype, strings as a list; numeric attributes as
/// `("__num__", dtype, bytes, scalar)` (decoded by `eosim._dataset`).
pub fn to_py<'py>(py: Python<'py>, raw: &Raw) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    out.set_item("attrs", attrs_py(py, &raw.attrs)?)?;
    let vars = PyList::empty(py);
    for v in &raw.vars {
        let (dt, data): (&str, Bound<'py, PyAny>) = match &v.data {
            Data::Num { dtype, bytes } => (dtype, PyBytes::new(py, bytes).into_any()),
            Data::Strs(s) => ("str", PyList::new(py, s)?.into_any()),
        };
        vars.append((
            &v.name,
            PyTuple::new(py, &v.dims)?,
            PyTuple::new(py, &v.shape)?,
            dt,
            data,
            attrs_py(py, &v.attrs)?,
        ))?;
    }
    out.set_item("variables", vars)?;
    Ok(out)
}
