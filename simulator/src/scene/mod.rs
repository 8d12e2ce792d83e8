//! 3D scenes: geometry (terrain BVH here, instanced objects in `instances`), materials, the
//! assembled [`Scene`] and its builders (bundle, canopy).
//!
//! Precision: the bundle stores each terrain tile in f32 relative to an f64 tile origin. The
//! BVH (obvhs, f32) is built in a *render frame* whose origin is the bundle's local-frame origin
//! (0, 0, 0) shifted to the centre of the terrain's bounding box, so that over a 100 km scene f32
//! coordinates stay below ~5·10⁴ m (≈ 4 mm resolution). Rays are given in the bundle's local
//! frame in f64 and converted once; hit distances are refined in f64 against the hit triangle
//! (computed from the f64 tile origin + f32 offsets), so the returned point is accurate to
//! rounding of the stored vertices.

pub mod area_mask;
pub mod build;
pub mod curvature;
pub mod instances;
pub mod material;
pub mod texture;
pub mod world;

pub use world::{Scene, SurfaceHit};

use glam::{DVec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::ray::{Ray, RayHit};
use obvhs::triangle::Triangle;
use obvhs::{bvh2::builder::build_bvh2, bvh2::Bvh2, BvhBuildParams};

use bundle::Bundle;

/// A hit on the terrain.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TerrainHit {
    /// Distance along the (unit) ray direction, m.
    pub t: f64,
    /// Tile index and triangle index within the tile.
    pub tile: usize,
    pub triangle: usize,
    /// Geometric normal (unit, facing the ray origin's side).
    pub normal: DVec3,
}

/// All terrain triangles of a bundle under one BVH.
pub struct TerrainBvh {
    bvh: Bvh2,
    tris: Vec<Triangle>,
    /// (tile, triangle) of each entry of `tris`.
    ids: Vec<(u32, u32)>,
    /// Render-frame origin in the bundle's local frame, m.
    render_origin: DVec3,
    /// f64 vertices of each triangle in the local frame (every hit is decided with them).
    verts: Vec<[DVec3; 3]>,
    /// Bounding box of the terrain (local frame), padded, for clipping rays in f64.
    lo: DVec3,
    hi: DVec3,
}

impl TerrainBvh {
    /// The bundle's terrain, bent onto a sphere when `bend` is given ([`curvature`]).
    pub fn new(bundle: &Bundle, bend: Option<curvature::Curvature>) -> Self {
        Self::from_tiles_bent(&bundle.terrain, bend)
    }

    /// Build from terrain tiles (f32 offsets from f64 origins).
    pub fn from_tiles(terrain: &[bundle::TerrainTile]) -> Self {
        Self::from_tiles_bent(terrain, None)
    }

