//! The `[geometry]` and `[atmosphere]` tables of the experiment file: raw serde types and their
//! resolution into layer optics per run wavelength (homogeneous, layered and molecular
//! atmospheres; particle layers; the planet radius of spherical shells). Gas absorption keys are
//! resolved by `absorption/config.rs`, phase tables by `phase/config.rs`. Keys and units are
//! documented in `docs/experiment.md`; lengths in km there, m here.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;

use serde::Deserialize;

use super::molecular::{depolarization as molecular_depolarization, rayleigh_cross_section};
use super::particles::{Distribution, ParticleDataset, VerticalProfile};
use super::thermo::RescaleValue;
use super::LayerOptics;
use crate::absorption::config::{
    resolve_ckd, resolve_cross_sections, resolve_mono_gas, AbsorptionBoundsConfig,
    CrossSectionConfig, GPoint, GasLayers,
};
use crate::error::{ConfigCtx, ConfigError};
use crate::phase::{Mixture, PhaseConfig, PhaseFunction, PhaseResolver, Rayleigh};
use crate::spectral::{Mode, SpectralConfig, Spectrum, SpectrumExt};

#[derive(Clone, Debug, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum GeometryConfig {
    PlaneParallel {
        /// km.
        #[serde(default = "default_toa")]
        toa_altitude: f64,
        /// km.
        #[serde(default)]
        ground_altitude: f64,
    },
    /// Concentric shells around a spherical planet.
    SphericalShell {
        /// km.
        #[serde(default = "default_toa")]
        toa_altitude: f64,
        /// km.
        #[serde(default)]
        ground_altitude: f64,
        /// km.
        #[serde(default = "default_planet_radius")]
        planet_radius: f64,
    },
}

fn default_planet_radius() -> f64 {
    6378.1
}

fn default_toa() -> f64 {
    100.0
}

impl Default for GeometryConfig {
    fn default() -> Self {
        GeometryConfig::PlaneParallel {
            toa_altitude: default_toa(),
            ground_altitude: 0.0,
        }
    }
}

/// The resolved geometry, m.
#[derive(Clone, Copy, Debug)]
pub struct Geometry {
    pub ground: f64,
    pub toa: f64,
    /// Spherical shells: the planet radius (None: plane-parallel).
    pub planet_radius: Option<f64>,
}

impl GeometryConfig {
    pub fn resolve(&self, ctx: &ConfigCtx) -> Result<Geometry, ConfigError> {
        let (toa_altitude, ground_altitude, planet_radius) = match *self {
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
                    return Err(
                        ctx.err("geometry.planet_radius", format!("{r} km must be positive"))
                    );
                }
                if r + ground_altitude <= 0.0 {
                    return Err(
                        ctx.err("geometry.ground_altitude", "lies below the planet's centre")
                    );
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
        Ok(Geometry {
            ground,
            toa,
            planet_radius,
        })
    }
}

#[derive(Clone, Debug, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum AtmosphereConfig {
    /// One layer from the ground to TOA.
    Homogeneous {
        optical_thickness: Spectrum,
        #[serde(default = "one")]
        single_scattering_albedo: Spectrum,
        #[serde(default)]
        phase: PhaseConfig,
        /// K: an isothermal layer (thermal emission); or `temperature_bottom` and
        /// `temperature_top`, the Planck source then linear in optical depth between them.
        #[serde(default)]
        temperature: Option<f64>,
        /// K, at the layer's bottom.
        #[serde(default)]
        temperature_bottom: Option<f64>,
        /// K, at the layer's top.
        #[serde(default)]
        temperature_top: Option<f64>,
    },
    /// Plane-parallel layers, each homogeneous.
    Layered { layers: Vec<LayerConfig> },
    /// Rayleigh-scattering air from a thermophysical profile, with gas absorption, continua and
    /// particle layers.
    Molecular {
        #[serde(default = "default_profile")]
        profile: String,
        /// km.
        #[serde(default = "default_layer_thickness")]
        layer_thickness: f64,
        /// Aerosol (particle) layers mixed into the molecular layers.
        #[serde(default)]
        particle_layers: Vec<ParticleLayerConfig>,
        /// Gas absorption: a CKD file or an axsdb database (`absorption/config.rs`).
        #[serde(default)]
        absorption_data: Option<String>,
        /// Rescale species' column amounts (`atmosphere::thermo`).
        #[serde(default)]
        rescale: BTreeMap<String, RescaleValue>,
        /// Out-of-range policy of absorption databases.
        #[serde(default)]
        absorption_bounds: AbsorptionBoundsConfig,
        /// Rayleigh scattering by the air (false: gas absorption and particles only).
        #[serde(default = "yes")]
        rayleigh: bool,
        /// Rayleigh depolarization factor; none: the value consistent with Bates' King factor.
        #[serde(default)]
        depolarization: Option<f64>,
        /// Continuum absorbers from cross-section tables (`absorption/cross_section.rs`).
        #[serde(default)]
        cross_sections: Vec<CrossSectionConfig>,
    },
    /// No atmosphere (same as omitting the table).
    None {},
}

