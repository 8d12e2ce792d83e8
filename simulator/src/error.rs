//! Library error types. Each variant says what failed and where (file, key path).

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
/// folder relative paths are taken from, and the number of run wavelengths (a spectral value
/// expands to one number per wavelength). It lives here, below every model module, so that the
/// models can resolve their own configuration without importing `config` back.
#[derive(Clone, Copy, Debug)]
pub struct ConfigCtx<'a> {
    pub path: &'a Path,
    pub base: &'a Path,
    pub nw: usize,
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

#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("cannot write {}: {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("cannot write netCDF file {}: {source}", path.display())]
    Netcdf {
        path: PathBuf,
        source: netcdf::Error,
    },
    /// A GDAL call failed while building a GeoTIFF product (`path` is the product's final name).
    #[error("cannot write GeoTIFF {}: {what}: {source}", path.display())]
    Gdal {
        path: PathBuf,
        what: String,
        source: gdal::errors::GdalError,
    },
    /// Another `simulate run` holds the output folder's lock.
    #[error("another simulate run is writing into {} (its lock {} is held); wait for it to finish or choose another output folder", dir.display(), lock.display())]
    Busy { dir: PathBuf, lock: PathBuf },
    /// PNG encoding failed (`path` is the product's final name).
    #[error("cannot write PNG {}: {source}", path.display())]
    Image {
        path: PathBuf,
        source: image::ImageError,
    },
}
