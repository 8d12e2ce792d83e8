//! Spherical-shell single-scattering limb radiance against the benchmark of Zawada et al. (2021),
//! "Systematic comparison of vectorial spherical radiative transfer models in limb scattering
//! geometry", AMT 14:3953–3972 (doi:10.5194/amt-14-3953-2021): the single-scattered radiance I
//! of their test case "polarized single scattering, no refraction" over a black surface, as
//! extracted from the paper's netCDF by S. Korkin in korkins/limbss_2026_01_27 @75f2204c4cb9
//! (files: `tests/data/zawada2021/`; provenance: `tests/data/fixtures/PROVENANCE.md`).
//!
//! Benchmark set-up and how it is expressed here. Sources in brackets; "limbss" is the
//! independent single-scattering code of that repository (Python), which reproduces the
//! benchmark to ≤ 0.18 % (mean 0.10 %) over ~11 500 points with exactly these assumptions
//! [limbss `doc/20260127__limbss.pptx`, slide 18; README]:
//! * Earth radius 6371 km [limbss `main_limbss.py`: `Re = 6371.0`]. Our quadrature of the set-up
//!   changes by < 1e-4 relative between 6371 and 6372 km.
//! * Atmosphere 0–100 km (TOA = the profile's last level); air and O3 number densities on 1 km
//!   levels, **linear in altitude** between levels [limbss `linear_coefficients.py`: extinction
//!   and scattering coefficients `a·r + b` in each shell]. Scattering coefficient n_air·σ_R,
//!   absorption n_O3·σ_O3 (cross-sections of `xsection_rayleigh_ozone.txt`, cm² → km⁻¹ with
//!   n in cm⁻³). Our shells are homogeneous, so each 1 km interval is split into `SUB` = 5 shells
//!   whose optical thicknesses are the exact integrals of the linear profile over them. With 5
//!   sub-shells every benchmark tangent height (x.5 km) is the centre of a sub-shell, which keeps
//!   the piecewise-constant error small: by quadrature it is ≈ +0.03 % at 30.5 km, whereas 4
//!   sub-shells (tangent heights on a shell boundary) give −0.13 % and 2 give −0.34 % there.
//! * Rayleigh phase function **without depolarization**, P = 3/4 (1 + cos²Θ) [limbss
//!   `main_limbss.py`]; for unpolarized sunlight the single-scattered I does not depend on
//!   polarization. (Depolarization 0.0286 would change I by −1 % … +0.3 % depending on Θ,
//!   whereas the quadrature below is offset by the same +0.06 … +0.11 % in all four geometries.)
//! * No refraction (test case `itst0`); black Lambertian surface (`ialb0`: albedo 0
//!   [limbss `main_limbss.py`: "black - do not change"]); no twilight (SZA ≤ 80° here).
//! * Radiance per unit solar irradiance on a plane normal to the beam (F0 = 1, no factor π)
//!   [limbss `limbss.py`: `Iss = ∫J ds · F0/(4π)` with `F0 = 1`; data MANIFEST §5], i.e. our
//!   `radiance` with `irradiance = 1`.
//! * Solar zenith angle SZA and relative azimuth RAA are given **at the tangent point**, and the
//!   Sun is one fixed direction (parallel beam) for the whole line of sight [limbss `limbss.py`,
//!   `xyz_sol_shell.py`: one global solar direction for every point of the LOS]. RAA is the angle
//!   between the horizontal projections of the viewing direction (observer → tangent point) and
//!   of the direction towards the Sun: RAA = 0 looks towards the Sun, cos Θ = sin SZA·cos RAA
//!   [limbss: sensor at +s along (cos RAA, sin RAA, 0) from the tangent point, direction to the
//!   Sun (−sin SZA, 0, cos SZA)]. Checked independently: a quadrature with this convention
//!   agrees with the benchmark to ≈ 0.1 % at 0.5 and 10.5 km (SZA 70°, RAA 30°); the mirrored
//!   convention (RAA → 180° − RAA) is 6 % off at 0.5 km.
//! * The observer is outside the atmosphere; without refraction its position along the line of
//!   sight is irrelevant: the whole chord TOA → tangent point → TOA counts [limbss integrates the
//!   whole chord].
//!
//! In our experiment the tangent point lies on the vertical of the frame origin, at altitude h_t:
//! the radiancemeter starts 3000 km before it, `origin = [0, -3000, h_t]` (≈ 700 km up, outside
//! the atmosphere), and looks horizontally North, `direction = [0, 1, 0]`. The experiment's solar
//! angles are defined on the vertical of the frame origin, i.e. at the tangent point, so
//! `zenith = SZA` and `azimuth = RAA` (clockwise from North towards the Sun; the look direction
//! is North; the sign of the azimuth is immaterial by mirror symmetry). `max_depth = 1` keeps
//! single scattering only.
//!
//! Comparison: `common::check_all`'s test, |diff| ≤ 4.5σ + floor, but with the floor set to the
//! benchmark's own accuracy, `BENCH_REL` = 0.2 % of the reference, instead of
//! max(1e-5, 2e-4·ref): the models of Zawada et al. agree with one another to ≈ 0.2 % in the
//! single-scatter cases (their abstract), limbss reproduces the tabulated values to ≤ 0.18 %, and
//! an independent deterministic quadrature of the set-up above (4-point Gauss–Legendre on ≤ 1 km
//! pieces between shell crossings, along the LOS and along every solar path; linear profile) is
//! itself +0.06 … +0.11 % above the tabulated values at every case and height tried
//! (0.5–60.5 km). The same quadrature on our 5-sub-shell atmosphere is −0.005 … +0.034 % off the
//! linear one, and this test's simulations agree with that quadrature to ≤ 3e-5 relative where
//! the noise allows (e.g. 50.5 km, SZA 70°: 3.50369e-3 vs 3.50370e-3; 60.5 km, SZA 50°:
//! 7.60645e-4 vs 7.60645e-4; 40.5 km, SZA 50°: 8.80211e-3 vs 8.80210e-3). Hence the expected
//! difference to the benchmark is ≈ +0.05 … +0.14 %, inside the floor. The absolute floor 1e-5 is
//! dropped: it would be 0.3–1 % of the radiances at 300 nm and at the upper tangent heights.
//!
//! Noise: with the default along-flight local estimate (`local_estimate = "expected"`) the
//! pure-Rayleigh points have ≤ 0.04 % relative standard error (≪ 0.01 % from 20.5 km up, where
//! the single-scatter estimate only varies with the solar transmittance at the sampled points), so
//! there the floor alone decides and z-scores against the benchmark are large by construction;
//! the Rayleigh + O3 points have ≈ 0.1–0.3 %.

