//! Polarized Rayleigh transport against the corrected Coulson tables of Natraj, Li & Yung
//! (2009) (`tests/data/natraj_2009/`, provenance in `tests/data/fixtures/PROVENANCE.md`): a
//! conservative Rayleigh slab (τ = 0.1, 0.5; no depolarization) over Lambertian ground
//! (A = 0, 0.25, 0.8), Stokes I, Q, U emerging at the top, for several μ0, μ and φ.
//!
//! Rationale: the tables are exact (X/Y-function solutions, 8 digits); they test the Rayleigh
//! phase matrix, the Stokes rotations between scattering and meridian planes, and the sign
//! conventions. Mapping (docs/conventions.md): table φ = 180° − raa with raa counter-clockwise,
//! so our view azimuth (clockwise, Sun at 0) is `φ − 180°`; BRF-like values are `table/μ0`, and
//! the tables' (Q, U) are −(Q, U) of our meridian frame.
//!
//! Also: the scalar run differs from the polarized I by the known polarization effect (a few %),
//! and for an isotropic (depolarizing) phase function polarized and scalar runs agree.
//! Statistical test: `common::check_all` (|diff| ≤ 4.5σ + max(1e-5, 2e-4·ref)).

mod common;
use common::*;

/// (μ0, μ, [value at φ = 0, 30, …, 180]) rows of one table block.
fn table(component: &str, tau: &str, albedo: &str) -> Vec<(f64, f64, [f64; 7])> {
    table_dir(component, "UP", tau, albedo)
}

fn table_dir(component: &str, dir: &str, tau: &str, albedo: &str) -> Vec<(f64, f64, [f64; 7])> {
    let path = data_dir().join(format!("natraj_2009/{component}_{dir}_TAU_{tau}"));
    let text = std::fs::read_to_string(&path).unwrap();
    let mut inside = false;
    let mut out = Vec::new();
    for line in text.lines() {
        let t = line.trim();
        if let Some(a) = t.strip_prefix("albedo = ") {
            inside = a.trim() == albedo;
            continue;
        }
        if !inside {
            continue;
        }
        let f: Vec<f64> = t
            .split_whitespace()
            .filter_map(|x| x.parse().ok())
            .collect();
        if f.len() == 9 {
            out.push((f[0], f[1], [f[2], f[3], f[4], f[5], f[6], f[7], f[8]]));
        }
    }
    assert!(
        !out.is_empty(),
        "no block albedo = {albedo} in {}",
        path.display()
    );
    out
}

const MU0: [f64; 3] = [0.2, 0.6, 1.0];
const MU: [f64; 6] = [0.1, 0.2, 0.4, 0.64, 0.84, 1.0];

fn run_case(tau: &str, albedo: &str, mu0: f64, spp: u64) -> Result<(), String> {
    run_case_with(tau, albedo, mu0, spp, "forward", 1)
}

fn run_case_with(
    tau: &str,
    albedo: &str,
    mu0: f64,
    spp: u64,
    integrator: &str,
    every: usize,
) -> Result<(), String> {
    let (ti, tq, tu) = (
        table("I", tau, albedo),
        table("Q", tau, albedo),
        table("U", tau, albedo),
    );
    let sza = mu0.acos().to_degrees();
    let (mut vza, mut vaa, mut refs) = (Vec::new(), Vec::new(), Vec::new());
    for &mu in &MU {
        let pick = |t: &Vec<(f64, f64, [f64; 7])>| {
            t.iter()
                .find(|r| (r.0 - mu0).abs() < 1e-9 && (r.1 - mu).abs() < 1e-9)
                .unwrap()
                .2
        };
        let (i, q, u) = (pick(&ti), pick(&tq), pick(&tu));
        for k in 0..7 {
            let phi = 30.0 * k as f64;
            vza.push(mu.acos().to_degrees());
            vaa.push((phi - 180.0f64).rem_euclid(360.0));
            refs.push((phi, mu, i[k] / mu0, -q[k] / mu0, -u[k] / mu0));
        }
    }
    let keep: Vec<usize> = (0..refs.len()).step_by(every).collect();
    let vza: Vec<f64> = keep.iter().map(|&k| vza[k]).collect();
    let vaa: Vec<f64> = keep.iter().map(|&k| vaa[k]).collect();
    let refs: Vec<_> = keep.iter().map(|&k| refs[k]).collect();
    let text = format!(
        "seed = 3\npolarized = true\n[spectral]\nwavelengths = [550.0]\n[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = {tau}\n\
         [surface]\ntype = \"lambertian\"\nreflectance = {albedo}\n[illumination]\ntype = \"directional\"\nzenith = {sza:?}\nazimuth = 0.0\n[integrator]\ntype = \"{integrator}\"\n{}",
        mdistant_toml("toa", &vza, &vaa, spp)
    );
    let rows = run_rows(&experiment(&text));
    let mut cmps = Vec::new();
    for (r, (phi, mu, i, q, u)) in rows.iter().zip(&refs) {
        let label = |c: &str| format!("{c} mu {mu} phi {phi}");
        let (vi, ei) = r.brf.unwrap();
        let (vq, eq) = r.brf_q.unwrap();
        let (vu, eu) = r.brf_u.unwrap();
        cmps.push(Cmp {
            label: label("I"),
            reference: *i,
            value: vi,
            stderr: ei,
        });
        cmps.push(Cmp {
            label: label("Q"),
            reference: *q,
            value: vq,
            stderr: eq,
        });
        cmps.push(Cmp {
            label: label("U"),
            reference: *u,
            value: vu,
            stderr: eu,
        });
    }
    check_all(
        &format!("Natraj 2009 tau={tau} A={albedo} mu0={mu0} [{integrator}]"),
        &cmps,
    )
}

