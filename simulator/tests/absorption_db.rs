//! Gas absorption from axsdb databases in runs (`atmosphere.absorption_data` = a database
//! directory): per-layer optical thicknesses from the profile's (p, T, x), Gauss–Legendre
//! g-points, rescaled columns, user and netCDF profiles. Each test states its rationale. Needs the
//! shared data folder (`ckd/axsdb/`); skips with a message when it is absent.
//!
//! The closed form used: with `rayleigh = false` and no particles the atmosphere only absorbs,
//! so over a Lambertian surface of reflectance ρ the TOA BRF of a CKD bin is exactly
//! ρ·Σ_g w_g·exp(−τ_g·(1/μ0 + 1/μv)). The test computes τ_g itself — the database's k at the
//! profile's levels (the netCDF profile, 1 km levels, so they coincide with the 1 km layers),
//! integrated by the trapezoid rule, with the 16-point Gauss–Legendre weights — and compares
//! with the Monte Carlo value by the suite's z-test (`common::check_all`).

mod common;

use std::path::{Path, PathBuf};

use common::{check_all, experiment, run_rows, Cmp};
use engine::absorption::{
    gauss_legendre_unit, AtmosphereProfile, AxsDatabase, BoundsPolicy, OutOfRange, SpectralPoint,
};
use engine::config::Experiment;

fn shared(sub: &str) -> Option<PathBuf> {
    let p = std::env::var_os("SIMULATOR_SHARED_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data"))
        .join(sub);
    if p.exists() {
        Some(p)
    } else {
        eprintln!("skipped: {} is absent", p.display());
        None
    }
}

const SZA: f64 = 30.0;
const VZA: [f64; 2] = [0.0, 40.0];

fn text(db: &Path, profile: &str, wavelengths: &[f64], extra: &str, seed: u64) -> String {
    format!(
        "mode = \"ckd\"\nseed = {seed}\n[spectral]\nwavelengths = {wavelengths:?}\n\
         [atmosphere]\ntype = \"molecular\"\nrayleigh = false\nprofile = \"{profile}\"\n\
         absorption_data = \"{}\"\n{extra}\
         [surface]\ntype = \"lambertian\"\nreflectance = 1.0\n\
         [illumination]\ntype = \"directional\"\nzenith = {SZA:?}\n\
         [[measures]]\nid = \"toa\"\ntype = \"mdistant\"\nconstruct = \"directions\"\n\
         zeniths = {VZA:?}\nazimuths = [0.0, 90.0]\nspp = 8192\n",
        db.display()
    )
}

/// The run's default out-of-range policy (`atmosphere.absorption_bounds`).
fn default_bounds() -> BoundsPolicy {
    BoundsPolicy {
        pressure: OutOfRange::Zero,
        temperature: OutOfRange::Clamp,
        mole_fraction: OutOfRange::Error,
    }
}

/// Column optical thickness 0–100 km of the database at `at`: k at the profile's levels
/// (1 km apart) by the trapezoid rule, the O3 mole fraction scaled by `o3_factor`.
fn column_tau(
    db: &AxsDatabase,
    prof: &AtmosphereProfile,
    at: SpectralPoint,
    o3_factor: f64,
) -> f64 {
    let z = &prof.altitude_m;
    let top = z.iter().position(|&v| v >= 100e3).unwrap();
    let mut tau = 0.0;
    let mut prev = None;
    for (i, &zi) in z.iter().enumerate().take(top + 1) {
        let lvl = prof.level(i);
        let mf: Vec<(&str, f64)> = lvl
            .mole_fractions
            .iter()
            .map(|&(s, x)| (s, if s == "O3" { x * o3_factor } else { x }))
            .collect();
        let state = engine::absorption::ThermoState {
            pressure_pa: lvl.pressure_pa,
            temperature_k: lvl.temperature_k,
            mole_fractions: &mf,
        };
        let k = db
            .absorption_coefficient(&state, at, default_bounds())
            .unwrap();
        if let Some((z0, k0)) = prev {
            tau += 0.5 * (k + k0) * (zi - z0);
        }
        prev = Some((zi, k));
    }
    tau
}

