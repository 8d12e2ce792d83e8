//! Georeferenced image products: a multi-band GeoTIFF with the physical values, and an 8-bit PNG
//! quicklook for eyes.
//!
//! # GeoTIFF (`write_geotiff`)
//!
//! * One band per quantity (e.g. `brf_550nm`), sample type **Float32** (values given as `f64` are
//!   rounded to the nearest `f32`).
//! * Values are row-major with **row 0 the northern edge** (the first row of the file), column 0
//!   the western edge, as GDAL expects with a north-up geotransform.
//! * The geotransform is in GDAL order `[x0, dx, rx, y0, ry, dy]` and refers to **pixel corners**
//!   (`x0, y0` is the outer corner of the top-left pixel; `dy` is negative for north-up images),
//!   i.e. the GeoTIFF `PixelIsArea` convention.
//! * The CRS is the WKT given by the caller; an empty WKT writes no CRS.
//! * **NaN is nodata**: every band's nodata value is NaN (pixels the run did not estimate).
//! * The band *description* (what GIS tools show as the band name) is `ImageBand::name`; the longer
//!   `ImageBand::description` goes into the band metadata item `long_name`. Dataset metadata
//!   (units, wavelength, angles, software version…) is written as GDAL metadata items in the
//!   default domain (TIFF tag `GDAL_METADATA`): it needs no `.aux.xml` side-car.
//! * Band units (`ImageBand::unit`, e.g. `W m-2 sr-1 nm-1`, `1` for the BRF) are GDAL's band unit
//!   type (`GDALSetRasterUnitType`, what `gdalinfo` prints as `Unit Type`).
//! * Spectral band metadata as GDAL's raster data model specifies for imagery, in the band
//!   metadata domain `IMAGERY`: `CENTRAL_WAVELENGTH_UM` (µm) when `ImageBand::wavelength_nm` is
//!   given, `FWHM_UM` (µm) when `ImageBand::fwhm_nm` is given (monochromatic runs give none: a
//!   single wavelength has no width). GDAL before 3.10 keeps only the default domain of a band in
//!   the TIFF, so the `IMAGERY` domain goes into GDAL's PAM side-car `path.aux.xml` (written
//!   only when a band has a wavelength, atomically, after the GeoTIFF), and the same items are
//!   also in the band's default domain inside the TIFF, where any reader finds them without the
//!   side-car.
//! * **Cloud-Optimized GeoTIFF**: written by GDAL's COG driver (GDAL ≥ 3.1): 256×256 tiles,
//!   DEFLATE, `BIGTIFF=IF_SAFER`, the driver's default interleaving, and overviews (averages, NaN ignored) halving
//!   the size until it fits in one tile; `IMAGE_STRUCTURE` metadata `LAYOUT=COG`. The image is
//!   first assembled in a GDAL `MEM` dataset, then copied by the COG driver.
//!
//! # PNG quicklook (`write_quicklook_png`)
//!
//! * **True colour** when the run has wavelengths within ±55 nm of 660, 550 and 440 nm (Sentinel-2’s 665, 560 and 490 nm bands qualify) (the closest
//!   to each goes to R, G and B); otherwise **grey** from the wavelength closest to 550 nm (or the
//!   mean of all channels when the wavelengths are not known: `wavelengths_nm` empty or of another
//!   length than `channels`).
//! * Stretch: one common linear scale for the drawn channels, from 0 to the 99th percentile of
//!   their finite values (so relative colour is kept; values above it saturate, below 0 clip to 0),
//!   then sRGB gamma encoding to 8 bits.
//! * Pixels that are not finite in any drawn channel are **magenta** in colour images and **black**
//!   in grey ones.
//!
//! # Atomicity
//!
//! Both files are first built in memory (the GeoTIFF in GDAL's `/vsimem/`), then written with
//! [`super::write_atomic`]: a temporary file in the destination folder renamed over `path`. A full
//! disk or a read-only folder is reported as an [`OutputError`] naming `path` and never leaves a
//! partial file at `path`. Building in memory also makes write errors visible with GDAL < 3.7,
//! whose `GDALClose` does not report them.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use gdal::raster::{Buffer, RasterCreationOptions};
use gdal::{DriverManager, Metadata};

use super::write_atomic;
use crate::error::OutputError;

