//! A probe of interleaved traversal (issue 21, BENCHMARKS.md "Where the 3D render's ray time
//! goes"; test-only): the traversals of `k` rays through obvhs' CWBVH are stepped one node at a
//! time in turn, each step prefetching what the ray's next step reads, so that the rays'
//! dependent cache misses overlap. The terrain's and the instances' probes (`amac_probe` in
//! `terrain.rs` and `instances.rs`) test their own primitives and share the rest here.

use glam::UVec2;
use obvhs::cwbvh::{firstbithigh, CwBvh, Traversal};
use obvhs::faststack::FastStack;
use obvhs::ray::Ray;

/// Ask the CPU to bring `p`'s cache line in.
#[inline(always)]
pub(super) fn prefetch<T>(p: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch is a hint; it reads nothing and never faults.
    unsafe {
        std::arch::x86_64::_mm_prefetch(p as *const T as *const i8, std::arch::x86_64::_MM_HINT_T0);
    }
}

/// The node the traversal visits next, if its current group holds one (as obvhs' `traverse!`
/// picks it).
#[inline(always)]
fn next_node(st: &Traversal) -> Option<usize> {
    let hits_imask = st.current_group.y;
    if hits_imask & 0xff000000 == 0 {
        return None;
    }
    let off = firstbithigh(hits_imask);
    let slot = (off - 24) ^ (st.oct_inv4 & 0xff);
    let rel = (hits_imask & !(0xffffffffu32 << slot)).count_ones();
    Some((st.current_group.x + rel) as usize)
}

/// The rest of one iteration of obvhs' `traverse!` loop once the caller has tested the
/// primitive group: visit the next node (or pop the stack); true when the traversal is done.
/// Prefetches the node after it; the caller prefetches its new primitive group.
#[inline(always)]
pub(super) fn visit(bvh: &CwBvh, st: &mut Traversal, ray: &Ray) -> bool {
    st.primitive_group = UVec2::ZERO;
    if let Some(n) = next_node(st) {
        let off = firstbithigh(st.current_group.y);
        st.current_group.y &= !(1u32 << off);
        if st.current_group.y & 0xff000000 != 0 {
            st.stack.push(st.current_group);
        }
        let node = &bvh.nodes[n];
        st.hitmask = node.intersect_ray(ray, st.oct_inv4);
        st.current_group.x = node.child_base_idx;
        st.primitive_group.x = node.primitive_base_idx;
        st.current_group.y = (st.hitmask & 0xff000000) | (node.imask as u32);
        st.primitive_group.y = st.hitmask & 0x00ffffff;
    } else {
        st.current_group = UVec2::ZERO;
    }
    if st.primitive_group.y == 0 && (st.current_group.y & 0xff000000) == 0 {
        if st.stack.is_empty() {
            return true;
        }
        st.current_group = st.stack.pop_fast();
    }
    if let Some(n) = next_node(st) {
        prefetch(&bvh.nodes[n]);
    }
    false
}

/// The slots (in `primitive_group.x + k` order, highest bit first) of the primitive group.
#[inline(always)]
pub(super) fn primitives(st: &Traversal) -> impl Iterator<Item = usize> {
    let (base, mut g) = (st.primitive_group.x, st.primitive_group.y);
    std::iter::from_fn(move || {
        (g != 0).then(|| {
            let k = firstbithigh(g);
            g &= !(1u32 << k);
            (base + k) as usize
        })
    })
}

/// Run rays `0..n` through `k` lanes: `start(i)` makes ray i's lane (`None`: nothing to
/// trace), `step` advances a lane by one node (true: done), `finish` takes a finished lane.
pub(super) fn run<L>(
    n: usize,
    k: usize,
    mut start: impl FnMut(usize) -> Option<L>,
    mut step: impl FnMut(&mut L) -> bool,
    mut finish: impl FnMut(L),
) {
    let mut next = 0;
    let mut lanes: Vec<L> = Vec::with_capacity(k);
    loop {
        while lanes.len() < k && next < n {
            if let Some(l) = start(next) {
                lanes.push(l);
            }
            next += 1;
        }
        if lanes.is_empty() {
            break;
        }
        let mut i = 0;
        while i < lanes.len() {
            if step(&mut lanes[i]) {
                finish(lanes.swap_remove(i));
            } else {
                i += 1;
            }
        }
    }
}
