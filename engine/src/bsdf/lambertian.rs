//! Lambertian (perfectly diffuse) reflection.
//!
//! Ranges are those of the shared table `bundle::BRDF_PARAM_RANGES`, which [`Lambertian::new`] checks.
//!
//! | parameter     | unit | range  | meaning                                   |
//! |---------------|------|--------|-------------------------------------------|
//! | `reflectance` | —    | [0, 1] | hemispherical reflectance ρ (= the BRF)   |
//!
//! `f_r = ρ/π` sr⁻¹. The parameter is a BRF (equal to the albedo for this model).

use glam::DVec3;

use super::error::{check_param, BrdfError};

#[derive(Clone, Debug)]
pub struct Lambertian {
    pub reflectance: f64,
}

impl Lambertian {
    pub fn new(reflectance: f64) -> Result<Self, BrdfError> {
        // Range from the shared table (`bundle::BRDF_PARAM_RANGES`).
        check_param("lambertian", "reflectance", "reflectance", reflectance)?;
        Ok(Self { reflectance })
    }

    #[inline]
    pub fn eval(&self, _wi: DVec3, _wo: DVec3) -> f64 {
        self.reflectance * std::f64::consts::FRAC_1_PI
    }
}
