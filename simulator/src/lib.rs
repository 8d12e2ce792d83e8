//! `simulator`: the application around the engine (`engine`): it schedules a run's blocks
//! (rounds, checkpoints, merging; `run.rs`), writes the products (netCDF, GeoTIFF, PNG, CSV;
//! `products/`), plans and merges cluster runs (`cluster/`), runs calibration-site sweeps
//! (`pics/`), benchmarks (`bench*.rs`) and previews (`preview.rs`), and holds the `simulate`
//! binary. It is the one writer of products, used by the command line and the Python package.
//!
//! ```text
//! Experiment (engine::config) ─► run (schedule, checkpoints) ─► engine::blocks (one block of
//! samples: sums) ─► MeasureResult ─► products (BRF, Stokes, standard errors) ─► CSV, netCDF,
//! GeoTIFF, PNG
//! ```

/// This build's identity: the crate version and a digest of the application's, the engine's
/// and the bundle crate's sources, the data compiled in (`simulator/data`, `engine/data`) and
/// the dependency versions (`Cargo.lock`) (`simulator/build.rs`), e.g. `0.1.0+src.1f3a…`.
/// Checkpoints and cluster plans are stamped with it, so a rebuilt simulator whose estimators,
/// scheduling, tables or libraries changed while the crate version did not never resumes or
/// merges another build's partial sums.
pub const BUILD_ID: &str = env!("SIMULATOR_BUILD_ID");

pub mod bench;
pub mod cloud_field;
pub mod cluster;
pub mod error;
pub mod heavy_tail;
pub mod lidar;
pub mod pics;
pub mod preview;
pub mod products;
pub mod run;
pub mod temperatures;
