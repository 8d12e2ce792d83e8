//! Surface reflection models (BRDFs), dispatched by an enum: one file per model.
//!
//! Frame and conventions, shared by every model:
//! * directions are unit vectors in the surface's local frame, `z` along the surface normal;
//! * `wi` points from the surface towards the light (the Sun, or the next vertex of a path),
//!   `wo` from the surface towards the viewer; both must have `z > 0`, else the BRDF is 0;
//! * `eval` returns the BRDF `f_r(wi, wo)` in sr⁻¹ (so a Lambertian of reflectance ρ gives ρ/π;
//!   the BRF is π·f_r);
//! * `sample` draws `wi` given `wo` and returns the weight `f_r·cos θ_i / pdf` and the pdf
//!   (solid-angle measure). All models sample the cosine-weighted hemisphere: their BRDFs are
//!   smooth, so the weight `π·f_r` stays bounded, and eval/pdf/sample agree by construction.
//!
//! Adding a model touches three files, all in this folder (see CONTRIBUTING.md): its file
//! (doc header with parameters, units, ranges and reference; its constructor checking the
//! ranges against `bundle::BRDF_PARAM_RANGES`; its tests),
//! a variant of [`Bsdf`] here, and a variant of [`SurfaceConfig`] with its arm in
//! [`SurfaceConfig::resolve`] (`config.rs`).

pub mod config;
pub mod hapke;
pub mod lambertian;
pub mod ocean;
pub mod rpv;
pub mod rtls;
pub mod rtls_hotspot;

use glam::DVec3;

pub use config::SurfaceConfig;
pub use hapke::Hapke;
pub use lambertian::Lambertian;
pub use ocean::Ocean;
pub use rpv::Rpv;
pub use rtls::Rtls;
pub use rtls_hotspot::RtlsHotspot;

use crate::frame::sample_cosine_hemisphere;

/// A sampled incident direction with its Monte Carlo weight.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    /// Sampled direction towards the light (local frame, `z > 0`).
    pub wi: DVec3,
    /// `f_r(wi, wo)·cos θ_i / pdf(wi)`, dimensionless.
    pub weight: f64,
    /// Solid-angle pdf of `wi`, sr⁻¹.
    pub pdf: f64,
}

/// A BRDF: a closed set of models.
#[derive(Clone, Debug)]
pub enum Bsdf {
    Lambertian(Lambertian),
    Rpv(Rpv),
    Rtls(Rtls),
    /// RTLS with the Maignan et al. (2004) hot spot.
    RtlsHotspot(RtlsHotspot),
    Hapke(Hapke),
    Ocean(Ocean),
}

impl Bsdf {
    /// BRDF value in sr⁻¹; 0 when either direction is below the horizon.
    #[inline]
    pub fn eval(&self, wi: DVec3, wo: DVec3) -> f64 {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        match self {
            Bsdf::Lambertian(m) => m.eval(wi, wo),
            Bsdf::Rpv(m) => m.eval(wi, wo),
            Bsdf::Rtls(m) => m.eval(wi, wo),
            Bsdf::RtlsHotspot(m) => m.eval(wi, wo),
            Bsdf::Hapke(m) => m.eval(wi, wo),
            Bsdf::Ocean(m) => m.eval(wi, wo),
        }
    }

    /// The reflection Mueller matrix in the scattering-plane frame of light going from `−wi` to
    /// `wo` (`stokes.rs`), for polarizing models; `None` for depolarizing ones (the reflected
    /// light is unpolarized with intensity `eval`).
    #[inline]
    pub fn matrix(&self, wi: DVec3, wo: DVec3) -> Option<crate::stokes::PhaseMatrix> {
        match self {
            Bsdf::Ocean(m) if wi.z > 0.0 && wo.z > 0.0 => Some(m.matrix(wi, wo)),
            Bsdf::Ocean(_) => Some(crate::stokes::PhaseMatrix::depolarizing(0.0)),
            _ => None,
        }
    }

    /// Solid-angle pdf of sampling `wi` given `wo`.
    #[inline]
    pub fn pdf(&self, wi: DVec3, _wo: DVec3) -> f64 {
        if wi.z <= 0.0 {
            0.0
        } else {
            wi.z * std::f64::consts::FRAC_1_PI
        }
    }

    /// Draw `wi` given `wo` from two uniform numbers in [0, 1).
    #[inline]
    pub fn sample(&self, wo: DVec3, u1: f64, u2: f64) -> BsdfSample {
        let wi = sample_cosine_hemisphere(u1, u2);
        let pdf = wi.z * std::f64::consts::FRAC_1_PI;
        let weight = self.sample_weight(wi, wo);
        BsdfSample { wi, weight, pdf }
    }

    /// The weight `f_r(wi, wo)·cos θ_i / pdf(wi)` that [`Bsdf::sample`] gives a drawn `wi`.
    /// Every model samples the same (cosine-weighted) density, so this is also the weight of a
    /// direction drawn from another model's `sample` (spectral ALIS walks rely on it).
    #[inline]
    pub fn sample_weight(&self, wi: DVec3, wo: DVec3) -> f64 {
        match self {
            Bsdf::Lambertian(m) => m.reflectance,
            _ => std::f64::consts::PI * self.eval(wi, wo),
        }
    }

