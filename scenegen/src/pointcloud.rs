//! Airborne lidar point clouds (LAS and LAZ, `las` crate with LAZ support): points reprojected to
//! the working CRS with their ASPRS class, a bucket index for "points inside this footprint"
//! queries, and gridding of chosen classes into a raster (ground → DTM, first returns → DSM).
//!
//! CRS: the file's OGC WKT VLR, else its GeoTIFF projected-CRS key (an EPSG code), else the
//! region's `crs` key for the point cloud; none of these is an error naming the file, and so is
//! a projected CRS not in metres (heights are taken in the file's unit, which must be metres). A file
//! without points is an error; so is a point outside the working CRS's domain.

use std::path::{Path, PathBuf};

use gdal::spatial_ref::{AxisMappingStrategy, CoordTransform, SpatialRef};

use crate::error::ScenegenError;
use crate::raster::{Grid, WorkingFrame};

fn bad(path: &Path, message: impl Into<String>) -> ScenegenError {
    ScenegenError::Input {
        path: path.into(),
        message: message.into(),
    }
}

/// Points in the working CRS (metres), heights as in the file (metres), ASPRS classes.
#[derive(Clone, Debug, Default)]
pub struct PointCloud {
    pub x: Vec<f64>,
    pub y: Vec<f64>,
    pub z: Vec<f64>,
    pub class: Vec<u8>,
}

impl PointCloud {
    pub fn len(&self) -> usize {
        self.x.len()
    }
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }
    /// Points per ASPRS class (index = class).
    pub fn class_counts(&self) -> [u64; 256] {
        let mut c = [0u64; 256];
        for &k in &self.class {
            c[k as usize] += 1;
        }
        c
    }
}

/// The CRS of a LAS/LAZ header: WKT VLR, else the projected EPSG GeoKey.
fn header_crs(h: &las::Header) -> Option<SpatialRef> {
    if let Some(w) = h.get_wkt_crs_bytes() {
        let text = String::from_utf8_lossy(w);
        let text = text.trim_end_matches('\0');
        if let Ok(s) = SpatialRef::from_wkt(text) {
            return Some(s);
        }
    }
    h.get_geotiff_crs()
        .ok()
        .flatten()?
        .get_projected_crs_geo_key_value()
        .filter(|&e| e != 0 && e != 32767)
        .and_then(|e| SpatialRef::from_epsg(e as u32).ok())
}

/// Read every point of `paths` into the working CRS. `crs` overrides the files' own CRS.
pub fn read(
    paths: &[PathBuf],
    crs: Option<&str>,
    frame: &WorkingFrame,
) -> Result<PointCloud, ScenegenError> {
    let mut out = PointCloud::default();
    let mut dst = frame.srs.clone();
    dst.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
    for path in paths {
        if !path.exists() {
            return Err(bad(path, "point-cloud file not found"));
        }
        let mut reader = las::Reader::from_path(path)
            .map_err(|e| bad(path, format!("not a readable LAS/LAZ file: {e}")))?;
        let mut src = match crs {
            Some(def) => SpatialRef::from_definition(def)
                .map_err(|e| bad(path, format!("GDAL cannot read CRS `{def}`: {e}")))?,
            None => header_crs(reader.header()).ok_or_else(|| {
                bad(
                    path,
                    "the point cloud declares no CRS (no WKT or EPSG GeoKey): give `crs` (e.g. \"EPSG:28992\")",
                )
            })?,
        };
        src.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
        let unit = src.linear_units();
        if src.is_projected() && (unit - 1.0).abs() > 1e-9 {
            return Err(bad(
                path,
                format!(
                    "its CRS counts {unit} m per unit (feet?): heights would be read in the wrong unit; reproject the points to a metric CRS first"
                ),
            ));
        }
        let n = reader.header().number_of_points();
        if n == 0 {
            return Err(bad(path, "the point cloud holds no points"));
        }
        let data = reader
            .read_all()
            .map_err(|e| bad(path, format!("cannot decode its points: {e}")))?;
        let mut xs: Vec<f64> = data.x().collect();
        let mut ys: Vec<f64> = data.y().collect();
        let zs: Vec<f64> = data.z().collect();
        let cls: Vec<u8> = data.classification().collect();
        let same = src.to_wkt().ok() == dst.to_wkt().ok() || src == dst;
        if !same {
            let t = CoordTransform::new(&src, &dst)
                .map_err(|e| bad(path, format!("no transformation to the working CRS: {e}")))?;
            for (cx, cy) in xs.chunks_mut(1 << 16).zip(ys.chunks_mut(1 << 16)) {
                t.transform_coords(cx, cy, &mut [])
                    .map_err(|e| bad(path, format!("cannot transform its points: {e}")))?;
            }
        }
        if let Some(k) = xs
            .iter()
            .zip(&ys)
            .zip(&zs)
            .position(|((x, y), z)| !(x.is_finite() && y.is_finite() && z.is_finite()))
        {
            return Err(bad(
                path,
                format!("point {k} is not finite in the working CRS"),
            ));
        }
        tracing::info!("point cloud {}: {} points", path.display(), xs.len());
        out.x.extend(xs);
        out.y.extend(ys);
        out.z.extend(zs);
        out.class.extend(cls);
    }
    Ok(out)
}

