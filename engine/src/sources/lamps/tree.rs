//! Many-light sampling: a binary tree over the lamps (a light BVH, after Conty Estevez & Kulla
//! 2018, *Importance sampling of many lights with adaptive tree splitting*, without the
//! orientation cones and the splitting), so that one lamp is drawn per next-event estimate in
//! O(log N) whatever the number of lamps, in proportion to an estimate of what it brings to
//! the shading point.
//!
//! Build: the lamps' positions split at the median of the longest axis of their bounding box,
//! down to one lamp per leaf. Each node keeps its box and its lamps' total power Φ (the
//! sampling weight of each lamp: its mean intensity over the run wavelengths times the solid
//! angle its profile fills).
//!
//! Draw at a point p: from the root, child k is taken with probability `w_k/(w_l + w_r)`,
//! `w_k = Φ_k / max(d_k², 1 m²)`, d_k the distance from p to the child's box (0 inside it: the
//! box's nearest possible lamp, so the lamps around p are found in O(log N) choices that
//! favour them, rather than halved at each level as a distance to the box's centre would); the
//! lamp's probability is the product of the choices, returned with it. On a one-sided surface
//! the weight also holds Conty Estevez & Kulla's receiver term, a bound of the cosine between
//! the surface normal and the directions to the box (at least 0.01): on the ground under a city
//! of lamps, a far box is seen at grazing angles and brings little. Every lamp of positive power keeps a
//! positive probability at every point, so the estimate `contribution/P` is unbiased whatever
//! the weights' quality (they only change the variance; tested in `mod.rs` against estimating
//! every lamp).

use glam::DVec3;

/// The distance below which a box's weight stops growing, m (a point on or next to a lamp).
pub const MIN_DISTANCE_M: f64 = 1.0;

/// A node: box, total power, and its two children or its one lamp.
#[derive(Clone, Debug)]
struct Node {
    lo: DVec3,
    hi: DVec3,
    power: f64,
    /// `Ok(lamp index)` for a leaf, `Err((left, right))` node indices otherwise.
    kind: Result<u32, (u32, u32)>,
}

/// A light tree.
#[derive(Clone, Debug, Default)]
pub struct LightTree {
    nodes: Vec<Node>,
}

impl LightTree {
    /// The tree over lamps at `positions` of sampling powers `power` (≥ 0; lamps of power 0 are
    /// left out, they are never drawn).
    pub fn new(positions: &[DVec3], power: &[f64]) -> Self {
        let mut ids: Vec<u32> = (0..positions.len() as u32)
            .filter(|&i| power[i as usize] > 0.0)
            .collect();
        let mut t = LightTree { nodes: Vec::new() };
        if !ids.is_empty() {
            t.build(&mut ids, positions, power);
        }
        t
    }

    fn build(&mut self, ids: &mut [u32], pos: &[DVec3], power: &[f64]) -> u32 {
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        let mut p = 0.0;
        for &i in ids.iter() {
            lo = lo.min(pos[i as usize]);
            hi = hi.max(pos[i as usize]);
            p += power[i as usize];
        }
        let me = self.nodes.len() as u32;
        self.nodes.push(Node {
            lo,
            hi,
            power: p,
            kind: Ok(ids[0]),
        });
        if ids.len() > 1 {
            let ext = hi - lo;
            let axis = if ext.x >= ext.y && ext.x >= ext.z {
                0
            } else if ext.y >= ext.z {
                1
            } else {
                2
            };
            let mid = ids.len() / 2;
            ids.select_nth_unstable_by(mid, |a, b| {
                pos[*a as usize][axis].total_cmp(&pos[*b as usize][axis])
            });
            let (left, right) = ids.split_at_mut(mid);
            let l = self.build(left, pos, power);
            let r = self.build(right, pos, power);
            self.nodes[me as usize].kind = Err((l, r));
        }
        me
    }

    /// How many lamps can be drawn.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    #[inline]
    fn weight(&self, k: u32, p: DVec3, normal: Option<DVec3>) -> f64 {
        let n = &self.nodes[k as usize];
        // The squared distance from p to the box (its nearest lamp's distance at most), at
        // least MIN_DISTANCE_M².
        let d = (n.lo - p).max(p - n.hi).max(DVec3::ZERO);
        let w = n.power / d.length_squared().max(MIN_DISTANCE_M * MIN_DISTANCE_M);
        match normal {
            None => w,
            Some(nr) => w * receiver_cosine(n, p, nr),
        }
    }

    /// The probability of taking child `l` rather than `r` at `p`.
    #[inline]
    fn left_probability(&self, l: u32, r: u32, p: DVec3, normal: Option<DVec3>) -> f64 {
        let (wl, wr) = (self.weight(l, p, normal), self.weight(r, p, normal));
        if wl + wr > 0.0 {
            wl / (wl + wr)
        } else {
            0.5
        }
    }

