//! Error-bounded terrain triangulation (a TIN) of the DEM node grid with `spade`, and its split
//! into tiles.
//!
//! Greedy insertion (Garland & Heckbert 1995, "Fast polygonal approximation of terrains and
//! height fields", CMU-CS-95-181), in rounds: start from the four corners of the grid; in each
//! round, every triangle not yet known to fit scans the DEM samples it covers and reports its
//! worst one; all worst samples off by more than the tolerance are inserted (sorted along a
//! Z-order curve, so that spade's point location walks short distances) and the Delaunay
//! triangulation updates. Only triangles created in the last round are scanned: insertion creates
//! triangles around the new vertex only, and an older triangle that did not fit was destroyed by
//! the insertion of its own worst sample, so every older survivor is known to fit.
//! The loop ends when no triangle has a sample off by more than the tolerance, so **every DEM
//! sample lies within the tolerance of the surface** (this is what the tests check). Inserting
//! one point per triangle per round, instead of the single worst point overall, may add a few
//! more vertices than the sequential greedy method; it parallelises the scans (rayon).
//!
//! Vertices are DEM nodes, handled in integer grid coordinates (column, row counted from the
//! south), so spade's predicates work on exact values. Flat areas get few triangles, rough
//! ones many.
//!
//! Tiles: square tiles of `tile_size` metres on the grid; each triangle belongs to the tile of
//! its centroid, so the tiles partition one global mesh and share their seam vertices.
//! Positions are stored relative to the tile origin (a grid node), exact in f32 (see
//! `raster.rs` on the 1/64 m spacing), so seams are bit-exact in world coordinates.

use std::collections::HashSet;

use rayon::prelude::*;
use spade::{DelaunayTriangulation, FloatTriangulation, HasPosition, Point2, Triangulation};

use crate::raster::Grid;

/// A TIN vertex: grid column and row from the south, and height in metres.
#[derive(Clone, Copy, Debug)]
pub struct Node {
    pub pos: Point2<f64>,
    pub h: f64,
}

impl HasPosition for Node {
    type Scalar = f64;
    fn position(&self) -> Point2<f64> {
        self.pos
    }
}

pub type Tin = DelaunayTriangulation<Node>;

/// Heights of the node grid, addressed by (column, row from the south).
pub struct HeightField<'a> {
    pub width: usize,
    pub height: usize,
    /// Row-major, row 0 at the north (GDAL order).
    pub h: &'a [f32],
}

impl HeightField<'_> {
    #[inline]
    pub fn at(&self, i: usize, j_south: usize) -> f64 {
        self.h[(self.height - 1 - j_south) * self.width + i] as f64
    }
}

/// Worst sample of the triangle (a, b, c) in grid coordinates: (error, i, j) with error =
/// |DEM − plane|, or None if the triangle covers no sample other than its corners.
fn worst_in_triangle(f: &HeightField, p: [[f64; 3]; 3]) -> Option<(f64, u32, u32)> {
    let [a, b, c] = p;
    let det = (b[1] - c[1]) * (a[0] - c[0]) + (c[0] - b[0]) * (a[1] - c[1]);
    if det == 0.0 {
        return None;
    }
    let inv = 1.0 / det;
    let i0 = a[0].min(b[0]).min(c[0]) as usize;
    let i1 = a[0].max(b[0]).max(c[0]) as usize;
    let j0 = a[1].min(b[1]).min(c[1]) as usize;
    let j1 = a[1].max(b[1]).max(c[1]) as usize;
    let mut best: Option<(f64, u32, u32)> = None;
    let eps = 1e-9;
    for j in j0..=j1 {
        let y = j as f64;
        for i in i0..=i1 {
            let x = i as f64;
            let l1 = ((b[1] - c[1]) * (x - c[0]) + (c[0] - b[0]) * (y - c[1])) * inv;
            let l2 = ((c[1] - a[1]) * (x - c[0]) + (a[0] - c[0]) * (y - c[1])) * inv;
            let l3 = 1.0 - l1 - l2;
            if l1 < -eps || l2 < -eps || l3 < -eps {
                continue;
            }
            let z = l1 * a[2] + l2 * b[2] + l3 * c[2];
            let e = (f.at(i, j) - z).abs();
            if best.is_none_or(|(be, _, _)| e > be) {
                best = Some((e, i as u32, j as u32));
            }
        }
    }
    best
}

fn morton(i: u32, j: u32) -> u64 {
    fn spread(mut v: u64) -> u64 {
        v &= 0xFFFF_FFFF;
        v = (v | (v << 16)) & 0x0000_FFFF_0000_FFFF;
        v = (v | (v << 8)) & 0x00FF_00FF_00FF_00FF;
        v = (v | (v << 4)) & 0x0F0F_0F0F_0F0F_0F0F;
        v = (v | (v << 2)) & 0x3333_3333_3333_3333;
        v = (v | (v << 1)) & 0x5555_5555_5555_5555;
        v
    }
    spread(i as u64) | (spread(j as u64) << 1)
}

