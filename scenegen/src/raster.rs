//! GDAL side of scenegen: the working frame, the working grids, and reading rasters into them
//! with GDAL's warper (`GDALReprojectImage`), with coverage checks and no-data handling.
//!
//! * Working CRS: by default a transverse Mercator centred on the area of interest
//!   (`+proj=tmerc +lat_0=φc +lon_0=λc +k=1 +x_0=0 +y_0=0 +datum=WGS84 +units=m`), so x = east and
//!   y = north in metres from the centre, with a scale error below 1.3·10⁻⁴ within 100 km of it.
//!   A region may name another projected metric CRS (`crs = "EPSG:32631"`).
//! * DEM grid: nodes (pixel centres) at integer multiples of the spacing `dx`, which is rounded
//!   to a multiple of 1/64 m. With `dx = m/64`, every node's coordinate relative to any other
//!   node is an integer times `m/64`, exact in f32 below 2²⁴/m nodes: terrain tiles stored in
//!   their own f32 frames then share bit-identical seam vertices in world coordinates.
//! * DEM heights: bilinear resampling; band scale/offset applied; unit from the band's unit
//!   type (metres, or feet converted); no-data holes up to `dem.max_fill_pixels` pixels
//!   (4-connected) are filled from their rim inwards with the mean of valid 8-neighbours; larger
//!   ones are refused with their size and location.
//! * Land cover: `mode` (most frequent class) when a material cell covers more than 1.5 source
//!   pixels across, else `nearest` (region key `landcover.resampling` forces one).
//!
//! GDAL `Dataset`s stay on the calling thread; the functions return owned arrays.

use std::path::{Path, PathBuf};

use gdal::raster::GdalType;
use gdal::spatial_ref::{AxisMappingStrategy, CoordTransform, SpatialRef};
use gdal::{Dataset, DriverManager};
use gdal_sys::GDALResampleAlg;

use crate::error::{gdal_err, input, ScenegenError};
use crate::region::{Area, Region};

/// The working CRS and the local frame's description.
pub struct WorkingFrame {
    pub srs: SpatialRef,
    pub wkt: String,
    pub epsg: Option<u32>,
    pub proj: Option<String>,
    pub centre_lon_lat: [f64; 2],
    /// Area of interest in the working CRS: xmin, ymin, xmax, ymax (metres).
    pub extent: [f64; 4],
    /// WGS 84 bounding box of the area: west, south, east, north (degrees).
    pub lon_lat_bbox: [f64; 4],
    /// The area's polygon in the working CRS when the region gives one (`extent` is its
    /// bounding box).
    pub mask: Option<crate::area_polygon::Mask>,
}

fn wgs84() -> Result<SpatialRef, ScenegenError> {
    let mut s = SpatialRef::from_epsg(4326).map_err(gdal_err("EPSG:4326"))?;
    s.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
    Ok(s)
}

/// Points along the boundary of a rectangle (for transforming extents).
fn ring(b: [f64; 4], n: usize) -> (Vec<f64>, Vec<f64>) {
    let (mut xs, mut ys) = (Vec::new(), Vec::new());
    for k in 0..=n {
        let t = k as f64 / n as f64;
        for (x, y) in [
            (b[0] + t * (b[2] - b[0]), b[1]),
            (b[0] + t * (b[2] - b[0]), b[3]),
            (b[0], b[1] + t * (b[3] - b[1])),
            (b[2], b[1] + t * (b[3] - b[1])),
        ] {
            xs.push(x);
            ys.push(y);
        }
    }
    (xs, ys)
}

fn bounds(xs: &[f64], ys: &[f64]) -> [f64; 4] {
    let f = |v: &[f64], max: bool| {
        v.iter().copied().fold(
            if max { f64::MIN } else { f64::MAX },
            if max { f64::max } else { f64::min },
        )
    };
    [f(xs, false), f(ys, false), f(xs, true), f(ys, true)]
}

