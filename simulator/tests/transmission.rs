//! General transmission in 3D scenes (issue 39 item 2): a glass pane (`thin_dielectric`) and a
//! rough dielectric interface (`rough_dielectric`) over a Lambertian floor, against closed
//! forms that share no code with the walk.
//!
//! Scene: a flat Lambertian terrain (1 km, with the flat background around it) under a
//! horizontal square sheet 4 km wide, 5 m above it (one instanced template whose front faces
//! up), no atmosphere, SZA 30°. Measured: the BRF of the central 200 m at three view
//! directions. Both configurations are horizontally uniform over the light's lateral reach,
//! so the plane-parallel closed forms hold:
//!
//! * **pane** (index n, no absorption): each face reflects `r` per polarization; the pane
//!   transmits `T(μ) = ½Σ_{s,p}(1 − r)/(1 + r)` and reflects `R = 1 − T`. The floor's radiosity
//!   `B = ρ(E0 μs T(μs) + B·R̄)`, `R̄ = 2∫R(μ)μ dμ` (light between floor and pane), and the
//!   sensor sees `T(μv)·B/π` (the Sun's glint in the pane is a delta the sensor's directions
//!   avoid): `BRF = T(μs)T(μv)ρ/(1 − ρR̄)`, with Fresnel written out here.
//! * **rough interface** (index n below, GGX α): light crosses it refracted, so a shadow ray
//!   from the floor is blocked and the Sun reaches the floor only through next-event
//!   estimates at the interface. With `A(s)` the interface's directional-hemispherical
//!   transmittance downwards, `r_i` the floor-side hemispherical reflectance (total internal
//!   reflection included) and `T_out(v)` the hemispherical-directional transmittance upwards
//!   into the view (the radiance BTDF's 1/n² included), `BRF = π f_r(s, v) + T_out(v)·ρ·A(s)/(1 − ρ r_i)`
//!   (the first term: the Sun's glossy reflection by the interface), each term integrated by
//!   quadrature of the model's `eval` (the walk samples it instead).
//!
//! Test: |BRF − closed form| ≤ 4σ + 2e-4.

mod common;
use common::bundles::{flat_plane, tmp, with_plate, write_plane};
use common::*;
use glam::DVec3;

fn text(bundle: &std::path::Path, integrator: &str) -> String {
    format!(
        "seed = 11\n{integrator}[spectral]\nwavelengths = [550.0]\n\
         [scene]\ntype = \"bundle\"\npath = \"{}\"\n\
         [illumination]\ntype = \"directional\"\nzenith = 30.0\nazimuth = 180.0\n{}\
         target_m = [499900.0, 3999900.0, 500100.0, 4000100.0]\ntarget_height_m = 10.0\n",
        bundle.display(),
        mdistant_toml("area", &[0.0, 20.0, 50.0], &[0.0, 90.0, 200.0], 30000)
    )
}

/// The view directions of [`text`] (towards the sensor) and the Sun's.
fn views() -> Vec<DVec3> {
    [(0.0f64, 0.0f64), (20.0, 90.0), (50.0, 200.0)]
        .iter()
        .map(|&(z, a)| {
            let (z, a) = (z.to_radians(), a.to_radians());
            DVec3::new(z.sin() * a.sin(), z.sin() * a.cos(), z.cos())
        })
        .collect()
}

fn check(label: &str, got: &[(f64, f64)], want: &[f64]) {
    for (g, w) in got.iter().zip(want) {
        let z = (g.0 - w) / g.1;
        println!(
            "{label}: BRF {:.5} ± {:.5}, closed form {w:.5}, z = {z:+.2}",
            g.0, g.1
        );
    }
    for (g, w) in got.iter().zip(want) {
        assert!((g.0 - w).abs() <= 4.0 * g.1 + 2e-4, "{label}: {g:?} vs {w}");
    }
}

fn brfs(text: &str) -> Vec<(f64, f64)> {
    run_rows(&experiment(text))
        .iter()
        .map(|r| r.brf.unwrap())
        .collect()
}

/// Transmittance of a non-absorbing pane of index `n` at incidence cosine `mu`, per
/// polarization (1 − r)/(1 + r), averaged.
fn pane_t(n: f64, mu: f64) -> f64 {
    let st2 = (1.0 - mu * mu) / (n * n);
    let ct = (1.0 - st2).sqrt();
    let rs = ((mu - n * ct) / (mu + n * ct)).powi(2);
    let rp = ((n * mu - ct) / (n * mu + ct)).powi(2);
    0.5 * ((1.0 - rs) / (1.0 + rs) + (1.0 - rp) / (1.0 + rp))
}

