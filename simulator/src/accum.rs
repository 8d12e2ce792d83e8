//! Tallies of a run: per-cell sums of samples and of their squares ([`Accum`]), and the result
//! of one measure at one wavelength ([`MeasureResult`]). Written by the run driver, read by the
//! products stage; sums merge exactly, so partial results of separate runs combine.

/// Component indices of an [`Accum`] cell: the total (Stokes I in polarized runs), its
/// single- and multiple-scattering parts, then Stokes Q, U, V (polarized runs only).
pub const TOTAL: usize = 0;
pub const SINGLE: usize = 1;
pub const MULTIPLE: usize = 2;
pub const Q: usize = 3;
pub const U: usize = 4;
pub const V: usize = 5;

/// Per-cell sums of samples and of their squares (and, for polarized runs, of the cross products
/// I·Q, I·U, Q·U, which the standard error of the degree of polarization needs). Sums merge
/// exactly, so partial results of separate runs combine.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Accum {
    /// Samples per cell.
    pub n: Vec<u64>,
    /// Components per cell: 3 (scalar) or 6 (polarized).
    pub ncomp: usize,
    /// `[cell * ncomp + component]`.
    pub sum: Vec<f64>,
    pub sum2: Vec<f64>,
    /// `[cell * 3 + k]` for (I·Q, I·U, Q·U); empty in scalar runs.
    pub cross: Vec<f64>,
    /// Per cell, of the total (I) only: sums of the third and fourth powers of the samples and
    /// the largest sample, for the heavy-tail diagnostic ([`Accum::tail`]).
    pub sum3: Vec<f64>,
    pub sum4: Vec<f64>,
    pub max: Vec<f64>,
}

/// Heavy-tail diagnostic of one cell (see [`Accum::tail`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tail {
    /// Relative variance of the variance estimate (MCNP's VOV):
    /// `Σ(x−x̄)⁴ / (Σ(x−x̄)²)² − 1/N`. Below 0.1 the standard error is trustworthy.
    pub vov: f64,
    /// The largest single sample's share of the sum.
    pub max_share: f64,
}

impl Tail {
    /// Whether the cell's standard error can be trusted: VOV ≤ [`VOV_LIMIT`].
    pub fn trusted(&self) -> bool {
        self.vov <= VOV_LIMIT
    }
}

/// Cells with fewer samples are not judged by [`Accum::tail`]: their VOV is too noisy.
pub const TAIL_MIN_SAMPLES: u64 = 1000;
/// MCNP's threshold on the VOV (X-5 Monte Carlo Team 2003, vol. I, §2.6.9).
pub const VOV_LIMIT: f64 = 0.1;

impl Accum {
    pub fn new(cells: usize) -> Self {
        Self {
            n: vec![0; cells],
            ncomp: 3,
            sum: vec![0.0; cells * 3],
            sum2: vec![0.0; cells * 3],
            cross: Vec::new(),
            sum3: vec![0.0; cells],
            sum4: vec![0.0; cells],
            max: vec![0.0; cells],
        }
    }

    pub fn new_polarized(cells: usize) -> Self {
        Self {
            n: vec![0; cells],
            ncomp: 6,
            sum: vec![0.0; cells * 6],
            sum2: vec![0.0; cells * 6],
            cross: vec![0.0; cells * 3],
            sum3: vec![0.0; cells],
            sum4: vec![0.0; cells],
            max: vec![0.0; cells],
        }
    }

    pub fn is_polarized(&self) -> bool {
        self.ncomp == 6
    }

    /// Add one sample (single part, multiple part) to `cell`.
    #[inline]
    pub fn add(&mut self, cell: usize, single: f64, multiple: f64) {
        let t = single + multiple;
        self.n[cell] += 1;
        self.add_tail(cell, t);
        let o = cell * self.ncomp;
        for (k, x) in [t, single, multiple].into_iter().enumerate() {
            self.sum[o + k] += x;
            self.sum2[o + k] += x * x;
        }
    }

    /// Add one polarized sample: I split into single/multiple parts, and Q, U, V.
    #[inline]
    pub fn add_stokes(&mut self, cell: usize, single: f64, multiple: f64, q: f64, u: f64, v: f64) {
        let i = single + multiple;
        self.n[cell] += 1;
        self.add_tail(cell, i);
        let o = cell * 6;
        for (k, x) in [i, single, multiple, q, u, v].into_iter().enumerate() {
            self.sum[o + k] += x;
            self.sum2[o + k] += x * x;
        }
        let c = cell * 3;
        self.cross[c] += i * q;
        self.cross[c + 1] += i * u;
        self.cross[c + 2] += q * u;
    }

    #[inline]
    fn add_tail(&mut self, cell: usize, x: f64) {
        let x2 = x * x;
        self.sum3[cell] += x2 * x;
        self.sum4[cell] += x2 * x2;
        self.max[cell] = self.max[cell].max(x.abs());
    }