impl WorkingFrame {
    pub fn new(region: &Region) -> Result<WorkingFrame, ScenegenError> {
        let [lon, lat] = region.area.centre();
        let (mut srs, proj) = if region.crs == "local" {
            let p = format!("+proj=tmerc +lat_0={lat} +lon_0={lon} +k=1 +x_0=0 +y_0=0 +datum=WGS84 +units=m +no_defs");
            (
                SpatialRef::from_proj4(&p).map_err(gdal_err("local transverse Mercator"))?,
                Some(p),
            )
        } else {
            let s =
                SpatialRef::from_definition(&region.crs).map_err(|e| ScenegenError::Region {
                    path: region.path.clone(),
                    key: "crs".into(),
                    message: format!("GDAL cannot read CRS `{}`: {e}", region.crs),
                })?;
            (s, None)
        };
        if !srs.is_projected() || (srs.linear_units() - 1.0).abs() > 1e-12 {
            return Err(ScenegenError::Region {
                path: region.path.clone(),
                key: "crs".into(),
                message: format!("`{}` is not a projected CRS in metres", region.crs),
            });
        }
        srs.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
        let geo = wgs84()?;
        let to_work = CoordTransform::new(&geo, &srs).map_err(gdal_err("WGS 84 → working CRS"))?;
        let mut mask = None;
        let (extent, lon_lat_bbox) = match &region.area {
            Area::Polygon { path, lon_lat } => {
                let work = crate::area_polygon::reproject(path, lon_lat, &geo, &srs)?;
                let m = crate::area_polygon::Mask::new(work);
                let e = m.bbox;
                mask = Some(m);
                (e, crate::area_polygon::bbox(lon_lat))
            }
            Area::BBox(b) => {
                let (mut xs, mut ys) = ring(*b, 32);
                to_work
                    .transform_coords(&mut xs, &mut ys, &mut [])
                    .map_err(gdal_err("area bbox → working CRS"))?;
                (bounds(&xs, &ys), *b)
            }
            Area::Centre { lon_lat, size_m } => {
                let (mut xs, mut ys) = (vec![lon_lat[0]], vec![lon_lat[1]]);
                to_work
                    .transform_coords(&mut xs, &mut ys, &mut [])
                    .map_err(gdal_err("area centre → working CRS"))?;
                let e = [
                    xs[0] - 0.5 * size_m[0],
                    ys[0] - 0.5 * size_m[1],
                    xs[0] + 0.5 * size_m[0],
                    ys[0] + 0.5 * size_m[1],
                ];
                let back =
                    CoordTransform::new(&srs, &geo).map_err(gdal_err("working CRS → WGS 84"))?;
                let (mut xs, mut ys) = ring(e, 32);
                back.transform_coords(&mut xs, &mut ys, &mut [])
                    .map_err(gdal_err("area → WGS 84"))?;
                (e, bounds(&xs, &ys))
            }
        };
        let wkt = srs.to_wkt().map_err(gdal_err("working CRS to WKT"))?;
        let epsg = if proj.is_none() {
            srs.auth_code().ok().map(|c| c as u32)
        } else {
            None
        };
        Ok(WorkingFrame {
            srs,
            wkt,
            epsg,
            proj,
            centre_lon_lat: [lon, lat],
            extent,
            lon_lat_bbox,
            mask,
        })
    }
}

/// A north-up grid in the working CRS. Pixel (col, row) has its centre at
/// (`x0 + col·dx`, `y0 − row·dx`); row 0 is the northernmost.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grid {
    /// Centre of pixel (0, 0), metres.
    pub x0: f64,
    pub y0: f64,
    pub dx: f64,
    pub width: usize,
    pub height: usize,
}

