//! Real places from observed data (`../shared/data/real_regions`, MANIFEST §14): the Zion example
//! (SRTM + NLCD through the built-in `nlcd` scheme), vector land cover (the Slovenian land-use
//! polygons against the raster made from the same map), and the errors of bad vector inputs.
//! Tests that read the shared data skip, saying so, when it is absent.

mod common;
use common::{scenegen, shared_data, tmp};
use std::path::{Path, PathBuf};

use bundle::Bundle;
use gdal::spatial_ref::{AxisMappingStrategy, CoordTransform, SpatialRef};

fn build(region: &Path, out: &Path) -> (Bundle, String) {
    let (code, stdout, stderr) = scenegen(&[
        "build",
        "--quiet",
        "--force",
        "-o",
        out.to_str().unwrap(),
        region.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "stdout {stdout}\nstderr {stderr}");
    (Bundle::open(out).unwrap(), stderr)
}

/// Rationale: the README's main job uses observed land cover only. Every material cell of the
/// Zion bundle must hold the material that the `nlcd` scheme gives to the NLCD 2011 class found
/// by an independent lookup: the cell centre transformed by PROJ into the NLCD's CRS (UTM 12N)
/// and the source pixel containing it read directly (no warper). Cells whose centre lies within
/// a few metres of an NLCD pixel edge may go either way (GDAL's warper approximates the
/// transformation to 1/8 pixel), so the agreement must be ≥ 99 %, and the classes present must
/// all be mapped (the build has no fallback material).
#[test]
fn zion_example_cells_hold_the_nlcd_class_material() {
    let Some(shared) = shared_data() else { return };
    let dir = tmp("zion");
    let region = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/zion/region.toml");
    let (b, _) = build(&region, &dir.join("bundle"));
    let m = &b.manifest;
    assert_eq!(m.material_raster.resampling, "nearest");

    let nlcd = gdal::Dataset::open(shared.join("real_regions/zion/nlcd2011.tif")).unwrap();
    let ngt = nlcd.geo_transform().unwrap();
    let (nw, nh) = nlcd.raster_size();
    let codes: Vec<u8> = nlcd
        .rasterband(1)
        .unwrap()
        .read_band_as::<u8>()
        .unwrap()
        .into_shape_and_vec()
        .1;
    let mut src = SpatialRef::from_wkt(&m.crs.wkt).unwrap();
    src.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
    let mut dst = nlcd.spatial_ref().unwrap();
    dst.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
    let t = CoordTransform::new(&src, &dst).unwrap();

    let scheme = landcover::Scheme::load("nlcd").unwrap();
    let index_of = |name: &str| m.materials.iter().find(|x| x.name == name).unwrap().index;
    let (w, h) = (
        m.material_raster.width as usize,
        m.material_raster.height as usize,
    );
    let gt = m.material_raster.geotransform;
    let (mut xs, mut ys) = (Vec::with_capacity(w * h), Vec::with_capacity(w * h));
    for r in 0..h {
        for c in 0..w {
            xs.push(gt[0] + (c as f64 + 0.5) * gt[1]);
            ys.push(gt[3] + (r as f64 + 0.5) * gt[5]);
        }
    }
    t.transform_coords(&mut xs, &mut ys, &mut []).unwrap();
    let (mut agree, mut total) = (0usize, 0usize);
    let mut unmapped = std::collections::BTreeSet::new();
    for k in 0..w * h {
        let col = ((xs[k] - ngt[0]) / ngt[1]).floor();
        let row = ((ys[k] - ngt[3]) / ngt[5]).floor();
        assert!(
            col >= 0.0 && row >= 0.0 && (col as usize) < nw && (row as usize) < nh,
            "cell {k} outside the NLCD raster"
        );
        let code = codes[row as usize * nw + col as usize] as i64;
        let Some(class) = scheme.classes.iter().find(|c| c.code == code) else {
            unmapped.insert(code);
            continue;
        };
        total += 1;
        if b.material_raster[k] == index_of(&class.material) {
            agree += 1;
        }
    }
    assert!(
        unmapped.is_empty(),
        "NLCD codes not in the scheme: {unmapped:?}"
    );
    let share = agree as f64 / total as f64;
    eprintln!("zion: {agree} of {total} cells agree with a direct NLCD lookup ({share:.4})");
    assert!(share >= 0.99, "agreement {share}");
    // Zion's cover: pinyon-juniper forest and shrub dominate, sandstone is the rest.
    let share_of = |name: &str| {
        let i = index_of(name);
        b.material_raster.iter().filter(|&&v| v == i).count() as f64 / (w * h) as f64
    };
    assert!(share_of("forest_floor") + share_of("shrub") > 0.8);
    assert!(share_of("rock") > 0.05);
    assert!(m.instances.per_template.iter().sum::<u64>() > 100_000);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Region text for the Slovenian patch; `landcover` is the body of its `[landcover]` table.
fn slovenia_region(shared: &Path, landcover: &str) -> String {
    let scheme =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/slovenia/lulc_scheme.toml");
    format!(
        "seed = 3\ncrs = \"EPSG:32633\"\n[area]\ncentre = [14.55775, 45.8704]\nsize_km = 0.9\n[dem]\nfiles = [\"{}\"]\n[terrain]\ntolerance_m = 0.5\ntile_size_m = 500\n[landcover]\nscheme = \"{}\"\ntile_size_m = 10\nfallback_material = \"grass\"\n{landcover}\n",
        shared.join("real_regions/slovenia/DEM_32633.tif").display(),
        scheme.display()
    )
}

/// Rationale: the Slovenian land-use map exists both as 88 polygons (`LULC.gpkg`) and as the
/// 10 m raster eo-learn rasterised from them (`LULC_32633.tif`, on a grid offset from ours by a
/// fraction of a cell). Burnt by our vector path at the cell centres, the polygons must give the
/// raster's class in ≥ 95 % of the cells, and every other cell's class must occur among the
/// raster build's 3 × 3 neighbours (a boundary moved by less than a cell) except for ≤ 0.1 %.
/// The example (mode of 4 × 4 samples) builds too.
#[test]
fn slovenia_polygons_match_their_raster() {
    let Some(shared) = shared_data() else { return };
    let dir = tmp("slovenia");
    let gpkg = shared.join("real_regions/slovenia/vector_timeless/LULC.gpkg");
    let rv = dir.join("vector.toml");
    std::fs::write(
        &rv,
        slovenia_region(
            &shared,
            &format!(
                "resampling = \"nearest\"\n[[landcover.vector]]\nfile = \"{}\"\nattribute = \"LULC_ID\"\n",
                gpkg.display()
            ),
        ),
    )
    .unwrap();
    let rr = dir.join("raster.toml");
    std::fs::write(
        &rr,
        slovenia_region(
            &shared,
            &format!(
                "resampling = \"nearest\"\nfile = \"{}\"\n",
                shared
                    .join("real_regions/slovenia/LULC_32633.tif")
                    .display()
            ),
        ),
    )
    .unwrap();
    let (bv, _) = build(&rv, &dir.join("bv"));
    let (br, _) = build(&rr, &dir.join("br"));
    assert_eq!(
        bv.manifest.material_raster.resampling,
        "polygons: cell centre"
    );
    let w = bv.manifest.material_raster.width as usize;
    let h = bv.manifest.material_raster.height as usize;
    assert_eq!(
        bv.manifest.material_raster.geotransform,
        br.manifest.material_raster.geotransform
    );
    let (v, r) = (&bv.material_raster, &br.material_raster);
    let (mut diff, mut unexplained) = (0, 0);
    for k in 0..w * h {
        if v[k] != r[k] {
            diff += 1;
            let (y, x) = ((k / w) as i64, (k % w) as i64);
            let near = (-1..=1).any(|dy| {
                (-1..=1).any(|dx| {
                    let (yy, xx) = (y + dy, x + dx);
                    yy >= 0
                        && xx >= 0
                        && (yy as usize) < h
                        && (xx as usize) < w
                        && r[yy as usize * w + xx as usize] == v[k]
                })
            });
            if !near {
                unexplained += 1;
            }
        }
    }
    eprintln!(
        "slovenia: {diff} of {} cells differ, {unexplained} not at a boundary",
        w * h
    );
    assert!(diff as f64 <= 0.05 * (w * h) as f64);
    assert!(unexplained as f64 <= 0.001 * (w * h) as f64);

    let example = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/slovenia/region.toml");
    let (b, _) = build(&example, &dir.join("example"));
    assert_eq!(
        b.manifest.material_raster.resampling,
        "polygons: mode of 4 × 4 samples"
    );
    assert!(b
        .manifest
        .provenance
        .inputs
        .iter()
        .any(|i| i.role == "landcover_vector" && i.path.ends_with("LULC.gpkg")));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A synthetic DEM (flat, 1 km around 5° E 45° N) for the vector tests that need no shared data.
fn flat_dem(dir: &Path) -> PathBuf {
    let p = dir.join("dem.tif");
    let (w, h) = (40, 40);
    scenegen::synth::write_geotiff(
        &p,
        w,
        h,
        Some([4.98, 0.001, 0.0, 45.02, 0.0, -0.001]),
        Some("EPSG:4326"),
        None,
        vec![300f32; w * h],
    )
    .unwrap();
    p
}

fn geojson(features: &[(&str, &str)]) -> String {
    let f: Vec<String> = features
        .iter()
        .map(|(props, coords)| {
            format!(
                "{{\"type\":\"Feature\",\"properties\":{{{props}}},\"geometry\":{{\"type\":\"Polygon\",\"coordinates\":{coords}}}}}"
            )
        })
        .collect();
    format!(
        "{{\"type\":\"FeatureCollection\",\"features\":[{}]}}",
        f.join(",")
    )
}

const WEST: &str = "[[[4.99,44.99],[5.0,44.99],[5.0,45.01],[4.99,45.01],[4.99,44.99]]]";
const EAST: &str = "[[[5.0,44.99],[5.01,44.99],[5.01,45.01],[5.0,45.01],[5.0,44.99]]]";
/// A bow tie: its two edges cross at (5.0, 45.0).
const BOWTIE: &str = "[[[4.99,44.99],[5.01,45.01],[5.01,44.99],[4.99,45.01],[4.99,44.99]]]";

fn vector_region(dir: &Path, vector: &str) -> PathBuf {
    flat_dem(dir);
    let p = dir.join("region.toml");
    std::fs::write(
        &p,
        format!("[area]\nbbox = [4.995, 44.995, 5.005, 45.005]\n[dem]\nfiles = [\"dem.tif\"]\n[landcover]\nscheme = \"nlcd\"\ntile_size_m = 20\n{vector}"),
    )
    .unwrap();
    p
}

/// Rationale: the two halves of a synthetic area, burnt from text classes mapped by `values`,
/// must split the material raster in two equal halves of grass and water (the boundary at 5° E
/// is the frame's centre meridian).
#[test]
fn text_classes_through_values_split_the_area() {
    let dir = tmp("halves");
    std::fs::write(
        dir.join("lc.geojson"),
        geojson(&[("\"kind\":\"meadow\"", WEST), ("\"kind\":\"pond\"", EAST)]),
    )
    .unwrap();
    let region = vector_region(
        &dir,
        "[[landcover.vector]]\nfile = \"lc.geojson\"\nattribute = \"kind\"\nvalues = { meadow = 71, pond = 11 }\n",
    );
    let (b, _) = build(&region, &dir.join("bundle"));
    let m = &b.manifest;
    let idx = |n: &str| m.materials.iter().find(|x| x.name == n).unwrap().index;
    let w = m.material_raster.width as usize;
    let (g, water) = (idx("grass"), idx("water"));
    for (k, &v) in b.material_raster.iter().enumerate() {
        let x = k % w;
        let want = if x < w / 2 { g } else { water };
        assert_eq!(v, want, "cell {k} (column {x} of {w})");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

fn expect_error(dir: &Path, vector: &str, needles: &[&str]) {
    let region = vector_region(dir, vector);
    let out = dir.join("bundle");
    let (code, _, stderr) = scenegen(&[
        "build",
        "--quiet",
        "--force",
        "-o",
        out.to_str().unwrap(),
        region.to_str().unwrap(),
    ]);
    assert_eq!(code, 2, "{vector}: {stderr}");
    for n in needles {
        assert!(stderr.contains(n), "{vector}: `{n}` not in: {stderr}");
    }
    assert!(!stderr.contains("panicked"), "{stderr}");
}

/// Rationale: bad vector land cover is refused naming the file, the layer, the feature id, the
/// key or the value; an invalid (self-intersecting) polygon and uncovered cells are named, never
/// silently dropped.
#[test]
fn bad_vector_landcover_is_named() {
    let dir = tmp("badvec");
    std::fs::write(
        dir.join("lc.geojson"),
        geojson(&[
            ("\"kind\":\"meadow\",\"code\":71", WEST),
            ("\"kind\":\"pond\",\"code\":null", EAST),
        ]),
    )
    .unwrap();
    expect_error(
        &dir,
        "[[landcover.vector]]\nfile = \"missing.gpkg\"\nclass = 71\n",
        &["missing.gpkg", "no such file"],
    );
    expect_error(
        &dir,
        "[[landcover.vector]]\nfile = \"lc.geojson\"\nattribute = \"typ\"\n",
        &["lc.geojson", "no attribute `typ`", "kind, code"],
    );
    expect_error(
        &dir,
        "[[landcover.vector]]\nfile = \"lc.geojson\"\nlayer = \"roads\"\nclass = 1\n",
        &["no layer `roads`"],
    );
    expect_error(
        &dir,
        "[[landcover.vector]]\nfile = \"lc.geojson\"\nattribute = \"kind\"\n",
        &[
            "feature 0",
            "\"meadow\" is not an integer class code",
            "values =",
        ],
    );
    expect_error(&dir, "[[landcover.vector]]\nfile = \"lc.geojson\"\nattribute = \"kind\"\nvalues = { meadow = 71 }\n", &["feature 1", "\"pond\" has no entry in `values`"]);
    expect_error(
        &dir,
        "[[landcover.vector]]\nfile = \"lc.geojson\"\nattribute = \"code\"\n",
        &["feature 1", "`code` is null"],
    );
    expect_error(
        &dir,
        "[[landcover.vector]]\nfile = \"lc.geojson\"\n",
        &["landcover.vector[0]", "`attribute`", "`class`"],
    );
    expect_error(
        &dir,
        "[[landcover.vector]]\nfile = \"lc.geojson\"\nclass = 3\nvalues = { a = 1 }\n",
        &["landcover.vector[0].values"],
    );
    expect_error(
        &dir,
        "[[landcover.vector]]\nfile = \"lc.geojson\"\nclas = 3\n",
        &["landcover.vector[0]", "clas"],
    );
    // A class code the scheme does not know, with its cell count.
    expect_error(
        &dir,
        "[[landcover.vector]]\nfile = \"lc.geojson\"\nclass = 77\n",
        &["77"],
    );
    // Only the west half covered: the east half is no data, an error without a fallback.
    std::fs::write(dir.join("west.geojson"), geojson(&[("\"code\":71", WEST)])).unwrap();
    expect_error(
        &dir,
        "[[landcover.vector]]\nfile = \"west.geojson\"\nattribute = \"code\"\n",
        &["west.geojson", "no data"],
    );
    // A line where polygons are expected.
    std::fs::write(
        dir.join("line.geojson"),
        "{\"type\":\"FeatureCollection\",\"features\":[{\"type\":\"Feature\",\"properties\":{},\"geometry\":{\"type\":\"LineString\",\"coordinates\":[[4.99,45.0],[5.01,45.0]]}}]}",
    )
    .unwrap();
    expect_error(
        &dir,
        "[[landcover.vector]]\nfile = \"line.geojson\"\nclass = 71\n",
        &["feature 0", "LINESTRING", "polygons are expected"],
    );

    // A bow tie is kept with a warning naming it.
    std::fs::write(
        dir.join("bowtie.geojson"),
        geojson(&[("\"code\":11", BOWTIE)]),
    )
    .unwrap();
    let region = vector_region(
        &dir,
        "fallback_material = \"grass\"\n[[landcover.vector]]\nfile = \"bowtie.geojson\"\nattribute = \"code\"\n",
    );
    let out = dir.join("bundle");
    let (code, _, stderr) = scenegen(&[
        "build",
        "--force",
        "-o",
        out.to_str().unwrap(),
        region.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{stderr}");
    assert!(
        stderr.contains("feature 0 is not a valid polygon"),
        "{stderr}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The Delft AHN3 points of ASPRS class `class`, read with the `las` crate.
fn ahn3_points(shared: &Path, class: u8) -> Vec<[f64; 3]> {
    let mut out = Vec::new();
    for f in ["ahn3_cropped_1.laz", "ahn3_cropped_2.laz"] {
        let mut r = las::Reader::from_path(shared.join("real_regions/delft/ahn3").join(f)).unwrap();
        for p in r.read_all().unwrap().points() {
            let p = p.unwrap();
            if u8::from(p.classification) == class {
                out.push([p.x, p.y, p.z]);
            }
        }
    }
    out
}

/// Build `region` through the library (for the per-building records).
fn build_lib(region: &Path, out: &Path) -> scenegen::build::BuildReport {
    let r = scenegen::region::Region::load(region).unwrap();
    scenegen::build::build(
        &r,
        out,
        &scenegen::build::BuildOptions {
            force: true,
            progress: false,
        },
    )
    .unwrap()
}

/// Ray–triangle intersection distance (Möller–Trumbore), both sides.
fn hit(o: [f64; 3], d: [f64; 3], t: [[f64; 3]; 3]) -> Option<f64> {
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let (e1, e2) = (sub(t[1], t[0]), sub(t[2], t[0]));
    let p = cross(d, e2);
    let det = dot(e1, p);
    if det.abs() < 1e-12 {
        return None;
    }
    let s = sub(o, t[0]);
    let u = dot(s, p) / det;
    let q = cross(s, e1);
    let v = dot(d, q) / det;
    if u < 0.0 || v < 0.0 || u + v > 1.0 {
        return None;
    }
    let dist = dot(e2, q) / det;
    (dist > 0.0).then_some(dist)
}

/// Every template whose name starts with `prefix`: its triangles in world-relative metres.
fn template_triangles(b: &Bundle, prefix: &str) -> Vec<([[f64; 3]; 3], u8)> {
    let mut out = Vec::new();
    for inst in &b.instances {
        let t = &b.templates[inst.template as usize];
        if !t.name.starts_with(prefix) {
            continue;
        }
        for (tri, &m) in t.indices.iter().zip(&t.materials) {
            let p = tri.map(|i| {
                let v = t.positions[i as usize];
                [
                    v[0] as f64 + inst.translation[0],
                    v[1] as f64 + inst.translation[1],
                    v[2] as f64 + inst.translation[2],
                ]
            });
            out.push((p, m));
        }
    }
    out
}

/// Rationale: the buildings must be closed solids. Every template's mesh is checked edge by
/// edge (each directed edge once, its reverse once), and 4 000 random vertical and slanted lines
/// through the block must cross the building surfaces an even number of times (a ray entering a
/// solid leaves it), the terrain watertightness ray test applied to the buildings.
fn assert_watertight(b: &Bundle, prefix: &str) {
    for t in b.templates.iter().filter(|t| t.name.starts_with(prefix)) {
        assert!(
            scenegen::buildings::closed_mesh(&t.indices),
            "{} is not closed",
            t.name
        );
    }
    let tris = template_triangles(b, prefix);
    assert!(!tris.is_empty());
    let o = b.manifest.frame.origin;
    let (x0, y0) = (
        b.manifest.extent.min[0] - o[0],
        b.manifest.extent.min[1] - o[1],
    );
    let (x1, y1) = (
        b.manifest.extent.max[0] - o[0],
        b.manifest.extent.max[1] - o[1],
    );
    // SplitMix64 (a fixed sequence).
    let mut state = 17u64;
    let mut uniform = || {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut crossings = 0;
    for k in 0..4000 {
        let start = [
            x0 + uniform() * (x1 - x0),
            y0 + uniform() * (y1 - y0),
            500.0,
        ];
        let d = if k % 2 == 0 {
            [0.0, 0.0, -1.0]
        } else {
            let (a, s) = (uniform() * std::f64::consts::TAU, 0.4);
            let n = (1.0f64 + s * s).sqrt();
            [s * a.cos() / n, s * a.sin() / n, -1.0 / n]
        };
        let n = tris
            .iter()
            .filter(|(t, _)| hit(start, d, *t).is_some())
            .count();
        assert!(
            n % 2 == 0,
            "line {k} from {start:?} along {d:?} crosses the buildings {n} times"
        );
        crossings += n;
    }
    assert!(crossings > 100, "the lines must hit buildings: {crossings}");
}

/// Rationale: the Delft example from its open data: a DTM from the AHN3 ground points, the BGT
/// polygons as land cover with every code mapped (no unknown code; the build has a fallback only
/// for the gaps between polygons), and the 160 BGT footprints extruded to the median of the AHN3
/// building points inside each. Checked against an independent reading of the same inputs (the
/// `las` reader and GDAL directly here): each roof within 0.5 m of the median of the class-6
/// points inside its footprint, the floor below the lowest ground; all prisms watertight.
#[test]
fn delft_buildings_from_footprints_and_lidar() {
    let Some(shared) = shared_data() else { return };
    let dir = tmp("delft");
    let region = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/delft/region.toml");
    let report = build_lib(&region, &dir.join("bundle"));
    let b = Bundle::open(&dir.join("bundle")).unwrap();
    assert_eq!(report.buildings.len() + report.buildings_skipped.len(), 160);
    assert!(
        report.buildings.len() >= 155,
        "{:?}",
        report.buildings_skipped
    );
    for (id, why) in &report.buildings_skipped {
        assert!(why.contains("outside the DEM"), "{id}: {why}");
    }
    // The land cover's codes are all in the scheme: only the gaps use the fallback.
    let m = &b.manifest;
    assert!(m
        .materials
        .iter()
        .any(|x| x.name == "water" && !x.class_codes.is_empty()));

    // Independent roof medians.
    let roof_points = ahn3_points(&shared, 6);
    let ds = gdal::Dataset::open(shared.join("real_regions/delft/bgt/bgt_pand.sqlite")).unwrap();
    let mut layer = ds.layer(0).unwrap();
    use gdal::vector::LayerAccess;
    let idx = layer.defn().field_index("identificatiebagpnd").unwrap();
    let mut footprints = std::collections::HashMap::new();
    for f in layer.features() {
        let id = f.field_as_string(idx).unwrap().unwrap();
        let g: geo::Geometry<f64> = f.geometry().unwrap().try_into().unwrap();
        footprints.insert(id, g);
    }
    let mut worst: f64 = 0.0;
    for rec in &report.buildings {
        let g = &footprints[&rec.id];
        use geo::Contains;
        let mut zs: Vec<f64> = roof_points
            .iter()
            .filter(|p| g.contains(&geo::Point::new(p[0], p[1])))
            .map(|p| p[2])
            .collect();
        assert!(!zs.is_empty(), "{}", rec.id);
        zs.sort_by(|a, b| a.total_cmp(b));
        let n = zs.len();
        let median = if n % 2 == 1 {
            zs[n / 2]
        } else {
            0.5 * (zs[n / 2 - 1] + zs[n / 2])
        };
        worst = worst.max((rec.roof - median).abs());
        assert!(rec.floor < rec.roof - 1.0, "{}: {rec:?}", rec.id);
    }
    eprintln!(
        "delft: {} buildings, roofs within {worst:.3} m of the AHN3 building points' median",
        report.buildings.len()
    );
    assert!(worst <= 0.5, "worst roof difference {worst} m");
    assert_watertight(&b, "buildings_");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Rationale: the CityJSON city model of the same block (3dfier's LoD1 solids: roofs at the 90th
/// percentile of the lidar's roof points, EPSG:7415) is read as it is: all 160 buildings placed,
/// every solid watertight (edge test and ray parity), its triangles as many as the file's, its
/// roofs compared per building (matched by the BAG id) with the footprint extrusion's AHN3
/// medians: the statistics are printed (measured: 0.02 … 7.1 m above, median 1.22 m, 24 of 159
/// within 0.5 m); no LoD1 roof may sit more than 0.5 m below the median of its roof points (a
/// 90th percentile lies above the median), and the median offset must be that of pitched roofs
/// (0.5–2.5 m), not of a datum or CRS error.
#[test]
fn delft_city_model_is_read_as_it_is() {
    if shared_data().is_none() {
        return;
    }
    let dir = tmp("delft-cityjson");
    let ex = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/delft");
    let city = build_lib(&ex.join("region_cityjson.toml"), &dir.join("city"));
    let foot = build_lib(&ex.join("region.toml"), &dir.join("foot"));
    assert_eq!(city.city_objects.len(), 160);
    assert_eq!(
        city.city_objects.iter().map(|o| o.triangles).sum::<usize>(),
        6854,
        "one triangle per triangular surface of the file"
    );
    let b = Bundle::open(&dir.join("city")).unwrap();
    assert_watertight(&b, "city_");
    let medians: std::collections::HashMap<&str, f64> = foot
        .buildings
        .iter()
        .map(|r| (r.id.as_str(), r.roof))
        .collect();
    let mut d: Vec<f64> = Vec::new();
    for o in &city.city_objects {
        let id = o.attributes["identificatiebagpnd"].as_str().unwrap();
        if let Some(m) = medians.get(id) {
            d.push(o.zmax - m);
        }
    }
    assert!(d.len() >= 155);
    let within = d.iter().filter(|x| x.abs() <= 0.5).count();
    let mut abs: Vec<f64> = d.iter().map(|x| x.abs()).collect();
    abs.sort_by(|a, b| a.total_cmp(b));
    eprintln!(
        "delft CityJSON roofs − AHN3 roof-point medians over {} buildings: median |Δ| {:.2} m, {} within 0.5 m, range {:.2} … {:.2} m",
        d.len(),
        abs[abs.len() / 2],
        within,
        d.iter().cloned().fold(f64::MAX, f64::min),
        d.iter().cloned().fold(f64::MIN, f64::max)
    );
    assert!(d.iter().all(|&x| x >= -0.5), "{d:?}");
    let median = abs[abs.len() / 2];
    assert!((0.5..=2.5).contains(&median), "median |Δ| {median}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Rationale: a broken city model is refused naming the file and what is wrong (never a panic).
#[test]
fn bad_city_models_are_named() {
    let dir = tmp("badcity");
    let cases: &[(&str, &[&str])] = &[
        ("{not json", &["not valid JSON"]),
        ("{\"type\":\"CityJSON\",\"vertices\":[]}", &["no `CityObjects`"]),
        (
            "{\"type\":\"CityJSON\",\"metadata\":{\"referenceSystem\":\"urn:ogc:def:crs:EPSG::32631\"},\"CityObjects\":{\"b\":{\"type\":\"Building\",\"geometry\":[{\"type\":\"Solid\",\"lod\":1,\"boundaries\":[[[[0,1,7]]]]}]}},\"vertices\":[[0,0,0],[1,0,0],[0,1,0]]}",
            &["city object b", "vertex index 7"],
        ),
        (
            "{\"type\":\"CityJSON\",\"CityObjects\":{},\"vertices\":[]}",
            &["no `metadata.referenceSystem`", "crs"],
        ),
        (
            "{\"type\":\"CityJSON\",\"metadata\":{\"referenceSystem\":\"urn:ogc:def:crs:EPSG::32631\"},\"CityObjects\":{},\"vertices\":[[0,0]]}",
            &["vertex 0 is not three numbers"],
        ),
    ];
    for (text, needles) in cases {
        std::fs::write(dir.join("city.json"), text).unwrap();
        expect_error(
            &dir,
            "class = 71\n[[city_models]]\nfile = \"city.json\"\n",
            needles,
        );
    }
    expect_error(
        &dir,
        "class = 71\n[[city_models]]\nfile = \"nowhere.json\"\n",
        &["nowhere.json", "cannot read"],
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Rationale: three cone-shaped crowns in a synthetic canopy-height raster (EPSG:4326, 0.5 m
/// cells warped to the working frame) give exactly three tree instances, at their apexes, whose
/// scaled template reaches the apex height above the terrain (to 1 cm) and whose crown spans
/// the Popescu–Wynne width of that height.
#[test]
fn trees_stand_on_their_canopy_maxima() {
    let dir = tmp("trees");
    flat_dem(&dir);
    // Cones in metres around (5.0° E, 45.0° N); the raster in degrees at ≈ 0.5 m.
    let (dlon, dlat) = (0.5 / 78_846.8, 0.5 / 111_132.0);
    let (w, h) = (400usize, 300usize);
    let (lon0, lat0) = (5.0 - 200.0 * dlon, 45.0 + 150.0 * dlat);
    let cones = [(-40.0, 10.0, 18.0), (0.0, -20.0, 9.0), (45.0, 30.0, 25.0)];
    let chm: Vec<f32> = (0..w * h)
        .map(|k| {
            let (c, r) = ((k % w) as f64 + 0.5, (k / w) as f64 + 0.5);
            let (x, y) = ((c - 200.0) * 0.5, (150.0 - r) * 0.5);
            cones
                .iter()
                .map(|&(cx, cy, top)| top - 1.2 * ((x - cx).powi(2) + (y - cy).powi(2)).sqrt())
                .fold(0.0f64, f64::max) as f32
        })
        .collect();
    scenegen::synth::write_geotiff(
        &dir.join("chm.tif"),
        w,
        h,
        Some([lon0, dlon, 0.0, lat0, 0.0, -dlat]),
        Some("EPSG:4326"),
        None,
        chm,
    )
    .unwrap();
    let region = dir.join("region.toml");
    std::fs::write(
        &region,
        "population = []\n[area]\nbbox = [4.9988, 44.9994, 5.0012, 45.0006]\n[dem]\nfiles = [\"dem.tif\"]\nspacing_m = 5\n[landcover]\nscheme = \"nlcd\"\nclass = 71\ntile_size_m = 10\n[[trees]]\nchm = \"chm.tif\"\ntemplate = \"conifer\"\nmin_height_m = 3\ncell_m = 0.5\n",
    )
    .unwrap();
    let report = build_lib(&region, &dir.join("bundle"));
    let b = Bundle::open(&dir.join("bundle")).unwrap();
    let tops = &report.trees[0];
    assert_eq!(tops.len(), 3, "{tops:?}");
    let t = b
        .templates
        .iter()
        .position(|t| t.name == "conifer")
        .unwrap();
    let tm = &b.templates[t];
    let th = tm.positions.iter().map(|p| p[2]).fold(f32::MIN, f32::max) as f64;
    let insts: Vec<_> = b
        .instances
        .iter()
        .filter(|i| i.template == t as u32)
        .collect();
    assert_eq!(insts.len(), 3);
    for &(cx, cy, top) in &cones {
        let tt = tops
            .iter()
            .min_by(|a, b| {
                let d = |p: &&scenegen::trees::TreeTop| (p.height - top).abs();
                d(a).total_cmp(&d(b))
            })
            .unwrap();
        // The apexes sit on pixel corners: the highest samples are 1.2 × 0.354 m lower.
        assert!(
            (tt.height - (top - 0.424)).abs() < 0.05,
            "{tt:?} vs apex {top}"
        );
        let i = insts
            .iter()
            .min_by(|a, b| {
                let d = |i: &&&bundle::Instance| {
                    (i.translation[0] - cx).powi(2) + (i.translation[1] - cy).powi(2)
                };
                d(a).total_cmp(&d(b))
            })
            .unwrap();
        assert!(
            (i.translation[0] - cx).abs() < 0.75 && (i.translation[1] - cy).abs() < 0.75,
            "instance at {:?}, apex at ({cx}, {cy})",
            i.translation
        );
        let sz = i.linear[8] as f64;
        assert!(
            (sz * th - tt.height).abs() < 0.01,
            "top {} vs {}",
            sz * th,
            tt.height
        );
        let sxy = (i.linear[0] as f64).hypot(i.linear[1] as f64);
        assert!(
            sxy > 0.0 && (sz / sxy - 1.0).abs() > 1e-3,
            "crown scaled apart from height"
        );
        assert!((scenegen::trees::crown_width(tt.height) - tt.crown).abs() < 1e-9);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Rationale: trees from the Delft lidar (the highest unclassified point per 1 m cell above the
/// DTM, cells with building points excluded): each detected tree's height must be within 1 m of
/// the canopy maximum computed here independently (highest class-1 point in its cell, minus the
/// terrain under the instance), and its instance must reach that height.
#[test]
fn delft_trees_from_lidar_match_their_canopy_maxima() {
    let Some(shared) = shared_data() else { return };
    let dir = tmp("delft-trees");
    let region = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/delft/region.toml");
    let report = build_lib(&region, &dir.join("bundle"));
    let b = Bundle::open(&dir.join("bundle")).unwrap();
    let tops = &report.trees[0];
    assert!(tops.len() > 100, "{}", tops.len());
    let pts = ahn3_points(&shared, 1);
    let t = b.templates.iter().position(|t| t.name == "tree").unwrap() as u32;
    let o = b.manifest.frame.origin;
    let insts: Vec<_> = b.instances.iter().filter(|i| i.template == t).collect();
    assert_eq!(insts.len(), tops.len());
    let th = b.templates[t as usize]
        .positions
        .iter()
        .map(|p| p[2])
        .fold(f32::MIN, f32::max) as f64;
    let mut worst: f64 = 0.0;
    for (top, inst) in tops.iter().zip(&insts) {
        assert!((inst.translation[0] + o[0] - top.x).abs() < 1e-6);
        let zmax = pts
            .iter()
            .filter(|p| (p[0] - top.x).abs() <= 0.5 && (p[1] - top.y).abs() <= 0.5)
            .map(|p| p[2])
            .fold(f64::MIN, f64::max);
        let canopy = zmax - inst.translation[2];
        worst = worst.max((canopy - top.height).abs());
        assert!(((inst.linear[8] as f64) * th - top.height).abs() < 0.01);
    }
    eprintln!(
        "delft trees: {} from lidar, heights within {worst:.3} m of the independent canopy maxima",
        tops.len()
    );
    assert!(worst <= 1.0, "{worst}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Rationale: OpenStreetMap buildings (GDAL's OSM driver, keys from `other_tags`) extruded to
/// their `height`, else `building:levels` × 3.2 m, else 12 m on a flat terrain: every built
/// prism's height is recomputed here from the feature's own tags (read through GDAL with its own
/// hstore parsing), every feature is accounted for (built, skipped with a warning, or outside
/// the area), and the prisms are watertight.
#[test]
fn helsinki_osm_buildings_take_their_tagged_heights() {
    let Some(shared) = shared_data() else { return };
    let dir = tmp("helsinki");
    let region = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/helsinki/region.toml");
    let report = build_lib(&region, &dir.join("bundle"));
    let b = Bundle::open(&dir.join("bundle")).unwrap();
    // The oracle reads each entry's filtered layer as the region file says (GDAL's OSM driver
    // assembles multipolygons per reading, so each filter is read on its own).
    let text = std::fs::read_to_string(&region).unwrap();
    let doc: toml::Value = toml::from_str(&text).unwrap();
    let mut expected = std::collections::HashMap::new();
    use gdal::vector::LayerAccess;
    for e in doc["buildings"].as_array().unwrap() {
        let ds =
            gdal::Dataset::open(shared.join("real_regions/helsinki_osm/Helsinki.osm.pbf")).unwrap();
        let mut layer = ds.layer_by_name("multipolygons").unwrap();
        layer
            .set_attribute_filter(e["filter"].as_str().unwrap())
            .unwrap();
        let col = |n: &str| layer.defn().field_index(n).unwrap();
        let (oi, wi, ri) = (col("other_tags"), col("osm_way_id"), col("osm_id"));
        let tag = |tags: &str, key: &str| -> Option<f64> {
            let pat = format!("\"{key}\"=>\"");
            let s = tags.find(&pat)? + pat.len();
            let v = tags[s..].split('"').next()?;
            v.trim_end_matches('m').trim().parse().ok()
        };
        for f in layer.features() {
            let tags = f.field_as_string(oi).unwrap().unwrap_or_default();
            let h = if e.get("height_attribute").is_some() {
                tag(&tags, "height").unwrap_or_else(|| panic!("no height in {tags}"))
            } else if e.get("levels_attribute").is_some() {
                tag(&tags, "building:levels").unwrap() * 3.2
            } else {
                e["height_m"].as_float().unwrap()
            };
            let id = match f.field_as_string(wi).unwrap().filter(|w| !w.is_empty()) {
                Some(w) => format!("way {w}"),
                None => format!("relation {}", f.field_as_string(ri).unwrap().unwrap()),
            };
            expected.insert(id, h);
        }
    }
    assert!(report.buildings.len() > 200, "{}", report.buildings.len());
    for r in &report.buildings {
        let id = r.id.split(" (part").next().unwrap();
        let h = *expected
            .get(id)
            .unwrap_or_else(|| panic!("{id} not among the tagged features"));
        let got = r.roof - r.ground;
        assert!((got - h).abs() < 1e-6, "{}: {got} vs tags {h}", r.id);
    }
    for (id, why) in &report.buildings_skipped {
        assert!(
            why.contains("outside the DEM")
                || why.contains("not a footprint")
                || why.contains("cross")
                || why.contains("touch"),
            "{id}: {why}"
        );
    }
    eprintln!(
        "helsinki: {} OSM buildings built, {} skipped (named), of {} tagged features",
        report.buildings.len(),
        report.buildings_skipped.len(),
        expected.len()
    );
    assert_watertight(&b, "buildings_");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Rationale: footprints with Z coordinates (GeoJSON 3-value positions, a shapefile PolygonZ)
/// and a courtyard are extruded like 2D ones: one closed prism of the footprint's area with the
/// hole, its roof at the lowest ground plus the attribute's height given as "9.5 m" text, its
/// floor below the terrain by at least the sink and the terrain tolerance.
#[test]
fn footprints_with_z_and_a_courtyard_build() {
    let dir = tmp("zfoot");
    std::fs::write(
        dir.join("b.geojson"),
        "{\"type\":\"FeatureCollection\",\"features\":[{\"type\":\"Feature\",\"properties\":{\"h\":\"9.5 m\"},\"geometry\":{\"type\":\"Polygon\",\"coordinates\":[[[4.9995,44.9996,7],[5.0005,44.9996,7],[5.0005,45.0004,7],[4.9995,45.0004,7],[4.9995,44.9996,7]],[[4.9999,44.9999,7],[4.9999,45.0001,7],[5.0001,45.0001,7],[5.0001,44.9999,7],[4.9999,44.9999,7]]]}}]}",
    )
    .unwrap();
    let region = vector_region(
        &dir,
        "class = 71\n[[buildings]]\nfile = \"b.geojson\"\nheight_attribute = \"h\"\n",
    );
    let report = build_lib(&region, &dir.join("bundle"));
    assert_eq!(report.buildings.len(), 1, "{:?}", report.buildings_skipped);
    let r = &report.buildings[0];
    assert!((r.roof - r.ground - 9.5).abs() < 1e-9, "{r:?}");
    assert!(
        r.ground - r.floor >= scenegen::buildings::SINK_M + 1.0 - 1e-9,
        "{r:?}"
    );
    // ≈ 79 m × 89 m minus ≈ 16 m × 22 m.
    assert!(r.area_m2 > 6000.0 && r.area_m2 < 6700.0, "{}", r.area_m2);
    let b = Bundle::open(&dir.join("bundle")).unwrap();
    for t in b
        .templates
        .iter()
        .filter(|t| t.name.starts_with("buildings_"))
    {
        assert!(scenegen::buildings::closed_mesh(&t.indices));
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Rationale: heights sampled from a surface model: over a flat DEM at 300 m, a DSM at 312 m on
/// the footprint (318 m on a quarter of it, a chimney-like block) and 300 m around gives the
/// median roof 312 m (the 75th percentile would be 312 too, the 90th 318).
#[test]
fn building_heights_from_a_surface_model() {
    let dir = tmp("dsmfoot");
    flat_dem(&dir);
    // A DSM in degrees, 0.0001° pixels over the area; the footprint 4.9995–5.0005 × 44.9996–45.0004.
    let (w, h) = (100usize, 100usize);
    let (lon0, lat0, d) = (4.995, 45.005, 0.0001);
    let dsm: Vec<f32> = (0..w * h)
        .map(|k| {
            let (lon, lat) = (
                lon0 + ((k % w) as f64 + 0.5) * d,
                lat0 - ((k / w) as f64 + 0.5) * d,
            );
            let inside = (4.9995..5.0005).contains(&lon) && (44.9996..45.0004).contains(&lat);
            if !inside {
                300.0
            } else if lon > 5.0 && lat > 45.0 {
                318.0
            } else {
                312.0
            }
        })
        .collect();
    scenegen::synth::write_geotiff(
        &dir.join("dsm.tif"),
        w,
        h,
        Some([lon0, d, 0.0, lat0, 0.0, -d]),
        Some("EPSG:4326"),
        None,
        dsm,
    )
    .unwrap();
    std::fs::write(
        dir.join("b.geojson"),
        "{\"type\":\"FeatureCollection\",\"features\":[{\"type\":\"Feature\",\"properties\":{},\"geometry\":{\"type\":\"Polygon\",\"coordinates\":[[[4.9995,44.9996],[5.0005,44.9996],[5.0005,45.0004],[4.9995,45.0004],[4.9995,44.9996]]]}}]}",
    )
    .unwrap();
    for (p, want) in [(50.0, 312.0), (90.0, 318.0)] {
        let region = vector_region(
            &dir,
            &format!("class = 71\n[[buildings]]\nfile = \"b.geojson\"\nheight_from_dsm = \"dsm.tif\"\nroof_percentile = {p}\n"),
        );
        let report = build_lib(&region, &dir.join("bundle"));
        let r = &report.buildings[0];
        assert!(
            (r.roof - want).abs() < 1e-3,
            "p{p}: roof {} vs {want}",
            r.roof
        );
        assert!((r.ground - 300.0).abs() < 1e-3);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Rationale: bad lidar and building inputs are named: an empty LAZ, a point cloud without a
/// CRS, a missing height attribute, a footprint without a height and no default.
#[test]
fn bad_lidar_and_building_inputs_are_named() {
    let dir = tmp("badlidar");
    // An empty LAZ and a LAS without CRS, written with the las crate.
    let write = |name: &str, points: &[(f64, f64, f64)]| {
        let mut b = las::Builder::from((1, 4));
        b.point_format = las::point::Format::new(6).unwrap();
        let mut w = las::Writer::from_path(dir.join(name), b.into_header().unwrap()).unwrap();
        for &(x, y, z) in points {
            w.write_point(las::Point {
                x,
                y,
                z,
                gps_time: Some(0.0),
                ..Default::default()
            })
            .unwrap();
        }
        w.close().unwrap();
    };
    write("empty.laz", &[]);
    write("nocrs.las", &[(0.0, 0.0, 1.0)]);
    std::fs::write(
        dir.join("b.geojson"),
        geojson(&[
            (
                "\"name\":\"A\",\"h\":null",
                "[[[4.996,44.996],[4.999,44.996],[4.999,44.999],[4.996,44.999],[4.996,44.996]]]",
            ),
            (
                "\"name\":\"B\",\"h\":5",
                "[[[5.001,45.001],[5.004,45.001],[5.004,45.004],[5.001,45.004],[5.001,45.001]]]",
            ),
        ]),
    )
    .unwrap();
    let lidar = |f: &str, crs: &str| {
        format!("class = 71\n[lidar]\nfiles = [\"{f}\"]\n{crs}\n[[buildings]]\nfile = \"b.geojson\"\nheight_from_lidar = true\n")
    };
    expect_error(
        &dir,
        &lidar("empty.laz", "crs = \"EPSG:32631\""),
        &["empty.laz", "no points"],
    );
    expect_error(
        &dir,
        &lidar("nocrs.las", ""),
        &["nocrs.las", "declares no CRS", "crs"],
    );
    expect_error(
        &dir,
        &lidar("missing.laz", "crs = \"EPSG:32631\""),
        &["missing.laz", "not found"],
    );
    expect_error(
        &dir,
        "class = 71\n[[buildings]]\nfile = \"b.geojson\"\nheight_attribute = \"height\"\n",
        &["b.geojson", "no attribute `height`", "name, h"],
    );
    expect_error(
        &dir,
        "class = 71\n[[buildings]]\nfile = \"b.geojson\"\nid_attribute = \"name\"\nheight_attribute = \"h\"\n",
        &["building A", "null or not a number", "default_height_m"],
    );
    expect_error(
        &dir,
        "class = 71\n[[buildings]]\nfile = \"b.geojson\"\nheight_m = 5\nroof_percentile = 50\n",
        &["buildings[0].roof_percentile"],
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Rationale: `roof_shape_attribute` makes the footprints tagged `gabled` gabled (ridge at the
/// building's height, eaves lower) and leaves the others flat; every prism stays closed.
#[test]
fn gabled_roofs_from_an_attribute() {
    let dir = tmp("gable");
    std::fs::write(
        dir.join("b.geojson"),
        geojson(&[
            (
                "\"h\":10,\"roof\":\"gabled\"",
                "[[[4.996,44.996],[4.999,44.996],[4.999,44.998],[4.996,44.998],[4.996,44.996]]]",
            ),
            (
                "\"h\":10,\"roof\":\"flat\"",
                "[[[5.001,45.001],[5.004,45.001],[5.004,45.004],[5.001,45.004],[5.001,45.001]]]",
            ),
        ]),
    )
    .unwrap();
    let region = vector_region(
        &dir,
        "class = 71\n[[buildings]]\nfile = \"b.geojson\"\nheight_attribute = \"h\"\nroof_shape_attribute = \"roof\"\nroof_pitch_deg = 20\n",
    );
    let report = build_lib(&region, &dir.join("bundle"));
    assert_eq!(report.buildings.len(), 2, "{:?}", report.buildings_skipped);
    let b = Bundle::open(&dir.join("bundle")).unwrap();
    let roof = b
        .manifest
        .materials
        .iter()
        .find(|m| m.name == "roof")
        .unwrap()
        .index;
    let mut heights: Vec<f32> = Vec::new();
    for t in b
        .templates
        .iter()
        .filter(|t| t.name.starts_with("buildings_"))
    {
        assert!(scenegen::buildings::closed_mesh(&t.indices));
        for (tri, &m) in t.indices.iter().zip(&t.materials) {
            if m == roof {
                heights.extend(tri.iter().map(|&i| t.positions[i as usize][2]));
            }
        }
    }
    heights.sort_by(|a, b| a.total_cmp(b));
    heights.dedup_by(|a, b| (*a - *b).abs() < 1e-3);
    // The flat roof and the ridge at 310 m, the gabled eaves lower.
    assert!(heights.len() >= 2, "{heights:?}");
    assert!(
        (heights.last().unwrap() - 310.0).abs() < 1e-3,
        "{heights:?}"
    );
    assert!(heights[0] < 309.0, "{heights:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}
