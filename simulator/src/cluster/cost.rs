//! What a shard will cost, from a short pilot timed by `simulate plan`.
//!
//! For every (wavelength group, measure) task, one block of samples (64 for images, 2048
//! otherwise; fewer if `spp` is smaller) is walked for up to 64 cells spread evenly over the
//! measure, on all the planning machine's threads, twice (the cheaper pass counts: the first
//! also pays for cold caches); CPU seconds per walk = the process's CPU time (`getrusage`: it
//! does not depend on other load on the machine) / walks. A unit then costs `spp × walks per
//! sample × that` (walks per sample: its cells for backward measures, 1 for forward ones, plus
//! the above-scene pool's `batch` walks for a pooled image, charged as whole walks; with
//! `target_rel_stderr`, `spp` is the cap, so the estimate is an upper bound). A shard's wall time on C CPUs is its CPU seconds / C.
//!
//! The time limit asked of Slurm is twice the heaviest shard's wall time plus twice the load
//! time plus 5 minutes (the pilot sees few pixels, and compute nodes differ from the planning
//! machine); the memory is 1.5 × (the planning process's peak resident memory after loading
//! the scene and the pilot + the heaviest shard's result sums), at least 256 MiB. Both can be
//! overridden on the command line.

use std::time::Instant;

use crate::run::units::Unit;
use crate::run::{method_for, Method};
use engine::config::resolve::Experiment;

/// Cells of measure `im` the pilot walks (at most 64, evenly spread).
fn pilot_cells(exp: &Experiment, im: usize) -> Vec<usize> {
    let m = &exp.measures[im];
    if method_for(exp, m) == Method::Forward {
        return vec![0];
    }
    let n = m.cell_count();
    let k = n.min(64);
    (0..k).map(|i| i * n / k).collect()
}

/// CPU seconds per walk of every task, indexed `[group][measure]` (group order of
/// `run::wavelength_groups`).
pub fn pilot(exp: &Experiment) -> Vec<Vec<f64>> {
    let threads = rayon::current_num_threads() as f64;
    crate::run::wavelength_groups(exp)
        .iter()
        .map(|group| {
            (0..exp.measures.len())
                .map(|im| {
                    let m = &exp.measures[im];
                    let cells = pilot_cells(exp, im);
                    let samples = m.block_size().min(m.spp).max(1);
                    // Twice, keeping the cheaper: the first pass also pays for cold caches
                    // and page faults in a freshly loaded scene.
                    let cpu = (0..2)
                        .map(|_| {
                            let (c0, t0) =
                                (engine::util::cpu_time::process_seconds(), Instant::now());
                            crate::run::pilot_blocks(exp, group, im, &cells, 0..samples);
                            let wall = t0.elapsed().as_secs_f64();
                            // Where the process's CPU time is unknown: wall × threads.
                            c0.zip(engine::util::cpu_time::process_seconds())
                                .map(|(a, b)| b - a)
                                .unwrap_or(wall * threads)
                        })
                        .fold(f64::INFINITY, f64::min);
                    cpu / (cells.len() as f64 * samples as f64)
                })
                .collect()
        })
        .collect()
}

/// Walks per sample of unit `u`.
fn walks(exp: &Experiment, u: &Unit) -> u64 {
    if method_for(exp, &exp.measures[u.measure]) == Method::Forward {
        1
    } else {
        u.cells.len() as u64
    }
}

/// Projected CPU seconds of unit `u` (`per_walk`: the pilot's figures).
pub fn unit_cpu_seconds(exp: &Experiment, per_walk: &[Vec<f64>], u: &Unit) -> f64 {
    let groups = crate::run::wavelength_groups(exp);
    let g = groups.iter().position(|g| *g == u.group).unwrap_or(0);
    let m = &exp.measures[u.measure];
    // A pooled image's unit also walks the above-scene pool for its samples (every tile of the
    // image recomputes it): `batch` short walks per sample, charged as whole walks (they end at
    // the scene's top, so this bounds them from above).
    let pool = if crate::run::pools_above_scene(exp, m) {
        engine::integrator::above_scene::batch(m.cell_count())
    } else {
        0
    };
    per_walk[g][u.measure] * (m.spp * (walks(exp, u) + pool)) as f64
}

/// Bytes of the result sums unit `u` holds (one accumulator per wavelength of its group).
pub fn unit_result_bytes(exp: &Experiment, u: &Unit) -> u64 {
    let m = &exp.measures[u.measure];
    let cells = if method_for(exp, m) == Method::Forward {
        m.cell_count()
    } else {
        u.cells.len()
    };
    let per_cell: u64 = if exp.polarized { 152 } else { 80 };
    cells as u64 * per_cell * u.group.len() as u64
}

/// Peak resident memory of this process so far (`VmHWM` of /proc/self/status), bytes; 0
/// where unknown.
pub fn peak_rss_bytes() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("VmHWM:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
        })
        .map(|kib| kib * 1024)
        .unwrap_or(0)
}

/// The time limit for a shard of `cpu_seconds` on `cpus` CPUs with `load_seconds` to load
/// (see the module header), as Slurm's `D-HH:MM:SS`.
pub fn time_limit(cpu_seconds: f64, cpus: usize, load_seconds: f64) -> String {
    let wall = cpu_seconds / cpus.max(1) as f64;
    let secs = (2.0 * wall + 2.0 * load_seconds + 300.0).ceil() as u64;
    let minutes = secs.div_ceil(60);
    let (d, h, m) = (minutes / 1440, (minutes / 60) % 24, minutes % 60);
    if d > 0 {
        format!("{d}-{h:02}:{m:02}:00")
    } else {
        format!("{h:02}:{m:02}:00")
    }
}

/// The memory to ask for (see the module header), as Slurm's `NNNM`.
pub fn memory_request(peak_rss: u64, results: u64) -> String {
    let mib = ((peak_rss + results) as f64 * 1.5 / (1 << 20) as f64).ceil() as u64;
    format!("{}M", mib.max(256))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_limits_read_as_slurm_durations() {
        assert_eq!(time_limit(0.0, 1, 0.0), "00:05:00");
        assert_eq!(time_limit(3600.0, 2, 30.0), "01:06:00");
        assert_eq!(time_limit(86400.0 * 4.0, 4, 0.0), "2-00:05:00");
    }

    #[test]
    fn memory_has_a_floor_and_a_margin() {
        assert_eq!(memory_request(0, 0), "256M");
        assert_eq!(memory_request(1 << 30, 0), "1536M");
    }
}
