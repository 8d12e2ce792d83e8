//! The `[surface]` table of the experiment file: its raw serde type, one variant per model, and
//! its resolution into one [`Bsdf`] per run wavelength. Keys and units are documented in
//! `docs/experiment.md`; each model's constructor checks its parameter ranges (against the
//! shared table `bundle::BRDF_PARAM_RANGES`).

use serde::Deserialize;

use super::error::BrdfError;
use super::tabulated::BrdfTable;
use super::{Bsdf, Hapke, Lambertian, Ocean, Rpv, Rtls, RtlsHotspot, Tabulated};
use crate::error::{ConfigCtx, ConfigError};
use crate::spectral::SpectralValue;

#[derive(Clone, Debug, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum SurfaceConfig {
    Lambertian {
        reflectance: SpectralValue,
        /// K: the surface's temperature, for thermal emission (`emissivity.rs`).
        #[serde(default)]
        temperature: Option<f64>,
        /// The surface's radiometry solver (`integrator/solver.rs`; default `generic`).
        #[serde(default)]
        solver: Option<bundle::SolverSpec>,
    },
    Rpv {
        rho_0: SpectralValue,
        k: SpectralValue,
        g: SpectralValue,
        #[serde(default)]
        rho_c: Option<SpectralValue>,
        /// K: the surface's temperature, for thermal emission (`emissivity.rs`).
        #[serde(default)]
        temperature: Option<f64>,
        /// The surface's radiometry solver (`integrator/solver.rs`; default `generic`).
        #[serde(default)]
        solver: Option<bundle::SolverSpec>,
    },
    Rtls {
        f_iso: SpectralValue,
        f_vol: SpectralValue,
        f_geo: SpectralValue,
        /// K: the surface's temperature, for thermal emission (`emissivity.rs`).
        #[serde(default)]
        temperature: Option<f64>,
        /// The surface's radiometry solver (`integrator/solver.rs`; default `generic`).
        #[serde(default)]
        solver: Option<bundle::SolverSpec>,
    },
    /// RTLS with the Maignan et al. (2004) hot-spot factor (`rtls_hotspot.rs`).
    RtlsHotspot {
        f_iso: SpectralValue,
        f_vol: SpectralValue,
        f_geo: SpectralValue,
        /// degrees.
        #[serde(default = "default_xi0")]
        xi0: SpectralValue,
        /// K: the surface's temperature, for thermal emission (`emissivity.rs`).
        #[serde(default)]
        temperature: Option<f64>,
        /// The surface's radiometry solver (`integrator/solver.rs`; default `generic`).
        #[serde(default)]
        solver: Option<bundle::SolverSpec>,
    },
    Hapke {
        w: SpectralValue,
        b: SpectralValue,
        c: SpectralValue,
        /// degrees.
        theta: SpectralValue,
        #[serde(rename = "B_0")]
        b_0: SpectralValue,
        h: SpectralValue,
        /// K: the surface's temperature, for thermal emission (`emissivity.rs`).
        #[serde(default)]
        temperature: Option<f64>,
        /// The surface's radiometry solver (`integrator/solver.rs`; default `generic`).
        #[serde(default)]
        solver: Option<bundle::SolverSpec>,
    },
    /// Rough ocean (Cox–Munk, Fresnel, shadowing); polarizing.
    Ocean {
        /// m/s.
        wind_speed: SpectralValue,
        #[serde(default)]
        refractive_index: Option<SpectralValue>,
        #[serde(default = "yes")]
        shadowing: bool,
        /// K: the surface's temperature, for thermal emission (`emissivity.rs`).
        #[serde(default)]
        temperature: Option<f64>,
        /// The surface's radiometry solver (`integrator/solver.rs`; default `generic`).
        #[serde(default)]
        solver: Option<bundle::SolverSpec>,
    },
    /// A measured BRDF from a netCDF table (`tabulated.rs`: layout, interpolation).
    Tabulated {
        /// Relative to the experiment file.
        file: String,
        #[serde(default)]
        symmetrize: bool,
        /// K: the surface's temperature, for thermal emission (`emissivity.rs`).
        #[serde(default)]
        temperature: Option<f64>,
        /// The surface's radiometry solver (`integrator/solver.rs`; default `generic`).
        #[serde(default)]
        solver: Option<bundle::SolverSpec>,
    },
}

fn yes() -> bool {
    true
}

fn default_xi0() -> SpectralValue {
    SpectralValue::Scalar(super::rtls_hotspot::DEFAULT_XI0_DEG)
}

/// Any finite number: the model's constructor checks the range and names the parameter.
const ANY: (f64, f64) = (-1e6, 1e6);

impl SurfaceConfig {
    /// `temperature` (K) of any model, if given.
    /// The surface's radiometry solver, if given.
    pub fn solver(&self) -> Option<bundle::SolverSpec> {
        match self {
            SurfaceConfig::Lambertian { solver, .. }
            | SurfaceConfig::Rpv { solver, .. }
            | SurfaceConfig::Rtls { solver, .. }
            | SurfaceConfig::RtlsHotspot { solver, .. }
            | SurfaceConfig::Hapke { solver, .. }
            | SurfaceConfig::Ocean { solver, .. }
            | SurfaceConfig::Tabulated { solver, .. } => *solver,
        }
    }

