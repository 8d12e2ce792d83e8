//! The run driver: for every wavelength and measure, split the samples into fixed blocks, run
//! them in parallel with rayon and merge the blocks' sums **in block order**. Block boundaries
//! and random streams depend only on sample indices, so the result is bit-identical for any
//! thread count.

use std::sync::atomic::{AtomicBool, Ordering};

use glam::DVec3;
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;

use crate::config::resolve::Experiment;
use crate::integrator::backward::{self, Adjoint, AtSensor};
use crate::integrator::backward_alis::{ChannelPath, ReferenceLayers};
use crate::integrator::forward::{self, ForwardTargets, Photon};
use crate::integrator::geometry::layers::Layers;
use crate::integrator::geometry::scene_layers::SceneInLayers;
use crate::integrator::geometry::scene_shells::SceneInShells;
use crate::integrator::geometry::shells::Shells;
use crate::integrator::geometry::Geometry;
use crate::integrator::scene_alis::SceneChannelTally;
use crate::integrator::settings::{IntegratorKind, IntegratorSettings};
use crate::integrator::weight::Weight;
use crate::integrator::weight::{MuellerPath, Scalar, StokesPhoton};
use crate::integrator::Accum;
use crate::measure::{Measure, MeasureKind};
use crate::optics::OpticalState;
use crate::rng::Stream;
use crate::sensor;

pub use crate::accum::{MeasureResult, Method};

pub fn method_for(exp: &Experiment, m: &Measure) -> Method {
    if exp.scene.is_some() {
        return Method::Scene;
    }
    if exp.planet_radius.is_some() || exp.moon.is_some() {
        return Method::Backward;
    }
    if exp.integrator.alis || exp.integrator.spectral_alis.is_some() {
        return Method::Backward;
    }
    match (exp.integrator.kind, &m.kind) {
        (_, MeasureKind::Radiancemeter { .. } | MeasureKind::Hdrf { .. }) => Method::Backward,
        (IntegratorKind::Backward, _) => Method::Backward,
        _ => Method::Forward,
    }
}

/// Run the samples `range` of measure `im` at wavelength `iw` (one block). In CKD runs block
/// `b` uses g-point `b mod N_g` and its samples are weighted by `w_g·N_g`: with whole cycles of
/// blocks (guaranteed by the round sizes) the mean is Σ_g w_g·R_g, unbiased; the pooled
/// variance over-estimates that of the stratified mean (honest, slightly pessimistic errors).
/// `alis_layers`: the ALIS layer tables of this bin ([`alis_layers`]), built once per task.
fn run_block(
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
fn alis_layers(exp: &Experiment, iw: usize) -> Option<crate::integrator::backward_alis::Layers> {
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
fn run_block_alis(
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
    channel_walks(exp, &g, iw as u64, &[exp.moon_ratio(iw)], im, cell, range)
}

/// Backward walks over channels `g` (one accumulator cell per output: the bin mean, or one per
/// wavelength), stream family `key`; `moon_ratio`: E_moon/E_sun per output (used with the Moon
/// beside the Sun).
#[allow(clippy::too_many_arguments)]
fn channel_walks(
    exp: &Experiment,
    g: &crate::integrator::backward_alis::Channels,
    key: u64,
    moon_ratio: &[f64],
    im: usize,
    cell: usize,
    range: std::ops::Range<u64>,
) -> Accum {
    let m = &exp.measures[im];
    let toa = g.reference.toa();
    let ids = [key, im as u64, cell as u64];
    let (geometry, moon) = sun_and_moon(exp, ids, moon_ratio, |dir| {
        ReferenceLayers::new(g, dir).with_sun_shining(exp.sun_shines)
    });
    backward_block(
        &geometry,
        moon.as_ref(),
        &exp.integrator,
        g.outputs(),
        range,
        SampleStreams::new(exp, ids),
        |rng| Some(sensor::backward_start_altitude(toa, m, cell, rng)),
        |g, _| ChannelPath::new(g),
        |_, _| {},
    )
}

/// Tag of the Moon's random streams when it shines beside the Sun: its walks are independent of
/// the Sun's.
const MOON_STREAM: u64 = 1 << 61;

/// The Moon's half of every sample when it shines beside the Sun (`illumination.moon`): the
/// same medium lit from the Moon's direction, E_moon/E_sun per accumulator cell (the factor that
/// brings a Moon-lit score into the Sun's units: a score is radiance per unit irradiance) and
/// the Moon's random streams.
struct MoonWalks<'a, G> {
    g: G,
    ratio: Vec<f64>,
    stream: Box<dyn Fn(u64) -> Stream + 'a>,
}

/// The walks keyed `ids`: the geometry lit from the Sun, `lit_from(Sun direction)`, and when the
/// experiment has a Moon beside the Sun its [`MoonWalks`] in `lit_from(Moon direction)`
/// (`ratio`: E_moon/E_sun per accumulator cell).
fn sun_and_moon<'a, G>(
    exp: &'a Experiment,
    ids: [u64; 3],
    ratio: &[f64],
    lit_from: impl Fn(DVec3) -> G,
) -> (G, Option<MoonWalks<'a, G>>) {
    let moon = exp.moon.as_ref().map(|moon| MoonWalks {
        g: lit_from(moon.dir),
        ratio: ratio.to_vec(),
        stream: Box::new(sample_stream(exp, [ids[0] | MOON_STREAM, ids[1], ids[2]])),
    });
    (lit_from(exp.sun_dir), moon)
}

