//! Polarized transport in 3D scenes: the backward estimator with a Mueller-matrix weight over a
//! scene geometry (no walk of its own, `integrator/backward.rs`).
//!
//! Rationale: a flat bundle of one Lambertian material whose background has the same material
//! and height is a uniform plane (or, bent onto a planet, a uniform sphere), so its area Stokes
//! vector at TOA must equal that of the 1D polarized walk over the same surface, for I, Q and U,
//! in every direction. The 1D reference uses the *forward* estimator in plane-parallel runs (a
//! different estimator and weight type than the scene's backward one) and the 1D backward
//! estimator in spherical shells. Runs use different seeds; the test is `common::check_all`
//! (|diff| ≤ 4.5σ + max(1e-5, 2e-4·|ref|), σ the combined standard error).
//!
//! The atmosphere is two layers: Rayleigh (strongly polarizing) over an HG aerosol layer.

mod common;

use common::bundles::{flat_plane, tmp, write_plane};
use common::{check_all, experiment, mdistant_toml, run_rows, Cmp};
use simulator::products::Row;

const ATMOSPHERE: &str = "[atmosphere]\ntype = \"layered\"\n\
    [[atmosphere.layers]]\nbottom = 2.0\ntop = 100.0\ntau_sca = 0.25\nphase = { type = \"rayleigh\" }\n\
    [[atmosphere.layers]]\nbottom = 0.0\ntop = 2.0\noptical_thickness = 0.2\nsingle_scattering_albedo = 0.9\nphase = { type = \"hg\", g = 0.7 }\n";

/// I, Q, U of two runs' rows compared direction by direction.
fn compare_stokes(case: &str, a: &[Row], b: &[Row]) -> Result<(), String> {
    assert_eq!(a.len(), b.len());
    let mut cmps = Vec::new();
    for (x, y) in a.iter().zip(b) {
        for (name, va, vb) in [
            ("I", x.brf, y.brf),
            ("Q", x.brf_q, y.brf_q),
            ("U", x.brf_u, y.brf_u),
        ] {
            let ((va, ea), (vb, eb)) = (va.unwrap(), vb.unwrap());
            cmps.push(Cmp {
                label: format!("{name} vza {:?} vaa {:?}", x.vza, x.vaa),
                reference: vb,
                value: va,
                stderr: (ea * ea + eb * eb).sqrt(),
            });
        }
    }
    check_all(case, &cmps)
}

/// Plane-parallel and spherical-shell geometries: flat polarized bundle = 1D polarized walk.
#[test]
fn flat_bundle_equals_1d_polarized_walk() {
    let b = write_plane(
        &tmp("pol-flat-bundle"),
        &flat_plane(2000.0, 0.0, -1000.0, 0.25),
    );
    let vza = [0.0, 30.0, 50.0, 60.0, 40.0];
    let vaa = [0.0, 0.0, 60.0, 180.0, 270.0];
    let mut errs = Vec::new();
    for (geometry, sza, spp) in [
        ("", 40.0, 400_000u64),
        (
            "[geometry]\ntype = \"spherical_shell\"\nplanet_radius = 6378.1\n",
            60.0,
            400_000,
        ),
    ] {
        let head = |seed: u64| {
            format!(
                "seed = {seed}\npolarized = true\n[spectral]\nwavelengths = [450.0]\n{geometry}{ATMOSPHERE}\
                 [illumination]\ntype = \"directional\"\nzenith = {sza:?}\nazimuth = 20.0\n"
            )
        };
        let m = mdistant_toml("toa", &vza, &vaa, spp);
        let e3 = experiment(&format!(
            "{}[scene]\ntype = \"bundle\"\npath = \"{}\"\n{m}target_m = [499000.0, 3999000.0, 501000.0, 4001000.0]\n",
            head(21),
            b.display(),
        ));
        let e1 = experiment(&format!(
            "{}[surface]\ntype = \"lambertian\"\nreflectance = 0.25\n{m}",
            head(22)
        ));
        let (r3, r1) = (run_rows(&e3), run_rows(&e1));
        assert!(
            r3.iter().all(|r| r.method == "scene"),
            "3D rows use the scene walk"
        );
        // The Rayleigh layer polarizes: |Q| is a sizeable fraction of I off nadir.
        let q_max = r1
            .iter()
            .map(|r| r.brf_q.unwrap().0.abs() / r.brf.unwrap().0)
            .fold(0.0, f64::max);
        assert!(q_max > 0.05, "the reference is hardly polarized ({q_max})");
        let case = format!("polarized flat bundle = 1D ({geometry:?} sza {sza})");
        println!("{case}: 1D max |Q|/I {q_max:.3}");
        if let Err(e) = compare_stokes(&case, &r3, &r1) {
            errs.push(e);
        }
    }
    assert!(errs.is_empty(), "{}", errs.join("\n"));
}