mod common;
use common::*;

use std::path::PathBuf;

/// Relative accuracy of the benchmark itself (inter-model agreement of the single-scatter cases,
/// Zawada et al. 2021).
const BENCH_REL: f64 = 2e-3;

/// Homogeneous sub-shells per 1 km level interval (odd: tangent heights x.5 km at shell centres).
const SUB: usize = 5;

/// Tangent heights compared (km), a subset of the benchmark's 0.5, 1.5, …, 79.5.
const HEIGHTS: [f64; 10] = [0.5, 5.5, 10.5, 15.5, 20.5, 25.5, 30.5, 40.5, 50.5, 60.5];

fn dir() -> PathBuf {
    data_dir().join("zawada2021")
}

/// Numeric rows of a whitespace- or comma-separated table (comment and header lines skipped).
fn table(name: &str) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(dir().join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
    text.lines()
        .filter(|l| l.trim().starts_with(|c: char| c.is_ascii_digit()))
        .map(|l| {
            l.split(|c: char| c == ',' || c.is_whitespace())
                .filter(|s| !s.is_empty())
                .map(|s| s.parse().unwrap_or_else(|e| panic!("{name}: {s}: {e}")))
                .collect()
        })
        .collect()
}

/// One benchmark case.
struct Case {
    label: &'static str,
    /// Benchmark file (tangent height km, I).
    file: &'static str,
    /// Row of `solar_zenith_azimuth.txt`.
    isol: usize,
    wavelength: f64,
    /// Ozone absorption on (Rayleigh + O3) or off (pure Rayleigh).
    ozone: bool,
}

