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
    /// Quasi-random runs (`integrator.sampler = "sobol"`): the samples of each cell form
    /// [`REPLICATES`] independently scrambled Sobol sequences (sample `s` belongs to replicate
    /// `s mod R`, `rng.rs`), and these hold each replicate's sample count and component sums,
    /// `[cell * R + r]` and `[(cell * R + r) * ncomp + component]` (empty otherwise). The
    /// standard error is then the scatter of the replicate means ([`Accum::mean_stderr`]):
    /// the points of one scrambled net are not independent, so the i.i.d. formula
    /// overestimates their error, while independent scramblings give an honest one.
    #[serde(default)]
    pub rep_n: Vec<u64>,
    #[serde(default)]
    pub rep_sum: Vec<f64>,
    /// The replicate of the samples being added (set per sample by the walks; not stored).
    #[serde(skip)]
    pub rep_now: Option<usize>,
    /// An independent estimate added to every cell's mean, with the variance of its mean,
    /// `[cell * ncomp + component]` (empty: none): the lamps' light of nadir ortho images from
    /// forward photons (`integrator/lamp_photons.rs`), whose batches' scatter gives its error.
    /// [`Accum::mean_stderr`] adds the mean and the variance to the samples' own.
    #[serde(default)]
    pub extra_mean: Vec<f64>,
    #[serde(default)]
    pub extra_var: Vec<f64>,
}

/// Independent scramblings per cell in quasi-random runs (see [`Accum::rep_sum`]).
pub const REPLICATES: usize = 16;

