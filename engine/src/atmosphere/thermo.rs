//! Thermophysical profiles of molecular atmospheres: where they come from, and rescaling of
//! column amounts.
//!
//! A profile gives, on levels of increasing altitude, the air pressure, temperature, number
//! density and the mole fractions of the absorbing species. The Rayleigh part of a molecular
//! atmosphere needs only the number density; gas absorption from an absorption database needs
//! p, T and the mole fractions ([`crate::absorption`]).
//!
//! ## Sources (config key `atmosphere.profile`)
//!
//! | value | what |
//! |---|---|
//! | `"afgl_1986-<name>"` | one of the six embedded AFGL 1986 profiles (Anderson et al. 1986, AFGL-TR-86-0110): tables 1a–1f (z, p, T, n, H2O, O3, N2O, CO, CH4) with CO2 and O2 from table 2a, as joseki assembles them |
//! | `"*.nc"` | a joseki / Eradiate netCDF profile: `z` (km), `p` (Pa), `t` (K), optional `n` (m⁻³), `x_<SP>` mole fractions (e.g. the Libya-4 CAMS profile `shared/data/eradiate/thermoprops/cams_lybia4_2005-04-01.nc`) |
//! | `"*.csv"` | a user table, see below |
//!
//! User CSV tables (comment lines start with `#`): a header naming the columns, then one row per
//! level, altitudes increasing or decreasing. Columns, with their unit in the name:
//! `z_km` (required), `p_pa` or `p_hpa` (required), `t_k` (required), `n_m3` (optional; air
//! number density, else p / k_B T), and any number of species as `x_<SP>` (mole fraction) or
//! `<SP>_ppmv`. Every value must be finite and non-negative (altitudes may be negative).
//!
//! ## Rescaling (config table `atmosphere.rescale`)
//!
//! `{ O3 = "300 DU", H2O = "2.5 g/cm^2", CO2 = "420 ppmv", CH4 = 1.1 }` multiplies each named
//! species' mole fraction at every level by one factor, chosen so that:
//!
//! | value | the result has |
//! |---|---|
//! | a number f ≥ 0 | f times the profile's amount |
//! | `"<v> DU"` | a column of v Dobson units (1 DU = 2.686 7·10²⁰ molecules m⁻²) |
//! | `"<v> g/cm^2"`, `"<v> kg/m^2"` | a column mass of v (1 g/cm² of water = 1 cm precipitable water) |
//! | `"<v> molec/cm^2"`, `"<v> molec/m^2"` | a column number density of v |
//! | `"<v> ppmv"` | a mole fraction of v·10⁻⁶ at the lowest level |
//!
//! Columns are integrated over the whole profile with x·n linear in altitude between levels
//! (the representation absorption uses). Molar masses: H2O 18.015, CO2 44.009, O3 47.998,
//! N2O 44.013, CO 28.010, CH4 16.043, O2 31.998, NO 30.006, SO2 64.066, NO2 46.006 g/mol.

use std::collections::BTreeMap;
use std::path::Path;

use serde::Deserialize;

use super::molecular::{Profile, PROFILES};
use super::ProfileError;
use crate::absorption::profile::AltitudeOrderError;
use crate::absorption::AtmosphereProfile;

/// What is wrong in a CSV profile table (a user table, or an embedded AFGL one). Lines are
/// 1-based lines of the text; rows are 1-based data rows.
#[derive(Debug, thiserror::Error)]
pub enum TableError {
    #[error("no header line")]
    NoHeader,
    #[error("line {line}: {fields} fields for {columns} columns")]
    FieldCount {
        line: usize,
        fields: usize,
        columns: usize,
    },
    #[error("line {line}: column `{column}`: `{value}` is not a number")]
    NotANumber {
        line: usize,
        column: String,
        value: String,
    },
    #[error("line {line}: column `{column}`: {value} is not finite")]
    NotFinite {
        line: usize,
        column: String,
        value: f64,
    },
    /// `header`: the table's header, comma-separated.
    #[error("needs a column `{column}` (header: {header})")]
    MissingColumn { column: String, header: String },
    #[error("give `p_pa` or `p_hpa`, not both")]
    BothPressures,
    #[error("needs a column `p_pa` (or `p_hpa`)")]
    NoPressure,
    #[error("species {species} is given twice")]
    DuplicateSpecies { species: String },
    #[error(
        "unknown column `{column}` (expected z_km, p_pa or p_hpa, t_k, n_m3, x_<species> or <species>_ppmv)"
    )]
    UnknownColumn { column: String },
    #[error("needs at least two levels")]
    TooFewLevels,
    #[error("column `{column}` is negative at row {row}")]
    Negative { column: String, row: usize },
    #[error("column `z_km`: {source}")]
    Altitudes { source: AltitudeOrderError },
}

