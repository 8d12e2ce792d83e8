//! The experiment file's gas-absorption keys of a `molecular` atmosphere
//! (`atmosphere.absorption_data`, `absorption_bounds`, `cross_sections`; `docs/experiment.md`):
//! raw serde types and their resolution into the absorption optical thickness of every
//! computational layer, per run wavelength (and per g-point in CKD mode).

use std::path::Path;

use serde::Deserialize;

use super::{AtmosphereProfile, BoundsPolicy, OutOfRange};
use crate::error::{ConfigCtx, ConfigError};

/// `atmosphere.absorption_bounds`: what an absorption database does with a state outside its
/// grid, per coordinate: "error", "clamp" (edge value) or "zero" (no absorption). Both clamp and
/// zero log a warning once per coordinate.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AbsorptionBoundsConfig {
    #[serde(default = "zero")]
    pub pressure: OutOfRange,
    #[serde(default = "clamp")]
    pub temperature: OutOfRange,
    #[serde(default)]
    pub mole_fraction: OutOfRange,
}

impl Default for AbsorptionBoundsConfig {
    fn default() -> Self {
        AbsorptionBoundsConfig {
            pressure: zero(),
            temperature: clamp(),
            mole_fraction: OutOfRange::Error,
        }
    }
}

fn zero() -> OutOfRange {
    OutOfRange::Zero
}
fn clamp() -> OutOfRange {
    OutOfRange::Clamp
}

impl AbsorptionBoundsConfig {
    /// The database policy.
    pub fn policy(&self) -> BoundsPolicy {
        BoundsPolicy {
            pressure: self.pressure,
            temperature: self.temperature,
            mole_fraction: self.mole_fraction,
        }
    }
}

/// One `[[atmosphere.cross_sections]]` table: a species' absorption cross-section σ(λ).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CrossSectionConfig {
    pub species: String,
    pub file: String,
    /// 1-based column of σ (column 1: wavelength, nm).
    #[serde(default = "default_xs_column")]
    pub column: usize,
    /// Unit of σ: per molecule, `"cm^2"` (default) or `"m^2"`.
    #[serde(default)]
    pub units: CrossSectionUnits,
    /// A wavelength outside the table: `"error"` (default) or `"zero"` (no absorption, logged).
    #[serde(default)]
    pub outside: OutsideTable,
}

fn default_xs_column() -> usize {
    2
}

/// `cross_sections[i].units`.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
pub enum CrossSectionUnits {
    #[default]
    #[serde(rename = "cm^2")]
    SquareCentimetre,
    #[serde(rename = "m^2")]
    SquareMetre,
}

impl CrossSectionUnits {
    /// Factor to m² per molecule.
    pub fn to_m2(self) -> f64 {
        match self {
            CrossSectionUnits::SquareCentimetre => 1e-4,
            CrossSectionUnits::SquareMetre => 1.0,
        }
    }
}

/// `cross_sections[i].outside`: a run wavelength outside the table.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum OutsideTable {
    /// An error naming the wavelength and the table's range.
    #[default]
    Error,
    /// No absorption by this species there (logged once).
    Zero,
}

/// What the gas-absorption resolvers compute for.
pub struct GasLayers<'a> {
    /// The thermophysical profile (p, T, mole fractions).
    pub gas: &'a AtmosphereProfile,
    /// The profile's name (for messages).
    pub profile_name: &'a str,
    /// Whether it is the unscaled embedded AFGL 1986 US standard profile.
    pub is_us_standard: bool,
    /// Computational layers (bottom, top), m, from the ground up.
    pub grid: &'a [(f64, f64)],
    /// Run wavelengths, nm.
    pub wavelengths: &'a [f64],
}

/// A g-point: its quadrature weight, the gas absorption optical thickness of each layer and,
/// from a longwave k-distribution, the factor on each layer's Planck source for this g-point,
/// `pfrac_g(layer)/w_g` (pfrac: the g-point's share of the band's thermal emission,
/// `absorption::rrtmgp`; w_g the band quadrature weight, even when `spectral.g_point` runs one
/// g-point with weight 1). The surface takes the lowest layer's factor.
#[derive(Clone, Debug)]
pub struct GPoint {
    pub weight: f64,
    pub tau: Vec<f64>,
    pub planck_scale: Option<Vec<f64>>,
}

impl GPoint {
    fn new(weight: f64, tau: Vec<f64>) -> Self {
        GPoint {
            weight,
            tau,
            planck_scale: None,
        }
    }
}

const KEY: &str = "atmosphere.absorption_data";

