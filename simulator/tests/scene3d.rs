//! 3D scenes in `simulate`: the scene walk against the 1D walks and against closed forms.
//! Each test states its rationale. Statistical comparisons use `common::check_all`
//! (|diff| ≤ 4.5σ + max(1e-5, 2e-4·ref)) with σ the combined standard error of both runs.

mod common;

use bundle::*;
use common::bundles::{
    lambertian, tmp, write_plane, write_plane_with_indices, write_random_leaves, PlaneSpec,
};
use common::{compare_brf_rows, experiment, run_on_1_and_2_threads, run_rows};

fn plane(
    size: f64,
    raster_width: usize,
    raster: Vec<u8>,
    materials: Vec<(String, BrdfSpec)>,
) -> PlaneSpec {
    PlaneSpec {
        x0: -0.5 * size,
        y0: -0.5 * size,
        size,
        h0: 0.0,
        sx: 0.0,
        sy: 0.0,
        tiles: 2,
        n: 4,
        raster_width,
        raster,
        materials,
        frame_origin: [500_000.0, 4_000_000.0, 0.0],
        wkt: String::new(),
    }
}

const ATM: &str = "[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = 0.2\nphase = { type = \"hg\", g = 0.5 }";

fn zeniths() -> (Vec<f64>, Vec<f64>) {
    (vec![0.0, 30.0, 55.0, 70.0], vec![0.0, 120.0, 30.0, 200.0])
}

fn distant(id: &str, vza: &[f64], vaa: &[f64], spp: u64, extra: &str) -> String {
    let z: Vec<String> = vza.iter().map(|v| format!("{v:?}")).collect();
    let a: Vec<String> = vaa.iter().map(|v| format!("{v:?}")).collect();
    format!(
        "[[measures]]\nid = \"{id}\"\ntype = \"mdistant\"\nconstruct = \"directions\"\nzeniths = [{}]\nazimuths = [{}]\nspp = {spp}\n{extra}\n",
        z.join(", "),
        a.join(", ")
    )
}

/// A flat bundle made of one material, with the background plane of the same material at the
/// same height, is an infinite uniform surface: its area-averaged TOA BRF must equal the 1D
/// surface's under the same atmosphere (Lambertian and RPV; the 3D walk traverses the terrain
/// BVH, the selector and the tilted-frame BRDF evaluation, the 1D walk does not).
#[test]
fn flat_bundle_equals_1d_surface() {
    let rpv = BrdfSpec::Rpv(RpvSpec {
        rho_0: Spectrum::Constant(0.12),
        k: Spectrum::Constant(0.8),
        g: Spectrum::Constant(-0.2),
        rho_c: None,
    });
    let cases = [
        (
            "lambertian",
            lambertian(0.3),
            "type = \"lambertian\"\nreflectance = 0.3",
        ),
        (
            "rpv",
            rpv,
            "type = \"rpv\"\nrho_0 = 0.12\nk = 0.8\ng = -0.2",
        ),
    ];
    let (vza, vaa) = zeniths();
    let mut errs = Vec::new();
    for (name, spec, surf) in cases {
        let dir = tmp(&format!("flat-{name}"));
        let b = write_plane(
            &dir,
            &plane(2000.0, 4, vec![0; 16], vec![(name.to_string(), spec)]),
        );
        let head = format!(
            "seed = 3\n[spectral]\nwavelengths = [550.0]\n[illumination]\ntype = \"directional\"\nzenith = 35.0\nazimuth = 40.0\n{ATM}\n"
        );
        let e3 = experiment(&format!(
            "{head}[scene]\ntype = \"bundle\"\npath = \"{}\"\n{}",
            b.display(),
            distant(
                "area",
                &vza,
                &vaa,
                100_000,
                "target_m = [499800.0, 3999800.0, 500200.0, 4000200.0]"
            )
        ));
        // Another seed: the two estimates must be independent for the z-test.
        let e1 = experiment(&format!(
            "{}[surface]\n{surf}\n[integrator]\ntype = \"backward\"\n{}",
            head.replace("seed = 3", "seed = 4"),
            distant("area", &vza, &vaa, 100_000, "")
        ));
        let (r3, r1) = (run_rows(&e3), run_rows(&e1));
        if let Err(e) = compare_brf_rows(&format!("flat bundle = 1D ({name})"), &r3, &r1) {
            errs.push(e);
        }
    }
    assert!(errs.is_empty(), "{}", errs.join("\n"));
}

