//! Validation of an [`ExperimentConfig`] into runtime types that cannot hold an invalid state:
//! ranges checked, files loaded, units converted (km → m, degrees → radians).
//!
//! This file holds the orchestration only: the order in which the parts are resolved, what
//! each part needs from the others, and the assembly of the [`Experiment`]. Each part is
//! resolved beside its models (see the table in `config/mod.rs`). It also holds the plumbing of
//! parse errors: every error names the experiment file and the key path (e.g.
//! `atmosphere.layers[1].tau_sca`), and serde's messages are completed with the key path of the
//! offending key or value when serde loses it.

use std::path::Path;
use std::sync::Arc;

pub use super::experiment::Experiment;
use super::*;
use crate::absorption::config::{ckd_bins, GPoint};
use crate::atmosphere::config::AtmosphereLayers;
use crate::atmosphere::spherical::SphericalShell;
use crate::atmosphere::{LayerOptics, PlaneParallel};
use crate::bsdf::{Bsdf, Lambertian};
use crate::error::{ConfigCtx, ConfigError};
pub use crate::integrator::settings::IntegratorKind;
use crate::integrator::settings::RunShape;
use crate::measure::config::{relax_targets_for_band, round_to_g_point_cycles, MeasureContext};
use crate::measure::{Measure, MeasureKind};
use crate::optics::OpticalState;
use crate::scene::Scene;
use crate::sources::illumination::Sun;
pub use crate::spectral::Band;

impl Experiment {
    /// Read and resolve an experiment file; relative paths inside are taken from its folder.
    pub fn load(path: &Path) -> Result<Experiment, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_str(&text, path)
    }

    /// [`Experiment::load`] with every measure's `spp` replaced by `spp` when given (the
    /// `simulate run --spp N` override for quick runs: `target_rel_stderr` still applies, and
    /// CKD rounding to whole g-point cycles happens after the override).
    pub fn load_with_spp(path: &Path, spp: Option<u64>) -> Result<Experiment, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse_with_spp(&text, path, spp)
    }

    /// Parse and resolve experiment text; `path` names it in errors and anchors relative paths.
    pub fn from_str(text: &str, path: &Path) -> Result<Experiment, ConfigError> {
        Self::parse_with_spp(text, path, None)
    }

    /// [`Experiment::from_str`] with every measure's `spp` replaced by `spp` when given (see
    /// [`Experiment::load_with_spp`]).
    pub fn parse_with_spp(
        text: &str,
        path: &Path,
        spp: Option<u64>,
    ) -> Result<Experiment, ConfigError> {
        use super::diagnostics::{cut_lines, line_of, quote, split_toml_message};
        let parse_err = |message: String| ConfigError::Parse {
            path: path.to_path_buf(),
            message: cut_lines(&message),
        };
        let de = toml::Deserializer::parse(text).map_err(|e| parse_err(e.to_string()))?;
        let mut cfg: ExperimentConfig = serde_path_to_error::deserialize(de).map_err(|e| {
            let key = e.path().to_string();
            let inner = e.into_inner().to_string().trim_end().to_string();
            let found = locate_offender(text, &inner);
            // Of several offenders, those under the table serde stopped in.
            let under: Vec<String> = found
                .iter()
                .filter(|f| key != "." && !key.is_empty() && f.starts_with(&key))
                .cloned()
                .collect();
            let found = if under.is_empty() { found } else { under };
            let (toml_line, core) = split_toml_message(&inner);
            let core = plain_number_types(&plain_closed_choice(&core));
            // serde's path, or the offender's when serde stopped at its table.
            let key = match found.as_slice() {
                [one] => one.clone(),
                _ if key == "." => String::new(),
                _ => key,
            };
            let hint = if found.len() > 1 {
                format!(" (offending keys: `{}`)", found.join("`, `"))
            } else {
                String::new()
            };
            // A dict from Python is written as TOML the user never saw: name the key path
            // only, without a line of that text.
            let from_dict = path.file_name().is_some_and(|n| n == "<dict>");
            let line = (!key.is_empty())
                .then(|| line_of(text, &key))
                .flatten()
                .or(toml_line)
                .filter(|_| !from_dict);
            let at = match (key.is_empty(), line) {
                (false, Some(n)) => format!("at key `{key}` (line {n}): "),
                (false, None) => format!("at key `{key}`: "),
                (true, Some(n)) => format!("line {n}: "),
                (true, None) => String::new(),
            };
            let core = match core.strip_prefix("missing field `") {
                Some(rest) => format!("missing required key `{rest}"),
                None => core,
            };
            let quoted = line
                .and_then(|n| quote(text, n))
                .map(|q| format!("\n{q}"))
                .unwrap_or_default();
            parse_err(format!("{at}{core}{hint}{quoted}"))
        })?;
        if let Some(n) = spp {
            cfg.measures.iter_mut().for_each(|m| m.set_spp(n));
            // A quick look: the lamps' forward photons shrink with the samples.
            let photons = cfg
                .integrator
                .lamp_photons
                .unwrap_or(crate::sources::lamps::LAMP_PHOTONS);
            cfg.integrator.lamp_photons = Some(photons.min(n.clamp(1, u64::from(u32::MAX)) as u32));
        }
        let unset = crate::measure::config::SPP_UNSET;
        if let Some(k) = cfg.measures.iter().position(|m| m.spp() == unset) {
            return Err(ConfigError::Invalid {
                path: path.to_path_buf(),
                key: format!("measures[{k}].spp"),
                message: "missing required key `spp` (samples per direction or pixel): give it in the measure, or for every measure of the run with `simulate run --spp N` (Python: `spp=N`)".into(),
            });
        }
        let mut exp = resolve(cfg, text, path)?;
        // The products' provenance and the checkpoints' hash must see the override.
        if let Some(n) = spp {
            exp.source_text
                .push_str(&format!("\n# overridden on the command line: --spp {n}\n"));
        }
        Ok(exp)
    }
}

