//! The Libya-4 calibration site in 3D, end to end: the shared terrain mesh of the site
//! (`terrain/libya4_20km.ply`) becomes a scene bundle (`examples/libya4/region.toml`, whose
//! `[dem]` is the mesh itself, rasterised by the build), and the bundle a 3D PICS site
//! (`examples/pics/libya4_3d_site.toml`) whose band TOA reflectance is compared with the 1D site
//! (`examples/pics/libya4_site.toml`, the same RPV on a flat ground).
//!
//! Expectation: the site is gentle (54 m of relief over 19 km, slopes below 2°), so over a
//! 10 km × 10 km target the terrain's effect on the band reflectance must be small: within
//! 4.5 combined standard errors plus 0.5 % (the order of the effect of such slopes on a
//! near-Lambertian surface, ≈ 1 − cos 2°). The run also checks the bundle's geometry against the
//! mesh (extent, heights). Needs the shared data folder; skips without it.

use std::path::Path;

use simulator::pics::{run, Acquisition};

#[test]
fn libya4_terrain_site_in_3d() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let shared = root.join("../shared");
    let mesh = shared.join("data/terrain/libya4_20km.ply");
    if !mesh.exists() || !shared.join("data/ckd").exists() {
        eprintln!("skipped: the shared data folder is absent");
        return;
    }
    let dir = std::env::temp_dir().join(format!("libya4_{}", std::process::id()));
    // The example files refer to out/libya4/… and ../../../shared from examples/…: lay out the
    // same tree under `dir`.
    let ex = dir.join("repo/examples");
    std::fs::create_dir_all(ex.join("libya4")).unwrap();
    std::fs::create_dir_all(ex.join("pics")).unwrap();
    // `out/libya4` is not created here: the bundle writer creates its output's parents.
    let out = dir.join("repo/out/libya4");
    for f in [
        "libya4/region.toml",
        "pics/libya4_site.toml",
        "pics/libya4_3d_site.toml",
    ] {
        let t = std::fs::read_to_string(root.join("examples").join(f))
            .unwrap()
            .replace("../../../shared", shared.to_str().unwrap())
            .replace("target_rel_stderr = 0.002", "target_rel_stderr = 0.003");
        std::fs::write(ex.join(f), t).unwrap();
    }
    let region = scenegen::Region::load(&ex.join("libya4/region.toml")).unwrap();
    let report = scenegen::build(
        &region,
        &out.join("bundle"),
        &scenegen::BuildOptions {
            force: true,
            progress: false,
        },
    )
    .unwrap();
    let b = bundle::Bundle::open(&out.join("bundle")).unwrap();
    let m = &b.manifest;
    println!(
        "bundle: {} x {} DEM nodes, heights {:?}",
        report.dem_width, report.dem_height, m.extent.height_range
    );
    assert!(m.extent.height_range[0] > 97.0 && m.extent.height_range[1] < 157.0);

    let acqs: Vec<Acquisition> = ["2026-01-15T09:45:00Z", "2026-06-15T09:45:00Z"]
        .iter()
        .map(|t| Acquisition {
            time_utc: t.to_string(),
            vza: 5.2,
            vaa: 103.0,
            srf: "sentinel_2a-msi-4".into(),
            sun: None,
        })
        .collect();
    let r3 = run(&ex.join("pics/libya4_3d_site.toml"), &acqs, |_| {}).unwrap();
    let r1 = run(&ex.join("pics/libya4_site.toml"), &acqs, |_| {}).unwrap();
    for (a, b) in r3.iter().zip(&r1) {
        let (x, ex3) = a.reflectance;
        let (y, ex1) = b.reflectance;
        let s = (ex3 * ex3 + ex1 * ex1).sqrt();
        println!(
            "{}: 3D {x:.5} ± {ex3:.1e}, 1D {y:.5} ± {ex1:.1e}, 3D − 1D = {:+.5} ({:+.2} σ)",
            a.acquisition.time_utc,
            x - y,
            (x - y) / s
        );
        assert_eq!(a.sza, b.sza);
        assert!((x - y).abs() <= 4.5 * s + 0.005 * y, "{x} vs {y}");
    }

    // The same sites under a spherical-shell atmosphere (the 3D terrain bent onto the Earth) on
    // a winter afternoon, SZA ≈ 76°: 3D and 1D agree as above, and both are brighter than
    // their plane-parallel values (plane-parallel air masses overestimate the slant solar path
    // above 60–70°).
    for f in ["libya4_site", "libya4_3d_site"] {
        let t = std::fs::read_to_string(ex.join(format!("pics/{f}.toml")))
            .unwrap()
            .replace("type = \"plane_parallel\"", "type = \"spherical_shell\"");
        std::fs::write(ex.join(format!("pics/{f}_sph.toml")), t).unwrap();
    }
    let late = vec![Acquisition {
        time_utc: "2026-12-21T15:00:00Z".into(),
        vza: 5.2,
        vaa: 103.0,
        srf: "sentinel_2a-msi-4".into(),
        sun: None,
    }];
    let site = |f: &str| run(&ex.join(format!("pics/{f}.toml")), &late, |_| {}).unwrap()[0].clone();
    let (s3, s1) = (site("libya4_3d_site_sph"), site("libya4_site_sph"));
    let (p3, p1) = (site("libya4_3d_site"), site("libya4_site"));
    assert!(s3.sza > 70.0, "sza {}", s3.sza);
    let z = |a: (f64, f64), b: (f64, f64)| (a.0 - b.0) / (a.1 * a.1 + b.1 * b.1).sqrt();
    println!(
        "sza {:.2}: spherical 3D {:.5} ± {:.1e}, 1D {:.5} ± {:.1e} (3D − 1D {:+.2} σ); plane-parallel 3D {:.5}, 1D {:.5}",
        s3.sza,
        s3.reflectance.0,
        s3.reflectance.1,
        s1.reflectance.0,
        s1.reflectance.1,
        z(s3.reflectance, s1.reflectance),
        p3.reflectance.0,
        p1.reflectance.0
    );
    let (x, y) = (s3.reflectance, s1.reflectance);
    assert!(
        (x.0 - y.0).abs() <= 4.5 * (x.1 * x.1 + y.1 * y.1).sqrt() + 0.005 * y.0,
        "spherical 3D {x:?} vs 1D {y:?}"
    );
    assert!(
        z(s3.reflectance, p3.reflectance) > 4.5,
        "3D: spherical vs plane-parallel"
    );
    assert!(
        z(s1.reflectance, p1.reflectance) > 4.5,
        "1D: spherical vs plane-parallel"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
