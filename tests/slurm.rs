//! A run split over a real Slurm and merged exactly (issue 19, item 3; docs/scaling.md).
//!
//! Runs `tests/slurm/run.sh` with the release binaries: it starts munged, slurmctld and slurmd
//! on this machine (one node, 2 CPUs, every state folder in a temporary folder;
//! `tests/slurm/cluster.sh`), submits the plan of the Grenoble ortho render in 4 shards
//! (`--spp 16`), merges, and compares every product byte for byte with an unsplit local run;
//! then cancels one array task while it runs, checks that `simulate merge` names it, re-runs it
//! alone and compares again. Needs root and Debian's `slurm-wlm` and `munge`
//! (`scripts/setup.sh` installs them): where Slurm cannot start, the test fails with the
//! reason. The only way to leave it out is to say so: `SIMULATOR_SKIP_SLURM=1` (it then prints
//! that it was skipped). Without the shared data folder (the Grenoble DEM) it is skipped with
//! a message, as the examples that read it are.

use e2e::{binary, repo_root, shared_dir, temp_dir};

#[test]
fn grenoble_render_split_over_slurm_merges_byte_for_byte() {
    if std::env::var_os("SIMULATOR_SKIP_SLURM").is_some_and(|v| v == "1") {
        eprintln!("SKIPPED: the Slurm test (SIMULATOR_SKIP_SLURM=1)");
        return;
    }
    let Some(shared) = shared_dir() else {
        eprintln!(
            "SKIPPED: the Slurm test needs the shared data folder beside the repository (the Grenoble DEM)"
        );
        return;
    };
    let root = repo_root();
    let (scenegen, simulate) = (binary("scenegen").unwrap(), binary("simulate").unwrap());
    let work = temp_dir("slurm");
    let t0 = std::time::Instant::now();
    let status = std::process::Command::new("bash")
        .arg(root.join("tests/slurm/run.sh"))
        .args([&simulate, &scenegen, &root, &shared, &work])
        .status()
        .expect("cannot start bash");
    eprintln!("slurm test: {:.0} s in all", t0.elapsed().as_secs_f64());
    assert!(
        status.success(),
        "tests/slurm/run.sh failed ({status}): its reason is printed above; the daemons' logs are in {}",
        work.join("cluster/log").display()
    );
    let _ = std::fs::remove_dir_all(&work);
}
