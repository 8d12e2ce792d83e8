//! Settings of the transport core and the `[integrator]` table they come from: its raw serde
//! type and [`IntegratorSettings::from_config`], which checks it against the rest of the run
//! (keys and meanings in `docs/experiment.md`).

use serde::Deserialize;

use crate::atmosphere::PlaneParallel;
use crate::error::{ConfigCtx, ConfigError};

/// The most channels (g-points or wavelengths) one walk carries (`backward_alis.rs`).
pub const MAX_CHANNELS: usize = 64;

/// The most wavelengths one walk through a 3D scene carries (`integrator.alis_group`,
/// `scene_alis.rs`).
pub const SCENE_CHANNELS: usize = 8;

/// Which walk serves the measures (`integrator.type`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum IntegratorKind {
    /// Forward for `mdistant` and `distant_flux`, backward for `radiancemeter`.
    #[default]
    Auto,
    /// Photons from the Sun with local estimates towards every direction (1D distant measures).
    Forward,
    /// Paths from the sensor with next-event estimation towards the Sun.
    Backward,
}

#[derive(Clone, Debug)]
pub struct IntegratorSettings {
    pub kind: IntegratorKind,
    /// Maximum scattering order counted (u32::MAX: unlimited).
    pub max_depth: u32,
    pub rr_depth: u32,
    /// Score the expected local estimate along each flight (true) or at sampled collisions.
    pub expected_local_estimate: bool,
    /// CKD runs: one backward walk for all g-points of a bin (`integrator/backward_alis.rs`).
    pub alis: bool,
    /// Monochromatic runs with `spectral_walk = "alis"`: the wavelengths per group (one backward
    /// walk serves a group, `integrator/backward_alis.rs`); None: independent walks.
    pub spectral_alis: Option<usize>,
    /// `spectral_alis` was chosen by `spectral_walk = "auto"`: a check that would refuse an
    /// explicit `"alis"` turns it off instead ([`IntegratorSettings::drop_auto_alis`]).
    pub spectral_alis_auto: bool,
    /// Samples before the first precision check (None: 4 blocks).
    pub first_check_spp: Option<u64>,
    /// DDIS mixture weight ε at peaked phase functions (`integrator/peak_sampling.rs`); 0: off.
    pub detector_sampling: f64,
    /// `integrator.sampler`: the first [`crate::rng::QMC_DIMS`] numbers of each sample from an
    /// Owen-scrambled Sobol sequence (`rng.rs`) instead of Philox alone.
    pub sampler: Sampler,
    /// The 1D surface's radiometry solver (`[surface] solver`, `solver.rs`); scene materials
    /// carry theirs in the scene.
    pub surface_solver: super::solver::SolverSpec,
    /// Keep replicate sums (sample s in replicate s mod 16) and take the standard error from
    /// their scatter: with the Sobol sampler, and in CKD runs that cycle through g-points in
    /// blocks (a replicate then holds whole cycles, so its mean is a stratified estimate of the
    /// bin and the scatter excludes the spread between g-points, which the i.i.d. formula
    /// would count).
    pub replicates: bool,
    /// `integrator.forced_flights`: the first this many flights of a backward path are split
    /// into a forced collision and the uncollided branch (`backward.rs`); 0: off.
    pub forced_flights: u32,
    /// `integrator.above_scene`: how ortho images of a scene estimate the light that the
    /// atmosphere above the scene sends before a path first goes below the scene's top
    /// (`integrator/above_scene.rs`).
    pub above_scene: AboveScene,
    /// `integrator.first_order_splits`: each backward sample's first-order (single-scattering)
    /// scores are the mean over this many independent first-order walks, its own included
    /// (`blocks/walks.rs` `backward_block`); 1: off.
    pub first_order_splits: u32,
    /// `integrator.lamp_sampling`: one lamp per estimate from the light tree, or every lamp
    /// (`sources/lamps/`).
    pub lamp_sampling: crate::sources::lamps::LampSampling,
}

/// `integrator.above_scene` (`integrator/above_scene.rs`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AboveScene {
    /// Pooled where it applies (ortho images of at least
    /// [`above_scene::MIN_PIXELS`](super::above_scene::MIN_PIXELS) pixels walked over
    /// wavelength groups), walked elsewhere.
    #[default]
    Auto,
    /// Every pixel's own walks (each sample scores it).
    Walked,
    /// One estimate shared by every pixel of the image.
    Pooled,
}

