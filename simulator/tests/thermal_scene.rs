//! Thermal emission of 3D scenes (issue 16, item 3). Each test states its rationale;
//! statistical comparisons use `common::check_all` (|diff| ≤ 4.5σ + floor).
//!
//! * **Flat bundle = 1D** (`flat_bundle_equals_1d_surface`): a flat one-material bundle at
//!   300 K, with the background plane of the same material, is an infinite uniform surface: its
//!   area radiance under an emitting, scattering layer equals the 1D surface's (another seed).
//! * **Kirchhoff closure in 3D** (`isothermal_cavity_radiates_planck`): a terrain, a floating
//!   bi-Lambertian leaf plate (ρ 0.3, τ 0.2: emissivity 0.5 on each face) and an RPV plate, all
//!   at 290 K under an opaque non-scattering isothermal 290 K sky: every camera pixel sees
//!   exactly B(290 K) whatever it looks at (what a surface does not emit it reflects or
//!   transmits from an isothermal enclosure), which fails if any emissivity, face or
//!   transmittance is wrong.
//! * **Land-surface temperature** (`lst_raster_sets_the_pixels`): a black flat plane, no
//!   atmosphere, a 4×4 LST GeoTIFF from 270 to 345 K; nadir ortho pixels aligned with it have
//!   exactly the raster's temperature as brightness temperature (zero variance), and the
//!   ortho product writes the brightness-temperature GeoTIFF.
//! * Errors: a material without a temperature is named, and one too cold to radiate anything
//!   representable (its Planck radiance underflows).

mod common;

use bundle::{BiLambertianSpec, BrdfSpec, RpvSpec, Spectrum};
use common::bundles::{lambertian, tmp, with_plate, write_plane, PlaneSpec};
use common::{check_all, experiment, run_rows, Cmp};
use engine::sources::planck;

const WL: f64 = 10_000.0;

fn plane(size: f64, materials: Vec<(String, BrdfSpec)>, wkt: String) -> PlaneSpec {
    PlaneSpec {
        x0: -0.5 * size,
        y0: -0.5 * size,
        size,
        h0: 0.0,
        sx: 0.0,
        sy: 0.0,
        tiles: 2,
        n: 4,
        raster_width: 4,
        raster: vec![0; 16],
        materials,
        frame_origin: [500_000.0, 4_000_000.0, 0.0],
        wkt,
    }
}

const LAYER: &str = "[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = 0.8\nsingle_scattering_albedo = 0.3\n\
                     phase = { type = \"hg\", g = 0.6 }\ntemperature_bottom = 285.0\ntemperature_top = 230.0";

fn mdistant(spp: u64, extra: &str) -> String {
    format!(
        "[[measures]]\nid = \"toa\"\ntype = \"mdistant\"\nconstruct = \"directions\"\nzeniths = [0.0, 40.0, 65.0]\n\
         azimuths = [0.0, 90.0, 200.0]\nspp = {spp}\n{extra}\n"
    )
}

#[test]
fn flat_bundle_equals_1d_surface() {
    let dir = tmp("thermal-flat");
    let b = write_plane(
        &dir,
        &plane(
            2000.0,
            vec![("soil".into(), lambertian(0.1))],
            String::new(),
        ),
    );
    let head = format!(
        "emission = true\nseed = 3\n[spectral]\nwavelengths = [{WL:?}]\n[illumination]\ntype = \"none\"\n{LAYER}\n"
    );
    let e3 = experiment(&format!(
        "{head}[scene]\ntype = \"bundle\"\npath = \"{}\"\n[scene.temperatures]\nsoil = 300.0\n{}",
        b.display(),
        mdistant(
            60_000,
            "target_m = [499800.0, 3999800.0, 500200.0, 4000200.0]"
        )
    ));
    let e1 = experiment(&format!(
        "{}[surface]\ntype = \"lambertian\"\nreflectance = 0.1\ntemperature = 300.0\n{}",
        head.replace("seed = 3", "seed = 4"),
        mdistant(60_000, "")
    ));
    let (r3, r1) = (run_rows(&e3), run_rows(&e1));
    let cmps: Vec<Cmp> = r3
        .iter()
        .zip(&r1)
        .map(|(a, b)| {
            let (va, sa) = a.radiance.unwrap();
            let (vb, sb) = b.radiance.unwrap();
            Cmp {
                label: format!("{}°", a.vza.unwrap()),
                reference: vb,
                value: va,
                stderr: (sa * sa + sb * sb).sqrt(),
            }
        })
        .collect();
    check_all("flat thermal bundle = 1D", &cmps).unwrap();
}

