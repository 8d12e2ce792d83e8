//! Spherical-shell single-scattering limb radiance against the benchmark of Zawada et al. (2021),
//! "Systematic comparison of vectorial spherical radiative transfer models in limb scattering
//! geometry", AMT 14:3953–3972 (doi:10.5194/amt-14-3953-2021): SASKTRAN-HR single-scatter
//! radiance I (their test case "polarized single scattering, no refraction", black surface),
//! as extracted from the paper's netCDF by S. Korkin in korkins/limbss_2026_01_27
//! @75f2204c4cb9 (files and provenance: `tests/data/zawada2021/`, `fixtures/PROVENANCE.md`).
//!
//! Benchmark set-up and how it is expressed here (sources in brackets; "limbss" is the
//! independent single-scattering code of that repository, which reproduces the benchmark to
//! ≤ 0.18 % over ~11 500 points with exactly these assumptions [limbss `doc/` slide 18]):
//! * Earth radius 6371 km [limbss `main_limbss.py`: `Re = 6371.0`]; the result changes by
//!   < 1e-4 relative between 6371 and 6372 km (checked by quadrature).
//! * Atmosphere 0–100 km (the profile's last level; TOA = 100 km); air and O3 number densities
//!   on 1 km levels, **linear in altitude** between levels [limbss `linear_coefficients.py`:
//!   extinction `a·r + b` per shell]. Scattering coefficient = n_air·σ_Rayleigh, absorption =
//!   n_O3·σ_O3 (cross-sections of `xsection_rayleigh_ozone.txt`). Our shells are homogeneous,
//!   so each 1 km level interval is split into `SUB` shells whose optical thicknesses are the
//!   exact integrals of the linear profile over them (the mean of its end values × thickness).
//!   The remaining discretisation error (piecewise-constant instead of linear inside a
//!   sub-shell) was measured by quadrature and is below the tolerance floor (see `SUB`).
//! * Rayleigh phase function **without depolarization**, P = 3/4 (1 + cos²Θ) [limbss
//!   `main_limbss.py`]; for unpolarized sunlight the single-scattered I does not depend on
//!   polarization. (With ρ = 0.0286 the radiance would change by −0.8 % … +0.3 % depending on
//!   Θ, which the benchmark excludes.)
//! * No refraction (test case itst0); black surface (`ialb0`, albedo 0); no twilight.
//! * Radiance per unit solar irradiance normal to the beam (F0 = 1, no factor π) [limbss
//!   `limbss.py`: `Iss = ∫J ds · F0/(4π)` with `F0 = 1`; data MANIFEST §5] = our `radiance` with
//!   `irradiance = 1`.
//! * Solar zenith angle and relative azimuth are given **at the tangent point** and the Sun is a
//!   fixed direction (parallel beam) along the whole line of sight [limbss `limbss.py`: one
//!   global solar direction for every point of the LOS; `solar_zenith_azimuth.txt`]. The
//!   relative azimuth RAA is the angle between the horizontal projection of the viewing
//!   direction (observer → tangent point) and that of the direction towards the Sun: RAA = 0
//!   looks towards the Sun (cos Θ = sin SZA·cos RAA) [limbss `limbss.py`, `xyz_sol_shell.py`:
//!   sensor at +s along (cos RAA, sin RAA, 0), direction to the Sun (−sin SZA, 0, cos SZA)].
//!   Verified independently: a quadrature with this convention agrees with the benchmark to
//!   ~0.1 % at tangent heights 0.5 and 10.5 km (SZA 70°, RAA 30°), the mirrored convention
//!   (RAA → 180° − RAA) is 6 % off at 0.5 km.
//! * The observer is outside the atmosphere; without refraction its position along the line of
//!   sight does not matter, only the full chord TOA → tangent point → TOA is integrated
//!   [limbss integrates the whole chord].
//!
//! Our frame: the tangent point is on the vertical of the frame origin, at `(0, 0, h_t)`; the
//! radiancemeter starts 3000 km before it at `[0, -3000, h_t]` (outside the atmosphere) and
//! looks horizontally North, `direction = [0, 1, 0]`. The experiment's solar zenith/azimuth are
//! defined at the frame origin, whose vertical is the tangent point's, so SZA is the
//! benchmark's and the solar azimuth (clockwise from North, towards the Sun) equals RAA (the
//! look direction is North; the sign of the azimuth is immaterial by mirror symmetry).
//! `max_depth = 1` keeps single scattering only.
//!
//! Comparison: `common::check_all` (|diff| ≤ 4.5σ + max(1e-5, 2e-4·ref)) is too strict a floor
//! for this reference: the benchmark models agree with each other only to ≈ 0.2 % in the
//! single-scatter cases (Zawada et al. 2021, abstract and Sect. 4), limbss reproduces SASKTRAN-HR
//! to ≤ 0.18 %, and our own quadrature of the stated set-up differs from the tabulated values by
//! a systematic +0.07 … +0.1 %. The floor is therefore the benchmark's quoted accuracy,
//! `BENCH_REL = 2e-3` relative (the absolute floor is dropped: radiances go down to 1e-4), with
//! the same 4.5σ Monte Carlo allowance.