/// Tag of the random streams of spectral ALIS groups (keyed by the group's first wavelength
/// index), apart from those of single wavelengths.
const GROUP_STREAM: u64 = 1 << 62;

/// What the walks of a spectral ALIS group share: the reference atmosphere (the group's
/// central wavelength's scattering with the group's least absorption) and the layer tables,
/// built once per task.
struct SpectralGroup {
    reference: crate::atmosphere::PlaneParallel,
    layers: crate::integrator::backward_alis::Layers,
    /// The member of the group whose scattering the reference has
    /// ([`IntegratorSettings::reference_member`](crate::integrator::settings::IntegratorSettings::reference_member)).
    reference_member: usize,
}

impl SpectralGroup {
    fn new(exp: &Experiment, group: &[usize]) -> Self {
        let atms: Vec<&crate::atmosphere::PlaneParallel> =
            group.iter().map(|&iw| &exp.optics[iw].atmosphere).collect();
        let reference_member = crate::integrator::settings::IntegratorSettings::reference_member(
            &atms,
            exp.scene.is_some(),
        );
        let reference =
            crate::integrator::backward_alis::group_reference(atms[reference_member], &atms);
        let layers = crate::integrator::backward_alis::Layers::spectral(&reference, &atms);
        SpectralGroup {
            reference,
            layers,
            reference_member,
        }
    }
}

/// `f` of the channels of wavelength group `group` (its atmospheres, reference and layer
/// tables, surfaces).
fn with_channels<R>(
    exp: &Experiment,
    sg: &SpectralGroup,
    group: &[usize],
    f: impl FnOnce(&crate::integrator::backward_alis::Channels) -> R,
) -> R {
    use crate::integrator::backward_alis::{Channels, Kind};
    let atms: Vec<&crate::atmosphere::PlaneParallel> =
        group.iter().map(|&iw| &exp.optics[iw].atmosphere).collect();
    let surfaces: Vec<&crate::bsdf::Bsdf> =
        group.iter().map(|&iw| &exp.optics[iw].surface).collect();
    f(&Channels {
        atms: &atms,
        reference: &sg.reference,
        layers: &sg.layers,
        kind: Kind::Wavelengths {
            surfaces: &surfaces,
            reference_surface: &exp.optics[group[sg.reference_member]].surface,
        },
    })
}

/// A block of spectral ALIS walks: every walk carries all wavelengths of `group` (one
/// accumulator per wavelength). `pool`: the above-scene pool of a pooled ortho image
/// (`integrator/above_scene.rs`), entry `s` for sample `s`; None for whole walks.
#[allow(clippy::too_many_arguments)]
fn run_block_spectral(
    exp: &Experiment,
    sg: &SpectralGroup,
    group: &[usize],
    im: usize,
    cell: usize,
    range: std::ops::Range<u64>,
    pool: Option<&[SceneChannelTally]>,
) -> Vec<Accum> {
    let key = GROUP_STREAM | group[0] as u64;
    // One cell per wavelength of the group, split into one accumulator each.
    let ratio: Vec<f64> = group.iter().map(|&iw| exp.moon_ratio(iw)).collect();
    let all = with_channels(exp, sg, group, |g| match &exp.scene {
        Some(_) => scene_channel_walks(
            exp,
            g,
            sg.reference_member,
            group,
            key,
            &ratio,
            im,
            cell,
            range,
            pool,
        ),
        None => channel_walks(exp, g, key, &ratio, im, cell, range),
    });
    (0..group.len())
        .map(|c| {
            let mut a = Accum::new(1);
            a.merge_cell(0, &all, c);
            a
        })
        .collect()
}

/// Backward walks of a 3D scene in plane-parallel layers over the wavelengths `group`
/// (channels `g`, whose reference is member `reference` of the group; `scene_alis.rs`): one
/// accumulator cell per wavelength; `moon_ratio`: E_moon/E_sun per wavelength (used with the
/// Moon beside the Sun).
#[allow(clippy::too_many_arguments)]
fn scene_channel_walks(
    exp: &Experiment,
    g: &crate::integrator::backward_alis::Channels,
    reference: usize,
    group: &[usize],
    key: u64,
    moon_ratio: &[f64],
    im: usize,
    cell: usize,
    range: std::ops::Range<u64>,
    pool: Option<&[SceneChannelTally]>,
) -> Accum {
    use crate::integrator::above_scene::Part;
    use crate::integrator::scene_alis::{SceneChannelPath, SceneChannels};
    let m = &exp.measures[im];
    let opt = &exp.optics[group[reference]];
    let (models, wavelengths) = group_scene_models(exp, group);
    let ids = [key, im as u64, cell as u64];
    let (geometry, moon) = sun_and_moon(exp, ids, moon_ratio, |sun| {
        let base = scene_in_layers(exp, sun, g.reference, opt, None);
        let part = if pool.is_some() {
            Part::AfterEntry
        } else {
            Part::Whole
        };
        SceneChannels::new(base, g, &models, &wavelengths, reference).scoring(part)
    });
    let ones = vec![1.0; group.len()];
    // The Moon's walks have no pool of their own (`pools_above_scene` excludes them).
    debug_assert!(pool.is_none() || moon.is_none());
    backward_block(
        &geometry,
        moon.as_ref(),
        &exp.integrator,
        group.len(),
        range,
        SampleStreams::new(exp, ids),
        |rng| Some(sensor::scene_start(&geometry.base, m, cell, rng)),
        |g, _| SceneChannelPath::new(g),
        |s, t| {
            if let Some(p) = pool {
                SceneChannelPath::add_tally(t, &p[s as usize], &ones);
            }
        },
    )
}

