//! Image products of `ortho` and `perspective` measures.
//!
//! For every image measure `ID` the run writes, beside `results.nc` (which holds the same data
//! as `ID_brf(wavelength, ID_y, ID_x)` and friends):
//! * ortho measures: `ID_brf.tif`, `ID_brf_stderr.tif`, `ID_radiance.tif`,
//!   `ID_radiance_stderr.tif` — Float32 GeoTIFFs in the scene's CRS (a bundle's working CRS;
//!   none for canopies) with the pixel-corner geotransform, one band per wavelength (band `k`
//!   is `exp.wavelengths[k]`, also given as the band's `CENTRAL_WAVELENGTH_UM` in the `IMAGERY`
//!   metadata domain), the band unit set (`W m-2 sr-1 nm-1` or `1`), NaN as nodata, written as
//!   Cloud-Optimized GeoTIFFs (256×256 tiles, overviews; `products::image`);
//! * polarized runs, ortho measures also: `ID_q.tif`, `ID_u.tif` (BRF-normalised Stokes Q and U,
//!   `π·Q/(E0 cos SZA)`, in the meridian frame of the view direction, `stokes.rs`), `ID_dolp.tif`
//!   and `ID_dolp_stderr.tif` (degree of linear polarization √(Q²+U²)/I and its standard error);
//! * thermal runs (`emission = true`), ortho measures also: `ID_brightness_temperature.tif` and
//!   `ID_brightness_temperature_stderr.tif` (K, inverse Planck of each pixel's radiance at the
//!   band's wavelength, delta-method error);
//! * ortho measures over a `[[clouds]]` field also: `ID_clouds.tif`, two bands: the cloud
//!   optical thickness along each pixel's lines of sight (times cos VZA) and the cloud fraction
//!   (`cloud_bands.rs`);
//! * both: `ID.png`, a quicklook of the BRF (true colour when wavelengths near 660/550/440 nm
//!   were simulated, grey otherwise; see `products::image`), or in thermal runs of the first
//!   wavelength's brightness temperature (grey from its 1st to its 99th percentile), or without
//!   the Sun above the horizon (twilight) of the radiance;
//! * without the Sun above the horizon (thermal emission only, twilight) there is no BRF: the
//!   BRF-normalised files (`ID_brf*.tif`, `ID_q.tif`, `ID_u.tif`) are not written.
//!
//! Units: radiance W m⁻² sr⁻¹ nm⁻¹ (the irradiance's unit per sr), BRF dimensionless.

use std::path::{Path, PathBuf};

use super::image::{write_geotiff, write_quicklook_png, ImageBand};
use crate::error::OutputError;
use engine::accum::MeasureResult;
use engine::config::resolve::Experiment;
use engine::measure::MeasureKind;

/// Per-wavelength pixel values, `[wavelength][pixel]`.
pub type Image = Vec<Vec<f64>>;

/// One image measure's results, per wavelength.
#[derive(Clone, Debug)]
pub struct ImageProduct {
    pub measure: usize,
    pub id: String,
    pub width: usize,
    pub height: usize,
    /// GDAL geotransform in the scene's CRS coordinates (ortho only).
    pub geotransform: Option<[f64; 6]>,
    /// WKT of the CRS (empty when the scene has none).
    pub wkt: String,
    /// Whether the BRF is defined (the Sun above the target's horizon): without, the files
    /// carry radiances only and `brf` holds π·L/E0 (normalised by cos SZA = 1).
    pub has_brf: bool,
    /// `[wavelength][pixel]`, row-major from the north / the top.
    pub brf: Vec<Vec<f64>>,
    pub brf_stderr: Vec<Vec<f64>>,
    pub brf_single: Vec<Vec<f64>>,
    pub brf_multiple: Vec<Vec<f64>>,
    pub radiance: Vec<Vec<f64>>,
    pub radiance_stderr: Vec<Vec<f64>>,
    /// The fewest samples of any pixel, per wavelength.
    pub n_samples: Vec<u64>,
    /// `[wavelength][pixel]`: samples of each pixel (they differ where adaptive rounds stopped
    /// pixels that met the target, `run.rs`).
    pub pixel_samples: Vec<Vec<u64>>,
    /// View angles of an ortho image, degrees.
    pub view: Option<(f64, f64)>,
    /// Polarized runs: per wavelength and pixel, BRF-normalised Q and U, the degree of linear
    /// polarization and its standard error.
    pub stokes: Option<ImageStokes>,
    /// Thermal runs (`emission = true`): per wavelength and pixel, the brightness temperature
    /// (K, inverse Planck of the radiance) and its delta-method standard error.
    pub brightness_temperature: Option<(Image, Image)>,
    /// Ortho images over a `[[clouds]]` field: per pixel, the cloud optical thickness seen and
    /// the cloud fraction (`cloud_bands.rs`).
    pub clouds: Option<(Vec<f64>, Vec<f64>)>,
}

