//! Experiments: loaded from TOML text (a file's, a string's or a dict's), run with the GIL
//! released, returned as the contents of `results.nc` (built in memory) and, when asked,
//! written as the command line writes them.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use engine::config::resolve::Experiment as Exp;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use simulator::products;

use crate::errors::{config, simulation, SimulationError};

/// A validated experiment (see `eosim.Experiment`).
#[pyclass(frozen, module = "eosim._native")]
pub struct Experiment {
    pub exp: Arc<Exp>,
}

/// Parse and validate experiment `text`; `path` names it in errors and anchors its relative
/// paths; `spp` replaces every measure's `spp` (as `simulate run --spp`).
#[pyfunction]
#[pyo3(signature = (text, path, spp=None))]
pub fn load_experiment(
    py: Python<'_>,
    text: &str,
    path: PathBuf,
    spp: Option<u64>,
) -> PyResult<Experiment> {
    let exp = py
        .allow_threads(|| Exp::parse_with_spp(text, &path, spp))
        .map_err(config)?;
    Ok(Experiment { exp: Arc::new(exp) })
}

/// Write the command line's products of a run into `output` (`simulator::products::write_all`:
/// staged, all or nothing), creating the folder first.
fn write_products(
    output: &Path,
    exp: &Exp,
    rows: &[products::Row],
    band: &[products::BandRow],
    images: &[products::imagery::ImageProduct],
    lidars: &[engine::lidar::LidarResult],
) -> Result<Vec<PathBuf>, simulator::error::OutputError> {
    std::fs::create_dir_all(output).map_err(|source| simulator::error::OutputError::Io {
        path: output.to_path_buf(),
        source,
    })?;
    products::write_all(output, exp, rows, band, images, lidars)
        .map(|w| w.files)
        .map_err(|e| *e.error)
}

#[pymethods]
impl Experiment {
    /// Run the experiment. `progress`: a callable `(walks_done, walks_total)` or None;
    /// `threads`: worker threads (None: all cores); `output`: a folder to write the command
    /// line's products into (results.nc, results.csv, GeoTIFFs, PNG), or None to write nothing.
    /// Returns the contents of `results.nc` (decoded into an xarray.Dataset by `eosim`).
    #[pyo3(signature = (progress=None, threads=None, output=None))]
    fn run<'py>(
        &self,
        py: Python<'py>,
        progress: Option<&Bound<'py, PyAny>>,
        threads: Option<usize>,
        output: Option<PathBuf>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let exp = &*self.exp;
        let total = simulator::run::progress_bar(exp, false)
            .length()
            .unwrap_or(0);
        let out = crate::released::run(py, progress, threads, total, |p| {
            let results = simulator::run::run_cancellable(exp, &p.bar, &p.cancel)?;
            let rows = products::rows(exp, &results);
            let band = products::band_rows(exp, &rows);
            let images = products::imagery::image_products(exp, &results);
            // Lidar measures are traced after the passive ones, as the command line does.
            let lidars = simulator::lidar::run_all(exp, false);
            let written = output
                .as_deref()
                .map(|o| write_products(o, exp, &rows, &band, &images, &lidars))
                .transpose();
            let raw = crate::dataset::in_memory(|f| {
                products::netcdf::fill(f, exp, &rows, &band, &images)?;
                products::netcdf::lidar::fill(f, &lidars)
            });
            Some((written, raw))
        })?;
        let Some((written, raw)) = out else {
            return Err(SimulationError::new_err("the run was cancelled"));
        };
        written.map_err(simulation)?;
        let raw = raw.map_err(simulation)?;
        crate::dataset::to_py(py, &raw)
    }

    /// The run's wavelengths, nm.
    #[getter]
    fn wavelengths(&self) -> Vec<f64> {
        self.exp.wavelengths.clone()
    }

    /// The measures' ids, in order (passive measures, then lidars).
    #[getter]
    fn measures(&self) -> Vec<String> {
        let passive = self.exp.measures.iter().map(|m| m.id.clone());
        passive
            .chain(self.exp.lidars.iter().map(|l| l.id.clone()))
            .collect()
    }

    #[getter]
    fn seed(&self) -> u64 {
        self.exp.seed
    }

    /// The experiment's TOML text.
    #[getter]
    fn text(&self) -> String {
        self.exp.source_text.clone()
    }

    /// The file (or `<dict>`, `<string>`) the experiment came from.
    #[getter]
    fn path(&self) -> PathBuf {
        self.exp.source_path.clone()
    }

    /// Memory the run needs, bytes: `{"results": …, "scene": …, "total": …}`.
    fn memory<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let m = engine::config::memory::estimate(&self.exp);
        let d = PyDict::new(py);
        d.set_item("results", m.results_bytes)?;
        d.set_item("scene", m.scene_bytes)?;
        d.set_item("total", m.total())?;
        Ok(d)
    }
}