/// A column amount of `atmosphere.rescale` (`"300 DU"`) that does not parse.
#[derive(Debug, thiserror::Error)]
pub enum AmountError {
    #[error("\"{value}\" has no unit (write e.g. \"300 DU\", or a plain number for a factor)")]
    NoUnit { value: String },
    #[error("\"{value}\": `{number}` is not a number")]
    NotANumber { value: String, number: String },
    #[error("\"{value}\": {amount} must be finite and non-negative")]
    Negative { value: String, amount: f64 },
}

/// Table 2a of AFGL 1986 (species common to the six profiles); CO2 and O2 are taken from it.
const TABLE_2A: &str = include_str!("../../data/afgl_1986/table_2a.csv");

const AVOGADRO: f64 = 6.022_140_76e23;
/// Molecules per m² in one Dobson unit.
pub const DOBSON_UNIT: f64 = 2.686_7e20;

/// A profile for both uses: Rayleigh (z, n) and absorption (p, T, x).
#[derive(Clone, Debug)]
pub struct Thermo {
    pub rayleigh: Profile,
    pub gas: AtmosphereProfile,
    /// Whether this is the embedded AFGL US standard profile, unscaled (what precomputed
    /// k(z) files are valid for).
    pub is_us_standard: bool,
}

/// One `atmosphere.rescale` value.
#[derive(Clone, Debug, Deserialize)]
#[serde(untagged)]
pub enum RescaleValue {
    Factor(f64),
    Amount(String),
}

/// Load the profile named by `spec` (embedded name, or a `.nc`/`.csv` path relative to `base`).
pub fn load(spec: &str, base: &Path) -> Result<Thermo, ProfileError> {
    if PROFILES.iter().any(|(n, _)| *n == spec) {
        let rayleigh = Profile::builtin(spec)?;
        let gas = builtin_gas(spec)?;
        return Ok(Thermo {
            rayleigh,
            gas,
            is_us_standard: spec == "afgl_1986-us_standard",
        });
    }
    let lower = spec.to_ascii_lowercase();
    let path = base.join(spec);
    let gas = if lower.ends_with(".nc") {
        AtmosphereProfile::open(&path).map_err(ProfileError::Netcdf)?
    } else if lower.ends_with(".csv") {
        let text = std::fs::read_to_string(&path).map_err(|source| ProfileError::Read {
            path: path.clone(),
            source,
        })?;
        from_user_csv(&path.display().to_string(), &text).map_err(|source| {
            ProfileError::UserTable {
                path: path.clone(),
                source,
            }
        })?
    } else {
        return Err(ProfileError::UnknownSpec {
            spec: spec.to_string(),
            known: PROFILES.iter().map(|p| p.0).collect(),
        });
    };
    let n = gas.air_number_density();
    if n.iter().any(|v| *v <= 0.0) {
        return Err(ProfileError::NonPositiveDensity {
            path: gas.path.clone(),
        });
    }
    let rayleigh = Profile {
        name: spec.to_string(),
        z: gas.altitude_m.clone(),
        n,
    };
    Ok(Thermo {
        rayleigh,
        gas,
        is_us_standard: false,
    })
}