/// Σ_g w_g exp(−τ_g m) with τ_g from [`column_tau`], the O3 mole fraction scaled by
/// `o3_factor`.
fn closed_form(db: &AxsDatabase, prof: &AtmosphereProfile, wl: f64, o3_factor: f64) -> [f64; 2] {
    let bin = db.bin_containing(wl).unwrap();
    let mut out = [0.0; 2];
    for (g, w) in gauss_legendre_unit(16) {
        let tau = column_tau(db, prof, SpectralPoint::Ckd { bin, g }, o3_factor);
        for (k, vza) in VZA.iter().enumerate() {
            let m = 1.0 / SZA.to_radians().cos() + 1.0 / vza.to_radians().cos();
            out[k] += w * (-tau * m).exp();
        }
    }
    out
}

fn compare(case: &str, exp: &Experiment, wl: &[f64], want: &dyn Fn(f64) -> [f64; 2]) {
    let rows = run_rows(exp);
    let mut cmps = Vec::new();
    for (iw, &w) in wl.iter().enumerate() {
        let r = want(w);
        for k in 0..2 {
            let row = &rows[iw * 2 + k];
            assert_eq!(row.wavelength_nm, w);
            let (v, e) = row.brf.unwrap();
            cmps.push(Cmp {
                label: format!("{w} nm vza {}", VZA[k]),
                reference: r[k],
                value: v,
                stderr: e,
            });
        }
    }
    check_all(case, &cmps).unwrap();
}

/// An absorbing-only US standard atmosphere over a white surface, in four bins of the Huggins
/// ozone band (305–355 nm; the bins hold O3, H2O and CO2 dimensions): the run equals the closed
/// form for every bin and direction. The absorption must matter (BRF well below 1 at 310 nm).
#[test]
fn ckd_database_run_equals_the_closed_form() {
    let (Some(dbdir), Some(profile)) = (
        shared("ckd/axsdb/nanockd_v1"),
        shared("ckd/axsdb/afgl_1986-us_standard.nc"),
    ) else {
        return;
    };
    let db = AxsDatabase::open(&dbdir).unwrap();
    let prof = AtmosphereProfile::open(&profile).unwrap();
    let wl = [310.0, 320.0, 330.0, 350.0, 380.0];
    let exp = experiment(&text(&dbdir, &profile.display().to_string(), &wl, "", 3));
    let want = |w: f64| closed_form(&db, &prof, w, 1.0);
    assert!(want(310.0)[0] < 0.3, "310 nm: {:?}", want(310.0));
    compare("axsdb CKD closed form", &exp, &wl, &want);
}

/// `rescale = { O3 = 1.25 }` scales the ozone mole fraction at every level: the run equals the
/// closed form with scaled x_O3 (the database interpolates in x_O3), and differs from the
/// unscaled one by many standard errors. `"431 DU"` (1.25 times the profile's 345 DU) gives the
/// same optical thicknesses to 1e-9. Doubling would exceed the database's x_O3 grid (1e-5): that
/// is an error naming the altitude and the file.
#[test]
fn rescaled_ozone_column() {
    let (Some(dbdir), Some(profile)) = (
        shared("ckd/axsdb/nanockd_v1"),
        shared("ckd/axsdb/afgl_1986-us_standard.nc"),
    ) else {
        return;
    };
    let db = AxsDatabase::open(&dbdir).unwrap();
    let prof = AtmosphereProfile::open(&profile).unwrap();
    let wl = [320.0];
    let p = profile.display().to_string();
    let exp = experiment(&text(&dbdir, &p, &wl, "rescale = { O3 = 1.25 }\n", 5));
    let want = |w: f64| closed_form(&db, &prof, w, 1.25);
    assert!(want(320.0)[0] < closed_form(&db, &prof, 320.0, 1.0)[0] - 0.02);
    compare("axsdb CKD, O3 x1.25", &exp, &wl, &want);

    let du = prof.column_density_m2("O3").unwrap() / engine::atmosphere::thermo::DOBSON_UNIT;
    let by_du = experiment(&text(
        &dbdir,
        &p,
        &wl,
        &format!("rescale = {{ O3 = \"{} DU\" }}\n", 1.25 * du),
        5,
    ));
    let a = &exp.optics[0].g_states;
    let b = &by_du.optics[0].g_states;
    assert_eq!(a.len(), 16);
    for (x, y) in a.iter().zip(b) {
        let (tx, ty) = (x.1.atmosphere.total_tau(), y.1.atmosphere.total_tau());
        assert!((tx / ty - 1.0).abs() < 1e-9, "{tx} {ty}");
    }
    let e = Experiment::from_str(
        &text(&dbdir, &p, &wl, "rescale = { O3 = 2.0 }\n", 5),
        Path::new("/tmp/x.toml"),
    )
    .err()
    .unwrap()
    .to_string();
    assert!(e.contains("x_O3") && e.contains("km (p ="), "{e}");
}