    /// Multiply every sample by `f` (the sums by f, the sums of squares and products by f², …).
    pub fn scale(&mut self, f: f64) {
        self.sum.iter_mut().for_each(|x| *x *= f);
        self.sum2.iter_mut().for_each(|x| *x *= f * f);
        self.cross.iter_mut().for_each(|x| *x *= f * f);
        self.sum3.iter_mut().for_each(|x| *x *= f * f * f);
        self.sum4.iter_mut().for_each(|x| *x *= (f * f) * (f * f));
        self.max.iter_mut().for_each(|x| *x *= f.abs());
    }

    /// The heavy-tail diagnostic of the total in `cell`; `None` with fewer than
    /// [`TAIL_MIN_SAMPLES`] samples or a zero variance (relative to the sum of squares, below
    /// 1e-12: samples constant to ~6 digits). The central moments come from the power sums;
    /// their cancellation matters only for nearly constant samples, which is why those are
    /// left out: with exactly constant samples it once reported a VOV of 1e10 (a thermal run
    /// through a non-scattering layer, `tests/thermal.rs`).
    pub fn tail(&self, cell: usize) -> Option<Tail> {
        let n = self.n[cell];
        if n < TAIL_MIN_SAMPLES {
            return None;
        }
        let nf = n as f64;
        let o = cell * self.ncomp + TOTAL;
        let (s1, s2, s3, s4) = (self.sum[o], self.sum2[o], self.sum3[cell], self.sum4[cell]);
        let m = s1 / nf;
        let m2 = s2 - nf * m * m;
        // Samples equal to within float rounding (a zero-variance estimator, e.g. thermal
        // emission through a non-scattering layer over a black ground): the central moments
        // are rounding noise and there is no tail to judge.
        if m2 <= 1e-12 * s2 {
            return None;
        }
        let m4 = s4 - 4.0 * m * s3 + 6.0 * m * m * s2 - 3.0 * nf * m.powi(4);
        let vov = (m4.max(0.0) / (m2 * m2) - 1.0 / nf).max(0.0);
        let max_share = if s1.abs() > 0.0 {
            self.max[cell] / s1.abs()
        } else {
            0.0
        };
        Some(Tail { vov, max_share })
    }

    /// Add `other` (same layout) into self; exact merge of partial results.
    pub fn merge(&mut self, other: &Accum) {
        assert_eq!(
            self.ncomp, other.ncomp,
            "merging accumulators of different kinds"
        );
        for (a, b) in self.n.iter_mut().zip(&other.n) {
            *a += b;
        }
        for (a, b) in self.sum.iter_mut().zip(&other.sum) {
            *a += b;
        }
        for (a, b) in self.sum2.iter_mut().zip(&other.sum2) {
            *a += b;
        }
        for (a, b) in self.cross.iter_mut().zip(&other.cross) {
            *a += b;
        }
        for (a, b) in self.sum3.iter_mut().zip(&other.sum3) {
            *a += b;
        }
        for (a, b) in self.sum4.iter_mut().zip(&other.sum4) {
            *a += b;
        }
        for (a, b) in self.max.iter_mut().zip(&other.max) {
            *a = a.max(*b);
        }
    }

    /// Add cell `from` of `other` into cell `to` of self.
    pub fn merge_cell(&mut self, to: usize, other: &Accum, from: usize) {
        let k = self.ncomp;
        self.n[to] += other.n[from];
        for j in 0..k {
            self.sum[to * k + j] += other.sum[from * k + j];
            self.sum2[to * k + j] += other.sum2[from * k + j];
        }
        if !self.cross.is_empty() {
            for j in 0..3 {
                self.cross[to * 3 + j] += other.cross[from * 3 + j];
            }
        }
        self.sum3[to] += other.sum3[from];
        self.sum4[to] += other.sum4[from];
        self.max[to] = self.max[to].max(other.max[from]);
    }

    /// Mean and standard error of the mean of component `k` in `cell`.
    pub fn mean_stderr(&self, cell: usize, k: usize) -> (f64, f64) {
        let n = self.n[cell] as f64;
        if n < 1.0 {
            return (f64::NAN, f64::NAN);
        }
        let o = cell * self.ncomp + k;
        let m = self.sum[o] / n;
        if n < 2.0 {
            return (m, f64::NAN);
        }
        let var = ((self.sum2[o] / n - m * m) * n / (n - 1.0)).max(0.0);
        (m, (var / n).sqrt())
    }

