//! The run driver: for every wavelength and measure, split the samples into fixed blocks, run
//! them in parallel with rayon and merge the blocks' sums **in block order**. Block boundaries
//! and random streams depend only on sample indices, so the result is bit-identical for any
//! thread count.

use glam::DVec3;
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;

use crate::config::resolve::{Experiment, IntegratorKind};
use crate::frame::sample_cosine_hemisphere;
use crate::integrator::forward::{self, ForwardTargets};
use crate::integrator::{backward, Accum};
use crate::measure::{Measure, MeasureKind};
use crate::optics::OpticalState;
use crate::rng::Stream;

/// Samples per block (the unit of parallel work and of deterministic merging).
pub const BLOCK: u64 = 2048;

/// Which walk serves a measure.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    Forward,
    Backward,
}

impl Method {
    pub fn name(self) -> &'static str {
        match self {
            Method::Forward => "forward",
            Method::Backward => "backward",
        }
    }
}

/// Result of one measure at one wavelength: sums per cell.
#[derive(Clone, Debug)]
pub struct MeasureResult {
    pub measure: usize,
    pub wavelength: usize,
    pub method: Method,
    pub acc: Accum,
}

pub fn method_for(exp: &Experiment, m: &Measure) -> Method {
    match (exp.integrator.kind, &m.kind) {
        (_, MeasureKind::Radiancemeter { .. }) => Method::Backward,
        (IntegratorKind::Backward, _) => Method::Backward,
        _ => Method::Forward,
    }
}

/// Run the samples `range` of measure `im` at wavelength `iw` (one block).
fn run_block(exp: &Experiment, iw: usize, im: usize, cell: usize, range: std::ops::Range<u64>) -> Accum {
    let m = &exp.measures[im];
    let opt = &exp.optics[iw];
    let method = method_for(exp, m);
    let ids = [iw as u64, im as u64, cell as u64];
    match method {
        Method::Forward => {
            let (dirs, flux_tau): (&[DVec3], Option<f64>) = match &m.kind {
                MeasureKind::Distant { directions, .. } => (directions, None),
                MeasureKind::DistantFlux { altitude } => (&[], Some(opt.atmosphere.tau_at_altitude(*altitude))),
                MeasureKind::Radiancemeter { .. } => unreachable!("resolver forbids forward radiancemeters"),
            };
            let targets = ForwardTargets { directions: dirs, flux_tau };
            let mut acc = Accum::new(m.cell_count());
            forward::run_block(opt, exp.sun_dir, &targets, &exp.integrator, exp.seed, ids, range, &mut acc);
            acc
        }
        Method::Backward => {
            let mut acc = Accum::new(1);
            for s in range {
                let mut rng = Stream::new(exp.seed, [ids[0], ids[1], ids[2], s]);
                let (tau0, d0) = backward_start(opt, m, cell, &mut rng);
                let (a, b) = backward::walk(opt, exp.sun_dir, tau0, d0, &exp.integrator, &mut rng);
                acc.add(0, a, b);
            }
            acc
        }
    }
}

/// Starting optical depth and path direction of a backward sample.
fn backward_start(opt: &OpticalState, m: &Measure, cell: usize, rng: &mut Stream) -> (f64, DVec3) {
    match &m.kind {
        MeasureKind::Distant { directions, .. } => (0.0, -directions[cell]),
        MeasureKind::Radiancemeter { origin, look } => (opt.atmosphere.tau_at_altitude(origin.z), *look),
        MeasureKind::DistantFlux { altitude } => {
            let up = sample_cosine_hemisphere(rng.next_f64(), rng.next_f64());
            (opt.atmosphere.tau_at_altitude(*altitude), -up)
        }
    }
}

/// Run `exp` completely. `progress`: draw a progress bar on stderr.
pub fn run(exp: &Experiment, progress: bool) -> Vec<MeasureResult> {
    let total: u64 = exp
        .measures
        .iter()
        .map(|m| {
            let per = if method_for(exp, m) == Method::Forward { 1 } else { m.cell_count() as u64 };
            m.spp * per
        })
        .sum::<u64>()
        * exp.wavelengths.len() as u64;
    let bar = if progress {
        let b = ProgressBar::new(total);
        b.set_style(
            ProgressStyle::with_template("{msg:24} [{elapsed_precise}] {wide_bar} {percent:>3}% ({per_sec}, eta {eta})")
                .unwrap(),
        );
        b
    } else {
        ProgressBar::hidden()
    };
    let mut out = Vec::new();
    for iw in 0..exp.wavelengths.len() {
        for (im, m) in exp.measures.iter().enumerate() {
            bar.set_message(format!("{} @ {} nm", m.id, exp.wavelengths[iw]));
            out.push(run_measure(exp, iw, im, &bar));
        }
    }
    bar.finish_and_clear();
    out
}

/// Run one measure at one wavelength, in rounds when a target precision is set.
pub fn run_measure(exp: &Experiment, iw: usize, im: usize, bar: &ProgressBar) -> MeasureResult {
    let m = &exp.measures[im];
    let method = method_for(exp, m);
    let cells = m.cell_count();
    let walk_cells: Vec<usize> = if method == Method::Forward { vec![0] } else { (0..cells).collect() };
    let mut acc = Accum::new(cells);
    let mut done = 0u64;
    // Rounds: the whole budget at once, or growing rounds until the target is met.
    let mut next = match m.target_rel_stderr {
        None => m.spp,
        Some(_) => (16 * BLOCK).min(m.spp),
    };
    loop {
        let blocks: Vec<(usize, u64)> = walk_cells
            .iter()
            .flat_map(|&c| {
                let first = done.div_ceil(BLOCK);
                let last = next.div_ceil(BLOCK);
                (first..last).map(move |b| (c, b))
            })
            .collect();
        let parts: Vec<(usize, Accum)> = blocks
            .par_iter()
            .map(|&(c, b)| {
                let range = (b * BLOCK).max(done)..((b + 1) * BLOCK).min(next);
                let n = range.end - range.start;
                let a = run_block(exp, iw, im, c, range);
                bar.inc(n);
                (c, a)
            })
            .collect();
        for (c, part) in &parts {
            if method == Method::Forward {
                acc.merge(part);
            } else {
                acc.n[*c] += part.n[0];
                for k in 0..3 {
                    acc.sum[*c][k] += part.sum[0][k];
                    acc.sum2[*c][k] += part.sum2[0][k];
                }
            }
        }
        done = next;
        let reached = m.target_rel_stderr.is_some_and(|t| acc.max_rel_stderr() <= t);
        if done >= m.spp || reached {
            if reached && done < m.spp {
                let per = if method == Method::Forward { 1 } else { cells as u64 };
                bar.inc((m.spp - done) * per);
            }
            break;
        }
        next = (done * 2).min(m.spp);
    }
    MeasureResult { measure: im, wavelength: iw, method, acc }
}