    /// Build from terrain tiles, every vertex bent onto a sphere (in f64) when `bend` is given.
    pub fn from_tiles_bent(
        terrain: &[bundle::TerrainTile],
        bend: Option<curvature::Curvature>,
    ) -> Self {
        let place = |q: DVec3| bend.map_or(q, |c| c.bend(q));
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for t in terrain {
            let o = DVec3::from_array(t.origin);
            for p in &t.positions {
                let q = place(o + DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64));
                lo = lo.min(q);
                hi = hi.max(q);
            }
        }
        let render_origin = if lo.x.is_finite() {
            0.5 * (lo + hi)
        } else {
            DVec3::ZERO
        };
        let (mut tris, mut ids, mut verts) = (Vec::new(), Vec::new(), Vec::new());
        for (it, t) in terrain.iter().enumerate() {
            let o = DVec3::from_array(t.origin);
            let v = |i: u32| {
                let p = t.positions[i as usize];
                place(o + DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64))
            };
            for (k, tri) in t.indices.iter().enumerate() {
                let w = [v(tri[0]), v(tri[1]), v(tri[2])];
                let r = |q: DVec3| Vec3A::from((q - render_origin).as_vec3());
                tris.push(Triangle {
                    v0: r(w[0]),
                    v1: r(w[1]),
                    v2: r(w[2]),
                });
                ids.push((it as u32, k as u32));
                verts.push(w);
            }
        }
        // Boxes padded beyond the f32 rounding of the render frame, so that the f32 traversal
        // never drops a triangle the f64 test would hit (hits are decided in f64 below).
        let size = if lo.x.is_finite() {
            (hi - lo).max_element()
        } else {
            0.0
        };
        let pad = (1e-3 + 1e-6 * size) as f32;
        let boxes: Vec<Aabb> = tris
            .iter()
            .map(|t| {
                Aabb::new(
                    t.v0.min(t.v1).min(t.v2) - Vec3A::splat(pad),
                    t.v0.max(t.v1).max(t.v2) + Vec3A::splat(pad),
                )
            })
            .collect();
        let bvh = build_bvh2(
            &boxes,
            BvhBuildParams::medium_build(),
            &mut std::time::Duration::default(),
        );
        let padv = DVec3::splat(1.0 + 1e-5 * size);
        Self {
            bvh,
            tris,
            ids,
            render_origin,
            verts,
            lo: if lo.x.is_finite() {
                lo - padv
            } else {
                DVec3::ZERO
            },
            hi: if lo.x.is_finite() {
                hi + padv
            } else {
                DVec3::ZERO
            },
        }
    }

    pub fn triangle_count(&self) -> usize {
        self.tris.len()
    }

    /// The terrain's bounding box (local frame, padded by about a metre).
    pub fn bounds(&self) -> (DVec3, DVec3) {
        (self.lo, self.hi)
    }

    /// The render-frame origin (centre of the terrain's bounding box, local frame).
    pub fn render_origin(&self) -> DVec3 {
        self.render_origin
    }

    /// Approximate memory of triangles, f64 copies, ids and BVH nodes, bytes.
    pub fn memory_bytes(&self) -> usize {
        self.tris.len()
            * (std::mem::size_of::<Triangle>()
                + std::mem::size_of::<[DVec3; 3]>()
                + std::mem::size_of::<(u32, u32)>())
            + self.bvh.nodes.len() * std::mem::size_of_val(&self.bvh.nodes[0])
            + self.bvh.primitive_indices.len() * 4
    }

    /// Closest terrain hit of the ray `origin + t·dir` (local frame, `dir` unit), `t > 0`.
    ///
    /// The ray is first clipped in f64 to the terrain's (padded) bounding box and its origin moved
    /// there, so the f32 traversal works with coordinates of the scene's size even for rays
    /// starting 100 km away; the traversal only proposes candidates (boxes padded beyond f32
    /// rounding) and every candidate triangle is decided by an f64 Möller–Trumbore test against
    /// the f64 vertices, so no ray slips between two triangles because of f32 rounding.
    pub fn intersect(&self, origin: DVec3, dir: DVec3) -> Option<TerrainHit> {
        if self.tris.is_empty() {
            return None;
        }
        // Slab test in f64.
        let inv = DVec3::ONE / dir;
        let ta = (self.lo - origin) * inv;
        let tb = (self.hi - origin) * inv;
        let tnear = ta.min(tb);
        let tfar = ta.max(tb);
        let pick = |a: f64, b: f64| if a.is_nan() { b } else { a };
        let t0 = pick(tnear.x, f64::NEG_INFINITY)
            .max(pick(tnear.y, f64::NEG_INFINITY))
            .max(pick(tnear.z, f64::NEG_INFINITY))
            .max(0.0);
        let t1 = pick(tfar.x, f64::INFINITY)
            .min(pick(tfar.y, f64::INFINITY))
            .min(pick(tfar.z, f64::INFINITY));
        if t1 < t0 {
            return None;
        }
        let o2 = origin + dir * t0;
        let o = Vec3A::from((o2 - self.render_origin).as_vec3());
        let ray = Ray::new(o, Vec3A::from(dir.as_vec3()), 0.0, f32::INFINITY);
        let mut hit = RayHit::none();
        let mut best = (f64::INFINITY, usize::MAX);
        self.bvh.ray_traverse(ray, &mut hit, |_, id| {
            let prim = self.bvh.primitive_indices[id] as usize;
            match moller_trumbore(o2, dir, &self.verts[prim]) {
                Some(t) if t > 0.0 => {
                    // Candidates are tested in f64; the traversal's f32 bound is a
                    // conservative copy (rounded up) of the f64 best.
                    if t < best.0 {
                        best = (t, prim);
                    }
                    (t as f32).max(f32::MIN_POSITIVE) * (1.0 + 4.0 * f32::EPSILON)
                }
                _ => f32::INFINITY,
            }
        });
        if best.1 == usize::MAX {
            return None;
        }
        let prim = best.1;
        let [a, b, c] = self.verts[prim];
        let mut n = (b - a).cross(c - a).normalize();
        if n.dot(dir) > 0.0 {
            n = -n;
        }
        let (tile, triangle) = self.ids[prim];
        Some(TerrainHit {
            t: t0 + best.0,
            tile: tile as usize,
            triangle: triangle as usize,
            normal: n,
        })
    }
}