    /// Covariance of the means of (I, Q), (I, U) or (Q, U) (`pair` = 0, 1, 2) in `cell`.
    pub fn cov_of_means(&self, cell: usize, pair: usize) -> f64 {
        let n = self.n[cell] as f64;
        if n < 2.0 || self.cross.is_empty() {
            return f64::NAN;
        }
        let (a, b) = [(TOTAL, Q), (TOTAL, U), (Q, U)][pair];
        let o = cell * self.ncomp;
        let (ma, mb) = (self.sum[o + a] / n, self.sum[o + b] / n);
        (self.cross[cell * 3 + pair] / n - ma * mb) / (n - 1.0)
    }

    /// Relative standard error of the total of `cell` (0 for a zero mean with zero error,
    /// infinite for a zero mean with an error; NaN with fewer than two samples).
    fn rel_stderr(&self, cell: usize) -> f64 {
        let (m, e) = self.mean_stderr(cell, TOTAL);
        if m.abs() > 0.0 {
            e / m.abs()
        } else if e > 0.0 {
            f64::INFINITY
        } else {
            0.0
        }
    }

    /// Median over cells of the relative standard error of the total (cells without an
    /// estimate count as infinite).
    pub fn median_rel_stderr(&self) -> f64 {
        let mut r: Vec<f64> = (0..self.n.len())
            .map(|c| self.rel_stderr(c))
            .map(|x| if x.is_nan() { f64::INFINITY } else { x })
            .collect();
        if r.is_empty() {
            return 0.0;
        }
        r.sort_by(|a, b| a.total_cmp(b));
        r[r.len() / 2]
    }

    /// Largest relative standard error of the total over all cells.
    pub fn max_rel_stderr(&self) -> f64 {
        (0..self.n.len())
            .map(|c| self.rel_stderr(c))
            .fold(0.0, f64::max)
    }
}

/// Which walk serves a measure.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    Forward,
    Backward,
    /// Backward walk through a 3D scene (`integrator::backward` over a scene geometry).
    Scene,
}

impl Method {
    pub fn name(self) -> &'static str {
        match self {
            Method::Forward => "forward",
            Method::Backward => "backward",
            Method::Scene => "scene",
        }
    }
}

/// Result of one measure at one wavelength: sums per cell.
#[derive(Clone, Debug)]
pub struct MeasureResult {
    pub measure: usize,
    pub wavelength: usize,
    pub method: Method,
    pub acc: Accum,
}

#[cfg(test)]
mod tail_tests {
    use super::*;

    /// The VOV from power sums against its definition computed directly, merged blocks equal
    /// one accumulator, scaling leaves it unchanged; light tails pass, a Pareto tail (α = 1.5,
    /// infinite variance) fails.
    #[test]
    fn vov_of_light_and_heavy_tails() {
        let mut rng = crate::rng::Stream::new(5, [3, 1, 4, 1]);
        let n = 20_000;
        // Exponential samples (kurtosis 9): VOV ≈ (κ − 1)/N ≈ 4e-4.
        let light: Vec<f64> = (0..n).map(|_| -(1.0 - rng.next_f64()).ln()).collect();
        let heavy: Vec<f64> = (0..n)
            .map(|_| (1.0 - rng.next_f64()).powf(-1.0 / 1.5))
            .collect();
        for (xs, is_heavy) in [(&light, false), (&heavy, true)] {
            let mut a = Accum::new(1);
            let mut b1 = Accum::new(1);
            let mut b2 = Accum::new(1);
            for (i, &x) in xs.iter().enumerate() {
                a.add(0, x, 0.0);
                if i % 2 == 0 {
                    b1.add(0, 0.0, x)
                } else {
                    b2.add(0, x, 0.0)
                }
            }
            b1.merge(&b2);
            let m = xs.iter().sum::<f64>() / n as f64;
            let m2: f64 = xs.iter().map(|x| (x - m).powi(2)).sum();
            let m4: f64 = xs.iter().map(|x| (x - m).powi(4)).sum();
            let direct = m4 / (m2 * m2) - 1.0 / n as f64;
            let t = a.tail(0).unwrap();
            assert!(
                (t.vov - direct).abs() < 1e-9 * direct.max(1e-3),
                "{} vs {direct}",
                t.vov
            );
            assert!((b1.tail(0).unwrap().vov - t.vov).abs() < 1e-9 * t.vov.max(1e-3));
            let mut s = a.clone();
            s.scale(3.7);
            assert!((s.tail(0).unwrap().vov - t.vov).abs() < 1e-9 * t.vov.max(1e-3));
            let max = xs.iter().cloned().fold(0.0, f64::max);
            assert!((t.max_share - max / (m * n as f64)).abs() < 1e-12);
            assert_eq!(t.vov > VOV_LIMIT, is_heavy, "vov {}", t.vov);
        }
        // Too few samples: not judged.
        let mut few = Accum::new(1);
        for k in 0..(TAIL_MIN_SAMPLES - 1) {
            few.add(0, k as f64, 0.0);
        }
        assert!(few.tail(0).is_none());
    }
}
