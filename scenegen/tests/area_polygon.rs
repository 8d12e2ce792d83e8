//! A region's area given as a polygon (`[area] polygon`), on the Grenoble example's data.
//!
//! Rationale and expectations: (1) the bundle's recorded area equals the shoelace area of the
//! polygon's vertices transformed to the working CRS independently here, and `geo`'s area;
//! (2) no instance lies outside the polygon, and some lie inside (forest and villages), while
//! a build over the polygon's longitude/latitude box puts many outside it; (3) the
//! extent is the polygon's bounding box, snapped to the DEM grid; (4) `scenegen info` reports
//! the area in km²; (5) the same polygon given as GeoJSON in a UTM CRS (reprojected by GDAL)
//! yields the same area to 0.1 %; (6) a missing file, an invalid (self-intersecting) polygon
//! and a non-polygon are errors naming the file and the key `area.polygon`, exit code 2.
//! Tests (1)-(5) need the shared data folder (the Copernicus DEM) and skip without it.

mod common;
use common::tmp;
use std::path::Path;
use std::process::Command;

use gdal::spatial_ref::{AxisMappingStrategy, CoordTransform, SpatialRef};

/// A pentagon around Grenoble's south-east suburbs and the Belledonne foothills, lon/lat.
const PENTAGON: [(f64, f64); 5] = [
    (5.70, 45.15),
    (5.76, 45.15),
    (5.78, 45.18),
    (5.74, 45.21),
    (5.69, 45.18),
];

fn wkt(points: &[(f64, f64)]) -> String {
    let mut p: Vec<String> = points.iter().map(|(x, y)| format!("{x} {y}")).collect();
    p.push(p[0].clone());
    format!("POLYGON (({}))", p.join(", "))
}

/// The Grenoble region with `[area]` replaced by `area` (paths made absolute).
fn region_text(area: &str) -> Option<String> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let ex = root.join("examples/grenoble");
    let dem = root.join(
        "../shared/data/terrain/copernicus_dem_grenoble/Copernicus_DSM_10_N45_00_E005_00_DEM.tif",
    );
    if !dem.exists() {
        return None;
    }
    let text = std::fs::read_to_string(ex.join("region.toml")).unwrap();
    Some(
        text.replace("bbox = [5.50, 45.02, 5.98, 45.40]", area)
            .replace(
                "../../../shared",
                root.join("../shared")
                    .canonicalize()
                    .unwrap()
                    .to_str()
                    .unwrap(),
            )
            .replace(
                "\"landcover_derived_corine.tif\"",
                &format!("\"{}\"", ex.join("landcover_derived_corine.tif").display()),
            ),
    )
}

fn shoelace(p: &[(f64, f64)]) -> f64 {
    let n = p.len();
    0.5 * (0..n)
        .map(|i| {
            let (a, b) = (p[i], p[(i + 1) % n]);
            a.0 * b.1 - b.0 * a.1
        })
        .sum::<f64>()
        .abs()
}

fn inside(p: &[(f64, f64)], x: f64, y: f64) -> bool {
    let mut c = false;
    for i in 0..p.len() {
        let (a, b) = (p[i], p[(i + 1) % p.len()]);
        if (a.1 > y) != (b.1 > y) && x < a.0 + (y - a.1) * (b.0 - a.0) / (b.1 - a.1) {
            c = !c;
        }
    }
    c
}

fn transform(points: &[(f64, f64)], from: &str, to: &str) -> Vec<(f64, f64)> {
    let mut a = SpatialRef::from_definition(from).unwrap();
    let mut b = SpatialRef::from_definition(to).unwrap();
    a.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
    b.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
    let t = CoordTransform::new(&a, &b).unwrap();
    let (mut xs, mut ys): (Vec<f64>, Vec<f64>) = points.iter().copied().unzip();
    t.transform_coords(&mut xs, &mut ys, &mut []).unwrap();
    xs.into_iter().zip(ys).collect()
}

