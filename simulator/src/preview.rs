//! `simulate preview`: a quick look at a scene before an expensive run (DIRSIG's Preview
//! solver). For every image measure (ortho or perspective) of an experiment with a scene it
//! traces one primary ray through each pixel centre and writes:
//!
//! * `ID_materials.tif` (ortho: georeferenced; perspective: pixel grid only): the material
//!   index of the first surface hit, `Byte`, 255 where the ray hits nothing; a GDAL colour table
//!   and the material names as category names, so QGIS and `gdalinfo` show the classes;
//!   `ID_materials.png`, the same in colour;
//! * `ID_relief.png`: shaded relief, `0.15 + 0.85·max(0, n·l)` with the light from the Sun
//!   (or from the north-west at 45° elevation when the Sun is below the horizon), shadows
//!   included;
//! * `ID_direct_brf.tif` and `.png`: the BRF of the direct Sun alone with no atmosphere,
//!   `π·f(ωs, ωv)·(n·ωs)/μs` where the Sun is visible from the hit, 0 in shadow, one band per
//!   wavelength (reflectance textures included) — the first-order term of a full run.
//!
//! No random numbers are drawn, so the output does not depend on the thread count.

use std::path::{Path, PathBuf};

use glam::DVec3;
use rayon::prelude::*;

use crate::error::OutputError;
use crate::products::image::{
    sidecar_path, write_geotiff, write_png, write_quicklook_png, ImageBand,
};
use engine::config::resolve::Experiment;
use engine::measure::{Measure, MeasureKind};
use engine::scene::material::SurfaceModel;
use engine::scene::Scene;

/// Material index written where the ray hits nothing (or a black helper surface).
pub const NO_HIT: u8 = 255;

/// The preview of one image measure.
pub struct Preview {
    pub id: String,
    pub width: usize,
    pub height: usize,
    /// Working-CRS geotransform (ortho only).
    pub geotransform: Option<[f64; 6]>,
    /// Per pixel, row-major from the top.
    pub material: Vec<u8>,
    pub relief: Vec<f64>,
    /// `[wavelength][pixel]`.
    pub direct_brf: Vec<Vec<f64>>,
}

/// Trace the previews of every image measure of `exp` (which must have a scene).
pub fn render(exp: &Experiment) -> Result<Vec<Preview>, String> {
    let scene = exp
        .scene
        .as_ref()
        .ok_or("`simulate preview` needs an experiment with a [scene]")?;
    let models: Vec<Vec<SurfaceModel>> = exp
        .wavelengths
        .iter()
        .enumerate()
        .map(|(iw, &w)| scene.models_at(iw, w).map_err(|e| e.to_string()))
        .collect::<Result<_, _>>()?;
    let sun = exp.sun_dir;
    let light = if sun.z > 1e-6 {
        sun
    } else {
        DVec3::new(-1.0, 1.0, 2f64.sqrt()).normalize()
    };
    let mut out = Vec::new();
    for m in exp.measures.iter().filter(|m| m.is_image()) {
        out.push(render_one(exp, scene, m, &models, sun, light));
    }
    if out.is_empty() {
        return Err("the experiment has no image measure (ortho or perspective) to preview".into());
    }
    Ok(out)
}

