//! `results.nc` through the command line: the non-image measures of a run with every kind
//! (`mdistant`, two `radiancemeter`s, `distant_flux`) form one table on the `measure` and
//! `direction` dimensions, and every value equals the matching row of `results.csv`.

use std::path::PathBuf;

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("simulate-results-nc-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

const EXPERIMENT: &str = r#"seed = 3
[spectral]
wavelengths = [440.0, 550.0]
[atmosphere]
type = "homogeneous"
optical_thickness = 0.3
[surface]
type = "lambertian"
reflectance = 0.2
[illumination]
type = "directional"
zenith = 30.0
azimuth = 0.0
[[measures]]
id = "pp"
type = "mdistant"
construct = "hplane"
azimuth = 0.0
zeniths = [-30.0, 0.0, 30.0]
spp = 2000
[[measures]]
id = "flux"
type = "distant_flux"
spp = 2000
[[measures]]
id = "rm_a"
type = "radiancemeter"
origin = [0.0, 0.0, 50.0]
direction = [0.0, 0.0, -1.0]
spp = 2000
[[measures]]
id = "rm_b"
type = "radiancemeter"
origin = [0.0, 0.0, 50.0]
direction = [0.3, 0.0, -1.0]
spp = 2000
"#;

#[test]
fn non_image_measures_form_one_table_equal_to_the_csv() {
    let dir = tmpdir("table");
    let exp = dir.join("exp.toml");
    std::fs::write(&exp, EXPERIMENT).unwrap();
    let out = dir.join("out");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_simulate"))
        .args([
            "run",
            exp.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--quiet",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    let _session = engine::netcdf_session();
    let f = netcdf::open(out.join("results.nc")).unwrap();
    assert_eq!(f.dimension_len("measure"), Some(4));
    assert_eq!(f.dimension_len("direction"), Some(6));
    let strings = |name: &str, n: usize| -> Vec<String> {
        let v = f.variable(name).unwrap();
        (0..n).map(|i| v.get_string(i).unwrap()).collect()
    };
    assert_eq!(strings("measure_id", 4), ["pp", "flux", "rm_a", "rm_b"]);
    assert_eq!(
        strings("measure_type", 4),
        ["mdistant", "distant_flux", "radiancemeter", "radiancemeter"]
    );
    let counts: Vec<i32> = f
        .variable("measure_direction_count")
        .unwrap()
        .get_values(..)
        .unwrap();
    assert_eq!(counts, [3, 1, 1, 1]);
    let owner: Vec<i32> = f
        .variable("direction_measure")
        .unwrap()
        .get_values(..)
        .unwrap();
    assert_eq!(owner, [0, 0, 0, 1, 2, 3]);
    assert_eq!(
        strings("direction_measure_id", 6),
        ["pp", "pp", "pp", "flux", "rm_a", "rm_b"]
    );
    let get = |name: &str| -> Vec<f64> { f.variable(name).unwrap().get_values(..).unwrap() };
    let (brf, brf_se, albedo, vza) = (get("brf"), get("brf_stderr"), get("albedo"), get("vza"));
    assert_eq!(brf.len(), 2 * 6);

    // Every CSV row at its place in the table: entry = first entry of its measure + its index.
    let csv = std::fs::read_to_string(out.join("results.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let idx = |c: &str| header.iter().position(|h| *h == c).unwrap();
    let first = [("pp", 0usize), ("flux", 3), ("rm_a", 4), ("rm_b", 5)];
    let mut seen = std::collections::HashMap::new();
    let num = |s: &str| s.parse::<f64>().unwrap_or(f64::NAN);
    let mut checked = 0;
    for line in lines {
        let r: Vec<&str> = line.split(',').collect();
        let m = r[idx("measure")];
        let w = if num(r[idx("wavelength_nm")]) == 440.0 {
            0
        } else {
            1
        };
        let k = seen.entry((m.to_string(), w)).or_insert(0usize);
        let d = first.iter().find(|(id, _)| *id == m).unwrap().1 + *k;
        *k += 1;
        let i = w * 6 + d;
        let same = |a: f64, b: f64| (a.is_nan() && b.is_nan()) || (a - b).abs() <= 1e-9 * b.abs();
        assert!(same(brf[i], num(r[idx("brf")])), "{m} brf row {line}");
        assert!(
            same(brf_se[i], num(r[idx("brf_stderr")])),
            "{m} stderr row {line}"
        );
        assert!(
            same(albedo[i], num(r[idx("albedo")])),
            "{m} albedo row {line}"
        );
        if w == 0 {
            // The CSV prints angles with 6 decimals.
            let want = num(r[idx("vza")]);
            assert!(
                (vza[d].is_nan() && want.is_nan()) || (vza[d] - want).abs() < 1e-6,
                "{m} vza row {line}"
            );
        }
        checked += 1;
    }
    assert_eq!(checked, 12);
    // A flux measure has no BRF, a directional one no albedo.
    assert!(brf[3].is_nan() && albedo[3] > 0.0 && albedo[0].is_nan() && brf[0] > 0.0);
    drop(f);
    let _ = std::fs::remove_dir_all(&dir);
}