/// The replicate of sample `s` of a cell in quasi-random runs (`rng.rs` scrambles each
/// replicate's points on their own).
#[inline]
pub fn replicate_of(s: u64) -> usize {
    (s % REPLICATES as u64) as usize
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
            rep_n: Vec::new(),
            rep_sum: Vec::new(),
            rep_now: None,
            extra_mean: Vec::new(),
            extra_var: Vec::new(),
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
            rep_n: Vec::new(),
            rep_sum: Vec::new(),
            rep_now: None,
            extra_mean: Vec::new(),
            extra_var: Vec::new(),
        }
    }

    pub fn is_polarized(&self) -> bool {
        self.ncomp == 6
    }

    /// `Err` with what is wrong when these sums cannot come from samples (a damaged or edited
    /// checkpoint or shard): array lengths that disagree with the cell count, a value that is
    /// not finite, a negative sum of squares, `n·Σx² < (Σx)²` (Cauchy–Schwarz, with a relative
    /// rounding margin of 1e-6), non-zero sums without samples, or replicate counts and sums
    /// that do not add up to the totals.
    pub fn check_invariants(&self) -> Result<(), String> {
        let cells = self.n.len();
        let nc = self.ncomp;
        if nc != 3 && nc != 6 {
            return Err(format!("{nc} components per cell (3 or 6)"));
        }
        let lens = [
            ("sum", self.sum.len(), cells * nc),
            ("sum2", self.sum2.len(), cells * nc),
            ("sum3", self.sum3.len(), cells),
            ("sum4", self.sum4.len(), cells),
            ("max", self.max.len(), cells),
            (
                "cross",
                self.cross.len(),
                if nc == 6 { cells * 3 } else { 0 },
            ),
        ];
        for (name, got, want) in lens {
            if got != want {
                return Err(format!(
                    "`{name}` has {got} values for {cells} cells (expected {want})"
                ));
            }
        }
        if !self.rep_n.is_empty()
            && (self.rep_n.len() != cells * REPLICATES
                || self.rep_sum.len() != self.rep_n.len() * nc)
        {
            return Err(format!(
                "replicate sums of the wrong length ({} counts, {} sums for {cells} cells)",
                self.rep_n.len(),
                self.rep_sum.len()
            ));
        }
        if !(self.extra_mean.is_empty() && self.extra_var.is_empty())
            && (self.extra_mean.len() != cells * nc || self.extra_var.len() != cells * nc)
        {
            return Err(format!(
                "added estimates of the wrong length ({} means, {} variances for {cells} cells)",
                self.extra_mean.len(),
                self.extra_var.len()
            ));
        }
        if let Some(i) = self.extra_var.iter().position(|&v| v < 0.0) {
            return Err(format!(
                "`extra_var`[{i}] = {} is negative",
                self.extra_var[i]
            ));
        }
        let all = [
            ("extra_mean", &self.extra_mean),
            ("extra_var", &self.extra_var),
            ("sum", &self.sum),
            ("sum2", &self.sum2),
            ("sum3", &self.sum3),
            ("sum4", &self.sum4),
            ("max", &self.max),
            ("cross", &self.cross),
            ("rep_sum", &self.rep_sum),
        ];
        for (name, v) in all {
            if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                return Err(format!("`{name}`[{i}] = {} is not finite", v[i]));
            }
        }
        for c in 0..cells {
            let n = self.n[c] as f64;
            if self.sum4[c] < 0.0 {
                return Err(format!("cell {c}: `sum4` = {} is negative", self.sum4[c]));
            }
            for k in 0..nc {
                let (s, q) = (self.sum[c * nc + k], self.sum2[c * nc + k]);
                if q < 0.0 {
                    return Err(format!("cell {c}: `sum2` = {q} is negative"));
                }
                if n == 0.0 && (s != 0.0 || q != 0.0) {
                    return Err(format!("cell {c}: sums {s}, {q} without samples"));
                }
                if n * q < s * s * (1.0 - 1e-6) {
                    return Err(format!(
                        "cell {c}: n·sum2 = {} < sum² = {} (no set of {n} samples has these sums)",
                        n * q,
                        s * s
                    ));
                }
            }
            if !self.rep_n.is_empty() {
                let r = &self.rep_n[c * REPLICATES..(c + 1) * REPLICATES];
                if r.iter().sum::<u64>() != self.n[c] {
                    return Err(format!(
                        "cell {c}: replicate counts add up to {}, not n = {}",
                        r.iter().sum::<u64>(),
                        self.n[c]
                    ));
                }
                for k in 0..nc {
                    let total: f64 = (0..REPLICATES)
                        .map(|j| self.rep_sum[(c * REPLICATES + j) * nc + k])
                        .sum();
                    let s = self.sum[c * nc + k];
                    let scale: f64 = (0..REPLICATES)
                        .map(|j| self.rep_sum[(c * REPLICATES + j) * nc + k].abs())
                        .sum::<f64>()
                        .max(s.abs());
                    if (total - s).abs() > 1e-9 * scale {
                        return Err(format!(
                            "cell {c}: replicate sums add up to {total}, not the total {s}"
                        ));
                    }
                }
            }
        }
        Ok(())
    }

    /// Add an independent estimate (mean `mean`, variance of that mean `var`) to component `k`
    /// of `cell` ([`Accum::extra_mean`]).
    pub fn add_extra(&mut self, cell: usize, k: usize, mean: f64, var: f64) {
        if self.extra_mean.is_empty() {
            self.extra_mean = vec![0.0; self.n.len() * self.ncomp];
            self.extra_var = vec![0.0; self.n.len() * self.ncomp];
        }
        let o = cell * self.ncomp + k;
        self.extra_mean[o] += mean;
        self.extra_var[o] += var;
    }

    /// Keep per-replicate sums (quasi-random runs); the walks then set [`Accum::rep_now`] to
    /// each sample's replicate before recording it.
    pub fn enable_replicates(&mut self) {
        let cells = self.n.len();
        if self.rep_n.is_empty() {
            self.rep_n = vec![0; cells * REPLICATES];
            self.rep_sum = vec![0.0; cells * REPLICATES * self.ncomp];
        }
    }

    /// The samples recorded next are sample `s` of their cell: with replicates enabled, they go
    /// to replicate `s mod R` as well (`rng.rs` scrambles that replicate's points); without,
    /// nothing.
    #[inline]
    pub fn begin_sample(&mut self, s: u64) {
        if !self.rep_n.is_empty() {
            self.rep_now = Some(replicate_of(s));
        }
    }

    #[inline]
    fn add_replicate(&mut self, cell: usize, x: &[f64]) {
        if let Some(r) = self.rep_now {
            if !self.rep_n.is_empty() {
                let i = cell * REPLICATES + r;
                self.rep_n[i] += 1;
                for (k, v) in x.iter().enumerate() {
                    self.rep_sum[i * self.ncomp + k] += v;
                }
            }
        }
    }

    /// Means of component `k` (and `k2`) per replicate of `cell`, with their sample counts, when
    /// every replicate has samples (None otherwise: too few samples to judge by replicates).
    fn replicate_means(&self, cell: usize, k: usize, k2: usize) -> Option<Vec<(f64, f64, f64)>> {
        if self.rep_n.is_empty() {
            return None;
        }
        let total: u64 = self.rep_n[cell * REPLICATES..(cell + 1) * REPLICATES]
            .iter()
            .sum();
        if total != self.n[cell] {
            // Samples recorded without replicates (e.g. a checkpoint of an older build).
            return None;
        }
        let mut out = Vec::with_capacity(REPLICATES);
        for r in 0..REPLICATES {
            let i = cell * REPLICATES + r;
            let n = self.rep_n[i];
            if n == 0 {
                return None;
            }
            let nf = n as f64;
            let o = i * self.ncomp;
            out.push((nf, self.rep_sum[o + k] / nf, self.rep_sum[o + k2] / nf));
        }
        Some(out)
    }

    /// Covariance of the means of components `a` and `b` of `cell` from the replicates:
    /// `Σ_r n_r (a_r − ā)(b_r − b̄) / ((R − 1)·N)` (for equal `n_r`, the sample covariance of
    /// the replicate means over R), or None without full replicates.
    fn replicate_cov(&self, cell: usize, a: usize, b: usize) -> Option<f64> {
        let reps = self.replicate_means(cell, a, b)?;
        let n: f64 = reps.iter().map(|r| r.0).sum();
        let ma = reps.iter().map(|r| r.0 * r.1).sum::<f64>() / n;
        let mb = reps.iter().map(|r| r.0 * r.2).sum::<f64>() / n;
        let c: f64 = reps.iter().map(|r| r.0 * (r.1 - ma) * (r.2 - mb)).sum();
        Some(c / ((REPLICATES as f64 - 1.0) * n))
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
        self.add_replicate(cell, &[t, single, multiple]);
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
        self.add_replicate(cell, &[i, single, multiple, q, u, v]);
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
        self.rep_sum.iter_mut().for_each(|x| *x *= f);
        self.extra_mean.iter_mut().for_each(|x| *x *= f);
        self.extra_var.iter_mut().for_each(|x| *x *= f * f);
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
        let terms = [s4, -4.0 * m * s3, 6.0 * m * m * s2, -3.0 * nf * m.powi(4)];
        let m4: f64 = terms.iter().sum();
        // The raw-moment form cancels: its rounding error (~ε·Σ|terms|) must stay well below
        // the m2² it is compared with, or the ratio is noise (near-deterministic estimators,
        // e.g. thermal emission where a few walks reach a thin scattering layer, relative
        // sample spread 1e-6: a vov of 1 from rounding alone).
        let rounding = 16.0 * f64::EPSILON * terms.iter().map(|t| t.abs()).sum::<f64>();
        if rounding > 1e-3 * m2 * m2 {
            return None;
        }
        // A standard error below 1e-5 of the mean: even if a rare walk carried it all (a vov
        // of 1: one walk of n differs, e.g. the few that reach a thin scattering layer under
        // an opaque band), the estimate is settled far below any digit reported.
        if m2 / (nf * nf) < 1e-10 * m * m {
            return None;
        }
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
        for c in 0..other.extra_mean.len() / other.ncomp.max(1) {
            for k in 0..other.ncomp {
                let o = c * other.ncomp + k;
                self.add_extra(c, k, other.extra_mean[o], other.extra_var[o]);
            }
        }
        if !other.rep_n.is_empty() {
            self.enable_replicates();
            for (a, b) in self.rep_n.iter_mut().zip(&other.rep_n) {
                *a += b;
            }
            for (a, b) in self.rep_sum.iter_mut().zip(&other.rep_sum) {
                *a += b;
            }
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
        if !other.extra_mean.is_empty() {
            for j in 0..k {
                let o = from * k + j;
                self.add_extra(to, j, other.extra_mean[o], other.extra_var[o]);
            }
        }
        if !other.rep_n.is_empty() {
            self.enable_replicates();
            for r in 0..REPLICATES {
                let (i, j) = (to * REPLICATES + r, from * REPLICATES + r);
                self.rep_n[i] += other.rep_n[j];
                for c in 0..k {
                    self.rep_sum[i * k + c] += other.rep_sum[j * k + c];
                }
            }
        }
    }

    /// Mean and standard error of the mean of component `k` in `cell`: from the scatter of the
    /// replicate means in quasi-random runs once every replicate has samples, else from the
    /// samples' variance (independent samples).
    pub fn mean_stderr(&self, cell: usize, k: usize) -> (f64, f64) {
        let n = self.n[cell] as f64;
        if n < 1.0 {
            return (f64::NAN, f64::NAN);
        }
        let o = cell * self.ncomp + k;
        let (xm, xv) = match (self.extra_mean.get(o), self.extra_var.get(o)) {
            (Some(&a), Some(&b)) => (a, b),
            _ => (0.0, 0.0),
        };
        let m = self.sum[o] / n;
        if let Some(v) = self.replicate_cov(cell, k, k) {
            return (m + xm, (v.max(0.0) + xv).sqrt());
        }
        if n < 2.0 {
            return (m + xm, f64::NAN);
        }
        let var = ((self.sum2[o] / n - m * m) * n / (n - 1.0)).max(0.0);
        (m + xm, (var / n + xv).sqrt())
    }

    /// Covariance of the means of (I, Q), (I, U) or (Q, U) (`pair` = 0, 1, 2) in `cell`.
    pub fn cov_of_means(&self, cell: usize, pair: usize) -> f64 {
        let n = self.n[cell] as f64;
        if n < 2.0 || self.cross.is_empty() {
            return f64::NAN;
        }
        let (a, b) = [(TOTAL, Q), (TOTAL, U), (Q, U)][pair];
        if let Some(c) = self.replicate_cov(cell, a, b) {
            return c;
        }
        let o = cell * self.ncomp;
        let (ma, mb) = (self.sum[o + a] / n, self.sum[o + b] / n);
        (self.cross[cell * 3 + pair] / n - ma * mb) / (n - 1.0)
    }

    /// Relative standard error of the total of `cell` (0 for a zero mean with zero error,
    /// infinite for a zero mean with an error; NaN with fewer than two samples).
    fn rel_stderr(&self, cell: usize) -> f64 {
        let (m, e) = self.mean_stderr(cell, TOTAL);
        relative(m, e)
    }

    /// Median over cells of the relative standard error of the total (cells without an
    /// estimate count as infinite).
    pub fn median_rel_stderr(&self) -> f64 {
        self.quantile_rel_stderr(0.5)
    }

    /// The `q`-quantile (0 < q ≤ 1) over cells of the relative standard error of the total:
    /// the value at index ⌊q·N⌋ (the last for q = 1) of the sorted errors, so that a fraction q
    /// of the cells is at most it (cells without an estimate count as infinite).
    pub fn quantile_rel_stderr(&self, q: f64) -> f64 {
        quantile(
            (0..self.n.len()).map(|c| self.cell_rel_stderr(c)).collect(),
            q,
        )
    }

    /// The relative standard error of the total of `cell` (infinite without an estimate).
    pub fn cell_rel_stderr(&self, cell: usize) -> f64 {
        let x = self.rel_stderr(cell);
        if x.is_nan() {
            f64::INFINITY
        } else {
            x
        }
    }

    /// Largest relative standard error of the total over all cells.
    pub fn max_rel_stderr(&self) -> f64 {
        (0..self.n.len())
            .map(|c| self.rel_stderr(c))
            .fold(0.0, f64::max)
    }
}