/// serde's names of Rust number types in words a user of the experiment file reads ("integer
/// `-5`, expected u64" becomes "integer `-5`, expected a non-negative integer").
fn plain_number_types(message: &str) -> String {
    let mut m = message.to_string();
    for (rust, plain) in [
        ("expected u64", "expected a non-negative integer"),
        ("expected u32", "expected a non-negative integer"),
        ("expected u16", "expected a non-negative integer"),
        ("expected u8", "expected a non-negative integer"),
        ("expected usize", "expected a non-negative integer"),
        ("expected i64", "expected an integer"),
        ("expected i32", "expected an integer"),
        ("expected f64", "expected a number"),
        ("expected f32", "expected a number"),
    ] {
        m = m.replace(rust, plain);
    }
    m
}

/// serde's messages about a closed choice (a `type` tag or a string value such as
/// `integrator.spectral_walk`) in the words of the resolvers' own messages: "unknown variant
/// `x`, expected `a` or `b`" becomes `"x" is unknown (known: "a", "b")`, and the TOML reader's
/// "wanted string or table" (a number or list given) says that a string is expected. Other
/// messages are returned unchanged.
fn plain_closed_choice(message: &str) -> String {
    const PREFIX: &str = "unknown variant `";
    let message = message.replace("wanted string or table", "invalid type: expected a string");
    let Some(i) = message.find(PREFIX) else {
        return message;
    };
    let rest = &message[i + PREFIX.len()..];
    let Some(end) = rest.find('`') else {
        return message;
    };
    let value = &rest[..end];
    // The line ends after the value (a value may itself hold a line break).
    let line_end = rest[end..].find('\n').map_or(rest.len(), |k| end + k);
    let expected = &rest[end + 1..line_end];
    // The allowed values are the back-quoted words of the rest of the line.
    let known: Vec<String> = expected
        .split('`')
        .skip(1)
        .step_by(2)
        .map(|v| format!("\"{v}\""))
        .collect();
    let plain = if known.is_empty() {
        format!("\"{value}\" is unknown")
    } else {
        format!("\"{value}\" is unknown (known: {})", known.join(", "))
    };
    format!("{}{plain}{}", &message[..i], &rest[line_end..])
}

/// serde loses the key path inside tagged tables (e.g. `atmosphere.phase`); find the full
/// path(s) of the offending key or value named in `message` by walking the TOML tree.
fn locate_offender(text: &str, message: &str) -> Vec<String> {
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
        let i = message
            .find("invalid type: ")
            .or_else(|| message.find("invalid value: "))?;
        let rest = &message[i..];
        let a = rest.find('`')? + 1;
        let b = a + rest[a..].find('`')?;
        Some(rest[a..b].to_string())
    };
    // What the message names: a key, a string value or a number (a string needle matches only
    // strings: "30" given for a number is not the 30.0 of another key).
    #[derive(Clone, Copy, PartialEq)]
    enum Kind {
        Key,
        Str,
        Num,
    }
    let (needle, kind) = if let Some(k) = quoted("unknown field `") {
        (k, Kind::Key)
    } else if let Some(v) = quoted("unknown variant `").or_else(string_value) {
        (v, Kind::Str)
    } else if let Some(v) = number_value() {
        (v, Kind::Num)
    } else {
        return Vec::new();
    };
    let Ok(root) = text.parse::<toml::Table>() else {
        return Vec::new();
    };
    let mut found = Vec::new();
    fn value_hit(x: &toml::Value, needle: &str, kind: Kind) -> bool {
        match (x, kind) {
            (toml::Value::String(s), Kind::Str) => s == needle,
            (toml::Value::Integer(i), Kind::Num) => i.to_string() == needle,
            (toml::Value::Float(f), Kind::Num) => {
                f.to_string() == needle || format!("{f:?}") == needle
            }
            _ => false,
        }
    }
    fn walk(v: &toml::Value, path: String, needle: &str, kind: Kind, found: &mut Vec<String>) {
        match v {
            toml::Value::Table(t) => {
                for (k, x) in t {
                    let p = if path.is_empty() {
                        k.clone()
                    } else {
                        format!("{path}.{k}")
                    };
                    let hit = match kind {
                        Kind::Key => k == needle,
                        _ => value_hit(x, needle, kind),
                    };
                    if hit {
                        found.push(p.clone());
                    }
                    walk(x, p, needle, kind, found);
                }
            }
            toml::Value::Array(a) => {
                for (i, x) in a.iter().enumerate() {
                    let p = format!("{path}[{i}]");
                    if kind != Kind::Key && value_hit(x, needle, kind) {
                        found.push(p.clone());
                    }
                    walk(x, p, needle, kind, found);
                }
            }
            _ => {}
        }
    }
    walk(
        &toml::Value::Table(root),
        String::new(),
        &needle,
        kind,
        &mut found,
    );
    found
}

