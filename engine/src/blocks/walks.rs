//! The backward block loop every backward task shares: each sample's stream and start, its
//! first-order split walks (`integrator.first_order_splits`) and, with the Moon beside the
//! Sun, an independent Moon-lit walk in the Sun's units; and the scene geometries walks see.

use glam::DVec3;

use crate::accum::Accum;
use crate::config::resolve::Experiment;
use crate::integrator::backward::{self, Adjoint};
use crate::integrator::backward_alis::{ChannelPath, ReferenceLayers};
use crate::integrator::geometry::scene_layers::SceneInLayers;
use crate::integrator::geometry::Geometry;
use crate::integrator::settings::IntegratorSettings;
use crate::optics::OpticalState;
use crate::rng::Stream;
use crate::sensor;

use super::streams::{sample_stream, SampleStreams, MOON_STREAM};

/// Backward walks over channels `g` into `acc` (one cell per output: the bin mean, or one per
/// wavelength), stream family `key`; `moon_ratio`: E_moon/E_sun per output (used with the Moon
/// beside the Sun).
#[allow(clippy::too_many_arguments)]
pub(super) fn channel_walks(
    acc: &mut Accum,
    exp: &Experiment,
    g: &crate::integrator::backward_alis::Channels,
    key: u64,
    moon_ratio: &[f64],
    im: usize,
    cell: usize,
    samples: impl IntoIterator<Item = u64>,
    factors: Option<&[f64]>,
) {
    let m = &exp.measures[im];
    let toa = g.reference.toa();
    let ids = [key, im as u64, cell as u64];
    let (geometry, moon) = sun_and_moon(exp, ids, moon_ratio, |dir| {
        ReferenceLayers::new(g, dir).with_sun_shining(exp.sun_shines)
    });
    backward_block_into(
        acc,
        &geometry,
        moon.as_ref(),
        &exp.integrator,
        samples,
        SampleStreams::new(exp, ids),
        |rng| Some(sensor::backward_start_altitude(toa, m, cell, rng)),
        |g, _| ChannelPath::new(g),
        |_, t| {
            if let Some(f) = factors {
                scale::<ChannelPath>(t, f);
            }
        },
    )
}

/// The Moon's half of every sample when it shines beside the Sun (`illumination.moon`): the
/// same medium lit from the Moon's direction, E_moon/E_sun per accumulator cell (the factor that
/// brings a Moon-lit score into the Sun's units: a score is radiance per unit irradiance) and
/// the Moon's random streams.
pub(super) struct MoonWalks<'a, G> {
    g: G,
    ratio: Vec<f64>,
    stream: Box<dyn Fn(u64) -> Stream + 'a>,
}

/// The walks keyed `ids`: the geometry lit from the Sun, `lit_from(Sun direction)`, and when the
/// experiment has a Moon beside the Sun its [`MoonWalks`] in `lit_from(Moon direction)`
/// (`ratio`: E_moon/E_sun per accumulator cell).
pub(super) fn sun_and_moon<'a, G>(
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

/// The 3D scene of `exp` in the plane-parallel layers `atmosphere`, lit from `sun` (the Sun's
/// direction, or the Moon's), with the material models and wavelength of `opt` and the
/// surfaces' thermal emission `emission`.
pub(super) fn scene_in_layers<'a>(
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
        clouds_top: exp
            .clouds
            .as_ref()
            .map_or(f64::NEG_INFINITY, |c| c.grid.z_range().1 + c.origin.z),
        lamps: None,
    }
}

/// The scene's clearance map for light from `sun` (none when the Sun does not shine).
pub(super) fn sun_clearance(
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

/// Backward walks of one cell into `cells` accumulator cells (one, or one per wavelength of a
/// spectral walk): each sample's stream, its start (None: the line of sight misses the medium,
/// a zero sample) and the weight it starts with (given the geometry it walks and the direction
/// it leaves the sensor).
/// With the Moon beside the Sun (`moon`), every sample is a Sun-lit walk plus an independent
/// Moon-lit one in the Sun's units, so the samples' scatter holds both sources' noise.
#[allow(clippy::too_many_arguments)]
pub(super) fn backward_block<'g, G: Geometry<W>, W: Adjoint>(
    g: &'g G,
    moon: Option<&'g MoonWalks<'_, G>>,
    settings: &crate::integrator::settings::IntegratorSettings,
    cells: usize,
    samples: impl IntoIterator<Item = u64>,
    streams: SampleStreams,
    start: impl Fn(&mut Stream) -> Option<(G::Pos, DVec3)>,
    weight: impl Fn(&'g G, DVec3) -> W,
    pool: impl Fn(u64, &mut W::Tally),
) -> Accum {
    let mut acc = W::accum(cells);
    backward_block_into(
        &mut acc, g, moon, settings, samples, streams, start, weight, pool,
    );
    acc
}

/// [`backward_block`] recording into `acc` (its cells: one, or one per channel).
#[allow(clippy::too_many_arguments)]
pub(super) fn backward_block_into<'g, G: Geometry<W>, W: Adjoint>(
    acc: &mut Accum,
    g: &'g G,
    moon: Option<&'g MoonWalks<'_, G>>,
    settings: &crate::integrator::settings::IntegratorSettings,
    samples: impl IntoIterator<Item = u64>,
    streams: SampleStreams,
    start: impl Fn(&mut Stream) -> Option<(G::Pos, DVec3)>,
    weight: impl Fn(&'g G, DVec3) -> W,
    pool: impl Fn(u64, &mut W::Tally),
) {
    let cells = acc.n.len();
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
    for s in samples {
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
        W::record(acc, 0, &t, k);
    }
}

/// Multiply every channel's scores of tally `t` by `f` (per channel).
pub(super) fn scale<W: Adjoint>(t: &mut W::Tally, f: &[f64]) {
    let mut scaled = W::zero_tally();
    W::add_tally(&mut scaled, t, f);
    *t = scaled;
}
