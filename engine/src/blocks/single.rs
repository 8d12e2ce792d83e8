//! Blocks of one wavelength: CKD g-points (one per block, or all of a bin in ALIS walks), and
//! the one place where a single wavelength's estimator (forward or backward), geometry
//! (layers, shells, a scene in either) and weight (scalar or polarized) are chosen.

use crate::accum::{Accum, Method};
use crate::config::resolve::Experiment;
use crate::integrator::backward::{Adjoint, AtSensor};
use crate::integrator::forward::{self, ForwardTargets, Photon};
use crate::integrator::geometry::layers::Layers;
use crate::integrator::geometry::scene_clouds::SceneCloudsInLayers;
use crate::integrator::geometry::scene_layers::LampLight;
use crate::integrator::geometry::scene_shells::SceneInShells;
use crate::integrator::geometry::shells::Shells;
use crate::integrator::weight::{MuellerPath, Scalar, StokesPhoton};
use crate::optics::OpticalState;
use crate::sensor;

use super::method_for;
use super::streams::SampleStreams;
use super::walks::{backward_block, channel_walks, scene_in_layers, sun_and_moon, sun_clearance};

/// Run the samples `range` of measure `im` at wavelength `iw` (one block). In CKD runs block
/// `b` uses g-point `b mod N_g` and its samples are weighted by `w_g·N_g`: with whole cycles of
/// blocks (guaranteed by the round sizes) the mean is Σ_g w_g·R_g, unbiased; the pooled
/// variance over-estimates that of the stratified mean (honest, slightly pessimistic errors).
/// `alis_layers`: the ALIS layer tables of this bin ([`alis_layers`]), built once per task.
pub(super) fn run_block(
    exp: &Experiment,
    iw: usize,
    im: usize,
    cell: usize,
    range: std::ops::Range<u64>,
    alis_layers: Option<&crate::integrator::backward_alis::Layers>,
) -> Accum {
    let base = &exp.optics[iw];
    if base.g_states.is_empty() {
        return run_block_at(exp, base, iw, im, cell, range);
    }
    if let Some(layers) = alis_layers {
        return run_block_alis(exp, base, layers, iw, im, cell, range);
    }
    let ng = base.g_states.len();
    let b = range.start / exp.measures[im].block_size();
    let (w, opt) = &base.g_states[(b % ng as u64) as usize];
    let mut acc = run_block_at(exp, opt, iw, im, cell, range);
    acc.scale(w * ng as f64);
    acc
}

/// The ALIS layer tables of CKD bin `iw` in ALIS runs (None otherwise). The reference is the
/// bin's atmosphere without gas absorption (scattering and particle absorption only), so every
/// g-point's path factor is a pure gas transmittance.
pub(super) fn alis_layers(
    exp: &Experiment,
    iw: usize,
) -> Option<crate::integrator::backward_alis::Layers> {
    let base = &exp.optics[iw];
    if !exp.integrator.alis || base.g_states.is_empty() {
        return None;
    }
    let atms: Vec<&crate::atmosphere::PlaneParallel> =
        base.g_states.iter().map(|(_, o)| &o.atmosphere).collect();
    Some(crate::integrator::backward_alis::Layers::new(
        &base.atmosphere,
        &atms,
    ))
}

/// A block of ALIS walks: every walk carries all g-points of the bin.
#[allow(clippy::too_many_arguments)]
pub(super) fn run_block_alis(
    exp: &Experiment,
    base: &OpticalState,
    layers: &crate::integrator::backward_alis::Layers,
    iw: usize,
    im: usize,
    cell: usize,
    range: std::ops::Range<u64>,
) -> Accum {
    use crate::integrator::backward_alis::{Channels, Kind};
    let weights: Vec<f64> = base.g_states.iter().map(|(w, _)| *w).collect();
    let atms: Vec<&crate::atmosphere::PlaneParallel> =
        base.g_states.iter().map(|(_, o)| &o.atmosphere).collect();
    let surface_emission: Vec<&crate::bsdf::SurfaceEmission> = base
        .g_states
        .iter()
        .filter_map(|(_, o)| o.surface_emission.as_ref())
        .collect();
    assert!(
        surface_emission.is_empty() || surface_emission.len() == atms.len(),
        "every g-point's surface emits, or none"
    );
    let g = Channels {
        atms: &atms,
        reference: &base.atmosphere,
        layers,
        kind: Kind::GPoints {
            weights: &weights,
            surface: &base.surface,
            surface_emission: &surface_emission,
        },
    };
    let mut acc = Accum::new(g.outputs());
    channel_walks(
        &mut acc,
        exp,
        &g,
        iw as u64,
        &[exp.moon_ratio(iw)],
        im,
        cell,
        range,
        None,
    );
    acc
}

pub(super) fn run_block_at(
    exp: &Experiment,
    opt: &OpticalState,
    iw: usize,
    im: usize,
    cell: usize,
    range: std::ops::Range<u64>,
) -> Accum {
    if exp.polarized {
        run_block_with::<StokesPhoton, MuellerPath>(exp, opt, iw, im, cell, range)
    } else {
        run_block_with::<Scalar, Scalar>(exp, opt, iw, im, cell, range)
    }
}