/// `integrator.sampler`: where each sample's random numbers come from. The resolved settings
/// hold `Random` or `Sobol` only ([`Sampler::resolve_auto`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Sampler {
    /// `Sobol` for 3D-scene runs without an atmosphere and without image measures, `Random`
    /// otherwise.
    #[default]
    Auto,
    /// Philox4x32 streams (independent samples).
    Random,
    /// Owen-scrambled Sobol points per cell for the first dimensions, Philox beyond.
    Sobol,
}

impl Sampler {
    /// What `"auto"` means for a run of shape `run`: Sobol points for the area measures of a
    /// 3D scene without an atmosphere (canopies: few cells of many samples each, whose noise
    /// is where the sensor's ray lands; stratified landing points give 1.35–1.8× less variance
    /// on the HOM canopy, 1.1× on HET01, BENCHMARKS.md); Philox streams elsewhere, where the
    /// gain was not measured or does not hold: 1D runs keep the independent samples their
    /// reference tests were written with, and images keep per-pixel errors from every sample
    /// (a Sobol cell's error comes from its 16 replicate means, noisier at the tens of samples
    /// a pixel gets) and 7× smaller accumulators.
    pub fn resolve_auto(self, run: &RunShape) -> Sampler {
        match self {
            Sampler::Auto if run.canopy_like() && !run.images => Sampler::Sobol,
            Sampler::Auto => Sampler::Random,
            s => s,
        }
    }
}

/// Default `integrator.rr_depth` (runs with an atmosphere, and 1D runs).
pub const RR_DEPTH: u32 = 5;

/// Default `integrator.detector_sampling`.
pub const DETECTOR_SAMPLING: f64 = 0.1;

/// Default `integrator.forced_flights`.
pub const FORCED_FLIGHTS: u32 = 1;

/// `integrator.local_estimate`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LocalEstimate {
    /// Expected local estimates integrated along flights.
    #[default]
    Expected,
    /// The classic estimate at sampled collisions.
    Collision,
}

/// `integrator.ckd_walk`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CkdWalk {
    /// Blocks of samples cycle through the g-points.
    #[default]
    Cycle,
    /// One backward walk carries every g-point of a bin.
    Alis,
}

/// `integrator.spectral_walk`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SpectralWalk {
    /// ALIS where it is built and pays ([`SpectralWalk::resolve_auto`]: monochromatic scalar
    /// plane-parallel scene runs of two or more wavelengths without emission, default
    /// solvers and groups that the reference supports), else independent walks.
    #[default]
    Auto,
    /// Every wavelength has its own walks.
    Independent,
    /// One backward walk carries a group of neighbouring wavelengths.
    Alis,
}

impl SpectralWalk {
    /// What `"auto"` chooses before the later checks: ALIS for a backward, monochromatic,
    /// scalar, plane-parallel run of a 3D scene with two or more wavelengths and no thermal
    /// emission (one walk then casts the scene's rays once for up to 8 wavelengths, and ortho
    /// images pool the light above the scene: 3.8–12× the efficiency of independent walks on
    /// the 13-band Sentinel-2 window, BENCHMARKS.md), else independent walks. The checks that
    /// would refuse an explicit `"alis"` (solvers, emission, unsupported groups) fall back to
    /// independent walks for `"auto"` ([`IntegratorSettings::spectral_alis_auto`]).
    pub fn resolve_auto(run: &RunShape, kind: IntegratorKind) -> SpectralWalk {
        let alis_pays = ((run.scene && run.wavelengths >= 2 && !run.ckd && !run.srf) || run.bands)
            && !run.polarized
            && !run.spherical
            && !run.emission
            && kind != IntegratorKind::Forward;
        if alis_pays {
            SpectralWalk::Alis
        } else {
            SpectralWalk::Independent
        }
    }
}

