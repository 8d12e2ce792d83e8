//! Vector land cover (`[[landcover.vector]]`): polygons with a class attribute (or one class per
//! layer) burnt onto the material grid by GDAL's rasteriser, over the raster land cover (or over
//! no data when there is none). Layers are burnt in the order given: a later layer wins where
//! polygons overlap.
//!
//! Rule per material cell. With `resampling = "nearest"` the class is the one whose polygon
//! contains the cell centre. Otherwise (`"mode"`, and `"auto"`, since polygons have no source
//! pixel size) the cell is sampled at the centres of a 4 × 4 sub-grid (3 × 3 or 2 × 2 when that
//! would exceed 2²⁶ samples, one sample per cell beyond) and takes the most frequent class;
//! samples in no polygon vote for the raster's class beneath (or no data), and ties go to the
//! polygons, then to the smallest code. Holes (courtyards, lakes) and multipolygons are GDAL's: a sample inside a hole
//! is outside the polygon.
//!
//! Class codes come from an integer attribute (`attribute`), from a text attribute through
//! `values = { "text" = code }`, or are one code for the layer (`class`); a feature whose
//! attribute is null or has no mapping is an error naming the file, layer, feature id and value
//! (nothing is dropped). The codes then go through the scheme like a raster's.

pub use crate::inputs::{CodeSource, VectorLandcover};

use gdal::DriverManager;

use crate::error::{gdal_err, ScenegenError};
use crate::raster::{Grid, WorkingFrame};
use crate::vector::{as_code, as_text, read_layer};

/// What a burn did, for the log and `scenegen info`.
#[derive(Clone, Debug, Default)]
pub struct BurnReport {
    /// Per layer: label, features burnt, features skipped (empty), invalid polygons kept.
    pub layers: Vec<(String, usize, usize, Vec<u64>)>,
    /// Cells whose class came from a polygon.
    pub cells_from_polygons: usize,
    /// Samples per cell side.
    pub oversampling: usize,
}

const NONE: i32 = i32::MIN;

/// Sub-samples per cell side for `mode`: 4, or fewer so that the sample grid stays ≤ 2²⁶.
pub fn oversampling(grid: &Grid, mode: bool) -> usize {
    if !mode {
        return 1;
    }
    let cells = (grid.width * grid.height).max(1);
    let mut k = 4;
    while k > 1 && cells * k * k > 1 << 26 {
        k -= 1;
    }
    k
}

