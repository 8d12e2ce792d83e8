//! Phase functions, dispatched by an enum: one file per model.
//!
//! Conventions shared by every model:
//! * the argument is `cos Θ`, Θ the scattering angle between the propagation direction before
//!   and after scattering (Θ = 0 is forward scattering);
//! * normalisation: the mean over 4π is 1, i.e. `∫ P dω = 4π` (the `p = P/4π` of a probability
//!   density in solid angle);
//! * `sample_cos` draws `cos Θ` with density `P(cos Θ)/2` on [−1, 1]; the azimuth about the
//!   incident direction is uniform, drawn by the caller.
//!
//! All models here are reciprocal (`P` depends on Θ only), so the same function serves forward
//! (photon) and backward (importance) walks.
//!
//! Adding a model touches three files, all in this folder (see CONTRIBUTING.md): its file (doc
//! header, tests), a variant of [`PhaseFunction`] here, and a variant of [`PhaseConfig`] with its
//! arm in [`PhaseResolver::resolve`] (`config.rs`).

pub mod config;
pub mod error;
pub mod hg;
pub mod mixture;
pub mod rayleigh;
pub mod tabulated;

pub use config::{PhaseConfig, PhaseResolver};
pub use error::PhaseError;
pub use hg::HenyeyGreenstein;
pub use mixture::Mixture;
pub use rayleigh::Rayleigh;
pub use tabulated::Tabulated;

use std::sync::Arc;

#[derive(Clone, Debug, PartialEq)]
pub enum PhaseFunction {
    Rayleigh(Rayleigh),
    Hg(HenyeyGreenstein),
    /// Shared: tables can be large and the same table serves many layers.
    Tabulated(Arc<Tabulated>),
    /// Weighted sum of phase functions (molecules + particles in one layer).
    Mixture(Arc<Mixture>),
}

impl PhaseFunction {
    /// `P(cos Θ)`, mean 1 over the sphere.
    #[inline]
    pub fn eval(&self, cos_theta: f64) -> f64 {
        match self {
            PhaseFunction::Rayleigh(p) => p.eval(cos_theta),
            PhaseFunction::Hg(p) => p.eval(cos_theta),
            PhaseFunction::Tabulated(p) => p.eval(cos_theta),
            PhaseFunction::Mixture(p) => p.eval(cos_theta),
        }
    }

    /// The forward peak `P(1)` in O(1) (a table's last node, a mixture's weighted peaks);
    /// asked at every scattering by detector-directional sampling.
    #[inline]
    pub fn forward_peak(&self) -> f64 {
        match self {
            PhaseFunction::Tabulated(p) => p.forward_peak(),
            PhaseFunction::Mixture(m) => m.components().map(|(w, p)| w * p.forward_peak()).sum(),
            PhaseFunction::Rayleigh(_) | PhaseFunction::Hg(_) => self.eval(1.0),
        }
    }

    /// Draw `cos Θ` with density `P/2` from one uniform number in [0, 1).
    #[inline]
    pub fn sample_cos(&self, u: f64) -> f64 {
        match self {
            PhaseFunction::Rayleigh(p) => p.sample_cos(u),
            PhaseFunction::Hg(p) => p.sample_cos(u),
            PhaseFunction::Tabulated(p) => p.sample_cos(u),
            PhaseFunction::Mixture(p) => p.sample_cos(u),
        }
    }

    /// The phase matrix at cos Θ (polarized runs). Rayleigh and tables with phase-matrix elements
    /// are polarizing; Henyey–Greenstein and P11-only tables act as depolarizers (only I scatters);
    /// a mixture's matrix is the weighted sum of its components'.
    #[inline]
    pub fn matrix(&self, cos_theta: f64) -> crate::stokes::PhaseMatrix {
        match self {
            PhaseFunction::Rayleigh(p) => p.matrix(cos_theta),
            PhaseFunction::Tabulated(t) => t.matrix(cos_theta),
            PhaseFunction::Mixture(m) => m.matrix(cos_theta),
            PhaseFunction::Hg(_) => crate::stokes::PhaseMatrix::depolarizing(self.eval(cos_theta)),
        }
    }

    /// Asymmetry parameter ⟨cos Θ⟩.
    pub fn asymmetry(&self) -> f64 {
        match self {
            PhaseFunction::Rayleigh(_) => 0.0,
            PhaseFunction::Hg(p) => p.g,
            PhaseFunction::Tabulated(p) => p.asymmetry(),
            PhaseFunction::Mixture(p) => p.asymmetry(),
        }
    }
}

#[cfg(test)]
pub(crate) mod test_support {
    use super::PhaseFunction;

    /// ∫ P dω / 4π by the midpoint rule in cos Θ (fine grid).
    pub fn mean_over_sphere(p: &PhaseFunction) -> f64 {
        let n = 200_000;
        (0..n)
            .map(|i| p.eval(-1.0 + 2.0 * (i as f64 + 0.5) / n as f64))
            .sum::<f64>()
            / n as f64
    }

    /// χ² test of `sample_cos` against `eval`: `nbins` bins in cos Θ with expected counts from
    /// the midpoint-integrated density, bins with expectation < 5 merged; returns (χ², dof).
    pub fn chi2(p: &PhaseFunction, nsamples: usize, nbins: usize) -> (f64, usize) {
        let mut rng = crate::rng::Stream::new(7, [9, 9, 9, 9]);
        let mut counts = vec![0f64; nbins];
        for _ in 0..nsamples {
            let c = p.sample_cos(rng.next_f64());
            assert!((-1.0..=1.0).contains(&c), "sample out of range: {c}");
            let i = (((c + 1.0) * 0.5 * nbins as f64) as usize).min(nbins - 1);
            counts[i] += 1.0;
        }
        let sub = 200;
        let mut expect = vec![0f64; nbins];
        for (i, e) in expect.iter_mut().enumerate() {
            let a = -1.0 + 2.0 * i as f64 / nbins as f64;
            let w = 2.0 / nbins as f64;
            let s: f64 = (0..sub)
                .map(|k| p.eval(a + w * (k as f64 + 0.5) / sub as f64))
                .sum();
            *e = s / sub as f64 * w * 0.5 * nsamples as f64;
        }
        let (mut chi2, mut dof) = (0.0, 0usize);
        let (mut acc_o, mut acc_e) = (0.0, 0.0);
        for i in 0..nbins {
            acc_o += counts[i];
            acc_e += expect[i];
            if acc_e >= 5.0 {
                chi2 += (acc_o - acc_e).powi(2) / acc_e;
                dof += 1;
                acc_o = 0.0;
                acc_e = 0.0;
            }
        }
        (chi2, dof.saturating_sub(1))
    }

    /// Upper 0.1 % quantile of χ² with `dof` degrees of freedom (Wilson–Hilferty).
    pub fn chi2_quantile_999(dof: usize) -> f64 {
        let k = dof as f64;
        let z = 3.090_232;
        k * (1.0 - 2.0 / (9.0 * k) + z * (2.0 / (9.0 * k)).sqrt()).powi(3)
    }
}