fn render_one(
    exp: &Experiment,
    scene: &Scene,
    m: &Measure,
    models: &[Vec<SurfaceModel>],
    sun: DVec3,
    light: DVec3,
) -> Preview {
    let (width, height, geotransform) = match &m.kind {
        MeasureKind::Ortho(g) => {
            let o = scene.georef.as_ref().map_or(DVec3::ZERO, |g| g.origin);
            let t = g.geotransform;
            (
                g.width,
                g.height,
                Some([t[0] + o.x, t[1], t[2], t[3] + o.y, t[4], t[5]]),
            )
        }
        MeasureKind::Perspective(c) => (c.width, c.height, None),
        MeasureKind::Distant { .. }
        | MeasureKind::Radiancemeter { .. }
        | MeasureKind::DistantFlux { .. }
        | MeasureKind::Hdrf { .. } => unreachable!("image measures only"),
    };
    let nw = exp.wavelengths.len();
    let mu_s = sun.z.max(1e-6);
    let pixels: Vec<(u8, f64, Vec<f64>)> = (0..width * height)
        .into_par_iter()
        .map(|cell| {
            let Some((o, d)) = engine::sensor::image_ray(scene, m, cell, 0.5, 0.5) else {
                return (NO_HIT, f64::NAN, vec![f64::NAN; nw]);
            };
            let Some(h) = scene.intersect(o, d, f64::INFINITY) else {
                return (NO_HIT, 0.0, vec![f64::NAN; nw]);
            };
            let wo = -d;
            let n = if h.normal.dot(wo) < 0.0 {
                -h.normal
            } else {
                h.normal
            };
            let lit = |l: DVec3| {
                n.dot(l) > 0.0 && !scene.occluded(scene.offset(h.point, n, l), l, f64::INFINITY)
            };
            let relief = 0.15 + 0.85 * if lit(light) { n.dot(light) } else { 0.0 };
            let sunlit = sun.z > 1e-6 && lit(sun);
            let material = if (h.material as usize) < scene.materials.len() {
                h.material.min(254) as u8
            } else {
                NO_HIT
            };
            let brf = (0..nw)
                .map(|iw| {
                    if !sunlit || material == NO_HIT {
                        return 0.0;
                    }
                    let model = match scene.texture_reflectance(&h, exp.wavelengths[iw]) {
                        Some(r) => SurfaceModel::Opaque(engine::bsdf::Bsdf::Lambertian(
                            engine::bsdf::Lambertian { reflectance: r },
                        )),
                        None => models[iw][h.material as usize].clone(),
                    };
                    std::f64::consts::PI * model.eval_cos(n, sun, wo) / mu_s
                })
                .collect();
            (material, relief, brf)
        })
        .collect();
    let mut p = Preview {
        id: m.id.clone(),
        width,
        height,
        geotransform,
        material: Vec::with_capacity(pixels.len()),
        relief: Vec::with_capacity(pixels.len()),
        direct_brf: vec![Vec::with_capacity(pixels.len()); nw],
    };
    for (mat, rel, brf) in pixels {
        p.material.push(mat);
        p.relief.push(rel);
        for (iw, b) in brf.into_iter().enumerate() {
            p.direct_brf[iw].push(b);
        }
    }
    p
}

/// A distinct colour per material index (golden-angle hues), black for [`NO_HIT`].
pub fn colour(index: u8) -> [u8; 3] {
    if index == NO_HIT {
        return [0, 0, 0];
    }
    let h = (index as f64 * 137.507_764).rem_euclid(360.0) / 60.0;
    let (s, v) = (0.55, 0.9);
    let c = v * s;
    let x = c * (1.0 - (h.rem_euclid(2.0) - 1.0).abs());
    let (r, g, b) = match h as u32 {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    let m = v - c;
    [r, g, b].map(|v| ((v + m) * 255.0).round() as u8)
}

/// Write the preview files of `p` into `dir`; returns the paths.
pub fn write(
    dir: &Path,
    exp: &Experiment,
    p: &Preview,
    names: &[String],
) -> Result<Vec<PathBuf>, OutputError> {
    let mut written = Vec::new();
    let wkt = exp
        .scene
        .as_ref()
        .and_then(|s| s.georef.as_ref())
        .map_or(String::new(), |g| g.wkt.clone());
    let path = dir.join(format!("{}_materials.tif", p.id));
    write_material_tiff(&path, p, &wkt, names)?;
    written.push(path);
    let rgb: Vec<u8> = p.material.iter().flat_map(|&m| colour(m)).collect();
    let path = dir.join(format!("{}_materials.png", p.id));
    write_png(
        &path,
        p.width as u32,
        p.height as u32,
        image::ExtendedColorType::Rgb8,
        &rgb,
    )?;
    written.push(path);
    let grey: Vec<u8> = p
        .relief
        .iter()
        .map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)
        .collect();
    let path = dir.join(format!("{}_relief.png", p.id));
    write_png(
        &path,
        p.width as u32,
        p.height as u32,
        image::ExtendedColorType::L8,
        &grey,
    )?;
    written.push(path);
    if let Some(gt) = p.geotransform {
        let bands: Vec<ImageBand> = exp
            .wavelengths
            .iter()
            .zip(&p.direct_brf)
            .map(|(w, v)| ImageBand {
                name: format!("direct_brf_{w}nm"),
                description: format!("direct-Sun BRF without atmosphere at {w} nm"),
                values: v,
                unit: "1".into(),
                wavelength_nm: Some(*w),
                fwhm_nm: None,
            })
            .collect();
        let path = dir.join(format!("{}_direct_brf.tif", p.id));
        write_geotiff(&path, p.width, p.height, gt, &wkt, &bands, &[])?;
        written.push(path);
    }
    let path = dir.join(format!("{}_direct_brf.png", p.id));
    let channels: Vec<&[f64]> = p.direct_brf.iter().map(|v| v.as_slice()).collect();
    write_quicklook_png(&path, p.width, p.height, &exp.wavelengths, &channels)?;
    written.push(path);
    Ok(written)
}

