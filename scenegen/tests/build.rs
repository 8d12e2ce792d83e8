//! End-to-end tests of `scenegen build` on synthetic GeoTIFFs written through GDAL (the same
//! reading path as real data): terrain tolerance at every DEM node, watertight tiles, material
//! raster = scheme mapping, deterministic instances on the terrain, and the bad-input errors
//! with their exit codes. Each test states its rationale.

mod common;
use common::{scenegen, shared_data, tmp};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use bundle::{Bundle, NO_MATERIAL};
use scenegen::raster::{self, WorkingFrame};
use scenegen::region::Region;
use scenegen::synth::write_geotiff;

const LON: f64 = 5.7;
const LAT: f64 = 45.2;
const LOCAL: &str =
    "+proj=tmerc +lat_0=45.2 +lon_0=5.7 +k=1 +x_0=0 +y_0=0 +datum=WGS84 +units=m +no_defs";

/// A hilly DEM in EPSG:4326 (so the build reprojects), 0.0004° pixels, around (LON, LAT),
/// covering ±0.06° — more than the 6 km area.
fn write_dem(dir: &Path, hole: Option<(usize, usize, usize)>) -> PathBuf {
    write_dem_cols(dir, "dem.tif", hole, 0..300)
}

/// The same DEM restricted to columns `cols` (for several-file tests).
fn write_dem_cols(
    dir: &Path,
    name: &str,
    hole: Option<(usize, usize, usize)>,
    cols: std::ops::Range<usize>,
) -> PathBuf {
    let (w, h) = (300, 300);
    let px = 0.0004;
    let (lon0, lat1) = (LON - 0.06, LAT + 0.06);
    let mut v = vec![0f32; w * h];
    for r in 0..h {
        for c in 0..w {
            let x = (c as f64 + 0.5) * px * 78_700.0;
            let y = (h - r) as f64 * px * 111_200.0;
            v[r * w + c] =
                (500.0 + 150.0 * (x / 1500.0).sin() * (y / 2100.0).cos() + 0.01 * x) as f32;
        }
    }
    if let Some((r0, c0, n)) = hole {
        for r in r0..r0 + n {
            for c in c0..c0 + n {
                v[r * w + c] = -32768.0;
            }
        }
    }
    let p = dir.join(name);
    let cw = cols.len();
    let sub: Vec<f32> = (0..h)
        .flat_map(|r| v[r * w + cols.start..r * w + cols.end].to_vec())
        .collect();
    let west = lon0 + cols.start as f64 * px;
    write_geotiff(
        &p,
        cw,
        h,
        Some([west, px, 0.0, lat1, 0.0, -px]),
        Some("EPSG:4326"),
        Some(-32768.0),
        sub,
    )
    .unwrap();
    p
}

/// A hand-made CORINE land cover on exactly the material grid (local frame, 100 m cells,
/// x, y ∈ [−3000, 3000] m), so that nearest resampling reads each cell's own code.
fn landcover_codes() -> Vec<u8> {
    let codes = [12u8, 18, 23, 24, 41, 2];
    (0..60 * 60)
        .map(|k| codes[(k / 60 / 10 + k % 60 / 7) % codes.len()])
        .collect()
}

fn write_landcover(dir: &Path, codes: Vec<u8>) -> PathBuf {
    let p = dir.join("lc.tif");
    write_geotiff(
        &p,
        60,
        60,
        Some([-3000.0, 100.0, 0.0, 3000.0, 0.0, -100.0]),
        Some(LOCAL),
        Some(255.0),
        codes,
    )
    .unwrap();
    p
}

fn region_text(extra: &str) -> String {
    format!(
        r#"seed = 11
[area]
centre = [{LON}, {LAT}]
size_km = 6
[dem]
files = ["dem.tif"]
spacing_m = 30
[terrain]
tolerance_m = 2.0
tile_size_m = 2000
[landcover]
file = "lc.tif"
scheme = "corine"
resampling = "nearest"
{extra}"#
    )
}

