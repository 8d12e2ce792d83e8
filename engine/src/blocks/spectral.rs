//! Blocks of spectral ALIS groups: every walk carries all wavelengths of a group (one
//! accumulator per wavelength), over a reference atmosphere built once per task; and the
//! above-scene pool of pooled ortho images (`integrator/above_scene.rs`).

use rayon::prelude::*;

use crate::accum::Accum;
use crate::config::resolve::Experiment;
use crate::integrator::backward;
use crate::integrator::scene_alis::SceneChannelTally;
use crate::integrator::weight::Weight;
use crate::optics::OpticalState;
use crate::sensor;

use super::streams::{sample_stream, SampleStreams, GROUP_STREAM, POOL_STREAM};
use super::walks::{backward_block_into, channel_walks, scale, scene_in_layers, sun_and_moon};

/// What the walks of a spectral ALIS group share: the reference atmosphere (the group's
/// central wavelength's scattering with the group's least absorption) and the layer tables,
/// built once per task.
pub(super) struct SpectralGroup {
    reference: crate::atmosphere::PlaneParallel,
    layers: crate::integrator::backward_alis::Layers,
    /// The member of the group whose scattering the reference has
    /// ([`IntegratorSettings::reference_member`](crate::integrator::settings::IntegratorSettings::reference_member)).
    reference_member: usize,
}

impl SpectralGroup {
    pub(super) fn new(exp: &Experiment, group: &[usize]) -> Self {
        Self::of(&states(exp, group), exp.scene.is_some())
    }

    /// The group of channels `opts` (one optical state each; `scene`: walks through a 3D
    /// scene, whose reference is the channel that scatters most).
    pub(super) fn of(opts: &[&OpticalState], scene: bool) -> Self {
        let atms: Vec<&crate::atmosphere::PlaneParallel> =
            opts.iter().map(|o| &o.atmosphere).collect();
        let reference_member =
            crate::integrator::settings::IntegratorSettings::reference_member(&atms, scene);
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

/// The optical states of run wavelengths `group`.
pub(super) fn states<'a>(exp: &'a Experiment, group: &[usize]) -> Vec<&'a OpticalState> {
    group.iter().map(|&iw| &exp.optics[iw]).collect()
}

/// `f` of the channels `opts` of spectral group `sg` (their atmospheres, reference and layer
/// tables, surfaces).
pub(super) fn with_channels<R>(
    sg: &SpectralGroup,
    opts: &[&OpticalState],
    f: impl FnOnce(&crate::integrator::backward_alis::Channels) -> R,
) -> R {
    use crate::integrator::backward_alis::{Channels, Kind};
    let atms: Vec<&crate::atmosphere::PlaneParallel> = opts.iter().map(|o| &o.atmosphere).collect();
    let surfaces: Vec<&crate::bsdf::Bsdf> = opts.iter().map(|o| &o.surface).collect();
    f(&Channels {
        atms: &atms,
        reference: &sg.reference,
        layers: &sg.layers,
        kind: Kind::Wavelengths {
            surfaces: &surfaces,
            reference_surface: &opts[sg.reference_member].surface,
        },
    })
}

/// A block of spectral ALIS walks: every walk carries all wavelengths of `group` (one
/// accumulator per wavelength). `pool`: the above-scene pool of a pooled ortho image
/// (`integrator/above_scene.rs`), entry `s` for sample `s`; None for whole walks.
#[allow(clippy::too_many_arguments)]
pub(super) fn run_block_spectral(
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
    let opts = states(exp, group);
    let mut all = Accum::new(group.len());
    group_walks(
        &mut all, exp, sg, &opts, key, &ratio, im, cell, range, pool, None,
    );
    split_cells(&all)
}

/// One accumulator per cell of `all` (one per wavelength or band of a group).
pub(super) fn split_cells(all: &Accum) -> Vec<Accum> {
    (0..all.n.len())
        .map(|c| {
            let mut a = Accum::new(1);
            a.merge_cell(0, all, c);
            a
        })
        .collect()
}

/// The walks of channels `opts` (spectral group `sg`) for samples `samples` of cell `cell`:
/// through the scene when the run has one, else through the layers, into `acc` (one cell per
/// channel); each sample's scores are multiplied by `factors` (per channel) when given.
#[allow(clippy::too_many_arguments)]
pub(super) fn group_walks(
    acc: &mut Accum,
    exp: &Experiment,
    sg: &SpectralGroup,
    opts: &[&OpticalState],
    key: u64,
    moon_ratio: &[f64],
    im: usize,
    cell: usize,
    samples: impl IntoIterator<Item = u64>,
    pool: Option<&[SceneChannelTally]>,
    factors: Option<&[f64]>,
) {
    with_channels(sg, opts, |g| match &exp.scene {
        Some(_) => scene_channel_walks(
            acc,
            exp,
            g,
            sg.reference_member,
            opts,
            key,
            moon_ratio,
            im,
            cell,
            samples,
            pool,
            factors,
        ),
        None => channel_walks(acc, exp, g, key, moon_ratio, im, cell, samples, factors),
    })
}