/// Per wavelength of `group`: the scene's material models, and the wavelength (nm).
fn group_scene_models<'a>(
    exp: &'a Experiment,
    group: &[usize],
) -> (Vec<&'a [crate::scene::material::SurfaceModel]>, Vec<f64>) {
    group
        .iter()
        .map(|&iw| {
            let o = &exp.optics[iw];
            (o.scene_models.as_slice(), o.wavelength)
        })
        .unzip()
}

/// Tag of the random streams of the above-scene pools (`integrator/above_scene.rs`): keyed
/// by the group, the measure and the sample index, not the pixel.
const POOL_STREAM: u64 = 1 << 60;

/// Whether ortho measure `m` of a run with wavelength groups pools the light of the atmosphere
/// above the scene (`integrator.above_scene`, `integrator/above_scene.rs`).
pub(crate) fn pools_above_scene(exp: &Experiment, m: &Measure) -> bool {
    use crate::integrator::settings::AboveScene;
    let applies = exp.scene.is_some()
        && exp.integrator.spectral_alis.is_some()
        && exp.moon.is_none()
        && matches!(m.kind, MeasureKind::Ortho(_));
    match exp.integrator.above_scene {
        AboveScene::Walked => false,
        AboveScene::Pooled => applies,
        AboveScene::Auto => applies && m.cell_count() >= crate::integrator::above_scene::MIN_PIXELS,
    }
}

/// Entries `range` of the above-scene pool of ortho measure `im` over wavelength group `group`:
/// entry `s` is the mean score of [`batch`](crate::integrator::above_scene::batch) walks that
/// end where they first go below the scene's top (`above_scene.rs`), on streams keyed by `s`.
fn above_scene_pool(
    exp: &Experiment,
    sg: &SpectralGroup,
    group: &[usize],
    im: usize,
    range: std::ops::Range<u64>,
) -> Vec<SceneChannelTally> {
    use crate::integrator::above_scene::{batch, Part};
    use crate::integrator::scene_alis::{SceneChannelPath, SceneChannels};
    let m = &exp.measures[im];
    let opt = &exp.optics[group[sg.reference_member]];
    let (models, wavelengths) = group_scene_models(exp, group);
    let key = POOL_STREAM | GROUP_STREAM | group[0] as u64;
    let batch = batch(m.cell_count());
    let mean = vec![1.0 / batch as f64; group.len()];
    with_channels(exp, sg, group, |g| {
        let geometry = || {
            let base = scene_in_layers(exp, exp.sun_dir, g.reference, opt, None);
            SceneChannels::new(base, g, &models, &wavelengths, sg.reference_member)
                .scoring(Part::BeforeEntry)
        };
        range
            .into_par_iter()
            .map_init(geometry, |geometry, s| {
                let geometry = &*geometry;
                let stream = sample_stream(exp, [key, im as u64, s]);
                let mut sum = SceneChannelPath::zero_tally();
                for b in 0..batch {
                    let mut rng = stream(b);
                    let (p0, d0) = sensor::scene_start(&geometry.base, m, 0, &mut rng);
                    let w = SceneChannelPath::new(geometry);
                    let t = backward::walk(geometry, p0, d0, w, &exp.integrator, &mut rng);
                    SceneChannelPath::add_tally(&mut sum, &t, &mean);
                }
                sum
            })
            .collect()
    })
}

/// The 3D scene of `exp` in the plane-parallel layers `atmosphere`, lit from `sun` (the Sun's
/// direction, or the Moon's), with the material models and wavelength of `opt` and the
/// surfaces' thermal emission `emission`.
fn scene_in_layers<'a>(
    exp: &'a Experiment,
    sun: DVec3,
    atmosphere: &'a crate::atmosphere::PlaneParallel,
    opt: &'a OpticalState,
    emission: Option<&'a crate::scene::emission::SceneEmission>,
) -> SceneInLayers<'a> {
    let scene = exp.scene.as_ref().expect("scene walks without a scene");
    SceneInLayers {
        atmosphere,
        scene,
        models: &opt.scene_models,
        sun,
        clearance: sun_clearance(exp, scene, sun),
        wavelength: opt.wavelength,
        emission,
        shines: exp.sun_shines,
    }
}

/// The scene's clearance map for light from `sun` (none when the Sun does not shine).
fn sun_clearance(
    exp: &Experiment,
    scene: &crate::scene::Scene,
    sun: DVec3,
) -> Option<std::sync::Arc<crate::scene::sun_clearance::SunClearance>> {
    if exp.sun_shines {
        scene.sun_clearance(sun)
    } else {
        None
    }
}

/// The random stream of each sample `s` of the walks keyed `ids` (Sobol-scrambled or not, as
/// `integrator.sampler` says).
fn sample_stream(exp: &Experiment, ids: [u64; 3]) -> impl Fn(u64) -> Stream + '_ {
    let streams = SampleStreams::new(exp, ids);
    move |s| streams.sample(s)
}

/// Tag of the streams of first-order split walks (`integrator.first_order_splits`): they are
/// independent of the samples' own walks.
const SPLIT_STREAM: u64 = 1 << 59;

/// The random streams of the backward walks keyed `ids`: each sample's own, and its
/// first-order split walks'.
#[derive(Clone, Copy)]
struct SampleStreams {
    seed: u64,
    sobol: bool,
    ids: [u64; 3],
}