/// Per wavelength, per g-point: (quadrature weight, gas absorption optical thickness of each
/// layer of `at.grid`). Three sources (`atmosphere.absorption_data`):
/// * a file in the eradiate v0 CKD format (k(z, bin, g) precomputed for the US standard
///   atmosphere, 16 Gauss–Legendre g-points per 10 nm bin; `absorption::eradiate_v0`), valid for
///   the unscaled embedded US standard profile only;
/// * the RRTMGP shortwave gas-optics file (`absorption::rrtmgp`): each wavelength takes the
///   g-points of the band holding it, weighted by the band's solar source;
/// * a directory: an axsdb CKD database, evaluated at the profile's (p, T, x) with `g_points`
///   Gauss–Legendre points (`spectral.g_points`, default 16; `absorption::layers`).
///
/// Each run wavelength selects the bin containing it; `g_point` (`spectral.g_point`) keeps one
/// g-point with weight 1.
pub fn resolve_ckd(
    ctx: &ConfigCtx,
    file: &Path,
    at: &GasLayers,
    g_point: Option<usize>,
    g_points: Option<usize>,
    bounds: BoundsPolicy,
) -> Result<Vec<Vec<GPoint>>, ConfigError> {
    use super::eradiate_v0::{EradiateV0Ckd, V0Interpolation};
    use super::{AxsDatabase, DatabaseKind, SpectralPoint};
    let (grid, wavelengths) = (at.grid, at.wavelengths);
    let pick = |ng: usize| -> Result<Vec<usize>, ConfigError> {
        match g_point {
            Some(g) if g >= ng => Err(ctx.err(
                "spectral.g_point",
                format!("{g} is not a g-point index (0..{})", ng - 1),
            )),
            Some(g) => Ok(vec![g]),
            None => Ok((0..ng).collect()),
        }
    };
    let no_bin = |iw: usize, wl: f64, lo: f64, hi: f64| {
        ctx.err(
            format!("spectral.wavelengths[{iw}]"),
            format!(
                "{wl} nm is in no bin of {} (bins cover {lo}..{hi} nm)",
                file.display()
            ),
        )
    };
    if file.is_dir() {
        let db = AxsDatabase::open(file).map_err(|e| ctx.err(KEY, e.to_string()))?;
        if db.kind() != DatabaseKind::Ckd {
            return Err(ctx.err(
                KEY,
                format!(
                    "{} is a monochromatic database; use it with mode = \"mono\"",
                    file.display()
                ),
            ));
        }
        let ng = g_points.unwrap_or(16);
        if !(1..=64).contains(&ng) {
            return Err(ctx.err("spectral.g_points", format!("{ng} must lie in 1..=64")));
        }
        let quad = super::gauss_legendre_unit(ng);
        let cols = super::layers::GasColumns::new(at.gas, grid);
        let (lo, hi) = db.spectral_range_nm();
        let mut out = Vec::with_capacity(wavelengths.len());
        for (iw, &wl) in wavelengths.iter().enumerate() {
            let bin = db
                .bin_containing(wl)
                .ok_or_else(|| no_bin(iw, wl, lo, hi))?;
            let mut per_g = Vec::new();
            for g in pick(ng)? {
                let (gv, w) = quad[g];
                let taus = cols
                    .layer_tau(&db, SpectralPoint::Ckd { bin, g: gv }, bounds)
                    .map_err(|m| ctx.err(KEY, format!("{} nm bin, g = {gv:.4}: {m}", wl)))?;
                per_g.push(GPoint::new(if g_point.is_some() { 1.0 } else { w }, taus));
            }
            out.push(per_g);
        }
        return Ok(out);
    }
    if g_points.is_some() {
        return Err(ctx.err(
            "spectral.g_points",
            "is used only with an axsdb CKD database (a directory); the eradiate v0 and RRTMGP files have fixed g-points",
        ));
    }
    if is_rrtmgp(file) {
        let rr = crate::util::file_cache::cached(file, "", || super::Rrtmgp::open(file))
            .map_err(|e| ctx.err(KEY, e.to_string()))?;
        let longwave = rr.has_planck_fractions();
        let bands = rr.bands_nm();
        type BandOptics = (Vec<Vec<f64>>, Option<Vec<Vec<f64>>>);
        let mut cache: Vec<Option<BandOptics>> = vec![None; bands.len()];
        let mut out = Vec::with_capacity(wavelengths.len());
        for (iw, &wl) in wavelengths.iter().enumerate() {
            let band = bands
                .iter()
                .position(|&(lo, hi)| lo <= wl && wl < hi)
                .ok_or_else(|| no_bin(iw, wl, bands[0].0, bands[bands.len() - 1].1))?;
            if cache[band].is_none() {
                cache[band] = Some(
                    rr.layer_optics(at.gas, grid, band, longwave)
                        .map_err(|e| ctx.err(KEY, e.to_string()))?,
                );
            }
            let (taus, pfrac) = cache[band].as_ref().expect("filled above");
            // Shortwave: the band's solar source per g-point. Longwave: the Planck fractions
            // of the lowest layer (RRTMGP's surface source), normalised over the band, so
            // that each g-point's thermal source B·pfrac_g/w_g is B at the surface.
            let weights = match pfrac {
                Some(pf) => {
                    let bottom: Vec<f64> = pf
                        .iter()
                        .map(|p| p.first().copied().unwrap_or(0.0))
                        .collect();
                    let sum: f64 = bottom.iter().sum();
                    if sum.is_nan() || sum <= 0.0 {
                        return Err(ctx.err(
                            KEY,
                            format!("{}: the Planck fractions of the band holding {wl} nm sum to {sum} in the lowest layer", file.display()),
                        ));
                    }
                    bottom.iter().map(|p| p / sum).collect()
                }
                None => rr
                    .solar_weights(band)
                    .expect("a shortwave file has a solar source"),
            };
            out.push(
                pick(taus.len())?
                    .into_iter()
                    .map(|g| GPoint {
                        weight: if g_point.is_some() { 1.0 } else { weights[g] },
                        tau: taus[g].iter().map(|t| t.max(0.0)).collect(),
                        planck_scale: pfrac.as_ref().map(|pf| {
                            pf[g]
                                .iter()
                                .map(|p| p / weights[g].max(f64::MIN_POSITIVE))
                                .collect()
                        }),
                    })
                    .collect(),
            );
        }
        return Ok(out);
    }
    if !at.is_us_standard {
        return Err(ctx.err(
            KEY,
            format!(
                "{} holds k(z) precomputed for the unscaled AFGL 1986 US standard atmosphere; it cannot \
                 describe profile \"{}\" or a rescaled one (use an axsdb database for other profiles)",
                file.display(),
                at.profile_name
            ),
        ));
    }
    let db = crate::util::file_cache::cached(file, "", || EradiateV0Ckd::open(file, None))
        .map_err(|e| ctx.err(KEY, e.to_string()))?;
    let mut out = Vec::with_capacity(wavelengths.len());
    for (iw, &wl) in wavelengths.iter().enumerate() {
        let bin = db.bin_containing(wl).ok_or_else(|| {
            let b = db.bins();
            no_bin(
                iw,
                wl,
                b.first().map_or(f64::NAN, |x| x.lower_nm),
                b.last().map_or(f64::NAN, |x| x.upper_nm),
            )
        })?;
        let mut per_g = Vec::new();
        for g in pick(bin.g.len())? {
            let w = if g_point.is_some() {
                1.0
            } else {
                bin.weights[g]
            };
            let taus = grid
                .iter()
                .map(|&(b, t)| {
                    db.optical_thickness(bin, g, b, t, V0Interpolation::Cells)
                        .map(|x| x.max(0.0))
                        .map_err(|e| ctx.err(KEY, e.to_string()))
                })
                .collect::<Result<Vec<f64>, _>>()?;
            per_g.push(GPoint::new(w, taus));
        }
        out.push(per_g);
    }
    Ok(out)
}

