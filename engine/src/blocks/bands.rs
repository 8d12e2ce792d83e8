//! Blocks of a run with sensor bands (`spectral.bands`, `spectral/bands.rs`): a task's walks
//! carry one channel per band of its group; each sample walks the set its index draws, and its
//! scores are weighted by the set's factors, so that a band's cell averages to the band's
//! quadrature over its nodes.

use std::collections::BTreeMap;

use rayon::prelude::*;

use crate::accum::Accum;
use crate::config::bands::BandWalks;
use crate::config::resolve::Experiment;
use crate::integrator::scene_alis::SceneChannelTally;
use crate::optics::OpticalState;
use crate::spectral::bands::{BandDraws, Sets};

use super::spectral::{group_walks, pool_entry, split_cells, SpectralGroup};
use super::streams::{GROUP_STREAM, POOL_STREAM};

/// What a task of band group `group` (band indices) builds once: the group's sets
/// ([`BandWalks::sets`]) and per set its spectral group over the set's nodes.
pub(super) struct BandGroups {
    sets: Sets,
    groups: Vec<SpectralGroup>,
}

impl BandGroups {
    /// The reference of every set's walks is its channel that scatters most (as in 3D
    /// scenes, also in 1D runs): a group spans distant bands, and channels that scatter more
    /// than the reference would carry heavy-tailed weights.
    pub(super) fn new(bw: &BandWalks, group: &[usize]) -> Self {
        let sets = bw.sets(group);
        let groups = sets
            .nodes
            .iter()
            .map(|nodes| SpectralGroup::of(&BandGroups::opts(bw, nodes), true))
            .collect();
        BandGroups { sets, groups }
    }

    fn opts<'a>(bw: &'a BandWalks, nodes: &[usize]) -> Vec<&'a OpticalState> {
        nodes.iter().map(|&n| &bw.nodes[n]).collect()
    }

    /// The set sample `s` of measure `im` walks.
    fn set_of(&self, exp: &Experiment, im: usize, s: u64) -> usize {
        self.sets.at(BandDraws::draw(exp.seed, im, s))
    }
}

fn walks(exp: &Experiment) -> &BandWalks {
    exp.bands.as_ref().expect("band blocks of a run with bands")
}

/// The samples `range` of cell `cell` of measure `im`, bands `group`: one accumulator per band.
/// The samples are walked set by set (in set order, so the sums do not depend on the thread).
pub(super) fn run_block_bands(
    exp: &Experiment,
    bg: &BandGroups,
    group: &[usize],
    im: usize,
    cell: usize,
    range: std::ops::Range<u64>,
    pool: Option<&[SceneChannelTally]>,
) -> Vec<Accum> {
    let bw = walks(exp);
    let mut by_set: BTreeMap<usize, Vec<u64>> = BTreeMap::new();
    for s in range {
        by_set.entry(bg.set_of(exp, im, s)).or_default().push(s);
    }
    let key = GROUP_STREAM | group[0] as u64;
    let ones = vec![1.0; group.len()];
    let mut all = Accum::new(group.len());
    for (j, samples) in by_set {
        let (sg, factors) = (&bg.groups[j], &bg.sets.factors[j]);
        let opts = BandGroups::opts(bw, &bg.sets.nodes[j]);
        group_walks(
            &mut all,
            exp,
            sg,
            &opts,
            key,
            &ones,
            im,
            cell,
            samples,
            pool,
            Some(factors),
        );
    }
    split_cells(&all)
}

/// Entries `range` of the above-scene pool of ortho measure `im` over bands `group`: entry `s`
/// is walked with the set sample `s` draws (the same for every pixel).
pub(super) fn band_pool(
    exp: &Experiment,
    bg: &BandGroups,
    group: &[usize],
    im: usize,
    range: std::ops::Range<u64>,
) -> Vec<SceneChannelTally> {
    let bw = walks(exp);
    let key = POOL_STREAM | GROUP_STREAM | group[0] as u64;
    range
        .into_par_iter()
        .map(|s| {
            let j = bg.set_of(exp, im, s);
            let opts = BandGroups::opts(bw, &bg.sets.nodes[j]);
            pool_entry(exp, &bg.groups[j], &opts, key, im, s)
        })
        .collect()
}
