//! The Moon as a source (issue 17 item 4), end to end through the experiment file.
//!
//! * The run's source direction is the ephemeris' (`moon::moon_position`, itself checked in
//!   `moon.rs` against Meeus' examples 47.a and 48.a and, through the same position chain,
//!   against NREL's SPA for the Sun).
//! * A Moon-lit scene equals the Sun-lit one under the same geometry scaled by the irradiance
//!   ratio: the same random numbers give the same BRF to the last bit, and radiances in the
//!   ratio E_moon/E_sun of the magnitude law.
//! * A Moon below the horizon of a plane-parallel run, a misspelt key and a thin crescent are
//!   errors naming the key.

mod common;
use common::*;

use engine::sources::moon::{irradiance_ratio, moon_position};

const PLACE: (f64, f64) = (28.55, 23.39); // Libya-4

/// A time on 2026-03-02/03 (near full Moon) with the Moon at a zenith below 60° at PLACE, and
/// one with the Moon well below the horizon.
fn times() -> (String, String) {
    let mut up = None;
    let mut down = None;
    for h in 0..48 {
        let t = format!("2026-03-{:02}T{:02}:00:00Z", 2 + h / 24, h % 24);
        let p = moon_position(&t, PLACE.0, PLACE.1, 0.0).unwrap();
        if p.zenith < 60.0 && up.is_none() {
            up = Some(t.clone());
        }
        if p.zenith > 120.0 && down.is_none() {
            down = Some(t);
        }
    }
    (up.unwrap(), down.unwrap())
}

fn text(illumination: &str) -> String {
    format!(
        r#"
seed = 5
[spectral]
wavelengths = [440.0, 865.0]
[atmosphere]
type = "homogeneous"
optical_thickness = 0.3
phase = {{ type = "rayleigh" }}
[surface]
type = "lambertian"
reflectance = 0.35
[illumination]
{illumination}
{}"#,
        mdistant_toml("toa", &[0.0, 30.0, 55.0], &[0.0, 90.0, 200.0], 20_000)
    )
}

#[test]
fn moonlit_scene_is_the_sunlit_one_scaled_by_the_irradiance_ratio() {
    let (time, _) = times();
    let moon = experiment(&text(&format!(
        "type = \"moon\"\ntime = \"{time}\"\nlatitude = {:?}\nlongitude = {:?}",
        PLACE.0, PLACE.1
    )));
    let p = moon_position(&time, PLACE.0, PLACE.1, 0.0).unwrap();
    assert_eq!(moon.sun_zenith_deg, p.zenith);
    assert_eq!(moon.sun_azimuth_deg, p.azimuth);
    let sun = experiment(&text(&format!(
        "type = \"directional\"\nzenith = {:?}\nazimuth = {:?}\nirradiance = \"thuillier_2003\"",
        p.zenith, p.azimuth
    )));
    let ratio = irradiance_ratio(&p).unwrap();
    println!(
        "Moon at {time}: zenith {:.3}°, azimuth {:.3}°, phase angle {:.2}°, E_moon/E_sun = {ratio:.4e}",
        p.zenith, p.azimuth, p.phase_angle
    );
    assert!(ratio > 1e-6 && ratio < 3e-6, "{ratio}");
    for (m, s) in moon.optics.iter().zip(&sun.optics) {
        assert!((m.irradiance / s.irradiance - ratio).abs() < 1e-12 * ratio);
    }
    let (rm, rs) = (run_rows(&moon), run_rows(&sun));
    assert_eq!(rm.len(), rs.len());
    for (a, b) in rm.iter().zip(&rs) {
        assert_eq!(a.brf, b.brf, "the same walks: identical BRF");
        let (la, ea) = a.radiance.unwrap();
        let (lb, eb) = b.radiance.unwrap();
        assert!((la / lb - ratio).abs() < 1e-9 * ratio, "{la} / {lb}");
        assert!((ea / eb - ratio).abs() < 1e-9 * ratio);
    }
}