/// Build the error-bounded TIN of `f` with vertical `tolerance` (metres). `progress` is told
/// the current vertex count after each round.
pub fn build_tin(f: &HeightField, tolerance: f64, mut progress: impl FnMut(usize, usize)) -> Tin {
    let mut tin = Tin::new();
    let (w, h) = (f.width as u32 - 1, f.height as u32 - 1);
    for (i, j) in [(0, 0), (w, 0), (w, h), (0, h)] {
        tin.insert(Node {
            pos: Point2::new(i as f64, j as f64),
            h: f.at(i as usize, j as usize),
        })
        .expect("finite corner");
    }
    // Faces to scan: at first all; then only faces incident to a vertex inserted in the last
    // round. Incremental Delaunay insertion only creates faces around the new vertex, and an
    // older face that did not fit had its worst sample inserted inside it (destroying it), so
    // every surviving older face is known to fit.
    let mut fresh: Vec<spade::handles::FixedVertexHandle> = Vec::new();
    let mut round = 0;
    loop {
        round += 1;
        let mut keys: HashSet<[u32; 3]> = HashSet::new();
        let mut faces: Vec<[[f64; 3]; 3]> = Vec::new();
        let mut take =
            |face: spade::handles::FaceHandle<'_, spade::handles::InnerTag, Node, (), (), ()>| {
                let v = face.vertices();
                let mut key = v.map(|v| v.fix().index() as u32);
                key.sort_unstable();
                if keys.insert(key) {
                    faces.push(v.map(|v| [v.position().x, v.position().y, v.data().h]));
                }
            };
        if round == 1 {
            tin.inner_faces().for_each(&mut take);
        } else {
            for &vh in &fresh {
                for e in tin.vertex(vh).out_edges() {
                    if let Some(f) = e.face().as_inner() {
                        take(f);
                    }
                }
            }
        }
        let results: Vec<Option<(f64, u32, u32)>> =
            faces.par_iter().map(|p| worst_in_triangle(f, *p)).collect();
        let mut inserts: Vec<(u32, u32)> = results
            .into_iter()
            .flatten()
            .filter(|(e, _, _)| *e > tolerance)
            .map(|(_, i, j)| (i, j))
            .collect();
        if inserts.is_empty() {
            break;
        }
        inserts.sort_unstable_by_key(|&(i, j)| morton(i, j));
        inserts.dedup();
        fresh.clear();
        for (i, j) in inserts {
            fresh.push(
                tin.insert(Node {
                    pos: Point2::new(i as f64, j as f64),
                    h: f.at(i as usize, j as usize),
                })
                .expect("finite vertex"),
            );
        }
        progress(round, tin.num_vertices());
    }
    tracing::debug!("TIN: {round} rounds, {} vertices", tin.num_vertices());
    tin
}

/// Terrain tiles of the TIN: (tile id [col, row from the south], origin node (i, j), world
/// origin, positions, uvs, indices).
pub struct TileMesh {
    pub id: [u32; 2],
    pub origin: [f64; 3],
    pub positions: Vec<[f32; 3]>,
    pub uvs: Vec<[f32; 2]>,
    pub indices: Vec<[u32; 3]>,
}