/// Validate a parsed experiment. `text` and `path` are kept for provenance and messages.
///
/// The parts are resolved in this order (the first error found is reported): spectral, geometry,
/// atmosphere, surface, illumination, scene, measures, integrator, then the checks that need
/// several parts.
pub fn resolve(cfg: ExperimentConfig, text: &str, path: &Path) -> Result<Experiment, ConfigError> {
    let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let ctx = ConfigCtx {
        path,
        base: &base,
        nw: 0,
        wavelengths: &[],
    };
    let ckd = cfg.mode == Mode::Ckd;
    let absorption_data = cfg.atmosphere.as_ref().and_then(|a| a.absorption_data());
    // Sensor bands in mono mode place their nodes by the solar spectrum.
    let solar = |w: &[f64]| -> Result<Vec<f64>, ConfigError> {
        let c = ConfigCtx {
            nw: w.len(),
            wavelengths: w,
            ..ctx
        };
        let spherical = cfg
            .geometry
            .resolve(&c)
            .map(|g| g.planet_radius.is_some())
            .unwrap_or(false);
        Ok(cfg.illumination.resolve(&c, w, spherical)?.irradiance)
    };
    let crate::spectral::Sampling {
        wavelengths,
        band,
        bands,
        centres,
    } = cfg
        .spectral
        .resolve(&ctx, cfg.mode, || ckd_bins(&ctx, absorption_data), &solar)?;
    let nw = wavelengths.len();
    let ctx = ConfigCtx {
        nw,
        wavelengths: &wavelengths,
        ..ctx
    };

    let geometry = cfg.geometry.resolve(&ctx)?;
    let (ground, toa, planet_radius) = (geometry.ground, geometry.toa, geometry.planet_radius);

    // Atmosphere: per wavelength, a list of layers (and per g-point gas absorption in CKD mode).
    let atmosphere = match &cfg.atmosphere {
        None => AtmosphereLayers {
            layers: vec![Vec::new(); nw],
            ckd: Vec::new(),
        },
        Some(a) => a.resolve(&ctx, &geometry, &wavelengths, cfg.mode, &cfg.spectral)?,
    };

    let surfaces = resolve_surfaces(&cfg, &ctx, &wavelengths)?;

    let sun = cfg
        .illumination
        .resolve(&ctx, &wavelengths, planet_radius.is_some())?;
    let thermal = super::thermal::resolve(&cfg, &ctx, &geometry, &wavelengths, &sun)?;

    let scene = resolve_scene(&cfg, &ctx, &sun, planet_radius, ground)?;
    let lamps = resolve_lamps(&cfg, &ctx, scene.as_deref(), planet_radius)?;
    if let (Some(_), Some(sc)) = (&thermal, &scene) {
        check_scene_temperatures(&ctx, sc, &wavelengths)?;
    }

    let clouds = crate::clouds::config::resolve(&ctx, &cfg.clouds, &wavelengths)?;
    if let Some(c) = &clouds {
        check_clouds(&cfg, &ctx, c, scene.as_deref(), planet_radius)?;
    }

    let mut measures = resolve_measures(&cfg, &ctx, ground, toa, scene.as_deref())?;
    let lidars = resolve_lidars(&cfg, &ctx, ground, scene.as_deref())?;
    if let Some(l) = lidars.first() {
        // The lidar flies through plane-parallel layers at one wavelength.
        let why = if ckd {
            Some("`mode = \"ckd\"` (use monochromatic wavelengths)")
        } else if clouds.is_some() {
            Some("`[[clouds]]` fields (the lidar flies through the layers only)")
        } else {
            None
        };
        if let Some(why) = why {
            return Err(ctx.err(
                format!("measures[{}]", l.index),
                format!("lidar measures do not support {why} yet"),
            ));
        }
    }

    let mut integrator = IntegratorSettings::from_config(
        &ctx,
        &cfg.integrator,
        RunShape {
            ckd,
            polarized: cfg.polarized,
            spherical: planet_radius.is_some(),
            scene: scene.is_some(),
            radiancemeter: measures.iter().position(|m| {
                matches!(
                    m.kind,
                    MeasureKind::Radiancemeter { .. } | MeasureKind::Hdrf { .. }
                )
            }),
            moon: sun.moon.is_some(),
            wavelengths: wavelengths.len(),
            emission: cfg.emission,
            atmosphere: atmosphere.layers.iter().any(|l| !l.is_empty()),
            images: measures.iter().any(|m| m.is_image()),
            bands: !bands.is_empty(),
            srf: band.is_some(),
        },
    )?;

    if let Some(t) = &thermal {
        t.check_integrator(&ctx, &mut integrator, &measures)?;
    }
    check_moon(&cfg, &ctx, &sun, &mut integrator)?;
    check_scene_solvers(&ctx, &mut integrator, scene.as_deref())?;
    if lamps.is_some() && (integrator.alis || integrator.spectral_alis.is_some()) {
        // Lamps are estimated in the Sun's independent walks (`blocks/single.rs`).
        if !integrator.drop_auto_alis() || integrator.alis {
            return Err(ctx.err(
                "integrator.spectral_walk",
                "spectral (ALIS) walks do not carry lamps (`[[lights]]`) yet: use spectral_walk = \"independent\" (or \"auto\")",
            ));
        }
    }
    apply_surface_solver(&cfg, &ctx, planet_radius, &mut integrator)?;
    if ckd && atmosphere.ckd.is_empty() {
        return Err(ctx.err(
            "atmosphere",
            "mode = \"ckd\" needs a `molecular` atmosphere with `absorption_data`",
        ));
    }
    let inputs = OpticsInputs {
        ctx: &ctx,
        wavelengths: &wavelengths,
        scene: &scene,
        thermal: &thermal,
        sun: &sun,
        ground,
        toa,
        planet_radius,
    };
    let mut optics = build_optics(&inputs, atmosphere, surfaces)?;

    let atmospheres: Vec<&PlaneParallel> = optics.iter().map(|o| &o.atmosphere).collect();
    if !bands.is_empty() {
        // The bands' sets are checked with them (`config/bands.rs`).
    } else if let Err(e) = crate::integrator::backward_alis::check_spectral_groups(
        &integrator,
        &ctx,
        &wavelengths,
        &atmospheres,
        scene.is_some(),
    ) {
        // `spectral_walk = "auto"` falls back to independent walks.
        if !integrator.drop_auto_alis() {
            return Err(e);
        }
    }
    if clouds.is_some() && (integrator.alis || integrator.spectral_alis.is_some()) {
        // The spectral walks' geometries (`scene_alis.rs`, `backward_alis.rs`) do not cross
        // cloud fields: `"auto"` falls back to independent walks, an explicit choice is refused.
        if !integrator.drop_auto_alis() || integrator.alis {
            return Err(ctx.err(
                "integrator.spectral_walk",
                "spectral (ALIS) walks do not cross `[[clouds]]` fields yet: use spectral_walk = \"independent\" (or \"auto\")",
            ));
        }
    }
    // The run's outputs: its wavelengths, or its bands.
    let mut outputs = wavelengths.clone();
    let band_walks = if bands.is_empty() {
        None
    } else {
        let walks = super::bands::resolve(
            &ctx,
            &bands,
            &centres,
            &mut outputs,
            &mut optics,
            &integrator,
            sun.zenith_deg,
        )?;
        if sun.moon.is_some() {
            return Err(ctx.err(
                "spectral.bands",
                "sensor bands are not rendered with the Moon beside the Sun yet (render the bands by day, or the Moon with `srf`)",
            ));
        }
        Some(walks)
    };
    crate::measure::config::finish_targets(
        &ctx,
        &measures,
        // An `srf` run's target is its band's: one number.
        if band.is_some() { 1 } else { outputs.len() },
        if band_walks.is_some() || band.is_some() {
            "band"
        } else {
            "wavelength"
        },
    )?;
    // After every check that may turn off the walks that `"auto"` chose.
    check_above_scene(&ctx, &integrator, scene.as_deref(), &sun)?;
    if let Some(b) = &band {
        relax_targets_for_band(&mut measures, &b.weights, &sun.irradiance);
    }
    // CKD: blocks of samples cycle through the g-points, so every measure's sample count is a
    // whole number of cycles (rounded up).
    if let Some(ng) = optics.first().map(|o: &OpticalState| o.g_states.len()) {
        integrator.check_g_points(&ctx, ng)?;
        if ng > 1 && !integrator.alis {
            round_to_g_point_cycles(&mut measures, ng);
            // Each replicate then holds whole g-point cycles (`IntegratorSettings::replicates`).
            integrator.replicates = true;
        }
    }
    let exp = Experiment {
        wavelengths: outputs,
        band,
        bands: band_walks,
        optics,
        sun_zenith: sun.zenith_deg.to_radians(),
        sun_azimuth: sun.azimuth_deg.to_radians(),
        sun_dir: sun.dir,
        sun_zenith_deg: sun.zenith_deg,
        sun_azimuth_deg: sun.azimuth_deg,
        sun_distance_au: sun.distance_au,
        measures,
        lidars,
        integrator,
        seed: cfg.seed,
        polarized: cfg.polarized,
        emission: cfg.emission,
        sun_shines: sun.shines,
        moon: sun.moon.clone(),
        lamps,
        planet_radius,
        scene,
        clouds,
        source_text: text.to_string(),
        source_path: path.to_path_buf(),
    };
    if let Some(l) = exp.lamps.as_deref() {
        if l.estimator == crate::sources::lamps::LampEstimator::Forward {
            if let Some(k) = exp
                .measures
                .iter()
                .position(|m| exp.lamp_photon_pixels(m).is_none())
            {
                return Err(ctx.err(
                    "integrator.lamp_estimator",
                    format!("\"forward\" serves nadir ortho images of scenes without rough dielectrics, not measures[{k}] (`{}`): use \"auto\" (forward photons where they apply, backward walks elsewhere)", exp.measures[k].id),
                ));
            }
        }
    }
    super::memory::check(&exp, super::memory::total_memory())?;
    Ok(exp)
}

