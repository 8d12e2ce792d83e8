//! A thin dielectric slab (a glass pane): specular reflection and straight-through
//! transmission, with the slab's internal reflections summed in closed form. Both faces are
//! alike. A scene material (`SurfaceModel::Pane`, `scene/material.rs`); shadow rays cross a
//! pane attenuated by its transmittance (`Scene::visibility`), since a thin slab does not
//! deviate the beam.
//!
//! | parameter | unit | range | meaning |
//! |---|---|---|---|
//! | `refractive_index` | — | [1, 3] | n of the slab's material (air outside) |
//! | `internal_transmittance` | — | [0, 1] | t₀: transmittance of one pass through the slab at normal incidence (default 1, no absorption); along a refracted path of cosine μ_t a pass transmits a = t₀^(1/μ_t) |
//!
//! For incidence cosine μ on either face, with r the Fresnel power reflectance of one face for
//! each polarization (s, p; `fresnel.rs`), the incoherent sum of the internal reflections is
//!
//! `R = r + (1 − r)²·r·a²/(1 − r²a²)`,  `T = (1 − r)²·a/(1 − r²a²)`,
//!
//! averaged over s and p (the two do not mix at parallel interfaces, so the series is summed per
//! polarization before averaging). The pane absorbs A = 1 − R − T, which is also its
//! emissivity (Kirchhoff). Without absorption `T = (1 − r)/(1 + r)` per polarization.
//!
//! Reference: Born & Wolf, *Principles of Optics*, 7th ed., §1.6.4 and §7.6 (incoherent
//! multiple reflections in a plate); the same closed form as the "thin dielectric" of Mitsuba
//! and PBRT (Pharr, Jakob & Humphreys 2016, §8.2), summed there for the unpolarized Fresnel
//! term; here per polarization.

use super::error::{check_param, BrdfError};
use super::fresnel;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThinDielectric {
    pub refractive_index: f64,
    pub internal_transmittance: f64,
}

impl ThinDielectric {
    pub fn new(refractive_index: f64, internal_transmittance: f64) -> Result<Self, BrdfError> {
        check_param(
            "thin_dielectric",
            "refractive_index",
            "refractive_index",
            refractive_index,
        )?;
        check_param(
            "thin_dielectric",
            "internal_transmittance",
            "internal_transmittance",
            internal_transmittance,
        )?;
        Ok(Self {
            refractive_index,
            internal_transmittance,
        })
    }

    /// `(R, T)`: the pane's reflectance and transmittance for a beam of incidence cosine `mu`
    /// (either face; its absolute value is taken).
    pub fn reflect_transmit(&self, mu: f64) -> (f64, f64) {
        let n = self.refractive_index;
        let mu = mu.abs().min(1.0);
        let Some(cos_t) = fresnel::cos_refracted(n, mu) else {
            return (1.0, 0.0);
        };
        let t0 = self.internal_transmittance;
        let a = if t0 >= 1.0 {
            1.0
        } else if t0 <= 0.0 || cos_t <= 0.0 {
            0.0
        } else {
            t0.powf(1.0 / cos_t)
        };
        let one = |r: f64| {
            if r >= 1.0 {
                return (1.0, 0.0);
            }
            let d = 1.0 - r * r * a * a;
            let q = (1.0 - r) * (1.0 - r);
            (r + q * r * a * a / d, q * a / d)
        };
        let (rs, rp) = fresnel::dielectric(n, mu);
        let (r1, t1) = one(rs);
        let (r2, t2) = one(rp);
        (0.5 * (r1 + r2), 0.5 * (t1 + t2))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An independent sum: the beam bounced inside the slab pass by pass (each polarization),
    /// until what is left is below 1e-16.
    fn by_passes(n: f64, t0: f64, mu: f64) -> (f64, f64) {
        let ct = fresnel::cos_refracted(n, mu).unwrap();
        let a = t0.powf(1.0 / ct);
        let (rs, rp) = fresnel::dielectric(n, mu);
        let mut out = (0.0, 0.0);
        for r in [rs, rp] {
            let (mut refl, mut tran) = (r, 0.0);
            // Inside, going down: (1 − r)·a after the first pass.
            let mut inside = (1.0 - r) * a;
            let mut down = true;
            while inside > 1e-16 {
                if down {
                    tran += inside * (1.0 - r);
                } else {
                    refl += inside * (1.0 - r);
                }
                inside *= r * a;
                down = !down;
            }
            out.0 += 0.5 * refl;
            out.1 += 0.5 * tran;
        }
        out
    }

    #[test]
    fn closed_form_equals_the_sum_of_passes() {
        for &n in &[1.0, 1.33, 1.52, 2.4] {
            for &t0 in &[1.0, 0.9, 0.3] {
                for &deg in &[0.0f64, 30.0, 60.0, 80.0, 89.0] {
                    let mu = deg.to_radians().cos();
                    let p = ThinDielectric::new(n, t0).unwrap();
                    let (r, t) = p.reflect_transmit(mu);
                    let (r2, t2) = by_passes(n, t0, mu);
                    assert!(
                        (r - r2).abs() < 1e-12 && (t - t2).abs() < 1e-12,
                        "{n} {t0} {deg}"
                    );
                    assert!(r + t <= 1.0 + 1e-12);
                    if t0 == 1.0 {
                        assert!((r + t - 1.0).abs() < 1e-12);
                    }
                }
            }
        }
    }

    #[test]
    fn textbook_pane() {
        // A non-absorbing pane of n = 1.5 at normal incidence: T = (1 − r)/(1 + r), r = 0.04.
        let p = ThinDielectric::new(1.5, 1.0).unwrap();
        let (r, t) = p.reflect_transmit(1.0);
        assert!((t - 0.96 / 1.04).abs() < 1e-12 && (r - 0.08 / 1.04).abs() < 1e-12);
        // At grazing incidence a pane reflects everything.
        assert_eq!(p.reflect_transmit(0.0), (1.0, 0.0));
        assert!(ThinDielectric::new(0.9, 1.0).is_err());
        assert!(ThinDielectric::new(1.5, 1.1).is_err());
    }
}
