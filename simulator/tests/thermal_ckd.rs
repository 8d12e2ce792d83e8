//! Thermal emission with gas absorption: `mode = "ckd"` with RRTMGP's longwave k-distribution
//! (`shared/data/ckd/rrtmgp/rrtmgp-gas-lw-g256.nc`) over a `molecular` atmosphere whose
//! temperatures come from its profile (issue 16, item 2).
//!
//! * **Closed form** (`non_scattering_column_equals_closed_form`): without scattering (no
//!   Rayleigh, no particles) over a black surface, the TOA radiance of every g-point is the
//!   formal solution `B_s·s_{g,0}·e^{−τ*_g/μ} + Σ_layers e^{−τ_above/μ}·∫ (source linear in τ)`,
//!   written out here independently of the simulator's transport (its own layer grid, level
//!   temperatures from the profile, the layer integral in closed form), with the gas optical
//!   thicknesses and Planck fractions of `absorption::Rrtmgp`. The backward walk has no variance
//!   there, so the test is exact (1e-9), for the independent g-point walk and the ALIS walk.
//! * **Quadrature** (`ckd_run_is_the_g_point_quadrature`): with scattering (a soot layer at
//!   10.9 µm) and a reflecting surface, a CKD run equals Σ_g w_g·R_g of sixteen runs with one
//!   g-point each (`spectral.g_point`; independent seeds): z-test.
//! * **ALIS = independent** (`alis_equals_independent_walks`): the g-point ALIS walk against
//!   independent g-point walks, scattering, thermal only at 10.9 µm and with the Sun at 3.8 µm:
//!   z-test on the radiances.
//! * **Physics** (`us_standard_physics`): over the US standard atmosphere with a black surface at
//!   its 288.2 K, the 10.9 µm window sees nearly the surface (BT 284–288.2 K), the 15 µm CO₂
//!   band the cold upper troposphere and stratosphere (210–235 K), the 6.7 µm water band the
//!   mid troposphere (225–250 K); and the outgoing longwave flux (`distant_flux` up at TOA,
//!   integrated over 3.08 µm–1 mm) is within 3 % of the 265 W m⁻² that Kiehl & Trenberth (1997,
//!   BAMS 78, 197–208) computed for clear skies with the US standard atmosphere: a sanity
//!   bound on the gas optics and the Planck fractions together, not a precision reference.
//! * Errors: emission with a shortwave k-distribution names `atmosphere.absorption_data`.

mod common;
use common::*;

use engine::absorption::Rrtmgp;
use engine::sources::planck;

fn lw_file() -> Option<std::path::PathBuf> {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/data/ckd/rrtmgp/rrtmgp-gas-lw-g256.nc");
    if p.exists() {
        Some(p)
    } else {
        eprintln!("skipped: {} not found", p.display());
        None
    }
}

/// An experiment over the US standard atmosphere with RRTMGP longwave gas optics.
fn text(file: &std::path::Path, wavelengths: &[f64], extra_atmosphere: &str, rest: &str) -> String {
    format!(
        "mode = \"ckd\"\nemission = true\nseed = 11\n[spectral]\nwavelengths = {wavelengths:?}\n\
         [atmosphere]\ntype = \"molecular\"\nprofile = \"afgl_1986-us_standard\"\n\
         layer_thickness = 2.0\nabsorption_data = \"{}\"\n{extra_atmosphere}\n{rest}",
        file.display()
    )
}

/// `∫₀^D e^{−y}·(a + (b − a)·y/D) dy` (a source linear in optical depth across a layer of
/// slant optical thickness D, seen from its top).
fn layer_integral(a: f64, b: f64, d: f64) -> f64 {
    let one_minus = -(-d).exp_m1();
    // (1 − (1 + D)e^{−D})/D, by its series for small D.
    let g = if d < 1e-3 {
        d / 2.0 - d * d / 3.0 + d * d * d / 8.0
    } else {
        (1.0 - (1.0 + d) * (-d).exp()) / d
    };
    a * one_minus + (b - a) * g
}

