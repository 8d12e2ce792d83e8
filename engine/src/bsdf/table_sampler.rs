//! A factored, tabulated importance sampler for smooth isotropic BRDFs, built from the BRDF
//! itself (RPV, RTLS, RTLS-H, Hapke, tabulated BRDFs): the sampler of
//! [`crate::bsdf::Bsdf::sample`] for every model but the Lambertian (exact cosine sampling) and
//! the ocean (facet sampling).
//!
//! **What it tabulates.** For `N_O` views (nodes at the centres of equal cells in
//! `cos θo ∈ [0, 1]`), the target density of `wi` is `f_r(wi, wo)·cos θi` (solid angle). In the
//! coordinates `s = cos²θi ∈ [0, 1]` and the relative azimuth `Δφ` (`cos θi dω = ½ ds dφ`) that
//! density is `∝ f_r` itself, so each node holds a piecewise-constant 2D distribution of `f_r`
//! over `N_S × N_PHI` equal cells in `(s, |Δφ|)`, `|Δφ| ∈ [0, π]` (isotropic BRDFs are even in
//! Δφ; the sign is drawn with probability ½): the value of a cell is `f_r` at its centre. It is
//! stored factored, as a marginal CDF over `s` and one conditional CDF over `|Δφ|` per `s` row
//! (as DIRSIG's and pbrt's tabulated samplers), in `f32`; probabilities are taken as differences
//! of the stored CDFs, so [`TableSampler::pdf`] is exactly the density that
//! [`TableSampler::sample`] draws.
//!
//! **Between nodes** the sampler draws from node j or j + 1 with probabilities `1 − t`, `t`
//! (linear in cos θo), so the table's density is the same mixture of the two nodes' densities.
//!
//! **Defensive mixture** (one-sample multiple importance sampling, Hesterberg 1995; Veach 1997
//! §9.2.3): with probability `ALPHA` the direction is drawn from the cosine-weighted hemisphere,
//! so `pdf = ALPHA·cos θi/π + (1 − ALPHA)·p_table` and the weight `f_r cos θi/pdf` is at most
//! `π f_r/ALPHA` wherever the table misses a narrow feature (a hot spot narrower than a cell)
//! and at most `(f_r/f_cell)·ρ/(1 − ALPHA)` elsewhere (`f_cell` the table's value of the cell,
//! ρ the directional albedo). This is the only MIS in surface sampling:
//! the Sun is a delta direction, so a BSDF sample never hits it and the next-event estimate to
//! the Sun needs no MIS weight (`docs/transport.md`).
//!
//! **Random numbers**: two uniforms, as the cosine sampler they replace (the counts per bounce
//! are fixed, `integrator/surface.rs`): the first chooses the component (cosine or node) and,
//! rescaled, the `s` cell and the position in it; the second the `Δφ` cell, the sign and the
//! position.
//!
//! **Cost**: `N_O·N_S·N_PHI` = 9 216 BRDF evaluations per model at construction (0.2–1.2 ms
//! depending on the model, `BENCHMARKS.md`), 39 KiB of CDFs shared by clones (`Arc`);
//! `sample` is two binary searches, one `sin_cos` and one `pdf`; `pdf` one binary search of
//! `cos Δφ` among the cells' bounds and two table lookups (no inverse trigonometry; about
//! 130 ns more per bounce than cosine sampling, `BENCHMARKS.md`).

use std::f64::consts::{FRAC_1_PI, PI};
use std::sync::Arc;

use glam::DVec3;

use crate::frame::sample_cosine_hemisphere;

/// View-zenith nodes.
pub const N_O: usize = 16;
/// Cells in `s = cos²θi`.
pub const N_S: usize = 24;
/// Cells in `|Δφ|` ∈ [0, π].
pub const N_PHI: usize = 24;
/// Probability of the cosine-weighted component of the defensive mixture.
pub const ALPHA: f64 = 0.15;

/// `cos(k·π/N_PHI)` for k = 0…N_PHI: the bounds of the Δφ cells.
static COS_BOUNDS: std::sync::LazyLock<[f64; N_PHI + 1]> = std::sync::LazyLock::new(|| {
    std::array::from_fn(|k| {
        if k == N_PHI {
            -1.0
        } else {
            (k as f64 * PI / N_PHI as f64).cos()
        }
    })
});