/// The `[integrator]` table.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IntegratorConfig {
    #[serde(default, rename = "type")]
    pub kind: IntegratorKind,
    /// Maximum scattering order (1 = single scattering); default unlimited.
    #[serde(default)]
    pub max_depth: Option<u32>,
    /// Scattering order from which Russian roulette may end paths (default 5; 1 in 3D scenes
    /// without an atmosphere).
    #[serde(default)]
    pub rr_depth: Option<u32>,
    #[serde(default)]
    pub local_estimate: LocalEstimate,
    /// `mode = "ckd"` only.
    #[serde(default)]
    pub ckd_walk: CkdWalk,
    /// `mode = "mono"` only.
    #[serde(default)]
    pub spectral_walk: SpectralWalk,
    /// `spectral_walk = "alis"`: wavelengths per group (1–64, default 32).
    #[serde(default)]
    pub alis_group: Option<usize>,
    /// Samples per direction before the first check of `target_rel_stderr` (default 8192).
    #[serde(default)]
    pub first_check_spp: Option<u64>,
    /// Detector-directional importance sampling at peaked phase functions: the mixture weight
    /// ε in [0, 0.5] (default 0.1; 0 turns it off).
    #[serde(default)]
    pub detector_sampling: Option<f64>,
    /// "auto" (default), "random" or "sobol" (quasi-random first dimensions, `rng.rs`).
    #[serde(default)]
    pub sampler: Sampler,
    /// Ortho images of scenes: "auto" (default), "walked" or "pooled" (`above_scene.rs`).
    #[serde(default)]
    pub above_scene: AboveScene,
    /// Backward walks: split the first N flights of each path into a forced collision and the
    /// uncollided branch (0–4, default [`FORCED_FLIGHTS`]).
    #[serde(default)]
    pub forced_flights: Option<u32>,
    /// Backward walks: first-order walks per sample (1–16, default 1 = off).
    #[serde(default)]
    pub first_order_splits: Option<u32>,
    /// Lamps: `"tree"` (default) or `"all"`.
    #[serde(default)]
    pub lamp_sampling: crate::sources::lamps::LampSampling,
    /// Lamps: lamps drawn per next-event estimate at a surface (1–64, default 1).
    #[serde(default)]
    pub lamp_samples: Option<u32>,
    /// Lamps: `"auto"` (default: forward photons for nadir ortho images), `"backward"` or
    /// `"forward"` (`integrator/lamp_photons.rs`).
    #[serde(default)]
    pub lamp_estimator: crate::sources::lamps::LampEstimator,
    /// Lamps: forward photons per lamp and wavelength (1–10⁶, default 256).
    #[serde(default)]
    pub lamp_photons: Option<u32>,
}

/// Most first-order walks per sample (`integrator.first_order_splits`).
pub const MAX_FIRST_ORDER_SPLITS: u32 = 16;

/// What of the rest of the run the integrator settings are checked against.
#[derive(Clone, Copy, Debug)]
pub struct RunShape {
    /// `mode = "ckd"`.
    pub ckd: bool,
    pub polarized: bool,
    /// A spherical-shell atmosphere.
    pub spherical: bool,
    /// A 3D scene.
    pub scene: bool,
    /// The index of the first measure only the backward estimator computes (a radiancemeter or
    /// an HDRF), if any.
    pub radiancemeter: Option<usize>,
    /// The Moon shines beside the Sun.
    pub moon: bool,
    /// Number of run wavelengths.
    pub wavelengths: usize,
    /// Thermal emission (`emission = true`).
    pub emission: bool,
    /// The run has an atmosphere (layers at some wavelength; `type = "none"` has none).
    pub atmosphere: bool,
    /// Some measure is an image (ortho or perspective).
    pub images: bool,
    /// Several sensor bands (`spectral.bands`): their nodes are walked as channels of grouped
    /// walks (`spectral/bands.rs`), in CKD mode too.
    pub bands: bool,
    /// One sensor band (`spectral.srf`): its wavelengths' errors are combined in quadrature,
    /// so they must be independent walks.
    pub srf: bool,
}

impl RunShape {
    /// A 3D scene without an atmosphere (canopies): after the first interaction only other
    /// surfaces light a path. The `rr_depth` and `sampler` defaults were measured for it.
    pub fn canopy_like(&self) -> bool {
        self.scene && !self.atmosphere
    }
}

