//! Several sensor bands in one run (`[spectral] bands = [...]`): every output is a band,
//! sampled by spectral Monte Carlo over the band's quadrature nodes, so that a sample of all
//! bands costs what a sample of their centre wavelengths costs.
//!
//! **Nodes.** In mono mode each band is sampled at `band_nodes` wavelengths of equal share:
//! the midpoints of the quantiles of `S(λ)·E0(λ)` on a 0.05 nm grid ([`quantile_nodes`]), so
//! the band BRF is their plain mean and the solar lines are in the weights. In `mode = "ckd"`
//! the absorption data's bins sample it as `srf` does (`w = ∫_bin S dλ`), each bin split into
//! its g-points (weight `w · g-weight`, the g-point's gas absorption). A node's *share* of its band is
//! `a_n = w_n E0_n / Σ w E0` (E0 the solar irradiance at the node), so that the band BRF is
//! `Σ a_n BRF_n` and the band radiance `E0_b · Σ a_n (L_n / E0_n)` with
//! `E0_b = Σ w E0 / Σ w`, the definitions of band quantities of the `srf` runs.
//!
//! **Sets.** Each band draws its node with probability `p_n` (its share `a_n` in mono mode;
//! in CKD mode the defensive mixture `p_n = a_n/2 + a_n t_n / (2 Σ a t)`, `t_n =
//! exp(−τ_abs (1/μ0 + 1))` the node's gas transmittance down at the Sun's zenith and back up
//! vertically, so that in absorption bands half the samples go where the light is and no factor
//! exceeds 2) and scores its channel's value times `f = a_n / p_n`, so that the expectation is
//! `Σ_n a_n v_n`: the band's quadrature, exactly. The bands of a walk are coupled
//! comonotonically: each band lays its nodes' probabilities on [0, 1) (in an order shuffled per
//! band), a sample draws one `u` and every band takes the node whose interval holds it. The
//! cells of the common refinement are the *sets* a group's walks are built for (at most the
//! sum of the bands' node counts; in mono mode, where every band has `band_nodes` nodes of
//! equal share, exactly that many, with every factor 1). `u` is drawn from a hash of the seed,
//! the measure and the sample index, the same for every pixel (an image's above-scene pool
//! serves every pixel). Samples are independent, so the usual per-cell standard errors hold;
//! the spectral variation inside a band adds to them.
//!
//! Reference: spectral Monte Carlo integration over a band's response is what MYSTIC
//! (Mayer 2009, "Radiative transfer in the cloudy atmosphere", EPJ Conf. 1) does; the
//! comonotone sets that let one precomputed walk carry one node of every band are ours.

use crate::spectral::srf::Srf;
use crate::spectral::{Band, Sampling};

/// Most nodes of a band (`band_nodes`; in CKD mode bins × g-points).
pub const MAX_NODES: usize = 1024;

/// Default `spectral.band_nodes`: wavelengths of equal share per band in mono mode.
pub const BAND_NODES: usize = 64;

/// Spacing of the fine grid a band's response and the solar spectrum are integrated on, nm
/// (both are linear between their samples, TSIS-1 every 1 nm).
const FINE_STEP: f64 = 0.05;

/// The fine grid over band `srf`'s support (where it is > 0, with the zeros just outside).
pub fn fine_grid(srf: &Srf) -> Vec<f64> {
    let first = srf.response.iter().position(|&r| r > 0.0);
    let last = srf.response.iter().rposition(|&r| r > 0.0);
    let (Some(first), Some(last)) = (first, last) else {
        return Vec::new();
    };
    let lo = srf.wavelength[first.saturating_sub(1)];
    let hi = srf.wavelength[(last + 1).min(srf.wavelength.len() - 1)];
    let n = ((hi - lo) / FINE_STEP).ceil().max(1.0) as usize;
    (0..=n)
        .map(|i| lo + (hi - lo) * i as f64 / n as f64)
        .collect()
}

