//! Rahman–Pinty–Verstraete (RPV) reflection model, four-parameter form with the hot-spot
//! parameter `ρ_c` (as in Eradiate's `rpv` BSDF and the RAMI benchmark).
//!
//! Ranges are those of the shared table `bundle::BRDF_PARAM_RANGES`, which [`Rpv::new`] checks.
//!
//! | parameter | unit | range     | meaning                                                        |
//! |-----------|------|-----------|----------------------------------------------------------------|
//! | `rho_0`   | —    | [0, 1]    | amplitude ρ₀ (a BRF level: the BRF is ρ₀ when the shape terms are 1) |
//! | `k`       | —    | [0, 2]    | Minnaert-like exponent: k < 1 bowl-shaped, k > 1 bell-shaped   |
//! | `g`       | —    | (−1, 1)   | Henyey–Greenstein asymmetry Θ: g < 0 backward (bright on the Sun's side), g > 0 forward |
//! | `rho_c`   | —    | [0, 1]    | hot-spot parameter ρ_c (the original 3-parameter RPV has ρ_c = ρ₀; ρ_c = 1 removes the hot spot) |
//!
//! **BRF vs BRDF.** The RPV formula gives the *BRF* (bidirectional reflectance factor), and
//! all four parameters are dimensionless BRF-side quantities:
//!
//! ```text
//! BRF(μi, μo, Δφ) = ρ₀ · M · F · H
//!   M = [μi μo (μi + μo)]^(k−1)                      (modified Minnaert term)
//!   F = (1 − Θ²) / (1 + 2Θ cos g + Θ²)^(3/2)          (Henyey–Greenstein term, Θ = `g`)
//!   H = 1 + (1 − ρ_c) / (1 + G)                       (hot-spot term)
//!   G = √(tan²θi + tan²θo − 2 tanθi tanθo cos Δφ)
//! ```
//!
//! and [`Rpv::eval`] returns the BRDF `f_r = BRF/π` (sr⁻¹), as the module contract requires.
//!
//! **Angle conventions.** `Δφ = φi − φo` is the relative azimuth of the two outgoing vectors
//! (`wi` towards the Sun, `wo` towards the viewer; the absolute azimuth origin — clockwise from
//! North in this crate — cancels). `Δφ = 0` puts the viewer on the Sun's side (backscattering);
//! `Δφ = π` is the forward (specular) side. The phase angle `g` (not the parameter) is the angle
//! between `wi` and `wo`: `cos g = μi μo + sinθi sinθo cos Δφ = wi·wo`, so `g = 0` at the hot
//! spot (θi = θo, Δφ = 0), where `G = 0` too. The scattering angle is `π − g`, so in the HG term
//! a negative Θ peaks towards `g = 0`: `Θ < 0` is backward scattering, as in RAMI's notation.
//!
//! **Energy.** The ranges above do not make the model energy-conserving everywhere: bright,
//! bowl-shaped sets (e.g. ρ₀ = 0.4, k = 0.75, Θ = −0.1, ρ_c = 0.4) reach a directional albedo
//! above 1 at grazing incidence. Parameters fitted to real surfaces stay well below.
//!
//! **Degenerate case.** `k = 1, g = 0, ρ_c = 1` gives `M = F = H = 1`: a Lambertian of
//! reflectance ρ₀.
//!
//! References: H. Rahman, B. Pinty, M. M. Verstraete (1993), *Coupled surface-atmosphere
//! reflectance (CSAR) model 2*, J. Geophys. Res. 98(D11), 20791–20801; the ρ_c extension as in
//! J.-L. Widlowski et al. (2006), *Rayspread*, Remote Sens. Environ. 101, 1–21 (RAMI).
//! Eradiate's `rpv` plugin uses the same expressions.

use glam::DVec3;

use super::error::{check_param, BrdfError};
use super::TableSampler;

