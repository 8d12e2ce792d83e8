//! `[[clouds]]` of the experiment file: a gridded cloud field placed in the scene's frame
//! (keys in `docs/experiment.md`, "Clouds"), resolved into [`PlacedClouds`].

use std::sync::Arc;

use serde::Deserialize;

use super::grid::{CloudGrid, Lateral, PerCell, Vertical};
use crate::error::{ConfigCtx, ConfigError};
use crate::phase::{PhaseConfig, PhaseFunction, PhaseResolver};

#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum LateralConfig {
    /// Clear air beyond the field's rectangle.
    #[default]
    Open,
    /// The field repeats in x and y.
    Periodic,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CloudConfig {
    /// The field (netCDF, `clouds/netcdf.rs`), relative to the experiment file.
    pub file: String,
    /// m, added to the file's x and y to place the field in the scene's frame.
    #[serde(default)]
    pub offset_m: [f64; 2],
    #[serde(default)]
    pub lateral: LateralConfig,
    /// Used where the file has no `ssa` variable.
    #[serde(default)]
    pub single_scattering_albedo: Option<f64>,
    /// Phase functions, indexed by the file's `phase_index` (one entry when it has none).
    pub phases: Vec<PhaseConfig>,
}

/// A cloud field in the scene's frame, with its phase functions at every run wavelength.
#[derive(Debug)]
pub struct PlacedClouds {
    /// The grid (its `phases`: those of the first run wavelength).
    pub grid: CloudGrid,
    /// Scene-frame position of the grid frame's origin (the rectangle's lower-left corner).
    pub origin: glam::DVec3,
    /// Phase functions per run wavelength, indexed like `grid.phases`.
    pub phases: Vec<Vec<PhaseFunction>>,
    /// Bytes the field holds (extinction, albedos, indices).
    pub bytes: usize,
    /// Whether any cell has extinction (a field without is the clear run's, bit for bit).
    pub any_extinction: bool,
}

impl PlacedClouds {
    /// `p` (scene frame) in the grid's frame.
    #[inline]
    pub fn local(&self, p: glam::DVec3) -> glam::DVec3 {
        p - self.origin
    }
}

/// Resolve `[[clouds]]` (at most one field for now) at the run wavelengths.
pub fn resolve(
    ctx: &ConfigCtx,
    clouds: &[CloudConfig],
    wavelengths: &[f64],
) -> Result<Option<Arc<PlacedClouds>>, ConfigError> {
    let Some(c) = clouds.first() else {
        return Ok(None);
    };
    if clouds.len() > 1 {
        return Err(ctx.err(
            "clouds[1]",
            "one cloud field per experiment for now: merge the fields into one grid",
        ));
    }
    let key = "clouds[0]";
    let path = ctx.file(&c.file);
    if !path.exists() {
        return Err(ctx.err(
            format!("{key}.file"),
            format!("file {} not found", path.display()),
        ));
    }
    let f =
        super::netcdf::read(&path).map_err(|e| ctx.err(format!("{key}.file"), e.to_string()))?;
    if c.phases.is_empty() {
        return Err(ctx.err(format!("{key}.phases"), "give at least one phase function"));
    }
    if c.phases.len() > 256 {
        return Err(ctx.err(format!("{key}.phases"), "at most 256 phase functions"));
    }
    if !c.offset_m.iter().all(|v| v.is_finite()) {
        return Err(ctx.err(format!("{key}.offset_m"), "must be finite"));
    }
    let albedo = match (&f.ssa, c.single_scattering_albedo) {
        (Some(_), Some(_)) => {
            return Err(ctx.err(
                format!("{key}.single_scattering_albedo"),
                format!(
                    "{} has an `ssa` variable: give one or the other",
                    path.display()
                ),
            ))
        }
        (Some(v), None) => PerCell::Cell(v.clone()),
        (None, Some(w)) if (0.0..=1.0).contains(&w) => PerCell::Uniform(w as f32),
        (None, Some(w)) => {
            return Err(ctx.err(
                format!("{key}.single_scattering_albedo"),
                format!("{w} must lie in [0, 1]"),
            ))
        }
        (None, None) => {
            return Err(ctx.err(
                format!("{key}.single_scattering_albedo"),
                format!("is required: {} has no `ssa` variable", path.display()),
            ))
        }
    };
    let mut resolver = PhaseResolver::default();
    let mut phases = Vec::with_capacity(wavelengths.len());
    for &wl in wavelengths {
        let list: Vec<PhaseFunction> = c
            .phases
            .iter()
            .enumerate()
            .map(|(k, p)| resolver.resolve(ctx, &format!("{key}.phases[{k}]"), p, wl))
            .collect::<Result<_, _>>()?;
        phases.push(list);
    }
    let index = match &f.phase_index {
        Some(v) => {
            if let Some(c_bad) = v.iter().position(|&k| usize::from(k) >= c.phases.len()) {
                return Err(ctx.err(
                    format!("{key}.phases"),
                    format!(
                        "{} gives phase_index {} at cell {c_bad}, but only {} phase functions are listed",
                        path.display(),
                        v[c_bad],
                        c.phases.len()
                    ),
                ));
            }
            PerCell::Cell(v.clone())
        }
        None => PerCell::Uniform(0),
    };
    let cells = f.extinction.len();
    let bytes = cells * 4
        + matches!(albedo, PerCell::Cell(_)) as usize * cells * 4
        + matches!(index, PerCell::Cell(_)) as usize * cells;
    let grid = CloudGrid::new(
        (f.nx, f.ny),
        (f.dx, f.dy),
        Vertical::Levels(f.z_edges.clone()),
        match c.lateral {
            LateralConfig::Open => Lateral::Open,
            LateralConfig::Periodic => Lateral::Periodic,
        },
        f.extinction,
        albedo,
        index,
        phases[0].clone(),
    )
    .map_err(|e| ctx.err(format!("{key}.file"), format!("{}: {e}", path.display())))?;
    let any_extinction = grid.extinction.iter().any(|&s| s > 0.0);
    Ok(Some(Arc::new(PlacedClouds {
        any_extinction,
        grid,
        origin: glam::DVec3::new(
            f.corner[0] + c.offset_m[0],
            f.corner[1] + c.offset_m[1],
            0.0,
        ),
        phases,
        bytes,
    })))
}
