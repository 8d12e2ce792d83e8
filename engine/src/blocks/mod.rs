//! One block of samples: where the estimator, the medium geometry and the path weight are
//! chosen for a (measure, wavelength or wavelength group) task, once per block; everything
//! below is monomorphised. The application's driver (`simulator::run`) decides which blocks
//! run, in which rounds, and merges their sums in block order; it never names an estimator,
//! a geometry or a weight.
//!
//! | file | job |
//! |---|---|
//! | `mod.rs` | [`TaskWalks`], the one entry point: what a task builds once (spectral ALIS group tables, CKD ALIS tables), its blocks and its above-scene pool; [`method_for`] |
//! | `single.rs` | one wavelength (and its CKD g-points): forward or backward, scalar or polarized, layers, shells or a scene |
//! | `spectral.rs` | spectral ALIS groups: one walk carries every wavelength of a group; the above-scene pool |
//! | `bands.rs` | sensor bands (`spectral.bands`): each sample walks the set of band nodes its index draws |
//! | `lamp_photons.rs` | one batch of forward lamp photons for a nadir ortho image |
//! | `walks.rs` | the backward block loop shared by all (`backward_block`): streams, first-order splits, the Moon beside the Sun |
//! | `streams.rs` | the random streams of samples, split walks, the Moon, groups and pools |
//!
//! Block boundaries and random streams depend only on sample indices, so a block's sums do not
//! depend on the thread that runs it.

mod bands;
mod lamp_photons;
mod single;
mod spectral;
mod streams;
mod walks;

use crate::accum::Accum;
use crate::config::resolve::Experiment;
use crate::integrator::settings::IntegratorKind;
use crate::measure::{Measure, MeasureKind};

pub use crate::accum::Method;
/// One entry of an above-scene pool (`integrator/above_scene.rs`): the mean score of a batch
/// of walks that end where they first go below the scene's top.
pub use crate::integrator::scene_alis::SceneChannelTally as PoolEntry;

use bands::{band_pool, run_block_bands, BandGroups};
pub use lamp_photons::{lamp_batch, LAMP_BATCHES};
use single::{alis_layers, run_block};
use spectral::{above_scene_pool, run_block_spectral, SpectralGroup};

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
    // Every kind is named, so a new measure kind is a compile error here until its estimator
    // is chosen.
    match (exp.integrator.kind, &m.kind) {
        (_, MeasureKind::Radiancemeter { .. } | MeasureKind::Hdrf { .. }) => Method::Backward,
        (IntegratorKind::Backward, _) => Method::Backward,
        (
            IntegratorKind::Auto | IntegratorKind::Forward,
            MeasureKind::Distant { .. }
            | MeasureKind::Ortho(_)
            | MeasureKind::Perspective(_)
            | MeasureKind::DistantFlux { .. },
        ) => Method::Forward,
    }
}

/// Walks a measure costs per sample index (a forward walk serves every direction).
pub fn walks_per_sample(exp: &Experiment, m: &Measure) -> u64 {
    if method_for(exp, m) == Method::Forward {
        1
    } else {
        m.cell_count() as u64
    }
}

/// Whether ortho measure `m` of a run with wavelength groups pools the light of the atmosphere
/// above the scene (`integrator.above_scene`, `integrator/above_scene.rs`).
pub fn pools_above_scene(exp: &Experiment, m: &Measure) -> bool {
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

/// The walks of one task: measure `im` at the wavelengths of `group` (one wavelength, or a
/// spectral ALIS group whose walks serve all of them), with what they share built once: the
/// group's reference atmosphere and layer tables, or a CKD bin's ALIS tables.
pub struct TaskWalks<'e> {
    exp: &'e Experiment,
    group: Vec<usize>,
    im: usize,
    spectral: Option<SpectralGroup>,
    /// Runs with sensor bands: the group's walks per set of band nodes.
    bands: Option<BandGroups>,
    ckd_alis: Option<crate::integrator::backward_alis::Layers>,
}

impl<'e> TaskWalks<'e> {
    /// The task (measure `im`, wavelength indices `group`: one index unless the run walks
    /// spectral ALIS groups).
    pub fn new(exp: &'e Experiment, group: &[usize], im: usize) -> Self {
        let bands = exp.bands.as_ref().map(|bw| BandGroups::new(bw, group));
        let spectral = match bands {
            Some(_) => None,
            None => exp
                .integrator
                .spectral_alis
                .map(|_| SpectralGroup::new(exp, group)),
        };
        assert!(spectral.is_some() || bands.is_some() || group.len() == 1);
        TaskWalks {
            exp,
            group: group.to_vec(),
            im,
            spectral,
            bands,
            ckd_alis: alis_layers(exp, group[0]),
        }
    }

    /// The estimator of the task's measure ([`method_for`]).
    pub fn method(&self) -> Method {
        method_for(self.exp, &self.exp.measures[self.im])
    }

    /// Whether the task's blocks take the light above the scene from a pool
    /// ([`pools_above_scene`]; only spectral groups pool).
    pub fn pooled(&self) -> bool {
        (self.spectral.is_some() || self.bands.is_some())
            && pools_above_scene(self.exp, &self.exp.measures[self.im])
    }

    /// Entries `range` of the task's above-scene pool (entry `s` serves sample `s` of every
    /// pixel), on streams keyed by the group, the measure and the sample, not the pixel. Empty
    /// when the task does not pool.
    pub fn pool(&self, range: std::ops::Range<u64>) -> Vec<PoolEntry> {
        if !self.pooled() {
            return Vec::new();
        }
        match (&self.spectral, &self.bands) {
            (Some(sg), _) => above_scene_pool(self.exp, sg, &self.group, self.im, range),
            (_, Some(bg)) => band_pool(self.exp, bg, &self.group, self.im, range),
            _ => Vec::new(),
        }
    }

    /// The samples `range` of cell `cell` (a pixel or direction of a backward measure; cell 0
    /// of a forward one, whose walks serve every cell): one accumulator per wavelength of the
    /// group. `pool`: the task's pool entries from 0 to at least `range.end` when
    /// [`pooled`](Self::pooled), None for whole walks.
    pub fn block(
        &self,
        cell: usize,
        range: std::ops::Range<u64>,
        pool: Option<&[PoolEntry]>,
    ) -> Vec<Accum> {
        if let Some(bg) = &self.bands {
            return run_block_bands(self.exp, bg, &self.group, self.im, cell, range, pool);
        }
        match &self.spectral {
            Some(sg) => run_block_spectral(self.exp, sg, &self.group, self.im, cell, range, pool),
            None => vec![run_block(
                self.exp,
                self.group[0],
                self.im,
                cell,
                range,
                self.ckd_alis.as_ref(),
            )],
        }
    }
}