#[derive(Clone, Debug)]
pub struct Rpv {
    pub rho_0: f64,
    pub k: f64,
    pub g: f64,
    pub rho_c: f64,
    // Precomputed constants.
    rho_0_over_pi: f64,
    k_minus_1: f64,
    one_minus_g2: f64,
    one_plus_g2: f64,
    two_g: f64,
    one_minus_rho_c: f64,
    /// Importance sampler built from this model (`table_sampler.rs`).
    pub(crate) sampler: TableSampler,
}

/// Checks that `v` is a number in `[lo, hi]` (open ends where `open_*`), naming the parameter.
/// Checks against the shared range table (`bundle::BRDF_PARAM_RANGES`, the ranges above).
fn check(name: &'static str, v: f64) -> Result<(), BrdfError> {
    check_param("rpv", name, name, v)
}

impl Rpv {
    /// RPV with amplitude `rho_0`, exponent `k`, HG asymmetry `g` and hot-spot parameter `rho_c`
    /// (all dimensionless; see the module header for ranges).
    pub fn new(rho_0: f64, k: f64, g: f64, rho_c: f64) -> Result<Self, BrdfError> {
        check("rho_0", rho_0)?;
        check("k", k)?;
        check("g", g)?;
        check("rho_c", rho_c)?;
        let mut m = Self {
            rho_0,
            k,
            g,
            rho_c,
            rho_0_over_pi: rho_0 * std::f64::consts::FRAC_1_PI,
            k_minus_1: k - 1.0,
            one_minus_g2: 1.0 - g * g,
            one_plus_g2: 1.0 + g * g,
            two_g: 2.0 * g,
            one_minus_rho_c: 1.0 - rho_c,
            sampler: TableSampler::unbuilt(),
        };
        m.sampler = TableSampler::build(|wi, wo| m.eval(wi, wo));
        Ok(m)
    }