/// Largest f64 below 1, to keep rescaled uniforms in [0, 1).
const BELOW_ONE: f64 = 1.0 - f64::EPSILON / 2.0;

/// The CDFs of one view-zenith node.
struct Node {
    /// Marginal CDF over the `s` rows, `N_S + 1` values from 0 to exactly 1.
    marginal: [f32; N_S + 1],
    /// Conditional CDFs over `|Δφ|`, `N_PHI + 1` values per row, each from 0 to exactly 1.
    conditional: [[f32; N_PHI + 1]; N_S],
}

/// See the module header. Cheap to clone (the tables are shared).
#[derive(Clone)]
pub struct TableSampler {
    nodes: Arc<[Node]>,
}

impl std::fmt::Debug for TableSampler {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "TableSampler({N_O}×{N_S}×{N_PHI})")
    }
}

/// Fills `out` (length `v.len() + 1`) with the CDF of the cell values `v`: 0, …, exactly 1;
/// uniform when the values sum to zero. Returns the sum.
fn fill_cdf(v: &[f64], out: &mut [f32]) -> f64 {
    let total: f64 = v.iter().sum();
    let n = v.len();
    out[0] = 0.0;
    let mut acc = 0.0;
    for (i, x) in v.iter().enumerate() {
        acc += x;
        out[i + 1] = if total > 0.0 {
            (acc / total) as f32
        } else {
            (i + 1) as f32 / n as f32
        };
    }
    out[n] = 1.0;
    total
}

/// The cell `j` with `cdf[j] ≤ u < cdf[j + 1]` and `u` rescaled to [0, 1) within it.
#[inline]
fn pick(cdf: &[f32], u: f64) -> (usize, f64) {
    let n = cdf.len() - 1;
    let j = cdf.partition_point(|&c| f64::from(c) <= u).clamp(1, n) - 1;
    let (lo, hi) = (f64::from(cdf[j]), f64::from(cdf[j + 1]));
    (j, ((u - lo) / (hi - lo)).clamp(0.0, BELOW_ONE))
}

/// The unit vectors `(a, b)` of the horizontal plane from which relative azimuths are measured
/// for a view `wo`: `a` along the horizontal part of `wo` (the x axis for a vertical `wo`),
/// `b = z × a`.
#[inline]
pub(crate) fn azimuth_axes(wo: DVec3) -> (DVec3, DVec3) {
    let r = (wo.x * wo.x + wo.y * wo.y).sqrt();
    if r > 1e-12 {
        let (ax, ay) = (wo.x / r, wo.y / r);
        (DVec3::new(ax, ay, 0.0), DVec3::new(-ay, ax, 0.0))
    } else {
        (DVec3::X, DVec3::Y)
    }
}

/// The node below `wo`'s cos θo and the weight `t` of the node above it.
#[inline]
fn node_weights(wo: DVec3) -> (usize, f64) {
    let x = wo.z.clamp(0.0, 1.0) * N_O as f64 - 0.5;
    if x <= 0.0 {
        (0, 0.0)
    } else if x >= (N_O - 1) as f64 {
        (N_O - 2, 1.0)
    } else {
        let j = x as usize;
        (j, x - j as f64)
    }
}

impl TableSampler {
    /// Tabulates `f(wi, wo)` (sr⁻¹, ≥ 0; negative or non-finite values count as 0) at the cell
    /// centres of every node. `f` must be isotropic (depend on the azimuths only through
    /// `|φi − φo|`).
    pub fn build(f: impl Fn(DVec3, DVec3) -> f64) -> Self {
        let mut nodes = Vec::with_capacity(N_O);
        let mut row = [0.0f64; N_PHI];
        let mut rows = [0.0f64; N_S];
        for n in 0..N_O {
            let mu_o = (n as f64 + 0.5) / N_O as f64;
            let wo = DVec3::new((1.0 - mu_o * mu_o).sqrt(), 0.0, mu_o);
            let mut node = Node {
                marginal: [0.0; N_S + 1],
                conditional: [[0.0; N_PHI + 1]; N_S],
            };
            for (j, total) in rows.iter_mut().enumerate() {
                let s = (j as f64 + 0.5) / N_S as f64;
                let (ct, st) = (s.sqrt(), (1.0 - s).sqrt());
                for (k, v) in row.iter_mut().enumerate() {
                    let dphi = (k as f64 + 0.5) / N_PHI as f64 * PI;
                    let wi = DVec3::new(st * dphi.cos(), st * dphi.sin(), ct);
                    let x = f(wi, wo);
                    *v = if x.is_finite() && x > 0.0 { x } else { 0.0 };
                }
                *total = fill_cdf(&row, &mut node.conditional[j]);
            }
            fill_cdf(&rows, &mut node.marginal);
            nodes.push(node);
        }
        TableSampler {
            nodes: nodes.into(),
        }
    }

