//! The BRDF vocabulary shared by `landcover`, `scenegen` and `simulate`: [`BrdfSpec`] (a tagged
//! table with spectral parameters, as written in bundle manifests, land-cover schemes, region
//! files and experiment files) and **the one table of allowed parameter ranges**,
//! [`BRDF_PARAM_RANGES`], with [`BrdfSpec::validate`].
//!
//! The simulator's surface models (`engine/src/bsdf/*.rs`) check their constructor arguments
//! against this same table, so a material that passes [`BrdfSpec::validate`] builds at every
//! wavelength, and scenegen and landcover cannot accept what `simulate` refuses.
//!
//! Spectra are piecewise linear with constant ends, so a spectrum lies within a (convex) range at
//! every wavelength exactly when all its table values do; likewise `reflectance + transmittance`
//! of a `bi_lambertian` material is checked at the union of both tables' wavelengths.

use std::fmt;

use serde::{Deserialize, Serialize};

/// An interval of allowed values; each end closed or open.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Range {
    pub lo: f64,
    pub hi: f64,
    /// `lo` itself is excluded.
    pub lo_open: bool,
    /// `hi` itself is excluded.
    pub hi_open: bool,
}

impl Range {
    /// `[lo, hi]`.
    pub const fn closed(lo: f64, hi: f64) -> Self {
        Range {
            lo,
            hi,
            lo_open: false,
            hi_open: false,
        }
    }
    /// `[lo, hi)`.
    pub const fn closed_open(lo: f64, hi: f64) -> Self {
        Range {
            lo,
            hi,
            lo_open: false,
            hi_open: true,
        }
    }
    /// `(lo, hi)`.
    pub const fn open(lo: f64, hi: f64) -> Self {
        Range {
            lo,
            hi,
            lo_open: true,
            hi_open: true,
        }
    }
    /// Whether `v` lies in the range (never for NaN).
    pub fn contains(&self, v: f64) -> bool {
        let lo = if self.lo_open {
            v > self.lo
        } else {
            v >= self.lo
        };
        let hi = if self.hi_open {
            v < self.hi
        } else {
            v <= self.hi
        };
        lo && hi
    }
}

impl fmt::Display for Range {
    /// Interval notation: `[0, 2]`, `(-1, 1)`, `[0, 90)`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}{}, {}{}",
            if self.lo_open { '(' } else { '[' },
            self.lo,
            self.hi,
            if self.hi_open { ')' } else { ']' }
        )
    }
}

/// One row of [`BRDF_PARAM_RANGES`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamRange {
    /// The BRDF's `type` tag (`rpv`, …).
    pub brdf: &'static str,
    /// The parameter's key, as written in TOML (`rho_0`, `B_0`, …).
    pub param: &'static str,
    /// Unit ("" for dimensionless).
    pub unit: &'static str,
    pub range: Range,
}

impl ParamRange {
    /// `Err` with the message "`label` = v [unit] must lie in RANGE" when `v` is outside.
    /// `label` is how the caller names the parameter (usually [`ParamRange::param`]).
    pub fn check(&self, label: &str, v: f64) -> Result<(), String> {
        if self.range.contains(v) {
            Ok(())
        } else {
            let unit = if self.unit.is_empty() {
                String::new()
            } else {
                format!(" {}", self.unit)
            };
            Err(format!("`{label}` = {v}{unit} must lie in {}", self.range))
        }
    }
}

const fn row(
    brdf: &'static str,
    param: &'static str,
    unit: &'static str,
    range: Range,
) -> ParamRange {
    ParamRange {
        brdf,
        param,
        unit,
        range,
    }
}