    /// BRDF (sr⁻¹) for unit vectors `wi` (towards the light) and `wo` (towards the viewer), both
    /// with `z > 0` (the caller, [`crate::bsdf::Bsdf::eval`], handles the horizon).
    #[inline]
    pub fn eval(&self, wi: DVec3, wo: DVec3) -> f64 {
        let (mi, mo) = (wi.z, wo.z);
        // Minnaert term.
        let m = if self.k_minus_1 == 0.0 {
            1.0
        } else {
            (mi * mo * (mi + mo)).powf(self.k_minus_1)
        };
        // Henyey–Greenstein term in the phase angle (cos g = wi·wo).
        let cos_g = wi.dot(wo).clamp(-1.0, 1.0);
        let d = self.one_plus_g2 + self.two_g * cos_g;
        let f = self.one_minus_g2 / (d * d.sqrt());
        // Hot-spot term: G is the distance between the projected tangent vectors
        // (tanθ cosφ, tanθ sinφ) of the two directions.
        let gx = wi.x / mi - wo.x / mo;
        let gy = wi.y / mi - wo.y / mo;
        let big_g = (gx * gx + gy * gy).sqrt();
        let h = 1.0 + self.one_minus_rho_c / (1.0 + big_g);
        self.rho_0_over_pi * m * f * h
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::{Bsdf, Lambertian};
    use crate::frame::direction_from_angles;
    use std::f64::consts::PI;

    /// Independent BRF written directly in angles (θi, θo, Δφ), term by term as in Rahman et
    /// al. (1993) with the ρ_c hot-spot factor: no vectors, powf for the 3/2 power.
    fn brf_angles(p: (f64, f64, f64, f64), ti: f64, to: f64, dphi: f64) -> f64 {
        let (rho_0, k, th, rho_c) = p;
        let (ci, co) = (ti.cos(), to.cos());
        let m = ci.powf(k - 1.0) * co.powf(k - 1.0) / (ci + co).powf(1.0 - k);
        let cos_g = ci * co + ti.sin() * to.sin() * dphi.cos();
        let f = (1.0 - th * th) / (1.0 + 2.0 * th * cos_g + th * th).powf(1.5);
        let big_g =
            (ti.tan().powi(2) + to.tan().powi(2) - 2.0 * ti.tan() * to.tan() * dphi.cos()).sqrt();
        let h = 1.0 + (1.0 - rho_c) / (1.0 + big_g);
        rho_0 * m * f * h
    }

    const SETS: [(f64, f64, f64, f64); 4] = [
        (0.2, 0.8, -0.2, 0.2),
        (0.1, 0.543, -0.29, 0.1),
        (0.497, 1.3, 0.2, 0.9),
        (0.05, 0.634, 0.086, 0.0),
    ];

    /// eval·π (vectors, tangent-plane G, dot-product phase angle) equals the angle-based BRF
    /// at many geometries: the two codings share no intermediate expression.
    #[test]
    fn eval_matches_angle_formula() {
        for &p in &SETS {
            let m = Rpv::new(p.0, p.1, p.2, p.3).unwrap();
            for &ti in &[0.0, 0.3, 0.9, 1.4] {
                for &to in &[0.0, 0.2, 0.7, 1.2, 1.5] {
                    for &dphi in &[0.0, 0.5, 1.7, PI] {
                        // Absolute azimuths arbitrary (1.1 rad); only Δφ = φi − φo matters.
                        let wi = direction_from_angles(ti, 1.1);
                        let wo = direction_from_angles(to, 1.1 - dphi);
                        let got = PI * m.eval(wi, wo);
                        let want = brf_angles(p, ti, to, dphi);
                        assert!(
                            (got - want).abs() <= 1e-12 * want.max(1.0),
                            "{p:?} {ti} {to} {dphi}: {got} vs {want}"
                        );
                    }
                }
            }
        }
    }

    /// Hand-checked number: at nadir/nadir M = 2^(k−1), cos g = 1 so F = (1−Θ)/(1+Θ)², G = 0
    /// so H = 2 − ρ_c. For (0.2, 0.8, −0.2, 0.2): BRF = 0.2 · 2^−0.2 · 1.875 · 1.8
    /// = 0.2 · 0.870550563296124 · 3.375 = 0.587621630224884.
    #[test]
    fn nadir_hand_value() {
        let m = Rpv::new(0.2, 0.8, -0.2, 0.2).unwrap();
        let brf = PI * m.eval(DVec3::Z, DVec3::Z);
        assert!((brf - 0.587621630224884).abs() < 1e-12, "{brf}");
    }

    /// Sign convention of Θ: with g < 0 (and no hot spot, flat Minnaert) the surface is
    /// brighter when the viewer is on the Sun's side (Δφ = 0) than on the forward side.
    #[test]
    fn negative_g_is_backward() {
        let m = Rpv::new(0.3, 1.0, -0.3, 1.0).unwrap();
        let sun = direction_from_angles(0.5, 0.0);
        let back = direction_from_angles(0.5, 0.0);
        let fwd = direction_from_angles(0.5, PI);
        assert!(m.eval(sun, back) > 1.5 * m.eval(sun, fwd));
        let m = Rpv::new(0.3, 1.0, 0.3, 1.0).unwrap();
        assert!(m.eval(sun, back) < m.eval(sun, fwd));
        // And the hot-spot term alone (Θ = 0) peaks at the hot spot: H = 2 − ρ_c there.
        let m = Rpv::new(0.3, 1.0, 0.0, 0.2).unwrap();
        assert!((PI * m.eval(sun, back) - 0.3 * 1.8).abs() < 1e-12);
    }

    /// Reciprocity f(wi, wo) = f(wo, wi): every term is symmetric in the two directions.
    #[test]
    fn reciprocity() {
        for &p in &SETS {
            let m = Rpv::new(p.0, p.1, p.2, p.3).unwrap();
            for &(a, b, c, d) in &[
                (0.2, 0.3, 1.0, 2.5),
                (1.3, 0.0, 0.1, 4.0),
                (0.7, 5.0, 1.45, 0.2),
            ] {
                let wi = direction_from_angles(a, b);
                let wo = direction_from_angles(c, d);
                let (x, y) = (m.eval(wi, wo), m.eval(wo, wi));
                assert!((x - y).abs() <= 1e-13 * x, "{p:?}: {x} vs {y}");
            }
        }
    }

    /// Degenerate case k = 1, Θ = 0, ρ_c = 1: M = F = H = 1, so RPV is a Lambertian of
    /// reflectance ρ₀ (same check as Eradiate's `test_eval_diffuse`).
    #[test]
    fn degenerate_is_lambertian() {
        for &rho in &[0.0, 0.25, 0.7, 1.0] {
            let m = Bsdf::Rpv(Rpv::new(rho, 1.0, 0.0, 1.0).unwrap());
            let l = Bsdf::Lambertian(Lambertian::new(rho).unwrap());
            for &(a, b, c, d) in &[
                (0.0, 0.0, 0.0, 0.0),
                (0.4, 0.3, 1.2, 2.0),
                (1.5, 1.0, 0.9, 1.0),
            ] {
                let (wi, wo) = (direction_from_angles(a, b), direction_from_angles(c, d));
                assert!((m.eval(wi, wo) - l.eval(wi, wo)).abs() < 1e-15);
            }
        }
    }

    /// Energy: directional-hemispherical albedo ≤ 1 for typical and for bright parameter sets
    /// (including a bowl-shaped k < 1, largest at grazing incidence).
    #[test]
    fn albedo_at_most_one() {
        for &p in SETS
            .iter()
            .chain(&[(0.3, 0.8, -0.1, 0.5), (0.9, 1.0, 0.0, 1.0)])
        {
            let m = Bsdf::Rpv(Rpv::new(p.0, p.1, p.2, p.3).unwrap());
            for &z in &[0.0, 0.6, 1.2, 1.5] {
                let a = m.directional_albedo(direction_from_angles(z, 0.3), 200);
                assert!(a > 0.0 && a <= 1.0, "{p:?} zenith {z}: albedo {a}");
            }
        }
        // The Lambertian degenerate case integrates to ρ₀.
        let m = Bsdf::Rpv(Rpv::new(0.9, 1.0, 0.0, 1.0).unwrap());
        assert!((m.directional_albedo(DVec3::Z, 100) - 0.9).abs() < 1e-9);
    }

    /// Constructors reject out-of-range and NaN parameters, naming the parameter.
    #[test]
    fn rejects_bad_parameters() {
        let bad = [
            (-0.1, 1.0, 0.0, 0.5, "rho_0"),
            (1.2, 1.0, 0.0, 0.5, "rho_0"),
            (f64::NAN, 1.0, 0.0, 0.5, "rho_0"),
            (0.2, 3.0, 0.0, 0.5, "k"),
            (0.2, -0.1, 0.0, 0.5, "k"),
            (0.2, f64::NAN, 0.0, 0.5, "k"),
            (0.2, 1.0, 1.0, 0.5, "g"),
            (0.2, 1.0, -1.0, 0.5, "g"),
            (0.2, 1.0, f64::NAN, 0.5, "g"),
            (0.2, 1.0, 0.0, 1.5, "rho_c"),
            (0.2, 1.0, 0.0, -0.5, "rho_c"),
            (0.2, 1.0, 0.0, f64::NAN, "rho_c"),
            (0.2, 1.0, 0.0, f64::INFINITY, "rho_c"),
        ];
        for &(a, b, c, d, name) in &bad {
            let e = Rpv::new(a, b, c, d).unwrap_err().to_string();
            assert!(e.contains(&format!("`{name}`")), "{e}");
        }
        assert_eq!(
            Rpv::new(0.2, 3.0, 0.0, 0.5).unwrap_err().to_string(),
            "`k` = 3 must lie in [0, 2]"
        );
        assert!(Rpv::new(0.0, 0.0, -0.999, 0.0).is_ok());
        assert!(Rpv::new(1.0, 2.0, 0.999, 1.0).is_ok());
    }
}
