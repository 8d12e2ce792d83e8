//! Validation of an [`ExperimentConfig`] into runtime types that cannot hold an invalid state:
//! ranges checked, files loaded, units converted (km → m, degrees → radians).
//! Every error names the experiment file and the key path (e.g. `atmosphere.layers[1].tau_sca`).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::DVec3;

use super::*;
use crate::atmosphere::molecular::{
    depolarization as molecular_depolarization, rayleigh_cross_section,
};
use crate::atmosphere::particles::{Distribution, ParticleDataset, VerticalProfile};
use crate::atmosphere::spherical::SphericalShell;
use crate::atmosphere::{LayerOptics, PlaneParallel};
use crate::bsdf::{Bsdf, Hapke, Lambertian, Ocean, Rpv, Rtls};
use crate::error::ConfigError;
use crate::frame::direction_from_angles;
pub use crate::integrator::settings::{IntegratorKind, IntegratorSettings};
use crate::measure::{Measure, MeasureKind};
use crate::optics::OpticalState;
use crate::phase::{HenyeyGreenstein, Mixture, PhaseFunction, Rayleigh, Tabulated};
use crate::scene::Scene;
use crate::solar::{day_of_year, earth_sun_factor, Spectrum};
use crate::srf::Srf;
use crate::sun_position::sun_position;

/// A sensor band sampled by the run's wavelengths.
#[derive(Clone, Debug)]
pub struct Band {
    pub name: String,
    /// Weights, one per wavelength: trapezoid `S(λ_k)·Δλ_k` in mono mode, `∫_bin S dλ` in CKD mode.
    pub weights: Vec<f64>,
}

/// A validated experiment.
#[derive(Clone, Debug)]
pub struct Experiment {
    pub wavelengths: Vec<f64>,
    /// The sensor band the wavelengths sample, if `spectral.srf` was given.
    pub band: Option<Band>,
    /// One per wavelength.
    pub optics: Vec<OpticalState>,
    /// Solar zenith and azimuth, radians.
    pub sun_zenith: f64,
    pub sun_azimuth: f64,
    /// Unit vector from the target towards the Sun.
    pub sun_dir: DVec3,
    /// The solar angles as given, degrees (azimuth normalised to [0, 360)).
    pub sun_zenith_deg: f64,
    pub sun_azimuth_deg: f64,
    /// Earth–Sun distance (AU) when the Sun comes from `illumination.time` (or `date`).
    pub sun_distance_au: Option<f64>,
    pub measures: Vec<Measure>,
    pub integrator: IntegratorSettings,
    pub seed: u64,
    /// Stokes-vector transport.
    pub polarized: bool,
    /// Spherical-shell geometry: the planet radius, m (None: plane-parallel).
    pub planet_radius: Option<f64>,
    /// The 3D scene, when the experiment renders one (shared: it can be large).
    pub scene: Option<Arc<Scene>>,
    /// The experiment file's text (written into the products for provenance).
    pub source_text: String,
    pub source_path: PathBuf,
}

impl Experiment {
    /// The cosine that normalises samples and BRFs: cos SZA when the Sun is above the target's
    /// horizon, else 1 (twilight in spherical shells: radiance only, no BRF).
    /// Whether the Sun is above the target's horizon (SZA below 90° by more than 0.2″).
    pub fn sun_up(&self) -> bool {
        self.sun_dir.z > 1e-6
    }

    pub fn mu_norm(&self) -> f64 {
        if self.sun_up() {
            self.sun_dir.z
        } else {
            1.0
        }
    }

    /// Read and resolve an experiment file; relative paths inside are taken from its folder.
    pub fn load(path: &Path) -> Result<Experiment, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_str(&text, path)
    }

    /// Parse and resolve experiment text; `path` names it in errors and anchors relative paths.
    pub fn from_str(text: &str, path: &Path) -> Result<Experiment, ConfigError> {
        let parse_err = |message: String| ConfigError::Parse {
            path: path.to_path_buf(),
            message,
        };
        let de = toml::Deserializer::parse(text).map_err(|e| parse_err(e.to_string()))?;
        let cfg: ExperimentConfig = serde_path_to_error::deserialize(de).map_err(|e| {
            let key = e.path().to_string();
            let inner = e.into_inner().to_string().trim_end().to_string();
            let hint = locate_offender(text, &inner);
            if key.is_empty() || key == "." {
                parse_err(format!("{inner}{hint}"))
            } else {
                parse_err(format!("at key `{key}`: {inner}{hint}"))
            }
        })?;
        resolve(cfg, text, path)
    }
}

/// serde loses the key path inside tagged tables (e.g. `atmosphere.phase`); find the full
/// path(s) of the offending key or value named in `message` by walking the TOML tree.
fn locate_offender(text: &str, message: &str) -> String {
    let quoted = |prefix: &str| -> Option<String> {
        let i = message.find(prefix)? + prefix.len();
        let rest = &message[i..];
        let end = rest.find('`')?;
        Some(rest[..end].to_string())
    };
    let string_value = || -> Option<String> {
        let i = message.find("invalid type: string \"")? + "invalid type: string \"".len();
        let rest = &message[i..];
        Some(rest[..rest.find('"')?].to_string())
    };
    let number_value = || -> Option<String> {
        let i = message.find("invalid type: ")?;
        let rest = &message[i..];
        let a = rest.find('`')? + 1;
        let b = a + rest[a..].find('`')?;
        Some(rest[a..b].to_string())
    };
    let (needle, is_key) = if let Some(k) = quoted("unknown field `") {
        (k, true)
    } else if let Some(v) = quoted("unknown variant `").or_else(string_value) {
        (v, false)
    } else if let Some(v) = number_value() {
        (v, false)
    } else {
        return String::new();
    };
    let Ok(root) = text.parse::<toml::Table>() else {
        return String::new();
    };
    let mut found = Vec::new();
    fn walk(v: &toml::Value, path: String, needle: &str, is_key: bool, found: &mut Vec<String>) {
        match v {
            toml::Value::Table(t) => {
                for (k, x) in t {
                    let p = if path.is_empty() {
                        k.clone()
                    } else {
                        format!("{path}.{k}")
                    };
                    let hit = if is_key {
                        k == needle
                    } else {
                        match x {
                            toml::Value::String(s) => s == needle,
                            toml::Value::Integer(i) => i.to_string() == needle,
                            toml::Value::Float(f) => {
                                f.to_string() == needle || format!("{f:?}") == needle
                            }
                            _ => false,
                        }
                    };
                    if hit {
                        found.push(p.clone());
                    }
                    walk(x, p, needle, is_key, found);
                }
            }
            toml::Value::Array(a) => {
                for (i, x) in a.iter().enumerate() {
                    walk(x, format!("{path}[{i}]"), needle, is_key, found);
                }
            }
            _ => {}
        }
    }
    walk(
        &toml::Value::Table(root),
        String::new(),
        &needle,
        is_key,
        &mut found,
    );
    if found.is_empty() {
        String::new()
    } else {
        format!(" (offending key: `{}`)", found.join("`, `"))
    }
}

struct Ctx<'a> {
    path: &'a Path,
    nw: usize,
}

impl Ctx<'_> {
    fn err(&self, key: impl Into<String>, message: impl Into<String>) -> ConfigError {
        ConfigError::Invalid {
            path: self.path.to_path_buf(),
            key: key.into(),
            message: message.into(),
        }
    }

    /// Expand a spectral value to one number per wavelength, each finite and within `range`.
    fn spectral(
        &self,
        key: &str,
        v: &SpectralValue,
        lo: f64,
        hi: f64,
    ) -> Result<Vec<f64>, ConfigError> {
        let vals = match v {
            SpectralValue::Scalar(x) => vec![*x; self.nw],
            SpectralValue::List(l) => {
                if l.len() != self.nw {
                    return Err(self.err(
                        key,
                        format!(
                            "has {} values but there are {} wavelengths",
                            l.len(),
                            self.nw
                        ),
                    ));
                }
                l.clone()
            }
        };
        for (i, x) in vals.iter().enumerate() {
            if !x.is_finite() || *x < lo || *x > hi {
                let at = if matches!(v, SpectralValue::List(_)) {
                    format!("[{i}]")
                } else {
                    String::new()
                };
                return Err(self.err(
                    format!("{key}{at}"),
                    format!("{x} must lie in [{lo}, {hi}]"),
                ));
            }
        }
        Ok(vals)
    }

    fn finite(&self, key: &str, x: f64) -> Result<f64, ConfigError> {
        if x.is_finite() {
            Ok(x)
        } else {
            Err(self.err(key, format!("{x} is not a finite number")))
        }
    }
}