mod common;
use common::*;

use std::path::PathBuf;

/// Relative accuracy of the benchmark itself (inter-model agreement of the single-scatter cases,
/// Zawada et al. 2021).
const BENCH_REL: f64 = 2e-3;

/// Homogeneous sub-shells per 1 km level interval.
const SUB: usize = 4;

fn dir() -> PathBuf {
    data_dir().join("zawada2021")
}

fn numbers(line: &str) -> Vec<f64> {
    line.split(|c: char| c == ',' || c.is_whitespace()).filter(|s| !s.is_empty()).map(|s| s.parse().unwrap()).collect()
}

fn data_lines(name: &str) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(dir().join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
    text.lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with('#') && !l.starts_with("tangent"))
        .map(numbers)
        .collect()
}

/// One benchmark case.
struct Case {
    label: &'static str,
    file: &'static str,
    isol: usize,
    wavelength: f64,
    ozone: bool,
}

/// `[[atmosphere.layers]]` tables: each level interval of the profile split into `SUB` shells,
/// τ = ∫ (n_air σ_R) dz and ∫ (n_O3 σ_O3) dz of the linearly interpolated profile, exact.
fn layers_toml(wavelength: f64, ozone: bool) -> (String, f64, f64) {
    let prof = data_lines("air_ozone_numden_profiles.txt");
    let xs = data_lines("xsection_rayleigh_ozone.txt");
    let x = xs.iter().find(|r| r[0] == wavelength).expect("wavelength in cross-section table");
    let (sig_r, sig_o3) = (x[1], x[2]);
    let cm_per_km = 1e5;
    let mut out = String::new();
    let (mut tau_r, mut tau_o3) = (0.0, 0.0);
    for w in prof.windows(2) {
        let (h0, h1) = (w[0][0] / 1000.0, w[1][0] / 1000.0);
        for k in 0..SUB {
            let (a, b) = (k as f64 / SUB as f64, (k + 1) as f64 / SUB as f64);
            let lin = |i: usize, t: f64| w[0][i] + (w[1][i] - w[0][i]) * t;
            let dz = (h1 - h0) / SUB as f64;
            let ts = 0.5 * (lin(1, a) + lin(1, b)) * sig_r * cm_per_km * dz;
            let ta = if ozone { 0.5 * (lin(2, a) + lin(2, b)) * sig_o3 * cm_per_km * dz } else { 0.0 };
            tau_r += ts;
            tau_o3 += ta;
            out += &format!(
                "[[atmosphere.layers]]\nbottom = {:?}\ntop = {:?}\ntau_sca = {ts:e}\ntau_abs = {ta:e}\nphase = {{ type = \"rayleigh\", depolarization = 0.0 }}\n",
                h0 + (h1 - h0) * a,
                h0 + (h1 - h0) * b
            );
        }
    }
    (out, tau_r, tau_o3)
}

/// Samples for a tangent height: most samples of a high, optically thin line of sight escape
/// without a collision (cheaply), so those get more.
fn spp_for(h: f64) -> u64 {
    if h < 35.0 {
        40_000
    } else if h < 55.0 {
        160_000
    } else {
        640_000
    }
}

const HEIGHTS: [f64; 10] = [0.5, 5.5, 10.5, 15.5, 20.5, 25.5, 30.5, 40.5, 50.5, 60.5];

fn run_case(c: &Case) -> Result<(), String> {
    let t0 = std::time::Instant::now();
    let bench: Vec<(f64, f64)> = data_lines(c.file).iter().map(|r| (r[0], r[1])).collect();
    let geo = data_lines("solar_zenith_azimuth.txt");
    let (sza, raa) = (geo[c.isol][0], geo[c.isol][1]);
    let (layers, tau_r, tau_o3) = layers_toml(c.wavelength, c.ozone);
    let mut measures = String::new();
    for h in HEIGHTS {
        measures += &format!(
            "[[measures]]\nid = \"th{:04}\"\ntype = \"radiancemeter\"\norigin = [0.0, -3000.0, {h:?}]\ndirection = [0.0, 1.0, 0.0]\nspp = {}\n",
            (h * 10.0).round() as i64,
            spp_for(h)
        );
    }
    let text = format!(
        "seed = 2021\n[spectral]\nwavelengths = [{:?}]\n[geometry]\ntype = \"spherical_shell\"\nplanet_radius = 6371.0\n\
         toa_altitude = 100.0\n[atmosphere]\ntype = \"layered\"\n{layers}[surface]\ntype = \"lambertian\"\nreflectance = 0.0\n\
         [illumination]\ntype = \"directional\"\nzenith = {sza:?}\nazimuth = {raa:?}\nirradiance = 1.0\n[integrator]\nmax_depth = 1\n{measures}",
        c.wavelength
    );
    let rows = run_rows(&experiment(&text));
    let mut cmps = Vec::new();
    println!(
        "{}: SZA {sza} RAA {raa}, {} nm, vertical τ Rayleigh {tau_r:.4} O3 {tau_o3:.4}",
        c.label, c.wavelength
    );
    for (h, row) in HEIGHTS.iter().zip(&rows) {
        assert_eq!(row.measure, format!("th{:04}", (h * 10.0).round() as i64));
        let (v, e) = row.radiance.expect("radiance");
        let reference = bench.iter().find(|b| (b.0 - h).abs() < 1e-6).expect("tangent height in benchmark").1;
        println!(
            "  h_t {h:5.1} km: simulate {v:.6e} ± {e:.1e}, Zawada {reference:.6e}, rel diff {:+.3}% (z = {:+.2})",
            100.0 * (v / reference - 1.0),
            (v - reference) / e
        );
        cmps.push(Cmp { label: format!("h_t {h} km"), reference, value: v, stderr: e });
    }
    println!("  ({:.1} s)", t0.elapsed().as_secs_f64());
    check(&format!("Zawada 2021 limb SS, {}", c.label), &cmps)
}

