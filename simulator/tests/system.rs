//! System tests: closed-form and conservation results the transport must reproduce exactly or
//! within its standard error. Each test states its rationale. Statistical test as in
//! `common::check_all` (|diff| ≤ 4.5σ + max(1e-5, 2e-4·ref)).

mod common;
use common::*;

fn base(
    atmosphere: &str,
    surface: &str,
    sza: f64,
    integrator: &str,
    extra: &str,
    measures: &str,
) -> String {
    format!(
        r#"
seed = 7
[spectral]
wavelengths = [550.0]
{atmosphere}
[surface]
{surface}
[illumination]
type = "directional"
zenith = {sza:?}
azimuth = 40.0
[integrator]
type = "{integrator}"
{extra}
{measures}"#
    )
}

const VZA: [f64; 7] = [0.0, 10.0, 30.0, 45.0, 60.0, 75.0, 85.0];
const VAA: [f64; 7] = [0.0, 40.0, 220.0, 130.0, 300.0, 40.0, 220.0];

/// White furnace: a conservative atmosphere (HG g = 0.6, τ = 2) over a white Lambertian ground
/// absorbs nothing, so everything that enters leaves through the top: the TOA albedo is 1, at
/// every solar zenith, by both walks. (Under a collimated Sun neither the radiance nor the upward
/// flux at an inner level is uniform, so only the TOA flux is tested here.)
#[test]
fn white_furnace() {
    let atm = "[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = 2.0\nphase = { type = \"hg\", g = 0.6 }";
    let surf = "type = \"lambertian\"\nreflectance = 1.0";
    let mut errs = Vec::new();
    for (integrator, spp) in [("forward", 40_000u64), ("backward", 20_000)] {
        for sza in [0.0, 35.0, 70.0] {
            let measures =
                format!("[[measures]]\nid = \"toa\"\ntype = \"distant_flux\"\nspp = {spp}\n");
            let exp = experiment(&base(atm, surf, sza, integrator, "", &measures));
            let rows = run_rows(&exp);
            let cmps: Vec<Cmp> = rows
                .iter()
                .map(|r| {
                    let (v, e) = r.albedo.unwrap();
                    Cmp {
                        label: r.measure.clone(),
                        reference: 1.0,
                        value: v,
                        stderr: e,
                    }
                })
                .collect();
            if let Err(e) = check_all(&format!("white furnace sza {sza} [{integrator}]"), &cmps) {
                errs.push(e);
            }
        }
    }
    assert!(errs.is_empty(), "{}", errs.join("\n"));
}

/// No atmosphere: the TOA BRF is the surface BRF, π·f_r(sun, view), exactly (every sample is
/// identical, so the standard error is 0), for every surface model, by both walks; the albedo is
/// the directional-hemispherical reflectance. `optical_thickness = 0` and no atmosphere agree.
#[test]
fn no_atmosphere_equals_bare_surface() {
    use engine::bsdf::Bsdf;
    use engine::frame::direction_from_angles;
    let surfaces = [
        "type = \"lambertian\"\nreflectance = 0.3",
        "type = \"rpv\"\nrho_0 = 0.2\nk = 0.8\ng = -0.2\nrho_c = 0.25",
        "type = \"rtls\"\nf_iso = 0.2\nf_vol = 0.05\nf_geo = 0.03",
        "type = \"hapke\"\nw = 0.5\nb = 0.3\nc = 0.4\ntheta = 15.0\nB_0 = 0.8\nh = 0.06",
    ];
    for surf in surfaces {
        for atm in [
            "",
            "[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = 0.0",
        ] {
            for integrator in ["forward", "backward"] {
                let exp = experiment(&base(
                    atm,
                    surf,
                    30.0,
                    integrator,
                    "",
                    &mdistant_toml("toa", &VZA, &VAA, 100),
                ));
                let bsdf: &Bsdf = &exp.optics[0].surface;
                let rows = run_rows(&exp);
                for (r, (z, a)) in rows.iter().zip(VZA.iter().zip(VAA)) {
                    let v = direction_from_angles(z.to_radians(), a.to_radians());
                    let expect = std::f64::consts::PI * bsdf.eval(exp.sun_dir, v);
                    let (got, se) = r.brf.unwrap();
                    assert!(
                        (got - expect).abs() <= 1e-12 * expect.max(1.0)
                            && se <= 1e-7 * expect.max(1e-3),
                        "{surf} {atm} {integrator} vza {z}: {got} ± {se} vs {expect}"
                    );
                }
            }
        }
    }
    // Lambertian albedo with no atmosphere is the reflectance.
    let exp = experiment(&base(
        "",
        surfaces[0],
        30.0,
        "forward",
        "",
        "[[measures]]\nid = \"f\"\ntype = \"distant_flux\"\nspp = 1000\n",
    ));
    let (a, _) = run_rows(&exp)[0].albedo.unwrap();
    assert!((a - 0.3).abs() < 1e-12, "{a}");
}

