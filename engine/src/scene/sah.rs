//! Top-down binned-SAH build of a binary BVH over boxes (the instances' top level, before its
//! conversion to a wide tree in [`super::instances`]).
//!
//! **What.** Each node's primitives are split at the best of 16 bins per axis over their
//! centroids by the surface area heuristic (Wald 2007, "On fast construction of SAH-based
//! bounding volume hierarchies"): a node visit costs 1, a primitive test `isect`, and a range
//! of at most `max_leaf` primitives becomes a leaf when that is cheaper than splitting it. A
//! range whose centroids coincide (no plane separates them), and every range with `balanced`,
//! is split at the centroids' median along their widest axis (depth ⌈log₂ n⌉ whatever the
//! input).
//!
//! **Output.** obvhs-layout nodes ([`Bvh2Node`]: root at 0, the children of an inner node at
//! `first_index` and `first_index + 1`, a leaf's primitives the slots
//! `first_index..first_index + prim_count` of the returned slot → input index list).
//!
//! **Parallel.** Ranges of more than [`PARALLEL_MIN`] primitives build their two halves with
//! `rayon::join` (see [`subtree`]). Where a range is split depends only on the
//! boxes, so the tree is the same for any number of threads (the node *order* differs from a
//! sequential build's, not the tree).

use glam::Vec3A;
use obvhs::aabb::Aabb;
use obvhs::bvh2::node::Bvh2Node;

/// Bins per axis.
const BINS: usize = 16;
/// Ranges larger than this build their halves in parallel.
const PARALLEL_MIN: usize = 50_000;

/// Build parameters (see the module header).
#[derive(Clone, Copy, Debug)]
pub(crate) struct SahParams {
    pub max_leaf: usize,
    pub isect: f32,
    pub balanced: bool,
}

/// The tree over `boxes` (module header): (nodes, slot → input index). Empty input → empty.
/// `boxes` is left in slot order (`boxes[k]` is the box of input `idx[k]`): the build moves
/// each box with its index, so its passes read the boxes in order instead of through the
/// index (a cache miss per box on large inputs), with no copy of them.
pub(crate) fn build(boxes: &mut [Aabb], p: SahParams) -> (Vec<Bvh2Node>, Vec<u32>) {
    let n = boxes.len();
    if n == 0 {
        return (Vec::new(), Vec::new());
    }
    let mut idx: Vec<u32> = (0..n as u32).collect();
    let (b0, c0) = bound(boxes);
    // About 2n / (mean leaf size) nodes; only the pages written count.
    let mut nodes = Vec::with_capacity(2 * n);
    nodes.push(Bvh2Node::default());
    subtree(&mut nodes, 0, boxes, &mut idx, 0, b0, c0, p);
    (nodes, idx)
}

/// Edges from the root to the deepest leaf of an obvhs-layout binary tree.
pub(crate) fn depth(nodes: &[Bvh2Node]) -> usize {
    if nodes.is_empty() {
        return 0;
    }
    let mut deepest = 0;
    let mut todo = vec![(0usize, 0usize)];
    while let Some((i, d)) = todo.pop() {
        let n = &nodes[i];
        if n.is_leaf() {
            deepest = deepest.max(d);
        } else {
            todo.push((n.first_index as usize, d + 1));
            todo.push((n.first_index as usize + 1, d + 1));
        }
    }
    deepest
}

/// Box of `boxes` and box of their centroids (centroids are computed where needed rather than
/// stored: 16 B per primitive less at the build's peak).
fn bound(boxes: &[Aabb]) -> (Aabb, Aabb) {
    let mut b = Aabb::INVALID;
    let mut c = Aabb::INVALID;
    for a in boxes {
        b = b.union(a);
        c.extend(a.center());
    }
    (b, c)
}

fn half_area(b: &Aabb) -> f32 {
    let d = (b.max - b.min).max(Vec3A::ZERO);
    d.x * d.y + d.y * d.z + d.z * d.x
}