fn one() -> Spectrum {
    Spectrum::Constant(1.0)
}

fn yes() -> bool {
    true
}

fn default_profile() -> String {
    "afgl_1986-us_standard".into()
}

/// Most computational layers a molecular atmosphere may have (memory and set-up time grow
/// with layers × wavelengths × g-points).
pub const MAX_LAYERS: usize = 10_000;

fn default_layer_thickness() -> f64 {
    1.0
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LayerConfig {
    /// km.
    pub bottom: f64,
    /// km.
    pub top: f64,
    /// Vertical scattering optical thickness.
    #[serde(default)]
    pub tau_sca: Option<Spectrum>,
    /// Vertical absorption optical thickness.
    #[serde(default)]
    pub tau_abs: Option<Spectrum>,
    /// Alternative to tau_sca/tau_abs: total optical thickness and single-scattering albedo.
    #[serde(default)]
    pub optical_thickness: Option<Spectrum>,
    #[serde(default)]
    pub single_scattering_albedo: Option<Spectrum>,
    #[serde(default)]
    pub phase: PhaseConfig,
    /// K: an isothermal layer (thermal emission); or `temperature_bottom` and
    /// `temperature_top`, the Planck source then linear in optical depth between them.
    #[serde(default)]
    pub temperature: Option<f64>,
    /// K, at the layer's bottom.
    #[serde(default)]
    pub temperature_bottom: Option<f64>,
    /// K, at the layer's top.
    #[serde(default)]
    pub temperature_top: Option<f64>,
}

/// One `[[atmosphere.particle_layers]]` table (see `atmosphere::particles`).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParticleLayerConfig {
    /// km.
    pub bottom: f64,
    /// km.
    pub top: f64,
    /// Extinction optical thickness of the whole layer at `reference_wavelength`.
    pub optical_thickness: f64,
    /// nm.
    #[serde(default = "default_reference_wavelength")]
    pub reference_wavelength: f64,
    #[serde(default)]
    pub distribution: DistributionConfig,
    /// Aer-Core v2 netCDF or libRadtran `.mie.cdf` file (relative to the experiment file).
    pub dataset: String,
    /// libRadtran files: index along `reff`/`hum`.
    #[serde(default)]
    pub size_index: usize,
}

fn default_reference_wavelength() -> f64 {
    550.0
}

/// Vertical distribution of a particle layer; lengths in km.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum DistributionConfig {
    #[default]
    Uniform,
    Exponential {
        scale_height: f64,
    },
    Gaussian {
        mean: f64,
        std: f64,
    },
}

/// The temperature of one layer (thermal emission): boundaries in m, temperatures in K.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LayerTemperature {
    pub bottom: f64,
    pub top: f64,
    pub t_bottom: f64,
    pub t_top: f64,
}

/// `temperature`, or `temperature_bottom` and `temperature_top`, of the table at `key`:
/// (bottom, top) in K. Temperatures must lie in (0, 10 000] K.
fn layer_temperature(
    ctx: &ConfigCtx,
    key: &str,
    t: Option<f64>,
    bottom: Option<f64>,
    top: Option<f64>,
) -> Result<(f64, f64), ConfigError> {
    let check = |name: &str, v: f64| -> Result<f64, ConfigError> {
        let k = format!("{key}.{name}");
        let v = ctx.finite(&k, v)?;
        if v <= 0.0 || v > 10_000.0 {
            return Err(ctx.err(k, format!("{v} K must lie in (0, 10000] K")));
        }
        Ok(v)
    };
    match (t, bottom, top) {
        (Some(t), None, None) => {
            let t = check("temperature", t)?;
            Ok((t, t))
        }
        (None, Some(b), Some(t)) => Ok((
            check("temperature_bottom", b)?,
            check("temperature_top", t)?,
        )),
        (Some(_), _, _) => Err(ctx.err(
            format!("{key}.temperature"),
            "give `temperature` or `temperature_bottom` and `temperature_top`, not both",
        )),
        (None, Some(_), None) => Err(ctx.err(
            format!("{key}.temperature_top"),
            "is required with `temperature_bottom`",
        )),
        (None, None, Some(_)) => Err(ctx.err(
            format!("{key}.temperature_bottom"),
            "is required with `temperature_top`",
        )),
        (None, None, None) => Err(ctx.err(
            format!("{key}.temperature"),
            "is required with `emission = true` (or `temperature_bottom` and `temperature_top`)",
        )),
    }
}

