//! Tabulated BRDFs (issue 14, item 3) against the model they were sampled from.
//!
//! Rationale: a table written from RPV on a fine grid (θ every 2°, Δφ every 5°, two wavelengths)
//! in the documented file layout is the same surface as RPV up to the interpolation error, so a
//! run over the table must reproduce the run over RPV: same experiment, different seeds, each
//! direction within 4.5 combined standard errors plus a small absolute floor (5·10⁻⁴ in BRF, for
//! the interpolation of the diffuse parts; the view and Sun angles lie on grid nodes, where the
//! table is exact). The walks sample the surface with the table's own sampler (backward) and
//! reflect photons with it (forward); the second wavelength lies between the table's two, so
//! the linear blend in wavelength is tested too (RPV is linear in ρ₀). The same holds for a
//! bundle material whose table lies in the bundle's folder (3D scene walk).

mod common;
use common::bundles::{flat_plane, tmp, write_plane};
use common::*;

use std::path::Path;

use engine::bsdf::Rpv;
use engine::bundle::*;
use engine::frame::direction_from_angles;

/// RPV parameters (ρ₀ at 500 and 700 nm; k, Θ, ρ_c).
const RHO_0: [f64; 2] = [0.1, 0.3];
const K_G_RHOC: (f64, f64, f64) = (0.8, -0.2, 0.3);

/// Writes the RPV table at 500 and 700 nm (`engine::bsdf::tabulated::write_table`, the
/// documented layout).
fn write_rpv_table(path: &Path) {
    let models: Vec<Rpv> = RHO_0
        .iter()
        .map(|&r| Rpv::new(r, K_G_RHOC.0, K_G_RHOC.1, K_G_RHOC.2).unwrap())
        .collect();
    let theta: Vec<f64> = (0..=44).map(|k| 2.0 * k as f64).collect();
    let dphi: Vec<f64> = (0..=36).map(|k| 5.0 * k as f64).collect();
    let wl = [500.0, 700.0];
    engine::bsdf::tabulated::write_table(path, &wl, &theta, &theta, &dphi, |w, ti, tr, dp| {
        let m = &models[if w == wl[0] { 0 } else { 1 }];
        // dphi = φ_r − φ_i, 0 = backscattering (both directions at one azimuth).
        let wi = direction_from_angles(f64::to_radians(ti), 0.0);
        let wo = direction_from_angles(f64::to_radians(tr), f64::to_radians(dp));
        m.eval(wi, wo)
    })
    .unwrap();
}

/// |a − b| ≤ 4.5·√(σa² + σb²) + 5·10⁻⁴ for every row's BRF.
fn compare(case: &str, a: &[simulator::products::Row], b: &[simulator::products::Row]) {
    let mut bad = Vec::new();
    let mut worst_z: f64 = 0.0;
    for (x, y) in a.iter().zip(b) {
        let ((va, ea), (vb, eb)) = (x.brf.unwrap(), y.brf.unwrap());
        let se = (ea * ea + eb * eb).sqrt();
        worst_z = worst_z.max((va - vb).abs() / se);
        if (va - vb).abs() > K * se + 5e-4 {
            bad.push(format!(
                "  {} nm vza {:?} vaa {:?}: table {va:.5} ± {ea:.1e}, RPV {vb:.5} ± {eb:.1e}",
                x.wavelength_nm, x.vza, x.vaa
            ));
        }
    }
    println!("{case}: {} rows, max z = {worst_z:.2}", a.len());
    assert!(bad.is_empty(), "{case}:\n{}", bad.join("\n"));
}

const ATMOSPHERE: &str = "[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = 0.2\nphase = { type = \"rayleigh\" }\n";

#[test]
fn rpv_table_reproduces_rpv_1d() {
    let dir = tmp("tabulated-1d");
    let table = dir.join("rpv.nc");
    write_rpv_table(&table);
    let (mut vza, mut vaa) = (Vec::new(), Vec::new());
    for z in [0.0, 20.0, 40.0, 60.0, 70.0] {
        for a in [0.0, 90.0, 180.0] {
            vza.push(z);
            vaa.push(a);
        }
    }
    let rpv = format!(
        "[surface]\ntype = \"rpv\"\nrho_0 = [{:?}, {:?}]\nk = {:?}\ng = {:?}\nrho_c = {:?}\n",
        RHO_0[0],
        0.5 * (RHO_0[0] + RHO_0[1]),
        K_G_RHOC.0,
        K_G_RHOC.1,
        K_G_RHOC.2
    );
    let tab = format!(
        "[surface]\ntype = \"tabulated\"\nfile = \"{}\"\n",
        table.display()
    );
    for (integrator, spp) in [("backward", 40_000u64), ("forward", 400_000)] {
        let run = |surface: &str, seed: u64| {
            let text = format!(
                "seed = {seed}\n[spectral]\nwavelengths = [500.0, 600.0]\n{ATMOSPHERE}{surface}\
                 [illumination]\ntype = \"directional\"\nzenith = 30.0\nazimuth = 0.0\n\
                 [integrator]\ntype = \"{integrator}\"\n{}",
                mdistant_toml("toa", &vza, &vaa, spp)
            );
            let exp = experiment(&text);
            (run_rows(&exp), exp)
        };
        let (a, exp) = run(&tab, 3);
        let (b, _) = run(&rpv, 4);
        compare(&format!("RPV table = RPV [{integrator}]"), &a, &b);
        // The model reports its file and its reciprocity error (RPV: reciprocal, to rounding).
        let info = exp.optics[0].surface.info().unwrap();
        assert!(
            info.contains("rpv.nc") && info.contains("max reciprocity error"),
            "{info}"
        );
    }
}

