//! Spectral walks through 3D scenes (`integrator.spectral_walk = "alis"` with a scene,
//! `engine/src/integrator/scene_alis.rs`): one backward walk per sample carries the
//! wavelengths of a group through the scene, each with its own Rayleigh scattering, materials and
//! solar transmittance. Every statistical test compares the grouped walk with independent
//! per-wavelength scene walks (other seeds) at every wavelength, view direction and part
//! (total and single scattering), with `common::check_all` (|diff| ≤ 4.5σ + max(1e-5,
//! 2e-4·ref), σ the combined standard error). The random sampler is used (honest
//! per-direction standard errors); fixed seeds.
//!
//! * `canopy_group_equals_independent_walks`: random leaves over a ground under the molecular
//!   atmosphere at 440/550/660 nm (Rayleigh σ_s varying 5×). The reference wavelength (440 nm,
//!   the most scattering) has leaves that transmit nothing and a black ground, the other
//!   wavelengths leaves that transmit up to 40 % and a ground up to 0.3: the walk must draw
//!   transmission and ground bounces from the group's mean leaf and fall back to the largest
//!   reflectance where the reference's is 0 (module header), or those paths go missing.
//! * `bundle_group_equals_independent_walks`: a bundle terrain with a spectral RPV and a
//!   spectral Lambertian (opaque sampler of the reference's RPV; per-wavelength evaluation),
//!   an area `mdistant` and an ortho image's mean.
//! * `group_results_do_not_depend_on_threads`: an ortho image with a target precision (rounds)
//!   and the Sobol sampler, bit-identical sums with 1 and 2 threads.
//! * `config_errors`: what the walk does not do is refused, naming the key.

mod common;

use bundle::*;
use common::bundles::{tmp, write_random_leaves, write_two_material_slope};
use common::{compare_brf_rows, experiment, run_on_1_and_2_threads, run_rows};

/// The experiment text with the spectral walk turned on and another seed (the texts ask for
/// independent walks explicitly: `"auto"`, the default, would choose ALIS for these scenes).
fn grouped(text: &str, seed: u64) -> String {
    text.replace(
        "spectral_walk = \"independent\"\n",
        "spectral_walk = \"alis\"\n",
    )
    .replace("seed = 1\n", &format!("seed = {seed}\n"))
}

fn table(values: [f64; 3]) -> String {
    format!(
        "{{ wavelengths_nm = [440.0, 550.0, 660.0], values = [{:?}, {:?}, {:?}] }}",
        values[0], values[1], values[2]
    )
}

const HEAD: &str = "seed = 1\n[spectral]\nwavelengths = [440.0, 550.0, 660.0]\n\
     [atmosphere]\ntype = \"molecular\"\n\
     [illumination]\ntype = \"directional\"\nzenith = 40.0\nazimuth = 30.0\n\
     [integrator]\nspectral_walk = \"independent\"\n";

fn mdistant(spp: u64, extra: &str) -> String {
    format!(
        "[[measures]]\nid = \"area\"\ntype = \"mdistant\"\nconstruct = \"directions\"\n\
         zeniths = [0.0, 35.0, 60.0]\nazimuths = [0.0, 30.0, 210.0]\nspp = {spp}\n{extra}\n"
    )
}

#[test]
fn canopy_group_equals_independent_walks() {
    let dir = tmp("alis-canopy");
    write_random_leaves(&dir.join("leaves.txt"), 9, 2500, 10.0, [0.5, 6.0], 0.25);
    let text = format!(
        "{HEAD}[scene]\ntype = \"canopy\"\n[[scene.objects]]\nleaves = \"{}\"\n\
         reflectance = {}\ntransmittance = {}\n\
         [scene.ground]\nbrdf = {{ type = \"lambertian\", reflectance = {} }}\n{}",
        dir.join("leaves.txt").display(),
        table([0.06, 0.12, 0.45]),
        table([0.0, 0.1, 0.4]),
        table([0.0, 0.15, 0.3]),
        mdistant(
            60_000,
            "target_m = [-8.0, -8.0, 8.0, 8.0]\ntarget_height_m = 6.5"
        )
    );
    let exp = experiment(&grouped(&text, 2));
    // The reference is the most scattering wavelength, 440 nm.
    assert_eq!(exp.wavelengths[0], 440.0);
    let t = std::time::Instant::now();
    let alis = run_rows(&exp);
    let t_alis = t.elapsed().as_secs_f64();
    let t = std::time::Instant::now();
    let independent = run_rows(&experiment(&text));
    println!(
        "canopy: grouped {t_alis:.1} s, independent {:.1} s",
        t.elapsed().as_secs_f64()
    );
    compare_brf_rows("canopy, grouped vs independent", &alis, &independent).unwrap();
    // Single scattering too (the first interaction's estimate, per wavelength).
    let single = |r: &[simulator::products::Row]| -> Vec<simulator::products::Row> {
        r.iter()
            .map(|x| simulator::products::Row {
                brf: x.brf_single,
                ..x.clone()
            })
            .collect()
    };
    compare_brf_rows(
        "canopy single scattering, grouped vs independent",
        &single(&alis),
        &single(&independent),
    )
    .unwrap();
    // The test sees transmission at 660 nm: the leaves' reflectance alone would leave less.
    let brf = |r: &[simulator::products::Row], wl: f64| -> f64 {
        r.iter()
            .filter(|x| x.wavelength_nm == wl)
            .map(|x| x.brf.unwrap().0)
            .sum()
    };
    assert!(brf(&alis, 660.0) > 2.0 * brf(&alis, 440.0));
}

