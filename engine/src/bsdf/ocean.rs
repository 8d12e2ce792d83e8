//! Rough ocean surface: Cox–Munk isotropic slope distribution, Fresnel reflection, Smith
//! shadowing — the reflection model of Mishchenko & Travis (1997) used by IPRT case A6.
//!
//! Ranges are those of the shared table `bundle::BRDF_PARAM_RANGES`, which [`Ocean::new`] checks.
//!
//! | parameter          | unit | range       | default | meaning                                   |
//! |--------------------|------|-------------|---------|-------------------------------------------|
//! | `wind_speed`       | m/s  | [0, 40]     | —       | 10 m wind speed W                         |
//! | `refractive_index` | —    | [1, 3]      | 1.33    | real refractive index of water            |
//! | `shadowing`        | bool |             | true    | Smith (Sancer 1969) shadowing             |
//!
//! Facet slopes are Gaussian with total variance `σ² = 0.003 + 0.00512·W` (Cox & Munk 1954):
//! `P(z_x, z_y) = exp(−tan²β/σ²)/(πσ²)`, β the facet tilt. For light from `wi` reflected to `wo`
//! the facet normal is the half vector `h`, and the BRDF is
//! `f_r = R(χ)·P·S / (4 μ_i μ_o cos⁴β)` (sr⁻¹), with the Fresnel reflectance `R` at the local
//! incidence angle χ (`cos χ = wi·h`) and the shadowing factor `S = 1/(1 + Λ(μ_i) + Λ(μ_o))`,
//! `Λ(μ) = ½[√(σ²/π)·e^{−c²/σ²}/c − erfc(c/σ)]`, `c = μ/√(1−μ²)`. No whitecaps, no water-leaving
//! radiance (the sea below is black). Parameters describe the surface, not a BRF.
//!
//! Polarization: the reflection is a Mueller matrix in the scattering-plane frame of the light
//! going from `−wi` to `wo` (the facet's plane of incidence; `stokes.rs` conventions):
//! `f·[[R₊, R₋, 0, 0], [R₋, R₊, 0, 0], [0, 0, Re(r_p r_s*), 0], [0, 0, 0, Re(r_p r_s*)]]`
//! normalised by `R = (R_p + R_s)/2`, with `R₊ = (R_p + R_s)/2`, `R₋ = (R_p − R_s)/2`, and the
//! Fresnel amplitudes `r_s = (cos χ − n cos t)/(cos χ + n cos t)`,
//! `r_p = (n cos χ − cos t)/(n cos χ + cos t)` for the parallel axes `l = r × d` of that frame
//! (at normal incidence `r_p = −r_s`, the mirror's flip of the parallel axis).
//!
//! **Sampling** ([`Ocean::sample`], [`Ocean::pdf`]): facet normals are drawn from the slope
//! distribution itself, `tan²β ~ Exp(mean σ²)` and a uniform facet azimuth (`P(z_x, z_y)` is an
//! isotropic Gaussian), which is the density `p_h(h) = P/cos³β` over the solid angle of `h`
//! (`D(h)·cos β` in microfacet terms, `D = P/cos⁴β`); `wi` is `wo` mirrored about `h`, so its
//! density is `p_h(h)/(4 wo·h)` with `h` the half vector of `(wi, wo)`. The weight is then
//! `f_r cos θi/pdf = R(χ)·S·(wo·h)/(μ_o cos β)`: the Fresnel reflectance times the shadowing
//! (≈ 1 at low wind away from grazing views), however narrow the glint. Facets turned away from
//! `wo` (`wo·h < 0`) mirror `wo` below the horizon: such draws have weight 0 and end the path,
//! which stays unbiased because the pdf is the true density of the draws above the horizon
//! (it integrates to the probability of landing there, < 1).
//!
//! References: Cox & Munk (1954), J. Opt. Soc. Am. 44:838; Mishchenko & Travis (1997),
//! J. Geophys. Res. 102:16989; Sancer (1969), IEEE Trans. Antennas Propag. 17:577.

use glam::DVec3;

use super::error::{check_param, BrdfError};
use crate::stokes::PhaseMatrix;

#[derive(Clone, Debug)]
pub struct Ocean {
    pub wind_speed: f64,
    pub refractive_index: f64,
    pub shadowing: bool,
    sigma2: f64,
}

/// Complementary error function, |relative error| < 1.2e-7 (Chebyshev fit of Press et al.,
/// "Numerical Recipes", §6.2, `erfcc`).
pub fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = -z * z - 1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_203_98
                                + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    let r = t * poly.exp();
    if x >= 0.0 {
        r
    } else {
        2.0 - r
    }
}

impl Ocean {
    pub fn new(wind_speed: f64, refractive_index: f64, shadowing: bool) -> Result<Self, BrdfError> {
        // Ranges from the shared table (`bundle::BRDF_PARAM_RANGES`, as above).
        check_param("ocean", "wind_speed", "wind_speed", wind_speed)?;
        check_param(
            "ocean",
            "refractive_index",
            "refractive_index",
            refractive_index,
        )?;
        Ok(Self {
            wind_speed,
            refractive_index,
            shadowing,
            sigma2: 0.003 + 0.00512 * wind_speed,
        })
    }