#[test]
fn non_scattering_column_equals_closed_form() {
    let Some(file) = lw_file() else { return };
    let wls = [10_900.0, 15_000.0, 6_700.0, 4_000.0, 25_000.0];
    let zeniths = [0.0, 60.0];
    let t_s = 288.15;
    let rest = format!(
        "[surface]\ntype = \"lambertian\"\nreflectance = 0.0\ntemperature = {t_s}\n\
         [illumination]\ntype = \"none\"\n{}",
        mdistant_toml("toa", &zeniths, &[0.0, 0.0], 16)
    );
    let base = text(&file, &wls, "rayleigh = false", &rest);
    let alis = base.clone() + "[integrator]\nckd_walk = \"alis\"\n";

    // The reference: the test's own layer grid (2 km from 0 to 100 km) and level temperatures
    // (linear in altitude between the profile's levels).
    let rr = Rrtmgp::open(&file).unwrap();
    let thermo =
        engine::atmosphere::thermo::load("afgl_1986-us_standard", std::path::Path::new("."))
            .unwrap();
    let prof = &thermo.gas;
    let grid: Vec<(f64, f64)> = (0..50)
        .map(|i| (i as f64 * 2000.0, (i + 1) as f64 * 2000.0))
        .collect();
    let t_at = |z: f64| -> f64 {
        let zs = &prof.altitude_m;
        let i = zs.iter().rposition(|&x| x <= z).unwrap().min(zs.len() - 2);
        let f = (z - zs[i]) / (zs[i + 1] - zs[i]);
        prof.temperature_k[i] + f * (prof.temperature_k[i + 1] - prof.temperature_k[i])
    };
    let bands = rr.bands_nm();
    let mut expected = Vec::new();
    for &wl in &wls {
        let band = bands
            .iter()
            .position(|&(lo, hi)| lo <= wl && wl < hi)
            .unwrap();
        let (tau, pfrac) = rr.layer_optics(prof, &grid, band, true).unwrap();
        let pfrac = pfrac.unwrap();
        let sum0: f64 = pfrac.iter().map(|p| p[0]).sum();
        let b = |t: f64| planck::radiance(wl, t);
        for &vza in &zeniths {
            let mu = f64::cos(vza * std::f64::consts::PI / 180.0);
            let mut l = 0.0;
            for g in 0..tau.len() {
                let w = pfrac[g][0] / sum0;
                let s = |layer: usize| pfrac[g][layer] / w;
                let total: f64 = tau[g].iter().sum();
                let mut lg = s(0) * b(t_s) * (-total / mu).exp();
                let mut above = 0.0;
                for layer in (0..grid.len()).rev() {
                    let (bottom, top) = grid[layer];
                    let d = tau[g][layer] / mu;
                    lg += (-above / mu).exp()
                        * layer_integral(s(layer) * b(t_at(top)), s(layer) * b(t_at(bottom)), d);
                    above += tau[g][layer];
                }
                l += w * lg;
            }
            expected.push((wl, vza, l));
        }
    }
    for (name, t) in [("independent", &base), ("alis", &alis)] {
        let rows = run_rows(&experiment(t));
        assert_eq!(rows.len(), expected.len());
        for (r, (wl, vza, l)) in rows.iter().zip(&expected) {
            assert_eq!(r.wavelength_nm, *wl);
            let (v, _) = r.radiance.unwrap();
            let rel = (v / l - 1.0).abs();
            println!(
                "{name} {wl} nm, {vza}°: {v:.9e} vs closed form {l:.9e} (rel {rel:.1e}), BT {:.3} K",
                r.brightness_temperature.unwrap().0
            );
            assert!(rel < 1e-9, "{name} {wl} nm {vza}°: {v} vs {l}");
        }
    }
}

/// The soot layer and surface of the scattering cases.
const SOOT: &str =
    "[[atmosphere.particle_layers]]\nbottom = 0.0\ntop = 3.0\noptical_thickness = 1.0\n\
                    reference_wavelength = 10000.0\n\
                    dataset = \"../../../../shared/data/eradiate/aerosol/soot.mie-aer_core_v2.nc\"";

fn soot_dataset_exists() -> bool {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/data/eradiate/aerosol/soot.mie-aer_core_v2.nc");
    p.exists()
}