fn setup(name: &str, extra: &str) -> (PathBuf, PathBuf) {
    let dir = tmp(name);
    write_dem(&dir, None);
    write_landcover(&dir, landcover_codes());
    let region = dir.join("region.toml");
    std::fs::write(&region, region_text(extra)).unwrap();
    (dir, region)
}

fn build(region: &Path, out: &Path) -> Bundle {
    let (code, stdout, stderr) = scenegen(&[
        "build",
        "--quiet",
        "-o",
        out.to_str().unwrap(),
        region.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "stdout {stdout}\nstderr {stderr}");
    Bundle::open(out).unwrap()
}

/// Height of the bundle's terrain at local (x, y), by brute force over all tiles' triangles
/// (independent of spade).
fn terrain_height(b: &Bundle, x: f64, y: f64) -> Option<f64> {
    for t in &b.terrain {
        for tri in &t.indices {
            let p = tri.map(|i| {
                let q = t.positions[i as usize];
                [
                    t.origin[0] + q[0] as f64,
                    t.origin[1] + q[1] as f64,
                    t.origin[2] + q[2] as f64,
                ]
            });
            let det = (p[1][1] - p[2][1]) * (p[0][0] - p[2][0])
                + (p[2][0] - p[1][0]) * (p[0][1] - p[2][1]);
            let l1 =
                ((p[1][1] - p[2][1]) * (x - p[2][0]) + (p[2][0] - p[1][0]) * (y - p[2][1])) / det;
            let l2 =
                ((p[2][1] - p[0][1]) * (x - p[2][0]) + (p[0][0] - p[2][0]) * (y - p[2][1])) / det;
            let l3 = 1.0 - l1 - l2;
            if l1 >= -1e-9 && l2 >= -1e-9 && l3 >= -1e-9 {
                return Some(l1 * p[0][2] + l2 * p[1][2] + l3 * p[2][2]);
            }
        }
    }
    None
}

/// Rationale: the issue's core properties on one real GDAL build. (1) Every DEM node of the
/// working grid lies within the tolerance of the stored terrain (read back from the bundle and
/// interpolated by brute force). (2) The tiles are watertight: in world coordinates every edge
/// is used by two triangles in opposite directions, except edges on the outer boundary. (3) The
/// material raster equals the scheme mapping of the hand-made land cover cell by cell. (4) Every
/// instance sits on the terrain surface, inside the land-cover tile it was placed for (the tile
/// has a class with a population rule).
#[test]
fn build_honours_tolerance_watertight_materials_and_instances() {
    let (dir, region) = setup("main", "");
    let out = dir.join("bundle");
    let b = build(&region, &out);
    let m = &b.manifest;
    assert!(
        m.terrain.tiles.len() >= 9,
        "6 km / 2 km tiles: {}",
        m.terrain.tiles.len()
    );
    let origin = m.frame.origin;

    // (1) Tolerance at every DEM node (the same warped grid the build used).
    let r = Region::load(&region).unwrap();
    let frame = WorkingFrame::new(&r).unwrap();
    let dem = raster::load_dem(&r, &frame).unwrap();
    let g = dem.grid;
    let mut worst = 0.0f64;
    for row in (0..g.height).step_by(3) {
        for col in 0..g.width {
            let (x, y) = (g.x(col) - origin[0], g.y(row) - origin[1]);
            let z = terrain_height(&b, x, y)
                .unwrap_or_else(|| panic!("node ({col}, {row}) not covered"));
            worst = worst.max((z - dem.heights[row * g.width + col] as f64).abs());
        }
    }
    assert!(
        worst <= 2.0 + 1e-3,
        "worst vertical error {worst} m > tolerance 2 m"
    );
    assert!(
        (m.terrain.vertex_count as usize) < g.width * g.height / 2,
        "the TIN must be sparser than the grid"
    );

    // (2) Watertight.
    let key = |t: &bundle::TerrainTile, i: u32| {
        let q = t.positions[i as usize];
        [
            (t.origin[0] + q[0] as f64).to_bits(),
            (t.origin[1] + q[1] as f64).to_bits(),
        ]
    };
    let mut directed: HashMap<([u64; 2], [u64; 2]), u32> = HashMap::new();
    for t in &b.terrain {
        for tri in &t.indices {
            for k in 0..3 {
                *directed
                    .entry((key(t, tri[k]), key(t, tri[(k + 1) % 3])))
                    .or_default() += 1;
            }
        }
    }
    let (xmin, xmax) = (m.extent.min[0] - origin[0], m.extent.max[0] - origin[0]);
    let (ymin, ymax) = (m.extent.min[1] - origin[1], m.extent.max[1] - origin[1]);
    let on_boundary = |a: [u64; 2], b: [u64; 2]| {
        let (ax, ay, bx, by) = (
            f64::from_bits(a[0]),
            f64::from_bits(a[1]),
            f64::from_bits(b[0]),
            f64::from_bits(b[1]),
        );
        (ax == xmin && bx == xmin)
            || (ax == xmax && bx == xmax)
            || (ay == ymin && by == ymin)
            || (ay == ymax && by == ymax)
    };
    let mut open = 0;
    for (&(a, bb), &n) in &directed {
        assert_eq!(n, 1, "edge used twice in the same direction");
        if !directed.contains_key(&(bb, a)) && !on_boundary(a, bb) {
            open += 1;
        }
    }
    assert_eq!(open, 0, "{open} open edges inside the terrain");

    // (3) Material raster = scheme mapping of the hand-made raster.
    let scheme = landcover::Scheme::load("corine").unwrap();
    let map = landcover::MaterialMap::new(&scheme, &Default::default(), &Default::default(), None)
        .unwrap();
    assert_eq!(
        (m.material_raster.width, m.material_raster.height),
        (60, 60)
    );
    for (k, (&got, &code)) in b
        .material_raster
        .iter()
        .zip(landcover_codes().iter())
        .enumerate()
    {
        let want = map.code_to_index[&(code as i64)];
        assert_eq!(got, want, "cell {k}: code {code}");
        assert_eq!(
            m.materials[got as usize].name,
            map.materials[want as usize].name
        );
    }

    // (4) Instances on the terrain, in a populated tile.
    assert!(!b.instances.is_empty());
    let gt = m.material_raster.geotransform;
    let codes = landcover_codes();
    let populated: Vec<i64> = scheme
        .population
        .iter()
        .flat_map(|r| r.classes.clone())
        .collect();
    for inst in b.instances.iter().step_by(7) {
        let [x, y, z] = inst.translation;
        let zt = terrain_height(&b, x, y).expect("instance over the terrain");
        assert!((z - zt).abs() < 1e-3, "instance at z {z}, terrain {zt}");
        let col = ((x + origin[0] - gt[0]) / gt[1]).floor() as usize;
        let row = ((y + origin[1] - gt[3]) / gt[5]).floor() as usize;
        assert!(
            populated.contains(&(codes[row * 60 + col] as i64)),
            "instance in a tile of class {}",
            codes[row * 60 + col]
        );
    }
    assert!(b.material_raster.iter().all(|&v| v != NO_MATERIAL));

    // `info` fails, naming the file, on a copy with a buffer deleted (issue 15).
    let damaged = dir.join("damaged");
    std::fs::create_dir_all(&damaged).unwrap();
    for e in std::fs::read_dir(&out).unwrap() {
        let e = e.unwrap();
        std::fs::copy(e.path(), damaged.join(e.file_name())).unwrap();
    }
    std::fs::remove_file(damaged.join("instances.bin")).unwrap();
    let (code, _, stderr) = scenegen(&["info", damaged.to_str().unwrap()]);
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains("instances.bin"), "{stderr}");

    // info and glTF export run on it.
    let (code, info, _) = scenegen(&["info", out.to_str().unwrap(), "--verify"]);
    assert_eq!(code, 0);
    assert!(
        info.contains("triangles") && info.contains("forest_floor") && info.contains("verify"),
        "{info}"
    );
    check_gltf_export(&b, &out, &dir);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Instances exported to a GLB with `EXT_mesh_gpu_instancing`: `n` per template.
fn gltf_instance_counts(glb: &Path, templates: usize) -> Vec<usize> {
    let g = gltf::Gltf::open(glb).unwrap();
    assert!(g.extensions_used().any(|e| e == "EXT_mesh_gpu_instancing"));
    let accessors: Vec<gltf::Accessor> = g.accessors().collect();
    let mut counts = vec![0; templates];
    let terrain_meshes = g.meshes().count() - templates;
    for node in g.nodes() {
        let Some(ext) = node.extension_value("EXT_mesh_gpu_instancing") else {
            continue;
        };
        let k = node.mesh().unwrap().index() - terrain_meshes;
        let attr = |name: &str| {
            let i = ext["attributes"][name].as_u64().unwrap() as usize;
            accessors[i].count()
        };
        let n = attr("TRANSLATION");
        assert_eq!(attr("ROTATION"), n);
        assert_eq!(attr("SCALE"), n);
        counts[k] += n;
    }
    counts
}

/// Rationale: a viewer must show every instance of the bundle (issue: the export used to keep
/// every 26th as nodes). The GLB parses with the `gltf` crate, its instance count per template
/// equals the bundle's, `--thin N` keeps every N-th, and the Khronos validator (when
/// `gltf_validator` is on PATH) reports no error.
fn check_gltf_export(b: &Bundle, out: &Path, dir: &Path) {
    let glb = dir.join("scene.glb");
    let (code, _, stderr) =
        scenegen(&["export-gltf", out.to_str().unwrap(), glb.to_str().unwrap()]);
    assert_eq!(code, 0, "{stderr}");
    let g = gltf::Gltf::open(&glb).unwrap();
    assert_eq!(g.meshes().count(), b.terrain.len() + b.templates.len());
    let mut want = vec![0; b.templates.len()];
    for i in &b.instances {
        want[i.template as usize] += 1;
    }
    assert!(b.instances.len() > 100, "{} instances", b.instances.len());
    assert_eq!(gltf_instance_counts(&glb, b.templates.len()), want);

    let thin = dir.join("thin.glb");
    let (code, _, stderr) = scenegen(&[
        "export-gltf",
        out.to_str().unwrap(),
        thin.to_str().unwrap(),
        "--thin",
        "7",
    ]);
    assert_eq!(code, 0, "{stderr}");
    assert!(stderr.contains("every 7-th"), "{stderr}");
    let total: usize = gltf_instance_counts(&thin, b.templates.len()).iter().sum();
    assert_eq!(total, b.instances.len().div_ceil(7));

    let validator = std::env::var_os("PATH").and_then(|p| {
        std::env::split_paths(&p)
            .map(|d| d.join("gltf_validator"))
            .find(|f| f.is_file())
    });
    let Some(validator) = validator else {
        println!("skipped the Khronos glTF validator: `gltf_validator` is not on PATH");
        return;
    };
    let o = Command::new(validator)
        .arg("-o")
        .arg(&glb)
        .output()
        .unwrap();
    let report = String::from_utf8_lossy(&o.stdout);
    let v: serde_json::Value =
        serde_json::from_str(&report).unwrap_or_else(|e| panic!("validator report: {e}\n{report}"));
    assert_eq!(
        v["issues"]["numErrors"].as_u64(),
        Some(0),
        "{}",
        serde_json::to_string_pretty(&v["issues"]).unwrap()
    );
    println!(
        "Khronos glTF validator: 0 errors, {} warnings",
        v["issues"]["numWarnings"]
    );
}

/// Rationale: instance placement must be a function of the seed: same seed, same bytes
/// (whatever the thread count); another seed, other instances.
#[test]
fn instances_are_deterministic_for_a_seed() {
    let (dir, region) = setup("seed", "");
    let a = build(&region, &dir.join("a"));
    let (code, _, _) = scenegen(&[
        "build",
        "--quiet",
        "-j",
        "1",
        "-o",
        dir.join("b").to_str().unwrap(),
        region.to_str().unwrap(),
    ]);
    assert_eq!(code, 0);
    let b = Bundle::open(&dir.join("b")).unwrap();
    assert_eq!(a.instances, b.instances);
    std::fs::write(&region, region_text("").replace("seed = 11", "seed = 12")).unwrap();
    let c = build(&region, &dir.join("c"));
    assert_ne!(a.instances, c.instances);
    assert_eq!(a.terrain, c.terrain, "the seed does not change the terrain");
    std::fs::remove_dir_all(&dir).unwrap();
}

fn expect_error(region: &Path, out: &Path, code: i32, needles: &[&str]) {
    let (c, _, stderr) = scenegen(&[
        "build",
        "--quiet",
        "-o",
        out.to_str().unwrap(),
        region.to_str().unwrap(),
    ]);
    assert_eq!(c, code, "{stderr}");
    for n in needles {
        assert!(stderr.contains(n), "stderr lacks `{n}`: {stderr}");
    }
    assert!(!out.exists(), "no half bundle after an error");
    let parent = out.parent().unwrap();
    assert!(
        std::fs::read_dir(parent).unwrap().all(|e| !e
            .unwrap()
            .file_name()
            .to_string_lossy()
            .contains(".tmp-")),
        "no temporary directory left"
    );
}

/// Rationale: each bad input named in the issue gives exit code 2 and a message naming the
/// file and what is wrong; nothing is written.
#[test]
fn bad_inputs_are_named() {
    let (dir, region) = setup("errors", "");
    let out = dir.join("out");

    // Missing DEM file.
    std::fs::write(&region, region_text("").replace("dem.tif", "missing.tif")).unwrap();
    expect_error(&region, &out, 2, &["missing.tif", "not found"]);

    // DEM that does not cover the area (a 10 km area needs ±0.064° in longitude).
    std::fs::write(
        &region,
        region_text("").replace("size_km = 6", "size_km = 12"),
    )
    .unwrap();
    expect_error(
        &region,
        &out,
        2,
        &[
            "dem.tif",
            "does not cover the area of interest",
            "km) on the west",
        ],
    );

    // DEM without georeferencing.
    let nogeo = dir.join("nogeo.tif");
    write_geotiff(&nogeo, 10, 10, None, None, None, vec![1f32; 100]).unwrap();
    std::fs::write(
        &region,
        region_text("").replace("\"dem.tif\"", "\"nogeo.tif\""),
    )
    .unwrap();
    expect_error(&region, &out, 2, &["nogeo.tif", "no georeferencing"]);

    // A no-data hole too large to fill, with its size and location.
    let holes = tmp("holes");
    write_dem(&holes, Some((140, 140, 20)));
    std::fs::rename(holes.join("dem.tif"), dir.join("holes.tif")).unwrap();
    std::fs::write(
        &region,
        region_text("").replace("\"dem.tif\"", "\"holes.tif\""),
    )
    .unwrap();
    expect_error(
        &region,
        &out,
        2,
        &[
            "holes.tif",
            "no-data holes too large",
            "pixels",
            "lon ",
            "max_fill_pixels",
        ],
    );
    // … and a small one is filled.
    write_dem(&holes, Some((140, 140, 2)));
    std::fs::rename(holes.join("dem.tif"), dir.join("small_hole.tif")).unwrap();
    std::fs::write(
        &region,
        region_text("").replace("\"dem.tif\"", "\"small_hole.tif\""),
    )
    .unwrap();
    build(&region, &dir.join("filled"));

    // Unknown class codes, with pixel counts; a fallback accepts them.
    let mut codes = landcover_codes();
    codes[0] = 99;
    codes[1] = 99;
    codes[2] = 77;
    write_landcover(&dir, codes);
    std::fs::write(&region, region_text("")).unwrap();
    expect_error(
        &region,
        &out,
        2,
        &["lc.tif", "99 (2 px)", "77 (1 px)", "fallback_material"],
    );
    std::fs::write(&region, region_text("fallback_material = \"soil\"")).unwrap();
    build(&region, &dir.join("fallback"));
    write_landcover(&dir, landcover_codes());

    // A template file that fails to load.
    std::fs::write(dir.join("broken.glb"), b"not a glb").unwrap();
    let extra = "\n[[templates]]\nname = \"broken\"\nfile = \"broken.glb\"\n\n[[population]]\nclasses = [12]\ntemplate = \"broken\"\ndensity_per_ha = 1\n";
    std::fs::write(&region, region_text(extra)).unwrap();
    expect_error(
        &region,
        &out,
        2,
        &["broken.glb", "cannot load template mesh"],
    );

    // Misspelt and out-of-range keys.
    std::fs::write(
        &region,
        region_text("").replace("tolerance_m = 2.0", "tolerence_m = 2.0"),
    )
    .unwrap();
    expect_error(&region, &out, 2, &["region.toml", "tolerence_m"]);
    std::fs::write(
        &region,
        region_text("").replace("tile_size_m = 2000", "tile_size_m = 5"),
    )
    .unwrap();
    expect_error(&region, &out, 2, &["region.toml", "terrain.tile_size_m"]);
    std::fs::write(
        &region,
        region_text("").replace("scheme = \"corine\"", "scheme = \"corrine\""),
    )
    .unwrap();
    expect_error(&region, &out, 2, &["landcover.scheme", "corrine"]);

    // Existing output directory: refused without --force, replaced with it.
    std::fs::write(&region, region_text("")).unwrap();
    std::fs::create_dir_all(&out).unwrap();
    let (c, _, stderr) = scenegen(&[
        "build",
        "--quiet",
        "-o",
        out.to_str().unwrap(),
        region.to_str().unwrap(),
    ]);
    assert_eq!(c, 2, "{stderr}");
    assert!(
        stderr.contains("already exists") && stderr.contains("--force"),
        "{stderr}"
    );
    let (c, _, stderr) = scenegen(&[
        "build",
        "--quiet",
        "--force",
        "-o",
        out.to_str().unwrap(),
        region.to_str().unwrap(),
    ]);
    assert_eq!(c, 0, "{stderr}");
    Bundle::open(&out).unwrap();
    // --force never empties a folder that is not a bundle: exit 2, the folder named, its data
    // intact (and the refusal comes before any work).
    let data = dir.join("my_data");
    std::fs::create_dir_all(&data).unwrap();
    std::fs::write(data.join("results.csv"), "keep me").unwrap();
    let (c, _, stderr) = scenegen(&[
        "build",
        "--quiet",
        "--force",
        "-o",
        data.to_str().unwrap(),
        region.to_str().unwrap(),
    ]);
    assert_eq!(c, 2, "{stderr}");
    assert!(
        stderr.contains("my_data") && stderr.contains("is not a scene bundle"),
        "{stderr}"
    );
    assert_eq!(
        std::fs::read_to_string(data.join("results.csv")).unwrap(),
        "keep me"
    );

    // An output that cannot be written (parent is a file; a full disk fails the same way, on
    // a write): exit code 1, the path named, no temporary directory left.
    let blocker = dir.join("file");
    std::fs::write(&blocker, b"x").unwrap();
    let (c, _, stderr) = scenegen(&[
        "build",
        "--quiet",
        "-o",
        blocker.join("out").to_str().unwrap(),
        region.to_str().unwrap(),
    ]);
    assert_eq!(c, 1, "{stderr}");
    assert!(
        stderr.contains("cannot write") && stderr.contains("file"),
        "{stderr}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
    std::fs::remove_dir_all(&holes).unwrap();
}

/// Rationale: several DEM files are merged (the first has priority, later ones fill its no
/// data): two halves give the same terrain as the whole; one half alone is refused as not
/// covering the area.
#[test]
fn several_dems_are_merged() {
    let (dir, region) = setup("multi", "");
    let whole = build(&region, &dir.join("whole"));
    write_dem_cols(&dir, "west.tif", None, 0..160);
    write_dem_cols(&dir, "east.tif", None, 140..300);
    std::fs::write(
        &region,
        region_text("").replace(
            "files = [\"dem.tif\"]",
            "files = [\"west.tif\", \"east.tif\"]",
        ),
    )
    .unwrap();
    let merged = build(&region, &dir.join("merged"));
    assert_eq!(whole.terrain, merged.terrain);
    std::fs::write(
        &region,
        region_text("").replace("files = [\"dem.tif\"]", "files = [\"west.tif\"]"),
    )
    .unwrap();
    expect_error(
        &region,
        &dir.join("out"),
        2,
        &["west.tif", "does not cover", "on the east"],
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Rationale: real data through every other code path — the SRTM sample (EPSG:4326, int16,
/// nodata −32768) warped into a user-named working CRS (UTM 37N), and a 20 m ESA WorldCover
/// raster in that CRS reduced to 100 m cells by `mode` (auto: a cell spans 5 source pixels).
/// The land cover is 1 km stripes of tree cover, grassland and water; the material shares
/// must follow the stripes (a third each, within the stripes' edge effects).
#[test]
fn srtm_with_worldcover_in_a_named_crs() {
    let Some(shared) = shared_data() else { return };
    let dir = tmp("srtm");
    // Area: 40.3–40.6° E, 39.4–39.7° N, inside the sample (40.0–40.83° E, 39.17–40.0° N).
    // UTM 37N easting/northing bounds of it, with a margin, for the land cover.
    let (e0, n0, e1, n1) = (595_000.0, 4_350_000.0, 655_000.0, 4_405_000.0);
    let px = 20.0;
    let (w, h) = (((e1 - e0) / px) as usize, ((n1 - n0) / px) as usize);
    let classes = [10u8, 30, 80];
    let lc: Vec<u8> = (0..w * h)
        .map(|k| classes[((k % w) as f64 * px / 1000.0) as usize % 3])
        .collect();
    write_geotiff(
        &dir.join("wc.tif"),
        w,
        h,
        Some([e0, px, 0.0, n1, 0.0, -px]),
        Some("EPSG:32637"),
        Some(0.0),
        lc,
    )
    .unwrap();
    let dem = shared.join("terrain/srtm_sample/srtm_ref.tif");
    let region = dir.join("region.toml");
    std::fs::write(
        &region,
        format!(
            "crs = \"EPSG:32637\"\n[area]\nbbox = [40.3, 39.4, 40.6, 39.7]\n[dem]\nfiles = [\"{}\"]\n[terrain]\ntolerance_m = 5\n[landcover]\nfile = \"wc.tif\"\nscheme = \"esa_worldcover\"\n",
            dem.display()
        ),
    )
    .unwrap();
    let b = build(&region, &dir.join("bundle"));
    let m = &b.manifest;
    assert_eq!(m.crs.epsg, Some(32637));
    assert_eq!(m.material_raster.resampling, "mode");
    assert!(
        m.extent.height_range[0] > 1000.0 && m.extent.height_range[1] < 3300.0,
        "{:?}",
        m.extent.height_range
    );
    let total = b.material_raster.len() as f64;
    for name in ["forest_floor", "grass", "water"] {
        let idx = m.materials.iter().find(|x| x.name == name).unwrap().index;
        let share = b.material_raster.iter().filter(|&&v| v == idx).count() as f64 / total;
        assert!((share - 1.0 / 3.0).abs() < 0.05, "{name}: share {share}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Rationale: the documented example builds from the real Copernicus DEM and its derived land
/// cover, with the glTF template from the shared meshes, and its numbers stay those its README
/// states (DEM grid, materials, templates).
#[test]
fn grenoble_example_builds() {
    if shared_data().is_none() {
        return;
    }
    let dir = tmp("grenoble");
    let region = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/grenoble/region.toml");
    let b = build(&region, &dir.join("bundle"));
    let m = &b.manifest;
    assert_eq!(m.terrain.dem_samples, 201 * 225);
    assert_eq!(m.templates.len(), 5);
    let citrus = m.templates.iter().find(|t| t.name == "citrus").unwrap();
    assert_eq!(
        citrus.triangle_count,
        22044 + 17206,
        "foliage and trunk merged"
    );
    assert_eq!(m.materials.len(), 15);
    assert!(
        m.instances.per_template.iter().all(|&n| n > 0),
        "{:?}",
        m.instances.per_template
    );
    assert_eq!(
        m.provenance.inputs.len(),
        5,
        "DEM, land cover, GLB, two PLY parts"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
