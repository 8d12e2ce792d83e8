//! Tabulated phase functions, read from libRadtran-format netCDF files (`*.mie.cdf`, written by
//! libRadtran's Mie tool or MOPSMAP).
//!
//! | config key    | unit | default            | meaning                                        |
//! |---------------|------|--------------------|------------------------------------------------|
//! | `file`        | —    | required           | path of the `.cdf`/`.nc` file                   |
//! | `wavelength`  | nm   | the run wavelength | use the table at this wavelength for every run wavelength (e.g. a single-wavelength file) |
//! | `size_index`  | —    | 0                  | index along the file's second dimension (`reff` or `hum`) |
//!
//! File layout used: `wavelen(nlam)` in µm; `theta(nlam, n2, nphamat, nthetamax)` in degrees (any
//! order); `phase(nlam, n2, nphamat, nthetamax)`; `ntheta(nlam, n2, nphamat)`. Scalar transport
//! uses `P11` only. Polarized runs use the full matrix: with `nphamat = 4` (spheres) the elements
//! are P11, P12, P33, P34 (P22 = P11, P44 = P33); with 6 (e.g. spheroids from MOPSMAP) P11, P12,
//! P33, P34, P22, P44 — i.e. `[[P11, P12, 0, 0], [P12, P22, 0, 0], [0, 0, P33, P34],
//! [0, 0, −P34, P44]]` in the scattering-plane frame of `stokes.rs`, each element interpolated
//! linearly in scattering angle and scaled with P11's normalisation.
//!
//! Representation: the table is interpolated **linearly in scattering angle** (the IPRT
//! convention) on a grid refined 16× between the file's nodes, and then treated as exactly
//! piecewise linear in cos Θ on that refined grid, renormalised to mean 1 over 4π. `eval`, the
//! CDF and `sample_cos` all use that one function, so sampling is exact for what is evaluated.
//! Between two tabulated wavelengths the two (normalised) tables are mixed linearly in wavelength.

use std::path::{Path, PathBuf};

use super::error::PhaseError;

/// Subdivisions of each file interval (linear in Θ) before the piecewise-linear-in-μ form.
const REFINE: usize = 16;

#[derive(Clone, Debug, PartialEq)]
pub struct Tabulated {
    /// Ascending cosines of the refined grid, from −1 to 1.
    mu: Vec<f64>,
    /// P at `mu`, mean 1 over the sphere.
    p: Vec<f64>,
    /// CDF of cos Θ at `mu` (density P/2), from 0 to 1.
    cdf: Vec<f64>,
    /// Polarized tables: the other phase-matrix elements (b1, a2, a3, b2, a4) at `mu`, with the
    /// same normalisation as `p`.
    pol: Option<[Vec<f64>; 5]>,
}

/// Linear interpolation in the first coordinate of sorted (x, y) pairs (clamped at the ends).
fn interp_sorted(pairs: &[(f64, f64)], x: f64) -> f64 {
    let i = pairs.partition_point(|p| p.0 <= x);
    if i == 0 {
        return pairs[0].1;
    }
    if i >= pairs.len() {
        return pairs[pairs.len() - 1].1;
    }
    let ((x0, y0), (x1, y1)) = (pairs[i - 1], pairs[i]);
    if x1 > x0 {
        y0 + (y1 - y0) * (x - x0) / (x1 - x0)
    } else {
        y0
    }
}

