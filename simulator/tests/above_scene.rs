//! The above-scene pool of ortho images (`integrator.above_scene`,
//! `engine/src/integrator/above_scene.rs`): every pixel sample scores what its walk sends
//! from its first entry below the scene's top on, plus a shared estimate of what comes before.
//!
//! * `pooled_image_equals_walked_image`: a sloped bundle terrain under the molecular atmosphere
//!   at 440/550/660 nm, a 40 × 40 ortho image (1600 pixels: `"auto"` pools it) against the same
//!   image walked whole (`"walked"`, another seed), random sampler. Per pixel and wavelength
//!   z = (a − b)/√(σa² + σb²): the mean of z over the pixels must be 0 within
//!   4·√(1/N + 1/B) (the pool is a term common to every pixel, its B walks per sample index
//!   each a walk's before-part: its share of a pixel's variance is about 1/B of that part's), and the RMS of z must lie in 0.9 … 1.12 (the standard
//!   errors are honest: the pool's variance is in each pixel's). The pool must also cut the
//!   median pixel error at 440 nm by at least 10 % (it is the point of it; measured: 48 %).
//! * `pooled_variants_equal_walked_image`: the same comparison (1024 pixels, 128 spp) with
//!   collision estimates and without forced collisions.
//! * `pooled_results_do_not_depend_on_threads`: a pooled image with a target (rounds), Sobol
//!   sampler, bit-identical sums with 1 and 2 threads.
//! * `config_errors`: `"pooled"` where it is not built is refused, naming the key.

mod common;

use common::bundles::{spectral_slope_image, tmp};
use common::{experiment, run_on_1_and_2_threads};
use engine::accum::TOTAL;
use engine::integrator::above_scene::batch;

fn scene_text(dir: &std::path::Path, seed: u64, above: &str, pixel: f64, spp: u64) -> String {
    spectral_slope_image(
        dir,
        seed,
        &format!("above_scene = \"{above}\"\n"),
        pixel,
        spp,
    )
}

/// Per wavelength, the per-pixel z between a pooled and a walked image (module header):
/// mean within 4·√(1/N + 1/B), RMS in 0.9 … 1.12; returns the median relative errors
/// (pooled, walked) per wavelength.
fn compare(
    case: &str,
    pooled: &[simulator::run::MeasureResult],
    walked: &[simulator::run::MeasureResult],
) -> Vec<(f64, f64)> {
    assert_eq!(pooled.len(), walked.len());
    let mut out = Vec::new();
    for (p, w) in pooled.iter().zip(walked) {
        let cells = p.acc.n.len();
        let (mut sum_z, mut sum_z2) = (0.0, 0.0);
        let mut err_p = Vec::new();
        let mut err_w = Vec::new();
        for c in 0..cells {
            let (mp, ep) = p.acc.mean_stderr(c, TOTAL);
            let (mw, ew) = w.acc.mean_stderr(c, TOTAL);
            let z = (mp - mw) / (ep * ep + ew * ew).sqrt();
            sum_z += z;
            sum_z2 += z * z;
            err_p.push(ep / mp);
            err_w.push(ew / mw);
        }
        let n = cells as f64;
        let (mean_z, rms_z) = (sum_z / n, (sum_z2 / n).sqrt());
        let median = |v: &mut Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let (ep, ew) = (median(&mut err_p), median(&mut err_w));
        println!(
            "{case}, wavelength {}: mean z {mean_z:+.3}, RMS z {rms_z:.3}, median rel. error pooled {:.3} % walked {:.3} %",
            p.wavelength,
            100.0 * ep,
            100.0 * ew
        );
        let bound = 4.0 * (1.0 / n + 1.0 / batch(cells) as f64).sqrt();
        assert!(
            mean_z.abs() <= bound,
            "{case}: mean z {mean_z} beyond {bound}"
        );
        assert!((0.9..=1.12).contains(&rms_z), "{case}: RMS z {rms_z}");
        out.push((ep, ew));
    }
    out
}

#[test]
fn pooled_image_equals_walked_image() {
    let dir = tmp("above-scene");
    let pooled = simulator::run::run(&experiment(&scene_text(&dir, 4, "auto", 50.0, 256)), false);
    let walked = simulator::run::run(
        &experiment(&scene_text(&dir, 3, "walked", 50.0, 256)),
        false,
    );
    assert_eq!(pooled.len(), 3);
    assert_eq!(pooled[0].acc.n.len(), 1600);
    let errors = compare("default", &pooled, &walked);
    let (ep, ew) = errors[0];
    assert!(ep < 0.9 * ew, "pooled {ep} against walked {ew} at 440 nm");
}

