//! `simulate plan EXPERIMENT --shards N -o OUT`: cut a run into N shards and write the plan
//! manifest and the Slurm job-array script (module header of `cluster`).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;

use super::cost;
use super::manifest::{Estimate, Plan, Resources};
use crate::run::units;
use engine::config::resolve::Experiment;
use engine::error::ConfigError;

/// The command line's choices.
pub struct Options {
    pub shards: usize,
    pub spp: Option<u64>,
    pub cpus_per_task: usize,
    /// Overrides of the measured memory and time (Slurm's own syntax).
    pub mem: Option<String>,
    pub time: Option<String>,
    pub partition: Option<String>,
    pub account: Option<String>,
    /// The `simulate` executable the tasks run.
    pub simulate: PathBuf,
}

fn invalid(path: &Path, key: &str, message: String) -> anyhow::Error {
    anyhow::Error::new(ConfigError::Invalid {
        path: path.to_path_buf(),
        key: key.into(),
        message,
    })
}

/// Most shards a plan accepts.
pub const MAX_SHARDS: usize = 1_000_000;

/// Plan `experiment` (as given, relative to the current folder) into `out` (absolute).
pub fn plan(experiment: &Path, out: &Path, o: &Options) -> anyhow::Result<Plan> {
    if o.shards == 0 {
        return Err(invalid(experiment, "--shards", "must be at least 1".into()));
    }
    if o.shards > MAX_SHARDS {
        // Checked before anything is sized by the count (per-shard lists, pixel tiles).
        return Err(invalid(
            experiment,
            "--shards",
            format!(
                "{} shards: at most {MAX_SHARDS} (Slurm's own array limit, MaxArraySize, is usually far lower)",
                o.shards
            ),
        ));
    }
    if o.cpus_per_task == 0 {
        return Err(invalid(
            experiment,
            "--cpus-per-task",
            "must be at least 1".into(),
        ));
    }
    for (what, v) in [
        ("--mem", &o.mem),
        ("--time", &o.time),
        ("--partition", &o.partition),
        ("--account", &o.account),
    ] {
        if let Some(v) = v {
            super::script::check_value(what, v).map_err(|m| invalid(experiment, what, m))?;
        }
    }
    let t0 = Instant::now();
    let exp = Experiment::load_with_spp(experiment, o.spp)?;
    let load_seconds = t0.elapsed().as_secs_f64();
    for (im, m) in exp.measures.iter().enumerate() {
        if m.is_image() && !units::tileable(&exp, im) && o.shards > 1 {
            tracing::info!(
                "measure \"{}\" is not cut into pixel tiles ({}): it stays one unit per wavelength, so merged results equal the unsplit run's",
                m.id,
                if m.target_rel_stderr.is_some() {
                    "it has target_rel_stderr, whose rounds are decided over the whole image"
                } else {
                    "its walks serve every pixel at once"
                }
            );
        }
    }
    let all = units::units(&exp, o.shards);
    if all.len() < o.shards {
        return Err(invalid(
            experiment,
            "--shards",
            format!(
                "{} shards for {} work unit(s): this experiment cannot be cut finer (image measures without target_rel_stderr are cut into pixel tiles; other measures are one unit per wavelength); use at most {} shards",
                o.shards,
                all.len(),
                all.len()
            ),
        ));
    }
    let mut per_shard = vec![Vec::new(); o.shards];
    for (k, u) in all.iter().enumerate() {
        per_shard[k % o.shards].push(u.clone());
    }
    tracing::info!(
        "{} work unit(s) over {} shard(s); timing a pilot",
        all.len(),
        o.shards
    );
    let per_walk = cost::pilot(&exp);
    let shard_cpu: Vec<f64> = per_shard
        .iter()
        .map(|us| {
            us.iter()
                .map(|u| cost::unit_cpu_seconds(&exp, &per_walk, u))
                .sum()
        })
        .collect();
    let results_bytes = per_shard
        .iter()
        .map(|us| us.iter().map(|u| cost::unit_result_bytes(&exp, u)).sum())
        .max()
        .unwrap_or(0);
    let peak = cost::peak_rss_bytes();
    let max_cpu = shard_cpu.iter().cloned().fold(0.0, f64::max);
    let resources = Resources {
        cpus_per_task: o.cpus_per_task,
        mem: o
            .mem
            .clone()
            .unwrap_or_else(|| cost::memory_request(peak, results_bytes)),
        time: o
            .time
            .clone()
            .unwrap_or_else(|| cost::time_limit(max_cpu, o.cpus_per_task, load_seconds)),
        partition: o.partition.clone(),
        account: o.account.clone(),
    };
    let workdir = std::env::current_dir().context("the current folder")?;
    let plan = Plan {
        simulator_version: crate::BUILD_ID.into(),
        experiment: experiment.to_path_buf(),
        workdir,
        experiment_hash: crate::run::checkpoint::experiment_hash(&exp),
        spp: o.spp,
        shards: o.shards,
        units: all.len(),
        units_per_shard: per_shard.iter().map(Vec::len).collect(),
        simulate: o.simulate.clone(),
        resources,
        estimate: Estimate {
            load_seconds,
            peak_rss_mib: peak as f64 / (1 << 20) as f64,
            results_mib: results_bytes as f64 / (1 << 20) as f64,
            max_shard_cpu_seconds: max_cpu,
            total_cpu_seconds: shard_cpu.iter().sum(),
            shard_cpu_seconds: shard_cpu.clone(),
        },
    };
    std::fs::create_dir_all(out.join("logs"))
        .with_context(|| format!("cannot create {}", out.join("logs").display()))?;
    crate::products::write_atomic(&out.join(super::PLAN_FILE), plan.to_text().as_bytes())?;
    let script = out.join(super::SCRIPT_FILE);
    crate::products::write_atomic(&script, super::script::text(&plan, out).as_bytes())?;
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&script, std::fs::Permissions::from_mode(0o755))
        .with_context(|| format!("cannot make {} executable", script.display()))?;
    Ok(plan)
}
