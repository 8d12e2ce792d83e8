//! `simulator`: a Monte Carlo radiative-transfer engine for Earth-observation scenes.
//!
//! Data flow inside one run:
//!
//! ```text
//! experiment.toml ─► config (serde, raw) ─► resolve() ─► Experiment (validated runtime types)
//!                                                         │
//!     per wavelength: OpticalState (atmosphere, shells, surface BRDF, scene materials)
//!                                                         │
//!   run (schedule, checkpoints) ─► sensor (start rays) ─► integrator (the transport core:
//!   forward and backward estimators, generic over weight and geometry) ─► Accum (sums,
//!   sums of squares per cell)
//!                                                         │
//!               products (BRF, Stokes, standard errors) ─► CSV, netCDF, GeoTIFF, PNG
//! ```
//!
//! Units and conventions are written once in `docs/conventions.md`: SI inside except where a
//! name says otherwise, wavelengths in nm, angles in degrees in config files and radians inside,
//! BRF = π·L/(E0·cos SZA) with E0 the solar irradiance normal to the beam.

/// This build's identity: the crate version and a digest of the simulator's and the bundle
/// crate's sources, the data compiled in (`simulator/data`) and the dependency versions
/// (`Cargo.lock`) (`simulator/build.rs`), e.g. `0.1.0+src.1f3a…`. Checkpoints, cluster plans
/// and BVH cache files are stamped with it, so a rebuilt simulator whose estimators, tables or
/// libraries changed while the crate version did not never resumes or merges another build's
/// partial sums, nor reads its trees.
pub const BUILD_ID: &str = env!("SIMULATOR_BUILD_ID");

pub mod absorption;
pub mod accum;
pub mod atmosphere;
pub mod bench;
pub mod bench_polarized;
pub mod bench_scene;
pub mod bsdf;
pub mod cluster;
/// The scene-bundle format, now its own crate (`bundle/`); re-exported so that
/// `simulator::bundle::…` and `crate::bundle::…` keep working.
pub use bundle;
pub mod config;
pub mod cpu_time;
pub mod direct_flux;
pub mod error;
pub mod file_cache;
pub mod frame;
pub mod heavy_tail;
pub mod illumination;
pub mod input_digest;
pub mod integrator;
pub mod measure;
pub mod moon;
pub mod nc_complete;
pub mod optics;
pub mod output_lock;
pub mod phase;
pub mod pics;
pub mod pics_catalogue;
pub mod planck;
pub mod preview;
pub mod products;
pub mod rng;
pub mod run;
pub mod scene;
pub mod sensor;
pub mod solar;
pub mod spectral;
pub mod srf;
pub mod stokes;
pub mod sun_position;

/// Hold the netCDF library for a whole file session (open, reads, close). The netcdf crate
/// locks each call, but parallel tests that opened and read files concurrently still crashed
/// inside HDF5 (SIGSEGV, NC_EHDFERR); every reader and writer here takes this guard for its
/// whole session. It is the crate's own reentrant lock, so nested readers and the crate's
/// per-call locking inside a session are fine.
pub fn netcdf_session() -> impl Drop {
    netcdf_sys::libnetcdf_lock.lock()
}