/// `check_all`'s statistical test with the benchmark's own accuracy as the floor:
/// pass when |value − reference| ≤ K·stderr + BENCH_REL·|reference|.
fn check(case: &str, cmps: &[Cmp]) -> Result<(), String> {
    // check_all adds max(ABS_FLOOR, REL_FLOOR·|ref|); fold the wider floor into the stderr slot
    // is not possible without changing its meaning, so apply the test here and report via
    // check_all's printout for the usual statistics.
    let _ = check_all(case, cmps);
    let failures: Vec<String> = cmps
        .iter()
        .filter(|c| {
            let tol = K * c.stderr + BENCH_REL * c.reference.abs();
            #[allow(clippy::neg_cmp_op_on_partial_ord)]
            let bad = !((c.value - c.reference).abs() <= tol);
            bad
        })
        .map(|c| {
            format!(
                "  {}: value {:.6e} ± {:.1e}, reference {:.6e}, rel diff {:+.3}%",
                c.label,
                c.value,
                c.stderr,
                c.reference,
                100.0 * (c.value / c.reference - 1.0)
            )
        })
        .collect();
    if failures.is_empty() {
        Ok(())
    } else {
        Err(format!("{case}: {} of {} beyond 4.5σ + {BENCH_REL}·ref:\n{}", failures.len(), cmps.len(), failures.join("\n")))
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
            label: "Rayleigh+O3 300 nm, SZA 80 RAA 60",
            file: "zawada2021_ss_imod0_itst0_isol1_icom1_ialb0_iwav0_istk0.csv",
            isol: 1,
            wavelength: 300.0,
            ozone: true,
        },
        Case {
            label: "Rayleigh+O3 300 nm, SZA 80 RAA 150",
            file: "zawada2021_ss_imod0_itst0_isol2_icom1_ialb0_iwav0_istk0.csv",
            isol: 2,
            wavelength: 300.0,
            ozone: true,
        },
    ];
    let errs: Vec<String> = cases.iter().filter_map(|c| run_case(c).err()).collect();
    assert!(errs.is_empty(), "{}", errs.join("\n"));
}

#[test]
#[ignore]
fn probe_cost() {
    for (wav, oz, isol) in [(351.0, false, 0usize), (300.0, true, 1)] {
        let geo = data_lines("solar_zenith_azimuth.txt");
        let (sza, raa) = (geo[isol][0], geo[isol][1]);
        let (layers, _, _) = layers_toml(wav, oz);
        let hs: Vec<f64> = std::env::var("PROBE_H").map(|v| v.split(',').map(|x| x.parse().unwrap()).collect()).unwrap_or(HEIGHTS.to_vec());
        let spp: u64 = std::env::var("PROBE_SPP").map(|v| v.parse().unwrap()).unwrap_or(20_000);
        for h in hs {
            let measures = format!("[[measures]]\nid = \"m\"\ntype = \"radiancemeter\"\norigin = [0.0, -3000.0, {h:?}]\ndirection = [0.0, 1.0, 0.0]\nspp = {spp}\n");
            let text = format!(
                "seed = 1\n[spectral]\nwavelengths = [{wav:?}]\n[geometry]\ntype = \"spherical_shell\"\nplanet_radius = 6371.0\n\
                 toa_altitude = 100.0\n[atmosphere]\ntype = \"layered\"\n{layers}[surface]\ntype = \"lambertian\"\nreflectance = 0.0\n\
                 [illumination]\ntype = \"directional\"\nzenith = {sza:?}\nazimuth = {raa:?}\n[integrator]\nmax_depth = 1\n{measures}");
            let exp = experiment(&text);
            let t0 = std::time::Instant::now();
            let rows = run_rows(&exp);
            let dt = t0.elapsed().as_secs_f64();
            let (v, e) = rows[0].radiance.unwrap();
            println!("{wav} h {h}: {v:.7e} ± {e:.2e} {:.2} us/sample, per-sample rel std {:.3}", dt / spp as f64 * 1e6, e / v * (spp as f64).sqrt());
        }
    }
}
