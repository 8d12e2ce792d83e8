//! Measures: what a run records. Runtime types, built by the config resolver.
//!
//! * `Distant` (config `mdistant`): TOA radiance leaving the plane-parallel atmosphere in a list
//!   of directions, averaged over the horizontal plane. Directions point from the target towards
//!   the sensor.
//! * `Radiancemeter`: radiance arriving at a point along one direction (the instrument looks along
//!   `look`; the radiance travels along `−look`). The directly transmitted solar beam is a delta
//!   in direction and is not part of it.
//! * `DistantFlux`: hemispherical flux through a horizontal level, upwelling (radiosity) or
//!   downwelling (irradiance), and the same divided by E0·cos SZA (`albedo`). Downwelling flux
//!   is the attenuated solar beam (direct, exact: [`crate::measure::direct_flux`]) plus the scattered
//!   (diffuse) light, which is what the walks estimate.
//! * `Hdrf`: the hemispherical–directional reflectance factor at a level (the surface by
//!   default): upwelling radiance at the level in a list of directions over the downwelling
//!   flux there, `HDRF = π·L↑(v)/E↓` (Schaepman-Strub et al. 2006, *Remote Sens. Environ.*
//!   103, 27–42, case 8), each cell a radiance and one more cell the diffuse downwelling flux.
//! * `Ortho` (3D scenes): an image on a north-up grid, each pixel the mean radiance leaving
//!   the terrain within the pixel towards one direction (parallel projection onto the terrain:
//!   orthorectified).
//! * `Perspective` (3D scenes): a pinhole camera; each pixel the mean radiance arriving through
//!   it.
//! * In 3D scenes, `Distant` measures the radiance leaving a horizontal target rectangle,
//!   averaged over it (RAMI's area BRF).
//!
//! The experiment file's `[[measures]]` tables are resolved into these types in `config.rs`.

pub mod config;
pub mod direct_flux;

use glam::DVec3;

/// Samples per block (the unit of parallel work and of deterministic merging).
pub const BLOCK: u64 = 2048;
/// Samples per block of image measures (ortho, perspective): their cells are pixels, each
/// needing far fewer samples than a direction of a distant measure. A block is also the
/// smallest step of a target-precision round (the application's `run.rs`): 32 rather than 64 lets the README
/// render stop at 288 samples per pixel instead of 320 (BENCHMARKS.md, 2026-11-27); it stays a
/// multiple of the Sobol replicates ([`REPLICATES`](crate::accum::REPLICATES)).
pub const IMAGE_BLOCK: u64 = 32;

#[derive(Clone, Debug)]
pub struct Measure {
    pub id: String,
    /// Samples per direction (the maximum when `target_rel_stderr` is set).
    pub spp: u64,
    /// Stop once every direction's relative standard error is at most this (optional; with
    /// per-output targets, the tightest of them).
    pub target_rel_stderr: Option<f64>,
    /// Per-output targets (`target_rel_stderr` given as a list, one per wavelength or band):
    /// each output's target over the tightest (≥ 1); empty when one target serves all.
    pub target_scale: Vec<f64>,
    /// Images: the fraction of pixels that must meet `target_rel_stderr` (0.5: the median
    /// pixel; 1: every pixel); other measures: every cell must (the value is not used).
    pub target_fraction: f64,
    /// Images with a target: after the first round only the pixels above the target are
    /// sampled (the application's `run.rs`); false: every pixel gets every round's samples.
    pub adaptive: bool,
    pub kind: MeasureKind,
    /// Samples per block when not the default (CKD image measures: [`IMAGE_BLOCK`] over the
    /// g-point count, so that a cycle of g-points stays IMAGE_BLOCK samples per pixel).
    pub block_override: Option<u64>,
}

#[derive(Clone, Debug)]
pub enum MeasureKind {
    Distant {
        /// Unit vectors towards the sensor, `z > 0`.
        directions: Vec<DVec3>,
        /// View zenith and azimuth in degrees (azimuth clockwise from North), for the products.
        vza: Vec<f64>,
        vaa: Vec<f64>,
        /// 3D scenes: the target rectangle and its height.
        area: Option<Area>,
    },
    Ortho(OrthoGrid),
    Perspective(Camera),
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
        /// Upwelling or downwelling.
        direction: FluxDirection,
    },
    /// Cells `0..n`: upwelling radiance at the level towards `directions[k]`; cell `n`: the
    /// diffuse downwelling flux there (the direct part is exact, `direct_flux.rs`).
    Hdrf {
        /// Unit vectors towards the sensor, `z > 0`.
        directions: Vec<DVec3>,
        /// degrees (azimuth clockwise from North), for the products.
        vza: Vec<f64>,
        vaa: Vec<f64>,
        /// Altitude of the level, m.
        altitude: f64,
    },
}