impl IntegratorSettings {
    /// Turn off ALIS walks that `spectral_walk = "auto"` chose, where a later check finds them
    /// unsupported; `false` (nothing changed) when they were asked for explicitly (the caller
    /// then reports the error) or are off.
    pub fn drop_auto_alis(&mut self) -> bool {
        if self.spectral_alis_auto && self.spectral_alis.is_some() {
            self.spectral_alis = None;
            self.spectral_alis_auto = false;
            true
        } else {
            false
        }
    }

    /// The settings of `cfg` for a run of shape `run`; errors name `integrator.…` (or the
    /// measure a forward walk cannot serve).
    pub fn from_config(
        ctx: &ConfigCtx,
        cfg: &IntegratorConfig,
        run: RunShape,
    ) -> Result<Self, ConfigError> {
        let kind = cfg.kind;
        if run.spherical && kind == IntegratorKind::Forward {
            return Err(ctx.err(
                "integrator.type",
                "spherical-shell atmospheres use the backward walk (\"auto\" or \"backward\")",
            ));
        }
        if kind == IntegratorKind::Forward {
            if let Some(im) = run.radiancemeter {
                return Err(ctx.err(format!("measures[{im}]"), "radiancemeters and hdrf measures need the backward integrator (`integrator.type = \"backward\"` or \"auto\")"));
            }
        }
        if run.scene && kind == IntegratorKind::Forward {
            return Err(ctx.err(
                "integrator.type",
                "3D scenes use the backward walk (\"auto\" or \"backward\")",
            ));
        }
        let max_depth = match cfg.max_depth {
            Some(0) => return Err(ctx.err("integrator.max_depth", "must be at least 1")),
            Some(d) => d,
            None => u32::MAX,
        };
        let alis = match cfg.ckd_walk {
            CkdWalk::Cycle => false,
            CkdWalk::Alis => {
                let key = "integrator.ckd_walk";
                if !run.ckd {
                    return Err(ctx.err(
                        key,
                        "is used only with mode = \"ckd\" (monochromatic runs: integrator.spectral_walk = \"alis\")",
                    ));
                }
                if run.polarized || run.spherical || run.scene {
                    return Err(ctx.err(
                        key,
                        "\"alis\" is implemented for scalar plane-parallel 1D runs only",
                    ));
                }
                if kind == IntegratorKind::Forward {
                    return Err(ctx.err(
                        key,
                        "\"alis\" is a backward walk (integrator.type \"auto\" or \"backward\")",
                    ));
                }
                true
            }
        };
        let walk = match cfg.spectral_walk {
            SpectralWalk::Auto => SpectralWalk::resolve_auto(&run, kind),
            w => w,
        };
        let spectral_alis = match walk {
            SpectralWalk::Auto | SpectralWalk::Independent => None,
            SpectralWalk::Alis => {
                let key = "integrator.spectral_walk";
                if run.srf {
                    return Err(ctx.err(
                        key,
                        "\"alis\" would correlate the wavelengths of an `srf` band, whose errors are combined as independent: use `spectral.bands = [...]` for grouped walks over sensor bands",
                    ));
                }
                if run.ckd && !run.bands {
                    return Err(ctx.err(
                        key,
                        "is used only with mode = \"mono\" (CKD bins: integrator.ckd_walk = \"alis\")",
                    ));
                }
                if run.polarized {
                    return Err(ctx.err(
                        key,
                        "\"alis\" is scalar only (polarized = true is not supported)",
                    ));
                }
                if run.spherical {
                    return Err(ctx.err(
                        key,
                        "\"alis\" is plane-parallel only (not for spherical-shell geometry)",
                    ));
                }
                if kind == IntegratorKind::Forward {
                    return Err(ctx.err(
                        key,
                        "\"alis\" is a backward walk (integrator.type \"auto\" or \"backward\", not \"forward\")",
                    ));
                }
                // A walk through a 3D scene carries fewer wavelengths (`scene_alis.rs`).
                let most = if run.scene {
                    SCENE_CHANNELS
                } else {
                    MAX_CHANNELS
                };
                Some(match cfg.alis_group {
                    None => most.min(32),
                    Some(n) if run.scene && n > most => {
                        return Err(ctx.err(
                            "integrator.alis_group",
                            format!("{n} wavelengths per group: a walk through a 3D scene carries at most {most}"),
                        ))
                    }
                    Some(n) if (1..=most).contains(&n) => n,
                    Some(n) => {
                        return Err(ctx.err(
                            "integrator.alis_group",
                            format!("{n} wavelengths per group: must lie in 1 … 64"),
                        ))
                    }
                })
            }
        };
        if spectral_alis.is_none() && cfg.alis_group.is_some() {
            return Err(ctx.err(
                "integrator.alis_group",
                "is used only with integrator.spectral_walk = \"alis\"",
            ));
        }
        let detector_sampling = match cfg.detector_sampling {
            None => DETECTOR_SAMPLING,
            Some(e) if (0.0..=0.5).contains(&e) => e,
            Some(e) => {
                return Err(ctx.err(
                    "integrator.detector_sampling",
                    format!("{e} must lie in 0 … 0.5 (the share of scatterings drawn towards the detector directions; 0 turns it off)"),
                ))
            }
        };
        let forced_flights = match cfg.forced_flights {
            None => FORCED_FLIGHTS,
            Some(n) if n <= 4 => n,
            Some(n) => {
                return Err(ctx.err(
                    "integrator.forced_flights",
                    format!("{n} must lie in 0 … 4 (a path splits into up to 2^N branches)"),
                ))
            }
        };
        let first_order_splits = match cfg.first_order_splits {
            None => 1,
            Some(n) if (1..=MAX_FIRST_ORDER_SPLITS).contains(&n) => n,
            Some(n) => {
                return Err(ctx.err(
                    "integrator.first_order_splits",
                    format!("{n} must lie in 1 … {MAX_FIRST_ORDER_SPLITS} (first-order walks per sample; 1 turns splitting off)"),
                ))
            }
        };
        if first_order_splits > 1 {
            let key = "integrator.first_order_splits";
            if kind == IntegratorKind::Forward {
                return Err(ctx.err(
                    key,
                    "splits the first order of backward walks (integrator.type \"auto\" or \"backward\", not \"forward\")",
                ));
            }
            if run.polarized {
                return Err(ctx.err(
                    key,
                    "is scalar only: a polarized path's Q, U and V are not split by scattering order (polarized = true)",
                ));
            }
            // Which measures walk backward (as `blocks::method_for` decides): with "auto", a 1D
            // plane-parallel run of distant measures walks forward and would ignore the key.
            let backward = kind == IntegratorKind::Backward
                || run.scene
                || run.spherical
                || run.moon
                || alis
                || spectral_alis.is_some()
                || run.radiancemeter.is_some();
            if !backward {
                return Err(ctx.err(
                    key,
                    "no measure of this run is walked backward (1D distant measures walk forward with integrator.type = \"auto\"): set integrator.type = \"backward\" or leave the key out",
                ));
            }
        }
        let sampler = cfg.sampler.resolve_auto(&run);
        Ok(IntegratorSettings {
            first_order_splits,
            lamp_sampling: cfg.lamp_sampling,
            above_scene: cfg.above_scene,
            forced_flights,
            replicates: sampler == Sampler::Sobol,
            surface_solver: Default::default(),
            sampler,
            detector_sampling,
            spectral_alis,
            spectral_alis_auto: cfg.spectral_walk == SpectralWalk::Auto && spectral_alis.is_some(),
            kind,
            max_depth,
            rr_depth: cfg.rr_depth.unwrap_or(if run.canopy_like() {
                // A scene without an atmosphere (canopies): after the first interaction only
                // other surfaces light a path, and roulette from the second order costs little
                // variance where paths are dark: HOM at 550 nm 2.9× the efficiency (its
                // multiple scattering is 3 % of the BRF), HET01's bright leaves 1.16×
                // (BENCHMARKS.md, "Canopies").
                1
            } else {
                RR_DEPTH
            }),
            expected_local_estimate: cfg.local_estimate == LocalEstimate::Expected,
            alis,
            first_check_spp: match cfg.first_check_spp {
                Some(n) if n < 64 => {
                    return Err(ctx.err(
                        "integrator.first_check_spp",
                        format!(
                            "{n} is too few samples to estimate a standard error (at least 64)"
                        ),
                    ))
                }
                other => other,
            },
        })
    }

