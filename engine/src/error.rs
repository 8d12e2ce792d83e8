//! The engine's error types. Each variant says what failed and where (file, key path).

use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("cannot read experiment file {}: {source}", path.display())]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    /// TOML syntax, unknown or missing key, wrong type; `message` names the key path.
    #[error("{}: {message}", path.display())]
    Parse { path: PathBuf, message: String },
    /// A value out of range or inconsistent.
    #[error("{}: `{key}`: {message}", path.display())]
    Invalid {
        path: PathBuf,
        key: String,
        message: String,
    },
}

/// What every part resolver of the experiment file (`bsdf/config.rs`, `phase/config.rs`, …)
/// needs to report an error and to read its inputs: the experiment file (named in errors), the
/// folder relative paths are taken from, and the run wavelengths (a spectral value expands to
/// one number per wavelength; empty, with `nw` 0, while `[spectral]` itself is resolved). It lives here, below every model module, so that the
/// models can resolve their own configuration without importing `config` back.
#[derive(Clone, Copy, Debug)]
pub struct ConfigCtx<'a> {
    pub path: &'a Path,
    pub base: &'a Path,
    pub nw: usize,
    /// nm; `nw` of them once `[spectral]` is resolved.
    pub wavelengths: &'a [f64],
}

impl ConfigCtx<'_> {
    /// An invalid value at `key` (the full key path, e.g. `atmosphere.layers[1].tau_sca`).
    pub fn err(&self, key: impl Into<String>, message: impl Into<String>) -> ConfigError {
        ConfigError::Invalid {
            path: self.path.to_path_buf(),
            key: key.into(),
            message: message.into(),
        }
    }

    /// `x` if it is finite, else an error naming `key`.
    pub fn finite(&self, key: &str, x: f64) -> Result<f64, ConfigError> {
        if x.is_finite() {
            Ok(x)
        } else {
            Err(self.err(key, format!("{x} is not a finite number")))
        }
    }

    /// A path of the experiment file, relative to its folder (absolute paths stay as they are).
    pub fn file(&self, relative: impl AsRef<Path>) -> PathBuf {
        self.base.join(relative)
    }
}
