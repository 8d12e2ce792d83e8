//! The application's error types: products, checkpoints and output folders. Each variant
//! says what failed and where (the file). Configuration errors are the engine's
//! ([`engine::error::ConfigError`]).

use std::path::PathBuf;

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
    /// A checkpoint (or a shard's) of this run whose sums were edited or damaged
    /// (`run/checkpoint.rs`, "Integrity").
    #[error("checkpoint {} belongs to this run but {problem}: it was edited or damaged; delete it (or run with --fresh) to compute its samples again", path.display())]
    Checkpoint { path: PathBuf, problem: String },
    /// PNG encoding failed (`path` is the product's final name).
    #[error("cannot write PNG {}: {source}", path.display())]
    Image {
        path: PathBuf,
        source: image::ImageError,
    },
}