/// The split at the first entry holds whatever else the walk does: collision estimates instead
/// of expected ones, no forced collision, two split flights (the second can be nearly
/// horizontal and optically thousands deep: its uncollided branch has no weight left and must
/// stop before its path factors overflow, or pixels are NaN; every pixel is checked finite).
#[test]
fn pooled_variants_equal_walked_image() {
    let dir = tmp("above-scene-variants");
    // Every variant's walked image also agrees with the default walk's (one split flight,
    // expected estimates): the variants are unbiased, not only pooled like walked.
    let reference = simulator::run::run(
        &experiment(&scene_text(&dir, 8, "walked", 62.5, 128)),
        false,
    );
    for (case, key) in [
        ("collision estimates", "local_estimate = \"collision\"\n"),
        ("no forced collision", "forced_flights = 0\n"),
        ("two split flights", "forced_flights = 2\n"),
    ] {
        let text = |seed, above| {
            scene_text(&dir, seed, above, 62.5, 128)
                .replace("[integrator]\n", &format!("[integrator]\n{key}"))
        };
        let pooled = simulator::run::run(&experiment(&text(6, "auto")), false);
        let walked = simulator::run::run(&experiment(&text(7, "walked")), false);
        assert_eq!(pooled[0].acc.n.len(), 1024);
        for r in pooled.iter().chain(&walked) {
            for c in 0..r.acc.n.len() {
                let (m, e) = r.acc.mean_stderr(c, TOTAL);
                assert!(
                    m.is_finite() && e.is_finite(),
                    "{case}: pixel {c}: {m} ± {e}"
                );
            }
        }
        compare(case, &pooled, &walked);
        compare(
            &format!("{case}, walked against the default walk"),
            &walked,
            &reference,
        );
    }
}

#[test]
fn pooled_results_do_not_depend_on_threads() {
    let dir = tmp("above-scene-threads");
    let text = scene_text(&dir, 5, "pooled", 500.0, 100_000)
        .replace("[integrator]\n", "[integrator]\nsampler = \"sobol\"\n")
        .replace("spp = 100000\n", "spp = 100000\ntarget_rel_stderr = 0.03\n");
    let exp = experiment(&text);
    let (a, b) = run_on_1_and_2_threads(&exp);
    assert_eq!(a.len(), 3);
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.acc, y.acc, "results differ between 1 and 2 threads");
    }
}

#[test]
fn config_errors() {
    let dir = tmp("above-scene-errors");
    let text = scene_text(&dir, 1, "pooled", 500.0, 100);
    let err = |t: &str| {
        engine::config::Experiment::from_str(t, &common::data_dir().join("test.toml"))
            .err()
            .unwrap_or_else(|| panic!("accepted:\n{t}"))
            .to_string()
    };
    let e = err(&text.replace(
        "spectral_walk = \"alis\"\n",
        "spectral_walk = \"independent\"\n",
    ));
    assert!(
        e.contains("integrator.above_scene") && e.contains("spectral_walk"),
        "{e}"
    );
    let e = err(&text.replace("above_scene = \"pooled\"", "above_scene = \"pool\""));
    assert!(e.contains("above_scene"), "{e}");
    // No scene: nothing to pool above (a 1D surface and a radiance meter instead).
    let scene = &text[text.find("[scene]").unwrap()..];
    let e = err(&text.replace(
        scene,
        "[surface]\ntype = \"lambertian\"\nreflectance = 0.2\n\
         [[measures]]\nid = \"nadir\"\ntype = \"radiancemeter\"\norigin = [0.0, 0.0, 700.0]\n\
         direction = [0.0, 0.0, -1.0]\nspp = 100\n",
    ));
    assert!(
        e.contains("integrator.above_scene") && e.contains("scene"),
        "{e}"
    );
    // The Moon beside the Sun (a Grenoble June afternoon, first quarter).
    let e = err(&text.replace(
        "zenith = 40.0\nazimuth = 30.0\n",
        "time = \"2026-06-21T15:00:00Z\"\nlatitude = 45.2\nlongitude = 5.74\nmoon = true\n",
    ));
    assert!(
        e.contains("integrator.above_scene") && e.contains("Moon"),
        "{e}"
    );
}