#[test]
fn isothermal_cavity_radiates_planck() {
    let dir = tmp("thermal-cavity");
    let base = write_plane(
        &dir.join("base"),
        &plane(
            400.0,
            vec![("soil".into(), lambertian(0.25))],
            String::new(),
        ),
    );
    let leaf = BrdfSpec::BiLambertian(BiLambertianSpec {
        reflectance: Spectrum::Constant(0.3),
        transmittance: Spectrum::Constant(0.2),
    });
    let with_leaf = with_plate(
        &base,
        &dir.join("leaf"),
        (0.0, 0.0, 12.0),
        20.0,
        1,
        "leaf",
        leaf,
        None,
    );
    let rpv = BrdfSpec::Rpv(RpvSpec {
        rho_0: Spectrum::Constant(0.15),
        k: Spectrum::Constant(0.6),
        g: Spectrum::Constant(-0.2),
        rho_c: None,
    });
    let b = with_plate(
        &with_leaf,
        &dir.join("both"),
        (30.0, 10.0, 6.0),
        8.0,
        2,
        "stone",
        rpv,
        None,
    );
    // A camera 40 m above the leaf plate's corner looking down at 30° off nadir: its pixels
    // see the leaf (top), the stone, the soil and the underside of the leaf's shadowed area.
    let text = format!(
        "emission = true\nseed = 9\n[spectral]\nwavelengths = [{WL:?}]\n[illumination]\ntype = \"none\"\n\
         [geometry]\ntype = \"plane_parallel\"\ntoa_altitude = 1.0\n\
         [atmosphere]\ntype = \"homogeneous\"\noptical_thickness = 30.0\nsingle_scattering_albedo = 0.0\ntemperature = 290.0\n\
         [scene]\ntype = \"bundle\"\npath = \"{}\"\n[scene.temperatures]\nsoil = 290.0\nleaf = 290.0\nstone = 290.0\n\
         [[measures]]\nid = \"cam\"\ntype = \"perspective\"\norigin_m = [499990.0, 3999980.0, 40.0]\n\
         target_m = [500010.0, 4000005.0, 0.0]\nup = [0.0, 1.0, 0.0]\nfov = 60.0\nwidth = 4\nheight = 4\nspp = 4000\n",
        b.display()
    );
    let e = experiment(&text);
    let res = simulator::run::run(&e, false);
    let img = &simulator::products::imagery::image_products(&e, &res)[0];
    let bt = planck::radiance(WL, 290.0);
    let cmps: Vec<Cmp> = (0..16)
        .map(|k| Cmp {
            label: format!("pixel {k}"),
            reference: 1.0,
            value: img.radiance[0][k] / bt,
            stderr: img.radiance_stderr[0][k] / bt,
        })
        .collect();
    check_all("isothermal cavity = B(T)", &cmps).unwrap();
    let (t, se) = img.brightness_temperature.as_ref().unwrap();
    for k in 0..16 {
        assert!(
            (t[0][k] - 290.0).abs() <= 4.5 * se[0][k] + 0.01,
            "pixel {k}: BT {} ± {}",
            t[0][k],
            se[0][k]
        );
    }
}