/// The selector picks the material of the raster cell under each hit: with no atmosphere, a flat
/// Lambertian checkerboard seen at nadir gives each ortho pixel (aligned with the raster cells)
/// exactly its cell's reflectance × (cos SZA / cos SZA) = ρ, with zero variance (one bounce, then
/// the path leaves). A one-class raster gives the plain BSDF everywhere.
#[test]
fn selector_and_ortho_pixels_are_exact() {
    let dir = tmp("selector");
    let rw = 4;
    let raster: Vec<u8> = (0..rw * rw)
        .map(|k| ((k / rw + k % rw) % 2) as u8)
        .collect();
    let b = write_plane(
        &dir,
        &plane(
            400.0,
            rw,
            raster.clone(),
            vec![
                ("dark".into(), lambertian(0.1)),
                ("bright".into(), lambertian(0.6)),
            ],
        ),
    );
    let e = experiment(&format!(
        "seed = 1\n[spectral]\nwavelengths = [550.0]\n[illumination]\ntype = \"directional\"\nzenith = 30.0\nazimuth = 0.0\n[scene]\ntype = \"bundle\"\npath = \"{}\"\nbackground = {{ type = \"none\" }}\n[[measures]]\nid = \"img\"\ntype = \"ortho\"\npixel_size_m = 100.0\nspp = 64\n",
        b.display()
    ));
    let res = simulator::run::run(&e, false);
    let imgs = simulator::products::imagery::image_products(&e, &res);
    assert_eq!(imgs.len(), 1);
    let img = &imgs[0];
    assert_eq!((img.width, img.height), (4, 4));
    for (k, &cls) in raster.iter().enumerate() {
        let want = if cls == 0 { 0.1 } else { 0.6 };
        let got = img.brf[0][k];
        assert!(
            (got - want).abs() < 1e-9,
            "pixel {k}: BRF {got}, want {want} (class {cls})"
        );
        assert!(img.brf_stderr[0][k] < 1e-9);
    }
    // Georeferencing: the grid covers the raster, north-up, in working-CRS coordinates.
    let gt = img.geotransform.unwrap();
    assert_eq!(gt, [499_800.0, 100.0, 0.0, 4_000_200.0, 0.0, -100.0]);
}

/// Material ids are the manifest's `index`, not positions in its list: a manifest listing
/// `dark` (index 5), `bright` (index 2) and `grey` (index 0), with raster cells holding 5, 2 and
/// 0, must show each cell's own material (exact per-pixel BRF as in the selector test). Read
/// by position, id 0 would be `dark`, id 2 `grey` and id 5 nothing. The default background
/// takes the most frequent id's material (id 2, `bright`).
#[test]
fn non_contiguous_material_indices_select_the_right_material() {
    let dir = tmp("sparse-ids");
    let rw = 4;
    let ids = [5u8, 2, 0];
    #[rustfmt::skip]
    let raster: Vec<u8> = vec![
        5, 2, 0, 2,
        2, 5, 2, 0,
        0, 2, 5, 2,
        2, 0, 2, 5,
    ];
    let b = write_plane_with_indices(
        &dir,
        &plane(
            400.0,
            rw,
            raster.clone(),
            vec![
                ("dark".into(), lambertian(0.1)),
                ("bright".into(), lambertian(0.6)),
                ("grey".into(), lambertian(0.3)),
            ],
        ),
        &ids,
    );
    let reflectance = |id: u8| match id {
        5 => 0.1,
        2 => 0.6,
        0 => 0.3,
        _ => unreachable!(),
    };
    let run = |background: &str, window: &str| {
        let e = experiment(&format!(
            "seed = 1\n[spectral]\nwavelengths = [550.0]\n[illumination]\ntype = \"directional\"\nzenith = 30.0\nazimuth = 0.0\n[scene]\ntype = \"bundle\"\npath = \"{}\"\n{background}[[measures]]\nid = \"img\"\ntype = \"ortho\"\npixel_size_m = 100.0\nspp = 64\n{window}",
            b.display()
        ));
        let res = simulator::run::run(&e, false);
        simulator::products::imagery::image_products(&e, &res).remove(0)
    };
    let img = run("background = { type = \"none\" }\n", "");
    assert_eq!((img.width, img.height), (4, 4));
    for (k, &id) in raster.iter().enumerate() {
        let (got, want) = (img.brf[0][k], reflectance(id));
        assert!(
            (got - want).abs() < 1e-9,
            "pixel {k}: BRF {got}, want {want} (id {id})"
        );
    }
    // The default background is the most frequent id's material, at the terrain's height:
    // id 2 (8 of 16 cells) is `bright`. Image a window east of the raster, all background.
    let counts = ids.map(|id| raster.iter().filter(|&&v| v == id).count());
    assert_eq!(counts, [4, 8, 4]);
    let img = run(
        "",
        "window_m = [500400.0, 3999800.0, 500800.0, 4000200.0]\n",
    );
    assert_eq!((img.width, img.height), (4, 4));
    for (k, got) in img.brf[0].iter().enumerate() {
        assert!((got - 0.6).abs() < 1e-9, "background pixel {k}: BRF {got}");
    }
}