/// `[[clouds]]` needs a 3D scene in plane-parallel layers, without thermal emission; in a
/// periodic scene the field repeats with a period that divides the scene's.
fn check_clouds(
    cfg: &ExperimentConfig,
    ctx: &ConfigCtx,
    c: &crate::clouds::config::PlacedClouds,
    scene: Option<&Scene>,
    planet_radius: Option<f64>,
) -> Result<(), ConfigError> {
    let Some(scene) = scene else {
        return Err(ctx.err(
            "clouds",
            "cloud fields are crossed by the 3D scene walks: add a `[scene]` (for a flat ground, a `canopy` scene with only a `ground`, and `periodic_m` for a periodic domain)",
        ));
    };
    if planet_radius.is_some() {
        return Err(ctx.err(
            "clouds",
            "cloud fields are not supported in spherical shells yet (use plane-parallel layers)",
        ));
    }
    if cfg.emission {
        return Err(ctx.err(
            "clouds",
            "cloud fields do not emit yet: thermal runs (`emission = true`) cannot have `[[clouds]]`",
        ));
    }
    if let Some(cell) = scene.periodic {
        let (w, h) = (cell[2] - cell[0], cell[3] - cell[1]);
        let (lx, ly) = c.grid.size();
        let whole =
            |a: f64, b: f64| (a / b - (a / b).round()).abs() < 1e-9 && a >= b * (1.0 - 1e-12);
        if c.grid.lateral != crate::clouds::Lateral::Periodic || !whole(w, lx) || !whole(h, ly) {
            return Err(ctx.err(
                "clouds[0].lateral",
                format!(
                    "the scene repeats every {w} × {h} m: the cloud field must be periodic (`lateral = \"periodic\"`) with a size ({lx} × {ly} m) that divides that period"
                ),
            ));
        }
    }
    Ok(())
}

/// The surface per wavelength: `[surface]`, or a black placeholder under a 3D scene.
fn resolve_surfaces(
    cfg: &ExperimentConfig,
    ctx: &ConfigCtx,
    wavelengths: &[f64],
) -> Result<Vec<Bsdf>, ConfigError> {
    let nw = wavelengths.len();
    Ok(match (&cfg.surface, &cfg.scene) {
        (Some(_), Some(_)) => {
            return Err(ctx.err(
                "surface",
                "is replaced by the scene: give `scene` or `surface`, not both (a bundle's surroundings are `scene.background`)",
            ))
        }
        (None, None) => return Err(ctx.err("surface", "is required (or a 3D `scene`)")),
        (None, Some(_)) => vec![Bsdf::Lambertian(Lambertian::new(0.0).expect("valid")); nw],
        (Some(s), None) => s.resolve(ctx, "surface", wavelengths)?,
    })
}

