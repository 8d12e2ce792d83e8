//! The BRDF vocabulary shared by `landcover`, `scenegen` and `simulate`: one spec struct per
//! model and the tagged enum [`BrdfSpec`] over them (`spec.rs`: as written in bundle
//! manifests, land-cover schemes, region files, experiment materials and the experiment's 1D
//! `[surface]`), the one [`Spectrum`] type of every spectral parameter (`spectrum.rs`), **the
//! one table of allowed parameter ranges**, [`BRDF_PARAM_RANGES`] (`spec.rs`, with the
//! interval types of `range.rs`), and [`BrdfSpec::validate`] here.
//!
//! The simulator's surface models (`engine/src/bsdf/*.rs`) check their constructor arguments
//! against this same table, so a material that passes [`BrdfSpec::validate`] builds at every
//! wavelength, and scenegen and landcover cannot accept what `simulate` refuses.
//!
//! Spectra are piecewise linear with constant ends, so a spectrum lies within a (convex) range at
//! every wavelength exactly when all its table values do; likewise `reflectance + transmittance`
//! of a `bi_lambertian` material is checked at the union of both tables' wavelengths (and value
//! by value for per-wavelength lists; a list beside a table is checked by the simulator at the
//! run's wavelengths).

mod range;
mod spec;
mod spectrum;

use std::fmt;

pub use range::{ParamRange, Range};
pub use spec::*;
pub use spectrum::Spectrum;

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

impl BrdfSpec {
    /// Checks every parameter against [`BRDF_PARAM_RANGES`] (at every value of a tabulated
    /// spectrum or a list) and the shape of every spectrum; returns all violations, each naming
    /// the parameter, its value (with the wavelength for tables) and the allowed range.
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
        if let BrdfSpec::Tabulated(TabulatedSpec { file, .. }) = self {
            if file.trim().is_empty() || file.contains('\0') {
                violations.push(BrdfViolation::File {
                    message: format!("{file:?} is not a file name"),
                });
            }
        }
        if let (
            BrdfSpec::BiLambertian(BiLambertianSpec {
                reflectance,
                transmittance,
            }),
            true,
        ) = (self, violations.is_empty())
        {
            let sum = if reflectance.is_per_wavelength() || transmittance.is_per_wavelength() {
                list_sum_above_one(reflectance, transmittance)
            } else {
                table_sum_above_one(reflectance, transmittance)
            };
            violations.extend(sum);
        }
        if violations.is_empty() {
            Ok(())
        } else {
            Err(BrdfError { brdf, violations })
        }
    }

    /// [`BrdfSpec::validate`] for a spec stored without a run (bundle manifests, land-cover
    /// schemes, region files): a per-wavelength list is refused there, since its values are
    /// tied to the wavelengths of one experiment.
    pub fn validate_stored(&self) -> Result<(), BrdfError> {
        let lists: Vec<BrdfViolation> = self
            .params()
            .into_iter()
            .filter(|(_, s)| s.is_per_wavelength())
            .map(|(param, _)| BrdfViolation::Spectrum {
                param,
                message: "a list of values (one per run wavelength) is only meaningful in an experiment file; give a number or a table { wavelengths_nm, values }".into(),
            })
            .collect();
        match (self.validate(), lists.is_empty()) {
            (r, true) => r,
            (Ok(()), false) => Err(BrdfError {
                brdf: self.type_name(),
                violations: lists,
            }),
            (Err(mut e), false) => {
                e.violations.extend(lists);
                Err(e)
            }
        }
    }
}

/// `reflectance + transmittance` of two constants or tables, at the union of their
/// wavelengths; `None` when it stays within [`BI_LAMBERTIAN_MAX_SUM`].
fn table_sum_above_one(reflectance: &Spectrum, transmittance: &Spectrum) -> Option<BrdfViolation> {
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
    probes.into_iter().find_map(|w| {
        let at = |s: &Spectrum| w.map_or_else(|| s.at(0.0), |w| s.at(w));
        let (r, t) = (at(reflectance), at(transmittance));
        (r + t > BI_LAMBERTIAN_MAX_SUM).then_some(BrdfViolation::SumAboveOne {
            reflectance: r,
            transmittance: t,
            wavelength_nm: w,
        })
    })
}