/// The polarized backward walk (adjoint transport of Mueller-matrix products, the walk behind
/// polarized radiancemeters) against the same tables, on every 5th direction of four cases.
#[test]
fn polarized_backward_matches_natraj_2009() {
    let mut errs = Vec::new();
    for (tau, albedo, mu0) in [
        ("0.1", "0.25", 0.6),
        ("0.5", "0.00", 0.2),
        ("0.5", "0.80", 0.6),
        ("0.5", "0.25", 1.0),
    ] {
        if let Err(e) = run_case_with(tau, albedo, mu0, 40_000, "backward", 5) {
            errs.push(e);
        }
    }
    assert!(errs.is_empty(), "{}", errs.join("\n"));
}

#[test]
fn polarized_rayleigh_matches_natraj_2009() {
    let mut errs = Vec::new();
    for tau in ["0.1", "0.5"] {
        for albedo in ["0.00", "0.25", "0.80"] {
            for mu0 in MU0 {
                if let Err(e) = run_case(tau, albedo, mu0, 300_000) {
                    errs.push(e);
                }
            }
        }
    }
    assert!(errs.is_empty(), "{}", errs.join("\n"));
}

/// Neglecting polarization biases Rayleigh radiance by a few percent (here: the scalar I differs
/// from the vector I by more than 1 % somewhere in the principal plane, and by less than 10 %),
/// while for an isotropic, depolarizing phase function scalar and vector runs agree within noise.
#[test]
fn scalar_vs_vector() {
    let run = |polarized: bool, phase: &str| {
        let zen: Vec<f64> = vec![0.0, 20.0, 40.0, 60.0, 75.0];
        let mut vaa = vec![0.0; 5];
        vaa.extend(vec![180.0; 5]);
        let mut vza = zen.clone();
        vza.extend(zen);
        let text = format!(
            "seed = 8\npolarized = {polarized}\n[spectral]\nwavelengths = [550.0]\n[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = 0.5\nphase = {phase}\n\
             [surface]\ntype = \"lambertian\"\nreflectance = 0.1\n[illumination]\ntype = \"directional\"\nzenith = 40.0\n{}",
            mdistant_toml("toa", &vza, &vaa, 400_000)
        );
        run_rows(&experiment(&text))
    };
    let (s, v) = (
        run(false, "{ type = \"rayleigh\" }"),
        run(true, "{ type = \"rayleigh\" }"),
    );
    let mut max_rel: f64 = 0.0;
    for (a, b) in s.iter().zip(&v) {
        let ((x, ex), (y, ey)) = (a.brf.unwrap(), b.brf.unwrap());
        let rel = (x / y - 1.0).abs();
        let z = (x - y).abs() / (ex * ex + ey * ey).sqrt();
        if z > 6.0 {
            max_rel = max_rel.max(rel);
        }
        assert!(rel < 0.1, "vza {:?}: scalar {x} vs vector {y}", a.vza);
    }
    println!("Rayleigh: largest significant |scalar/vector − 1| = {max_rel:.3}");
    assert!(max_rel > 0.01, "polarization effect not seen: {max_rel}");
    let (s, v) = (
        run(false, "{ type = \"isotropic\" }"),
        run(true, "{ type = \"isotropic\" }"),
    );
    let cmps: Vec<Cmp> = s
        .iter()
        .zip(&v)
        .map(|(a, b)| {
            let ((x, ex), (y, ey)) = (a.brf.unwrap(), b.brf.unwrap());
            Cmp {
                label: format!("vza {:?} vaa {:?}", a.vza, a.vaa),
                reference: x,
                value: y,
                stderr: (ex * ex + ey * ey).sqrt(),
            }
        })
        .collect();
    check_all("isotropic: vector I vs scalar", &cmps).unwrap();
    for r in &v {
        assert!(r.brf_q.unwrap().0.abs() < 1e-12 && r.brf_u.unwrap().0.abs() < 1e-12);
    }
}