/// One particle layer, resolved: its fraction in each computational layer, and per run
/// wavelength its column optical thickness, single-scattering albedo and phase function.
struct ResolvedParticles {
    fractions: Vec<f64>,
    tau: Vec<f64>,
    ssa: Vec<f64>,
    phase: Vec<PhaseFunction>,
}

/// Resolve `atmosphere.particle_layers` on the computational `grid` (m, bottom to top).
fn resolve_particle_layers(
    ctx: &Ctx,
    base: &Path,
    layers: &[ParticleLayerConfig],
    grid: &[(f64, f64)],
    wavelengths: &[f64],
) -> Result<Vec<ResolvedParticles>, ConfigError> {
    let (ground, toa) = (grid[0].0, grid[grid.len() - 1].1);
    // Datasets and phase functions shared between layers: (file, size_index) and run wavelength.
    let mut datasets: Vec<(PathBuf, usize, ParticleDataset)> = Vec::new();
    let mut phases: Vec<(usize, usize, PhaseFunction)> = Vec::new();
    let mut out = Vec::with_capacity(layers.len());
    for (ip, l) in layers.iter().enumerate() {
        let key = format!("atmosphere.particle_layers[{ip}]");
        let k = |s: &str| format!("{key}.{s}");
        let bottom = ctx.finite(&k("bottom"), l.bottom)? * 1e3;
        let top = ctx.finite(&k("top"), l.top)? * 1e3;
        if bottom < ground - 1e-6 || top > toa + 1e-6 {
            return Err(ctx.err(
                k(if bottom < ground - 1e-6 {
                    "bottom"
                } else {
                    "top"
                }),
                format!(
                    "{}..{} km must lie within ground_altitude..toa_altitude = {}..{} km",
                    l.bottom,
                    l.top,
                    ground / 1e3,
                    toa / 1e3
                ),
            ));
        }
        let tau_ref = ctx.finite(&k("optical_thickness"), l.optical_thickness)?;
        if tau_ref < 0.0 {
            return Err(ctx.err(k("optical_thickness"), format!("{tau_ref} must be ≥ 0")));
        }
        let wl_ref = ctx.finite(&k("reference_wavelength"), l.reference_wavelength)?;
        if wl_ref <= 0.0 {
            return Err(ctx.err(
                k("reference_wavelength"),
                format!("{wl_ref} nm must be positive"),
            ));
        }
        let shape = match l.distribution {
            DistributionConfig::Uniform => Distribution::Uniform,
            DistributionConfig::Exponential { scale_height } => Distribution::Exponential {
                scale_height: scale_height * 1e3,
            },
            DistributionConfig::Gaussian { mean, std } => Distribution::Gaussian {
                mean: mean * 1e3,
                std: std * 1e3,
            },
        };
        let profile =
            VerticalProfile::new(bottom, top, shape).map_err(|(sub, m)| ctx.err(k(&sub), m))?;
        let fractions = profile.fractions(grid);
        let fpath = base.join(&l.dataset);
        let ids = match datasets
            .iter()
            .position(|(p, s, _)| *p == fpath && *s == l.size_index)
        {
            Some(i) => i,
            None => {
                if !fpath.exists() {
                    return Err(
                        ctx.err(k("dataset"), format!("file {} not found", fpath.display()))
                    );
                }
                let d = ParticleDataset::load(&fpath, l.size_index)
                    .map_err(|e| ctx.err(k("dataset"), e.to_string()))?;
                datasets.push((fpath.clone(), l.size_index, d));
                datasets.len() - 1
            }
        };
        let ds = &datasets[ids].2;
        ds.extinction(wl_ref)
            .map_err(|e| ctx.err(k("reference_wavelength"), e.to_string()))?;
        let (mut tau, mut ssa, mut phase) = (Vec::new(), Vec::new(), Vec::new());
        for (iw, &wl) in wavelengths.iter().enumerate() {
            let at = |e: crate::atmosphere::particles::DatasetError| {
                ctx.err(k("dataset"), format!("run wavelength {wl} nm: {e}"))
            };
            tau.push(tau_ref * ds.extinction_ratio(wl, wl_ref).map_err(at)?);
            ssa.push(ds.albedo(wl).map_err(at)?);
            let p = match phases.iter().find(|(d, w, _)| *d == ids && *w == iw) {
                Some((_, _, p)) => p.clone(),
                None => {
                    let p = PhaseFunction::Tabulated(Arc::new(ds.phase(wl).map_err(at)?));
                    phases.push((ids, iw, p.clone()));
                    p
                }
            };
            phase.push(p);
        }
        out.push(ResolvedParticles {
            fractions,
            tau,
            ssa,
            phase,
        });
    }
    Ok(out)
}