/// Self-intersection on a tilted terrain 40 km from the frame origin: with no atmosphere and no
/// background, a sunlit Lambertian plane of normal n has BRF = ρ·(n·s)/cos SZA at every point
/// and nothing else (reflected paths leave the plane for good). A ray that re-hit its own
/// triangle, or a shadow ray blocked by it, would darken pixels; a path that slipped through
/// the surface would brighten nothing but lose its estimate. Every pixel must be exact.
#[test]
fn tilted_far_terrain_has_no_self_intersection() {
    let dir = tmp("tilted");
    let mut p = plane(2000.0, 1, vec![0], vec![("soil".into(), lambertian(0.4))]);
    p.x0 = 40_000.0;
    p.y0 = -1_000.0;
    p.h0 = 300.0;
    p.sx = 0.15;
    p.sy = -0.1;
    p.n = 16;
    let b = write_plane(&dir, &p);
    let (sza, saa) = (40.0_f64, 250.0_f64);
    let e = experiment(&format!(
        "seed = 2\n[spectral]\nwavelengths = [550.0]\n[illumination]\ntype = \"directional\"\nzenith = {sza}\nazimuth = {saa}\n[scene]\ntype = \"bundle\"\npath = \"{}\"\nbackground = {{ type = \"none\" }}\n[[measures]]\nid = \"img\"\ntype = \"ortho\"\npixel_size_m = 100.0\nzenith = 20.0\nazimuth = 100.0\nwindow_m = [540100.0, 3999100.0, 541900.0, 4000900.0]\nspp = 16\n",
        b.display()
    ));
    let res = simulator::run::run(&e, false);
    let img = &simulator::products::imagery::image_products(&e, &res)[0];
    let n = glam::DVec3::new(-p.sx, -p.sy, 1.0).normalize();
    let s = engine::frame::direction_from_angles(sza.to_radians(), saa.to_radians());
    let want = 0.4 * n.dot(s) / s.z;
    for (k, &v) in img.brf[0].iter().enumerate() {
        assert!((v - want).abs() < 1e-9, "pixel {k}: {v} vs {want}");
    }
}