    /// The member of a spectral ALIS group (its wavelengths' atmospheres `atms`, ascending in
    /// wavelength) whose scattering and phase functions the group's reference takes: the
    /// central one in 1D runs (groups of neighbouring wavelengths, `backward_alis.rs`); in 3D
    /// scenes (`scene_alis.rs`), whose groups span the visible, the one with the largest
    /// scattering optical thickness, so that the other wavelengths' path factors shrink at
    /// collisions instead of growing (measured on the README render: the 440 nm error of a
    /// 440/550/660 nm group was 2.55 % with the 550 nm reference and 2.11 % with the 440 nm
    /// one, as independent walks give; BENCHMARKS.md).
    pub fn reference_member(atms: &[&PlaneParallel], scene: bool) -> usize {
        if !scene {
            return atms.len() / 2;
        }
        let scattering = |a: &PlaneParallel| -> f64 {
            let t: Vec<(f64, f64)> = a.boundaries().collect();
            (0..t.len() - 1)
                .map(|i| a.albedo(i) * (t[i + 1].1 - t[i].1))
                .sum()
        };
        let mut best = 0;
        let mut most = f64::NEG_INFINITY;
        for (i, a) in atms.iter().enumerate() {
            let s = scattering(a);
            if s > most {
                best = i;
                most = s;
            }
        }
        best
    }

