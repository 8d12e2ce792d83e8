//! Particle (aerosol) layers in the molecular atmosphere (`[[atmosphere.particle_layers]]`).
//!
//! * `molecular_with_particles_equals_layered`: a molecular atmosphere with an exponential
//!   layer of the IPRT water-soluble aerosol (`fixtures/waso.mie.cdf`, 350 nm) is the same
//!   medium as a `layered` atmosphere built by hand from the same per-layer Rayleigh optical
//!   thickness τ_ray (read from a Rayleigh-only molecular run), aerosol optical thickness
//!   τ_aer = τ·(closed-form fraction of the exponential) and ω of the file, whose mixed layers use
//!   a tabulated phase function P = (τ_ray·P_R + τ_aer·ω·P_aer)/(τ_ray + τ_aer·ω) written to a
//!   libRadtran-format file (0.05° grid). The two TOA BRFs must agree within the statistical test
//!   (independent seeds, σ of the difference); the aerosol's effect on the BRF is many σ, so the
//!   comparison has power.
//! * `column_optical_thickness`: the column particle optical thickness read back from the
//!   resolved optics (total τ minus the Rayleigh-only τ) equals `optical_thickness` at the
//!   reference wavelength, and scales as ext(λ)/ext(λ_ref) elsewhere (Aer-Core v2 desert
//!   dataset); per-layer albedos are (τ_ray + τ_aer·ω)/(τ_ray + τ_aer).
//! * `config_errors`: errors name the key path, file and range.

mod common;
use common::*;

use engine::config::Experiment;
use engine::phase::{PhaseFunction, Rayleigh, Tabulated};
use std::path::{Path, PathBuf};

const WASO_SSA: f64 = 0.975682810500885; // ncdump of fixtures/waso.mie.cdf, `ssa`

fn experiment_text(wavelengths: &str, atmosphere: &str, seed: u64, measures: &str) -> String {
    format!(
        r#"
seed = {seed}
[spectral]
wavelengths = [{wavelengths}]
[atmosphere]
{atmosphere}
[surface]
type = "lambertian"
reflectance = 0.1
[illumination]
type = "directional"
zenith = 30.0
azimuth = 0.0
[integrator]
type = "forward"
{measures}"#
    )
}

/// Per-layer (bottom m, top m, extinction τ, single-scattering albedo), bottom to top.
fn layer_optics(exp: &Experiment, iw: usize) -> Vec<(f64, f64, f64, f64)> {
    let atm = &exp.optics[iw].atmosphere;
    let b: Vec<(f64, f64)> = atm.boundaries().collect();
    let mut out: Vec<_> = (0..b.len() - 1)
        .map(|i| (b[i + 1].0, b[i].0, b[i + 1].1 - b[i].1, atm.albedo(i)))
        .collect();
    out.reverse();
    out
}

/// A libRadtran-format netCDF with one P11 table at 350 nm.
fn write_phase_file(path: &Path, theta: &[f64], p: &[f64]) {
    let n = theta.len();
    let mut f = netcdf::create(path).unwrap();
    for (d, len) in [("nlam", 1), ("nreff", 1), ("nphamat", 1), ("nthetamax", n)] {
        f.add_dimension(d, len).unwrap();
    }
    f.add_variable::<f64>("wavelen", &["nlam"])
        .unwrap()
        .put_values(&[0.35], ..)
        .unwrap();
    let dims = ["nlam", "nreff", "nphamat", "nthetamax"];
    f.add_variable::<f64>("theta", &dims)
        .unwrap()
        .put_values(theta, ..)
        .unwrap();
    f.add_variable::<f64>("phase", &dims)
        .unwrap()
        .put_values(p, ..)
        .unwrap();
    f.add_variable::<i32>("ntheta", &["nlam", "nreff", "nphamat"])
        .unwrap()
        .put_values(&[n as i32], ..)
        .unwrap();
}