/// Build the subtree over `idx` (the slots from `base` on; box `nb`, centroid box `cb`) into
/// `out`: its root at `out[root]` (a slot the caller has allocated), the other nodes appended.
/// Leaves give global slots. A range of more than [`PARALLEL_MIN`] primitives builds its left
/// half into `out` and, at the same time, its right half into a list of its own, appended (the
/// only copy: at most the right half's nodes are held twice).
#[allow(clippy::too_many_arguments)]
fn subtree(
    out: &mut Vec<Bvh2Node>,
    root: usize,
    boxes: &mut [Aabb],
    idx: &mut [u32],
    base: usize,
    nb: Aabb,
    cb: Aabb,
    p: SahParams,
) {
    let n = idx.len();
    out[root] = Bvh2Node::new(nb, n as u32, base as u32);
    if n <= PARALLEL_MIN {
        return sequential(out, root, boxes, idx, base, cb, p);
    }
    let Some(Split {
        mid,
        left,
        right: rside,
    }) = split(boxes, idx, nb, cb, p)
    else {
        return;
    };
    let (li, ri) = idx.split_at_mut(mid);
    let (lb, rb) = boxes.split_at_mut(mid);
    let l = out.len();
    out.extend([Bvh2Node::default(); 2]);
    out[root].prim_count = 0;
    out[root].first_index = l as u32;
    let mut right = Vec::with_capacity(2 * ri.len());
    right.push(Bvh2Node::default());
    rayon::join(
        || subtree(out, l, lb, li, base, left.0, left.1, p),
        || subtree(&mut right, 0, rb, ri, base + mid, rside.0, rside.1, p),
    );
    // right[0] goes to slot l + 1, right[i ≥ 1] to the end of `out`.
    let shift = out.len() as u32 - 1;
    let at = |i: u32| if i == 0 { l as u32 + 1 } else { i + shift };
    let moved = |mut node: Bvh2Node| {
        if !node.is_leaf() {
            node.first_index = at(node.first_index);
        }
        node
    };
    out[l + 1] = moved(right[0]);
    out.extend(right[1..].iter().map(|&q| moved(q)));
}

/// The subtree over `idx` built in one thread (same convention as [`subtree`], whose caller
/// has set `out[root]` to the whole range as a leaf).
fn sequential(
    out: &mut Vec<Bvh2Node>,
    root: usize,
    boxes: &mut [Aabb],
    idx: &mut [u32],
    base: usize,
    cb: Aabb,
    p: SahParams,
) {
    // (node, start, end, centroid box), positions local to `idx`.
    let mut todo = vec![(root, 0usize, idx.len(), cb)];
    while let Some((ni, start, end, cb)) = todo.pop() {
        let range = &mut idx[start..end];
        let Some(Split { mid, left, right }) =
            split(&mut boxes[start..end], range, out[ni].aabb, cb, p)
        else {
            continue;
        };
        let mid = start + mid;
        let ((lb, lc), (rb, rc)) = (left, right);
        let l = out.len();
        out.push(Bvh2Node::new(
            lb,
            (mid - start) as u32,
            (base + start) as u32,
        ));
        out.push(Bvh2Node::new(rb, (end - mid) as u32, (base + mid) as u32));
        out[ni].prim_count = 0;
        out[ni].first_index = l as u32;
        todo.push((l + 1, mid, end, rc));
        todo.push((l, start, mid, lc));
    }
}

/// A split of a range: `idx[..mid]` on the left; each side's box and centroid box.
struct Split {
    mid: usize,
    left: (Aabb, Aabb),
    right: (Aabb, Aabb),
}

