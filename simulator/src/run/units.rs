//! Work units: what one shard computes and one checkpoint holds (docs/scaling.md).
//!
//! A unit is a (wavelength group, measure) task, or a pixel tile of one: a contiguous range of
//! an image measure's pixels (row-major cell indices). Every sample of every pixel draws its
//! random numbers from a stream keyed by (seed, wavelength or group, measure, pixel, sample
//! index) only (`rng.rs`, `run.rs`), and a pixel's block sums merge in block order whatever
//! else runs, so a tile's pixels hold exactly the sums the unsplit run gives them; assembling
//! the tiles copies those sums into a fresh accumulator (`0 + x = x` in IEEE arithmetic, and
//! sums that start at +0 are never −0): merged runs are bit-identical to the unsplit run.
//!
//! Only image measures **without** `target_rel_stderr` are tiled: the stopping rule of an
//! image is the median error over all its pixels, which a tile cannot see, so a measure with a
//! target stays one unit and its rounds are decided exactly as in the unsplit run. Forward
//! walks serve every direction of a measure at once and are never tiled either.
//!
//! Tiling depends only on the experiment and the shard count N: with U (group, measure)
//! tasks, each tileable image is cut into `N / gcd(N, U)` tiles (at most one per pixel), so
//! that when every task is an image the unit count is a multiple of N. Unit k runs in shard
//! k mod N; units are ordered group-major, then measure, then tile.

use std::ops::Range;

use super::{method_for, wavelength_groups, MeasureResult, Method};
use engine::config::resolve::Experiment;

/// One work unit.
#[derive(Clone, Debug, PartialEq)]
pub struct Unit {
    /// Wavelength indices (one, or a spectral ALIS group).
    pub group: Vec<usize>,
    /// Measure index.
    pub measure: usize,
    /// Tile index, from 0.
    pub tile: usize,
    /// Tiles of this measure (1: the whole measure).
    pub tiles: usize,
    /// The measure's cells this unit computes.
    pub cells: Range<usize>,
}

/// Whether measure `im` may be cut into pixel tiles (see the module header).
pub fn tileable(exp: &Experiment, im: usize) -> bool {
    let m = &exp.measures[im];
    m.is_image() && m.target_rel_stderr.is_none() && method_for(exp, m) != Method::Forward
}

fn gcd(a: usize, b: usize) -> usize {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

/// Tiles per tileable image measure for a run split into `shards` (1 for an unsplit run).
pub fn tiles_per_image(exp: &Experiment, shards: usize) -> usize {
    let tasks = wavelength_groups(exp).len() * exp.measures.len();
    if shards <= 1 || tasks == 0 {
        return 1;
    }
    shards / gcd(shards, tasks)
}

/// Cells `[t·C/T, (t+1)·C/T)` of `C` cells cut into `T` tiles.
pub fn tile_cells(cells: usize, tile: usize, tiles: usize) -> Range<usize> {
    let at = |t: usize| ((t as u128 * cells as u128) / tiles as u128) as usize;
    at(tile)..at(tile + 1)
}

/// Every unit of a run split into `shards`, in order (unit k runs in shard k mod `shards`).
pub fn units(exp: &Experiment, shards: usize) -> Vec<Unit> {
    let t = tiles_per_image(exp, shards);
    let mut out = Vec::new();
    for group in wavelength_groups(exp) {
        for (im, m) in exp.measures.iter().enumerate() {
            let cells = m.cell_count();
            let tiles = if tileable(exp, im) {
                t.min(cells).max(1)
            } else {
                1
            };
            for tile in 0..tiles {
                out.push(Unit {
                    group: group.clone(),
                    measure: im,
                    tile,
                    tiles,
                    cells: if tiles == 1 {
                        0..cells
                    } else {
                        tile_cells(cells, tile, tiles)
                    },
                });
            }
        }
    }
    out
}

/// The units of shard `shard` of `shards`.
pub fn shard_units(exp: &Experiment, shard: usize, shards: usize) -> Vec<Unit> {
    units(exp, shards)
        .into_iter()
        .enumerate()
        .filter(|(k, _)| k % shards == shard)
        .map(|(_, u)| u)
        .collect()
}

/// One (wavelength, measure) result from its tiles (`parts`: tile results of that pair, any
/// order, each with its cell range); `None` unless the tiles cover every cell exactly once.
pub fn assemble(
    exp: &Experiment,
    mut parts: Vec<(Range<usize>, MeasureResult)>,
) -> Option<MeasureResult> {
    if parts.len() == 1 && parts[0].0.start == 0 {
        let (range, r) = parts.pop()?;
        return (range.end == exp.measures[r.measure].cell_count()).then_some(r);
    }
    parts.sort_by_key(|(r, _)| r.start);
    let first = &parts.first()?.1;
    let cells = exp.measures[first.measure].cell_count();
    let mut next = 0;
    for (r, p) in &parts {
        if r.start != next || p.acc.n.len() != r.len() {
            return None;
        }
        next = r.end;
    }
    if next != cells {
        return None;
    }
    let mut acc = if first.acc.ncomp == 6 {
        engine::accum::Accum::new_polarized(cells)
    } else {
        engine::accum::Accum::new(cells)
    };
    for (r, p) in &parts {
        for (local, cell) in r.clone().enumerate() {
            acc.merge_cell(cell, &p.acc, local);
        }
    }
    Some(MeasureResult {
        measure: first.measure,
        wavelength: first.wavelength,
        method: first.method,
        acc,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_cover_every_cell_once() {
        for cells in [1usize, 7, 100, 1001] {
            for tiles in 1..=9.min(cells) {
                let mut next = 0;
                for t in 0..tiles {
                    let r = tile_cells(cells, t, tiles);
                    assert_eq!(r.start, next);
                    assert!(!r.is_empty());
                    next = r.end;
                }
                assert_eq!(next, cells);
            }
        }
    }

    #[test]
    fn gcd_sizes_tiles_to_a_multiple_of_the_shards() {
        assert_eq!(gcd(4, 3), 1);
        assert_eq!(4 / gcd(4, 3), 4); // 3 tasks × 4 tiles = 12 units over 4 shards
        assert_eq!(6 / gcd(6, 3), 2);
        assert_eq!(3 / gcd(3, 3), 1);
    }
}
