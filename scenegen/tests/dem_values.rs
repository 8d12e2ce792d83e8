//! Damaged or absurd DEM heights are refused before any work is done, naming the file and the
//! source pixel (issue 15): an `inf` pixel, a 1e30 spike, and −32768 voids in a band without a
//! no-data tag used to build a bundle with infinite heights or pits.

mod common;
use common::tmp;
use std::path::{Path, PathBuf};
use std::process::Command;

use scenegen::synth::write_geotiff;

const LOCAL: &str = "+proj=tmerc +lat_0=45 +lon_0=5.7 +k=1 +x_0=0 +y_0=0 +datum=WGS84 +units=m";

/// A 2 km square region over a 40 × 40 DEM at 60 m in the local frame; `damage` edits heights.
fn setup(name: &str, nodata: Option<f64>, damage: impl Fn(&mut [f32])) -> (PathBuf, PathBuf) {
    setup_sized(name, nodata, damage, 60.0, "")
}

/// As [`setup`] with DEM pixels of `px` metres (the area is 2/60 of the DEM's side less one
/// pixel per side) and `extra` appended to the region.
fn setup_sized(
    name: &str,
    nodata: Option<f64>,
    damage: impl Fn(&mut [f32]),
    px: f64,
    extra: &str,
) -> (PathBuf, PathBuf) {
    let dir = tmp(name);
    let mut v: Vec<f32> = (0..40 * 40).map(|k| 300.0 + (k % 40) as f32).collect();
    damage(&mut v);
    write_geotiff(
        &dir.join("dem.tif"),
        40,
        40,
        Some([-20.0 * px, px, 0.0, 20.0 * px, 0.0, -px]),
        Some(LOCAL),
        nodata,
        v,
    )
    .unwrap();
    write_geotiff(
        &dir.join("lc.tif"),
        20,
        20,
        Some([-20.0 * px, 2.0 * px, 0.0, 20.0 * px, 0.0, -2.0 * px]),
        Some(LOCAL),
        Some(255.0),
        vec![18u8; 400],
    )
    .unwrap();
    let region = dir.join("region.toml");
    let size_km = 38.0 * px / 1000.0;
    std::fs::write(
        &region,
        format!("seed = 1\n[area]\ncentre = [5.7, 45.0]\nsize_km = {size_km}\n[dem]\nfiles = [\"dem.tif\"]\nspacing_m = {px}\n[landcover]\nfile = \"lc.tif\"\nscheme = \"corine\"\n{extra}"),
    )
    .unwrap();
    (dir, region)
}

fn build(dir: &Path, region: &Path) -> (i32, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_scenegen"))
        .args(["build", "--quiet", region.to_str().unwrap(), "-o"])
        .arg(dir.join("out"))
        .output()
        .unwrap();
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[test]
fn bad_heights_are_refused_with_file_and_pixel() {
    let at = 20 * 40 + 17; // row 20, column 17
    let cases: Vec<(&str, Option<f64>, f32, &[&str])> = vec![
        (
            "inf",
            Some(-32768.0),
            f32::INFINITY,
            &["inf", "column 17, row 20"],
        ),
        (
            "spike",
            Some(-32768.0),
            1e30,
            &["1.000e30", "column 17, row 20"],
        ),
        (
            "void",
            None,
            -32768.0,
            &["-32768", "no-data", "gdal_edit", "column 17, row 20"],
        ),
        ("pit", None, -20000.0, &["-20000", "column 17, row 20"]),
    ];
    for (name, nodata, value, needles) in cases {
        let (dir, region) = setup(name, nodata, |v| v[at] = value);
        let (code, stderr) = build(&dir, &region);
        assert_eq!(code, 2, "{name}: {stderr}");
        assert!(stderr.contains("dem.tif"), "{name}: {stderr}");
        for n in needles {
            assert!(stderr.contains(n), "{name}: `{n}` not in {stderr}");
        }
        assert!(!stderr.contains("panicked"), "{stderr}");
        assert!(!dir.join("out").exists(), "{name}: output left behind");
        std::fs::remove_dir_all(&dir).unwrap();
    }
    // A tagged −32768 void is a hole (filled), and a clean DEM builds.
    let (dir, region) = setup("tagged", Some(-32768.0), |v| v[at] = -32768.0);
    let (code, stderr) = build(&dir, &region);
    assert_eq!(code, 0, "{stderr}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// An absurd instance density over a 11 km square (1.1·10⁹ expected instances) used to abort
/// on allocation; it is refused before placement, naming the rule's key.
#[test]
fn absurd_instance_density_is_refused_before_placement() {
    let (dir, region) = setup_sized(
        "density",
        None,
        |_| {},
        300.0,
        "[[population]]\nclasses = [18]\ntemplate = \"tree\"\ndensity_per_ha = 100000\n",
    );
    let (code, stderr) = build(&dir, &region);
    assert_eq!(code, 2, "{stderr}");
    for n in [
        "population[0].density_per_ha",
        "instances",
        "GiB",
        "region.toml",
    ] {
        assert!(stderr.contains(n), "`{n}` not in {stderr}");
    }
    assert!(!dir.join("out").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}