/// RTLS-H (Ross-Li with the Maignan et al. 2004 hot spot) over a bare surface: with no
/// atmosphere, or one of zero optical depth, the TOA BRF is the surface BRF π·f_r at the
/// sensor geometry, by both walks, within the z-test of `check_all`. The views include the exact
/// hot spot (view = Sun, ξ = 0), where the factor doubles the Ross scattering term and the
/// reference is also the closed form f_iso + f_vol·(π/4)(2 sec θ − 1) + f_geo·(sec²θ − sec θ),
/// views at ξ ≈ ξ0 and 3ξ0 from it, and views far from it.
#[test]
fn rtls_hotspot_bare_surface() {
    use engine::frame::direction_from_angles;
    let (f_iso, f_vol, f_geo, sza) = (0.25, 0.12, 0.04, 30.0f64);
    let surf = format!(
        "type = \"rtls_hotspot\"\nf_iso = {f_iso}\nf_vol = {f_vol}\nf_geo = {f_geo}\nxi0 = 1.5"
    );
    // The Sun's azimuth in `base` is 40°.
    let vza = [30.0, 31.5, 34.5, 0.0, 45.0, 60.0, 30.0];
    let vaa = [40.0, 40.0, 40.0, 0.0, 130.0, 300.0, 220.0];
    let sec = 1.0 / sza.to_radians().cos();
    let hot_spot =
        f_iso + f_vol * std::f64::consts::FRAC_PI_4 * (2.0 * sec - 1.0) + f_geo * (sec * sec - sec);
    let mut errs = Vec::new();
    for atm in [
        "",
        "[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = 0.0",
    ] {
        for integrator in ["forward", "backward"] {
            let exp = experiment(&base(
                atm,
                &surf,
                sza,
                integrator,
                "",
                &mdistant_toml("toa", &vza, &vaa, 1000),
            ));
            let bsdf = &exp.optics[0].surface;
            let rows = run_rows(&exp);
            let mut cmps = Vec::new();
            for (r, (z, a)) in rows.iter().zip(vza.iter().zip(vaa)) {
                let v = direction_from_angles(z.to_radians(), a.to_radians());
                let (value, stderr) = r.brf.unwrap();
                cmps.push(Cmp {
                    label: format!("vza {z} vaa {a}"),
                    reference: std::f64::consts::PI * bsdf.eval(exp.sun_dir, v),
                    value,
                    stderr,
                });
            }
            cmps.push(Cmp {
                label: "hot spot, closed form".into(),
                reference: hot_spot,
                ..cmps[0].clone()
            });
            let case = format!(
                "RTLS-H, {} [{integrator}]",
                if atm.is_empty() {
                    "no atmosphere"
                } else {
                    "τ = 0"
                }
            );
            println!(
                "{case}: hot spot BRF {:.6} (closed form {hot_spot:.6}), 3ξ0 away {:.6}, forward {:.6}",
                cmps[0].value, cmps[2].value, cmps[6].value
            );
            if let Err(e) = check_all(&case, &cmps) {
                errs.push(e);
            }
        }
    }
    assert!(errs.is_empty(), "{}", errs.join("\n"));
}