/// Validate a parsed experiment. `text` and `path` are kept for provenance and messages.
pub fn resolve(cfg: ExperimentConfig, text: &str, path: &Path) -> Result<Experiment, ConfigError> {
    let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let mut ctx = Ctx { path, nw: 0 };
    let ckd = match cfg.mode.as_str() {
        "mono" => false,
        "ckd" => true,
        other => {
            return Err(ctx.err(
                "mode",
                format!("\"{other}\" is not supported (supported: \"mono\", \"ckd\")"),
            ))
        }
    };
    if cfg.spectral.g_point.is_some() && !ckd {
        return Err(ctx.err("spectral.g_point", "is used only with mode = \"ckd\""));
    }
    if cfg.spectral.g_points.is_some() && !ckd {
        return Err(ctx.err("spectral.g_points", "is used only with mode = \"ckd\""));
    }
    let (wavelengths, band) = match (&cfg.spectral.wavelengths, &cfg.spectral.srf) {
        (Some(w), None) => {
            if cfg.spectral.wavelength_step.is_some() {
                return Err(ctx.err("spectral.wavelength_step", "is used only with `srf`"));
            }
            (w.clone(), None)
        }
        (None, Some(name)) => {
            let srf = match Srf::builtin(name).map_err(|m| ctx.err("spectral.srf", m))? {
                Some(s) => s,
                None => {
                    let fpath = base.join(name);
                    let text = std::fs::read_to_string(&fpath).map_err(|e| {
                        ctx.err("spectral.srf", format!("\"{name}\" is neither an embedded SRF (e.g. \"sentinel_2a-msi-4\") nor a readable file ({}: {e})", fpath.display()))
                    })?;
                    Srf::from_csv(name, &text)
                        .map_err(|m| ctx.err("spectral.srf", format!("{}: {m}", fpath.display())))?
                }
            };
            let bins = if ckd {
                ckd_bins(&ctx, &base, &cfg)?
            } else {
                None
            };
            if let Some(bins) = bins {
                if cfg.spectral.wavelength_step.is_some() {
                    return Err(ctx.err(
                        "spectral.wavelength_step",
                        "is not used in mode = \"ckd\": the absorption data's bins sample the band",
                    ));
                }
                let weights = srf.bin_weights(&bins);
                let (mut w, mut wt) = (Vec::new(), Vec::new());
                for (&(lo, hi), &x) in bins.iter().zip(&weights) {
                    if x > 0.0 {
                        w.push(0.5 * (lo + hi));
                        wt.push(x);
                    }
                }
                if w.is_empty() {
                    return Err(ctx.err(
                        "spectral.srf",
                        format!("band \"{name}\" overlaps no bin of the absorption data"),
                    ));
                }
                (
                    w,
                    Some(Band {
                        name: name.clone(),
                        weights: wt,
                    }),
                )
            } else {
                let step = cfg.spectral.wavelength_step.unwrap_or(5.0);
                if !(step > 0.0 && step.is_finite()) {
                    return Err(ctx.err(
                        "spectral.wavelength_step",
                        format!("{step} nm must be positive"),
                    ));
                }
                let (w, weights) = srf.grid(step).map_err(|m| ctx.err("spectral.srf", m))?;
                (
                    w,
                    Some(Band {
                        name: name.clone(),
                        weights,
                    }),
                )
            }
        }
        (Some(_), Some(_)) => {
            return Err(ctx.err("spectral", "give either `wavelengths` or `srf`, not both"))
        }
        (None, None) => {
            return Err(ctx.err("spectral", "give `wavelengths` (nm) or a sensor band `srf`"))
        }
    };
    if wavelengths.is_empty() {
        return Err(ctx.err("spectral.wavelengths", "must list at least one wavelength"));
    }
    for (i, w) in wavelengths.iter().enumerate() {
        if !w.is_finite() || *w <= 0.0 {
            return Err(ctx.err(
                format!("spectral.wavelengths[{i}]"),
                format!("{w} nm must be positive"),
            ));
        }
    }
    ctx.nw = wavelengths.len();
    let nw = ctx.nw;

    // Geometry.
    let (toa_altitude, ground_altitude, planet_radius) = match cfg.geometry {
        GeometryConfig::PlaneParallel {
            toa_altitude,
            ground_altitude,
        } => (toa_altitude, ground_altitude, None),
        GeometryConfig::SphericalShell {
            toa_altitude,
            ground_altitude,
            planet_radius,
        } => {
            let r = ctx.finite("geometry.planet_radius", planet_radius)?;
            if r <= 0.0 {
                return Err(ctx.err("geometry.planet_radius", format!("{r} km must be positive")));
            }
            if r + ground_altitude <= 0.0 {
                return Err(ctx.err("geometry.ground_altitude", "lies below the planet's centre"));
            }
            (toa_altitude, ground_altitude, Some(r * 1e3))
        }
    };
    let toa = ctx.finite("geometry.toa_altitude", toa_altitude)? * 1e3;
    let ground = ctx.finite("geometry.ground_altitude", ground_altitude)? * 1e3;
    if toa <= ground {
        return Err(ctx.err(
            "geometry.toa_altitude",
            format!("{toa_altitude} km must be above ground_altitude = {ground_altitude} km"),
        ));
    }

    // Atmosphere: per wavelength, a list of layers.
    let mut layers_per_w: Vec<Vec<LayerOptics>> = vec![Vec::new(); nw];
    // CKD: per wavelength, per g-point: (weight, gas absorption optical thickness per layer of
    // `layers_per_w[iw]`, in order).
    let mut ckd_tau: Vec<Vec<GPoint>> = Vec::new();
    let mut phase_cache: Vec<(String, f64, usize, Arc<Tabulated>)> = Vec::new();
    let mut make_phase =
        |key: &str, p: &PhaseConfig, iw: usize| -> Result<PhaseFunction, ConfigError> {
            Ok(match p {
                PhaseConfig::Rayleigh { depolarization } => PhaseFunction::Rayleigh(
                    Rayleigh::new(*depolarization)
                        .map_err(|m| ctx.err(format!("{key}.depolarization"), m))?,
                ),
                PhaseConfig::Hg { g } => PhaseFunction::Hg(
                    HenyeyGreenstein::new(*g).map_err(|m| ctx.err(format!("{key}.g"), m))?,
                ),
                PhaseConfig::Isotropic {} => PhaseFunction::Hg(HenyeyGreenstein { g: 0.0 }),
                PhaseConfig::Tabulated {
                    file,
                    wavelength,
                    size_index,
                } => {
                    let wl = wavelength.unwrap_or(wavelengths[iw]);
                    if let Some((_, _, _, t)) = phase_cache
                        .iter()
                        .find(|(f, w, s, _)| f == file && *w == wl && s == size_index)
                    {
                        return Ok(PhaseFunction::Tabulated(t.clone()));
                    }
                    let fpath = base.join(file);
                    if !fpath.exists() {
                        return Err(ctx.err(
                            format!("{key}.file"),
                            format!("file {} not found", fpath.display()),
                        ));
                    }
                    let t = Tabulated::load_libradtran(&fpath, wl, *size_index)
                        .map_err(|e| ctx.err(format!("{key}.file"), e.to_string()))?;
                    let t = Arc::new(t);
                    phase_cache.push((file.clone(), wl, *size_index, t.clone()));
                    PhaseFunction::Tabulated(t)
                }
            })
        };
    match &cfg.atmosphere {
        None | Some(AtmosphereConfig::None {}) => {}
        Some(AtmosphereConfig::Homogeneous {
            optical_thickness,
            single_scattering_albedo,
            phase,
        }) => {
            let tau = ctx.spectral("atmosphere.optical_thickness", optical_thickness, 0.0, 1e6)?;
            let ssa = ctx.spectral(
                "atmosphere.single_scattering_albedo",
                single_scattering_albedo,
                0.0,
                1.0,
            )?;
            for iw in 0..nw {
                let phase = make_phase("atmosphere.phase", phase, iw)?;
                layers_per_w[iw].push(LayerOptics {
                    bottom: ground,
                    top: toa,
                    tau_sca: tau[iw] * ssa[iw],
                    tau_abs: tau[iw] * (1.0 - ssa[iw]),
                    phase,
                });
            }
        }
        Some(AtmosphereConfig::Molecular {
            profile,
            layer_thickness,
            particle_layers,
            absorption_data,
            rayleigh,
            depolarization,
            rescale,
            absorption_bounds,
            cross_sections,
        }) => {
            let mut thermo = crate::atmosphere::thermo::load(profile, &base)
                .map_err(|m| ctx.err("atmosphere.profile", m))?;
            crate::atmosphere::thermo::rescale(&mut thermo, rescale)
                .map_err(|(k, m)| ctx.err(k, m))?;
            let bounds = resolve_bounds(&ctx, absorption_bounds)?;
            let prof = thermo.rayleigh.clone();
            if let Some(d) = depolarization {
                let d = ctx.finite("atmosphere.depolarization", *d)?;
                if !(0.0..0.5).contains(&d) {
                    return Err(ctx.err(
                        "atmosphere.depolarization",
                        format!("{d} must lie in [0, 0.5)"),
                    ));
                }
            }
            let dz = ctx.finite("atmosphere.layer_thickness", *layer_thickness)? * 1e3;
            if dz <= 0.0 {
                return Err(ctx.err(
                    "atmosphere.layer_thickness",
                    format!("{layer_thickness} km must be positive"),
                ));
            }
            if ground < prof.z[0] || toa > prof.top() + 1e-6 {
                return Err(ctx.err(
                    "geometry",
                    format!(
                        "ground_altitude..toa_altitude = {}..{} km must lie within the profile's {}..{} km",
                        ground / 1e3,
                        toa / 1e3,
                        prof.z[0] / 1e3,
                        prof.top() / 1e3
                    ),
                ));
            }
            let mut grid = Vec::new();
            let mut z = ground;
            while z < toa - 1e-6 {
                let top = (z + dz).min(toa);
                grid.push((z, top));
                z = top;
            }
            let particles =
                resolve_particle_layers(&ctx, &base, particle_layers, &grid, &wavelengths)?;
            let continuum =
                resolve_cross_sections(&ctx, &base, cross_sections, &thermo, &grid, &wavelengths)?;
            let mut mono_gas: Vec<Vec<f64>> = Vec::new();
            match (ckd, absorption_data) {
                (true, None) => {
                    return Err(ctx.err(
                        "atmosphere.absorption_data",
                        "mode = \"ckd\" needs a correlated-k absorption file or database",
                    ))
                }
                (false, None) => {
                    if !rescale.is_empty() {
                        tracing::warn!(
                            "atmosphere.rescale changes only gas absorption, and this atmosphere has no `absorption_data`"
                        );
                    }
                }
                (false, Some(file)) => {
                    mono_gas = resolve_mono_gas(
                        &ctx,
                        &base.join(file),
                        &thermo,
                        &grid,
                        &wavelengths,
                        bounds,
                    )?;
                }
                (true, Some(file)) => {
                    ckd_tau = resolve_ckd(
                        &ctx,
                        &base.join(file),
                        &thermo,
                        &grid,
                        &wavelengths,
                        &cfg.spectral,
                        bounds,
                    )?;
                }
            }
            for (j, &(bottom, top)) in grid.iter().enumerate() {
                let column = prof.column(bottom, top);
                for iw in 0..nw {
                    let wl = wavelengths[iw];
                    let rayleigh_phase = PhaseFunction::Rayleigh(
                        Rayleigh::new(
                            depolarization.unwrap_or_else(|| molecular_depolarization(wl)),
                        )
                        .expect("air depolarization is in range"),
                    );
                    let tau_ray = if *rayleigh {
                        column * rayleigh_cross_section(wl)
                    } else {
                        0.0
                    };
                    // Rayleigh first, then each particle layer's scattering (τ_aer·ω) and
                    // absorption (τ_aer·(1 − ω)); the phase function is the mixture weighted by
                    // the scattering optical thicknesses (plain Rayleigh without particles).
                    let gas = mono_gas.get(iw).map_or(0.0, |t| t[j]) + continuum[iw][j];
                    let (mut tau_sca, mut tau_abs) = (tau_ray, gas);
                    let mut parts = Vec::new();
                    for p in &particles {
                        let tau_aer = p.tau[iw] * p.fractions[j];
                        if tau_aer > 0.0 {
                            tau_sca += tau_aer * p.ssa[iw];
                            tau_abs += tau_aer * (1.0 - p.ssa[iw]);
                            parts.push((tau_aer * p.ssa[iw], p.phase[iw].clone()));
                        }
                    }
                    let phase = if parts.iter().all(|(w, _)| *w <= 0.0) {
                        rayleigh_phase
                    } else {
                        if tau_ray > 0.0 {
                            parts.insert(0, (tau_ray, rayleigh_phase));
                        }
                        Mixture::build(parts).map_err(|m| {
                            ctx.err("atmosphere.particle_layers", format!("{wl} nm: {m}"))
                        })?
                    };
                    layers_per_w[iw].push(LayerOptics {
                        bottom,
                        top,
                        tau_sca,
                        tau_abs,
                        phase,
                    });
                }
            }
        }
        Some(AtmosphereConfig::Layered { layers }) => {
            if layers.is_empty() {
                return Err(ctx.err("atmosphere.layers", "must list at least one layer"));
            }
            let mut spans = Vec::new();
            for (il, l) in layers.iter().enumerate() {
                let key = format!("atmosphere.layers[{il}]");
                let (b, t) = (
                    ctx.finite(&format!("{key}.bottom"), l.bottom)?,
                    ctx.finite(&format!("{key}.top"), l.top)?,
                );
                if t <= b {
                    return Err(ctx.err(
                        format!("{key}.top"),
                        format!("{t} km must be above bottom = {b} km"),
                    ));
                }
                spans.push((b * 1e3, t * 1e3, il));
                let (tau_sca, tau_abs) = match (&l.tau_sca, &l.tau_abs, &l.optical_thickness, &l.single_scattering_albedo) {
                    (sca, abs, None, None) if sca.is_some() || abs.is_some() => {
                        let zero = SpectralValue::Scalar(0.0);
                        (
                            ctx.spectral(&format!("{key}.tau_sca"), sca.as_ref().unwrap_or(&zero), 0.0, 1e6)?,
                            ctx.spectral(&format!("{key}.tau_abs"), abs.as_ref().unwrap_or(&zero), 0.0, 1e6)?,
                        )
                    }
                    (None, None, Some(tau), ssa) => {
                        let tau = ctx.spectral(&format!("{key}.optical_thickness"), tau, 0.0, 1e6)?;
                        let ssa = ctx.spectral(
                            &format!("{key}.single_scattering_albedo"),
                            ssa.as_ref().unwrap_or(&SpectralValue::Scalar(1.0)),
                            0.0,
                            1.0,
                        )?;
                        (
                            tau.iter().zip(&ssa).map(|(t, s)| t * s).collect(),
                            tau.iter().zip(&ssa).map(|(t, s)| t * (1.0 - s)).collect(),
                        )
                    }
                    _ => {
                        return Err(ctx.err(
                            key,
                            "give either `tau_sca` and/or `tau_abs`, or `optical_thickness` (with an optional \
                             `single_scattering_albedo`), not both",
                        ))
                    }
                };
                for iw in 0..nw {
                    let phase = make_phase(&format!("{key}.phase"), &l.phase, iw)?;
                    layers_per_w[iw].push(LayerOptics {
                        bottom: b * 1e3,
                        top: t * 1e3,
                        tau_sca: tau_sca[iw],
                        tau_abs: tau_abs[iw],
                        phase,
                    });
                }
            }
            // The layers must tile [ground, toa].
            spans.sort_by(|a, b| a.0.partial_cmp(&b.0).unwrap());
            let mut z = ground;
            for &(b, t, il) in &spans {
                if (b - z).abs() > 1e-6 {
                    let what = if b > z {
                        "leaves a gap below it"
                    } else {
                        "overlaps the layer below"
                    };
                    return Err(ctx.err(
                        format!("atmosphere.layers[{il}].bottom"),
                        format!("{} km {what} (expected {} km; layers must tile ground_altitude..toa_altitude)", b / 1e3, z / 1e3),
                    ));
                }
                z = t;
            }
            if (z - toa).abs() > 1e-6 {
                return Err(ctx.err(
                    "atmosphere.layers",
                    format!(
                        "the top layer ends at {} km but toa_altitude is {} km",
                        z / 1e3,
                        toa / 1e3
                    ),
                ));
            }
        }
    }

    // Surface, per wavelength.
    let surfaces: Vec<Bsdf> = match (&cfg.surface, &cfg.scene) {
        (Some(_), Some(_)) => {
            return Err(ctx.err(
                "surface",
                "is replaced by the scene: give `scene` or `surface`, not both (a bundle's surroundings are `scene.background`)",
            ))
        }
        (None, None) => {
            return Err(ctx.err(
                "surface",
                "is required (or a 3D `scene`)",
            ))
        }
        (None, Some(_)) => vec![Bsdf::Lambertian(Lambertian::new(0.0).expect("valid")); nw],
        (Some(s), None) => {
        let big = 1e6;
        let mut out = Vec::with_capacity(nw);
        match s {
            SurfaceConfig::Lambertian { reflectance } => {
                let r = ctx.spectral("surface.reflectance", reflectance, 0.0, 1.0)?;
                for v in r {
                    out.push(Bsdf::Lambertian(
                        Lambertian::new(v).map_err(|m| ctx.err("surface.reflectance", m))?,
                    ));
                }
            }
            SurfaceConfig::Rpv { rho_0, k, g, rho_c } => {
                let r0 = ctx.spectral("surface.rho_0", rho_0, -big, big)?;
                let kk = ctx.spectral("surface.k", k, -big, big)?;
                let gg = ctx.spectral("surface.g", g, -big, big)?;
                let rc = match rho_c {
                    Some(v) => ctx.spectral("surface.rho_c", v, -big, big)?,
                    None => r0.clone(),
                };
                for iw in 0..nw {
                    out.push(Bsdf::Rpv(
                        Rpv::new(r0[iw], kk[iw], gg[iw], rc[iw])
                            .map_err(|m| ctx.err("surface", m))?,
                    ));
                }
            }
            SurfaceConfig::Rtls {
                f_iso,
                f_vol,
                f_geo,
            } => {
                let a = ctx.spectral("surface.f_iso", f_iso, -big, big)?;
                let b = ctx.spectral("surface.f_vol", f_vol, -big, big)?;
                let c = ctx.spectral("surface.f_geo", f_geo, -big, big)?;
                for iw in 0..nw {
                    out.push(Bsdf::Rtls(
                        Rtls::new(a[iw], b[iw], c[iw]).map_err(|m| ctx.err("surface", m))?,
                    ));
                }
            }
            SurfaceConfig::Ocean {
                wind_speed,
                refractive_index,
                shadowing,
            } => {
                let ws = ctx.spectral("surface.wind_speed", wind_speed, 0.0, 40.0)?;
                let n = ctx.spectral(
                    "surface.refractive_index",
                    refractive_index
                        .as_ref()
                        .unwrap_or(&SpectralValue::Scalar(1.33)),
                    1.0,
                    3.0,
                )?;
                for iw in 0..nw {
                    out.push(Bsdf::Ocean(
                        Ocean::new(ws[iw], n[iw], *shadowing).map_err(|m| ctx.err("surface", m))?,
                    ));
                }
            }
            SurfaceConfig::Hapke {
                w,
                b,
                c,
                theta,
                b_0,
                h,
            } => {
                let w = ctx.spectral("surface.w", w, -big, big)?;
                let b = ctx.spectral("surface.b", b, -big, big)?;
                let c = ctx.spectral("surface.c", c, -big, big)?;
                let th = ctx.spectral("surface.theta", theta, -big, big)?;
                let b0 = ctx.spectral("surface.B_0", b_0, -big, big)?;
                let h = ctx.spectral("surface.h", h, -big, big)?;
                for iw in 0..nw {
                    out.push(Bsdf::Hapke(
                        Hapke::new(w[iw], b[iw], c[iw], th[iw], b0[iw], h[iw])
                            .map_err(|m| ctx.err("surface", m))?,
                    ));
                }
            }
        }
        out
        }
    };

    // Illumination.
    let IlluminationConfig::Directional {
        zenith,
        azimuth,
        irradiance,
        date,
        time,
        latitude,
        longitude,
        elevation,
    } = &cfg.illumination;
    let mut sun_distance_factor = None;
    let mut sun_distance_au = None;
    let (zenith, azimuth) = match (time, zenith) {
        (Some(t), None) => {
            if azimuth.is_some() {
                return Err(ctx.err(
                    "illumination.azimuth",
                    "is computed from `time`; give one or the other",
                ));
            }
            if date.is_some() {
                return Err(ctx.err(
                    "illumination.date",
                    "is implied by `time`; give one or the other",
                ));
            }
            let lat = latitude
                .ok_or_else(|| ctx.err("illumination.latitude", "is required with `time`"))?;
            let lon = longitude
                .ok_or_else(|| ctx.err("illumination.longitude", "is required with `time`"))?;
            let p = sun_position(
                t,
                ctx.finite("illumination.latitude", lat)?,
                ctx.finite("illumination.longitude", lon)?,
                elevation.unwrap_or(0.0),
                None,
            )
            .map_err(|m| ctx.err("illumination.time", m))?;
            tracing::debug!(
                "Sun at {t}: zenith {:.4}°, azimuth {:.4}°, distance {:.6} AU",
                p.zenith,
                p.azimuth,
                p.distance_au
            );
            sun_distance_factor = Some(1.0 / (p.distance_au * p.distance_au));
            sun_distance_au = Some(p.distance_au);
            (p.zenith, p.azimuth)
        }
        (None, Some(z)) => {
            if latitude.is_some() || longitude.is_some() || elevation.is_some() {
                return Err(ctx.err(
                    "illumination",
                    "`latitude`/`longitude`/`elevation` are used only with `time`",
                ));
            }
            (*z, azimuth.unwrap_or(0.0))
        }
        (Some(_), Some(_)) => {
            return Err(ctx.err(
                "illumination.zenith",
                "give either `zenith` (and `azimuth`) or `time` with a place, not both",
            ))
        }
        (None, None) => {
            return Err(ctx.err(
                "illumination",
                "give `zenith` (and `azimuth`), or `time` with `latitude` and `longitude`",
            ))
        }
    };
    let zenith = ctx.finite("illumination.zenith", zenith)?;
    if planet_radius.is_none() && !(0.0..90.0).contains(&zenith) {
        return Err(ctx.err("illumination.zenith", format!("{zenith} degrees must lie in [0, 90) (a plane-parallel atmosphere has no twilight; use geometry.type = \"spherical_shell\")")));
    }
    if !(0.0..=180.0).contains(&zenith) {
        return Err(ctx.err(
            "illumination.zenith",
            format!("{zenith} degrees must lie in [0, 180]"),
        ));
    }
    let azimuth = ctx.finite("illumination.azimuth", azimuth)?;
    if !(-360.0..=360.0).contains(&azimuth) {
        return Err(ctx.err(
            "illumination.azimuth",
            format!("{azimuth} degrees must lie in [-360, 360]"),
        ));
    }
    let mut irradiance = match irradiance {
        IrradianceValue::Value(v) => ctx.spectral("illumination.irradiance", v, 0.0, 1e9)?,
        IrradianceValue::Spectrum(name) => {
            let spectrum = match Spectrum::builtin(name) {
                Some(s) => s,
                None => {
                    let fpath = base.join(name);
                    let text = std::fs::read_to_string(&fpath).map_err(|e| {
                        ctx.err("illumination.irradiance", format!("\"{name}\" is neither a built-in spectrum (\"tsis_1\", \"thuillier_2003\") nor a readable file ({}: {e})", fpath.display()))
                    })?;
                    Spectrum::from_csv(name, &text).map_err(|m| {
                        ctx.err(
                            "illumination.irradiance",
                            format!("{}: {m}", fpath.display()),
                        )
                    })?
                }
            };
            wavelengths
                .iter()
                .map(|&w| {
                    spectrum.at(w).ok_or_else(|| {
                        ctx.err(
                            "illumination.irradiance",
                            format!(
                                "wavelength {w} nm is outside the spectrum \"{name}\" ({}–{} nm)",
                                spectrum.wavelength[0],
                                spectrum.wavelength[spectrum.wavelength.len() - 1]
                            ),
                        )
                    })
                })
                .collect::<Result<Vec<f64>, _>>()?
        }
    };
    if let Some(d) = date {
        let doy = day_of_year(d).map_err(|m| ctx.err("illumination.date", m))?;
        sun_distance_factor = Some(earth_sun_factor(doy));
        sun_distance_au = Some(1.0 / earth_sun_factor(doy).sqrt());
    }
    if let Some(k) = sun_distance_factor {
        irradiance.iter_mut().for_each(|e| *e *= k);
    }
    let sun_zenith = zenith.to_radians();
    let sun_azimuth = azimuth.rem_euclid(360.0).to_radians();
    let sun_dir = direction_from_angles(sun_zenith, sun_azimuth);

    // Scene.
    let scene: Option<Arc<Scene>> = match &cfg.scene {
        None => None,
        Some(sc) => {
            if sun_dir.z <= 1e-6 {
                return Err(ctx.err(
                    "illumination.zenith",
                    "the Sun must be above the horizon to render a 3D scene",
                ));
            }
            // Under a spherical shell the scene is bent onto the planet (scene::curvature).
            let bend = planet_radius.map(|radius| crate::scene::curvature::Curvature { radius });
            let built =
                scene::build_scene_shared(sc, &base, bend).map_err(|(k, m)| ctx.err(k, m))?;
            // (Bent scenes hold bent heights: their lowest point sags below its altitude.)
            if cfg.atmosphere.is_some()
                && built.curvature.is_none()
                && built.z_range[0] < ground - 1e-6
            {
                tracing::warn!(
                    "the scene's lowest point ({:.1} m) is below the atmosphere's bottom ({:.1} m): no atmosphere below it",
                    built.z_range[0],
                    ground
                );
            }
            Some(built)
        }
    };

    // Measures.
    if cfg.measures.is_empty() {
        return Err(ctx.err("measures", "at least one measure is required"));
    }
    let mut measures = Vec::new();
    for (im, m) in cfg.measures.iter().enumerate() {
        let key = format!("measures[{im}]");
        let (id, spp, target) = match m {
            MeasureConfig::Mdistant {
                id,
                spp,
                target_rel_stderr,
                ..
            }
            | MeasureConfig::Radiancemeter {
                id,
                spp,
                target_rel_stderr,
                ..
            }
            | MeasureConfig::DistantFlux {
                id,
                spp,
                target_rel_stderr,
                ..
            }
            | MeasureConfig::Ortho {
                id,
                spp,
                target_rel_stderr,
                ..
            }
            | MeasureConfig::Perspective {
                id,
                spp,
                target_rel_stderr,
                ..
            } => (id, *spp, *target_rel_stderr),
        };
        if id.is_empty()
            || !id.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
            || id.starts_with(|c: char| c.is_ascii_digit())
        {
            return Err(ctx.err(format!("{key}.id"), format!("\"{id}\" must be a non-empty identifier of letters, digits and _ (not starting with a digit)")));
        }
        if measures.iter().any(|x: &Measure| &x.id == id) {
            return Err(ctx.err(
                format!("{key}.id"),
                format!("\"{id}\" is used by another measure"),
            ));
        }
        if spp < 2 {
            return Err(ctx.err(
                format!("{key}.spp"),
                format!("{spp} must be at least 2 (a standard error needs two samples)"),
            ));
        }
        if let Some(t) = target {
            if !(t > 0.0 && t < 1.0) {
                return Err(ctx.err(
                    format!("{key}.target_rel_stderr"),
                    format!("{t} must lie in (0, 1)"),
                ));
            }
        }
        let kind = match m {
            MeasureConfig::Mdistant {
                construct,
                azimuth,
                zeniths,
                azimuths,
                target_m,
                target_height_m,
                ..
            } => {
                let construct = construct.clone().unwrap_or_else(|| {
                    if azimuths.is_some() {
                        "directions".into()
                    } else {
                        "hplane".into()
                    }
                });
                if zeniths.is_empty() {
                    return Err(ctx.err(format!("{key}.zeniths"), "must list at least one zenith"));
                }
                let (mut vza, mut vaa) = (Vec::new(), Vec::new());
                match construct.as_str() {
                    "hplane" => {
                        if azimuths.is_some() {
                            return Err(ctx.err(
                                format!("{key}.azimuths"),
                                "is not used by construct \"hplane\" (use `azimuth`)",
                            ));
                        }
                        let az = azimuth.ok_or_else(|| {
                            ctx.err(
                                format!("{key}.azimuth"),
                                "is required by construct \"hplane\"",
                            )
                        })?;
                        let az = ctx.finite(&format!("{key}.azimuth"), az)?;
                        for (i, &z) in zeniths.iter().enumerate() {
                            if !z.is_finite() || z <= -90.0 || z >= 90.0 {
                                return Err(ctx.err(
                                    format!("{key}.zeniths[{i}]"),
                                    format!("{z} degrees must lie in (-90, 90)"),
                                ));
                            }
                            vza.push(z.abs());
                            vaa.push(if z >= 0.0 { az } else { az + 180.0 }.rem_euclid(360.0));
                        }
                    }
                    "directions" => {
                        if azimuth.is_some() {
                            return Err(ctx.err(
                                format!("{key}.azimuth"),
                                "is not used by construct \"directions\" (use `azimuths`)",
                            ));
                        }
                        let azs = azimuths.as_ref().ok_or_else(|| {
                            ctx.err(
                                format!("{key}.azimuths"),
                                "is required by construct \"directions\"",
                            )
                        })?;
                        if azs.len() != zeniths.len() {
                            return Err(ctx.err(
                                format!("{key}.azimuths"),
                                format!(
                                    "has {} values but `zeniths` has {}",
                                    azs.len(),
                                    zeniths.len()
                                ),
                            ));
                        }
                        for (i, (&z, &a)) in zeniths.iter().zip(azs).enumerate() {
                            if !z.is_finite() || !(0.0..90.0).contains(&z) {
                                return Err(ctx.err(
                                    format!("{key}.zeniths[{i}]"),
                                    format!("{z} degrees must lie in [0, 90)"),
                                ));
                            }
                            let a = ctx.finite(&format!("{key}.azimuths[{i}]"), a)?;
                            vza.push(z);
                            vaa.push(a.rem_euclid(360.0));
                        }
                    }
                    other => {
                        return Err(ctx.err(
                            format!("{key}.construct"),
                            format!("\"{other}\" is unknown (known: \"hplane\", \"directions\")"),
                        ))
                    }
                }
                let directions = vza
                    .iter()
                    .zip(&vaa)
                    .map(|(z, a): (&f64, &f64)| {
                        direction_from_angles(z.to_radians(), a.to_radians())
                    })
                    .collect();
                let area = match (&scene, target_m, target_height_m) {
                    (Some(sc), r, h) => Some(
                        scene::area(sc, *r, *h).map_err(|m| ctx.err(format!("{key}.target_m"), m))?,
                    ),
                    (None, None, None) => None,
                    (None, _, _) => {
                        return Err(ctx.err(
                            format!("{key}.target_m"),
                            "a target area needs a 3D `scene`",
                        ))
                    }
                };
                MeasureKind::Distant {
                    directions,
                    vza,
                    vaa,
                    area,
                }
            }
            MeasureConfig::Ortho {
                pixel_size_m,
                window_m,
                zenith,
                azimuth,
                ..
            } => {
                let sc = scene
                    .as_ref()
                    .ok_or_else(|| ctx.err(key.clone(), "an ortho measure needs a 3D `scene`"))?;
                MeasureKind::Ortho(
                    scene::ortho_grid(sc, *pixel_size_m, *window_m, *zenith, *azimuth)
                        .map_err(|(k, m)| ctx.err(format!("{key}.{k}"), m))?,
                )
            }
            MeasureConfig::Perspective {
                origin_m,
                target_m,
                up,
                fov,
                width,
                height,
                ..
            } => {
                let sc = scene.as_ref().ok_or_else(|| {
                    ctx.err(key.clone(), "a perspective measure needs a 3D `scene`")
                })?;
                MeasureKind::Perspective(
                    scene::camera(sc, *origin_m, *target_m, *up, *fov, *width, *height)
                        .map_err(|(k, m)| ctx.err(format!("{key}.{k}"), m))?,
                )
            }
            MeasureConfig::Radiancemeter { .. } | MeasureConfig::DistantFlux { .. }
                if scene.is_some() =>
            {
                return Err(ctx.err(
                    key.clone(),
                    "radiancemeter and distant_flux measures are 1D; with a 3D scene use `perspective` or an `mdistant` with a target area",
                ))
            }
            MeasureConfig::Radiancemeter {
                origin,
                direction,
                frame_azimuth,
                ..
            } => {
                for i in 0..3 {
                    ctx.finite(&format!("{key}.origin[{i}]"), origin[i])?;
                    ctx.finite(&format!("{key}.direction[{i}]"), direction[i])?;
                }
                let o = DVec3::from_array(*origin) * 1e3;
                let d = DVec3::from_array(*direction);
                if d.length() < 1e-12 {
                    return Err(ctx.err(format!("{key}.direction"), "must not be the zero vector"));
                }
                if o.z < ground {
                    return Err(ctx.err(
                        format!("{key}.origin[2]"),
                        format!(
                            "altitude {} km is below the ground ({} km)",
                            origin[2],
                            ground / 1e3
                        ),
                    ));
                }
                let frame_azimuth = match frame_azimuth {
                    Some(a) => ctx
                        .finite(&format!("{key}.frame_azimuth"), *a)?
                        .to_radians(),
                    None => 0.0,
                };
                MeasureKind::Radiancemeter {
                    origin: o,
                    look: d.normalize(),
                    frame_azimuth,
                }
            }
            MeasureConfig::DistantFlux { altitude, .. } => {
                let a = altitude.map(|a| a * 1e3).unwrap_or(toa);
                if !a.is_finite() || a < ground || a > toa {
                    return Err(ctx.err(
                        format!("{key}.altitude"),
                        format!(
                            "{} km must lie between the ground and the top of the atmosphere",
                            a / 1e3
                        ),
                    ));
                }
                MeasureKind::DistantFlux { altitude: a }
            }
        };
        measures.push(Measure {
            id: id.clone(),
            spp,
            target_rel_stderr: target,
            kind,
        });
    }

    // Integrator.
    let kind = match cfg.integrator.kind.as_deref() {
        None | Some("auto") => IntegratorKind::Auto,
        Some("forward") => IntegratorKind::Forward,
        Some("backward") => IntegratorKind::Backward,
        Some(other) => {
            return Err(ctx.err(
                "integrator.type",
                format!("\"{other}\" is unknown (known: \"auto\", \"forward\", \"backward\")"),
            ))
        }
    };
    if planet_radius.is_some() && kind == IntegratorKind::Forward {
        return Err(ctx.err(
            "integrator.type",
            "spherical-shell atmospheres use the backward walk (\"auto\" or \"backward\")",
        ));
    }
    if kind == IntegratorKind::Forward {
        if let Some((im, _)) = measures
            .iter()
            .enumerate()
            .find(|(_, m)| matches!(m.kind, MeasureKind::Radiancemeter { .. }))
        {
            return Err(ctx.err(format!("measures[{im}]"), "a radiancemeter needs the backward integrator (`integrator.type = \"backward\"` or \"auto\")"));
        }
    }
    if scene.is_some() && kind == IntegratorKind::Forward {
        return Err(ctx.err(
            "integrator.type",
            "3D scenes use the backward walk (\"auto\" or \"backward\")",
        ));
    }
    let max_depth = match cfg.integrator.max_depth {
        Some(0) => return Err(ctx.err("integrator.max_depth", "must be at least 1")),
        Some(d) => d,
        None => u32::MAX,
    };
    let expected_local_estimate = match cfg.integrator.local_estimate.as_deref() {
        None | Some("expected") => true,
        Some("collision") => false,
        Some(other) => {
            return Err(ctx.err(
                "integrator.local_estimate",
                format!("\"{other}\" is unknown (known: \"expected\", \"collision\")"),
            ))
        }
    };
    let alis = match cfg.integrator.ckd_walk.as_deref() {
        None | Some("cycle") => false,
        Some("alis") => {
            if !ckd {
                return Err(ctx.err(
                    "integrator.ckd_walk",
                    "is used only with mode = \"ckd\" (monochromatic runs: integrator.spectral_walk = \"alis\")",
                ));
            }
            if cfg.polarized || planet_radius.is_some() || scene.is_some() {
                return Err(ctx.err(
                    "integrator.ckd_walk",
                    "\"alis\" is implemented for scalar plane-parallel 1D runs only",
                ));
            }
            if kind == IntegratorKind::Forward {
                return Err(ctx.err(
                    "integrator.ckd_walk",
                    "\"alis\" is a backward walk (integrator.type \"auto\" or \"backward\")",
                ));
            }
            true
        }
        Some(other) => {
            return Err(ctx.err(
                "integrator.ckd_walk",
                format!("\"{other}\" is unknown (known: \"cycle\", \"alis\")"),
            ))
        }
    };
    let spectral_alis = match cfg.integrator.spectral_walk.as_deref() {
        None | Some("independent") => None,
        Some("alis") => {
            let key = "integrator.spectral_walk";
            if ckd {
                return Err(ctx.err(
                    key,
                    "is used only with mode = \"mono\" (CKD bins: integrator.ckd_walk = \"alis\")",
                ));
            }
            if cfg.polarized {
                return Err(ctx.err(
                    key,
                    "\"alis\" is scalar only (polarized = true is not supported)",
                ));
            }
            if planet_radius.is_some() {
                return Err(ctx.err(
                    key,
                    "\"alis\" is plane-parallel only (not for spherical-shell geometry)",
                ));
            }
            if scene.is_some() {
                return Err(ctx.err(key, "\"alis\" is for 1D runs only (not with a 3D scene)"));
            }
            if kind == IntegratorKind::Forward {
                return Err(ctx.err(
                    key,
                    "\"alis\" is a backward walk (integrator.type \"auto\" or \"backward\", not \"forward\")",
                ));
            }
            Some(match cfg.integrator.alis_group {
                None => 32,
                Some(n) if (1..=crate::integrator::backward_alis::MAX_CHANNELS).contains(&n) => n,
                Some(n) => {
                    return Err(ctx.err(
                        "integrator.alis_group",
                        format!("{n} wavelengths per group: must lie in 1 … 64"),
                    ))
                }
            })
        }
        Some(other) => {
            return Err(ctx.err(
                "integrator.spectral_walk",
                format!("\"{other}\" is unknown (known: \"independent\", \"alis\")"),
            ))
        }
    };
    if spectral_alis.is_none() && cfg.integrator.alis_group.is_some() {
        return Err(ctx.err(
            "integrator.alis_group",
            "is used only with integrator.spectral_walk = \"alis\"",
        ));
    }
    let integrator = IntegratorSettings {
        spectral_alis,
        kind,
        max_depth,
        rr_depth: cfg.integrator.rr_depth.unwrap_or(5),
        expected_local_estimate,
        alis,
        first_check_spp: match cfg.integrator.first_check_spp {
            Some(n) if n < 64 => {
                return Err(ctx.err(
                    "integrator.first_check_spp",
                    format!("{n} is too few samples to estimate a standard error (at least 64)"),
                ))
            }
            other => other,
        },
    };

    if ckd && ckd_tau.is_empty() {
        return Err(ctx.err(
            "atmosphere",
            "mode = \"ckd\" needs a `molecular` atmosphere with `absorption_data`",
        ));
    }
    let optics = layers_per_w
        .into_iter()
        .zip(surfaces)
        .enumerate()
        .map(|(iw, (layers, surface))| {
            let g_states: Vec<(f64, OpticalState)> = match ckd_tau.get(iw) {
                None => Vec::new(),
                Some(gs) => gs
                    .iter()
                    .map(|(w, taus)| {
                        let mut l = layers.clone();
                        for (layer, t) in l.iter_mut().zip(taus) {
                            layer.tau_abs += t;
                        }
                        let atmosphere = PlaneParallel::new(l, ground, toa);
                        let shell = planet_radius.map(|r| SphericalShell::new(&atmosphere, r));
                        (
                            *w,
                            OpticalState {
                                wavelength: wavelengths[iw],
                                atmosphere,
                                shell,
                                surface: surface.clone(),
                                scene_models: Vec::new(),
                                irradiance: irradiance[iw],
                                g_states: Vec::new(),
                            },
                        )
                    })
                    .collect(),
            };
            let atmosphere = PlaneParallel::new(layers, ground, toa);
            let shell = planet_radius.map(|r| SphericalShell::new(&atmosphere, r));
            let scene_models = match &scene {
                Some(sc) => sc
                    .models_at(wavelengths[iw])
                    .map_err(|m| ctx.err("scene", m))?,
                None => Vec::new(),
            };
            let mut g_states = g_states;
            for (_, g) in &mut g_states {
                g.scene_models = scene_models.clone();
            }
            Ok(OpticalState {
                wavelength: wavelengths[iw],
                atmosphere,
                shell,
                surface,
                scene_models,
                irradiance: irradiance[iw],
                g_states,
            })
        })
        .collect::<Result<Vec<_>, ConfigError>>()?;

    // Spectral ALIS: each group's reference (its central wavelength's scattering) must scatter
    // wherever one of its wavelengths does, or the walks would miss paths.
    if let Some(n) = integrator.spectral_alis {
        for group in crate::spectral::wavelength_groups_of(&wavelengths, Some(n)) {
            let central = group[group.len() / 2];
            let atms: Vec<&PlaneParallel> =
                group.iter().map(|&iw| &optics[iw].atmosphere).collect();
            let reference = crate::integrator::backward_alis::group_reference(
                &optics[central].atmosphere,
                &atms,
            );
            if let Some(i) =
                crate::integrator::backward_alis::Layers::unsupported_layer(&reference, &atms)
            {
                return Err(ctx.err(
                    "integrator.spectral_walk",
                    format!(
                        "layer {i} (from the top) scatters at some wavelength of the group {}–{} nm but not at its reference wavelength {} nm; use smaller groups (integrator.alis_group) or \"independent\"",
                        wavelengths[group[0]],
                        wavelengths[group[group.len() - 1]],
                        wavelengths[central]
                    ),
                ));
            }
        }
    }
    // With a sensor band, `target_rel_stderr` is the target of the band-weighted result: each of
    // the N independent wavelengths may then be √N_eff times noisier, with
    // N_eff = (Σ a_k)² / Σ a_k² and a_k = w_k·E0_k (equal relative errors combine this way).
    if let Some(b) = &band {
        let a: Vec<f64> = b
            .weights
            .iter()
            .zip(&irradiance)
            .map(|(w, e)| w * e)
            .collect();
        let (s1, s2) = (a.iter().sum::<f64>(), a.iter().map(|x| x * x).sum::<f64>());
        if s2 > 0.0 {
            let n_eff = s1 * s1 / s2;
            for m in &mut measures {
                if let Some(t) = m.target_rel_stderr {
                    m.target_rel_stderr = Some((t * n_eff.sqrt()).min(0.5));
                }
            }
        }
    }
    // CKD: blocks of samples cycle through the g-points, so every measure's sample count is a
    // whole number of cycles (rounded up).
    if let Some(ng) = optics.first().map(|o: &OpticalState| o.g_states.len()) {
        if ng > 64 && integrator.alis {
            return Err(ctx.err(
                "integrator.ckd_walk",
                format!("\"alis\" handles at most 64 g-points per bin (this file has {ng})"),
            ));
        }
        if ng > 1 && !integrator.alis {
            for m in &mut measures {
                let unit = m.block_size() * ng as u64;
                let spp = m.spp.div_ceil(unit) * unit;
                if spp != m.spp {
                    tracing::info!(
                        "measure `{}`: spp {} rounded up to {spp} (whole cycles of {ng} g-points × {} samples)",
                        m.id,
                        m.spp,
                        unit / ng as u64
                    );
                    m.spp = spp;
                }
            }
        }
    }
    Ok(Experiment {
        wavelengths,
        band,
        optics,
        sun_zenith,
        sun_azimuth,
        sun_dir,
        sun_zenith_deg: zenith,
        sun_azimuth_deg: azimuth.rem_euclid(360.0),
        sun_distance_au,
        measures,
        integrator,
        seed: cfg.seed,
        polarized: cfg.polarized,
        planet_radius,
        scene,
        source_text: text.to_string(),
        source_path: path.to_path_buf(),
    })
}

