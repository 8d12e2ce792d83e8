//! Spectral bookkeeping: the `[spectral]` table and `mode` of the experiment file (raw serde
//! types and their resolution into the run's wavelengths and sensor band), per-wavelength values
//! of the other tables ([`Spectrum`]), and which wavelengths one walk serves together
//! (spectral ALIS groups), shared by the resolver and the run driver; solar spectra
//! (`solar.rs`) and sensors' spectral response functions (`srf.rs`).

pub mod bands;
pub mod solar;
pub mod srf;

use serde::Deserialize;

use crate::error::{ConfigCtx, ConfigError};
use crate::spectral::srf::Srf;

/// Why a spectrum (solar irradiance, `solar.rs`), a spectral response function (`srf.rs`) or a
/// date for the Earth–Sun distance is refused. `name` is the spectrum's name or file as given.
#[derive(Debug, thiserror::Error)]
pub enum SpectrumError {
    /// `line` is 1-based.
    #[error("line {line}: expected `wavelength_nm,value` (two numbers, the value non-negative)")]
    Row { name: String, line: usize },
    #[error("need at least two rows with increasing wavelengths")]
    TooFewRows { name: String },
    #[error("\"{value}\" is not a date of the form YYYY-MM-DD")]
    BadDate { value: String },
    /// A number of an embedded SRF table that does not parse.
    #[error("{source}")]
    EmbeddedNumber {
        family: String,
        value: String,
        source: std::num::ParseFloatError,
    },
    #[error("{family} has no band \"{band}\" (bands: {})", .bands.join(", "))]
    NoBand {
        family: String,
        band: String,
        bands: Vec<String>,
    },
    #[error("the response is zero everywhere")]
    ZeroResponse { name: String },
    /// A sampling step that would give more than [`MAX_SRF_WAVELENGTHS`] wavelengths.
    #[error("{step} nm samples the {lo}–{hi} nm band at {count:.3e} wavelengths: at most {MAX_SRF_WAVELENGTHS} (use a step of at least {:.3e} nm)", (hi - lo) / (MAX_SRF_WAVELENGTHS as f64 - 1.0))]
    TooManyWavelengths {
        step: f64,
        lo: f64,
        hi: f64,
        count: f64,
    },
}

/// `mode`: how wavelengths are simulated.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    /// Monochromatic.
    #[default]
    Mono,
    /// Correlated-k: each wavelength stands for the CKD bin of the absorption data holding it.
    Ckd,
}

/// Shortest wavelength a run accepts, nm (the far ultraviolet).
pub const MIN_WAVELENGTH_NM: f64 = 100.0;
/// Longest wavelength a run accepts, nm (1 mm, the end of the longwave k-distributions).
pub const MAX_WAVELENGTH_NM: f64 = 1.0e6;

pub use bundle::Spectrum;

/// The experiment's reading of a [`Spectrum`] (a number, a list with one value per run
/// wavelength, or a `{ wavelengths_nm, values }` table): one value per run wavelength, checked
/// against a range, errors naming the key.
pub trait SpectrumExt {
    /// One number per run wavelength (`ctx.wavelengths`), each finite and within `[lo, hi]`;
    /// errors name `key` (and the list index, or the wavelength).
    fn expand(&self, ctx: &ConfigCtx, key: &str, lo: f64, hi: f64)
        -> Result<Vec<f64>, ConfigError>;
}

impl SpectrumExt for Spectrum {
    fn expand(
        &self,
        ctx: &ConfigCtx,
        key: &str,
        lo: f64,
        hi: f64,
    ) -> Result<Vec<f64>, ConfigError> {
        if let Spectrum::Table { .. } = self {
            self.validate().map_err(|m| ctx.err(key, m))?;
        }
        self.check_len(ctx.nw).map_err(|m| ctx.err(key, m))?;
        let vals: Vec<f64> = (0..ctx.nw)
            .map(|i| {
                let w = ctx.wavelengths.get(i).copied().unwrap_or(f64::NAN);
                self.at_run(i, w)
            })
            .collect();
        for (i, x) in vals.iter().enumerate() {
            if !x.is_finite() || *x < lo || *x > hi {
                let at = match self {
                    Spectrum::PerWavelength(_) => format!("[{i}]"),
                    _ => String::new(),
                };
                let nm = match self {
                    Spectrum::Table { .. } => format!(" at {} nm", ctx.wavelengths[i]),
                    _ => String::new(),
                };
                return Err(ctx.err(
                    format!("{key}{at}"),
                    format!("{x}{nm} must lie in [{lo}, {hi}]"),
                ));
            }
        }
        Ok(vals)
    }
}