/// Single scattering in closed form: with `max_depth = 1`, a homogeneous layer (τ, ω, P) over a
/// Lambertian ground ρ gives BRF = ω P(Θ) / (4(μ0+μ)) · (1 − e^{−τ(1/μ0+1/μ)}) + ρ e^{−τ(1/μ0+1/μ)}
/// (Chandrasekhar 1950; Liou 2002 §6.3), and the `brf_single` column of a full run equals the same
/// value. Tests the local estimates, the scattering-angle convention (asymmetric HG), and the
/// single/multiple split.
#[test]
fn single_scattering_closed_form() {
    use engine::phase::HenyeyGreenstein;
    let (tau, omega, g, rho, sza) = (0.4, 0.9, 0.7, 0.2, 40.0f64);
    let atm = format!(
        "[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = {tau}\nsingle_scattering_albedo = {omega}\nphase = {{ type = \"hg\", g = {g} }}"
    );
    let surf = format!("type = \"lambertian\"\nreflectance = {rho}");
    let hg = HenyeyGreenstein::new(g).unwrap();
    let mu0 = sza.to_radians().cos();
    let sun = engine::frame::direction_from_angles(sza.to_radians(), 40f64.to_radians());
    let reference = |z: f64, a: f64| {
        let v = engine::frame::direction_from_angles(z.to_radians(), a.to_radians());
        let mu = v.z;
        // Light travels along −sun and leaves along v: cos Θ = −sun·v.
        let p = hg.eval(-sun.dot(v));
        let att = (-tau * (1.0 / mu0 + 1.0 / mu)).exp();
        omega * p / (4.0 * (mu0 + mu)) * (1.0 - att) + rho * att
    };
    let mut errs = Vec::new();
    for (integrator, spp, extra) in [
        ("forward", 200_000u64, "max_depth = 1"),
        ("backward", 40_000, "max_depth = 1"),
        ("forward", 200_000, ""),
    ] {
        let exp = experiment(&base(
            &atm,
            &surf,
            sza,
            integrator,
            extra,
            &mdistant_toml("toa", &VZA, &VAA, spp),
        ));
        let rows = run_rows(&exp);
        let cmps: Vec<Cmp> = rows
            .iter()
            .map(|r| {
                let (v, e) = if extra.is_empty() {
                    r.brf_single.unwrap()
                } else {
                    r.brf.unwrap()
                };
                let (z, a) = (r.vza.unwrap(), r.vaa.unwrap());
                Cmp {
                    label: format!("vza {z} vaa {a}"),
                    reference: reference(z, a),
                    value: v,
                    stderr: e,
                }
            })
            .collect();
        if let Err(e) = check_all(&format!("single scattering [{integrator} {extra}]"), &cmps) {
            errs.push(e);
        }
    }
    assert!(errs.is_empty(), "{}", errs.join("\n"));
}

/// Determinism: random streams depend on (wavelength, measure, direction, sample) only, and
/// blocks merge in a fixed order, so 1 and 2 threads give bit-identical results.
#[test]
fn thread_count_independence() {
    let atm = "[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = 0.5";
    let surf = "type = \"lambertian\"\nreflectance = 0.3";
    for integrator in ["auto", "backward"] {
        let measures = format!(
            "{}[[measures]]\nid = \"rm\"\ntype = \"radiancemeter\"\norigin = [0.0, 0.0, 5.0]\ndirection = [0.1, 0.0, -1.0]\nspp = 10000\n",
            mdistant_toml("toa", &VZA, &VAA, 10_000)
        );
        let exp = experiment(&base(atm, surf, 30.0, integrator, "", &measures));
        let (a, b) = run_on_1_and_2_threads(&exp);
        for (x, y) in a.iter().zip(&b) {
            assert_eq!(
                x.acc, y.acc,
                "{integrator}: results differ between 1 and 2 threads"
            );
        }
    }
}