    /// Slope variance σ² (Cox–Munk, isotropic).
    pub fn sigma2(&self) -> f64 {
        self.sigma2
    }

    fn lambda(&self, mu: f64) -> f64 {
        let s2 = self.sigma2;
        let c = mu / (1.0 - mu * mu).max(1e-300).sqrt();
        0.5 * ((s2 / std::f64::consts::PI).sqrt() * (-c * c / s2).exp() / c - erfc(c / s2.sqrt()))
    }

    /// Fresnel amplitude coefficients (r_s, r_p) at local incidence cos χ (real index).
    fn fresnel(&self, cos_chi: f64) -> (f64, f64) {
        let n = self.refractive_index;
        let sin_t2 = (1.0 - cos_chi * cos_chi) / (n * n);
        let cos_t = (1.0 - sin_t2).max(0.0).sqrt();
        let rs = (cos_chi - n * cos_t) / (cos_chi + n * cos_t);
        let rp = (n * cos_chi - cos_t) / (n * cos_chi + cos_t);
        (rs, rp)
    }

    /// The geometric factor `P·S/(4 μ_i μ_o cos⁴β)` and cos χ.
    #[inline]
    fn geometry(&self, wi: DVec3, wo: DVec3) -> (f64, f64) {
        let h = (wi + wo).normalize();
        let cb = h.z;
        if cb <= 0.0 {
            return (0.0, 1.0);
        }
        let cb2 = cb * cb;
        let tan2 = (1.0 - cb2) / cb2;
        let p = (-tan2 / self.sigma2).exp() / (std::f64::consts::PI * self.sigma2);
        let s = if self.shadowing {
            1.0 / (1.0 + self.lambda(wi.z) + self.lambda(wo.z))
        } else {
            1.0
        };
        (
            p * s / (4.0 * wi.z * wo.z * cb2 * cb2),
            wi.dot(h).clamp(0.0, 1.0),
        )
    }

    /// Draws `wi` given `wo` (local frame) from two uniforms in [0, 1): a facet normal from the
    /// slope distribution, `wo` mirrored about it (below the horizon for facets turned away
    /// from `wo`; see the module header).
    #[inline]
    pub fn sample(&self, wo: DVec3, u1: f64, u2: f64) -> DVec3 {
        let tan2 = -self.sigma2 * (1.0 - u1).ln();
        let cb = 1.0 / (1.0 + tan2).sqrt();
        let sb = tan2.sqrt() * cb;
        let (sp, cp) = (std::f64::consts::TAU * u2).sin_cos();
        let h = DVec3::new(sb * cp, sb * sp, cb);
        2.0 * wo.dot(h) * h - wo
    }

    /// The solid-angle density of [`Ocean::sample`] at `wi` given `wo`: `p_h(h)/(4 |wo·h|)`,
    /// `h` the half vector of `(wi, wo)` turned upwards. Valid on the whole sphere of `wi` (a
    /// facet turned away from `wo` mirrors it below the horizon); [`crate::bsdf::Bsdf::pdf`]
    /// restricts it to the upper hemisphere, where every draw keeps its path.
    #[inline]
    pub fn pdf(&self, wi: DVec3, wo: DVec3) -> f64 {
        let s = wi + wo;
        let len = s.length();
        if len < 1e-12 {
            return 0.0;
        }
        let h = if s.z < 0.0 { -s / len } else { s / len };
        let cb = h.z;
        if cb <= 0.0 {
            return 0.0;
        }
        let cb2 = cb * cb;
        let tan2 = (1.0 - cb2) / cb2;
        let p_h = (-tan2 / self.sigma2).exp() / (std::f64::consts::PI * self.sigma2 * cb2 * cb);
        p_h / (4.0 * wo.dot(h).abs())
    }

    #[inline]
    pub fn eval(&self, wi: DVec3, wo: DVec3) -> f64 {
        let (g, cos_chi) = self.geometry(wi, wo);
        if g == 0.0 {
            return 0.0;
        }
        let (rs, rp) = self.fresnel(cos_chi);
        g * 0.5 * (rs * rs + rp * rp)
    }

