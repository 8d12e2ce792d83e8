//! `emission = true`: the checks and the per-wavelength thermal sources of a run.
//!
//! Temperatures come from `[atmosphere]` (`temperature`, or `temperature_bottom` and
//! `temperature_top`, per layer: `atmosphere/config.rs`) and `[surface]` (`temperature`, every
//! BRDF: `bsdf/config.rs`). Each layer's source is the Planck radiance (`planck.rs`) at its
//! boundaries, linear in optical depth inside (`atmosphere/emission.rs`); the surface emits
//! `ε·B(T_s)` with Kirchhoff's emissivity (`bsdf/emissivity.rs`). Sources are stored divided
//! by the irradiance that normalises the tallies (E0 with a Sun, 1 without), so that products
//! turn them into radiance as they turn reflected sunlight (`docs/transport.md`).
//!
//! In `mode = "ckd"` every g-point's sources are the wavelength's Planck radiance times its
//! Planck fraction over its quadrature weight (`GPoint::planck_scale`, from a longwave
//! k-distribution: RRTMGP's `rrtmgp-gas-lw-g256.nc`), layer by layer; the surface takes the
//! lowest layer's factor (RRTMGP's surface source).
//!
//! Built for plane-parallel runs with the backward estimator (scalar or polarized; the
//! default; the CKD ALIS walk too) or, on request, the forward one (directional measures);
//! other shapes of run are refused with the key that selects them.

use super::ExperimentConfig;
use crate::atmosphere::config::{Geometry, LayerTemperature};
use crate::atmosphere::PlaneParallel;
use crate::bsdf::{Bsdf, SurfaceEmission};
use crate::error::{ConfigCtx, ConfigError};
use crate::integrator::settings::{IntegratorKind, IntegratorSettings};
use crate::measure::Measure;
use crate::sources::illumination::Sun;
use crate::sources::planck;

/// The thermal sources of a run.
pub struct Thermal {
    layers: Vec<LayerTemperature>,
    /// K.
    surface: f64,
    wavelengths: Vec<f64>,
    /// Per wavelength, the irradiance the tallies are normalised by (W m⁻² nm⁻¹).
    norm: Vec<f64>,
}

/// The thermal sources of `cfg` (None without `emission`); errors name the key.
pub fn resolve(
    cfg: &ExperimentConfig,
    ctx: &ConfigCtx,
    geometry: &Geometry,
    wavelengths: &[f64],
    sun: &Sun,
) -> Result<Option<Thermal>, ConfigError> {
    if !cfg.emission {
        // A lidar brings its own light; passive measures need the Sun or emission.
        let passive = cfg
            .measures
            .iter()
            .any(|m| !matches!(m, crate::measure::config::MeasureConfig::Lidar(_)));
        if !sun.shines && passive && !cfg.has_lamps() {
            return Err(ctx.err(
                "illumination.type",
                "\"none\" leaves nothing for the passive measures to see without thermal emission (`emission = true`) or lamps (`[[lights]]`, `scene.lamps`, `scene.emitters`); only lidar measures bring their own light",
            ));
        }
        return Ok(None);
    }
    let layers = match &cfg.atmosphere {
        None => Vec::new(),
        Some(a) => a.temperatures(ctx, geometry)?,
    };
    let surface = match cfg.surface.as_ref().and_then(|s| s.temperature) {
        // A 3D scene's materials carry their own temperatures (`scene::emission`).
        None if cfg.scene.is_some() => 0.0,
        None => {
            return Err(ctx.err(
                "surface.temperature",
                "is required with `emission = true` (K)",
            ))
        }
        Some(t) => {
            let t = ctx.finite("surface.temperature", t)?;
            if t <= 0.0 || t > 10_000.0 {
                return Err(ctx.err(
                    "surface.temperature",
                    format!("{t} K must lie in (0, 10000] K"),
                ));
            }
            t
        }
    };
    // Sources so cold that their Planck radiance underflows at the shortest run wavelength
    // emit nothing representable (issue 43): refused, naming the key.
    let shortest = wavelengths.iter().cloned().fold(f64::INFINITY, f64::min);
    let t_min = planck::lowest_temperature(shortest);
    let too_cold = |key: &str, t: f64| {
        ctx.err(
            key,
            format!(
                "{t} K radiates nothing representable at {shortest} nm (its Planck radiance underflows); at the run's wavelengths temperatures must be at least {t_min:.3} K"
            ),
        )
    };
    if surface > 0.0 && surface < t_min {
        return Err(too_cold("surface.temperature", surface));
    }
    for (i, l) in layers.iter().enumerate() {
        let t = l.t_bottom.min(l.t_top);
        if t < t_min {
            return Err(too_cold(
                &format!(
                    "atmosphere (layer {i} from the ground, base {} m)",
                    l.bottom
                ),
                t,
            ));
        }
    }
    if sun.shines {
        if let Some(e) = sun.irradiance.iter().find(|e| e.is_nan() || **e <= 0.0) {
            return Err(ctx.err(
                "illumination.irradiance",
                format!(
                    "{e} must be positive with `emission = true` (it normalises the radiances)"
                ),
            ));
        }
    }
    Ok(Some(Thermal {
        layers,
        surface,
        wavelengths: wavelengths.to_vec(),
        norm: sun.irradiance.clone(),
    }))
}

