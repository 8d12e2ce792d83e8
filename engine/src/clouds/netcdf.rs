//! Cloud fields in netCDF (CF-style), the format `[[clouds]] file` reads and
//! `tools/clouds/write_field.py` writes:
//!
//! | variable | dimensions | units | |
//! |---|---|---|---|
//! | `x`, `y` | `x`, `y` | `m` | cell centres, evenly spaced, ascending (one cell: its width in a `spacing` attribute) |
//! | `z_edges` | `z_edge` (= nz + 1) | `m` | cell boundaries (altitude), ascending, spacing free |
//! | `extinction` | `(z, y, x)` | `m-1` or `km-1` | σ per cell, ≥ 0, no fill values |
//! | `ssa` (optional) | `(z, y, x)` | 1 | single-scattering albedo per cell |
//! | `phase_index` (optional) | `(z, y, x)` | 1 | index into the experiment's `phases` list |
//!
//! The field's frame: x east, y north, from the rectangle's lower-left corner
//! `(x[0] − dx/2, y[0] − dy/2)`, which the reader returns so the experiment can place it.

use std::path::{Path, PathBuf};

/// A field as read: what [`super::CloudGrid::new`] needs, plus the corner of its rectangle.
pub struct FieldFile {
    pub nx: usize,
    pub ny: usize,
    pub dx: f64,
    pub dy: f64,
    /// Lower-left corner of the rectangle in the file's x/y coordinates (m).
    pub corner: [f64; 2],
    pub z_edges: Vec<f64>,
    /// σ per cell (1/m), `(iz·ny + iy)·nx + ix`.
    pub extinction: Vec<f32>,
    pub ssa: Option<Vec<f32>>,
    pub phase_index: Option<Vec<u8>>,
}

#[derive(Debug, thiserror::Error)]
pub enum FieldError {
    #[error("cloud field {}: {source}", path.display())]
    Netcdf {
        path: PathBuf,
        source: netcdf::Error,
    },
    #[error("cloud field {}: variable `{var}` {msg}", path.display())]
    Variable {
        path: PathBuf,
        var: String,
        msg: String,
    },
    #[error("cloud field {}: {msg}", path.display())]
    Truncated { path: PathBuf, msg: String },
}