#[test]
fn moon_errors_name_their_key() {
    let (_, down) = times();
    let dir = std::env::temp_dir().join(format!("moon-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let load = |illumination: &str| {
        let path = dir.join("exp.toml");
        std::fs::write(&path, text(illumination)).unwrap();
        engine::config::resolve::Experiment::load(&path)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default()
    };
    let place = format!("latitude = {:?}\nlongitude = {:?}", PLACE.0, PLACE.1);
    let e = load(&format!("type = \"moon\"\ntime = \"{down}\"\n{place}"));
    assert!(
        e.contains("illumination.time") && e.contains("below the horizon"),
        "{e}"
    );
    let e = load(&format!("type = \"moon\"\ntim = \"{down}\"\n{place}"));
    println!("{e}");
    assert!(e.contains("tim =") && e.contains("unknown"), "{e}");
    let e = load(&format!(
        "type = \"moon\"\ntime = \"{down}\"\n{place}\nirradiance = 1e-6\nsolar_spectrum = \"tsis_1\""
    ));
    assert!(e.contains("illumination.solar_spectrum"), "{e}");
    // Two days before new Moon (2026-03-19 01:23 UT) the crescent is beyond the magnitude law.
    let mut thin = None;
    for h in 0..48 {
        let t = format!("2026-03-{:02}T{:02}:00:00Z", 17 + h / 24, h % 24);
        let p = moon_position(&t, PLACE.0, PLACE.1, 0.0).unwrap();
        if p.zenith < 80.0 && p.phase_angle > 150.0 {
            thin = Some(t);
            break;
        }
    }
    let t = thin.expect("a thin crescent above the horizon");
    let e = load(&format!("type = \"moon\"\ntime = \"{t}\"\n{place}"));
    assert!(
        e.contains("illumination.time") && e.contains("phase angle"),
        "{e}"
    );
    // With a given lunar spectrum the crescent runs.
    let e = load(&format!(
        "type = \"moon\"\ntime = \"{t}\"\n{place}\nirradiance = 1e-7"
    ));
    assert!(e.is_empty(), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A time at PLACE (late February 2026, the Moon waxing past first quarter) with the Sun and the
/// Moon both higher than 30° above the horizon.
fn daytime_moon() -> String {
    for h in 0..(9 * 24) {
        let t = format!("2026-02-{:02}T{:02}:00:00Z", 20 + h / 24, h % 24);
        let m = moon_position(&t, PLACE.0, PLACE.1, 0.0).unwrap();
        let s =
            engine::sources::sun_position::sun_position(&t, PLACE.0, PLACE.1, 0.0, None).unwrap();
        if m.zenith < 60.0 && s.zenith < 60.0 && m.phase_angle < 120.0 {
            return t;
        }
    }
    panic!("no time with the Sun and the Moon up");
}

/// The Moon beside the Sun (`moon = true`) over a Lambertian ground without atmosphere, in
/// closed form: every sample scores exactly ρ/π·(E_s·μ_s + E_m·μ_m) (each source's next-event
/// estimate at the ground; nothing else scatters), so the radiance equals it to rounding with a
/// zero standard error, the BRF is that radiance in the Sun's units, and the downwelling flux
/// is E_s·μ_s + E_m·μ_m (both direct beams). The same in a polarized run (Stokes tallies),
/// through a 3D canopy whose leaves are `null` (the scene walks), and through spectral walks
/// (`spectral_walk = "alis"`, a Moon spectrum that differs from the Sun's at each wavelength:
/// the Moon's factor per channel). Then under a purely absorbing layer (τ 0.2): each source's
/// term is attenuated along its own beam, e^{−τ/μ}, and the view by e^{−τ/μv}: 1D and scene,
/// scalar and spectral walks (whose weights carry each source's transmittances: a Moon walk
/// built with the Sun's weight once gave the Moon the Sun's transmittance, found in review).
/// 1D spectral walks sample there, so they get a z-test (4σ) instead.
#[test]
fn moon_beside_the_sun_adds_its_light_in_closed_form() {
    let time = daytime_moon();
    let m = moon_position(&time, PLACE.0, PLACE.1, 0.0).unwrap();
    let s =
        engine::sources::sun_position::sun_position(&time, PLACE.0, PLACE.1, 0.0, None).unwrap();
    println!(
        "{time}: Sun zenith {:.2}°, Moon zenith {:.2}° (phase angle {:.1}°)",
        s.zenith, m.zenith, m.phase_angle
    );
    let rho = 0.35;
    let illumination = format!(
        "[illumination]\ntype = \"directional\"\ntime = \"{time}\"\nlatitude = {:?}\nlongitude = {:?}\n\
         irradiance = [1.0, 2.0]\nmoon = true\nmoon_irradiance = [0.4, 0.1]\n",
        PLACE.0, PLACE.1
    );
    let flat = format!(
        "seed = 2\n[spectral]\nwavelengths = [440.0, 865.0]\n\
         [surface]\ntype = \"lambertian\"\nreflectance = {rho}\n{illumination}{}\
         [[measures]]\nid = \"down\"\ntype = \"distant_flux\"\naltitude = 0.0\ndirection = \"down\"\nspp = 500\n",
        mdistant_toml("toa", &[0.0, 40.0], &[0.0, 120.0], 500)
    );
    let dir = std::env::temp_dir().join(format!("moon-sun-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    common::bundles::write_random_leaves(&dir.join("leaves.txt"), 4, 200, 10.0, [0.5, 6.0], 0.25);
    let canopy = |walk: &str| {
        format!(
            "seed = 2\n[spectral]\nwavelengths = [440.0, 865.0]\n{walk}{illumination}\
             [scene]\ntype = \"canopy\"\n[[scene.objects]]\nname = \"leaves\"\nleaves = \"{}\"\n\
             reflectance = 0.08\ntransmittance = 0.04\n\
             [scene.ground]\nbrdf = {{ type = \"lambertian\", reflectance = {rho} }}\n\
             [scene.solvers.leaves]\ntype = \"null\"\n{}",
            dir.join("leaves.txt").display(),
            mdistant_toml("area", &[0.0, 40.0], &[0.0, 120.0], 500)
                + "target_m = [-8.0, -8.0, 8.0, 8.0]\ntarget_height_m = 6.5\n"
        )
    };
    // Spectral walks through a scene follow the default solver only: one small leaf far out of
    // every path's way instead of null leaves.
    let spectral_canopy = canopy("[integrator]\nspectral_walk = \"alis\"\n")
        .replace("[scene.solvers.leaves]\ntype = \"null\"\n", "")
        .replace("leaves.txt", "far.txt");
    let spectral_flat = flat.replacen(
        "[surface]",
        "[integrator]\nspectral_walk = \"alis\"\n[surface]",
        1,
    );
    // A purely absorbing layer (τ 0.2, ω 0): each source's beam and the view are attenuated.
    let tau = 0.2;
    let absorbing = |text: &str| {
        text.replacen(
            "wavelengths = [440.0, 865.0]\n",
            &format!("wavelengths = [440.0, 865.0]\n[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = {tau}\nsingle_scattering_albedo = 0.0\n"),
            1,
        )
    };
    let mut checked = 0;
    for text in [
        format!("polarized = true\n{flat}"),
        absorbing(&flat),
        absorbing(&spectral_flat),
        absorbing(&canopy("")),
        absorbing(&spectral_canopy),
        flat,
        canopy(""),
        spectral_canopy,
    ] {
        if text.contains("far.txt") {
            std::fs::write(dir.join("far.txt"), "9000 9000 0.5 0 0 1 0.01\n").unwrap();
        }
        let exp = experiment(&text);
        let moon = exp.moon.clone().expect("the Moon beside the Sun");
        assert!((moon.zenith_deg - m.zenith).abs() < 1e-12);
        assert!((exp.sun_zenith_deg - s.zenith).abs() < 1e-12);
        let (mu_s, mu_m) = (exp.sun_dir.z, moon.dir.z);
        let tau = if text.contains("optical_thickness") {
            tau
        } else {
            0.0
        };
        let t = |mu: f64| (-tau / mu).exp();
        // 1D spectral walks under the absorbing layer draw their path lengths from a reference
        // atmosphere: their samples vary, so they get a z-test; every other case is exact.
        let sampled = tau > 0.0 && text.contains("spectral_walk") && !text.contains("[scene]");
        // Paths through `null` leaves under an absorbing layer come out 4e-7 high (relative),
        // the Sun alone as well: after a leaf the flight is not split, so the absorption below
        // it is sampled as a rare kill (probability ~1e-5) that 500 samples do not meet; the
        // estimate is unbiased (the shift grows as τ: 3.9e-6 at τ 2).
        let exact = if tau > 0.0 && text.contains("\"null\"") {
            1e-6
        } else {
            1e-12
        };
        for r in run_rows(&exp) {
            let iw = exp
                .wavelengths
                .iter()
                .position(|w| *w == r.wavelength_nm)
                .unwrap();
            let (es, em) = (exp.optics[iw].irradiance, moon.irradiance[iw]);
            assert!((es - [1.0, 2.0][iw] / (s.distance_au * s.distance_au)).abs() < 1e-12);
            assert_eq!(em, [0.4, 0.1][iw]);
            let e_down = es * mu_s * t(mu_s) + em * mu_m * t(mu_m);
            if let Some((f, fe)) = r.flux {
                assert!(
                    (f - e_down).abs() < 1e-12 * e_down && fe == 0.0,
                    "{f} ± {fe} vs {e_down}"
                );
                continue;
            }
            let (l, le) = r.radiance.unwrap();
            let t_view = t(r.vza.unwrap().to_radians().cos());
            let want = rho / std::f64::consts::PI * e_down * t_view;
            let (b, be) = r.brf.unwrap();
            let b_want = rho * e_down * t_view / (es * mu_s);
            if sampled {
                // z-test: |x − closed form| ≤ 4σ.
                assert!((l - want).abs() <= 4.0 * le, "{l} ± {le} vs {want}");
                assert!((b - b_want).abs() <= 4.0 * be, "{b} ± {be} vs {b_want}");
            } else {
                // (The standard error of constant samples is rounding.)
                assert!(
                    (l - want).abs() < exact * want && le < 1e-7 * want,
                    "{l} ± {le} vs {want}"
                );
                assert!((b - b_want).abs() < exact * b_want, "{b} vs {b_want}");
            }
            checked += 1;
        }
    }
    assert_eq!(checked, 8 * 2 * 2);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Twilight: the Sun 8° below the horizon lights the upper layers of a spherical-shell
/// molecular atmosphere while the nearly full Moon is 17° above it. The Sun-and-Moon run's
/// samples are the Sun-only run's (the same random streams) plus independent Moon-lit walks,
/// so its radiance minus the Sun-only run's is an estimate of the Moon-only run's: they agree
/// within 4 standard errors of the difference (√2 × the Moon-only run's). The Moon's part is 5 %
/// of the total here.
#[test]
fn twilight_with_the_moon_is_the_sum_of_both_sources() {
    let text = |illumination: &str| {
        format!(
            "seed = 11\n[spectral]\nwavelengths = [550.0]\n[geometry]\ntype = \"spherical_shell\"\n\
             [atmosphere]\ntype = \"molecular\"\nprofile = \"afgl_1986-us_standard\"\n\
             [surface]\ntype = \"lambertian\"\nreflectance = 0.35\n\
             [illumination]\ntime = \"2026-03-02T17:00:00Z\"\nlatitude = {:?}\nlongitude = {:?}\n{illumination}\n\
             [[measures]]\nid = \"nadir\"\ntype = \"radiancemeter\"\norigin = [0.0, 0.0, 700.0]\n\
             direction = [0.0, 0.0, -1.0]\nspp = 20000\n",
            PLACE.0, PLACE.1
        )
    };
    let both = experiment(&text(
        "type = \"directional\"\nirradiance = \"thuillier_2003\"\nmoon = true",
    ));
    assert!(both.sun_zenith_deg > 95.0 && both.moon.as_ref().unwrap().zenith_deg < 80.0);
    let sun = experiment(&text(
        "type = \"directional\"\nirradiance = \"thuillier_2003\"",
    ));
    let moon = experiment(&text(
        "type = \"moon\"\nsolar_spectrum = \"thuillier_2003\"",
    ));
    // The Moon beside the Sun has the Moon-only run's irradiance (the lunar model on the Sun's
    // spectrum at 1 AU).
    let e_moon = both.moon.as_ref().unwrap().irradiance[0];
    assert!((e_moon / moon.optics[0].irradiance - 1.0).abs() < 1e-12);
    let (b, s, m) = (&run_rows(&both)[0], &run_rows(&sun)[0], &run_rows(&moon)[0]);
    let (lb, eb) = b.radiance.unwrap();
    let (ls, es) = s.radiance.unwrap();
    let (lm, em) = m.radiance.unwrap();
    assert!(b.brf.is_none(), "no BRF with the Sun below the horizon");
    let z = (lb - ls - lm) / (2.0f64.sqrt() * em);
    println!(
        "Sun and Moon {lb:.5e} ± {eb:.2e}; Sun {ls:.5e} ± {es:.2e}; Moon {lm:.5e} ± {em:.2e}; z = {z:.2}"
    );
    assert!(z.abs() < 4.0, "z = {z}");
    assert!(lm > 0.02 * lb, "the Moon should matter here: {lm} of {lb}");
}

/// Keys of the Moon beside the Sun: errors name them.
#[test]
fn moon_beside_the_sun_errors_name_their_key() {
    let place = format!("latitude = {:?}\nlongitude = {:?}", PLACE.0, PLACE.1);
    let (_, down) = times();
    let time = daytime_moon();
    let load = |illumination: &str, extra: &str| {
        engine::config::resolve::Experiment::from_str(
            &(text(illumination) + extra),
            std::path::Path::new("twilight.toml"),
        )
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default()
    };
    for (illumination, extra, key, words) in [
        ("type = \"directional\"\nzenith = 30.0\nmoon = true".to_string(), "", "illumination.moon", "time"),
        (format!("type = \"directional\"\ntime = \"{time}\"\n{place}\nmoon_irradiance = 1e-6"), "", "illumination.moon_irradiance", "moon = true"),
        (format!("type = \"directional\"\ntime = \"{down}\"\n{place}\nmoon = true"), "", "illumination", "horizon"),
        (format!("type = \"directional\"\ntime = \"{time}\"\n{place}\nmoon = true"), "[integrator]\ntype = \"forward\"\n", "illumination.moon", "backward"),
        (format!("type = \"directional\"\ntime = \"{time}\"\n{place}\nmoon = true\nirradiance = [1.0, 0.0]"), "", "illumination.irradiance", "positive"),
    ] {
        let e = load(&illumination, extra);
        println!("{e}");
        assert!(e.contains("twilight.toml") && e.contains(key) && e.contains(words), "{e}");
    }
    let ok = load(
        &format!("type = \"directional\"\ntime = \"{time}\"\n{place}\nmoon = true"),
        "",
    );
    assert!(ok.is_empty(), "{ok}");
}
