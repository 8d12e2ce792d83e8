//! The terrain of a bundle: all its triangles under one 8-wide compressed BVH.
//!
//! **Structure.** obvhs 0.4's CWBVH (compressed wide BVH, 8 children per node with boxes
//! quantized to 8 bits against the parent, traversed with SSE: Ylitie, Karras & Laine 2017,
//! "Efficient incoherent ray traversal on GPUs through compressed wide BVHs"), built by PLOC
//! with reinsertion (`BvhBuildParams::medium_build`) over the triangles' padded boxes, at most
//! three triangles per leaf. The triangles are stored in leaf order, so a leaf slot indexes
//! them directly.
//!
//! **Precision.** The bundle stores each tile in f32 relative to an f64 tile origin. The BVH is
//! built in an f32 *render frame* whose origin is the centre of the terrain's bounding box, so
//! over a 100 km scene f32 coordinates stay below ~7·10⁴ m (≈ 4 mm resolution). A ray (local
//! frame, f64) is first clipped in f64 to the terrain's padded box and its origin moved there,
//! so the f32 traversal works with coordinates of the scene's size even for rays starting
//! 100 km away. The traversal only *proposes* candidates; each is decided in f64:
//! 1. node boxes: every triangle box is padded by `1 mm + 10⁻⁶ × the terrain's size` (about
//!    4 cm on a 40 km scene), more than the f32 rounding of the ray, so the f32 traversal never
//!    drops a triangle the f64 ray meets. Direction components below 2.4·10⁻⁷ are set to zero
//!    in the f32 ray (obvhs replaces the inverse of a tiny component by ±1/ε, which would shrink
//!    the slab of a near-vertical ray); the ray then drifts from the f64 one by at most
//!    2.4·10⁻⁷ × its length in the box, within the pad.
//! 2. an f32 Möller–Trumbore *prefilter* with a barycentric margin: `max(10⁻², δ / h)` where
//!    `h` is the triangle's smallest altitude and `δ = 1 mm + 5·10⁻⁷ × (largest render
//!    coordinate + diagonal)` bounds the f32 errors of the ray and of the test in metres
//!    (a sliver triangle gets a wide margin, never a false miss);
//! 3. the exact test: f64 Möller–Trumbore on the f64 vertices (tile origin + f32 offset) with a
//!    10⁻¹² barycentric margin that closes the rounding gaps along shared edges.
//!
//! The returned distance is the f64 one; the traversal's f32 bound is a copy rounded up.
//! `simulator/tests/scene3d.rs::terrain_is_watertight_for_distant_rays` (300 000 rays from
//! 100 km, a third exactly on edges) and the brute-force comparisons below hold it.
//!
//! **Memory per triangle**: the f32 prefilter record (40 B), the f64 vertices (72 B), the
//! (tile, triangle) id (8 B) and about 1/3 of a CWBVH node (80 B per node).