#[test]
fn ckd_run_is_the_g_point_quadrature() {
    let Some(file) = lw_file() else { return };
    if !soot_dataset_exists() {
        return;
    }
    let rest = |spp: u64| {
        format!(
            "[surface]\ntype = \"lambertian\"\nreflectance = 0.1\ntemperature = 290.0\n\
             [illumination]\ntype = \"none\"\n{}",
            mdistant_toml("toa", &[0.0, 50.0], &[0.0, 0.0], spp)
        )
    };
    let bin = run_rows(&experiment(&text(&file, &[10_900.0], SOOT, &rest(64_000))));
    let rr = Rrtmgp::open(&file).unwrap();
    let band = rr
        .bands_nm()
        .iter()
        .position(|&(lo, hi)| lo <= 10_900.0 && 10_900.0 < hi)
        .unwrap();
    let ng = rr.gpoints_of_band(band).len();
    // The bin's quadrature weights: the lowest layer's Planck fractions, normalised.
    let thermo =
        engine::atmosphere::thermo::load("afgl_1986-us_standard", std::path::Path::new("."))
            .unwrap();
    let (_, pf) = rr
        .layer_optics(&thermo.gas, &[(0.0, 2000.0)], band, true)
        .unwrap();
    let pf = pf.unwrap();
    let sum: f64 = pf.iter().map(|p| p[0]).sum();
    let mut total = [0.0f64; 2];
    let mut var = [0.0f64; 2];
    #[allow(clippy::needless_range_loop)]
    for g in 0..ng {
        let t = text(&file, &[10_900.0], SOOT, &rest(8_000))
            .replace("seed = 11", &format!("seed = {}", 100 + g))
            .replace("[spectral]\n", &format!("[spectral]\ng_point = {g}\n"));
        let rows = run_rows(&experiment(&t));
        let w = pf[g][0] / sum;
        for (i, r) in rows.iter().enumerate() {
            let (v, se) = r.radiance.unwrap();
            total[i] += w * v;
            var[i] += (w * se).powi(2);
        }
    }
    let cmps: Vec<Cmp> = bin
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let (v, se) = r.radiance.unwrap();
            Cmp {
                label: format!("10.9 µm, direction {i}"),
                reference: total[i],
                value: v,
                stderr: (se * se + var[i]).sqrt(),
            }
        })
        .collect();
    check_all("CKD bin = Σ w_g R_g", &cmps).unwrap();
}

#[test]
fn alis_equals_independent_walks() {
    let Some(file) = lw_file() else { return };
    if !soot_dataset_exists() {
        return;
    }
    let cases = [
        (
            "thermal only, 10.9 µm",
            10_900.0,
            "[illumination]\ntype = \"none\"",
        ),
        (
            "Sun and emission, 3.8 µm",
            3_800.0,
            "[illumination]\ntype = \"directional\"\nzenith = 30.0\nazimuth = 0.0\nirradiance = 0.01",
        ),
    ];
    for (case, wl, illumination) in cases {
        let rest = format!(
            "[surface]\ntype = \"lambertian\"\nreflectance = 0.2\ntemperature = 300.0\n{illumination}\n{}",
            mdistant_toml("toa", &[0.0, 40.0, 70.0], &[0.0, 180.0, 0.0], 32_000)
        );
        let ind = run_rows(&experiment(&text(&file, &[wl], SOOT, &rest)));
        let alis = text(&file, &[wl], SOOT, &rest).replace("seed = 11", "seed = 12")
            + "[integrator]\nckd_walk = \"alis\"\n";
        let alis = run_rows(&experiment(&alis));
        let cmps: Vec<Cmp> = ind
            .iter()
            .zip(&alis)
            .enumerate()
            .map(|(i, (a, b))| {
                let (va, sa) = a.radiance.unwrap();
                let (vb, sb) = b.radiance.unwrap();
                Cmp {
                    label: format!("{case}, direction {i}"),
                    reference: va,
                    value: vb,
                    stderr: (sa * sa + sb * sb).sqrt(),
                }
            })
            .collect();
        check_all(case, &cmps).unwrap();
    }
}