/// What went wrong reading a libRadtran phase-function file; each variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum PhaseTableError {
    /// netCDF cannot open the file or read one of its variables.
    #[error("cannot read phase-function file {}: {source}", path.display())]
    Netcdf {
        path: PathBuf,
        source: netcdf::Error,
    },
    /// A file that stops before the end its netCDF header declares, or whose classic header is
    /// damaged (`source` says how).
    #[error("phase-function file {}: {source}", path.display())]
    Truncated {
        path: PathBuf,
        source: crate::util::nc_complete::NcError,
    },
    /// A variable of the libRadtran layout is absent.
    #[error(
        "phase-function file {}: has no variable `{variable}` (not a libRadtran Mie file?)",
        path.display()
    )]
    MissingVariable {
        path: PathBuf,
        variable: &'static str,
    },
    /// `theta` with `found` dimensions instead of 4.
    #[error(
        "phase-function file {}: `theta` has {found} dimensions, expected 4",
        path.display()
    )]
    ThetaDimensions { path: PathBuf, found: usize },
    /// A `size_index` beyond the file's `sizes` entries.
    #[error(
        "phase-function file {}: `size_index` = {size_index} but the file has {sizes} size entries",
        path.display()
    )]
    SizeIndex {
        path: PathBuf,
        size_index: usize,
        sizes: usize,
    },
    /// `wavelen` with `wavelen` values where `theta` has `theta` wavelengths.
    #[error(
        "phase-function file {}: `wavelen` and `theta` disagree on the wavelength count",
        path.display()
    )]
    WavelengthCount {
        path: PathBuf,
        wavelen: usize,
        theta: usize,
    },
    /// An `ntheta` of P11 below 2 or above the file's angle dimension.
    #[error(
        "phase-function file {}: ntheta = {ntheta} out of range at wavelength index {wavelength_index}",
        path.display()
    )]
    Ntheta {
        path: PathBuf,
        ntheta: usize,
        wavelength_index: usize,
    },
    /// An `ntheta` of phase-matrix element `element` (from 1) out of range.
    #[error(
        "phase-function file {}: ntheta = {ntheta} out of range for element {element} at wavelength index {wavelength_index}",
        path.display()
    )]
    ElementNtheta {
        path: PathBuf,
        ntheta: usize,
        element: usize,
        wavelength_index: usize,
    },
    /// A table of the file that is not a phase function, at its wavelength.
    #[error(
        "phase-function file {}: wavelength {wavelength_nm} nm: {source}",
        path.display()
    )]
    Table {
        path: PathBuf,
        wavelength_nm: f64,
        source: PhaseError,
    },
    /// A `wavelen` value (µm) that is not finite, at `index`.
    #[error(
        "phase-function file {}: `wavelen` at index {index} is {value_um}, not a finite wavelength",
        path.display()
    )]
    WavelengthNotFinite {
        path: PathBuf,
        index: usize,
        value_um: f64,
    },
    /// A run wavelength outside the file's (`tabulated_nm`, in the file's order).
    #[error(
        "phase-function file {}: wavelength {wavelength_nm} nm is outside the tabulated range {tabulated_nm:?} nm; set the phase's `wavelength` key to use one table for every wavelength",
        path.display()
    )]
    WavelengthOutside {
        path: PathBuf,
        wavelength_nm: f64,
        tabulated_nm: Vec<f64>,
    },
}

impl Tabulated {
    /// Build from scattering angles (degrees, any order) and phase values (any positive scale).
    pub fn from_table(theta_deg: &[f64], values: &[f64]) -> Result<Self, PhaseError> {
        if theta_deg.len() != values.len() || theta_deg.len() < 2 {
            return Err(PhaseError::TooFewPairs {
                angles: theta_deg.len(),
                values: values.len(),
            });
        }
        let mut pairs: Vec<(f64, f64)> = theta_deg
            .iter()
            .copied()
            .zip(values.iter().copied())
            .collect();
        for &(t, v) in &pairs {
            if !t.is_finite() || !(0.0..=180.0).contains(&t) {
                return Err(PhaseError::Angle { theta: t });
            }
            if !v.is_finite() || v < 0.0 {
                return Err(PhaseError::Value { theta: t, value: v });
            }
        }
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
        pairs.dedup_by(|a, b| a.0 == b.0);
        if pairs[0].0 > 1e-9 || pairs[pairs.len() - 1].0 < 180.0 - 1e-9 {
            return Err(PhaseError::Span {
                first: pairs[0].0,
                last: pairs[pairs.len() - 1].0,
            });
        }
        // Refine linearly in Θ, then order by ascending μ (Θ descending).
        let mut mu = Vec::with_capacity(pairs.len() * REFINE);
        let mut p = Vec::with_capacity(pairs.len() * REFINE);
        for w in pairs.windows(2).rev() {
            let ((t0, v0), (t1, v1)) = (w[0], w[1]);
            for k in 0..REFINE {
                // From t1 down towards t0 (μ ascending).
                let f = k as f64 / REFINE as f64;
                let t = t1 + (t0 - t1) * f;
                mu.push(t.to_radians().cos());
                p.push(v1 + (v0 - v1) * f);
            }
        }
        mu.push(1.0);
        p.push(pairs[0].1);
        mu[0] = -1.0;
        Self::from_mu(mu, p)
    }

