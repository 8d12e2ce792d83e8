//! Spectral ALIS in monochromatic runs (`integrator.spectral_walk = "alis"`,
//! `engine/src/integrator/backward_alis.rs`): one backward walk per sample carries a group of
//! neighbouring wavelengths, each with its own absorption, scattering, phase function and
//! surface. Every test compares the grouped walk with independent per-wavelength backward walks
//! (`integrator.type = "backward"`, other seeds) at every wavelength and view direction.
//!
//! Statistical test (`check`): |a − b| ≤ K·√(σ_a² + σ_b²) + floor with K = 4.5 (as
//! `common::check_all`), σ the two runs' standard errors and floor = max(1e-9, 1e-6·|b|): the
//! two estimators are unbiased estimates of the same quantity, so the floor only covers float
//! rounding (the single scattering of a distant measure is computed exactly along the first
//! flight by both walks, with zero variance, and differs in rounding only). Seeds are fixed. The
//! grouped results of neighbouring wavelengths are strongly correlated (same walks), so a group
//! may sit ~1σ to one side of the independent runs at every wavelength; each point is still a
//! valid test of its own.
//!
//! * `artdeco_o2a_group_equals_independent_walks` (a) + (c): the ARTDECO O2 A-band layered case
//!   (shared data, skipped when absent), scalar, 48 contiguous wavelengths across the deepest
//!   line core and its continuum (column gas τ from < 0.1 to ~100, two groups of 24): grouped vs
//!   independent walks, and the single-scattering part of the grouped run against the analytic
//!   single scattering at every wavelength (|ss − analytic| ≤ K·σ + 1e-6·analytic).
//! * `aerosol_rpv_group_equals_independent_walks` (b): 440–480 nm in one group of 24 wavelengths:
//!   US-standard Rayleigh (σ_s varies by 45 % across the group), a desert aerosol layer (Aer-Core
//!   v2 dataset, τ = 0.3 at 550 nm, phase function and extinction varying with wavelength), an
//!   RPV surface whose ρ_0 grows from 0.05 to 0.30 across the group.
//! * `thread_count_and_zero_reference_surface` (d): a Rayleigh group whose central wavelength
//!   has a black surface (the bounce weights fall back to the largest reflectance) equals
//!   independent walks; its sums are bit-identical with 1 and 2 rayon threads, and a resumed
//!   run (checkpoints per wavelength) reproduces them.
//! * `config_errors` (e): invalid combinations name `integrator.spectral_walk` /
//!   `integrator.alis_group` / `integrator.ckd_walk`.

mod common;
use common::artdeco::{layer, read_cumulative, shared_dir, single_scattering, Cumulative};
use common::{data_dir, experiment, run_on_1_and_2_threads, run_rows, K};

use engine::config::Experiment;
use simulator::products::Row;

const ABS_FLOOR: f64 = 1e-9;
const REL_FLOOR: f64 = 1e-6;