/// Honest uncertainty: over 40 independent seeds, the scatter of the estimates matches the
/// reported standard error. The ratio (empirical std / mean reported stderr) of 40 estimates has
/// a relative sampling error of about 1/√(2·39) ≈ 11 %; we require it in [0.7, 1.35].
#[test]
fn standard_errors_are_honest() {
    let atm = "[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = 0.3\nphase = { type = \"hg\", g = 0.5 }";
    let surf = "type = \"lambertian\"\nreflectance = 0.2";
    for integrator in ["forward", "backward"] {
        let mut means = Vec::new();
        let mut ses = Vec::new();
        for seed in 0..40u64 {
            let text = base(
                atm,
                surf,
                30.0,
                integrator,
                "",
                &mdistant_toml("toa", &[20.0], &[220.0], 4000),
            )
            .replace("seed = 7", &format!("seed = {seed}"));
            let rows = run_rows(&experiment(&text));
            let (v, e) = rows[0].brf.unwrap();
            means.push(v);
            ses.push(e);
        }
        let n = means.len() as f64;
        let m = means.iter().sum::<f64>() / n;
        let sd = (means.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        let se = ses.iter().sum::<f64>() / n;
        let ratio = sd / se;
        println!(
            "{integrator}: empirical std {sd:.3e}, mean reported stderr {se:.3e}, ratio {ratio:.3}"
        );
        assert!((0.7..1.35).contains(&ratio), "{integrator}: ratio {ratio}");
    }
}

/// The two walks are independent estimators of the same radiance: a radiancemeter at TOA
/// looking down equals the mdistant value of that direction; a radiancemeter on the ground
/// looking up sees the sky radiance, compared with the forward-free backward value of the
/// reciprocal problem is not available, so it is checked against DISORT-free physics: zero with
/// no atmosphere, positive otherwise.
#[test]
fn radiancemeter_matches_distant() {
    let atm = "[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = 0.5\nphase = { type = \"hg\", g = 0.7 }";
    let surf = "type = \"lambertian\"\nreflectance = 0.3";
    // Looking down along −v with v at vza 30°, vaa 220°.
    let v = engine::frame::direction_from_angles(30f64.to_radians(), 220f64.to_radians());
    let measures = format!(
        "{}[[measures]]\nid = \"rm\"\ntype = \"radiancemeter\"\norigin = [1.0, 2.0, 100.0]\ndirection = [{}, {}, {}]\nspp = 200000\n",
        mdistant_toml("toa", &[30.0], &[220.0], 400_000),
        -v.x,
        -v.y,
        -v.z
    );
    let rows = run_rows(&experiment(&base(atm, surf, 30.0, "auto", "", &measures)));
    let (a, ae) = rows[0].brf.unwrap();
    let (b, be) = rows[1].brf.unwrap();
    assert_eq!(rows[1].method, "backward");
    assert!(
        (rows[1].vza.unwrap() - 30.0).abs() < 1e-9 && (rows[1].vaa.unwrap() - 220.0).abs() < 1e-9
    );
    let z = (a - b).abs() / (ae * ae + be * be).sqrt();
    println!("mdistant {a} ± {ae}, radiancemeter {b} ± {be}, z = {z:.2}");
    assert!(z < 4.5, "z = {z}");
    // Looking up from the ground: the sky is dark without an atmosphere, bright with one.
    let up = "[[measures]]\nid = \"sky\"\ntype = \"radiancemeter\"\norigin = [0.0, 0.0, 0.0]\ndirection = [0.0, 0.3, 1.0]\nspp = 1000\n";
    let rows = run_rows(&experiment(&base("", surf, 30.0, "auto", "", up)));
    assert_eq!(rows[0].brf.unwrap().0, 0.0);
    let rows = run_rows(&experiment(&base(atm, surf, 30.0, "auto", "", up)));
    assert!(rows[0].brf.unwrap().0 > 0.0);
}

/// Forward and backward walks agree on the TOA albedo of a layered, absorbing atmosphere over an
/// RPV surface (two independent estimators of one quantity).
#[test]
fn forward_backward_flux_agree() {
    let atm = r#"
[atmosphere]
type = "layered"
[[atmosphere.layers]]
bottom = 0.0
top = 2.0
tau_sca = 0.3
tau_abs = 0.05
phase = { type = "hg", g = 0.6 }
[[atmosphere.layers]]
bottom = 2.0
top = 100.0
optical_thickness = 0.1
single_scattering_albedo = 0.9
"#;
    let surf = "type = \"rpv\"\nrho_0 = 0.15\nk = 0.7\ng = -0.15";
    let m = |spp| {
        format!("[[measures]]\nid = \"f\"\ntype = \"distant_flux\"\nspp = {spp}\n[[measures]]\nid = \"boa\"\ntype = \"distant_flux\"\naltitude = 1.0\nspp = {spp}\n")
    };
    let f = run_rows(&experiment(&base(
        atm,
        surf,
        50.0,
        "forward",
        "",
        &m(400_000),
    )));
    let b = run_rows(&experiment(&base(
        atm,
        surf,
        50.0,
        "backward",
        "",
        &m(100_000),
    )));
    for (x, y) in f.iter().zip(&b) {
        let ((a, ae), (c, ce)) = (x.albedo.unwrap(), y.albedo.unwrap());
        let z = (a - c).abs() / (ae * ae + ce * ce).sqrt();
        println!(
            "{}: forward {a:.5} ± {ae:.1e}, backward {c:.5} ± {ce:.1e}, z = {z:.2}",
            x.measure
        );
        assert!(z < 4.5, "{}: z = {z}", x.measure);
    }
}

/// A molecular (AFGL US standard, Rayleigh) atmosphere in plane-parallel geometry: every layer
/// has the same phase function and albedo, and the walks move in optical depth, so a stack of
/// 200 layers is indistinguishable from one homogeneous layer of the same total τ (0.0972 at
/// 550 nm) and depolarization (from Bates' King factor): with the same seed the results must be
/// identical to rounding. Catches wrong layer sums, gaps, or a wrong depolarization. The τ value
/// itself is checked against the literature in `atmosphere::molecular`.
#[test]
fn molecular_equals_homogeneous() {
    use engine::atmosphere::molecular::{depolarization, rayleigh_cross_section, Profile};
    let p = Profile::builtin("afgl_1986-us_standard").unwrap();
    let tau = p.column(0.0, 100e3) * rayleigh_cross_section(550.0);
    let rho = depolarization(550.0);
    let surf = "type = \"lambertian\"\nreflectance = 0.1";
    let m = mdistant_toml("toa", &VZA, &VAA, 20_000);
    let a = run_rows(&experiment(&base(
        "[atmosphere]\ntype = \"molecular\"\nlayer_thickness = 0.5",
        surf,
        40.0,
        "forward",
        "",
        &m,
    )));
    let b = run_rows(&experiment(&base(
        &format!("[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = {tau:?}\nphase = {{ type = \"rayleigh\", depolarization = {rho:?} }}"),
        surf,
        40.0,
        "forward",
        "",
        &m,
    )));
    for (x, y) in a.iter().zip(&b) {
        let (u, v) = (x.brf.unwrap().0, y.brf.unwrap().0);
        assert!(
            (u - v).abs() <= 1e-12 * v,
            "vza {:?}: layered {u} vs homogeneous {v}",
            x.vza
        );
    }
}

/// Solar spectra and the Earth–Sun distance scale radiances, never BRFs: with the same seed,
/// `irradiance = "tsis_1"` and a date give the same BRF as E0 = 1 and a radiance larger by
/// E_TSIS(λ)·(r0/r)² exactly; unknown spectra and wavelengths outside a spectrum are errors
/// naming the key.
#[test]
fn solar_spectrum_and_date() {
    use engine::spectral::solar::{day_of_year, earth_sun_factor, Spectrum};
    let atm = "[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = 0.2";
    let surf = "type = \"lambertian\"\nreflectance = 0.2";
    let m = mdistant_toml("toa", &[10.0, 50.0], &[0.0, 90.0], 2000);
    let a = run_rows(&experiment(&base(atm, surf, 30.0, "forward", "", &m)));
    let text = base(atm, surf, 30.0, "forward", "", &m).replace(
        "azimuth = 40.0\n",
        "azimuth = 40.0\nirradiance = \"tsis_1\"\ndate = \"2024-01-03\"\n",
    );
    let b = run_rows(&experiment(&text));
    let k = Spectrum::builtin("tsis_1").unwrap().at(550.0).unwrap()
        * earth_sun_factor(day_of_year("2024-01-03").unwrap());
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.brf, y.brf);
        let (ra, rb) = (x.radiance.unwrap().0, y.radiance.unwrap().0);
        assert!((rb / ra / k - 1.0).abs() < 1e-12, "{rb} / {ra} vs {k}");
    }
    let bad = engine::config::Experiment::from_str(
        &text.replace("wavelengths = [550.0]", "wavelengths = [3000.0]"),
        std::path::Path::new("x.toml"),
    )
    .unwrap_err()
    .to_string();
    assert!(
        bad.contains("illumination.irradiance") && bad.contains("3000"),
        "{bad}"
    );
    let bad = engine::config::Experiment::from_str(
        &text.replace("tsis_1", "no_such_sun"),
        std::path::Path::new("x.toml"),
    )
    .unwrap_err()
    .to_string();
    assert!(
        bad.contains("illumination.irradiance") && bad.contains("no_such_sun"),
        "{bad}"
    );
}