    /// Build a polarized table: P11 on `theta_deg`, and the elements (b1, a2, a3, b2, a4) each on
    /// its own angle grid (degrees), all interpolated linearly in scattering angle and sharing
    /// P11's normalisation.
    pub fn from_matrix_table(
        theta_deg: &[f64],
        p11: &[f64],
        elems: [(&[f64], &[f64]); 5],
    ) -> Result<Self, PhaseError> {
        let mut t = Self::from_table(theta_deg, p11)?;
        let mut raw: Vec<(f64, f64)> = theta_deg.iter().copied().zip(p11.iter().copied()).collect();
        raw.sort_by(|a, b| a.0.total_cmp(&b.0));
        // The normalisation factor applied to P11, recovered at the forward peak node.
        let scale = t.p[t.p.len() - 1] / raw[0].1.max(1e-300);
        let mut out: [Vec<f64>; 5] = Default::default();
        for (k, (th, val)) in elems.iter().enumerate() {
            if th.len() != val.len() || th.len() < 2 {
                return Err(PhaseError::ElementTooFewPairs { element: k + 2 });
            }
            let mut pairs: Vec<(f64, f64)> = th.iter().copied().zip(val.iter().copied()).collect();
            if pairs.iter().any(|p| !p.0.is_finite() || !p.1.is_finite()) {
                return Err(PhaseError::ElementNotFinite { element: k + 2 });
            }
            pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
            out[k] =
                t.mu.iter()
                    .map(|&m| interp_sorted(&pairs, m.clamp(-1.0, 1.0).acos().to_degrees()) * scale)
                    .collect();
        }
        t.pol = Some(out);
        Ok(t)
    }

    /// Whether the table carries a full phase matrix.
    pub fn is_polarized(&self) -> bool {
        self.pol.is_some()
    }

    /// Phase matrix at cos Θ (a depolarizer for P11-only tables).
    #[inline]
    pub fn matrix(&self, mu: f64) -> crate::stokes::PhaseMatrix {
        let mu = mu.clamp(-1.0, 1.0);
        let i = self.interval(mu);
        let (m0, m1) = (self.mu[i], self.mu[i + 1]);
        let f = if m1 > m0 { (mu - m0) / (m1 - m0) } else { 0.0 };
        let at = |v: &Vec<f64>| v[i] + (v[i + 1] - v[i]) * f;
        let a1 = at(&self.p);
        match &self.pol {
            None => crate::stokes::PhaseMatrix::depolarizing(a1),
            Some(e) => crate::stokes::PhaseMatrix {
                a1,
                b1: at(&e[0]),
                a2: at(&e[1]),
                a3: at(&e[2]),
                b2: at(&e[3]),
                a4: at(&e[4]),
            },
        }
    }

    fn from_mu(mu: Vec<f64>, mut p: Vec<f64>) -> Result<Self, PhaseError> {
        let mut cdf = vec![0.0; mu.len()];
        for i in 1..mu.len() {
            cdf[i] = cdf[i - 1] + 0.5 * (p[i] + p[i - 1]) * (mu[i] - mu[i - 1]);
        }
        let total = cdf[mu.len() - 1];
        if total.is_nan() || total <= 0.0 {
            return Err(PhaseError::ZeroIntegral);
        }
        // ∫P dμ must be 2 (mean 1 over the sphere).
        let scale = 2.0 / total;
        p.iter_mut().for_each(|v| *v *= scale);
        cdf.iter_mut().for_each(|v| *v /= total);
        Ok(Self {
            mu,
            p,
            cdf,
            pol: None,
        })
    }

