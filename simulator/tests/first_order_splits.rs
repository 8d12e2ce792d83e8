//! First-order splitting (`integrator.first_order_splits`, `run.rs` `backward_block`): each
//! backward sample's first-order scores are the mean over k independent first-order walks (its
//! own included); its higher orders stay.
//!
//! * `same_seed_keeps_higher_orders`: with the same seed and sampler, a split run's
//!   multiple-scattering sums are bit-identical to the unsplit run's (the sample's own walk
//!   draws the same numbers), and its single-scattering sums differ. Scalar 1D, spectral 1D and
//!   spectral 3D walks (walked whole and with the above-scene pool).
//! * `split_image_equals_unsplit_image`: a sloped two-material bundle under the molecular
//!   atmosphere at 440/550/660 nm, a 32 × 32 ortho image walked whole (no above-scene pool,
//!   whose noise is common to every pixel), 3 walks per sample against 1 (other seeds). Per
//!   pixel and wavelength z = (a − b)/√(σa² + σb²): the mean of z over the N pixels within
//!   4/√N, the RMS of z in 0.9 … 1.12 (honest standard errors), and the split must cut the
//!   median pixel error of the single-scattering part at 660 nm by at least 25 % (3 walks: at
//!   most 1 − 1/√3 = 42 %; measured 42 %).
//!   The same against a split image with the above-scene pool (bound 4·√(1/N + 1/B), the
//!   pool being common to every pixel, `above_scene.rs`).
//! * `split_results_do_not_depend_on_threads`: a pooled split image with a target (adaptive
//!   rounds, some pixels stopping inside blocks, checked), Sobol sampler: bit-identical sums on
//!   1 and 2 threads.
//! * `config_errors`: out-of-range counts, polarization, the forward walk (explicit, and 1D
//!   distant measures under "auto") are refused, naming the key; the Moon beside the Sun is
//!   accepted.

mod common;

use common::bundles::{spectral_slope_image, tmp};
use common::{experiment, run_on_1_and_2_threads};
use engine::accum::{MULTIPLE, SINGLE, TOTAL};
use engine::integrator::above_scene::batch;
use simulator::run::MeasureResult;

fn scene_text(dir: &std::path::Path, seed: u64, splits: u32, pixel: f64, spp: u64) -> String {
    let integrator = format!("first_order_splits = {splits}\n");
    spectral_slope_image(dir, seed, &integrator, pixel, spp)
}

/// A 1D run: Rayleigh over a Lambertian surface, three radiance meters, backward walks
/// (`spectral`: one spectral ALIS walk for two wavelengths).
fn layers_text(seed: u64, splits: u32, spectral: bool) -> String {
    let (wl, walk) = if spectral {
        ("[450.0, 500.0]", "spectral_walk = \"alis\"\n")
    } else {
        ("[500.0]", "")
    };
    let meters: String = [0.0_f64, 30.0, 60.0]
        .iter()
        .enumerate()
        .map(|(i, vza)| {
            let t = vza.to_radians();
            format!(
                "[[measures]]\nid = \"m{i}\"\ntype = \"radiancemeter\"\norigin = [0.0, 0.0, 100000.0]\n\
                 direction = [{}, 0.0, {}]\nspp = 4000\n",
                -t.sin(),
                -t.cos()
            )
        })
        .collect();
    format!(
        "seed = {seed}\n[spectral]\nwavelengths = {wl}\n\
         [atmosphere]\ntype = \"molecular\"\n\
         [surface]\ntype = \"lambertian\"\nreflectance = 0.3\n\
         [illumination]\ntype = \"directional\"\nzenith = 30.0\nazimuth = 0.0\n\
         [integrator]\ntype = \"backward\"\n{walk}first_order_splits = {splits}\n{meters}"
    )
}

/// Every cell of `a` and `b`: multiple-scattering mean and error bit-identical. Returns
/// whether some cell's single-scattering mean differs.
fn same_higher_orders(case: &str, a: &[MeasureResult], b: &[MeasureResult]) -> bool {
    assert_eq!(a.len(), b.len());
    let mut single_differs = false;
    for (x, y) in a.iter().zip(b) {
        for c in 0..x.acc.n.len() {
            assert_eq!(
                x.acc.mean_stderr(c, MULTIPLE),
                y.acc.mean_stderr(c, MULTIPLE),
                "{case}: cell {c}"
            );
            single_differs |= x.acc.mean_stderr(c, SINGLE).0 != y.acc.mean_stderr(c, SINGLE).0;
        }
    }
    single_differs
}

#[test]
fn same_seed_keeps_higher_orders() {
    for spectral in [false, true] {
        let run = |k| simulator::run::run(&experiment(&layers_text(21, k, spectral)), false);
        // (In 1D the first order of a backward walk has no variance to split: its expected
        // estimates along the sensor's line of sight and the uncollided path to the surface
        // are exact, so the sums may or may not differ in their last bits.)
        same_higher_orders(&format!("1D, spectral {spectral}"), &run(1), &run(4));
    }
    let dir = tmp("first-order-splits-same-seed");
    for above in ["walked", "pooled"] {
        let run = |k| {
            let text = scene_text(&dir, 22, k, 250.0, 64).replace(
                "[integrator]\n",
                &format!("[integrator]\nabove_scene = \"{above}\"\n"),
            );
            simulator::run::run(&experiment(&text), false)
        };
        assert!(
            same_higher_orders(&format!("3D scene, {above}"), &run(1), &run(3)),
            "3D scene, {above}: the split changed no single-scattering sum"
        );
    }
}