/// The 3D scene, if any: checked against the Sun's elevation and built (bent onto the planet
/// under a spherical shell).
fn resolve_scene(
    cfg: &ExperimentConfig,
    ctx: &ConfigCtx,
    sun: &Sun,
    planet_radius: Option<f64>,
    ground: f64,
) -> Result<Option<Arc<Scene>>, ConfigError> {
    let Some(sc) = &cfg.scene else {
        return Ok(flat_ground_for_lamps(cfg, ground));
    };
    // Plane-parallel layers refuse a Sun below the horizon already; in spherical shells a
    // scene may lie in twilight (the shells' sunlit air lights it; radiances only).
    if sun.dir.z <= 1e-6 && planet_radius.is_none() {
        return Err(ctx.err(
            "illumination.zenith",
            "the Sun must be above the horizon to render a 3D scene in plane-parallel layers (use geometry.type = \"spherical_shell\" for twilight)",
        ));
    }
    // Under a spherical shell the scene is bent onto the planet (scene::curvature).
    let bend = planet_radius.map(|radius| crate::scene::curvature::Curvature { radius });
    let built = scene::build_scene_shared(sc, ctx.base, bend).map_err(|(k, m)| ctx.err(k, m))?;
    // An experiment's material may give a list with one value per run wavelength.
    built
        .check_spectra(ctx.nw)
        .map_err(|m| ctx.err("scene", m))?;
    // (Bent scenes hold bent heights: their lowest point sags below its altitude.)
    if cfg.atmosphere.is_some() && built.curvature.is_none() && built.z_range[0] < ground - 1e-6 {
        tracing::warn!(
            "the scene's lowest point ({:.1} m) is below the atmosphere's bottom ({:.1} m): no atmosphere below it",
            built.z_range[0],
            ground
        );
    }
    Ok(Some(built))
}

/// A 1D run with lamps: its uniform ground as a flat scene at the ground altitude (lamps light
/// it unevenly, so its paths need positions), its default area 1 km about the lamps.
fn flat_ground_for_lamps(cfg: &ExperimentConfig, ground: f64) -> Option<Arc<Scene>> {
    let surface = cfg.surface.as_ref()?;
    if cfg.lights.is_empty() {
        return None;
    }
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for l in &cfg.lights {
        for k in 0..2 {
            lo[k] = lo[k].min(l.position_m[k]);
            hi[k] = hi[k].max(l.position_m[k]);
        }
    }
    let extent = if lo[0].is_finite() && hi[0].is_finite() && lo[1].is_finite() && hi[1].is_finite()
    {
        [lo[0] - 500.0, lo[1] - 500.0, hi[0] + 500.0, hi[1] + 500.0]
    } else {
        [-500.0, -500.0, 500.0, 500.0]
    };
    Some(Arc::new(crate::scene::build::flat_ground(
        surface.brdf.clone(),
        surface.solver,
        surface.temperature,
        ground,
        extent,
    )))
}

/// The lamps of `[[lights]]` (None without any), in the scene's frame; refused where the walks
/// do not estimate them.
fn resolve_lamps(
    cfg: &ExperimentConfig,
    ctx: &ConfigCtx,
    scene: Option<&Scene>,
    planet_radius: Option<f64>,
) -> Result<Option<Arc<crate::sources::lamps::Lamps>>, ConfigError> {
    let bundle_lamps = matches!(
        cfg.scene,
        Some(scene::SceneConfig::Bundle { lamps: true, .. })
    );
    let emitters = match &cfg.scene {
        Some(scene::SceneConfig::Bundle { emitters, .. }) => Some(emitters),
        _ => None,
    }
    .filter(|e| !e.is_empty());
    if !cfg.has_lamps() {
        return Ok(None);
    }
    let why = if cfg.polarized {
        Some("polarized runs (`polarized = true`)")
    } else if planet_radius.is_some() {
        Some("spherical-shell atmospheres (use plane-parallel layers)")
    } else if !cfg.clouds.is_empty() {
        Some("`[[clouds]]` fields")
    } else if cfg.mode == Mode::Ckd {
        Some("`mode = \"ckd\"` (use monochromatic wavelengths)")
    } else {
        None
    };
    if let Some(why) = why {
        return Err(ctx.err("lights", format!("lamps are not built for {why} yet")));
    }
    let scene = scene.ok_or_else(|| {
        ctx.err(
            "lights",
            "lamps need a `[surface]` or a 3D `scene` to light",
        )
    })?;
    let frame = scene::frame(scene);
    let mut more = Vec::new();
    if bundle_lamps {
        for t in &scene.template_lamps {
            more.extend(crate::sources::lamps::template_lamps(
                &t.specs,
                &t.sites,
                &format!("scene.lamps: template `{}` lamps", t.template),
                ctx,
            )?);
        }
        if more.is_empty() && cfg.lights.is_empty() {
            return Err(ctx.err(
                "scene.lamps",
                "the bundle's templates carry no lamps (a template's `lamps` in the region file, e.g. the built-in `streetlight`)",
            ));
        }
    }
    let mut lamps = crate::sources::lamps::Lamps::resolve_with(
        &cfg.lights,
        ctx,
        |x, y| frame.to_local(x, y),
        cfg.integrator.lamp_sampling,
        more,
    )?;
    if let Some(emitters) = emitters {
        lamps.emitters = vec![Vec::new(); scene.materials.len()];
        for (name, radiance) in emitters {
            let key = format!("scene.emitters.{name}");
            let id = crate::scene::world::material_id(&scene.materials, name)
                .map_err(|e| ctx.err(key.clone(), e.to_string()))?;
            lamps.emitters[id] =
                crate::spectral::SpectrumExt::expand(radiance, ctx, &key, 0.0, 1e6)?;
        }
    }
    if let Some(k) = cfg.integrator.lamp_samples {
        if !(1..=64).contains(&k) {
            return Err(ctx.err(
                "integrator.lamp_samples",
                format!("{k} must be an integer in 1..=64"),
            ));
        }
        lamps.samples = k;
    }
    if let Some(n) = cfg.integrator.lamp_photons {
        if !(1..=1_000_000).contains(&n) {
            return Err(ctx.err(
                "integrator.lamp_photons",
                format!("{n} must be an integer in 1..=1000000"),
            ));
        }
        lamps.photons = n;
    }
    lamps.estimator = cfg.integrator.lamp_estimator;
    tracing::info!("{} lamps", lamps.lamps.len());
    Ok(Some(Arc::new(lamps)))
}