/// End to end through the command line: the ortho GeoTIFFs open in GDAL with the bundle's CRS
/// and the measure's geotransform, one band per wavelength, and their pixels equal the image
/// variables of `results.nc` (which also carries pixel-centre coordinates); the PNG quicklook is
/// true colour for 440/550/660 nm.
#[test]
fn ortho_geotiff_matches_netcdf() {
    use gdal::{Dataset, Metadata};
    let dir = tmp("geotiff");
    let wkt = gdal::spatial_ref::SpatialRef::from_epsg(32631)
        .unwrap()
        .to_wkt()
        .unwrap();
    let mut p = plane(
        600.0,
        3,
        vec![0, 1, 0, 1, 0, 1, 0, 1, 0],
        vec![
            ("a".into(), lambertian(0.05)),
            ("b".into(), lambertian(0.4)),
        ],
    );
    p.wkt = wkt;
    let b = write_plane(&dir, &p);
    let exp = dir.join("exp.toml");
    std::fs::write(
        &exp,
        format!(
            "seed = 4\n[spectral]\nwavelengths = [440.0, 550.0, 660.0]\n[illumination]\ntype = \"directional\"\nzenith = 30.0\nazimuth = 120.0\nirradiance = \"tsis_1\"\n{ATM}\n[scene]\ntype = \"bundle\"\npath = \"{}\"\n[[measures]]\nid = \"toa\"\ntype = \"ortho\"\npixel_size_m = 150.0\nzenith = 10.0\nazimuth = 45.0\nspp = 200\n",
            b.display()
        ),
    )
    .unwrap();
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
    assert!(
        o.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    let nc = netcdf::open(out.join("results.nc")).unwrap();
    let brf_nc: Vec<f64> = nc.variable("toa_brf").unwrap().get_values(..).unwrap();
    let xs: Vec<f64> = nc.variable("toa_x").unwrap().get_values(..).unwrap();
    let ys: Vec<f64> = nc.variable("toa_y").unwrap().get_values(..).unwrap();
    let ds = Dataset::open(out.join("toa_brf.tif")).unwrap();
    assert_eq!(ds.raster_size(), (4, 4));
    assert_eq!(ds.raster_count(), 3);
    let gt = ds.geo_transform().unwrap();
    assert_eq!(gt, [499_700.0, 150.0, 0.0, 4_000_300.0, 0.0, -150.0]);
    assert_eq!(ds.spatial_ref().unwrap().auth_code().unwrap(), 32631);
    assert!((xs[0] - 499_775.0).abs() < 1e-9 && (ys[0] - 4_000_225.0).abs() < 1e-9);
    for band in 1..=3 {
        let v = ds
            .rasterband(band)
            .unwrap()
            .read_band_as::<f32>()
            .unwrap()
            .data()
            .to_vec();
        for (k, x) in v.iter().enumerate() {
            let want = brf_nc[(band - 1) * 16 + k];
            assert!(
                (*x as f64 - want).abs() <= 1e-6 * want.abs().max(1e-3),
                "band {band} pixel {k}: tif {x} nc {want}"
            );
        }
    }
    for f in [
        "toa_brf_stderr.tif",
        "toa_radiance.tif",
        "toa_radiance_stderr.tif",
        "toa.png",
    ] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("true colour"), "{stdout}");

    // The GeoTIFFs are Cloud-Optimized, with band units and GDAL's imagery band metadata.
    assert_eq!(
        ds.metadata_item("LAYOUT", "IMAGE_STRUCTURE").as_deref(),
        Some("COG")
    );
    for (k, w) in ["0.44", "0.55", "0.66"].iter().enumerate() {
        let band = ds.rasterband(k + 1).unwrap();
        assert_eq!(band.block_size(), (256, 256));
        assert_eq!(band.unit(), "1");
        assert_eq!(
            band.metadata_item("CENTRAL_WAVELENGTH_UM", "IMAGERY")
                .as_deref(),
            Some(*w)
        );
    }
    let rad = Dataset::open(out.join("toa_radiance.tif")).unwrap();
    assert_eq!(rad.rasterband(1).unwrap().unit(), "W m-2 sr-1 nm-1");

    // results.nc is georeferenced for GDAL: the image variable opens with the GeoTIFF's
    // geotransform and CRS, one band per wavelength, the same pixels.
    drop(nc);
    let _session = engine::netcdf_session();
    let sub = format!("NETCDF:\"{}\":toa_brf", out.join("results.nc").display());
    let g = Dataset::open(&sub).unwrap();
    assert_eq!(g.raster_size(), (4, 4));
    assert_eq!(g.raster_count(), 3);
    let gt_nc = g.geo_transform().unwrap();
    for (a, b) in gt_nc.iter().zip(&gt) {
        assert!((a - b).abs() < 1e-6, "{gt_nc:?} vs {gt:?}");
    }
    let srs = g.spatial_ref().unwrap();
    assert!(srs == ds.spatial_ref().unwrap(), "{:?}", srs.to_wkt());
    assert_eq!(srs.auth_code().unwrap(), 32631);
    let v = g.rasterband(2).unwrap().read_band_as::<f64>().unwrap();
    for (k, x) in v.data().iter().enumerate() {
        assert_eq!(*x, brf_nc[16 + k], "netCDF band 2 pixel {k}");
    }
}

