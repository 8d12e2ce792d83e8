//! Adaptive rounds of image measures with a target (`run.rs`; `target_fraction`, `adaptive`):
//! after the first round only the pixels above the target are sampled.
//!
//! * `every_pixel_target_is_met_and_unbiased`: a flat uniform Lambertian bundle under a hazy
//!   layer, a 20 × 20 ortho image at 0 and 30° view with `target_fraction = 1`: every pixel ends
//!   at or below the target, the pixels' sample counts differ (the run really is adaptive), and
//!   the pixels estimate the 1D value of the same surface and atmosphere (independent
//!   reference: a plane-parallel backward run of 2·10⁶ samples per direction, whose standard
//!   error is a small part of the image mean's). Stopping a pixel on its own estimated error
//!   biases it by a small part of its standard error (docs/experiment.md): over 400 pixels the
//!   image mean's z-score must stay within 4.5, and the bias per pixel within 0.2 of a pixel's
//!   standard error.
//! * `fraction_and_uniform_rounds`: `target_fraction = 0.9` stops once 90 % of the pixels meet
//!   the target, not all; `adaptive = false` gives every pixel the same count; a target out of
//!   reach gives every pixel all of `spp`.
//! * `config_errors`: out-of-range `target_fraction`, and either key without a target.

mod common;

use common::bundles::{flat_plane, tmp, write_plane};
use common::{experiment, run_rows};

const ATM: &str = "[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = 0.2\nphase = { type = \"hg\", g = 0.5 }";

fn head(seed: u64) -> String {
    format!(
        "seed = {seed}\n[spectral]\nwavelengths = [550.0]\n[illumination]\ntype = \"directional\"\nzenith = 35.0\nazimuth = 40.0\n{ATM}\n"
    )
}

fn image(exp: &engine::config::Experiment) -> simulator::products::imagery::ImageProduct {
    let res = simulator::run::run(exp, false);
    simulator::products::imagery::image_products(exp, &res)
        .pop()
        .expect("one image")
}

#[test]
fn every_pixel_target_is_met_and_unbiased() {
    let dir = tmp("adaptive-flat");
    let b = write_plane(&dir, &flat_plane(2000.0, 0.0, -1000.0, 0.3));
    for (zenith, azimuth) in [(0.0, 0.0), (30.0, 120.0)] {
        let exp = experiment(&format!(
            "{}[scene]\ntype = \"bundle\"\npath = \"{}\"\n[[measures]]\nid = \"img\"\ntype = \"ortho\"\npixel_size_m = 100.0\nzenith = {zenith:?}\nazimuth = {azimuth:?}\nspp = 100000\ntarget_rel_stderr = 0.01\ntarget_fraction = 1.0\n",
            head(5),
            b.display()
        ));
        let p = image(&exp);
        let n = p.width * p.height;
        assert_eq!(n, 400);
        let rel: Vec<f64> = (0..n).map(|c| p.brf_stderr[0][c] / p.brf[0][c]).collect();
        let worst = rel.iter().copied().fold(0.0, f64::max);
        assert!(worst <= 0.01, "worst pixel error {worst}");
        let counts = &p.pixel_samples[0];
        let (lo, hi) = (
            counts.iter().min().copied().unwrap(),
            counts.iter().max().copied().unwrap(),
        );
        assert_eq!(lo, p.n_samples[0]);
        assert!(hi > lo, "every pixel got {lo} samples: not adaptive");
        // The 1D reference.
        let r1 = run_rows(&experiment(&format!(
            "{}[surface]\ntype = \"lambertian\"\nreflectance = 0.3\n[integrator]\ntype = \"backward\"\n[[measures]]\nid = \"d\"\ntype = \"mdistant\"\nconstruct = \"directions\"\nzeniths = [{zenith:?}]\nazimuths = [{azimuth:?}]\nspp = 2000000\n",
            head(6)
        )));
        let (mu, mu_se) = r1[0].brf.unwrap();
        let mean = p.brf[0].iter().sum::<f64>() / n as f64;
        let se = (p.brf_stderr[0].iter().map(|e| e * e).sum::<f64>()).sqrt() / n as f64;
        let z = (mean - mu) / (se * se + mu_se * mu_se).sqrt();
        let mut sig: Vec<f64> = p.brf_stderr[0].clone();
        sig.sort_by(f64::total_cmp);
        let per_pixel = (mean - mu) / sig[n / 2];
        println!(
            "view {zenith}°: image mean {mean:.6} ± {se:.1e}, 1D {mu:.6} ± {mu_se:.1e}, z = {z:+.2}, bias {per_pixel:+.3} pixel σ; samples per pixel {lo}–{hi}"
        );
        assert!(z.abs() < 4.5, "image mean z = {z}");
        assert!(per_pixel.abs() < 0.2, "bias {per_pixel} pixel σ");
    }
}

