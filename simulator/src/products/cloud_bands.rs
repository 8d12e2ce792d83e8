//! Cloud bands of ortho images over a scene with a `[[clouds]]` field: per pixel, the cloud
//! optical thickness the sensor looks through and the cloud fraction (`ID_clouds.tif`, two
//! bands, and `ID_cloud_optical_thickness`, `ID_cloud_fraction` in `results.nc`).
//!
//! Definitions (deterministic, no Monte Carlo): each pixel is sampled on a 4 × 4 grid of
//! points of its square at the terrain's height (the point an ortho pixel's rays aim at); from
//! each, the cloud's optical depth along the line of sight towards the sensor is
//! `τ_los` (exact, the grid's DDA). `cloud_optical_thickness` is the mean of `τ_los·cos VZA`
//! (the vertical-equivalent thickness seen); `cloud_fraction` the share of the 16 points with
//! `τ_los·cos VZA ≥` [`MASK_TAU`] (a cloud mask where it is 1).

use engine::config::resolve::Experiment;
use engine::measure::OrthoGrid;
use glam::DVec3;

/// Vertical-equivalent optical thickness from which a line of sight counts as cloudy.
pub const MASK_TAU: f64 = 0.1;
/// Points per pixel side.
const SUB: usize = 4;

/// `(cloud_optical_thickness, cloud_fraction)` per pixel (row-major from the north), or None
/// without a cloud field.
pub fn ortho_cloud_bands(exp: &Experiment, g: &OrthoGrid) -> Option<(Vec<f64>, Vec<f64>)> {
    let clouds = exp.clouds.as_ref()?;
    let scene = exp.scene.as_ref()?;
    let t = g.geotransform;
    let top = scene.z_range[1] + 1.0;
    let mu = g.view.z;
    let n = g.width * g.height;
    let (mut cot, mut frac) = (vec![0.0; n], vec![0.0; n]);
    for c in 0..n {
        let (col, row) = ((c % g.width) as f64, (c / g.width) as f64);
        let (mut sum, mut cloudy) = (0.0, 0usize);
        for k in 0..SUB * SUB {
            let fx = ((k % SUB) as f64 + 0.5) / SUB as f64;
            let fy = ((k / SUB) as f64 + 0.5) / SUB as f64;
            let x = t[0] + (col + fx) * t[1];
            let y = t[3] + (row + fy) * t[5];
            // The terrain under the point (the scene's floor where nothing is hit).
            let z = scene
                .intersect(DVec3::new(x, y, top), -DVec3::Z, f64::INFINITY)
                .map_or(scene.z_range[0], |h| h.point.z);
            let p = clouds.local(DVec3::new(x, y, z));
            let tau = clouds.grid.optical_depth(p, g.view, f64::INFINITY) * mu;
            sum += tau;
            cloudy += usize::from(tau >= MASK_TAU);
        }
        cot[c] = sum / (SUB * SUB) as f64;
        frac[c] = cloudy as f64 / (SUB * SUB) as f64;
    }
    Some((cot, frac))
}