/// A g-point: its quadrature weight and the gas absorption optical thickness of each layer.
type GPoint = (f64, Vec<f64>);

/// Per wavelength, per g-point: (quadrature weight, gas absorption optical thickness of each
/// layer of `grid`). Two sources (`atmosphere.absorption_data`):
/// * a file: the eradiate v0 CKD format (k(z, bin, g) precomputed for the US standard
///   atmosphere, 16 Gauss–Legendre g-points per 10 nm bin; `absorption::eradiate_v0`), valid for
///   the unscaled embedded US standard profile only;
/// * a directory: an axsdb CKD database, evaluated at the profile's (p, T, x) with
///   `spectral.g_points` Gauss–Legendre points (default 16; `absorption::layers`).
///
/// Each run wavelength selects the bin containing it; `g_point` keeps one g-point with weight 1.
fn resolve_ckd(
    ctx: &Ctx,
    file: &Path,
    thermo: &crate::atmosphere::thermo::Thermo,
    grid: &[(f64, f64)],
    wavelengths: &[f64],
    spectral: &super::SpectralConfig,
    bounds: crate::absorption::BoundsPolicy,
) -> Result<Vec<Vec<GPoint>>, ConfigError> {
    use crate::absorption::eradiate_v0::{EradiateV0Ckd, V0Interpolation};
    use crate::absorption::{AxsDatabase, DatabaseKind, SpectralPoint};
    let key = "atmosphere.absorption_data";
    let g_point = spectral.g_point;
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
        let db = AxsDatabase::open(file).map_err(|e| ctx.err(key, e.to_string()))?;
        if db.kind() != DatabaseKind::Ckd {
            return Err(ctx.err(
                key,
                format!(
                    "{} is a monochromatic database; use it with mode = \"mono\"",
                    file.display()
                ),
            ));
        }
        let ng = spectral.g_points.unwrap_or(16);
        if !(1..=64).contains(&ng) {
            return Err(ctx.err("spectral.g_points", format!("{ng} must lie in 1..=64")));
        }
        let quad = crate::absorption::gauss_legendre_unit(ng);
        let cols = crate::absorption::layers::GasColumns::new(&thermo.gas, grid);
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
                    .map_err(|m| ctx.err(key, format!("{} nm bin, g = {gv:.4}: {m}", wl)))?;
                per_g.push((if g_point.is_some() { 1.0 } else { w }, taus));
            }
            out.push(per_g);
        }
        return Ok(out);
    }
    if spectral.g_points.is_some() {
        return Err(ctx.err(
            "spectral.g_points",
            "is used only with an axsdb CKD database (a directory); the eradiate v0 and RRTMGP files have fixed g-points",
        ));
    }
    if is_rrtmgp(file) {
        let rr =
            crate::absorption::RrtmgpSw::open(file).map_err(|e| ctx.err(key, e.to_string()))?;
        let bands = rr.bands_nm();
        let mut cache: Vec<Option<Vec<Vec<f64>>>> = vec![None; bands.len()];
        let mut out = Vec::with_capacity(wavelengths.len());
        for (iw, &wl) in wavelengths.iter().enumerate() {
            let band = bands
                .iter()
                .position(|&(lo, hi)| lo <= wl && wl < hi)
                .ok_or_else(|| no_bin(iw, wl, bands[0].0, bands[bands.len() - 1].1))?;
            if cache[band].is_none() {
                cache[band] = Some(
                    rr.layer_optical_thickness(&thermo.gas, grid, band)
                        .map_err(|e| ctx.err(key, e.to_string()))?,
                );
            }
            let taus = cache[band].as_ref().expect("filled above");
            let weights = rr.solar_weights(band);
            out.push(
                pick(taus.len())?
                    .into_iter()
                    .map(|g| {
                        let w = if g_point.is_some() { 1.0 } else { weights[g] };
                        (w, taus[g].iter().map(|t| t.max(0.0)).collect())
                    })
                    .collect(),
            );
        }
        return Ok(out);
    }
    if !thermo.is_us_standard {
        return Err(ctx.err(
            key,
            format!(
                "{} holds k(z) precomputed for the unscaled AFGL 1986 US standard atmosphere; it cannot \
                 describe profile \"{}\" or a rescaled one (use an axsdb database for other profiles)",
                file.display(),
                thermo.rayleigh.name
            ),
        ));
    }
    let db = EradiateV0Ckd::open(file, None).map_err(|e| ctx.err(key, e.to_string()))?;
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
                        .map_err(|e| ctx.err(key, e.to_string()))
                })
                .collect::<Result<Vec<f64>, _>>()?;
            per_g.push((w, taus));
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