/// Allowed values of every BRDF parameter, at every wavelength. The single source of truth:
/// the simulator's surface models (`engine/src/bsdf/`), land-cover schemes, region files and
/// the bundle reader and writer all check against it. The model files' `//!` headers say why
/// each range is what it is.
pub const BRDF_PARAM_RANGES: &[ParamRange] = &[
    row("lambertian", "reflectance", "", Range::closed(0.0, 1.0)),
    // bi_lambertian: also reflectance + transmittance ≤ BI_LAMBERTIAN_MAX_SUM.
    row("bi_lambertian", "reflectance", "", Range::closed(0.0, 1.0)),
    row(
        "bi_lambertian",
        "transmittance",
        "",
        Range::closed(0.0, 1.0),
    ),
    row("rpv", "rho_0", "", Range::closed(0.0, 1.0)),
    row("rpv", "k", "", Range::closed(0.0, 2.0)),
    row("rpv", "g", "", Range::open(-1.0, 1.0)),
    row("rpv", "rho_c", "", Range::closed(0.0, 1.0)),
    row("rtls", "f_iso", "", Range::closed(0.0, 2.0)),
    row("rtls", "f_vol", "", Range::closed(-1.0, 1.0)),
    row("rtls", "f_geo", "", Range::closed(-1.0, 1.0)),
    row("hapke", "w", "", Range::closed(0.0, 1.0)),
    row("hapke", "b", "", Range::closed_open(0.0, 1.0)),
    row("hapke", "c", "", Range::closed(0.0, 1.0)),
    row("hapke", "theta", "deg", Range::closed_open(0.0, 90.0)),
    row("hapke", "B_0", "", Range::closed(0.0, 1.0)),
    row("hapke", "h", "", Range::closed(0.0, 1.0)),
    row("ocean", "wind_speed", "m/s", Range::closed(0.0, 40.0)),
    row("ocean", "refractive_index", "", Range::closed(1.0, 3.0)),
];

/// Upper bound of `reflectance + transmittance` of a `bi_lambertian` material (energy).
pub const BI_LAMBERTIAN_MAX_SUM: f64 = 1.0;

/// The row of (`brdf`, `param`) in [`BRDF_PARAM_RANGES`].
pub fn param_range(brdf: &str, param: &str) -> Option<&'static ParamRange> {
    BRDF_PARAM_RANGES
        .iter()
        .find(|r| r.brdf == brdf && r.param == param)
}

/// Checks `v` against the row of (`brdf`, `param`); the message names `label`.
///
/// # Panics
/// If the table has no such row (a programming error, caught by the callers' tests).
pub fn check_param(brdf: &str, param: &str, label: &str, v: f64) -> Result<(), String> {
    param_range(brdf, param)
        .unwrap_or_else(|| panic!("no range for {brdf}.{param} in BRDF_PARAM_RANGES"))
        .check(label, v)
}

/// One thing wrong with a [`BrdfSpec`].
#[derive(Clone, Debug, PartialEq)]
pub enum BrdfViolation {
    /// A malformed spectrum (lengths, order of wavelengths, non-finite values).
    Spectrum {
        param: &'static str,
        message: String,
    },
    /// A value outside [`BRDF_PARAM_RANGES`]; `wavelength_nm` is set for tabulated spectra.
    OutOfRange {
        param: &'static str,
        value: f64,
        wavelength_nm: Option<f64>,
        range: ParamRange,
    },
    /// `tabulated`: the `file` key is not a usable path (the file itself is read and checked by
    /// the simulator, which names the variable at fault).
    File { message: String },
    /// `bi_lambertian`: reflectance + transmittance above [`BI_LAMBERTIAN_MAX_SUM`].
    SumAboveOne {
        reflectance: f64,
        transmittance: f64,
        wavelength_nm: Option<f64>,
    },
}

impl BrdfViolation {
    /// The parameter concerned (for key paths such as `materials.NAME.brdf.PARAM`);
    /// `transmittance` for the bi-Lambertian sum.
    pub fn param(&self) -> &'static str {
        match self {
            BrdfViolation::Spectrum { param, .. } | BrdfViolation::OutOfRange { param, .. } => {
                param
            }
            BrdfViolation::SumAboveOne { .. } => "transmittance",
            BrdfViolation::File { .. } => "file",
        }
    }
}

fn at_nm(w: Option<f64>) -> String {
    w.map_or(String::new(), |w| format!(" at {w} nm"))
}

impl fmt::Display for BrdfViolation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BrdfViolation::Spectrum { param, message } => write!(f, "`{param}`: {message}"),
            BrdfViolation::File { message } => write!(f, "`file`: {message}"),
            BrdfViolation::OutOfRange {
                param,
                value,
                wavelength_nm,
                range,
            } => {
                let unit = if range.unit.is_empty() {
                    String::new()
                } else {
                    format!(" {}", range.unit)
                };
                write!(
                    f,
                    "`{param}` = {value}{unit}{} must lie in {}",
                    at_nm(*wavelength_nm),
                    range.range
                )
            }
            BrdfViolation::SumAboveOne {
                reflectance,
                transmittance,
                wavelength_nm,
            } => write!(
                f,
                "the sum `reflectance` + `transmittance` = {reflectance} + {transmittance}{} must not exceed {BI_LAMBERTIAN_MAX_SUM}",
                at_nm(*wavelength_nm)
            ),
        }
    }
}

