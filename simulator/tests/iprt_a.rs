//! Polarized transport against IPRT phase A (Emde et al. 2015), MYSTIC reference results with
//! their standard deviations (`tests/data/iprt/`, provenance in `fixtures/PROVENANCE.md`):
//! * A1: Rayleigh layer τ = 0.5 over a black surface; (sza, saa, depolarization) = (0, 65, 0),
//!   (30, 0, 0.03), (30, 65, 0.1);
//! * A2: Rayleigh τ = 0.1, depolarization 0.03, Lambertian 0.3, sza 50, saa 0;
//! * A3: spherical aerosol (`waso.mie.cdf`, 4 phase-matrix elements, ω 0.97568) τ = 0.2, black
//!   surface, sza 40, saa 0;
//! * A4: prolate spheroids (`sizedistr_spheroid.cdf`, 6 elements, ω 0.787581), otherwise as A3;
//! * A6: Rayleigh τ = 0.1, depolarization 0.03, over a rough ocean (Cox–Munk, n = 1.33, wind
//!   2 m/s, with shadowing: Mishchenko & Travis 1997), sza 45, saa 0 — forward and backward walks.
//!
//! Only the top-of-layer rows are compared (our `mdistant` is a TOA measure). IPRT conventions
//! (MANIFEST §2): radiance for F0 = 1 normal to the beam (so BRF-like = π·L/μ0); (vza, vaa) is the
//! line of sight, opposite to the photon travel: at the top, vza = 180 − our view zenith and our
//! view azimuth (target → sensor) is vaa + 180; azimuths clockwise (as ours). Stokes Q, U in the
//! meridian frame with the same Q as ours but **U of opposite sign**: IPRT ties the frame to the
//! line of sight, the reverse of the propagation direction our frame uses, which flips the
//! handedness (the MANIFEST warns of U/V sign differences between codes; this test pins it).
//! Statistical test: `common::check_all` with σ² = σ_ours² + σ_MYSTIC².

mod common;
use common::*;

struct Row {
    zout: f64,
    depol: f64,
    sza: f64,
    saa: f64,
    va: f64,
    phi: f64,
    iquv: [f64; 3],
    std: [f64; 3],
}

fn load(name: &str) -> Vec<Row> {
    let text = std::fs::read_to_string(data_dir().join("iprt").join(name)).unwrap();
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let f: Vec<f64> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            Row {
                zout: f[1],
                depol: f[0],
                sza: f[2],
                saa: f[3],
                va: f[4],
                phi: f[5],
                iquv: [f[6], f[7], f[8]],
                std: [f[10], f[11], f[12]],
            }
        })
        .collect()
}

fn run_case(case: &str, rows: &[&Row], tau: f64, albedo: f64, spp: u64) -> Result<(), String> {
    let phase = format!(
        "{{ type = \"rayleigh\", depolarization = {:?} }}",
        rows[0].depol
    );
    run_case_with(
        case,
        rows,
        &format!("optical_thickness = {tau:?}\nphase = {phase}"),
        albedo,
        spp,
    )
}

fn run_case_with(
    case: &str,
    rows: &[&Row],
    atmosphere: &str,
    albedo: f64,
    spp: u64,
) -> Result<(), String> {
    run_case_full(
        case,
        rows,
        atmosphere,
        &format!("type = \"lambertian\"\nreflectance = {albedo:?}"),
        "forward",
        spp,
    )
}

fn run_case_full(
    case: &str,
    rows: &[&Row],
    atmosphere: &str,
    surface: &str,
    integrator: &str,
    spp: u64,
) -> Result<(), String> {
    let r0 = rows[0];
    let vza: Vec<f64> = rows.iter().map(|r| 180.0 - r.va).collect();
    let vaa: Vec<f64> = rows
        .iter()
        .map(|r| (r.phi + 180.0).rem_euclid(360.0))
        .collect();
    let text = format!(
        "seed = 5\npolarized = true\n[spectral]\nwavelengths = [550.0]\n[atmosphere]\ntype = \"homogeneous\"\n{atmosphere}\n\
         [surface]\n{surface}\n\
         [illumination]\ntype = \"directional\"\nzenith = {:?}\nazimuth = {:?}\n[integrator]\ntype = \"{integrator}\"\n{}",
        r0.sza,
        r0.saa,
        mdistant_toml("toa", &vza, &vaa, spp)
    );
    let out = run_rows(&experiment(&text));
    let k = std::f64::consts::PI / r0.sza.to_radians().cos();
    let mut cmps = Vec::new();
    for (r, o) in rows.iter().zip(&out) {
        let (u, eu) = o.brf_u.unwrap();
        let ours = [o.brf.unwrap(), o.brf_q.unwrap(), (-u, eu)];
        for (c, name) in ["I", "Q", "U"].iter().enumerate() {
            let (v, e) = ours[c];
            let se = (e * e + (k * r.std[c]).powi(2)).sqrt();
            cmps.push(Cmp {
                label: format!("{name} va {} phi {}", r.va, r.phi),
                reference: k * r.iquv[c],
                value: v,
                stderr: se,
            });
        }
    }
    check_all(case, &cmps)
}