/// Read a cloud field (module doc); every value checked, errors name the file, variable and
/// cell.
pub fn read(path: &Path) -> Result<FieldFile, FieldError> {
    let _session = crate::netcdf_session();
    crate::util::nc_complete::check(path).map_err(|e| FieldError::Truncated {
        path: path.into(),
        msg: e.to_string(),
    })?;
    let file = netcdf::open(path).map_err(|source| FieldError::Netcdf {
        path: path.into(),
        source,
    })?;
    let verr = |var: &str, msg: String| FieldError::Variable {
        path: path.into(),
        var: var.into(),
        msg,
    };
    let var = |name: &str| {
        file.variable(name)
            .ok_or_else(|| verr(name, "is missing".into()))
    };
    let vals = |name: &str| -> Result<Vec<f64>, FieldError> {
        var(name)?
            .get_values::<f64, _>(..)
            .map_err(|e| verr(name, e.to_string()))
    };
    let units = |name: &str| -> Option<String> {
        match file.variable(name)?.attribute_value("units") {
            Some(Ok(netcdf::AttributeValue::Str(s))) => Some(s.trim().to_string()),
            Some(Ok(netcdf::AttributeValue::Strs(v))) if !v.is_empty() => {
                Some(v[0].trim().to_string())
            }
            _ => None,
        }
    };
    let axis = |name: &str| -> Result<(usize, f64, f64), FieldError> {
        let v = vals(name)?;
        if let Some(u) = units(name) {
            if u != "m" {
                return Err(verr(
                    name,
                    format!("has units \"{u}\"; metres (\"m\") expected"),
                ));
            }
        }
        if v.is_empty() {
            return Err(verr(name, "is empty".into()));
        }
        let d =
            if v.len() == 1 {
                // One cell (a 2D field): its width from the `spacing` attribute.
                match file
                    .variable(name)
                    .and_then(|x| x.attribute_value("spacing"))
                {
                    Some(Ok(netcdf::AttributeValue::Double(s))) if s.is_finite() && s > 0.0 => s,
                    Some(Ok(netcdf::AttributeValue::Float(s))) if s.is_finite() && s > 0.0 => {
                        f64::from(s)
                    }
                    _ => return Err(verr(
                        name,
                        "has one value: give its cell width as a positive `spacing` attribute (m)"
                            .into(),
                    )),
                }
            } else {
                v[1] - v[0]
            };
        for k in 1..v.len() {
            let dk = v[k] - v[k - 1];
            if !(dk.is_finite() && dk > 0.0 && (dk - d).abs() <= 1e-6 * d.abs().max(1.0)) {
                return Err(verr(
                    name,
                    format!(
                        "must be evenly spaced and ascending: {name}[{}] = {}, {name}[{k}] = {}",
                        k - 1,
                        v[k - 1],
                        v[k]
                    ),
                ));
            }
        }
        Ok((v.len(), d, v[0] - d / 2.0))
    };
    let (nx, dx, x0) = axis("x")?;
    let (ny, dy, y0) = axis("y")?;
    let z_edges = vals("z_edges")?;
    if let Some(u) = units("z_edges") {
        if u != "m" {
            return Err(verr(
                "z_edges",
                format!("has units \"{u}\"; metres (\"m\") expected"),
            ));
        }
    }
    if z_edges.len() < 2 {
        return Err(verr("z_edges", "needs at least two edges".into()));
    }
    let nz = z_edges.len() - 1;
    let cells = nx * ny * nz;
    let cell_name = |c: usize| {
        format!(
            "cell (x {}, y {}, z {})",
            c % nx,
            (c / nx) % ny,
            c / (nx * ny)
        )
    };
    let field = |name: &str| -> Result<Vec<f64>, FieldError> {
        let v = var(name)?;
        let dims: Vec<(String, usize)> =
            v.dimensions().iter().map(|d| (d.name(), d.len())).collect();
        let lens: Vec<usize> = dims.iter().map(|d| d.1).collect();
        if lens != [nz, ny, nx] {
            return Err(verr(
                name,
                format!("has dimensions {dims:?}; (z = {nz}, y = {ny}, x = {nx}) expected"),
            ));
        }
        let data = vals(name)?;
        if let Some(c) = data.iter().position(|x| !x.is_finite()) {
            return Err(verr(
                name,
                format!(
                    "is {} at {} (fill values and NaN are not allowed)",
                    data[c],
                    cell_name(c)
                ),
            ));
        }
        Ok(data)
    };
    let scale = match units("extinction").as_deref() {
        Some("m-1" | "m^-1" | "1/m") => 1.0,
        Some("km-1" | "km^-1" | "1/km") => 1e-3,
        Some(u) => {
            return Err(verr(
                "extinction",
                format!("has units \"{u}\"; \"m-1\" or \"km-1\" expected"),
            ))
        }
        None => {
            return Err(verr(
                "extinction",
                "has no `units` attribute (\"m-1\" or \"km-1\")".into(),
            ))
        }
    };
    let ext = field("extinction")?;
    if let Some(c) = ext.iter().position(|&s| s < 0.0) {
        return Err(verr(
            "extinction",
            format!("is negative ({}) at {}", ext[c], cell_name(c)),
        ));
    }
    let extinction: Vec<f32> = ext.iter().map(|&s| (s * scale) as f32).collect();
    debug_assert_eq!(extinction.len(), cells);
    let ssa = if file.variable("ssa").is_some() {
        let v = field("ssa")?;
        if let Some(c) = v.iter().position(|w| !(0.0..=1.0).contains(w)) {
            return Err(verr(
                "ssa",
                format!("is {} at {}; it must lie in [0, 1]", v[c], cell_name(c)),
            ));
        }
        Some(v.iter().map(|&w| w as f32).collect())
    } else {
        None
    };
    let phase_index = if file.variable("phase_index").is_some() {
        let v = field("phase_index")?;
        if let Some(c) = v
            .iter()
            .position(|k| !(k.fract() == 0.0 && (0.0..256.0).contains(k)))
        {
            return Err(verr(
                "phase_index",
                format!(
                    "is {} at {}; whole numbers 0–255 expected",
                    v[c],
                    cell_name(c)
                ),
            ));
        }
        Some(v.iter().map(|&k| k as u8).collect())
    } else {
        None
    };
    Ok(FieldFile {
        nx,
        ny,
        dx,
        dy,
        corner: [x0, y0],
        z_edges,
        extinction,
        ssa,
        phase_index,
    })
}