/// Sensor bands: with `spectral.srf` the run samples the band and reports band-weighted values.
/// Over a bare Lambertian surface whose reflectance varies across the band the BRF of each
/// wavelength is exact, so the band BRF must equal Σ S·Δλ·E0·ρ / Σ S·Δλ·E0 computed here from the
/// same SRF and the TSIS-1 spectrum, to rounding.
#[test]
fn band_weighted_outputs() {
    use engine::spectral::solar::Spectrum;
    use engine::spectral::srf::Srf;
    let (wl, w) = Srf::builtin("sentinel_2a-msi-4")
        .unwrap()
        .unwrap()
        .grid(2.0)
        .unwrap();
    let rho: Vec<f64> = wl.iter().map(|l| 0.2 + 0.004 * (l - 650.0)).collect();
    let list: Vec<String> = rho.iter().map(|r| format!("{r:?}")).collect();
    let text = format!(
        "[spectral]\nsrf = \"sentinel_2a-msi-4\"\nwavelength_step = 2.0\n[surface]\ntype = \"lambertian\"\nreflectance = [{}]\n\
         [illumination]\ntype = \"directional\"\nzenith = 30.0\nirradiance = \"tsis_1\"\n{}",
        list.join(", "),
        mdistant_toml("toa", &[0.0, 40.0], &[0.0, 90.0], 100)
    );
    let exp = experiment(&text);
    assert_eq!(exp.wavelengths, wl);
    let rows = run_rows(&exp);
    let band = simulator::products::band_rows(&exp, &rows);
    assert_eq!(band.len(), 2);
    let tsis = Spectrum::builtin("tsis_1").unwrap();
    let e0: Vec<f64> = wl.iter().map(|l| tsis.at(*l).unwrap()).collect();
    let num: f64 = (0..wl.len()).map(|k| w[k] * e0[k] * rho[k]).sum();
    let den: f64 = (0..wl.len()).map(|k| w[k] * e0[k]).sum();
    for b in &band {
        let (v, _) = b.brf.unwrap();
        assert!(
            (v / (num / den) - 1.0).abs() < 1e-12,
            "{v} vs {}",
            num / den
        );
        // Band radiance and band irradiance are consistent with the band BRF.
        let (l, _) = b.radiance.unwrap();
        let mu0 = 30f64.to_radians().cos();
        assert!((std::f64::consts::PI * l / (b.irradiance * mu0) / v - 1.0).abs() < 1e-12);
    }
    let err = engine::config::Experiment::from_str(
        &text.replace("sentinel_2a-msi-4", "sentinel_2a-msi-99"),
        std::path::Path::new("x.toml"),
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("spectral.srf") && err.contains("8a"), "{err}");
}