/// Burn `layers` over `codes` (the raster's classes on `grid`, `None` = no data). `region_path`
/// names the region file in errors about its keys.
pub fn burn(
    layers: &[VectorLandcover],
    frame: &WorkingFrame,
    grid: &Grid,
    mode: bool,
    codes: &mut [Option<i64>],
) -> Result<BurnReport, ScenegenError> {
    let k = oversampling(grid, mode);
    let (w, h) = (grid.width * k, grid.height * k);
    let driver = DriverManager::get_driver_by_name("MEM").map_err(gdal_err("MEM driver"))?;
    let mut ds = driver
        .create_with_band_type::<i32, _>("", w, h, 1)
        .map_err(gdal_err(format!("in-memory raster {w} × {h}")))?;
    let gt = grid.geotransform();
    let sub = grid.dx / k as f64;
    ds.set_geo_transform(&[gt[0], sub, 0.0, gt[3], 0.0, -sub])
        .map_err(gdal_err("set geotransform"))?;
    ds.set_projection(&frame.wkt)
        .map_err(gdal_err("set projection"))?;
    ds.rasterband(1)
        .map_err(gdal_err("band"))?
        .fill(NONE as f64, None)
        .map_err(gdal_err("fill"))?;

    let mut report = BurnReport {
        oversampling: k,
        ..Default::default()
    };
    for l in layers {
        let attrs: Vec<&str> = match &l.code {
            CodeSource::Class(_) => vec![],
            CodeSource::Attribute { name, .. } => vec![name.as_str()],
        };
        let layer = read_layer(
            &l.file,
            l.layer.as_deref(),
            l.crs.as_deref(),
            l.filter.as_deref(),
            &attrs,
            frame,
        )?;
        if let Some((id, ty)) = layer.not_polygons.first() {
            return Err(ScenegenError::Input {
                path: l.file.clone(),
                message: format!(
                    "{}, feature {id}: a {ty} where polygons are expected ({} such feature(s); select the polygons with `filter`)",
                    layer.label,
                    layer.not_polygons.len()
                ),
            });
        }
        let mut geoms = Vec::with_capacity(layer.features.len());
        let mut burn = Vec::with_capacity(layer.features.len());
        for f in &layer.features {
            let code = match &l.code {
                CodeSource::Class(c) => *c,
                CodeSource::Attribute { name, values } => {
                    let v = f.values[0].as_ref().ok_or_else(|| ScenegenError::Input {
                        path: l.file.clone(),
                        message: format!(
                            "{}, feature {}: attribute `{name}` is null (no class)",
                            layer.label, f.id
                        ),
                    })?;
                    let text = as_text(v);
                    match values.get(&text).copied().or_else(|| {
                        if values.is_empty() {
                            as_code(v)
                        } else {
                            None
                        }
                    }) {
                        Some(c) => c,
                        None => {
                            return Err(ScenegenError::Input {
                                path: l.file.clone(),
                                message: if values.is_empty() {
                                    format!(
                                        "{}, feature {}: attribute `{name}` = \"{text}\" is not an integer class code; map its text values with `values = {{ \"{text}\" = CODE, … }}`",
                                        layer.label, f.id
                                    )
                                } else {
                                    format!(
                                        "{}, feature {}: attribute `{name}` = \"{text}\" has no entry in `values` ({})",
                                        layer.label,
                                        f.id,
                                        values.keys().map(|k| format!("\"{k}\"")).collect::<Vec<_>>().join(", ")
                                    )
                                },
                            })
                        }
                    }
                }
            };
            if code < i32::MIN as i64 + 1 || code > i32::MAX as i64 {
                return Err(ScenegenError::Input {
                    path: l.file.clone(),
                    message: format!(
                        "{}, feature {}: class code {code} is outside the 32-bit range",
                        layer.label, f.id
                    ),
                });
            }
            geoms.push(f.geometry.clone());
            burn.push(code as f64);
        }
        if !geoms.is_empty() {
            gdal::raster::rasterize(&mut ds, &[1], &geoms, &burn, None)
                .map_err(gdal_err(format!("rasterise {}", layer.label)))?;
        }
        tracing::info!(
            "land cover: {} polygons from {} ({} empty skipped, {} invalid kept)",
            geoms.len(),
            layer.label,
            layer.empty,
            layer.invalid.len()
        );
        report
            .layers
            .push((layer.label, geoms.len(), layer.empty, layer.invalid));
    }
    let samples: Vec<i32> = ds
        .rasterband(1)
        .map_err(gdal_err("band"))?
        .read_band_as::<i32>()
        .map_err(gdal_err("read rasterised band"))?
        .into_shape_and_vec()
        .1;

    let mut votes: Vec<(i32, usize)> = Vec::with_capacity(k * k);
    let mut cell: Vec<i32> = Vec::with_capacity(k * k);
    for row in 0..grid.height {
        for col in 0..grid.width {
            cell.clear();
            for sr in 0..k {
                let base = (row * k + sr) * w + col * k;
                cell.extend_from_slice(&samples[base..base + k]);
            }
            let at = row * grid.width + col;
            if let Some(c) = cell_class(&cell, codes[at], &mut votes) {
                codes[at] = Some(c);
                report.cells_from_polygons += 1;
            }
        }
    }
    Ok(report)
}