impl AtmosphereConfig {
    /// The layers' temperatures for thermal emission (`emission = true`): one entry per layer
    /// of a homogeneous or layered atmosphere, one per computational layer of a molecular one
    /// (its profile's temperatures at the layer boundaries), none without an atmosphere.
    /// Errors name the missing or bad key.
    pub fn temperatures(
        &self,
        ctx: &ConfigCtx,
        geometry: &Geometry,
    ) -> Result<Vec<LayerTemperature>, ConfigError> {
        match self {
            AtmosphereConfig::None {} => Ok(Vec::new()),
            AtmosphereConfig::Homogeneous {
                temperature,
                temperature_bottom,
                temperature_top,
                ..
            } => {
                let (b, t) = layer_temperature(
                    ctx,
                    "atmosphere",
                    *temperature,
                    *temperature_bottom,
                    *temperature_top,
                )?;
                Ok(vec![LayerTemperature {
                    bottom: geometry.ground,
                    top: geometry.toa,
                    t_bottom: b,
                    t_top: t,
                }])
            }
            AtmosphereConfig::Layered { layers } => layers
                .iter()
                .enumerate()
                .map(|(i, l)| {
                    let (b, t) = layer_temperature(
                        ctx,
                        &format!("atmosphere.layers[{i}]"),
                        l.temperature,
                        l.temperature_bottom,
                        l.temperature_top,
                    )?;
                    Ok(LayerTemperature {
                        bottom: l.bottom * 1e3,
                        top: l.top * 1e3,
                        t_bottom: b,
                        t_top: t,
                    })
                })
                .collect(),
            AtmosphereConfig::Molecular {
                profile,
                layer_thickness,
                ..
            } => {
                // The profile's temperatures (linear in altitude between its levels) at the
                // boundaries of every computational layer: the source is linear in optical
                // depth inside each (the DISORT convention at computational levels).
                let thermo = super::thermo::load(profile, ctx.base)
                    .map_err(|e| ctx.err("atmosphere.profile", e.to_string()))?;
                let gas = &thermo.gas;
                let t_at = |z: f64| -> f64 {
                    let zs = &gas.altitude_m;
                    let n = zs.len();
                    let i = zs.partition_point(|&x| x <= z).clamp(1, n - 1) - 1;
                    let f = ((z - zs[i]) / (zs[i + 1] - zs[i])).clamp(0.0, 1.0);
                    gas.temperature_k[i] + f * (gas.temperature_k[i + 1] - gas.temperature_k[i])
                };
                if gas.altitude_m.len() < 2 {
                    return Err(ctx.err("atmosphere.profile", "needs at least 2 levels"));
                }
                let dz = ctx.finite("atmosphere.layer_thickness", *layer_thickness)? * 1e3;
                Ok(layer_grid(geometry.ground, geometry.toa, dz)
                    .into_iter()
                    .map(|(bottom, top)| LayerTemperature {
                        bottom,
                        top,
                        t_bottom: t_at(bottom),
                        t_top: t_at(top),
                    })
                    .collect())
            }
        }
    }
}

/// The computational layers (bottom, top) \[m\] of a `molecular` atmosphere: `dz` thick from
/// `ground` up, the last one ending at `toa`.
fn layer_grid(ground: f64, toa: f64, dz: f64) -> Vec<(f64, f64)> {
    let mut grid = Vec::new();
    let mut z = ground;
    while z < toa - 1e-6 && dz > 0.0 {
        let top = (z + dz).min(toa);
        grid.push((z, top));
        z = top;
    }
    grid
}

/// The resolved atmosphere: per run wavelength, its layers (bottom and top in m), and in CKD
/// mode per wavelength and g-point the gas absorption optical thickness to add to each layer.
#[derive(Default)]
pub struct AtmosphereLayers {
    pub layers: Vec<Vec<LayerOptics>>,
    /// Empty unless `mode = "ckd"` with a molecular atmosphere.
    pub ckd: Vec<Vec<GPoint>>,
}

