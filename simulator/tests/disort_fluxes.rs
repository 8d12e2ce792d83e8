//! Hemispherical fluxes against DISORT (issue 17 item 5): upwelling, direct downwelling and
//! diffuse downwelling flux at the top, middle and bottom of one homogeneous layer, on the
//! shared case A set (conservative Rayleigh, τ 0.1 and 0.5, Lambertian 0 and 0.3, SZA 30° and
//! 60°) and an absorbing Henyey–Greenstein layer (τ 1, ω 0.9, g 0.7, Lambertian 0.2), from
//! `tests/data/disort/fluxes.csv` (`tools/disort_reference/fluxes.py`: cdisort, 128 streams,
//! fluxes only, converged to 2e-9 against 96 streams).
//!
//! Rationale: DISORT's fluxes are deterministic solutions of the same plane-parallel problem.
//! The direct part is closed form in both codes, so it must agree to rounding (1e-12); the
//! upwelling and diffuse downwelling fluxes are Monte Carlo estimates and must agree within
//! `common::check_all` (|diff| ≤ 4.5σ + max(1e-5, 2e-4·ref)). Both estimators are tested: the
//! forward one (expected level crossings) and the backward one (cosine-distributed paths
//! from the level); the spherical-shell backward walk with an overhead Sun is checked against
//! the plane-parallel one at the surface of a 1 km layer, where curvature does not matter (see
//! that test). Values compared are fluxes / (E0 cos SZA), E0 = 1.

mod common;
use common::*;

struct RefRow {
    case: String,
    tau: f64,
    ssa: f64,
    g: Option<f64>,
    albedo: f64,
    sza: f64,
    altitude_km: f64,
    quantity: String,
    value: f64,
}

fn load() -> Vec<RefRow> {
    let text = std::fs::read_to_string(data_dir().join("disort/fluxes.csv")).unwrap();
    text.lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let p = |i: usize| f[i].parse::<f64>().unwrap();
            RefRow {
                case: f[0].to_string(),
                tau: p(1),
                ssa: p(2),
                g: (!f[3].is_empty()).then(|| p(3)),
                albedo: p(4),
                sza: p(5),
                altitude_km: p(7),
                quantity: f[8].to_string(),
                value: p(9),
            }
        })
        .collect()
}

const LEVELS_KM: [f64; 3] = [100.0, 50.0, 0.0];

/// An experiment with an upwelling and a downwelling flux measure at each level.
fn experiment_text(r: &RefRow, integrator: &str, spp: u64, planet: bool) -> String {
    let phase = match r.g {
        Some(g) => format!("{{ type = \"hg\", g = {g:?} }}"),
        None => "{ type = \"rayleigh\" }".to_string(),
    };
    let mut measures = String::new();
    for z in LEVELS_KM {
        for dir in ["up", "down"] {
            let zi = z as i64;
            measures += &format!(
                "[[measures]]\ntype = \"distant_flux\"\nid = \"{dir}{zi}\"\naltitude = {z:?}\ndirection = \"{dir}\"\nspp = {spp}\n"
            );
        }
    }
    let geometry = if planet {
        "[geometry]\ntype = \"spherical_shell\"\n"
    } else {
        ""
    };
    format!(
        r#"
seed = 77
{geometry}[spectral]
wavelengths = [550.0]
[atmosphere]
type = "homogeneous"
optical_thickness = {tau:?}
single_scattering_albedo = {ssa:?}
phase = {phase}
[surface]
type = "lambertian"
reflectance = {albedo:?}
[illumination]
type = "directional"
zenith = {sza:?}
azimuth = 0.0
[integrator]
type = "{integrator}"
{measures}"#,
        tau = r.tau,
        ssa = r.ssa,
        albedo = r.albedo,
        sza = r.sza,
    )
}

/// Which part of a flux row a reference row compares with.
type Part = fn(&simulator::products::Row) -> (f64, f64);

fn run_case(all: &[RefRow], case: &str, integrator: &str, spp: u64) -> Result<(), String> {
    let refs: Vec<&RefRow> = all.iter().filter(|r| r.case == case).collect();
    let first = refs[0];
    let exp = experiment(&experiment_text(first, integrator, spp, false));
    let out = run_rows_light_tailed(&exp);
    let mu0 = first.sza.to_radians().cos();
    let mut cmps = Vec::new();
    let mut direct_err: f64 = 0.0;
    for r in &refs {
        let (id, get): (String, Part) = match r.quantity.as_str() {
            "up" => (format!("up{}", r.altitude_km as i64), |o| o.flux.unwrap()),
            "down_direct" => (format!("down{}", r.altitude_km as i64), |o| {
                o.flux_direct.unwrap()
            }),
            "down_diffuse" => (format!("down{}", r.altitude_km as i64), |o| {
                o.flux_diffuse.unwrap()
            }),
            q => panic!("unknown quantity {q}"),
        };
        let row = out.iter().find(|o| o.measure == id).unwrap();
        let (v, e) = get(row);
        let (v, e) = (v / mu0, e / mu0);
        if r.quantity == "down_direct" {
            assert_eq!(e, 0.0, "the direct flux is exact");
            direct_err = direct_err.max((v - r.value).abs());
            continue;
        }
        // total = direct + diffuse, and albedo = flux / (E0 cos SZA).
        let (f, _) = row.flux.unwrap();
        let (a, _) = row.albedo.unwrap();
        let (dd, _) = row.flux_direct.unwrap();
        let (df, _) = row.flux_diffuse.unwrap();
        assert!((f - dd - df).abs() <= 1e-12 * f.abs().max(1.0));
        assert!((a * mu0 - f).abs() <= 1e-12 * f.abs().max(1.0));
        cmps.push(Cmp {
            label: format!("{} at {} km", r.quantity, r.altitude_km),
            reference: r.value,
            value: v,
            stderr: e,
        });
    }
    // The table holds 11 significant digits.
    assert!(
        direct_err < 1e-9,
        "{case}: direct flux off by {direct_err:e}"
    );
    check_all(&format!("fluxes {case} [{integrator}]"), &cmps)
}