impl Thermal {
    /// Refuse the estimators that do not carry emission; `integrator.type = "auto"` becomes
    /// the backward estimator (the forward one serves directional measures only, on request).
    pub fn check_integrator(
        &self,
        ctx: &ConfigCtx,
        s: &mut IntegratorSettings,
        measures: &[Measure],
    ) -> Result<(), ConfigError> {
        match s.kind {
            IntegratorKind::Forward => {
                if let Some(i) = measures.iter().position(|m| m.is_flux()) {
                    return Err(ctx.err(
                        format!("measures[{i}]"),
                        "a flux measure with thermal emission needs the backward estimator (`integrator.type = \"auto\"` or \"backward\")",
                    ));
                }
            }
            IntegratorKind::Auto => s.kind = IntegratorKind::Backward,
            IntegratorKind::Backward => {}
        }
        if s.spectral_alis.is_some() && !s.drop_auto_alis() {
            return Err(ctx.err(
                "integrator.spectral_walk",
                "\"alis\" does not carry thermal emission yet: use \"independent\"",
            ));
        }
        Ok(())
    }

    /// The factor on Planck radiances at wavelength `iw`: 1 over the irradiance that normalises
    /// the tallies.
    pub fn k(&self, iw: usize) -> f64 {
        1.0 / self.norm[iw]
    }

    /// Set the sources of wavelength `iw` on `atm` and return the surface's emission. A CKD
    /// g-point passes `scale`, the factor on each layer's source (`GPoint::planck_scale`:
    /// its Planck fraction over its quadrature weight); the surface takes the lowest layer's.
    pub fn apply(
        &self,
        iw: usize,
        atm: &mut PlaneParallel,
        surface: &Bsdf,
        scale: Option<&[f64]>,
    ) -> Option<SurfaceEmission> {
        let wl = self.wavelengths[iw];
        let k = 1.0 / self.norm[iw];
        let b = |t: f64| crate::sources::planck::radiance(wl, t) * k;
        let layers = &self.layers;
        // B linear in optical depth inside a configured layer is linear in altitude there (the
        // layer is homogeneous); a computational layer takes the values at its boundaries.
        let at = |z: f64, inside: f64| -> f64 {
            let Some(l) = layers
                .iter()
                .find(|l| l.bottom <= inside && inside <= l.top)
            else {
                return 0.0;
            };
            let f = ((z - l.bottom) / (l.top - l.bottom)).clamp(0.0, 1.0);
            b(l.t_bottom) + (b(l.t_top) - b(l.t_bottom)) * f
        };
        atm.set_sources(|top, bottom| {
            let mid = 0.5 * (top + bottom);
            [at(top, mid), at(bottom, mid)]
        });
        let mut surface_source = b(self.surface);
        if let Some(s) = scale {
            atm.scale_sources(s);
            surface_source *= s.first().copied().unwrap_or(1.0);
        }
        Some(SurfaceEmission::new(surface, surface_source))
    }
}
