//! A thin two-sided bi-Lambertian leaf: Lambertian reflection on the side the light arrives
//! from and Lambertian transmission to the other side, identical on both faces.
//!
//! Ranges are those of the shared table `bundle::BRDF_PARAM_RANGES`, which
//! [`BiLambertian::new`] checks, plus energy conservation.
//!
//! | parameter       | unit | range  | meaning                                     |
//! |-----------------|------|--------|---------------------------------------------|
//! | `reflectance`   | —    | [0, 1] | hemispherical reflectance ρ                 |
//! | `transmittance` | —    | [0, 1] | hemispherical transmittance τ; ρ + τ ≤ 1    |
//!
//! `f = ρ/π` sr⁻¹ for light and viewer on the same side, `τ/π` across. In 3D scenes it is the
//! `Leaf` surface model (`scene/material.rs`: evaluation and exact importance sampling). As the
//! ground of a 1D atmosphere, the transmitted light enters the ground and is absorbed: the
//! surface is then the [`super::Lambertian`] of reflectance ρ ([`super::Built::into_opaque`]).
//!
//! Reference: bi-Lambertian leaves as in the RAMI-3 protocol, Widlowski et al. (2007), JGR 112,
//! D09111.

use super::error::{check_param, BrdfError};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BiLambertian {
    pub reflectance: f64,
    pub transmittance: f64,
}

impl BiLambertian {
    /// A leaf at `wavelength_nm` (named in the error when ρ + τ exceeds 1).
    pub fn new(
        reflectance: f64,
        transmittance: f64,
        wavelength_nm: f64,
    ) -> Result<Self, BrdfError> {
        check_param("bi_lambertian", "reflectance", "reflectance", reflectance)?;
        check_param(
            "bi_lambertian",
            "transmittance",
            "transmittance",
            transmittance,
        )?;
        if reflectance + transmittance > bundle::BI_LAMBERTIAN_MAX_SUM {
            return Err(BrdfError::LeafSum {
                reflectance,
                transmittance,
                wavelength_nm,
                max: bundle::BI_LAMBERTIAN_MAX_SUM,
            });
        }
        Ok(Self {
            reflectance,
            transmittance,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rationale: each parameter's range and the energy bound are checked, with messages
    /// naming the parameter or the sum and the wavelength.
    #[test]
    fn ranges_and_sum_are_checked() {
        assert!(BiLambertian::new(0.45, 0.45, 550.0).is_ok());
        let e = BiLambertian::new(1.2, 0.0, 550.0).unwrap_err();
        assert_eq!(e.to_string(), "`reflectance` = 1.2 must lie in [0, 1]");
        let e = BiLambertian::new(0.6, 0.5, 550.0).unwrap_err();
        assert!(e.to_string().contains("0.6 + 0.5 at 550 nm"), "{e}");
        assert!(BiLambertian::new(0.5, f64::NAN, 550.0).is_err());
    }
}
