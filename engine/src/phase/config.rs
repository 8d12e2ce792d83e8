//! Phase tables of the experiment file (`atmosphere.phase`, `atmosphere.layers[i].phase`): the
//! raw serde type, one variant per model, and its resolution into a [`PhaseFunction`] at a run
//! wavelength. Keys and units are documented in `docs/experiment.md`.

use std::sync::Arc;

use serde::Deserialize;

use super::{HenyeyGreenstein, PhaseFunction, Rayleigh, Tabulated};
use crate::error::{ConfigCtx, ConfigError};

#[derive(Clone, Debug, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum PhaseConfig {
    Rayleigh {
        #[serde(default)]
        depolarization: f64,
    },
    Hg {
        g: f64,
    },
    Isotropic {},
    Tabulated {
        file: String,
        /// nm; default: each run wavelength.
        #[serde(default)]
        wavelength: Option<f64>,
        #[serde(default)]
        size_index: usize,
    },
}

impl Default for PhaseConfig {
    fn default() -> Self {
        PhaseConfig::Rayleigh {
            depolarization: 0.0,
        }
    }
}

/// Resolves phase tables, reading each tabulated file once per (file, wavelength, size index)
/// and sharing the table between the layers and wavelengths that use it.
#[derive(Default)]
pub struct PhaseResolver {
    tables: Vec<(String, f64, usize, Arc<Tabulated>)>,
}

impl PhaseResolver {
    /// The phase function of `p` at the run wavelength `wavelength` (nm); `key` is the table's
    /// key path (e.g. `atmosphere.layers[2].phase`), completed with the offending key in errors.
    pub fn resolve(
        &mut self,
        ctx: &ConfigCtx,
        key: &str,
        p: &PhaseConfig,
        wavelength: f64,
    ) -> Result<PhaseFunction, ConfigError> {
        Ok(match p {
            PhaseConfig::Rayleigh { depolarization } => PhaseFunction::Rayleigh(
                Rayleigh::new(*depolarization)
                    .map_err(|m| ctx.err(format!("{key}.depolarization"), m.to_string()))?,
            ),
            PhaseConfig::Hg { g } => PhaseFunction::Hg(
                HenyeyGreenstein::new(*g)
                    .map_err(|m| ctx.err(format!("{key}.g"), m.to_string()))?,
            ),
            PhaseConfig::Isotropic {} => PhaseFunction::Hg(HenyeyGreenstein { g: 0.0 }),
            PhaseConfig::Tabulated {
                file,
                wavelength: pinned,
                size_index,
            } => {
                let wl = pinned.unwrap_or(wavelength);
                if let Some((_, _, _, t)) = self
                    .tables
                    .iter()
                    .find(|(f, w, s, _)| f == file && *w == wl && s == size_index)
                {
                    return Ok(PhaseFunction::Tabulated(t.clone()));
                }
                let fpath = ctx.file(file);
                if !fpath.exists() {
                    return Err(ctx.err(
                        format!("{key}.file"),
                        format!("file {} not found", fpath.display()),
                    ));
                }
                let t = Tabulated::load_libradtran(&fpath, wl, *size_index)
                    .map_err(|e| ctx.err(format!("{key}.file"), e.to_string()))?;
                let t = Arc::new(t);
                self.tables.push((file.clone(), wl, *size_index, t.clone()));
                PhaseFunction::Tabulated(t)
            }
        })
    }
}