/// (label, grouped (v, σ), independent (v, σ)) for every row, BRF total and single part.
fn check(case: &str, a: &[Row], b: &[Row]) -> Result<(), String> {
    assert_eq!(a.len(), b.len());
    let mut fails = Vec::new();
    let (mut worst_z, mut n) = (0.0_f64, 0);
    let (mut se_a, mut se_b) = (Vec::new(), Vec::new());
    for (x, y) in a.iter().zip(b) {
        assert_eq!(x.wavelength_nm, y.wavelength_nm);
        assert_eq!(x.vza, y.vza);
        for (part, p, q) in [
            ("brf", x.brf.unwrap(), y.brf.unwrap()),
            ("single", x.brf_single.unwrap(), y.brf_single.unwrap()),
        ] {
            let s = (p.1 * p.1 + q.1 * q.1).sqrt();
            let d = (p.0 - q.0).abs();
            let tol = K * s + ABS_FLOOR.max(REL_FLOOR * q.0.abs());
            n += 1;
            if s > 0.0 {
                worst_z = worst_z.max(d / s);
            }
            if part == "brf" {
                se_a.push(p.1 / p.0.abs());
                se_b.push(q.1 / q.0.abs());
            }
            #[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN must fail
            if !(d <= tol) {
                fails.push(format!(
                    "  {part} {:.4} nm vza {:?}: grouped {:.6e} ± {:.1e}, independent {:.6e} ± {:.1e} (z = {:.1})",
                    x.wavelength_nm, x.vza, p.0, p.1, q.0, q.1, d / s
                ));
            }
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    println!(
        "{case}: {n} comparisons, max z = {worst_z:.2}, median rel stderr grouped {:.2e}, independent {:.2e}",
        median(&mut se_a),
        median(&mut se_b)
    );
    if fails.is_empty() {
        Ok(())
    } else {
        Err(format!(
            "{case}: {} failed\n{}",
            fails.len(),
            fails.join("\n")
        ))
    }
}

/// The experiment text with the spectral ALIS keys added to its `[integrator]` table.
fn grouped(text: &str, group: usize, seed: u64) -> String {
    text.replace(
        "[integrator]\n",
        &format!("[integrator]\nspectral_walk = \"alis\"\nalis_group = {group}\n"),
    )
    .replace("seed = 1\n", &format!("seed = {seed}\n"))
}

fn list(v: impl IntoIterator<Item = f64>) -> String {
    v.into_iter()
        .map(|x| format!("{x:?}"))
        .collect::<Vec<_>>()
        .join(", ")
}

const SZA: f64 = 30.0;
const VZA: [f64; 2] = [20.0, 60.0];
const VAA: [f64; 2] = [180.0, 0.0];

/// ARTDECO's layers at wavelength indices `idx`, scalar, black surface, independent backward
/// walks (seed 1).
fn artdeco_text(gas: &Cumulative, ray: &Cumulative, idx: &[usize], spp: u64) -> String {
    let mut t = format!(
        "seed = 1\npolarized = false\n[spectral]\nwavelengths = [{}]\n\
         [geometry]\ntype = \"plane_parallel\"\ntoa_altitude = 120.0\n\
         [atmosphere]\ntype = \"layered\"\n",
        list(idx.iter().map(|&k| gas.wavelengths[k]))
    );
    for l in 0..gas.altitudes.len() - 1 {
        t += &format!(
            "[[atmosphere.layers]]\nbottom = {:?}\ntop = {:?}\nphase = {{ type = \"rayleigh\", depolarization = 0.0 }}\n\
             tau_sca = [{}]\ntau_abs = [{}]\n",
            gas.altitudes[l + 1],
            gas.altitudes[l],
            list(idx.iter().map(|&k| layer(ray, l, k))),
            list(idx.iter().map(|&k| layer(gas, l, k))),
        );
    }
    t + &format!(
        "[surface]\ntype = \"lambertian\"\nreflectance = 0.0\n\
         [illumination]\ntype = \"directional\"\nzenith = {SZA:?}\nazimuth = 0.0\n\
         [integrator]\ntype = \"backward\"\n\
         [[measures]]\nid = \"toa\"\ntype = \"mdistant\"\nconstruct = \"directions\"\n\
         zeniths = [{}]\nazimuths = [{}]\nspp = {spp}\n",
        list(VZA),
        list(VAA)
    )
}

#[test]
fn artdeco_o2a_group_equals_independent_walks() {
    let Some(dir) = shared_dir() else {
        eprintln!("skipped: shared data folder artdeco_o2a not found");
        return;
    };
    let gas = read_cumulative(&dir.join("cTauGas_ray_O2.dat"));
    let ray = read_cumulative(&dir.join("cTauRay_ray_O2.dat"));
    let col = |k: usize| *gas.cum.last().unwrap().get(k).unwrap();
    // 48 contiguous wavelengths centred on the deepest line core.
    let n = gas.wavelengths.len();
    let core = (0..n).max_by(|&a, &b| col(a).total_cmp(&col(b))).unwrap();
    let start = core.saturating_sub(24).min(n - 48);
    let idx: Vec<usize> = (start..start + 48).collect();
    let (lo, hi) = idx.iter().fold((f64::INFINITY, 0.0_f64), |(a, b), &k| {
        (a.min(col(k)), b.max(col(k)))
    });
    println!(
        "{:.4}–{:.4} nm, column gas τ {lo:.3} … {hi:.1}",
        gas.wavelengths[idx[0]], gas.wavelengths[idx[47]]
    );
    assert!(lo < 0.2 && hi > 50.0, "window must span continuum and core");
    let text = artdeco_text(&gas, &ray, &idx, 8192);
    let t = std::time::Instant::now();
    let independent = run_rows(&experiment(&text));
    let t_ind = t.elapsed().as_secs_f64();
    let t = std::time::Instant::now();
    let alis = run_rows(&experiment(&grouped(
        &text.replace("spp = 8192", "spp = 65536"),
        24,
        2,
    )));
    println!(
        "independent {t_ind:.1} s (48 × 8192 walks per direction), grouped {:.1} s (2 × 65536)",
        t.elapsed().as_secs_f64()
    );
    check(
        "ARTDECO O2 A-band, grouped vs independent",
        &alis,
        &independent,
    )
    .unwrap();
    // (c) single scattering against the closed form, every wavelength and direction.
    let mut errs = Vec::new();
    for r in &alis {
        let k = idx
            .iter()
            .copied()
            .find(|&k| (gas.wavelengths[k] - r.wavelength_nm).abs() < 1e-9)
            .unwrap();
        let vza = r.vza.unwrap();
        let raa = if vza == VZA[0] { VAA[0] } else { VAA[1] };
        let ss = single_scattering(&gas, &ray, k, SZA, vza, raa);
        let (s, e) = r.brf_single.unwrap();
        #[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN must fail
        if !((s - ss).abs() <= K * e + 1e-6 * ss) {
            errs.push(format!(
                "  {} nm vza {vza}: single {s:.8e} ± {e:.1e}, analytic {ss:.8e}",
                r.wavelength_nm
            ));
        }
    }
    assert!(errs.is_empty(), "single scattering:\n{}", errs.join("\n"));
}

/// 440–480 nm (24 wavelengths), US-standard Rayleigh, desert aerosol 0–3 km (τ 0.3 at 550 nm),
/// RPV surface with ρ_0 from 0.05 to 0.30; independent backward walks, seed 1.
fn aerosol_text(desert: &std::path::Path, spp: u64) -> String {
    let wl: Vec<f64> = (0..24).map(|i| 440.0 + 40.0 * i as f64 / 23.0).collect();
    let rho: Vec<f64> = wl
        .iter()
        .map(|w| 0.05 + 0.25 * (w - 440.0) / 40.0)
        .collect();
    format!(
        "seed = 1\n[spectral]\nwavelengths = [{}]\n\
         [atmosphere]\ntype = \"molecular\"\n\
         [[atmosphere.particle_layers]]\nbottom = 0.0\ntop = 3.0\noptical_thickness = 0.3\ndataset = \"{}\"\n\
         [surface]\ntype = \"rpv\"\nrho_0 = [{}]\nk = 0.8\ng = -0.2\n\
         [illumination]\ntype = \"directional\"\nzenith = 35.0\nazimuth = 0.0\n\
         [integrator]\ntype = \"backward\"\n\
         [[measures]]\nid = \"toa\"\ntype = \"mdistant\"\nconstruct = \"directions\"\n\
         zeniths = [0.0, 35.0, 60.0]\nazimuths = [0.0, 0.0, 180.0]\nspp = {spp}\n",
        list(wl.iter().copied()),
        desert.display(),
        list(rho)
    )
}

#[test]
fn aerosol_rpv_group_equals_independent_walks() {
    let desert = std::env::var_os("SIMULATOR_SHARED_DATA")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| {
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data")
        })
        .join("eradiate/aerosol/govaerts_2021-desert-aer_core_v2.nc");
    if !desert.exists() {
        eprintln!("skipped: shared data folder (desert aerosol dataset) not found");
        return;
    }
    let text = aerosol_text(&desert, 8192);
    let exp = experiment(&text);
    // The group's scattering really varies: Rayleigh+aerosol σ_s and the phase functions.
    let (a, b) = (&exp.optics[0].atmosphere, &exp.optics[23].atmosphere);
    let n = a.layer_count();
    let tau_sca = |p: &engine::atmosphere::PlaneParallel| -> f64 {
        let t: Vec<(f64, f64)> = p.boundaries().collect();
        (0..n).map(|i| p.albedo(i) * (t[i + 1].1 - t[i].1)).sum()
    };
    println!(
        "column τ_sca 440 nm {:.4}, 480 nm {:.4}",
        tau_sca(a),
        tau_sca(b)
    );
    assert!(tau_sca(a) / tau_sca(b) > 1.15);
    assert!((0..n).any(|i| a.phase(i) != b.phase(i)));
    let t = std::time::Instant::now();
    let independent = run_rows(&exp);
    let t_ind = t.elapsed().as_secs_f64();
    let t = std::time::Instant::now();
    let alis = run_rows(&experiment(&grouped(
        &text.replace("spp = 8192", "spp = 16384"),
        24,
        3,
    )));
    println!(
        "independent {t_ind:.1} s (24 × 8192 walks per direction), grouped {:.1} s (16384)",
        t.elapsed().as_secs_f64()
    );
    check(
        "aerosol + RPV 440–480 nm, grouped vs independent",
        &alis,
        &independent,
    )
    .unwrap();
}

/// Five Rayleigh wavelengths over a Lambertian whose reflectance is 0 at the central one.
const RAYLEIGH: &str = "seed = 1\n[spectral]\nwavelengths = [520.0, 500.0, 510.0, 505.0, 515.0]\n\
     [atmosphere]\ntype = \"molecular\"\n\
     [surface]\ntype = \"lambertian\"\nreflectance = [0.25, 0.2, 0.0, 0.1, 0.3]\n\
     [illumination]\ntype = \"directional\"\nzenith = 40.0\n\
     [integrator]\ntype = \"backward\"\n\
     [[measures]]\nid = \"toa\"\ntype = \"mdistant\"\nconstruct = \"directions\"\n\
     zeniths = [10.0, 55.0]\nazimuths = [0.0, 180.0]\nspp = SPP\n\
     [[measures]]\nid = \"up\"\ntype = \"distant_flux\"\nspp = SPP\n";

#[test]
fn thread_count_and_zero_reference_surface() {
    let text = RAYLEIGH.replace("SPP", "16384");
    let independent = run_rows(&experiment(&text));
    let exp = experiment(&grouped(&text, 5, 4));
    let (one, two) = run_on_1_and_2_threads(&exp);
    assert_eq!(one.len(), 10);
    for (x, y) in one.iter().zip(&two) {
        assert_eq!((x.wavelength, x.measure), (y.wavelength, y.measure));
        assert_eq!(x.acc, y.acc, "results differ between 1 and 2 threads");
    }
    let rows = simulator::products::rows(&exp, &one);
    let brf = |r: &[Row]| -> Vec<Row> { r.iter().filter(|x| x.brf.is_some()).cloned().collect() };
    check(
        "Rayleigh, black central surface, grouped vs independent",
        &brf(&rows),
        &brf(&independent),
    )
    .unwrap();
    // Fluxes (albedo) too.
    for (x, y) in rows
        .iter()
        .zip(&independent)
        .filter(|(x, _)| x.albedo.is_some())
    {
        let (p, q) = (x.albedo.unwrap(), y.albedo.unwrap());
        let s = (p.1 * p.1 + q.1 * q.1).sqrt();
        assert!(
            (p.0 - q.0).abs() <= K * s + 1e-9,
            "albedo {} nm: {p:?} vs {q:?}",
            x.wavelength_nm
        );
    }
    // Checkpoints stay per wavelength: a resumed run loads every group and changes nothing.
    let dir = std::env::temp_dir().join(format!("simulate-mono-alis-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let (full, resumed) = simulator::run::run_resumable(&exp, false, &dir).unwrap();
    assert_eq!(resumed, 0);
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 10);
    std::fs::remove_file(dir.join("w002_m001.json")).unwrap();
    let (again, resumed) = simulator::run::run_resumable(&exp, false, &dir).unwrap();
    assert_eq!(resumed, 5, "the other measure's group is loaded");
    for ((x, y), z) in full.iter().zip(&again).zip(&one) {
        assert_eq!(x.acc, y.acc);
        assert_eq!(x.acc, z.acc);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn config_errors() {
    let base = RAYLEIGH.replace("SPP", "100");
    let err = |text: String| match Experiment::from_str(&text, &data_dir().join("test.toml")) {
        Ok(_) => panic!("accepted:\n{text}"),
        Err(e) => e.to_string(),
    };
    let alis = |extra: &str| {
        base.replace(
            "[integrator]\ntype = \"backward\"\n",
            &format!("[integrator]\ntype = \"backward\"\nspectral_walk = \"alis\"\n{extra}"),
        )
    };
    let cases: Vec<(String, Vec<&str>)> = vec![
        (
            format!("polarized = true\n{}", alis("")),
            vec!["integrator.spectral_walk", "polarized"],
        ),
        (
            alis("").replace("type = \"backward\"\n", "type = \"forward\"\n"),
            vec!["integrator.spectral_walk", "backward walk"],
        ),
        (
            alis("").replace(
                "[atmosphere]",
                "[geometry]\ntype = \"spherical_shell\"\n[atmosphere]",
            ),
            vec!["integrator.spectral_walk", "plane-parallel"],
        ),
        (
            alis("alis_group = 0\n"),
            vec!["integrator.alis_group", "1 … 64"],
        ),
        (
            alis("alis_group = 65\n"),
            vec!["integrator.alis_group", "65"],
        ),
        (
            alis("").replace("spectral_walk = \"alis\"", "spectral_walk = \"grouped\""),
            vec!["integrator.spectral_walk", "\"grouped\"", "independent"],
        ),
        (
            base.replace("[integrator]\n", "[integrator]\nalis_group = 8\n"),
            vec!["integrator.alis_group", "spectral_walk"],
        ),
        (
            base.replace("[integrator]\n", "[integrator]\nckd_walk = \"alis\"\n"),
            vec!["integrator.ckd_walk", "spectral_walk"],
        ),
    ];
    for (text, needles) in cases {
        let e = err(text);
        println!("{e}");
        for n in needles {
            assert!(e.contains(n), "`{n}` not in: {e}");
        }
    }
}