    pub fn temperature(&self) -> Option<f64> {
        match self {
            SurfaceConfig::Lambertian { temperature, .. }
            | SurfaceConfig::Rpv { temperature, .. }
            | SurfaceConfig::Rtls { temperature, .. }
            | SurfaceConfig::RtlsHotspot { temperature, .. }
            | SurfaceConfig::Hapke { temperature, .. }
            | SurfaceConfig::Ocean { temperature, .. }
            | SurfaceConfig::Tabulated { temperature, .. } => *temperature,
        }
    }

    /// One BRDF per run wavelength (`wavelengths`, nm). `key` is the table's key path
    /// (`surface`): a value that is not a finite number, or a list of the wrong length, is
    /// reported at `key.NAME`; a value out of its model's range at `key`, with the model's
    /// message naming the parameter; a bad table file at `key.file`, naming file and variable.
    pub fn resolve(
        &self,
        ctx: &ConfigCtx,
        key: &str,
        wavelengths: &[f64],
    ) -> Result<Vec<Bsdf>, ConfigError> {
        let spectral =
            |name: &str, v: &SpectralValue| v.expand(ctx, &format!("{key}.{name}"), ANY.0, ANY.1);
        let model = |m: BrdfError| ctx.err(key, m.to_string());
        let nw = ctx.nw;
        Ok(match self {
            SurfaceConfig::Lambertian { reflectance, .. } => {
                let name = format!("{key}.reflectance");
                reflectance
                    .expand(ctx, &name, 0.0, 1.0)?
                    .into_iter()
                    .map(|v| {
                        Ok(Bsdf::Lambertian(
                            Lambertian::new(v).map_err(|m| ctx.err(&name, m.to_string()))?,
                        ))
                    })
                    .collect::<Result<_, ConfigError>>()?
            }
            SurfaceConfig::Rpv {
                rho_0, k, g, rho_c, ..
            } => {
                let r0 = spectral("rho_0", rho_0)?;
                let kk = spectral("k", k)?;
                let gg = spectral("g", g)?;
                let rc = match rho_c {
                    Some(v) => spectral("rho_c", v)?,
                    None => r0.clone(),
                };
                (0..nw)
                    .map(|i| {
                        Ok(Bsdf::Rpv(
                            Rpv::new(r0[i], kk[i], gg[i], rc[i]).map_err(model)?,
                        ))
                    })
                    .collect::<Result<_, ConfigError>>()?
            }
            SurfaceConfig::Rtls {
                f_iso,
                f_vol,
                f_geo,
                ..
            } => {
                let a = spectral("f_iso", f_iso)?;
                let b = spectral("f_vol", f_vol)?;
                let c = spectral("f_geo", f_geo)?;
                (0..nw)
                    .map(|i| Ok(Bsdf::Rtls(Rtls::new(a[i], b[i], c[i]).map_err(model)?)))
                    .collect::<Result<_, ConfigError>>()?
            }
            SurfaceConfig::RtlsHotspot {
                f_iso,
                f_vol,
                f_geo,
                xi0,
                ..
            } => {
                let a = spectral("f_iso", f_iso)?;
                let b = spectral("f_vol", f_vol)?;
                let c = spectral("f_geo", f_geo)?;
                let x = spectral("xi0", xi0)?;
                (0..nw)
                    .map(|i| {
                        Ok(Bsdf::RtlsHotspot(
                            RtlsHotspot::new(a[i], b[i], c[i], x[i]).map_err(model)?,
                        ))
                    })
                    .collect::<Result<_, ConfigError>>()?
            }
            SurfaceConfig::Ocean {
                wind_speed,
                refractive_index,
                shadowing,
                ..
            } => {
                let ws = wind_speed.expand(ctx, &format!("{key}.wind_speed"), 0.0, 40.0)?;
                let n = refractive_index
                    .as_ref()
                    .unwrap_or(&SpectralValue::Scalar(1.33))
                    .expand(ctx, &format!("{key}.refractive_index"), 1.0, 3.0)?;
                (0..nw)
                    .map(|i| {
                        Ok(Bsdf::Ocean(
                            Ocean::new(ws[i], n[i], *shadowing).map_err(model)?,
                        ))
                    })
                    .collect::<Result<_, ConfigError>>()?
            }
            SurfaceConfig::Tabulated {
                file, symmetrize, ..
            } => {
                let table = BrdfTable::load(&ctx.file(file))
                    .map_err(|m| ctx.err(format!("{key}.file"), m.to_string()))?;
                wavelengths
                    .iter()
                    .map(|&w| Bsdf::Tabulated(Tabulated::new(table.clone(), w, *symmetrize)))
                    .collect()
            }
            SurfaceConfig::Hapke {
                w,
                b,
                c,
                theta,
                b_0,
                h,
                ..
            } => {
                let w = spectral("w", w)?;
                let b = spectral("b", b)?;
                let c = spectral("c", c)?;
                let th = spectral("theta", theta)?;
                let b0 = spectral("B_0", b_0)?;
                let h = spectral("h", h)?;
                (0..nw)
                    .map(|i| {
                        Ok(Bsdf::Hapke(
                            Hapke::new(w[i], b[i], c[i], th[i], b0[i], h[i]).map_err(model)?,
                        ))
                    })
                    .collect::<Result<_, ConfigError>>()?
            }
        })
    }
}