#[test]
fn iprt_a1_rayleigh_black_surface() {
    let rows = load("a1_toa.dat");
    let mut errs = Vec::new();
    for (sza, saa, depol) in [(0.0, 65.0, 0.0), (30.0, 0.0, 0.03), (30.0, 65.0, 0.1)] {
        let sub: Vec<&Row> = rows
            .iter()
            .filter(|r| r.sza == sza && r.saa == saa && r.depol == depol && (r.va as i64) % 10 == 0)
            .collect();
        assert!(!sub.is_empty());
        if let Err(e) = run_case(
            &format!("IPRT A1 sza {sza} saa {saa} depol {depol}"),
            &sub,
            0.5,
            0.0,
            200_000,
        ) {
            errs.push(e);
        }
    }
    assert!(errs.is_empty(), "{}", errs.join("\n"));
}

#[test]
fn iprt_a2_rayleigh_lambertian() {
    let rows = load("a2_toa.dat");
    let sub: Vec<&Row> = rows.iter().collect();
    run_case("IPRT A2", &sub, 0.1, 0.3, 300_000).unwrap();
}

#[test]
fn iprt_a3_a4_aerosol_phase_matrices() {
    let mut errs = Vec::new();
    for (file, table, ssa) in [
        ("a3_toa.dat", "waso.mie.cdf", 0.97568),
        ("a4_toa.dat", "sizedistr_spheroid.cdf", 0.787581),
    ] {
        let rows = load(file);
        let sub: Vec<&Row> = rows.iter().collect();
        let atm = format!(
            "optical_thickness = 0.2\nsingle_scattering_albedo = {ssa:?}\nphase = {{ type = \"tabulated\", file = \"fixtures/{table}\", wavelength = 350.0 }}"
        );
        if let Err(e) = run_case_with(&format!("IPRT {file}"), &sub, &atm, 0.0, 300_000) {
            errs.push(e);
        }
    }
    assert!(errs.is_empty(), "{}", errs.join("\n"));
}

#[test]
fn iprt_a6_ocean() {
    let rows = load("a6_toa.dat");
    // Exact nadir views (va = 180) are left out: there the Stokes vectors of all `phi` are the
    // same light in rotated frames, so √(Q²+U²) must not depend on `phi`; in the MYSTIC file it
    // varies by 3 % (0.01376 at phi 0, 0.01337 at phi 60, in BRF units), far beyond its stated
    // standard deviations (~0.3 %), so the reference is not usable there. Ours is invariant.
    let sub: Vec<&Row> = rows.iter().filter(|r| r.va < 179.5).collect();
    let atm = "optical_thickness = 0.1\nphase = { type = \"rayleigh\", depolarization = 0.03 }";
    let surf = "type = \"ocean\"\nwind_speed = 2.0\nrefractive_index = 1.33";
    let mut errs = Vec::new();
    for (integrator, spp) in [("forward", 400_000), ("backward", 30_000)] {
        let pick: Vec<&Row> = if integrator == "backward" {
            sub.iter().copied().step_by(9).collect()
        } else {
            sub.clone()
        };
        if let Err(e) = run_case_full(
            &format!("IPRT A6 ocean [{integrator}]"),
            &pick,
            atm,
            surf,
            integrator,
            spp,
        ) {
            errs.push(e);
        }
    }
    assert!(errs.is_empty(), "{}", errs.join("\n"));
}