/// The embedded AFGL profile `name` with its species (ppmv → mole fractions, mb → Pa).
fn builtin_gas(name: &str) -> Result<AtmosphereProfile, ProfileError> {
    let (_, text) = PROFILES
        .iter()
        .find(|(n, _)| *n == name)
        .ok_or_else(|| ProfileError::UnknownEmbedded { name: name.into() })?;
    let embedded = |source| ProfileError::EmbeddedTable {
        name: name.into(),
        source,
    };
    let t1 = parse_csv(text).map_err(embedded)?;
    let t2 = parse_csv(TABLE_2A).map_err(embedded)?;
    let col = |t: &Csv, c: &str| -> Result<Vec<f64>, ProfileError> {
        t.column(c).ok_or_else(|| ProfileError::EmbeddedColumn {
            name: name.into(),
            column: c.into(),
        })
    };
    let z: Vec<f64> = col(&t1, "z")?.iter().map(|v| v * 1e3).collect();
    if col(&t2, "z")? != col(&t1, "z")? {
        return Err(ProfileError::EmbeddedLevels { name: name.into() });
    }
    let mut x = Vec::new();
    for sp in ["H2O", "O3", "N2O", "CO", "CH4"] {
        x.push((
            sp.to_string(),
            col(&t1, sp)?.iter().map(|v| v * 1e-6).collect(),
        ));
    }
    for sp in ["CO2", "O2"] {
        x.push((
            sp.to_string(),
            col(&t2, sp)?.iter().map(|v| v * 1e-6).collect(),
        ));
    }
    Ok(AtmosphereProfile {
        path: format!("embedded {name}"),
        altitude_m: z,
        pressure_pa: col(&t1, "p")?.iter().map(|v| v * 100.0).collect(),
        temperature_k: col(&t1, "t")?,
        number_density_m3: Some(col(&t1, "n")?.iter().map(|v| v * 1e6).collect()),
        mole_fractions: x,
    })
}

struct Csv {
    header: Vec<String>,
    rows: Vec<Vec<f64>>,
}

impl Csv {
    fn column(&self, name: &str) -> Option<Vec<f64>> {
        let i = self
            .header
            .iter()
            .position(|h| h.eq_ignore_ascii_case(name))?;
        Some(self.rows.iter().map(|r| r[i]).collect())
    }
}

fn parse_csv(text: &str) -> Result<Csv, TableError> {
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    let (_, head) = lines.next().ok_or(TableError::NoHeader)?;
    let header: Vec<String> = head.split(',').map(|h| h.trim().to_string()).collect();
    let mut rows = Vec::new();
    for (k, l) in lines {
        let f: Vec<&str> = l.split(',').map(str::trim).collect();
        if f.len() != header.len() {
            return Err(TableError::FieldCount {
                line: k + 1,
                fields: f.len(),
                columns: header.len(),
            });
        }
        let mut row = Vec::with_capacity(f.len());
        for (c, v) in f.iter().enumerate() {
            let x: f64 = v.parse().map_err(|_| TableError::NotANumber {
                line: k + 1,
                column: header[c].clone(),
                value: v.to_string(),
            })?;
            if !x.is_finite() {
                return Err(TableError::NotFinite {
                    line: k + 1,
                    column: header[c].clone(),
                    value: x,
                });
            }
            row.push(x);
        }
        rows.push(row);
    }
    Ok(Csv { header, rows })
}

