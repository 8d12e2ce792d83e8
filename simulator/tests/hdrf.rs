//! The `hdrf` measure (issue 17 item 5): the hemispherical–directional reflectance factor
//! `π·L↑(v)/E↓` at the surface of a 1D atmosphere, against three independent references:
//!
//! * **DisORT++** (`tests/data/disort/hdrf.csv`, `tools/disort_reference/fluxes.py`): RPV
//!   surfaces E1 and E2 under a Rayleigh layer (τ 0.2, SZA 30°), 9 zeniths in the principal
//!   (both halves) and cross planes, 96 streams (converged to 3e-6 against 80), the directly
//!   reflected beam made exact as for the TOA case E tables;
//! * **closed form, Lambertian**: `L↑ = ρ·E↓/π` at the surface whatever the sky, so HDRF = ρ in
//!   every direction (a Rayleigh layer and an absorbing HG layer, SZA 30° and 60°, and the
//!   Rayleigh layer in spherical shells);
//! * **closed form, no atmosphere**: with τ = 0 all light is the direct beam, so the HDRF is the
//!   BRF `π·f(s, v)` of the surface; the RPV formula is written out here from Rahman et al.
//!   (1993), independently of `bsdf/rpv.rs`.
//!
//! Statistical test: `common::check_all` (|diff| ≤ 4.5σ + max(1e-5, 2e-4·ref)); σ is the
//! delta-method standard error of the ratio of the two independent estimates (radiance and
//! diffuse downwelling flux).

mod common;
use common::*;

fn experiment_text(atmosphere: &str, surface: &str, sza: f64, measure: &str) -> String {
    format!(
        r#"
seed = 11
[spectral]
wavelengths = [550.0]
[atmosphere]
{atmosphere}
[surface]
{surface}
[illumination]
type = "directional"
zenith = {sza:?}
azimuth = 0.0
{measure}"#
    )
}

fn hdrf_toml(vza: &[f64], vaa: &[f64], spp: u64) -> String {
    directions_toml("hdrf", "boa", vza, vaa, spp)
}

/// RPV BRF (Rahman, Pinty & Verstraete 1993, ρ_c = ρ_0), raa = 0 on the Sun's side.
fn rpv_brf(rho0: f64, k: f64, g: f64, sza: f64, vza: f64, raa: f64) -> f64 {
    let (ti, to, dphi) = (sza.to_radians(), vza.to_radians(), raa.to_radians());
    let (ci, co) = (ti.cos(), to.cos());
    let m = (ci * co * (ci + co)).powf(k - 1.0);
    let cos_g = ci * co + ti.sin() * to.sin() * dphi.cos();
    let f = (1.0 - g * g) / (1.0 + 2.0 * g * cos_g + g * g).powf(1.5);
    let big_g = (ti.tan().powi(2) + to.tan().powi(2) - 2.0 * ti.tan() * to.tan() * dphi.cos())
        .max(0.0)
        .sqrt();
    rho0 * m * f * (1.0 + (1.0 - rho0) / (1.0 + big_g))
}

#[test]
fn hdrf_matches_disortpp_over_rpv() {
    let text = std::fs::read_to_string(data_dir().join("disort/hdrf.csv")).unwrap();
    let rows: Vec<Vec<String>> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect();
    let mut errs = Vec::new();
    for case in ["E1", "E2"] {
        let refs: Vec<&Vec<String>> = rows.iter().filter(|r| r[0] == case).collect();
        let p = |r: &Vec<String>, i: usize| r[i].parse::<f64>().unwrap();
        let (tau, sza, rho0, k, g) = (
            p(refs[0], 1),
            p(refs[0], 2),
            p(refs[0], 3),
            p(refs[0], 4),
            p(refs[0], 5),
        );
        let vza: Vec<f64> = refs.iter().map(|r| p(r, 7)).collect();
        let raa: Vec<f64> = refs.iter().map(|r| p(r, 6)).collect();
        let exp = experiment(&experiment_text(
            &format!(
                "type = \"homogeneous\"\noptical_thickness = {tau:?}\nphase = {{ type = \"rayleigh\" }}"
            ),
            &format!("type = \"rpv\"\nrho_0 = {rho0:?}\nk = {k:?}\ng = {g:?}"),
            sza,
            &hdrf_toml(&vza, &raa, 200_000),
        ));
        let out = run_rows_light_tailed(&exp);
        assert_eq!(out.len(), refs.len(), "one row per direction");
        let cmps: Vec<Cmp> = refs
            .iter()
            .zip(&out)
            .map(|(r, o)| {
                let (v, e) = o.hdrf.unwrap();
                Cmp {
                    label: format!("vza {} raa {}", r[7], r[6]),
                    reference: p(r, 9),
                    value: v,
                    stderr: e,
                }
            })
            .collect();
        if let Err(e) = check_all(&format!("HDRF {case} vs DisORT++"), &cmps) {
            errs.push(e);
        }
    }
    assert!(errs.is_empty(), "{}", errs.join("\n"));
}