/// `spectral.g_points` sets the Gauss–Legendre rule: 4 points give weights summing to 1 and a
/// bin transmittance within the database's own `error` table for 4 points of the 16-point value
/// (×3 margin: our path is two-way and our g-interpolation is linear, as axsdb's).
#[test]
fn configurable_g_points() {
    let (Some(dbdir), Some(profile)) = (
        shared("ckd/axsdb/nanockd_v1"),
        shared("ckd/axsdb/afgl_1986-us_standard.nc"),
    ) else {
        return;
    };
    let p = profile.display().to_string();
    let t = |ng: usize| {
        let exp = experiment(
            &text(&dbdir, &p, &[350.0], "", 1)
                .replace("[atmosphere]", &format!("g_points = {ng}\n[atmosphere]")),
        );
        let gs = &exp.optics[0].g_states;
        assert_eq!(gs.len(), ng);
        let wsum: f64 = gs.iter().map(|g| g.0).sum();
        assert!((wsum - 1.0).abs() < 1e-12);
        gs.iter()
            .map(|(w, s)| w * (-s.atmosphere.total_tau()).exp())
            .sum::<f64>()
    };
    let (t4, t16) = (t(4), t(16));
    let db = AxsDatabase::open(&dbdir).unwrap();
    let bin = db.bin_containing(350.0).unwrap();
    let err4 = db
        .quadrature_error(bin)
        .unwrap()
        .and_then(|e| e.iter().find(|(n, _)| *n == 4).map(|x| x.1))
        .unwrap();
    println!("350 nm bin: T(4) = {t4:.6e}, T(16) = {t16:.6e}, file error(4) = {err4:.3e}");
    assert!(((t4 - t16) / t16).abs() <= 3.0 * err4.abs() + 1e-6);
}

