//! The whole chain through the command-line tools, on synthetic inputs (no shared data needed):
//! a DEM and a CORINE land cover written as GeoTIFFs → `scenegen build` of a region file →
//! `scenegen info` and `export-gltf` of the bundle (into folders that do not exist yet) →
//! `simulate run` of an experiment rendering it (an ortho image
//! and a target-area BRF) → the products read back with GDAL (GeoTIFF) and netCDF.
//!
//! Rationale: each crate has its own tests; this one checks what they hand each other. Expected:
//! the bundle opens and `info` reports its counts; the ortho GeoTIFF is in the bundle's CRS, its
//! geotransform lies inside the bundle extent with the requested pixel size, one band per
//! wavelength, every BRF finite and physical (0 < BRF < 1.5); `results.nc` carries the same
//! image (same values as the GeoTIFF), its CF conventions and the experiment text with the
//! `--spp` override; `results.csv` has the area BRF with a standard error.
//!
//! A second test checks the polygonal area end to end (region `[area] polygon` → manifest
//! `[area]` → the target area of a distant measure masked in `simulate`), on a flat scene whose
//! south-east triangle is bright (Lambertian 0.6) and north-west triangle dark (0.05): over the
//! polygon = the bright triangle, the nadir BRF is far above the BRF over the same square
//! without the polygon (by more than 10 standard errors), and a target area outside the polygon
//! is an error naming `measures[0].target_m` (exit 2).

use std::path::Path;

use e2e::{binary, run, temp_dir};
use scenegen::synth::write_geotiff;

const LOCAL: &str =
    "+proj=tmerc +lat_0=45.2 +lon_0=5.7 +k=1 +x_0=0 +y_0=0 +datum=WGS84 +units=m +no_defs";

/// The area BRF (value, standard error) of measure `id` in a results.csv.
fn csv_brf(path: &Path, id: &str) -> (f64, f64) {
    let csv = std::fs::read_to_string(path).unwrap();
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let col = |n: &str| header.iter().position(|h| *h == n).unwrap();
    let row = csv
        .lines()
        .find(|l| l.starts_with(&format!("{id},")))
        .expect("measure row");
    let f: Vec<&str> = row.split(',').collect();
    (
        f[col("brf")].parse().unwrap(),
        f[col("brf_stderr")].parse().unwrap(),
    )
}

/// 4 km × 4 km of hills at 50 m, and CORINE codes in 200 m blocks (urban, arable, forest,
/// grassland), both in the local transverse Mercator frame, a little larger than the area.
fn write_inputs(dir: &Path) {
    let (n, px) = (90usize, 50.0);
    let gt = [-2250.0, px, 0.0, 2250.0, 0.0, -px];
    let h: Vec<f32> = (0..n * n)
        .map(|k| {
            let (x, y) = ((k % n) as f64 * px, (k / n) as f64 * px);
            (300.0 + 40.0 * (x / 700.0).sin() * (y / 900.0).cos()) as f32
        })
        .collect();
    write_geotiff(&dir.join("dem.tif"), n, n, Some(gt), Some(LOCAL), None, h).unwrap();
    let codes = [2u8, 12, 23, 18];
    let lc: Vec<u8> = (0..n * n)
        .map(|k| codes[((k % n) / 4 + (k / n) / 4) % codes.len()])
        .collect();
    write_geotiff(
        &dir.join("lc.tif"),
        n,
        n,
        Some(gt),
        Some(LOCAL),
        Some(255.0),
        lc,
    )
    .unwrap();
}

const REGION: &str = r#"seed = 3
[area]
centre = [5.7, 45.2]
size_km = 4
[dem]
files = ["dem.tif"]
[terrain]
tolerance_m = 2
tile_size_m = 2000
[landcover]
file = "lc.tif"
scheme = "corine"
"#;