    /// CKD: the ALIS walk carries at most 64 g-points per bin (`ng` in this run's data).
    pub fn check_g_points(&self, ctx: &ConfigCtx, ng: usize) -> Result<(), ConfigError> {
        if ng > 64 && self.alis {
            return Err(ctx.err(
                "integrator.ckd_walk",
                format!("\"alis\" handles at most 64 g-points per bin (this file has {ng})"),
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shape(scene: bool, atmosphere: bool, images: bool) -> RunShape {
        RunShape {
            ckd: false,
            polarized: false,
            spherical: false,
            scene,
            radiancemeter: None,
            moon: false,
            wavelengths: 1,
            emission: false,
            atmosphere,
            images,
            bands: false,
            srf: false,
        }
    }

    fn settings(text: &str, run: RunShape) -> IntegratorSettings {
        let cfg: IntegratorConfig = toml::from_str(text).expect("integrator table");
        let ctx = ConfigCtx {
            path: std::path::Path::new("exp.toml"),
            base: std::path::Path::new("."),
            nw: 1,
            wavelengths: &[550.0],
        };
        IntegratorSettings::from_config(&ctx, &cfg, run).expect("valid settings")
    }

    /// Rationale: the defaults that depend on the run. `sampler = "auto"` is Sobol (with its
    /// replicate sums) for 3D scenes without atmosphere or images and Philox otherwise;
    /// `rr_depth` is 1 in
    /// scenes without an atmosphere and 5 elsewhere; explicit values win in every case.
    #[test]
    fn run_dependent_defaults() {
        let cases = [
            // (scene, atmosphere, images, sampler, rr_depth)
            (false, true, false, Sampler::Random, RR_DEPTH),
            (false, false, false, Sampler::Random, RR_DEPTH),
            (true, true, false, Sampler::Random, RR_DEPTH),
            (true, false, false, Sampler::Sobol, 1),
            (true, true, true, Sampler::Random, RR_DEPTH),
            (true, false, true, Sampler::Random, 1),
        ];
        for (scene, atmosphere, images, sampler, rr) in cases {
            let s = settings("", shape(scene, atmosphere, images));
            let case = format!("scene {scene}, atmosphere {atmosphere}, images {images}");
            assert_eq!(s.sampler, sampler, "{case}");
            assert_eq!(s.replicates, sampler == Sampler::Sobol, "{case}");
            assert_eq!(s.rr_depth, rr, "{case}");
            let explicit = settings(
                "sampler = \"random\"\nrr_depth = 7",
                shape(scene, atmosphere, images),
            );
            assert_eq!(explicit.sampler, Sampler::Random, "{case}");
            assert!(!explicit.replicates, "{case}");
            assert_eq!(explicit.rr_depth, 7, "{case}");
            let sobol = settings("sampler = \"sobol\"", shape(scene, atmosphere, images));
            assert_eq!(sobol.sampler, Sampler::Sobol, "{case}");
        }
    }
}