use glam::{DVec3, Vec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::cwbvh::{builder::build_cwbvh, CwBvh};
use obvhs::ray::{Ray, RayHit};
use obvhs::BvhBuildParams;

use super::{clip, curvature};
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

/// The f32 prefilter of one triangle (render frame): a vertex, two edges and the barycentric
/// margin.
#[derive(Clone, Copy, Debug)]
struct Tri32 {
    a: Vec3,
    e1: Vec3,
    e2: Vec3,
    margin: f32,
}

impl Tri32 {
    /// Whether the f32 ray `o + t d` may meet the triangle (barycentric test with the margin;
    /// the distance is left to the f64 test).
    #[inline(always)]
    fn may_hit(&self, o: Vec3A, d: Vec3A) -> bool {
        let e1 = Vec3A::from(self.e1);
        let e2 = Vec3A::from(self.e2);
        let p = d.cross(e2);
        let det = e1.dot(p);
        // A ray in the triangle's plane (or a degenerate triangle): let f64 decide.
        if det.abs() < 1e-20 {
            return true;
        }
        let inv = 1.0 / det;
        let s = o - Vec3A::from(self.a);
        let u = s.dot(p) * inv;
        let m = self.margin;
        if !(u >= -m && u <= 1.0 + m) {
            return !(u.is_finite());
        }
        let v = d.dot(s.cross(e1)) * inv;
        (v >= -m && u + v <= 1.0 + m) || !v.is_finite()
    }
}

/// A ray clipped to the terrain box ([`TerrainBvh::clipped`]): the clip start `t0` and the
/// f64 start `o2` there, the f32 start and direction, the f64 segment `(lo, hi)` from the clip
/// start, and obvhs' traversal ray.
struct Clipped {
    t0: f64,
    o2: DVec3,
    o: Vec3A,
    d: Vec3A,
    lo: f64,
    hi: f64,
    ray: Ray,
}

/// All terrain triangles of a bundle under one CWBVH.
pub struct TerrainBvh {
    bvh: CwBvh,
    /// Prefilter records, in leaf order.
    tris: Vec<Tri32>,
    /// f64 vertices of each triangle in the local frame (every hit is decided with them), in
    /// leaf order.
    verts: Vec<[DVec3; 3]>,
    /// (tile, triangle) of each triangle, in leaf order.
    ids: Vec<(u32, u32)>,
    /// Render-frame origin in the bundle's local frame, m.
    render_origin: DVec3,
    /// Bounding box of the terrain (local frame), padded, for clipping rays in f64.
    lo: DVec3,
    hi: DVec3,
    /// Box padding (m), also the lower bound of the f32 traversal interval.
    pad: f32,
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
        let mut verts = Vec::with_capacity(terrain.iter().map(|t| t.indices.len()).sum());
        let mut ids = Vec::with_capacity(verts.capacity());
        for (it, t) in terrain.iter().enumerate() {
            let o = DVec3::from_array(t.origin);
            let v = |i: u32| {
                let p = t.positions[i as usize];
                place(o + DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64))
            };
            for (k, tri) in t.indices.iter().enumerate() {
                let w = [v(tri[0]), v(tri[1]), v(tri[2])];
                for q in w {
                    lo = lo.min(q);
                    hi = hi.max(q);
                }
                verts.push(w);
                ids.push((it as u32, k as u32));
            }
        }
        if verts.is_empty() {
            return Self {
                bvh: CwBvh::default(),
                tris: Vec::new(),
                verts,
                ids,
                render_origin: DVec3::ZERO,
                lo: DVec3::ZERO,
                hi: DVec3::ZERO,
                pad: 0.0,
            };
        }
        let render_origin = 0.5 * (lo + hi);
        let size = (hi - lo).max_element();
        let diagonal = (hi - lo).length();
        let reach = (hi - render_origin).abs().max((lo - render_origin).abs());
        // Box padding and the prefilter's error bound (module header).
        let pad = (1e-3 + 1e-6 * size) as f32;
        let delta = 1e-3 + 5e-7 * (reach.max_element() + diagonal);
        let r = |q: DVec3| (q - render_origin).as_vec3();
        let boxes: Vec<Aabb> = verts
            .iter()
            .map(|w| {
                let (a, b, c) = (r(w[0]), r(w[1]), r(w[2]));
                Aabb::new(
                    Vec3A::from(a.min(b).min(c)) - Vec3A::splat(pad),
                    Vec3A::from(a.max(b).max(c)) + Vec3A::splat(pad),
                )
            })
            .collect();
        let mut bvh = cached_cwbvh(&boxes, super::bvh_cache::dir());
        tracing::debug!(
            "terrain CWBVH: {} triangles, {} nodes, {} levels",
            boxes.len(),
            bvh.nodes.len(),
            super::cwbvh_depth(&bvh)
        );
        drop(boxes);
        // Leaf order: slot k of the BVH is triangle primitive_indices[k].
        let order = std::mem::take(&mut bvh.primitive_indices);
        let verts: Vec<[DVec3; 3]> = order.iter().map(|&i| verts[i as usize]).collect();
        let ids: Vec<(u32, u32)> = order.iter().map(|&i| ids[i as usize]).collect();
        bvh.primitive_indices = (0..order.len() as u32).collect();
        let tris = verts
            .iter()
            .map(|w| {
                let (e1, e2) = (w[1] - w[0], w[2] - w[0]);
                let longest = e1.length().max(e2.length()).max((w[2] - w[1]).length());
                let h = e1.cross(e2).length() / longest.max(f64::MIN_POSITIVE);
                let margin = (delta / h).max(1e-2);
                Tri32 {
                    a: r(w[0]),
                    e1: e1.as_vec3(),
                    e2: e2.as_vec3(),
                    margin: if margin.is_finite() {
                        margin as f32
                    } else {
                        f32::INFINITY
                    },
                }
            })
            .collect();
        let padv = DVec3::splat(1.0 + 1e-5 * size);
        Self {
            bvh,
            tris,
            verts,
            ids,
            render_origin,
            lo: lo - padv,
            hi: hi + padv,
            pad,
        }
    }

    /// The f64 box of each triangle (local frame).
    pub fn triangle_boxes(&self) -> impl Iterator<Item = (DVec3, DVec3)> + '_ {
        self.verts
            .iter()
            .map(|[a, b, c]| (a.min(*b).min(*c), a.max(*b).max(*c)))
    }

    pub fn triangle_count(&self) -> usize {
        self.verts.len()
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
        self.verts.len()
            * (std::mem::size_of::<Tri32>()
                + std::mem::size_of::<[DVec3; 3]>()
                + std::mem::size_of::<(u32, u32)>()
                + 4)
            + self.bvh.nodes.len() * std::mem::size_of::<obvhs::cwbvh::node::CwBvhNode>()
    }

    /// Closest terrain hit of the ray `origin + t·dir` (local frame, `dir` unit), `t > 0`.
    pub fn intersect(&self, origin: DVec3, dir: DVec3) -> Option<TerrainHit> {
        self.intersect_within(origin, dir, f64::INFINITY)
    }

    /// Closest terrain hit with `0 < t < tmax`.
    pub fn intersect_within(&self, origin: DVec3, dir: DVec3, tmax: f64) -> Option<TerrainHit> {
        let (t0, k, t) = self.trace::<false>(origin, dir, tmax)?;
        let [a, b, c] = self.verts[k];
        let mut n = (b - a).cross(c - a).normalize();
        if n.dot(dir) > 0.0 {
            n = -n;
        }
        let (tile, triangle) = self.ids[k];
        Some(TerrainHit {
            t: t0 + t,
            tile: tile as usize,
            triangle: triangle as usize,
            normal: n,
        })
    }

    /// Whether the terrain blocks `origin + t·dir` for `0 < t < tmax` (any-hit traversal that
    /// stops at the first hit found).
    pub fn occluded(&self, origin: DVec3, dir: DVec3, tmax: f64) -> bool {
        self.trace::<true>(origin, dir, tmax).is_some()
    }

    /// The ray `origin + t·dir`, `0 < t < tmax`, clipped in f64 to the padded terrain box, and
    /// its f32 traversal ray from the clip start.
    #[inline(always)]
    fn clipped(&self, origin: DVec3, dir: DVec3, tmax: f64) -> Option<Clipped> {
        let (t0, t1) = clip(origin, dir, self.lo, self.hi, 0.0, tmax)?;
        let o2 = origin + dir * t0;
        let o = Vec3A::from((o2 - self.render_origin).as_vec3());
        let snap = |x: f32| if x.abs() < 2.0 * f32::EPSILON { 0.0 } else { x };
        let d32 = dir.as_vec3();
        let d = Vec3A::new(snap(d32.x), snap(d32.y), snap(d32.z));
        // The f64 segment is (−t0, t1 − t0) from the clip start (t > 0 in the caller's frame).
        let (lo, hi) = (-t0, t1 - t0);
        let ray = Ray::new(o, d, -self.pad, up(hi) + self.pad);
        Some(Clipped {
            t0,
            o2,
            o,
            d,
            lo,
            hi,
            ray,
        })
    }

    /// The traversal: (clip start `t0`, leaf slot, `t` from the clip start) of the closest hit
    /// (with `ANY`, of the first hit found).
    #[inline]
    fn trace<const ANY: bool>(
        &self,
        origin: DVec3,
        dir: DVec3,
        tmax: f64,
    ) -> Option<(f64, usize, f64)> {
        if self.verts.is_empty() || !origin.is_finite() || !dir.is_finite() || tmax.is_nan() {
            return None;
        }
        let Clipped {
            t0,
            o2,
            o,
            d,
            lo,
            hi,
            ray,
        } = self.clipped(origin, dir, tmax)?;
        let mut best = (hi, usize::MAX);
        let test = |id: usize, best_t: f64| -> Option<f64> {
            if !self.tris[id].may_hit(o, d) {
                return None;
            }
            moller_trumbore(o2, dir, &self.verts[id]).filter(|&t| t > lo && t < best_t)
        };
        if ANY {
            let miss = self.bvh.ray_traverse_miss(ray, |_, id| match test(id, hi) {
                Some(t) => {
                    best = (t, id);
                    0.0
                }
                None => f32::INFINITY,
            });
            return (!miss).then_some((t0, best.1, best.0));
        }
        let mut hit = RayHit::none();
        self.bvh
            .ray_traverse(ray, &mut hit, |_, id| match test(id, best.0) {
                Some(t) => {
                    best = (t, id);
                    up(t)
                }
                None => f32::INFINITY,
            });
        (best.1 != usize::MAX).then_some((t0, best.1, best.0))
    }
}