/// Everything wrong with a [`BrdfSpec`] (at least one violation).
#[derive(Clone, Debug, PartialEq)]
pub struct BrdfError {
    /// The BRDF's `type` tag.
    pub brdf: &'static str,
    pub violations: Vec<BrdfViolation>,
}

impl fmt::Display for BrdfError {
    /// `rpv: `k` = 5 must lie in [0, 2]; …`
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: ", self.brdf)?;
        for (i, v) in self.violations.iter().enumerate() {
            if i > 0 {
                write!(f, "; ")?;
            }
            write!(f, "{v}")?;
        }
        Ok(())
    }
}

impl std::error::Error for BrdfError {}

/// A reflectance-like quantity: one value at every wavelength, or a table (linear interpolation,
/// constant beyond the ends).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Spectrum {
    Constant(f64),
    Table {
        wavelengths_nm: Vec<f64>,
        values: Vec<f64>,
    },
}

impl Spectrum {
    /// Value at `wavelength_nm`.
    pub fn at(&self, wavelength_nm: f64) -> f64 {
        match self {
            Spectrum::Constant(v) => *v,
            Spectrum::Table {
                wavelengths_nm: w,
                values: v,
            } => {
                if w.is_empty() {
                    return f64::NAN;
                }
                if wavelength_nm <= w[0] {
                    return v[0];
                }
                if wavelength_nm >= w[w.len() - 1] {
                    return v[v.len() - 1];
                }
                let i = w.partition_point(|&x| x <= wavelength_nm) - 1;
                let t = (wavelength_nm - w[i]) / (w[i + 1] - w[i]);
                v[i] + t * (v[i + 1] - v[i])
            }
        }
    }

    /// The values that define the spectrum, with their wavelengths (`None` for a constant).
    pub fn points(&self) -> Vec<(Option<f64>, f64)> {
        match self {
            Spectrum::Constant(v) => vec![(None, *v)],
            Spectrum::Table {
                wavelengths_nm,
                values,
            } => wavelengths_nm
                .iter()
                .zip(values)
                .map(|(w, v)| (Some(*w), *v))
                .collect(),
        }
    }

    /// Checks: same lengths, increasing wavelengths, values finite. Returns a message.
    pub fn validate(&self) -> Result<(), String> {
        match self {
            Spectrum::Constant(v) if !v.is_finite() => Err(format!("value {v} is not finite")),
            Spectrum::Constant(_) => Ok(()),
            Spectrum::Table {
                wavelengths_nm: w,
                values: v,
            } => {
                if w.is_empty() || w.len() != v.len() {
                    return Err(format!(
                        "wavelengths_nm ({}) and values ({}) must be non-empty and of equal length",
                        w.len(),
                        v.len()
                    ));
                }
                if w.windows(2).any(|p| p[1] <= p[0]) {
                    return Err("wavelengths_nm must increase".into());
                }
                if v.iter().any(|x| !x.is_finite()) {
                    return Err("values must be finite".into());
                }
                Ok(())
            }
        }
    }
}

/// BRDF of a material, named as in the simulator's surface models (`docs/experiment.md`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum BrdfSpec {
    /// Lambertian, hemispherical reflectance in [0, 1].
    Lambertian { reflectance: Spectrum },
    /// Two-sided leaf: Lambertian reflection and transmission (reflectance + transmittance ≤ 1).
    BiLambertian {
        reflectance: Spectrum,
        transmittance: Spectrum,
    },
    /// Rahman–Pinty–Verstraete.
    Rpv {
        rho_0: Spectrum,
        k: Spectrum,
        g: Spectrum,
        #[serde(default)]
        rho_c: Option<Spectrum>,
    },
    /// Ross-Thick Li-Sparse (MODIS kernels).
    Rtls {
        f_iso: Spectrum,
        f_vol: Spectrum,
        f_geo: Spectrum,
    },
    /// Hapke (parameters as the simulator's `hapke` surface; `theta` in degrees).
    Hapke {
        w: Spectrum,
        b: Spectrum,
        c: Spectrum,
        theta: Spectrum,
        #[serde(rename = "B_0")]
        b_0: Spectrum,
        h: Spectrum,
    },
    /// Rough water surface (Cox–Munk, Fresnel; wind speed in m/s).
    Ocean {
        wind_speed: Spectrum,
        #[serde(default)]
        refractive_index: Option<Spectrum>,
        #[serde(default = "yes")]
        shadowing: bool,
    },
    /// A measured BRDF: a netCDF table over (wavelength, θi, θr, Δφ) in sr⁻¹, layout in the
    /// simulator's `bsdf/tabulated.rs` and `docs/experiment.md`. `file` is relative to the
    /// bundle folder (in a manifest) or to the experiment file (in an experiment's materials);
    /// `symmetrize` averages f(i, r) and f(r, i).
    Tabulated {
        file: String,
        #[serde(default)]
        symmetrize: bool,
    },
}