#[test]
fn fraction_and_uniform_rounds() {
    let dir = tmp("adaptive-fraction");
    let b = write_plane(&dir, &flat_plane(2000.0, 0.0, -1000.0, 0.3));
    let text = format!(
        "{}[scene]\ntype = \"bundle\"\npath = \"{}\"\n[[measures]]\nid = \"img\"\ntype = \"ortho\"\npixel_size_m = 100.0\nspp = 100000\ntarget_rel_stderr = 0.01\ntarget_fraction = 0.9\n",
        head(7),
        b.display()
    );
    let p = image(&experiment(&text));
    let n = p.width * p.height;
    let met = (0..n)
        .filter(|&c| p.brf_stderr[0][c] <= 0.01 * p.brf[0][c])
        .count();
    assert!(
        met as f64 >= 0.9 * n as f64,
        "{met} of {n} pixels meet the target"
    );
    let u = image(&experiment(&format!("{text}adaptive = false\n")));
    let counts = &u.pixel_samples[0];
    assert!(counts.iter().all(|&c| c == counts[0]), "uniform rounds");
    assert!(p.pixel_samples[0]
        .iter()
        .any(|&c| c != p.pixel_samples[0][0]));
    // A target no pixel can reach within `spp`: every pixel goes on to all of it.
    let capped = image(&experiment(
        &text
            .replace("spp = 100000\n", "spp = 2048\n")
            .replace("target_rel_stderr = 0.01\n", "target_rel_stderr = 0.0005\n"),
    ));
    assert!(
        capped.pixel_samples[0].iter().all(|&c| c == 2048),
        "{:?}",
        capped.pixel_samples[0]
    );
}

#[test]
fn config_errors() {
    let dir = tmp("adaptive-errors");
    let b = write_plane(&dir, &flat_plane(2000.0, 0.0, -1000.0, 0.3));
    let base = format!(
        "{}[scene]\ntype = \"bundle\"\npath = \"{}\"\n[[measures]]\nid = \"img\"\ntype = \"ortho\"\npixel_size_m = 100.0\nspp = 1000\n",
        head(1),
        b.display()
    );
    let err = |extra: &str| {
        engine::config::Experiment::from_str(
            &format!("{base}{extra}"),
            &common::data_dir().join("test.toml"),
        )
        .err()
        .unwrap_or_else(|| panic!("accepted: {extra}"))
        .to_string()
    };
    let e = err("target_rel_stderr = 0.01\ntarget_fraction = 1.5\n");
    assert!(
        e.contains("measures[0].target_fraction") && e.contains("(0, 1]"),
        "{e}"
    );
    let e = err("target_fraction = 0.9\n");
    assert!(
        e.contains("measures[0].target_fraction") && e.contains("target_rel_stderr"),
        "{e}"
    );
    let e = err("adaptive = false\n");
    assert!(e.contains("measures[0].adaptive"), "{e}");
}