impl Grid {
    /// GDAL geotransform (pixel corners).
    pub fn geotransform(&self) -> [f64; 6] {
        [
            self.x0 - 0.5 * self.dx,
            self.dx,
            0.0,
            self.y0 + 0.5 * self.dx,
            0.0,
            -self.dx,
        ]
    }
    pub fn x(&self, col: usize) -> f64 {
        self.x0 + col as f64 * self.dx
    }
    /// Row-major index of the pixel whose area holds (x, y), `None` outside the grid.
    pub fn cell_index(&self, x: f64, y: f64) -> Option<usize> {
        let c = ((x - (self.x0 - 0.5 * self.dx)) / self.dx).floor();
        let r = ((self.y0 + 0.5 * self.dx - y) / self.dx).floor();
        (c >= 0.0 && r >= 0.0 && c < self.width as f64 && r < self.height as f64)
            .then(|| r as usize * self.width + c as usize)
    }
    pub fn y(&self, row: usize) -> f64 {
        self.y0 - row as f64 * self.dx
    }

    /// The DEM node grid covering `extent` with spacing `spacing` rounded to 1/64 m.
    pub fn dem_nodes(extent: [f64; 4], spacing: f64) -> Grid {
        let dx = ((spacing * 64.0).round() / 64.0).max(1.0 / 64.0);
        let i0 = (extent[0] / dx).floor();
        let i1 = (extent[2] / dx).ceil();
        let jb = (extent[1] / dx).floor();
        let jt = (extent[3] / dx).ceil();
        Grid {
            x0: i0 * dx,
            y0: jt * dx,
            dx,
            width: (i1 - i0) as usize + 1,
            height: (jt - jb) as usize + 1,
        }
    }

    /// Cells of size `cell` covering the same area as the node grid `nodes` (its outer nodes on
    /// the cells' outer edges).
    pub fn cells_over(nodes: &Grid, cell: f64) -> Grid {
        let w = (nodes.width - 1) as f64 * nodes.dx;
        let h = (nodes.height - 1) as f64 * nodes.dx;
        let width = ((w / cell).ceil() as usize).max(1);
        let height = ((h / cell).ceil() as usize).max(1);
        Grid {
            x0: nodes.x0 + 0.5 * cell,
            y0: nodes.y0 - 0.5 * cell,
            dx: cell,
            width,
            height,
        }
    }
}

/// Open a raster and check it has georeferencing.
pub fn open_georeferenced(path: &Path, role: &str) -> Result<Dataset, ScenegenError> {
    if !path.exists() {
        return Err(input(path, format!("{role} file not found")));
    }
    let ds = Dataset::open(path)
        .map_err(|e| input(path, format!("GDAL cannot open the {role}: {e}")))?;
    if ds.raster_count() == 0 {
        return Err(input(path, format!("the {role} has no raster band")));
    }
    if ds.geo_transform().is_err() {
        return Err(input(
            path,
            format!("the {role} has no georeferencing (no geotransform)"),
        ));
    }
    if ds.projection().trim().is_empty() {
        return Err(input(
            path,
            format!("the {role} has no CRS (georeferencing without a coordinate reference system)"),
        ));
    }
    Ok(ds)
}

fn source_srs(ds: &Dataset, path: &Path) -> Result<SpatialRef, ScenegenError> {
    let mut s = ds
        .spatial_ref()
        .map_err(|e| input(path, format!("unreadable CRS: {e}")))?;
    s.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
    Ok(s)
}

/// Mean pixel size of `ds` in metres of the working CRS, near the area's centre.
pub fn pixel_size_m(ds: &Dataset, path: &Path, frame: &WorkingFrame) -> Result<f64, ScenegenError> {
    let gt = ds.geo_transform().map_err(|e| input(path, e.to_string()))?;
    let src = source_srs(ds, path)?;
    let to_src = CoordTransform::new(&frame.srs, &src)
        .map_err(|e| input(path, format!("no transformation from the working CRS: {e}")))?;
    let c = [
        0.5 * (frame.extent[0] + frame.extent[2]),
        0.5 * (frame.extent[1] + frame.extent[3]),
    ];
    let (mut x, mut y) = (vec![c[0]], vec![c[1]]);
    to_src
        .transform_coords(&mut x, &mut y, &mut [])
        .map_err(|e| input(path, format!("cannot transform the area's centre: {e}")))?;
    let to_work = CoordTransform::new(&src, &frame.srs).map_err(|e| input(path, e.to_string()))?;
    let mut xs = vec![x[0], x[0] + gt[1], x[0] + gt[2]];
    let mut ys = vec![y[0], y[0] + gt[4], y[0] + gt[5]];
    to_work
        .transform_coords(&mut xs, &mut ys, &mut [])
        .map_err(|e| input(path, e.to_string()))?;
    let d = |k: usize| ((xs[k] - xs[0]).powi(2) + (ys[k] - ys[0]).powi(2)).sqrt();
    Ok(0.5 * (d(1) + d(2)))
}