/// A number or a list of numbers, as a list (`wavelengths = 550.0` is `[550.0]`).
fn one_or_many<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Option<Vec<f64>>, D::Error> {
    match Spectrum::deserialize(d)? {
        Spectrum::Constant(v) => Ok(Some(vec![v])),
        Spectrum::PerWavelength(l) => Ok(Some(l)),
        Spectrum::Table { .. } => Err(serde::de::Error::custom(
            "invalid type: table, expected a number or a list of numbers (nm)",
        )),
    }
}

/// Most wavelengths an `srf` band is sampled at in `mode = "mono"` (`wavelength_step`).
pub const MAX_SRF_WAVELENGTHS: usize = 100_000;

/// The `[spectral]` table.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpectralConfig {
    /// nm; one number is a list of one.
    #[serde(default, deserialize_with = "one_or_many")]
    pub wavelengths: Option<Vec<f64>>,
    /// A sensor band (embedded SRF name or CSV file): sample it and add band-weighted outputs.
    #[serde(default)]
    pub srf: Option<String>,
    /// Several sensor bands rendered together, each output a band (`bands.rs`).
    #[serde(default)]
    pub bands: Option<Vec<String>>,
    /// `bands` in mono mode: wavelengths of equal share per band (default 64).
    #[serde(default)]
    pub band_nodes: Option<usize>,
    /// nm: spacing of the wavelengths sampling an SRF (default 5).
    #[serde(default)]
    pub wavelength_step: Option<f64>,
    /// `mode = "ckd"`: use only this g-point (index from 0) with weight 1 (validation).
    #[serde(default)]
    pub g_point: Option<usize>,
    /// `mode = "ckd"` with an axsdb database: number of Gauss–Legendre g-points per bin.
    #[serde(default)]
    pub g_points: Option<usize>,
}

/// A sensor band sampled by the run's wavelengths.
#[derive(Clone, Debug)]
pub struct Band {
    pub name: String,
    /// Weights, one per wavelength: trapezoid `S(λ_k)·Δλ_k` in mono mode, `∫_bin S dλ` in CKD mode.
    pub weights: Vec<f64>,
}

/// The solar irradiance (W m⁻² nm⁻¹) at the given wavelengths (nm), as the experiment's
/// illumination gives it: how sensor bands in mono mode place their nodes.
pub type SolarAt<'a> = dyn Fn(&[f64]) -> Result<Vec<f64>, ConfigError> + 'a;

/// What `[spectral]` resolves to: the run's wavelengths, the sensor band they sample
/// (`srf`), or the sensor bands (`bands`, [`bands`]), each with one
/// weight per run wavelength (zero outside the band).
#[derive(Clone, Debug)]
pub struct Sampling {
    pub wavelengths: Vec<f64>,
    pub band: Option<Band>,
    pub bands: Vec<Band>,
    /// `bands` in mono mode: per band, its effective wavelength and irradiance from the fine
    /// grid its nodes were drawn on (empty otherwise: computed from the nodes).
    pub centres: Vec<bands::BandCentre>,
}