/// The material raster as a `Byte` GeoTIFF with a colour table and category names.
fn write_material_tiff(
    path: &Path,
    p: &Preview,
    wkt: &str,
    names: &[String],
) -> Result<(), OutputError> {
    use gdal::raster::{Buffer, ColorEntry, ColorTable, PaletteInterpretation};
    use gdal::Metadata;
    let gerr = |what: &str| {
        let what = what.to_string();
        move |source| OutputError::Gdal {
            path: path.to_path_buf(),
            what,
            source,
        }
    };
    let tmp = crate::products::tmp_path(path);
    let result = (|| -> Result<(), OutputError> {
        let driver =
            gdal::DriverManager::get_driver_by_name("GTiff").map_err(gerr("GTiff driver"))?;
        let mut ds = driver
            .create_with_band_type::<u8, _>(&tmp, p.width, p.height, 1)
            .map_err(gerr("create"))?;
        if let Some(gt) = p.geotransform {
            ds.set_geo_transform(&gt).map_err(gerr("geotransform"))?;
            if !wkt.is_empty() {
                ds.set_projection(wkt).map_err(gerr("projection"))?;
            }
        }
        let mut band = ds.rasterband(1).map_err(gerr("band"))?;
        let mut buf = Buffer::new((p.width, p.height), p.material.clone());
        band.write((0, 0), (p.width, p.height), &mut buf)
            .map_err(gerr("write"))?;
        band.set_no_data_value(Some(NO_HIT as f64))
            .map_err(gerr("nodata"))?;
        band.set_description("material index of the first surface hit")
            .map_err(gerr("description"))?;
        let mut table = ColorTable::new(PaletteInterpretation::Rgba);
        for k in 0..=255u8 {
            let [r, g, b] = colour(k);
            table.set_color_entry(
                k as u16,
                &ColorEntry::rgba(
                    r as i16,
                    g as i16,
                    b as i16,
                    if k == NO_HIT { 0 } else { 255 },
                ),
            );
        }
        band.set_color_table(&table);
        // Category names: the material of each index, "" for unused ones, "no hit" at 255.
        let mut cats: Vec<String> = (0..256).map(|_| String::new()).collect();
        for (k, n) in names.iter().enumerate().take(255) {
            cats[k] = n.clone();
        }
        cats[NO_HIT as usize] = "no hit".into();
        let c: Vec<std::ffi::CString> = cats
            .iter()
            .map(|s| std::ffi::CString::new(s.replace('\0', "")).unwrap_or_default())
            .collect();
        let mut ptrs: Vec<*mut std::ffi::c_char> = c
            .iter()
            .map(|s| s.as_ptr() as *mut std::ffi::c_char)
            .collect();
        ptrs.push(std::ptr::null_mut());
        // SAFETY: a NULL-terminated list of valid C strings that outlive the call (GDAL copies).
        let rv =
            unsafe { gdal_sys::GDALSetRasterCategoryNames(band.c_rasterband(), ptrs.as_mut_ptr()) };
        if rv != gdal_sys::CPLErr::CE_None {
            return Err(OutputError::Io {
                path: path.to_path_buf(),
                source: std::io::Error::other("GDAL could not set the category names"),
            });
        }
        ds.close().map_err(gerr("close"))?;
        // GDAL does not always report a full disk: read every pixel back before the rename,
        // so a truncated GeoTIFF never takes the product's place.
        let back = gdal::Dataset::open(&tmp).map_err(gerr("read back (a full disk?)"))?;
        back.rasterband(1)
            .and_then(|b| b.read_as::<u8>((0, 0), (p.width, p.height), (p.width, p.height), None))
            .map_err(gerr("read back (a full disk?)"))?;
        Ok(())
    })();
    // GDAL keeps the category names in its PAM side-car (`.aux.xml`), which follows the file.
    let (tmp_aux, aux) = (sidecar_path(&tmp), sidecar_path(path));
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        let _ = std::fs::remove_file(&tmp_aux);
        return Err(e);
    }
    let io = |source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    };
    if tmp_aux.is_file() {
        std::fs::rename(&tmp_aux, &aux).map_err(io)?;
    } else {
        let _ = std::fs::remove_file(&aux);
    }
    std::fs::rename(&tmp, path).map_err(io)
}
