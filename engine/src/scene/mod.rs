//! 3D scenes: geometry (the terrain BVH in `terrain`, instanced objects in `instances`),
//! materials, the assembled [`Scene`] and its builders (bundle, canopy). Each geometry module's
//! header states its precision scheme: f32 traversal in a render frame centred on the scene,
//! every hit decided in f64.

pub mod area_mask;
pub mod build;
pub(crate) mod bvh_cache;
pub mod curvature;
pub mod emission;
pub mod error;
pub mod instances;
#[cfg(test)]
mod interleave;
pub mod material;
pub(crate) mod sah;
pub mod sun_clearance;
pub mod terrain;
pub mod texture;
pub mod world;

pub use error::SceneError;
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

/// Deepest level of a CWBVH's inner nodes (the root is level 1; 0 for an empty tree). obvhs 0.4's
/// traversal keeps its node groups on a fixed stack of [`CWBVH_MAX_DEPTH`]` + 1` entries and
/// *overwrites the top one* when it is full (dropping a subtree without a word), at most one
/// push per level below the root, so a tree may be traversed only when this is at most
/// [`CWBVH_MAX_DEPTH`].
pub(crate) fn cwbvh_depth(bvh: &obvhs::cwbvh::CwBvh) -> usize {
    if bvh.nodes.is_empty() {
        return 0;
    }
    let mut deepest = 0;
    let mut todo = vec![(0usize, 1usize)];
    while let Some((k, level)) = todo.pop() {
        deepest = deepest.max(level);
        let node = &bvh.nodes[k];
        for child in 0..8 {
            if !node.is_child_empty(child) && !node.is_leaf(child) {
                todo.push((node.child_node_index(child) as usize, level + 1));
            }
        }
    }
    deepest
}

/// Deepest CWBVH that obvhs 0.4's traversal stack (32 entries, the last one overwritten when
/// full) handles exactly; see [`cwbvh_depth`].
pub(crate) const CWBVH_MAX_DEPTH: usize = 30;

/// `src.into_iter().map(f).collect()` for large lists without holding both whole: `src` is
/// consumed from its end and shrunk every sixteenth (at least every 65 536 items), and the
/// output reversed in place at the end. For the million-instance lists of scene bundles, where
/// the two lists side by side made the set-up's peak memory.
pub(crate) fn map_freeing<T, U>(mut src: Vec<T>, mut f: impl FnMut(T) -> U) -> Vec<U> {
    let shrink_every = (src.len() / 16).max(1 << 16);
    let mut out = Vec::with_capacity(src.len());
    while let Some(x) = src.pop() {
        if src.len() % shrink_every == 0 {
            src.shrink_to_fit();
        }
        out.push(f(x));
    }
    out.reverse();
    out
}

/// Hand the allocator's free memory back to the system (glibc's `malloc_trim`; elsewhere
/// nothing). glibc keeps memory freed by worker threads in their arenas; between the phases of
/// a large build this lets the next phase reuse the pages instead of adding to the peak.
pub(crate) fn release_free_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only returns free pages of the allocator's own heaps to the system.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// While alive, glibc serves allocations of 1 MiB and more by `mmap`, so that they go back to
/// the system when freed; dropped, the threshold becomes 32 MiB (the most glibc's own dynamic
/// threshold reaches), so that the render's large per-round buffers are reused from the heap
/// as before. A scene build allocates and frees many large temporaries (the instance tree's
/// halves, its conversion): by default the first freed block raises glibc's threshold and the
/// later ones stay in the heap once freed. On the README render this cut the peak RSS from 288
/// to 272 MB and the RSS after the build from 181 to 149 MB (BENCHMARKS.md).
pub(crate) struct LargeBlocksReturned;

impl LargeBlocksReturned {
    pub(crate) fn new() -> Self {
        set_mmap_threshold(1 << 20);
        LargeBlocksReturned
    }
}

impl Drop for LargeBlocksReturned {
    fn drop(&mut self) {
        set_mmap_threshold(32 << 20);
    }
}

fn set_mmap_threshold(_bytes: i32) {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only changes the allocator's policy for later allocations.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, _bytes);
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn map_freeing_keeps_the_order() {
        let v: Vec<u64> = (0..200_000).collect();
        let w = super::map_freeing(v, |x| 2 * x + 1);
        assert_eq!(w, (0..200_000).map(|x| 2 * x + 1).collect::<Vec<u64>>());
        assert!(super::map_freeing(Vec::<u8>::new(), |x| x).is_empty());
    }
}