/// The two atmospheric estimators of the scene walk — expected value along each flight (exact
/// above the scene, one forced collision with a shadow ray below its top) and the classic
/// estimate at sampled collisions — are both unbiased, so they must agree on a scene where the
/// geometry shadows the air inside it: a cloud of random leaves 6 m tall inside a hazy layer
/// (HG g = 0.7, τ = 0.4 over 0–1 km, so a good part of the scattering happens among the
/// leaves), over a Lambertian soil.
#[test]
fn expected_and_collision_estimators_agree_in_a_canopy() {
    let dir = tmp("estimators");
    write_random_leaves(&dir.join("leaves.txt"), 9, 3000, 10.0, [0.5, 6.0], 0.25);
    let mut errs = Vec::new();
    let mut rows = Vec::new();
    for (seed, est) in [(5, "expected"), (6, "collision")] {
        let e = experiment(&format!(
            "seed = {seed}\n[spectral]\nwavelengths = [550.0]\n[illumination]\ntype = \"directional\"\nzenith = 50.0\nazimuth = 30.0\n[atmosphere]\ntype = \"layered\"\n[[atmosphere.layers]]\nbottom = 0.0\ntop = 1.0\ntau_sca = 0.4\nphase = {{ type = \"hg\", g = 0.7 }}\n[[atmosphere.layers]]\nbottom = 1.0\ntop = 100.0\ntau_sca = 0.1\n[integrator]\nlocal_estimate = \"{est}\"\n[scene]\ntype = \"canopy\"\n[[scene.objects]]\nleaves = \"{}\"\nreflectance = 0.45\ntransmittance = 0.4\n[scene.ground]\nbrdf = {{ type = \"lambertian\", reflectance = 0.2 }}\n{}",
            dir.join("leaves.txt").display(),
            distant("area", &[0.0, 35.0, 60.0], &[0.0, 30.0, 210.0], 150_000, "target_m = [-8.0, -8.0, 8.0, 8.0]\ntarget_height_m = 6.5")
        ));
        rows.push(run_rows(&e));
    }
    if let Err(e) = compare_brf_rows(
        "scene walk: expected vs collision estimators",
        &rows[0],
        &rows[1],
    ) {
        errs.push(e);
    }
    // The expected estimator is the less noisy one.
    let se = |r: &[simulator::products::Row]| r.iter().map(|x| x.brf.unwrap().1).sum::<f64>();
    println!(
        "stderr sum: expected {:.3e}, collision {:.3e}",
        se(&rows[0]),
        se(&rows[1])
    );
    assert!(errs.is_empty(), "{}", errs.join("\n"));
}

/// Reflectance textures: (1) a uniform texture equal to the material's reflectance gives results
/// bit-identical to the untextured run (same random draws, same models); (2) without atmosphere,
/// nadir ortho pixels aligned with a two-band texture equal its pixel values interpolated at the
/// run's wavelength exactly; (3) a texture in another CRS is refused, naming the file.
#[test]
fn textures_replace_the_reflectance_pixel_by_pixel() {
    use simulator::products::image::{write_geotiff, ImageBand};
    let dir = tmp("texture");
    let wkt = gdal::spatial_ref::SpatialRef::from_epsg(32631)
        .unwrap()
        .to_wkt()
        .unwrap();
    // 0.25 is exact in f32 (the texture's storage), so (1) can ask for bit identity.
    let mut p = plane(
        400.0,
        2,
        vec![0; 4],
        vec![("soil".into(), lambertian(0.25))],
    );
    p.wkt = wkt.clone();
    let b = write_plane(&dir, &p);
    let gt = [499_800.0, 100.0, 0.0, 4_000_200.0, 0.0, -100.0];
    let uniform = vec![0.25; 16];
    write_geotiff(
        &dir.join("uniform.tif"),
        4,
        4,
        gt,
        &wkt,
        &[ImageBand {
            name: "r".into(),
            description: "r".into(),
            values: &uniform,
            ..Default::default()
        }],
        &[],
    )
    .unwrap();
    let b400: Vec<f64> = (0..16).map(|k| 0.05 * (k % 5) as f64).collect();
    let b700: Vec<f64> = (0..16).map(|k| 0.9 - 0.05 * (k % 7) as f64).collect();
    write_geotiff(
        &dir.join("two_band.tif"),
        4,
        4,
        gt,
        &wkt,
        &[
            ImageBand {
                name: "r400".into(),
                description: "".into(),
                values: &b400,
                ..Default::default()
            },
            ImageBand {
                name: "r700".into(),
                description: "".into(),
                values: &b700,
                ..Default::default()
            },
        ],
        &[],
    )
    .unwrap();
    let other = gdal::spatial_ref::SpatialRef::from_epsg(32632)
        .unwrap()
        .to_wkt()
        .unwrap();
    write_geotiff(
        &dir.join("utm32.tif"),
        4,
        4,
        gt,
        &other,
        &[ImageBand {
            name: "r".into(),
            description: "".into(),
            values: &uniform,
            ..Default::default()
        }],
        &[],
    )
    .unwrap();
    let text = |atm: &str, tex: &str, measure: &str| {
        format!(
            "seed = 8\n[spectral]\nwavelengths = [500.0]\n[illumination]\ntype = \"directional\"\nzenith = 25.0\nazimuth = 70.0\n{atm}\n[scene]\ntype = \"bundle\"\npath = \"{}\"\n{tex}\n{measure}",
            b.display()
        )
    };
    // (1) Uniform texture = untextured, bit for bit.
    let meas = "[[measures]]\nid = \"img\"\ntype = \"ortho\"\npixel_size_m = 100.0\nspp = 300\n";
    let tex_u = format!(
        "[[scene.textures]]\nmaterial = \"soil\"\nfile = \"{}\"",
        dir.join("uniform.tif").display()
    );
    let (e1, e2) = (
        experiment(&text(ATM, "", meas)),
        experiment(&text(ATM, &tex_u, meas)),
    );
    let (r1, r2) = (
        simulator::run::run(&e1, false),
        simulator::run::run(&e2, false),
    );
    assert_eq!(r1[0].acc, r2[0].acc, "uniform texture changed the result");
    // (2) Exact pixels without atmosphere.
    let tex_2 = format!(
        "background = {{ type = \"none\" }}\n[[scene.textures]]\nmaterial = \"soil\"\nfile = \"{}\"\nwavelengths_nm = [400.0, 700.0]",
        dir.join("two_band.tif").display()
    );
    let e = experiment(&text("", &tex_2, meas));
    let res = simulator::run::run(&e, false);
    let img = &simulator::products::imagery::image_products(&e, &res)[0];
    for k in 0..16 {
        let want = b400[k] + (500.0 - 400.0) / 300.0 * (b700[k] - b400[k]);
        assert!(
            (img.brf[0][k] - want).abs() < 1e-6,
            "pixel {k}: {} vs {want}",
            img.brf[0][k]
        );
    }
    // (3) Wrong CRS.
    let tex_3 = format!(
        "[[scene.textures]]\nmaterial = \"soil\"\nfile = \"{}\"",
        dir.join("utm32.tif").display()
    );
    let err = engine::config::Experiment::from_str(
        &text("", &tex_3, meas),
        &common::data_dir().join("t.toml"),
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("utm32.tif") && err.contains("CRS"), "{err}");
}