impl AtmosphereConfig {
    /// `atmosphere.absorption_data`, when this is a molecular atmosphere that has it.
    pub fn absorption_data(&self) -> Option<&str> {
        match self {
            AtmosphereConfig::Molecular {
                absorption_data, ..
            } => absorption_data.as_deref(),
            _ => None,
        }
    }

    /// The layers between `geometry.ground` and `geometry.toa` at every run wavelength; errors
    /// name `atmosphere.…` (or `spectral.…` for CKD g-point choices and wavelengths outside the
    /// absorption data).
    pub fn resolve(
        &self,
        ctx: &ConfigCtx,
        geometry: &Geometry,
        wavelengths: &[f64],
        mode: Mode,
        spectral: &SpectralConfig,
    ) -> Result<AtmosphereLayers, ConfigError> {
        let (ground, toa) = (geometry.ground, geometry.toa);
        let nw = wavelengths.len();
        let mut out = AtmosphereLayers {
            layers: vec![Vec::new(); nw],
            ckd: Vec::new(),
        };
        let mut phases = PhaseResolver::default();
        match self {
            AtmosphereConfig::None {} => {}
            AtmosphereConfig::Homogeneous {
                optical_thickness,
                single_scattering_albedo,
                phase,
                ..
            } => {
                let tau =
                    optical_thickness.expand(ctx, "atmosphere.optical_thickness", 0.0, 1e6)?;
                let ssa = single_scattering_albedo.expand(
                    ctx,
                    "atmosphere.single_scattering_albedo",
                    0.0,
                    1.0,
                )?;
                for iw in 0..nw {
                    let phase = phases.resolve(ctx, "atmosphere.phase", phase, wavelengths[iw])?;
                    out.layers[iw].push(LayerOptics {
                        bottom: ground,
                        top: toa,
                        tau_sca: tau[iw] * ssa[iw],
                        tau_abs: tau[iw] * (1.0 - ssa[iw]),
                        phase,
                    });
                }
            }
            AtmosphereConfig::Layered { layers } => {
                resolve_layered(ctx, layers, geometry, wavelengths, &mut phases, &mut out)?
            }
            AtmosphereConfig::Molecular {
                profile,
                layer_thickness,
                particle_layers,
                absorption_data,
                rayleigh,
                depolarization,
                rescale,
                absorption_bounds,
                cross_sections,
            } => {
                let mut thermo = super::thermo::load(profile, ctx.base)
                    .map_err(|e| ctx.err("atmosphere.profile", e.to_string()))?;
                super::thermo::rescale(&mut thermo, rescale).map_err(|(k, m)| ctx.err(k, m))?;
                let bounds = absorption_bounds.policy();
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
                // Refuse before allocating: 1e-6 km over 100 km would be 10⁸ layers.
                let n_layers = ((toa - ground) / dz).ceil();
                if n_layers > MAX_LAYERS as f64 {
                    return Err(ctx.err(
                        "atmosphere.layer_thickness",
                        format!(
                            "{layer_thickness} km makes {n_layers:.0} layers between {} and {} km (at most {MAX_LAYERS}); use at least {:.3} km",
                            ground / 1e3,
                            toa / 1e3,
                            (toa - ground) / 1e3 / MAX_LAYERS as f64
                        ),
                    ));
                }
                let grid = layer_grid(ground, toa, dz);
                let particles = resolve_particle_layers(ctx, particle_layers, &grid, wavelengths)?;
                let gas = GasLayers {
                    gas: &thermo.gas,
                    profile_name: &thermo.rayleigh.name,
                    is_us_standard: thermo.is_us_standard,
                    grid: &grid,
                    wavelengths,
                };
                let continuum = resolve_cross_sections(ctx, cross_sections, &gas)?;
                let mut mono_gas: Vec<Vec<f64>> = Vec::new();
                match (mode, absorption_data) {
                    (Mode::Ckd, None) => {
                        return Err(ctx.err(
                            "atmosphere.absorption_data",
                            "mode = \"ckd\" needs a correlated-k absorption file or database",
                        ))
                    }
                    (Mode::Mono, None) => {
                        if !rescale.is_empty() {
                            tracing::warn!(
                                "atmosphere.rescale changes only gas absorption, and this atmosphere has no `absorption_data`"
                            );
                        }
                    }
                    (Mode::Mono, Some(file)) => {
                        mono_gas = resolve_mono_gas(ctx, &ctx.file(file), &gas, bounds)?;
                    }
                    (Mode::Ckd, Some(file)) => {
                        out.ckd = resolve_ckd(
                            ctx,
                            &ctx.file(file),
                            &gas,
                            spectral.g_point,
                            spectral.g_points,
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
                        // absorption (τ_aer·(1 − ω)); the phase function is the mixture weighted
                        // by the scattering optical thicknesses (plain Rayleigh without particles).
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
                        out.layers[iw].push(LayerOptics {
                            bottom,
                            top,
                            tau_sca,
                            tau_abs,
                            phase,
                        });
                    }
                }
            }
        }
        Ok(out)
    }
}

/// `type = "layered"`: the layers as given (any order), which must tile ground..TOA.
fn resolve_layered(
    ctx: &ConfigCtx,
    layers: &[LayerConfig],
    geometry: &Geometry,
    wavelengths: &[f64],
    phases: &mut PhaseResolver,
    out: &mut AtmosphereLayers,
) -> Result<(), ConfigError> {
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
        let (tau_sca, tau_abs) = match (
            &l.tau_sca,
            &l.tau_abs,
            &l.optical_thickness,
            &l.single_scattering_albedo,
        ) {
            (sca, abs, None, None) if sca.is_some() || abs.is_some() => {
                let zero = Spectrum::Constant(0.0);
                (
                    sca.as_ref().unwrap_or(&zero).expand(
                        ctx,
                        &format!("{key}.tau_sca"),
                        0.0,
                        1e6,
                    )?,
                    abs.as_ref().unwrap_or(&zero).expand(
                        ctx,
                        &format!("{key}.tau_abs"),
                        0.0,
                        1e6,
                    )?,
                )
            }
            (None, None, Some(tau), ssa) => {
                let tau = tau.expand(ctx, &format!("{key}.optical_thickness"), 0.0, 1e6)?;
                let ssa = ssa.as_ref().unwrap_or(&Spectrum::Constant(1.0)).expand(
                    ctx,
                    &format!("{key}.single_scattering_albedo"),
                    0.0,
                    1.0,
                )?;
                (
                    tau.iter().zip(&ssa).map(|(t, s)| t * s).collect(),
                    tau.iter().zip(&ssa).map(|(t, s)| t * (1.0 - s)).collect(),
                )
            }
            _ => return Err(ctx.err(
                key,
                "give either `tau_sca` and/or `tau_abs`, or `optical_thickness` (with an optional \
                     `single_scattering_albedo`), not both",
            )),
        };
        for (iw, &wl) in wavelengths.iter().enumerate() {
            let phase = phases.resolve(ctx, &format!("{key}.phase"), &l.phase, wl)?;
            out.layers[iw].push(LayerOptics {
                bottom: b * 1e3,
                top: t * 1e3,
                tau_sca: tau_sca[iw],
                tau_abs: tau_abs[iw],
                phase,
            });
        }
    }
    // The layers must tile [ground, toa].
    spans.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut z = geometry.ground;
    for &(b, t, il) in &spans {
        if (b - z).abs() > 1e-6 {
            let what = if b > z {
                "leaves a gap below it"
            } else {
                "overlaps the layer below"
            };
            return Err(ctx.err(
                format!("atmosphere.layers[{il}].bottom"),
                format!(
                    "{} km {what} (expected {} km; layers must tile ground_altitude..toa_altitude)",
                    b / 1e3,
                    z / 1e3
                ),
            ));
        }
        z = t;
    }
    if (z - geometry.toa).abs() > 1e-6 {
        return Err(ctx.err(
            "atmosphere.layers",
            format!(
                "the top layer ends at {} km but toa_altitude is {} km",
                z / 1e3,
                geometry.toa / 1e3
            ),
        ));
    }
    Ok(())
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
    ctx: &ConfigCtx,
    layers: &[ParticleLayerConfig],
    grid: &[(f64, f64)],
    wavelengths: &[f64],
) -> Result<Vec<ResolvedParticles>, ConfigError> {
    let (ground, toa) = (grid[0].0, grid[grid.len() - 1].1);
    // Datasets and phase functions shared between layers: (file, size_index) and run wavelength.
    let mut datasets: Vec<(PathBuf, usize, std::sync::Arc<ParticleDataset>)> = Vec::new();
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
        let fpath = ctx.file(&l.dataset);
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
                let d = crate::util::file_cache::cached(&fpath, &l.size_index.to_string(), || {
                    ParticleDataset::load(&fpath, l.size_index)
                })
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
            let at = |e: super::particles::DatasetError| {
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
