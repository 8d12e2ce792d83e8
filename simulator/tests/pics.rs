//! The PICS workflow (`simulator::pics`, `simulate pics`).

mod common;

use simulator::pics::{read_acquisitions, run, Acquisition};

fn tmp(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("simulate-pics-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A year of monthly acquisitions over a bare Lambertian site: the TOA reflectance is the
/// surface reflectance exactly, whatever the season, while the radiance follows the seasons
/// exactly as E0_b·cos SZA/(π r²)·ρ, with SZA and r from NREL SPA at each time — the seasonal
/// behaviour calibration relies on, checked without Monte Carlo noise.
#[test]
fn seasonal_cycle_of_a_lambertian_site() {
    let dir = tmp("season");
    let site = dir.join("site.toml");
    std::fs::write(
        &site,
        "name = \"flat\"\nlatitude = 28.55\nlongitude = 23.39\nelevation = 118.0\nspp = 100\nirradiance = \"tsis_1\"\n\
         [surface]\ntype = \"lambertian\"\nreflectance = 0.4\n",
    )
    .unwrap();
    let acqs: Vec<Acquisition> = (1..=12)
        .map(|m| Acquisition {
            time_utc: format!("2026-{m:02}-15T10:00:00Z"),
            vza: 3.0,
            vaa: 100.0,
            srf: "sentinel_2a-msi-4".into(),
            sun: None,
        })
        .collect();
    let rows = run(&site, &acqs, |_| {}).unwrap();
    let e1au = rows[0].band_irradiance * rows[0].earth_sun_distance_au.powi(2);
    let mut szas = Vec::new();
    for r in &rows {
        let p = engine::sources::sun_position::sun_position(
            &r.acquisition.time_utc,
            28.55,
            23.39,
            118.0,
            None,
        )
        .unwrap();
        assert!(
            (r.sza - p.zenith).abs() < 1e-9
                && (r.earth_sun_distance_au - p.distance_au).abs() < 1e-12
        );
        assert!((r.reflectance.0 - 0.4).abs() < 1e-12, "{:?}", r.reflectance);
        let want =
            0.4 * e1au / p.distance_au.powi(2) * p.zenith.to_radians().cos() / std::f64::consts::PI;
        assert!(
            (r.radiance.0 / want - 1.0).abs() < 1e-12,
            "{} vs {want}",
            r.radiance.0
        );
        szas.push(r.sza);
    }
    // The Sun is highest in June and lowest in December at this northern site.
    let (imin, imax) = (
        szas.iter()
            .enumerate()
            .min_by(|a, b| a.1.partial_cmp(b.1).unwrap())
            .unwrap()
            .0,
        szas.iter()
            .enumerate()
            .max_by(|a, b| a.1.partial_cmp(b.1).unwrap())
            .unwrap()
            .0,
    );
    assert!(
        (5..=6).contains(&imin) && (imax == 11 || imax == 0),
        "{szas:?}"
    );
}

/// The command end to end on the shipped example (fewer samples), and bad acquisitions files
/// are errors naming the file and line (exit code 2).
#[test]
fn cli_pics() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let dir = tmp("cli");
    let shared = root.join("../shared");
    if !shared.join("data/ckd").exists() {
        eprintln!("skipped: the shared data folder is absent");
        return;
    }
    // The example's data paths are relative to examples/pics/.
    let site = std::fs::read_to_string(root.join("examples/pics/libya4_site.toml"))
        .unwrap()
        .replace("spp = 100000", "spp = 3000")
        .replace("../../../shared", shared.to_str().unwrap());
    std::fs::write(dir.join("site.toml"), site).unwrap();
    let out = dir.join("out");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_simulate"))
        .args([
            "pics",
            root.join("examples/pics/acquisitions.csv")
                .to_str()
                .unwrap(),
            "--site",
        ])
        .arg(dir.join("site.toml"))
        .args(["-o", out.to_str().unwrap(), "--quiet"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let csv = std::fs::read_to_string(out.join("pics.csv")).unwrap();
    assert_eq!(csv.lines().count(), 7);
    let refl: Vec<f64> = {
        // HDF5 is not thread-safe: concurrent tests must not read while another writes.
        let _session = engine::netcdf_session();
        let f = netcdf::open(out.join("pics.nc")).unwrap();
        f.variable("reflectance")
            .unwrap()
            .get_values::<f64, _>(..)
            .unwrap()
    };
    assert_eq!(refl.len(), 6);
    assert!(refl.iter().all(|r| *r > 0.3 && *r < 0.8), "{refl:?}");
    let bad = dir.join("bad.csv");
    std::fs::write(
        &bad,
        "time_utc,vza,vaa,srf\n2026-01-15T09:45:00Z,abc,103.0,sentinel_2a-msi-4\n",
    )
    .unwrap();
    let e = read_acquisitions(&bad).unwrap_err().to_string();
    assert!(
        e.contains("bad.csv") && e.contains("line 2") && e.contains("vza"),
        "{e}"
    );
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_simulate"))
        .args([
            "pics",
            bad.to_str().unwrap(),
            "--site",
            dir.join("site.toml").to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
}

/// A 3D site: the same flat Lambertian site given as a scene bundle (with a background of the
/// same material) and as a 1D surface gives the same band TOA reflectance and radiance per
/// acquisition (no atmosphere, so both are exactly ρ, without noise: the scene path, the scene
/// shared by the acquisitions, the band weighting and the target area are all exercised).
#[test]
fn three_d_site_equals_the_1d_site_when_flat() {
    use common::bundles::{lambertian, write_plane, PlaneSpec};
    let dir = tmp("site3d");
    let b = write_plane(
        &dir,
        &PlaneSpec {
            x0: -1000.0,
            y0: -1000.0,
            size: 2000.0,
            h0: 118.0,
            sx: 0.0,
            sy: 0.0,
            tiles: 2,
            n: 4,
            raster_width: 2,
            raster: vec![0; 4],
            materials: vec![("sand".into(), lambertian(0.4))],
            frame_origin: [0.0, 0.0, 0.0],
            wkt: String::new(),
        },
    );
    let acqs: Vec<Acquisition> = (1..=3)
        .map(|m| Acquisition {
            time_utc: format!("2026-{:02}-15T10:00:00Z", 2 * m),
            vza: 5.0 * m as f64,
            vaa: 100.0,
            srf: "sentinel_2a-msi-4".into(),
            sun: None,
        })
        .collect();
    let head = "name = \"flat\"\nlatitude = 28.55\nlongitude = 23.39\nelevation = 118.0\nspp = 2000\nirradiance = \"tsis_1\"\nwavelength_step = 10.0\n";
    let site3 = dir.join("site3d.toml");
    std::fs::write(
        &site3,
        format!(
            "{head}target_m = [-500.0, -500.0, 500.0, 500.0]\n[scene]\ntype = \"bundle\"\npath = \"{}\"\n",
            b.display()
        ),
    )
    .unwrap();
    let site1 = dir.join("site1d.toml");
    std::fs::write(
        &site1,
        format!("{head}[surface]\ntype = \"lambertian\"\nreflectance = 0.4\n"),
    )
    .unwrap();
    let (r3, r1) = (
        run(&site3, &acqs, |_| {}).unwrap(),
        run(&site1, &acqs, |_| {}).unwrap(),
    );
    for (a, b) in r3.iter().zip(&r1) {
        assert!((a.reflectance.0 - 0.4).abs() < 1e-9, "{:?}", a.reflectance);
        assert!((a.reflectance.0 - b.reflectance.0).abs() < 1e-9);
        assert!((a.radiance.0 / b.radiance.0 - 1.0).abs() < 1e-9);
        assert_eq!(a.sza, b.sza);
    }
}

/// The site catalogue: a site file with `catalogue = "libya4"` takes the catalogued CEOS centre
/// (the Sun of an acquisition is the one at 28.55 N, 23.39 E), its own keys win; `--site libya4`
/// without a file explains that a surface and an atmosphere are needed; an unknown catalogue key
/// lists the known sites.
#[test]
fn catalogue_sites() {
    let dir = tmp("catalogue");
    let body =
        "spp = 2000\nwavelength_step = 10.0\n[surface]\ntype = \"lambertian\"\nreflectance = 0.3\n";
    let by_key = dir.join("by_key.toml");
    std::fs::write(&by_key, format!("catalogue = \"Libya-4\"\n{body}")).unwrap();
    let explicit = dir.join("explicit.toml");
    std::fs::write(
        &explicit,
        format!("name = \"Libya-4\"\nlatitude = 28.55\nlongitude = 23.39\n{body}"),
    )
    .unwrap();
    let acq = vec![Acquisition {
        time_utc: "2026-06-15T09:45:00Z".into(),
        vza: 5.0,
        vaa: 100.0,
        srf: "sentinel_2a-msi-4".into(),
        sun: None,
    }];
    let (a, b) = (
        run(&by_key, &acq, |_| {}).unwrap(),
        run(&explicit, &acq, |_| {}).unwrap(),
    );
    assert_eq!((a[0].sza, a[0].saa), (b[0].sza, b[0].saa));
    assert_eq!(a[0].reflectance, b[0].reflectance);
    let e = run(std::path::Path::new("libya4"), &acq, |_| {})
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("catalogue site Libya-4") && e.contains("catalogue = \"libya4\""),
        "{e}"
    );
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, format!("catalogue = \"atlantis\"\n{body}")).unwrap();
    let e = run(&bad, &acq, |_| {}).unwrap_err().to_string();
    assert!(e.contains("catalogue") && e.contains("libya4"), "{e}");
}

/// Sun angles given in the acquisitions CSV replace SPA's: the reflectance of a Lambertian site
/// is still ρ, the radiance follows cos(given SZA), and the Earth–Sun distance is still SPA's at
/// the acquisition time. A row with empty `sza,saa` cells keeps the computed Sun. An offset time
/// is the same instant as its UTC form.
#[test]
fn given_sun_angles_override_spa() {
    let dir = tmp("sun");
    let site = dir.join("site.toml");
    std::fs::write(
        &site,
        "latitude = 28.55\nlongitude = 23.39\nelevation = 118.0\nspp = 100\nirradiance = \"tsis_1\"\n\
         [surface]\ntype = \"lambertian\"\nreflectance = 0.4\n",
    )
    .unwrap();
    let csv = dir.join("acq.csv");
    std::fs::write(
        &csv,
        "time_utc,vza,vaa,srf,sza,saa\n\
         2026-06-15T09:45:00Z,5,100,sentinel_2a-msi-4,,\n\
         2026-06-15T11:45:00+02:00,5,100,sentinel_2a-msi-4,60.0,200.0\n",
    )
    .unwrap();
    let acqs = read_acquisitions(&csv).unwrap();
    assert_eq!(acqs[0].time_utc, acqs[1].time_utc);
    // A plane-parallel site has no twilight: a given SZA of 95° is refused, naming the
    // acquisition and where its angles came from.
    let mut night = acqs.clone();
    night[1].sun = Some((95.0, 200.0));
    let e = run(&site, &night, |_| {}).unwrap_err().to_string();
    assert!(
        e.contains("site.toml")
            && e.contains("acquisition 2")
            && e.contains("from the acquisitions file")
            && e.contains("illumination.zenith"),
        "{e}"
    );
    let rows = run(&site, &acqs, |_| {}).unwrap();
    let p = engine::sources::sun_position::sun_position(
        "2026-06-15T09:45:00Z",
        28.55,
        23.39,
        118.0,
        None,
    )
    .unwrap();
    assert!((rows[0].sza - p.zenith).abs() < 1e-9);
    assert_eq!((rows[1].sza, rows[1].saa), (60.0, 200.0));
    for r in &rows {
        assert!((r.earth_sun_distance_au - p.distance_au).abs() < 1e-12);
        assert!((r.reflectance.0 - 0.4).abs() < 1e-12, "{:?}", r.reflectance);
    }
    let ratio = rows[1].radiance.0 / rows[0].radiance.0;
    let want = 60f64.to_radians().cos() / p.zenith.to_radians().cos();
    assert!((ratio / want - 1.0).abs() < 1e-12, "{ratio} vs {want}");

    // pics.nc: a CF numeric time coordinate.
    let out = dir.join("out");
    std::fs::create_dir_all(&out).unwrap();
    let nc = out.join("pics.nc");
    simulator::pics::write_netcdf(&nc, &site, &rows).unwrap();
    // HDF5 is not thread-safe: hold the library while reading (tests run concurrently).
    let _session = engine::netcdf_session();
    let f = netcdf::open(&nc).unwrap();
    let t = f.variable("time").unwrap();
    let attr = |v: &netcdf::Variable, k: &str| -> String {
        match v.attribute_value(k).unwrap().unwrap() {
            netcdf::AttributeValue::Str(s) => s,
            other => panic!("{k}: {other:?}"),
        }
    };
    assert_eq!(attr(&t, "units"), "seconds since 1970-01-01T00:00:00Z");
    assert_eq!(attr(&t, "calendar"), "standard");
    assert_eq!(attr(&t, "standard_name"), "time");
    assert_eq!(t.dimensions()[0].name(), "acquisition");
    let secs: Vec<f64> = t.get_values::<f64, _>(..).unwrap();
    // 2026-06-15T09:45:00Z = 20619 days and 35100 s after the epoch.
    assert_eq!(secs, vec![20619.0 * 86400.0 + 35100.0; 2]);
    let refl = f.variable("reflectance").unwrap();
    assert_eq!(attr(&refl, "coordinates"), "time");
    let given: Vec<i8> = f
        .variable("sun_angles_given")
        .unwrap()
        .get_values::<i8, _>(..)
        .unwrap();
    assert_eq!(given, vec![0, 1]);
    let idx: Vec<i32> = f
        .variable("acquisition")
        .unwrap()
        .get_values::<i32, _>(..)
        .unwrap();
    assert_eq!(idx, vec![1, 2]);
}

/// `simulate check` recognises a PICS site file and validates it (with a sample acquisition, or
/// with `--acquisitions`); a bad key or a bad CSV line is reported with its file, and the exit
/// code is 2.
#[test]
fn check_validates_site_files() {
    let dir = tmp("check");
    let site = dir.join("site.toml");
    std::fs::write(
        &site,
        "catalogue = \"libya4\"\nspp = 100\n[surface]\ntype = \"lambertian\"\nreflectance = 0.4\n",
    )
    .unwrap();
    let check = |args: &[&std::path::Path]| {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_simulate"))
            .arg("check")
            .args(args)
            .output()
            .unwrap();
        (
            o.status.code(),
            String::from_utf8_lossy(&o.stdout).to_string() + &String::from_utf8_lossy(&o.stderr),
        )
    };
    let (code, text) = check(&[&site]);
    assert_eq!(code, Some(0), "{text}");
    assert!(text.contains("valid PICS site file"), "{text}");

    let csv = dir.join("acq.csv");
    std::fs::write(
        &csv,
        "time_utc,vza,vaa,srf\n2026-06-15T09:45:00Z,5,100,sentinel_2a-msi-4\n",
    )
    .unwrap();
    let (code, text) = check(&[&site, std::path::Path::new("--acquisitions"), &csv]);
    assert_eq!(code, Some(0), "{text}");
    assert!(text.contains("1 acquisition(s)"), "{text}");

    std::fs::write(
        &csv,
        "time_utc,vza,vaa,srf,sza\n2026-06-15T09:45:00Z,5,100,sentinel_2a-msi-4,30\n",
    )
    .unwrap();
    let (code, text) = check(&[&site, std::path::Path::new("--acquisitions"), &csv]);
    assert_eq!(code, Some(2), "{text}");
    assert!(text.contains("acq.csv") && text.contains("saa"), "{text}");

    let bad = dir.join("bad.toml");
    std::fs::write(
        &bad,
        "latitude = 28.55\nlongitude = 23.39\nspp = 100\nsurfce = 1\n[surface]\ntype = \"lambertian\"\nreflectance = 0.4\n",
    )
    .unwrap();
    let (code, text) = check(&[&bad]);
    assert_eq!(code, Some(2), "{text}");
    assert!(
        text.contains("bad.toml") && text.contains("surfce"),
        "{text}"
    );
}
