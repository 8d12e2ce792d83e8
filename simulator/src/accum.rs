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
}

impl Accum {
    pub fn new(cells: usize) -> Self {
        Self {
            n: vec![0; cells],
            ncomp: 3,
            sum: vec![0.0; cells * 3],
            sum2: vec![0.0; cells * 3],
            cross: Vec::new(),
        }
    }

    pub fn new_polarized(cells: usize) -> Self {
        Self {
            n: vec![0; cells],
            ncomp: 6,
            sum: vec![0.0; cells * 6],
            sum2: vec![0.0; cells * 6],
            cross: vec![0.0; cells * 3],
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

    /// Multiply every sample by `f` (the sums by f, the sums of squares and products by f²).
    pub fn scale(&mut self, f: f64) {
        self.sum.iter_mut().for_each(|x| *x *= f);
        self.sum2.iter_mut().for_each(|x| *x *= f * f);
        self.cross.iter_mut().for_each(|x| *x *= f * f);
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