/// Points bucketed on a square grid for footprint queries.
pub struct PointIndex {
    x0: f64,
    y0: f64,
    cell: f64,
    nx: usize,
    ny: usize,
    /// CSR: bucket b holds `order[start[b]..start[b + 1]]`.
    start: Vec<u32>,
    order: Vec<u32>,
}

impl PointIndex {
    /// Index the points of `pc` whose class is in `classes` and that lie in `within` (xmin,
    /// ymin, xmax, ymax: the area, so that a stray point far away cannot blow up the grid).
    pub fn new(pc: &PointCloud, classes: &[u8], cell: f64, within: [f64; 4]) -> PointIndex {
        let keep: Vec<u32> = (0..pc.len() as u32)
            .filter(|&i| {
                let (x, y) = (pc.x[i as usize], pc.y[i as usize]);
                classes.contains(&pc.class[i as usize])
                    && x >= within[0]
                    && x <= within[2]
                    && y >= within[1]
                    && y <= within[3]
            })
            .collect();
        let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        for &i in &keep {
            let (x, y) = (pc.x[i as usize], pc.y[i as usize]);
            x0 = x0.min(x);
            y0 = y0.min(y);
            x1 = x1.max(x);
            y1 = y1.max(y);
        }
        if keep.is_empty() {
            (x0, y0, x1, y1) = (0.0, 0.0, 0.0, 0.0);
        }
        let nx = (((x1 - x0) / cell).floor() as usize + 1).max(1);
        let ny = (((y1 - y0) / cell).floor() as usize + 1).max(1);
        let bucket = |i: u32| {
            let cx = (((pc.x[i as usize] - x0) / cell) as usize).min(nx - 1);
            let cy = (((pc.y[i as usize] - y0) / cell) as usize).min(ny - 1);
            cy * nx + cx
        };
        let mut start = vec![0u32; nx * ny + 1];
        for &i in &keep {
            start[bucket(i) + 1] += 1;
        }
        for b in 0..nx * ny {
            start[b + 1] += start[b];
        }
        let mut fill = start.clone();
        let mut order = vec![0u32; keep.len()];
        for &i in &keep {
            let b = bucket(i);
            order[fill[b] as usize] = i;
            fill[b] += 1;
        }
        PointIndex {
            x0,
            y0,
            cell,
            nx,
            ny,
            start,
            order,
        }
    }

    /// Indices of the indexed points inside the box [xmin, xmax] × [ymin, ymax] (and some near
    /// it: callers test containment).
    pub fn candidates(&self, b: [f64; 4], out: &mut Vec<u32>) {
        out.clear();
        if self.order.is_empty() {
            return;
        }
        let cx = |x: f64| (((x - self.x0) / self.cell).floor().max(0.0) as usize).min(self.nx - 1);
        let cy = |y: f64| (((y - self.y0) / self.cell).floor().max(0.0) as usize).min(self.ny - 1);
        if b[2] < self.x0 || b[3] < self.y0 {
            return;
        }
        for y in cy(b[1])..=cy(b[3]) {
            for x in cx(b[0])..=cx(b[2]) {
                let k = y * self.nx + x;
                out.extend_from_slice(
                    &self.order[self.start[k] as usize..self.start[k + 1] as usize],
                );
            }
        }
    }
}