#[test]
fn us_standard_physics() {
    let Some(file) = lw_file() else { return };
    let rest = format!(
        "[surface]\ntype = \"lambertian\"\nreflectance = 0.0\ntemperature = 288.2\n\
         [illumination]\ntype = \"none\"\n{}",
        mdistant_toml("toa", &[0.0], &[0.0], 16)
    );
    let rows = run_rows(&experiment(
        &(text(&file, &[10_900.0, 15_000.0, 6_700.0], "", &rest)
            + "[integrator]\nckd_walk = \"alis\"\n"),
    ));
    let bt: Vec<f64> = rows
        .iter()
        .map(|r| r.brightness_temperature.unwrap().0)
        .collect();
    println!(
        "nadir BT: 10.9 µm {:.2} K, 15 µm {:.2} K, 6.7 µm {:.2} K",
        bt[0], bt[1], bt[2]
    );
    assert!((284.0..288.2).contains(&bt[0]), "window {}", bt[0]);
    assert!((210.0..235.0).contains(&bt[1]), "CO2 {}", bt[1]);
    assert!((225.0..250.0).contains(&bt[2]), "H2O {}", bt[2]);

    // Outgoing longwave flux: 8 wavelengths per RRTMGP band at the midpoints of equal
    // wavenumber intervals, each flux (W m⁻² nm⁻¹) times its interval's width in nm.
    let rr = Rrtmgp::open(&file).unwrap();
    let mut wls = Vec::new();
    let mut widths = Vec::new();
    for (lo, hi) in rr.bands_nm() {
        let (nu_lo, nu_hi) = (1e7 / hi, 1e7 / lo);
        let k = 8;
        for j in 0..k {
            let a = nu_lo + (nu_hi - nu_lo) * j as f64 / k as f64;
            let b = nu_lo + (nu_hi - nu_lo) * (j + 1) as f64 / k as f64;
            wls.push(1e7 / (0.5 * (a + b)));
            widths.push(1e7 / a - 1e7 / b);
        }
    }
    let rest = "[surface]\ntype = \"lambertian\"\nreflectance = 0.0\ntemperature = 288.2\n\
                [illumination]\ntype = \"none\"\n\
                [[measures]]\nid = \"olr\"\ntype = \"distant_flux\"\ndirection = \"up\"\nspp = 4096\n\
                [integrator]\nckd_walk = \"alis\"\n";
    // 1 km layers (the default): 2 km ones give 259.0 W m⁻², 0.5 km 260.8 (the source linear
    // in τ across coarse, optically thick layers).
    let rows = run_rows(&experiment(
        &text(&file, &wls, "", rest).replace("layer_thickness = 2.0", "layer_thickness = 1.0"),
    ));
    let mut olr = 0.0;
    let mut var = 0.0;
    for r in &rows {
        let i = wls.iter().position(|&w| w == r.wavelength_nm).unwrap();
        let (f, se) = r.flux.expect("flux");
        olr += f * widths[i];
        var += (se * widths[i]).powi(2);
    }
    println!(
        "US standard clear-sky OLR: {olr:.2} ± {:.2} W m⁻² (Kiehl & Trenberth 1997: 265)",
        var.sqrt()
    );
    assert!((olr / 265.0 - 1.0).abs() < 0.03, "OLR {olr}");
}

#[test]
fn emission_needs_planck_fractions() {
    let sw = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/data/ckd/rrtmgp/rrtmgp-gas-sw-g224.nc");
    if !sw.exists() {
        return;
    }
    let rest = format!(
        "[surface]\ntype = \"lambertian\"\nreflectance = 0.0\ntemperature = 288.2\n\
         [illumination]\ntype = \"none\"\n{}",
        mdistant_toml("toa", &[0.0], &[0.0], 16)
    );
    let t = text(&sw, &[10_900.0], "", &rest);
    let e = engine::config::Experiment::from_str(&t, &data_dir().join("test.toml"))
        .expect_err("a shortwave file cannot serve thermal emission")
        .to_string();
    assert!(
        e.contains("atmosphere.absorption_data") && e.contains("Planck fractions"),
        "{e}"
    );
}
