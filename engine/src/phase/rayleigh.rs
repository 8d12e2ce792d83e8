//! Rayleigh phase function with an optional depolarization factor.
//!
//! | parameter        | unit | range     | meaning                                     |
//! |------------------|------|-----------|---------------------------------------------|
//! | `depolarization` | —    | [0, 0.5)  | depolarization factor ρ_n (0: pure dipole)  |
//!
//! `P(Θ) = 3/(4(1+2γ)) · [(1+3γ) + (1−γ) cos²Θ]` with `γ = ρ_n / (2 − ρ_n)`
//! (Hansen & Travis 1974, eq. 2.15; Chandrasekhar 1950). With ρ_n = 0, `P = ¾(1 + cos²Θ)`.
//! Sampling inverts the cubic CDF in closed form (Cardano; one real root since the CDF is
//! strictly increasing).

use super::error::PhaseError;

#[derive(Clone, Debug, PartialEq)]
pub struct Rayleigh {
    pub depolarization: f64,
    /// P = a + b·μ².
    a: f64,
    b: f64,
}

impl Rayleigh {
    pub fn new(depolarization: f64) -> Result<Self, PhaseError> {
        if !(0.0..0.5).contains(&depolarization) {
            return Err(PhaseError::OutOfRange {
                model: "rayleigh",
                param: "depolarization",
                value: depolarization,
                range: "[0, 0.5)",
            });
        }
        let gamma = depolarization / (2.0 - depolarization);
        let c = 3.0 / (4.0 * (1.0 + 2.0 * gamma));
        Ok(Self {
            depolarization,
            a: c * (1.0 + 3.0 * gamma),
            b: c * (1.0 - gamma),
        })
    }

    #[inline]
    pub fn eval(&self, mu: f64) -> f64 {
        self.a + self.b * mu * mu
    }

    /// Phase matrix (Hansen & Travis 1974, eqs. 2.15–2.16): `Δ·F_R + (1−Δ)·diag(1, 0, 0, 0)` with
    /// the pure Rayleigh matrix `F_R`, `Δ = (1−ρ)/(1+ρ/2)`, and the circular element scaled by
    /// `Δ' = (1−2ρ)/(1−ρ)`. Its a1 equals `eval`.
    #[inline]
    pub fn matrix(&self, mu: f64) -> crate::stokes::PhaseMatrix {
        let rho = self.depolarization;
        let delta = (1.0 - rho) / (1.0 + 0.5 * rho);
        let delta_p = (1.0 - 2.0 * rho) / (1.0 - rho);
        let m2 = mu * mu;
        let a2 = delta * 0.75 * (1.0 + m2);
        crate::stokes::PhaseMatrix {
            a1: a2 + (1.0 - delta),
            b1: -delta * 0.75 * (1.0 - m2),
            a2,
            a3: delta * 1.5 * mu,
            b2: 0.0,
            a4: delta * delta_p * 1.5 * mu,
        }
    }

    #[inline]
    pub fn sample_cos(&self, u: f64) -> f64 {
        // CDF F(μ) = [a(μ+1) + b(μ³+1)/3] / 2 (since the mean over the sphere is 1, a + b/3 = 1).
        // Solve μ³ + pμ + q = 0 with p = 3a/b, q = 3(a + b/3 − 2u)/b.
        let p = 3.0 * self.a / self.b;
        let q = 3.0 * (self.a + self.b / 3.0 - 2.0 * u) / self.b;
        let disc = (0.25 * q * q + p * p * p / 27.0).sqrt();
        let mu = (-0.5 * q + disc).cbrt() + (-0.5 * q - disc).cbrt();
        mu.clamp(-1.0, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phase::{test_support::*, PhaseFunction};

    /// Normalisation (mean 1 over 4π) and the textbook value at ρ_n = 0.
    #[test]
    fn normalised_and_textbook() {
        for d in [0.0, 0.0279, 0.2] {
            let p = PhaseFunction::Rayleigh(Rayleigh::new(d).unwrap());
            assert!((mean_over_sphere(&p) - 1.0).abs() < 1e-9);
        }
        let r = Rayleigh::new(0.0).unwrap();
        for mu in [-1.0, -0.3, 0.0, 0.5, 1.0] {
            assert!((r.eval(mu) - 0.75 * (1.0 + mu * mu)).abs() < 1e-15);
        }
        // ρ_n = 1/2 would be γ = 1/3: isotropic part only grows; the bound is exclusive.
        assert!(Rayleigh::new(0.5).is_err() && Rayleigh::new(f64::NAN).is_err());
    }

    /// The second Legendre moment χ₂ equals 0.1 at ρ_n = 0 (CONVENTIONS.md).
    #[test]
    fn legendre_moment_two() {
        let p = Rayleigh::new(0.0).unwrap();
        let n = 100_000;
        let chi2: f64 = (0..n)
            .map(|i| {
                let mu = -1.0 + 2.0 * (i as f64 + 0.5) / n as f64;
                p.eval(mu) * 0.5 * (3.0 * mu * mu - 1.0)
            })
            .sum::<f64>()
            / n as f64;
        assert!((chi2 - 0.1).abs() < 1e-8, "{chi2}");
    }

    /// The matrix's a1 is the scalar phase function; at ρ = 0 it is the textbook matrix.
    #[test]
    fn matrix_consistent() {
        for d in [0.0, 0.03, 0.2] {
            let r = Rayleigh::new(d).unwrap();
            for mu in [-1.0, -0.4, 0.0, 0.3, 1.0] {
                assert!((r.matrix(mu).a1 - r.eval(mu)).abs() < 1e-14);
            }
        }
        let m = Rayleigh::new(0.0).unwrap().matrix(0.5);
        assert!(
            (m.b1 + 0.75 * 0.75).abs() < 1e-15
                && (m.a3 - 0.75).abs() < 1e-15
                && (m.a4 - 0.75).abs() < 1e-15
        );
    }

    #[test]
    fn chi2_sampling() {
        for d in [0.0, 0.1] {
            let p = PhaseFunction::Rayleigh(Rayleigh::new(d).unwrap());
            let (c, dof) = chi2(&p, 200_000, 50);
            assert!(c < chi2_quantile_999(dof), "chi2 {c} dof {dof}");
        }
    }
}