/// Refuse a raster that does not cover `extent` (working CRS) by more than one of its pixels,
/// saying by how much on each side.
pub fn check_coverage(
    ds: &Dataset,
    path: &Path,
    role: &str,
    frame: &WorkingFrame,
    extent: [f64; 4],
) -> Result<(), ScenegenError> {
    let gt = ds.geo_transform().map_err(|e| input(path, e.to_string()))?;
    let (w, h) = ds.raster_size();
    let (cx, cy): (Vec<f64>, Vec<f64>) = [
        (0.0, 0.0),
        (w as f64, 0.0),
        (0.0, h as f64),
        (w as f64, h as f64),
    ]
    .iter()
    .map(|(c, r)| (gt[0] + c * gt[1] + r * gt[2], gt[3] + c * gt[4] + r * gt[5]))
    .unzip();
    let have = bounds(&cx, &cy);
    let src = source_srs(ds, path)?;
    let need = area_in_source(ds, path, role, frame, extent)?;
    let px = gt[1].abs().max(gt[5].abs());
    let miss = [
        have[0] - need[0],
        have[1] - need[1],
        need[2] - have[2],
        need[3] - have[3],
    ];
    if miss.iter().all(|&m| m <= px) {
        return Ok(());
    }
    let geographic = src.is_geographic();
    if geographic {
        // A raster in 0…360° longitudes (or −180…180° for an area given past 180°) that would
        // cover the area one turn away: say so instead of "misses 360° on the west".
        for turn in [360.0, -360.0] {
            let covered = have[0] - (need[0] + turn) <= px
                && need[2] + turn - have[2] <= px
                && miss[1] <= px
                && miss[3] <= px;
            if covered {
                return Err(input(
                    path,
                    format!(
                        "the {role} uses longitudes {} ({:.4}…{:.4}°), the area lies at {:.4}…{:.4}°: the {role} covers it one turn ({turn:+}°) away. Rewrite it in −180…180° longitudes (e.g. `gdalwarp -t_srs EPSG:4326 --config CENTER_LONG 0 in.tif out.tif`)",
                        if turn > 0.0 { "beyond 180°" } else { "below −180°" },
                        have[0],
                        have[2],
                        need[0],
                        need[2]
                    ),
                ));
            }
        }
    }
    let lat = frame.centre_lon_lat[1].to_radians();
    let describe = |m: f64, side: usize| {
        if geographic {
            let km = m * 111.32 * if side % 2 == 0 { lat.cos() } else { 1.0 };
            format!("{m:.4}° (≈{km:.2} km)")
        } else {
            format!("{:.2} km", m / 1000.0)
        }
    };
    let sides = ["west", "south", "east", "north"];
    let parts: Vec<String> = (0..4)
        .filter(|&k| miss[k] > px)
        .map(|k| format!("{} on the {}", describe(miss[k], k), sides[k]))
        .collect();
    Err(input(
        path,
        format!(
            "the {role} does not cover the area of interest: it misses {}. The {role} spans x ∈ [{:.4}, {:.4}], y ∈ [{:.4}, {:.4}] in its CRS; the area needs x ∈ [{:.4}, {:.4}], y ∈ [{:.4}, {:.4}]",
            parts.join(", "),
            have[0], have[2], have[1], have[3], need[0], need[2], need[1], need[3]
        ),
    ))
}