impl SampleStreams {
    fn new(exp: &Experiment, ids: [u64; 3]) -> Self {
        Self {
            seed: exp.seed,
            sobol: exp.integrator.sampler == crate::integrator::settings::Sampler::Sobol,
            ids,
        }
    }

    /// Sample `s`'s stream.
    fn sample(&self, s: u64) -> Stream {
        let [a, b, c] = self.ids;
        Stream::for_sample(self.seed, [a, b, c, s], self.sobol)
    }

    /// The stream of first-order walk `j` (1 ≤ j < `k`) of sample `s`, `k` walks per sample:
    /// index [`split_index`] of the split family ([`SPLIT_STREAM`]).
    fn split(&self, s: u64, j: u32, k: u32) -> Stream {
        let [a, b, c] = self.ids;
        Stream::for_sample(
            self.seed,
            [a | SPLIT_STREAM, b, c, split_index(s, j, k)],
            self.sobol,
        )
    }
}

/// The sample index, in the split family, of first-order walk `j` (1 ≤ j < `k`) of sample
/// `s`: in the same replicate as `s` (the replicates' means stay independent, `accum.rs`),
/// whose points the samples of that replicate share out `k − 1` each, in sample order (so with
/// the Sobol sampler a replicate's split walks are stratified among themselves, as its samples
/// are).
fn split_index(s: u64, j: u32, k: u32) -> u64 {
    let reps = crate::accum::REPLICATES as u64;
    let point = (s / reps) * u64::from(k - 1) + u64::from(j - 1);
    point * reps + crate::accum::replicate_of(s) as u64
}