fn yes() -> bool {
    true
}

impl BrdfSpec {
    /// The `type` tag.
    pub fn type_name(&self) -> &'static str {
        match self {
            BrdfSpec::Lambertian { .. } => "lambertian",
            BrdfSpec::BiLambertian { .. } => "bi_lambertian",
            BrdfSpec::Rpv { .. } => "rpv",
            BrdfSpec::Rtls { .. } => "rtls",
            BrdfSpec::Hapke { .. } => "hapke",
            BrdfSpec::Ocean { .. } => "ocean",
            BrdfSpec::Tabulated { .. } => "tabulated",
        }
    }

    /// The parameters present, by key, in the order of the table.
    pub fn params(&self) -> Vec<(&'static str, &Spectrum)> {
        match self {
            BrdfSpec::Lambertian { reflectance } => vec![("reflectance", reflectance)],
            BrdfSpec::BiLambertian {
                reflectance,
                transmittance,
            } => vec![
                ("reflectance", reflectance),
                ("transmittance", transmittance),
            ],
            BrdfSpec::Rpv { rho_0, k, g, rho_c } => {
                let mut v = vec![("rho_0", rho_0), ("k", k), ("g", g)];
                if let Some(c) = rho_c {
                    v.push(("rho_c", c));
                }
                v
            }
            BrdfSpec::Rtls {
                f_iso,
                f_vol,
                f_geo,
            } => vec![("f_iso", f_iso), ("f_vol", f_vol), ("f_geo", f_geo)],
            BrdfSpec::Hapke {
                w,
                b,
                c,
                theta,
                b_0,
                h,
            } => vec![
                ("w", w),
                ("b", b),
                ("c", c),
                ("theta", theta),
                ("B_0", b_0),
                ("h", h),
            ],
            BrdfSpec::Ocean {
                wind_speed,
                refractive_index,
                ..
            } => {
                let mut v = vec![("wind_speed", wind_speed)];
                if let Some(n) = refractive_index {
                    v.push(("refractive_index", n));
                }
                v
            }
            // A table, not parameters: its values are checked when the simulator reads it.
            BrdfSpec::Tabulated { .. } => Vec::new(),
        }
    }

    /// Checks every parameter against [`BRDF_PARAM_RANGES`] (at every value of a tabulated
    /// spectrum) and the shape of every spectrum; returns all violations, each naming the
    /// parameter, its value (with the wavelength for tables) and the allowed range.
    pub fn validate(&self) -> Result<(), BrdfError> {
        let brdf = self.type_name();
        let mut violations = Vec::new();
        for (param, s) in self.params() {
            if let Err(message) = s.validate() {
                violations.push(BrdfViolation::Spectrum { param, message });
                continue;
            }
            let range = *param_range(brdf, param)
                .unwrap_or_else(|| panic!("no range for {brdf}.{param} in BRDF_PARAM_RANGES"));
            for (wavelength_nm, value) in s.points() {
                if !range.range.contains(value) {
                    violations.push(BrdfViolation::OutOfRange {
                        param,
                        value,
                        wavelength_nm,
                        range,
                    });
                    break;
                }
            }
        }
        if let BrdfSpec::Tabulated { file, .. } = self {
            if file.trim().is_empty() || file.contains('\0') {
                violations.push(BrdfViolation::File {
                    message: format!("{file:?} is not a file name"),
                });
            }
        }
        if let (
            BrdfSpec::BiLambertian {
                reflectance,
                transmittance,
            },
            true,
        ) = (self, violations.is_empty())
        {
            // Both piecewise linear with constant ends: their sum is linear between the union
            // of their wavelengths, so checking there is exact.
            let mut ws: Vec<f64> = reflectance
                .points()
                .into_iter()
                .chain(transmittance.points())
                .filter_map(|(w, _)| w)
                .collect();
            ws.sort_by(f64::total_cmp);
            ws.dedup();
            let probes: Vec<Option<f64>> = if ws.is_empty() {
                vec![None]
            } else {
                ws.into_iter().map(Some).collect()
            };
            for w in probes {
                let at = |s: &Spectrum| w.map_or_else(|| s.at(0.0), |w| s.at(w));
                let (r, t) = (at(reflectance), at(transmittance));
                if r + t > BI_LAMBERTIAN_MAX_SUM {
                    violations.push(BrdfViolation::SumAboveOne {
                        reflectance: r,
                        transmittance: t,
                        wavelength_nm: w,
                    });
                    break;
                }
            }
        }
        if violations.is_empty() {
            Ok(())
        } else {
            Err(BrdfError { brdf, violations })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn c(v: f64) -> Spectrum {
        Spectrum::Constant(v)
    }

    fn table(w: &[f64], v: &[f64]) -> Spectrum {
        Spectrum::Table {
            wavelengths_nm: w.to_vec(),
            values: v.to_vec(),
        }
    }

    /// One spec of every type with every optional parameter given.
    fn every_type() -> Vec<BrdfSpec> {
        vec![
            BrdfSpec::Lambertian {
                reflectance: c(0.2),
            },
            BrdfSpec::BiLambertian {
                reflectance: c(0.4),
                transmittance: c(0.5),
            },
            BrdfSpec::Rpv {
                rho_0: c(0.1),
                k: c(0.8),
                g: c(-0.1),
                rho_c: Some(c(0.3)),
            },
            BrdfSpec::Rtls {
                f_iso: c(0.2),
                f_vol: c(0.1),
                f_geo: c(0.05),
            },
            BrdfSpec::Hapke {
                w: c(0.5),
                b: c(0.3),
                c: c(0.4),
                theta: c(15.0),
                b_0: c(0.8),
                h: c(0.06),
            },
            BrdfSpec::Ocean {
                wind_speed: c(5.0),
                refractive_index: Some(c(1.33)),
                shadowing: true,
            },
            BrdfSpec::Tabulated {
                file: "brdf/sand.nc".into(),
                symmetrize: false,
            },
        ]
    }

    /// Rationale: the table is the one source of the ranges; a parameter without a row would
    /// escape every check, and a row without a parameter would be a stale rule.
    #[test]
    fn every_parameter_has_exactly_one_row_and_every_row_a_parameter() {
        let mut used = Vec::new();
        for spec in every_type() {
            spec.validate().unwrap();
            for (param, _) in spec.params() {
                let rows = BRDF_PARAM_RANGES
                    .iter()
                    .filter(|r| r.brdf == spec.type_name() && r.param == param)
                    .count();
                assert_eq!(rows, 1, "{}.{param}", spec.type_name());
                used.push((spec.type_name(), param));
            }
        }
        for r in BRDF_PARAM_RANGES {
            assert!(used.contains(&(r.brdf, r.param)), "stale row {r:?}");
        }
    }

    /// Rationale: each violation must name the parameter, its value (and wavelength for
    /// tables) and the allowed range, with open ends written as such; all violations of a spec
    /// are reported at once.
    #[test]
    fn violations_name_parameter_value_and_range() {
        let rpv = |k: Spectrum, g: f64| BrdfSpec::Rpv {
            rho_0: c(0.1),
            k,
            g: c(g),
            rho_c: None,
        };
        let e = rpv(c(5.0), 0.0).validate().unwrap_err();
        assert_eq!(e.to_string(), "rpv: `k` = 5 must lie in [0, 2]");
        assert_eq!(e.violations[0].param(), "k");
        assert!(rpv(c(2.0), -0.999).validate().is_ok());
        let e = rpv(c(3.0), 1.0).validate().unwrap_err();
        assert_eq!(
            e.to_string(),
            "rpv: `k` = 3 must lie in [0, 2]; `g` = 1 must lie in (-1, 1)"
        );
        let e = rpv(table(&[400.0, 800.0], &[0.5, 2.5]), 0.0)
            .validate()
            .unwrap_err();
        assert_eq!(e.to_string(), "rpv: `k` = 2.5 at 800 nm must lie in [0, 2]");
        let e = rpv(table(&[800.0, 400.0], &[0.5, 0.5]), 0.0)
            .validate()
            .unwrap_err();
        assert!(
            matches!(&e.violations[0], BrdfViolation::Spectrum { param: "k", .. }),
            "{e}"
        );
        let e = rpv(c(f64::NAN), 0.0).validate().unwrap_err();
        assert!(e.to_string().contains("`k`"), "{e}");
        let e = BrdfSpec::Hapke {
            w: c(0.5),
            b: c(0.3),
            c: c(0.4),
            theta: c(90.0),
            b_0: c(0.8),
            h: c(0.06),
        }
        .validate()
        .unwrap_err();
        assert_eq!(e.to_string(), "hapke: `theta` = 90 deg must lie in [0, 90)");
        let e = BrdfSpec::Ocean {
            wind_speed: c(50.0),
            refractive_index: None,
            shadowing: true,
        }
        .validate()
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            "ocean: `wind_speed` = 50 m/s must lie in [0, 40]"
        );
    }

    /// Rationale: reflectance + transmittance ≤ 1 must hold at every wavelength; both spectra
    /// are piecewise linear, so checking the union of their wavelengths is exact — a check at
    /// the nodes of one spectrum only would miss a peak of the other.
    #[test]
    fn bi_lambertian_sum_is_checked_on_the_union_of_wavelengths() {
        let leaf = |r: Spectrum, t: Spectrum| BrdfSpec::BiLambertian {
            reflectance: r,
            transmittance: t,
        };
        let e = leaf(
            table(&[400.0, 800.0], &[0.5, 0.5]),
            table(&[500.0, 600.0, 700.0], &[0.3, 0.6, 0.3]),
        )
        .validate()
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            "bi_lambertian: the sum `reflectance` + `transmittance` = 0.5 + 0.6 at 600 nm must not exceed 1"
        );
        assert_eq!(e.violations[0].param(), "transmittance");
        assert!(leaf(
            table(&[400.0, 800.0], &[0.3, 0.6]),
            table(&[400.0, 800.0], &[0.6, 0.3])
        )
        .validate()
        .is_ok());
        assert!(leaf(c(0.7), c(0.4)).validate().is_err());
        assert!(leaf(c(0.6), c(0.4)).validate().is_ok());
    }

    /// Rationale: a tabulated material names a file, which only the simulator can read; the
    /// bundle checks that the key is a file name and that the spec round-trips through TOML
    /// (manifests).
    #[test]
    fn tabulated_names_a_file() {
        let t: BrdfSpec = toml::from_str("type = \"tabulated\"\nfile = \"brdf/sand.nc\"").unwrap();
        assert_eq!(
            t,
            BrdfSpec::Tabulated {
                file: "brdf/sand.nc".into(),
                symmetrize: false
            }
        );
        assert_eq!(t.type_name(), "tabulated");
        assert!(t.validate().is_ok());
        let back: BrdfSpec = toml::from_str(&toml::to_string(&t).unwrap()).unwrap();
        assert_eq!(back, t);
        let e = BrdfSpec::Tabulated {
            file: " ".into(),
            symmetrize: true,
        }
        .validate()
        .unwrap_err();
        assert_eq!(e.to_string(), "tabulated: `file`: \" \" is not a file name");
        assert_eq!(e.violations[0].param(), "file");
        assert!(
            toml::from_str::<BrdfSpec>("type = \"tabulated\"\nfile = \"a.nc\"\nfle = 1").is_err()
        );
    }

    #[test]
    fn ranges_print_in_interval_notation() {
        assert_eq!(Range::closed(0.0, 2.0).to_string(), "[0, 2]");
        assert_eq!(Range::open(-1.0, 1.0).to_string(), "(-1, 1)");
        assert_eq!(Range::closed_open(0.0, 90.0).to_string(), "[0, 90)");
        assert!(!Range::open(-1.0, 1.0).contains(1.0));
        assert!(!Range::closed(0.0, 1.0).contains(f64::NAN));
        assert_eq!(
            check_param("rpv", "k", "k", 3.0).unwrap_err(),
            "`k` = 3 must lie in [0, 2]"
        );
    }
}