/// A pinhole camera looking straight down at a uniform Lambertian plane without atmosphere sees
/// BRF = ρ in every pixel, exactly; looking at the checkerboard, the centre pixel sees the class
/// under the camera's target point and a pixel whose ray misses the terrain (no background)
/// is black.
#[test]
fn perspective_camera_sees_the_plane() {
    let dir = tmp("camera");
    let b = write_plane(
        &dir,
        &plane(
            400.0,
            2,
            vec![0, 1, 1, 0],
            vec![
                ("dark".into(), lambertian(0.1)),
                ("bright".into(), lambertian(0.6)),
            ],
        ),
    );
    // Camera 300 m above (500010, 4000010) (the north-east cell, class 1 = bright), looking down,
    // 60° field of view over 31 × 31 px: the centre pixel sees (500010, 4000010) ± 6 m.
    let e = experiment(&format!(
        "seed = 1\n[spectral]\nwavelengths = [550.0]\n[illumination]\ntype = \"directional\"\nzenith = 30.0\n[scene]\ntype = \"bundle\"\npath = \"{}\"\nbackground = {{ type = \"none\" }}\n[[measures]]\nid = \"cam\"\ntype = \"perspective\"\norigin_m = [500010.0, 4000010.0, 300.0]\ntarget_m = [500010.0, 4000010.0, 0.0]\nup = [0.0, 1.0, 0.0]\nfov = 60.0\nwidth = 31\nheight = 31\nspp = 16\n",
        b.display()
    ));
    let res = simulator::run::run(&e, false);
    let img = &simulator::products::imagery::image_products(&e, &res)[0];
    assert_eq!((img.width, img.height), (31, 31));
    let centre = img.brf[0][15 * 31 + 15];
    assert!((centre - 0.6).abs() < 1e-9, "centre pixel {centre}");
    // Top-left pixel: image up = north, right = east, so it looks north-west of the camera,
    // at about (500010 − 167, 4000010 + 167): on the plane, in the north-west cell (class 0).
    let tl = img.brf[0][0];
    assert!((tl - 0.1).abs() < 1e-9, "top-left pixel {tl}");
    for v in &img.brf[0] {
        assert!(
            (v - 0.1).abs() < 1e-9 || (v - 0.6).abs() < 1e-9 || *v == 0.0 || (*v > 0.1 && *v < 0.6),
            "{v}"
        );
    }
}

