//! Measures: what a run records. Runtime types, built by the config resolver.
//!
//! * `Distant` (config `mdistant`): TOA radiance leaving the plane-parallel atmosphere in a list
//!   of directions, averaged over the horizontal plane. Directions point from the target towards
//!   the sensor.
//! * `Radiancemeter`: radiance arriving at a point along one direction (the instrument looks along
//!   `look`; the radiance travels along `−look`). The directly transmitted solar beam is a delta
//!   in direction and is not part of it.
//! * `DistantFlux`: upwelling hemispherical flux (radiosity) through a horizontal level, and the
//!   albedo = flux / (E0·cos SZA).

use glam::DVec3;

#[derive(Clone, Debug)]
pub struct Measure {
    pub id: String,
    /// Samples per direction (the maximum when `target_rel_stderr` is set).
    pub spp: u64,
    /// Stop once every direction's relative standard error is at most this (optional).
    pub target_rel_stderr: Option<f64>,
    pub kind: MeasureKind,
}

#[derive(Clone, Debug)]
pub enum MeasureKind {
    Distant {
        /// Unit vectors towards the sensor, `z > 0`.
        directions: Vec<DVec3>,
        /// View zenith and azimuth in degrees (azimuth clockwise from North), for the products.
        vza: Vec<f64>,
        vaa: Vec<f64>,
    },
    Radiancemeter {
        /// Position, m (x, y, altitude).
        origin: DVec3,
        /// Unit looking direction.
        look: DVec3,
        /// Azimuth (radians, clockwise from North) of the direction towards the sensor that fixes
        /// the Stokes meridian plane of a vertical view.
        frame_azimuth: f64,
    },
    DistantFlux {
        /// Altitude of the level, m.
        altitude: f64,
    },
}

impl Measure {
    /// Number of output cells (directions, or 1).
    pub fn cell_count(&self) -> usize {
        match &self.kind {
            MeasureKind::Distant { directions, .. } => directions.len(),
            _ => 1,
        }
    }

    pub fn type_name(&self) -> &'static str {
        match self.kind {
            MeasureKind::Distant { .. } => "mdistant",
            MeasureKind::Radiancemeter { .. } => "radiancemeter",
            MeasureKind::DistantFlux { .. } => "distant_flux",
        }
    }
}