/// One band of an image: name (e.g. "brf_550nm"), description, row-major values (row 0 = north),
/// f64, and optionally its unit and spectral position.
#[derive(Clone, Debug, Default)]
pub struct ImageBand<'a> {
    pub name: String,
    pub description: String,
    pub values: &'a [f64],
    /// Unit of the values (GDAL band unit type); empty: none.
    pub unit: String,
    /// Central wavelength (nm), written as `CENTRAL_WAVELENGTH_UM` in the `IMAGERY` domain.
    pub wavelength_nm: Option<f64>,
    /// Full width at half maximum (nm), written as `FWHM_UM` in the `IMAGERY` domain.
    pub fwhm_nm: Option<f64>,
}

/// COG tile size (pixels on a side); overviews are built down to one tile.
const TILE: usize = 256;

fn invalid(path: &Path, message: String) -> OutputError {
    OutputError::Io {
        path: path.to_path_buf(),
        source: std::io::Error::new(std::io::ErrorKind::InvalidInput, message),
    }
}

/// Removes an in-memory GDAL file (and a possible PAM side-car) when dropped.
struct MemFile(PathBuf);

impl Drop for MemFile {
    fn drop(&mut self) {
        let _ = gdal::vsi::unlink_mem_file(&self.0);
        let mut aux = self.0.clone().into_os_string();
        aux.push(".aux.xml");
        let _ = gdal::vsi::unlink_mem_file(PathBuf::from(aux));
    }
}

/// Write a multi-band Float32 GeoTIFF atomically (temp file in the same folder, then rename):
/// `geotransform` in GDAL order (pixel corners), `wkt` the CRS (may be empty: then no CRS is set),
/// NaN as nodata, band descriptions, units and wavelengths set, metadata key/values on the dataset
/// (e.g. units, wavelength, view angles, software version). A Cloud-Optimized GeoTIFF: DEFLATE,
/// 256×256 tiles, overviews. See the module documentation for the conventions.
pub fn write_geotiff(
    path: &Path,
    width: usize,
    height: usize,
    geotransform: [f64; 6],
    wkt: &str,
    bands: &[ImageBand],
    metadata: &[(String, String)],
) -> Result<(), OutputError> {
    if width == 0 || height == 0 {
        return Err(invalid(path, format!("empty image ({width}×{height})")));
    }
    if bands.is_empty() {
        return Err(invalid(path, "no band to write".into()));
    }
    let n = width
        .checked_mul(height)
        .ok_or_else(|| invalid(path, format!("image too large ({width}×{height})")))?;
    for b in bands {
        if b.values.len() != n {
            return Err(invalid(
                path,
                format!(
                    "band {} has {} values, expected {width}×{height} = {n}",
                    b.name,
                    b.values.len()
                ),
            ));
        }
    }
    let gdal_err = |what: &str| {
        let what = what.to_string();
        move |source| OutputError::Gdal {
            path: path.to_path_buf(),
            what,
            source,
        }
    };

    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let mem = MemFile(PathBuf::from(format!(
        "/vsimem/simulator_image_{}_{}.tif",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    )));

    // The image in memory, with all its metadata; the COG driver then lays it out.
    let mem_driver = DriverManager::get_driver_by_name("MEM").map_err(gdal_err("MEM driver"))?;
    let mut ds = mem_driver
        .create_with_band_type::<f32, _>("", width, height, bands.len())
        .map_err(gdal_err("create"))?;
    ds.set_geo_transform(&geotransform)
        .map_err(gdal_err("set geotransform"))?;
    if !wkt.trim().is_empty() {
        ds.set_projection(wkt).map_err(gdal_err("set CRS"))?;
    }
    for (k, v) in metadata {
        ds.set_metadata_item(k, v, "")
            .map_err(gdal_err(&format!("metadata item {k}")))?;
    }
    for (i, b) in bands.iter().enumerate() {
        let mut band = ds.rasterband(i + 1).map_err(gdal_err("band"))?;
        band.set_no_data_value(Some(f64::NAN))
            .map_err(gdal_err("set nodata"))?;
        band.set_description(&b.name)
            .map_err(gdal_err("band description"))?;
        if !b.description.is_empty() {
            band.set_metadata_item("long_name", &b.description, "")
                .map_err(gdal_err("band long_name"))?;
        }
        if !b.unit.is_empty() {
            set_unit(&band, &b.unit).map_err(gdal_err(&format!("unit of band {}", b.name)))?;
        }
        for (key, um) in spectral_items(b) {
            for domain in ["IMAGERY", ""] {
                band.set_metadata_item(key, &um, domain)
                    .map_err(gdal_err(&format!("{key} of band {}", b.name)))?;
            }
        }
        let data: Vec<f32> = b.values.iter().map(|&v| v as f32).collect();
        let mut buf = Buffer::new((width, height), data);
        band.write((0, 0), (width, height), &mut buf)
            .map_err(gdal_err(&format!("write band {}", b.name)))?;
    }
    let cog = DriverManager::get_driver_by_name("COG").map_err(gdal_err("COG driver"))?;
    let mut opts = RasterCreationOptions::new();
    for (k, v) in [
        ("COMPRESS", "DEFLATE"),
        ("BIGTIFF", "IF_SAFER"),
        ("BLOCKSIZE", &TILE.to_string()),
        ("OVERVIEWS", "AUTO"),
        ("RESAMPLING", "AVERAGE"),
    ] {
        opts.add_name_value(k, v)
            .map_err(gdal_err("creation options"))?;
    }
    let out = ds
        .create_copy(&cog, &mem.0, &opts)
        .map_err(gdal_err("COG copy"))?;
    out.close().map_err(gdal_err("close"))?;
    ds.close().map_err(gdal_err("close in-memory image"))?;
    gdal::vsi::call_on_mem_file_bytes(&mem.0, |bytes| write_atomic(path, bytes))
        .map_err(gdal_err("read in-memory GeoTIFF"))??;
    match imagery_sidecar(bands) {
        Some(xml) => write_atomic(&sidecar_path(path), xml.as_bytes()),
        None => Ok(()),
    }
}

