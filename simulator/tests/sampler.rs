//! The quasi-random sampler's standard errors are honest (issue 17 item 2): with
//! `integrator.sampler = "sobol"` each cell's samples form 16 independently scrambled Sobol
//! sequences and the reported error is the scatter of their means (`accum.rs`). Over 20 seeds
//! of the plane-parallel reference workload (Rayleigh τ 0.5 over Lambertian 0.3, SZA 30°, five
//! principal-plane directions, 4096 samples), forward and backward, the RMS of
//! (value − mean over seeds)/reported error must be near 1 (0.75–1.3: a 100-value pooled
//! estimate, ±15 % sampling spread), and the reported error must be smaller than the random
//! sampler's (the variance gain shows in the error, so `target_rel_stderr` runs stop sooner).

mod common;
use common::*;

fn text(seed: u64, integrator: &str, sampler: &str) -> String {
    format!(
        r#"
seed = {seed}
[spectral]
wavelengths = [550.0]
[atmosphere]
type = "homogeneous"
optical_thickness = 0.5
phase = {{ type = "rayleigh" }}
[surface]
type = "lambertian"
reflectance = 0.3
[illumination]
type = "directional"
zenith = 30.0
[integrator]
type = "{integrator}"
sampler = "{sampler}"
[[measures]]
type = "mdistant"
id = "pp"
construct = "hplane"
azimuth = 0.0
zeniths = [-60.0, -30.0, 0.0, 30.0, 60.0]
spp = 4096
"#
    )
}

/// (values, reported errors) per seed and direction.
fn runs(integrator: &str, sampler: &str) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let mut vals = Vec::new();
    let mut errs = Vec::new();
    for seed in 1..=20 {
        let rows = run_rows(&experiment(&text(seed, integrator, sampler)));
        vals.push(rows.iter().map(|r| r.brf.unwrap().0).collect());
        errs.push(rows.iter().map(|r| r.brf.unwrap().1).collect());
    }
    (vals, errs)
}

#[test]
fn sobol_errors_are_honest_and_smaller() {
    for integrator in ["forward", "backward"] {
        let (v, e) = runs(integrator, "sobol");
        let (_, e_random) = runs(integrator, "random");
        let dirs = v[0].len();
        let mut z2 = 0.0;
        let mut count = 0.0;
        for d in 0..dirs {
            let mean = v.iter().map(|r| r[d]).sum::<f64>() / v.len() as f64;
            for (vals, errs) in v.iter().zip(&e) {
                z2 += ((vals[d] - mean) / errs[d]).powi(2);
                count += 1.0;
            }
        }
        // (value − mean of 20) has variance σ²·19/20.
        let rms = (z2 / count * 20.0 / 19.0).sqrt();
        let mean_err = |e: &Vec<Vec<f64>>| e.iter().flatten().sum::<f64>() / count;
        let gain = mean_err(&e_random) / mean_err(&e);
        println!("{integrator}: RMS z of Sobol results over seeds {rms:.3}; reported error random/Sobol {gain:.2}");
        assert!((0.75..1.3).contains(&rms), "{integrator}: RMS z {rms}");
        assert!(
            gain > 1.2,
            "{integrator}: Sobol's reported error is not smaller ({gain})"
        );
    }
}