/// A user table (format in the module header).
pub fn from_user_csv(path: &str, text: &str) -> Result<AtmosphereProfile, TableError> {
    let text = crate::util::without_bom(text);
    let t = parse_csv(text)?;
    let need = |c: &str| {
        t.column(c).ok_or_else(|| TableError::MissingColumn {
            column: c.into(),
            header: t.header.join(","),
        })
    };
    let z: Vec<f64> = need("z_km")?.iter().map(|v| v * 1e3).collect();
    let p: Vec<f64> = match (t.column("p_pa"), t.column("p_hpa")) {
        (Some(p), None) => p,
        (None, Some(p)) => p.iter().map(|v| v * 100.0).collect(),
        (Some(_), Some(_)) => return Err(TableError::BothPressures),
        (None, None) => return Err(TableError::NoPressure),
    };
    let tk = need("t_k")?;
    let n = t.column("n_m3");
    let mut x = Vec::new();
    for h in &t.header {
        let sp = if let Some(s) = h.strip_prefix("x_") {
            Some((s.to_string(), 1.0))
        } else {
            h.strip_suffix("_ppmv").map(|s| (s.to_string(), 1e-6))
        };
        if let Some((sp, f)) = sp {
            if x.iter().any(|(s, _): &(String, Vec<f64>)| *s == sp) {
                return Err(TableError::DuplicateSpecies { species: sp });
            }
            let v = t.column(h).unwrap();
            x.push((sp, v.iter().map(|v| v * f).collect()));
        } else if !["z_km", "p_pa", "p_hpa", "t_k", "n_m3"]
            .iter()
            .any(|k| h.eq_ignore_ascii_case(k))
        {
            return Err(TableError::UnknownColumn { column: h.clone() });
        }
    }
    if z.len() < 2 {
        return Err(TableError::TooFewLevels);
    }
    let named = |name: &str, v: &[f64]| -> Result<(), TableError> {
        match v.iter().position(|x| *x < 0.0) {
            Some(i) => Err(TableError::Negative {
                column: name.into(),
                row: i + 1,
            }),
            None => Ok(()),
        }
    };
    named("p", &p)?;
    named("t_k", &tk)?;
    if let Some(n) = &n {
        named("n_m3", n)?;
    }
    for (sp, v) in &x {
        named(sp, v)?;
    }
    let mut prof = AtmosphereProfile {
        path: path.to_string(),
        altitude_m: z,
        pressure_pa: p,
        temperature_k: tk,
        number_density_m3: n,
        mole_fractions: x,
    };
    prof.make_ascending()
        .map_err(|source| TableError::Altitudes { source })?;
    Ok(prof)
}

/// Molar mass [kg/mol] of a species, for column masses.
fn molar_mass(species: &str) -> Option<f64> {
    Some(
        match species {
            "H2O" => 18.015,
            "CO2" => 44.009,
            "O3" => 47.998,
            "N2O" => 44.013,
            "CO" => 28.010,
            "CH4" => 16.043,
            "O2" => 31.998,
            "NO" => 30.006,
            "SO2" => 64.066,
            "NO2" => 46.006,
            _ => return None,
        } * 1e-3,
    )
}

