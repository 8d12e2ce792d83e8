//! Henyey–Greenstein phase function.
//!
//! | parameter | unit | range    | meaning                                      |
//! |-----------|------|----------|----------------------------------------------|
//! | `g`       | —    | (−1, 1)  | asymmetry ⟨cos Θ⟩; g > 0 scatters forward     |
//!
//! `P(Θ) = (1 − g²) / (1 + g² − 2g cos Θ)^{3/2}` (Henyey & Greenstein 1941), mean 1 over 4π;
//! its Legendre moments are `χ_l = g^l`. Sampled by the standard closed-form inversion.

use super::error::PhaseError;

#[derive(Clone, Debug, PartialEq)]
pub struct HenyeyGreenstein {
    pub g: f64,
}

impl HenyeyGreenstein {
    pub fn new(g: f64) -> Result<Self, PhaseError> {
        if !(g > -1.0 && g < 1.0) {
            return Err(PhaseError::OutOfRange {
                model: "hg",
                param: "g",
                value: g,
                range: "(-1, 1)",
            });
        }
        Ok(Self { g })
    }

    #[inline]
    pub fn eval(&self, mu: f64) -> f64 {
        let g = self.g;
        let d = 1.0 + g * g - 2.0 * g * mu;
        (1.0 - g * g) / (d * d.sqrt())
    }

    #[inline]
    pub fn sample_cos(&self, u: f64) -> f64 {
        let g = self.g;
        if g.abs() < 1e-6 {
            return 1.0 - 2.0 * u;
        }
        let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u);
        ((1.0 + g * g - s * s) / (2.0 * g)).clamp(-1.0, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phase::{test_support::*, PhaseFunction};

    /// Normalisation, asymmetry = g, and χ² of the sampler, for forward, backward and ~isotropic.
    #[test]
    fn hg_consistency() {
        for g in [-0.5, 0.0, 0.3, 0.7, 0.9] {
            let p = PhaseFunction::Hg(HenyeyGreenstein::new(g).unwrap());
            assert!((mean_over_sphere(&p) - 1.0).abs() < 2e-6, "g={g}");
            let n = 400_000;
            let m1: f64 = (0..n)
                .map(|i| {
                    let mu = -1.0 + 2.0 * (i as f64 + 0.5) / n as f64;
                    p.eval(mu) * mu
                })
                .sum::<f64>()
                / n as f64;
            assert!((m1 - g).abs() < 1e-5, "g={g} m1={m1}");
            let (c, dof) = chi2(&p, 200_000, 100);
            assert!(c < chi2_quantile_999(dof), "g={g}: chi2 {c} dof {dof}");
        }
        assert!(HenyeyGreenstein::new(1.0).is_err() && HenyeyGreenstein::new(f64::NAN).is_err());
    }
}