fn bundle_text(dir: &std::path::Path, spp_area: u64, spp_image: u64) -> String {
    let rpv = BrdfSpec::Rpv(RpvSpec {
        rho_0: Spectrum::Table {
            wavelengths_nm: vec![440.0, 660.0],
            values: vec![0.04, 0.25],
        },
        k: Spectrum::Constant(0.75),
        g: Spectrum::Table {
            wavelengths_nm: vec![440.0, 660.0],
            values: vec![-0.3, 0.1],
        },
        rho_c: None,
    });
    let b = write_two_material_slope(dir, rpv, 0.05, -0.03, 4);
    format!(
        "{HEAD}[scene]\ntype = \"bundle\"\npath = \"{}\"\n{}\
         [[measures]]\nid = \"img\"\ntype = \"ortho\"\npixel_size_m = 1000.0\nzenith = 10.0\nazimuth = 60.0\nspp = {spp_image}\n",
        b.display(),
        mdistant(
            spp_area,
            "target_m = [499200.0, 3999200.0, 500800.0, 4000800.0]"
        )
    )
}

#[test]
fn bundle_group_equals_independent_walks() {
    let dir = tmp("alis-bundle");
    let text = bundle_text(&dir, 40_000, 20_000);
    let alis = run_rows(&experiment(&grouped(&text, 2)));
    let independent = run_rows(&experiment(&text));
    compare_brf_rows("bundle, grouped vs independent", &alis, &independent).unwrap();
}

#[test]
fn group_results_do_not_depend_on_threads() {
    let dir = tmp("alis-threads");
    let text = bundle_text(&dir, 2000, 100_000)
        .replace("[integrator]\n", "[integrator]\nsampler = \"sobol\"\n")
        .replace("spp = 100000\n", "spp = 100000\ntarget_rel_stderr = 0.03\n");
    let exp = experiment(&grouped(&text, 5));
    let (a, b) = run_on_1_and_2_threads(&exp);
    assert_eq!(a.len(), 6);
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.acc, y.acc, "results differ between 1 and 2 threads");
    }
}

#[test]
fn config_errors() {
    let dir = tmp("alis-errors");
    let text = grouped(&bundle_text(&dir, 100, 100), 2);
    let err = |t: &str| {
        engine::config::Experiment::from_str(t, &common::data_dir().join("test.toml"))
            .err()
            .unwrap_or_else(|| panic!("accepted:\n{t}"))
            .to_string()
    };
    // More than 8 wavelengths per group in a scene.
    let e = err(&text.replace(
        "spectral_walk = \"alis\"\n",
        "spectral_walk = \"alis\"\nalis_group = 9\n",
    ));
    assert!(
        e.contains("integrator.alis_group") && e.contains("at most 8"),
        "{e}"
    );
    // Polarized runs.
    let e = err(&format!("polarized = true\n{text}"));
    assert!(e.contains("integrator.spectral_walk"), "{e}");
    // Spherical shells.
    let e = err(&text.replace(
        "[integrator]\n",
        "[geometry]\ntype = \"spherical_shell\"\n[integrator]\n",
    ));
    assert!(e.contains("integrator.spectral_walk"), "{e}");
    // Per-material solvers other than the default.
    let e = err(&format!("{text}[scene.solvers.soil]\ntype = \"simple\"\n"));
    assert!(e.contains("scene.solvers.soil"), "{e}");
}