/// Where to split the range `idx` (box `nb`, centroid box `cb`): `Some` after partitioning
/// `idx` in place, `None` to keep it as a leaf. The three axes are binned in one pass over the
/// primitives, and the bins also give the two sides' boxes (unions of exact boxes, so the same
/// as a pass over each side would).
fn split(boxes: &mut [Aabb], idx: &mut [u32], nb: Aabb, cb: Aabb, p: SahParams) -> Option<Split> {
    let count = idx.len();
    if count <= 1 {
        return None;
    }
    let ext = cb.max - cb.min;
    let binned = [0, 1, 2].map(|axis| !(p.balanced && count > p.max_leaf) && ext[axis] > 0.0);
    let scale = [0, 1, 2].map(|axis| BINS as f32 * (1.0 - 1e-6) / ext[axis]);
    let bin =
        |c: Vec3A, axis: usize| (((c[axis] - cb.min[axis]) * scale[axis]) as usize).min(BINS - 1);
    // Per axis and bin: box, centroid box, count.
    let mut bb = [[Aabb::INVALID; BINS]; 3];
    let mut bcb = [[Aabb::INVALID; BINS]; 3];
    let mut bc = [[0u32; BINS]; 3];
    if binned.iter().any(|&b| b) {
        for a in boxes.iter() {
            let c = a.center();
            for axis in 0..3 {
                if binned[axis] {
                    let k = bin(c, axis);
                    bc[axis][k] += 1;
                    bb[axis][k] = bb[axis][k].union(a);
                    bcb[axis][k].extend(c);
                }
            }
        }
    }
    // Best split over the three axes: (cost, axis, bins on the left).
    let mut best = (f32::INFINITY, 0usize, 0usize);
    for axis in (0..3).filter(|&a| binned[a]) {
        let (bb, bc) = (&bb[axis], &bc[axis]);
        let mut right_area = [0f32; BINS];
        let mut cnt = [0u32; BINS];
        let (mut acc, mut c) = (Aabb::INVALID, 0);
        for k in (1..BINS).rev() {
            acc = acc.union(&bb[k]);
            c += bc[k];
            right_area[k] = half_area(&acc);
            cnt[k] = c;
        }
        let (mut acc, mut c) = (Aabb::INVALID, 0);
        for k in 0..BINS - 1 {
            acc = acc.union(&bb[k]);
            c += bc[k];
            if c == 0 || cnt[k + 1] == 0 {
                continue;
            }
            let cost = half_area(&acc) * c as f32 + right_area[k + 1] * cnt[k + 1] as f32;
            if cost < best.0 {
                best = (cost, axis, k + 1);
            }
        }
    }
    let parent_area = half_area(&nb).max(f32::MIN_POSITIVE);
    let split_cost = 1.0 + p.isect * best.0 / parent_area;
    let leaf_cost = p.isect * count as f32;
    if count <= p.max_leaf && leaf_cost <= split_cost {
        return None;
    }
    if best.0.is_finite() {
        let (axis, k) = (best.1, best.2);
        // In-place partition.
        let (mut a, mut b) = (0, count);
        while a < b {
            if bin(boxes[a].center(), axis) < k {
                a += 1;
            } else {
                b -= 1;
                idx.swap(a, b);
                boxes.swap(a, b);
            }
        }
        let side = |bins: std::ops::Range<usize>| {
            bins.fold((Aabb::INVALID, Aabb::INVALID), |(b, c), j| {
                (b.union(&bb[axis][j]), c.union(&bcb[axis][j]))
            })
        };
        return Some(Split {
            mid: a,
            left: side(0..k),
            right: side(k..BINS),
        });
    }
    // All centroids equal, or `balanced`: the median along the widest axis.
    let axis = if ext.x >= ext.y && ext.x >= ext.z {
        0
    } else if ext.y >= ext.z {
        1
    } else {
        2
    };
    let mid = count / 2;
    // The same selection on local positions (the same comparisons, so the same order as on
    // the indices themselves), then applied to both.
    let mut perm: Vec<u32> = (0..count as u32).collect();
    perm.select_nth_unstable_by(mid, |&a, &b| {
        let (ca, cb) = (boxes[a as usize].center(), boxes[b as usize].center());
        ca[axis].total_cmp(&cb[axis])
    });
    let moved_idx: Vec<u32> = perm.iter().map(|&k| idx[k as usize]).collect();
    let moved_boxes: Vec<Aabb> = perm.iter().map(|&k| boxes[k as usize]).collect();
    idx.copy_from_slice(&moved_idx);
    boxes.copy_from_slice(&moved_boxes);
    Some(Split {
        mid,
        left: bound(&boxes[..mid]),
        right: bound(&boxes[mid..]),
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::rng::Stream;

    /// `n` random boxes (1–5 m half-size) over a 10 km × 10 km × 30 m slab (test fixture,
    /// also of the BVH cache tests).
    pub(crate) fn boxes(n: usize, seed: u64) -> Vec<Aabb> {
        let mut rng = Stream::new(seed, [3, 0, 0, 0]);
        (0..n)
            .map(|_| {
                let c = Vec3A::new(
                    1e4 * rng.next_f64() as f32,
                    1e4 * rng.next_f64() as f32,
                    30.0 * rng.next_f64() as f32,
                );
                let h = Vec3A::splat(1.0 + 4.0 * rng.next_f64() as f32);
                Aabb::new(c - h, c + h)
            })
            .collect()
    }

    fn within(outer: &Aabb, inner: &Aabb) -> bool {
        outer.min.cmple(inner.min).all() && inner.max.cmple(outer.max).all()
    }

    /// The nodes of `nodes` in depth-first order (left first), as (box, leaf slots' inputs).
    fn canonical(nodes: &[Bvh2Node], idx: &[u32]) -> Vec<(Aabb, Vec<u32>)> {
        let mut out = Vec::new();
        let mut todo = vec![0usize];
        while let Some(i) = todo.pop() {
            let n = &nodes[i];
            if n.is_leaf() {
                let s = n.first_index as usize;
                out.push((n.aabb, idx[s..s + n.prim_count as usize].to_vec()));
            } else {
                out.push((n.aabb, Vec::new()));
                todo.push(n.first_index as usize + 1);
                todo.push(n.first_index as usize);
            }
        }
        out
    }

    /// The parallel build (ranges over [`PARALLEL_MIN`] split across threads) makes the same tree
    /// as a sequential build, with 1 and 2 threads; every node's box holds its primitives and
    /// every primitive is in exactly one leaf; the balanced build is ⌈log₂ n⌉ deep.
    #[test]
    fn parallel_build_equals_sequential() {
        let a = boxes(3 * PARALLEL_MIN, 5);
        let p = SahParams {
            max_leaf: 3,
            isect: 0.25,
            balanced: false,
        };
        let reference = {
            let mut idx: Vec<u32> = (0..a.len() as u32).collect();
            let mut boxes = a.clone();
            let (b0, c0) = bound(&boxes);
            let mut nodes = vec![Bvh2Node::new(b0, a.len() as u32, 0)];
            sequential(&mut nodes, 0, &mut boxes, &mut idx, 0, c0, p);
            canonical(&nodes, &idx)
        };
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut boxes = a.clone();
            let (nodes, idx) = pool.install(|| build(&mut boxes, p));
            assert!(idx.iter().zip(&boxes).all(|(&i, b)| a[i as usize] == *b));
            assert_eq!(canonical(&nodes, &idx), reference, "{threads} threads");
            // Boxes hold their children and primitives; each input once.
            let mut seen = vec![0u8; a.len()];
            for (k, n) in nodes.iter().enumerate() {
                if n.is_leaf() {
                    let s = n.first_index as usize;
                    for &i in &idx[s..s + n.prim_count as usize] {
                        seen[i as usize] += 1;
                        assert!(within(&n.aabb, &a[i as usize]), "node {k}");
                    }
                } else {
                    for c in [n.first_index, n.first_index + 1] {
                        assert!(within(&n.aabb, &nodes[c as usize].aabb), "node {k}");
                    }
                }
            }
            assert!(seen.iter().all(|&s| s == 1));
        }
        let (nodes, _) = build(
            &mut a.clone(),
            SahParams {
                balanced: true,
                ..p
            },
        );
        let n = a.len() as f64;
        assert!(
            depth(&nodes) <= n.log2().ceil() as usize,
            "{}",
            depth(&nodes)
        );
        assert_eq!(build(&mut [], p).0.len(), 0);
    }
}
