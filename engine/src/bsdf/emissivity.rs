//! Thermal emission of a surface: Kirchhoff's law for any BRDF.
//!
//! | parameter | unit | meaning |
//! |---|---|---|
//! | `temperature` | K | the surface's temperature (every `[surface]` type takes it) |
//!
//! A surface in local thermodynamic equilibrium emits, into direction `v`,
//! `ε(v)·B_λ(T_s)` with the directional emissivity `ε(v) = 1 − ρ_dh(v)`, `ρ_dh(v) = ∫ f(v, i)
//! cos θ_i dω_i` the directional-hemispherical reflectance (Kirchhoff's law; by the BRDF's
//! reciprocity the reflectance for light arriving from `v`). For a Lambertian surface of
//! reflectance ρ, `ε = 1 − ρ` in every direction. Other models are integrated once per
//! wavelength ([`reflectance`], 128 × 256 nodes in √μ and azimuth) at 33 view cosines and
//! interpolated linearly in μ; the 1D surfaces these serve depend on the relative azimuth only,
//! so `ε` depends on μ only. Reference: Siegel & Howell, *Thermal Radiation Heat Transfer*,
//! ch. 3 (Kirchhoff's law for directional spectral properties).

use glam::DVec3;

use super::Bsdf;

/// View cosines of the emissivity table: `μ_i = i/N_MU`, `i = 0..=N_MU`.
const N_MU: usize = 32;

/// Nodes per axis of [`reflectance`] (`N_QUAD` in u, `2·N_QUAD` in azimuth).
const N_QUAD: usize = 128;

/// Directional-hemispherical reflectance `∫ f(v, w) cos θ_w dω_w` by the midpoint rule in
/// `u = √μ` (cos θ dω = 2u³ du dφ) and in azimuth. The substitution tames the `μ^{k−1}`
/// singularity of RPV-like models at grazing incidence (k < 1), which the midpoint rule in μ
/// or μ² converges to only slowly (3e-3 off at 64 nodes for k = 0.6).
pub fn reflectance(bsdf: &Bsdf, v: DVec3, n: usize) -> f64 {
    let mut sum = 0.0;
    for i in 0..n {
        let u = (i as f64 + 0.5) / n as f64;
        let mu = u * u;
        let st = (1.0 - mu * mu).sqrt();
        let mut ring = 0.0;
        for j in 0..2 * n {
            let phi = std::f64::consts::PI * (j as f64 + 0.5) / n as f64;
            ring += bsdf.eval(v, DVec3::new(st * phi.cos(), st * phi.sin(), mu));
        }
        sum += ring * 2.0 * u * u * u;
    }
    sum * (1.0 / n as f64) * (std::f64::consts::PI / n as f64)
}

/// A surface's thermal source at one wavelength.
#[derive(Clone, Debug)]
pub struct SurfaceEmission {
    /// `B_λ(T_s)` in the units of the path tally.
    pub source: f64,
    /// `ε` at `μ_i = i/N_MU` (one value for a Lambertian surface).
    emissivity: Vec<f64>,
}

impl SurfaceEmission {
    /// The emission of `bsdf` at temperature source `source` (`B_λ(T_s)`, tally units).
    pub fn new(bsdf: &Bsdf, source: f64) -> Self {
        let emissivity = match bsdf {
            Bsdf::Lambertian(l) => vec![(1.0 - l.reflectance).clamp(0.0, 1.0)],
            _ => (0..=N_MU)
                .map(|i| {
                    // μ = 0 exactly is a grazing direction; take a nearly grazing one.
                    let mu = (i as f64 / N_MU as f64).max(1e-3);
                    let v = DVec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
                    (1.0 - reflectance(bsdf, v, N_QUAD)).clamp(0.0, 1.0)
                })
                .collect(),
        };
        SurfaceEmission { source, emissivity }
    }

    /// Directional emissivity into a direction of vertical cosine `mu` (> 0).
    pub fn emissivity(&self, mu: f64) -> f64 {
        if self.emissivity.len() == 1 {
            return self.emissivity[0];
        }
        let x = mu.clamp(0.0, 1.0) * N_MU as f64;
        let i = (x.floor() as usize).min(N_MU - 1);
        let f = x - i as f64;
        self.emissivity[i] * (1.0 - f) + self.emissivity[i + 1] * f
    }

    /// Emitted radiance into a direction of vertical cosine `mu`, tally units.
    pub fn radiance(&self, mu: f64) -> f64 {
        self.source * self.emissivity(mu)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::{Lambertian, Rpv};

    #[test]
    fn lambertian_is_one_minus_reflectance() {
        let e = SurfaceEmission::new(&Bsdf::Lambertian(Lambertian::new(0.3).unwrap()), 2.0);
        for mu in [0.01, 0.5, 1.0] {
            assert!((e.radiance(mu) - 1.4).abs() < 1e-15);
        }
    }

    /// Kirchhoff closure: a Lambertian-like RPV (k = 1, g = 0, ρ_c = 1) has ε = 1 − ρ₀ up to
    /// the quadrature; a general RPV has ε in [0, 1] and equals 1 − ρ_dh at the table's nodes.
    #[test]
    fn table_matches_the_integral() {
        let flat = Bsdf::Rpv(Rpv::new(0.2, 1.0, 0.0, 1.0).unwrap());
        let e = SurfaceEmission::new(&flat, 1.0);
        for mu in [0.05, 0.3, 0.77, 1.0] {
            assert!(
                (e.emissivity(mu) - 0.8).abs() < 2e-3,
                "{}",
                e.emissivity(mu)
            );
        }
        let rpv = Bsdf::Rpv(Rpv::new(0.1, 0.543, -0.29, 0.1).unwrap());
        let e = SurfaceEmission::new(&rpv, 1.0);
        let mu = 0.5;
        let v = DVec3::new((1.0f64 - mu * mu).sqrt(), 0.0, mu);
        let want = 1.0 - reflectance(&rpv, v, 512);
        assert!(
            (e.emissivity(mu) - want).abs() < 2e-4,
            "{} {want}",
            e.emissivity(mu)
        );
        assert!((0.0..=1.0).contains(&e.emissivity(0.1)));
    }
}

#[cfg(test)]
mod convergence {
    use super::*;
    use crate::bsdf::Rpv;

    /// The √μ substitution converges where the midpoint rule in μ² does not: RPV k = 0.6
    /// (singular at grazing incidence), 128 against 512 nodes.
    #[test]
    fn singular_rpv_converges() {
        let rpv = Bsdf::Rpv(Rpv::new(0.3, 0.6, -0.3, 0.3).unwrap());
        for mu in [0.1f64, 0.28, 0.5, 1.0] {
            let v = DVec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
            let (a, b) = (reflectance(&rpv, v, 128), reflectance(&rpv, v, 512));
            assert!((a - b).abs() < 2e-4, "mu {mu}: {a} {b}");
        }
    }
}
