//! Correlated-k runs (`mode = "ckd"`): blocks of samples cycle through a bin's g-points, each
//! weighted by w_g·N_g. Each test states its rationale. Needs the shared data folder (the eradiate
//! v0 CKD file); skips with a message when it is absent.

mod common;

use std::path::Path;

use common::{check_all, experiment, run_rows, Cmp};

fn text(file: &Path, seed: u64, wavelength: f64, g_point: Option<usize>, spp: u64) -> String {
    let g = g_point.map_or(String::new(), |g| format!("g_point = {g}\n"));
    format!(
        "mode = \"ckd\"\nseed = {seed}\n[spectral]\nwavelengths = [{wavelength:?}]\n{g}\
         [atmosphere]\ntype = \"molecular\"\nlayer_thickness = 2.0\nabsorption_data = \"{}\"\n\
         [surface]\ntype = \"lambertian\"\nreflectance = 0.3\n\
         [illumination]\ntype = \"directional\"\nzenith = 40.0\n\
         [[measures]]\nid = \"toa\"\ntype = \"mdistant\"\nconstruct = \"directions\"\n\
         zeniths = [0.0, 50.0]\nazimuths = [0.0, 180.0]\nspp = {spp}\n",
        file.display()
    )
}

/// The CKD run of the O2 A-band bin (755–765 nm, 16 g-points spanning 7 decades of column
/// optical thickness) equals the quadrature Σ_g w_g·R_g of 16 independent runs with one g-point
/// each (z-test with the combined standard error): the stratified g-point sampling and its
/// weights are unbiased. The band is deep: the result must also be far below the neighbouring
/// 750 nm bin's.
#[test]
fn ckd_run_equals_the_g_point_quadrature() {
    let Some(file) = common::ckd_v0_file() else {
        eprintln!("skipped: shared data folder not found");
        return;
    };
    let full = run_rows(&experiment(&text(&file, 1, 760.0, None, 16 * 2048 * 8)));
    let db = engine::absorption::eradiate_v0::EradiateV0Ckd::open(&file, None).unwrap();
    let bin = db.bin_containing(760.0).unwrap();
    let (mut sum, mut var) = (vec![0.0; 2], vec![0.0; 2]);
    for g in 0..16 {
        let rows = run_rows(&experiment(&text(
            &file,
            100 + g as u64,
            760.0,
            Some(g),
            40_000,
        )));
        for (k, r) in rows.iter().enumerate() {
            let (v, e) = r.brf.unwrap();
            sum[k] += bin.weights[g] * v;
            var[k] += (bin.weights[g] * e).powi(2);
        }
    }
    let cmps: Vec<Cmp> = full
        .iter()
        .enumerate()
        .map(|(k, r)| {
            let (v, e) = r.brf.unwrap();
            Cmp {
                label: format!("vza {:?}", r.vza),
                reference: sum[k],
                value: v,
                stderr: (e * e + var[k]).sqrt(),
            }
        })
        .collect();
    check_all("CKD 760 nm = Σ w_g R_g", &cmps).unwrap();
    // The ALIS walk (one backward walk carrying all 16 g-points) against the same quadrature.
    let alis_text = text(&file, 7, 760.0, None, 400_000).replace(
        "[surface]",
        "[integrator]\ntype = \"backward\"\nckd_walk = \"alis\"\n[surface]",
    );
    let alis = run_rows(&experiment(&alis_text));
    let cmps: Vec<Cmp> = alis
        .iter()
        .enumerate()
        .map(|(k, r)| {
            let (v, e) = r.brf.unwrap();
            Cmp {
                label: format!("alis vza {:?}", r.vza),
                reference: sum[k],
                value: v,
                stderr: (e * e + var[k]).sqrt(),
            }
        })
        .collect();
    check_all("ALIS 760 nm = Σ w_g R_g", &cmps).unwrap();
    // Walks needed for equal noise: per-walk variance of the cycling estimator over ALIS's.
    let var_per_walk = |r: &simulator::products::Row| r.brf.unwrap().1.powi(2) * r.n_samples as f64;
    println!(
        "per-walk variance ratio cycle/ALIS at 760 nm: nadir {:.1}, 50° {:.1}",
        var_per_walk(&full[0]) / var_per_walk(&alis[0]),
        var_per_walk(&full[1]) / var_per_walk(&alis[1])
    );
    let window = run_rows(&experiment(&text(&file, 2, 750.0, None, 16 * 2048)));
    println!(
        "nadir BRF: 750 nm bin {:.4}, 760 nm bin {:.4}",
        window[0].brf.unwrap().0,
        full[0].brf.unwrap().0
    );
    assert!(full[0].brf.unwrap().0 < 0.8 * window[0].brf.unwrap().0);
}

