//! The plan manifest `OUT/plan.toml`: what `simulate plan` decided and measured, read back by
//! `simulate merge` (which refuses a manifest of another simulator version, or an experiment
//! or input files that changed since the plan).

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

/// Resources each array task asks Slurm for.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Resources {
    /// `--cpus-per-task`.
    pub cpus_per_task: usize,
    /// `--mem`, as Slurm reads it (e.g. `1200M`, `8G`).
    pub mem: String,
    /// `--time`, as Slurm reads it (e.g. `00:20:00`, `1-00:00:00`).
    pub time: String,
    /// `--partition`, if given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub partition: Option<String>,
    /// `--account`, if given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub account: Option<String>,
}

/// What the pilot measured and the plan projects per shard (`cost.rs`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Estimate {
    /// Seconds to load and resolve the experiment (scene included), once per task.
    pub load_seconds: f64,
    /// Peak resident memory of the planning process after loading and the pilot, MiB.
    pub peak_rss_mib: f64,
    /// Result memory of the heaviest shard, MiB.
    pub results_mib: f64,
    /// Projected CPU seconds of transport of the heaviest shard (at full `spp`).
    pub max_shard_cpu_seconds: f64,
    /// Projected CPU seconds of transport of the whole run.
    pub total_cpu_seconds: f64,
    /// Projected CPU seconds of transport of each shard.
    #[serde(default)]
    pub shard_cpu_seconds: Vec<f64>,
}

/// The manifest.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    /// Build of the simulator that wrote the plan ([`crate::BUILD_ID`]: version and source
    /// digest; shards and merge must run the same).
    pub simulator_version: String,
    /// The experiment file as given to `simulate plan` (relative to `workdir`).
    pub experiment: PathBuf,
    /// The folder `simulate plan` ran in: tasks and `merge` read the experiment from there.
    pub workdir: PathBuf,
    /// Hash of the experiment text, the build ([`crate::BUILD_ID`]) and every input file (as in
    /// checkpoints).
    pub experiment_hash: String,
    /// The `--spp` override of every measure, if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spp: Option<u64>,
    /// Number of shards (array tasks).
    pub shards: usize,
    /// Number of work units, and of those in each shard.
    pub units: usize,
    pub units_per_shard: Vec<usize>,
    /// The `simulate` executable the tasks run.
    pub simulate: PathBuf,
    pub resources: Resources,
    pub estimate: Estimate,
}

impl Plan {
    /// Read `OUT/plan.toml`; errors name the file (bad input: exit 2).
    pub fn read(out: &Path) -> Result<Plan, engine::error::ConfigError> {
        let path = out.join(super::PLAN_FILE);
        let bad = |message: String| engine::error::ConfigError::Parse {
            path: path.clone(),
            message,
        };
        let text = std::fs::read_to_string(&path).map_err(|e| {
            bad(format!(
                "{e} (is {} a folder written by `simulate plan`?)",
                out.display()
            ))
        })?;
        let plan: Plan = toml::from_str(&text).map_err(|e| bad(e.to_string()))?;
        if plan.shards == 0 || plan.units_per_shard.len() != plan.shards {
            return Err(bad(format!(
                "shards = {} but units_per_shard has {} entries",
                plan.shards,
                plan.units_per_shard.len()
            )));
        }
        Ok(plan)
    }

    /// The manifest's text, with a header saying what wrote it.
    pub fn to_text(&self) -> String {
        let body = toml::to_string_pretty(self).expect("a plan serialises");
        format!("# Written by `simulate plan`; read by `simulate merge` (docs/scaling.md).\n{body}")
    }

    /// The experiment file's path as the tasks and `merge` open it.
    pub fn experiment_path(&self) -> PathBuf {
        self.workdir.join(&self.experiment)
    }
}
