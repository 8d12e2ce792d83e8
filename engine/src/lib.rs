//! `engine`: the Monte Carlo radiative-transfer engine for Earth-observation scenes.
//!
//! Data flow inside one run:
//!
//! ```text
//! experiment.toml ─► config (serde, raw) ─► resolve() ─► Experiment (validated runtime types)
//!                                                         │
//!     per wavelength: OpticalState (atmosphere, shells, surface BRDF, scene materials)
//!                                                         │
//!   blocks (the estimator, geometry and weight chosen once per block) ─► sensor (start rays)
//!   ─► integrator (the transport core: forward and backward estimators, generic over weight
//!   and geometry) ─► Accum (sums, sums of squares per cell)
//! ```
//!
//! What runs the blocks (scheduling, checkpoints, merging) and what turns the sums into
//! products (netCDF, GeoTIFF, PNG, CSV) is the application crate's (`simulator`): this crate
//! has no command line, progress bar or product writer (`engine/README.md`).
//!
//! Units and conventions are written once in `docs/conventions.md`: SI inside except where a
//! name says otherwise, wavelengths in nm, angles in degrees in config files and radians inside,
//! BRF = π·L/(E0·cos SZA) with E0 the solar irradiance normal to the beam.

/// The engine build's identity: the crate version and a digest of the engine's and the bundle
/// crate's sources, the data compiled in (`engine/data`) and the dependency versions
/// (`Cargo.lock`) (`engine/build_id.rs`), e.g. `0.1.0+src.1f3a…`. BVH cache files are stamped
/// with it; checkpoints and cluster plans with the application's `simulator::BUILD_ID`, which
/// covers the engine too.
pub const BUILD_ID: &str = env!("ENGINE_BUILD_ID");

pub mod absorption;
pub mod accum;
pub mod atmosphere;
pub mod blocks;
pub mod bsdf;
pub mod clouds;
/// The scene-bundle format, its own crate (`bundle/`); re-exported so that `engine::bundle::…`
/// and `crate::bundle::…` name it.
pub use bundle;
pub mod config;
pub mod error;
pub mod frame;
pub mod integrator;
pub mod lidar;
pub mod measure;
pub mod optics;
pub mod phase;
pub mod rng;
pub mod scene;
pub mod sensor;
pub mod sources;
pub mod spectral;
pub mod stokes;
pub mod temperature;
pub mod util;

/// Hold the netCDF library for a whole file session (open, reads, close). The netcdf crate
/// locks each call, but parallel tests that opened and read files concurrently still crashed
/// inside HDF5 (SIGSEGV, NC_EHDFERR); every reader and writer here takes this guard for its
/// whole session. It is the crate's own reentrant lock, so nested readers and the crate's
/// per-call locking inside a session are fine.
pub fn netcdf_session() -> impl Drop {
    netcdf_sys::libnetcdf_lock.lock()
}