    /// Draw a lamp for shading point `p` (on a surface of unit normal `normal`, which only
    /// light from its side reaches; `None` in the air or on two-sided leaves) from the uniform
    /// number `u`: its index and probability.
    pub fn sample(&self, p: DVec3, normal: Option<DVec3>, mut u: f64) -> Option<(usize, f64)> {
        if self.nodes.is_empty() {
            return None;
        }
        let mut k = 0u32;
        let mut prob = 1.0;
        loop {
            match self.nodes[k as usize].kind {
                Ok(lamp) => return Some((lamp as usize, prob)),
                Err((l, r)) => {
                    let pl = self.left_probability(l, r, p, normal);
                    // Reuse the number: rescaled into the chosen branch.
                    if u < pl {
                        u /= pl;
                        prob *= pl;
                        k = l;
                    } else {
                        u = ((u - pl) / (1.0 - pl)).min(1.0 - f64::EPSILON);
                        prob *= 1.0 - pl;
                        k = r;
                    }
                }
            }
        }
    }

    /// The probability with which [`LightTree::sample`] draws lamp `lamp` at `p` (tests).
    pub fn probability(&self, p: DVec3, normal: Option<DVec3>, lamp: usize) -> f64 {
        fn walk(t: &LightTree, k: u32, p: DVec3, nr: Option<DVec3>, lamp: usize) -> Option<f64> {
            match t.nodes[k as usize].kind {
                Ok(i) => (i as usize == lamp).then_some(1.0),
                Err((l, r)) => {
                    let pl = t.left_probability(l, r, p, nr);
                    walk(t, l, p, nr, lamp)
                        .map(|q| q * pl)
                        .or_else(|| walk(t, r, p, nr, lamp).map(|q| q * (1.0 - pl)))
                }
            }
        }
        if self.nodes.is_empty() {
            return 0.0;
        }
        walk(self, 0, p, normal, lamp).unwrap_or(0.0)
    }
}

/// An upper bound of the cosine between the surface normal `nr` at `p` and the directions from
/// `p` to the box of `n` (Conty Estevez & Kulla 2018's receiver term): the angle to the box's
/// centre less the box's angular radius; at least 0.01, so that every lamp keeps a positive
/// probability (lamps behind the surface bring nothing, but a bound that is too tight would
/// bias nothing either: only zero would).
#[inline]
fn receiver_cosine(n: &Node, p: DVec3, nr: DVec3) -> f64 {
    let c = 0.5 * (n.lo + n.hi);
    let v = c - p;
    let d = v.length();
    let r = 0.5 * (n.hi - n.lo).length();
    if d <= r || d <= 0.0 {
        return 1.0;
    }
    let cos_c = (nr.dot(v) / d).clamp(-1.0, 1.0);
    let sin_a = r / d;
    let cos_a = (1.0 - sin_a * sin_a).max(0.0).sqrt();
    // cos(θ_c − α) when θ_c > α, else 1.
    let sin_c = (1.0 - cos_c * cos_c).max(0.0).sqrt();
    let cos_bound = if cos_c >= cos_a {
        1.0
    } else {
        cos_c * cos_a + sin_c * sin_a
    };
    cos_bound.clamp(0.01, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn probabilities_sum_to_one_and_match_the_draws() {
        let mut rng = crate::rng::Stream::new(3, [0, 0, 0, 0]);
        let n = 200;
        let pos: Vec<DVec3> = (0..n)
            .map(|_| DVec3::new(rng.next_f64() * 1000.0, rng.next_f64() * 1000.0, 8.0))
            .collect();
        let mut power: Vec<f64> = (0..n).map(|_| 0.5 + rng.next_f64()).collect();
        power[7] = 0.0;
        let t = LightTree::new(&pos, &power);
        let p = DVec3::new(300.0, 420.0, 0.0);
        let up = Some(DVec3::Z);
        let probs: Vec<f64> = (0..n).map(|i| t.probability(p, up, i)).collect();
        assert!((probs.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        assert_eq!(probs[7], 0.0);
        assert!(probs.iter().enumerate().all(|(i, q)| i == 7 || *q > 0.0));
        // The nearest lamps are favoured over far ones of equal power.
        let near = (0..n)
            .filter(|&i| i != 7)
            .min_by(|&a, &b| (pos[a] - p).length().total_cmp(&(pos[b] - p).length()))
            .unwrap();
        assert!(probs[near] > 5.0 / n as f64, "{}", probs[near]);
        // Draws: the returned probability is the lamp's, and frequencies follow it.
        let draws = 400_000;
        let mut count = vec![0usize; n];
        for _ in 0..draws {
            let (i, q) = t.sample(p, up, rng.next_f64()).unwrap();
            assert!((q - probs[i]).abs() < 1e-12);
            count[i] += 1;
        }
        let chi2: f64 = (0..n)
            .filter(|&i| probs[i] * draws as f64 >= 5.0)
            .map(|i| {
                let e = probs[i] * draws as f64;
                (count[i] as f64 - e).powi(2) / e
            })
            .sum();
        let df = (0..n).filter(|&i| probs[i] * draws as f64 >= 5.0).count() as f64;
        assert!(
            chi2 < df + 5.0 * (2.0 * df).sqrt(),
            "χ² {chi2} for {df} lamps"
        );
        assert!(LightTree::new(&pos, &vec![0.0; n])
            .sample(p, None, 0.3)
            .is_none());
    }
}