    /// Reflection Mueller matrix (sr⁻¹) in the scattering-plane frame of light going from `−wi`
    /// to `wo`; its `a1` equals `eval`.
    #[inline]
    pub fn matrix(&self, wi: DVec3, wo: DVec3) -> PhaseMatrix {
        let (g, cos_chi) = self.geometry(wi, wo);
        let (rs, rp) = self.fresnel(cos_chi);
        let (rs2, rp2) = (rs * rs, rp * rp);
        let a = g * 0.5 * (rp2 + rs2);
        let b = g * 0.5 * (rp2 - rs2);
        let c = g * rp * rs;
        PhaseMatrix {
            a1: a,
            b1: b,
            a2: a,
            a3: c,
            b2: 0.0,
            a4: c,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::direction_from_angles;

    /// erfc against reference values (Abramowitz & Stegun table 7.1).
    #[test]
    fn erfc_values() {
        for (x, v) in [
            (0.0, 1.0),
            (0.5, 0.479_500_122),
            (1.0, 0.157_299_207),
            (2.0, 0.004_677_735),
            (-1.0, 1.842_700_793),
        ] {
            assert!((erfc(x) - v).abs() < 2e-7 * v.max(1e-3), "{x}: {}", erfc(x));
        }
    }

    /// The BRDF against an independent evaluation in angles at the specular geometry (facet
    /// flat, β = 0): f = R(θ)·S/(4 μ² π σ²) with the Fresnel reflectance written from Snell's law.
    #[test]
    fn specular_value() {
        let o = Ocean::new(5.0, 1.33, true).unwrap();
        let th: f64 = 40f64.to_radians();
        let wi = direction_from_angles(th, 0.0);
        let wo = direction_from_angles(th, std::f64::consts::PI);
        let tt = (th.sin() / 1.33).asin();
        let rs = ((th - tt).sin() / (th + tt).sin()).powi(2);
        let rp = ((th - tt).tan() / (th + tt).tan()).powi(2);
        let s = 1.0 / (1.0 + 2.0 * o.lambda(th.cos()));
        let expect =
            0.5 * (rs + rp) * s / (4.0 * th.cos().powi(2) * std::f64::consts::PI * o.sigma2());
        assert!(
            (o.eval(wi, wo) / expect - 1.0).abs() < 1e-12,
            "{} vs {expect}",
            o.eval(wi, wo)
        );
        // Reciprocity and matrix consistency.
        let (a, b) = (
            direction_from_angles(0.3, 1.0),
            direction_from_angles(1.1, 4.0),
        );
        assert!((o.eval(a, b) - o.eval(b, a)).abs() < 1e-14 * o.eval(a, b).max(1e-30));
        assert!((o.matrix(a, b).a1 - o.eval(a, b)).abs() < 1e-15);
    }

    /// At the Brewster angle (tan χ = n) the specular reflection is fully polarized
    /// perpendicular to the plane of incidence: R_p = 0, so b1 = −a1.
    #[test]
    fn brewster() {
        let o = Ocean::new(2.0, 1.33, false).unwrap();
        let th = 1.33f64.atan();
        let m = o.matrix(
            direction_from_angles(th, 0.0),
            direction_from_angles(th, std::f64::consts::PI),
        );
        assert!((m.b1 + m.a1).abs() < 1e-9 * m.a1, "{m:?}");
    }

    /// The facet sampler's density over the whole sphere of `wi` (draws below the horizon
    /// included) integrates to 1 (the Jacobian `p_h/(4|wo·h|)` of the mirror map), at low and
    /// high wind and views to 86°. Quadrature in two charts, each dense near its centre (angle
    /// ψ = π v² from it, uniform azimuth about it) and covering the points nearer to it: the
    /// specular direction (the glint) and `−wo`, where facets seen edge-on (`wo·h → 0`) put an
    /// integrable 1/distance singularity.
    #[test]
    fn sampling_density_integrates_to_one() {
        use std::f64::consts::PI;
        for wind in [2.0, 10.0] {
            let o = Ocean::new(wind, 1.33, true).unwrap();
            for tz in [0.0, 0.6, 1.3, 1.5] {
                let wo = direction_from_angles(tz, 0.4);
                let r = DVec3::new(-wo.x, -wo.y, wo.z);
                let mut sum = 0.0;
                for (c, other) in [(r, -wo), (-wo, r)] {
                    let (a, b) = crate::frame::basis_around(c);
                    let (nv, nc) = (4000, 512);
                    for i in 0..nv {
                        let v = (i as f64 + 0.5) / nv as f64;
                        let psi = PI * v * v;
                        // dω = sin ψ dψ dχ, dψ = 2π v dv.
                        let w = psi.sin() * 2.0 * PI * v / nv as f64 * (2.0 * PI / nc as f64);
                        for j in 0..nc {
                            let chi = 2.0 * PI * (j as f64 + 0.5) / nc as f64;
                            let d = (a * chi.cos() + b * chi.sin()) * psi.sin() + c * psi.cos();
                            if d.dot(c) >= d.dot(other) {
                                sum += o.pdf(d, wo) * w;
                            }
                        }
                    }
                }
                assert!(
                    (sum - 1.0).abs() < 1e-4,
                    "wind {wind}, zenith {tz}: ∫pdf = {sum}"
                );
            }
        }
    }

    /// Energy: the directional albedo stays below 1 and near the Fresnel value (~0.02–0.06) for
    /// moderate sun; parameters out of range are rejected.
    #[test]
    fn albedo_and_ranges() {
        let o = crate::bsdf::Bsdf::Ocean(Ocean::new(2.0, 1.33, true).unwrap());
        for z in [0.0f64, 0.5, 1.0] {
            let a = o.directional_albedo(direction_from_angles(z, 0.0), 400);
            assert!(a > 0.015 && a < 0.1, "zenith {z}: albedo {a}");
        }
        assert!(Ocean::new(-1.0, 1.33, true).is_err() && Ocean::new(5.0, f64::NAN, true).is_err());
    }
}