/// The band's `IMAGERY` items: `CENTRAL_WAVELENGTH_UM`, `FWHM_UM` (µm), those that are known.
fn spectral_items(b: &ImageBand) -> Vec<(&'static str, String)> {
    [
        ("CENTRAL_WAVELENGTH_UM", b.wavelength_nm),
        ("FWHM_UM", b.fwhm_nm),
    ]
    .into_iter()
    .filter_map(|(k, nm)| nm.map(|nm| (k, format!("{}", nm / 1000.0))))
    .collect()
}

/// `path.aux.xml`: GDAL's PAM side-car of `path`.
pub fn sidecar_path(path: &Path) -> PathBuf {
    let mut p = path.as_os_str().to_owned();
    p.push(".aux.xml");
    PathBuf::from(p)
}

/// The PAM side-car holding the bands' `IMAGERY` metadata domain (`None` when no band has a
/// wavelength). GDAL < 3.10 does not store a band's `IMAGERY` domain in the TIFF itself (its COG
/// and GTiff copies keep only the default domain), but every GDAL reads it from the side-car.
fn imagery_sidecar(bands: &[ImageBand]) -> Option<String> {
    let mut xml = String::from("<PAMDataset>\n");
    let mut any = false;
    for (i, b) in bands.iter().enumerate() {
        let items = spectral_items(b);
        if items.is_empty() {
            continue;
        }
        any = true;
        xml.push_str(&format!(
            "  <PAMRasterBand band=\"{}\">\n    <Metadata domain=\"IMAGERY\">\n",
            i + 1
        ));
        for (k, v) in items {
            xml.push_str(&format!("      <MDI key=\"{k}\">{v}</MDI>\n"));
        }
        xml.push_str("    </Metadata>\n  </PAMRasterBand>\n");
    }
    xml.push_str("</PAMDataset>\n");
    any.then_some(xml)
}

/// GDAL's band unit type (the gdal crate has no setter for it).
fn set_unit(band: &gdal::raster::RasterBand, unit: &str) -> gdal::errors::Result<()> {
    let c = std::ffi::CString::new(unit)?;
    // SAFETY: a valid band handle borrowed from an open dataset and a NUL-terminated string that
    // GDAL copies.
    let rv = unsafe { gdal_sys::GDALSetRasterUnitType(band.c_rasterband(), c.as_ptr()) };
    if rv == gdal_sys::CPLErr::CE_None {
        Ok(())
    } else {
        Err(gdal::errors::GdalError::CplError {
            class: rv,
            number: 0,
            msg: format!("GDALSetRasterUnitType({unit}) failed"),
        })
    }
}