/// `k` wavelengths of equal share of band `srf` (mono mode): the midpoints `(j + ½)/k` of the
/// cumulative distribution of `S(λ)·E0(λ)` on the fine `grid` (E0 `e0` there; trapezoids,
/// the quantile found linearly inside its cell), so that the band BRF is their plain mean (a
/// quadrature whose weights hold the solar lines exactly). Also the band's effective
/// wavelength `∫S λ / ∫S` and irradiance `∫S E0 / ∫S`.
pub fn quantile_nodes(
    srf: &Srf,
    grid: &[f64],
    e0: &[f64],
    k: usize,
) -> Result<(Vec<f64>, BandCentre), String> {
    let s: Vec<f64> = grid.iter().map(|&x| srf.at(x)).collect();
    let mut cdf = vec![0.0; grid.len()];
    let (mut ss, mut sl, mut se) = (0.0, 0.0, 0.0);
    for i in 1..grid.len() {
        let h = grid[i] - grid[i - 1];
        let f0 = s[i - 1] * e0[i - 1];
        let f1 = s[i] * e0[i];
        cdf[i] = cdf[i - 1] + 0.5 * (f0 + f1) * h;
        ss += 0.5 * (s[i - 1] + s[i]) * h;
        sl += 0.5 * (s[i - 1] * grid[i - 1] + s[i] * grid[i]) * h;
        se += 0.5 * (f0 + f1) * h;
    }
    let total = cdf.last().copied().unwrap_or(0.0);
    if !(total > 0.0 && ss > 0.0) {
        return Err(format!(
            "band \"{}\" has no response under the solar spectrum",
            srf.name
        ));
    }
    let nodes = (0..k)
        .map(|j| {
            let q = (j as f64 + 0.5) / k as f64 * total;
            let i = cdf.partition_point(|&c| c < q).clamp(1, grid.len() - 1);
            let t = (q - cdf[i - 1]) / (cdf[i] - cdf[i - 1]).max(f64::MIN_POSITIVE);
            grid[i - 1] + t.clamp(0.0, 1.0) * (grid[i] - grid[i - 1])
        })
        .collect();
    Ok((
        nodes,
        BandCentre {
            wavelength: sl / ss,
            irradiance: se / ss,
        },
    ))
}

/// The union of the bands' equal-share nodes (`each[b]`: band `b`'s nodes and centre), each
/// band weighing its nodes 1 (a node listed twice weighs 2).
pub fn union_quantiles(names: &[String], each: Vec<(Vec<f64>, BandCentre)>) -> Sampling {
    let (nodes, centres): (Vec<_>, Vec<_>) = each.into_iter().unzip();
    let mut s = union(
        names,
        nodes
            .into_iter()
            .map(|w| {
                let n = w.len();
                (w, vec![1.0; n])
            })
            .collect(),
    );
    s.centres = centres;
    s
}

/// The union of the bands' wavelengths (sorted, equal values merged) and each band's weights
/// over it (zero outside the band). `each[b]`: band `b`'s wavelengths and weights.
pub fn union(names: &[String], each: Vec<(Vec<f64>, Vec<f64>)>) -> Sampling {
    let mut wavelengths: Vec<f64> = each.iter().flat_map(|(w, _)| w.iter().copied()).collect();
    wavelengths.sort_by(f64::total_cmp);
    wavelengths.dedup();
    let bands = names
        .iter()
        .zip(each)
        .map(|(name, (w, wt))| {
            let mut weights = vec![0.0; wavelengths.len()];
            for (x, v) in w.iter().zip(wt) {
                let i = wavelengths.partition_point(|y| y < x);
                weights[i] += v;
            }
            Band {
                name: name.clone(),
                weights,
            }
        })
        .collect();
    Sampling {
        wavelengths,
        band: None,
        bands,
        centres: Vec::new(),
    }
}

/// How a run with `bands` draws its nodes (see the module header); the nodes themselves are
/// the run's ([`BandWalks`](crate::config::bands::BandWalks)).
#[derive(Clone, Debug)]
pub struct BandDraws {
    /// The bands' names, in output order.
    pub names: Vec<String>,
    /// Per band, its nodes in the order their probabilities are laid on [0, 1): (node, share
    /// `a`, probability `p`); shares and probabilities each sum to 1.
    pub draws: Vec<Vec<(usize, f64, f64)>>,
}

