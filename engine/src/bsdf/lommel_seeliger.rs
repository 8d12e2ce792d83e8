//! Lommel–Seeliger reflection: single scattering by an isotropically scattering, semi-infinite
//! particulate medium, the first-order term of every radiative-transfer regolith model (Hapke's
//! without multiple scattering, opposition effect or roughness). Used for dark, low-albedo
//! surfaces (the Moon, asteroids, dark soils) and as the limb-darkening law of such bodies.
//!
//! Ranges are those of the shared table `bundle::BRDF_PARAM_RANGES`, which
//! [`LommelSeeliger::new`] checks.
//!
//! | parameter | unit | range  | meaning                                     |
//! |-----------|------|--------|---------------------------------------------|
//! | `w`       | —    | [0, 1] | single-scattering albedo of the particles   |
//!
//! The bidirectional reflectance is `r = (w/4π) μ0/(μ0 + μ)`, so the BRDF is
//!
//! ```text
//! f_r = r/μ0 = (w/4π) / (μi + μo)   sr⁻¹
//! ```
//!
//! reciprocal, and its directional-hemispherical reflectance is, in closed form,
//! `ρ_dh(μ) = (w/2)·[1 − μ ln((1 + μ)/μ)]`, below w/2 ≤ ½ (tested against quadrature below).
//! The BRF at nadir under a vertical Sun is `π f_r = w/8`.
//!
//! Reference: B. Hapke (2012), *Theory of Reflectance and Emittance Spectroscopy*, 2nd ed.,
//! Cambridge University Press, §9.D (eq. 9.35 with isotropic scattering); M. Fairbairn (2005),
//! Planetary photometry: the Lommel–Seeliger law, JRASC 99, 92–93.

use glam::DVec3;

use super::error::{check_param, BrdfError};
use super::TableSampler;

#[derive(Clone, Debug)]
pub struct LommelSeeliger {
    pub w: f64,
    /// `w/4π`, sr⁻¹.
    w_over_4pi: f64,
    /// Importance sampler built from this model (`table_sampler.rs`).
    pub(crate) sampler: TableSampler,
}

impl LommelSeeliger {
    pub fn new(w: f64) -> Result<Self, BrdfError> {
        // Range from the shared table (`bundle::BRDF_PARAM_RANGES`).
        check_param("lommel_seeliger", "w", "w", w)?;
        let mut m = Self {
            w,
            w_over_4pi: w / (4.0 * std::f64::consts::PI),
            sampler: TableSampler::unbuilt(),
        };
        m.sampler = TableSampler::build(|wi, wo| m.eval(wi, wo));
        Ok(m)
    }

    /// BRDF (sr⁻¹) for unit vectors with `z > 0` (the caller handles the horizon).
    #[inline]
    pub fn eval(&self, wi: DVec3, wo: DVec3) -> f64 {
        self.w_over_4pi / (wi.z + wo.z)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::Bsdf;
    use crate::frame::direction_from_angles;

    /// Rationale: the closed form r = (w/4π) μ0/(μ0 + μ) written out independently, at nadir
    /// (BRF w/8) and at oblique, reciprocal pairs.
    #[test]
    fn closed_form_and_reciprocity() {
        let m = LommelSeeliger::new(0.6).unwrap();
        let nadir = m.eval(DVec3::Z, DVec3::Z) * std::f64::consts::PI;
        assert!((nadir - 0.6 / 8.0).abs() < 1e-15, "{nadir}");
        let (a, b) = (
            direction_from_angles(0.5, 0.0),
            direction_from_angles(1.1, 2.0),
        );
        let (m0, m1) = (0.5f64.cos(), 1.1f64.cos());
        let r = 0.6 / (4.0 * std::f64::consts::PI) * m0 / (m0 + m1);
        assert!((m.eval(a, b) * m0 - r).abs() < 1e-15);
        assert_eq!(m.eval(a, b), m.eval(b, a));
    }

    /// Rationale: the directional-hemispherical reflectance has the closed form
    /// (w/2)[1 − μ ln((1 + μ)/μ)]; the generic quadrature must reproduce it (energy below ½).
    #[test]
    fn albedo_matches_closed_form() {
        let w = 0.9;
        let m = Bsdf::LommelSeeliger(LommelSeeliger::new(w).unwrap());
        for &z in &[0.0f64, 0.6, 1.2, 1.5] {
            let mu = z.cos();
            let exact = 0.5 * w * (1.0 - mu * ((1.0 + mu) / mu).ln());
            let a = m.directional_albedo(direction_from_angles(z, 0.0), 400);
            assert!(
                (a - exact).abs() < 2e-3 * exact,
                "zenith {z}: {a} vs {exact}"
            );
        }
    }

    /// Constructors reject out-of-range and NaN albedos, naming the parameter.
    #[test]
    fn rejects_bad_parameters() {
        assert_eq!(
            LommelSeeliger::new(1.5).unwrap_err().to_string(),
            "`w` = 1.5 must lie in [0, 1]"
        );
        assert!(LommelSeeliger::new(f64::NAN).is_err());
        assert!(LommelSeeliger::new(0.0).is_ok() && LommelSeeliger::new(1.0).is_ok());
    }
}