/// A polarized radiancemeter at TOA looking down along −v measures the same Stokes vector as the
/// forward mdistant walk in direction v (independent estimators; HG aerosol below Rayleigh makes
/// the case less symmetric).
#[test]
fn polarized_radiancemeter_matches_mdistant() {
    let v = engine::frame::direction_from_angles(60f64.to_radians(), 120f64.to_radians());
    let text = format!(
        "seed = 9\npolarized = true\n[spectral]\nwavelengths = [550.0]\n[atmosphere]\ntype = \"layered\"\n\
         [[atmosphere.layers]]\nbottom = 0.0\ntop = 2.0\ntau_sca = 0.2\ntau_abs = 0.02\nphase = {{ type = \"hg\", g = 0.7 }}\n\
         [[atmosphere.layers]]\nbottom = 2.0\ntop = 100.0\ntau_sca = 0.3\n\
         [surface]\ntype = \"lambertian\"\nreflectance = 0.2\n[illumination]\ntype = \"directional\"\nzenith = 35.0\nazimuth = 0.0\n{}\
         [[measures]]\nid = \"rm\"\ntype = \"radiancemeter\"\norigin = [0.0, 0.0, 100.0]\ndirection = [{:?}, {:?}, {:?}]\nspp = 200000\n",
        mdistant_toml("toa", &[60.0], &[120.0], 400_000),
        -v.x,
        -v.y,
        -v.z
    );
    let rows = run_rows(&experiment(&text));
    let (a, b) = (&rows[0], &rows[1]);
    assert_eq!(b.method, "backward");
    let mut cmps = Vec::new();
    for (name, x, y) in [
        ("I", a.brf, b.brf),
        ("Q", a.brf_q, b.brf_q),
        ("U", a.brf_u, b.brf_u),
    ] {
        let ((va, ea), (vb, eb)) = (x.unwrap(), y.unwrap());
        cmps.push(Cmp {
            label: name.into(),
            reference: va,
            value: vb,
            stderr: (ea * ea + eb * eb).sqrt(),
        });
    }
    check_all("polarized radiancemeter vs mdistant", &cmps).unwrap();
}

/// Diffuse radiation emerging at the bottom (the tables' DN): radiancemeters on the ground look
/// up at sky zenith acos μ; the table's φ = 0 is the forward-scattering side, i.e. looking
/// towards the Sun (our look azimuth = φ with the Sun at azimuth 0). Same Stokes mapping as at
/// the top ((Q, U) of opposite sign to the tables'). Tests downward polarized transport.
#[test]
fn polarized_downward_matches_natraj_2009() {
    let mut errs = Vec::new();
    for (tau, albedo, mu0) in [("0.5", "0.25", 0.6), ("0.1", "0.80", 0.2)] {
        let (ti, tq, tu) = (
            table_dir("I", "DN", tau, albedo),
            table_dir("Q", "DN", tau, albedo),
            table_dir("U", "DN", tau, albedo),
        );
        let mut measures = String::new();
        let mut refs = Vec::new();
        for mu in [0.2, 0.4, 0.84] {
            let pick = |t: &Vec<(f64, f64, [f64; 7])>| {
                t.iter()
                    .find(|r| (r.0 - mu0).abs() < 1e-9 && (r.1 - mu).abs() < 1e-9)
                    .unwrap()
                    .2
            };
            let (i, q, u) = (pick(&ti), pick(&tq), pick(&tu));
            for k in [0usize, 2, 4, 6] {
                let phi = 30.0 * k as f64;
                let look = engine::frame::direction_from_angles(f64::acos(mu), phi.to_radians());
                measures += &format!(
                    "[[measures]]\nid = \"m{}\"\ntype = \"radiancemeter\"\norigin = [0.0, 0.0, 0.0]\ndirection = [{:?}, {:?}, {:?}]\nspp = 160000\n",
                    refs.len(),
                    look.x,
                    look.y,
                    look.z
                );
                refs.push((mu, phi, i[k] / mu0, -q[k] / mu0, -u[k] / mu0));
            }
        }
        let text = format!(
            "seed = 12\npolarized = true\n[spectral]\nwavelengths = [550.0]\n[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = {tau}\n\
             [surface]\ntype = \"lambertian\"\nreflectance = {albedo}\n[illumination]\ntype = \"directional\"\nzenith = {:?}\nazimuth = 0.0\n{measures}",
            f64::acos(mu0).to_degrees()
        );
        let rows = run_rows(&experiment(&text));
        let mut cmps = Vec::new();
        for (r, (mu, phi, i, q, u)) in rows.iter().zip(&refs) {
            for (name, x, reference) in [("I", r.brf, i), ("Q", r.brf_q, q), ("U", r.brf_u, u)] {
                let (v, e) = x.unwrap();
                cmps.push(Cmp {
                    label: format!("{name} mu {mu} phi {phi}"),
                    reference: *reference,
                    value: v,
                    stderr: e,
                });
            }
        }
        if let Err(e) = check_all(
            &format!("Natraj 2009 DN tau={tau} A={albedo} mu0={mu0}"),
            &cmps,
        ) {
            errs.push(e);
        }
    }
    assert!(errs.is_empty(), "{}", errs.join("\n"));
}