/// Bounds (xmin, ymin, xmax, ymax) of `extent` (working CRS) in the CRS of `ds`.
pub(crate) fn area_in_source(
    ds: &Dataset,
    path: &Path,
    role: &str,
    frame: &WorkingFrame,
    extent: [f64; 4],
) -> Result<[f64; 4], ScenegenError> {
    let src = source_srs(ds, path)?;
    let to_src = CoordTransform::new(&frame.srs, &src)
        .map_err(|e| input(path, format!("no transformation from the working CRS: {e}")))?;
    let (mut xs, mut ys) = ring(extent, 32);
    to_src
        .transform_coords(&mut xs, &mut ys, &mut [])
        .map_err(|e| {
            input(
                path,
                format!("cannot transform the area into the {role}'s CRS: {e}"),
            )
        })?;
    Ok(bounds(&xs, &ys))
}

/// Warp band 1 of `src` onto `grid` in the working CRS. Pixels that no source pixel covers (or
/// only no-data ones) come back as `nodata`.
pub fn warp<T: GdalType + Copy + Default>(
    src: &Dataset,
    path: &Path,
    frame: &WorkingFrame,
    grid: &Grid,
    alg: GDALResampleAlg::Type,
    nodata: f64,
) -> Result<Vec<T>, ScenegenError> {
    let driver = DriverManager::get_driver_by_name("MEM").map_err(gdal_err("MEM driver"))?;
    let mut dst = driver
        .create_with_band_type::<T, _>("", grid.width, grid.height, 1)
        .map_err(gdal_err(format!(
            "in-memory raster {} × {}",
            grid.width, grid.height
        )))?;
    dst.set_geo_transform(&grid.geotransform())
        .map_err(gdal_err("set geotransform"))?;
    dst.set_projection(&frame.wkt)
        .map_err(gdal_err("set projection"))?;
    {
        let mut band = dst.rasterband(1).map_err(gdal_err("band"))?;
        band.set_no_data_value(Some(nodata))
            .map_err(gdal_err("set nodata"))?;
        band.fill(nodata, None).map_err(gdal_err("fill"))?;
    }
    // GDALReprojectImage takes the source's and destination's no-data values from their bands.
    let rv = unsafe {
        gdal_sys::GDALReprojectImage(
            src.c_dataset(),
            std::ptr::null(),
            dst.c_dataset(),
            std::ptr::null(),
            alg,
            0.0,
            0.125,
            None,
            std::ptr::null_mut(),
            std::ptr::null_mut(),
        )
    };
    if rv != gdal_sys::CPLErr::CE_None {
        let msg = unsafe { std::ffi::CStr::from_ptr(gdal_sys::CPLGetLastErrorMsg()) }
            .to_string_lossy()
            .into_owned();
        return Err(input(
            path,
            format!("GDAL cannot warp it into the working CRS: {msg}"),
        ));
    }
    let band = dst.rasterband(1).map_err(gdal_err("band"))?;
    let buf = band
        .read_band_as::<T>()
        .map_err(gdal_err("read warped band"))?;
    Ok(buf.into_shape_and_vec().1)
}

/// Band 1 of the raster at `path` on a grid of the working CRS over the area (`frame.extent`),
/// with cells of `cell` m (default: the raster's own pixel size there), warped by nearest
/// neighbour so that every value is one of the source's; no data (the band's, or no source
/// pixel) is NaN. A raster that does not cover the area is refused, naming `role`.
pub fn read_nearest(
    path: &Path,
    role: &str,
    frame: &WorkingFrame,
    cell: Option<f64>,
) -> Result<(Vec<f32>, Grid), ScenegenError> {
    let ds = open_georeferenced(path, role)?;
    check_coverage(&ds, path, role, frame, frame.extent)?;
    let dx = match cell {
        Some(c) => c,
        None => pixel_size_m(&ds, path, frame)?,
    };
    let grid = Grid::dem_nodes(frame.extent, dx);
    let band_nodata = ds
        .rasterband(1)
        .map_err(|e| input(path, e.to_string()))?
        .no_data_value();
    let mut v: Vec<f32> = warp(
        &ds,
        path,
        frame,
        &grid,
        GDALResampleAlg::GRA_NearestNeighbour,
        -1.0e30,
    )?;
    for x in v.iter_mut() {
        if *x <= -1.0e29 || Some(*x as f64) == band_nodata {
            *x = f32::NAN;
        }
    }
    Ok((v, grid))
}