/// Which hemisphere a flux measure integrates: the light travelling up or down.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FluxDirection {
    Up,
    Down,
}

impl FluxDirection {
    pub fn name(self) -> &'static str {
        match self {
            FluxDirection::Up => "up",
            FluxDirection::Down => "down",
        }
    }
}

/// A horizontal rectangle in the scene's local frame, m, masked by the bundle's area polygon
/// when it has one (the target is then the rectangle's part inside the polygon).
#[derive(Clone, Debug)]
pub struct Area {
    /// [xmin, ymin, xmax, ymax].
    pub rect: [f64; 4],
    pub height: f64,
    pub mask: Option<std::sync::Arc<crate::scene::area_mask::AreaMask>>,
}

/// A north-up image grid with its view direction.
#[derive(Clone, Debug)]
pub struct OrthoGrid {
    pub width: usize,
    pub height: usize,
    /// GDAL geotransform in the scene's **local** frame (pixel corners, row 0 at the north).
    pub geotransform: [f64; 6],
    /// Unit vector towards the sensor.
    pub view: DVec3,
    /// degrees.
    pub vza: f64,
    pub vaa: f64,
}

/// A pinhole camera: pixel (col, row) looks along `forward + x·right − y·up` with
/// `x = (2(col+½)/width − 1)·tan_x`, `y = (2(row+½)/height − 1)·tan_y`.
#[derive(Clone, Debug)]
pub struct Camera {
    pub origin: DVec3,
    pub forward: DVec3,
    pub right: DVec3,
    pub up: DVec3,
    pub tan_x: f64,
    pub tan_y: f64,
    pub width: usize,
    pub height: usize,
}

impl Measure {
    /// Whether the cells form an image (the stopping rule then uses the median error).
    pub fn is_image(&self) -> bool {
        matches!(
            self.kind,
            MeasureKind::Ortho(_) | MeasureKind::Perspective(_)
        )
    }

    /// Number of simulated cells (directions, or 1; an HDRF's directions and its flux).
    pub fn cell_count(&self) -> usize {
        match &self.kind {
            MeasureKind::Distant { directions, .. } => directions.len(),
            MeasureKind::Hdrf { directions, .. } => directions.len() + 1,
            MeasureKind::Ortho(g) => g.width * g.height,
            MeasureKind::Perspective(c) => c.width * c.height,
            MeasureKind::Radiancemeter { .. } | MeasureKind::DistantFlux { .. } => 1,
        }
    }

    pub fn type_name(&self) -> &'static str {
        match self.kind {
            MeasureKind::Distant { .. } => "mdistant",
            MeasureKind::Radiancemeter { .. } => "radiancemeter",
            MeasureKind::DistantFlux { .. } => "distant_flux",
            MeasureKind::Hdrf { .. } => "hdrf",
            MeasureKind::Ortho(_) => "ortho",
            MeasureKind::Perspective(_) => "perspective",
        }
    }

    /// Whether the cells are hemispherical fluxes (albedo) rather than radiances (BRF).
    pub fn is_flux(&self) -> bool {
        matches!(self.kind, MeasureKind::DistantFlux { .. })
    }

    /// View zenith and azimuth (degrees) of a radiance cell of a non-image measure, for the
    /// result rows (None for fluxes and images, whose pixels have their own products).
    pub fn view_angles(&self, cell: usize) -> Option<(f64, f64)> {
        match &self.kind {
            MeasureKind::Distant { vza, vaa, .. } | MeasureKind::Hdrf { vza, vaa, .. } => {
                Some((vza[cell], vaa[cell]))
            }
            MeasureKind::Radiancemeter { look, .. } => {
                let (z, a) = crate::frame::angles_from_direction(-*look);
                Some((z.to_degrees(), a.to_degrees()))
            }
            MeasureKind::DistantFlux { .. }
            | MeasureKind::Ortho(_)
            | MeasureKind::Perspective(_) => None,
        }
    }
}

impl Measure {
    /// Number of output rows of a non-image measure: its cells, less an HDRF's flux cell (which
    /// only normalises the others).
    pub fn row_count(&self) -> usize {
        match &self.kind {
            MeasureKind::Hdrf { directions, .. } => directions.len(),
            MeasureKind::Distant { .. }
            | MeasureKind::Radiancemeter { .. }
            | MeasureKind::DistantFlux { .. }
            | MeasureKind::Ortho(_)
            | MeasureKind::Perspective(_) => self.cell_count(),
        }
    }

    /// Samples per block of this measure (the unit of parallel work and of merging).
    pub fn block_size(&self) -> u64 {
        if let Some(b) = self.block_override {
            b
        } else if self.is_image() {
            IMAGE_BLOCK
        } else {
            BLOCK
        }
    }
}