/// Ray–triangle distance in f64 (Möller & Trumbore 1997), two-sided; `None` for a miss or a
/// ray parallel to the triangle.
#[inline]
fn moller_trumbore(o: DVec3, d: DVec3, v: &[DVec3; 3]) -> Option<f64> {
    let e1 = v[1] - v[0];
    let e2 = v[2] - v[0];
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-300 {
        return None;
    }
    // A margin of 1e-12 in barycentric coordinates (≈ 1e-10 m on a 100 m triangle) closes
    // the rounding gaps along shared edges: a ray through an edge hits both neighbours (at the
    // same distance) instead of possibly neither.
    const EPS: f64 = 1e-12;
    let inv = 1.0 / det;
    let s = o - v[0];
    let u = s.dot(p) * inv;
    if !(-EPS..=1.0 + EPS).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let w = d.dot(q) * inv;
    if w < -EPS || u + w > 1.0 + EPS {
        return None;
    }
    Some(e2.dot(q) * inv)
}

#[cfg(test)]
mod tests {
    use super::*;
    use bundle::TerrainTile;

    /// A bundle with a tilted plane z = 300 + 0.1·x + 0.05·y made of two tiles far from the origin
    /// (x ≈ 40 km), each tile a grid of triangles in f32 offsets from its f64 origin.
    fn plane_bundle() -> Vec<TerrainTile> {
        let h = |x: f64, y: f64| 300.0 + 0.1 * x + 0.05 * y;
        let mut tiles = Vec::new();
        for (k, x0) in [40_000.0, 41_000.0].into_iter().enumerate() {
            let origin = [x0, -500.0, 300.0];
            let n = 10;
            let step = 100.0;
            let mut positions = Vec::new();
            for j in 0..=n {
                for i in 0..=n {
                    let (x, y) = (x0 + i as f64 * step, -500.0 + j as f64 * step);
                    positions.push([
                        (x - origin[0]) as f32,
                        (y - origin[1]) as f32,
                        (h(x, y) - origin[2]) as f32,
                    ]);
                }
            }
            let mut indices = Vec::new();
            for j in 0..n {
                for i in 0..n {
                    let a = (j * (n + 1) + i) as u32;
                    let (b, c, d) = (a + 1, a + (n + 1) as u32, a + (n + 2) as u32);
                    indices.push([a, b, d]);
                    indices.push([a, d, c]);
                }
            }
            tiles.push(TerrainTile {
                id: [k as u32, 0],
                origin,
                uvs: vec![[0.0, 0.0]; positions.len()],
                positions,
                indices,
            });
        }
        tiles
    }

