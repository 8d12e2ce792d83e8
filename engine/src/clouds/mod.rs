//! Clouds in three dimensions: gridded fields of extinction, albedo and phase function, and the
//! estimators that track photons through them exactly.
//!
//! * [`grid`]: the field ([`grid::CloudGrid`]: columns on a regular x–y grid, cut on shared
//!   (stretched) levels or as one box per column; periodic or open laterally) and its exact
//!   tracking (optical depth and free-path sampling cell by cell, a 2D DDA over columns).
//! * [`columns`]: per-column fluxes (R, T, A) and radiances of a periodic field over a
//!   Lambertian surface, by forward photon tracing with local estimates: the I3RC outputs.
//! * [`config`]: `[[clouds]]` of the experiment file and its field placed in the scene's frame,
//!   which the backward scene walks cross (`integrator/geometry/scene_clouds.rs`); [`netcdf`]:
//!   the field's file format.
//! * [`cumulus`]: a generated field of fair-weather cumulus (`simulate cloud-field`).
//! * [`kit`]: the I3RC Phase 1 and IPRT phase B C2 input files (`shared/clouds`) read into
//!   grids.
//!
//! Units: metres, 1/m; directions are unit vectors of photon travel in the field's frame (x, y
//! horizontal, z up). Conventions of the outputs: `columns.rs`.
pub mod columns;
pub mod config;
pub mod cumulus;
pub mod grid;
pub mod kit;
pub mod netcdf;

pub use grid::{CloudGrid, GridError, Lateral, PerCell, Vertical};
