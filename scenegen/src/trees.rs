//! Trees from canopy height (`[[trees]]`): individual trees detected as local maxima of a
//! canopy-height model (CHM), each placed as an instance of a template scaled to its height and
//! crown. Keys: docs/region.md, "`[[trees]]`".
//!
//! **The CHM**: a raster of heights above ground (`chm`), or a surface model minus a terrain model
//! (`dsm` − `dtm`, the two rasters warped onto one grid), or the region's lidar (`from_lidar`:
//! the highest point of `vegetation_classes` in each cell minus the DEM there; cells that hold a
//! point of `exclude_classes`, buildings by default, are not canopy). It is read on a
//! grid of the working CRS at `cell_m` (default: the raster's pixel size; 1 m from lidar), by
//! nearest-neighbour warping so that maxima are the source's own values.
//!
//! **Detection rule** (a variable-window local-maximum filter, Popescu & Wynne 2004,
//! Photogramm. Eng. Remote Sens. 70(5), 589–604): a cell of height h ≥ `min_height_m` is a tree
//! top when no other cell within the circle of radius CW(h)/2 around it is higher (equal heights:
//! the first in row-major order wins), where CW is the crown width predicted from the height by
//! Popescu & Wynne's deciduous/mixed-forest regression, CW(h) = 3.09632 + 0.00895·h² (m, h in m),
//! or a fixed `window_m` diameter when given. No smoothing is applied.
//!
//! **Instances**: at the cell centre on the terrain surface; the template is scaled vertically to
//! the tree's height and horizontally to CW(h) (`crown_scale` × the regression's width, or the
//! template's own proportions with `keep_proportions`), rotated by a random yaw from the region's
//! seed. A CHM that does not cover the area, or holds no cell above `min_height_m`, is an error
//! naming the file; heights above [`MAX_TREE_M`] are no data, with a warning giving their count.

pub use crate::inputs::{ChmSource, TreesSpec};
use std::path::PathBuf;

use crate::error::ScenegenError;
use crate::raster::{Grid, WorkingFrame};

/// Canopy heights above this (m) are taken as no data (an undeclared fill value, a CHM in
/// centimetres, a bird in the lidar): the tallest trees are about 116 m.
pub const MAX_TREE_M: f32 = 150.0;

/// Popescu & Wynne (2004) crown width of a deciduous/mixed-forest tree of height `h` (m).
pub fn crown_width(h: f64) -> f64 {
    3.09632 + 0.00895 * h * h
}

/// One detected tree top.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TreeTop {
    /// Working-CRS position of the cell centre.
    pub x: f64,
    pub y: f64,
    /// CHM height there, m.
    pub height: f64,
    /// Crown width used for the window and the instance, m.
    pub crown: f64,
}

/// Tree tops of `chm` on `grid` (row-major, row 0 north; NaN = no data) by the rule above.
pub fn detect(chm: &[f32], grid: &Grid, min_height: f64, window_m: Option<f64>) -> Vec<TreeTop> {
    let (w, h) = (grid.width, grid.height);
    let mut tops = Vec::new();
    for r in 0..h {
        for c in 0..w {
            let k = r * w + c;
            let v = chm[k] as f64;
            if v.is_nan() || v < min_height {
                continue;
            }
            let cw = crown_width(v);
            let rad = 0.5 * window_m.unwrap_or(cw);
            let n = (rad / grid.dx).floor() as i64;
            let (r0, r1) = ((r as i64 - n).max(0), (r as i64 + n).min(h as i64 - 1));
            let (c0, c1) = ((c as i64 - n).max(0), (c as i64 + n).min(w as i64 - 1));
            let mut top = true;
            'win: for rr in r0..=r1 {
                for cc in c0..=c1 {
                    let (dr, dc) = (rr - r as i64, cc - c as i64);
                    if (dr == 0 && dc == 0)
                        || ((dr * dr + dc * dc) as f64) * grid.dx * grid.dx > rad * rad
                    {
                        continue;
                    }
                    let kk = rr as usize * w + cc as usize;
                    let u = chm[kk] as f64;
                    if u > v || (u == v && kk < k) {
                        top = false;
                        break 'win;
                    }
                }
            }
            if top {
                tops.push(TreeTop {
                    x: grid.x(c),
                    y: grid.y(r),
                    height: v,
                    crown: cw,
                });
            }
        }
    }
    tops
}