/// `mode = "ckd"` with `spectral.srf`: the bins (lower, upper) [nm] of the absorption data, or
/// None for RRTMGP, whose bands are too wide to sample a sensor band (the band is then sampled
/// every `wavelength_step` nm, each wavelength with its RRTMGP band's g-points).
fn ckd_bins(
    ctx: &Ctx,
    base: &Path,
    cfg: &ExperimentConfig,
) -> Result<Option<Vec<(f64, f64)>>, ConfigError> {
    let key = "atmosphere.absorption_data";
    let Some(AtmosphereConfig::Molecular {
        absorption_data: Some(file),
        ..
    }) = &cfg.atmosphere
    else {
        return Err(ctx.err(
            "atmosphere",
            "mode = \"ckd\" needs a `molecular` atmosphere with `absorption_data`",
        ));
    };
    let path = base.join(file);
    if path.is_dir() {
        let db =
            crate::absorption::AxsDatabase::open(&path).map_err(|e| ctx.err(key, e.to_string()))?;
        Ok(Some(
            db.bins().iter().map(|b| (b.lower_nm, b.upper_nm)).collect(),
        ))
    } else if is_rrtmgp(&path) {
        Ok(None)
    } else {
        let db = crate::absorption::EradiateV0Ckd::open(&path, None)
            .map_err(|e| ctx.err(key, e.to_string()))?;
        Ok(Some(
            db.bins().iter().map(|b| (b.lower_nm, b.upper_nm)).collect(),
        ))
    }
}

