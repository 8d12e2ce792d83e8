//! Runs split over a Slurm cluster (`simulate plan`, `simulate merge`; docs/scaling.md).
//!
//! `plan` resolves the experiment, cuts it into work units (`run/units.rs`) and shards, times
//! a short pilot to size the jobs (`cost.rs`), and writes into its folder OUT the plan manifest
//! `plan.toml` (`manifest.rs`) and a Slurm job-array script `job.sh` (`script.rs`): array task
//! K runs `simulate run --shard K/N` into `OUT/shards/K` and leaves its exit status in
//! `OUT/shards/K/status`. `merge` (`merge.rs`) checks that every shard's units are present and
//! belong to the planned experiment and inputs, names the shards that are missing or failed
//! (with the `sbatch` command that re-runs them alone), and gathers the results, from which the
//! products are written exactly as an unsplit run writes them (bit-identical).

pub mod cost;
pub mod manifest;
pub mod merge;
pub mod plan;
pub mod script;

/// The plan manifest's file name in the plan folder.
pub const PLAN_FILE: &str = "plan.toml";
/// The job-array script's file name in the plan folder.
pub const SCRIPT_FILE: &str = "job.sh";

/// Folder of shard `k` in plan folder `out`.
pub fn shard_dir(out: &std::path::Path, k: usize) -> std::path::PathBuf {
    out.join("shards").join(k.to_string())
}

/// Slurm log of shard `k` in plan folder `out`.
pub fn shard_log(out: &std::path::Path, k: usize) -> std::path::PathBuf {
    out.join("logs").join(format!("shard_{k}.log"))
}