/// The terrain's tree over `boxes`: obvhs' build (median splits if that is too deep for its
/// traversal), or the same tree from the disk cache (`bvh_cache.rs`) when `cache_dir` holds
/// one built from exactly these boxes by this build.
fn cached_cwbvh(boxes: &[Aabb], cache_dir: Option<std::path::PathBuf>) -> CwBvh {
    use super::bvh_cache::{self, Kind};
    let n = boxes.len();
    let cache = cache_dir
        .filter(|_| n >= bvh_cache::MIN_PRIMITIVES)
        .map(|dir| (dir, bvh_cache::key(Kind::Terrain, boxes)));
    if let Some((dir, key)) = &cache {
        // The slot order must be a permutation of the triangles.
        let valid = |c: &bvh_cache::Cached| {
            let mut seen = vec![false; n];
            c.first.len() == n
                && c.first
                    .iter()
                    .all(|&i| (i as usize) < n && !std::mem::replace(&mut seen[i as usize], true))
        };
        if let Some(c) = bvh_cache::load(dir, key).filter(valid) {
            tracing::debug!("terrain CWBVH read from the cache in {}", dir.display());
            return bvh_cache::Cached::tree(c.nodes, c.total_aabb, c.first);
        }
    }
    let mut params = BvhBuildParams::medium_build();
    params.max_prims_per_leaf = 3;
    let mut bvh = build_cwbvh(boxes, params, &mut std::time::Duration::default());
    let depth = super::cwbvh_depth(&bvh);
    if depth > super::CWBVH_MAX_DEPTH {
        // obvhs' traversal would silently drop subtrees: rebuild with median splits.
        tracing::warn!(
            "terrain BVH of {} triangles has {depth} levels; rebuilt with median splits",
            boxes.len()
        );
        bvh = balanced_cwbvh(boxes);
    }
    if let Some((dir, key)) = &cache {
        let view = bvh_cache::View {
            nodes: &bvh.nodes,
            total_aabb: bvh.total_aabb,
            first: &bvh.primitive_indices,
            second: &[],
            depth: super::cwbvh_depth(&bvh),
        };
        match bvh_cache::store(dir, key, &view) {
            Ok(()) => tracing::debug!("terrain CWBVH cached in {}", dir.display()),
            Err(e) => tracing::debug!("terrain CWBVH not cached: {e}"),
        }
    }
    bvh
}

