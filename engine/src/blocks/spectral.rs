//! Blocks of spectral ALIS groups: every walk carries all wavelengths of a group (one
//! accumulator per wavelength), over a reference atmosphere built once per task; and the
//! above-scene pool of pooled ortho images (`integrator/above_scene.rs`).

use rayon::prelude::*;

use crate::accum::Accum;
use crate::config::resolve::Experiment;
use crate::integrator::backward;
use crate::integrator::scene_alis::SceneChannelTally;
use crate::integrator::weight::Weight;
use crate::sensor;

use super::streams::{sample_stream, SampleStreams, GROUP_STREAM, POOL_STREAM};
use super::walks::{backward_block, channel_walks, scene_in_layers, sun_and_moon};

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
pub(super) fn with_channels<R>(
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
pub(super) fn scene_channel_walks(
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
pub(super) fn group_scene_models<'a>(
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