/// The class a cell takes from its polygon samples (`NONE` = in no polygon) over the class
/// `beneath` (the raster's): samples in no polygon vote for the class beneath, together with the
/// polygon samples of that class; the most votes win, ties going to the polygons, then to the
/// smallest code. `None`: the class beneath stays.
fn cell_class(samples: &[i32], beneath: Option<i64>, votes: &mut Vec<(i32, usize)>) -> Option<i64> {
    votes.clear();
    let mut outside = 0;
    for &c in samples {
        if c == NONE {
            outside += 1;
        } else if let Some(v) = votes.iter_mut().find(|v| v.0 == c) {
            v.1 += 1;
        } else {
            votes.push((c, 1));
        }
    }
    if let Some(v) = beneath.and_then(|b| votes.iter_mut().find(|v| v.0 as i64 == b)) {
        v.1 += outside;
        outside = 0;
    }
    let (c, n) = votes
        .iter()
        .copied()
        .max_by(|a, b| a.1.cmp(&b.1).then(b.0.cmp(&a.0)))?;
    (n >= outside).then_some(c as i64)
}

/// Land-cover class codes on `grid` (`None` = no data) and the resampling used: the raster (or
/// uniform class, `raster::load_landcover_raster`), then the `[[landcover.vector]]` polygons
/// burnt over it.
pub fn load(
    region: &crate::region::Region,
    frame: &WorkingFrame,
    grid: &Grid,
    scheme_nodata: Option<i64>,
) -> Result<(Vec<Option<i64>>, &'static str), ScenegenError> {
    let (mut codes, how) =
        crate::raster::load_landcover_raster(region, frame, grid, scheme_nodata)?;
    if region.landcover_vectors.is_empty() {
        return Ok((codes, how));
    }
    use crate::region::Resampling;
    let mode = region.resampling != Resampling::Nearest;
    let report = burn(&region.landcover_vectors, frame, grid, mode, &mut codes)?;
    if let Some(nd) = scheme_nodata {
        for c in codes.iter_mut() {
            if *c == Some(nd) {
                *c = None;
            }
        }
    }
    let how = match (how, mode) {
        ("uniform", true) | ("none", true) => "polygons: mode of 4 × 4 samples",
        ("uniform", false) | ("none", false) => "polygons: cell centre",
        (_, true) => "raster and polygons: mode",
        (_, false) => "raster and polygons: nearest",
    };
    tracing::info!(
        "land cover: {} of {} cells from polygons ({} × {} samples per cell)",
        report.cells_from_polygons,
        codes.len(),
        report.oversampling,
        report.oversampling
    );
    Ok((codes, how))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_class_beneath_counts_its_uncovered_samples() {
        let mut v = Vec::new();
        // 6 samples of polygon class 3, 4 of polygon class 5, 6 in no polygon over raster 5:
        // class 5 has 10 votes.
        let mut s = vec![3; 6];
        s.extend([5; 4]);
        s.extend([NONE; 6]);
        assert_eq!(cell_class(&s, Some(5), &mut v), Some(5));
        // Over raster 7 the uncovered samples (6) tie with class 3 (6): the polygon wins.
        assert_eq!(cell_class(&s, Some(7), &mut v), Some(3));
        // Mostly uncovered: the raster's class stays.
        let s = [NONE, NONE, NONE, 4];
        assert_eq!(cell_class(&s, Some(1), &mut v), None);
        // Polygon tie: the smaller code.
        assert_eq!(cell_class(&[9, 9, 2, 2], None, &mut v), Some(2));
    }

    #[test]
    fn oversampling_shrinks_for_huge_grids() {
        let g = |w, h| Grid {
            x0: 0.0,
            y0: 0.0,
            dx: 1.0,
            width: w,
            height: h,
        };
        assert_eq!(oversampling(&g(100, 100), true), 4);
        assert_eq!(oversampling(&g(100, 100), false), 1);
        assert_eq!(oversampling(&g(4096, 4096), true), 2);
        assert_eq!(oversampling(&g(10000, 10000), true), 1);
    }
}