impl SpectralConfig {
    /// The run's wavelengths (nm) and the sensor band(s) they sample. In CKD mode a sensor band
    /// is sampled by the bins of the absorption data, which `ckd_bins` reads when it is needed
    /// (`None`: bins too wide to sample a band, e.g. RRTMGP's; the band is then sampled every
    /// `wavelength_step` nm). `ctx.nw` is not used.
    pub fn resolve(
        &self,
        ctx: &ConfigCtx,
        mode: Mode,
        ckd_bins: impl FnOnce() -> Result<Option<Vec<(f64, f64)>>, ConfigError>,
        irradiance: &SolarAt,
    ) -> Result<Sampling, ConfigError> {
        let ckd = mode == Mode::Ckd;
        if self.g_point.is_some() && !ckd {
            return Err(ctx.err("spectral.g_point", "is used only with mode = \"ckd\""));
        }
        if self.g_points.is_some() && !ckd {
            return Err(ctx.err("spectral.g_points", "is used only with mode = \"ckd\""));
        }
        let given = [
            self.wavelengths.is_some(),
            self.srf.is_some(),
            self.bands.is_some(),
        ];
        if given.iter().filter(|&&g| g).count() > 1 {
            return Err(ctx.err(
                "spectral",
                "give one of `wavelengths`, `srf` (one sensor band) or `bands` (several), not more",
            ));
        }
        let bins = if ckd && (self.srf.is_some() || self.bands.is_some()) {
            ckd_bins()?
        } else {
            None
        };
        let sample = |key: &str, name: &str| -> Result<(Vec<f64>, Vec<f64>), ConfigError> {
            let srf = load_srf(ctx, key, name)?;
            self.sample_band(ctx, key, name, &srf, bins.as_deref())
        };
        let sampling = match (&self.wavelengths, &self.srf, &self.bands) {
            (Some(w), _, _) => {
                if self.wavelength_step.is_some() {
                    return Err(ctx.err(
                        "spectral.wavelength_step",
                        "is used only with `srf` or `bands`",
                    ));
                }
                Sampling {
                    wavelengths: w.clone(),
                    band: None,
                    bands: Vec::new(),
                    centres: Vec::new(),
                }
            }
            (_, Some(name), _) => {
                let (w, weights) = sample("spectral.srf", name)?;
                Sampling {
                    wavelengths: w,
                    band: Some(Band {
                        name: name.clone(),
                        weights,
                    }),
                    bands: Vec::new(),
                    centres: Vec::new(),
                }
            }
            (_, _, Some(names)) => {
                if names.is_empty() {
                    return Err(ctx.err("spectral.bands", "must name at least one sensor band"));
                }
                for (i, name) in names.iter().enumerate() {
                    if names[..i].contains(name) {
                        return Err(ctx.err(
                            format!("spectral.bands[{i}]"),
                            format!("\"{name}\" is listed twice"),
                        ));
                    }
                }
                if ckd {
                    if self.band_nodes.is_some() {
                        return Err(ctx.err(
                            "spectral.band_nodes",
                            "is used only with mode = \"mono\": in CKD mode the bins' g-points are the nodes",
                        ));
                    }
                    if bins.is_none() {
                        return Err(ctx.err(
                            "atmosphere.absorption_data",
                            "`spectral.bands` in mode = \"ckd\" needs absorption data with narrow bins (the eradiate v0 file or an axsdb database), not RRTMGP's bands",
                        ));
                    }
                    let mut each = Vec::new();
                    for (i, name) in names.iter().enumerate() {
                        each.push(sample(&format!("spectral.bands[{i}]"), name)?);
                    }
                    bands::union(names, each)
                } else {
                    if self.wavelength_step.is_some() {
                        return Err(ctx.err(
                            "spectral.wavelength_step",
                            "is not used with `bands`: each band is sampled at `band_nodes` wavelengths of equal share",
                        ));
                    }
                    let k = self.band_nodes.unwrap_or(bands::BAND_NODES);
                    if !(1..=bands::MAX_NODES).contains(&k) {
                        return Err(ctx.err(
                            "spectral.band_nodes",
                            format!("{k} must lie in 1 … {}", bands::MAX_NODES),
                        ));
                    }
                    let mut each = Vec::new();
                    for (i, name) in names.iter().enumerate() {
                        let key = format!("spectral.bands[{i}]");
                        let srf = load_srf(ctx, &key, name)?;
                        let grid = bands::fine_grid(&srf);
                        let e0 = irradiance(&grid)?;
                        each.push(
                            bands::quantile_nodes(&srf, &grid, &e0, k)
                                .map_err(|m| ctx.err(key.as_str(), m))?,
                        );
                    }
                    bands::union_quantiles(names, each)
                }
            }
            (None, None, None) => {
                return Err(ctx.err(
                    "spectral",
                    "give `wavelengths` (nm), a sensor band `srf` or sensor bands `bands`",
                ))
            }
        };
        if sampling.wavelengths.is_empty() {
            return Err(ctx.err("spectral.wavelengths", "must list at least one wavelength"));
        }
        for (i, w) in sampling.wavelengths.iter().enumerate() {
            if !w.is_finite() || !(MIN_WAVELENGTH_NM..=MAX_WAVELENGTH_NM).contains(w) {
                return Err(ctx.err(
                    format!("spectral.wavelengths[{i}]"),
                    format!(
                        "{w} nm is outside [{MIN_WAVELENGTH_NM}, {MAX_WAVELENGTH_NM}] nm (ultraviolet to far infrared; wavelengths are in nm)"
                    ),
                ));
            }
        }
        Ok(sampling)
    }