/// `atmosphere.cross_sections`: per wavelength, the continuum absorption optical thickness of
/// every layer of `grid`, summed over the tables (`absorption/cross_section.rs`).
fn resolve_cross_sections(
    ctx: &Ctx,
    base: &Path,
    tables: &[crate::config::CrossSectionConfig],
    thermo: &crate::atmosphere::thermo::Thermo,
    grid: &[(f64, f64)],
    wavelengths: &[f64],
) -> Result<Vec<Vec<f64>>, ConfigError> {
    use crate::absorption::cross_section::{layer_columns, CrossSection};
    let mut tau = vec![vec![0.0; grid.len()]; wavelengths.len()];
    for (i, t) in tables.iter().enumerate() {
        let key = format!("atmosphere.cross_sections[{i}]");
        let to_m2 = match t.units.as_str() {
            "cm^2" => 1e-4,
            "m^2" => 1.0,
            other => {
                return Err(ctx.err(
                    format!("{key}.units"),
                    format!("\"{other}\" is unknown (known: \"cm^2\", \"m^2\")"),
                ))
            }
        };
        let zero_outside = match t.outside.as_deref() {
            None | Some("error") => false,
            Some("zero") => true,
            Some(other) => {
                return Err(ctx.err(
                    format!("{key}.outside"),
                    format!("\"{other}\" is unknown (known: \"error\", \"zero\")"),
                ))
            }
        };
        let xs = CrossSection::read(&base.join(&t.file), t.column, to_m2)
            .map_err(|m| ctx.err(format!("{key}.file"), m))?;
        let cols = layer_columns(&thermo.gas, &t.species, grid)
            .map_err(|m| ctx.err(format!("{key}.species"), m))?;
        let mut zeroed = Vec::new();
        for (iw, &wl) in wavelengths.iter().enumerate() {
            let Some(sigma) = xs.at(wl) else {
                if zero_outside {
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
fn resolve_mono_gas(
    ctx: &Ctx,
    dir: &Path,
    thermo: &crate::atmosphere::thermo::Thermo,
    grid: &[(f64, f64)],
    wavelengths: &[f64],
    bounds: crate::absorption::BoundsPolicy,
) -> Result<Vec<Vec<f64>>, ConfigError> {
    use crate::absorption::{AxsDatabase, DatabaseKind, SpectralPoint};
    let key = "atmosphere.absorption_data";
    if !dir.is_dir() {
        return Err(ctx.err(
            key,
            format!(
                "{}: in mode = \"mono\" this must be an axsdb monochromatic database directory \
                 (correlated-k files and databases need mode = \"ckd\")",
                dir.display()
            ),
        ));
    }
    let db = AxsDatabase::open(dir).map_err(|e| ctx.err(key, e.to_string()))?;
    if db.kind() != DatabaseKind::Mono {
        return Err(ctx.err(
            key,
            format!(
                "{} is a correlated-k database; use it with mode = \"ckd\"",
                dir.display()
            ),
        ));
    }
    let cols = crate::absorption::layers::GasColumns::new(&thermo.gas, grid);
    let (lo, hi) = db.spectral_range_nm();
    wavelengths
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
                .map_err(|m| ctx.err(key, format!("{wl} nm: {m}")))
        })
        .collect()
}

/// `atmosphere.absorption_bounds` → the database policy.
fn resolve_bounds(
    ctx: &Ctx,
    cfg: &super::AbsorptionBoundsConfig,
) -> Result<crate::absorption::BoundsPolicy, ConfigError> {
    use crate::absorption::OutOfRange;
    let one = |k: &str, v: &str| match v {
        "error" => Ok(OutOfRange::Error),
        "clamp" => Ok(OutOfRange::Clamp),
        "zero" => Ok(OutOfRange::Zero),
        other => Err(ctx.err(
            format!("atmosphere.absorption_bounds.{k}"),
            format!("\"{other}\" is not one of \"error\", \"clamp\", \"zero\""),
        )),
    };
    Ok(crate::absorption::BoundsPolicy {
        pressure: one("pressure", &cfg.pressure)?,
        temperature: one("temperature", &cfg.temperature)?,
        mole_fraction: one("mole_fraction", &cfg.mole_fraction)?,
    })
}
