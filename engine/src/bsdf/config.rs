//! The `[surface]` table of the experiment file: the 1D ground as `{ brdf, temperature, solver }`
//! ([`SurfaceConfig`]), and its resolution into one [`Bsdf`] per run wavelength by
//! [`Bsdf::build`], the same constructors as every material of a 3D scene.
//!
//! The BRDF is a `bundle::BrdfSpec`, the one vocabulary of 1D surfaces and bundle materials.
//! It is written either flat, its keys beside `temperature` and `solver` (every example does
//! so):
//!
//! ```toml
//! [surface]
//! type = "rpv"
//! rho_0 = 0.1
//! k = 0.8
//! g = -0.1
//! temperature = 300.0
//! ```
//!
//! or nested, as a material's: `[surface] brdf = { type = "rpv", … }` with `temperature` and
//! `solver` beside it. Keys and units are documented in `docs/experiment.md`.

use serde::Deserialize;

use super::error::BrdfError;
use super::Bsdf;
use crate::error::{ConfigCtx, ConfigError};
use crate::spectral::SpectrumExt;
use bundle::BrdfSpec;

/// The experiment's 1D ground.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceConfig {
    pub brdf: BrdfSpec,
    /// K: the surface's temperature, for thermal emission (`emissivity.rs`).
    pub temperature: Option<f64>,
    /// The surface's radiometry solver (`integrator/solver.rs`; default `generic`).
    pub solver: Option<bundle::SolverSpec>,
}

/// The keys of `[surface]` that are not the BRDF's.
const OWN_KEYS: [&str; 2] = ["temperature", "solver"];

/// The flat form (the BRDF's keys beside `temperature` and `solver`) or the nested one
/// (`brdf = { … }`); an unknown key is reported by the BRDF's own reader, which names it and
/// the model's keys.
impl<'de> Deserialize<'de> for SurfaceConfig {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::Error;
        let mut table = toml::Table::deserialize(d)?;
        let own = |table: &mut toml::Table, key: &str| table.remove(key);
        let temperature = match own(&mut table, OWN_KEYS[0]) {
            Some(v) => Some(f64::deserialize(v).map_err(|e| D::Error::custom(message(&e)))?),
            None => None,
        };
        let solver = match own(&mut table, OWN_KEYS[1]) {
            Some(v) => Some(
                bundle::SolverSpec::deserialize(v).map_err(|e| D::Error::custom(message(&e)))?,
            ),
            None => None,
        };
        let brdf = match table.remove("brdf") {
            Some(nested) => {
                if let Some(k) = table.keys().next() {
                    return Err(D::Error::custom(format!(
                        "unknown field `{k}`: with a nested `brdf` table, `[surface]` holds only `brdf`, `temperature` and `solver`"
                    )));
                }
                BrdfSpec::deserialize(nested)
            }
            None => BrdfSpec::deserialize(toml::Value::Table(table)),
        }
        .map_err(|e| D::Error::custom(message(&e)))?;
        Ok(SurfaceConfig {
            brdf,
            temperature,
            solver,
        })
    }
}

/// A TOML value reader's message, without the location it cannot know (the caller's path
/// names the table).
fn message(e: &toml::de::Error) -> String {
    e.message().trim_end().to_string()
}

/// Any finite number: the model's constructor checks the range and names the parameter.
const ANY: (f64, f64) = (-1e6, 1e6);

impl SurfaceConfig {
    /// One BRDF per run wavelength (`wavelengths`, nm). `key` is the table's key path
    /// (`surface`): a value that is not a finite number, or a list of the wrong length, is
    /// reported at `key.NAME`; a value out of its model's range at `key.NAME` (with `[i]` for a
    /// list), with the model's message naming the parameter (and the wavelength for a table);
    /// a bad table file at `key.file`, naming file and variable.
    pub fn resolve(
        &self,
        ctx: &ConfigCtx,
        key: &str,
        wavelengths: &[f64],
    ) -> Result<Vec<Bsdf>, ConfigError> {
        for (name, s) in self.brdf.params() {
            s.expand(ctx, &format!("{key}.{name}"), ANY.0, ANY.1)?;
        }
        // A tabulated BRDF's file is relative to the experiment file.
        let spec = match &self.brdf {
            BrdfSpec::Tabulated(t) => BrdfSpec::Tabulated(bundle::TabulatedSpec {
                file: ctx.file(&t.file).to_string_lossy().into_owned(),
                symmetrize: t.symmetrize,
            }),
            other => other.clone(),
        };
        let params = self.brdf.params();
        wavelengths
            .iter()
            .enumerate()
            .map(|(iw, &w)| {
                Bsdf::build(&spec, iw, w)
                    .and_then(super::Built::into_opaque)
                    .map_err(|e| self.error_at(ctx, key, &params, iw, w, e))
            })
            .collect()
    }

