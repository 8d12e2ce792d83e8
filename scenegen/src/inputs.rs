//! Validated descriptions of a region's geodata inputs beyond the DEM and the land-cover raster
//! (`[[landcover.vector]]`, `[[buildings]]`, `[[city_models]]`, `[[trees]]`), with paths resolved:
//! plain data made by `region.rs` and read by the stages that build from them
//! (`landcover_vector.rs`, `buildings.rs`, `cityjson.rs`, `trees.rs`). Kept apart so the region
//! file's module depends on no stage.

use std::collections::BTreeMap;
use std::path::PathBuf;

/// One `[[landcover.vector]]` entry, paths resolved.
#[derive(Clone, Debug, PartialEq)]
pub struct VectorLandcover {
    pub file: PathBuf,
    pub layer: Option<String>,
    pub crs: Option<String>,
    /// OGR SQL attribute filter (`WHERE` clause).
    pub filter: Option<String>,
    pub code: CodeSource,
}

/// Where a feature's class code comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum CodeSource {
    /// One code for every feature of the layer.
    Class(i64),
    /// An attribute holding integer codes, or text mapped by `values`.
    Attribute {
        name: String,
        values: BTreeMap<String, i64>,
    },
}

/// Where a building's height comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum HeightSource {
    /// An attribute in metres.
    Attribute(String),
    /// A storey-count attribute times a storey height (m).
    Levels { attribute: String, storey_m: f64 },
    /// One height for every footprint, m.
    Constant(f64),
    /// A percentile of the region's lidar points of these classes inside the footprint.
    Lidar { classes: Vec<u8>, percentile: f64 },
    /// A percentile of the heights of a surface model's pixels inside the footprint.
    Dsm { path: PathBuf, percentile: f64 },
}

/// One `[[buildings]]` entry, paths resolved.
#[derive(Clone, Debug, PartialEq)]
pub struct BuildingsSpec {
    pub file: PathBuf,
    pub layer: Option<String>,
    pub crs: Option<String>,
    /// OGR SQL attribute filter (`WHERE` clause), e.g. `building IS NOT NULL`.
    pub filter: Option<String>,
    /// Attribute naming the buildings in messages (default: the feature id).
    pub id_attribute: Option<String>,
    pub height: HeightSource,
    pub default_height_m: Option<f64>,
    pub roof_material: String,
    pub wall_material: String,
    pub roof: RoofSpec,
}

/// Roof shapes of a `[[buildings]]` entry.
#[derive(Clone, Debug, PartialEq)]
pub struct RoofSpec {
    /// Every footprint gabled (else flat, unless `attribute` says gabled).
    pub gabled: bool,
    /// Attribute whose value `gabled` makes a footprint's roof gabled (OSM `roof:shape`).
    pub attribute: Option<String>,
    /// Slope of the gables, degrees.
    pub pitch_deg: f64,
}

/// One `[[city_models]]` entry, paths resolved.
#[derive(Clone, Debug, PartialEq)]
pub struct CityModelSpec {
    pub file: PathBuf,
    pub crs: Option<String>,
    /// City object types to take.
    pub types: Vec<String>,
    /// Level of detail to take (default: each object's highest).
    pub lod: Option<String>,
    pub roof_material: String,
    pub wall_material: String,
}

/// Where the canopy heights come from.
#[derive(Clone, Debug, PartialEq)]
pub enum ChmSource {
    Chm(PathBuf),
    DsmMinusDtm {
        dsm: PathBuf,
        dtm: PathBuf,
    },
    /// Highest point of `classes` per cell minus the DEM; cells holding any point of `exclude`
    /// (buildings) are not canopy.
    Lidar {
        classes: Vec<u8>,
        exclude: Vec<u8>,
    },
}

/// One `[[trees]]` entry, paths resolved.
#[derive(Clone, Debug, PartialEq)]
pub struct TreesSpec {
    pub source: ChmSource,
    pub template: String,
    pub min_height_m: f64,
    /// Fixed detection window diameter, m (default: the crown-width regression).
    pub window_m: Option<f64>,
    /// Cell of the CHM grid, m (default: the raster's pixel size, 1 m for lidar).
    pub cell_m: Option<f64>,
    pub crown_scale: f64,
    pub keep_proportions: bool,
}