/// The measures, each checked against the atmosphere's levels, the scene and the ones before it.
fn resolve_measures(
    cfg: &ExperimentConfig,
    ctx: &ConfigCtx,
    ground: f64,
    toa: f64,
    scene: Option<&Scene>,
) -> Result<Vec<Measure>, ConfigError> {
    if cfg.measures.is_empty() {
        return Err(ctx.err("measures", "at least one measure is required"));
    }
    check_ids(cfg, ctx)?;
    let frame = scene.map(scene::frame);
    let at = MeasureContext {
        ground,
        toa,
        scene: frame.as_ref(),
    };
    let mut measures = Vec::with_capacity(cfg.measures.len());
    for (im, m) in cfg.measures.iter().enumerate() {
        if matches!(m, MeasureConfig::Lidar(_)) {
            continue;
        }
        let m = m.resolve(ctx, im, &measures, &at)?;
        measures.push(m);
    }
    Ok(measures)
}

/// Lidar measures' ids must differ from every other measure's (the passive ones check their
/// own among themselves).
fn check_ids(cfg: &ExperimentConfig, ctx: &ConfigCtx) -> Result<(), ConfigError> {
    for (i, m) in cfg.measures.iter().enumerate() {
        if let MeasureConfig::Lidar(l) = m {
            if let Some(j) = cfg.measures[..i].iter().position(|o| o.id() == l.id) {
                return Err(ctx.err(
                    format!("measures[{i}].id"),
                    format!(
                        "`{}` is also the id of measures[{j}]; ids must be unique",
                        l.id
                    ),
                ));
            }
        } else if let Some(j) = cfg.measures[..i]
            .iter()
            .position(|o| matches!(o, MeasureConfig::Lidar(_)) && o.id() == m.id())
        {
            return Err(ctx.err(
                format!("measures[{i}].id"),
                format!(
                    "`{}` is also the id of measures[{j}]; ids must be unique",
                    m.id()
                ),
            ));
        }
    }
    Ok(())
}

/// The lidar measures, resolved at their wavelengths against the 1D ground or the scene.
fn resolve_lidars(
    cfg: &ExperimentConfig,
    ctx: &ConfigCtx,
    ground: f64,
    scene: Option<&Scene>,
) -> Result<Vec<crate::lidar::Lidar>, ConfigError> {
    let mut out = Vec::new();
    for (im, m) in cfg.measures.iter().enumerate() {
        if let MeasureConfig::Lidar(l) = m {
            out.push(l.resolve(ctx, im, ground, scene)?);
        }
    }
    Ok(out)
}

/// With thermal emission, every material of the scene needs a temperature, none so cold that
/// its Planck radiance underflows at the shortest run wavelength (`planck::lowest_temperature`).
fn check_scene_temperatures(
    ctx: &ConfigCtx,
    sc: &Scene,
    wavelengths: &[f64],
) -> Result<(), ConfigError> {
    let shortest = wavelengths.iter().cloned().fold(f64::INFINITY, f64::min);
    let t_min = crate::sources::planck::lowest_temperature(shortest);
    if let Some((t, row, column)) = sc.lst.as_ref().and_then(|m| m.coldest()) {
        if t < t_min {
            return Err(ctx.err(
                "scene.land_surface_temperature",
                format!(
                    "pixel (row {row}, column {column}) holds {t} K, which radiates nothing representable at {shortest} nm (its Planck radiance underflows); at the run's wavelengths temperatures must be at least {t_min:.3} K"
                ),
            ));
        }
    }
    for (id, (name, _)) in sc.materials.iter().enumerate() {
        if let Some(t) = sc.temperature(id as u16) {
            if t < t_min {
                return Err(ctx.err(
                    format!("scene.temperatures.{name}"),
                    format!(
                        "{t} K radiates nothing representable at {shortest} nm (its Planck radiance underflows); at the run's wavelengths temperatures must be at least {t_min:.3} K"
                    ),
                ));
            }
        }
    }
    let missing: Vec<&str> = sc
        .materials
        .iter()
        .enumerate()
        .filter(|(id, _)| sc.temperature(*id as u16).is_none())
        .map(|(_, (name, _))| name.as_str())
        .collect();
    if !missing.is_empty() {
        return Err(ctx.err(
            "scene.temperatures",
            format!(
                "thermal emission (`emission = true`) needs a temperature (K) for every material of the scene (the bundle's `temperature`, or `[scene.temperatures]`); missing: {}",
                missing.join(", ")
            ),
        ));
    }
    Ok(())
}

/// The Moon beside the Sun: refused with thermal emission, and run by the backward integrator.
fn check_moon(
    cfg: &ExperimentConfig,
    ctx: &ConfigCtx,
    sun: &Sun,
    integrator: &mut IntegratorSettings,
) -> Result<(), ConfigError> {
    if sun.moon.is_some() && cfg.emission {
        return Err(ctx.err(
            "illumination.moon",
            "the Moon beside the Sun is built for reflected light, not with thermal emission (`emission = true`): drop one or the other",
        ));
    }
    if sun.moon.is_some() {
        use crate::integrator::settings::IntegratorKind;
        // The Moon's walk joins each sample of the Sun's in the backward estimator (`blocks/walks.rs`).
        match integrator.kind {
            IntegratorKind::Forward => {
                return Err(ctx.err(
                    "illumination.moon",
                    "the Moon beside the Sun needs the backward integrator (`integrator.type = \"auto\"` or \"backward\")",
                ))
            }
            IntegratorKind::Auto => integrator.kind = IntegratorKind::Backward,
            IntegratorKind::Backward => {}
        }
    }
    Ok(())
}

/// `integrator.above_scene = "pooled"` needs a scene, spectral walks and no Moon.
fn check_above_scene(
    ctx: &ConfigCtx,
    integrator: &IntegratorSettings,
    scene: Option<&Scene>,
    sun: &Sun,
) -> Result<(), ConfigError> {
    // `integrator.above_scene = "pooled"` (`integrator/above_scene.rs`) is built for ortho
    // images walked over wavelength groups, lit by the Sun alone.
    if integrator.above_scene == crate::integrator::settings::AboveScene::Pooled {
        let why = if scene.is_none() {
            Some("needs a 3D scene (`[scene]`)")
        } else if integrator.spectral_alis.is_none() {
            Some("is built for walks over wavelength groups: add `integrator.spectral_walk = \"alis\"`")
        } else if sun.moon.is_some() {
            Some("is not built for the Moon beside the Sun (`illumination.moon`)")
        } else {
            None
        };
        if let Some(why) = why {
            return Err(ctx.err(
                "integrator.above_scene",
                format!("\"pooled\" {why}; or leave it at \"auto\""),
            ));
        }
    }
    Ok(())
}