#[test]
fn split_image_equals_unsplit_image() {
    let dir = tmp("first-order-splits-image");
    // Walked whole, without the above-scene pool: its noise is common to every pixel and
    // would widen the bound on the mean z (`above_scene.rs`).
    let walked = |seed, k| {
        let text = scene_text(&dir, seed, k, 62.5, 128)
            .replace("[integrator]\n", "[integrator]\nabove_scene = \"walked\"\n");
        simulator::run::run(&experiment(&text), false)
    };
    let plain = walked(32, 1);
    compare("walked", &walked(31, 3), &plain, 4.0 / 1024f64.sqrt());
    // With the above-scene pool (the default for such images): its part of each sample is
    // added after the first orders are averaged, and is common to every pixel.
    let pooled = simulator::run::run(&experiment(&scene_text(&dir, 33, 3, 62.5, 128)), false);
    let bound = 4.0 * (1.0 / 1024.0 + 1.0 / batch(1024) as f64).sqrt();
    compare("pooled", &pooled, &plain, bound);
}

/// Per wavelength, the per-pixel z of a split image against an unsplit one: mean within
/// `bound`, RMS in 0.9 … 1.12, and at 660 nm the single-scattering part's median error below
/// 0.75 of the unsplit one's.
fn compare(case: &str, split: &[MeasureResult], plain: &[MeasureResult], bound: f64) {
    assert_eq!(split.len(), 3);
    assert_eq!(split[0].acc.n.len(), 1024);
    for (s, p) in split.iter().zip(plain) {
        let cells = s.acc.n.len();
        let (mut sum_z, mut sum_z2) = (0.0, 0.0);
        let (mut single_s, mut single_p) = (Vec::new(), Vec::new());
        for c in 0..cells {
            let (ms, es) = s.acc.mean_stderr(c, TOTAL);
            let (mp, ep) = p.acc.mean_stderr(c, TOTAL);
            assert!(ms.is_finite() && es.is_finite(), "pixel {c}: {ms} ± {es}");
            let z = (ms - mp) / (es * es + ep * ep).sqrt();
            sum_z += z;
            sum_z2 += z * z;
            single_s.push(s.acc.mean_stderr(c, SINGLE).1);
            single_p.push(p.acc.mean_stderr(c, SINGLE).1);
        }
        let n = cells as f64;
        let (mean_z, rms_z) = (sum_z / n, (sum_z2 / n).sqrt());
        let median = |v: &mut Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let ratio = median(&mut single_s) / median(&mut single_p);
        println!(
            "{case}, wavelength {}: mean z {mean_z:+.3}, RMS z {rms_z:.3}, single-scattering error split/plain {ratio:.3}",
            s.wavelength
        );
        assert!(
            mean_z.abs() <= bound,
            "{case}: mean z {mean_z} beyond {bound}"
        );
        assert!((0.9..=1.12).contains(&rms_z), "{case}: RMS z {rms_z}");
        if s.wavelength == 2 {
            assert!(
                ratio < 0.75,
                "{case}: single-scattering error ratio {ratio} at 660 nm"
            );
        }
    }
}

#[test]
fn split_results_do_not_depend_on_threads() {
    let dir = tmp("first-order-splits-threads");
    let text = scene_text(&dir, 5, 2, 250.0, 100_000)
        .replace(
            "[integrator]\n",
            "[integrator]\nsampler = \"sobol\"\nabove_scene = \"pooled\"\n",
        )
        .replace(
            "spp = 100000\n",
            "spp = 100000\ntarget_rel_stderr = 0.003\n",
        );
    let exp = experiment(&text);
    let (a, b) = run_on_1_and_2_threads(&exp);
    assert_eq!(a.len(), 3);
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.acc, y.acc, "results differ between 1 and 2 threads");
    }
    // The adaptive rounds ran: some pixels stopped inside a 32-sample block.
    assert!(
        a[0].acc.n.iter().any(|&n| n % 32 != 0),
        "no pixel stopped inside a block: {:?}",
        a[0].acc.n
    );
}

#[test]
fn config_errors() {
    let text = layers_text(1, 2, false);
    let err = |t: &str| {
        engine::config::Experiment::from_str(t, &common::data_dir().join("test.toml"))
            .err()
            .unwrap_or_else(|| panic!("accepted:\n{t}"))
            .to_string()
    };
    // Refused, naming the key and `why`.
    let refused = |t: &str, why: &str| {
        let e = err(t);
        assert!(
            e.contains("integrator.first_order_splits") && e.contains(why),
            "{e}"
        );
    };
    for bad in ["0", "17"] {
        refused(
            &text.replace(
                "first_order_splits = 2",
                &format!("first_order_splits = {bad}"),
            ),
            "1 … 16",
        );
    }
    refused(
        &text.replace("seed = 1\n", "seed = 1\npolarized = true\n"),
        "polarized",
    );
    let forward = text
        .replace("type = \"backward\"", "type = \"forward\"")
        .replace(
            &text[text.find("[[measures]]").unwrap()..],
            &common::mdistant_toml("toa", &[0.0], &[0.0], 100),
        );
    refused(&forward, "forward");
    // With "auto", 1D distant measures walk forward: nothing would be split.
    refused(
        &forward.replace("type = \"forward\"", "type = \"auto\""),
        "backward",
    );
    let ok = |t: &str| {
        engine::config::Experiment::from_str(t, &common::data_dir().join("test.toml"))
            .unwrap_or_else(|e| panic!("refused: {e}\n{t}"));
    };
    // Splitting off (1) is accepted wherever; with the Moon beside the Sun it splits the
    // Sun's walks.
    ok(&forward.replace("first_order_splits = 2", "first_order_splits = 1"));
    ok(&text.replace(
        "zenith = 30.0\nazimuth = 0.0\n",
        "time = \"2026-06-21T15:00:00Z\"\nlatitude = 45.2\nlongitude = 5.74\nmoon = true\n",
    ));
}