impl Case {
    /// Samples per tangent height, for a per-point noise of ≲ 0.04 % (pure Rayleigh) and
    /// ≲ 0.3 % (Rayleigh + O3) with the default along-flight local estimate
    /// (`local_estimate = "expected"`). Measured per-sample relative standard deviations: pure
    /// Rayleigh 0.05 at 0.5 km, 0.015 at 15.5 km, < 0.004 from 20.5 km up (the single-scatter
    /// estimate then only varies with the solar transmittance at the sampled points);
    /// Rayleigh + O3 at 300 nm 0.6 up to 30 km, 0.15–0.25 above.
    fn spp(&self, h: f64) -> u64 {
        if !self.ozone {
            match h {
                h if h < 8.0 => 16_384,
                h if h < 13.0 => 8_192,
                h if h < 18.0 => 4_096,
                _ => 2_048,
            }
        } else if h < 35.0 {
            49_152
        } else {
            24_576
        }
    }
}

/// `[[atmosphere.layers]]` tables: each level interval of the profile split into `SUB` shells
/// with τ_sca = ∫ n_air σ_R dz and τ_abs = ∫ n_O3 σ_O3 dz of the linearly interpolated profile
/// (exact: the mean of the end values times the thickness). Also returns the vertical totals.
fn layers_toml(wavelength: f64, ozone: bool) -> (String, f64, f64) {
    let prof = table("air_ozone_numden_profiles.txt");
    let xs = table("xsection_rayleigh_ozone.txt");
    let x = xs
        .iter()
        .find(|r| r[0] == wavelength)
        .expect("wavelength in the cross-section table");
    let (sig_r, sig_o3) = (x[1], x[2]);
    let cm_per_km = 1e5;
    let mut out = String::new();
    let (mut tau_r, mut tau_o3) = (0.0, 0.0);
    for w in prof.windows(2) {
        let (h0, h1) = (w[0][0] / 1000.0, w[1][0] / 1000.0);
        let lin = |i: usize, t: f64| w[0][i] + (w[1][i] - w[0][i]) * t;
        let dz = (h1 - h0) / SUB as f64;
        for k in 0..SUB {
            let (a, b) = (k as f64 / SUB as f64, (k + 1) as f64 / SUB as f64);
            let ts = 0.5 * (lin(1, a) + lin(1, b)) * sig_r * cm_per_km * dz;
            let ta = if ozone {
                0.5 * (lin(2, a) + lin(2, b)) * sig_o3 * cm_per_km * dz
            } else {
                0.0
            };
            tau_r += ts;
            tau_o3 += ta;
            out += &format!(
                "[[atmosphere.layers]]\nbottom = {:?}\ntop = {:?}\ntau_sca = {ts:e}\ntau_abs = {ta:e}\n\
                 phase = {{ type = \"rayleigh\", depolarization = 0.0 }}\n",
                h0 + (h1 - h0) * a,
                if k + 1 == SUB { h1 } else { h0 + (h1 - h0) * b },
            );
        }
    }
    (out, tau_r, tau_o3)
}

fn measure_id(h: f64) -> String {
    format!("th{:04}", (h * 10.0).round() as i64)
}

fn run_case(c: &Case, seed: u64) -> Result<(), String> {
    let t0 = std::time::Instant::now();
    let bench: Vec<(f64, f64)> = table(c.file).iter().map(|r| (r[0], r[1])).collect();
    let geo = table("solar_zenith_azimuth.txt");
    let (sza, raa) = (geo[c.isol][0], geo[c.isol][1]);
    let (layers, tau_r, tau_o3) = layers_toml(c.wavelength, c.ozone);
    let mut measures = String::new();
    for h in HEIGHTS {
        measures += &format!(
            "[[measures]]\nid = \"{}\"\ntype = \"radiancemeter\"\norigin = [0.0, -3000.0, {h:?}]\n\
             direction = [0.0, 1.0, 0.0]\nspp = {}\n",
            measure_id(h),
            c.spp(h)
        );
    }
    let text = format!(
        "seed = {seed}\n[spectral]\nwavelengths = [{:?}]\n[geometry]\ntype = \"spherical_shell\"\n\
         planet_radius = 6371.0\ntoa_altitude = 100.0\n[atmosphere]\ntype = \"layered\"\n{layers}\
         [surface]\ntype = \"lambertian\"\nreflectance = 0.0\n[illumination]\ntype = \"directional\"\n\
         zenith = {sza:?}\nazimuth = {raa:?}\nirradiance = 1.0\n[integrator]\nmax_depth = 1\n{measures}",
        c.wavelength
    );
    let rows = run_rows(&experiment(&text));
    println!(
        "{}: SZA {sza}° RAA {raa}° at the tangent point, {} nm, vertical τ Rayleigh {tau_r:.4}, O3 {tau_o3:.4}",
        c.label, c.wavelength
    );
    let mut cmps = Vec::new();
    for (h, row) in HEIGHTS.iter().zip(&rows) {
        assert_eq!(row.measure, measure_id(*h));
        let (v, e) = row.radiance.expect("radiance");
        let reference = bench
            .iter()
            .find(|b| (b.0 - h).abs() < 1e-6)
            .expect("tangent height in the benchmark")
            .1;
        println!(
            "  h_t {h:4.1} km: simulate {v:.5e} ± {e:.1e}, Zawada {reference:.5e}, diff {:+.3} % (z = {:+.2})",
            100.0 * (v / reference - 1.0),
            (v - reference) / e
        );
        cmps.push(Cmp {
            label: format!("h_t {h} km"),
            reference,
            value: v,
            stderr: e,
        });
    }
    println!("  ({:.1} s)", t0.elapsed().as_secs_f64());
    check(
        &format!("Zawada 2021 limb single scattering, {}", c.label),
        &cmps,
    )
}

