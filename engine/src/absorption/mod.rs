//! Molecular absorption databases (issue 6 groundwork).
//!
//! Three readers, one file per concern:
//!
//! | file              | reads                                                                 |
//! |-------------------|-----------------------------------------------------------------------|
//! | `axsdb.rs`        | eradiate/axsdb databases (CKD or monochromatic): `sigma_a` vs (x, p, T, spectral) |
//! | `eradiate_v0.rs`  | the older eradiate CKD file of precomputed k(z, bin, g) for one profile |
//! | `profile.rs`      | joseki/axsdb thermophysical profiles (z, p, T, n, mole fractions)    |
//! | `layers.rs`       | layer optical thicknesses: k at a profile's states, integrated per layer |
//! | `cross_section.rs`| continuum absorption of one species from a σ(λ) table (e.g. O3 Chappuis) |
//! | `config.rs`       | the experiment file's absorption keys, resolved into layer optical thicknesses |
//!
//! Units follow `docs/conventions.md`: everything returned is SI (absorption coefficients in
//! **m⁻¹**, altitudes in m, pressures in Pa, temperatures in K, number densities in m⁻³),
//! except wavelengths, in nm. The files store km⁻¹ and km; the conversion happens once, when a
//! file is read, from the `units` attribute of each variable (an unknown unit is an error, never
//! a guess).
//!
//! The experiment configuration (`atmosphere.absorption_data`) uses the eradiate v0 file for the
//! US standard atmosphere, and axsdb CKD / monochromatic databases for any profile.

pub mod axsdb;
pub mod config;
pub mod cross_section;
pub mod eradiate_v0;
pub mod layers;
pub mod profile;
pub mod rrtmgp;

pub use axsdb::{
    gauss_legendre, gauss_legendre_unit, AbsorptionTable, AxsDatabase, BoundsPolicy, CkdBin,
    DataFile, DatabaseKind, OutOfRange, SpectralPoint, ThermoState,
};
pub use eradiate_v0::{EradiateV0Ckd, V0Bin, V0Interpolation};
pub use profile::{integrate_piecewise_linear, AtmosphereProfile, ProfileLevel};
pub use rrtmgp::Rrtmgp;

/// Every failure of the absorption readers. Each variant names the file and the variable,
/// coordinate or value at fault.
#[derive(Debug, thiserror::Error)]
pub enum AbsorptionError {
    #[error("{path}: cannot read file: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("{path}: netCDF error while reading `{variable}`: {source}")]
    Netcdf {
        path: String,
        variable: String,
        source: netcdf::Error,
    },
    #[error("{path}: has no {what} `{name}`")]
    Missing {
        path: String,
        /// "variable", "dimension", "column", "attribute", "file" …
        what: &'static str,
        name: String,
    },
    #[error("{path}: `{variable}` has units `{units}`, expected {expected}")]
    Units {
        path: String,
        variable: String,
        units: String,
        expected: &'static str,
    },
    #[error("{path}: `{variable}`: {message}")]
    Format {
        path: String,
        variable: String,
        message: String,
    },
    #[error(
        "{path}: `{variable}` holds the non-finite or negative value {value} at flat index {index}"
    )]
    BadValue {
        path: String,
        variable: String,
        value: f64,
        index: usize,
    },
    #[error(
        "{path}: coordinate `{coordinate}` = {value} is outside the table's range [{min}, {max}] \
         (ask for OutOfRange::Clamp or OutOfRange::Zero to accept it)"
    )]
    OutOfRange {
        path: String,
        coordinate: String,
        value: f64,
        min: f64,
        max: f64,
    },
    #[error(
        "{path}: the table depends on the mole fraction of `{species}` (coordinate `x_{species}`) \
         but the thermodynamic state gives none (pass 0 to exclude the species)"
    )]
    MissingSpecies { path: String, species: String },
    #[error("{path}: bin `{bin}` does not exist ({count} bins)")]
    NoSuchBin {
        path: String,
        bin: String,
        count: usize,
    },
    #[error("{path}: `{operation}` needs a {expected} database, this one is {actual}")]
    WrongKind {
        path: String,
        operation: &'static str,
        expected: &'static str,
        actual: &'static str,
    },
}

/// Shorthand used by the readers.
pub type Result<T> = std::result::Result<T, AbsorptionError>;

// ---- small netCDF and unit helpers shared by the readers (cold paths) --------------------------

/// A variable's `units` attribute, if it is a string.
pub(crate) fn units_of(var: &netcdf::Variable<'_>) -> Option<String> {
    match var.attribute_value("units") {
        Some(Ok(netcdf::AttributeValue::Str(s))) => Some(s.trim().to_string()),
        _ => None,
    }
}

/// The variable, or `Missing`.
pub(crate) fn variable<'f>(
    file: &'f netcdf::File,
    path: &str,
    name: &str,
) -> Result<netcdf::Variable<'f>> {
    file.variable(name).ok_or_else(|| AbsorptionError::Missing {
        path: path.to_string(),
        what: "variable",
        name: name.to_string(),
    })
}

