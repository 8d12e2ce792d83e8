//! Instanced geometry (template meshes and disc clouds placed many times) under a two-level BVH.
//!
//! **What.** Each template's geometry (a triangle mesh, or a cloud of analytic discs: the leaves
//! of RAMI canopies) is stored once, in template coordinates, under its own bottom-level BVH
//! (BLAS). An instance is a template placed by `p_world = translation + linear · p_template`
//! (`linear` any invertible 3×3: rotation × scale, shear allowed). A top-level BVH (TLAS) is
//! built over the world bounding boxes of the instances. A ray is tested against an instance by
//! taking it into template space with the precomputed inverse of `linear`; the direction is
//! *not* normalised there, so the hit parameter `t` is the same in both spaces (the world
//! distance for a unit world direction). This is the classic instancing scheme (PBRT 4th ed.,
//! §7.1.4 "Object instancing"; the two-level acceleration structures of Embree/OptiX).
//!
//! * BLAS: built by obvhs 0.4 ([`BvhBuildParams::medium_build`]: PLOC + reinsertion + leaf
//!   collapse to ≤ 8 primitives) over the primitives' boxes, primitives reordered to leaf order.
//! * Instance boxes: the exact world box of the transformed template box, intersected with the
//!   union of the transformed boxes of a 16-node cut of the BLAS (tighter for rotated instances).
//! * TLAS: our own top-down binned-SAH build (16 bins) into *clusters* of at most 3 instances
//!   (the binary leaves). On the 1M-instance forest of the tests the binned SAH is as fast to
//!   build as obvhs' `medium_build` (≈ 1 s) but its trees need about 3× fewer node visits per
//!   ray (≈ 28 vs 91 node pairs; obvhs' reinsertion closes the gap only with 10–20 s of build).
//!   The binary tree is then converted by obvhs to its 8-wide compressed CWBVH (80-byte nodes,
//!   boxes quantized to 8 bits, children ordered by ray octant; Ylitie, Karras & Laine 2017),
//!   one cluster per CWBVH leaf, and traversed by obvhs' SSE traversal. On the Grenoble bundle
//!   (1.27 M instances in 545 k clusters) the wide top level has 9 levels where the binary one
//!   had 22, and 136 k nodes (10.9 MB) where the binary one had 422 k pairs (27 MB), and random
//!   primary rays run 15 % faster (BENCHMARKS.md). Converting with one instance per leaf would
//!   make the tree another 15 % faster but triples the conversion's working memory (the binary
//!   nodes and obvhs' cost table, 7 entries per binary node): the render's set-up peak RSS rose
//!   from 293 to 454 MiB. obvhs' traversal stack holds 31 levels and silently overwrites its
//!   top beyond that, so a deeper tree (only pathological inputs) is rebuilt with median splits
//!   (`scene::cwbvh_depth`).
//! * BLAS nodes are converted to a 64-byte *pair* layout (the two children of a node, boxes as
//!   struct-of-arrays, in one cache line; depth-first order) and traversed by our own stack
//!   traversal: stack in a fixed-size array (heap only for trees deeper than 128 levels), near
//!   child first, leaves tested as soon as reached, early exit at the first hit for
//!   [`InstanceBvh::occluded`]. No allocation per ray and no dynamic dispatch (primitive kinds
//!   are monomorphised, the template kind is a `match`).
//!
//! **Precision.** World coordinates can lie 50 km or more from the frame origin while leaves are
//! millimetres wide, so f32 is used only where its errors are bounded by the geometry's own
//! size, and every hit is decided in f64:
//! * TLAS: boxes are in the f32 *render frame* (world − `render_origin`). The ray is first
//!   clipped in f64 against the (padded) world box and its origin moved to the clip start, so
//!   f32 coordinates stay within the scene. Direction components below 2.4·10⁻⁷ are set to
//!   zero in the f32 ray (obvhs replaces the inverse of a tiny component by ±1/ε, which would
//!   shrink the slab; as for the terrain). Instance boxes are padded by
//!   `10⁻⁶ · (max |render coordinate| + world diagonal) + 1 mm` (≈ 20 cm for a ±50 km scene;
//!   at least 1 mm because obvhs' box test ignores the ray's `tmin` and culls every box that the
//!   ray leaves within 10⁻⁴ m of its f32 origin: geometry lies `pad` inside its box, so a hit at
//!   `t ≥ 0` always leaves its box later than that),
//!   which bounds the f32 rounding of the ray's origin and direction over the scene, the drift
//!   of the snapped direction and the rounding of obvhs' (unwidened) slab tests; the CWBVH's
//!   quantized boxes only grow them. So the TLAS is conservative (it may propose an instance
//!   the ray misses, never drops one it hits).
//! * Instance: per candidate instance the ray origin is first moved, in f64, to the ray's point
//!   of closest approach to the instance's translation (`s = (T − o)·d`), then
//!   `o_t = L⁻¹ (o + s d − T)` and `d_t = L⁻¹ d` are computed in f64 (and rounded to f32 for the
//!   BLAS traversal), so the template-space ray has coordinates of the template's size whatever
//!   the distance to the origin; `t = s + t'`.
//! * BLAS: f32 traversal and f32 primitive tests with widened tolerances (node boxes padded by
//!   10⁻⁵ × the template's size, barycentric margin 10⁻², disc radius + 10⁻⁵ × the template's
//!   size) act as a conservative prefilter; every candidate is then decided **in f64** in
//!   template space (Möller–Trumbore for triangles, ray–plane then `|p − c| ≤ r` for discs,
//!   vertices converted exactly from f32) against the f64 interval `(tmin, t_best)`. So `tmin`
//!   and `tmax` are honoured exactly (in f64) at the primitive level, they also cull at both BVH
//!   levels, and the returned `t` is the f64 refinement (accurate to the rounding of the f32
//!   inverse linear part applied to template-sized vectors: sub-µm for metre-sized objects, at
//!   any distance from the origin).
//!
//! **Memory layout per instance** (instances whose template has no primitives cost nothing):
//! a 64-byte record — translation `[f64; 3]` (24 B), column-major inverse linear part
//! `[f32; 9]` (36 B), template id `u32` (4 B) — stored in TLAS leaf order, plus a `u32` original
//! instance id (4 B), plus the TLAS's cluster starts (4 B per cluster, about one per 2.5
//! instances) and CWBVH nodes (80 B each, about one per 12 instances): ≈ 76 B per instance in
//! all on the 1M-instance test scene (see [`InstanceBvh::memory_bytes`]). Per template primitive (in BLAS leaf order): a triangle is
//! its three f32 vertices (36 B) or a disc its centre, unit normal and radius (28 B), plus a
//! `u32` original primitive id and a `u16` material, plus the BLAS node pairs.
//!
//! **Normals.** [`InstanceHit::normal`] is the unit *geometric* normal in the world frame,
//! `normalize(L⁻ᵀ n_template)` (correct under non-uniform scale and shear), turned to face the
//! ray origin (`normal · dir < 0`). Triangles and discs are two-sided: both faces are hit.

use glam::{DMat3, DVec3, Mat3, Vec3, Vec3A, Vec4, Vec4Swizzles};
use obvhs::aabb::Aabb;
use obvhs::bvh2::builder::build_bvh2;
use obvhs::bvh2::node::Bvh2Node;
use obvhs::cwbvh::node::CwBvhNode;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::{Ray, RayHit};
use obvhs::BvhBuildParams;

use super::error::SceneError;
use super::sah::SahParams;
use std::path::PathBuf;

use super::clip;

/// A disc (thin leaf): centre, unit normal, radius, in template coordinates (m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Disc {
    pub centre: [f32; 3],
    pub normal: [f32; 3],
    pub radius: f32,
}

/// The geometry of one template, stored once whatever the number of instances.
#[derive(Clone, Debug, PartialEq)]
pub enum TemplateGeometry {
    /// Triangle mesh with one material id per triangle.
    Triangles {
        positions: Vec<[f32; 3]>,
        indices: Vec<[u32; 3]>,
        materials: Vec<u16>,
    },
    /// Analytic discs with one material id per disc (RAMI canopies are made of discs).
    Discs {
        discs: Vec<Disc>,
        materials: Vec<u16>,
    },
}

impl TemplateGeometry {
    /// The triangles of a bundle template (materials widened to `u16`).
    pub fn from_mesh(mesh: &bundle::TemplateMesh) -> Self {
        TemplateGeometry::Triangles {
            positions: mesh.positions.clone(),
            indices: mesh.indices.clone(),
            materials: mesh.materials.iter().map(|&m| m as u16).collect(),
        }
    }

    /// Number of primitives (triangles or discs).
    pub fn primitive_count(&self) -> usize {
        match self {
            TemplateGeometry::Triangles { indices, .. } => indices.len(),
            TemplateGeometry::Discs { discs, .. } => discs.len(),
        }
    }
}

/// Placement of one instance: `p_world = translation + linear · p_template`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InstanceTransform {
    pub translation: DVec3,
    pub linear: Mat3,
}

impl InstanceTransform {
    /// (template id, transform) of a bundle instance (`linear` is column-major there too).
    pub fn from_bundle(inst: &bundle::Instance) -> (u32, Self) {
        (
            inst.template,
            InstanceTransform {
                translation: DVec3::from_array(inst.translation),
                linear: Mat3::from_cols_array(&inst.linear),
            },
        )
    }
}

/// A hit on an instance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InstanceHit {
    /// Ray parameter of the hit (the distance for a unit direction), m.
    pub t: f64,
    /// Unit geometric normal in the world frame, facing the ray origin (`normal · dir < 0`).
    pub normal: DVec3,
    /// Material id of the primitive.
    pub material: u16,
    /// Index of the instance in the list given to [`InstanceBvh::new`].
    pub instance: u32,
    /// Index of the triangle or disc within its template.
    pub primitive: u32,
    /// Whether the ray meets the primitive's front face (the side its template normal — a
    /// triangle's winding, a disc's normal — points to).
    pub front: bool,
}

/// Per-instance record, in TLAS leaf order (64 bytes).
#[derive(Clone, Copy, Debug)]
#[repr(C)]
struct InstanceRecord {
    translation: [f64; 3],
    /// Inverse of the linear part, column-major.
    linv: [f32; 9],
    template: u32,
}

const _: () = assert!(std::mem::size_of::<InstanceRecord>() == 64);

/// Stack size kept on the machine stack; deeper trees use a heap stack (allocated per ray).
const INLINE_STACK: usize = 128;
/// Barycentric margin of the f32 triangle prefilter.
const BARY_MARGIN: f32 = 1e-2;
/// Relative expansion of the f32 slab test (PBRT's robust bound 1 + 2γ₃, rounded up).
const SLAB_ROBUST: f32 = 4e-7;
/// TLAS clusters (binary leaves, one per CWBVH leaf): at most this many instances, and the cost
/// of an instance test relative to a node visit used by the SAH.
const TLAS_MAX_LEAF: usize = 3;
const TLAS_INSTANCE_COST: f32 = 0.25;
/// Deepest binary SAH tree handed to obvhs' (recursive) CWBVH conversion; deeper ones are
/// rebuilt with median splits.
const TLAS_BINARY_DEPTH: usize = 256;

/// A ray in f32 for the BVH and prefilter tests.
#[derive(Clone, Copy)]
struct RayF {
    o: Vec3A,
    d: Vec3A,
    /// Origin and inverse direction, each component splatted (for [`Pair`] tests).
    ox: Vec4,
    oy: Vec4,
    oz: Vec4,
    ix: Vec4,
    iy: Vec4,
    iz: Vec4,
}

impl RayF {
    #[inline(always)]
    fn new(o: Vec3A, d: Vec3A) -> Self {
        // A zero component gets a tiny stand-in so that 0·∞ (NaN) never happens in the slabs;
        // overflows to ±∞ are harmless (see `slab2`).
        let nz = |x: f32| if x == 0.0 { 1e-30 } else { x };
        RayF {
            o,
            d,
            ox: Vec4::splat(o.x),
            oy: Vec4::splat(o.y),
            oz: Vec4::splat(o.z),
            ix: Vec4::splat(1.0 / nz(d.x)),
            iy: Vec4::splat(1.0 / nz(d.y)),
            iz: Vec4::splat(1.0 / nz(d.z)),
        }
    }