/// Apply `atmosphere.rescale`; returns (species, factor) in key order. Errors are
/// (config key, message).
pub fn rescale(
    thermo: &mut Thermo,
    rules: &BTreeMap<String, RescaleValue>,
) -> Result<Vec<(String, f64)>, (String, String)> {
    let mut applied = Vec::new();
    for (sp, value) in rules {
        let key = format!("atmosphere.rescale.{sp}");
        let prof = &thermo.gas;
        let Some(x) = prof.mole_fraction(sp) else {
            let have: Vec<&str> = prof
                .mole_fractions
                .iter()
                .map(|(s, _)| s.as_str())
                .collect();
            return Err((
                key,
                format!(
                    "the profile {} has no species {sp} (it has {})",
                    prof.path,
                    have.join(", ")
                ),
            ));
        };
        let column = prof.column_density_m2(sp).unwrap_or(0.0);
        let bad = |m: String| Err((key.clone(), m));
        let factor = match value {
            RescaleValue::Factor(f) => {
                if !(f.is_finite() && *f >= 0.0) {
                    return bad(format!("factor {f} must be finite and non-negative"));
                }
                *f
            }
            RescaleValue::Amount(s) => {
                let (v, unit) = parse_amount(s).map_err(|e| (key.clone(), e.to_string()))?;
                let target = match unit.as_str() {
                    "du" => Target::Column(v * DOBSON_UNIT),
                    "molec/cm^2" | "molecules/cm^2" => Target::Column(v * 1e4),
                    "molec/m^2" | "molecules/m^2" => Target::Column(v),
                    "g/cm^2" | "kg/m^2" => {
                        let Some(m) = molar_mass(sp) else {
                            return bad(format!(
                                "no molar mass is known for {sp}; give the column in DU or molec/m^2"
                            ));
                        };
                        let kg_m2 = if unit == "g/cm^2" { v * 10.0 } else { v };
                        Target::Column(kg_m2 / m * AVOGADRO)
                    }
                    "ppmv" | "ppm" => Target::Surface(v * 1e-6),
                    _ => {
                        return bad(format!(
                            "unknown unit `{unit}` in \"{s}\" (use DU, g/cm^2, kg/m^2, molec/cm^2, molec/m^2, ppmv, or a plain factor)"
                        ))
                    }
                };
                let (have, want) = match target {
                    Target::Column(c) => (column, c),
                    Target::Surface(x1) => (x[0], x1),
                };
                if want == 0.0 {
                    0.0
                } else if have <= 0.0 {
                    return bad(format!(
                        "the profile holds no {sp}, so it cannot be rescaled to \"{s}\""
                    ));
                } else {
                    want / have
                }
            }
        };
        let gas = &mut thermo.gas;
        let (_, xs) = gas
            .mole_fractions
            .iter_mut()
            .find(|(s, _)| s == sp)
            .expect("checked above");
        for v in xs.iter_mut() {
            *v *= factor;
        }
        if let Some((i, v)) = xs.iter().enumerate().find(|(_, v)| **v > 1.0) {
            return bad(format!(
                "rescaling by {factor:.4} makes the {sp} mole fraction {v:.3} > 1 at {} km",
                gas.altitude_m[i] / 1e3
            ));
        }
        if factor != 1.0 {
            thermo.is_us_standard = false;
        }
        tracing::info!(
            "rescaled {sp} by {factor:.6} (column {:.6e} → {:.6e} molecules/m², {:.2} → {:.2} DU)",
            column,
            column * factor,
            column / DOBSON_UNIT,
            column * factor / DOBSON_UNIT
        );
        applied.push((sp.clone(), factor));
    }
    Ok(applied)
}

enum Target {
    Column(f64),
    Surface(f64),
}

