//! [`Spectrum`]: the one type of every spectral parameter, in BRDF specs (bundle manifests,
//! land-cover schemes, region files, experiment materials and the experiment's `[surface]`) and
//! in the experiment's other per-wavelength keys (optical thicknesses, albedos, irradiances).
//!
//! Three forms, as written in TOML:
//! * a number: the same value at every wavelength;
//! * a list of numbers: one value per **run** wavelength, in the order of
//!   `spectral.wavelengths` (only meaningful in an experiment file; manifests and schemes, which
//!   do not know the run's wavelengths, refuse it: [`crate::BrdfSpec::validate_stored`]);
//! * a table `{ wavelengths_nm = [...], values = [...] }`: piecewise linear in wavelength (nm),
//!   constant beyond its ends.

use std::fmt;

use serde::{Deserialize, Serialize};

/// A spectral quantity (see the module header for its three forms).
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Spectrum {
    Constant(f64),
    /// One value per run wavelength (`spectral.wavelengths`, in order).
    PerWavelength(Vec<f64>),
    Table {
        wavelengths_nm: Vec<f64>,
        values: Vec<f64>,
    },
}

/// A number, a list of numbers or a `{ wavelengths_nm, values }` table; anything else is
/// "invalid type: string "abc", expected a number, a list of numbers (one per wavelength) or a
/// table { wavelengths_nm, values }", which names the value (an untagged enum would only say
/// that no variant matched, and the key could not be found).
impl<'de> Deserialize<'de> for Spectrum {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = Spectrum;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str(
                    "a number, a list of numbers (one per wavelength) or a table { wavelengths_nm, values }",
                )
            }
            fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<Spectrum, E> {
                Ok(Spectrum::Constant(v))
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<Spectrum, E> {
                Ok(Spectrum::Constant(v as f64))
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<Spectrum, E> {
                Ok(Spectrum::Constant(v as f64))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut seq: A,
            ) -> Result<Spectrum, A::Error> {
                let mut out = Vec::with_capacity(seq.size_hint().unwrap_or(0).min(1 << 16));
                while let Some(x) = seq.next_element::<f64>()? {
                    out.push(x);
                }
                Ok(Spectrum::PerWavelength(out))
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(self, map: A) -> Result<Spectrum, A::Error> {
                #[derive(Deserialize)]
                #[serde(deny_unknown_fields)]
                struct Table {
                    wavelengths_nm: Vec<f64>,
                    values: Vec<f64>,
                }
                let t = Table::deserialize(serde::de::value::MapAccessDeserializer::new(map))?;
                Ok(Spectrum::Table {
                    wavelengths_nm: t.wavelengths_nm,
                    values: t.values,
                })
            }
        }
        d.deserialize_any(V)
    }
}

impl Spectrum {
    /// Value at run wavelength `iw` (`wavelength_nm`, nm): the list's `iw`-th value for a
    /// per-wavelength list (NaN past its end: lengths are checked by [`Spectrum::check_len`]
    /// before), else [`Spectrum::at`].
    pub fn at_run(&self, iw: usize, wavelength_nm: f64) -> f64 {
        match self {
            Spectrum::PerWavelength(l) => l.get(iw).copied().unwrap_or(f64::NAN),
            _ => self.at(wavelength_nm),
        }
    }