impl BandDraws {
    /// The draws of bands `names`: per band, its nodes as (node, share `a` (summing to 1), gas
    /// transmittance `t`). The probability is the defensive mixture `a/2 + a t / (2 Σ a t)`
    /// (`a` where nothing gets through), the order shuffled per band.
    pub fn new(names: Vec<String>, bands: Vec<Vec<(usize, f64, f64)>>) -> Self {
        let draws = bands
            .into_iter()
            .enumerate()
            .map(|(ib, list)| {
                let lit: f64 = list.iter().map(|&(_, a, t)| a * t).sum();
                let mut d: Vec<(usize, f64, f64)> = list
                    .iter()
                    .map(|&(n, a, t)| {
                        // No factor a/p exceeds 2.
                        let p = if lit > 0.0 {
                            0.5 * a + 0.5 * a * t / lit
                        } else {
                            a
                        };
                        (n, a, p)
                    })
                    .collect();
                shuffle(&mut d, ib as u64);
                d
            })
            .collect();
        BandDraws { names, draws }
    }
}

/// The sets of a group of bands: set `j` covers `[lo[j], lo[j + 1])` of [0, 1) (the last ends
/// at 1) and holds, per band of the group, the node whose interval contains it and its factor
/// `a/p`.
#[derive(Clone, Debug)]
pub struct Sets {
    pub lo: Vec<f64>,
    pub nodes: Vec<Vec<usize>>,
    pub factors: Vec<Vec<f64>>,
}

impl Sets {
    /// The set holding `u` ∈ [0, 1).
    pub fn at(&self, u: f64) -> usize {
        self.lo.partition_point(|&x| x <= u).saturating_sub(1)
    }
}

/// Per band: the effective wavelength `Σ w λ / Σ w` (nm) and the band irradiance
/// `E0_b = Σ w E0 / Σ w` (W m⁻² nm⁻¹).
#[derive(Clone, Copy, Debug)]
pub struct BandCentre {
    pub wavelength: f64,
    pub irradiance: f64,
}

impl BandDraws {
    /// The sets of bands `group`: the cells of the common refinement of the bands' partitions
    /// of [0, 1) into their nodes' probabilities (a comonotone coupling: each band's node is
    /// drawn with its own probability, exactly, whatever the other bands).
    pub fn sets(&self, group: &[usize]) -> Sets {
        // Each band's breakpoints, and the merged ones.
        let cuts: Vec<Vec<f64>> = group
            .iter()
            .map(|&b| {
                let mut c = Vec::with_capacity(self.draws[b].len() + 1);
                let mut acc = 0.0;
                c.push(0.0);
                for &(_, _, p) in &self.draws[b] {
                    acc += p;
                    c.push(acc);
                }
                // Rounding: the last cut is 1.
                let last = c.len() - 1;
                c[last] = 1.0;
                c
            })
            .collect();
        let mut lo: Vec<f64> = cuts
            .iter()
            .flat_map(|c| c[..c.len() - 1].iter().copied())
            .collect();
        lo.sort_by(f64::total_cmp);
        lo.dedup();
        let mut nodes = Vec::with_capacity(lo.len());
        let mut factors = Vec::with_capacity(lo.len());
        let mut keep = Vec::with_capacity(lo.len());
        for (j, &x) in lo.iter().enumerate() {
            let hi = lo.get(j + 1).copied().unwrap_or(1.0);
            if hi <= x {
                continue;
            }
            let mid = 0.5 * (x + hi);
            let (mut ns, mut fs) = (Vec::new(), Vec::new());
            for (k, &b) in group.iter().enumerate() {
                let i = cuts[k]
                    .partition_point(|&c| c <= mid)
                    .clamp(1, self.draws[b].len())
                    - 1;
                let (n, a, p) = self.draws[b][i];
                ns.push(n);
                fs.push(a / p);
            }
            keep.push(x);
            nodes.push(ns);
            factors.push(fs);
        }
        Sets {
            lo: keep,
            nodes,
            factors,
        }
    }