#[test]
fn molecular_with_particles_equals_layered() {
    let tau_aer_total = 0.3;
    let h: f64 = 1.0; // km
    let particles = format!(
        "[[atmosphere.particle_layers]]\nbottom = 0.0\ntop = 2.0\noptical_thickness = {tau_aer_total:?}\n\
         reference_wavelength = 350.0\ndistribution = {{ type = \"exponential\", scale_height = {h:?} }}\n\
         dataset = \"fixtures/waso.mie.cdf\"\n"
    );
    let molecular =
        "type = \"molecular\"\nprofile = \"afgl_1986-us_standard\"\nlayer_thickness = 1.0\n";
    let vza = [0.0, 20.0, 40.0, 60.0, 70.0, 40.0, 60.0];
    let vaa = [0.0, 0.0, 0.0, 0.0, 0.0, 180.0, 180.0];
    let spp = 200_000;
    let measures = mdistant_toml("toa", &vza, &vaa, spp);

    // Rayleigh-only optics: τ_ray per layer.
    let ray_exp = experiment(&experiment_text("350.0", molecular, 7, &measures));
    let ray = layer_optics(&ray_exp, 0);
    assert!(ray.iter().all(|l| l.3 == 1.0));
    let with = experiment(&experiment_text(
        "350.0",
        &format!("{molecular}{particles}"),
        7,
        &measures,
    ));

    // The layered equivalent, by hand.
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("aerosol_equivalence");
    std::fs::create_dir_all(&dir).unwrap();
    let waso =
        Tabulated::load_libradtran(&data_dir().join("fixtures/waso.mie.cdf"), 350.0, 0).unwrap();
    let depol = engine::atmosphere::molecular::depolarization(350.0);
    let rayleigh = PhaseFunction::Rayleigh(Rayleigh::new(depol).unwrap());
    let theta: Vec<f64> = (0..=3600).map(|i| i as f64 * 0.05).collect();
    let norm = 1.0 - (-2.0 / h).exp();
    let mut layers = String::new();
    let mut tau_aer_sum = 0.0;
    for (j, &(b, t, tau_ray, _)) in ray.iter().enumerate() {
        let (bk, tk) = (b / 1e3, t / 1e3);
        let frac = if tk <= 2.0 {
            ((-bk / h).exp() - (-tk / h).exp()) / norm
        } else {
            0.0
        };
        let tau_aer = tau_aer_total * frac;
        tau_aer_sum += tau_aer;
        let (sca, abs) = (tau_ray + tau_aer * WASO_SSA, tau_aer * (1.0 - WASO_SSA));
        let phase = if tau_aer > 0.0 {
            let (w_r, w_a) = (tau_ray / sca, tau_aer * WASO_SSA / sca);
            let p: Vec<f64> = theta
                .iter()
                .map(|t| {
                    let mu = t.to_radians().cos();
                    w_r * rayleigh.eval(mu) + w_a * waso.eval(mu)
                })
                .collect();
            let file = dir.join(format!("mixed_layer_{j}.cdf"));
            write_phase_file(&file, &theta, &p);
            format!("{{ type = \"tabulated\", file = \"{}\" }}", file.display())
        } else {
            format!("{{ type = \"rayleigh\", depolarization = {depol:?} }}")
        };
        layers.push_str(&format!(
            "[[atmosphere.layers]]\nbottom = {bk:?}\ntop = {tk:?}\ntau_sca = {sca:?}\ntau_abs = {abs:?}\nphase = {phase}\n"
        ));
    }
    assert!((tau_aer_sum - tau_aer_total).abs() < 1e-15);
    let layered = experiment(&experiment_text(
        "350.0",
        &format!("type = \"layered\"\n{layers}"),
        8,
        &measures,
    ));
    // Same optical depths and albedos, layer by layer (only the phase representation differs).
    let (lm, ll) = (layer_optics(&with, 0), layer_optics(&layered, 0));
    assert_eq!(lm.len(), ll.len());
    for (j, (a, b)) in lm.iter().zip(&ll).enumerate() {
        assert!(
            (a.2 - b.2).abs() <= 1e-13 * a.2 && (a.3 - b.3).abs() < 1e-12,
            "layer {j}: molecular {a:?} vs layered {b:?}"
        );
    }

    let rows_m = run_rows(&with);
    let rows_l = run_rows(&layered);
    let rows_r = run_rows(&ray_exp);
    let mut cmps = Vec::new();
    let mut min_effect: f64 = f64::INFINITY;
    for ((m, l), r) in rows_m.iter().zip(&rows_l).zip(&rows_r) {
        let ((vm, em), (vl, el), (vr, er)) = (m.brf.unwrap(), l.brf.unwrap(), r.brf.unwrap());
        println!(
            "vza {:>4} vaa {:>5}: molecular+aerosol {vm:.6} ± {em:.1e}, layered {vl:.6} ± {el:.1e}, Rayleigh only {vr:.6}",
            m.vza.unwrap(),
            m.vaa.unwrap()
        );
        min_effect = min_effect.min((vm - vr).abs() / (em * em + er * er).sqrt());
        cmps.push(Cmp {
            label: format!("vza {} vaa {}", m.vza.unwrap(), m.vaa.unwrap()),
            reference: vl,
            value: vm,
            stderr: (em * em + el * el).sqrt(),
        });
    }
    println!("smallest aerosol effect on the BRF: {min_effect:.1} sigma");
    assert!(min_effect > 10.0, "the aerosol must change the BRF visibly");
    check_all("molecular + waso vs layered", &cmps).unwrap();
}