#[test]
fn grenoble_polygon_area_instances_info() {
    let dir = tmp("grenoble");
    std::fs::write(dir.join("area.wkt"), wkt(&PENTAGON)).unwrap();
    let Some(text) = region_text("polygon = \"area.wkt\"") else {
        eprintln!("skipped: the shared data folder is absent");
        return;
    };
    let region_path = dir.join("region.toml");
    std::fs::write(&region_path, &text).unwrap();
    let region = scenegen::Region::load(&region_path).unwrap();
    let out = dir.join("bundle");
    let opts = scenegen::BuildOptions {
        force: true,
        progress: false,
    };
    scenegen::build(&region, &out, &opts).unwrap();
    let b = bundle::Bundle::open(&out).unwrap();
    let m = &b.manifest;
    let area = m.area.as_ref().expect("the manifest records the polygon");

    // (1) Area: independent transform to the working CRS, shoelace.
    let proj = m.crs.proj.as_deref().expect("local working CRS");
    let work = transform(&PENTAGON, "EPSG:4326", proj);
    let expected = shoelace(&work);
    println!(
        "polygon area {:.1} m² (shoelace {expected:.1} m²)",
        area.area_m2
    );
    assert!(
        (area.area_m2 - expected).abs() <= 1e-9 * expected,
        "{} vs {expected}",
        area.area_m2
    );
    assert!(expected > 1.5e7 && expected < 4e7, "{expected}");

    // (2) Instances: none outside, some inside.
    let o = m.frame.origin;
    let n_out = b
        .instances
        .iter()
        .filter(|i| !inside(&work, i.translation[0] + o[0], i.translation[1] + o[1]))
        .count();
    println!("{} instances, {n_out} outside", b.instances.len());
    assert_eq!(n_out, 0);
    assert!(b.instances.len() > 1000, "{}", b.instances.len());
    // The mask matters: over the polygon's lon/lat box, many instances fall outside it.
    let boxed = dir.join("boxed.toml");
    std::fs::write(
        &boxed,
        text.replace(
            "polygon = \"area.wkt\"",
            "bbox = [5.69, 45.15, 5.78, 45.21]",
        ),
    )
    .unwrap();
    scenegen::build(
        &scenegen::Region::load(&boxed).unwrap(),
        &dir.join("boxed"),
        &opts,
    )
    .unwrap();
    let bb = bundle::Bundle::open(&dir.join("boxed")).unwrap();
    let ob = bb.manifest.frame.origin;
    let outside_box = bb
        .instances
        .iter()
        .filter(|i| !inside(&work, i.translation[0] + ob[0], i.translation[1] + ob[1]))
        .count();
    println!(
        "over the box: {} instances, {outside_box} outside the polygon",
        bb.instances.len()
    );
    assert!(outside_box > 1000, "{outside_box}");

    // (3) Extent: the polygon's bounding box, to within a DEM step.
    let (xs, ys): (Vec<f64>, Vec<f64>) = work.iter().copied().unzip();
    let bb = [
        xs.iter().copied().fold(f64::MAX, f64::min),
        ys.iter().copied().fold(f64::MAX, f64::min),
        xs.iter().copied().fold(f64::MIN, f64::max),
        ys.iter().copied().fold(f64::MIN, f64::max),
    ];
    let step = m.terrain.dem_spacing_m;
    for (a, e) in [m.extent.min, m.extent.max].concat().iter().zip(bb) {
        assert!(
            (a - e).abs() <= step,
            "extent {:?} vs bbox {bb:?}",
            m.extent
        );
    }

    // (4) info reports the area.
    let info = Command::new(env!("CARGO_BIN_EXE_scenegen"))
        .args(["info", out.to_str().unwrap()])
        .output()
        .unwrap();
    let s = String::from_utf8_lossy(&info.stdout);
    let km2 = format!("{:.3} km²", area.area_m2 / 1e6);
    assert!(s.contains("area: polygon from") && s.contains(&km2), "{s}");

    // (5) The same polygon as GeoJSON in UTM 31N, reprojected by the build.
    let utm = transform(&PENTAGON, "EPSG:4326", "EPSG:32631");
    let mut ring: Vec<String> = utm.iter().map(|(x, y)| format!("[{x}, {y}]")).collect();
    ring.push(ring[0].clone());
    let gj = format!(
        r#"{{"type": "FeatureCollection", "features": [{{"type": "Feature", "properties": {{}}, "geometry": {{"type": "Polygon", "coordinates": [[{}]]}}}}]}}"#,
        ring.join(", ")
    );
    std::fs::write(dir.join("area.geojson"), gj).unwrap();
    std::fs::write(
        &region_path,
        text.replace(
            "polygon = \"area.wkt\"",
            "polygon = \"area.geojson\"\npolygon_crs = \"EPSG:32631\"",
        ),
    )
    .unwrap();
    let region = scenegen::Region::load(&region_path).unwrap();
    let out2 = dir.join("bundle2");
    scenegen::build(&region, &out2, &opts).unwrap();
    let a2 = bundle::Bundle::open(&out2).unwrap().manifest.area.unwrap();
    assert!(
        (a2.area_m2 - expected).abs() <= 1e-3 * expected,
        "{} vs {expected}",
        a2.area_m2
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_polygon_files_name_the_file_and_key() {
    let dir = tmp("bad");
    let region = |file: &str| {
        format!(
            "[area]\npolygon = \"{file}\"\n[dem]\nfiles = [\"dem.tif\"]\n[landcover]\nfile = \"lc.tif\"\nscheme = \"corine\"\n"
        )
    };
    // A bow tie (self-intersecting), a line, and a missing file.
    std::fs::write(
        dir.join("bowtie.wkt"),
        "POLYGON ((5.7 45.1, 5.8 45.2, 5.8 45.1, 5.7 45.2, 5.7 45.1))",
    )
    .unwrap();
    std::fs::write(
        dir.join("line.geojson"),
        r#"{"type": "FeatureCollection", "features": [{"type": "Feature", "properties": {}, "geometry": {"type": "LineString", "coordinates": [[5.7, 45.1], [5.8, 45.2]]}}]}"#,
    )
    .unwrap();
    for (file, what) in [
        ("bowtie.wkt", "invalid polygon"),
        ("line.geojson", "LineString"),
        ("missing.geojson", "not found"),
    ] {
        let p = dir.join(format!("region_{file}.toml"));
        std::fs::write(&p, region(file)).unwrap();
        let e = scenegen::Region::load(&p).unwrap_err().to_string();
        assert!(
            e.contains("area.polygon") && e.contains(file) && e.contains(what),
            "{file}: {e}"
        );
        let o = Command::new(env!("CARGO_BIN_EXE_scenegen"))
            .args(["check", p.to_str().unwrap()])
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(2), "{file}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