/// Reference wavelengths (nm) of the true-colour channels R, G, B and the tolerance.
const RGB_NM: [f64; 3] = [660.0, 550.0, 440.0];
const RGB_TOLERANCE_NM: f64 = 55.0;

/// Index of the wavelength closest to `target`.
fn closest(wavelengths_nm: &[f64], target: f64) -> Option<usize> {
    wavelengths_nm
        .iter()
        .enumerate()
        .filter(|(_, w)| w.is_finite())
        .min_by(|a, b| (a.1 - target).abs().total_cmp(&(b.1 - target).abs()))
        .map(|(i, _)| i)
}

/// Linear [0, 1] → sRGB-encoded 8-bit value.
fn srgb8(linear: f64) -> u8 {
    let v = linear.clamp(0.0, 1.0);
    let e = if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    };
    (e * 255.0).round().clamp(0.0, 255.0) as u8
}

/// 99th percentile (nearest rank) of the finite values; `None` when there are none.
fn percentile_99(values: impl Iterator<Item = f64>) -> Option<f64> {
    let mut v: Vec<f64> = values.filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    let k = ((v.len() - 1) as f64 * 0.99).round() as usize;
    let (_, p, _) = v.select_nth_unstable_by(k, f64::total_cmp);
    Some(*p)
}

