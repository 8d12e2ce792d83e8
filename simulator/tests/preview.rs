//! `simulate preview` (issue 17, DIRSIG's Preview solver): over a flat Lambertian bundle the
//! direct-Sun BRF without atmosphere is exactly the reflectance in every pixel, the material
//! GeoTIFF holds the material's index with its name as a category and a colour table, the
//! shaded relief is 0.15 + 0.85·cos SZA; an experiment without a scene or image is refused.

mod common;

use std::process::Command;

use common::bundles::{flat_plane, tmp, write_plane};
use gdal::Dataset;

fn simulate(args: &[&str]) -> (i32, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_simulate"))
        .args(args)
        .output()
        .unwrap();
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[test]
fn flat_lambertian_preview_is_exact() {
    let dir = tmp("preview");
    let b = write_plane(&dir, &flat_plane(2000.0, 0.0, -1000.0, 0.25));
    let exp = dir.join("exp.toml");
    std::fs::write(
        &exp,
        format!(
            "[spectral]\nwavelengths = [550.0, 660.0]\n[scene]\ntype = \"bundle\"\npath = \"{}\"\n[illumination]\ntype = \"directional\"\nzenith = 30.0\nazimuth = 40.0\n[[measures]]\nid = \"img\"\ntype = \"ortho\"\npixel_size_m = 200.0\nwindow_m = [499200.0, 3999200.0, 500800.0, 4000800.0]\nspp = 2\n",
            b.display()
        ),
    )
    .unwrap();
    let out = dir.join("out");
    let (code, err) = simulate(&[
        "preview",
        exp.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");

    let brf = Dataset::open(out.join("img_direct_brf.tif")).unwrap();
    assert_eq!(brf.raster_count(), 2);
    for k in 1..=2 {
        let v = brf.rasterband(k).unwrap().read_band_as::<f64>().unwrap();
        for x in v.data() {
            assert!((x - 0.25).abs() < 1e-6, "direct BRF {x}, expected 0.25");
        }
    }
    let mat = Dataset::open(out.join("img_materials.tif")).unwrap();
    let band = mat.rasterband(1).unwrap();
    let v = band.read_band_as::<u8>().unwrap();
    assert!(v.data().iter().all(|&m| m == 0), "{:?}", v.data());
    assert!(band.color_table().is_some());
    let cats = unsafe {
        let list = gdal_sys::GDALGetRasterCategoryNames(band.c_rasterband());
        assert!(!list.is_null(), "no category names");
        std::ffi::CStr::from_ptr(*list)
            .to_string_lossy()
            .into_owned()
    };
    assert_eq!(cats, "soil");
    let relief = image::open(out.join("img_relief.png")).unwrap().to_luma8();
    let want = ((0.15 + 0.85 * 30f64.to_radians().cos()) * 255.0).round() as u8;
    assert!(
        relief.pixels().all(|p| p.0[0].abs_diff(want) <= 1),
        "relief != {want}"
    );

    // No image measure, and no scene: refused, naming the file.
    let no_img = dir.join("no_img.toml");
    let text = std::fs::read_to_string(&exp)
        .unwrap()
        .replace("type = \"ortho\"\npixel_size_m = 200.0\nwindow_m = [499200.0, 3999200.0, 500800.0, 4000800.0]", "type = \"mdistant\"\nconstruct = \"hplane\"\nazimuth = 0.0\nzeniths = [0.0]\ntarget_m = [499500.0, 3999500.0, 500500.0, 4000500.0]");
    std::fs::write(&no_img, text).unwrap();
    let (code, err) = simulate(&[
        "preview",
        no_img.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("no_img.toml") && err.contains("no image measure"),
        "{err}"
    );
    let (code, err) = simulate(&[
        "preview",
        "../examples/rayleigh_lambertian.toml",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("[scene]"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}
