//! Shared helpers of the system and benchmark tests.
#![allow(dead_code)]

pub mod artdeco;
pub mod bundles;

use std::path::{Path, PathBuf};

use engine::config::Experiment;
use simulator::products::{rows, Row};

pub fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data")
}

/// The eradiate v0 CKD file of the shared data folder (`SIMULATOR_SHARED_DATA` or
/// `../shared/data`), if present.
pub fn ckd_v0_file() -> Option<PathBuf> {
    let p = std::env::var_os("SIMULATOR_SHARED_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data"))
        .join("ckd/eradiate_v0_ckd/afgl1986-us_standard-10nm.nc");
    p.exists().then_some(p)
}

pub fn experiment(text: &str) -> Experiment {
    // Relative paths in test experiments are taken from tests/data.
    Experiment::from_str(text, &data_dir().join("test.toml"))
        .unwrap_or_else(|e| panic!("{e}\n{text}"))
}

pub fn run_rows(exp: &Experiment) -> Vec<Row> {
    let res = simulator::run::run(exp, false);
    rows(exp, &res)
}

/// [`run_rows`], asserting that the heavy-tail check (`simulator::heavy_tail`) finds nothing:
/// for reference cases whose standard errors must be trustworthy.
pub fn run_rows_light_tailed(exp: &Experiment) -> Vec<Row> {
    let res = simulator::run::run(exp, false);
    let tails = simulator::heavy_tail::check(exp, &res);
    assert!(
        tails.is_empty(),
        "heavy-tail warnings on a reference case: {}",
        tails
            .iter()
            .map(|t| t.to_string())
            .collect::<Vec<_>>()
            .join("; ")
    );
    rows(exp, &res)
}

/// One comparison of a Monte Carlo value with a reference value.
#[derive(Clone, Debug)]
pub struct Cmp {
    pub label: String,
    pub reference: f64,
    pub value: f64,
    pub stderr: f64,
}

/// The statistical test used by every reference comparison:
/// pass when |value − reference| ≤ K·stderr + max(ABS_FLOOR, REL_FLOOR·|reference|).
/// K = 4.5 keeps the chance of a false alarm below 1e-3 over the few hundred comparisons of a
/// test (seeds are fixed, so a result is reproducible either way); the floors cover the
/// references' own discretisation error (DISORT: < 1e-6 relative; tables are printed with 10
/// digits) and float noise.
pub const K: f64 = 4.5;
pub const ABS_FLOOR: f64 = 1e-5;
pub const REL_FLOOR: f64 = 2e-4;

pub fn check_all(case: &str, cmps: &[Cmp]) -> Result<(), String> {
    let mut worst_rel: f64 = 0.0;
    let mut worst_z: f64 = 0.0;
    let mut failures = Vec::new();
    for c in cmps {
        let diff = (c.value - c.reference).abs();
        let tol = K * c.stderr + ABS_FLOOR.max(REL_FLOOR * c.reference.abs());
        let rel = if c.reference != 0.0 {
            diff / c.reference.abs()
        } else {
            diff
        };
        worst_rel = worst_rel.max(rel);
        if c.stderr > 0.0 {
            worst_z = worst_z.max(diff / c.stderr);
        }
        #[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN must fail
        if !(diff <= tol) {
            failures.push(format!(
                "  {}: value {:.6e} ± {:.2e}, reference {:.6e}, |diff| {:.2e} > tol {:.2e} (z = {:.1})",
                c.label,
                c.value,
                c.stderr,
                c.reference,
                diff,
                tol,
                diff / c.stderr
            ));
        }
    }
    let med_se = {
        let mut v: Vec<f64> = cmps
            .iter()
            .map(|c| c.stderr / c.reference.abs().max(1e-12))
            .collect();
        v.sort_by(|a, b| a.partial_cmp(b).unwrap());
        v.get(v.len() / 2).copied().unwrap_or(0.0)
    };
    println!(
        "{case}: {} comparisons, max |rel diff| = {:.3e}, max z = {:.2}, median rel stderr = {:.2e}",
        cmps.len(),
        worst_rel,
        worst_z,
        med_se
    );
    if failures.is_empty() {
        Ok(())
    } else {
        Err(format!(
            "{case}: {} of {} comparisons failed:\n{}",
            failures.len(),
            cmps.len(),
            failures.join("\n")
        ))
    }
}

/// `f` run in a rayon pool of `threads` threads (thread-count independence tests).
pub fn with_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

/// `exp` run with 1 and with 2 threads.
pub fn run_on_1_and_2_threads(
    exp: &Experiment,
) -> (
    Vec<simulator::run::MeasureResult>,
    Vec<simulator::run::MeasureResult>,
) {
    let run = |n| with_threads(n, || simulator::run::run(exp, false));
    (run(1), run(2))
}

/// [`check_all`] on the BRFs of two independent runs' rows, row by row (same measures and
/// directions), with the combined standard error of both.
pub fn compare_brf_rows(case: &str, a: &[Row], b: &[Row]) -> Result<(), String> {
    assert_eq!(a.len(), b.len());
    let cmps: Vec<Cmp> = a
        .iter()
        .zip(b)
        .map(|(x, y)| {
            let (va, ea) = x.brf.unwrap();
            let (vb, eb) = y.brf.unwrap();
            Cmp {
                label: format!("vza {:?} vaa {:?}", x.vza, x.vaa),
                reference: vb,
                value: va,
                stderr: (ea * ea + eb * eb).sqrt(),
            }
        })
        .collect();
    check_all(case, &cmps)
}

/// An `mdistant` measure TOML listing explicit directions.
pub fn mdistant_toml(id: &str, vza: &[f64], vaa: &[f64], spp: u64) -> String {
    directions_toml("mdistant", id, vza, vaa, spp)
}

/// A `[[measures]]` table of type `kind` (`mdistant`, `hdrf`) over explicit directions.
pub fn directions_toml(kind: &str, id: &str, vza: &[f64], vaa: &[f64], spp: u64) -> String {
    let z: Vec<String> = vza.iter().map(|v| format!("{v:?}")).collect();
    let a: Vec<String> = vaa.iter().map(|v| format!("{v:?}")).collect();
    format!(
        "[[measures]]\nid = \"{id}\"\ntype = \"{kind}\"\nconstruct = \"directions\"\nzeniths = [{}]\nazimuths = [{}]\nspp = {spp}\n",
        z.join(", "),
        a.join(", ")
    )
}