/// `x` with 3 significant digits, without trailing zeros.
fn fmt_sig(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let mag = x.abs().log10().floor() as i32;
    if !(-4..6).contains(&mag) {
        return format!("{x:.2e}");
    }
    let decimals = (2 - mag).max(0) as usize;
    let s = format!("{x:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

fn fmt_nm(w: f64) -> String {
    fmt_sig(w)
}

/// PNG quicklook (8-bit, written atomically). `channels` holds one image per wavelength (same
/// size, row-major, row 0 north); `wavelengths_nm` their wavelengths. True colour when the run
/// has wavelengths within ±55 nm of 660, 550 and 440 nm (Sentinel-2’s 665, 560 and 490 nm bands qualify) (closest for R, G, B), otherwise grey from
/// the channel closest to 550 nm (the mean of all channels when the wavelengths are not given).
/// Common linear stretch from 0 to the 99th percentile of the finite drawn values, then sRGB
/// gamma; non-finite pixels magenta (colour) or black (grey). Returns a short description of what
/// was drawn, e.g. "true colour R=660 G=550 B=440 nm, 0..0.31".
pub fn write_quicklook_png(
    path: &Path,
    width: usize,
    height: usize,
    wavelengths_nm: &[f64],
    channels: &[&[f64]],
) -> Result<String, OutputError> {
    if width == 0 || height == 0 {
        return Err(invalid(path, format!("empty image ({width}×{height})")));
    }
    if channels.is_empty() {
        return Err(invalid(path, "no channel to draw".into()));
    }
    let (w32, h32) = match (u32::try_from(width), u32::try_from(height)) {
        (Ok(w), Ok(h)) => (w, h),
        _ => return Err(invalid(path, format!("image too large ({width}×{height})"))),
    };
    let n = width * height;
    for (i, c) in channels.iter().enumerate() {
        if c.len() != n {
            return Err(invalid(
                path,
                format!(
                    "channel {i} has {} values, expected {width}×{height} = {n}",
                    c.len()
                ),
            ));
        }
    }
    let known = wavelengths_nm.len() == channels.len();

    // True-colour channel choice.
    let rgb: Option<[usize; 3]> = if known {
        let pick = |t: f64| {
            closest(wavelengths_nm, t)
                .filter(|&i| (wavelengths_nm[i] - t).abs() <= RGB_TOLERANCE_NM)
        };
        match (pick(RGB_NM[0]), pick(RGB_NM[1]), pick(RGB_NM[2])) {
            (Some(r), Some(g), Some(b)) => Some([r, g, b]),
            _ => None,
        }
    } else {
        None
    };

    let (bytes, color, description) = if let Some([r, g, b]) = rgb {
        let (cr, cg, cb) = (channels[r], channels[g], channels[b]);
        let top = percentile_99(cr.iter().chain(cg).chain(cb).copied());
        let scale = stretch_top(top);
        let mut px = Vec::with_capacity(3 * n);
        for i in 0..n {
            let (vr, vg, vb) = (cr[i], cg[i], cb[i]);
            if vr.is_finite() && vg.is_finite() && vb.is_finite() {
                px.extend([srgb8(vr / scale), srgb8(vg / scale), srgb8(vb / scale)]);
            } else {
                px.extend([255, 0, 255]);
            }
        }
        let d = format!(
            "true colour R={} G={} B={} nm, 0..{}",
            fmt_nm(wavelengths_nm[r]),
            fmt_nm(wavelengths_nm[g]),
            fmt_nm(wavelengths_nm[b]),
            fmt_sig(scale)
        );
        (px, ::image::ExtendedColorType::Rgb8, d)
    } else {
        let (grey, what): (Vec<f64>, String) = match closest(wavelengths_nm, RGB_NM[1]) {
            Some(i) if known => (
                channels[i].to_vec(),
                format!("grey from {} nm", fmt_nm(wavelengths_nm[i])),
            ),
            _ => (
                (0..n)
                    .map(|p| channels.iter().map(|c| c[p]).sum::<f64>() / channels.len() as f64)
                    .collect(),
                format!("grey, mean of {} channels", channels.len()),
            ),
        };
        let scale = stretch_top(percentile_99(grey.iter().copied()));
        let px: Vec<u8> = grey
            .iter()
            .map(|&v| if v.is_finite() { srgb8(v / scale) } else { 0 })
            .collect();
        let d = format!("{what}, 0..{}", fmt_sig(scale));
        (px, ::image::ExtendedColorType::L8, d)
    };

    write_png(path, w32, h32, color, &bytes)?;
    Ok(description)
}

/// A grey quicklook of a quantity with an offset (brightness temperature): linear from its
/// 1st to its 99th percentile over the finite pixels (black to white), NaN black; returns the
/// description (the stretch, in `unit`).
pub fn write_stretched_png(
    path: &Path,
    width: usize,
    height: usize,
    values: &[f64],
    what: &str,
    unit: &str,
) -> Result<String, OutputError> {
    let (w32, h32) = match (u32::try_from(width), u32::try_from(height)) {
        (Ok(w), Ok(h)) if w > 0 && h > 0 && values.len() == width * height => (w, h),
        _ => {
            return Err(invalid(
                path,
                format!("{} values for a {width}×{height} image", values.len()),
            ))
        }
    };
    let mut finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    finite.sort_by(|a, b| a.total_cmp(b));
    let pick = |q: f64| {
        finite
            .get(((finite.len() as f64 - 1.0) * q).round() as usize)
            .copied()
            .unwrap_or(0.0)
    };
    let (lo, hi) = (pick(0.01), pick(0.99));
    let span = if hi > lo { hi - lo } else { 1.0 };
    let px: Vec<u8> = values
        .iter()
        .map(|&v| {
            if v.is_finite() {
                (((v - lo) / span).clamp(0.0, 1.0) * 255.0).round() as u8
            } else {
                0
            }
        })
        .collect();
    write_png(path, w32, h32, ::image::ExtendedColorType::L8, &px)?;
    Ok(format!(
        "{what}, grey {} .. {} {unit}",
        fmt_sig(lo),
        fmt_sig(hi)
    ))
}

/// Encode `bytes` (`width × height` pixels of `color`) as a PNG in memory and write it to
/// `path` atomically.
pub fn write_png(
    path: &Path,
    width: u32,
    height: u32,
    color: ::image::ExtendedColorType,
    bytes: &[u8],
) -> Result<(), OutputError> {
    let mut png = Vec::new();
    ::image::ImageEncoder::write_image(
        ::image::codecs::png::PngEncoder::new(&mut png),
        bytes,
        width,
        height,
        color,
    )
    .map_err(|source| OutputError::Image {
        path: path.to_path_buf(),
        source,
    })?;
    write_atomic(path, &png)
}

/// The value drawn as full white: the 99th percentile when positive, else 1.
fn stretch_top(p99: Option<f64>) -> f64 {
    match p99 {
        Some(p) if p > 0.0 => p,
        _ => 1.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gdal::spatial_ref::SpatialRef;
    use gdal::Dataset;

    /// A fresh, empty folder under the system temporary folder.
    fn temp_dir(test: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!(
            "simulator_products_image_{test}_{}",
            std::process::id()
        ));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn geotiff_round_trip() -> Result<(), Box<dyn std::error::Error>> {
        let dir = temp_dir("round_trip");
        let path = dir.join("toa.tif");
        let (w, h) = (7usize, 5usize);
        let wkt = SpatialRef::from_epsg(32631)?.to_wkt()?;
        let gt = [500_000.0, 30.0, 0.0, 4_600_150.0, 0.0, -30.0];
        let data: Vec<Vec<f64>> = (0..3)
            .map(|b| {
                (0..w * h)
                    .map(|i| 0.01 * i as f64 + b as f64 + 1.0 / 3.0)
                    .collect()
            })
            .collect();
        let mut b1 = data[1].clone();
        b1[w + 2] = f64::NAN; // row 1, column 2
        let bands = vec![
            ImageBand {
                name: "brf_440nm".into(),
                description: "BRF at 440 nm".into(),
                values: &data[0],
                ..Default::default()
            },
            ImageBand {
                name: "brf_550nm".into(),
                description: "BRF at 550 nm".into(),
                values: &b1,
                unit: "W m-2 sr-1 nm-1".into(),
                wavelength_nm: Some(550.0),
                fwhm_nm: Some(20.0),
            },
            ImageBand {
                name: "brf_660nm".into(),
                description: "BRF at 660 nm".into(),
                values: &data[2],
                ..Default::default()
            },
        ];
        let metadata = vec![
            ("units".to_string(), "1".to_string()),
            ("vza_deg".to_string(), "0".to_string()),
            ("software".to_string(), "simulator test".to_string()),
        ];
        write_geotiff(&path, w, h, gt, &wkt, &bands, &metadata)?;
        // Only the product and its side-car (the band with a wavelength) in the folder: no
        // temporary file.
        let names: Vec<_> = std::fs::read_dir(&dir)?
            .map(|e| e.map(|e| e.file_name()))
            .collect::<Result<_, _>>()?;
        let mut names: Vec<String> = names.iter().map(|n| n.to_string_lossy().into()).collect();
        names.sort();
        assert_eq!(names, ["toa.tif", "toa.tif.aux.xml"]);

        let ds = Dataset::open(&path)?;
        assert_eq!(ds.raster_size(), (w, h));
        assert_eq!(ds.raster_count(), 3);
        assert_eq!(ds.geo_transform()?, gt);
        assert_eq!(ds.spatial_ref()?.auth_code()?, 32631);
        assert_eq!(ds.metadata_item("units", "").as_deref(), Some("1"));
        assert_eq!(
            ds.metadata_item("software", "").as_deref(),
            Some("simulator test")
        );
        for (k, b) in bands.iter().enumerate() {
            let band = ds.rasterband(k + 1)?;
            assert_eq!(band.band_type(), gdal::raster::GdalDataType::Float32);
            assert_eq!(band.description()?, b.name);
            assert_eq!(
                band.metadata_item("long_name", "").as_deref(),
                Some(b.description.as_str())
            );
            assert!(band.no_data_value().is_some_and(f64::is_nan));
            let got = band.read_band_as::<f32>()?;
            assert_eq!(got.shape(), (w, h));
            for (i, (&g, &v)) in got.data().iter().zip(b.values).enumerate() {
                if v.is_nan() {
                    assert!(g.is_nan(), "band {k} pixel {i}");
                } else {
                    assert_eq!(g, v as f32, "band {k} pixel {i}");
                }
            }
        }
        assert!(ds.rasterband(2)?.read_band_as::<f32>()?.data()[w + 2].is_nan());
        // Band unit and GDAL's imagery band metadata (µm); none where not given.
        let b2 = ds.rasterband(2)?;
        assert_eq!(b2.unit(), "W m-2 sr-1 nm-1");
        assert_eq!(
            b2.metadata_item("CENTRAL_WAVELENGTH_UM", "").as_deref(),
            Some("0.55")
        );
        assert_eq!(
            b2.metadata_item("CENTRAL_WAVELENGTH_UM", "IMAGERY")
                .as_deref(),
            Some("0.55")
        );
        assert_eq!(
            b2.metadata_item("FWHM_UM", "IMAGERY").as_deref(),
            Some("0.02")
        );
        let b1 = ds.rasterband(1)?;
        assert_eq!(b1.unit(), "");
        assert_eq!(b1.metadata_item("CENTRAL_WAVELENGTH_UM", "IMAGERY"), None);
        assert_eq!(
            ds.metadata_item("LAYOUT", "IMAGE_STRUCTURE").as_deref(),
            Some("COG")
        );
        drop(ds);
        std::fs::remove_dir_all(&dir)?;
        Ok(())
    }

    #[test]
    fn geotiff_large_is_tiled_and_empty_wkt_has_no_crs() -> Result<(), Box<dyn std::error::Error>> {
        let dir = temp_dir("tiled");
        let path = dir.join("big.tif");
        let (w, h) = (300usize, 20usize);
        let v: Vec<f64> = (0..w * h).map(|i| i as f64).collect();
        let bands = [ImageBand {
            name: "x".into(),
            description: String::new(),
            values: &v,
            ..Default::default()
        }];
        write_geotiff(
            &path,
            w,
            h,
            [0.0, 1.0, 0.0, 0.0, 0.0, -1.0],
            "",
            &bands,
            &[],
        )?;
        let ds = Dataset::open(&path)?;
        assert!(ds.spatial_ref().is_err() || ds.projection().is_empty());
        assert_eq!(ds.rasterband(1)?.block_size(), (256, 256));
        assert_eq!(
            ds.metadata_item("COMPRESSION", "IMAGE_STRUCTURE")
                .as_deref(),
            Some("DEFLATE")
        );
        assert_eq!(
            ds.rasterband(1)?.read_band_as::<f32>()?.data()[w * h - 1],
            5999.0
        );
        drop(ds);
        std::fs::remove_dir_all(&dir)?;
        Ok(())
    }

    /// A 600×600 image is a COG with 256×256 tiles and two overviews (300² and 150², the first
    /// size within one tile), which average the pixels and skip the NaN nodata.
    #[test]
    fn geotiff_is_cloud_optimized_with_overviews() -> Result<(), Box<dyn std::error::Error>> {
        let dir = temp_dir("cog");
        let path = dir.join("cog.tif");
        let n = 600usize;
        let mut v: Vec<f64> = (0..n * n).map(|i| ((i % n) / 2) as f64).collect();
        v[1] = f64::NAN; // row 0, column 1: the first overview pixel averages columns 0 only
        let bands = [ImageBand {
            name: "brf_865nm".into(),
            description: "BRF at 865 nm".into(),
            values: &v,
            unit: "1".into(),
            wavelength_nm: Some(865.0),
            fwhm_nm: None,
        }];
        let gt = [0.0, 10.0, 0.0, 6000.0, 0.0, -10.0];
        let wkt = SpatialRef::from_epsg(32631)?.to_wkt()?;
        write_geotiff(&path, n, n, gt, &wkt, &bands, &[])?;
        let ds = Dataset::open(&path)?;
        assert_eq!(
            ds.metadata_item("LAYOUT", "IMAGE_STRUCTURE").as_deref(),
            Some("COG")
        );
        assert_eq!(ds.geo_transform()?, gt);
        let band = ds.rasterband(1)?;
        assert_eq!(band.block_size(), (256, 256));
        assert_eq!(band.overview_count()?, 2);
        let ov = band.overview(0)?;
        assert_eq!(ov.size(), (300, 300));
        assert_eq!(band.overview(1)?.size(), (150, 150));
        let o = ov.read_band_as::<f32>()?;
        // Column pair (2c, 2c+1) holds c in both: the average is c, NaN skipped.
        assert_eq!(o.data()[0], 0.0);
        assert_eq!(o.data()[7], 7.0);
        assert_eq!(band.unit(), "1");
        assert_eq!(
            band.metadata_item("CENTRAL_WAVELENGTH_UM", "IMAGERY")
                .as_deref(),
            Some("0.865")
        );
        assert_eq!(band.metadata_item("FWHM_UM", "IMAGERY"), None);
        drop(ds);
        std::fs::remove_dir_all(&dir)?;
        Ok(())
    }

    #[test]
    fn geotiff_into_missing_folder_fails_naming_the_path() {
        let dir = temp_dir("missing").join("does_not_exist");
        let path = dir.join("toa.tif");
        let v = vec![0.5; 4];
        let bands = [ImageBand {
            name: "brf".into(),
            description: "BRF".into(),
            values: &v,
            ..Default::default()
        }];
        let err = write_geotiff(
            &path,
            2,
            2,
            [0.0, 1.0, 0.0, 2.0, 0.0, -1.0],
            "",
            &bands,
            &[],
        )
        .unwrap_err();
        let msg = err.to_string();
        assert!(msg.contains(&path.display().to_string()), "{msg}");
        assert!(!path.exists());
        assert!(!dir.exists());
        // Wrong band size: an error naming the file, nothing written.
        let err = write_geotiff(
            &path,
            3,
            2,
            [0.0, 1.0, 0.0, 2.0, 0.0, -1.0],
            "",
            &bands,
            &[],
        )
        .unwrap_err();
        assert!(err.to_string().contains(&path.display().to_string()));
        let _ = std::fs::remove_dir_all(dir.parent().unwrap());
    }

    #[test]
    fn quicklook_true_colour_and_grey() -> Result<(), Box<dyn std::error::Error>> {
        let dir = temp_dir("quicklook");
        let (w, h) = (4usize, 3usize);
        let n = w * h;
        // Grey background 0.1 everywhere; pixel 5 bright only at 660 nm; pixel 7 NaN at 550 nm.
        let mut c440 = vec![0.1; n];
        let mut c550 = vec![0.1; n];
        let mut c660 = vec![0.1; n];
        c660[5] = 0.3;
        c550[7] = f64::NAN;
        c440[0] = 0.05;
        let path = dir.join("ql.png");
        let d = write_quicklook_png(&path, w, h, &[440.0, 550.0, 660.0], &[&c440, &c550, &c660])?;
        assert!(d.starts_with("true colour"), "{d}");
        assert!(d.contains("R=660 G=550 B=440 nm"), "{d}");
        let img = ::image::open(&path)?.to_rgb8();
        assert_eq!(img.dimensions(), (w as u32, h as u32));
        let p = img.get_pixel(5 % w as u32, 5 / w as u32).0;
        assert!(p[0] > p[1] + 50 && p[0] > p[2] + 50, "{p:?}");
        assert_eq!(img.get_pixel(7 % w as u32, 7 / w as u32).0, [255, 0, 255]);
        let bg = img.get_pixel(1, 0).0;
        assert!(bg[0] == bg[1] && bg[1] == bg[2] && bg[0] > 0, "{bg:?}");

        // A single near-infrared channel: grey; NaN black.
        let mut nir = vec![0.4; n];
        nir[2] = 0.2;
        nir[3] = f64::NAN;
        let path = dir.join("nir.png");
        let d = write_quicklook_png(&path, w, h, &[865.0], &[&nir])?;
        assert!(d.starts_with("grey from 865 nm"), "{d}");
        let img = ::image::open(&path)?.to_rgb8();
        assert_eq!(img.dimensions(), (w as u32, h as u32));
        for px in img.pixels() {
            assert!(px.0[0] == px.0[1] && px.0[1] == px.0[2]);
        }
        assert_eq!(img.get_pixel(3, 0).0, [0, 0, 0]);
        assert_eq!(img.get_pixel(0, 0).0, [255, 255, 255]);
        assert!(img.get_pixel(2, 0).0[0] < 255 && img.get_pixel(2, 0).0[0] > 0);
        // Wavelengths out of the ±55 nm windows: grey from the one closest to 550 nm.
        let d = write_quicklook_png(&path, w, h, &[490.0, 560.0, 865.0], &[&c550, &c550, &nir])?;
        assert!(d.starts_with("grey from 560 nm"), "{d}");

        // Into a missing folder: an error naming the file.
        let bad = dir.join("nope").join("ql.png");
        let err = write_quicklook_png(&bad, w, h, &[865.0], &[&nir]).unwrap_err();
        assert!(err.to_string().contains(&bad.display().to_string()));
        assert!(!bad.exists());
        std::fs::remove_dir_all(&dir)?;
        Ok(())
    }

    #[test]
    fn helpers() {
        assert_eq!(srgb8(0.0), 0);
        assert_eq!(srgb8(1.0), 255);
        assert_eq!(srgb8(2.0), 255);
        assert_eq!(srgb8(0.18), 118);
        assert_eq!(fmt_sig(0.3123), "0.312");
        assert_eq!(fmt_sig(660.0), "660");
        assert_eq!(fmt_sig(0.5), "0.5");
        let v: Vec<f64> = (0..=100).map(f64::from).chain([f64::NAN]).collect();
        assert_eq!(percentile_99(v.into_iter()), Some(99.0));
        assert_eq!(percentile_99([f64::NAN].into_iter()), None);
    }
}