/// `spectral_walk = "auto"` (the default) walks a scene's wavelengths together where ALIS is
/// built (scalar, plane-parallel, two or more wavelengths, default solvers) and falls back to
/// independent walks, without an error, where an explicit `"alis"` is refused.
#[test]
fn auto_chooses_grouped_walks_where_they_are_built() {
    let dir = tmp("alis-auto");
    let text = bundle_text(&dir, 100, 100).replace("spectral_walk = \"independent\"\n", "");
    let walk = |t: &str| {
        engine::config::Experiment::from_str(t, &common::data_dir().join("test.toml"))
            .unwrap_or_else(|e| panic!("{e}\n{t}"))
            .integrator
            .spectral_alis
    };
    assert_eq!(walk(&text), Some(8));
    assert_eq!(
        walk(&text.replace(
            "wavelengths = [440.0, 550.0, 660.0]",
            "wavelengths = [550.0]"
        )),
        None
    );
    assert_eq!(walk(&format!("polarized = true\n{text}")), None);
    assert_eq!(
        walk(&text.replace(
            "[integrator]\n",
            "[geometry]\ntype = \"spherical_shell\"\n[integrator]\n",
        )),
        None
    );
    assert_eq!(
        walk(&format!("{text}[scene.solvers.soil]\ntype = \"simple\"\n")),
        None
    );
    assert_eq!(
        walk(&text.replace("[integrator]\n", "[integrator]\nalis_group = 2\n")),
        Some(2)
    );
}

/// `simulate bench-image` (issue 45): the samples per pixel it projects for a target are
/// `(σ·√n / target)²` of the σ it measured at `n` samples, the worst band sets the tile's
/// samples, and the core-hours are pixels × samples × CPU per sample; a file without an image
/// measure is refused naming it.
#[test]
fn bench_image_projects_from_what_it_measured() {
    let dir = tmp("bench-image");
    let text = bundle_text(&dir, 100, 64).replace("spectral_walk = \"independent\"\n", "");
    let exp = dir.join("exp.toml");
    std::fs::write(&exp, &text).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_simulate"))
        .args([
            "bench-image",
            "--target",
            "0.01",
            "--tile-km",
            "10",
            "-j",
            "2",
            "-q",
        ])
        .arg(&exp)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("64 samples per pixel"), "{stdout}");
    assert!(stdout.contains("grouped ALIS walks"), "{stdout}");
    let mut worst = 0.0f64;
    for w in ["440.0", "550.0", "660.0"] {
        let line = stdout
            .lines()
            .find(|l| l.trim_start().starts_with(w))
            .unwrap_or_else(|| panic!("no row for {w}:\n{stdout}"));
        // nm, median σ %, spread, target %, spp for target (no band name: wavelengths).
        let v: Vec<f64> = line
            .split_whitespace()
            .map(|x| x.parse().unwrap())
            .collect();
        assert_eq!(v.len(), 5, "{line}");
        assert_eq!(v[3], 1.0, "{line}");
        let (sigma, spread, n_t) = (v[1] / 100.0, v[2], v[4]);
        assert!((spread - sigma * 8.0).abs() < 2e-4, "{line}");
        assert!(
            (n_t - (sigma * 8.0 / 0.01f64).powi(2)).abs() <= 1.0 + 2e-3 * n_t,
            "{line}"
        );
        worst = worst.max(n_t);
    }
    assert!(
        stdout.contains(&format!("{worst:.0} samples per pixel (set by")),
        "{stdout}"
    );
    let us: f64 = stdout
        .split(" CPU µs per sample")
        .next()
        .and_then(|s| s.rsplit(' ').next())
        .unwrap()
        .parse()
        .unwrap();
    let hours: f64 = stdout
        .split(" core-hours")
        .next()
        .and_then(|s| s.rsplit(' ').next())
        .unwrap()
        .parse()
        .unwrap();
    let expected = (10_000.0f64 / 1000.0).powi(2) * worst * us * 1e-6 / 3600.0;
    assert!(
        (hours - expected).abs() <= 0.5 + 0.02 * expected,
        "{hours} vs {expected}\n{stdout}"
    );
    // No image measure.
    let no_image: String = text
        .lines()
        .take_while(|l| !l.contains("id = \"img\""))
        .collect::<Vec<_>>()
        .join("\n");
    let no_image = no_image
        .trim_end()
        .trim_end_matches("[[measures]]")
        .to_string();
    std::fs::write(&exp, no_image).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_simulate"))
        .args(["bench-image", "-q"])
        .arg(&exp)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(
        !out.status.success() && stderr.contains("needs an image measure"),
        "{stderr}"
    );
}
