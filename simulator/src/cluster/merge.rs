//! `simulate merge OUT`: gather the shards of a plan.
//!
//! Checks, in order: the experiment and every input file it names hash as they did when the
//! plan was written (else the shards would mix two experiments); then every unit of every
//! shard is read from `OUT/shards/K/checkpoints` and must carry that hash. A shard with a
//! missing or foreign unit is reported with why (its exit status, a task that ended without
//! one: cancelled, out of time or memory, or still running; a task that never started) and
//! the log to read, and the error ends with the `sbatch` command that re-runs those shards
//! alone. When all are present the (wavelength, measure) results are assembled from their
//! units (`run/units.rs`), bit for bit as the unsplit run holds them.

use std::path::Path;

use super::manifest::Plan;
use crate::run::checkpoint;
use crate::run::units::{shard_units, Unit};
use crate::run::MeasureResult;
use engine::config::resolve::Experiment;

/// Why a shard is incomplete.
#[derive(Debug, PartialEq)]
pub struct Incomplete {
    pub shard: usize,
    /// Units of the shard without a valid checkpoint, of `units`.
    pub missing: usize,
    pub units: usize,
    /// Units whose checkpoint belongs to another experiment or other inputs.
    pub foreign: usize,
    /// What the task left: its exit status and log.
    pub reason: String,
}

impl std::fmt::Display for Incomplete {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "shard {}: {} of {} unit(s) missing",
            self.shard, self.missing, self.units
        )?;
        if self.foreign > 0 {
            write!(
                f,
                " ({} written for another experiment or other inputs)",
                self.foreign
            )?;
        }
        write!(f, "; {}", self.reason)
    }
}

/// The experiment hash stored in a checkpoint file, if it is one.
fn stored_hash(file: &Path) -> Option<String> {
    #[derive(serde::Deserialize)]
    struct Head {
        experiment_hash: String,
    }
    let text = std::fs::read_to_string(file).ok()?;
    serde_json::from_str::<Head>(&text)
        .ok()
        .map(|h| h.experiment_hash)
}

/// What shard `k`'s task left behind (see the module header).
fn task_state(out: &Path, k: usize) -> String {
    let log = super::shard_log(out, k);
    let status = super::shard_dir(out, k).join("status");
    let last_line = || {
        std::fs::read_to_string(&log)
            .ok()
            .and_then(|t| {
                t.lines()
                    .rev()
                    .find(|l| !l.trim().is_empty())
                    .map(String::from)
            })
            .map(|l| format!(", last line: \"{}\"", l.trim()))
            .unwrap_or_default()
    };
    match std::fs::read_to_string(&status) {
        Ok(s) if s.trim() == "0" => format!(
            "its task exited 0 but its checkpoints are not all there (removed? see {})",
            log.display()
        ),
        Ok(s) => format!(
            "its task failed with exit status {} (log {}{})",
            s.trim(),
            log.display(),
            last_line()
        ),
        Err(_) if log.exists() => format!(
            "its task ended without an exit status: cancelled, killed (time or memory limit) or still running (log {}{})",
            log.display(),
            last_line()
        ),
        Err(_) => format!("its task never started (no log {})", log.display()),
    }
}

/// Every unit's results, or the incomplete shards.
pub fn collect(
    out: &Path,
    plan: &Plan,
    exp: &Experiment,
) -> Result<Vec<(Unit, Vec<MeasureResult>)>, Vec<Incomplete>> {
    let key = &plan.experiment_hash;
    let mut found = Vec::new();
    let mut incomplete = Vec::new();
    for k in 0..plan.shards {
        let dir = super::shard_dir(out, k).join("checkpoints");
        let units = shard_units(exp, k, plan.shards);
        let (mut missing, mut foreign) = (0, 0);
        let mut bad = Vec::new();
        for u in &units {
            let rs: Result<Vec<Option<MeasureResult>>, _> = u
                .group
                .iter()
                .map(|&iw| checkpoint::load(&dir, exp, key, iw, u))
                .collect();
            let rs = match rs {
                Ok(rs) => rs.into_iter().collect::<Option<Vec<_>>>(),
                Err(e) => {
                    // An edited or damaged checkpoint: the shard must run again.
                    missing += 1;
                    bad.push(e.to_string());
                    continue;
                }
            };
            match rs {
                Some(rs) => found.push((u.clone(), rs)),
                None => {
                    missing += 1;
                    let other = u.group.iter().any(|&iw| {
                        stored_hash(&checkpoint::path(&dir, iw, u)).is_some_and(|h| h != *key)
                    });
                    foreign += other as usize;
                }
            }
        }
        if missing > 0 {
            incomplete.push(Incomplete {
                shard: k,
                missing,
                units: units.len(),
                foreign,
                reason: if bad.is_empty() {
                    task_state(out, k)
                } else {
                    bad.join("; ")
                },
            });
        }
    }
    if incomplete.is_empty() {
        Ok(found)
    } else {
        Err(incomplete)
    }
}

/// The error text for incomplete shards: one line each, then the command that re-runs them.
pub fn report(out: &Path, incomplete: &[Incomplete], shards: usize) -> String {
    let mut s = format!(
        "{} of {shards} shard(s) of the plan in {} are incomplete:\n",
        incomplete.len(),
        out.display()
    );
    for i in incomplete {
        s += &format!("  {i}\n");
    }
    let list: Vec<String> = incomplete.iter().map(|i| i.shard.to_string()).collect();
    s += &format!(
        "re-run them alone (completed units are kept): sbatch --array={} {}; then run `simulate merge {}` again",
        list.join(","),
        out.join(super::SCRIPT_FILE).display(),
        out.display()
    );
    s
}