    /// Directional-hemispherical reflectance for light incident from `wi` (numerical quadrature,
    /// for tests and products; `n` is the number of nodes per axis).
    pub fn directional_albedo(&self, wi: DVec3, n: usize) -> f64 {
        // Midpoint rule in (cos²θ, φ): the measure cos θ dω = ½ d(cos²θ) dφ.
        let mut sum = 0.0;
        for i in 0..n {
            let c2 = (i as f64 + 0.5) / n as f64;
            let ct = c2.sqrt();
            let st = (1.0 - c2).sqrt();
            for j in 0..(2 * n) {
                let phi = std::f64::consts::PI * (j as f64 + 0.5) / n as f64;
                let wo = DVec3::new(st * phi.cos(), st * phi.sin(), ct);
                sum += self.eval(wi, wo);
            }
        }
        // ∫ f cosθ dω = ∫∫ f · ½ d(c²) dφ ; cells: Δ(c²) = 1/n, Δφ = π/n.
        sum * 0.5 * (1.0 / n as f64) * (std::f64::consts::PI / n as f64)
    }
}

#[cfg(test)]
pub(crate) mod test_support {
    use glam::DVec3;

    /// The 0.1 % upper quantile of χ² with 99 degrees of freedom.
    pub const CHI2_99_DOF_999: f64 = 148.2;

    /// χ² of directions drawn by `draw(u1, u2)` against the cosine-weighted hemisphere density
    /// that every model samples (`Bsdf::pdf`): 10×10 cells equal in probability (sin²θ and φ
    /// in 10 bins each), 100 000 draws from a fixed stream; 99 degrees of freedom.
    pub fn chi2_cosine(mut draw: impl FnMut(f64, f64) -> DVec3) -> f64 {
        let mut rng = crate::rng::Stream::new(1234, [1, 2, 3, 4]);
        let n = 10;
        let mut counts = vec![0u32; n * n];
        let total = 100_000;
        for _ in 0..total {
            let (u1, u2) = (rng.next_f64(), rng.next_f64());
            let d = draw(u1, u2);
            assert!(d.z > 0.0 && (d.length() - 1.0).abs() < 1e-12, "{d}");
            let s2 = 1.0 - d.z * d.z;
            let mut phi = d.y.atan2(d.x);
            if phi < 0.0 {
                phi += std::f64::consts::TAU;
            }
            let i = ((s2 * n as f64) as usize).min(n - 1);
            let j = ((phi / std::f64::consts::TAU * n as f64) as usize).min(n - 1);
            counts[i * n + j] += 1;
        }
        let e = total as f64 / (n * n) as f64;
        counts.iter().map(|&c| (c as f64 - e).powi(2) / e).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::direction_from_angles;

    fn models() -> Vec<Bsdf> {
        vec![
            Bsdf::Lambertian(Lambertian::new(0.3).unwrap()),
            Bsdf::Rpv(Rpv::new(0.2, 0.8, -0.2, 0.2).unwrap()),
            Bsdf::Rtls(Rtls::new(0.2, 0.05, 0.03).unwrap()),
            Bsdf::RtlsHotspot(RtlsHotspot::new(0.2, 0.05, 0.03, 1.5).unwrap()),
            Bsdf::Hapke(Hapke::new(0.5, 0.3, 0.4, 15.0, 0.8, 0.06).unwrap()),
        ]
    }

    /// Sampling weight equals eval·cos/pdf, for every model (the integrators rely on it).
    #[test]
    fn sample_weight_is_eval_cos_over_pdf() {
        let wo = direction_from_angles(0.6, 1.0);
        for m in models() {
            for k in 0..50 {
                let u1 = (k as f64 + 0.37) / 50.0;
                let u2 = ((k * 7) % 50) as f64 / 50.0 + 0.01;
                let s = m.sample(wo, u1, u2);
                let expect = m.eval(s.wi, wo) * s.wi.z / m.pdf(s.wi, wo);
                assert!(
                    (s.weight - expect).abs() <= 1e-12 * expect.max(1.0),
                    "{m:?}"
                );
                assert!((s.pdf - m.pdf(s.wi, wo)).abs() < 1e-12);
            }
        }
    }

    /// χ² test of the cosine-weighted hemisphere sampler shared by all models (see
    /// [`test_support::chi2_cosine`]).
    #[test]
    fn chi2_cosine_sampling() {
        let chi2 = test_support::chi2_cosine(sample_cosine_hemisphere);
        assert!(chi2 < test_support::CHI2_99_DOF_999, "chi2 = {chi2}");
    }

    /// Energy conservation: directional albedo ≤ 1 for every model at several incidences.
    #[test]
    fn directional_albedo_at_most_one() {
        for m in models() {
            for &z in &[0.0, 0.5, 1.0, 1.4] {
                let a = m.directional_albedo(direction_from_angles(z, 0.0), 200);
                assert!(a > 0.0 && a <= 1.0, "{m:?} zenith {z}: albedo {a}");
            }
        }
        let lam = Bsdf::Lambertian(Lambertian::new(0.3).unwrap());
        let a = lam.directional_albedo(DVec3::Z, 100);
        assert!((a - 0.3).abs() < 1e-9, "{a}");
    }
}