    /// The uniform number sample `s` of measure `im` draws its set with (the same for every
    /// cell of the measure, so that an image's above-scene pool serves every pixel).
    pub fn draw(seed: u64, im: usize, s: u64) -> f64 {
        let h = splitmix(splitmix(seed ^ 0xb5ad_4ece_da1c_e2a9) ^ ((im as u64) << 40) ^ s);
        (h >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Per band, its node count.
    pub fn node_counts(&self) -> Vec<usize> {
        self.draws.iter().map(Vec::len).collect()
    }
}

fn splitmix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Fisher–Yates with a fixed stream per band (the sets do not depend on the run's seed), so
/// that the bands' nodes are not drawn in step (a red and a blue node of the same rank).
fn shuffle<T>(v: &mut [T], band: u64) {
    let mut state = splitmix(0x5e75_u64 ^ (band << 17));
    for i in (1..v.len()).rev() {
        state = splitmix(state);
        let j = (state % (i as u64 + 1)) as usize;
        v.swap(i, j);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn walks(draws: Vec<Vec<(usize, f64, f64)>>) -> BandDraws {
        BandDraws {
            names: vec![],
            draws,
        }
    }

    /// Rationale: the sets reproduce every band's quadrature exactly: Σ_j (hi_j − lo_j) f v =
    /// Σ_n a_n v_n for any values v, with each band's nodes drawn with their own probabilities
    /// whatever the other bands' (the coupling's marginals are exact).
    #[test]
    fn sets_reproduce_each_bands_quadrature() {
        let band = |n: usize, seed: f64| -> Vec<(usize, f64, f64)> {
            let a: Vec<f64> = (0..n)
                .map(|i| 0.1 + ((i as f64 + seed) * 0.77).sin().abs())
                .collect();
            let p: Vec<f64> = (0..n)
                .map(|i| 0.3 + ((i as f64 - seed) * 1.3).cos().abs())
                .collect();
            let (sa, sp): (f64, f64) = (a.iter().sum(), p.iter().sum());
            (0..n).map(|i| (i, a[i] / sa, p[i] / sp)).collect()
        };
        let w = walks(vec![band(37, 0.2), band(5, 1.1), band(64, 2.7)]);
        let sets = w.sets(&[0, 1, 2]);
        assert!(sets.lo.len() <= 37 + 5 + 64);
        for (k, b) in [0usize, 1, 2].iter().enumerate() {
            let v = |n: usize| 1.0 + (n as f64 * 0.3).cos();
            let est: f64 = (0..sets.lo.len())
                .map(|j| {
                    let hi = sets.lo.get(j + 1).copied().unwrap_or(1.0);
                    (hi - sets.lo[j]) * sets.factors[j][k] * v(sets.nodes[j][k])
                })
                .sum();
            let exact: f64 = w.draws[*b].iter().map(|&(n, a, _)| a * v(n)).sum();
            assert!((est - exact).abs() < 1e-12, "band {b}: {est} vs {exact}");
        }
        // A draw lands in the set whose interval holds it.
        for u in [0.0, 0.25, 0.5, 0.999_999] {
            let j = sets.at(u);
            assert!(sets.lo[j] <= u && sets.lo.get(j + 1).is_none_or(|&h| u < h));
        }
    }

    /// Equal shares drawn with their shares: every factor is 1 (no spectral weight noise).
    #[test]
    fn equal_shares_have_unit_factors() {
        let eq = |n: usize| {
            (0..n)
                .map(|i| (i, 1.0 / n as f64, 1.0 / n as f64))
                .collect()
        };
        let w = walks(vec![eq(64), eq(64), eq(16)]);
        let sets = w.sets(&[0, 1, 2]);
        assert_eq!(sets.lo.len(), 64);
        assert!(sets
            .factors
            .iter()
            .flatten()
            .all(|&f| (f - 1.0).abs() < 1e-12));
    }

    /// The draws are uniform on [0, 1) (a χ² test over 64 cells).
    #[test]
    fn draws_are_uniform() {
        let n = 64_000u64;
        let mut count = [0u64; 64];
        for s in 0..n {
            let u = BandDraws::draw(7, 0, s);
            assert!((0.0..1.0).contains(&u));
            count[(u * 64.0) as usize] += 1;
        }
        let e = n as f64 / 64.0;
        let chi2: f64 = count.iter().map(|&c| (c as f64 - e).powi(2) / e).sum();
        // 63 degrees of freedom: the 99.9 % quantile is 103.4.
        assert!(chi2 < 103.4, "chi2 {chi2}");
    }

    #[test]
    fn union_merges_equal_wavelengths() {
        let s = union(
            &["a".into(), "b".into()],
            vec![
                (vec![440.0, 450.0], vec![1.0, 2.0]),
                (vec![450.0, 460.0], vec![3.0, 4.0]),
            ],
        );
        assert_eq!(s.wavelengths, vec![440.0, 450.0, 460.0]);
        assert_eq!(s.bands[0].weights, vec![1.0, 2.0, 0.0]);
        assert_eq!(s.bands[1].weights, vec![0.0, 3.0, 4.0]);
    }
}