/// Bad CKD input is named: a profile the file was not computed for, a wavelength outside its
/// bins, a correlated-k file without `mode = "ckd"`, a g-point index out of range.
#[test]
fn ckd_errors_name_the_key() {
    let Some(file) = common::ckd_v0_file() else {
        eprintln!("skipped: shared data folder not found");
        return;
    };
    let t = text(&file, 1, 760.0, None, 100);
    let try_ = |s: String| {
        engine::config::Experiment::from_str(&s, &common::data_dir().join("t.toml"))
            .unwrap_err()
            .to_string()
    };
    let e = try_(t.replace(
        "type = \"molecular\"\n",
        "type = \"molecular\"\nprofile = \"afgl_1986-tropical\"\n",
    ));
    assert!(
        e.contains("atmosphere.absorption_data") && e.contains("US standard"),
        "{e}"
    );
    let e = try_(t.replace("[760.0]", "[3000.0]"));
    assert!(e.contains("spectral.wavelengths[0]"), "{e}");
    let e = try_(t.replace("mode = \"ckd\"", "mode = \"mono\""));
    assert!(e.contains("need mode = \"ckd\""), "{e}");
    let e = try_(t.replace("[spectral]\n", "[spectral]\ng_point = 16\n"));
    assert!(e.contains("spectral.g_point"), "{e}");
}

/// With a precision target, rounds end on whole cycles of g-point blocks (the weights stay
/// unbiased) and the run stops once the target is met (this once panicked: a cycle of 16 blocks
/// is larger than the default round growth).
#[test]
fn ckd_rounds_are_whole_g_cycles() {
    let Some(file) = common::ckd_v0_file() else {
        eprintln!("skipped: shared data folder not found");
        return;
    };
    let t = text(&file, 3, 940.0, None, 4_000_000).replace(
        "spp = 4000000\n",
        "spp = 4000000\ntarget_rel_stderr = 0.004\n",
    );
    let rows = run_rows(&experiment(&t));
    for r in &rows {
        let (v, e) = r.brf.unwrap();
        assert!(e / v <= 0.004, "{e} / {v}");
        assert_eq!(r.n_samples % (16 * 2048), 0, "{}", r.n_samples);
        assert!(r.n_samples < 4_000_000);
    }
}

/// A sensor band in CKD mode is sampled by the bins it overlaps: Sentinel-2A MSI B4 (≈ 646–685
/// nm) runs exactly the four 10 nm bins 650…680 of the eradiate v0 file at their centres, with
/// weights ∫_bin S dλ that add up to the SRF's integral, and the band BRF is Σ w E0 BRF / Σ w E0
/// of the per-bin rows. `wavelength_step` is refused (bins are the sampling).
#[test]
fn ckd_band_is_sampled_by_bins() {
    let Some(file) = common::ckd_v0_file() else {
        eprintln!("skipped: shared data folder not found");
        return;
    };
    let t = text(&file, 7, 760.0, None, 16 * 512)
        .replace("wavelengths = [760.0]", "srf = \"sentinel_2a-msi-4\"");
    let exp = experiment(&t);
    assert_eq!(exp.wavelengths, vec![650.0, 660.0, 670.0, 680.0]);
    let band = exp.band.as_ref().unwrap();
    let srf = engine::spectral::srf::Srf::builtin("sentinel_2a-msi-4")
        .unwrap()
        .unwrap();
    let total: f64 = srf
        .wavelength
        .windows(2)
        .zip(srf.response.windows(2))
        .map(|(x, r)| 0.5 * (r[0] + r[1]) * (x[1] - x[0]))
        .sum();
    let sum: f64 = band.weights.iter().sum();
    assert!((sum / total - 1.0).abs() < 1e-9, "{sum} vs {total}");
    let rows = run_rows(&exp);
    let b = simulator::products::band_rows(&exp, &rows);
    let (mut num, mut den) = (0.0, 0.0);
    for (k, r) in rows.iter().filter(|r| r.vza == Some(0.0)).enumerate() {
        let e0 = exp.optics[k].irradiance;
        num += band.weights[k] * e0 * r.brf.unwrap().0;
        den += band.weights[k] * e0;
    }
    let got = b
        .iter()
        .find(|r| r.vza == Some(0.0))
        .unwrap()
        .brf
        .unwrap()
        .0;
    assert!(
        (got / (num / den) - 1.0).abs() < 1e-12,
        "{got} vs {}",
        num / den
    );
    let e = engine::config::Experiment::from_str(
        &t.replace("[spectral]\n", "[spectral]\nwavelength_step = 1.0\n"),
        &common::data_dir().join("t.toml"),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("spectral.wavelength_step"), "{e}");
}
