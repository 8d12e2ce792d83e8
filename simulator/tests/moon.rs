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

use simulator::moon::{irradiance_ratio, moon_position};

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
        simulator::config::resolve::Experiment::load(&path)
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