/// Spectral walks through a scene follow the scene materials' default solver only, and carry
/// no dielectric materials.
fn check_scene_solvers(
    ctx: &ConfigCtx,
    integrator: &mut IntegratorSettings,
    scene: Option<&Scene>,
) -> Result<(), ConfigError> {
    // Spectral walks through a scene (`scene_alis.rs`) follow the default solver only.
    if let (Some(sc), Some(_)) = (scene, integrator.spectral_alis) {
        if let Some((name, solver)) = sc
            .materials
            .iter()
            .enumerate()
            .map(|(i, (name, _))| (name, sc.solver(i as u16)))
            .find(|(_, s)| *s != bundle::SolverSpec::default())
        {
            if integrator.drop_auto_alis() {
                return Ok(());
            }
            return Err(ctx.err(
                format!("scene.solvers.{name}"),
                format!("the `{}` solver is not built into spectral walks through a scene (`integrator.spectral_walk = \"alis\"`): drop one or the other", solver.type_name()),
            ));
        }
        // Dielectrics transmit with per-wavelength deltas and pane-filtered shadow rays, which
        // the spectral walk's shared directions and visibility do not carry.
        if let Some((name, spec)) = sc.materials.iter().find(|(_, s)| s.is_dielectric()) {
            if integrator.drop_auto_alis() {
                return Ok(());
            }
            return Err(ctx.err(
                "integrator.spectral_walk",
                format!("material `{name}` is a `{}`, which spectral walks through a scene (`\"alis\"`) do not carry: use \"auto\" or \"independent\"", spec.type_name()),
            ));
        }
    }
    Ok(())
}

/// Check the surface's solver against the run and hand it to the integrator.
fn apply_surface_solver(
    cfg: &ExperimentConfig,
    ctx: &ConfigCtx,
    planet_radius: Option<f64>,
    integrator: &mut IntegratorSettings,
) -> Result<(), ConfigError> {
    if let Some(solver) = cfg.surface.as_ref().and_then(|s| s.solver) {
        solver
            .validate()
            .map_err(|(k, m)| ctx.err(format!("surface.solver.{k}"), m))?;
        if !solver.is_default() {
            use crate::integrator::settings::IntegratorKind;
            // The solvers act in the backward estimator (`integrator/solver.rs`).
            match integrator.kind {
                IntegratorKind::Forward => {
                    return Err(ctx.err(
                        "surface.solver",
                        format!("the `{}` solver needs the backward integrator (`integrator.type = \"auto\"` or \"backward\")", solver.type_name()),
                    ))
                }
                IntegratorKind::Auto => integrator.kind = IntegratorKind::Backward,
                IntegratorKind::Backward => {}
            }
            if matches!(solver, bundle::SolverSpec::Mirror { .. })
                && (cfg.polarized || planet_radius.is_some())
            {
                return Err(ctx.err(
                    "surface.solver",
                    "a `mirror` ground is built for scalar plane-parallel runs (its reflected sunbeam lights the layers through a mirror-image Sun; polarized and spherical-shell runs lack it)",
                ));
            }
            if integrator.alis || integrator.spectral_alis.is_some() {
                return Err(ctx.err(
                    "surface.solver",
                    format!("the `{}` solver is not built into ALIS walks: drop `integrator.ckd_walk = \"alis\"` or `integrator.spectral_walk = \"alis\"`", solver.type_name()),
                ));
            }
        }
        integrator.surface_solver = solver;
    }
    Ok(())
}

/// The resolved parts the per-wavelength optical states are built from.
struct OpticsInputs<'a> {
    ctx: &'a ConfigCtx<'a>,
    wavelengths: &'a [f64],
    scene: &'a Option<Arc<Scene>>,
    thermal: &'a Option<super::thermal::Thermal>,
    sun: &'a Sun,
    ground: f64,
    toa: f64,
    planet_radius: Option<f64>,
}

/// The optical state of every wavelength (with its g-points' states in CKD mode).
fn build_optics(
    inputs: &OpticsInputs,
    atmosphere: AtmosphereLayers,
    surfaces: Vec<Bsdf>,
) -> Result<Vec<OpticalState>, ConfigError> {
    let ckd_tau = atmosphere.ckd;
    atmosphere
        .layers
        .into_iter()
        .zip(surfaces)
        .enumerate()
        .map(|(iw, (layers, surface))| optical_state(inputs, iw, layers, surface, ckd_tau.get(iw)))
        .collect::<Result<Vec<_>, ConfigError>>()
}