    /// Entry parameters of the two boxes of a pair clipped to `[lo, hi]`, +∞ for a miss.
    /// `hi` must be finite.
    #[inline(always)]
    fn slab2(&self, p: &Pair, lo: f32, hi: f32) -> (f32, f32) {
        // Lanes: [a.min, b.min, a.max, b.max] per axis; the swizzle pairs min with max.
        let tx = (p.x - self.ox) * self.ix;
        let ty = (p.y - self.oy) * self.iy;
        let tz = (p.z - self.oz) * self.iz;
        let (sx, sy, sz) = (tx.zwxy(), ty.zwxy(), tz.zwxy());
        let near = tx.min(sx).max(ty.min(sy)).max(tz.min(sz));
        let far = tx.max(sx).min(ty.max(sy)).min(tz.max(sz));
        // Robust widening by a relative 1 ± ε, written so that ±∞ stays ±∞ (never NaN).
        let (up, down) = (
            Vec4::splat(1.0 + SLAB_ROBUST),
            Vec4::splat(1.0 - SLAB_ROBUST),
        );
        let near = (near * up).min(near * down).max(Vec4::splat(lo));
        let far = (far * up).max(far * down).min(Vec4::splat(hi));
        let m = near.cmple(far).bitmask();
        (
            if m & 1 != 0 { near.x } else { f32::INFINITY },
            if m & 2 != 0 { near.y } else { f32::INFINITY },
        )
    }
}

/// Two sibling nodes in one cache line (64 B): their boxes, struct-of-arrays per axis as
/// `[a.min, b.min, a.max, b.max]`, and for each either a leaf (`count > 0` primitives from slot
/// `first`) or an inner node (`count == 0`, children in pair `first`). Pair 0 holds the root
/// (as `a`) and an empty box far away (as `b`, never within a finite `hi`).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct Pair {
    x: Vec4,
    y: Vec4,
    z: Vec4,
    first: [u32; 2],
    count: [u32; 2],
}

const _: () = assert!(std::mem::size_of::<Pair>() == 64);

impl Pair {
    fn new(a: (&Aabb, u32, u32), b: (&Aabb, u32, u32)) -> Self {
        let (ba, bb) = (a.0, b.0);
        Pair {
            x: Vec4::new(ba.min.x, bb.min.x, ba.max.x, bb.max.x),
            y: Vec4::new(ba.min.y, bb.min.y, ba.max.y, bb.max.y),
            z: Vec4::new(ba.min.z, bb.min.z, ba.max.z, bb.max.z),
            first: [a.1, b.1],
            count: [a.2, b.2],
        }
    }
}

/// A BVH in [`Pair`] layout (depth-first order) and its depth (edges root → deepest leaf).
struct Tree {
    pairs: Vec<Pair>,
    depth: usize,
}

/// A primitive of a BLAS: an f32 prefilter and an exact f64 test.
trait Primitive {
    /// Conservative f32 test: the hit parameter if the ray may hit (NaN otherwise). `eps` is a
    /// spatial margin in template units.
    fn hit32(&self, r: &RayF, eps: f32) -> f32;
    /// Exact f64 test: the hit parameter of the line `o + t d` (any sign of t).
    fn hit64(&self, o: DVec3, d: DVec3) -> Option<f64>;
    /// Geometric normal in template space (not normalised).
    fn normal64(&self) -> DVec3;
    /// f64 bounding box in template space.
    fn bounds64(&self) -> (DVec3, DVec3);
}

#[derive(Clone, Copy, Debug)]
struct Tri {
    a: Vec3,
    b: Vec3,
    c: Vec3,
}

#[inline(always)]
fn d3(v: Vec3) -> DVec3 {
    v.as_dvec3()
}

impl Primitive for Tri {
    #[inline(always)]
    fn hit32(&self, r: &RayF, _eps: f32) -> f32 {
        let a = Vec3A::from(self.a);
        let e1 = Vec3A::from(self.b) - a;
        let e2 = Vec3A::from(self.c) - a;
        let p = r.d.cross(e2);
        let det = e1.dot(p);
        if det == 0.0 {
            return f32::NAN;
        }
        let inv = 1.0 / det;
        let s = r.o - a;
        let u = s.dot(p) * inv;
        if !(-BARY_MARGIN..=1.0 + BARY_MARGIN).contains(&u) {
            return f32::NAN;
        }
        let q = s.cross(e1);
        let v = r.d.dot(q) * inv;
        if !(v >= -BARY_MARGIN && u + v <= 1.0 + BARY_MARGIN) {
            return f32::NAN;
        }
        e2.dot(q) * inv
    }

    #[inline]
    fn hit64(&self, o: DVec3, d: DVec3) -> Option<f64> {
        let a = d3(self.a);
        let e1 = d3(self.b) - a;
        let e2 = d3(self.c) - a;
        let p = d.cross(e2);
        let det = e1.dot(p);
        if det == 0.0 {
            return None;
        }
        let inv = 1.0 / det;
        let s = o - a;
        let u = s.dot(p) * inv;
        if !(0.0..=1.0).contains(&u) {
            return None;
        }
        let q = s.cross(e1);
        let v = d.dot(q) * inv;
        if v < 0.0 || u + v > 1.0 {
            return None;
        }
        Some(e2.dot(q) * inv)
    }

    fn normal64(&self) -> DVec3 {
        let a = d3(self.a);
        (d3(self.b) - a).cross(d3(self.c) - a)
    }

    fn bounds64(&self) -> (DVec3, DVec3) {
        let (a, b, c) = (d3(self.a), d3(self.b), d3(self.c));
        (a.min(b).min(c), a.max(b).max(c))
    }
}

#[derive(Clone, Copy, Debug)]
struct DiscPrim {
    c: Vec3,
    /// Unit normal (normalised in f64 at build, then rounded).
    n: Vec3,
    r: f32,
}

impl Primitive for DiscPrim {
    #[inline(always)]
    fn hit32(&self, r: &RayF, eps: f32) -> f32 {
        let n = Vec3A::from(self.n);
        let denom = r.d.dot(n);
        if denom == 0.0 {
            return f32::NAN;
        }
        let c = Vec3A::from(self.c);
        let t = (c - r.o).dot(n) / denom;
        let p = r.o + r.d * t - c;
        let rr = self.r + eps;
        if p.length_squared() <= rr * rr {
            t
        } else {
            f32::NAN
        }
    }

    #[inline]
    fn hit64(&self, o: DVec3, d: DVec3) -> Option<f64> {
        let n = d3(self.n);
        let denom = d.dot(n);
        if denom == 0.0 {
            return None;
        }
        let c = d3(self.c);
        let t = (c - o).dot(n) / denom;
        let p = o + d * t - c;
        let r = self.r as f64;
        (p.length_squared() <= r * r).then_some(t)
    }

    fn normal64(&self) -> DVec3 {
        d3(self.n)
    }

    fn bounds64(&self) -> (DVec3, DVec3) {
        // Normalised in f64 (the stored f32 normal is unit only to rounding, which matters
        // near n_i = ±1 where the half extent r·√(1 − n_i²) is ill-conditioned).
        let n = d3(self.n).normalize();
        let c = d3(self.c);
        let e = (DVec3::ONE - n * n).max(DVec3::ZERO).sqrt() * self.r as f64;
        (c - e, c + e)
    }
}

/// One bottom-level BVH with its primitives in leaf order.
struct Blas<P> {
    tree: Tree,
    prims: Vec<P>,
    /// Original primitive index of each slot.
    ids: Vec<u32>,
    /// Material of each slot.
    materials: Vec<u16>,
    /// Spatial margin (template units) of the f32 stage.
    eps: f32,
    /// f64 box of all primitives (template space); `None` if empty.
    bounds: Option<(DVec3, DVec3)>,
    /// (centre, half extent) of up to [`CUT_BOXES`] BLAS nodes covering all primitives: the
    /// world box of an instance is the union of these transformed, tighter than the
    /// transformed template box for rotated instances.
    cut: Vec<(DVec3, DVec3)>,
}

/// Number of BLAS boxes transformed to bound an instance.
const CUT_BOXES: usize = 16;

/// (centre, half extent) of the boxes of a cut of at most `k` nodes of the tree, covering
/// all its primitives: starting from the root, the inner node of largest area is replaced by
/// its children while there are fewer than `k` nodes.
fn tree_cut(tree: &Tree, k: usize) -> Vec<(DVec3, DVec3)> {
    if tree.pairs.is_empty() {
        return Vec::new();
    }
    let get = |(p, l): (usize, usize)| {
        let q = &tree.pairs[p];
        let lo = DVec3::new(q.x[l] as f64, q.y[l] as f64, q.z[l] as f64);
        let hi = DVec3::new(q.x[l + 2] as f64, q.y[l + 2] as f64, q.z[l + 2] as f64);
        (lo, hi, q.count[l] == 0, q.first[l] as usize)
    };
    let area = |(lo, hi): (DVec3, DVec3)| {
        let d = hi - lo;
        d.x * d.y + d.y * d.z + d.z * d.x
    };
    let mut cut = vec![(0usize, 0usize)];
    while cut.len() < k {
        let mut best: Option<(usize, f64)> = None;
        for (i, &n) in cut.iter().enumerate() {
            let (lo, hi, inner, _) = get(n);
            if inner && best.is_none_or(|(_, a)| area((lo, hi)) > a) {
                best = Some((i, area((lo, hi))));
            }
        }
        let Some((i, _)) = best else { break };
        let child = get(cut[i]).3;
        cut[i] = (child, 0);
        cut.push((child, 1));
    }
    cut.into_iter()
        .map(|n| {
            let (lo, hi, _, _) = get(n);
            (0.5 * (lo + hi), 0.5 * (hi - lo))
        })
        .collect()
}

/// Widen an f64 box by `pad` and round it to f32 outwards (by at least one ulp where the
/// conversion rounded inwards).
fn aabb_f32(lo: DVec3, hi: DVec3, pad: f64) -> Aabb {
    let ulp = |f: f32| f.abs() * f32::EPSILON + f32::MIN_POSITIVE;
    let down = |x: f64| {
        let f = x as f32;
        if f as f64 > x {
            f - ulp(f)
        } else {
            f
        }
    };
    let up = |x: f64| {
        let f = x as f32;
        if (f as f64) < x {
            f + ulp(f)
        } else {
            f
        }
    };
    let (lo, hi) = (lo - pad, hi + pad);
    Aabb::new(
        Vec3A::new(down(lo.x), down(lo.y), down(lo.z)),
        Vec3A::new(up(hi.x), up(hi.y), up(hi.z)),
    )
}

/// Build a BVH over boxes with obvhs and convert it to [`Pair`] layout; returns the tree and
/// the input index of each primitive slot (leaves index slots). Empty input → empty tree.
fn build_obvhs(aabbs: &[Aabb], params: BvhBuildParams) -> (Tree, Vec<u32>) {
    if aabbs.is_empty() {
        return (
            Tree {
                pairs: Vec::new(),
                depth: 0,
            },
            Vec::new(),
        );
    }
    let bvh = build_bvh2(aabbs, params, &mut std::time::Duration::default());
    (to_pairs(&bvh.nodes), bvh.primitive_indices)
}

/// Convert obvhs-layout nodes (root at 0, children of an inner node at `first_index` and
/// `first_index + 1`, leaves with `prim_count > 0`) to [`Pair`] layout, depth first.
fn to_pairs(nodes: &[Bvh2Node]) -> Tree {
    let info = |i: usize| (&nodes[i].aabb, nodes[i].first_index, nodes[i].prim_count);
    let far = Aabb::new(Vec3A::splat(f32::MAX), Vec3A::splat(f32::MAX));
    let mut pairs = Vec::with_capacity(nodes.len().div_ceil(2));
    pairs.push(Pair::new(info(0), (&far, 0, 1)));
    // Depth-first: (pair, lane, obvhs node, depth of that node) of inner nodes to expand.
    let mut depth = 0;
    let mut todo = vec![(0usize, 0usize, 0usize, 0usize)];
    while let Some((p, lane, i, d)) = todo.pop() {
        let n = &nodes[i];
        if n.is_leaf() {
            depth = depth.max(d);
            continue;
        }
        let c = n.first_index as usize;
        let k = pairs.len();
        pairs.push(Pair::new(info(c), info(c + 1)));
        pairs[p].first[lane] = k as u32;
        pairs[p].count[lane] = 0;
        todo.push((k, 1, c + 1, d + 1));
        todo.push((k, 0, c, d + 1));
    }
    pairs.shrink_to_fit();
    Tree { pairs, depth }
}