/// Split the TIN into tiles of `tile_nodes` grid steps. `grid` maps grid coordinates to the
/// working CRS; `frame_origin` is subtracted from tile origins (the bundle's local frame);
/// `uv_of(x, y)` maps working-CRS coordinates to material-raster texture coordinates.
pub fn split_tiles(
    tin: &Tin,
    grid: &Grid,
    tile_nodes: u32,
    frame_origin: [f64; 3],
    uv_of: impl Fn(f64, f64) -> [f32; 2] + Sync,
) -> Vec<TileMesh> {
    let ntx = ((grid.width as u32 - 1).div_ceil(tile_nodes)).max(1);
    let nty = ((grid.height as u32 - 1).div_ceil(tile_nodes)).max(1);
    let nverts = tin.num_vertices();
    let ybottom = grid.y(grid.height - 1);
    // Triangles per tile, counter-clockwise seen from above (spade's inner faces are).
    let mut per_tile: Vec<Vec<[u32; 3]>> = vec![Vec::new(); (ntx * nty) as usize];
    for face in tin.inner_faces() {
        let v = face.vertices();
        let cx = (v[0].position().x + v[1].position().x + v[2].position().x) / 3.0;
        let cy = (v[0].position().y + v[1].position().y + v[2].position().y) / 3.0;
        let tx = ((cx / tile_nodes as f64) as u32).min(ntx - 1);
        let ty = ((cy / tile_nodes as f64) as u32).min(nty - 1);
        per_tile[(ty * ntx + tx) as usize].push(v.map(|v| v.fix().index() as u32));
    }
    let verts: Vec<Node> = tin.vertices().map(|v| *v.data()).collect();
    per_tile
        .into_par_iter()
        .enumerate()
        .filter(|(_, tris)| !tris.is_empty())
        .map(|(k, tris)| {
            let (tx, ty) = (k as u32 % ntx, k as u32 / ntx);
            let (oi, oj) = (tx * tile_nodes, ty * tile_nodes);
            let ox = grid.x0 + oi as f64 * grid.dx;
            let oy = ybottom + oj as f64 * grid.dx;
            let mut map = std::collections::HashMap::with_capacity(tris.len());
            let mut positions = Vec::new();
            let mut uvs = Vec::new();
            let mut indices = Vec::with_capacity(tris.len());
            for t in tris {
                let mut out = [0u32; 3];
                for (s, &g) in t.iter().enumerate() {
                    out[s] = *map.entry(g).or_insert_with(|| {
                        let n = verts[g as usize];
                        let (i, j) = (n.pos.x, n.pos.y);
                        // Exact: (i − oi)·dx with dx a multiple of 1/64 m.
                        positions.push([
                            ((i - oi as f64) * grid.dx) as f32,
                            ((j - oj as f64) * grid.dx) as f32,
                            n.h as f32,
                        ]);
                        uvs.push(uv_of(grid.x0 + i * grid.dx, ybottom + j * grid.dx));
                        (positions.len() - 1) as u32
                    });
                }
                indices.push(out);
            }
            debug_assert!(positions.len() <= nverts);
            TileMesh {
                id: [tx, ty],
                origin: [
                    ox - frame_origin[0],
                    oy - frame_origin[1],
                    0.0 - frame_origin[2],
                ],
                positions,
                uvs,
                indices,
            }
        })
        .collect()
}

/// Height of the TIN surface at working-CRS (x, y), for placing instances. One per thread
/// (spade's interpolator keeps a scratch buffer).
pub struct SurfaceHeight<'a> {
    interp: spade::Barycentric<'a, Tin>,
    grid: Grid,
    ybottom: f64,
}

impl<'a> SurfaceHeight<'a> {
    pub fn new(tin: &'a Tin, grid: &Grid) -> Self {
        SurfaceHeight {
            interp: tin.barycentric(),
            grid: *grid,
            ybottom: grid.y(grid.height - 1),
        }
    }
    pub fn at(&self, x: f64, y: f64) -> Option<f64> {
        let p = Point2::new(
            (x - self.grid.x0) / self.grid.dx,
            (y - self.ybottom) / self.grid.dx,
        );
        self.interp.interpolate(|v| v.data().h, p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn field(w: usize, h: usize, f: impl Fn(f64, f64) -> f64) -> Vec<f32> {
        let mut v = vec![0f32; w * h];
        for r in 0..h {
            for c in 0..w {
                v[r * w + c] = f(c as f64, (h - 1 - r) as f64) as f32;
            }
        }
        v
    }

    /// Rationale: the defining property — every DEM sample within the tolerance of the TIN —
    /// checked with spade's own point location (an independent path from the scan).
    #[test]
    fn every_sample_is_within_tolerance() {
        let (w, h) = (97, 81);
        let hv = field(w, h, |x, y| {
            50.0 * (x / 9.0).sin() * (y / 13.0).cos()
                + 0.02 * x * y
                + if x > 60.0 { 30.0 } else { 0.0 }
        });
        let f = HeightField {
            width: w,
            height: h,
            h: &hv,
        };
        for tol in [0.5, 2.0] {
            let tin = build_tin(&f, tol, |_, _| {});
            let interp = tin.barycentric();
            let mut worst = 0.0f64;
            for j in 0..h {
                for i in 0..w {
                    let z = interp
                        .interpolate(|v| v.data().h, Point2::new(i as f64, j as f64))
                        .unwrap();
                    worst = worst.max((z - f.at(i, j)).abs());
                }
            }
            assert!(worst <= tol + 1e-9, "tolerance {tol}: worst {worst}");
            assert!(tin.num_vertices() < w * h, "fewer vertices than samples");
        }
    }

    /// Rationale: a plane needs no vertex beyond the corners, a rough surface many: the TIN
    /// adapts to the terrain.
    #[test]
    fn flat_terrain_gets_two_triangles() {
        let (w, h) = (64, 64);
        let hv = field(w, h, |x, y| 100.0 + 0.5 * x - 0.25 * y);
        let tin = build_tin(
            &HeightField {
                width: w,
                height: h,
                h: &hv,
            },
            0.1,
            |_, _| {},
        );
        assert_eq!(tin.num_inner_faces(), 2);
    }
}
