//! Library error types. Each variant says what failed and where (file, key path).

use std::path::PathBuf;

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
    /// PNG encoding failed (`path` is the product's final name).
    #[error("cannot write PNG {}: {source}", path.display())]
    Image {
        path: PathBuf,
        source: image::ImageError,
    },
}