/// All values of a variable as f64 (the library converts numeric types), in file order.
pub(crate) fn read_f64(var: &netcdf::Variable<'_>, path: &str) -> Result<Vec<f64>> {
    var.get_values::<f64, _>(..)
        .map_err(|source| AbsorptionError::Netcdf {
            path: path.to_string(),
            variable: var.name(),
            source,
        })
}

/// Open a netCDF file.
pub(crate) fn open_nc(path: &std::path::Path) -> Result<netcdf::File> {
    crate::util::nc_complete::check(path).map_err(|e| AbsorptionError::Format {
        path: path.display().to_string(),
        variable: "(file)".into(),
        message: e.to_string(),
    })?;
    netcdf::open(path).map_err(|source| AbsorptionError::Netcdf {
        path: path.display().to_string(),
        variable: "(file)".into(),
        source,
    })
}

/// Normalised unit spelling: lower case, no spaces, `**` → `^`, `kilometer` → `km` …
fn normalise_units(u: &str) -> String {
    u.trim()
        .to_ascii_lowercase()
        .replace(' ', "")
        .replace("**", "^")
        .replace("kilometers", "km")
        .replace("kilometer", "km")
        .replace("kilometre", "km")
        .replace("centimeters", "cm")
        .replace("centimeter", "cm")
        .replace("meters", "m")
        .replace("meter", "m")
        .replace("metre", "m")
}

/// Factor converting an inverse length (absorption coefficient, wavenumber) to m⁻¹.
pub(crate) fn per_metre_factor(units: &str) -> Option<f64> {
    match normalise_units(units).as_str() {
        "km^-1" | "km-1" | "1/km" | "/km" => Some(1e-3),
        "m^-1" | "m-1" | "1/m" | "/m" => Some(1.0),
        "cm^-1" | "cm-1" | "1/cm" | "/cm" => Some(1e2),
        _ => None,
    }
}

/// Factor converting a length to m.
pub(crate) fn metre_factor(units: &str) -> Option<f64> {
    match normalise_units(units).as_str() {
        "km" => Some(1e3),
        "m" => Some(1.0),
        "cm" => Some(1e-2),
        "nm" => Some(1e-9),
        _ => None,
    }
}

/// Factor converting a pressure to Pa.
pub(crate) fn pascal_factor(units: &str) -> Option<f64> {
    match normalise_units(units).as_str() {
        "pa" | "pascal" | "pascals" => Some(1.0),
        "hpa" | "hectopascal" | "mbar" | "millibar" => Some(100.0),
        "kpa" | "kilopascal" => Some(1e3),
        "bar" => Some(1e5),
        "atm" => Some(101_325.0),
        _ => None,
    }
}

/// `true` for units of a temperature in kelvin.
pub(crate) fn is_kelvin(units: &str) -> bool {
    matches!(normalise_units(units).as_str(), "k" | "kelvin" | "kelvins")
}

/// `true` for the spellings of a dimensionless quantity.
pub(crate) fn is_dimensionless(units: &str) -> bool {
    matches!(
        normalise_units(units).as_str(),
        "" | "1" | "dimensionless" | "-" | "none" | "mol/mol" | "ppv"
    )
}

/// Factor converting a number density to m⁻³.
pub(crate) fn per_cubic_metre_factor(units: &str) -> Option<f64> {
    match normalise_units(units).as_str() {
        "m^-3" | "m-3" | "1/m^3" | "/m^3" => Some(1.0),
        "cm^-3" | "cm-3" | "1/cm^3" | "/cm^3" => Some(1e6),
        _ => None,
    }
}

/// Read a variable, check its units with `factor_of` and return the values scaled to SI.
pub(crate) fn read_scaled(
    file: &netcdf::File,
    path: &str,
    name: &str,
    expected: &'static str,
    factor_of: impl Fn(&str) -> Option<f64>,
) -> Result<Vec<f64>> {
    let var = variable(file, path, name)?;
    let units = units_of(&var).ok_or_else(|| AbsorptionError::Missing {
        path: path.to_string(),
        what: "attribute",
        name: format!("{name}:units"),
    })?;
    let factor = factor_of(&units).ok_or_else(|| AbsorptionError::Units {
        path: path.to_string(),
        variable: name.to_string(),
        units: units.clone(),
        expected,
    })?;
    let values = read_f64(&var, path)?;
    Ok(values.into_iter().map(|v| v * factor).collect())
}

#[cfg(test)]
pub(crate) mod test_data {
    //! Location of `shared/data` for the tests that read it.
    use std::path::PathBuf;

    /// `$SIMULATOR_SHARED_DATA`, else `<workspace>/../shared/data`; `None` (and a printed
    /// message) when the named sub-path is absent, so that the test can skip.
    pub fn shared(sub: &str) -> Option<PathBuf> {
        let root = std::env::var_os("SIMULATOR_SHARED_DATA")
            .map(PathBuf::from)
            .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data"));
        let p = root.join(sub);
        if p.exists() {
            Some(p)
        } else {
            println!("skipped: {} is absent", p.display());
            None
        }
    }
}