#[test]
fn a_glass_pane_over_a_lambertian_floor_matches_the_closed_form() {
    let dir = tmp("pane-floor");
    let rho = 0.3;
    let plane = write_plane(&dir, &flat_plane(1000.0, 0.0, -500.0, rho));
    let n = 1.5;
    let pane = bundle::BrdfSpec::ThinDielectric(bundle::ThinDielectricSpec {
        refractive_index: bundle::Spectrum::Constant(n),
        internal_transmittance: None,
    });
    let b = with_plate(
        &plane,
        &dir.join("pane"),
        (0.0, 0.0, 5.0),
        2000.0,
        7,
        "glass",
        pane,
        None,
    );
    // R̄ = 2∫(1 − T(μ))μ dμ by the midpoint rule.
    let m = 200_000;
    let r_bar: f64 = (0..m)
        .map(|i| {
            let mu = (i as f64 + 0.5) / m as f64;
            2.0 * (1.0 - pane_t(n, mu)) * mu / m as f64
        })
        .sum();
    let mu_s = 30f64.to_radians().cos();
    let want: Vec<f64> = views()
        .iter()
        .map(|v| pane_t(n, mu_s) * pane_t(n, v.z) * rho / (1.0 - rho * r_bar))
        .collect();
    println!(
        "pane n = {n}: T(μs) = {:.5}, R̄ = {r_bar:.5}",
        pane_t(n, mu_s)
    );
    check("pane", &brfs(&text(&b, "")), &want);
    // The same with the spectral walk asked for explicitly is refused, naming the key.
    let e = engine::config::Experiment::from_str(
        &text(&b, "[integrator]\nspectral_walk = \"alis\"\n")
            .replace("wavelengths = [550.0]", "wavelengths = [550.0, 660.0]"),
        &data_dir().join("test.toml"),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("integrator.spectral_walk") && e.contains("glass"),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// `∫ g(w) dω` over the upper hemisphere: midpoint rule in θ (not cos θ: the lobes crossing
/// an interface near the normal are narrow in θ, and cos θ cells are coarse there) and φ.
fn hemisphere(n: usize, g: impl Fn(DVec3) -> f64) -> f64 {
    let h = std::f64::consts::FRAC_PI_2 / n as f64;
    let dp = std::f64::consts::PI / n as f64;
    let mut s = 0.0;
    for i in 0..n {
        let t = (i as f64 + 0.5) * h;
        let (st, ct) = (t.sin(), t.cos());
        for j in 0..2 * n {
            let p = (j as f64 + 0.5) * dp;
            s += g(DVec3::new(st * p.cos(), st * p.sin(), ct)) * st;
        }
    }
    s * h * dp
}

#[test]
fn a_rough_interface_over_a_lambertian_floor_matches_quadrature() {
    use engine::bsdf::RoughDielectric;
    let dir = tmp("rough-floor");
    let rho = 0.5;
    let plane = write_plane(&dir, &flat_plane(1000.0, 0.0, -500.0, rho));
    let (n, alpha) = (1.33, 0.4);
    let spec = bundle::BrdfSpec::RoughDielectric(bundle::RoughDielectricSpec {
        refractive_index: bundle::Spectrum::Constant(n),
        roughness: bundle::Spectrum::Constant(alpha),
    });
    let b = with_plate(
        &plane,
        &dir.join("rough"),
        (0.0, 0.0, 5.0),
        2000.0,
        7,
        "water",
        spec,
        None,
    );
    // Seen from above (the viewer outside, local z up) and from the floor (flipped: local z
    // down, index 1/n).
    let outside = RoughDielectric::new(n, alpha).unwrap();
    let inside = outside.flipped();
    let flip = |v: DVec3| DVec3::new(v.x, v.y, -v.z);
    let q = 200;
    let sun = DVec3::new(0.0, -30f64.to_radians().sin(), 30f64.to_radians().cos());
    // A(s): the Sun's light crossing down, over every direction the floor side sees.
    let a_s = hemisphere(q, |w| inside.eval(flip(sun), w) * w.z);
    // r_i = 2∫R_dh(μ)μ dμ, R_dh(μ) = ∫ f_inside(u, w) w_z dw for light from the floor at μ.
    let k = 48;
    let r_i: f64 = (0..k)
        .map(|i| {
            let mu = (i as f64 + 0.5) / k as f64;
            let u = DVec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
            2.0 * hemisphere(q, |w| inside.eval(u, w) * w.z) * mu / k as f64
        })
        .sum();
    let want: Vec<f64> = views()
        .iter()
        .map(|v| {
            let t_out = hemisphere(q, |u| outside.eval(flip(u), *v) * u.z);
            // The Sun's glossy reflection by the interface, plus what crossed it twice.
            let glossy = std::f64::consts::PI * outside.eval(sun, *v);
            let t2 = hemisphere(2 * q, |u| outside.eval(flip(u), *v) * u.z);
            println!("view {v:?}: T_out {t_out:.5} ({t2:.5} on a grid twice as fine), glossy {glossy:.5}");
            glossy + t_out * rho * a_s / (1.0 - rho * r_i)
        })
        .collect();
    println!("rough interface n = {n}, α = {alpha}: A(s) = {a_s:.5}, r_i = {r_i:.5}");
    check("rough interface", &brfs(&text(&b, "")), &want);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_dielectric_ground_of_a_1d_atmosphere_is_refused() {
    let e = engine::config::Experiment::from_str(
        "[spectral]\nwavelengths = [550.0]\n[surface]\ntype = \"thin_dielectric\"\n\
         refractive_index = 1.5\n[illumination]\ntype = \"directional\"\nzenith = 30.0\n\
         [[measures]]\ntype = \"mdistant\"\nid = \"m\"\nzeniths = [0.0]\nazimuth = 0.0\nspp = 100\n",
        &data_dir().join("test.toml"),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("surface") && e.contains("3D scenes only"), "{e}");
}
