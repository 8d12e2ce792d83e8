//! Lidar measures of a run (`engine::lidar`): every shot traced, photon-counting statistics and
//! events, discrete returns (their products: `products/lidar.rs`).

use engine::config::resolve::Experiment;
use engine::lidar::counting::{self, CountingStats, PhotonEvent};
use engine::lidar::trace::{trace_shot, ShotWaveform, Stat, World, FIRST_GROUND, TOTAL};
use engine::lidar::{Lidar, LidarMode, LidarResult};
use engine::scene::material::SurfaceModel;

/// Lines of sight per footprint that class discrete returns by the surfaces they come from.
const CLASS_SAMPLES: u64 = 4096;
/// Passive samples per footprint for the solar background's radiance.
const BACKGROUND_SPP: u64 = 16_384;

/// The passive radiance (W m⁻² sr⁻¹ nm⁻¹) the receiver of shot `k` sees, by the run's own
/// passive estimators (every order, the air's path radiance included): a radiancemeter at the
/// sensor looking along the beam over a 1D ground, or over a scene the radiance leaving the
/// square around the field of view (at the scene's top, along the line of sight) towards the
/// sensor (an `mdistant` with a target area).
pub fn passive_radiance(exp: &Experiment, lidar: &Lidar, k: usize) -> Stat {
    use engine::measure::{Area, Measure, MeasureKind};
    let c = lidar.shots[k];
    let kind = match exp.scene.as_deref() {
        Some(sc) => {
            let top = sc.z_range[1];
            let at = c + lidar.to_sensor * ((top - c.z) / lidar.to_sensor.z);
            let r = lidar.range0(c) * lidar.fov_half_angle.tan();
            MeasureKind::Distant {
                directions: vec![lidar.to_sensor],
                vza: vec![lidar.zenith_deg],
                vaa: vec![lidar.azimuth_deg],
                area: Some(Area {
                    rect: [at.x - r, at.y - r, at.x + r, at.y + r],
                    height: top,
                    mask: None,
                }),
            }
        }
        None => MeasureKind::Radiancemeter {
            origin: lidar.sensor(c),
            look: -lidar.to_sensor,
            frame_azimuth: 0.0,
        },
    };
    let mut e2 = exp.clone();
    e2.measures.push(Measure {
        id: format!("{}_background", lidar.id),
        spp: BACKGROUND_SPP,
        target_rel_stderr: None,
        target_scale: Vec::new(),
        target_fraction: 1.0,
        adaptive: false,
        kind,
        block_override: None,
    });
    let im = e2.measures.len() - 1;
    let res = crate::run::run_measure(&e2, lidar.iw, im, &indicatif::ProgressBar::hidden());
    // The tally is in units of E0·cos SZA / π of radiance (as the products convert it).
    let (t, te) = res.acc.mean_stderr(0, 0);
    let to_rad = exp.optics[lidar.iw].irradiance * exp.mu_norm() / std::f64::consts::PI;
    Stat {
        mean: t * to_rad,
        stderr: te * to_rad,
    }
}

/// One shot's photon-counting statistics and simulated photons.
type Counted = (CountingStats, Vec<PhotonEvent>);

/// Run every lidar measure of `exp`.
pub fn run_all(exp: &Experiment, progress: bool) -> Vec<LidarResult> {
    exp.lidars
        .iter()
        .map(|l| run_one(exp, l, progress))
        .collect()
}

/// Run one lidar measure.
pub fn run_one(exp: &Experiment, lidar: &Lidar, progress: bool) -> LidarResult {
    let optics = &exp.optics[lidar.iw];
    let world = World {
        atmosphere: match &optics.shell {
            Some(shell) => engine::lidar::air::Air::Shells(shell),
            None => engine::lidar::air::Air::Layers(&optics.atmosphere),
        },
        has_air: optics.atmosphere.total_tau() > 0.0,
        scene: exp.scene.as_deref(),
        models: &optics.scene_models,
        ground: SurfaceModel::Opaque(optics.surface.clone()),
        ground_z: optics.atmosphere.ground(),
    };
    let t0 = std::time::Instant::now();
    let bar = progress.then(|| {
        let b = indicatif::ProgressBar::new(lidar.shots.len() as u64);
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "{prefix:>16} lidar [{bar:30}] {pos}/{len} shots {elapsed}<{eta}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        b.set_prefix(lidar.id.clone());
        b
    });
    // Shots in parallel (each shot's photon blocks too): every shot's result depends only on
    // its own streams, so the order of work does not matter.
    use rayon::prelude::*;
    let per_shot: Vec<(ShotWaveform, Option<Counted>)> = (0..lidar.shots.len())
        .into_par_iter()
        .map(|k| {
            let w = trace_shot(lidar, &world, exp.seed, k);
            let counted = (lidar.mode == LidarMode::PhotonCounting).then(|| {
                let bg = if exp.sun_up() && lidar.filter_width_nm > 0.0 {
                    let l_bg = passive_radiance(exp, lidar, k);
                    counting::background_from_radiance(lidar, l_bg)
                } else {
                    Stat::default()
                };
                let st = counting::stats(lidar, &w, k, bg);
                let ev = counting::simulate_shots(lidar, &st, exp.seed, k);
                (st, ev)
            });
            if let Some(b) = &bar {
                b.inc(1);
            }
            (w, counted)
        })
        .collect();
    let mut shots = Vec::with_capacity(per_shot.len());
    let mut stats = Vec::new();
    let mut events = Vec::new();
    for (w, counted) in per_shot {
        shots.push(w);
        if let Some((st, ev)) = counted {
            stats.push(st);
            events.extend(ev);
        }
    }
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    tracing::info!(
        "lidar `{}`: {} shot(s), {} photon paths in all, in {:.2} s",
        lidar.id,
        lidar.shots.len(),
        shots.iter().map(|w| w.photons).sum::<u64>(),
        t0.elapsed().as_secs_f64()
    );
    let returns = if lidar.mode == LidarMode::Discrete {
        use engine::lidar::discrete::{self, GROUND, UNCLASSIFIED};
        use rayon::prelude::*;
        shots
            .par_iter()
            .enumerate()
            .map(|(k, w)| {
                let total: Vec<f64> = w.bins.iter().map(|b| b[TOTAL].mean).collect();
                let ground: Vec<f64> = w.bins.iter().map(|b| b[FIRST_GROUND].mean).collect();
                let rets = discrete::detect(
                    &total,
                    &ground,
                    lidar.bins.first_ns,
                    lidar.bins.width_ns,
                    lidar.detect_threshold,
                    lidar.min_separation_ns,
                    lidar.max_returns,
                );
                let samples =
                    discrete::first_order_classes(lidar, &world, exp.seed, k, CLASS_SAMPLES);
                rets.into_iter()
                    .map(|r| {
                        let fallback = if r.ground_share > 0.5 {
                            GROUND
                        } else {
                            UNCLASSIFIED
                        };
                        (r, discrete::class_in(&samples, r.window_ns, fallback))
                    })
                    .collect()
            })
            .collect()
    } else {
        Vec::new()
    };
    LidarResult {
        lidar: lidar.clone(),
        shots,
        counting: stats,
        events,
        returns,
        georef: exp.scene.as_ref().and_then(|s| s.georef.clone()),
    }
}