    /// The key and message of a model's error at run wavelength `iw` (`w`, nm).
    fn error_at(
        &self,
        ctx: &ConfigCtx,
        key: &str,
        params: &[(&'static str, &bundle::Spectrum)],
        iw: usize,
        w: f64,
        e: BrdfError,
    ) -> ConfigError {
        let param = match &e {
            BrdfError::Param { param, .. } => Some(*param),
            BrdfError::LeafSum { .. } => Some("transmittance"),
            _ => None,
        };
        let Some(param) = param else {
            return ctx.err(format!("{key}.file"), e.to_string());
        };
        let (at, nm) = match params.iter().find(|(p, _)| *p == param).map(|(_, s)| *s) {
            Some(bundle::Spectrum::PerWavelength(_)) => (format!("[{iw}]"), String::new()),
            Some(bundle::Spectrum::Table { .. }) if !matches!(e, BrdfError::LeafSum { .. }) => {
                (String::new(), format!(" (at {w} nm)"))
            }
            _ => (String::new(), String::new()),
        };
        ctx.err(format!("{key}.{param}{at}"), format!("{e}{nm}"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn surface(text: &str) -> Result<SurfaceConfig, String> {
        #[derive(Deserialize)]
        struct T {
            surface: SurfaceConfig,
        }
        toml::from_str::<T>(text)
            .map(|t| t.surface)
            .map_err(|e| e.to_string())
    }

    fn resolve(text: &str, wavelengths: &[f64]) -> Result<Vec<Bsdf>, String> {
        let s = surface(text)?;
        let ctx = ConfigCtx {
            path: std::path::Path::new("exp.toml"),
            base: std::path::Path::new("."),
            nw: wavelengths.len(),
            wavelengths,
        };
        s.resolve(&ctx, "surface", wavelengths)
            .map_err(|e| e.to_string())
    }

    /// Rationale: the flat form (every existing experiment) and the nested form read as the
    /// same `{ brdf, temperature, solver }`; a misspelt key is refused naming it, in either.
    #[test]
    fn flat_and_nested_forms_are_the_same_surface() {
        let flat = surface(
            "[surface]\ntype = \"rpv\"\nrho_0 = 0.1\nk = 0.8\ng = -0.1\ntemperature = 300.0",
        )
        .unwrap();
        let nested = surface(
            "[surface]\ntemperature = 300\nbrdf = { type = \"rpv\", rho_0 = 0.1, k = 0.8, g = -0.1 }",
        )
        .unwrap();
        assert_eq!(flat, nested);
        assert_eq!(flat.temperature, Some(300.0));
        assert_eq!(flat.brdf.type_name(), "rpv");
        let e = surface("[surface]\ntype = \"lambertian\"\nreflectanse = 0.3").unwrap_err();
        assert!(e.contains("unknown field `reflectanse`"), "{e}");
        let e = surface("[surface]\nbrdf = { type = \"lambertian\", reflectance = 0.3 }\nk = 1")
            .unwrap_err();
        assert!(e.contains("unknown field `k`"), "{e}");
        let e = surface("[surface]\ntype = \"lambertian\"").unwrap_err();
        assert!(e.contains("missing field `reflectance`"), "{e}");
    }

    /// Rationale: every model, including the scene-only `bi_lambertian` and the once 1D-only
    /// `rtls_hotspot`, builds as a 1D ground; out-of-range values are reported at the
    /// parameter's key with the list index or the wavelength.
    #[test]
    fn every_model_resolves_and_errors_name_the_parameter() {
        let w = [500.0, 600.0];
        let leaf = resolve(
            "[surface]\ntype = \"bi_lambertian\"\nreflectance = [0.3, 0.4]\ntransmittance = 0.5",
            &w,
        )
        .unwrap();
        match &leaf[1] {
            Bsdf::Lambertian(l) => assert_eq!(l.reflectance, 0.4),
            other => panic!("{other:?}"),
        }
        let h = resolve(
            "[surface]\ntype = \"rtls_hotspot\"\nf_iso = 0.2\nf_vol = 0.1\nf_geo = 0.02",
            &w,
        )
        .unwrap();
        assert!(matches!(h[0], Bsdf::RtlsHotspot(_)));
        let e = resolve(
            "[surface]\ntype = \"rpv\"\nrho_0 = 0.1\nk = [0.5, 2.5]\ng = 0.0",
            &w,
        )
        .unwrap_err();
        assert!(
            e.contains("surface.k[1]") && e.contains("`k` = 2.5 must lie in [0, 2]"),
            "{e}"
        );
        let e = resolve(
            "[surface]\ntype = \"rpv\"\nrho_0 = 0.1\nk = { wavelengths_nm = [500.0, 600.0], values = [0.5, 2.5] }\ng = 0.0",
            &w,
        )
        .unwrap_err();
        assert!(e.contains("surface.k") && e.contains("(at 600 nm)"), "{e}");
        let e = resolve(
            "[surface]\ntype = \"lambertian\"\nreflectance = [0.1, 0.2, 0.3]",
            &w,
        )
        .unwrap_err();
        assert!(
            e.contains("has 3 values but there are 2 wavelengths"),
            "{e}"
        );
    }
}