/// Heights on the DEM node grid and the description of where they came from.
pub struct DemData {
    pub grid: Grid,
    /// Row-major, row 0 at the north, metres.
    pub heights: Vec<f32>,
    /// Pixels filled in small holes.
    pub filled: u64,
}

const DEM_NODATA: f64 = -1.0e30;

/// Metres per unit of a band's unit type.
fn unit_factor(unit: &str, path: &Path) -> Result<f64, ScenegenError> {
    match unit.trim().to_ascii_lowercase().as_str() {
        "" | "m" | "metre" | "meter" | "metres" | "meters" => Ok(1.0),
        "ft" | "foot" | "feet" | "international foot" => Ok(0.3048),
        "us-ft" | "us survey foot" | "ftus" => Ok(1200.0 / 3937.0),
        "km" => Ok(1000.0),
        other => Err(input(
            path,
            format!("DEM height unit `{other}` is not supported (metres, feet or km)"),
        )),
    }
}

/// Read the DEM file(s) onto a node grid over the area (first file first; later files fill
/// what earlier ones leave as no data), fill small holes, refuse large ones.
pub fn load_dem(region: &Region, frame: &WorkingFrame) -> Result<DemData, ScenegenError> {
    let mut grid = None;
    let mut heights: Vec<f32> = Vec::new();
    for (k, path) in region.dem_files.iter().enumerate() {
        let ds = open_georeferenced(path, "DEM")?;
        if grid.is_none() {
            let spacing = match region.dem_spacing_m {
                Some(s) => s,
                None => pixel_size_m(&ds, path, frame)?,
            };
            let g = Grid::dem_nodes(frame.extent, spacing);
            if g.width < 2 || g.height < 2 || g.width as u64 * g.height as u64 > 400_000_000 {
                return Err(ScenegenError::Region {
                    path: region.path.clone(),
                    key: "dem.spacing_m".into(),
                    message: format!(
                        "a {} × {} DEM grid at {} m is not usable (2 to 400 million nodes)",
                        g.width, g.height, g.dx
                    ),
                });
            }
            grid = Some(g);
        }
        let g = grid.unwrap();
        // With several DEMs the union must cover the area: only the last one is checked alone
        // when it is the only one; holes left by all of them are reported below.
        if region.dem_files.len() == 1 {
            let e = [g.x0, g.y(g.height - 1), g.x(g.width - 1), g.y0];
            check_coverage(&ds, path, "DEM", frame, e)?;
        }
        let band = ds.rasterband(1).map_err(|e| input(path, e.to_string()))?;
        let factor = unit_factor(&band.unit(), path)?;
        let scale = band.scale().unwrap_or(1.0);
        let offset = band.offset().unwrap_or(0.0);
        let e = [g.x0, g.y(g.height - 1), g.x(g.width - 1), g.y0];
        let window = area_in_source(&ds, path, "DEM", frame, e)?;
        crate::dem_values::check(&ds, path, window, |v| (v * scale + offset) * factor)?;

        let mut h: Vec<f32> = warp(
            &ds,
            path,
            frame,
            &g,
            GDALResampleAlg::GRA_Bilinear,
            DEM_NODATA,
        )?;
        for v in &mut h {
            if (*v as f64) > DEM_NODATA * 0.5 {
                *v = ((*v as f64 * scale + offset) * factor) as f32;
            } else {
                *v = f32::NAN;
            }
        }
        if k == 0 {
            heights = h;
        } else {
            for (a, b) in heights.iter_mut().zip(h) {
                if a.is_nan() {
                    *a = b;
                }
            }
        }
        tracing::info!(
            "DEM {}: {} × {} nodes at {} m",
            path.display(),
            g.width,
            g.height,
            g.dx
        );
    }
    let grid = grid.expect("at least one DEM (checked by the region)");
    let filled = fill_holes(&mut heights, &grid, region, frame)?;
    Ok(DemData {
        grid,
        heights,
        filled,
    })
}