/// The polarization images of a polarized run, `[wavelength][pixel]`.
#[derive(Clone, Debug)]
pub struct ImageStokes {
    pub q: Vec<Vec<f64>>,
    pub u: Vec<Vec<f64>>,
    pub dolp: Vec<Vec<f64>>,
    pub dolp_stderr: Vec<Vec<f64>>,
}

/// Collect the image measures' results.
pub fn image_products(exp: &Experiment, results: &[MeasureResult]) -> Vec<ImageProduct> {
    let mu_s = exp.mu_norm();
    let mut out: Vec<ImageProduct> = Vec::new();
    for r in results {
        let m = &exp.measures[r.measure];
        let (width, height, gt, view) = match &m.kind {
            MeasureKind::Ortho(g) => {
                let o = exp
                    .scene
                    .as_ref()
                    .and_then(|s| s.georef.as_ref())
                    .map_or((0.0, 0.0), |g| (g.origin.x, g.origin.y));
                let t = g.geotransform;
                (
                    g.width,
                    g.height,
                    Some([t[0] + o.0, t[1], t[2], t[3] + o.1, t[4], t[5]]),
                    Some((g.vza, g.vaa)),
                )
            }
            MeasureKind::Perspective(c) => (c.width, c.height, None, None),
            MeasureKind::Distant { .. }
            | MeasureKind::Radiancemeter { .. }
            | MeasureKind::DistantFlux { .. }
            | MeasureKind::Hdrf { .. } => continue,
        };
        let idx = match out.iter().position(|p| p.measure == r.measure) {
            Some(i) => i,
            None => {
                let nw = exp.wavelengths.len();
                let blank = vec![vec![f64::NAN; width * height]; nw];
                out.push(ImageProduct {
                    measure: r.measure,
                    id: m.id.clone(),
                    width,
                    height,
                    geotransform: gt,
                    wkt: exp
                        .scene
                        .as_ref()
                        .and_then(|s| s.georef.as_ref())
                        .map_or(String::new(), |g| g.wkt.clone()),
                    has_brf: exp.sun_up(),
                    brf: blank.clone(),
                    brf_stderr: blank.clone(),
                    brf_single: blank.clone(),
                    brf_multiple: blank.clone(),
                    radiance: blank.clone(),
                    radiance_stderr: blank.clone(),
                    n_samples: vec![0; nw],
                    pixel_samples: vec![vec![0; width * height]; nw],
                    view,
                    stokes: exp.polarized.then(|| ImageStokes {
                        q: blank.clone(),
                        u: blank.clone(),
                        dolp: blank.clone(),
                        dolp_stderr: blank.clone(),
                    }),
                    brightness_temperature: exp.emission.then(|| (blank.clone(), blank.clone())),
                    clouds: match &m.kind {
                        MeasureKind::Ortho(g) => super::cloud_bands::ortho_cloud_bands(exp, g),
                        _ => None,
                    },
                });
                out.len() - 1
            }
        };
        let p = &mut out[idx];
        let iw = r.wavelength;
        let to_rad = exp.optics[iw].irradiance * mu_s / std::f64::consts::PI;
        for c in 0..width * height {
            let (t, e) = r.acc.mean_stderr(c, 0);
            p.brf[iw][c] = t;
            p.brf_stderr[iw][c] = e;
            p.brf_single[iw][c] = r.acc.mean_stderr(c, 1).0;
            p.brf_multiple[iw][c] = r.acc.mean_stderr(c, 2).0;
            p.radiance[iw][c] = t * to_rad;
            p.radiance_stderr[iw][c] = e * to_rad;
            if let (Some(st), true) = (p.stokes.as_mut(), r.acc.is_polarized()) {
                st.q[iw][c] = r.acc.mean_stderr(c, engine::integrator::Q).0;
                st.u[iw][c] = r.acc.mean_stderr(c, engine::integrator::U).0;
                let (d, de) = super::dolp(&r.acc, c);
                st.dolp[iw][c] = d;
                st.dolp_stderr[iw][c] = de;
            }
        }
        if let Some((bt, bt_se)) = p.brightness_temperature.as_mut() {
            let wl = exp.wavelengths[iw];
            for c in 0..width * height {
                let (l, se) = (p.radiance[iw][c], p.radiance_stderr[iw][c]);
                let (t, st) = engine::sources::planck::brightness_temperature_stderr(wl, l, se);
                bt[iw][c] = t;
                bt_se[iw][c] = st;
            }
        }
        p.n_samples[iw] = r.acc.n.iter().copied().min().unwrap_or(0);
        p.pixel_samples[iw].copy_from_slice(&r.acc.n[..width * height]);
    }
    mask_to_area(exp, &mut out);
    out
}

