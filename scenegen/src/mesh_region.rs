//! A region whose `[dem]` is a gridded terrain mesh (`dem.mesh`, `dem.mesh_origin`): the build
//! rasterises the mesh with [`crate::mesh_dem`] (the same DEM as `scenegen mesh-to-dem` writes:
//! pixel centres at the vertices, transverse Mercator CRS centred on the mesh origin) into a
//! temporary GeoTIFF, reads it like any DEM, and removes it when done. So a region file over a
//! mesh builds in one command, without a preparatory step or files left behind.

use std::path::{Path, PathBuf};

use crate::error::ScenegenError;
use crate::region::Region;

/// A temporary folder removed on drop (also when the build fails).
#[derive(Debug)]
pub struct TempDir(PathBuf);

impl TempDir {
    pub fn path(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The region to build from: `region` itself when its DEM is a raster, else a copy whose
/// `dem_files` is the rasterised mesh, with the temporary folder holding it (keep it alive for
/// the build). `dem_mesh` stays set, so provenance names the mesh, not the temporary file.
pub fn with_rasterised_mesh(region: &Region) -> Result<(Region, Option<TempDir>), ScenegenError> {
    let Some(mesh) = &region.dem_mesh else {
        return Ok((region.clone(), None));
    };
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.subsec_nanos())
        .unwrap_or(0);
    let dir =
        TempDir(std::env::temp_dir().join(format!("scenegen-mesh-{}-{nanos}", std::process::id())));
    std::fs::create_dir_all(dir.path()).map_err(|e| ScenegenError::Input {
        path: dir.path().into(),
        message: format!("cannot create a temporary folder for the mesh's DEM: {e}"),
    })?;
    let dem = dir.path().join("dem.tif");
    let [lon, lat] = mesh.origin;
    crate::mesh_dem::mesh_to_dem(&mesh.path, lon, lat, &dem, None)?;
    let mut r = region.clone();
    r.dem_files = vec![dem];
    Ok((r, Some(dir)))
}
