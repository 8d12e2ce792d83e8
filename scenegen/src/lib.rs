//! `scenegen`: from a DEM and a land-cover raster (any GDAL-readable raster, any CRS) to a scene
//! bundle (`bundle` crate, documented in `docs/bundle.md`) with an error-bounded terrain
//! TIN split into tiles, an 8-bit material-index raster, and instanced 3D tile templates.
//!
//! Modules: [`region`] (the region file, `docs/region.md`), [`raster`] (GDAL: working frame,
//! warping, coverage and no-data checks), [`tin`] (greedy error-bounded triangulation with
//! spade, tiling), [`build`](mod@build) (the pipeline), [`gltf_export`] (a GLB for a standard 3D viewer),
//! [`info`] (bundle summaries), [`bench`](mod@bench) (the scale benchmark), [`mesh_dem`] (gridded PLY
//! and OBJ terrain meshes to DEMs), [`mesh_region`] (a region's mesh DEM rasterised for a build).
//! Units: metres, degrees for longitudes and latitudes.

pub mod area_polygon;
pub mod bench;
pub mod build;
pub mod buildings;
pub mod cityjson;
pub mod dem_values;
pub mod error;
pub mod gltf_export;
pub mod info;
pub mod inputs;
pub mod landcover_vector;
pub mod mesh_dem;
pub mod mesh_region;
pub mod pointcloud;
pub mod raster;
pub mod region;
pub mod synth;
pub mod tin;
pub mod trees;
pub mod vector;

pub use build::{build, BuildOptions, BuildReport};
pub use error::ScenegenError;
pub use region::Region;