    /// Value at `wavelength_nm` of a constant or a table; NaN for a per-wavelength list, which
    /// has no wavelengths of its own (use [`Spectrum::at_run`]).
    pub fn at(&self, wavelength_nm: f64) -> f64 {
        match self {
            Spectrum::Constant(v) => *v,
            Spectrum::PerWavelength(_) => f64::NAN,
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

    /// Whether this is the per-run-wavelength list form.
    pub fn is_per_wavelength(&self) -> bool {
        matches!(self, Spectrum::PerWavelength(_))
    }

    /// The values that define the spectrum, with their wavelengths (`None` for a constant and
    /// for the values of a per-wavelength list).
    pub fn points(&self) -> Vec<(Option<f64>, f64)> {
        match self {
            Spectrum::Constant(v) => vec![(None, *v)],
            Spectrum::PerWavelength(l) => l.iter().map(|v| (None, *v)).collect(),
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

    /// Checks: same lengths, increasing wavelengths, values finite, a list non-empty. Returns a
    /// message.
    pub fn validate(&self) -> Result<(), String> {
        match self {
            Spectrum::Constant(v) if !v.is_finite() => Err(format!("value {v} is not finite")),
            Spectrum::Constant(_) => Ok(()),
            Spectrum::PerWavelength(l) => {
                if l.is_empty() {
                    return Err("the list of values (one per wavelength) is empty".into());
                }
                match l.iter().position(|x| !x.is_finite()) {
                    Some(i) => Err(format!("value [{i}] = {} is not finite", l[i])),
                    None => Ok(()),
                }
            }
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
                if w.iter().any(|x| !x.is_finite()) {
                    return Err("wavelengths_nm must be finite".into());
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

    /// `Err` with a message when a per-wavelength list does not have one value for each of the
    /// `nw` run wavelengths; other forms always pass.
    pub fn check_len(&self, nw: usize) -> Result<(), String> {
        match self {
            Spectrum::PerWavelength(l) if l.len() != nw => Err(format!(
                "has {} values but there are {nw} wavelengths",
                l.len()
            )),
            _ => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Deserialize)]
    struct T {
        s: Spectrum,
    }

    fn parse(v: &str) -> Result<Spectrum, String> {
        toml::from_str::<T>(&format!("s = {v}"))
            .map(|t| t.s)
            .map_err(|e| e.to_string())
    }

    /// Rationale: the three written forms must read as the three variants, and anything else
    /// must be refused with a message that says what is expected.
    #[test]
    fn three_forms_read_and_others_are_refused() {
        assert_eq!(parse("0.3").unwrap(), Spectrum::Constant(0.3));
        assert_eq!(parse("1").unwrap(), Spectrum::Constant(1.0));
        assert_eq!(
            parse("[0.1, 0.2]").unwrap(),
            Spectrum::PerWavelength(vec![0.1, 0.2])
        );
        assert_eq!(
            parse("{ wavelengths_nm = [400.0, 800.0], values = [0.1, 0.5] }").unwrap(),
            Spectrum::Table {
                wavelengths_nm: vec![400.0, 800.0],
                values: vec![0.1, 0.5]
            }
        );
        let e = parse("\"abc\"").unwrap_err();
        assert!(e.contains("invalid type: string \"abc\", expected a number, a list of numbers (one per wavelength) or a table"), "{e}");
        let e = parse("{ wavelengths_nm = [400.0], value = [0.1] }").unwrap_err();
        assert!(e.contains("unknown field `value`"), "{e}");
        let e = parse("[0.1, \"x\"]").unwrap_err();
        assert!(e.contains("invalid type"), "{e}");
    }

    /// Rationale: a list serves the run's wavelengths by index, a table by interpolation with
    /// constant ends; both must round-trip through TOML (manifests are written by scenegen).
    #[test]
    fn values_at_run_wavelengths_and_round_trip() {
        let l = Spectrum::PerWavelength(vec![0.1, 0.2]);
        assert_eq!(l.at_run(1, 999.0), 0.2);
        assert!(l.at_run(2, 999.0).is_nan());
        assert!(l.check_len(2).is_ok());
        assert_eq!(
            l.check_len(3).unwrap_err(),
            "has 2 values but there are 3 wavelengths"
        );
        let t = Spectrum::Table {
            wavelengths_nm: vec![400.0, 800.0],
            values: vec![0.1, 0.5],
        };
        assert_eq!(t.at_run(7, 600.0), 0.30000000000000004);
        assert_eq!(t.at(300.0), 0.1);
        assert_eq!(t.at(900.0), 0.5);
        for s in [Spectrum::Constant(0.25), l.clone(), t.clone()] {
            #[derive(Serialize, Deserialize)]
            struct W {
                s: Spectrum,
            }
            let text = toml::to_string(&W { s: s.clone() }).unwrap();
            let back: W = toml::from_str(&text).unwrap();
            assert_eq!(back.s, s, "{text}");
        }
        assert!(Spectrum::PerWavelength(vec![]).validate().is_err());
        assert!(Spectrum::PerWavelength(vec![0.1, f64::NAN])
            .validate()
            .unwrap_err()
            .contains("[1]"));
    }
}