    /// The wavelengths sampling sensor band `srf` (key `key`, named `name`) and their weights:
    /// the absorption data's bins overlapping it (`bins`, CKD mode) or a grid every
    /// `wavelength_step` nm.
    fn sample_band(
        &self,
        ctx: &ConfigCtx,
        key: &str,
        name: &str,
        srf: &Srf,
        bins: Option<&[(f64, f64)]>,
    ) -> Result<(Vec<f64>, Vec<f64>), ConfigError> {
        if let Some(bins) = bins {
            if self.wavelength_step.is_some() {
                return Err(ctx.err(
                    "spectral.wavelength_step",
                    "is not used in mode = \"ckd\": the absorption data's bins sample the band",
                ));
            }
            let weights = srf.bin_weights(bins);
            let (mut w, mut wt) = (Vec::new(), Vec::new());
            for (&(lo, hi), &x) in bins.iter().zip(&weights) {
                if x > 0.0 {
                    w.push(0.5 * (lo + hi));
                    wt.push(x);
                }
            }
            if w.is_empty() {
                return Err(ctx.err(
                    key,
                    format!("band \"{name}\" overlaps no bin of the absorption data"),
                ));
            }
            return Ok((w, wt));
        }
        let step = self.wavelength_step.unwrap_or(5.0);
        if !(step > 0.0 && step.is_finite()) {
            return Err(ctx.err(
                "spectral.wavelength_step",
                format!("{step} nm must be positive"),
            ));
        }
        srf.grid(step).map_err(|e| {
            let key = match e {
                SpectrumError::TooManyWavelengths { .. } => "spectral.wavelength_step",
                _ => key,
            };
            ctx.err(key, e.to_string())
        })
    }
}

/// Sensor band `name` (key `key`): an embedded SRF or a `wavelength_nm,response` CSV file.
fn load_srf(ctx: &ConfigCtx, key: &str, name: &str) -> Result<Srf, ConfigError> {
    if let Some(s) = Srf::builtin(name).map_err(|e| ctx.err(key, e.to_string()))? {
        return Ok(s);
    }
    let fpath = ctx.file(name);
    let text = std::fs::read_to_string(&fpath).map_err(|e| {
        ctx.err(key, format!("\"{name}\" is neither an embedded SRF (e.g. \"sentinel_2a-msi-4\") nor a readable file ({}: {e})", fpath.display()))
    })?;
    Srf::from_csv(name, &text).map_err(|e| ctx.err(key, format!("{}: {e}", fpath.display())))
}

/// The wavelength groups of a wavelength list and group size (None: one wavelength each).
pub fn wavelength_groups_of(wavelengths: &[f64], group: Option<usize>) -> Vec<Vec<usize>> {
    match group {
        None => (0..wavelengths.len()).map(|iw| vec![iw]).collect(),
        Some(n) => {
            let mut order: Vec<usize> = (0..wavelengths.len()).collect();
            order.sort_by(|&a, &b| wavelengths[a].total_cmp(&wavelengths[b]).then(a.cmp(&b)));
            order.chunks(n.max(1)).map(|c| c.to_vec()).collect()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rationale (issue 42): `wavelengths = 550.0` is the list `[550.0]`, as Eradiate users
    /// write it; a list stays a list; a table is not a set of wavelengths.
    #[test]
    fn one_wavelength_may_be_a_number() {
        let w = |t: &str| toml::from_str::<SpectralConfig>(t).map(|c| c.wavelengths);
        assert_eq!(w("wavelengths = 550.0").unwrap(), Some(vec![550.0]));
        assert_eq!(w("wavelengths = 550").unwrap(), Some(vec![550.0]));
        assert_eq!(
            w("wavelengths = [440.0, 550.0]").unwrap(),
            Some(vec![440.0, 550.0])
        );
        assert_eq!(w("").unwrap(), None);
        assert!(w("wavelengths = { wavelengths_nm = [1.0], values = [1.0] }").is_err());
        assert!(w("wavelengths = \"550\"").is_err());
    }
}
