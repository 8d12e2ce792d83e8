//! Scene bundles: built from a region (TOML text) with `scenegen`, and opened for inspection
//! (the manifest as a dict, the `scenegen info` summary, sizes).

use std::path::PathBuf;

use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors::{config, simulation};

fn scenegen_err(e: scenegen::ScenegenError) -> PyErr {
    match e {
        scenegen::ScenegenError::Region { .. } | scenegen::ScenegenError::ReadRegion { .. } => {
            config(e)
        }
        e => simulation(e),
    }
}

/// Build the bundle of region `text` (`path` names it in errors and anchors its relative
/// paths) into `output`; `force` replaces an existing bundle. Returns the path and the stages'
/// durations (s).
#[pyfunction]
#[pyo3(signature = (text, path, output, force=false))]
pub fn build_bundle<'py>(
    py: Python<'py>,
    text: &str,
    path: PathBuf,
    output: PathBuf,
    force: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let region = scenegen::Region::from_str(text, &path).map_err(scenegen_err)?;
    let opts = scenegen::BuildOptions {
        force,
        progress: false,
    };
    let report = py
        .allow_threads(|| scenegen::build(&region, &output, &opts))
        .map_err(scenegen_err)?;
    let d = PyDict::new(py);
    d.set_item("path", output)?;
    let stages = PyDict::new(py);
    for (name, t) in &report.stages {
        stages.set_item(*name, t.as_secs_f64())?;
    }
    d.set_item("stages_s", stages)?;
    Ok(d)
}

/// The bundle in `path`: `{"manifest": dict, "summary": str, "disk_bytes": int,
/// "instanced_triangles": int, "flattened_triangles": float}` (files checked present).
#[pyfunction]
pub fn open_bundle<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let m = bundle::Bundle::read_manifest(&path).map_err(simulation)?;
    bundle::Bundle::check_present(&path, &m).map_err(simulation)?;
    let summary = scenegen::info::summary(&path).map_err(simulation)?;
    let value = toml::Value::try_from(&m).map_err(|e| {
        simulation(std::io::Error::other(format!(
            "manifest of {}: {e}",
            path.display()
        )))
    })?;
    let d = PyDict::new(py);
    d.set_item("manifest", crate::convert::from_toml(py, &value)?)?;
    d.set_item("summary", summary)?;
    let disk: u64 = m.provenance.files.iter().map(|f| f.bytes).sum();
    d.set_item("disk_bytes", disk)?;
    let tpl: u64 = m.templates.iter().map(|t| t.triangle_count).sum();
    d.set_item("instanced_triangles", m.terrain.triangle_count + tpl)?;
    let flat = m.terrain.triangle_count as f64
        + m.templates
            .iter()
            .map(|t| {
                t.triangle_count as f64
                    * m.instances
                        .per_template
                        .get(t.id as usize)
                        .copied()
                        .unwrap_or(0) as f64
            })
            .sum::<f64>();
    d.set_item("flattened_triangles", flat)?;
    Ok(d)
}