/// A bundle material `tabulated` whose table the writer copied into the bundle (`brdf/rpv.nc`)
/// reproduces the same bundle with the RPV material (scene walk, 500 nm).
#[test]
fn rpv_table_reproduces_rpv_bundle_material() {
    let rpv = BrdfSpec::Rpv(RpvSpec {
        rho_0: Spectrum::Constant(RHO_0[0]),
        k: Spectrum::Constant(K_G_RHOC.0),
        g: Spectrum::Constant(K_G_RHOC.1),
        rho_c: Some(Spectrum::Constant(K_G_RHOC.2)),
    });
    // The writer copies the table into the bundle (`brdf/rpv.nc`) and hashes it.
    let table = tmp("tabulated-bundle-table").join("rpv.nc");
    write_rpv_table(&table);
    let tab = BrdfSpec::Tabulated(TabulatedSpec {
        file: table.to_string_lossy().into_owned(),
        symmetrize: false,
    });
    let mut rows = Vec::new();
    for (name, spec, seed) in [("rpv", rpv, 5u64), ("tab", tab, 6)] {
        let mut plane = flat_plane(2000.0, 0.0, -1000.0, 0.2);
        plane.materials[0].1 = spec;
        let b = write_plane(&tmp(&format!("tabulated-bundle-{name}")), &plane);
        if name == "tab" {
            assert!(b.join("brdf/rpv.nc").is_file());
        }
        let text = format!(
            "seed = {seed}\n[spectral]\nwavelengths = [500.0]\n{ATMOSPHERE}\
             [illumination]\ntype = \"directional\"\nzenith = 30.0\nazimuth = 0.0\n\
             [scene]\ntype = \"bundle\"\npath = \"{}\"\n{}target_m = [499000.0, 3999000.0, 501000.0, 4001000.0]\n",
            b.display(),
            mdistant_toml(
                "toa",
                &[0.0, 30.0, 30.0, 60.0, 60.0],
                &[0.0, 0.0, 180.0, 90.0, 180.0],
                40_000
            )
        );
        rows.push(run_rows(&experiment(&text)));
    }
    assert!(rows[1].iter().all(|r| r.method == "scene"));
    compare("RPV table = RPV (bundle material)", &rows[1], &rows[0]);
}

/// A missing file or variable is reported at `surface.file`, naming the file (and variable).
#[test]
fn bad_table_is_reported_at_the_key() {
    let dir = tmp("tabulated-bad");
    let head = "[spectral]\nwavelengths = [500.0]\n[illumination]\ntype = \"directional\"\nzenith = 30.0\n\
                [[measures]]\nid = \"toa\"\ntype = \"mdistant\"\nazimuth = 0.0\nzeniths = [0.0]\nspp = 100\n";
    let missing = dir.join("none.nc");
    let text = format!(
        "{head}[surface]\ntype = \"tabulated\"\nfile = \"{}\"\n",
        missing.display()
    );
    let e = engine::config::Experiment::from_str(&text, &dir.join("x.toml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("surface.file") && e.contains("none.nc"), "{e}");
    // A file without `brdf`.
    let partial = dir.join("partial.nc");
    {
        let _session = engine::netcdf_session();
        let mut nc = netcdf::create_with(&partial, netcdf::Options::_64BIT_OFFSET).unwrap();
        for name in ["wavelength", "theta_i", "theta_r", "dphi"] {
            nc.add_dimension(name, 1).unwrap();
            nc.add_variable::<f64>(name, &[name]).unwrap();
        }
        nc.enddef().unwrap();
        for (name, v) in [
            ("wavelength", 500.0),
            ("theta_i", 0.0),
            ("theta_r", 0.0),
            ("dphi", 0.0),
        ] {
            nc.variable_mut(name).unwrap().put_values(&[v], ..).unwrap();
        }
    }
    let text = format!("{head}[surface]\ntype = \"tabulated\"\nfile = \"partial.nc\"\n");
    let e = engine::config::Experiment::from_str(&text, &dir.join("x.toml"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("surface.file")
            && e.contains("partial.nc")
            && e.contains("missing variable `brdf`"),
        "{e}"
    );
}