/// A block of one measure at one optical state, with photon weight `F` for forward walks and
/// path weight `B` for backward walks (the one place where the estimator, the geometry and the
/// weight are chosen; everything below is monomorphised).
pub(super) fn run_block_with<F: Photon, B: Adjoint + AtSensor>(
    exp: &Experiment,
    opt: &OpticalState,
    iw: usize,
    im: usize,
    cell: usize,
    range: std::ops::Range<u64>,
) -> Accum {
    let m = &exp.measures[im];
    let ids = [iw as u64, im as u64, cell as u64];
    let settings = &exp.integrator;
    let stream = SampleStreams::new(exp, ids);
    let hint = || sensor::frame_azimuth(m, cell);
    let at_sensor = |d0| B::at_sensor(d0, hint);
    let ratio = [exp.moon_ratio(iw)];
    match method_for(exp, m) {
        Method::Forward => {
            let (dirs, flux, hints) = sensor::forward_targets(m, opt);
            let targets = ForwardTargets {
                directions: &dirs,
                flux,
                azimuth_hints: &hints,
            };
            let mut acc = F::accum(m.cell_count());
            let thermal = exp.emission.then(|| {
                forward::ThermalSources::new(
                    &opt.atmosphere,
                    opt.surface_emission.as_ref(),
                    &dirs,
                    exp.mu_norm(),
                )
            });
            forward::run_block::<F>(
                &opt.atmosphere,
                &opt.surface,
                exp.sun_dir,
                &targets,
                settings,
                exp.seed,
                ids,
                range,
                &mut acc,
                thermal.as_ref(),
                exp.sun_shines,
            );
            acc
        }
        Method::Scene => {
            let scene = exp.scene.as_ref().expect("scene method without a scene");
            if let Some(shell) = &opt.shell {
                let (g, moon) = sun_and_moon(exp, ids, &ratio, |sun| SceneInShells {
                    shell,
                    scene,
                    models: &opt.scene_models,
                    sun,
                    clearance: sun_clearance(exp, scene, sun),
                    mu_norm: exp.mu_norm(),
                    wavelength: opt.wavelength,
                    emission: opt.scene_emission.as_ref(),
                    shines: exp.sun_shines,
                });
                backward_block::<_, B>(
                    &g,
                    moon.as_ref(),
                    settings,
                    1,
                    range,
                    stream,
                    |rng| sensor::scene_start_sph(&g, m, cell, rng).map(|(p, l, d)| ((p, l), d)),
                    |_, d0| at_sensor(d0),
                    |_, _| {},
                )
            } else if let Some(clouds) = &exp.clouds {
                let (g, moon) = sun_and_moon(exp, ids, &ratio, |sun| SceneCloudsInLayers {
                    base: scene_in_layers(exp, sun, &opt.atmosphere, opt, None),
                    clouds,
                    phases: &clouds.phases[iw],
                });
                backward_block::<_, B>(
                    &g,
                    moon.as_ref(),
                    settings,
                    1,
                    range,
                    stream,
                    |rng| Some(sensor::scene_start(&g.base, m, cell, rng)),
                    |_, d0| at_sensor(d0),
                    |_, _| {},
                )
            } else {
                let (mut g, moon) = sun_and_moon(exp, ids, &ratio, |sun| {
                    scene_in_layers(exp, sun, &opt.atmosphere, opt, opt.scene_emission.as_ref())
                });
                // Lamps light the Sun's walks only, not the Moon's beside them.
                // Forward photons carry the point lamps of nadir ortho images
                // (`blocks/lamp_photons.rs`).
                let points = exp.lamp_photon_pixels(m).is_none();
                g.lamps = exp.lamps.as_deref().map(|lamps| LampLight {
                    lamps,
                    iw,
                    scale: 1.0 / opt.irradiance,
                    points,
                });
                backward_block::<_, B>(
                    &g,
                    moon.as_ref(),
                    settings,
                    1,
                    range,
                    stream,
                    |rng| Some(sensor::scene_start(&g, m, cell, rng)),
                    |_, d0| at_sensor(d0),
                    |_, _| {},
                )
            }
        }
        Method::Backward => {
            if let Some(shell) = &opt.shell {
                let (g, moon) = sun_and_moon(exp, ids, &ratio, |sun| Shells {
                    shell,
                    surface: &opt.surface,
                    sun,
                    mu_norm: exp.mu_norm(),
                    solver: settings.surface_solver,
                    surface_emission: opt.surface_emission.as_ref(),
                    shines: exp.sun_shines,
                });
                backward_block::<_, B>(
                    &g,
                    moon.as_ref(),
                    settings,
                    1,
                    range,
                    stream,
                    |rng| sensor::spherical_start(shell, m, cell, rng).map(|(p, l, d)| ((p, l), d)),
                    |_, d0| at_sensor(d0),
                    |_, _| {},
                )
            } else {
                let (g, moon) = sun_and_moon(exp, ids, &ratio, |sun| {
                    Layers::new(&opt.atmosphere, &opt.surface, sun)
                        .with_emission(opt.surface_emission.as_ref(), exp.sun_shines)
                        .with_solver(settings.surface_solver)
                });
                backward_block::<_, B>(
                    &g,
                    moon.as_ref(),
                    settings,
                    1,
                    range,
                    stream,
                    |rng| Some(sensor::backward_start(opt, m, cell, rng)),
                    |_, d0| at_sensor(d0),
                    |_, _| {},
                )
            }
        }
    }
}
