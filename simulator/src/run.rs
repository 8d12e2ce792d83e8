//! The run driver: for every wavelength and measure, split the samples into fixed blocks, run
//! them in parallel with rayon and merge the blocks' sums **in block order**. Block boundaries
//! and random streams depend only on sample indices, so the result is bit-identical for any
//! thread count. What a block walks (estimator, geometry, weight) is the engine's choice
//! (`engine::blocks`); this module schedules rounds, stores checkpoints and merges.

use std::sync::atomic::{AtomicBool, Ordering};

use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;

use engine::blocks::{PoolEntry, TaskWalks};
use engine::config::resolve::Experiment;
use engine::integrator::Accum;

pub use engine::accum::{MeasureResult, Method};
pub use engine::blocks::{method_for, pools_above_scene};

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
    let walks = TaskWalks::new(exp, group, im);
    cells
        .par_iter()
        .for_each(|&c| drop(walks.block(c, range.clone(), None)));
}

/// The run's progress bar (hidden when `progress` is false), counted in walks; a hidden bar
/// still counts (its `position` and `length`), for callers that draw progress themselves.
pub fn progress_bar(exp: &Experiment, progress: bool) -> ProgressBar {
    let total: u64 = exp
        .measures
        .iter()
        .map(|m| m.spp * engine::blocks::walks_per_sample(exp, m))
        .sum::<u64>()
        * exp.wavelengths.len() as u64;
    if !progress {
        let b = ProgressBar::hidden();
        b.set_length(total);
        return b;
    }
    if !std::io::IsTerminal::is_terminal(&std::io::stderr()) {
        // A log file or a batch job: no redrawn bar, plain lines at every 10 % instead.
        let b = ProgressBar::hidden();
        b.set_length(total);
        log_progress_lines(&b, "simulate", "walks");
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

/// For a hidden bar (stderr is not a terminal): a thread that writes a plain line to stderr
/// each time the count passes a tenth of the total, and at the end (`what: done/total unit
/// (elapsed s)`); it stops when the bar is finished or dropped.
pub fn log_progress_lines(b: &ProgressBar, what: &'static str, unit: &'static str) {
    let weak = b.downgrade();
    let t0 = std::time::Instant::now();
    let spawned = std::thread::Builder::new()
        .name("progress-lines".into())
        .spawn(move || {
            let mut next = 1u64;
            loop {
                std::thread::sleep(std::time::Duration::from_millis(200));
                let Some(b) = weak.upgrade() else { return };
                let (pos, len) = (b.position(), b.length().unwrap_or(0).max(1));
                let finished = b.is_finished() || pos >= len;
                if finished || pos * 10 >= next * len {
                    eprintln!(
                        "{what}: {pos}/{len} {unit} ({:.1} s)",
                        t0.elapsed().as_secs_f64()
                    );
                    next = pos * 10 / len + 1;
                }
                if finished {
                    return;
                }
            }
        });
    if let Err(e) = spawned {
        tracing::debug!("progress lines: {e}");
    }
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
    let out = run_unchecked(exp, bar, cancel)?;
    crate::heavy_tail::warn(exp, &out);
    Some(out)
}

/// [`run`] without the heavy-tail warnings, for callers that judge the combined error of many
/// small internal runs themselves (the temperature solver's sky runs).
pub fn run_without_tail_warnings(exp: &Experiment) -> Vec<MeasureResult> {
    run_unchecked(exp, &ProgressBar::hidden(), &NEVER)
        .expect("a run without cancellation completes")
}

fn run_unchecked(
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

pub use engine::spectral::wavelength_groups_of;

/// Every (wavelength group, measure) pair, group-major (wavelength-major without groups).
fn tasks(exp: &Experiment) -> Vec<(Vec<usize>, usize)> {
    wavelength_groups(exp)
        .into_iter()
        .flat_map(|g| (0..exp.measures.len()).map(move |im| (g.clone(), im)))
        .collect()
}

/// Photon sets a lamp image may grow to (`LampSums::grow`): 16 × `integrator.lamp_photons`.
const MAX_LAMP_SETS: u64 = 16;

/// The forward lamp photons' image of measure `im` at wavelength `iw`
/// (`integrator/lamp_photons.rs`): per cell of the measure, the sums over batches of the
/// (single, multiple, total) scores and of their squares. Batches are independent estimates of
/// the whole image ([`engine::blocks::LAMP_BATCHES`] per set, each with `lamp_photons` photons
/// per lamp), run in parallel and summed in batch order (thread-count independent).
struct LampSums {
    iw: usize,
    im: usize,
    batches: u64,
    s1: Vec<f64>,
    s2: Vec<f64>,
}

impl LampSums {
    fn new(exp: &Experiment, iw: usize, im: usize) -> Self {
        let cells = exp.measures[im].cell_count();
        LampSums {
            iw,
            im,
            batches: 0,
            s1: vec![0.0; 3 * cells],
            s2: vec![0.0; 3 * cells],
        }
    }

    /// One more set of batches.
    fn grow(&mut self, exp: &Experiment, cancel: &AtomicBool) {
        let t0 = std::time::Instant::now();
        let next: Vec<u64> = (self.batches..self.batches + engine::blocks::LAMP_BATCHES).collect();
        let cells = self.s1.len() / 3;
        // A few batches at a time: each holds a whole image.
        for chunk in next.chunks(rayon::current_num_threads().max(1)) {
            let parts: Vec<Vec<f64>> = chunk
                .par_iter()
                .map(|&b| {
                    if cancel.load(Ordering::Relaxed) {
                        return Vec::new();
                    }
                    engine::blocks::lamp_batch(exp, self.iw, self.im, b)
                })
                .collect();
            for part in parts.iter().filter(|p| !p.is_empty()) {
                for c in 0..cells {
                    let (a, b) = (part[2 * c], part[2 * c + 1]);
                    for (j, x) in [a, b, a + b].into_iter().enumerate() {
                        self.s1[3 * c + j] += x;
                        self.s2[3 * c + j] += x * x;
                    }
                }
            }
        }
        self.batches += engine::blocks::LAMP_BATCHES;
        tracing::info!(
            "measure `{}` at {} nm: lamps by forward photons, {} batches ({:.1} s)",
            exp.measures[self.im].id,
            exp.wavelengths[self.iw],
            self.batches,
            t0.elapsed().as_secs_f64()
        );
    }

    /// Mean and variance of the mean of component `j` (0 single, 1 multiple, 2 total) in
    /// measure cell `c`.
    fn mean_var(&self, c: usize, j: usize) -> (f64, f64) {
        let n = self.batches as f64;
        let m = self.s1[3 * c + j] / n;
        let var = ((self.s2[3 * c + j] / n - m * m) * n / (n - 1.0)).max(0.0) / n;
        (m, var)
    }

    /// Set `acc`'s added estimates (cells `tile` of the measure) to this image.
    fn apply(&self, acc: &mut Accum, tile: std::ops::Range<usize>) {
        use engine::accum::{MULTIPLE, SINGLE, TOTAL};
        acc.extra_mean.clear();
        acc.extra_var.clear();
        for (i, c) in tile.enumerate() {
            for (j, k) in [SINGLE, MULTIPLE, TOTAL].into_iter().enumerate() {
                let (m, v) = self.mean_var(c, j);
                acc.add_extra(i, k, m, v);
            }
        }
    }

    /// The `q`-quantile over the tile's cells of this image's own standard error relative to
    /// the cell's combined mean in `acc` (the walks cannot bring a cell's error below it).
    fn quantile_rel(&self, acc: &Accum, tile: std::ops::Range<usize>, q: f64) -> f64 {
        let r = tile
            .enumerate()
            .map(|(i, c)| {
                let e = self.mean_var(c, 2).1.sqrt();
                engine::accum::relative(acc.mean_stderr(i, engine::accum::TOTAL).0, e)
            })
            .collect();
        engine::accum::quantile(r, q)
    }
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
    let walks = TaskWalks::new(exp, group, im);
    let method = walks.method();
    let bs = m.block_size();
    let iw0 = group[0];
    // Rounds end on whole cycles of g-point blocks in CKD runs.
    let cycle = if exp.integrator.alis {
        1
    } else {
        exp.optics[iw0].g_states.len().max(1)
    };
    let unit = bs * cycle as u64;
    let first_cell = tile.start;
    let tile_cells = tile.clone();
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
    // Lamps by forward photons: one set of batches now; more where the photons' own error
    // keeps an image from its target (below).
    let mut lamps: Vec<LampSums> = Vec::new();
    if exp.lamp_photon_pixels(m).is_some() {
        for (acc, &iw) in accs.iter_mut().zip(group) {
            let mut l = LampSums::new(exp, iw, im);
            l.grow(exp, cancel);
            l.apply(acc, tile_cells.clone());
            lamps.push(l);
        }
    }
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
    let pooled = walks.pooled();
    let mut pool: Vec<PoolEntry> = Vec::new();
    loop {
        if let (true, Some(&end)) = (pooled, want.iter().max()) {
            if end > pool.len() as u64 {
                pool.extend(walks.pool(pool.len() as u64..end));
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
                    let a = walks.block(c, range, pooled.then_some(pool.as_slice()));
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
        // Per-output targets: each output's error in units of the tightest target.
        let scale = |k: usize| m.target_scale.get(group[k]).copied().unwrap_or(1.0);
        let rel = accs
            .iter()
            .enumerate()
            .map(|(k, acc)| {
                if m.is_image() {
                    acc.quantile_rel_stderr(m.target_fraction) / scale(k)
                } else {
                    acc.max_rel_stderr() / scale(k)
                }
            })
            .fold(0.0, f64::max);
        // A standard error that cannot be trusted (heavy tails, `heavy_tail.rs`) does not stop
        // the run early.
        let trusted = |accs: &[Accum]| {
            accs.iter()
                .all(|acc| (0..acc.n.len()).all(|c| acc.tail(c).is_none_or(|t| t.trusted())))
        };
        let reached = m.target_rel_stderr.is_some_and(|t| rel <= t) && trusted(&accs);
        // Lamp images whose photons alone are above the target at its quantile (the walks
        // cannot lower that part) get another set of photons, up to MAX_LAMP_SETS sets.
        if let (false, Some(t)) = (reached, m.target_rel_stderr) {
            for (k, (l, acc)) in lamps.iter_mut().zip(accs.iter_mut()).enumerate() {
                let own = l.quantile_rel(acc, tile_cells.clone(), m.target_fraction);
                if own > t * scale(k) && l.batches < MAX_LAMP_SETS * engine::blocks::LAMP_BATCHES {
                    l.grow(exp, cancel);
                    l.apply(acc, tile_cells.clone());
                }
            }
        }
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
                    .enumerate()
                    .map(|(k, acc)| acc.cell_rel_stderr(c) / scale(k))
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
            trusted(&accs),
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
pub mod input_digest;
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
                .collect::<Result<Vec<_>, _>>()?
                .into_iter()
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