    /// The BVH agrees with a brute-force f64 Möller–Trumbore search over every triangle (same
    /// closest triangle, same distance to 1 mm) for random rays, including grazing ones.
    #[test]
    fn bvh_equals_brute_force() {
        let terrain = plane_bundle();
        let bvh = TerrainBvh::from_tiles(&terrain);
        let brute = |o: DVec3, d: DVec3| -> Option<f64> {
            let mut best: Option<f64> = None;
            for t in &terrain {
                let org = DVec3::from_array(t.origin);
                let v = |i: u32| {
                    org + DVec3::new(
                        t.positions[i as usize][0] as f64,
                        t.positions[i as usize][1] as f64,
                        t.positions[i as usize][2] as f64,
                    )
                };
                for tri in &t.indices {
                    let (a, b, c) = (v(tri[0]), v(tri[1]), v(tri[2]));
                    let (e1, e2) = (b - a, c - a);
                    let p = d.cross(e2);
                    let det = e1.dot(p);
                    if det.abs() < 1e-12 {
                        continue;
                    }
                    let s = o - a;
                    let u = s.dot(p) / det;
                    let q = s.cross(e1);
                    let w = d.dot(q) / det;
                    let tt = e2.dot(q) / det;
                    if u >= 0.0
                        && w >= 0.0
                        && u + w <= 1.0
                        && tt > 0.0
                        && best.is_none_or(|b| tt < b)
                    {
                        best = Some(tt);
                    }
                }
            }
            best
        };
        let mut rng = crate::rng::Stream::new(6, [0, 0, 0, 0]);
        let mut n_hits = 0;
        for _ in 0..300 {
            let o = DVec3::new(
                39_800.0 + 2_400.0 * rng.next_f64(),
                -700.0 + 1_400.0 * rng.next_f64(),
                4_500.0 + 3_000.0 * rng.next_f64(),
            );
            let d = crate::frame::direction_from_angles(
                std::f64::consts::FRAC_PI_2 + 1.4 * rng.next_f64(),
                std::f64::consts::TAU * rng.next_f64(),
            );
            match (bvh.intersect(o, d), brute(o, d)) {
                (Some(h), Some(t)) => {
                    assert!((h.t - t).abs() < 1e-3, "{} vs {t}", h.t);
                    n_hits += 1;
                }
                (None, None) => {}
                (a, b) => panic!("BVH {a:?} vs brute force {b:?}"),
            }
        }
        assert!(n_hits > 50, "{n_hits}");
    }

    /// Vertical and oblique rays hit the plane where the analytic plane says, to millimetres,
    /// 40 km from the frame origin; rays beside the terrain miss; the normal faces the ray.
    #[test]
    fn rays_hit_a_far_plane_exactly() {
        let terrain = plane_bundle();
        let bvh = TerrainBvh::from_tiles(&terrain);
        assert_eq!(bvh.triangle_count(), 400);
        let h = |x: f64, y: f64| 300.0 + 0.1 * x + 0.05 * y;
        let mut rng = crate::rng::Stream::new(5, [0, 0, 0, 0]);
        let mut hits = 0;
        for _ in 0..2000 {
            let (x, y) = (
                40_010.0 + 1_980.0 * rng.next_f64(),
                -490.0 + 980.0 * rng.next_f64(),
            );
            let dir = crate::frame::direction_from_angles(
                std::f64::consts::PI - 0.6 * rng.next_f64(),
                std::f64::consts::TAU * rng.next_f64(),
            );
            // Start 2 km above the target point, back along the ray.
            let target = DVec3::new(x, y, h(x, y));
            let origin = target - dir * (2000.0 / -dir.z);
            // The target point lies on the terrain, so the ray must hit it (or terrain before it).
            let hit = bvh
                .intersect(origin, dir)
                .expect("a ray aimed at the terrain hits it");
            hits += 1;
            let p = origin + dir * hit.t;
            assert!(
                (p.z - h(p.x, p.y)).abs() < 2e-3,
                "off the plane by {}",
                p.z - h(p.x, p.y)
            );
            assert!(hit.normal.dot(dir) < 0.0);
        }
        assert_eq!(hits, 2000);
        // Straight down onto every tile centre: always a hit at the right height.
        for x in [40_500.0, 41_500.0] {
            let hit = bvh
                .intersect(DVec3::new(x, 10.0, 5_000.0), -DVec3::Z)
                .unwrap();
            assert!((5_000.0 - hit.t - h(x, 10.0)).abs() < 1e-3);
        }
        assert!(bvh
            .intersect(DVec3::new(10_000.0, 0.0, 5_000.0), -DVec3::Z)
            .is_none());
        assert!(bvh
            .intersect(DVec3::new(40_500.0, 0.0, 5_000.0), DVec3::Z)
            .is_none());
    }
}