/// Grid the points of `classes` onto `grid` (mean height per cell). Empty cells are filled from
/// their rim inwards with the mean of their filled 8-neighbours (so a DTM is complete under
/// buildings and water). Returns the heights (row-major, row 0 north) and the number of cells
/// filled that way; no point at all is an error.
pub fn grid_heights(
    pc: &PointCloud,
    classes: &[u8],
    grid: &Grid,
    path: &Path,
) -> Result<(Vec<f32>, usize), ScenegenError> {
    let (w, h) = (grid.width, grid.height);
    // The points must cover the grid (to within two cells): beyond them a "DTM" would be made up.
    let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for i in 0..pc.len() {
        x0 = x0.min(pc.x[i]);
        y0 = y0.min(pc.y[i]);
        x1 = x1.max(pc.x[i]);
        y1 = y1.max(pc.y[i]);
    }
    let need = [grid.x0, grid.y(h - 1), grid.x(w - 1), grid.y0];
    let slack = 2.0 * grid.dx;
    let miss = [
        ("west", x0 - need[0]),
        ("south", y0 - need[1]),
        ("east", need[2] - x1),
        ("north", need[3] - y1),
    ];
    let short: Vec<String> = miss
        .iter()
        .filter(|(_, d)| *d > slack)
        .map(|(side, d)| format!("{d:.1} m on the {side}"))
        .collect();
    if !short.is_empty() {
        return Err(bad(
            path,
            format!(
                "the point cloud does not cover the area of interest: it misses {}. The points span x ∈ [{x0:.2}, {x1:.2}], y ∈ [{y0:.2}, {y1:.2}] in the working CRS; the DEM grid needs x ∈ [{:.2}, {:.2}], y ∈ [{:.2}, {:.2}]",
                short.join(", "),
                need[0],
                need[2],
                need[1],
                need[3]
            ),
        ));
    }
    let mut sum = vec![0f64; w * h];
    let mut n = vec![0u32; w * h];
    for i in 0..pc.len() {
        if !classes.contains(&pc.class[i]) {
            continue;
        }
        let Some(k) = grid.cell_index(pc.x[i], pc.y[i]) else {
            continue;
        };
        sum[k] += pc.z[i];
        n[k] += 1;
    }
    if n.iter().all(|&c| c == 0) {
        return Err(bad(
            path,
            format!("no point of classes {classes:?} inside the area of interest"),
        ));
    }
    let mut z: Vec<f32> = sum
        .iter()
        .zip(&n)
        .map(|(s, &c)| {
            if c > 0 {
                (s / c as f64) as f32
            } else {
                f32::NAN
            }
        })
        .collect();
    let mut filled = 0;
    let mut empty: Vec<usize> = (0..w * h).filter(|&k| z[k].is_nan()).collect();
    while !empty.is_empty() {
        let mut next = Vec::new();
        for &k in &empty {
            let (r, c) = (k / w, k % w);
            let (mut s, mut m) = (0f64, 0);
            for dr in -1i64..=1 {
                for dc in -1i64..=1 {
                    let (rr, cc) = (r as i64 + dr, c as i64 + dc);
                    if rr < 0 || cc < 0 || rr >= h as i64 || cc >= w as i64 {
                        continue;
                    }
                    let v = z[rr as usize * w + cc as usize];
                    if !v.is_nan() {
                        s += v as f64;
                        m += 1;
                    }
                }
            }
            if m > 0 {
                next.push((k, (s / m as f64) as f32));
            }
        }
        filled += next.len();
        for &(k, v) in &next {
            z[k] = v;
        }
        empty.retain(|&k| z[k].is_nan());
    }
    Ok((z, filled))
}