fn eradiate_desert() -> Option<PathBuf> {
    let p = std::env::var_os("SIMULATOR_SHARED_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data"))
        .join("eradiate/aerosol/govaerts_2021-desert-aer_core_v2.nc");
    p.exists().then_some(p)
}

#[test]
fn column_optical_thickness() {
    let measures = "[[measures]]\nid = \"toa\"\ntype = \"distant_flux\"\nspp = 10\n";
    let molecular = "type = \"molecular\"\nlayer_thickness = 0.7\n";
    // waso at its wavelength, exponential; and the desert dataset at three wavelengths.
    let mut cases = vec![(
        "350.0".to_string(),
        "[[atmosphere.particle_layers]]\nbottom = 0.3\ntop = 4.1\noptical_thickness = 0.37\n\
         reference_wavelength = 350.0\ndistribution = { type = \"exponential\", scale_height = 1.3 }\n\
         dataset = \"fixtures/waso.mie.cdf\"\n"
            .to_string(),
        vec![(0.37, WASO_SSA)],
    )];
    if let Some(desert) = eradiate_desert() {
        // ncdump: ext(443, 550, 860) = 0.035996782, 0.031535548, 0.025125728 km⁻¹;
        // ssa = 0.922829712944896, 0.931394184112482, 0.943026128436955.
        let r = |e: f64| 0.2 * e / 0.031535548;
        cases.push((
            "550.0, 443.0, 860.0".into(),
            format!(
                "[[atmosphere.particle_layers]]\nbottom = 1.0\ntop = 5.0\noptical_thickness = 0.2\n\
                 distribution = {{ type = \"gaussian\", mean = 2.5, std = 0.8 }}\ndataset = \"{}\"\n",
                desert.display()
            ),
            vec![
                (0.2, 0.931394184112482),
                (r(0.035996782), 0.922829712944896),
                (r(0.025125728), 0.943026128436955),
            ],
        ));
    } else {
        eprintln!("skipping the Aer-Core part: shared/data/eradiate/aerosol not found");
    }
    for (wl, particles, want) in cases {
        let ray = experiment(&experiment_text(&wl, molecular, 1, measures));
        let with = experiment(&experiment_text(
            &wl,
            &format!("{molecular}{particles}"),
            1,
            measures,
        ));
        for (iw, &(tau_want, ssa)) in want.iter().enumerate() {
            let (lr, lw) = (layer_optics(&ray, iw), layer_optics(&with, iw));
            let tau_aer: Vec<f64> = lr.iter().zip(&lw).map(|(r, w)| w.2 - r.2).collect();
            let column: f64 = tau_aer.iter().sum();
            let total =
                with.optics[iw].atmosphere.total_tau() - ray.optics[iw].atmosphere.total_tau();
            println!(
                "{} nm: column particle tau = {column:.15} (from totals {total:.15}), expected {tau_want:.15}",
                with.wavelengths[iw]
            );
            assert!((column - tau_want).abs() < 1e-13, "{column} vs {tau_want}");
            assert!((total - tau_want).abs() < 1e-13, "{total} vs {tau_want}");
            for (j, ((r, w), ta)) in lr.iter().zip(&lw).zip(&tau_aer).enumerate() {
                let albedo = (r.2 + ta * ssa) / (r.2 + ta);
                assert!(
                    (w.3 - albedo).abs() < 1e-12,
                    "layer {j}: {} vs {albedo}",
                    w.3
                );
                if *ta < 1e-13 {
                    // No particles: plain Rayleigh, the Rayleigh-only layer (τ read back as
                    // differences of cumulative depths, so equal up to rounding).
                    assert!((w.2 - r.2).abs() < 1e-14, "layer {j}");
                    assert!(matches!(
                        with.optics[iw].atmosphere.phase(lw.len() - 1 - j),
                        PhaseFunction::Rayleigh(_)
                    ));
                } else {
                    assert!(matches!(
                        with.optics[iw].atmosphere.phase(lw.len() - 1 - j),
                        PhaseFunction::Mixture(_)
                    ));
                }
            }
        }
    }
}