/// Watertight terrain: rays from 100 km above (where an f32 origin is only good to ~8 mm) aimed
/// at random points and exactly at the triangle edges and vertices of a tiled terrain never slip
/// through, and shadow rays from the hits never hit the terrain they leave (this failed for
/// ~0.04 % of rays before rays were clipped to the terrain in f64 and hits decided in f64).
#[test]
fn terrain_is_watertight_for_distant_rays() {
    let dir = tmp("watertight");
    let p = plane(
        400.0,
        2,
        vec![0; 4],
        vec![("soil".into(), lambertian(0.25))],
    );
    let b = write_plane(&dir, &p);
    let scene = engine::scene::build::from_bundle(
        &b,
        &engine::scene::build::Background::None,
        &[],
        &[],
        None,
    )
    .unwrap();
    let mut rng = engine::rng::Stream::new(1, [0, 0, 0, 0]);
    let sun = engine::frame::direction_from_angles(25f64.to_radians(), 70f64.to_radians());
    let (mut miss, mut occl, mut n) = (0, 0, 0);
    for k in 0..300_000 {
        // Every third ray exactly on a grid line of the 50 m quads (edges, diagonals' ends).
        let mut x = -199.9 + 399.8 * rng.next_f64();
        let mut y = -199.9 + 399.8 * rng.next_f64();
        if k % 3 == 1 {
            x = -150.0 + 50.0 * (rng.next_f64() * 7.0).floor();
        } else if k % 3 == 2 {
            y = -150.0 + 50.0 * (rng.next_f64() * 7.0).floor();
            x = y + 50.0 * (rng.next_f64() * 3.0).floor() - 50.0; // on a diagonal x − y = const
        }
        if x.abs() >= 199.9 {
            continue;
        }
        n += 1;
        let zen = std::f64::consts::PI - 0.3 * rng.next_f64();
        let d = engine::frame::direction_from_angles(zen, std::f64::consts::TAU * rng.next_f64());
        let target = glam::DVec3::new(x, y, 0.0);
        let o = target - d * (100_000.0 / -d.z);
        match scene.intersect(o, d, f64::INFINITY) {
            None => miss += 1,
            Some(h) => {
                assert!(
                    (h.point - target).length() < 1e-6,
                    "{:?} vs {target:?}",
                    h.point
                );
                let s = scene.offset(h.point, h.normal, sun);
                if scene.occluded(s, sun, f64::INFINITY) {
                    occl += 1;
                }
            }
        }
    }
    assert_eq!((miss, occl), (0, 0), "of {n} rays");
}

/// A periodic canopy cell equals the same cell padded with many copies: with `periodic_m` the
/// ray is followed cell by cell (wrapped) and the neighbours' protruding leaves are seen; with
/// 6 copies on each side (130 m) the paths lost beyond the patch are negligible for the central
/// cell's BRF. Bright leaves (ρ 0.45, τ 0.4) make multiple scattering — and so the crossing of
/// cell walls — important.
#[test]
fn periodic_cell_equals_wide_padding() {
    let dir = tmp("periodic");
    // LAI ≈ 2 of r = 0.15 m discs in a 10 × 10 × 2 m cell; centres up to the walls, so discs
    // stick out into the neighbours.
    write_random_leaves(&dir.join("leaves.txt"), 21, 2800, 5.0, [0.2, 2.0], 0.15);
    // Different seeds: the two estimates must be independent for the z-test to be calibrated
    // (with one seed most paths would be identical and any difference hidden).
    let run = |seed: u64, extra: &str| {
        let e = experiment(&format!(
            "seed = {seed}\n[spectral]\nwavelengths = [850.0]\n[illumination]\ntype = \"directional\"\nzenith = 30.0\nazimuth = 90.0\n[scene]\ntype = \"canopy\"\n{extra}\n[[scene.objects]]\nleaves = \"{}\"\nreflectance = 0.45\ntransmittance = 0.4\n[scene.ground]\nbrdf = {{ type = \"lambertian\", reflectance = 0.2 }}\n{}",
            dir.join("leaves.txt").display(),
            distant("cell", &[0.0, 30.0, 60.0], &[0.0, 90.0, 270.0], 200_000, "target_m = [-5.0, -5.0, 5.0, 5.0]\ntarget_height_m = 2.2")
        ));
        run_rows(&e)
    };
    let periodic = run(3, "periodic_m = [-5.0, -5.0, 5.0, 5.0]");
    let padded = run(4, "[scene.padding]\ncell_m = [10.0, 10.0]\ncopies = 6");
    if let Err(e) = compare_brf_rows("periodic cell = 13 × 13 padded cells", &periodic, &padded) {
        panic!("{e}");
    }
}

