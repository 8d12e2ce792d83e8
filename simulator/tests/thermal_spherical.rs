//! Thermal emission in spherical shells (issue 16, item 1).
//!
//! * **Closed form along the chord** (`non_scattering_shell_equals_chord_integral`): one
//!   non-scattering, absorbing shell (τ 0.8 vertically, 0–100 km) whose source falls linearly
//!   in radius from B(285 K) at the ground to B(230 K) at the top, over a black 300 K ground, on
//!   an Earth-sized sphere; TOA radiance towards the target at 0°, 60°, 80° and 85°. The test
//!   integrates `ε B_s e^{−kL} + ∫₀^L k S(r(s)) e^{−k(L − s)} ds` along the slant chord itself
//!   (midpoint rule, 2·10⁵ steps, r(s) = |q₀ + s·v|). The walk's per-segment estimate
//!   (`SphericalShell::emission_along`) is random in its collision point: z-test.
//! * **Plane-parallel limit** (`large_planet_equals_plane_parallel`): the scattering
//!   `examples/thermal_1d.toml` case on a planet 1000× Earth's radius equals the plane-parallel
//!   run (z-test on both errors), where curvature is 1e-5 of the path.

mod common;
use common::*;

use engine::sources::planck;

const WL: f64 = 10_000.0;

fn layer(extra: &str) -> String {
    format!(
        "[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = 0.8\nsingle_scattering_albedo = 0.0\n\
         temperature_bottom = 285.0\ntemperature_top = 230.0\n{extra}"
    )
}

#[test]
fn non_scattering_shell_equals_chord_integral() {
    let zeniths = [0.0, 60.0, 80.0, 85.0];
    let text = format!(
        "emission = true\nseed = 5\n[geometry]\ntype = \"spherical_shell\"\n\
         [spectral]\nwavelengths = [{WL:?}]\n{}\n\
         [surface]\ntype = \"lambertian\"\nreflectance = 0.0\ntemperature = 300.0\n\
         [illumination]\ntype = \"none\"\n{}",
        layer(""),
        mdistant_toml("toa", &zeniths, &[0.0; 4], 20_000)
    );
    let rows = run_rows(&experiment(&text));
    let r0 = 6_378_100.0;
    let h = 100_000.0;
    let k = 0.8 / h;
    let (bb, bt) = (planck::radiance(WL, 285.0), planck::radiance(WL, 230.0));
    let src = |r: f64| bb + (bt - bb) * ((r - r0) / h).clamp(0.0, 1.0);
    let cmps: Vec<Cmp> = rows
        .iter()
        .zip(zeniths)
        .map(|(row, vza)| {
            let th = f64::to_radians(vza);
            let (q0, v) = ([0.0, r0], [th.sin(), th.cos()]);
            // Chord length from the ground point to the top sphere.
            let b = q0[1] * v[1];
            let rt = r0 + h;
            let l = -b + (b * b - (r0 * r0 - rt * rt)).sqrt();
            let n = 200_000;
            let ds = l / n as f64;
            let mut sum = 0.0;
            for i in 0..n {
                let s = (i as f64 + 0.5) * ds;
                let r = ((q0[0] + s * v[0]).powi(2) + (q0[1] + s * v[1]).powi(2)).sqrt();
                sum += k * src(r) * (-k * (l - s)).exp() * ds;
            }
            let reference = sum + planck::radiance(WL, 300.0) * (-k * l).exp();
            let (value, se) = row.radiance.unwrap();
            Cmp {
                label: format!("{vza}°"),
                reference,
                value,
                stderr: se,
            }
        })
        .collect();
    check_all("spherical shell, non-scattering", &cmps).unwrap();
    // The chord at 85° is 9.1× the vertical, against 11.5× in plane-parallel geometry: the
    // curvature matters and the test sees it (the plane-parallel value is 8 % away).
    let pp = {
        let mu = f64::cos(85f64.to_radians());
        let d = 0.8 / mu;
        let g = (1.0 - (1.0 + d) * (-d).exp()) / d;
        bt * (1.0 - (-d).exp()) + (bb - bt) * g + planck::radiance(WL, 300.0) * (-d).exp()
    };
    let v85 = rows[3].radiance.unwrap().0;
    assert!((v85 / pp - 1.0).abs() > 0.02, "{v85} {pp}");
}

#[test]
fn large_planet_equals_plane_parallel() {
    let body = |geometry: &str, seed: u64| {
        format!(
            "emission = true\nseed = {seed}\n{geometry}[spectral]\nwavelengths = [{WL:?}]\n\
             [atmosphere]\ntype = \"homogeneous\"\noptical_thickness = 0.8\nsingle_scattering_albedo = 0.3\n\
             phase = {{ type = \"hg\", g = 0.6 }}\ntemperature_bottom = 285.0\ntemperature_top = 230.0\n\
             [surface]\ntype = \"lambertian\"\nreflectance = 0.05\ntemperature = 300.0\n\
             [illumination]\ntype = \"none\"\n{}",
            mdistant_toml("toa", &[0.0, 45.0, 70.0], &[0.0; 3], 100_000)
        )
    };
    let pp = run_rows(&experiment(&body("", 1)));
    let sph = run_rows(&experiment(&body(
        "[geometry]\ntype = \"spherical_shell\"\nplanet_radius = 6378100.0\n",
        2,
    )));
    let cmps: Vec<Cmp> = pp
        .iter()
        .zip(&sph)
        .map(|(a, b)| {
            let (va, sa) = a.radiance.unwrap();
            let (vb, sb) = b.radiance.unwrap();
            Cmp {
                label: format!("{}°", a.vza.unwrap()),
                reference: va,
                value: vb,
                stderr: (sa * sa + sb * sb).sqrt(),
            }
        })
        .collect();
    check_all("planet 1000× Earth = plane-parallel", &cmps).unwrap();
}