/// Illumination from a time and a place (NREL SPA): the experiment's solar angles are those of
/// `sun_position` for that instant (checked against the SPA paper in its unit test), and the
/// 1 AU irradiance is scaled by 1/r²; conflicting keys are errors naming them.
#[test]
fn illumination_from_time_and_place() {
    use engine::sources::sun_position::sun_position;
    let ill = "type = \"directional\"\ntime = \"2024-06-21T10:30:00Z\"\nlatitude = 28.55\nlongitude = 23.39\nelevation = 118.0\nirradiance = 1.5";
    let text = format!(
        "[spectral]\nwavelengths = [550.0]\n[surface]\ntype = \"lambertian\"\nreflectance = 0.4\n[illumination]\n{ill}\n{}",
        mdistant_toml("toa", &[0.0], &[0.0], 100)
    );
    let exp = experiment(&text);
    let p = sun_position("2024-06-21T10:30:00Z", 28.55, 23.39, 118.0, None).unwrap();
    assert!(
        (exp.sun_zenith_deg - p.zenith).abs() < 1e-12
            && (exp.sun_azimuth_deg - p.azimuth).abs() < 1e-12
    );
    // Libya-4 near local noon at the June solstice: the Sun is high, in the south-east to south.
    assert!(
        p.zenith > 4.0 && p.zenith < 15.0 && p.azimuth > 90.0 && p.azimuth < 200.0,
        "{p:?}"
    );
    assert!((exp.optics[0].irradiance - 1.5 / (p.distance_au * p.distance_au)).abs() < 1e-12);
    assert!(
        (p.distance_au - 1.0163).abs() < 2e-4,
        "aphelion season: {}",
        p.distance_au
    );
    for (bad, key) in [
        (
            text.replace("irradiance = 1.5", "irradiance = 1.5\nzenith = 30.0"),
            "illumination.zenith",
        ),
        (
            text.replace(
                "irradiance = 1.5",
                "irradiance = 1.5\ndate = \"2024-06-21\"",
            ),
            "illumination.date",
        ),
        (
            text.replace("latitude = 28.55\n", ""),
            "illumination.latitude",
        ),
        (text.replace("10:30:00Z", "10:30:00"), "illumination.time"),
    ] {
        let e = engine::config::Experiment::from_str(&bad, std::path::Path::new("x.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains(key), "{key}: {e}");
    }
}

/// With a sensor band, `target_rel_stderr` is the target of the band-weighted value: each
/// wavelength's target is relaxed by √N_eff (N_eff = (Σa)²/Σa², a = SRF weight × E0), since N
/// independent wavelengths with equal relative errors average down that way.
#[test]
fn band_precision_target() {
    use engine::spectral::srf::Srf;
    let (_, w) = Srf::builtin("sentinel_2a-msi-4")
        .unwrap()
        .unwrap()
        .grid(5.0)
        .unwrap();
    let text = format!(
        "[spectral]\nsrf = \"sentinel_2a-msi-4\"\n[surface]\ntype = \"lambertian\"\nreflectance = 0.3\n\
         [illumination]\ntype = \"directional\"\nzenith = 30.0\n{}target_rel_stderr = 0.002\n",
        mdistant_toml("toa", &[0.0], &[0.0], 1_000_000)
    );
    let exp = experiment(&text);
    // Constant E0 = 1 here, so a = w.
    let n_eff = w.iter().sum::<f64>().powi(2) / w.iter().map(|x| x * x).sum::<f64>();
    let t = exp.measures[0].target_rel_stderr.unwrap();
    assert!(
        (t - 0.002 * n_eff.sqrt()).abs() < 1e-12 && n_eff > 3.0,
        "{t} {n_eff}"
    );
}
