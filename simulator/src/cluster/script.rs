//! The Slurm job-array script `OUT/job.sh` (submitted with `sbatch OUT/job.sh`; one shard
//! re-run alone with `sbatch --array=K OUT/job.sh`).
//!
//! Array task K changes to the plan's working folder, runs
//! `simulate -q run EXPERIMENT -o OUT/shards/K --shard K/N -j CPUS [--spp S]` and writes its
//! exit status to `OUT/shards/K/status` (atomically) when the run ends by itself; a task killed
//! by Slurm (cancelled, out of time or memory) leaves none, which `merge` reports. Completed
//! units of a shard are checkpoints, so a re-run resumes where the killed task stopped.

use std::path::Path;

use super::manifest::Plan;

/// Quote `s` for a POSIX shell (single quotes).
pub fn shell_quote(s: &str) -> String {
    format!("'{}'", s.replace('\'', "'\\''"))
}

/// A Slurm option value from the command line: no blanks, quotes or control characters
/// (they would break the `#SBATCH` line). `what` names the option in the error.
pub fn check_value(what: &str, v: &str) -> Result<(), String> {
    if v.is_empty()
        || v.chars()
            .any(|c| c.is_whitespace() || c.is_control() || c == '\'' || c == '"')
    {
        return Err(format!(
            "{what} \"{v}\" must be one word without blanks or quotes"
        ));
    }
    Ok(())
}

/// The script's text for `plan`, whose folder is `out` (absolute).
pub fn text(plan: &Plan, out: &Path) -> String {
    let r = &plan.resources;
    let n = plan.shards;
    let name: String = plan
        .experiment
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "run".into())
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    let mut s = String::from("#!/bin/bash\n");
    s += &format!("#SBATCH --job-name=simulate-{name}\n");
    s += &format!("#SBATCH --array=0-{}\n", n - 1);
    s += "#SBATCH --ntasks=1\n";
    s += &format!("#SBATCH --cpus-per-task={}\n", r.cpus_per_task);
    s += &format!("#SBATCH --mem={}\n", r.mem);
    s += &format!("#SBATCH --time={}\n", r.time);
    s += &format!(
        "#SBATCH --output={}\n",
        out.join("logs").join("shard_%a.log").display()
    );
    if let Some(p) = &r.partition {
        s += &format!("#SBATCH --partition={p}\n");
    }
    if let Some(a) = &r.account {
        s += &format!("#SBATCH --account={a}\n");
    }
    s += &format!(
        "#\n# Written by `simulate plan` (docs/scaling.md): {n} shard(s), {} work unit(s).\n",
        plan.units
    );
    s += &format!(
        "# Submit: sbatch {0}\n# Re-run shard K alone: sbatch --array=K {0}\n# Then: simulate merge {1}\n",
        out.join(super::SCRIPT_FILE).display(),
        out.display()
    );
    s += "set -u\n";
    s += "K=\"${SLURM_ARRAY_TASK_ID:?run this script with sbatch: it is a job array}\"\n";
    s += &format!("OUT={}\n", shell_quote(&out.to_string_lossy()));
    s += "D=\"$OUT/shards/$K\"\n";
    s += "mkdir -p \"$D\" || exit 1\n";
    s += "rm -f \"$D/status\"\n";
    s += &format!(
        "cd {} || exit 1\n",
        shell_quote(&plan.workdir.to_string_lossy())
    );
    let spp = plan.spp.map(|v| format!(" --spp {v}")).unwrap_or_default();
    s += &format!(
        "{} -q run {} -o \"$D\" --shard \"$K/{n}\" -j \"${{SLURM_CPUS_PER_TASK:-1}}\"{spp}\n",
        shell_quote(&plan.simulate.to_string_lossy()),
        shell_quote(&plan.experiment.to_string_lossy()),
    );
    s += "rc=$?\n";
    s += "echo \"$rc\" > \"$D/status.tmp\" && mv \"$D/status.tmp\" \"$D/status\"\n";
    s += "exit \"$rc\"\n";
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quotes_survive_the_shell() {
        assert_eq!(shell_quote("a b"), "'a b'");
        assert_eq!(shell_quote("it's"), "'it'\\''s'");
    }

    #[test]
    fn values_with_blanks_are_refused() {
        assert!(check_value("--mem", "8G").is_ok());
        assert!(check_value("--mem", "8 G").is_err());
        assert!(check_value("--partition", "a\nb").is_err());
        assert!(check_value("--time", "").is_err());
    }
}