/// Whether a file is an RRTMGP k-distribution (it has `kmajor`).
fn is_rrtmgp(file: &Path) -> bool {
    let _session = crate::netcdf_session();
    file.is_file()
        && netcdf::open(file)
            .map(|f| f.variable("kmajor").is_some())
            .unwrap_or(false)
}

/// `mode = "ckd"` with `spectral.srf`: the bins (lower, upper) \[nm\] of the absorption data
/// `file` (`atmosphere.absorption_data` of a `molecular` atmosphere; None: there is none), or
/// None for RRTMGP, whose bands are too wide to sample a sensor band (the band is then sampled
/// every `wavelength_step` nm, each wavelength with its RRTMGP band's g-points).
pub fn ckd_bins(
    ctx: &ConfigCtx,
    file: Option<&str>,
) -> Result<Option<Vec<(f64, f64)>>, ConfigError> {
    let Some(file) = file else {
        return Err(ctx.err(
            "atmosphere",
            "mode = \"ckd\" needs a `molecular` atmosphere with `absorption_data`",
        ));
    };
    let path = ctx.file(file);
    if path.is_dir() {
        let db = super::AxsDatabase::open(&path).map_err(|e| ctx.err(KEY, e.to_string()))?;
        Ok(Some(
            db.bins().iter().map(|b| (b.lower_nm, b.upper_nm)).collect(),
        ))
    } else if is_rrtmgp(&path) {
        Ok(None)
    } else {
        let db =
            crate::util::file_cache::cached(&path, "", || super::EradiateV0Ckd::open(&path, None))
                .map_err(|e| ctx.err(KEY, e.to_string()))?;
        Ok(Some(
            db.bins().iter().map(|b| (b.lower_nm, b.upper_nm)).collect(),
        ))
    }
}

