//! Monte Carlo integrators for plane-parallel atmospheres over a flat surface.
//!
//! * [`forward`]: photons leave the Sun; at every interaction a *local estimate* (next-event
//!   estimation towards the sensor) is added for **every** direction of a distant measure, so one
//!   walk serves all directions at once (the method of MYSTIC and SMART-G). Used for `mdistant`
//!   and `distant_flux`.
//! * [`backward`]: paths leave the sensor; at every interaction a local estimate towards the Sun
//!   is added (next-event estimation). Used for `radiancemeter`, and for distant measures when
//!   asked for (a cross-check of the forward walk: two independent estimators of one quantity).
//!
//! Both produce samples of the *normalised radiance* `π·L/(E0·cos SZA)` (the BRF for a TOA
//! measure) or, for fluxes, of `F↑/(E0·cos SZA)`; each sample is split into its single-scattering
//! part (paths with one interaction, at the surface or in the atmosphere) and the rest.
//!
//! Weights: absorption multiplies the weight by the single-scattering albedo (survival biasing);
//! Russian roulette starts at scattering order `rr_depth` and only touches weights below
//! [`RR_THRESHOLD`], so it is unbiased and costs little variance.

pub mod backward;
pub mod forward;

/// Weight below which Russian roulette plays (after `rr_depth` interactions).
pub const RR_THRESHOLD: f64 = 0.25;

/// Per-cell sums of samples and of their squares, for the total and its two parts.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Accum {
    /// Samples per cell.
    pub n: Vec<u64>,
    /// `[cell][component]` with components (total, single, multiple).
    pub sum: Vec<[f64; 3]>,
    pub sum2: Vec<[f64; 3]>,
}

impl Accum {
    pub fn new(cells: usize) -> Self {
        Self { n: vec![0; cells], sum: vec![[0.0; 3]; cells], sum2: vec![[0.0; 3]; cells] }
    }

    /// Add one sample (single part, multiple part) to `cell`.
    #[inline]
    pub fn add(&mut self, cell: usize, single: f64, multiple: f64) {
        let t = single + multiple;
        self.n[cell] += 1;
        let s = &mut self.sum[cell];
        let q = &mut self.sum2[cell];
        s[0] += t;
        s[1] += single;
        s[2] += multiple;
        q[0] += t * t;
        q[1] += single * single;
        q[2] += multiple * multiple;
    }

    /// Add `other` (same cell count) into self; exact merge of partial results.
    pub fn merge(&mut self, other: &Accum) {
        for c in 0..self.n.len() {
            self.n[c] += other.n[c];
            for k in 0..3 {
                self.sum[c][k] += other.sum[c][k];
                self.sum2[c][k] += other.sum2[c][k];
            }
        }
    }

    /// Mean and standard error of the mean of component `k` in `cell`.
    pub fn mean_stderr(&self, cell: usize, k: usize) -> (f64, f64) {
        let n = self.n[cell] as f64;
        if n < 1.0 {
            return (f64::NAN, f64::NAN);
        }
        let m = self.sum[cell][k] / n;
        if n < 2.0 {
            return (m, f64::NAN);
        }
        let var = ((self.sum2[cell][k] / n - m * m) * n / (n - 1.0)).max(0.0);
        (m, (var / n).sqrt())
    }

    /// Largest relative standard error of the total over all cells.
    pub fn max_rel_stderr(&self) -> f64 {
        (0..self.n.len())
            .map(|c| {
                let (m, e) = self.mean_stderr(c, 0);
                if m.abs() > 0.0 { e / m.abs() } else if e > 0.0 { f64::INFINITY } else { 0.0 }
            })
            .fold(0.0, f64::max)
    }
}

/// Russian roulette on a weight: returns false when the path dies.
#[inline]
pub(crate) fn roulette(w: &mut f64, u: f64) -> bool {
    if *w >= RR_THRESHOLD {
        return true;
    }
    let p = *w / RR_THRESHOLD;
    if u < p {
        *w = RR_THRESHOLD;
        true
    } else {
        false
    }
}