/// Bottom-of-layer rows (zout = 0): the radiance arriving at the ground, seen by radiancemeters on
/// the ground looking up along IPRT's line of sight (vza 0–80, clockwise vaa). Tests downward
/// transport and the polarized backward walk; the same frame mapping as at the top (Q equal, U of
/// opposite sign: the meridian axis of the line of sight equals that of the propagation direction).
#[test]
fn iprt_a1_a2_bottom_of_layer() {
    let mut errs = Vec::new();
    for (file, tau, albedo, spp) in [
        ("a1_boa.dat", 0.5, 0.0, 80_000u64),
        ("a2_boa.dat", 0.1, 0.3, 80_000),
    ] {
        let rows = load(file);
        let mut groups: Vec<(f64, f64, f64)> = Vec::new();
        for r in &rows {
            assert_eq!(r.zout, 0.0);
            if !groups.contains(&(r.sza, r.saa, r.depol)) {
                groups.push((r.sza, r.saa, r.depol));
            }
        }
        for (sza, saa, depol) in groups {
            let sub: Vec<&Row> = rows
                .iter()
                .filter(|r| (r.sza, r.saa, r.depol) == (sza, saa, depol))
                .collect();
            let mut measures = String::new();
            for (k, r) in sub.iter().enumerate() {
                let look =
                    engine::frame::direction_from_angles(r.va.to_radians(), r.phi.to_radians());
                measures += &format!(
                    "[[measures]]\nid = \"m{k}\"\ntype = \"radiancemeter\"\norigin = [0.0, 0.0, 0.0]\ndirection = [{:?}, {:?}, {:?}]\nframe_azimuth = {:?}\nspp = {spp}\n",
                    look.x,
                    look.y,
                    look.z,
                    // A zenith-looking view: its meridian plane is that of IPRT's `phi`, as for the
                    // nadir views at the top (towards-the-sensor azimuth = phi + 180).
                    (r.phi + 180.0).rem_euclid(360.0)
                );
            }
            let text = format!(
                "seed = 6\npolarized = true\n[spectral]\nwavelengths = [550.0]\n[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = {tau:?}\n\
                 phase = {{ type = \"rayleigh\", depolarization = {depol:?} }}\n[surface]\ntype = \"lambertian\"\nreflectance = {albedo:?}\n\
                 [illumination]\ntype = \"directional\"\nzenith = {sza:?}\nazimuth = {saa:?}\n{measures}"
            );
            let out = run_rows(&experiment(&text));
            let k = std::f64::consts::PI / sza.to_radians().cos();
            let mut cmps = Vec::new();
            for (r, o) in sub.iter().zip(&out) {
                let (u, eu) = o.brf_u.unwrap();
                let ours = [o.brf.unwrap(), o.brf_q.unwrap(), (-u, eu)];
                for (c, name) in ["I", "Q", "U"].iter().enumerate() {
                    let (v, e) = ours[c];
                    let se = (e * e + (k * r.std[c]).powi(2)).sqrt();
                    cmps.push(Cmp {
                        label: format!("{name} va {} phi {}", r.va, r.phi),
                        reference: k * r.iquv[c],
                        value: v,
                        stderr: se,
                    });
                }
            }
            if let Err(e) = check_all(
                &format!("IPRT {file} sza {sza} saa {saa} depol {depol} (bottom)"),
                &cmps,
            ) {
                errs.push(e);
            }
        }
    }
    assert!(errs.is_empty(), "{}", errs.join("\n"));
}

/// IPRT A5: a water cloud (τ 5, r_eff 10 µm at 800 nm, `watercloud.mie.cdf` with its strong
/// diffraction peak), black surface, SZA 50°, principal plane at the top. The local estimates of
/// such a forward-peaked phase function are heavy-tailed; detector-directional importance
/// sampling with splitting (`integrator/peak_sampling.rs`, on by default) tames them. This test
/// runs 600 000 photons (about 1–2 % per direction); the full-precision comparison (3·10⁶ photons,
/// 0.63 % relative RMS against MYSTIC in 2 minutes) is in BENCHMARKS.md. I, Q, U are compared
/// with the z-test on both uncertainties.
#[test]
fn iprt_a5_water_cloud() {
    let text = std::fs::read_to_string(data_dir().join("iprt/a5_pp_toa.dat")).unwrap();
    let rows: Vec<Row> = text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let f: Vec<f64> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            Row {
                zout: f[0],
                depol: 0.0,
                sza: f[1],
                saa: f[2],
                va: f[3],
                phi: f[4],
                iquv: [f[5], f[6], f[7]],
                std: [f[9], f[10], f[11]],
            }
        })
        .collect();
    let sub: Vec<&Row> = rows
        .iter()
        .filter(|r| r.va < 179.5 || r.phi == 0.0)
        .collect();
    let atm = "optical_thickness = 5.0\nsingle_scattering_albedo = 0.999978830724981\n\
               phase = { type = \"tabulated\", file = \"fixtures/watercloud.mie.cdf\", wavelength = 800.0 }";
    run_case_full(
        "IPRT A5 water cloud",
        &sub,
        atm,
        "type = \"lambertian\"\nreflectance = 0.0",
        "forward",
        600_000,
    )
    .unwrap();
}
