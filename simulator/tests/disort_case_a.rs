//! Regression against DISORT, case A (`shared/reference/caseA_disort_public.csv`, copied to
//! `tests/data/fixtures/`): a homogeneous conservative Rayleigh layer (τ = 0.1, 0.5) over a
//! Lambertian surface (0, 0.3), SZA 30° and 60°, TOA BRF in the principal and cross planes.
//!
//! Rationale: DISORT solves the same plane-parallel scalar problem deterministically (96
//! streams, error < 1e-7), so the Monte Carlo estimate must agree within its standard error.
//! Both integrators are tested: the forward walk on all 53 directions of every case, and the
//! backward walk on a subset (it costs one walk per direction).
//! Statistical test: `common::check_all` (|diff| ≤ 4.5σ + max(1e-5, 2e-4·ref)).

mod common;
use common::*;

struct RefRow {
    tau: f64,
    albedo: f64,
    sza: f64,
    raa: f64,
    vza: f64,
    value: f64,
}

fn load() -> Vec<RefRow> {
    let text =
        std::fs::read_to_string(data_dir().join("fixtures/caseA_disort_public.csv")).unwrap();
    text.lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let p = |i: usize| f[i].parse::<f64>().unwrap();
            RefRow {
                tau: p(2),
                albedo: p(3),
                sza: p(4),
                raa: p(6),
                vza: p(8),
                value: p(10),
            }
        })
        .collect()
}

fn cases(rows: &[RefRow]) -> Vec<(f64, f64, f64)> {
    let mut c: Vec<(f64, f64, f64)> = Vec::new();
    for r in rows {
        if !c.contains(&(r.tau, r.albedo, r.sza)) {
            c.push((r.tau, r.albedo, r.sza));
        }
    }
    c
}

fn experiment_text(tau: f64, albedo: f64, sza: f64, integrator: &str, measure: &str) -> String {
    let (integrator, estimator) = match integrator.split_once('+') {
        Some((i, e)) => (i, e),
        None => (integrator, "expected"),
    };
    format!(
        r#"
seed = 2024
[spectral]
wavelengths = [550.0]
[atmosphere]
type = "homogeneous"
optical_thickness = {tau:?}
phase = {{ type = "rayleigh" }}
[surface]
type = "lambertian"
reflectance = {albedo:?}
[illumination]
type = "directional"
zenith = {sza:?}
azimuth = 0.0
[integrator]
type = "{integrator}"
local_estimate = "{estimator}"
{measure}"#
    )
}

fn run_case(
    all: &[RefRow],
    (tau, albedo, sza): (f64, f64, f64),
    integrator: &str,
    spp: u64,
    every: usize,
) -> Result<(), String> {
    let rows: Vec<&RefRow> = all
        .iter()
        .filter(|r| (r.tau, r.albedo, r.sza) == (tau, albedo, sza))
        .step_by(every)
        .collect();
    // raa = φ_v − φ_s with the Sun at azimuth 0, so the view azimuth is raa.
    let vza: Vec<f64> = rows.iter().map(|r| r.vza).collect();
    let vaa: Vec<f64> = rows.iter().map(|r| r.raa).collect();
    let text = experiment_text(
        tau,
        albedo,
        sza,
        integrator,
        &mdistant_toml("toa", &vza, &vaa, spp),
    );
    let out = run_rows_light_tailed(&experiment(&text));
    let cmps: Vec<Cmp> = rows
        .iter()
        .zip(&out)
        .map(|(r, o)| {
            let (v, e) = o.brf.unwrap();
            Cmp {
                label: format!("vza {} raa {}", r.vza, r.raa),
                reference: r.value,
                value: v,
                stderr: e,
            }
        })
        .collect();
    check_all(
        &format!("caseA tau={tau} albedo={albedo} sza={sza} [{integrator}]"),
        &cmps,
    )
}

#[test]
fn forward_matches_disort_case_a() {
    let all = load();
    let errs: Vec<String> = cases(&all)
        .into_iter()
        .filter_map(|c| run_case(&all, c, "forward", 1_500_000, 1).err())
        .collect();
    assert!(errs.is_empty(), "{}", errs.join("\n"));
}

#[test]
fn backward_matches_disort_case_a() {
    let all = load();
    let errs: Vec<String> = cases(&all)
        .into_iter()
        .filter_map(|c| run_case(&all, c, "backward", 200_000, 6).err())
        .collect();
    assert!(errs.is_empty(), "{}", errs.join("\n"));
}

/// The classic point local estimate at sampled collisions (`local_estimate = "collision"`) is
/// an independent estimator of the same quantities: it must match DISORT too.
#[test]
fn collision_estimator_matches_disort_case_a() {
    let all = load();
    let picks = [(0.5, 0.3, 30.0), (0.1, 0.0, 60.0)];
    let mut errs = Vec::new();
    for c in picks {
        for (integrator, spp, every) in [
            ("forward+collision", 300_000, 1),
            ("backward+collision", 60_000, 6),
        ] {
            if let Err(e) = run_case(&all, c, integrator, spp, every) {
                errs.push(e);
            }
        }
    }
    assert!(errs.is_empty(), "{}", errs.join("\n"));
}
