//! 3D scenes: geometry (the terrain BVH in `terrain`, instanced objects in `instances`),
//! materials, the assembled [`Scene`] and its builders (bundle, canopy). Each geometry module's
//! header states its precision scheme: f32 traversal in a render frame centred on the scene,
//! every hit decided in f64.

pub mod area_mask;
pub mod build;
pub mod curvature;
pub mod emission;
pub mod instances;
pub mod material;
pub mod sun_clearance;
pub mod terrain;
pub mod texture;
pub mod world;

pub use terrain::{TerrainBvh, TerrainHit};
pub use world::{Scene, SurfaceHit};

use glam::DVec3;

/// Clip the ray `o + t d`, `t ∈ [t0, t1]`, to the box `[lo, hi]` (f64); `None` if it misses.
#[inline(always)]
pub(crate) fn clip(
    o: DVec3,
    d: DVec3,
    lo: DVec3,
    hi: DVec3,
    t0: f64,
    t1: f64,
) -> Option<(f64, f64)> {
    let (mut a, mut b) = (t0, t1);
    for k in 0..3 {
        if d[k] == 0.0 {
            if o[k] < lo[k] || o[k] > hi[k] {
                return None;
            }
        } else {
            let inv = 1.0 / d[k];
            let (x, y) = ((lo[k] - o[k]) * inv, (hi[k] - o[k]) * inv);
            a = a.max(x.min(y));
            b = b.min(x.max(y));
        }
    }
    (a <= b).then_some((a, b))
}
