//! Per-material radiometry solvers (DIRSIG4's solver concept): how a path that reaches a
//! material gathers the light leaving it. Stored per material in bundles (`solver` in a
//! `[[materials]]` table; absent = `generic` with one sample) and given in experiment files
//! (`[surface] solver`, `[scene.solvers] NAME`). What each does in the transport is documented
//! in the simulator (`integrator/solver.rs`, `docs/transport.md`).
//!
//! | `type` | keys (default) | meaning |
//! |---|---|---|
//! | `generic` | `first_bounce_samples` (1), `decay` (1), `max_generations` (none) | importance-sampled hemisphere; generation g draws `max(1, round(N·decay^(g−1)))` directions |
//! | `classic` | `zeniths` (8), `azimuths` (16) | a fixed cosine-spaced zenith × azimuth quadrature of the first bounce, single directions later |
//! | `simple` | — | direct sunlight only, no further generation |
//! | `mirror` | `refractive_index` (required), `absorption_index` (0) | perfectly specular with Fresnel reflectance n + ik |
//! | `null` | — | pass-through: the material does not interact |

use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum SolverSpec {
    Generic {
        #[serde(default = "one")]
        first_bounce_samples: u32,
        #[serde(default = "one_f")]
        decay: f64,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        max_generations: Option<u32>,
    },
    Classic {
        #[serde(default = "eight")]
        zeniths: u32,
        #[serde(default = "sixteen")]
        azimuths: u32,
    },
    Simple {},
    Mirror {
        refractive_index: f64,
        #[serde(default)]
        absorption_index: f64,
    },
    Null {},
}

fn one() -> u32 {
    1
}
fn one_f() -> f64 {
    1.0
}
fn eight() -> u32 {
    8
}
fn sixteen() -> u32 {
    16
}

/// Most directions one bounce may fan out into.
pub const MAX_SOLVER_SAMPLES: u32 = 4096;

impl Default for SolverSpec {
    fn default() -> Self {
        SolverSpec::Generic {
            first_bounce_samples: 1,
            decay: 1.0,
            max_generations: None,
        }
    }
}

impl SolverSpec {
    pub fn type_name(&self) -> &'static str {
        match self {
            SolverSpec::Generic { .. } => "generic",
            SolverSpec::Classic { .. } => "classic",
            SolverSpec::Simple {} => "simple",
            SolverSpec::Mirror { .. } => "mirror",
            SolverSpec::Null {} => "null",
        }
    }

    /// Whether this is the default (today's walk: one sampled direction per bounce, no limit).
    pub fn is_default(&self) -> bool {
        *self == SolverSpec::default()
    }

    /// Checks the parameters; the error names the key (relative to the solver table).
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        match self {
            SolverSpec::Generic {
                first_bounce_samples: n,
                decay,
                max_generations,
            } => {
                if !(1..=MAX_SOLVER_SAMPLES).contains(n) {
                    return Err((
                        "first_bounce_samples",
                        format!("{n} must lie in [1, {MAX_SOLVER_SAMPLES}]"),
                    ));
                }
                if !(decay.is_finite() && *decay > 0.0 && *decay <= 1.0) {
                    return Err(("decay", format!("{decay} must lie in (0, 1]")));
                }
                if *max_generations == Some(0) {
                    return Err(("max_generations", "must be at least 1".into()));
                }
            }
            SolverSpec::Classic { zeniths, azimuths } => {
                if *zeniths == 0 || *azimuths == 0 || zeniths * azimuths > MAX_SOLVER_SAMPLES {
                    return Err((
                        "zeniths",
                        format!(
                            "{zeniths} × {azimuths} directions: each at least 1, at most {MAX_SOLVER_SAMPLES} in all"
                        ),
                    ));
                }
            }
            SolverSpec::Mirror {
                refractive_index: n,
                absorption_index: k,
            } => {
                if !(n.is_finite() && *n > 0.0 && *n <= 100.0) {
                    return Err(("refractive_index", format!("{n} must lie in (0, 100]")));
                }
                if !(k.is_finite() && *k >= 0.0 && *k <= 1e6) {
                    return Err(("absorption_index", format!("{k} must lie in [0, 1e6]")));
                }
            }
            SolverSpec::Simple {} | SolverSpec::Null {} => {}
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_and_validation() {
        let s: SolverSpec = toml::from_str("type = \"generic\"").unwrap();
        assert!(s.is_default());
        let s: SolverSpec = toml::from_str("type = \"classic\"").unwrap();
        assert_eq!(
            s,
            SolverSpec::Classic {
                zeniths: 8,
                azimuths: 16
            }
        );
        let bad: SolverSpec =
            toml::from_str("type = \"generic\"\nfirst_bounce_samples = 8\ndecay = 1.5").unwrap();
        assert_eq!(bad.validate().unwrap_err().0, "decay");
        let bad: SolverSpec = toml::from_str("type = \"mirror\"\nrefractive_index = -1.0").unwrap();
        assert_eq!(bad.validate().unwrap_err().0, "refractive_index");
        assert!(toml::from_str::<SolverSpec>("type = \"simple\"\nsamples = 3").is_err());
        // Round trip through the manifest's TOML.
        let m = SolverSpec::Mirror {
            refractive_index: 1.5,
            absorption_index: 0.0,
        };
        let back: SolverSpec = toml::from_str(&toml::to_string(&m).unwrap()).unwrap();
        assert_eq!(back, m);
    }
}