/// The TLAS: a binned-SAH binary tree over the instance boxes ([`super::sah`], leaves of
/// at most [`TLAS_MAX_LEAF`] instances) converted to obvhs' CWBVH with each binary leaf as one
/// *cluster* (a CWBVH leaf holds one cluster). Converting the leaves as clusters rather than one
/// instance per leaf keeps the conversion's working memory (the binary nodes and a cost table
/// of 7 entries per binary node) to about a third; the boxes are freed before it. A tree deeper
/// than obvhs' traversal stack allows ([`super::CWBVH_MAX_DEPTH`], only pathological inputs)
/// is rebuilt with median splits.
fn build_tlas(aabbs: Vec<Aabb>, cache_dir: Option<PathBuf>) -> Result<Tlas, SceneError> {
    use super::bvh_cache::{self, Kind};
    let n = aabbs.len();
    // A tree built before from exactly these boxes by this build (`bvh_cache.rs`); its
    // lists are the cluster starts (rising from 0 to the record count) and the slot order (a
    // permutation of the instances).
    let cache = cache_dir
        .filter(|_| n >= bvh_cache::MIN_PRIMITIVES)
        .map(|dir| (dir, bvh_cache::key(Kind::Instances, &aabbs)));
    if let Some((dir, key)) = &cache {
        let valid = |c: &bvh_cache::Cached| {
            let mut seen = vec![false; n];
            c.second.len() == n
                && c.first.first() == Some(&0)
                && c.first.last() == Some(&(n as u32))
                && c.first.windows(2).all(|w| w[0] <= w[1])
                && c.second
                    .iter()
                    .all(|&i| (i as usize) < n && !std::mem::replace(&mut seen[i as usize], true))
        };
        if let Some(c) = bvh_cache::load(dir, key).filter(valid) {
            tracing::debug!(
                "instance TLAS: {n} instances in {} clusters, {} CWBVH nodes, {} levels (cached in {})",
                c.first.len().saturating_sub(1),
                c.nodes.len(),
                c.depth,
                dir.display()
            );
            return Ok(Tlas {
                tree: bvh_cache::Cached::tree(c.nodes, c.total_aabb, Vec::new()),
                cluster_start: c.first,
                order: c.second,
                depth: c.depth,
            });
        }
    }
    let tlas = build_tlas_uncached(aabbs)?;
    if let Some((dir, key)) = &cache {
        let view = bvh_cache::View {
            nodes: &tlas.tree.nodes,
            total_aabb: tlas.tree.total_aabb,
            first: &tlas.cluster_start,
            second: &tlas.order,
            depth: tlas.depth,
        };
        match bvh_cache::store(dir, key, &view) {
            Ok(()) => tracing::debug!("instance TLAS cached in {}", dir.display()),
            Err(e) => tracing::debug!("instance TLAS not cached: {e}"),
        }
    }
    Ok(tlas)
}

/// [`build_tlas`] without the cache.
fn build_tlas_uncached(mut aabbs: Vec<Aabb>) -> Result<Tlas, SceneError> {
    let n = aabbs.len();
    let params = |balanced| SahParams {
        max_leaf: TLAS_MAX_LEAF,
        isect: TLAS_INSTANCE_COST,
        balanced,
    };
    // A rebuild starts from the boxes in the order the last build left them (`sah::build`):
    // its slots index that order, mapped back to the instances through the last build's.
    let rebuild = |aabbs: &mut Vec<Aabb>, idx: &[u32]| {
        let (nodes, again) = super::sah::build(aabbs, params(true));
        let idx: Vec<u32> = again.iter().map(|&k| idx[k as usize]).collect();
        (nodes, idx)
    };
    let (mut nodes, mut idx) = super::sah::build(&mut aabbs, params(false));
    // obvhs' conversion recurses over the binary tree: no very deep one.
    let mut binary_depth = super::sah::depth(&nodes);
    if binary_depth > TLAS_BINARY_DEPTH {
        (nodes, idx) = rebuild(&mut aabbs, &idx);
        binary_depth = super::sah::depth(&nodes);
    }
    super::release_free_memory();
    // A wide tree is never deeper than its binary one: keep the boxes (and their order) only
    // if a rebuild may be needed.
    let mut kept = (binary_depth > super::CWBVH_MAX_DEPTH).then(|| (aabbs, idx.clone()));
    let mut tlas = cluster_cwbvh(nodes, idx);
    if tlas.depth > super::CWBVH_MAX_DEPTH {
        if let Some((mut aabbs, idx)) = kept.take() {
            let (nodes, idx) = rebuild(&mut aabbs, &idx);
            drop(aabbs);
            tlas = cluster_cwbvh(nodes, idx);
        }
    }
    tracing::debug!(
        "instance TLAS: {n} instances in {} clusters, {} CWBVH nodes, {} levels",
        tlas.cluster_start.len().saturating_sub(1),
        tlas.tree.nodes.len(),
        tlas.depth
    );
    if tlas.depth > super::CWBVH_MAX_DEPTH {
        return Err(SceneError::TlasTooDeep {
            instances: n,
            depth: tlas.depth,
            max: super::CWBVH_MAX_DEPTH,
        });
    }
    Ok(tlas)
}

/// Convert a binary tree (leaves: ranges of `idx`) to the CWBVH of clusters.
fn cluster_cwbvh(mut nodes: Vec<Bvh2Node>, idx: Vec<u32>) -> Tlas {
    if nodes.is_empty() {
        return Tlas {
            tree: CwBvh::default(),
            cluster_start: Vec::new(),
            order: Vec::new(),
            depth: 0,
        };
    }
    let mut clusters = Vec::new();
    for n in nodes.iter_mut().filter(|n| n.is_leaf()) {
        clusters.push((n.first_index, n.prim_count));
        n.first_index = clusters.len() as u32 - 1;
        n.prim_count = 1;
    }
    let bvh2 = obvhs::bvh2::Bvh2 {
        primitive_indices: (0..clusters.len() as u32).collect(),
        nodes,
        ..Default::default()
    };
    let mut tree = obvhs::cwbvh::bvh2_to_cwbvh::bvh2_to_cwbvh(&bvh2, 1, true, false);
    drop(bvh2);
    let depth = super::cwbvh_depth(&tree);
    // Records in leaf order: cluster slot k holds records cluster_start[k]..[k + 1].
    let mut order = Vec::with_capacity(idx.len());
    let mut cluster_start = Vec::with_capacity(clusters.len() + 1);
    for &c in &tree.primitive_indices {
        let (first, count) = clusters[c as usize];
        cluster_start.push(order.len() as u32);
        order.extend_from_slice(&idx[first as usize..(first + count) as usize]);
    }
    cluster_start.push(order.len() as u32);
    tree.primitive_indices = Vec::new();
    Tlas {
        tree,
        cluster_start,
        order,
        depth,
    }
}

/// Reorder `v` so that slot k holds the old `v[order[k]]` (`order` a permutation of the
/// slots), in place: each cycle of the permutation is followed once (`order` marks the slots
/// done).
fn permute_in_place<T>(v: &mut [T], mut order: Vec<u32>) {
    assert_eq!(v.len(), order.len());
    for start in 0..v.len() {
        if order[start] == u32::MAX {
            continue;
        }
        // Slot j takes the item of slot order[j]: swap along the cycle.
        let mut j = start;
        loop {
            let k = order[j] as usize;
            order[j] = u32::MAX;
            if k == start {
                break;
            }
            v.swap(j, k);
            j = k;
        }
    }
}

/// A built TLAS ([`build_tlas`]).
struct Tlas {
    tree: CwBvh,
    /// First record of each leaf cluster, and the total at the end.
    cluster_start: Vec<u32>,
    /// Input index of each record slot.
    order: Vec<u32>,
    depth: usize,
}

impl<P: Primitive + Copy> Blas<P> {
    fn build(prims: Vec<P>, materials: &[u16]) -> Self {
        let boxes: Vec<(DVec3, DVec3)> = prims.iter().map(|p| p.bounds64()).collect();
        let bounds = boxes
            .iter()
            .copied()
            .reduce(|(a, b), (c, d)| (a.min(c), b.max(d)));
        let eps = bounds.map_or(0.0, |(lo, hi)| {
            1e-5 * (lo.abs().max(hi.abs()).max_element() + (hi - lo).length())
        });
        let eps = (eps as f32).max(f32::MIN_POSITIVE);
        let aabbs: Vec<Aabb> = boxes
            .iter()
            .map(|&(lo, hi)| aabb_f32(lo, hi, eps as f64))
            .collect();
        let (tree, order) = build_obvhs(&aabbs, BvhBuildParams::medium_build());
        let cut = tree_cut(&tree, CUT_BOXES);
        Blas {
            cut,
            tree,
            prims: order.iter().map(|&i| prims[i as usize]).collect(),
            materials: order.iter().map(|&i| materials[i as usize]).collect(),
            ids: order,
            eps,
            bounds,
        }
    }

    fn memory_bytes(&self) -> usize {
        self.tree.pairs.len() * std::mem::size_of::<Pair>()
            + self.prims.len() * (std::mem::size_of::<P>() + 4 + 2)
            + std::mem::size_of::<Self>()
    }

    /// Closest (or, with `ANY`, first found) hit of the template-space ray `o + t d` with
    /// `t` in `(lo, hi)` (f64): (t, slot).
    #[inline(always)]
    fn intersect<const ANY: bool>(
        &self,
        o: DVec3,
        d: DVec3,
        lo: f64,
        hi: f64,
        stack: &mut [u32],
    ) -> Option<(f64, u32)> {
        let ray = RayF::new(Vec3A::from(o.as_vec3()), Vec3A::from(d.as_vec3()));
        // Tolerance on t matching the spatial margin (t is in world units, d is not unit).
        let tol = self.eps / ray.d.length() + 1e-30;
        let lo32 = lo as f32 - tol - (lo.abs() as f32) * 1e-6;
        let mut hi32 = hi as f32 + tol + (hi.abs() as f32) * 1e-6;
        let mut best_t = hi;
        let mut best = u32::MAX;
        let eps = self.eps;
        traverse(
            &self.tree.pairs,
            &ray,
            lo32,
            &mut hi32,
            stack,
            |first, count, h| {
                for j in first..first + count {
                    let p = &self.prims[j as usize];
                    let t = p.hit32(&ray, eps);
                    if !(t > lo32 && t < *h) {
                        continue;
                    }
                    if let Some(t64) = p.hit64(o, d) {
                        if t64 > lo && t64 < best_t {
                            best_t = t64;
                            best = j;
                            if ANY {
                                return true;
                            }
                            *h = t64 as f32 + tol + (t64.abs() as f32) * 1e-6;
                        }
                    }
                }
                false
            },
        );
        (best != u32::MAX).then_some((best_t, best))
    }
}

/// Stack traversal of a [`Tree`], near child first. `leaf(first, count, &mut hi)` tests a
/// leaf's primitives, may lower `hi`, and returns `true` to stop. Returns whether it was
/// stopped. `hi` must be finite; `stack` must hold at least the tree's depth.
#[inline(always)]
fn traverse<F: FnMut(u32, u32, &mut f32) -> bool>(
    pairs: &[Pair],
    ray: &RayF,
    lo: f32,
    hi: &mut f32,
    stack: &mut [u32],
    mut leaf: F,
) -> bool {
    if pairs.is_empty() {
        return false;
    }
    let mut sp = 0usize;
    let mut cur = 0usize;
    loop {
        let p = &pairs[cur];
        let (mut ta, mut tb) = ray.slab2(p, lo, *hi);
        let (mut a, mut b) = (0, 1);
        if tb < ta {
            std::mem::swap(&mut a, &mut b);
            std::mem::swap(&mut ta, &mut tb);
        }
        let mut next = u32::MAX;
        if ta < f32::INFINITY {
            if p.count[a] > 0 {
                if leaf(p.first[a], p.count[a], hi) {
                    return true;
                }
            } else {
                next = p.first[a];
            }
        }
        // `hi` may have been lowered by the near leaf.
        if tb <= *hi {
            if p.count[b] > 0 {
                if leaf(p.first[b], p.count[b], hi) {
                    return true;
                }
            } else if next == u32::MAX {
                next = p.first[b];
            } else {
                stack[sp] = p.first[b];
                sp += 1;
            }
        }
        if next == u32::MAX {
            if sp == 0 {
                return false;
            }
            sp -= 1;
            next = stack[sp];
        }
        cur = next as usize;
    }
}