/// `reflectance + transmittance` of two per-wavelength lists (or a list and a constant), value
/// by value; `None` when it stays within [`BI_LAMBERTIAN_MAX_SUM`] or cannot be checked here.
fn list_sum_above_one(r: &Spectrum, t: &Spectrum) -> Option<BrdfViolation> {
    let values = |s: &Spectrum, n: usize| -> Option<Vec<f64>> {
        match s {
            Spectrum::PerWavelength(l) => Some(l.clone()),
            Spectrum::Constant(v) => Some(vec![*v; n]),
            Spectrum::Table { .. } => None,
        }
    };
    let n = match (r, t) {
        (Spectrum::PerWavelength(a), _) => a.len(),
        (_, Spectrum::PerWavelength(b)) => b.len(),
        _ => return None,
    };
    let (rv, tv) = (values(r, n)?, values(t, n)?);
    rv.iter()
        .zip(&tv)
        .find(|(a, b)| *a + *b > BI_LAMBERTIAN_MAX_SUM)
        .map(|(a, b)| BrdfViolation::SumAboveOne {
            reflectance: *a,
            transmittance: *b,
            wavelength_nm: None,
        })
}

#[cfg(test)]
mod tests {
    use super::spec::every_type;
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
        let rpv = |k: Spectrum, g: f64| {
            BrdfSpec::Rpv(RpvSpec {
                rho_0: c(0.1),
                k,
                g: c(g),
                rho_c: None,
            })
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
        let e = BrdfSpec::Hapke(HapkeSpec {
            w: c(0.5),
            b: c(0.3),
            c: c(0.4),
            theta: c(90.0),
            b_0: c(0.8),
            h: c(0.06),
        })
        .validate()
        .unwrap_err();
        assert_eq!(e.to_string(), "hapke: `theta` = 90 deg must lie in [0, 90)");
        let e = BrdfSpec::Ocean(OceanSpec {
            wind_speed: c(50.0),
            refractive_index: None,
            shadowing: true,
        })
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
        let leaf = |r: Spectrum, t: Spectrum| {
            BrdfSpec::BiLambertian(BiLambertianSpec {
                reflectance: r,
                transmittance: t,
            })
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
            BrdfSpec::Tabulated(TabulatedSpec {
                file: "brdf/sand.nc".into(),
                symmetrize: false
            })
        );
        assert_eq!(t.type_name(), "tabulated");
        assert!(t.validate().is_ok());
        let back: BrdfSpec = toml::from_str(&toml::to_string(&t).unwrap()).unwrap();
        assert_eq!(back, t);
        let e = BrdfSpec::Tabulated(TabulatedSpec {
            file: " ".into(),
            symmetrize: true,
        })
        .validate()
        .unwrap_err();
        assert_eq!(e.to_string(), "tabulated: `file`: \" \" is not a file name");
        assert_eq!(e.violations[0].param(), "file");
        assert!(
            toml::from_str::<BrdfSpec>("type = \"tabulated\"\nfile = \"a.nc\"\nfle = 1").is_err()
        );
    }

    /// Rationale: a per-wavelength list is checked value by value (range, leaf sum) in an
    /// experiment, and refused where no run's wavelengths exist (manifests, schemes); every
    /// model must read from the same TOML in every place, `rtls_hotspot` with its default ξ0.
    #[test]
    fn lists_are_checked_and_refused_where_stored() {
        let list = |v: &[f64]| Spectrum::PerWavelength(v.to_vec());
        let lamb = BrdfSpec::Lambertian(LambertianSpec {
            reflectance: list(&[0.2, 0.3]),
        });
        assert!(lamb.validate().is_ok());
        let e = lamb.validate_stored().unwrap_err();
        assert!(
            e.to_string().contains("only meaningful in an experiment"),
            "{e}"
        );
        let e = BrdfSpec::Lambertian(LambertianSpec {
            reflectance: list(&[0.2, 1.3]),
        })
        .validate()
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            "lambertian: `reflectance` = 1.3 must lie in [0, 1]"
        );
        let e = BrdfSpec::BiLambertian(BiLambertianSpec {
            reflectance: list(&[0.4, 0.6]),
            transmittance: c(0.45),
        })
        .validate()
        .unwrap_err();
        assert!(e.to_string().contains("0.6 + 0.45"), "{e}");
        let h: BrdfSpec =
            toml::from_str("type = \"rtls_hotspot\"\nf_iso = 0.2\nf_vol = 0.1\nf_geo = 0.05")
                .unwrap();
        match &h {
            BrdfSpec::RtlsHotspot(s) => assert_eq!(s.xi0, c(DEFAULT_XI0_DEG)),
            other => panic!("{other:?}"),
        }
        assert!(h.validate_stored().is_ok());
        assert!(toml::from_str::<BrdfSpec>(
            "type = \"rpv\"\nrho_0 = 0.1\nk = 0.5\ng = 0.0\nrh_c = 1"
        )
        .is_err());
        for spec in every_type() {
            let text = toml::to_string(&spec).unwrap();
            let back: BrdfSpec = toml::from_str(&text).unwrap();
            assert_eq!(back, spec, "{text}");
        }
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
