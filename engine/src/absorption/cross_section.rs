//! Continuum absorption from a tabulated absorption cross-section of one species (e.g. the
//! ozone Chappuis band, which the eradiate v0 CKD file lacks).
//!
//! | config (`[[atmosphere.cross_sections]]`) | unit | meaning |
//! |---|---|---|
//! | `species` | — | the absorber, a species of the profile (e.g. `"O3"`) |
//! | `file` | — | a text table: `#` comments, then rows of numbers separated by spaces, tabs or commas; column 1 the wavelength (nm, increasing) |
//! | `column` | — | the 1-based column holding σ (default 2) |
//! | `units` | — | `"cm^2"` (default) or `"m^2"`: σ per molecule |
//! | `outside` | — | a wavelength outside the table: `"error"` (default) or `"zero"` (no absorption; logged once) |
//!
//! Model: in each layer [z_b, z_t] the absorption optical thickness is
//! `τ = σ(λ) · ∫ x(z) n(z) dz`, with the profile's mole fraction x times air number density n
//! linear in altitude between the profile's levels (the representation of
//! [`AtmosphereProfile::column_density_m2`] and of the rescaling), and σ(λ) linear between the
//! table's wavelengths, at the run's wavelength (the bin centre in CKD mode). The cross-section
//! is temperature-independent and grey within a CKD bin; the absorption is added to every
//! g-point alike. A wavelength outside the table is an error, never an extrapolation, unless
//! `outside = "zero"` says the species does not absorb there.
//!
//! Reference: Beer–Lambert with a column density; the shipped example table is the ozone
//! cross-section of the Zawada et al. (2021, AMT 14, 3953) limb benchmark,
//! `shared/data/spherical_limb_zawada2021/inputs/xsection_rayleigh_ozone.txt` (column 3).

use std::path::{Path, PathBuf};

use super::{integrate_piecewise_linear, AtmosphereProfile};

/// Why a cross-section table or a species' layer columns are refused; the table's errors name
/// the file and the 1-based line.
#[derive(Debug, thiserror::Error)]
pub enum CrossSectionError {
    #[error("column {column}: σ must be in column 2 or later (column 1 is the wavelength)")]
    Column { column: usize },
    #[error("{}: {source}", path.display())]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{}:{line}: no column {column} ({columns} columns)", path.display())]
    NoColumn {
        path: PathBuf,
        line: usize,
        column: usize,
        columns: usize,
    },
    #[error("{}:{line}: column {column}: `{value}` is not a number", path.display())]
    NotANumber {
        path: PathBuf,
        line: usize,
        column: usize,
        value: String,
    },
    #[error("{}:{line}: negative cross-section {value}", path.display())]
    Negative {
        path: PathBuf,
        line: usize,
        value: f64,
    },
    #[error("{}:{line}: wavelength {wavelength_nm} nm does not increase", path.display())]
    NotIncreasing {
        path: PathBuf,
        line: usize,
        wavelength_nm: f64,
    },
    #[error("{}: needs at least two rows", path.display())]
    TooFewRows { path: PathBuf },
    #[error(
        "the profile {profile} has no species `{species}` (it has: {})",
        .available.join(", ")
    )]
    NoSpecies {
        /// The profile's path (or embedded name).
        profile: String,
        species: String,
        available: Vec<String>,
    },
}

/// σ(λ) of one species.
#[derive(Clone, Debug)]
pub struct CrossSection {
    pub path: String,
    /// nm, strictly increasing.
    pub wavelength_nm: Vec<f64>,
    /// m² per molecule.
    pub sigma_m2: Vec<f64>,
}

impl CrossSection {
    /// Read column `column` (1-based; column 1 is the wavelength) of the table at `path`;
    /// `to_m2` converts its unit to m².
    pub fn read(path: &Path, column: usize, to_m2: f64) -> Result<Self, CrossSectionError> {
        let name = path.display().to_string();
        if column < 2 {
            return Err(CrossSectionError::Column { column });
        }
        let text = std::fs::read_to_string(path).map_err(|source| CrossSectionError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        let (mut wl, mut sigma) = (Vec::new(), Vec::new());
        let text = crate::util::without_bom(&text);
        for (i, line) in text.lines().enumerate() {
            let line = line.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let cols: Vec<&str> = line
                .split(|c: char| c.is_whitespace() || c == ',')
                .filter(|s| !s.is_empty())
                .collect();
            let num = |k: usize| -> Result<f64, CrossSectionError> {
                let s = cols.get(k - 1).ok_or_else(|| CrossSectionError::NoColumn {
                    path: path.to_path_buf(),
                    line: i + 1,
                    column: k,
                    columns: cols.len(),
                })?;
                s.parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| CrossSectionError::NotANumber {
                        path: path.to_path_buf(),
                        line: i + 1,
                        column: k,
                        value: s.to_string(),
                    })
            };
            let (w, s) = (num(1)?, num(column)?);
            if s < 0.0 {
                return Err(CrossSectionError::Negative {
                    path: path.to_path_buf(),
                    line: i + 1,
                    value: s,
                });
            }
            if wl.last().is_some_and(|&last| w <= last) {
                return Err(CrossSectionError::NotIncreasing {
                    path: path.to_path_buf(),
                    line: i + 1,
                    wavelength_nm: w,
                });
            }
            wl.push(w);
            sigma.push(s * to_m2);
        }
        if wl.len() < 2 {
            return Err(CrossSectionError::TooFewRows {
                path: path.to_path_buf(),
            });
        }
        Ok(Self {
            path: name,
            wavelength_nm: wl,
            sigma_m2: sigma,
        })
    }