fn run_block_at(
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
fn run_block_with<F: Photon, B: Adjoint + AtSensor>(
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
            } else {
                let (g, moon) = sun_and_moon(exp, ids, &ratio, |sun| {
                    scene_in_layers(exp, sun, &opt.atmosphere, opt, opt.scene_emission.as_ref())
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

/// Backward walks of one cell into `cells` accumulator cells (one, or one per wavelength of a
/// spectral walk): each sample's stream, its start (None: the line of sight misses the medium,
/// a zero sample) and the weight it starts with (given the geometry it walks and the direction
/// it leaves the sensor).
/// With the Moon beside the Sun (`moon`), every sample is a Sun-lit walk plus an independent
/// Moon-lit one in the Sun's units, so the samples' scatter holds both sources' noise.
#[allow(clippy::too_many_arguments)]
fn backward_block<'g, G: Geometry<W>, W: Adjoint>(
    g: &'g G,
    moon: Option<&'g MoonWalks<'_, G>>,
    settings: &crate::integrator::settings::IntegratorSettings,
    cells: usize,
    range: std::ops::Range<u64>,
    streams: SampleStreams,
    start: impl Fn(&mut Stream) -> Option<(G::Pos, DVec3)>,
    weight: impl Fn(&'g G, DVec3) -> W,
    pool: impl Fn(u64, &mut W::Tally),
) -> Accum {
    let mut acc = W::accum(cells);
    if settings.replicates {
        acc.enable_replicates();
    }
    let k = Geometry::<W>::light(g).normalization;
    // First-order splitting: walks that stop after their first collision (their scores are
    // exactly the first-order part of a full walk's, `max_depth` = 1).
    let splits = settings.first_order_splits;
    let first_order = (splits > 1).then(|| IntegratorSettings {
        max_depth: 1,
        ..settings.clone()
    });
    let ones = vec![1.0; cells.max(1)];
    for s in range {
        let mut rng = streams.sample(s);
        acc.begin_sample(s);
        let mut t = match start(&mut rng) {
            Some((p0, d0)) => backward::walk(g, p0, d0, weight(g, d0), settings, &mut rng),
            None => W::zero_tally(),
        };
        if let Some(fo) = &first_order {
            // The sample's first-order scores become the mean of its own and `splits − 1`
            // independent first-order walks' (the same expectation), its higher orders stay.
            let mut others = W::zero_tally();
            for j in 1..splits {
                let mut rng = streams.split(s, j, splits);
                if let Some((p0, d0)) = start(&mut rng) {
                    let tj = backward::walk(g, p0, d0, weight(g, d0), fo, &mut rng);
                    W::add_tally(&mut others, &tj, &ones);
                }
            }
            W::mean_first_order(&mut t, &others, splits);
        }
        if let Some(mw) = moon {
            let mut rng = (mw.stream)(s);
            if let Some((p0, d0)) = start(&mut rng) {
                // The weight is bound to the Moon's geometry (channel weights carry its
                // transmittances).
                let tm = backward::walk(&mw.g, p0, d0, weight(&mw.g, d0), settings, &mut rng);
                W::add_tally(&mut t, &tm, &mw.ratio);
            }
        }
        pool(s, &mut t);
        W::record(&mut acc, 0, &t, k);
    }
    acc
}

/// One block of samples `range` for each of `cells` of measure `im` at wavelength group
/// `group`, in parallel, sums discarded: the pilot that `simulate plan` times to size its
/// jobs (`cluster/cost.rs`). Forward measures walk cell 0 only (one walk serves every cell).
pub fn pilot_blocks(
    exp: &Experiment,
    group: &[usize],
    im: usize,
    cells: &[usize],
    range: std::ops::Range<u64>,
) {
    let spectral = exp
        .integrator
        .spectral_alis
        .map(|_| SpectralGroup::new(exp, group));
    let ckd_alis = alis_layers(exp, group[0]);
    cells.par_iter().for_each(|&c| {
        let r = range.clone();
        match &spectral {
            Some(sg) => drop(run_block_spectral(exp, sg, group, im, c, r, None)),
            None => drop(run_block(exp, group[0], im, c, r, ckd_alis.as_ref())),
        }
    });
}

/// Walks a measure costs per sample index (a forward walk serves every direction).
fn walks_per_sample(exp: &Experiment, m: &Measure) -> u64 {
    if method_for(exp, m) == Method::Forward {
        1
    } else {
        m.cell_count() as u64
    }
}

/// The run's progress bar (hidden when `progress` is false), counted in walks; a hidden bar
/// still counts (its `position` and `length`), for callers that draw progress themselves.
pub fn progress_bar(exp: &Experiment, progress: bool) -> ProgressBar {
    let total: u64 = exp
        .measures
        .iter()
        .map(|m| m.spp * walks_per_sample(exp, m))
        .sum::<u64>()
        * exp.wavelengths.len() as u64;
    if !progress {
        let b = ProgressBar::hidden();
        b.set_length(total);
        return b;
    }
    let b = ProgressBar::new(total);
    // The bar counts walks (one per sample and direction cell of a backward walk, one per sample
    // of a forward walk), so its rate is in walks per second, said with the unit.
    match ProgressStyle::with_template(
        "{msg:24} [{elapsed_precise}] {wide_bar} {percent:>3}% ({rate}, eta {eta})",
    ) {
        Ok(style) => b.set_style(style.with_key(
            "rate",
            |s: &indicatif::ProgressState, w: &mut dyn std::fmt::Write| {
                let _ = write!(w, "{:.3e} walks/s", s.per_sec());
            },
        )),
        Err(e) => tracing::debug!("progress bar template: {e}"),
    }
    b
}

/// Never set: the cancellation flag of runs that cannot be cancelled.
static NEVER: AtomicBool = AtomicBool::new(false);

/// Run `exp` completely. `progress`: draw a progress bar on stderr.
pub fn run(exp: &Experiment, progress: bool) -> Vec<MeasureResult> {
    run_cancellable(exp, &progress_bar(exp, progress), &NEVER)
        .expect("a run without cancellation completes")
}

/// [`run`] counting its walks on `bar` ([`progress_bar`]) and checking `cancel` before every
/// block: once it is set, the remaining blocks are skipped and `None` is returned (the Python
/// package's Ctrl-C). A run that is not cancelled returns exactly what [`run`] returns.
pub fn run_cancellable(
    exp: &Experiment,
    bar: &ProgressBar,
    cancel: &AtomicBool,
) -> Option<Vec<MeasureResult>> {
    // Tasks (a wavelength or a spectral ALIS group, and a measure) run concurrently as well as
    // their blocks: a task whose round is a single block (precise CKD/ALIS walks) would
    // otherwise leave cores idle. Each task's result depends only on its own random streams, so
    // not on the scheduling.
    let parts: Vec<Vec<MeasureResult>> = tasks(exp)
        .into_par_iter()
        .map(|(group, im)| {
            bar.set_message(task_message(exp, &group, im));
            let cells = 0..exp.measures[im].cell_count();
            run_task(exp, &group, im, cells, bar, cancel)
        })
        .collect();
    bar.finish_and_clear();
    if cancel.load(Ordering::Relaxed) {
        return None;
    }
    let mut slots: Vec<Option<MeasureResult>> = (0..exp.wavelengths.len() * exp.measures.len())
        .map(|_| None)
        .collect();
    let nm = exp.measures.len();
    for r in parts.into_iter().flatten() {
        let k = r.wavelength * nm + r.measure;
        slots[k] = Some(r);
    }
    let out: Vec<MeasureResult> = slots
        .into_iter()
        .map(|r| r.expect("every (wavelength, measure) pair has a task"))
        .collect();
    crate::heavy_tail::warn(exp, &out);
    Some(out)
}

/// The progress bar's message for a task.
fn task_message(exp: &Experiment, group: &[usize], im: usize) -> String {
    let id = &exp.measures[im].id;
    match group {
        [iw] => format!("{id} @ {} nm", exp.wavelengths[*iw]),
        _ => format!(
            "{id} @ {}–{} nm",
            exp.wavelengths[group[0]],
            exp.wavelengths[group[group.len() - 1]]
        ),
    }
}

/// The wavelength groups of a run: with `integrator.spectral_walk = "alis"`, runs of at most
/// `alis_group` consecutive wavelengths of the sorted list (one walk serves a group); otherwise
/// one wavelength each. Wavelength indices, ascending in wavelength within a group.
pub fn wavelength_groups(exp: &Experiment) -> Vec<Vec<usize>> {
    wavelength_groups_of(&exp.wavelengths, exp.integrator.spectral_alis)
}

pub use crate::spectral::wavelength_groups_of;

/// Every (wavelength group, measure) pair, group-major (wavelength-major without groups).
fn tasks(exp: &Experiment) -> Vec<(Vec<usize>, usize)> {
    wavelength_groups(exp)
        .into_iter()
        .flat_map(|g| (0..exp.measures.len()).map(move |im| (g.clone(), im)))
        .collect()
}

/// The most blocks one round of a task lists at once.
const MAX_ROUND_BLOCKS: u64 = 1 << 18;
/// Blocks run in parallel before their sums are merged (and their accumulators freed).
const MERGE_CHUNK: usize = 4096;

/// End of the next round: the sample count at which the target should be met (the standard
/// error falls as 1/√n), times `margin` (1.1 for uniform rounds, whose every round costs the
/// whole measure; 1.0 for adaptive images, whose short extra round costs only the pixels
/// still above the target), at least `min_grow` more samples and at most 4× the samples done
/// (or `min_grow` more, if that is larger), rounded up to whole units (`block`: a block, or a
/// whole cycle of g-point blocks in CKD runs). Depends only on results, so it is thread-count
/// independent.
fn next_round_end(
    done: u64,
    rel: f64,
    target: f64,
    margin: f64,
    spp: u64,
    block: u64,
    min_grow: u64,
) -> u64 {
    let grow = if rel.is_finite() && target > 0.0 {
        (done as f64 * (rel / target).powi(2) * margin).ceil() as u64
    } else {
        done * 4
    };
    let lo = done + min_grow;
    let n = grow.clamp(lo, (done * 4).max(lo));
    (n.div_ceil(block) * block).min(spp)
}

/// Run one measure at one wavelength, in rounds when a target precision is set.
pub fn run_measure(exp: &Experiment, iw: usize, im: usize, bar: &ProgressBar) -> MeasureResult {
    let cells = 0..exp.measures[im].cell_count();
    run_task(exp, &[iw], im, cells, bar, &NEVER)
        .pop()
        .expect("one result per wavelength")
}

/// Run one measure at the wavelengths of `group` (one wavelength, or a spectral ALIS group whose
/// walks serve all of them), in rounds when a target precision is set: the group stops when
/// every wavelength meets the target (or at `spp`). One result per wavelength of the group.
/// `tile`: the cells to walk (all of them, or a pixel tile of a backward measure,
/// `units.rs`); the results hold those cells only, in order.
/// Once `cancel` is set, blocks are skipped and the (meaningless) partial sums returned.
fn run_task(
    exp: &Experiment,
    group: &[usize],
    im: usize,
    tile: std::ops::Range<usize>,
    bar: &ProgressBar,
    cancel: &AtomicBool,
) -> Vec<MeasureResult> {
    let m = &exp.measures[im];
    let method = method_for(exp, m);
    let bs = m.block_size();
    let spectral = exp
        .integrator
        .spectral_alis
        .map(|_| SpectralGroup::new(exp, group));
    assert!(spectral.is_some() || group.len() == 1);
    let iw0 = group[0];
    let ckd_alis = alis_layers(exp, iw0);
    // Rounds end on whole cycles of g-point blocks in CKD runs.
    let cycle = if exp.integrator.alis {
        1
    } else {
        exp.optics[iw0].g_states.len().max(1)
    };
    let unit = bs * cycle as u64;
    let first_cell = tile.start;
    let (cells, walk_cells): (usize, Vec<usize>) = if method == Method::Forward {
        (m.cell_count(), vec![0])
    } else {
        (tile.len(), tile.collect())
    };
    let new_acc = || {
        if exp.polarized {
            Accum::new_polarized(cells)
        } else {
            Accum::new(cells)
        }
    };
    let mut accs: Vec<Accum> = group.iter().map(|_| new_acc()).collect();
    let mut done = 0u64;
    // Rounds: the whole budget at once, or growing rounds until the target is met.
    let mut next = match m.target_rel_stderr {
        None => m.spp,
        Some(_) => {
            let first = exp.integrator.first_check_spp.unwrap_or(4 * bs);
            (first.div_ceil(unit) * unit).min(m.spp)
        }
    };
    // Rounds hold at most MAX_ROUND_BLOCKS blocks in memory (a huge `spp` without a target used
    // to list all its blocks at once and abort on allocation). Blocks merge in the same order
    // whatever the rounds, so capping changes no result.
    let round_cap = (MAX_ROUND_BLOCKS / (walk_cells.len() as u64 * cycle as u64)).max(1) * unit;
    next = next.min(done + round_cap);
    let per_walk = group.len() as u64;
    // Adaptive images (a target set): after the first round, only the pixels above the target
    // are sampled, each up to its own projection (at most the uniform schedule's `next`).
    // `have[i]`: samples of walk_cells[i] so far; `want[i]`: the end of its current round.
    let adaptive =
        m.adaptive && m.is_image() && m.target_rel_stderr.is_some() && method != Method::Forward;
    let mut have = vec![0u64; walk_cells.len()];
    let mut want = vec![next; walk_cells.len()];
    // Pooled ortho images (`integrator/above_scene.rs`): entry s serves sample s of every pixel.
    let pooled = spectral.is_some() && pools_above_scene(exp, m);
    let mut pool: Vec<SceneChannelTally> = Vec::new();
    loop {
        if let (true, Some(sg), Some(&end)) = (pooled, &spectral, want.iter().max()) {
            if end > pool.len() as u64 {
                pool.extend(above_scene_pool(exp, sg, group, im, pool.len() as u64..end));
            }
        }
        let blocks: Vec<(usize, u64)> = walk_cells
            .iter()
            .enumerate()
            .flat_map(|(i, &c)| {
                // Adaptive pixels may stop inside a block (`pixel_unit` below): their next
                // round starts in that block.
                let first = have[i] / bs;
                let last = if want[i] > have[i] {
                    want[i].div_ceil(bs)
                } else {
                    first
                };
                (first..last).map(move |b| (c, b))
            })
            .collect();
        // Merged chunk by chunk, in block order (the same sums as merging the whole round at
        // once): a round of an image holds every pixel's blocks, and per-block accumulators
        // would otherwise all be alive together (tens of MB on the README render).
        for chunk in blocks.chunks(MERGE_CHUNK) {
            let parts: Vec<(usize, Vec<Accum>)> = chunk
                .par_iter()
                .map(|&(c, b)| {
                    if cancel.load(Ordering::Relaxed) {
                        return (c, Vec::new());
                    }
                    let i = c - first_cell;
                    let range = (b * bs).max(have[i])..((b + 1) * bs).min(want[i]);
                    let n = range.end - range.start;
                    let a = match &spectral {
                        Some(sg) => run_block_spectral(
                            exp,
                            sg,
                            group,
                            im,
                            c,
                            range,
                            pooled.then_some(pool.as_slice()),
                        ),
                        None => vec![run_block(exp, iw0, im, c, range, ckd_alis.as_ref())],
                    };
                    bar.inc(n * per_walk);
                    (c, a)
                })
                .collect();
            for (c, part) in &parts {
                for (acc, p) in accs.iter_mut().zip(part) {
                    if method == Method::Forward {
                        acc.merge(p);
                    } else {
                        acc.merge_cell(*c - first_cell, p, 0);
                    }
                }
            }
        }
        done = next;
        have.copy_from_slice(&want);
        if cancel.load(Ordering::Relaxed) {
            break;
        }
        // Images stop on the pixel error of quantile `target_fraction` (the median by default),
        // other measures on the worst cell (the worst wavelength of a group).
        let rel = accs
            .iter()
            .map(|acc| {
                if m.is_image() {
                    acc.quantile_rel_stderr(m.target_fraction)
                } else {
                    acc.max_rel_stderr()
                }
            })
            .fold(0.0, f64::max);
        // A standard error that cannot be trusted (heavy tails, `heavy_tail.rs`) does not stop
        // the run early.
        let trusted = || {
            accs.iter()
                .all(|acc| (0..acc.n.len()).all(|c| acc.tail(c).is_none_or(|t| t.trusted())))
        };
        let reached = m.target_rel_stderr.is_some_and(|t| rel <= t) && trusted();
        if done >= m.spp || reached {
            let left: u64 = have.iter().map(|&h| m.spp.saturating_sub(h)).sum();
            bar.inc(left * per_walk);
            break;
        }
        // At least 8 blocks more (at most 4× what is done, after an early first check), or one
        // more g-point cycle (cycles are already 16 blocks). An image's block is already a
        // round over every pixel (32 samples each), so images grow by at least one block: the
        // projection to the target then decides, instead of a jump from 256 to 768 samples.
        let min_grow = if unit > bs {
            unit
        } else if m.is_image() {
            bs
        } else {
            (8 * bs).min(4 * done).max(bs)
        };
        // Adaptive images aim at the target without a margin, and each pixel grows in
        // quarter blocks (measured on the README render: 12 % fewer samples for the same
        // stopping rule, BENCHMARKS.md).
        let margin = if adaptive { 1.0 } else { 1.1 };
        let pixel_unit = if unit == bs { (bs / 4).max(1) } else { unit };
        next = next_round_end(
            done,
            rel,
            m.target_rel_stderr.unwrap_or(0.0),
            margin,
            m.spp,
            unit,
            min_grow,
        )
        .min(done + round_cap);
        let target = m.target_rel_stderr.unwrap_or(0.0);
        for (i, w) in want.iter_mut().enumerate() {
            *w = next;
            if adaptive {
                let c = walk_cells[i] - first_cell;
                let rel_c = accs
                    .iter()
                    .map(|acc| acc.cell_rel_stderr(c))
                    .fold(0.0, f64::max);
                // A pixel stops only once its error is both small and trusted (its heavy-tail
                // check, which the run's stop also needs); in the last round (the schedule at
                // `spp`) every pixel still going gets all of `spp`.
                let settled = rel_c <= target
                    && accs
                        .iter()
                        .all(|acc| acc.tail(c).is_none_or(|t| t.trusted()));
                *w = if settled {
                    have[i]
                } else if next >= m.spp {
                    next
                } else {
                    // Above the target: grow to the projection in quarter blocks. At or below
                    // it but not trusted yet: a whole block more, as the uniform schedule.
                    let min_pixel = if rel_c > target { pixel_unit } else { min_grow };
                    next_round_end(have[i], rel_c, target, margin, m.spp, pixel_unit, min_pixel)
                        .min(next)
                        .max(have[i])
                };
            }
        }
        // Every pixel meets the target but the errors are not trusted yet: all go on.
        if want.iter().zip(&have).all(|(w, h)| w <= h) {
            want.fill(next);
        }
        tracing::debug!(
            "measure `{}`: {done} samples, relative standard error {rel:.4} (trusted: {}), next round to {next} ({} of {} cells sampled)",
            m.id,
            trusted(),
            want.iter().zip(&have).filter(|(w, h)| w > h).count(),
            want.len()
        );
    }
    group
        .iter()
        .zip(accs)
        .map(|(&iw, acc)| MeasureResult {
            measure: im,
            wavelength: iw,
            method,
            acc,
        })
        .collect()
}

pub mod checkpoint;
pub mod units;

/// [`run`] with checkpoints in `dir`: completed tasks are loaded instead of recomputed, and
/// each newly completed task is stored before the next starts. Returns the results and the
/// number of tasks resumed.
pub fn run_resumable(
    exp: &Experiment,
    progress: bool,
    dir: &std::path::Path,
) -> Result<(Vec<MeasureResult>, usize), crate::error::OutputError> {
    let (out, resumed) = run_shard(exp, progress, dir, 0, 1)?;
    Ok((
        out.into_iter()
            .map(|r| r.expect("every task runs in shard 0/1"))
            .collect(),
        resumed,
    ))
}

/// Run only the work units (`units.rs`: a (wavelength group, measure) task or a pixel tile of
/// one) whose index is `shard` modulo `shards`, storing each unit's results in `dir`; units of
/// other shards are loaded from `dir` when present (so collecting the checkpoint files of all
/// shards in one folder and running shard 0/1 there writes the products without recomputing
/// anything: runs split across machines merge exactly, bit for bit). A group is loaded only
/// when every one of its wavelengths is stored. Returns one entry per (wavelength, measure),
/// wavelength-major (`None`: a unit of another shard not available), and the count of
/// (wavelength, unit) results loaded.
pub fn run_shard(
    exp: &Experiment,
    progress: bool,
    dir: &std::path::Path,
    shard: usize,
    shards: usize,
) -> Result<(Vec<Option<MeasureResult>>, usize), crate::error::OutputError> {
    let bar = progress_bar(exp, progress);
    let resumed = std::sync::atomic::AtomicUsize::new(0);
    let key = checkpoint::experiment_hash(exp);
    // Units run concurrently (see `run`); each stores its checkpoints as soon as it is done.
    let parts = units::units(exp, shards)
        .into_par_iter()
        .enumerate()
        .map(|(k, u)| {
            let m = &exp.measures[u.measure];
            let walks = if method_for(exp, m) == Method::Forward {
                1
            } else {
                u.cells.len() as u64
            };
            let per = walks * u.group.len() as u64;
            let loaded: Option<Vec<MeasureResult>> = u
                .group
                .iter()
                .map(|&iw| checkpoint::load(dir, exp, &key, iw, &u))
                .collect();
            if let Some(rs) = loaded {
                bar.inc(m.spp * per);
                resumed.fetch_add(rs.len(), std::sync::atomic::Ordering::Relaxed);
                return Ok(Some((u, rs)));
            }
            if k % shards != shard {
                bar.inc(m.spp * per);
                return Ok(None);
            }
            bar.set_message(task_message(exp, &u.group, u.measure));
            let rs = run_task(exp, &u.group, u.measure, u.cells.clone(), &bar, &NEVER);
            for r in &rs {
                checkpoint::store(dir, exp, &key, &u, r)?;
            }
            Ok(Some((u, rs)))
        })
        .collect::<Result<Vec<_>, crate::error::OutputError>>()?;
    bar.finish_and_clear();
    let out = gather(exp, parts.into_iter().flatten());
    crate::heavy_tail::warn(exp, out.iter().flatten());
    Ok((out, resumed.into_inner()))
}

/// One entry per (wavelength, measure), wavelength-major, assembled from unit results (`None`
/// where a tile or the whole task is missing).
pub fn gather(
    exp: &Experiment,
    parts: impl IntoIterator<Item = (units::Unit, Vec<MeasureResult>)>,
) -> Vec<Option<MeasureResult>> {
    let nm = exp.measures.len();
    let mut pieces: Vec<Vec<(std::ops::Range<usize>, MeasureResult)>> = (0..exp.wavelengths.len()
        * nm)
        .map(|_| Vec::new())
        .collect();
    for (u, rs) in parts {
        for r in rs {
            pieces[r.wavelength * nm + r.measure].push((u.cells.clone(), r));
        }
    }
    pieces
        .into_iter()
        .map(|p| {
            if p.is_empty() {
                None
            } else {
                units::assemble(exp, p)
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// First-order split walks get indices of their own: distinct per sample and walk, in
    /// the sample's replicate, and the first n samples of a replicate use exactly its first
    /// n·(k − 1) points (a prefix, as Sobol stratification needs); their streams differ from
    /// the samples' own.
    #[test]
    fn split_indices_are_distinct_prefixes_in_the_replicate() {
        let reps = crate::accum::REPLICATES as u64;
        for k in 2..=5u32 {
            let mut seen = std::collections::HashSet::new();
            for s in 0..(20 * reps) {
                for j in 1..k {
                    let i = split_index(s, j, k);
                    assert!(seen.insert(i), "k {k}, s {s}, j {j}: index {i} twice");
                    assert_eq!(
                        crate::accum::replicate_of(i),
                        crate::accum::replicate_of(s),
                        "k {k}, s {s}, j {j}"
                    );
                }
                // After sample s, replicate r holds the points 0..n·(k − 1) of its sequence.
                let r = crate::accum::replicate_of(s) as u64;
                let n = s / reps + 1;
                let points: std::collections::BTreeSet<u64> = seen
                    .iter()
                    .filter(|&&i| i % reps == r)
                    .map(|&i| i / reps)
                    .collect();
                let want: std::collections::BTreeSet<u64> = (0..n * u64::from(k - 1)).collect();
                assert_eq!(points, want, "k {k}, s {s}");
            }
        }
        for sobol in [false, true] {
            let streams = SampleStreams {
                seed: 3,
                sobol,
                ids: [1, 2, 3],
            };
            let own: std::collections::HashSet<u64> = (0..200)
                .map(|s| {
                    let mut r = streams.sample(s);
                    (u64::from(r.next_u32()) << 32) | u64::from(r.next_u32())
                })
                .collect();
            for s in 0..200 {
                let mut r = streams.split(s, 1, 2);
                let x = (u64::from(r.next_u32()) << 32) | u64::from(r.next_u32());
                assert!(!own.contains(&x), "sobol {sobol}, s {s}");
            }
        }
    }
}