fn case_ids(all: &[RefRow]) -> Vec<String> {
    let mut ids: Vec<String> = Vec::new();
    for r in all {
        if !ids.contains(&r.case) {
            ids.push(r.case.clone());
        }
    }
    ids
}

#[test]
fn forward_fluxes_match_disort() {
    let all = load();
    let errs: Vec<String> = case_ids(&all)
        .iter()
        .filter_map(|c| run_case(&all, c, "forward", 1_000_000).err())
        .collect();
    assert!(errs.is_empty(), "{}", errs.join("\n"));
}

#[test]
fn backward_fluxes_match_disort() {
    let all = load();
    let errs: Vec<String> = case_ids(&all)
        .iter()
        .filter_map(|c| run_case(&all, c, "backward", 300_000).err())
        .collect();
    assert!(errs.is_empty(), "{}", errs.join("\n"));
}

/// Spherical shells, overhead Sun: the direct beam is exactly the plane-parallel one, and the
/// diffuse downwelling flux at the surface agrees with DISORT within its standard error plus
/// 0.5 % (the sphericity of a 100 km thick layer: diffuse light arrives along slant paths).
/// The spherical-shell backward walk against the plane-parallel one, with an overhead Sun, in a
/// layer thin enough (1 km) that the planet's curvature does not matter: the slant path to the
/// top of the layer at 5° elevation is 1.2 % shorter over the sphere, and the flux-weighted
/// effect is below 0.1 %. (In the 100 km layer of the DISORT cases it does matter: there the
/// sphere's diffuse flux at the ground is 1.7 % lower, 0.2642 against 0.2687 with 400 000
/// samples each, as the line of sight at 10–30° elevation is 3–18 % shorter.)
///
/// Also the exact identity of a Lambertian ground: the upwelling flux leaving it is `ρ` times
/// the downwelling flux reaching it (direct + diffuse). Paths that start on the ground and look
/// down once flew through the planet (an upwelling flux 3× too high); `SphericalShell::exit` now
/// crosses the ground at once.
#[test]
fn spherical_fluxes_match_plane_parallel_in_a_thin_layer() {
    let text = experiment_text(
        &RefRow {
            case: String::new(),
            tau: 0.5,
            ssa: 1.0,
            g: None,
            albedo: 0.3,
            sza: 0.0,
            altitude_km: 0.0,
            quantity: String::new(),
            value: 0.0,
        },
        "backward",
        100_000,
        true,
    );
    // Only the measures at the ground, in a 1 km layer.
    let cut = text.find("[[measures]]").unwrap();
    let mut text = text[..cut].to_string();
    for dir in ["up", "down"] {
        text += &format!(
            "[[measures]]\ntype = \"distant_flux\"\nid = \"{dir}0\"\naltitude = 0.0\ndirection = \"{dir}\"\nspp = 100000\n"
        );
    }
    let sph = text.replace(
        "[geometry]\ntype = \"spherical_shell\"\n",
        "[geometry]\ntype = \"spherical_shell\"\ntoa_altitude = 1.0\n",
    );
    let plane = text.replace(
        "[geometry]\ntype = \"spherical_shell\"\n",
        "[geometry]\ntype = \"plane_parallel\"\ntoa_altitude = 1.0\n",
    );
    assert_ne!(sph, plane);
    let sph = run_rows(&experiment(&sph));
    let pp = run_rows(&experiment(&plane));
    let at = |rows: &[simulator::products::Row], id: &str| {
        rows.iter().find(|r| r.measure == id).unwrap().clone()
    };
    let (s, p) = (at(&sph, "down0"), at(&pp, "down0"));
    let (sd, pd) = (s.flux_direct.unwrap().0, p.flux_direct.unwrap().0);
    assert!((sd - (-0.5f64).exp()).abs() < 1e-9, "direct {sd}");
    assert!((pd - (-0.5f64).exp()).abs() < 1e-12, "direct {pd}");
    let ((sv, se), (pv, pe)) = (s.flux_diffuse.unwrap(), p.flux_diffuse.unwrap());
    let tol = 4.5 * (se * se + pe * pe).sqrt() + 0.002 * pv;
    println!(
        "spherical vs plane-parallel diffuse down at BOA: {sv:.5} ± {se:.1e} vs {pv:.5} ± {pe:.1e}"
    );
    assert!((sv - pv).abs() < tol, "{sv} vs {pv} (tol {tol})");
    for (name, rows) in [("spherical", &sph), ("plane-parallel", &pp)] {
        let (up, ue) = at(rows, "up0").flux.unwrap();
        let (down, de) = at(rows, "down0").flux.unwrap();
        let tol = 4.5 * (ue * ue + 0.09 * de * de).sqrt() + 1e-4;
        println!(
            "{name}: up at the ground {up:.5} ± {ue:.1e}, 0.3 × down {:.5}",
            0.3 * down
        );
        assert!(
            (up - 0.3 * down).abs() < tol,
            "{name}: up {up} vs 0.3 × {down} (tol {tol})"
        );
    }
}