/// Ortho pixels whose centre lies outside the bundle's area polygon (`[area] polygon` of the
/// region) are set to NaN in every image: the area of interest is the polygon, not its box.
fn mask_to_area(exp: &Experiment, images: &mut [ImageProduct]) {
    let Some(mask) = exp.scene.as_ref().and_then(|s| s.area_mask.as_ref()) else {
        return;
    };
    for p in images.iter_mut() {
        let MeasureKind::Ortho(g) = &exp.measures[p.measure].kind else {
            continue;
        };
        let t = g.geotransform; // local frame
        let outside: Vec<usize> = (0..p.width * p.height)
            .filter(|&c| {
                let (col, row) = ((c % p.width) as f64 + 0.5, (c / p.width) as f64 + 0.5);
                !mask.contains(t[0] + col * t[1], t[3] + row * t[5])
            })
            .collect();
        let mut images: Vec<&mut Vec<Vec<f64>>> = vec![
            &mut p.brf,
            &mut p.brf_stderr,
            &mut p.brf_single,
            &mut p.brf_multiple,
            &mut p.radiance,
            &mut p.radiance_stderr,
        ];
        if let Some(st) = p.stokes.as_mut() {
            images.extend([&mut st.q, &mut st.u, &mut st.dolp, &mut st.dolp_stderr]);
        }
        if let Some((bt, bt_se)) = p.brightness_temperature.as_mut() {
            images.extend([bt, bt_se]);
        }
        for img in images {
            for band in img.iter_mut() {
                for &c in &outside {
                    band[c] = f64::NAN;
                }
            }
        }
        if let Some((cot, frac)) = p.clouds.as_mut() {
            for &c in &outside {
                cot[c] = f64::NAN;
                frac[c] = f64::NAN;
            }
        }
    }
}