/// The CHM of `spec` on a grid over `extent` (working CRS); `dem` gives terrain heights for the
/// lidar source.
pub fn load_chm(
    spec: &TreesSpec,
    frame: &WorkingFrame,
    lidar: Option<&crate::pointcloud::PointCloud>,
    dem_at: impl Fn(f64, f64) -> Option<f64>,
) -> Result<(Vec<f32>, Grid, PathBuf), ScenegenError> {
    use crate::raster::read_nearest as read;
    let e = frame.extent;
    let (mut v, g, src) = match &spec.source {
        ChmSource::Chm(p) => {
            let (v, g) = read(p, "canopy-height raster", frame, spec.cell_m)?;
            (v, g, p.clone())
        }
        ChmSource::DsmMinusDtm { dsm, dtm } => {
            let (s, g) = read(dsm, "surface model (DSM)", frame, spec.cell_m)?;
            let (t, g2) = read(dtm, "terrain model (DTM)", frame, Some(g.dx))?;
            debug_assert_eq!(g, g2);
            let v = s.iter().zip(&t).map(|(a, b)| a - b).collect();
            (v, g, dsm.clone())
        }
        ChmSource::Lidar { classes, exclude } => {
            let pc = lidar.expect("checked by the region");
            let grid = Grid::dem_nodes(e, spec.cell_m.unwrap_or(1.0));
            let mut top = vec![f32::NAN; grid.width * grid.height];
            let mut excluded = vec![false; top.len()];
            for i in 0..pc.len() {
                let (veg, excl) = (
                    classes.contains(&pc.class[i]),
                    exclude.contains(&pc.class[i]),
                );
                if !(veg || excl) {
                    continue;
                }
                let Some(k) = grid.cell_index(pc.x[i], pc.y[i]) else {
                    continue;
                };
                excluded[k] |= excl;
                let z = pc.z[i] as f32;
                if veg && (top[k].is_nan() || z > top[k]) {
                    top[k] = z;
                }
            }
            for r in 0..grid.height {
                for c in 0..grid.width {
                    let k = r * grid.width + c;
                    if excluded[k] {
                        top[k] = f32::NAN;
                    } else if !top[k].is_nan() {
                        top[k] = match dem_at(grid.x(c), grid.y(r)) {
                            Some(g) => top[k] - g as f32,
                            None => f32::NAN,
                        };
                    }
                }
            }
            (top, grid, PathBuf::from("[lidar]"))
        }
    };
    let mut high = 0;
    for x in v.iter_mut() {
        if *x > MAX_TREE_M {
            *x = f32::NAN;
            high += 1;
        }
    }
    if high > 0 {
        tracing::warn!(
            "{}: {high} canopy height(s) above {MAX_TREE_M} m taken as no data (fill values, units or outliers)",
            src.display()
        );
    }
    Ok((v, g, src))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(n: usize) -> Grid {
        Grid {
            x0: 0.0,
            y0: 0.0,
            dx: 1.0,
            width: n,
            height: n,
        }
    }

    /// Two cone-shaped crowns (10 m and 20 m tall, 12 m apart) on a 40 × 40 m grid: exactly their
    /// apexes are found, with their heights; a third cone 2 m from the taller one is absorbed
    /// (inside its window), and a plateau gives one top.
    #[test]
    fn cones_give_their_apexes() {
        let g = grid(40);
        let cone = |cx: f64, cy: f64, h: f64, x: f64, y: f64| {
            (h - 1.5 * ((x - cx).powi(2) + (y - cy).powi(2)).sqrt()).max(0.0)
        };
        let chm: Vec<f32> = (0..1600)
            .map(|k| {
                let (x, y) = ((k % 40) as f64, -((k / 40) as f64));
                cone(10.0, -10.0, 10.0, x, y)
                    .max(cone(22.0, -10.0, 20.0, x, y))
                    .max(cone(24.0, -10.0, 12.0, x, y)) as f32
            })
            .collect();
        let tops = detect(&chm, &g, 2.0, None);
        assert_eq!(tops.len(), 2, "{tops:?}");
        assert_eq!((tops[0].x, tops[0].y, tops[0].height), (10.0, -10.0, 10.0));
        assert_eq!((tops[1].x, tops[1].y, tops[1].height), (22.0, -10.0, 20.0));
        assert!((tops[1].crown - crown_width(20.0)).abs() < 1e-12);
        let flat = vec![5.0f32; 100];
        assert_eq!(detect(&flat, &grid(10), 2.0, Some(30.0)).len(), 1);
        assert!(detect(&flat, &grid(10), 6.0, None).is_empty());
    }
}