/// Fill 4-connected no-data components of at most `max_fill_pixels`; refuse larger ones with
/// the largest hole's size and location.
fn fill_holes(
    h: &mut [f32],
    g: &Grid,
    region: &Region,
    frame: &WorkingFrame,
) -> Result<u64, ScenegenError> {
    let (w, ht) = (g.width, g.height);
    let mut seen = vec![false; h.len()];
    let mut filled = 0u64;
    let mut big: Vec<(usize, usize)> = Vec::new(); // (size, first pixel)
    let mut stack = Vec::new();
    let mut comp = Vec::new();
    for start in 0..h.len() {
        if !h[start].is_nan() || seen[start] {
            continue;
        }
        comp.clear();
        stack.push(start);
        seen[start] = true;
        while let Some(p) = stack.pop() {
            comp.push(p);
            let (c, r) = (p % w, p / w);
            let mut push = |q: usize| {
                if h[q].is_nan() && !seen[q] {
                    seen[q] = true;
                    stack.push(q);
                }
            };
            if c > 0 {
                push(p - 1);
            }
            if c + 1 < w {
                push(p + 1);
            }
            if r > 0 {
                push(p - w);
            }
            if r + 1 < ht {
                push(p + w);
            }
        }
        if comp.len() as u64 > region.max_fill_pixels {
            big.push((comp.len(), comp[0]));
            continue;
        }
        // Peel from the rim inwards: each pass fills pixels with a valid 8-neighbour.
        let mut todo: Vec<usize> = comp.clone();
        while !todo.is_empty() {
            let mut next = Vec::new();
            let mut updates = Vec::new();
            for &p in &todo {
                let (c, r) = ((p % w) as isize, (p / w) as isize);
                let (mut s, mut n) = (0.0f64, 0u32);
                for dr in -1..=1 {
                    for dc in -1..=1 {
                        let (cc, rr) = (c + dc, r + dr);
                        if (dc != 0 || dr != 0)
                            && cc >= 0
                            && rr >= 0
                            && (cc as usize) < w
                            && (rr as usize) < ht
                        {
                            let v = h[rr as usize * w + cc as usize];
                            if !v.is_nan() {
                                s += v as f64;
                                n += 1;
                            }
                        }
                    }
                }
                if n > 0 {
                    updates.push((p, (s / n as f64) as f32));
                } else {
                    next.push(p);
                }
            }
            if updates.is_empty() {
                break; // the whole grid is no data; reported below
            }
            for (p, v) in updates {
                h[p] = v;
                filled += 1;
            }
            todo = next;
        }
    }
    if h.iter().any(|v| v.is_nan()) && big.is_empty() {
        big.push((
            h.iter().filter(|v| v.is_nan()).count(),
            h.iter().position(|v| v.is_nan()).unwrap(),
        ));
    }
    if !big.is_empty() {
        big.sort_by_key(|b| std::cmp::Reverse(b.0));
        let total: usize = big.iter().map(|b| b.0).sum();
        let (n, p) = big[0];
        let (c, r) = (p % w, p / w);
        let (x, y) = (g.x(c), g.y(r));
        let ll = to_lon_lat(frame, x, y)
            .map(|(lo, la)| format!(" (lon {lo:.5}°, lat {la:.5}°)"))
            .unwrap_or_default();
        let files: Vec<String> = region
            .dem_files
            .iter()
            .map(|p| p.display().to_string())
            .collect();
        return Err(input(
            PathBuf::from(files.join(", ")),
            format!(
                "no-data holes too large to fill: {} hole(s) of {total} pixels in all; the largest has {n} pixels, starting at row {r}, column {c} of the working grid, x = {x:.1} m, y = {y:.1} m{ll}. \
                 Holes up to `dem.max_fill_pixels` = {} pixels are filled; give another DEM in `dem.files` to cover them, or raise the limit",
                big.len(),
                region.max_fill_pixels
            ),
        ));
    }
    Ok(filled)
}

