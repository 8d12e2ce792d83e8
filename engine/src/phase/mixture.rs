//! Weighted mixtures of phase functions: the phase function of a layer holding several
//! scattering species (air molecules and particles).
//!
//! | parameter | unit | range | meaning |
//! |-----------|------|-------|---------|
//! | `wᵢ`      | —    | ≥ 0, Σ > 0 | weight of component i: its **scattering** optical thickness in the layer (normalised here to Σ wᵢ = 1) |
//! | `Pᵢ`      | —    | any `PhaseFunction` | phase function of component i (mean 1 over 4π) |
//!
//! Formula: `P(cos Θ) = Σ wᵢ Pᵢ(cos Θ)`, so P keeps mean 1 over 4π; the phase matrix is
//! `M = Σ wᵢ Mᵢ` (each `Mᵢ` with its own normalisation, depolarizers contributing to a1 only);
//! the asymmetry parameter is `g = Σ wᵢ gᵢ`.
//!
//! Sampling uses the caller's **single** uniform number `u` (the integrators draw one number per
//! `sample_cos` call): component k is picked when `Wₖ₋₁ ≤ u < Wₖ` (W the cumulative weights),
//! and `u' = (u − Wₖ₋₁)/wₖ`, which is uniform on [0, 1) given k and independent of the choice,
//! is handed to component k's sampler. The density of the result is then exactly `Σ wᵢ Pᵢ/2`.
//! The split costs `log₂(1/wₖ)` bits of `u`'s 53 (a component of weight 10⁻⁶ still samples with
//! 33 bits), which is harmless.
//!
//! Components with zero weight are dropped. [`Mixture::build`] returns the single component
//! itself when only one is left, so a layer without particles keeps its plain Rayleigh phase
//! function (bit-identical results).

use super::error::PhaseError;
use super::PhaseFunction;
use std::sync::Arc;

#[derive(Clone, Debug, PartialEq)]
pub struct Mixture {
    /// Normalised weights (Σ = 1), each > 0.
    weights: Vec<f64>,
    /// Cumulative weights, the last forced to 1.
    cum: Vec<f64>,
    parts: Vec<PhaseFunction>,
}

impl Mixture {
    /// A mixture of `(weight, phase)` pairs; weights are finite, ≥ 0, and not all zero (they
    /// need not sum to 1). Zero-weight components are dropped.
    pub fn new(components: Vec<(f64, PhaseFunction)>) -> Result<Self, PhaseError> {
        let mut total = 0.0;
        for (i, (w, _)) in components.iter().enumerate() {
            if !w.is_finite() || *w < 0.0 {
                return Err(PhaseError::MixtureWeight {
                    index: i,
                    weight: *w,
                });
            }
            total += w;
        }
        if total <= 0.0 {
            return Err(PhaseError::MixtureZero);
        }
        let (mut weights, mut cum, mut parts) = (Vec::new(), Vec::new(), Vec::new());
        let mut acc = 0.0;
        for (w, p) in components {
            if w > 0.0 {
                weights.push(w / total);
                acc += w / total;
                cum.push(acc);
                parts.push(p);
            }
        }
        *cum.last_mut().expect("at least one positive weight") = 1.0;
        Ok(Self {
            weights,
            cum,
            parts,
        })
    }

    /// The phase function of a mixture: the component itself when only one has a positive
    /// weight, else a `PhaseFunction::Mixture`.
    pub fn build(components: Vec<(f64, PhaseFunction)>) -> Result<PhaseFunction, PhaseError> {
        let mut m = Self::new(components)?;
        if m.parts.len() == 1 {
            return Ok(m.parts.pop().expect("one component"));
        }
        Ok(PhaseFunction::Mixture(Arc::new(m)))
    }

    /// The normalised weights and their components.
    pub fn components(&self) -> impl Iterator<Item = (f64, &PhaseFunction)> {
        self.weights.iter().copied().zip(self.parts.iter())
    }

    #[inline]
    pub fn eval(&self, cos_theta: f64) -> f64 {
        self.components().map(|(w, p)| w * p.eval(cos_theta)).sum()
    }

    #[inline]
    pub fn sample_cos(&self, u: f64) -> f64 {
        let k = self
            .cum
            .partition_point(|&c| c <= u)
            .min(self.cum.len() - 1);
        let lo = if k == 0 { 0.0 } else { self.cum[k - 1] };
        let v = ((u - lo) / self.weights[k]).clamp(0.0, 1.0 - f64::EPSILON / 2.0);
        self.parts[k].sample_cos(v)
    }