/// Write the GeoTIFFs (ortho) and the PNG quicklook of one image into `dir`; returns the paths
/// written and the quicklook's description.
pub fn write_files(
    dir: &Path,
    exp: &Experiment,
    p: &ImageProduct,
) -> Result<(Vec<PathBuf>, String), OutputError> {
    let mut written = Vec::new();
    if let Some(gt) = p.geotransform {
        let mut meta = vec![
            (
                "software".to_string(),
                format!("simulator {}", crate::BUILD_ID),
            ),
            (
                "sun_zenith_deg".to_string(),
                format!("{}", exp.sun_zenith_deg),
            ),
            (
                "sun_azimuth_deg".to_string(),
                format!("{}", exp.sun_azimuth_deg),
            ),
            (
                "samples_per_pixel".to_string(),
                format!("{:?}", p.n_samples),
            ),
        ];
        if let Some(m) = &exp.moon {
            meta.push(("moon_zenith_deg".into(), format!("{}", m.zenith_deg)));
            meta.push(("moon_azimuth_deg".into(), format!("{}", m.azimuth_deg)));
        }
        if let Some((vza, vaa)) = p.view {
            meta.push(("view_zenith_deg".into(), format!("{vza}")));
            meta.push(("view_azimuth_deg".into(), format!("{vaa}")));
        }
        let mut sets: Vec<(&str, &Vec<Vec<f64>>, &str, &str)> = vec![
            ("brf", &p.brf, "1", "bidirectional reflectance factor"),
            (
                "brf_stderr",
                &p.brf_stderr,
                "1",
                "standard error of the BRF",
            ),
            ("radiance", &p.radiance, "W m-2 sr-1 nm-1", "TOA radiance"),
            (
                "radiance_stderr",
                &p.radiance_stderr,
                "W m-2 sr-1 nm-1",
                "standard error of the radiance",
            ),
        ];

        if let Some((bt, bt_se)) = &p.brightness_temperature {
            sets.extend([
                ("brightness_temperature", bt, "K", "brightness temperature"),
                (
                    "brightness_temperature_stderr",
                    bt_se,
                    "K",
                    "standard error of the brightness temperature",
                ),
            ]);
        }
        if let Some(st) = &p.stokes {
            sets.extend([
                (
                    "q",
                    &st.q,
                    "1",
                    "Stokes Q (BRF-normalised, meridian frame of the view)",
                ),
                (
                    "u",
                    &st.u,
                    "1",
                    "Stokes U (BRF-normalised, meridian frame of the view)",
                ),
                ("dolp", &st.dolp, "1", "degree of linear polarization"),
                (
                    "dolp_stderr",
                    &st.dolp_stderr,
                    "1",
                    "standard error of the degree of linear polarization",
                ),
            ]);
        }
        if !p.has_brf {
            // No Sun (thermal emission only) or the Sun below the horizon: no BRF-normalised
            // files (the radiances, brightness temperatures and DoLP stay).
            sets.retain(|s| !(s.0.starts_with("brf") || s.0 == "q" || s.0 == "u"));
        }
        for (name, data, units, long) in sets {
            let bands: Vec<ImageBand> = exp
                .wavelengths
                .iter()
                .zip(data.iter())
                .enumerate()
                .map(|(i, (w, v))| ImageBand {
                    name: match &exp.bands {
                        Some(b) => format!("{name}_{}", b.names[i]),
                        None => format!("{name}_{w}nm"),
                    },
                    description: match &exp.bands {
                        Some(b) => format!(
                            "{long} in band {} (effective wavelength {w} nm)",
                            b.names[i]
                        ),
                        None => format!("{long} at {w} nm"),
                    },
                    values: v,
                    unit: units.to_string(),
                    wavelength_nm: Some(*w),
                    // Monochromatic wavelengths have no width.
                    fwhm_nm: None,
                })
                .collect();
            let mut md = meta.clone();
            if let Some(b) = &exp.bands {
                md.push(("bands".into(), b.names.join(",")));
            }
            md.push(("units".into(), units.into()));
            md.push(("quantity".into(), long.into()));
            md.push((
                "wavelengths_nm".into(),
                exp.wavelengths
                    .iter()
                    .map(|w| w.to_string())
                    .collect::<Vec<_>>()
                    .join(","),
            ));
            let path = dir.join(format!("{}_{name}.tif", p.id));
            write_geotiff(&path, p.width, p.height, gt, &p.wkt, &bands, &md)?;
            written.push(path);
        }
    }
    if let (Some(gt), Some((cot, frac))) = (p.geotransform, &p.clouds) {
        let band = |name: &str, description: &str, values| ImageBand {
            name: name.into(),
            description: description.into(),
            values,
            unit: "1".into(),
            wavelength_nm: None,
            fwhm_nm: None,
        };
        let bands = [
            band(
                "cloud_optical_thickness",
                "cloud optical thickness along the line of sight times cos VZA, pixel mean",
                cot,
            ),
            band(
                "cloud_fraction",
                "share of the pixel's lines of sight with cloud optical thickness >= 0.1",
                frac,
            ),
        ];
        let md = vec![
            (
                "software".to_string(),
                format!("simulator {}", crate::BUILD_ID),
            ),
            (
                "quantity".to_string(),
                "cloud optical thickness; cloud fraction".to_string(),
            ),
        ];
        let path = dir.join(format!("{}_clouds.tif", p.id));
        write_geotiff(&path, p.width, p.height, gt, &p.wkt, &bands, &md)?;
        written.push(path);
    }
    let path = dir.join(format!("{}.png", p.id));
    if let Some((bt, _)) = &p.brightness_temperature {
        // Thermal runs: the brightness temperature of the first wavelength.
        let what = format!("brightness temperature at {} nm", exp.wavelengths[0]);
        let d = super::image::write_stretched_png(&path, p.width, p.height, &bt[0], &what, "K")?;
        written.push(path);
        return Ok((written, d));
    }
    let (images, unit) = if p.has_brf {
        (&p.brf, "BRF")
    } else {
        (&p.radiance, "W m-2 sr-1 nm-1 radiance")
    };
    let channels: Vec<&[f64]> = images.iter().map(|v| v.as_slice()).collect();
    let what = write_quicklook_png(&path, p.width, p.height, &exp.wavelengths, &channels)?;
    written.push(path);
    Ok((written, format!("{what} {unit}")))
}

/// Per wavelength: median BRF (the median radiance where [`ImageProduct::has_brf`] is false),
/// median relative standard error and median single-scattering fraction over the pixels with
/// a finite, positive BRF (for summaries).
pub fn medians(p: &ImageProduct) -> Vec<(f64, f64, f64)> {
    let med = |mut v: Vec<f64>| -> f64 {
        if v.is_empty() {
            return f64::NAN;
        }
        v.sort_by(|a, b| a.total_cmp(b));
        v[v.len() / 2]
    };
    (0..p.brf.len())
        .map(|iw| {
            let ok: Vec<usize> = (0..p.brf[iw].len())
                .filter(|&c| p.brf[iw][c].is_finite() && p.brf[iw][c] > 0.0)
                .collect();
            let value = if p.has_brf { &p.brf } else { &p.radiance };
            (
                med(ok.iter().map(|&c| value[iw][c]).collect()),
                med(ok
                    .iter()
                    .map(|&c| p.brf_stderr[iw][c] / p.brf[iw][c])
                    .collect()),
                med(ok
                    .iter()
                    .map(|&c| p.brf_single[iw][c] / p.brf[iw][c])
                    .collect()),
            )
        })
        .collect()
}