/// A user CSV profile, written here from the embedded AFGL US standard tables (z, p in hPa, T,
/// H2O and O3 in ppmv, CO2 and O2 from table 2a), gives the embedded profile's gas optical
/// thicknesses to 1e-12 (the CSV path parses units from the column names). The Libya-4 CAMS
/// netCDF profile runs (to 60 km: it ends at 65.6 km) and its own ozone and hot surface give a
/// 320 nm transmittance different from the US standard one by many standard errors.
#[test]
fn user_and_cams_profiles() {
    let (Some(dbdir), Some(cams)) = (
        shared("ckd/axsdb/nanockd_v1"),
        shared("eradiate/thermoprops/cams_lybia4_2005-04-01.nc"),
    ) else {
        return;
    };
    let dir = std::env::temp_dir().join(format!("absorption_db_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let csv = dir.join("profile.csv");
    let t1 = engine::atmosphere::molecular::PROFILES[5].1;
    let t2 = include_str!("../../engine/data/afgl_1986/table_2a.csv");
    let mut s = String::from("# AFGL US standard, from the embedded tables\nz_km,p_hpa,t_k,H2O_ppmv,O3_ppmv,N2O_ppmv,CO_ppmv,CH4_ppmv,CO2_ppmv,O2_ppmv\n");
    for (a, b) in t1.lines().skip(1).zip(t2.lines().skip(1)) {
        let a: Vec<&str> = a.split(',').collect();
        let b: Vec<&str> = b.split(',').collect();
        // table 1: z,p,t,n,H2O,O3,N2O,CO,CH4; table 2a: z,H2O,CO2,O3,N2O,CO,CH4,O2
        s += &format!(
            "{},{},{},{},{},{},{},{},{},{}\n",
            a[0], a[1], a[2], a[4], a[5], a[6], a[7], a[8], b[2], b[7]
        );
    }
    std::fs::write(&csv, s).unwrap();
    let exp = |profile: &str, seed: u64| {
        experiment(&text(&dbdir, profile, &[320.0], "", seed).replace(
            "[surface]",
            "[geometry]\ntype = \"plane_parallel\"\ntoa_altitude = 60.0\n[surface]",
        ))
    };
    let (user, us, cams_exp) = (
        exp(&csv.display().to_string(), 9),
        exp("afgl_1986-us_standard", 10),
        exp(&cams.display().to_string(), 11),
    );
    for (a, b) in user.optics[0].g_states.iter().zip(&us.optics[0].g_states) {
        let (ta, tb) = (a.1.atmosphere.total_tau(), b.1.atmosphere.total_tau());
        assert!((ta / tb - 1.0).abs() < 1e-12, "{ta} {tb}");
    }
    let brf = |e: &Experiment| run_rows(e)[0].brf.unwrap();
    let ((u, eu), (c, ec)) = (brf(&us), brf(&cams_exp));
    println!("320 nm nadir BRF: US standard {u:.5} ± {eu:.1e}, CAMS Libya-4 {c:.5} ± {ec:.1e}");
    assert!((c - u).abs() > 5.0 * (eu * eu + ec * ec).sqrt());
    let _ = std::fs::remove_dir_all(&dir);
}

/// `mode = "mono"` with an axsdb monochromatic database: each wavelength's gas optical thickness
/// is the database's k (linear in wavelength between its 8165 points) at the profile's levels,
/// integrated over the layers: equal to the test's own trapezoid sum to 1e-9. (The shared
/// `nanomono_v1` set holds O2, CO2, CH4, H2, O near 350 nm, whose k is at most 2.2e-13 km⁻¹, so
/// the comparison is relative; the physics of the mono path is the CKD path's, tested above.)
#[test]
fn mono_database_layers() {
    let (Some(dbdir), Some(profile)) = (
        shared("ckd/axsdb/nanomono_v1"),
        shared("ckd/axsdb/afgl_1986-us_standard.nc"),
    ) else {
        return;
    };
    let db = AxsDatabase::open(&dbdir).unwrap();
    let prof = AtmosphereProfile::open(&profile).unwrap();
    let wl = [345.5, 350.0, 354.9];
    let exp = experiment(
        &text(&dbdir, &profile.display().to_string(), &wl, "", 1).replace("\"ckd\"", "\"mono\""),
    );
    for (iw, &w) in wl.iter().enumerate() {
        let tau = column_tau(&db, &prof, SpectralPoint::Mono { wavelength_nm: w }, 1.0);
        let got = exp.optics[iw].atmosphere.total_tau();
        println!("{w} nm: gas tau {got:.6e} (test {tau:.6e})");
        assert!(
            tau > 0.0 && (got / tau - 1.0).abs() < 1e-9,
            "{w}: {got} vs {tau}"
        );
    }
}

/// Bad input names the key: the v0 file with another profile or a rescaled one, `g_points` with
/// the v0 file, a CKD database in mono mode, a pressure policy of "error" (names the
/// altitude), an unknown policy, a rescaled species the profile lacks, a missing profile file, a
/// depolarization out of range.
#[test]
fn bad_absorption_input_is_named() {
    let (Some(dbdir), Some(v0)) = (
        shared("ckd/axsdb/nanockd_v1"),
        shared("ckd/eradiate_v0_ckd/afgl1986-us_standard-10nm.nc"),
    ) else {
        return;
    };
    let err = |t: String| {
        Experiment::from_str(&t, Path::new("/tmp/x.toml"))
            .err()
            .unwrap_or_else(|| panic!("accepted:\n{t}"))
            .to_string()
    };
    let base = |db: &Path, profile: &str, extra: &str| text(db, profile, &[760.0], extra, 1);
    for (t, want) in [
        (
            base(&v0, "afgl_1986-tropical", ""),
            "cannot describe profile",
        ),
        (
            base(&v0, "afgl_1986-us_standard", "rescale = { O3 = 1.1 }\n"),
            "or a rescaled one",
        ),
        (
            base(&v0, "afgl_1986-us_standard", "")
                .replace("[atmosphere]", "g_points = 8\n[atmosphere]"),
            "spectral.g_points",
        ),
        (
            text(&dbdir, "afgl_1986-us_standard", &[320.0], "", 1).replace("\"ckd\"", "\"mono\""),
            "use it with mode = \"ckd\"",
        ),
        (
            text(
                &dbdir,
                "afgl_1986-us_standard",
                &[320.0],
                "absorption_bounds = { pressure = \"error\" }\n",
                1,
            ),
            "km (p =",
        ),
        (
            text(
                &dbdir,
                "afgl_1986-us_standard",
                &[320.0],
                "absorption_bounds = { pressure = \"ignore\" }\n",
                1,
            ),
            "atmosphere.absorption_bounds.pressure",
        ),
        (
            text(
                &dbdir,
                "afgl_1986-us_standard",
                &[320.0],
                "rescale = { NH3 = 2.0 }\n",
                1,
            ),
            "atmosphere.rescale.NH3",
        ),
        (
            text(&dbdir, "nope.csv", &[320.0], "", 1),
            "atmosphere.profile",
        ),
        (
            text(
                &dbdir,
                "afgl_1986-us_standard",
                &[320.0],
                "depolarization = 0.7\n",
                1,
            ),
            "atmosphere.depolarization",
        ),
    ] {
        let e = err(t);
        assert!(e.contains(want), "expected `{want}` in: {e}");
    }
}

/// RRTMGP's shortwave k-distribution in runs (`absorption_data` = the RRTMGP gas-optics file):
/// each wavelength takes the g-points of the RRTMGP band holding it, weighted by the band's
/// solar source; over a white surface under an absorbing-only US standard atmosphere the run
/// equals Σ_g w_g exp(−τ_g(1/μ0 + 1/μv)) with the column τ_g from `Rrtmgp` (whose kernels are
/// tested in `absorption::rrtmgp` against the v0 file and published columns). A sensor band is
/// sampled every `wavelength_step` nm (RRTMGP bands are wider than sensor bands).
#[test]
fn rrtmgp_run_equals_the_closed_form() {
    let Some(file) = shared("ckd/rrtmgp/rrtmgp-gas-sw-g224.nc") else {
        return;
    };
    let rr = engine::absorption::Rrtmgp::open(&file).unwrap();
    let thermo = engine::atmosphere::thermo::load("afgl_1986-us_standard", Path::new(".")).unwrap();
    let grid: Vec<(f64, f64)> = (0..100)
        .map(|i| (i as f64 * 1e3, (i + 1) as f64 * 1e3))
        .collect();
    let wl = [700.0, 940.0, 1600.0];
    let exp = experiment(&text(&file, "afgl_1986-us_standard", &wl, "", 13));
    let bands = rr.bands_nm();
    let want = |w: f64| {
        let b = bands
            .iter()
            .position(|&(lo, hi)| lo <= w && w < hi)
            .unwrap();
        let taus = rr.layer_optical_thickness(&thermo.gas, &grid, b).unwrap();
        let weights = rr.solar_weights(b).unwrap();
        let mut out = [0.0; 2];
        for (t, wg) in taus.iter().zip(&weights) {
            let tau: f64 = t.iter().sum();
            for (k, vza) in VZA.iter().enumerate() {
                let m = 1.0 / SZA.to_radians().cos() + 1.0 / vza.to_radians().cos();
                out[k] += wg * (-tau * m).exp();
            }
        }
        out
    };
    assert!(want(940.0)[0] < 0.9, "{:?}", want(940.0));
    compare("RRTMGP closed form", &exp, &wl, &want);
    let band = experiment(
        &text(&file, "afgl_1986-us_standard", &[665.0], "", 1).replace(
            "wavelengths = [665.0]",
            "srf = \"sentinel_2a-msi-4\"\nwavelength_step = 5.0",
        ),
    );
    assert!(band.wavelengths.len() >= 7, "{:?}", band.wavelengths);
}

/// Ozone continuum from a cross-section table (`[[atmosphere.cross_sections]]`): an absorbing-only
/// US standard atmosphere (no Rayleigh, no database) over a white surface, at the table's 525,
/// 600, 675 nm nodes and between them. The closed form ρ·exp(−σ(λ)·N·(1/μ0 + 1/μv)) takes σ from
/// the file read here (linear between nodes, cm² → m²) and the O3 column N over 0–100 km by the
/// trapezoid rule over the profile's levels (exact for x·n linear between levels). Bad input:
/// a wavelength outside the table and an unknown species name their key.
#[test]
fn ozone_continuum_from_cross_sections() {
    let Some(file) = shared("spherical_limb_zawada2021/inputs/xsection_rayleigh_ozone.txt") else {
        return;
    };
    let rows: Vec<(f64, f64)> = std::fs::read_to_string(&file)
        .unwrap()
        .lines()
        .filter(|l| !l.trim_start().starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let c: Vec<f64> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            (c[0], c[2] * 1e-4)
        })
        .collect();
    let sigma = |w: f64| {
        let i = rows.iter().rposition(|r| r.0 <= w).unwrap();
        if rows[i].0 == w {
            return rows[i].1;
        }
        let (a, b) = (rows[i], rows[i + 1]);
        a.1 + (b.1 - a.1) * (w - a.0) / (b.0 - a.0)
    };
    let th = engine::atmosphere::thermo::load("afgl_1986-us_standard", Path::new(".")).unwrap();
    let (z, x, n) = (
        &th.gas.altitude_m,
        th.gas.mole_fraction("O3").unwrap(),
        th.gas.air_number_density(),
    );
    let mut column = 0.0;
    for i in 1..z.len() {
        if z[i] <= 100e3 + 1e-6 {
            column += 0.5 * (x[i] * n[i] + x[i - 1] * n[i - 1]) * (z[i] - z[i - 1]);
        }
    }
    let wl = [525.0, 600.0, 640.0, 675.0];
    let body = |wavelengths: &str, species: &str| {
        format!(
            "seed = 5\n[spectral]\nwavelengths = {wavelengths}\n\
             [atmosphere]\ntype = \"molecular\"\nrayleigh = false\nprofile = \"afgl_1986-us_standard\"\n\
             [[atmosphere.cross_sections]]\nspecies = \"{species}\"\nfile = \"{}\"\ncolumn = 3\n\
             [surface]\ntype = \"lambertian\"\nreflectance = 1.0\n\
             [illumination]\ntype = \"directional\"\nzenith = {SZA:?}\n\
             [[measures]]\nid = \"toa\"\ntype = \"mdistant\"\nconstruct = \"directions\"\n\
             zeniths = {VZA:?}\nazimuths = [0.0, 90.0]\nspp = 4096\n",
            file.display()
        )
    };
    let exp = experiment(&body(&format!("{wl:?}"), "O3"));
    let want = |w: f64| {
        let tau = sigma(w) * column;
        let mut out = [0.0; 2];
        for (k, vza) in VZA.iter().enumerate() {
            let m = 1.0 / SZA.to_radians().cos() + 1.0 / vza.to_radians().cos();
            out[k] = (-tau * m).exp();
        }
        out
    };
    // The Chappuis band matters: τ(600 nm) ≈ 0.05 for ~345 DU.
    assert!((0.04..0.06).contains(&(sigma(600.0) * column)));
    compare("O3 continuum closed form", &exp, &wl, &want);
    // Outside the table: an error by default, no absorption with `outside = "zero"`.
    let with = |t: String, line: &str| t.replace("column = 3\n", &format!("column = 3\n{line}\n"));
    let zero = experiment(&with(body("[1800.0]", "O3"), "outside = \"zero\""));
    assert_eq!(zero.optics[0].atmosphere.total_tau(), 0.0);
    for (text, key) in [
        (body("[1800.0]", "O3"), "atmosphere.cross_sections[0].file"),
        (
            body("[600.0]", "O4"),
            "atmosphere.cross_sections[0].species",
        ),
        (
            with(body("[600.0]", "O3"), "outside = \"clamp\""),
            "atmosphere.cross_sections[0].outside",
        ),
    ] {
        let e = Experiment::from_str(&text, Path::new("x.toml"))
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(e.contains(key), "{e}");
    }
}