    /// Linear mixture `(1−t)·a + t·b` of two normalised tables, on the union of their grids.
    pub fn mix(a: &Tabulated, b: &Tabulated, t: f64) -> Tabulated {
        let mut mu: Vec<f64> = a.mu.iter().chain(b.mu.iter()).copied().collect();
        mu.sort_by(|x, y| x.total_cmp(y));
        mu.dedup();
        let p: Vec<f64> = mu
            .iter()
            .map(|&m| (1.0 - t) * a.eval(m) + t * b.eval(m))
            .collect();
        let mut out = Self::from_mu(mu, p).expect("mixture of valid tables is valid");
        if a.is_polarized() && b.is_polarized() {
            // Both inputs are normalised, so the mixture needs no further scaling.
            let mats: Vec<_> = out.mu.iter().map(|&m| (a.matrix(m), b.matrix(m))).collect();
            let mix = |g: fn(&crate::stokes::PhaseMatrix) -> f64| -> Vec<f64> {
                mats.iter()
                    .map(|(x, y)| (1.0 - t) * g(x) + t * g(y))
                    .collect()
            };
            out.pol = Some([
                mix(|m| m.b1),
                mix(|m| m.a2),
                mix(|m| m.a3),
                mix(|m| m.b2),
                mix(|m| m.a4),
            ]);
        }
        out
    }

    #[inline]
    fn interval(&self, mu: f64) -> usize {
        // Index i with mu[i] <= mu < mu[i+1].
        let i = self.mu.partition_point(|&m| m <= mu);
        i.clamp(1, self.mu.len() - 1) - 1
    }

    /// `P(1)`: the value at the grid's last node (cos Θ = 1), without a search.
    #[inline]
    pub fn forward_peak(&self) -> f64 {
        self.p[self.p.len() - 1]
    }

    #[inline]
    pub fn eval(&self, mu: f64) -> f64 {
        let mu = mu.clamp(-1.0, 1.0);
        let i = self.interval(mu);
        let (m0, m1) = (self.mu[i], self.mu[i + 1]);
        let f = if m1 > m0 { (mu - m0) / (m1 - m0) } else { 0.0 };
        self.p[i] + (self.p[i + 1] - self.p[i]) * f
    }

    #[inline]
    pub fn sample_cos(&self, u: f64) -> f64 {
        let i = self
            .cdf
            .partition_point(|&c| c <= u)
            .clamp(1, self.cdf.len() - 1)
            - 1;
        let (m0, m1) = (self.mu[i], self.mu[i + 1]);
        let h = m1 - m0;
        if h <= 0.0 {
            return m0;
        }
        // Density P/2 linear on [m0, m1]: P(x) = p0 + s·x, x = μ − m0; solve
        // ½(p0 x + s x²/2) = target.
        let (p0, p1) = (self.p[i], self.p[i + 1]);
        let s = (p1 - p0) / h;
        let target = 2.0 * (u - self.cdf[i]).max(0.0);
        let x = if s.abs() < 1e-12 * p0.max(1e-300) {
            target / p0
        } else {
            let disc = (p0 * p0 + 2.0 * s * target).max(0.0);
            // Numerically stable root of (s/2)x² + p0 x − target = 0.
            2.0 * target / (p0 + disc.sqrt())
        };
        (m0 + x.clamp(0.0, h)).clamp(-1.0, 1.0)
    }

    /// ⟨cos Θ⟩, exact for the piecewise-linear representation.
    pub fn asymmetry(&self) -> f64 {
        let mut s = 0.0;
        for i in 0..self.mu.len() - 1 {
            let (a, b) = (self.mu[i], self.mu[i + 1]);
            let (pa, pb) = (self.p[i], self.p[i + 1]);
            // ∫ μ P dμ for P linear: exact Simpson.
            let m = 0.5 * (a + b);
            let pm = 0.5 * (pa + pb);
            s += (b - a) / 6.0 * (a * pa + 4.0 * m * pm + b * pb);
        }
        0.5 * s
    }