#[test]
fn lst_raster_sets_the_pixels() {
    use simulator::products::image::{write_geotiff, ImageBand};
    let dir = tmp("thermal-lst");
    let wkt = gdal::spatial_ref::SpatialRef::from_epsg(32631)
        .unwrap()
        .to_wkt()
        .unwrap();
    let b = write_plane(
        &dir,
        &plane(400.0, vec![("soil".into(), lambertian(0.0))], wkt.clone()),
    );
    let gt = [499_800.0, 100.0, 0.0, 4_000_200.0, 0.0, -100.0];
    let lst: Vec<f64> = (0..16).map(|k| 270.0 + 5.0 * k as f64).collect();
    write_geotiff(
        &dir.join("lst.tif"),
        4,
        4,
        gt,
        &wkt,
        &[ImageBand {
            name: "lst".into(),
            description: "K".into(),
            values: &lst,
            ..Default::default()
        }],
        &[],
    )
    .unwrap();
    let out = dir.join("out");
    let text = format!(
        "emission = true\nseed = 1\n[spectral]\nwavelengths = [{WL:?}]\n[illumination]\ntype = \"none\"\n\
         [scene]\ntype = \"bundle\"\npath = \"{}\"\nbackground = {{ type = \"none\" }}\n\
         land_surface_temperature = \"{}\"\n[scene.temperatures]\nsoil = 250.0\n\
         [[measures]]\nid = \"img\"\ntype = \"ortho\"\npixel_size_m = 100.0\nspp = 16\n",
        b.display(),
        dir.join("lst.tif").display()
    );
    let e = experiment(&text);
    let res = simulator::run::run(&e, false);
    let img = &simulator::products::imagery::image_products(&e, &res)[0];
    let (t, se) = img.brightness_temperature.as_ref().unwrap();
    for k in 0..16 {
        assert!(
            (t[0][k] - lst[k]).abs() < 1e-6,
            "pixel {k}: {} vs {}",
            t[0][k],
            lst[k]
        );
        assert!(se[0][k] < 1e-6, "{}", se[0][k]);
    }
    // The products: the brightness-temperature GeoTIFF and its quicklook.
    let (files, what) = simulator::products::imagery::write_files(&out_dir(&out), &e, img).unwrap();
    assert!(
        files
            .iter()
            .any(|f| f.ends_with("img_brightness_temperature.tif")),
        "{files:?}"
    );
    assert!(what.contains("brightness temperature"), "{what}");
    let ds = gdal::Dataset::open(out.join("img_brightness_temperature.tif")).unwrap();
    let band = ds.rasterband(1).unwrap().read_band_as::<f64>().unwrap();
    assert!((band.data()[5] - lst[5]).abs() < 1e-3);
}

fn out_dir(p: &std::path::Path) -> std::path::PathBuf {
    std::fs::create_dir_all(p).unwrap();
    p.to_path_buf()
}

#[test]
fn a_material_without_temperature_is_named() {
    let dir = tmp("thermal-missing");
    let b = write_plane(
        &dir,
        &plane(400.0, vec![("soil".into(), lambertian(0.1))], String::new()),
    );
    let text = format!(
        "emission = true\n[spectral]\nwavelengths = [{WL:?}]\n[illumination]\ntype = \"none\"\n\
         [scene]\ntype = \"bundle\"\npath = \"{}\"\n{}",
        b.display(),
        mdistant(16, "")
    );
    let e = engine::config::Experiment::from_str(&text, &common::data_dir().join("t.toml"))
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("scene.temperatures") && e.contains("soil"),
        "{e}"
    );
    let bad = text.replace(
        "[[measures]]",
        "[scene.temperatures]\nsand = 300.0\n[[measures]]",
    );
    let e = engine::config::Experiment::from_str(&bad, &common::data_dir().join("t.toml"))
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("scene.temperatures.sand"), "{e}");
    // A material so cold that its Planck radiance underflows at 10 µm (issue 43).
    let cold = text.replace(
        "[[measures]]",
        "[scene.temperatures]\nsoil = 1.0\n[[measures]]",
    );
    let e = engine::config::Experiment::from_str(&cold, &common::data_dir().join("t.toml"))
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("scene.temperatures.soil") && e.contains("underflows"),
        "{e}"
    );
}