#[test]
fn config_errors() {
    let measures = "[[measures]]\nid = \"toa\"\ntype = \"distant_flux\"\nspp = 10\n";
    let err = |wl: &str, layer: &str| {
        let text = experiment_text(
            wl,
            &format!("type = \"molecular\"\n[[atmosphere.particle_layers]]\n{layer}"),
            1,
            measures,
        );
        match Experiment::from_str(&text, &data_dir().join("test.toml")) {
            Ok(_) => panic!("accepted:\n{text}"),
            Err(e) => e.to_string(),
        }
    };
    let waso = "dataset = \"fixtures/waso.mie.cdf\"\n";
    let cases = [
        (
            "550.0",
            format!("bottom = 0.0\ntop = 2.0\noptical_thickness = 0.1\nreference_wavelength = 350.0\n{waso}"),
            vec!["atmosphere.particle_layers[0].dataset", "550 nm", "350..350 nm", "waso.mie.cdf"],
        ),
        (
            "350.0",
            format!("bottom = 0.0\ntop = 2.0\noptical_thickness = 0.1\n{waso}"),
            vec!["atmosphere.particle_layers[0].reference_wavelength", "550 nm", "350..350 nm"],
        ),
        (
            "350.0",
            "bottom = 0.0\ntop = 2.0\noptical_thickness = 0.1\ndataset = \"nope.nc\"\n".into(),
            vec!["atmosphere.particle_layers[0].dataset", "nope.nc", "not found"],
        ),
        (
            "350.0",
            format!("bottom = 0.0\ntop = 200.0\noptical_thickness = 0.1\nreference_wavelength = 350.0\n{waso}"),
            vec!["atmosphere.particle_layers[0].top"],
        ),
        (
            "350.0",
            format!("bottom = 0.0\ntop = 2.0\noptical_thickness = -0.1\nreference_wavelength = 350.0\n{waso}"),
            vec!["atmosphere.particle_layers[0].optical_thickness"],
        ),
        (
            "350.0",
            format!("bottom = 0.0\ntop = 2.0\noptical_thickness = 0.1\nreference_wavelength = 350.0\ndistribution = {{ type = \"exponential\", scale_height = 0.0 }}\n{waso}"),
            vec!["atmosphere.particle_layers[0].distribution.scale_height"],
        ),
        (
            "350.0",
            format!("bottom = 0.0\ntop = 2.0\noptical_thickness = 0.1\nreference_wavelength = 350.0\nthickness = 3.0\n{waso}"),
            vec!["thickness"],
        ),
    ];
    for (wl, layer, needles) in cases {
        let e = err(wl, &layer);
        println!("{e}");
        for n in needles {
            assert!(e.contains(n), "`{n}` not in: {e}");
        }
        assert!(!e.contains("NaN"), "{e}");
    }
}