    /// Load `P11` from a libRadtran netCDF file, at `wavelength_nm` (linear mixture between the
    /// two bracketing tables; exact match within 1e-3 nm uses one table).
    pub fn load_libradtran(
        path: &Path,
        wavelength_nm: f64,
        size_index: usize,
    ) -> Result<Tabulated, PhaseTableError> {
        let p = || path.to_path_buf();
        let nc_err = |source| PhaseTableError::Netcdf { path: p(), source };
        let _session = crate::netcdf_session();
        crate::util::nc_complete::check(path)
            .map_err(|source| PhaseTableError::Truncated { path: p(), source })?;
        let file = netcdf::open(path).map_err(nc_err)?;
        let var = |name: &'static str| {
            file.variable(name)
                .ok_or_else(|| PhaseTableError::MissingVariable {
                    path: p(),
                    variable: name,
                })
        };
        let wl_um: Vec<f64> = var("wavelen")?.get_values::<f64, _>(..).map_err(nc_err)?;
        let theta_v = var("theta")?;
        let dims: Vec<usize> = theta_v.dimensions().iter().map(|d| d.len()).collect();
        if dims.len() != 4 {
            return Err(PhaseTableError::ThetaDimensions {
                path: p(),
                found: dims.len(),
            });
        }
        let (nlam, n2, nphamat, nthmax) = (dims[0], dims[1], dims[2], dims[3]);
        if size_index >= n2 {
            return Err(PhaseTableError::SizeIndex {
                path: p(),
                size_index,
                sizes: n2,
            });
        }
        let theta: Vec<f64> = theta_v.get_values::<f64, _>(..).map_err(nc_err)?;
        let phase: Vec<f64> = var("phase")?.get_values::<f64, _>(..).map_err(nc_err)?;
        let ntheta: Vec<i32> = var("ntheta")?.get_values::<i32, _>(..).map_err(nc_err)?;
        if wl_um.len() != nlam {
            return Err(PhaseTableError::WavelengthCount {
                path: p(),
                wavelen: wl_um.len(),
                theta: nlam,
            });
        }
        let table_at = |il: usize| -> Result<Tabulated, PhaseTableError> {
            let nt = ntheta[(il * n2 + size_index) * nphamat] as usize;
            if nt < 2 || nt > nthmax {
                return Err(PhaseTableError::Ntheta {
                    path: p(),
                    ntheta: nt,
                    wavelength_index: il,
                });
            }
            let off = ((il * n2 + size_index) * nphamat) * nthmax;
            let elem = |k: usize| -> Result<(&[f64], &[f64]), PhaseTableError> {
                let n = ntheta[(il * n2 + size_index) * nphamat + k] as usize;
                if n < 2 || n > nthmax {
                    return Err(PhaseTableError::ElementNtheta {
                        path: p(),
                        ntheta: n,
                        element: k + 1,
                        wavelength_index: il,
                    });
                }
                let o = off + k * nthmax;
                Ok((&theta[o..o + n], &phase[o..o + n]))
            };
            let wl_err = |source| PhaseTableError::Table {
                path: p(),
                wavelength_nm: wl_um[il] * 1e3,
                source,
            };
            // Element order (libRadtran / MOPSMAP): 4 elements for spheres P11, P12, P33, P34
            // (P22 = P11, P44 = P33); 6 elements P11, P12, P33, P34, P22, P44.
            match nphamat {
                4 => {
                    let (e11, e12, e33, e34) = (elem(0)?, elem(1)?, elem(2)?, elem(3)?);
                    Tabulated::from_matrix_table(
                        &theta[off..off + nt],
                        &phase[off..off + nt],
                        [e12, e11, e33, e34, e33],
                    )
                    .map_err(wl_err)
                }
                6 => {
                    let (e12, e33, e34, e22, e44) =
                        (elem(1)?, elem(2)?, elem(3)?, elem(4)?, elem(5)?);
                    Tabulated::from_matrix_table(
                        &theta[off..off + nt],
                        &phase[off..off + nt],
                        [e12, e22, e33, e34, e44],
                    )
                    .map_err(wl_err)
                }
                _ => Tabulated::from_table(&theta[off..off + nt], &phase[off..off + nt])
                    .map_err(wl_err),
            }
        };
        let wl_nm: Vec<f64> = wl_um.iter().map(|w| w * 1e3).collect();
        if let Some(il) = wl_nm.iter().position(|w| !w.is_finite()) {
            return Err(PhaseTableError::WavelengthNotFinite {
                path: p(),
                index: il,
                value_um: wl_um[il],
            });
        }
        if let Some(i) = wl_nm.iter().position(|&w| (w - wavelength_nm).abs() < 1e-3) {
            return table_at(i);
        }
        let mut order: Vec<usize> = (0..nlam).collect();
        order.sort_by(|&a, &b| wl_nm[a].total_cmp(&wl_nm[b]));
        for w in order.windows(2) {
            let (a, b) = (w[0], w[1]);
            if wl_nm[a] <= wavelength_nm && wavelength_nm <= wl_nm[b] {
                let t = (wavelength_nm - wl_nm[a]) / (wl_nm[b] - wl_nm[a]);
                return Ok(Tabulated::mix(&table_at(a)?, &table_at(b)?, t));
            }
        }
        Err(PhaseTableError::WavelengthOutside {
            path: p(),
            wavelength_nm,
            tabulated_nm: wl_nm,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phase::{test_support::*, HenyeyGreenstein, PhaseFunction};
    use std::sync::Arc;

    fn hg_table(g: f64, n: usize) -> Tabulated {
        let hg = HenyeyGreenstein::new(g).unwrap();
        let th: Vec<f64> = (0..=n).map(|i| 180.0 * i as f64 / n as f64).collect();
        let v: Vec<f64> = th.iter().map(|t| hg.eval(t.to_radians().cos())).collect();
        Tabulated::from_table(&th, &v).unwrap()
    }

    /// A finely tabulated HG function reproduces HG (values, normalisation, asymmetry).
    #[test]
    fn tabulated_hg_matches_analytic() {
        let t = hg_table(0.5, 1800);
        let hg = HenyeyGreenstein::new(0.5).unwrap();
        for mu in [-1.0, -0.5, 0.0, 0.5, 0.9, 1.0] {
            let r = t.eval(mu) / hg.eval(mu) - 1.0;
            assert!(r.abs() < 2e-3, "mu {mu}: rel {r}");
        }
        assert!((t.asymmetry() - 0.5).abs() < 1e-3, "{}", t.asymmetry());
        let p = PhaseFunction::Tabulated(Arc::new(t));
        assert!((mean_over_sphere(&p) - 1.0).abs() < 1e-6);
    }

    /// The O(1) forward peak equals `eval(1)`, for a table and a mixture containing it.
    #[test]
    fn forward_peak_is_eval_at_one() {
        let t = PhaseFunction::Tabulated(Arc::new(hg_table(0.9, 360)));
        let m = PhaseFunction::Mixture(Arc::new(
            crate::phase::Mixture::new(vec![
                (
                    0.3,
                    PhaseFunction::Rayleigh(crate::phase::Rayleigh::new(0.03).unwrap()),
                ),
                (0.7, t.clone()),
            ])
            .unwrap(),
        ));
        for p in [&t, &m] {
            let (a, b) = (p.forward_peak(), p.eval(1.0));
            assert!((a - b).abs() <= 1e-12 * b, "{a} vs {b}");
        }
    }

    /// χ² of the sampler against eval, on a strongly peaked table.
    #[test]
    fn chi2_sampling() {
        let p = PhaseFunction::Tabulated(Arc::new(hg_table(0.8, 360)));
        let (c, dof) = chi2(&p, 300_000, 200);
        assert!(c < chi2_quantile_999(dof), "chi2 {c} dof {dof}");
    }

    /// Reading the IPRT water-soluble aerosol file: normalised, asymmetry near the Mie value.
    #[test]
    fn reads_libradtran_file() {
        // Fixture copied from shared/data/iprt_phase_a/inputs/waso.mie.cdf (see PROVENANCE.md).
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../simulator/tests/data/fixtures/waso.mie.cdf");
        let t = Tabulated::load_libradtran(&path, 350.0, 0).unwrap();
        let p = PhaseFunction::Tabulated(Arc::new(t.clone()));
        assert!((mean_over_sphere(&p) - 1.0).abs() < 1e-6);
        let g = t.asymmetry();
        assert!(g > 0.5 && g < 0.8, "g = {g}");
        let err = Tabulated::load_libradtran(&path, 550.0, 0)
            .unwrap_err()
            .to_string();
        assert!(err.contains("outside the tabulated range"), "{err}");
        let err = Tabulated::load_libradtran(Path::new("/nonexistent.cdf"), 550.0, 0).unwrap_err();
        assert!(err.to_string().contains("/nonexistent.cdf"));
        // Rationale (issue 15): netCDF-C reads a truncated classic file's missing data as
        // zeros (BRF off by 40 %, exit 0); it is refused, naming the file.
        let bytes = std::fs::read(&path).unwrap();
        let cut = std::env::temp_dir().join(format!("waso-cut-{}.mie.cdf", std::process::id()));
        std::fs::write(&cut, &bytes[..bytes.len() * 3 / 4]).unwrap();
        let err = Tabulated::load_libradtran(&cut, 350.0, 0)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("truncated") && err.contains("waso-cut"),
            "{err}"
        );
        std::fs::remove_file(&cut).unwrap();
    }
}
