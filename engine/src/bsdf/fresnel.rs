//! Fresnel reflectance of a smooth interface between two non-absorbing dielectrics, the one
//! formula the transmitting models share (`rough_dielectric.rs` on each microfacet,
//! `thin_dielectric.rs` on each face of a pane).
//!
//! | argument | unit | range | meaning |
//! |---|---|---|---|
//! | `eta` | — | > 0 | index of the far side over the index of the side the light arrives from |
//! | `cos_i` | — | [0, 1] | cosine of the angle of incidence (its absolute value is taken) |
//!
//! Reference: Born & Wolf, *Principles of Optics*, 7th ed., §1.5.2 (power reflectances
//! `R_s = r_s²`, `R_p = r_p²`); total internal reflection (`eta < 1` beyond the critical
//! angle) gives 1 for both.

/// Power reflectances `(R_s, R_p)` for light arriving with incidence cosine `cos_i` on an
/// interface of relative index `eta` (far side over near side).
#[inline]
pub fn dielectric(eta: f64, cos_i: f64) -> (f64, f64) {
    let c = cos_i.abs().min(1.0);
    let sin_t2 = (1.0 - c * c) / (eta * eta);
    if sin_t2 >= 1.0 {
        return (1.0, 1.0);
    }
    let ct = (1.0 - sin_t2).sqrt();
    let rs = (c - eta * ct) / (c + eta * ct);
    let rp = (eta * c - ct) / (eta * c + ct);
    (rs * rs, rp * rp)
}

/// The unpolarized reflectance `(R_s + R_p)/2`.
#[inline]
pub fn unpolarized(eta: f64, cos_i: f64) -> f64 {
    let (s, p) = dielectric(eta, cos_i);
    0.5 * (s + p)
}

/// Cosine of the refraction angle for incidence cosine `cos_i` into relative index `eta`
/// (`None` beyond the critical angle).
#[inline]
pub fn cos_refracted(eta: f64, cos_i: f64) -> Option<f64> {
    let c = cos_i.abs().min(1.0);
    let sin_t2 = (1.0 - c * c) / (eta * eta);
    (sin_t2 < 1.0).then(|| (1.0 - sin_t2).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn textbook_values() {
        // Normal incidence on glass: ((n − 1)/(n + 1))² = 0.04.
        let (s, p) = dielectric(1.5, 1.0);
        assert!((s - 0.04).abs() < 1e-12 && (p - 0.04).abs() < 1e-12);
        // Brewster's angle tan θ_B = n: no p reflection.
        let cb = (1.0f64 / (1.0 + 1.5 * 1.5)).sqrt();
        assert!(dielectric(1.5, cb).1 < 1e-20);
        // Grazing incidence reflects everything; so does glass → air beyond 41.8°.
        assert!((unpolarized(1.5, 0.0) - 1.0).abs() < 1e-12);
        assert_eq!(unpolarized(1.0 / 1.5, 45f64.to_radians().cos()), 1.0);
        assert!(unpolarized(1.0 / 1.5, 40f64.to_radians().cos()) < 1.0);
        // The same reflectance from both sides of a refraction pair (Stokes relations).
        for &ci in &[0.9, 0.5, 0.2] {
            let ct = cos_refracted(1.33, ci).unwrap();
            assert!((unpolarized(1.33, ci) - unpolarized(1.0 / 1.33, ct)).abs() < 1e-12);
        }
    }
}