/// "300 DU" → (300, "du"); units lower-cased with spaces removed.
fn parse_amount(s: &str) -> Result<(f64, String), AmountError> {
    let t = s.trim();
    let split = t
        .find(|c: char| c.is_ascii_alphabetic() && c != 'e' && c != 'E')
        .or_else(|| t.find(' '))
        .ok_or_else(|| AmountError::NoUnit { value: s.into() })?;
    let (num, unit) = t.split_at(split);
    let v: f64 = num.trim().parse().map_err(|_| AmountError::NotANumber {
        value: s.into(),
        number: num.trim().into(),
    })?;
    if !(v.is_finite() && v >= 0.0) {
        return Err(AmountError::Negative {
            value: s.into(),
            amount: v,
        });
    }
    let unit: String = unit
        .chars()
        .filter(|c| !c.is_whitespace())
        .collect::<String>()
        .to_ascii_lowercase()
        .replace("cm-2", "/cm^2")
        .replace("m-2", "/m^2");
    Ok((v, unit))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The embedded US standard profile's columns match the literature: O3 ≈ 345 DU, H2O ≈
    /// 1.42 g/cm² (AFGL 1986 tables, Anderson et al. 1986 Table 3: 343.8 DU, 1.4 g/cm²), and
    /// rescaling hits its targets exactly.
    #[test]
    fn us_standard_columns_and_rescaling() {
        let mut th = load("afgl_1986-us_standard", Path::new(".")).unwrap();
        assert!(th.is_us_standard);
        let o3 = th.gas.column_density_m2("O3").unwrap() / DOBSON_UNIT;
        let h2o = th.gas.column_density_m2("H2O").unwrap() * 18.015e-3 / AVOGADRO / 10.0;
        assert!((o3 - 345.0).abs() < 8.0, "O3 {o3} DU");
        assert!((h2o - 1.42).abs() < 0.05, "H2O {h2o} g/cm2");
        let mut rules = BTreeMap::new();
        rules.insert("O3".to_string(), RescaleValue::Amount("300 DU".into()));
        rules.insert("H2O".to_string(), RescaleValue::Amount("2.5 g/cm^2".into()));
        rules.insert("CO2".to_string(), RescaleValue::Amount("420 ppmv".into()));
        rules.insert("CH4".to_string(), RescaleValue::Factor(2.0));
        let ch4 = th.gas.column_density_m2("CH4").unwrap();
        let f = rescale(&mut th, &rules).unwrap();
        assert_eq!(f.len(), 4);
        assert!(!th.is_us_standard);
        let o3 = th.gas.column_density_m2("O3").unwrap() / DOBSON_UNIT;
        assert!((o3 - 300.0).abs() < 1e-9, "{o3}");
        let h2o = th.gas.column_density_m2("H2O").unwrap() * 18.015e-3 / AVOGADRO / 10.0;
        assert!((h2o - 2.5).abs() < 1e-9, "{h2o}");
        assert!((th.gas.mole_fraction("CO2").unwrap()[0] - 420e-6).abs() < 1e-15);
        let r = th.gas.column_density_m2("CH4").unwrap() / ch4;
        assert!((r - 2.0).abs() < 1e-12);
        // The Rayleigh part is untouched and equal to the embedded one.
        let plain = Profile::builtin("afgl_1986-us_standard").unwrap();
        assert_eq!(th.rayleigh.n, plain.n);
    }

    #[test]
    fn bad_rescaling_is_named() {
        let mut th = load("afgl_1986-tropical", Path::new(".")).unwrap();
        for (sp, v, want) in [
            ("XYZ", RescaleValue::Factor(1.0), "no species XYZ"),
            (
                "O3",
                RescaleValue::Amount("300 furlongs".into()),
                "unknown unit",
            ),
            ("O3", RescaleValue::Amount("DU".into()), "not a number"),
            ("O3", RescaleValue::Factor(-1.0), "non-negative"),
            ("O2", RescaleValue::Factor(10.0), "> 1"),
        ] {
            let mut rules = BTreeMap::new();
            rules.insert(sp.to_string(), v);
            let (key, msg) = rescale(&mut th, &rules).unwrap_err();
            assert_eq!(key, format!("atmosphere.rescale.{sp}"));
            assert!(msg.contains(want), "{msg}");
        }
    }

    /// A user table: units from the column names, descending altitudes accepted, n from the
    /// ideal gas law when absent; bad tables name the line or column.
    #[test]
    fn user_tables() {
        let text = "# test\nz_km,p_hpa,t_k,H2O_ppmv,x_O3\n1,898.8,281.7,6070,3e-8\n0,1013.0,288.2,7750,2.66e-8\n";
        let p = from_user_csv("t.csv", text).unwrap();
        assert_eq!(p.altitude_m, vec![0.0, 1000.0]);
        assert_eq!(p.pressure_pa[0], 101300.0);
        assert!((p.mole_fraction("H2O").unwrap()[0] - 7.75e-3).abs() < 1e-15);
        let n = p.air_number_density();
        assert!((n[0] / (101300.0 / (1.380_649e-23 * 288.2)) - 1.0).abs() < 1e-12);
        for (bad, want) in [
            ("z_km,t_k\n0,288\n1,280\n", "p_pa"),
            (
                "z_km,p_pa,t_k,foo\n0,1,1,1\n1,1,1,1\n",
                "unknown column `foo`",
            ),
            ("z_km,p_pa,t_k\n0,1,x\n1,1,1\n", "line 2: column `t_k`"),
            ("z_km,p_pa,t_k\n0,1,1\n0,1,1\n", "strictly monotonic"),
            ("z_km,p_pa,t_k\n0,-1,1\n1,1,1\n", "negative"),
        ] {
            let e = from_user_csv("t.csv", bad).unwrap_err().to_string();
            assert!(e.contains(want), "{e}");
        }
    }
}
