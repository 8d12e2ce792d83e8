//! Errors of the BRDF models: a parameter out of range (constructors), a bi-Lambertian leaf
//! that reflects and transmits too much (`scene/material.rs`), and a tabulated BRDF's file
//! ([`super::tabulated::BrdfTable`]). Each variant names what is wrong and where (model and
//! parameter, or file, variable and grid point); the messages are those users and tests match.

use std::path::PathBuf;

/// What went wrong building a BRDF model or reading a BRDF table.
#[derive(Debug, thiserror::Error)]
pub enum BrdfError {
    /// A parameter outside its range of `bundle::BRDF_PARAM_RANGES` (or of a model's own range
    /// such as RTLS-H's `xi0`); `message` is the range check's ("`k` = 5 must lie in [0, 2]").
    #[error("{message}")]
    Param {
        /// The model's `type` tag (`rpv`, `hapke`, …).
        model: &'static str,
        /// The parameter's key (`rho_0`, `B_0`, …).
        param: &'static str,
        value: f64,
        message: String,
    },
    /// A bi-Lambertian leaf whose reflectance and transmittance add up to more than `max`.
    #[error(
        "bi_lambertian: the sum `reflectance` + `transmittance` = {reflectance} + {transmittance} at {wavelength_nm} nm must not exceed {max}"
    )]
    LeafSum {
        reflectance: f64,
        transmittance: f64,
        wavelength_nm: f64,
        max: f64,
    },
    /// A transmitting model (`rough_dielectric`, `thin_dielectric`) used where only an opaque
    /// surface can be (the ground of a 1D atmosphere, a canopy's ground).
    #[error(
        "`type = \"{model}\"` transmits light and is a material of 3D scenes only: the ground of a 1D atmosphere is opaque (give it an opaque BRDF, or render the pane or water surface as a scene object)"
    )]
    SceneOnly { model: &'static str },
    /// A BRDF table that stops before the end its netCDF header declares, or whose classic
    /// header is damaged (`source` says how).
    #[error("BRDF table {}: {source}", path.display())]
    Truncated {
        path: PathBuf,
        source: crate::util::nc_complete::NcError,
    },
    /// A BRDF table that netCDF cannot open.
    #[error("cannot read BRDF table {}: {source}", path.display())]
    Open {
        path: PathBuf,
        source: netcdf::Error,
    },
    /// A variable the table must have is absent (`what`: its meaning and unit).
    #[error("BRDF table {}: missing variable `{variable}` ({what})", path.display())]
    MissingVariable {
        path: PathBuf,
        variable: &'static str,
        what: &'static str,
    },
    /// A variable whose `units` attribute is not the unit it must have (`what`).
    #[error("BRDF table {}: variable `{variable}` has units \"{units}\" ({what})", path.display())]
    Units {
        path: PathBuf,
        variable: &'static str,
        units: String,
        what: &'static str,
    },
    /// A variable whose values netCDF cannot read.
    #[error("BRDF table {}: cannot read variable `{variable}`: {source}", path.display())]
    ReadVariable {
        path: PathBuf,
        variable: &'static str,
        source: netcdf::Error,
    },
    /// An axis variable (`wavelength`, `theta_i`, `theta_r`, `dphi`) not on its own dimension.
    #[error(
        "BRDF table {}: variable `{variable}` must have the one dimension `{variable}`",
        path.display()
    )]
    AxisDimensions {
        path: PathBuf,
        variable: &'static str,
    },
    /// `brdf` not on the dimensions (wavelength, theta_i, theta_r, dphi); `found`: its own.
    #[error(
        "BRDF table {}: variable `brdf` must have the dimensions (wavelength, theta_i, theta_r, dphi), not ({})",
        path.display(),
        found.join(", ")
    )]
    BrdfDimensions { path: PathBuf, found: Vec<String> },
    /// An axis with no values.
    #[error("BRDF table {}: variable `{variable}` is empty", path.display())]
    EmptyAxis {
        path: PathBuf,
        variable: &'static str,
    },
    /// An axis value outside the axis' range `[lo, hi]` (or not a number).
    #[error(
        "BRDF table {}: variable `{variable}` has the value {value} outside [{lo}, {hi}]",
        path.display()
    )]
    AxisRange {
        path: PathBuf,
        variable: &'static str,
        value: f64,
        lo: f64,
        hi: f64,
    },
    /// Two successive axis values `previous`, `next` not strictly increasing.
    #[error(
        "BRDF table {}: variable `{variable}` must increase strictly ({previous} then {next})",
        path.display()
    )]
    NotIncreasing {
        path: PathBuf,
        variable: &'static str,
        previous: f64,
        next: f64,
    },
    /// `brdf` holding `found` values where the grids call for `shape` (wavelength, theta_i,
    /// theta_r, dphi).
    #[error(
        "BRDF table {}: variable `brdf` has {found} values, expected {}×{}×{}×{}",
        path.display(),
        shape[0],
        shape[1],
        shape[2],
        shape[3]
    )]
    ValueCount {
        path: PathBuf,
        found: usize,
        shape: [usize; 4],
    },
    /// A BRDF value that is negative or not finite, at its grid point (nm and degrees).
    #[error(
        "BRDF table {}: variable `brdf` is {value} at wavelength {wavelength_nm} nm, theta_i {theta_i}°, theta_r {theta_r}°, dphi {dphi}° (values must be finite and ≥ 0)",
        path.display()
    )]
    BadValue {
        path: PathBuf,
        value: f64,
        wavelength_nm: f64,
        theta_i: f64,
        theta_r: f64,
        dphi: f64,
    },
}

/// `Ok` when `value` lies in the range of `model.param` in `bundle::BRDF_PARAM_RANGES`, else
/// [`BrdfError::Param`] (`label`: how the message names the parameter).
pub(crate) fn check_param(
    model: &'static str,
    param: &'static str,
    label: &str,
    value: f64,
) -> Result<(), BrdfError> {
    bundle::check_param(model, param, label, value).map_err(|message| BrdfError::Param {
        model,
        param,
        value,
        message,
    })
}