/// The optical state of wavelength `iw`: its layers, surface, sources and scene models, and
/// the states of its g-points `gs` (CKD mode).
fn optical_state(
    inputs: &OpticsInputs,
    iw: usize,
    layers: Vec<LayerOptics>,
    surface: Bsdf,
    gs: Option<&Vec<GPoint>>,
) -> Result<OpticalState, ConfigError> {
    let &OpticsInputs {
        ctx,
        wavelengths,
        scene,
        thermal,
        sun,
        ground,
        toa,
        planet_radius,
    } = inputs;
    let scene_models = match &scene {
        Some(sc) => sc
            .models_at(iw, wavelengths[iw])
            .map_err(|m| ctx.err("scene", m.to_string()))?,
        None => Vec::new(),
    };
    // A scene's emission at this wavelength, its Planck radiances times `scale`.
    let scene_emission = |scale: f64| match (&thermal, &scene) {
        (Some(t), Some(sc)) => Some(crate::scene::emission::SceneEmission::new(
            sc,
            &scene_models,
            wavelengths[iw],
            t.k(iw) * scale,
        )),
        _ => None,
    };
    let g_states: Vec<(f64, OpticalState)> = match gs {
        None => Vec::new(),
        Some(gs) => gs
            .iter()
            .map(|gp| g_point_state(inputs, iw, &layers, &surface, gp, &scene_emission))
            .collect::<Result<Vec<_>, ConfigError>>()?,
    };
    let mut atmosphere = PlaneParallel::new(layers, ground, toa);
    // In CKD mode the g-points carry the sources (above); the bin's own atmosphere
    // (no gas absorption: the ALIS reference) gets none.
    let surface_emission = match &thermal {
        Some(t) if g_states.is_empty() => t.apply(iw, &mut atmosphere, &surface, None),
        _ => None,
    };
    let shell = planet_radius.map(|r| SphericalShell::new(&atmosphere, r));
    let scene_emission = if g_states.is_empty() {
        scene_emission(1.0)
    } else {
        None
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
        surface_emission,
        scene_models,
        scene_emission,
        irradiance: sun.irradiance[iw],
        g_states,
    })
}

/// The weight and optical state of one g-point `gp` of wavelength `iw` (its gas absorption
/// added to the layers, its thermal sources scaled by its Planck fractions).
fn g_point_state(
    inputs: &OpticsInputs,
    iw: usize,
    layers: &[LayerOptics],
    surface: &Bsdf,
    gp: &GPoint,
    scene_emission: &dyn Fn(f64) -> Option<crate::scene::emission::SceneEmission>,
) -> Result<(f64, OpticalState), ConfigError> {
    let &OpticsInputs {
        ctx,
        wavelengths,
        thermal,
        sun,
        ground,
        toa,
        planet_radius,
        ..
    } = inputs;
    let mut l = layers.to_vec();
    for (layer, t) in l.iter_mut().zip(&gp.tau) {
        layer.tau_abs += t;
    }
    let mut atmosphere = PlaneParallel::new(l, ground, toa);
    let scale0 = gp
        .planck_scale
        .as_ref()
        .and_then(|s| s.first().copied())
        .unwrap_or(1.0);
    let surface_emission = match &thermal {
        None => None,
        Some(t) => {
            let Some(scale) = gp.planck_scale.as_deref() else {
                return Err(ctx.err(
                    "atmosphere.absorption_data",
                    "thermal emission (`emission = true`) in mode = \"ckd\" needs a longwave k-distribution with Planck fractions per g-point (RRTMGP's `rrtmgp-gas-lw-g256.nc`)",
                ));
            };
            t.apply(iw, &mut atmosphere, surface, Some(scale))
        }
    };
    let shell = planet_radius.map(|r| SphericalShell::new(&atmosphere, r));
    Ok((
        gp.weight,
        OpticalState {
            wavelength: wavelengths[iw],
            atmosphere,
            shell,
            surface: surface.clone(),
            surface_emission,
            scene_models: Vec::new(),
            scene_emission: scene_emission(scale0),
            irradiance: sun.irradiance[iw],
            g_states: Vec::new(),
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::plain_closed_choice;

    /// Rationale (issue 42): Eradiate users give the sample count once for the run
    /// (`eosim.run(exp, spp=N)`, `simulate run --spp N`); a measure may then leave `spp` out.
    /// Without an override a missing `spp` is named at `measures[k].spp`.
    #[test]
    fn run_spp_fills_measures_without_one() {
        use crate::config::Experiment;
        let text = "[spectral]\nwavelengths = [550.0]\n[atmosphere]\ntype = \"homogeneous\"\n\
                    optical_thickness = 0.1\nsingle_scattering_albedo = 1.0\nphase = { type = \"rayleigh\" }\n\
                    [surface]\ntype = \"lambertian\"\nreflectance = 0.2\n\
                    [illumination]\ntype = \"directional\"\nzenith = 30.0\n\
                    [[measures]]\nid = \"a\"\ntype = \"mdistant\"\nazimuth = 0.0\nzeniths = [0.0]\nspp = 10\n\
                    [[measures]]\nid = \"b\"\ntype = \"mdistant\"\nazimuth = 0.0\nzeniths = [0.0]\n";
        let p = std::path::Path::new("x.toml");
        let e = Experiment::from_str(text, p).unwrap_err().to_string();
        assert!(
            e.contains("measures[1].spp")
                && e.contains("missing required key")
                && e.contains("--spp"),
            "{e}"
        );
        let exp = Experiment::parse_with_spp(text, p, Some(77)).unwrap();
        assert!(exp.measures.iter().all(|m| m.spp == 77));
    }

    /// serde's words for closed choices become the resolvers' (the value, the allowed values).
    #[test]
    fn closed_choice_in_plain_words() {
        assert_eq!(
            plain_closed_choice("unknown variant `grouped`, expected `independent` or `alis`"),
            "\"grouped\" is unknown (known: \"independent\", \"alis\")"
        );
        assert_eq!(
            plain_closed_choice(
                "TOML parse error at line 4, column 1\n  |\n4 | x\n  | ^\nunknown variant `mie`, expected one of `rayleigh`, `hg`, `isotropic`\n"
            ),
            "TOML parse error at line 4, column 1\n  |\n4 | x\n  | ^\n\"mie\" is unknown (known: \"rayleigh\", \"hg\", \"isotropic\")\n"
        );
        assert_eq!(
            plain_closed_choice("unknown variant `x y`, expected `r x y z nx ny nz`"),
            "\"x y\" is unknown (known: \"r x y z nx ny nz\")"
        );
        assert_eq!(
            plain_closed_choice("missing field `g`"),
            "missing field `g`"
        );
        assert_eq!(
            plain_closed_choice("wanted string or table"),
            "invalid type: expected a string"
        );
        // A value holding a line break (found by proptest_config: it used to panic).
        assert_eq!(
            plain_closed_choice("unknown variant `a\nb`, expected `hplane` or `directions`\nx"),
            "\"a\nb\" is unknown (known: \"hplane\", \"directions\")\nx"
        );
    }
}