    /// σ at `wl` nm (m²), linear between the table's wavelengths; `None` outside the table.
    pub fn at(&self, wl: f64) -> Option<f64> {
        let w = &self.wavelength_nm;
        if !(wl >= w[0] && wl <= w[w.len() - 1]) {
            return None;
        }
        let i = w.partition_point(|&x| x <= wl).clamp(1, w.len() - 1) - 1;
        let f = (wl - w[i]) / (w[i + 1] - w[i]);
        Some(self.sigma_m2[i] + f * (self.sigma_m2[i + 1] - self.sigma_m2[i]))
    }
}

/// Column density of `species` in each layer of `grid` (m, bottom-up pairs) [molecules m⁻²],
/// with x·n linear between the profile's levels.
pub fn layer_columns(
    prof: &AtmosphereProfile,
    species: &str,
    grid: &[(f64, f64)],
) -> Result<Vec<f64>, CrossSectionError> {
    let x = prof
        .mole_fraction(species)
        .ok_or_else(|| CrossSectionError::NoSpecies {
            profile: prof.path.clone(),
            species: species.to_string(),
            available: prof.mole_fractions.iter().map(|(n, _)| n.clone()).collect(),
        })?;
    let nx: Vec<f64> = prof
        .air_number_density()
        .iter()
        .zip(x)
        .map(|(n, x)| n * x)
        .collect();
    Ok(grid
        .iter()
        .map(|&(b, t)| integrate_piecewise_linear(&prof.altitude_m, &nx, b, t))
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(text: &str) -> Result<CrossSection, CrossSectionError> {
        let dir = std::env::temp_dir().join(format!("xs-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join(format!("t{}.txt", text.len()));
        std::fs::write(&p, text).unwrap();
        CrossSection::read(&p, 3, 1e-4)
    }

    /// Linear interpolation, unit conversion, bounds; errors name the line and column.
    #[test]
    fn reads_and_interpolates() {
        let t = table("# wl, ray, o3\n500 1 2e-21\n600, 1, 4e-21\n700 1 0\n").unwrap();
        assert!((t.at(550.0).unwrap() - 3e-25).abs() < 1e-40);
        assert!((t.at(700.0).unwrap()).abs() < 1e-40);
        assert!(t.at(499.0).is_none() && t.at(f64::NAN).is_none());
        let e = table("500 1 2e-21\n490 1 3e-21\n").unwrap_err().to_string();
        assert!(e.contains(":2:") && e.contains("does not increase"), "{e}");
        let e = table("500 1 x\n600 1 1\n").unwrap_err().to_string();
        assert!(e.contains(":1:") && e.contains("column 3"), "{e}");
        let e = table("500 1\n600 1 1\n").unwrap_err().to_string();
        assert!(e.contains("no column 3"), "{e}");
    }

    /// Layer columns add up to the profile's total column (US standard ozone, about 345 DU).
    #[test]
    fn layer_columns_sum_to_the_column() {
        let th = crate::atmosphere::thermo::load("afgl_1986-us_standard", Path::new(".")).unwrap();
        let z = &th.gas.altitude_m;
        let top = z[z.len() - 1];
        let grid: Vec<(f64, f64)> = (0..(top / 1e3) as usize)
            .map(|k| (k as f64 * 1e3, ((k + 1) as f64 * 1e3).min(top)))
            .collect();
        let cols = layer_columns(&th.gas, "O3", &grid).unwrap();
        let total: f64 = cols.iter().sum();
        let du = total / crate::atmosphere::thermo::DOBSON_UNIT;
        let whole = th.gas.column_density_m2("O3").unwrap();
        assert!((total / whole - 1.0).abs() < 1e-12, "{total} {whole}");
        assert!((330.0..360.0).contains(&du), "{du} DU");
        assert!(layer_columns(&th.gas, "XX", &grid)
            .unwrap_err()
            .to_string()
            .contains("no species `XX`"));
    }
}