/// The relative error `e/|m|` of a mean `m` with standard error `e`: 0 for a zero mean with
/// zero error, infinite for a zero mean with an error.
pub fn relative(m: f64, e: f64) -> f64 {
    if m.abs() > 0.0 {
        e / m.abs()
    } else if e > 0.0 {
        f64::INFINITY
    } else {
        0.0
    }
}

/// The `q`-quantile (0 < q ≤ 1) of `r`: the value at index ⌊q·N⌋ (the last for q = 1) of the
/// sorted values, so that a fraction q of them is at most it; 0 for none.
pub fn quantile(mut r: Vec<f64>, q: f64) -> f64 {
    if r.is_empty() {
        return 0.0;
    }
    r.sort_by(|a, b| a.total_cmp(b));
    r[((q * r.len() as f64) as usize).min(r.len() - 1)]
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
    /// Rationale (issue 43): sums that samples produced pass, whatever the samples (equal ones
    /// included: n·Σx² = (Σx)² up to rounding), scalar, polarized and with replicates; doubled
    /// sums, a negative sum of squares, sums without samples, a NaN and replicates that do not
    /// add up are refused, naming the cell.
    #[test]
    fn invariants_of_sampled_sums() {
        let mut rng = crate::rng::Stream::new(9, [2, 7, 1, 8]);
        let mut a = Accum::new(3);
        for i in 0..5000 {
            a.add(i % 3, rng.next_f64(), 0.3);
        }
        let mut same = Accum::new(1);
        (0..1000).for_each(|_| same.add(0, 0.1, 0.2));
        let mut p = Accum::new_polarized(2);
        (0..100).for_each(|i| p.add_stokes(i % 2, 0.2, 0.1, -0.05, 0.01, 0.0));
        let mut r = Accum::new(2);
        r.enable_replicates();
        for s in 0..320u64 {
            r.rep_now = Some((s % REPLICATES as u64) as usize);
            r.add((s % 2) as usize, rng.next_f64(), 0.0);
        }
        for ok in [&a, &same, &p, &r] {
            ok.check_invariants().unwrap();
        }
        let mut doubled = a.clone();
        doubled.sum.iter_mut().for_each(|x| *x *= 2.0);
        doubled.sum2.iter_mut().for_each(|x| *x *= 2.0);
        assert!(doubled.check_invariants().unwrap_err().contains("n·sum2"));
        let mut neg = a.clone();
        neg.sum2[4] = -5.0;
        assert!(neg
            .check_invariants()
            .unwrap_err()
            .contains("cell 1: `sum2` = -5"));
        let mut none = Accum::new(2);
        none.sum[0] = 1.0;
        assert!(none
            .check_invariants()
            .unwrap_err()
            .contains("without samples"));
        let mut nan = a.clone();
        nan.max[0] = f64::NAN;
        assert!(nan.check_invariants().unwrap_err().contains("`max`[0]"));
        let mut rep = r.clone();
        rep.rep_sum[0] += 1.0;
        assert!(rep
            .check_invariants()
            .unwrap_err()
            .contains("replicate sums"));
        let mut short = a.clone();
        short.sum.pop();
        assert!(short.check_invariants().is_err());
    }

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

    /// Replicate errors (quasi-random runs): with every replicate filled, the standard error
    /// is the sample standard deviation of the replicate means over √R (equal counts), merged
    /// halves give the same sums, and without full replicates the i.i.d. formula applies.
    #[test]
    fn replicate_errors() {
        let mut rng = crate::rng::Stream::new(1, [2, 3, 4, 5]);
        let xs: Vec<f64> = (0..(REPLICATES * 10)).map(|_| rng.next_f64()).collect();
        let mut a = Accum::new(1);
        a.enable_replicates();
        let (mut h1, mut h2) = (Accum::new(1), Accum::new(1));
        h1.enable_replicates();
        h2.enable_replicates();
        for (s, &x) in xs.iter().enumerate() {
            for acc in [&mut a, if s < xs.len() / 2 { &mut h1 } else { &mut h2 }] {
                acc.begin_sample(s as u64);
                acc.add(0, x, 0.0);
            }
        }
        let means: Vec<f64> = (0..REPLICATES)
            .map(|r| xs.iter().skip(r).step_by(REPLICATES).sum::<f64>() / 10.0)
            .collect();
        let m = means.iter().sum::<f64>() / REPLICATES as f64;
        let sd =
            (means.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (REPLICATES as f64 - 1.0)).sqrt();
        let (mean, se) = a.mean_stderr(0, TOTAL);
        assert!((mean - m).abs() < 1e-12);
        assert!((se - sd / (REPLICATES as f64).sqrt()).abs() < 1e-12, "{se}");
        let mut merged = Accum::new(1);
        merged.merge(&h1);
        merged.merge(&h2);
        assert_eq!(merged.rep_n, a.rep_n);
        assert!((merged.mean_stderr(0, TOTAL).1 - se).abs() < 1e-12);
        // One replicate empty: the i.i.d. formula.
        let mut part = Accum::new(1);
        part.enable_replicates();
        for (s, &x) in xs.iter().enumerate().take(REPLICATES - 1) {
            part.begin_sample(s as u64);
            part.add(0, x, 0.0);
        }
        let mut plain = Accum::new(1);
        for &x in xs.iter().take(REPLICATES - 1) {
            plain.add(0, x, 0.0);
        }
        assert_eq!(part.mean_stderr(0, TOTAL), plain.mean_stderr(0, TOTAL));
    }
}