/// `common::check_all`'s test with the benchmark's accuracy as the floor:
/// pass when |value − reference| ≤ K·stderr + BENCH_REL·|reference|.
fn check(case: &str, cmps: &[Cmp]) -> Result<(), String> {
    let (mut worst_rel, mut worst_z) = (0.0_f64, 0.0_f64);
    let mut failures = Vec::new();
    for c in cmps {
        let diff = (c.value - c.reference).abs();
        let tol = K * c.stderr + BENCH_REL * c.reference.abs();
        worst_rel = worst_rel.max(diff / c.reference.abs());
        worst_z = worst_z.max(diff / c.stderr);
        #[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN must fail
        if !(diff <= tol) {
            failures.push(format!(
                "  {}: value {:.6e} ± {:.1e}, reference {:.6e}, |diff| {:.2e} > tol {:.2e} (z = {:.1})",
                c.label,
                c.value,
                c.stderr,
                c.reference,
                diff,
                tol,
                diff / c.stderr
            ));
        }
    }
    println!(
        "{case}: {} comparisons, max |rel diff| = {worst_rel:.3e}, max z = {worst_z:.2}",
        cmps.len()
    );
    if failures.is_empty() {
        Ok(())
    } else {
        Err(format!(
            "{case}: {} of {} comparisons failed:\n{}",
            failures.len(),
            cmps.len(),
            failures.join("\n")
        ))
    }
}

#[test]
fn zawada2021_single_scatter_limb() {
    let cases = [
        Case {
            label: "Rayleigh 351 nm, SZA 70 RAA 30",
            file: "zawada2021_ss_imod0_itst0_isol0_icom0_ialb0_iwav2_istk0.csv",
            isol: 0,
            wavelength: 351.0,
            ozone: false,
        },
        Case {
            label: "Rayleigh 351 nm, SZA 50 RAA 130",
            file: "zawada2021_ss_imod0_itst0_isol5_icom0_ialb0_iwav2_istk0.csv",
            isol: 5,
            wavelength: 351.0,
            ozone: false,
        },
        Case {
            label: "Rayleigh + O3 300 nm, SZA 80 RAA 60",
            file: "zawada2021_ss_imod0_itst0_isol1_icom1_ialb0_iwav0_istk0.csv",
            isol: 1,
            wavelength: 300.0,
            ozone: true,
        },
        Case {
            label: "Rayleigh + O3 300 nm, SZA 80 RAA 150",
            file: "zawada2021_ss_imod0_itst0_isol2_icom1_ialb0_iwav0_istk0.csv",
            isol: 2,
            wavelength: 300.0,
            ozone: true,
        },
    ];
    // One seed per case, so the four comparisons are statistically independent.
    let errs: Vec<String> = cases
        .iter()
        .zip(1u64..)
        .filter_map(|(c, i)| run_case(c, 2021 + i).err())
        .collect();
    assert!(errs.is_empty(), "{}", errs.join("\n"));
}