/// Working-CRS point to WGS 84 (lon, lat).
pub fn to_lon_lat(frame: &WorkingFrame, x: f64, y: f64) -> Option<(f64, f64)> {
    let geo = wgs84().ok()?;
    let t = CoordTransform::new(&frame.srs, &geo).ok()?;
    let (mut xs, mut ys) = (vec![x], vec![y]);
    t.transform_coords(&mut xs, &mut ys, &mut []).ok()?;
    Some((xs[0], ys[0]))
}

/// Land-cover class codes of the raster (or uniform class) on `grid` (`None` = no data) and the
/// resampling used; `landcover_vector::load` burns the polygons over them.
pub fn load_landcover_raster(
    region: &Region,
    frame: &WorkingFrame,
    grid: &Grid,
    scheme_nodata: Option<i64>,
) -> Result<(Vec<Option<i64>>, &'static str), ScenegenError> {
    let path = match &region.landcover {
        crate::region::LandcoverInput::File(p) => p,
        crate::region::LandcoverInput::Uniform(c) => {
            let code = (Some(*c) != scheme_nodata).then_some(*c);
            return Ok((vec![code; grid.width * grid.height], "uniform"));
        }
        crate::region::LandcoverInput::None => {
            return Ok((vec![None; grid.width * grid.height], "none"));
        }
    };
    let ds = open_georeferenced(path, "land-cover raster")?;
    let e = [
        grid.x0 - 0.5 * grid.dx,
        grid.y(grid.height - 1) - 0.5 * grid.dx,
        grid.x(grid.width - 1) + 0.5 * grid.dx,
        grid.y0 + 0.5 * grid.dx,
    ];
    check_coverage(&ds, path, "land-cover raster", frame, e)?;
    let src_px = pixel_size_m(&ds, path, frame)?;
    use crate::region::Resampling;
    let mode = match region.resampling {
        Resampling::Mode => true,
        Resampling::Nearest => false,
        Resampling::Auto => grid.dx > 1.5 * src_px,
    };
    let band = ds.rasterband(1).map_err(|e| input(path, e.to_string()))?;
    let band_nodata = band.no_data_value();

    const NODATA: i32 = i32::MIN;
    let alg = if mode {
        GDALResampleAlg::GRA_Mode
    } else {
        GDALResampleAlg::GRA_NearestNeighbour
    };
    let nodata =
        |c: i64| c == NODATA as i64 || Some(c as f64) == band_nodata || Some(c) == scheme_nodata;
    use gdal::raster::GdalDataType;
    let float = matches!(
        band.band_type(),
        GdalDataType::Float32 | GdalDataType::Float64
    );
    let codes = if float {
        // A float raster must hold class codes: integers, or NaN/nodata for holes. Read as
        // floats (an integer warp would round 18.7 to class 19 and turn NaN into i32::MIN + 1).
        let v: Vec<f64> = warp(&ds, path, frame, grid, alg, NODATA as f64)?;
        let mut codes = Vec::with_capacity(v.len());
        for (k, x) in v.into_iter().enumerate() {
            if x.is_nan() || Some(x) == band_nodata {
                codes.push(None);
            } else if x.fract() != 0.0 || x.abs() > 2f64.powi(31) {
                let (col, row) = (k % grid.width, k / grid.width);
                return Err(input(
                    path,
                    format!(
                        "land cover holds {x} near working-frame x = {:.0} m, y = {:.0} m: a float raster must hold integer class codes (or NaN / nodata for holes)",
                        grid.x(col),
                        grid.y(row)
                    ),
                ));
            } else {
                let c = x as i64;
                codes.push((!nodata(c)).then_some(c));
            }
        }
        codes
    } else {
        let v: Vec<i32> = warp(&ds, path, frame, grid, alg, NODATA as f64)?;
        v.into_iter()
            .map(|c| {
                let c = c as i64;
                (!nodata(c)).then_some(c)
            })
            .collect()
    };
    Ok((codes, if mode { "mode" } else { "nearest" }))
}
