//! The time bins of a lidar waveform, and the spreading of a return over them by the pulse.
//!
//! Bins are uniform in the two-way delay `t` (ns) relative to `t0 = 2 R0 / c`: bin `k` covers
//! `[t_first + k·Δt − Δt/2, t_first + k·Δt + Δt/2]`. Bins given in apparent height (`bin_m`)
//! are the same bins, `z = z_c − c t / 2` (height bins of width `w` are time bins of `2w/c`,
//! in decreasing height). A return of energy `e` arriving at `t` adds to bin `k` the pulse's
//! integral over the bin: `e·[Φ((b_k − t)/σ_t) − Φ((a_k − t)/σ_t)]` for a Gaussian pulse of
//! standard deviation `σ_t`, all of `e` to the bin holding `t` for a delta pulse (a return on
//! a bin edge goes to the later bin). `Φ` is read from a table ([`normal_cdf`]), since a return
//! spreads over up to a hundred bins and `erf` would dominate the cost.

use std::sync::OnceLock;

use crate::atmosphere::particles::erf;

/// Standard normal CDF `Φ(x)` from a table (module header): cubic Hermite interpolation of
/// `Φ` with its exact derivative `φ` at nodes 10⁻³ apart over ±7 (error below 10⁻¹⁴).
#[inline]
pub fn normal_cdf(x: f64) -> f64 {
    const STEP: f64 = 1e-3;
    const HALF: f64 = 7.0;
    static TABLE: OnceLock<Vec<(f64, f64)>> = OnceLock::new();
    let table = TABLE.get_or_init(|| {
        let n = (2.0 * HALF / STEP).round() as usize;
        (0..=n)
            .map(|i| {
                let x = -HALF + i as f64 * STEP;
                let cdf = 0.5 * (1.0 + erf(x / std::f64::consts::SQRT_2));
                let pdf = (-0.5 * x * x).exp() / (std::f64::consts::TAU).sqrt();
                (cdf, pdf * STEP)
            })
            .collect()
    });
    if x <= -HALF {
        return 0.0;
    }
    if x >= HALF {
        return 1.0;
    }
    let f = (x + HALF) / STEP;
    let i = (f as usize).min(table.len() - 2);
    let t = f - i as f64;
    let ((p0, m0), (p1, m1)) = (table[i], table[i + 1]);
    let (t2, t3) = (t * t, t * t * t);
    (2.0 * t3 - 3.0 * t2 + 1.0) * p0
        + (t3 - 2.0 * t2 + t) * m0
        + (-2.0 * t3 + 3.0 * t2) * p1
        + (t3 - t2) * m1
}

/// Uniform time bins (see the module header).
#[derive(Clone, Debug, PartialEq)]
pub struct Bins {
    /// Centre of the first bin, ns.
    pub first_ns: f64,
    /// Width, ns.
    pub width_ns: f64,
    pub count: usize,
    /// Whether the experiment gave the bins in apparent height (`bin_m`): the products then
    /// list them from the highest (earliest) bin as given.
    pub in_height: bool,
}

impl Bins {
    /// Centre of bin `k`, ns.
    pub fn centre_ns(&self, k: usize) -> f64 {
        self.first_ns + k as f64 * self.width_ns
    }

    /// Add the pulse-spread energy `e` of a return at delay `t` (ns) to `out[k]` through
    /// `add(k, value)`; `sigma_ns = 0`: a delta pulse.
    #[inline]
    pub fn spread(&self, t: f64, e: f64, sigma_ns: f64, mut add: impl FnMut(usize, f64)) {
        let lo = self.first_ns - 0.5 * self.width_ns;
        if sigma_ns <= 0.0 {
            let k = ((t - lo) / self.width_ns).floor();
            if k >= 0.0 && (k as usize) < self.count {
                add(k as usize, e);
            }
            return;
        }
        // Bins within 7σ of t (Φ beyond is below 1.3e-12).
        let reach = 7.0 * sigma_ns;
        let k0 = (((t - reach) - lo) / self.width_ns).floor().max(0.0);
        let k1 = (((t + reach) - lo) / self.width_ns).ceil();
        if k1 < 0.0 || k0 >= self.count as f64 {
            return;
        }
        let (k0, k1) = (k0 as usize, (k1 as usize).min(self.count));
        let s = 1.0 / sigma_ns;
        let mut below = normal_cdf((lo + k0 as f64 * self.width_ns - t) * s);
        for k in k0..k1 {
            let above = normal_cdf((lo + (k + 1) as f64 * self.width_ns - t) * s);
            let f = above - below;
            if f > 0.0 {
                add(k, e * f);
            }
            below = above;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bins() -> Bins {
        Bins {
            first_ns: -10.0,
            width_ns: 0.5,
            count: 41,
            in_height: false,
        }
    }

    /// A Gaussian pulse well inside the bins puts all of its energy in them, centred on t.
    #[test]
    fn gaussian_spread_conserves_energy_and_mean() {
        let b = bins();
        let mut v = vec![0.0; b.count];
        b.spread(1.3, 2.0, 1.7, |k, x| v[k] += x);
        // The bins hold the pulse between their outer edges.
        let phi = |x: f64| 0.5 * (1.0 + erf(x / std::f64::consts::SQRT_2));
        let inside = 2.0 * (phi((10.25 - 1.3) / 1.7) - phi((-10.25 - 1.3) / 1.7));
        let sum: f64 = v.iter().sum();
        assert!((sum - inside).abs() < 1e-12, "{sum} {inside}");
        let mean: f64 = v
            .iter()
            .enumerate()
            .map(|(k, x)| x * b.centre_ns(k))
            .sum::<f64>()
            / sum;
        assert!((mean - 1.3).abs() < 1e-3, "{mean}");
        // Bin k's share is the normal integral over it.
        let k = 22; // centre 1.0
        let phi = |x: f64| 0.5 * (1.0 + erf(x / std::f64::consts::SQRT_2));
        let want = 2.0 * (phi((1.25 - 1.3) / 1.7) - phi((0.75 - 1.3) / 1.7));
        assert!((v[k] - want).abs() < 1e-13);
    }

    /// The table against erf over its range.
    #[test]
    fn normal_cdf_table_matches_erf() {
        let mut worst: f64 = 0.0;
        for i in 0..=20_000 {
            let x = -8.0 + i as f64 * 8e-4 + 1.3e-5;
            let want = 0.5 * (1.0 + erf(x / std::f64::consts::SQRT_2));
            worst = worst.max((normal_cdf(x) - want).abs());
        }
        // At most Φ(−7) beyond the table's ends.
        assert!(worst < 1.3e-12, "{worst}");
    }

    #[test]
    fn delta_pulse_goes_to_one_bin_and_edges_go_later() {
        let b = bins();
        let mut v = vec![0.0; b.count];
        b.spread(0.1, 1.0, 0.0, |k, x| v[k] += x);
        assert_eq!(v[20], 1.0);
        b.spread(0.25, 1.0, 0.0, |k, x| v[k] += x);
        assert_eq!(v[21], 1.0);
        // Outside the bins: nothing.
        b.spread(100.0, 1.0, 0.0, |k, x| v[k] += x);
        b.spread(100.0, 1.0, 2.0, |k, x| v[k] += x);
        assert_eq!(v.iter().sum::<f64>(), 2.0);
    }
}