    #[inline]
    pub fn matrix(&self, cos_theta: f64) -> crate::stokes::PhaseMatrix {
        let mut m = crate::stokes::PhaseMatrix::depolarizing(0.0);
        for (w, p) in self.components() {
            let c = p.matrix(cos_theta);
            m.a1 += w * c.a1;
            m.b1 += w * c.b1;
            m.a2 += w * c.a2;
            m.a3 += w * c.a3;
            m.b2 += w * c.b2;
            m.a4 += w * c.a4;
        }
        m
    }

    pub fn asymmetry(&self) -> f64 {
        self.components().map(|(w, p)| w * p.asymmetry()).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phase::{test_support::*, HenyeyGreenstein, Rayleigh};

    fn rayleigh() -> PhaseFunction {
        PhaseFunction::Rayleigh(Rayleigh::new(0.0279).unwrap())
    }
    fn hg(g: f64) -> PhaseFunction {
        PhaseFunction::Hg(HenyeyGreenstein::new(g).unwrap())
    }

    /// Rayleigh + a forward and a backward HG: mean 1 over the sphere, eval = Σ wᵢ Pᵢ,
    /// asymmetry = Σ wᵢ gᵢ (checked against quadrature too), χ² of the sampler against eval.
    #[test]
    fn mixture_consistency() {
        let parts = vec![(0.3, rayleigh()), (0.5, hg(0.8)), (0.2, hg(-0.4))];
        let p = Mixture::build(parts.clone()).unwrap();
        assert!(matches!(p, PhaseFunction::Mixture(_)));
        let norm = mean_over_sphere(&p);
        assert!((norm - 1.0).abs() < 1e-6, "{norm}");
        for mu in [-1.0, -0.3, 0.0, 0.5, 0.99] {
            let direct: f64 = parts.iter().map(|(w, q)| w * q.eval(mu)).sum();
            assert!((p.eval(mu) - direct).abs() < 1e-12 * direct);
        }
        let g = p.asymmetry();
        assert!((g - (0.5 * 0.8 - 0.2 * 0.4)).abs() < 1e-12, "{g}");
        let n = 400_000;
        let m1: f64 = (0..n)
            .map(|i| {
                let mu = -1.0 + 2.0 * (i as f64 + 0.5) / n as f64;
                p.eval(mu) * mu
            })
            .sum::<f64>()
            / n as f64;
        assert!((m1 - g).abs() < 1e-5, "quadrature {m1} vs {g}");
        let (c, dof) = chi2(&p, 400_000, 200);
        println!("mixture chi2 = {c:.1}, dof = {dof}");
        assert!(c < chi2_quantile_999(dof), "chi2 {c} dof {dof}");
    }

    /// Weights need not be normalised; unequal scales give the same mixture. The phase matrix is
    /// the weighted sum (HG contributes to a1 only).
    #[test]
    fn weights_and_matrix() {
        let a = Mixture::new(vec![(2.0, rayleigh()), (6.0, hg(0.5))]).unwrap();
        let b = Mixture::new(vec![(0.25, rayleigh()), (0.75, hg(0.5))]).unwrap();
        for mu in [-0.7, 0.1, 0.8] {
            assert!((a.eval(mu) - b.eval(mu)).abs() < 1e-14);
            let m = a.matrix(mu);
            let r = rayleigh().matrix(mu);
            assert!((m.a1 - a.eval(mu)).abs() < 1e-12);
            assert!((m.b1 - 0.25 * r.b1).abs() < 1e-14);
            assert!((m.a3 - 0.25 * r.a3).abs() < 1e-14);
        }
    }

    /// Zero weights are dropped; a single survivor is returned as itself; bad weights fail.
    #[test]
    fn degenerate_cases() {
        let p = Mixture::build(vec![(0.7, rayleigh()), (0.0, hg(0.5))]).unwrap();
        assert!(matches!(p, PhaseFunction::Rayleigh(_)));
        assert!(Mixture::new(vec![(0.0, rayleigh())]).is_err());
        assert!(Mixture::new(vec![(-1.0, rayleigh()), (2.0, hg(0.1))]).is_err());
        assert!(Mixture::new(vec![(f64::NAN, rayleigh())]).is_err());
        // u at the ends stays in range.
        let m = Mixture::new(vec![(1e-9, hg(0.9)), (1.0, hg(-0.2))]).unwrap();
        for u in [0.0, 1e-12, 0.5, 1.0 - 1e-16] {
            let c = m.sample_cos(u);
            assert!((-1.0..=1.0).contains(&c), "{u}: {c}");
        }
    }
}