    /// A sampler without tables, to be replaced by [`TableSampler::build`] (a model's
    /// constructor builds its sampler from the finished model).
    pub(crate) fn unbuilt() -> Self {
        TableSampler {
            nodes: Vec::new().into(),
        }
    }

    /// Draws `wi` given `wo` (local frame, `wo.z > 0`) from two uniforms in [0, 1).
    #[inline]
    pub fn sample(&self, wo: DVec3, u1: f64, u2: f64) -> DVec3 {
        if u1 < ALPHA {
            return sample_cosine_hemisphere(u1 / ALPHA, u2);
        }
        let u = ((u1 - ALPHA) / (1.0 - ALPHA)).min(BELOW_ONE);
        let (j0, t) = node_weights(wo);
        let (node, u) = if u < 1.0 - t {
            (&self.nodes[j0], (u / (1.0 - t)).min(BELOW_ONE))
        } else {
            (
                &self.nodes[j0 + 1],
                ((u - (1.0 - t)) / t).clamp(0.0, BELOW_ONE),
            )
        };
        let (j, us) = pick(&node.marginal, u);
        let s = (j as f64 + us) / N_S as f64;
        let (k, v) = pick(&node.conditional[j], u2);
        let (sign, v) = if v < 0.5 {
            (1.0, 2.0 * v)
        } else {
            (-1.0, 2.0 * v - 1.0)
        };
        let dphi = (k as f64 + v) / N_PHI as f64 * PI;
        let (ct, st) = (s.sqrt(), (1.0 - s).max(0.0).sqrt());
        let (a, b) = azimuth_axes(wo);
        let (sp, cp) = dphi.sin_cos();
        a * (st * cp) + b * (sign * st * sp) + DVec3::Z * ct
    }

    /// The solid-angle density of [`TableSampler::sample`] at `wi` given `wo`; 0 below the
    /// horizon.
    #[inline]
    pub fn pdf(&self, wi: DVec3, wo: DVec3) -> f64 {
        if wi.z <= 0.0 {
            return 0.0;
        }
        let ct = wi.z.min(1.0);
        let j = ((ct * ct * N_S as f64) as usize).min(N_S - 1);
        // The Δφ cell from cos Δφ against the cells' bounds (decreasing in Δφ).
        let (a, b) = azimuth_axes(wo);
        let (x, y) = (wi.dot(a), wi.dot(b));
        let r = (x * x + y * y).sqrt();
        let cos_dphi = if r > 0.0 { x / r } else { 1.0 };
        let k = COS_BOUNDS
            .partition_point(|&c| c > cos_dphi)
            .clamp(1, N_PHI)
            - 1;
        let cell = |n: &Node| {
            let pj = f64::from(n.marginal[j + 1]) - f64::from(n.marginal[j]);
            let row = &n.conditional[j];
            pj * (f64::from(row[k + 1]) - f64::from(row[k]))
        };
        let (j0, t) = node_weights(wo);
        let mut p = (1.0 - t) * cell(&self.nodes[j0]);
        if t > 0.0 {
            p += t * cell(&self.nodes[j0 + 1]);
        }
        // Density in (s, signed Δφ) is P/(2·Δs·Δφ); dω = ds dφ/(2 cos θ).
        let table = p * ct * (N_S * N_PHI) as f64 * FRAC_1_PI;
        ALPHA * ct * FRAC_1_PI + (1.0 - ALPHA) * table
    }
}