enum TemplateBlas {
    Tris(Blas<Tri>),
    Discs(Blas<DiscPrim>),
}

impl TemplateBlas {
    fn depth(&self) -> usize {
        match self {
            TemplateBlas::Tris(b) => b.tree.depth,
            TemplateBlas::Discs(b) => b.tree.depth,
        }
    }
    fn bounds(&self) -> Option<(DVec3, DVec3)> {
        match self {
            TemplateBlas::Tris(b) => b.bounds,
            TemplateBlas::Discs(b) => b.bounds,
        }
    }
    /// Covering boxes of a cut of the BLAS (see [`tree_cut`]).
    fn cut(&self) -> &[(DVec3, DVec3)] {
        match self {
            TemplateBlas::Tris(b) => &b.cut,
            TemplateBlas::Discs(b) => &b.cut,
        }
    }
    fn len(&self) -> usize {
        match self {
            TemplateBlas::Tris(b) => b.prims.len(),
            TemplateBlas::Discs(b) => b.prims.len(),
        }
    }
    fn memory_bytes(&self) -> usize {
        match self {
            TemplateBlas::Tris(b) => b.memory_bytes(),
            TemplateBlas::Discs(b) => b.memory_bytes(),
        }
    }
}

/// Best hit so far during a traversal.
#[derive(Clone, Copy)]
struct Best {
    t: f64,
    /// TLAS slot of the instance and BLAS slot of the primitive (`u32::MAX`: none).
    slot: u32,
    prim: u32,
}

/// Instances of templates under a two-level BVH (see the module header).
pub struct InstanceBvh {
    templates: Vec<TemplateBlas>,
    /// TLAS (render frame, f32, padded boxes); its leaf slot k is the cluster of records
    /// `cluster_start[k]..cluster_start[k + 1]`.
    tlas: CwBvh,
    cluster_start: Vec<u32>,
    /// Instance records in TLAS slot order.
    records: Vec<InstanceRecord>,
    /// Original instance index of each TLAS slot.
    ids: Vec<u32>,
    render_origin: DVec3,
    /// World box of all geometry (unpadded) and its padded version used for clipping rays.
    lo: DVec3,
    hi: DVec3,
    lo_pad: DVec3,
    hi_pad: DVec3,
    /// TLAS padding, m (also the t margin of the TLAS interval).
    pad: f32,
    /// Levels of the TLAS, and the stack needed by the deepest BLAS.
    tlas_depth: usize,
    blas_depth: usize,
    n_instances: usize,
}

impl std::fmt::Debug for InstanceBvh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("InstanceBvh")
            .field("templates", &self.templates.len())
            .field("instances", &self.n_instances)
            .field("primitives", &self.primitive_count())
            .field("tlas_nodes", &self.tlas.nodes.len())
            .field("tlas_depth", &self.tlas_depth)
            .field("bounds", &self.bounds())
            .finish()
    }
}

fn finite3(v: [f32; 3]) -> bool {
    v.iter().all(|x| x.is_finite())
}

impl InstanceBvh {
    /// Build the two-level BVH. `render_origin`: world point subtracted before converting to f32
    /// (callers pass the scene centre).
    ///
    /// Errors: a template id out of range, a singular or non-finite linear part, a non-finite
    /// translation, vertex, disc or origin, a triangle index out of range, a disc with a zero
    /// normal or a negative radius, a material list whose length differs from the primitives'.
    pub fn new(
        templates: Vec<TemplateGeometry>,
        instances: Vec<(u32, InstanceTransform)>,
        render_origin: DVec3,
    ) -> Result<Self, SceneError> {
        if !render_origin.is_finite() {
            return Err(SceneError::RenderOrigin {
                origin: render_origin,
            });
        }
        if instances.len() > u32::MAX as usize {
            return Err(SceneError::TooManyInstances {
                count: instances.len(),
            });
        }
        let mut blas = Vec::with_capacity(templates.len());
        for (k, t) in templates.into_iter().enumerate() {
            blas.push(Self::build_template(k, t)?);
        }

        // World boxes of the instances with geometry.
        let mut lo = DVec3::INFINITY;
        let mut hi = DVec3::NEG_INFINITY;
        // Unpadded, in f32 in the render frame (rounded outwards); padded below.
        let mut aabbs: Vec<Aabb> = Vec::with_capacity(instances.len());
        let mut records: Vec<InstanceRecord> = Vec::with_capacity(instances.len());
        let mut ids: Vec<u32> = Vec::with_capacity(instances.len());
        // The instances are consumed from the end and their list shrunk as it goes, so that
        // they and the records built from them are never both held whole.
        let n_instances = instances.len();
        let mut instances = instances;
        let shrink_every = (n_instances / 16).max(1 << 16);
        while let Some((tid, tr)) = instances.pop() {
            let i = instances.len();
            if i % shrink_every == 0 {
                instances.shrink_to_fit();
            }
            let Some(b) = blas.get(tid as usize) else {
                return Err(SceneError::TemplateOutOfRange {
                    instance: i,
                    template: tid,
                    templates: blas.len(),
                });
            };
            if !tr.translation.is_finite() {
                return Err(SceneError::Translation {
                    instance: i,
                    translation: tr.translation,
                });
            }
            let l = tr.linear.as_dmat3();
            let det = l.determinant();
            let scale = l.to_cols_array().iter().fold(0.0f64, |m, x| m.max(x.abs()));
            if !det.is_finite() || det.abs() <= 1e-12 * scale.powi(3) || scale == 0.0 {
                return Err(SceneError::SingularLinear {
                    instance: i,
                    linear: tr.linear.to_cols_array(),
                });
            }
            let linv = l.inverse().as_mat3();
            if !linv.is_finite() {
                return Err(SceneError::NotInvertible { instance: i });
            }
            if b.cut().is_empty() {
                continue; // no geometry: nothing to hit
            }
            // World box: union of the transformed cut boxes (exact box of each transformed box:
            // centre L·c, half extent |L|·h).
            let labs = DMat3::from_cols(l.x_axis.abs(), l.y_axis.abs(), l.z_axis.abs());
            let (mut wlo, mut whi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
            for &(c, h) in b.cut() {
                let (wc, wh) = (tr.translation + l * c, labs * h);
                wlo = wlo.min(wc - wh);
                whi = whi.max(wc + wh);
            }
            // The transformed exact template box also bounds the instance: keep the overlap.
            if let Some((blo, bhi)) = b.bounds() {
                let (c, h) = (0.5 * (blo + bhi), 0.5 * (bhi - blo));
                let (wc, wh) = (tr.translation + l * c, labs * h);
                wlo = wlo.max(wc - wh);
                whi = whi.min(wc + wh);
            }
            lo = lo.min(wlo);
            hi = hi.max(whi);
            aabbs.push(aabb_f32(wlo - render_origin, whi - render_origin, 0.0));
            ids.push(i as u32);
            records.push(InstanceRecord {
                translation: tr.translation.to_array(),
                linv: linv.to_cols_array(),
                template: tid,
            });
        }

        // TLAS padding: bounds the f32 error of the clipped ray (origin rounding ≤ ~1.04·10⁻⁷·R
        // per unit, direction rounding ≤ ~1.04·10⁻⁷ per unit length over ≤ the diagonal, and
        // direction components below 2.4·10⁻⁷ snapped to zero: ≤ 2.4·10⁻⁷ per unit length) and
        // of obvhs' unwidened slab tests (a few ulps of the distances).
        let pad = if aabbs.is_empty() {
            0.0
        } else {
            let r = (lo - render_origin)
                .abs()
                .max((hi - render_origin).abs())
                .max_element();
            1e-6 * (r + (hi - lo).length()) + 1e-3
        };
        // The f32 sums are rounded outwards by one more ulp, so each box grows by at least
        // `pad`.
        let ulp = |f: Vec3A| f.abs() * f32::EPSILON + Vec3A::splat(f32::MIN_POSITIVE);
        let pad32 = Vec3A::splat(pad as f32) * (1.0 + f32::EPSILON);
        for a in &mut aabbs {
            let (lo, hi) = (a.min - pad32, a.max + pad32);
            *a = Aabb::new(lo - ulp(lo), hi + ulp(hi));
        }
        let Tlas {
            tree: tlas,
            cluster_start,
            order,
            depth: tlas_depth,
        } = build_tlas(aabbs, super::bvh_cache::dir())?;
        // Records in TLAS slot order, permuted in place (slot k takes record order[k]) so that
        // the records are never held twice.
        permute_in_place(&mut ids, order.clone());
        permute_in_place(&mut records, order);
        let blas_depth = blas.iter().map(|b| b.depth()).max().unwrap_or(0);
        Ok(InstanceBvh {
            templates: blas,
            tlas,
            records,
            ids,
            render_origin,
            lo,
            hi,
            lo_pad: lo - 2.0 * pad,
            hi_pad: hi + 2.0 * pad,
            pad: pad as f32,
            tlas_depth,
            cluster_start,
            blas_depth,
            n_instances,
        })
    }

    fn build_template(k: usize, t: TemplateGeometry) -> Result<TemplateBlas, SceneError> {
        match t {
            TemplateGeometry::Triangles {
                positions,
                indices,
                materials,
            } => {
                if materials.len() != indices.len() {
                    return Err(SceneError::MaterialCount {
                        template: k,
                        materials: materials.len(),
                        primitives: indices.len(),
                        kind: "triangles",
                    });
                }
                if indices.len() > u32::MAX as usize {
                    return Err(SceneError::TooManyPrimitives {
                        template: k,
                        kind: "triangles",
                    });
                }
                let mut tris = Vec::with_capacity(indices.len());
                for (j, ix) in indices.iter().enumerate() {
                    let mut v = [Vec3::ZERO; 3];
                    for (m, &i) in ix.iter().enumerate() {
                        let Some(p) = positions.get(i as usize) else {
                            return Err(SceneError::VertexIndex {
                                template: k,
                                triangle: j,
                                vertex: i,
                                positions: positions.len(),
                            });
                        };
                        if !finite3(*p) {
                            return Err(SceneError::Vertex {
                                template: k,
                                vertex: i,
                            });
                        }
                        v[m] = Vec3::from_array(*p);
                    }
                    tris.push(Tri {
                        a: v[0],
                        b: v[1],
                        c: v[2],
                    });
                }
                Ok(TemplateBlas::Tris(Blas::build(tris, &materials)))
            }
            TemplateGeometry::Discs { discs, materials } => {
                if materials.len() != discs.len() {
                    return Err(SceneError::MaterialCount {
                        template: k,
                        materials: materials.len(),
                        primitives: discs.len(),
                        kind: "discs",
                    });
                }
                if discs.len() > u32::MAX as usize {
                    return Err(SceneError::TooManyPrimitives {
                        template: k,
                        kind: "discs",
                    });
                }
                let mut prims = Vec::with_capacity(discs.len());
                for (j, d) in discs.iter().enumerate() {
                    let n = Vec3::from_array(d.normal).as_dvec3();
                    let len = n.length();
                    if !(finite3(d.centre) && len > 0.0 && len.is_finite()) {
                        return Err(SceneError::DiscGeometry {
                            template: k,
                            disc: j,
                        });
                    }
                    if !(d.radius >= 0.0 && d.radius.is_finite()) {
                        return Err(SceneError::DiscRadius {
                            template: k,
                            disc: j,
                            radius: d.radius,
                        });
                    }
                    prims.push(DiscPrim {
                        c: Vec3::from_array(d.centre),
                        n: (n / len).as_vec3(),
                        r: d.radius,
                    });
                }
                Ok(TemplateBlas::Discs(Blas::build(prims, &materials)))
            }
        }
    }
}

impl InstanceBvh {
    /// Closest hit with `t` in `(tmin, tmax)` of the ray `origin + t·dir` (world frame, f64,
    /// `dir` unit).
    pub fn intersect(
        &self,
        origin: DVec3,
        dir: DVec3,
        tmin: f64,
        tmax: f64,
    ) -> Option<InstanceHit> {
        let best = self.trace::<false>(origin, dir, tmin, tmax)?;
        let rec = &self.records[best.slot as usize];
        let p = best.prim as usize;
        let (n_t, material, primitive) = match &self.templates[rec.template as usize] {
            TemplateBlas::Tris(b) => (b.prims[p].normal64(), b.materials[p], b.ids[p]),
            TemplateBlas::Discs(b) => (b.prims[p].normal64(), b.materials[p], b.ids[p]),
        };
        // Normals transform with the inverse transpose of the linear part.
        let mut normal = (linv64(rec).transpose() * n_t).normalize();
        let front = normal.dot(dir) <= 0.0;
        if !front {
            normal = -normal;
        }
        Some(InstanceHit {
            t: best.t,
            normal,
            material,
            instance: self.ids[best.slot as usize],
            primitive,
            front,
        })
    }