/// A CWBVH over `boxes` from a binary tree split at the centroids' median (depth ⌈log₂ n⌉, so
/// at most 32 binary levels and fewer wide ones): the fallback for a PLOC tree too deep for
/// obvhs' traversal stack. The `primitive_indices` map leaf slots to input indices.
fn balanced_cwbvh(boxes: &[Aabb]) -> CwBvh {
    let params = super::sah::SahParams {
        max_leaf: 1,
        isect: 1.0,
        balanced: true,
    };
    let (nodes, order) = super::sah::build(&mut boxes.to_vec(), params);
    let bvh2 = obvhs::bvh2::Bvh2 {
        nodes,
        primitive_indices: order,
        ..Default::default()
    };
    obvhs::cwbvh::bvh2_to_cwbvh::bvh2_to_cwbvh(&bvh2, 3, true, false)
}

/// An f64 distance as an f32 bound that is never below it (and never below the smallest
/// positive f32, so a hit at the clip start still bounds the traversal).
#[inline(always)]
fn up(t: f64) -> f32 {
    if t.is_infinite() {
        return f32::INFINITY;
    }
    (t as f32).max(f32::MIN_POSITIVE) * (1.0 + 4.0 * f32::EPSILON)
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

    /// The terrain's tree read from the disk cache (`bvh_cache.rs`) is the tree obvhs builds,
    /// node for node and slot for slot; the first build writes it, the second reads it.
    #[test]
    fn cached_tree_equals_built() {
        let n = super::super::bvh_cache::MIN_PRIMITIVES + 77;
        let boxes = super::super::sah::tests::boxes(n, 23);
        let dir = std::env::temp_dir().join(format!("eosim-terrain-bvh-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let built = cached_cwbvh(&boxes, None);
        let first = cached_cwbvh(&boxes, Some(dir.clone()));
        assert_eq!(std::fs::read_dir(&dir).map_or(0, |d| d.count()), 1);
        let cached = cached_cwbvh(&boxes, Some(dir.clone()));
        for t in [&first, &cached] {
            assert!(t.nodes == built.nodes);
            assert_eq!(t.primitive_indices, built.primitive_indices);
            assert_eq!(t.total_aabb, built.total_aabb);
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// The median-split fallback tree is valid for obvhs (every node and triangle reached once,
    /// quantized boxes containing their contents) and shallow, and the PLOC tree of a terrain
    /// is within obvhs' traversal stack.
    #[test]
    fn balanced_fallback_is_valid_and_shallow() {
        let terrain = TerrainBvh::from_tiles(&plane_bundle());
        assert!(super::super::cwbvh_depth(&terrain.bvh) <= super::super::CWBVH_MAX_DEPTH);
        let boxes: Vec<Aabb> = terrain
            .triangle_boxes()
            .map(|(a, b)| Aabb::new(a.as_vec3a(), b.as_vec3a()))
            .collect();
        let tree = balanced_cwbvh(&boxes);
        let v = tree.validate(&boxes, false);
        let levels = super::super::cwbvh_depth(&tree);
        assert_eq!(levels, v.max_depth as usize + 1);
        // 400 triangles: ⌈log₂ 400⌉ = 9 binary levels, at most 9 wide ones.
        assert!(levels <= 9, "{levels} levels");
        let mut seen = tree.primitive_indices.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..boxes.len() as u32).collect::<Vec<_>>());
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

#[cfg(test)]
mod amac_probe {
    use super::super::interleave::{self, prefetch};
    use super::*;

    struct Lane {
        st: obvhs::cwbvh::Traversal,
        c: Clipped,
        dir: DVec3,
        best: (f64, usize),
        idx: usize,
    }

    impl TerrainBvh {
        /// One step of a lane: its primitive group's triangles, then the next node; true
        /// when done.
        #[inline(always)]
        fn step(&self, l: &mut Lane) -> bool {
            for id in interleave::primitives(&l.st) {
                if self.tris[id].may_hit(l.c.o, l.c.d) {
                    if let Some(t) = moller_trumbore(l.c.o2, l.dir, &self.verts[id])
                        .filter(|&t| t > l.c.lo && t < l.best.0)
                    {
                        l.best = (t, id);
                        l.c.ray.tmax = up(t);
                    }
                }
            }
            if interleave::visit(&self.bvh, &mut l.st, &l.c.ray) {
                return true;
            }
            if let Some(id) = interleave::primitives(&l.st).next() {
                prefetch(&self.tris[id]);
                prefetch(&self.verts[id]);
            }
            false
        }

        /// Closest hits (t, leaf slot) of `rays`, `k` traced at a time.
        pub(crate) fn closest_many(
            &self,
            rays: &[(DVec3, DVec3)],
            k: usize,
        ) -> Vec<Option<(f64, usize)>> {
            let mut out = vec![None; rays.len()];
            interleave::run(
                rays.len(),
                k,
                |idx| {
                    let (origin, dir) = rays[idx];
                    let c = self.clipped(origin, dir, f64::INFINITY)?;
                    Some(Lane {
                        st: self.bvh.new_traversal(c.d),
                        best: (c.hi, usize::MAX),
                        c,
                        dir,
                        idx,
                    })
                },
                |l| self.step(l),
                |l| {
                    if l.best.1 != usize::MAX {
                        out[l.idx] = Some((l.c.t0 + l.best.0, l.best.1));
                    }
                },
            );
            out
        }
    }

    #[test]
    #[ignore]
    fn amac_probe_grenoble() {
        let b = Bundle::open(std::path::Path::new("../out/grenoble")).unwrap();
        let t = TerrainBvh::new(&b, None);
        let (lo, hi) = t.bounds();
        let mut rng = crate::rng::Stream::new(1, [0, 0, 0, 0]);
        let top = hi.z + 100.0;
        let rays: Vec<(DVec3, DVec3)> = (0..1_000_000)
            .map(|_| {
                let o = DVec3::new(
                    lo.x + (hi.x - lo.x) * rng.next_f64(),
                    lo.y + (hi.y - lo.y) * rng.next_f64(),
                    top,
                );
                let zen = std::f64::consts::PI - 30f64.to_radians() * rng.next_f64().sqrt();
                let d = crate::frame::direction_from_angles(
                    zen,
                    std::f64::consts::TAU * rng.next_f64(),
                );
                (o, d)
            })
            .collect();
        for _ in 0..2 {
            let s = std::time::Instant::now();
            let a: Vec<_> = rays
                .iter()
                .map(|&(o, d)| t.intersect(o, d).map(|h| h.t))
                .collect();
            let ta = s.elapsed().as_secs_f64();
            println!("sequential: {:.3e} rays/s", rays.len() as f64 / ta);
            for k in [1, 4, 8, 16, 32] {
                let s = std::time::Instant::now();
                let b2 = t.closest_many(&rays, k);
                let tb = s.elapsed().as_secs_f64();
                let same = a
                    .iter()
                    .zip(&b2)
                    .filter(|(x, y)| x.map(|v| v.to_bits()) == y.map(|v| v.0.to_bits()))
                    .count();
                println!(
                    "interleaved k={k}: {:.3e} rays/s, same hits {same}/{}",
                    rays.len() as f64 / tb,
                    rays.len()
                );
            }
        }
    }
}