const EXPERIMENT: &str = r#"seed = 1
[spectral]
wavelengths = [550.0, 660.0]
[atmosphere]
type = "homogeneous"
optical_thickness = 0.1
[illumination]
type = "directional"
zenith = 30.0
azimuth = 120.0
[scene]
type = "bundle"
path = "bundle"
[[measures]]
id = "img"
type = "ortho"
pixel_size_m = 500.0
spp = 1000
[[measures]]
id = "area"
type = "mdistant"
construct = "directions"
zeniths = [0.0]
azimuths = [0.0]
spp = 100000
"#;

#[test]
fn region_to_products_through_the_command_line() {
    let (scenegen, simulate) = (binary("scenegen").unwrap(), binary("simulate").unwrap());
    let dir = temp_dir("pipeline");
    write_inputs(&dir);
    std::fs::write(dir.join("region.toml"), REGION).unwrap();
    std::fs::write(dir.join("exp.toml"), EXPERIMENT).unwrap();
    let s = |v: &[&str]| v.iter().map(|a| a.to_string()).collect::<Vec<_>>();

    let o = run(
        &scenegen,
        &s(&["build", "region.toml", "-o", "bundle", "-q"]),
        &dir,
    );
    assert_eq!(o.code, Some(0), "build: {}", o.stderr);
    let b = bundle::Bundle::open(&dir.join("bundle")).unwrap();
    let m = &b.manifest;
    let o = run(&scenegen, &s(&["info", "bundle"]), &dir);
    assert_eq!(o.code, Some(0), "info: {}", o.stderr);
    let tri = format!("terrain: {} triangles", m.terrain.triangle_count);
    assert!(o.stdout.contains(&tri), "{}", o.stdout);
    // Every output's parent folders are created (a fresh clone has no `out/`).
    let o = run(
        &scenegen,
        &s(&["export-gltf", "bundle", "out/gltf/scene.glb"]),
        &dir,
    );
    assert_eq!(o.code, Some(0), "export-gltf: {}", o.stderr);
    assert!(dir.join("out/gltf/scene.glb").is_file());

    // Nested output folders are created.
    let o = run(
        &simulate,
        &s(&["run", "exp.toml", "-o", "out/run", "--spp", "16", "-q"]),
        &dir,
    );
    assert_eq!(o.code, Some(0), "simulate: {}", o.stderr);
    let out = dir.join("out/run");

    // GeoTIFF: CRS, geotransform, bands, values.
    let ds = gdal::Dataset::open(out.join("img_brf.tif")).unwrap();
    let srs = ds.spatial_ref().unwrap();
    let bundle_srs = gdal::spatial_ref::SpatialRef::from_wkt(&m.crs.wkt).unwrap();
    assert!(srs == bundle_srs, "CRS {:?}", srs.to_proj4());
    let gt = ds.geo_transform().unwrap();
    assert_eq!((gt[1], gt[5]), (500.0, -500.0), "{gt:?}");
    let (w, h) = ds.raster_size();
    let eps = 1e-6;
    assert!(
        gt[0] >= m.extent.min[0] - eps
            && gt[3] <= m.extent.max[1] + eps
            && gt[0] + w as f64 * gt[1] <= m.extent.max[0] + eps
            && gt[3] + h as f64 * gt[5] >= m.extent.min[1] - eps,
        "image {gt:?} {w}×{h} outside the bundle extent {:?}",
        m.extent
    );
    assert_eq!(ds.raster_count(), 2);
    let band = ds.rasterband(1).unwrap();
    let tif: Vec<f64> = band
        .read_as::<f64>((0, 0), (w, h), (w, h), None)
        .unwrap()
        .data()
        .to_vec();
    assert!(tif.iter().all(|v| v.is_finite() && *v > 0.0 && *v < 1.5));

    // netCDF: conventions, provenance, the same image.
    let nc = netcdf::open(out.join("results.nc")).unwrap();
    let attr = |name: &str| match nc.attribute(name).unwrap().value().unwrap() {
        netcdf::AttributeValue::Str(s) => s,
        other => panic!("{name}: {other:?}"),
    };
    assert!(attr("Conventions").starts_with("CF-"));
    assert!(attr("experiment").contains("--spp 16"));
    let v = nc.variable("img_brf").expect("img_brf in results.nc");
    let dims: Vec<usize> = v.dimensions().iter().map(|d| d.len()).collect();
    assert_eq!(dims, vec![2, h, w]);
    let first: Vec<f64> = v.get_values((0..1, 0..h, 0..w)).unwrap();
    let first = &first[..w * h];
    // Same orientation (row 0 at the north) and values as the GeoTIFF, to f32 precision.
    for (a, b) in first.iter().zip(&tif) {
        assert!((a - b).abs() <= 1e-6 * a.abs().max(1e-3), "{a} vs {b}");
    }

    // CSV: the area BRF with its standard error.
    let (brf, err) = csv_brf(&out.join("results.csv"), "area");
    assert!(
        brf > 0.0 && brf < 1.0 && err > 0.0 && err < 0.1 * brf,
        "{brf} ± {err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn polygon_area_masks_the_target_area() {
    let (scenegen, simulate) = (binary("scenegen").unwrap(), binary("simulate").unwrap());
    let dir = temp_dir("polygon");
    let (n, px) = (90usize, 50.0);
    let gt = [-2250.0, px, 0.0, 2250.0, 0.0, -px];
    write_geotiff(
        &dir.join("dem.tif"),
        n,
        n,
        Some(gt),
        Some(LOCAL),
        None,
        vec![300f32; n * n],
    )
    .unwrap();
    // Code 30 (bright) where x > y (south-east of the diagonal), 31 (dark) elsewhere.
    let lc: Vec<u8> = (0..n * n)
        .map(|k| {
            let (x, y) = (
                gt[0] + ((k % n) as f64 + 0.5) * px,
                gt[3] - ((k / n) as f64 + 0.5) * px,
            );
            if x > y {
                30
            } else {
                31
            }
        })
        .collect();
    write_geotiff(
        &dir.join("lc.tif"),
        n,
        n,
        Some(gt),
        Some(LOCAL),
        Some(255.0),
        lc,
    )
    .unwrap();
    std::fs::write(
        dir.join("triangle.wkt"),
        "POLYGON ((-1500 -1500, 1500 -1500, 1500 1500, -1500 -1500))",
    )
    .unwrap();
    let region = |area: &str| {
        format!(
            "{area}\n[dem]\nfiles = [\"dem.tif\"]\n[landcover]\nfile = \"lc.tif\"\nscheme = \"corine\"\nclass_materials = {{ \"30\" = \"bright\", \"31\" = \"dark\" }}\n\
             [materials.bright]\nsource = \"test\"\nbrdf = {{ type = \"lambertian\", reflectance = 0.6 }}\n\
             [materials.dark]\nsource = \"test\"\nbrdf = {{ type = \"lambertian\", reflectance = 0.05 }}\n"
        )
    };
    std::fs::write(
        dir.join("poly.toml"),
        region(&format!(
            "[area]\npolygon = \"triangle.wkt\"\npolygon_crs = \"{LOCAL}\""
        )),
    )
    .unwrap();
    std::fs::write(
        dir.join("box.toml"),
        region("[area]\ncentre = [5.7, 45.2]\nsize_km = 3"),
    )
    .unwrap();
    let s = |v: &[&str]| v.iter().map(|a| a.to_string()).collect::<Vec<_>>();
    for r in ["poly", "box"] {
        let o = run(
            &scenegen,
            &s(&["build", &format!("{r}.toml"), "-o", r, "-q"]),
            &dir,
        );
        assert_eq!(o.code, Some(0), "build {r}: {}", o.stderr);
    }
    let exp = |bundle: &str, target: &str| {
        format!(
            "seed = 2\n[spectral]\nwavelengths = [550.0]\n[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = 0.1\n\
             [illumination]\ntype = \"directional\"\nzenith = 30.0\nazimuth = 0.0\n[scene]\ntype = \"bundle\"\npath = \"{bundle}\"\n\
             [[measures]]\nid = \"toa\"\ntype = \"mdistant\"\nconstruct = \"directions\"\nzeniths = [0.0]\nazimuths = [0.0]\nspp = 20000\n{target}"
        )
    };
    let mut brf = Vec::new();
    for r in ["poly", "box"] {
        std::fs::write(dir.join(format!("{r}_exp.toml")), exp(r, "")).unwrap();
        let o = run(
            &simulate,
            &s(&[
                "run",
                &format!("{r}_exp.toml"),
                "-o",
                &format!("out_{r}"),
                "-q",
            ]),
            &dir,
        );
        assert_eq!(o.code, Some(0), "simulate {r}: {}", o.stderr);
        brf.push(csv_brf(&dir.join(format!("out_{r}/results.csv")), "toa"));
    }
    let (p, b) = (brf[0], brf[1]);
    println!(
        "nadir BRF over the polygon {:.4} ± {:.4}, over its box {:.4} ± {:.4}",
        p.0, p.1, b.0, b.1
    );
    assert!(
        p.0 - b.0 > 10.0 * (p.1 * p.1 + b.1 * b.1).sqrt(),
        "{p:?} vs {b:?}"
    );
    assert!(p.0 > 0.4 && b.0 < 0.45, "{p:?} vs {b:?}");

    // An ortho image of the polygon's bundle: pixels whose centre is outside the triangle are
    // NaN (no data), those inside are finite and bright.
    std::fs::write(
        dir.join("ortho_exp.toml"),
        exp("poly", "").replace(
            "type = \"mdistant\"\nconstruct = \"directions\"\nzeniths = [0.0]\nazimuths = [0.0]\nspp = 20000\n",
            "type = \"ortho\"\npixel_size_m = 500.0\nspp = 16\n",
        ),
    )
    .unwrap();
    let o = run(
        &simulate,
        &s(&["run", "ortho_exp.toml", "-o", "out_ortho", "-q"]),
        &dir,
    );
    assert_eq!(o.code, Some(0), "{}", o.stderr);
    let ds = gdal::Dataset::open(dir.join("out_ortho/toa_brf.tif")).unwrap();
    let g = ds.geo_transform().unwrap();
    let (w, h) = ds.raster_size();
    let v = ds.rasterband(1).unwrap().read_band_as::<f64>().unwrap();
    let (mut inside, mut outside) = (0, 0);
    for (k, b) in v.data().iter().enumerate() {
        let x = g[0] + ((k % w) as f64 + 0.5) * g[1];
        let y = g[3] + ((k / w) as f64 + 0.5) * g[5];
        // The image spans the polygon's bounding box, so relative to the image centre the
        // triangle is x > y, |x|, |y| < 1500 m.
        let (cx, cy) = (
            x - (g[0] + 0.5 * w as f64 * g[1]),
            y - (g[3] + 0.5 * h as f64 * g[5]),
        );
        let margin = 0.75 * g[1];
        if cx - cy > g[1] && cx.abs() < 1500.0 - 0.5 * g[1] && cy.abs() < 1500.0 - 0.5 * g[1] {
            assert!(
                b.is_finite() && *b > 0.3,
                "pixel {k} inside the triangle: {b}"
            );
            inside += 1;
        } else if cy - cx > margin || cx.abs() > 1500.0 + margin || cy.abs() > 1500.0 + margin {
            assert!(b.is_nan(), "pixel {k} outside the triangle: {b}");
            outside += 1;
        }
    }
    assert!(
        inside > 3 && outside > 3,
        "{inside} inside, {outside} outside"
    );

    // A target area entirely outside the polygon (north-west corner) is refused.
    std::fs::write(
        dir.join("out_exp.toml"),
        exp("poly", "target_m = [-1400.0, 900.0, -900.0, 1400.0]\n"),
    )
    .unwrap();
    let o = run(
        &simulate,
        &s(&["run", "out_exp.toml", "-o", "out_out", "-q"]),
        &dir,
    );
    assert_eq!(o.code, Some(2), "{}", o.stderr);
    assert!(
        o.stderr.contains("measures[0].target_m") && o.stderr.contains("area polygon"),
        "{}",
        o.stderr
    );
    let _ = std::fs::remove_dir_all(&dir);
}