    /// The distinct planes of the primitives whose material `is_mirror` (unit world normal, up
    /// to sign, and material), or `None` when there are more than `max` of them. Primitives of
    /// one template and instances with one rotation share a plane (normals within 1e-9).
    pub fn mirror_planes(
        &self,
        is_mirror: impl Fn(u16) -> bool,
        max: usize,
    ) -> Option<Vec<(DVec3, u16)>> {
        // Per template, its mirror planes; a template with more than `max` already ends the
        // search (a curved mirror mesh would otherwise cost a quadratic dedup).
        let per_template: Vec<Vec<(DVec3, u16)>> = self
            .templates
            .iter()
            .map(|t| {
                let (normals, materials): (Vec<DVec3>, &[u16]) = match t {
                    TemplateBlas::Tris(b) => {
                        (b.prims.iter().map(|p| p.normal64()).collect(), &b.materials)
                    }
                    TemplateBlas::Discs(b) => {
                        (b.prims.iter().map(|p| p.normal64()).collect(), &b.materials)
                    }
                };
                let mut out = Vec::new();
                for (n, &m) in normals.iter().zip(materials) {
                    if is_mirror(m) {
                        push_plane(&mut out, (n.normalize(), m));
                        if out.len() > max {
                            return None;
                        }
                    }
                }
                Some(out)
            })
            .collect::<Option<_>>()?;
        let mut planes = Vec::new();
        if per_template.iter().all(|p| p.is_empty()) {
            return Some(planes);
        }
        for rec in &self.records {
            for &(n_t, m) in &per_template[rec.template as usize] {
                push_plane(
                    &mut planes,
                    ((linv64(rec).transpose() * n_t).normalize(), m),
                );
                if planes.len() > max {
                    return None;
                }
            }
        }
        Some(planes)
    }

    /// Whether anything is hit with `t` in `(tmin, tmax)` (shadow rays): any-hit traversal that
    /// stops at the first hit found.
    pub fn occluded(&self, origin: DVec3, dir: DVec3, tmin: f64, tmax: f64) -> bool {
        self.trace::<true>(origin, dir, tmin, tmax).is_some()
    }

    /// Approximate memory, bytes: template primitives (in BLAS order, with ids and materials)
    /// and BLAS node pairs, TLAS CWBVH nodes (80 B each) and cluster starts (4 B each), instance records (64 B) and original
    /// instance ids (4 B). Vector headers, allocator slack and the transient memory of the
    /// build (≈ 250 B per instance at its peak) are not counted.
    pub fn memory_bytes(&self) -> usize {
        self.templates
            .iter()
            .map(TemplateBlas::memory_bytes)
            .sum::<usize>()
            + self.tlas.nodes.len() * std::mem::size_of::<CwBvhNode>()
            + self.records.len() * std::mem::size_of::<InstanceRecord>()
            + self.cluster_start.len() * 4
            + self.ids.len() * 4
            + std::mem::size_of::<Self>()
    }

    /// The boxes of the TLAS leaves (world frame, padded, as quantized in the CWBVH's nodes):
    /// together they cover every instance.
    pub fn leaf_boxes(&self) -> impl Iterator<Item = (DVec3, DVec3)> + '_ {
        let o = self.render_origin;
        self.tlas.nodes.iter().flat_map(move |n| {
            (0..8)
                .filter(move |&c| !n.is_child_empty(c) && n.is_leaf(c))
                .map(move |c| {
                    let b = n.child_aabb(c);
                    (o + b.min.as_dvec3(), o + b.max.as_dvec3())
                })
        })
    }

    /// Number of instances given to [`InstanceBvh::new`] (including those of empty templates).
    pub fn instance_count(&self) -> usize {
        self.n_instances
    }

    /// Number of primitives over the templates (each counted once, not per instance).
    pub fn primitive_count(&self) -> usize {
        self.templates.iter().map(TemplateBlas::len).sum()
    }

    /// World-space bounding box of all instanced geometry (min, max); the empty box
    /// (+∞, −∞) when there is none.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        (self.lo, self.hi)
    }

    /// Closest (or with `ANY` first found) hit: TLAS slot, BLAS slot, f64 `t`.
    #[inline]
    fn trace<const ANY: bool>(
        &self,
        origin: DVec3,
        dir: DVec3,
        tmin: f64,
        tmax: f64,
    ) -> Option<Best> {
        // NaN bounds or a degenerate ray: no hit.
        if self.tlas.nodes.is_empty()
            || tmin.is_nan()
            || tmax.is_nan()
            || tmin >= tmax
            || !origin.is_finite()
            || !dir.is_finite()
            || dir == DVec3::ZERO
        {
            return None;
        }
        let (a, b) = clip(origin, dir, self.lo_pad, self.hi_pad, tmin, tmax)?;
        let need = self.blas_depth + 1;
        if need <= INLINE_STACK {
            let mut buf = [0u32; INLINE_STACK];
            self.trace_in::<ANY>(origin, dir, tmin, a, b, &mut buf)
        } else {
            let mut buf = vec![0u32; need];
            self.trace_in::<ANY>(origin, dir, tmin, a, b, &mut buf)
        }
    }

    /// The f32 traversal ray of the clipped segment `[a, b]` in the render frame, starting at
    /// `a` where it enters the scene's box; direction components below 2.4·10⁻⁷ are snapped to
    /// zero (obvhs would replace their inverse by ±1/ε, which shrinks the slab; the drift is
    /// within the pad, as for the terrain).
    #[inline(always)]
    fn f32_ray(&self, origin: DVec3, dir: DVec3, tmin: f64, a: f64, b: f64) -> Ray {
        let o32 = (origin + dir * a - self.render_origin).as_vec3();
        let snap = |x: f32| if x.abs() < 2.0 * f32::EPSILON { 0.0 } else { x };
        let d32 = dir.as_vec3();
        Ray::new(
            Vec3A::from(o32),
            Vec3A::new(snap(d32.x), snap(d32.y), snap(d32.z)),
            (tmin - a) as f32 - self.pad,
            (b - a) as f32 + self.pad,
        )
    }

    /// The traversal proper on the clipped segment `[a, b]` (`a ≥ tmin`, `b ≤ tmax`).
    #[inline(always)]
    fn trace_in<const ANY: bool>(
        &self,
        origin: DVec3,
        dir: DVec3,
        tmin: f64,
        a: f64,
        b: f64,
        buf: &mut [u32],
    ) -> Option<Best> {
        let s0 = a;
        let pad = self.pad;
        let ray = self.f32_ray(origin, dir, tmin, a, b);
        let mut best = Best {
            t: b,
            slot: u32::MAX,
            prim: u32::MAX,
        };
        // A leaf's cluster: the new bound if it was hit (−∞ to stop with `ANY`), else +∞.
        let mut test = |k: usize| -> f32 {
            let mut bound = f32::INFINITY;
            for j in self.cluster_start[k]..self.cluster_start[k + 1] {
                if let Some((t, prim)) = self.hit_instance::<ANY>(j, origin, dir, tmin, best.t, buf)
                {
                    best = Best { t, slot: j, prim };
                    if ANY {
                        return f32::NEG_INFINITY;
                    }
                    bound = (t - s0) as f32 + pad;
                }
            }
            bound
        };
        if ANY {
            self.tlas.ray_traverse_miss(ray, |_, k| test(k));
        } else {
            self.tlas
                .ray_traverse(ray, &mut RayHit::none(), |_, k| test(k));
        }
        (best.slot != u32::MAX).then_some(best)
    }

    /// Hit of the instance in TLAS slot `slot` with `t ∈ (tmin, tbest)`: (t, BLAS slot).
    #[inline(always)]
    fn hit_instance<const ANY: bool>(
        &self,
        slot: u32,
        origin: DVec3,
        dir: DVec3,
        tmin: f64,
        tbest: f64,
        stack: &mut [u32],
    ) -> Option<(f64, u32)> {
        let rec = &self.records[slot as usize];
        let tr = DVec3::from_array(rec.translation);
        let linv = linv64(rec);
        // Shift the origin (in f64) to the closest approach to the instance's origin so that the
        // template-space ray has small coordinates; t = s + t'.
        let s = (tr - origin).dot(dir);
        let o_t = linv * ((origin - tr) + dir * s);
        let d_t = linv * dir;
        let (lo, hi) = (tmin - s, tbest - s);
        let (tp, prim) = match &self.templates[rec.template as usize] {
            TemplateBlas::Tris(b) => b.intersect::<ANY>(o_t, d_t, lo, hi, stack),
            TemplateBlas::Discs(b) => b.intersect::<ANY>(o_t, d_t, lo, hi, stack),
        }?;
        let t = s + tp;
        (t > tmin && t < tbest).then_some((t, prim))
    }
}

/// Normals within this of each other (1 − |cos|) are one mirror plane.
pub const SAME_PLANE: f64 = 1e-9;

/// Add the plane (unit normal up to sign, material) to `planes` unless one like it is there.
fn push_plane(planes: &mut Vec<(DVec3, u16)>, (n, m): (DVec3, u16)) {
    if !planes
        .iter()
        .any(|(q, k)| *k == m && n.dot(*q).abs() > 1.0 - SAME_PLANE)
    {
        planes.push((n, m));
    }
}