/// `atmosphere.cross_sections`: per wavelength, the continuum absorption optical thickness of
/// every layer of `at.grid`, summed over the tables (`absorption/cross_section.rs`).
pub fn resolve_cross_sections(
    ctx: &ConfigCtx,
    tables: &[CrossSectionConfig],
    at: &GasLayers,
) -> Result<Vec<Vec<f64>>, ConfigError> {
    use super::cross_section::{layer_columns, CrossSection};
    let (grid, wavelengths) = (at.grid, at.wavelengths);
    let mut tau = vec![vec![0.0; grid.len()]; wavelengths.len()];
    for (i, t) in tables.iter().enumerate() {
        let key = format!("atmosphere.cross_sections[{i}]");
        let xs = CrossSection::read(&ctx.file(&t.file), t.column, t.units.to_m2())
            .map_err(|e| ctx.err(format!("{key}.file"), e.to_string()))?;
        let cols = layer_columns(at.gas, &t.species, grid)
            .map_err(|e| ctx.err(format!("{key}.species"), e.to_string()))?;
        let mut zeroed = Vec::new();
        for (iw, &wl) in wavelengths.iter().enumerate() {
            let Some(sigma) = xs.at(wl) else {
                if t.outside == OutsideTable::Zero {
                    zeroed.push(wl);
                    continue;
                }
                return Err(ctx.err(
                    format!("{key}.file"),
                    format!(
                        "{wl} nm lies outside the table's {}..{} nm ({})",
                        xs.wavelength_nm[0],
                        xs.wavelength_nm[xs.wavelength_nm.len() - 1],
                        xs.path
                    ),
                ));
            };
            for (j, c) in cols.iter().enumerate() {
                tau[iw][j] += sigma * c;
            }
        }
        if !zeroed.is_empty() {
            tracing::warn!(
                "{key}: {} wavelength(s) outside the table ({}..{} nm) get no {} absorption (`outside = \"zero\"`), e.g. {} nm",
                zeroed.len(),
                xs.wavelength_nm[0],
                xs.wavelength_nm[xs.wavelength_nm.len() - 1],
                t.species,
                zeroed[0]
            );
        }
        let column: f64 = cols.iter().sum();
        tracing::info!(
            "{key}: {} continuum from {} (column {:.4e} m⁻² in the atmosphere)",
            t.species,
            xs.path,
            column
        );
    }
    Ok(tau)
}

/// `mode = "mono"` with `absorption_data`: per wavelength, the gas absorption optical thickness
/// of each layer from an axsdb monochromatic database (linear in wavelength between its
/// spectral points) at the profile's (p, T, x).
pub fn resolve_mono_gas(
    ctx: &ConfigCtx,
    dir: &Path,
    at: &GasLayers,
    bounds: BoundsPolicy,
) -> Result<Vec<Vec<f64>>, ConfigError> {
    use super::{AxsDatabase, DatabaseKind, SpectralPoint};
    if !dir.is_dir() {
        return Err(ctx.err(
            KEY,
            format!(
                "{}: in mode = \"mono\" this must be an axsdb monochromatic database directory \
                 (correlated-k files and databases need mode = \"ckd\")",
                dir.display()
            ),
        ));
    }
    let db = AxsDatabase::open(dir).map_err(|e| ctx.err(KEY, e.to_string()))?;
    if db.kind() != DatabaseKind::Mono {
        return Err(ctx.err(
            KEY,
            format!(
                "{} is a correlated-k database; use it with mode = \"ckd\"",
                dir.display()
            ),
        ));
    }
    let cols = super::layers::GasColumns::new(at.gas, at.grid);
    let (lo, hi) = db.spectral_range_nm();
    at.wavelengths
        .iter()
        .enumerate()
        .map(|(iw, &wl)| {
            if wl < lo || wl > hi {
                return Err(ctx.err(
                    format!("spectral.wavelengths[{iw}]"),
                    format!("{wl} nm is outside {} ({lo}..{hi} nm)", dir.display()),
                ));
            }
            cols.layer_tau(&db, SpectralPoint::Mono { wavelength_nm: wl }, bounds)
                .map_err(|m| ctx.err(KEY, format!("{wl} nm: {m}")))
        })
        .collect()
}