/// Results of a 3D scene do not depend on the thread count: an ortho image with a target
/// precision (rounds) and an area mdistant under an atmosphere, with 1 and 2 threads, give
/// bit-identical sums.
#[test]
fn scene_results_do_not_depend_on_threads() {
    let dir = tmp("threads");
    let b = write_plane(
        &dir,
        &plane(
            400.0,
            2,
            vec![0, 1, 1, 0],
            vec![
                ("dark".into(), lambertian(0.1)),
                ("bright".into(), lambertian(0.6)),
            ],
        ),
    );
    let e = experiment(&format!(
        "seed = 9\n[spectral]\nwavelengths = [500.0]\n[illumination]\ntype = \"directional\"\nzenith = 35.0\nazimuth = 20.0\n{ATM}\n[scene]\ntype = \"bundle\"\npath = \"{}\"\n[[measures]]\nid = \"img\"\ntype = \"ortho\"\npixel_size_m = 100.0\nspp = 100000\ntarget_rel_stderr = 0.02\n{}",
        b.display(),
        distant("area", &[0.0, 40.0], &[0.0, 200.0], 5000, "")
    ));
    let (a, b) = run_on_1_and_2_threads(&e);
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.acc, y.acc, "results differ between 1 and 2 threads");
    }
}

/// The Sun clearance map (`scene/sun_clearance.rs`) only skips shadow rays that the scene's BVHs
/// would answer "not blocked": for 60 cone trees (instanced trunks and crowns) up to 25 m over a
/// ground and for a tilted terrain 40 km from the origin, random points (among the leaves, above them, near the
/// terrain) and Sun directions from overhead to 80° zenith, a point the map clears is never
/// occluded; and the map clears nearly all the unoccluded points above the geometry's top.
#[test]
fn sun_clearance_never_hides_a_shadow() {
    use engine::scene::build::{canopy, from_bundle, Background};
    use glam::DVec3;
    // 60 cone trees up to 25 m tall over 200 m × 200 m: shadows with gaps between them.
    let mut rng = engine::rng::Stream::new(4, [0, 0, 0, 0]);
    let trees = engine::scene::build::ConeTrees {
        positions: (0..60)
            .map(|_| {
                DVec3::new(
                    200.0 * rng.next_f64() - 100.0,
                    200.0 * rng.next_f64() - 100.0,
                    0.0,
                )
            })
            .collect(),
        trunk_radius: 0.3,
        trunk_bottom: 0.0,
        trunk_top: 8.0,
        trunk_brdf: lambertian(0.1),
        crown_height: 17.0,
        crown_radius: 4.0,
        leaves: 200,
        leaf_radius: 0.3,
        mu: 2.0,
        nu: 2.0,
        leaf_brdf: lambertian(0.4),
        variants: 3,
        seed: 1,
    };
    let ground = engine::scene::build::CanopyGround {
        altitude: 0.0,
        extent: None,
        brdf: lambertian(0.2),
    };
    let leafy = canopy(&[], &[trees], Some(&ground), None, None).unwrap();
    let mut p = plane(2000.0, 1, vec![0], vec![("soil".into(), lambertian(0.4))]);
    (p.x0, p.y0, p.h0, p.sx, p.sy, p.n) = (40_000.0, -1_000.0, 300.0, 0.15, -0.1, 16);
    let hill = from_bundle(
        &write_plane(&tmp("clearance_hill"), &p),
        &Background::None,
        &[],
        &[],
        None,
    )
    .unwrap();
    let mut rng = engine::rng::Stream::new(8, [0, 0, 0, 0]);
    for (name, scene) in [("canopy", &leafy), ("terrain", &hill)] {
        let (e, z) = (scene.extent, scene.z_range);
        let (mut cleared, mut free, mut high_free) = (0usize, 0usize, 0usize);
        for k in 0..10 {
            let zen = if k == 0 {
                0.0
            } else {
                80f64.to_radians() * rng.next_f64()
            };
            let sun =
                engine::frame::direction_from_angles(zen, std::f64::consts::TAU * rng.next_f64());
            let map = scene.sun_clearance(sun).expect("a map");
            for _ in 0..5000 {
                let q = DVec3::new(
                    e[0] + (e[2] - e[0]) * rng.next_f64(),
                    e[1] + (e[3] - e[1]) * rng.next_f64(),
                    z[0] + 1.5 * (z[1] - z[0]) * rng.next_f64(),
                );
                let blocked = scene.occluded(q, sun, f64::INFINITY);
                if map.clear(q) {
                    assert!(!blocked, "{name}: sun {sun}, point {q} cleared but blocked");
                    cleared += 1;
                }
                if !blocked && q.z > z[1] {
                    high_free += 1;
                }
                free += !blocked as usize;
            }
        }
        println!("{name}: {cleared} cleared of {free} unblocked ({high_free} above the top)");
        // (Points just above the top, within the boxes' padding, are not cleared.)
        assert!(
            cleared as f64 >= 0.9 * high_free as f64,
            "{name}: {cleared} < 0.9 × {high_free}"
        );
    }
}