/// The inverse linear part of an instance in f64.
#[inline(always)]
fn linv64(rec: &InstanceRecord) -> DMat3 {
    let l = rec.linv.map(|x| x as f64);
    DMat3::from_cols_array(&l)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::direction_from_angles;
    use crate::rng::Stream;
    use std::f64::consts::{PI, TAU};

    /// A closed box [-1, 1] × [-1.5, 1.5] × [0, 4] of 12 triangles, material = 10 + triangle.
    fn box_mesh() -> TemplateGeometry {
        let (x, y, z) = (1.0f32, 1.5f32, 4.0f32);
        let positions = vec![
            [-x, -y, 0.0],
            [x, -y, 0.0],
            [x, y, 0.0],
            [-x, y, 0.0],
            [-x, -y, z],
            [x, -y, z],
            [x, y, z],
            [-x, y, z],
        ];
        let indices = vec![
            [0, 2, 1],
            [0, 3, 2],
            [4, 5, 6],
            [4, 6, 7],
            [0, 1, 5],
            [0, 5, 4],
            [1, 2, 6],
            [1, 6, 5],
            [2, 3, 7],
            [2, 7, 6],
            [3, 0, 4],
            [3, 4, 7],
        ];
        let materials = (0..12).map(|k| 10 + k as u16).collect();
        TemplateGeometry::Triangles {
            positions,
            indices,
            materials,
        }
    }

    fn random_unit(rng: &mut Stream) -> DVec3 {
        direction_from_angles((1.0 - 2.0 * rng.next_f64()).acos(), TAU * rng.next_f64())
    }

    /// `n` random discs in a ball of radius 3 m centred 5 m up, material = 100 + disc.
    fn disc_cloud(rng: &mut Stream, n: usize) -> TemplateGeometry {
        let mut discs = Vec::new();
        for _ in 0..n {
            let c = random_unit(rng) * 3.0 * rng.next_f64().cbrt() + DVec3::new(0.0, 0.0, 5.0);
            discs.push(Disc {
                centre: c.as_vec3().to_array(),
                normal: random_unit(rng).as_vec3().to_array(),
                radius: (0.05 + 0.25 * rng.next_f64()) as f32,
            });
        }
        TemplateGeometry::Discs {
            discs,
            materials: (0..n).map(|k| 100 + k as u16).collect(),
        }
    }

    fn rot_z_scale(angle: f64, scale: f64) -> Mat3 {
        (glam::DMat3::from_rotation_z(angle) * scale).as_mat3()
    }

    /// Brute-force closest hit over every primitive of every instance, in world coordinates
    /// (f64): (t, instance, primitive, normal up to sign).
    fn brute(
        templates: &[TemplateGeometry],
        instances: &[(u32, InstanceTransform)],
        o: DVec3,
        d: DVec3,
        tmin: f64,
        tmax: f64,
    ) -> Option<(f64, u32, u32, DVec3)> {
        let mut best: Option<(f64, u32, u32, DVec3)> = None;
        let mut consider = |t: f64, i: usize, j: usize, n: DVec3| {
            if t > tmin && t < tmax && best.is_none_or(|b| t < b.0) {
                best = Some((t, i as u32, j as u32, n));
            }
        };
        for (i, (tid, tr)) in instances.iter().enumerate() {
            let l = tr.linear.as_dmat3();
            let w = |p: [f32; 3]| tr.translation + l * Vec3::from_array(p).as_dvec3();
            match &templates[*tid as usize] {
                TemplateGeometry::Triangles {
                    positions, indices, ..
                } => {
                    for (j, ix) in indices.iter().enumerate() {
                        let (a, b, c) = (
                            w(positions[ix[0] as usize]),
                            w(positions[ix[1] as usize]),
                            w(positions[ix[2] as usize]),
                        );
                        let (e1, e2) = (b - a, c - a);
                        let p = d.cross(e2);
                        let det = e1.dot(p);
                        if det.abs() < 1e-15 {
                            continue;
                        }
                        let s = o - a;
                        let u = s.dot(p) / det;
                        let q = s.cross(e1);
                        let v = d.dot(q) / det;
                        if u >= 0.0 && v >= 0.0 && u + v <= 1.0 {
                            consider(e2.dot(q) / det, i, j, e1.cross(e2).normalize());
                        }
                    }
                }
                TemplateGeometry::Discs { discs, .. } => {
                    // Similarity transforms only: a disc stays a disc of radius scale × r.
                    let scale = l.x_axis.length();
                    for (j, dc) in discs.iter().enumerate() {
                        let c = w(dc.centre);
                        let n = (l * Vec3::from_array(dc.normal).as_dvec3()).normalize();
                        let den = d.dot(n);
                        if den == 0.0 {
                            continue;
                        }
                        let t = (c - o).dot(n) / den;
                        let r = dc.radius as f64 * scale;
                        if (o + d * t - c).length_squared() <= r * r {
                            consider(t, i, j, n);
                        }
                    }
                }
            }
        }
        best
    }

    /// The top-level tree read from the disk cache (`bvh_cache.rs`) is the tree built
    /// without it, node for node; the first build writes the cache, the second reads it, and
    /// other boxes are not served another tree.
    #[test]
    fn cached_tlas_equals_built() {
        let n = super::super::bvh_cache::MIN_PRIMITIVES + 123;
        let boxes = super::super::sah::tests::boxes(n, 17);
        let dir = std::env::temp_dir().join(format!("eosim-tlas-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let built = build_tlas(boxes.clone(), None).unwrap();
        let first = build_tlas(boxes.clone(), Some(dir.clone())).unwrap();
        let files = || std::fs::read_dir(&dir).map_or(0, |d| d.count());
        assert_eq!(files(), 1, "the first build writes the cache");
        let cached = build_tlas(boxes.clone(), Some(dir.clone())).unwrap();
        for t in [&first, &cached] {
            assert!(t.tree.nodes == built.tree.nodes);
            assert_eq!(t.tree.total_aabb, built.tree.total_aabb);
            assert_eq!(t.cluster_start, built.cluster_start);
            assert_eq!(t.order, built.order);
            assert_eq!(t.depth, built.depth);
        }
        let mut moved = boxes;
        moved[7].max.x += 1.0;
        let other = build_tlas(moved, Some(dir.clone())).unwrap();
        assert_eq!(files(), 2);
        assert_eq!(other.order.len(), n);
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// The two-level BVH agrees with a brute-force f64 search (same instance and primitive,
    /// `t` to 1 mm, the same normal turned towards the ray) for random rays over a ±40 km
    /// scene, including rays starting inside objects, limited by `tmin`/`tmax`; `occluded`
    /// agrees with the existence of a brute-force hit.
    #[test]
    fn equals_brute_force() {
        let mut rng = Stream::new(11, [0, 0, 0, 0]);
        let templates = vec![
            box_mesh(),
            disc_cloud(&mut rng, 200),
            TemplateGeometry::Triangles {
                positions: vec![],
                indices: vec![],
                materials: vec![],
            },
            disc_cloud(&mut rng, 1),
        ];
        let mut instances = Vec::new();
        for k in 0..310 {
            let tid = match k % 31 {
                0 => 2,
                1 => 3,
                m if m % 2 == 0 => 0,
                _ => 1,
            };
            let translation = if k < 200 {
                DVec3::new(
                    40_000.0 + 80_000.0 * (rng.next_f64() - 0.5),
                    80_000.0 * (rng.next_f64() - 0.5),
                    50.0 * rng.next_f64(),
                )
            } else {
                // A dense cluster near the far corner: rays cross several instances.
                DVec3::new(
                    79_950.0 + 40.0 * rng.next_f64(),
                    -39_990.0 + 40.0 * rng.next_f64(),
                    5.0 * rng.next_f64(),
                )
            };
            let linear = rot_z_scale(TAU * rng.next_f64(), 0.5 + 1.5 * rng.next_f64());
            instances.push((
                tid,
                InstanceTransform {
                    translation,
                    linear,
                },
            ));
        }
        let bvh = InstanceBvh::new(
            templates.clone(),
            instances.clone(),
            DVec3::new(40_000.0, 0.0, 0.0),
        )
        .unwrap();
        assert_eq!(bvh.instance_count(), 310);
        assert_eq!(bvh.primitive_count(), 12 + 200 + 1);
        let (lo, hi) = bvh.bounds();
        assert!(lo.x > -1.0 && hi.x < 80_010.0 && lo.y > -40_010.0 && hi.y < 40_010.0);

        let (mut hits, mut occl, mut in_cluster, mut continued) = (0, 0, 0, 0);
        for n in 0..2000 {
            // Aim at a random point of a random instance's neighbourhood.
            let i = if n % 2 == 0 {
                (rng.next_f64() * 200.0) as usize
            } else {
                200 + (rng.next_f64() * 110.0) as usize
            };
            let (_, tr) = instances[i];
            let local = DVec3::new(
                3.0 * (2.0 * rng.next_f64() - 1.0),
                3.0 * (2.0 * rng.next_f64() - 1.0),
                -1.0 + 10.0 * rng.next_f64(),
            );
            let target = tr.translation + tr.linear.as_dmat3() * local;
            let d = random_unit(&mut rng);
            let dist = 10f64.powf(-1.0 + 5.7 * rng.next_f64());
            let o = target - d * dist;
            let tmin = if rng.next_f64() < 0.2 {
                dist * rng.next_f64()
            } else {
                1e-4
            };
            let tmax = if rng.next_f64() < 0.3 {
                dist * (0.5 + 1.5 * rng.next_f64())
            } else {
                f64::INFINITY
            };
            let expect = brute(&templates, &instances, o, d, tmin, tmax);
            let got = bvh.intersect(o, d, tmin, tmax);
            match (got, expect) {
                (Some(h), Some((t, inst, prim, nb))) => {
                    assert!(
                        (h.t - t).abs() < 1e-3 && h.instance == inst && h.primitive == prim,
                        "ray {n}: BVH {h:?} vs brute force t {t} instance {inst} primitive {prim}"
                    );
                    assert!(h.normal.dot(d) < 0.0);
                    assert!((h.normal.length() - 1.0).abs() < 1e-12);
                    assert!(
                        h.normal.dot(nb).abs() > 1.0 - 1e-6,
                        "{:?} vs {nb}",
                        h.normal
                    );
                    let tid = instances[inst as usize].0;
                    let m = if tid == 0 { 10 + prim } else { 100 + prim };
                    assert_eq!(h.material as u32, m);
                    hits += 1;
                    in_cluster += (inst >= 200) as usize;
                    // Continue from the hit point (tens of km from the origin) with a small
                    // tmin: the surface just left is not hit again, and the next hit is the
                    // brute-force one.
                    let p = o + d * h.t;
                    let next = bvh.intersect(p, d, 1e-4, f64::INFINITY);
                    if let Some(q) = next {
                        assert!(
                            (q.instance, q.primitive) != (inst, prim),
                            "ray {n}: self-hit"
                        );
                    }
                    let expect = brute(&templates, &instances, p, d, 1e-4, f64::INFINITY);
                    assert_eq!(
                        next.map(|q| (q.instance, q.primitive)),
                        expect.map(|e| (e.1, e.2))
                    );
                    if let (Some(q), Some(e)) = (next, expect) {
                        assert!((q.t - e.0).abs() < 1e-3);
                    }
                    assert_eq!(bvh.occluded(p, d, 1e-4, f64::INFINITY), expect.is_some());
                    continued += next.is_some() as usize;
                }
                (None, None) => {}
                (a, b) => panic!("ray {n} from {o} along {d}: BVH {a:?} vs brute force {b:?}"),
            }
            let oc = bvh.occluded(o, d, tmin, tmax);
            assert_eq!(oc, expect.is_some(), "ray {n}: occluded");
            occl += oc as usize;
        }
        println!(
            "{hits} hits of 2000 rays, {in_cluster} in the cluster, {continued} hits after a hit"
        );
        assert!(
            hits > 600 && in_cluster > 300 && continued > 100,
            "{hits} hits, {in_cluster} in the cluster, {continued} hits after a hit"
        );
        assert_eq!(occl, hits);
    }

    /// One disc and one triangle far from the origin: exact `t`, normals facing the ray from
    /// both sides, misses just outside the rim / edges, `tmin` and `tmax` respected.
    #[test]
    fn single_disc_and_triangle_exact() {
        let templates = vec![
            TemplateGeometry::Discs {
                discs: vec![Disc {
                    centre: [0.0; 3],
                    normal: [0.0, 0.0, 1.0],
                    radius: 1.0,
                }],
                materials: vec![7],
            },
            TemplateGeometry::Triangles {
                positions: vec![[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]],
                indices: vec![[0, 1, 2]],
                materials: vec![9],
            },
        ];
        let td = DVec3::new(50_000.0, -30_000.0, 10.0);
        let tt = DVec3::new(50_010.0, -30_000.0, 10.0);
        // Triangle instance: rotation by 90° about z, scale 2: template (x, y) → world (−2y, 2x).
        let instances = vec![
            (
                0,
                InstanceTransform {
                    translation: td,
                    linear: Mat3::IDENTITY,
                },
            ),
            (
                1,
                InstanceTransform {
                    translation: tt,
                    linear: rot_z_scale(PI / 2.0, 2.0),
                },
            ),
        ];
        let bvh = InstanceBvh::new(templates, instances, DVec3::new(40_000.0, 0.0, 0.0)).unwrap();
        assert_eq!((bvh.instance_count(), bvh.primitive_count()), (2, 2));
        let (lo, hi) = bvh.bounds();
        assert!(
            (lo - DVec3::new(49_999.0, -30_001.0, 10.0))
                .abs()
                .max_element()
                < 1e-5
        );
        assert!(
            (hi - DVec3::new(50_010.0, -29_996.0, 10.0))
                .abs()
                .max_element()
                < 1e-5
        );
        assert!(bvh.memory_bytes() > 0);

        // Disc from above and from below.
        let o = td + DVec3::new(0.3, 0.2, 20.0);
        let h = bvh.intersect(o, -DVec3::Z, 1e-4, f64::INFINITY).unwrap();
        assert!((h.t - 20.0).abs() < 1e-9, "{}", h.t);
        assert_eq!(h.normal, DVec3::Z);
        assert_eq!((h.instance, h.primitive, h.material), (0, 0, 7));
        let h = bvh
            .intersect(
                td + DVec3::new(0.3, 0.2, -5.0),
                DVec3::Z,
                1e-4,
                f64::INFINITY,
            )
            .unwrap();
        assert!((h.t - 5.0).abs() < 1e-9);
        assert_eq!(h.normal, -DVec3::Z);
        // Oblique, both sides: aimed at a point of the disc 7 m away.
        for zen in [0.3, 1.2, PI - 0.3, PI - 1.2] {
            let d = direction_from_angles(zen, 2.0);
            let o = td + DVec3::new(-0.4, 0.5, 0.0) - d * 7.0;
            let h = bvh.intersect(o, d, 0.0, f64::INFINITY).unwrap();
            assert!((h.t - 7.0).abs() < 1e-9, "{}", h.t);
            assert!((h.normal.z.abs() - 1.0).abs() < 1e-12 && h.normal.dot(d) < 0.0);
        }
        // The rim.
        let down = |x: f64, y: f64| bvh.intersect(td + DVec3::new(x, y, 3.0), -DVec3::Z, 0.0, 1e9);
        assert!(down(0.9999, 0.0).is_some() && down(1.0001, 0.0).is_none());
        assert!(down(0.0, -0.9999).is_some() && down(0.0, -1.0001).is_none());
        assert!(down(0.6, 0.7999).is_some() && down(-0.6, 0.8001).is_none());
        // In the plane of the disc: no hit.
        assert!(bvh
            .intersect(td - DVec3::X * 5.0, DVec3::X, 0.0, 9.0)
            .is_none());
        // tmin / tmax, closest hit and occlusion.
        for (tmin, tmax, hit) in [
            (1e-4, 19.999, false),
            (1e-4, 20.001, true),
            (19.999, f64::INFINITY, true),
            (20.001, f64::INFINITY, false),
            (20.0 - 1e-7, 20.0 + 1e-7, true),
        ] {
            assert_eq!(bvh.intersect(o, -DVec3::Z, tmin, tmax).is_some(), hit);
            assert_eq!(bvh.occluded(o, -DVec3::Z, tmin, tmax), hit);
        }

        // Triangle: template (0.5, 0.5) is world tt + (−1, 1, 0).
        let at = |u: f64, v: f64| tt + DVec3::new(-2.0 * v, 2.0 * u, 0.0);
        let h = bvh
            .intersect(
                at(0.5, 0.5) + DVec3::Z * 12.5,
                -DVec3::Z,
                1e-4,
                f64::INFINITY,
            )
            .unwrap();
        assert!((h.t - 12.5).abs() < 1e-9);
        assert_eq!(h.normal, DVec3::Z);
        assert_eq!((h.instance, h.primitive, h.material), (1, 0, 9));
        let h = bvh
            .intersect(at(0.5, 0.5) - DVec3::Z * 3.0, DVec3::Z, 1e-4, f64::INFINITY)
            .unwrap();
        assert!((h.t - 3.0).abs() < 1e-9);
        assert_eq!(h.normal, -DVec3::Z);
        let d = direction_from_angles(2.5, 4.0);
        let h = bvh
            .intersect(at(0.2, 0.3) - d * 9.0, d, 1e-4, f64::INFINITY)
            .unwrap();
        assert!((h.t - 9.0).abs() < 1e-9 && h.normal == DVec3::Z, "{h:?}");
        // Edges (hypotenuse u + v = 2, u = 0, v = 0) in template coordinates (1 unit = 2 m).
        let down = |u: f64, v: f64| bvh.occluded(at(u, v) + DVec3::Z, -DVec3::Z, 0.0, 2.0);
        assert!(down(0.9995, 0.9995) && !down(1.0005, 1.0005));
        assert!(down(0.0005, 0.5) && !down(-0.0005, 0.5));
        assert!(down(0.5, 0.0005) && !down(0.5, -0.0005));
        // tmin just past the triangle.
        assert!(!bvh.occluded(at(0.5, 0.5) + DVec3::Z, -DVec3::Z, 1.0 + 1e-6, 2.0));
        assert!(bvh.occluded(at(0.5, 0.5) + DVec3::Z, -DVec3::Z, 1.0 - 1e-6, 2.0));
    }

    /// Mirror planes: the box's faces of the mirror materials, turned by each instance; the
    /// same rotation twice and the two opposite faces of the box (one plane up to sign) count
    /// once; more than `max` distinct planes give `None`; normals follow the inverse transpose.
    #[test]
    fn mirror_planes_are_the_distinct_turned_faces() {
        let tr = |angle: f64| InstanceTransform {
            translation: DVec3::new(10.0 * angle, 0.0, 0.0),
            linear: rot_z_scale(angle, 2.0),
        };
        // Materials 10..22 are the box's triangles: 12, 13 its top; 14, 15 the −y face and
        // 18, 19 the +y face (the same plane).
        let is_mirror = |m: u16| [12, 13, 14, 15, 18, 19].contains(&m);
        let bvh = InstanceBvh::new(
            vec![box_mesh()],
            vec![(0, tr(0.0)), (0, tr(0.3)), (0, tr(0.3))],
            DVec3::ZERO,
        )
        .unwrap();
        let planes = bvh.mirror_planes(|m| [12, 13].contains(&m), 16).unwrap();
        assert_eq!(planes.len(), 2, "{planes:?}");
        assert!(planes.iter().all(|(n, _)| (n.z.abs() - 1.0).abs() < 1e-12));
        let planes = bvh.mirror_planes(is_mirror, 16).unwrap();
        // The top once (a rotation about z keeps it; materials 12 and 13 apart), and per
        // rotation the ±y faces (14, 15, 18, 19: four materials).
        assert_eq!(planes.len(), 2 + 2 * 4, "{planes:?}");
        let sides: Vec<&(DVec3, u16)> = planes.iter().filter(|(_, m)| *m == 14).collect();
        assert_eq!(sides.len(), 2);
        let want = DVec3::new(-(0.3f64.sin()), 0.3f64.cos(), 0.0);
        assert!(
            sides.iter().any(|(n, _)| n.dot(want).abs() > 1.0 - 1e-6),
            "{sides:?}"
        );
        assert!(bvh.mirror_planes(is_mirror, 9).is_none());
        assert!(bvh.mirror_planes(|_| false, 0).unwrap().is_empty());
        // Normals turn with the inverse transpose: a shear of x along y keeps the ±y faces in
        // planes y = const (the linear part itself would tilt the normal to (0.45, 0.89, 0)).
        let shear = InstanceTransform {
            translation: DVec3::ZERO,
            linear: Mat3::from_cols(Vec3::X, Vec3::new(0.5, 1.0, 0.0), Vec3::Z),
        };
        let bvh = InstanceBvh::new(vec![box_mesh()], vec![(0, shear)], DVec3::ZERO).unwrap();
        let planes = bvh.mirror_planes(|m| m == 14, 16).unwrap();
        assert_eq!(planes.len(), 1);
        assert!((planes[0].0.y.abs() - 1.0).abs() < 1e-12, "{planes:?}");
    }

    /// Invalid inputs are refused; empty scenes and empty templates hit nothing.
    #[test]
    fn errors_and_degenerate_cases() {
        let tr = |linear: Mat3| InstanceTransform {
            translation: DVec3::new(1.0, 2.0, 3.0),
            linear,
        };
        let one = || vec![box_mesh()];
        assert!(InstanceBvh::new(one(), vec![(1, tr(Mat3::IDENTITY))], DVec3::ZERO).is_err());
        assert!(InstanceBvh::new(one(), vec![(0, tr(Mat3::ZERO))], DVec3::ZERO).is_err());
        let flat = Mat3::from_cols(Vec3::X, Vec3::Y, Vec3::X + Vec3::Y);
        assert!(InstanceBvh::new(one(), vec![(0, tr(flat))], DVec3::ZERO).is_err());
        let mut nan = tr(Mat3::IDENTITY);
        nan.translation.x = f64::NAN;
        assert!(InstanceBvh::new(one(), vec![(0, nan)], DVec3::ZERO).is_err());
        assert!(
            InstanceBvh::new(one(), vec![(0, tr(Mat3::IDENTITY * f32::NAN))], DVec3::ZERO).is_err()
        );
        let bad = TemplateGeometry::Triangles {
            positions: vec![[0.0; 3]],
            indices: vec![[0, 0, 1]],
            materials: vec![0],
        };
        assert!(InstanceBvh::new(vec![bad], vec![], DVec3::ZERO).is_err());
        let bad = TemplateGeometry::Discs {
            discs: vec![Disc {
                centre: [0.0; 3],
                normal: [0.0; 3],
                radius: 1.0,
            }],
            materials: vec![0],
        };
        assert!(InstanceBvh::new(vec![bad], vec![], DVec3::ZERO).is_err());

        fn send_sync<T: Send + Sync>() {}
        send_sync::<InstanceBvh>();
        // No instances.
        let empty = InstanceBvh::new(one(), vec![], DVec3::ZERO).unwrap();
        assert_eq!(empty.instance_count(), 0);
        assert!(empty.intersect(DVec3::ZERO, DVec3::Z, 0.0, 1e9).is_none());
        assert!(!empty.occluded(DVec3::ZERO, DVec3::Z, 0.0, 1e9));
        let (lo, hi) = empty.bounds();
        assert!(lo.x > hi.x);
        // Instances of an empty template.
        let none = InstanceBvh::new(
            vec![TemplateGeometry::Discs {
                discs: vec![],
                materials: vec![],
            }],
            vec![(0, tr(Mat3::IDENTITY)); 3],
            DVec3::ZERO,
        )
        .unwrap();
        assert_eq!((none.instance_count(), none.primitive_count()), (3, 0));
        assert!(none
            .intersect(DVec3::new(1.0, 2.0, 10.0), -DVec3::Z, 0.0, 1e9)
            .is_none());
        // A sheared, non-uniformly scaled box is still hit where expected.
        let m = Mat3::from_cols(
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.5, 1.0, 0.0),
            Vec3::Z * 0.5,
        );
        let b = InstanceBvh::new(one(), vec![(0, tr(m))], DVec3::ZERO).unwrap();
        // Top face z = 3 + 0.5·4 = 5, normal +z.
        let h = b
            .intersect(DVec3::new(1.0, 2.0, 9.0), -DVec3::Z, 0.0, f64::INFINITY)
            .unwrap();
        assert!((h.t - 4.0).abs() < 1e-9 && h.normal == DVec3::Z);
        // Side face x_t = 1 → world plane spanned by (0.5, 1, 0) and z through (3, 2, 3):
        // normal ∝ (1, −0.5, 0)·… : hit from +x along −x at y = 2.
        let h = b
            .intersect(DVec3::new(10.0, 2.0, 4.0), -DVec3::X, 0.0, f64::INFINITY)
            .unwrap();
        assert!((h.t - 7.0).abs() < 1e-9, "{}", h.t);
        let n = DVec3::new(1.0, -0.5, 0.0).normalize();
        assert!((h.normal - n).length() < 1e-6, "{}", h.normal);
    }

    /// CPU time of the calling thread, s ([`crate::util::cpu_time`]; 0 where it cannot be read).
    fn thread_cpu_seconds() -> f64 {
        crate::util::cpu_time::thread_seconds().unwrap_or(0.0)
    }

    /// Rays starting within 10⁻⁴ m of a single small instance still hit it (obvhs' box test
    /// culls boxes the ray leaves within 10⁻⁴ m of its f32 origin; the TLAS pad keeps every
    /// instance's box beyond that), from above and from just below, closest and any hit.
    #[test]
    fn rays_starting_close_to_a_lone_instance() {
        let tri = TemplateGeometry::Triangles {
            positions: vec![[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [0.0, 1.0, 0.0]],
            indices: vec![[0, 1, 2]],
            materials: vec![0],
        };
        let at = |z: f64| InstanceTransform {
            translation: DVec3::new(0.0, 0.0, z),
            linear: Mat3::IDENTITY,
        };
        let one = InstanceBvh::new(vec![tri.clone()], vec![(0, at(0.0))], DVec3::ZERO).unwrap();
        for z in [10.0, 1.0, 1e-3, 2e-4, 1e-4, 5e-5, 1e-5] {
            let o = DVec3::new(0.1, -0.2, z);
            let h = one.intersect(o, -DVec3::Z, 0.0, 100.0);
            assert!(
                h.is_some_and(|h| (h.t - z).abs() < 1e-9),
                "from z = {z}: {h:?}"
            );
            assert!(
                one.occluded(o, -DVec3::Z, 0.0, 100.0),
                "occluded from z = {z}"
            );
        }
        let two =
            InstanceBvh::new(vec![tri], vec![(0, at(0.0)), (0, at(-3.0))], DVec3::ZERO).unwrap();
        for z in [-5e-5, -1e-5] {
            let o = DVec3::new(0.1, -0.2, z);
            let h = two.intersect(o, DVec3::Z, 0.0, 100.0);
            assert!(
                h.is_some_and(|h| (h.t + z).abs() < 1e-9),
                "from z = {z} up: {h:?}"
            );
            assert!(
                two.occluded(o, DVec3::Z, 0.0, 100.0),
                "occluded from z = {z} up"
            );
        }
    }

    /// `permute_in_place` puts the old `v[order[k]]` in slot k, for random permutations (long
    /// cycles) and for fixed points and 2-cycles.
    #[test]
    fn permute_in_place_follows_the_order() {
        let mut rng = Stream::new(5, [1, 0, 0, 0]);
        for n in [0usize, 1, 2, 7, 1000] {
            let mut order: Vec<u32> = (0..n as u32).collect();
            for i in (1..n).rev() {
                let j = (rng.next_f64() * (i + 1) as f64) as usize;
                order.swap(i, j.min(i));
            }
            let v: Vec<u64> = (0..n as u64).map(|x| 10 * x + 3).collect();
            let expect: Vec<u64> = order.iter().map(|&k| v[k as usize]).collect();
            let mut w = v.clone();
            permute_in_place(&mut w, order);
            assert_eq!(w, expect, "n = {n}");
        }
        let mut w = vec!['a', 'b', 'c', 'd'];
        permute_in_place(&mut w, vec![1, 0, 2, 3]);
        assert_eq!(w, vec!['b', 'a', 'c', 'd']);
    }

    /// A slab test of a node pair agrees with obvhs' reference ray–box test, and the empty
    /// stand-in box of the root pair is never hit, whatever the direction's signs (an ∞ − ∞ in
    /// the robust widening once made it a NaN that passed).
    #[test]
    fn pair_slab_test() {
        let mut rng = Stream::new(1, [0, 0, 0, 0]);
        let mut r = || rng.next_f64() as f32;
        let far = Aabb::new(Vec3A::splat(f32::MAX), Vec3A::splat(f32::MAX));
        for _ in 0..100_000 {
            let a = Aabb::new(Vec3A::new(r(), r(), r()), Vec3A::new(r(), r(), r()) + 1.0);
            let lo = Vec3A::new(r(), r(), r()) * 3.0;
            let b = Aabb::new(lo, lo + Vec3A::new(r(), r(), r()));
            let o = Vec3A::new(r(), r(), r()) * 6.0 - 3.0;
            let mut d = Vec3A::new(r() - 0.5, r() - 0.5, r() - 0.5).normalize();
            if r() < 0.1 {
                d.x = 0.0; // axis-parallel rays
            }
            let ray = RayF::new(o, d);
            let (ta, tb) = ray.slab2(&Pair::new((&a, 0, 0), (&b, 0, 0)), 0.0, 100.0);
            let reference = obvhs::ray::Ray::new(o, d, 0.0, 100.0);
            assert_eq!(ta < f32::INFINITY, a.intersect_ray(&reference) < 100.0);
            assert_eq!(tb < f32::INFINITY, b.intersect_ray(&reference) < 100.0);
            let (_, tf) = ray.slab2(&Pair::new((&a, 0, 0), (&far, 0, 1)), -1e6, 1e6);
            assert_eq!(tf, f32::INFINITY);
        }
    }

    /// 1M instances of a 200-disc crown (9 in 10) and a 12-triangle box over 10 km × 10 km,
    /// 40 km from the origin: build time, memory and single-thread ray throughput. Run with
    /// `cargo test --release -p simulator --lib instances -- --ignored --nocapture`.
    #[test]
    #[ignore]
    fn bench_one_million_instances() {
        use std::time::Instant;
        let mut rng = Stream::new(3, [0, 0, 0, 0]);
        let templates = vec![disc_cloud(&mut rng, 200), box_mesh()];
        let n = 1000usize;
        let side = 10.0 * n as f64;
        let centre = DVec3::new(40_000.0, 0.0, 0.0);
        let mut instances = Vec::with_capacity(n * n);
        for j in 0..n {
            for i in 0..n {
                let translation = centre
                    + DVec3::new(
                        10.0 * (i as f64 - n as f64 / 2.0) + 6.0 * (rng.next_f64() - 0.5),
                        10.0 * (j as f64 - n as f64 / 2.0) + 6.0 * (rng.next_f64() - 0.5),
                        0.0,
                    );
                let tid = ((i + j) % 10 == 0) as u32;
                let linear = rot_z_scale(TAU * rng.next_f64(), 0.7 + 0.6 * rng.next_f64());
                instances.push((
                    tid,
                    InstanceTransform {
                        translation,
                        linear,
                    },
                ));
            }
        }
        let (c0, t0) = (thread_cpu_seconds(), Instant::now());
        let bvh = InstanceBvh::new(templates, instances, centre).unwrap();
        let (build, build_cpu) = (t0.elapsed().as_secs_f64(), thread_cpu_seconds() - c0);
        let mem = bvh.memory_bytes();
        println!(
            "build {build:.2} s wall, {build_cpu:.2} s CPU for {} instances; memory {:.1} MiB = {:.1} B/instance; TLAS depth {}, {} nodes",
            bvh.instance_count(),
            mem as f64 / 1048576.0,
            mem as f64 / bvh.instance_count() as f64,
            bvh.tlas_depth,
            bvh.tlas.nodes.len()
        );
        let nr = 1_000_000;
        let mut above = Vec::with_capacity(nr);
        let mut inside = Vec::with_capacity(nr);
        for _ in 0..nr {
            let (x, y) = (
                0.9 * side * (rng.next_f64() - 0.5),
                0.9 * side * (rng.next_f64() - 0.5),
            );
            let d = direction_from_angles(PI - 0.8 * rng.next_f64(), TAU * rng.next_f64());
            above.push((centre + DVec3::new(x, y, 20.0), d));
            let (x, y) = (
                0.9 * side * (rng.next_f64() - 0.5),
                0.9 * side * (rng.next_f64() - 0.5),
            );
            let z = 1.0 + 8.0 * rng.next_f64();
            inside.push((centre + DVec3::new(x, y, z), random_unit(&mut rng)));
        }
        for (name, set) in [
            ("from above, downwards", &above),
            ("inside the canopy, isotropic", &inside),
        ] {
            let (c0, t0) = (thread_cpu_seconds(), Instant::now());
            let mut hits = 0usize;
            let mut tsum = 0.0;
            for &(o, d) in set.iter() {
                if let Some(h) = bvh.intersect(o, d, 1e-4, f64::INFINITY) {
                    hits += 1;
                    tsum += h.t;
                }
            }
            let (dt, dc) = (t0.elapsed().as_secs_f64(), thread_cpu_seconds() - c0);
            let (c0, t0) = (thread_cpu_seconds(), Instant::now());
            let mut occ = 0usize;
            for &(o, d) in set.iter() {
                occ += bvh.occluded(o, d, 1e-4, f64::INFINITY) as usize;
            }
            let (dt1, dc1) = (t0.elapsed().as_secs_f64(), thread_cpu_seconds() - c0);
            assert_eq!(occ, hits);
            println!(
                "{name}: {:.1}% hit (mean t {:.1} m); closest hit {:.2} Mrays/s wall, {:.2} µs/ray CPU; occluded {:.2} Mrays/s wall, {:.2} µs/ray CPU",
                100.0 * hits as f64 / nr as f64,
                tsum / hits.max(1) as f64,
                nr as f64 / dt / 1e6,
                dc / nr as f64 * 1e6,
                nr as f64 / dt1 / 1e6,
                dc1 / nr as f64 * 1e6,
            );
        }
    }
}

#[cfg(test)]
mod amac_probe {
    use super::super::interleave::{self, prefetch};
    use super::*;

    struct Lane {
        st: obvhs::cwbvh::Traversal,
        ray: Ray,
        origin: DVec3,
        dir: DVec3,
        s0: f64,
        best: Best,
        idx: usize,
        buf: [u32; 64],
    }

    impl InstanceBvh {
        /// One step of a lane: its primitive group's clusters (their instances' templates
        /// traced at once), then the next node; true when done.
        #[inline(always)]
        fn step(&self, l: &mut Lane) -> bool {
            for c in interleave::primitives(&l.st) {
                for j in self.cluster_start[c]..self.cluster_start[c + 1] {
                    if let Some((t, prim)) =
                        self.hit_instance::<false>(j, l.origin, l.dir, 0.0, l.best.t, &mut l.buf)
                    {
                        l.best = Best { t, slot: j, prim };
                        let bound = (t - l.s0) as f32 + self.pad;
                        if bound < l.ray.tmax {
                            l.ray.tmax = bound;
                        }
                    }
                }
            }
            if interleave::visit(&self.tlas, &mut l.st, &l.ray) {
                return true;
            }
            for c in interleave::primitives(&l.st) {
                let j = self.cluster_start[c] as usize;
                prefetch(&self.records[j]);
                prefetch(&self.records[(j + 2).min(self.records.len() - 1)]);
            }
            false
        }

        /// Closest hits (t) of `rays` within `tmax`, `k` traced at a time.
        fn closest_many(
            &self,
            rays: &[(DVec3, DVec3)],
            tmax: &[f64],
            k: usize,
        ) -> Vec<Option<f64>> {
            let mut out = vec![None; rays.len()];
            interleave::run(
                rays.len(),
                k,
                |idx| {
                    let (origin, dir) = rays[idx];
                    let (a, b) = clip(origin, dir, self.lo_pad, self.hi_pad, 0.0, tmax[idx])?;
                    let ray = self.f32_ray(origin, dir, 0.0, a, b);
                    Some(Lane {
                        st: self.tlas.new_traversal(ray.direction),
                        ray,
                        origin,
                        dir,
                        s0: a,
                        best: Best {
                            t: b,
                            slot: u32::MAX,
                            prim: u32::MAX,
                        },
                        idx,
                        buf: [0; 64],
                    })
                },
                |l| self.step(l),
                |l| {
                    if l.best.slot != u32::MAX {
                        out[l.idx] = Some(l.best.t);
                    }
                },
            );
            out
        }
    }

    #[test]
    #[ignore]
    fn amac_probe_grenoble_instances() {
        let scene = crate::scene::build::from_bundle(
            std::path::Path::new("../out/grenoble"),
            &crate::scene::build::Background::Flat {
                altitude: None,
                brdf: None,
            },
            &[],
            &[],
            None,
        )
        .unwrap();
        let objects = scene.objects.as_ref().unwrap();
        let e = scene.extent;
        let mut rng = crate::rng::Stream::new(1, [0, 0, 0, 0]);
        let top = scene.z_range[1] + 100.0;
        let rays: Vec<(DVec3, DVec3)> = (0..1_000_000)
            .map(|_| {
                let o = DVec3::new(
                    e[0] + (e[2] - e[0]) * rng.next_f64(),
                    e[1] + (e[3] - e[1]) * rng.next_f64(),
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
        let (terrain, _) = scene.terrain.as_ref().unwrap();
        for _ in 0..2 {
            // The whole query (terrain, then instances bounded by its hit), one ray at a time
            // and interleaved.
            let s = std::time::Instant::now();
            let whole: Vec<_> = rays
                .iter()
                .map(|&(o, d)| scene.intersect(o, d, f64::INFINITY).map(|h| h.t))
                .collect();
            let t_whole = s.elapsed().as_secs_f64();
            let s = std::time::Instant::now();
            let ter = terrain.closest_many(&rays, 16);
            let bound: Vec<f64> = ter
                .iter()
                .map(|h| h.map_or(f64::INFINITY, |h| h.0))
                .collect();
            let inst = objects.closest_many(&rays, &bound, 16);
            let t_il = s.elapsed().as_secs_f64();
            let same = whole
                .iter()
                .zip(inst.iter().zip(&bound))
                .filter(|(w, (i, b))| {
                    let t = i.unwrap_or(**b);
                    w.map(|v| v.to_bits()) == Some(t).filter(|t| t.is_finite()).map(|v| v.to_bits())
                })
                .count();
            println!(
                "whole scene: sequential {:.3e} rays/s, interleaved (16) {:.3e} rays/s, same hits {same}",
                rays.len() as f64 / t_whole,
                rays.len() as f64 / t_il
            );
            let s = std::time::Instant::now();
            let a: Vec<_> = rays
                .iter()
                .map(|&(o, d)| objects.intersect(o, d, 0.0, f64::INFINITY).map(|h| h.t))
                .collect();
            let ta = s.elapsed().as_secs_f64();
            println!("sequential: {:.3e} rays/s", rays.len() as f64 / ta);
            for k in [1, 8, 16, 32] {
                let s = std::time::Instant::now();
                let b2 = objects.closest_many(&rays, &vec![f64::INFINITY; rays.len()], k);
                let tb = s.elapsed().as_secs_f64();
                let same = a
                    .iter()
                    .zip(&b2)
                    .filter(|(x, y)| x.map(|v| v.to_bits()) == y.map(|v| v.to_bits()))
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