/// Backward walks of a 3D scene in plane-parallel layers over the channels `opts` (channels
/// `g`, whose reference is member `reference`; `scene_alis.rs`) into `acc`, one cell per
/// channel; `moon_ratio`: E_moon/E_sun per channel (used with the Moon beside the Sun);
/// `factors`: per channel, what each sample's scores are multiplied by.
#[allow(clippy::too_many_arguments)]
pub(super) fn scene_channel_walks(
    acc: &mut Accum,
    exp: &Experiment,
    g: &crate::integrator::backward_alis::Channels,
    reference: usize,
    opts: &[&OpticalState],
    key: u64,
    moon_ratio: &[f64],
    im: usize,
    cell: usize,
    samples: impl IntoIterator<Item = u64>,
    pool: Option<&[SceneChannelTally]>,
    factors: Option<&[f64]>,
) {
    use crate::integrator::above_scene::Part;
    use crate::integrator::scene_alis::{SceneChannelPath, SceneChannels};
    let m = &exp.measures[im];
    let opt = opts[reference];
    let (models, wavelengths) = group_scene_models(opts);
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
    let ones = vec![1.0; opts.len()];
    // The Moon's walks have no pool of their own (`pools_above_scene` excludes them).
    debug_assert!(pool.is_none() || moon.is_none());
    backward_block_into(
        acc,
        &geometry,
        moon.as_ref(),
        &exp.integrator,
        samples,
        SampleStreams::new(exp, ids),
        |rng| Some(sensor::scene_start(&geometry.base, m, cell, rng)),
        |g, _| SceneChannelPath::new(g),
        |s, t| {
            if let Some(p) = pool {
                SceneChannelPath::add_tally(t, &p[s as usize], &ones);
            }
            if let Some(f) = factors {
                scale::<SceneChannelPath>(t, f);
            }
        },
    )
}

/// Per channel: the scene's material models, and the wavelength (nm).
pub(super) fn group_scene_models<'a>(
    opts: &[&'a OpticalState],
) -> (Vec<&'a [crate::scene::material::SurfaceModel]>, Vec<f64>) {
    opts.iter()
        .map(|o| (o.scene_models.as_slice(), o.wavelength))
        .unzip()
}

/// Entries `range` of the above-scene pool of ortho measure `im` over wavelength group `group`:
/// entry `s` is the mean score of [`batch`](crate::integrator::above_scene::batch) walks that
/// end where they first go below the scene's top (`above_scene.rs`), on streams keyed by `s`.
pub(super) fn above_scene_pool(
    exp: &Experiment,
    sg: &SpectralGroup,
    group: &[usize],
    im: usize,
    range: std::ops::Range<u64>,
) -> Vec<SceneChannelTally> {
    let key = POOL_STREAM | GROUP_STREAM | group[0] as u64;
    let opts = states(exp, group);
    range
        .into_par_iter()
        .map(|s| pool_entry(exp, sg, &opts, key, im, s))
        .collect()
}

/// Entry `s` of an above-scene pool (stream family `key`) over channels `opts` of spectral
/// group `sg`.
pub(super) fn pool_entry(
    exp: &Experiment,
    sg: &SpectralGroup,
    opts: &[&OpticalState],
    key: u64,
    im: usize,
    s: u64,
) -> SceneChannelTally {
    use crate::integrator::above_scene::{batch, Part};
    use crate::integrator::scene_alis::{SceneChannelPath, SceneChannels};
    let m = &exp.measures[im];
    let opt = opts[sg.reference_member];
    let (models, wavelengths) = group_scene_models(opts);
    let batch = batch(m.cell_count());
    let mean = vec![1.0 / batch as f64; opts.len()];
    with_channels(sg, opts, |g| {
        let base = scene_in_layers(exp, exp.sun_dir, g.reference, opt, None);
        let geometry = SceneChannels::new(base, g, &models, &wavelengths, sg.reference_member)
            .scoring(Part::BeforeEntry);
        let stream = sample_stream(exp, [key, im as u64, s]);
        let mut sum = SceneChannelPath::zero_tally();
        for b in 0..batch {
            let mut rng = stream(b);
            let (p0, d0) = sensor::scene_start(&geometry.base, m, 0, &mut rng);
            let w = SceneChannelPath::new(&geometry);
            let t = backward::walk(&geometry, p0, d0, w, &exp.integrator, &mut rng);
            SceneChannelPath::add_tally(&mut sum, &t, &mean);
        }
        sum
    })
}
