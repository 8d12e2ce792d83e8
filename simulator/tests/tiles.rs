//! Runs split into pixel tiles merge bit for bit (issue 19, item 1; `run/units.rs`).
//!
//! Rationale: every pixel's samples draw from streams keyed by pixel and sample index only, so
//! a shard that walks some pixels holds exactly the sums the unsplit run gives them; the
//! checkpoints of N shards, gathered in one folder, must assemble to results equal to the
//! unsplit run's in every bit, for shard counts that do and do not divide the tasks. An image
//! with `target_rel_stderr` (its rounds are decided over the whole image) is never tiled.
//! The same holds for an image walked over a wavelength group whose above-scene light is pooled
//! (`integrator.above_scene = "pooled"`): every tile recomputes the same pool entries.
//! `merge::collect` names a shard that left nothing.

mod common;

use common::bundles::{flat_plane, tmp, write_plane};
use common::experiment;

/// Walks of one wavelength each (`"auto"` would group the two wavelengths into one walk, and
/// these tests count the units of independent ones).
const INDEPENDENT: &str = "[integrator]\nspectral_walk = \"independent\"\n";

fn exp_text(bundle: &std::path::Path, extra: &str) -> String {
    format!(
        "seed = 3\n[spectral]\nwavelengths = [450.0, 650.0]\n[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = 0.3\n[illumination]\ntype = \"directional\"\nzenith = 30.0\nazimuth = 0.0\n[scene]\ntype = \"bundle\"\npath = \"{}\"\n[[measures]]\nid = \"img\"\ntype = \"ortho\"\npixel_size_m = 100.0\nspp = 16\n{extra}",
        bundle.display()
    )
}

#[test]
fn tiled_shards_merge_bit_for_bit() {
    let dir = tmp("tiles");
    let b = write_plane(&dir.join("bundle"), &flat_plane(1000.0, 0.0, -500.0, 0.2));
    let pooled = "[integrator]\nspectral_walk = \"alis\"\nabove_scene = \"pooled\"\n";
    for (variant, extra) in [("", INDEPENDENT), ("pooled", pooled)] {
        let exp = experiment(&exp_text(&b, extra));
        let unsplit = simulator::run::run(&exp, false);
        tiled_runs_equal(&dir.join(variant), &exp, &unsplit);
    }
}

fn tiled_runs_equal(
    dir: &std::path::Path,
    exp: &engine::config::Experiment,
    unsplit: &[simulator::run::MeasureResult],
) {
    let exp = exp.clone();
    for shards in [3usize, 4, 7] {
        let units = simulator::run::units::units(&exp, shards);
        assert!(
            units.len() >= shards,
            "{shards} shards: {} units",
            units.len()
        );
        assert!(units.iter().all(|u| u.tiles > 1), "images must be tiled");
        let all = dir.join(format!("all{shards}"));
        for k in 0..shards {
            let d = dir.join(format!("s{shards}_{k}"));
            let (part, _) = simulator::run::run_shard(&exp, false, &d, k, shards).unwrap();
            assert!(
                part.iter().any(Option::is_none),
                "one shard of {shards} must not hold every result"
            );
            std::fs::create_dir_all(&all).unwrap();
            for e in std::fs::read_dir(&d).unwrap() {
                let e = e.unwrap();
                std::fs::copy(e.path(), all.join(e.file_name())).unwrap();
            }
        }
        let (merged, resumed) = simulator::run::run_shard(&exp, false, &all, 0, 1).unwrap();
        assert_eq!(resumed, unsplit.len(), "{shards} shards: everything loaded");
        for (u, m) in unsplit.iter().zip(&merged) {
            let m = m.as_ref().expect("assembled from tiles");
            assert_eq!(u.acc, m.acc, "{shards} shards: wavelength {}", u.wavelength);
            assert!(u.acc.n.iter().all(|&n| n == 16));
        }
    }
}

#[test]
fn images_with_a_target_are_not_tiled() {
    let dir = tmp("tiles-target");
    let b = write_plane(&dir.join("bundle"), &flat_plane(1000.0, 0.0, -500.0, 0.2));
    let exp = experiment(&exp_text(
        &b,
        &format!("target_rel_stderr = 0.05\n{INDEPENDENT}"),
    ));
    let units = simulator::run::units::units(&exp, 5);
    assert_eq!(units.len(), 2);
    assert!(units.iter().all(|u| u.tiles == 1 && u.cells == (0..100)));
}

#[test]
fn merge_names_a_shard_that_left_nothing() {
    use simulator::cluster::manifest::{Estimate, Plan, Resources};
    let dir = tmp("tiles-merge");
    let b = write_plane(&dir.join("bundle"), &flat_plane(1000.0, 0.0, -500.0, 0.2));
    let exp = experiment(&exp_text(&b, INDEPENDENT));
    let out = dir.join("plan");
    let shards = 3;
    let plan = Plan {
        simulator_version: simulator::BUILD_ID.into(),
        experiment: "exp.toml".into(),
        workdir: dir.clone(),
        experiment_hash: simulator::run::checkpoint::experiment_hash(&exp),
        spp: None,
        shards,
        units: 6,
        units_per_shard: vec![2; 3],
        simulate: "simulate".into(),
        resources: Resources {
            cpus_per_task: 1,
            mem: "1G".into(),
            time: "00:10:00".into(),
            partition: None,
            account: None,
        },
        estimate: Estimate {
            load_seconds: 0.0,
            peak_rss_mib: 0.0,
            results_mib: 0.0,
            max_shard_cpu_seconds: 0.0,
            total_cpu_seconds: 0.0,
            shard_cpu_seconds: Vec::new(),
        },
    };
    for k in [0, 2] {
        let d = simulator::cluster::shard_dir(&out, k).join("checkpoints");
        simulator::run::run_shard(&exp, false, &d, k, shards).unwrap();
    }
    let bad = simulator::cluster::merge::collect(&out, &plan, &exp).unwrap_err();
    assert_eq!(bad.len(), 1);
    assert_eq!(bad[0].shard, 1);
    let text = simulator::cluster::merge::report(&out, &bad, shards);
    assert!(text.contains("shard 1: 2 of 2 unit(s) missing"), "{text}");
    assert!(text.contains("never started"), "{text}");
    assert!(text.contains("--array=1 "), "{text}");
    // Shard 1 run: everything merges and equals the unsplit run.
    let d = simulator::cluster::shard_dir(&out, 1).join("checkpoints");
    simulator::run::run_shard(&exp, false, &d, 1, shards).unwrap();
    let parts = simulator::cluster::merge::collect(&out, &plan, &exp).unwrap();
    let merged = simulator::run::gather(&exp, parts);
    for (u, m) in simulator::run::run(&exp, false).iter().zip(&merged) {
        assert_eq!(u.acc, m.as_ref().unwrap().acc);
    }
    // A plan of other inputs: every unit is foreign.
    let other = Plan {
        experiment_hash: "0000000000000000".into(),
        ..plan
    };
    let bad = simulator::cluster::merge::collect(&out, &other, &exp).unwrap_err();
    assert_eq!(bad.len(), 3);
    assert!(bad.iter().all(|i| i.foreign == i.units), "{bad:?}");
}