/// A polarized ortho image writes Q, U and DoLP GeoTIFF bands (and the netCDF variables), whose
/// values are the image products', and whose area means agree with the 1D walk at the ortho's
/// view direction.
#[test]
fn polarized_ortho_writes_stokes_bands() {
    let mut spec = flat_plane(2000.0, 0.0, -1000.0, 0.25);
    spec.wkt = gdal::spatial_ref::SpatialRef::from_epsg(32631)
        .unwrap()
        .to_wkt()
        .unwrap();
    let b = write_plane(&tmp("pol-ortho-bundle"), &spec);
    let head = |seed: u64| {
        format!(
            "seed = {seed}\npolarized = true\n[spectral]\nwavelengths = [450.0, 650.0]\n{ATMOSPHERE}\
             [illumination]\ntype = \"directional\"\nzenith = 45.0\nazimuth = 100.0\n"
        )
    };
    let e3 = experiment(&format!(
        "{}[scene]\ntype = \"bundle\"\npath = \"{}\"\n\
         [[measures]]\nid = \"img\"\ntype = \"ortho\"\npixel_size_m = 500.0\nzenith = 35.0\nazimuth = 280.0\nspp = 32768\n",
        head(31),
        b.display(),
    ));
    let out = tmp("pol-ortho-out");
    let _ = std::fs::remove_dir_all(&out);
    std::fs::create_dir_all(&out).unwrap();
    let res = simulator::run::run(&e3, false);
    let imgs = simulator::products::imagery::image_products(&e3, &res);
    let img = &imgs[0];
    let st = img
        .stokes
        .as_ref()
        .expect("polarized images carry Q, U, DoLP");
    let written = simulator::products::imagery::write_files(&out, &e3, img)
        .unwrap()
        .0;
    for name in ["q", "u", "dolp", "dolp_stderr"] {
        let path = out.join(format!("img_{name}.tif"));
        assert!(written.contains(&path), "{} not written", path.display());
        let ds = gdal::Dataset::open(&path).unwrap();
        assert_eq!(ds.raster_count(), 2, "{name}: one band per wavelength");
        let want = match name {
            "q" => &st.q,
            "u" => &st.u,
            "dolp" => &st.dolp,
            _ => &st.dolp_stderr,
        };
        for (k, w) in want.iter().enumerate() {
            let band = ds.rasterband(k + 1).unwrap();
            let buf = band
                .read_as::<f32>(
                    (0, 0),
                    (img.width, img.height),
                    (img.width, img.height),
                    None,
                )
                .unwrap();
            for (g, v) in buf.data().iter().zip(w) {
                assert!(
                    (*g as f64 - v).abs() <= 1e-6 * v.abs().max(1e-3),
                    "{name}: {g} vs {v}"
                );
            }
        }
    }
    // The image's mean Q and U agree with the 1D walk in the view direction.
    let m1 = mdistant_toml("toa", &[35.0], &[280.0], 200_000);
    let e1 = experiment(&format!(
        "{}[surface]\ntype = \"lambertian\"\nreflectance = 0.25\n{m1}",
        head(32)
    ));
    let r1 = run_rows(&e1);
    let mut cmps = Vec::new();
    for (iw, row) in r1.iter().enumerate() {
        let n = (img.width * img.height) as f64;
        for (name, img_vals, reference) in [
            ("I", &img.brf[iw], row.brf.unwrap()),
            ("Q", &st.q[iw], row.brf_q.unwrap()),
            ("U", &st.u[iw], row.brf_u.unwrap()),
        ] {
            let mean = img_vals.iter().sum::<f64>() / n;
            // Pixels are independent: the mean's variance is the mean of the variances / n;
            // Q and U standard errors are not stored per pixel, so use the pixels' scatter.
            let var = img_vals.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0) / n;
            cmps.push(Cmp {
                label: format!("{name} at {} nm", row.wavelength_nm),
                reference: reference.0,
                value: mean,
                stderr: (var + reference.1 * reference.1).sqrt(),
            });
        }
    }
    check_all("polarized ortho image mean = 1D", &cmps).unwrap();
}