#[test]
fn hdrf_of_a_lambertian_surface_is_its_reflectance() {
    let vza = [0.0, 30.0, 60.0, 75.0];
    let vaa = [0.0, 90.0, 180.0, 45.0];
    let mut errs = Vec::new();
    for (atm, sza) in [
        (
            "type = \"homogeneous\"\noptical_thickness = 0.5\nphase = { type = \"rayleigh\" }",
            30.0,
        ),
        (
            "type = \"homogeneous\"\noptical_thickness = 1.0\nsingle_scattering_albedo = 0.9\nphase = { type = \"hg\", g = 0.7 }",
            60.0,
        ),
        // Spherical shells: the paths start on the ground looking down (they once flew
        // through the planet instead of meeting the ground at once).
        (
            "type = \"homogeneous\"\noptical_thickness = 0.5\nphase = { type = \"rayleigh\" }\n[geometry]\ntype = \"spherical_shell\"",
            30.0,
        ),
    ] {
        let exp = experiment(&experiment_text(
            atm,
            "type = \"lambertian\"\nreflectance = 0.3",
            sza,
            &hdrf_toml(&vza, &vaa, 150_000),
        ));
        let out = run_rows_light_tailed(&exp);
        let cmps: Vec<Cmp> = out
            .iter()
            .map(|o| {
                let (v, e) = o.hdrf.unwrap();
                Cmp {
                    label: format!("vza {:?} vaa {:?}", o.vza.unwrap(), o.vaa.unwrap()),
                    reference: 0.3,
                    value: v,
                    stderr: e,
                }
            })
            .collect();
        if let Err(e) = check_all(&format!("Lambertian HDRF, sza {sza}"), &cmps) {
            errs.push(e);
        }
    }
    assert!(errs.is_empty(), "{}", errs.join("\n"));
}

#[test]
fn hdrf_without_atmosphere_is_the_brf() {
    let (rho0, k, g, sza) = (0.25, 1.2, 0.15, 40.0);
    let vza = [0.0, 20.0, 40.0, 60.0, 40.0, 40.0];
    let vaa = [0.0, 0.0, 0.0, 180.0, 90.0, 120.0];
    let exp = experiment(&experiment_text(
        "type = \"homogeneous\"\noptical_thickness = 0.0",
        &format!("type = \"rpv\"\nrho_0 = {rho0:?}\nk = {k:?}\ng = {g:?}"),
        sza,
        &hdrf_toml(&vza, &vaa, 64),
    ));
    let out = run_rows(&exp);
    for (o, (z, a)) in out.iter().zip(vza.iter().zip(&vaa)) {
        let (v, e) = o.hdrf.unwrap();
        let want = rpv_brf(rho0, k, g, sza, *z, *a);
        println!("vza {z} raa {a}: HDRF {v:.8} ± {e:.1e}, BRF {want:.8}");
        assert!(
            (v - want).abs() < 1e-9 * want,
            "vza {z} raa {a}: {v} vs {want}"
        );
        // Every sample is the same number: the variance is rounding only.
        assert!(
            e < 1e-8 * want,
            "no Monte Carlo noise without an atmosphere: {e}"
        );
    }
}
