//! Hapke reflection model for particulate surfaces, six-parameter form as in Eradiate's `hapke`
//! BSDF: isotropic multiple-scattering approximation with the shadow-hiding opposition effect
//! (SHOE), a two-parameter double Henyey–Greenstein particle phase function and Hapke's
//! macroscopic-roughness correction (no coherent-backscatter term, no porosity factor).
//!
//! Ranges are those of the shared table `bundle::BRDF_PARAM_RANGES`, which [`Hapke::new`] checks.
//!
//! | parameter   | unit | range   | meaning                                                      |
//! |-------------|------|---------|--------------------------------------------------------------|
//! | `w`         | —    | [0, 1]  | single-scattering albedo of the particles                    |
//! | `b`         | —    | [0, 1)  | shape (asymmetry magnitude) of each HG lobe                   |
//! | `c`         | —    | [0, 1]  | weight of the *backward* lobe (1 − c weights the forward one) |
//! | `theta_deg` | deg  | [0, 90) | mean slope angle θ̄ of the macroscopic roughness (key `theta`) |
//! | `b_0`       | —    | [0, 1]  | SHOE amplitude B₀ (key `B_0`)                                 |
//! | `h`         | —    | [0, 1]  | SHOE angular width h (h = 0 switches the opposition peak off) |
//!
//! **BRF vs BRDF.** Hapke's *bidirectional reflectance* `r` (radiance per unit irradiance on a
//! plane normal to the beam) is
//!
//! ```text
//! r = (w/4π) · μ0e/(μ0e + μe) · [P(g)(1 + B(g)) + H(μ0e) H(μe) − 1] · S(i, e, ψ)
//! P(g) = (1 − c)(1 − b²)/(1 + 2b cos g + b²)^(3/2) + c(1 − b²)/(1 − 2b cos g + b²)^(3/2)
//! B(g) = B₀ / (1 + tan(g/2)/h)
//! H(x) = 1/{1 − w x [r₀ + (1 − 2 r₀ x)/2 · ln((1 + x)/x)]},  r₀ = (1 − γ)/(1 + γ), γ = √(1 − w)
//! ```
//!
//! The BRDF is `r/μ0` and the BRF is `π r/μ0`; [`Hapke::eval`] returns the BRDF (sr⁻¹) as the
//! module contract requires. (Eradiate's plugin returns `π r/μ0`, the BRF, from its BRDF
//! evaluation: its test values — e.g. 0.24746648 at θi = θo = 30°, Δφ = 0 with Pommerol et al.
//! (2013) parameters — equal π × our `eval`; see the tests.) `w`, `b`, `c`, `B₀`, `h` are
//! particle/regolith properties, not BRF levels.
//!
//! Roughness (Hapke 1984; Hapke 2012, ch. 12), with χ = 1/√(1 + π tan²θ̄),
//! `E₁(x) = exp(−(2/π) cot θ̄ cot x)`, `E₂(x) = exp(−(1/π) cot²θ̄ cot²x)`,
//! `η(x) = χ [cos x + sin x tan θ̄ E₂(x)/(2 − E₁(x))]`, `f(ψ) = exp(−2 tan(ψ/2))`:
//!
//! ```text
//! i ≤ e: μ0e = χ[cos i + sin i tanθ̄ (cosψ E₂(e) + sin²(ψ/2) E₂(i)) / (2 − E₁(e) − (ψ/π) E₁(i))]
//!        μe  = χ[cos e + sin e tanθ̄ (E₂(e) − sin²(ψ/2) E₂(i))     / (2 − E₁(e) − (ψ/π) E₁(i))]
//!        S   = (μe/η(e)) (μ0/η(i)) χ / [1 − f(ψ) + f(ψ) χ μ0/η(i)]
//! e ≤ i: the same with i ↔ e exchanged in the brackets, and χ μ/η(e) in S's denominator.
//! ```
//!
//! With θ̄ = 0: μ0e = μ0, μe = μ, S = 1. The BRDF is reciprocal.
//!
//! **Angle conventions.** `i`, `e`: zeniths of `wi` (towards the light) and `wo` (towards the
//! viewer), μ0 = cos i, μ = cos e. `ψ ∈ [0, π]` is the relative azimuth between the two
//! outgoing vectors (the absolute origin — clockwise from North in this crate — cancels): ψ = 0
//! puts the viewer on the light's side (backscattering). `g` is the phase angle between `wi`
//! and `wo` (`cos g = wi·wo = μ0μ + sin i sin e cos ψ`), g = 0 at opposition; the lobe weighted
//! by `c` peaks at g = 0 (backward), the one weighted by `1 − c` at g = π (forward). Hapke
//! (2012)'s `c ∈ [−1, 1]` with `(1 + c)/2` on the backward lobe maps to this `c` as
//! `(1 + c_2012)/2`.
//!
//! **Limits used as checks.** No parameter set is exactly Lambertian. With θ̄ = 0, B₀ = 0,
//! b = 0 (any c) the model is Hapke's isotropic-scatterer law
//! `f_r = (w/4π) H(μ0) H(μ)/(μ0 + μ)` (Lommel–Seeliger times the multiple-scattering H
//! functions), whose directional albedo is `1 − γ H(μ0)` for the exact H (so 1 when w = 1);
//! with the approximate H above it is within about 1.5 % of that, from below.
//!
//! References: B. Hapke (1984), *Bidirectional reflectance spectroscopy 3. Correction for
//! macroscopic roughness*, Icarus 59, 41–59; B. Hapke (2002), Icarus 157, 523–534 (the H
//! approximation); B. Hapke (2012), *Theory of Reflectance and Emittance Spectroscopy*, 2nd ed.,
//! Cambridge University Press (eqs. 6.7, 9.22, 8.56, ch. 12).

use glam::DVec3;
use std::f64::consts::{FRAC_1_PI, PI};

use super::error::{check_param, BrdfError};
use super::TableSampler;

#[derive(Clone, Debug)]
pub struct Hapke {
    pub w: f64,
    pub b: f64,
    pub c: f64,
    pub theta_deg: f64,
    pub b_0: f64,
    pub h: f64,
    // Precomputed constants.
    w_over_4pi: f64,
    r0: f64,
    one_minus_b2: f64,
    one_plus_b2: f64,
    two_b: f64,
    inv_h: f64,
    rough: bool,
    tan_tb: f64,
    cot_tb: f64,
    chi: f64,
    /// Importance sampler built from this model (`table_sampler.rs`).
    pub(crate) sampler: TableSampler,
}

/// Checks against the shared range table (`bundle::BRDF_PARAM_RANGES`, the ranges above); the
/// message names the parameter by its key in experiment files and bundles (`theta`, `B_0`).
fn check(key: &'static str, v: f64) -> Result<(), BrdfError> {
    check_param("hapke", key, key, v)
}

impl Hapke {
    /// Hapke model from single-scattering albedo `w`, phase-function parameters `b`, `c`, mean
    /// slope `theta_deg` (degrees), SHOE amplitude `b_0` and width `h` (see the module header).
    pub fn new(
        w: f64,
        b: f64,
        c: f64,
        theta_deg: f64,
        b_0: f64,
        h: f64,
    ) -> Result<Self, BrdfError> {
        check("w", w)?;
        check("b", b)?;
        check("c", c)?;
        check("theta", theta_deg)?;
        check("B_0", b_0)?;
        check("h", h)?;
        let gamma = (1.0 - w).sqrt();
        let tan_tb = theta_deg.to_radians().tan();
        let mut m = Self {
            w,
            b,
            c,
            theta_deg,
            b_0,
            h,
            w_over_4pi: w * 0.25 * FRAC_1_PI,
            r0: (1.0 - gamma) / (1.0 + gamma),
            one_minus_b2: 1.0 - b * b,
            one_plus_b2: 1.0 + b * b,
            two_b: 2.0 * b,
            inv_h: if h > 0.0 { 1.0 / h } else { 0.0 },
            rough: theta_deg > 0.0,
            tan_tb,
            cot_tb: if theta_deg > 0.0 { 1.0 / tan_tb } else { 0.0 },
            chi: 1.0 / (1.0 + PI * tan_tb * tan_tb).sqrt(),
            sampler: TableSampler::unbuilt(),
        };
        m.sampler = TableSampler::build(|wi, wo| m.eval(wi, wo));
        Ok(m)
    }

    /// Ambartsumian–Chandrasekhar H function, Hapke (2002) approximation.
    #[inline]
    fn h_fn(&self, x: f64) -> f64 {
        let l = (1.0 / x).ln_1p();
        1.0 / (1.0 - self.w * x * (self.r0 + 0.5 * (1.0 - 2.0 * self.r0 * x) * l))
    }

    /// Roughness correction: `(μ0e, μe, S/μ0)`.
    #[inline]
    fn roughness(&self, wi: DVec3, wo: DVec3) -> (f64, f64, f64) {
        let (mu0, mu) = (wi.z, wo.z);
        if !self.rough {
            return (mu0, mu, 1.0 / mu0);
        }
        let si = (wi.x * wi.x + wi.y * wi.y).sqrt();
        let se = (wo.x * wo.x + wo.y * wo.y).sqrt();
        // Relative azimuth ψ ∈ [0, π] from the horizontal components (atan2 of the 2-D cross
        // and dot products: accurate near ψ = 0 and π, unlike acos). At nadir ψ is undefined
        // and the result does not depend on it (sin i = 0 there), so take ψ = 0.
        let sp = si * se;
        let (cos_psi, psi_over_pi, tan_half) = if sp > 0.0 {
            let dot2 = wi.x * wo.x + wi.y * wo.y;
            let cross2 = (wi.x * wo.y - wi.y * wo.x).abs();
            // tan(ψ/2) = sinψ/(1 + cosψ) = (1 − cosψ)/sinψ: the form without cancellation.
            let tan_half = if dot2 >= 0.0 {
                cross2 / (sp + dot2)
            } else if cross2 > 0.0 {
                (sp - dot2) / cross2
            } else {
                f64::INFINITY
            };
            (
                (dot2 / sp).clamp(-1.0, 1.0),
                cross2.atan2(dot2) * FRAC_1_PI,
                tan_half,
            )
        } else {
            (1.0, 0.0, 0.0)
        };
        let sin2_half = 0.5 * (1.0 - cos_psi);
        // f(ψ) = exp(−2 tan(ψ/2)); f(π) = exp(−∞) = 0.
        let f = (-2.0 * tan_half).exp();
        let (kt, tt, chi) = (self.cot_tb, self.tan_tb, self.chi);
        // cot of each zenith (+∞ at nadir: E₁ = E₂ = 0 there).
        let (cot_i, cot_e) = (mu0 / si, mu / se);
        let e1 = |cot: f64| (-2.0 * FRAC_1_PI * kt * cot).exp();
        let e2 = |cot: f64| (-FRAC_1_PI * kt * kt * cot * cot).exp();
        let (e1i, e1e, e2i, e2e) = (e1(cot_i), e1(cot_e), e2(cot_i), e2(cot_e));
        let eta_i = chi * (mu0 + si * tt * e2i / (2.0 - e1i));
        let eta_e = chi * (mu + se * tt * e2e / (2.0 - e1e));
        let (mu0e, mue, ratio) = if mu0 >= mu {
            // i ≤ e
            let q = tt / (2.0 - e1e - psi_over_pi * e1i);
            (
                chi * (mu0 + si * q * (cos_psi * e2e + sin2_half * e2i)),
                chi * (mu + se * q * (e2e - sin2_half * e2i)),
                chi * mu0 / eta_i,
            )
        } else {
            // e < i
            let q = tt / (2.0 - e1i - psi_over_pi * e1e);
            (
                chi * (mu0 + si * q * (e2i - sin2_half * e2e)),
                chi * (mu + se * q * (cos_psi * e2i + sin2_half * e2e)),
                chi * mu / eta_e,
            )
        };
        // S/μ0 = (μe/η(e)) χ / (η(i) [1 − f + f·ratio]): symmetric in (i, e) given the swap.
        let s_over_mu0 = mue * chi / (eta_e * eta_i * (1.0 - f + f * ratio));
        (mu0e, mue, s_over_mu0)
    }

    /// BRDF (sr⁻¹) `r/μ0` for unit vectors `wi` (towards the light) and `wo` (towards the
    /// viewer), both with `z > 0` (the caller, [`crate::bsdf::Bsdf::eval`], handles the horizon).
    #[inline]
    pub fn eval(&self, wi: DVec3, wo: DVec3) -> f64 {
        let cos_g = wi.dot(wo).clamp(-1.0, 1.0);
        // Double HG particle phase function.
        let d_fwd = self.one_plus_b2 + self.two_b * cos_g;
        let d_bwd = self.one_plus_b2 - self.two_b * cos_g;
        let p = self.one_minus_b2
            * ((1.0 - self.c) / (d_fwd * d_fwd.sqrt()) + self.c / (d_bwd * d_bwd.sqrt()));
        // SHOE, tan(g/2) = |wi×wo| / (1 + wi·wo).
        let b_sh = if self.inv_h > 0.0 {
            let tan_half_g = wi.cross(wo).length() / (1.0 + cos_g);
            self.b_0 / (1.0 + tan_half_g * self.inv_h)
        } else {
            0.0
        };
        let (mu0e, mue, s_over_mu0) = self.roughness(wi, wo);
        let ms = self.h_fn(mu0e) * self.h_fn(mue) - 1.0;
        self.w_over_4pi * mu0e / (mu0e + mue) * (p * (1.0 + b_sh) + ms) * s_over_mu0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::Bsdf;
    use crate::frame::direction_from_angles;

    type Params = (f64, f64, f64, f64, f64, f64);

    /// Pommerol et al. (2013) parameters as used in Eradiate's test suite (c = (1 + 0.273)/2).
    const POMMEROL: Params = (0.526, 0.187, 0.6365, 13.3, 1.0, 0.083);

    fn model(p: Params) -> Hapke {
        Hapke::new(p.0, p.1, p.2, p.3, p.4, p.5).unwrap()
    }

    /// Independent evaluation written in angles (i, e, ψ), following Hapke (1984)/(2012)
    /// literally: both roughness cases spelled out, tan/cot of the angles, acos for g, the
    /// bidirectional reflectance r first and the BRDF r/μ0 last.
    fn brdf_angles(p: Params, i: f64, e: f64, psi: f64) -> f64 {
        let (w, b, c, thd, b0, h) = p;
        let hf = |x: f64| {
            let gam = (1.0 - w).sqrt();
            let r0 = (1.0 - gam) / (1.0 + gam);
            1.0 / (1.0 - w * x * (r0 + (1.0 - 2.0 * r0 * x) / 2.0 * ((1.0 + x) / x).ln()))
        };
        let (mu0e, mue, s) = if thd == 0.0 {
            (i.cos(), e.cos(), 1.0)
        } else {
            let tb = thd.to_radians().tan();
            let chi = 1.0 / (1.0 + PI * tb * tb).sqrt();
            let e1 = |x: f64| (-2.0 / PI / tb / x.tan()).exp();
            let e2 = |x: f64| (-1.0 / PI / (tb * tb) / (x.tan() * x.tan())).exp();
            let eta = |x: f64| chi * (x.cos() + x.sin() * tb * e2(x) / (2.0 - e1(x)));
            let f = if psi < PI {
                (-2.0 * (psi / 2.0).tan()).exp()
            } else {
                0.0
            };
            let s2 = (psi / 2.0).sin().powi(2);
            if i <= e {
                let den = 2.0 - e1(e) - psi / PI * e1(i);
                let mu0e = chi * (i.cos() + i.sin() * tb * (psi.cos() * e2(e) + s2 * e2(i)) / den);
                let mue = chi * (e.cos() + e.sin() * tb * (e2(e) - s2 * e2(i)) / den);
                let s =
                    mue / eta(e) * i.cos() / eta(i) * chi / (1.0 - f + f * chi * i.cos() / eta(i));
                (mu0e, mue, s)
            } else {
                let den = 2.0 - e1(i) - psi / PI * e1(e);
                let mu0e = chi * (i.cos() + i.sin() * tb * (e2(i) - s2 * e2(e)) / den);
                let mue = chi * (e.cos() + e.sin() * tb * (psi.cos() * e2(i) + s2 * e2(e)) / den);
                let s =
                    mue / eta(e) * i.cos() / eta(i) * chi / (1.0 - f + f * chi * e.cos() / eta(e));
                (mu0e, mue, s)
            }
        };
        let cos_g = i.cos() * e.cos() + i.sin() * e.sin() * psi.cos();
        let g = cos_g.clamp(-1.0, 1.0).acos();
        let pp = (1.0 - c) * (1.0 - b * b) / (1.0 + 2.0 * b * cos_g + b * b).powf(1.5)
            + c * (1.0 - b * b) / (1.0 - 2.0 * b * cos_g + b * b).powf(1.5);
        let bb = if h > 0.0 {
            b0 / (1.0 + (g / 2.0).tan() / h)
        } else {
            0.0
        };
        let r =
            w / (4.0 * PI) * mu0e / (mu0e + mue) * (pp * (1.0 + bb) + hf(mu0e) * hf(mue) - 1.0) * s;
        r / i.cos()
    }

    const SETS: [Params; 4] = [
        POMMEROL,
        (0.5, 0.3, 0.4, 15.0, 0.8, 0.06),
        (0.9, 0.6, 0.1, 35.0, 0.3, 0.4),
        (0.2, 0.0, 0.0, 0.0, 0.0, 0.0),
    ];

    /// eval (vectors, unified roughness branch, S/μ0 folded) equals the angle-form evaluation
    /// over a grid of geometries, on both sides of i = e and across azimuths.
    #[test]
    fn eval_matches_angle_formula() {
        for &p in &SETS {
            let m = model(p);
            for &i in &[0.0, 0.3, 0.8, 1.2, 1.5] {
                for &e in &[0.0, 0.2, 0.8, 1.0, 1.45] {
                    for &psi in &[0.0, 0.6, 1.7, 2.9, PI] {
                        let wi = direction_from_angles(i, 2.0);
                        let wo = direction_from_angles(e, 2.0 + psi);
                        // ψ is undefined at nadir; the formula does not depend on it there.
                        let psi_a = if i == 0.0 || e == 0.0 { 0.0 } else { psi };
                        let (got, want) = (m.eval(wi, wo), brdf_angles(p, i, e, psi_a));
                        assert!(
                            (got - want).abs() <= 1e-9 * want.abs().max(1e-3),
                            "{p:?} i={i} e={e} psi={psi}: {got} vs {want}"
                        );
                    }
                }
            }
        }
    }

    /// Published example values: Eradiate's `hapke` tests (Pommerol et al. 2013 parameters,
    /// θi = 30°) give 0.24746648 at θo = 30° same azimuth (hot spot), 0.15426355 at θo = 89°
    /// opposite azimuth, 0.19555340 at θo = 80° same azimuth. They are float32 values of
    /// π·r/μ0 (the BRF; see the header), so compare π·eval to 1e-6 relative.
    #[test]
    fn eradiate_reference_values() {
        let m = model(POMMEROL);
        let d = |z: f64, a: f64| direction_from_angles(z.to_radians(), a.to_radians());
        for &(to, phi, want) in &[
            (30.0, 0.0, 0.24746648),
            (89.0, 180.0, 0.15426355),
            (80.0, 0.0, 0.19555340),
        ] {
            let got = PI * m.eval(d(30.0, 0.0), d(to, phi));
            assert!(
                ((got - want) / want).abs() < 1e-6,
                "θo={to}: {got} vs {want}"
            );
        }
    }

    /// Hand check at nadir/nadir: S = 1 (η(0) = χ), μ0e = μe = χ, g = 0 so B = B₀ and
    /// P(0) = (1−c)(1−b)/(1+b)² + c(1+b)/(1−b)²; f_r = (w/4π)(1/2)[P(0)(1+B₀) + H(χ)² − 1].
    /// For Pommerol: χ = 0.922314234, P(0) = 1.352803311, H(χ) = 1.261069251, f_r = 0.0689795268.
    #[test]
    fn nadir_hand_value() {
        let got = model(POMMEROL).eval(DVec3::Z, DVec3::Z);
        assert!((got - 0.068_979_526_827_249_56).abs() < 1e-12, "{got}");
    }

    /// Reciprocity f(wi, wo) = f(wo, wi), with and without roughness, on both sides of i = e.
    #[test]
    fn reciprocity() {
        for &p in &SETS {
            let m = model(p);
            for &(a, b, c, d) in &[
                (0.2, 0.3, 1.0, 2.5),
                (1.3, 0.0, 0.1, 4.0),
                (0.7, 5.0, 1.45, 0.2),
                (0.9, 1.0, 0.9, 1.2),
            ] {
                let wi = direction_from_angles(a, b);
                let wo = direction_from_angles(c, d);
                let (x, y) = (m.eval(wi, wo), m.eval(wo, wi));
                assert!((x - y).abs() <= 1e-12 * x, "{p:?}: {x} vs {y}");
            }
        }
    }

    /// Limiting case (no exact Lambertian limit exists): θ̄ = 0, B₀ = 0, b = 0 reduce the model
    /// to f_r = (w/4π) H(μ0)H(μ)/(μ0+μ), any c. Its albedo is 1 − γH(μ0) for the exact H; with
    /// Hapke's approximate H it stays within 1.5 % of that (below it), and for w = 1
    /// (conservative scattering) within 1.5 % of 1.
    #[test]
    fn isotropic_smooth_limit() {
        for &w in &[0.3, 0.9, 1.0] {
            let m = Hapke::new(w, 0.0, 0.7, 0.0, 0.0, 0.5).unwrap();
            let gam = (1.0 - w).sqrt();
            let r0 = (1.0 - gam) / (1.0 + gam);
            let hf = |x: f64| 1.0 / (1.0 - w * x * (r0 + (0.5 - r0 * x) * ((1.0 + x) / x).ln()));
            for &(i, e, psi) in &[(0.0, 0.5, 0.0), (0.4, 1.1, 2.0), (1.3, 0.2, 3.0)] {
                let (wi, wo) = (direction_from_angles(i, 0.0), direction_from_angles(e, psi));
                let (u0, u) = (i.cos(), e.cos());
                let want = w / (4.0 * PI) * hf(u0) * hf(u) / (u0 + u);
                assert!((m.eval(wi, wo) - want).abs() < 1e-14, "{w} {i} {e}");
            }
            let bs = Bsdf::Hapke(m);
            for &i in &[0.0, 1.0, 1.4] {
                let a = bs.directional_albedo(direction_from_angles(i, 0.0), 400);
                let exact = 1.0 - gam * hf(i.cos());
                assert!(
                    a <= exact + 1e-3 && a > exact - 0.015,
                    "w={w} i={i}: {a} vs {exact}"
                );
            }
        }
    }

    /// Energy: directional-hemispherical albedo ≤ 1 for several parameter sets, including a
    /// bright forward-scattering rough surface and a bright strongly backscattering one.
    #[test]
    fn albedo_at_most_one() {
        for &p in SETS.iter().chain(&[
            (0.95, 0.2, 0.9, 25.0, 1.0, 0.05),
            (0.99, 0.5, 0.0, 45.0, 1.0, 1.0),
        ]) {
            let m = Bsdf::Hapke(model(p));
            for &z in &[0.0, 0.6, 1.2, 1.5] {
                let a = m.directional_albedo(direction_from_angles(z, 0.0), 200);
                assert!(a > 0.0 && a <= 1.0, "{p:?} zenith {z}: albedo {a}");
            }
        }
    }

    /// Constructors reject out-of-range and NaN parameters, naming the parameter by its key in
    /// experiment files and bundles (`theta`, `B_0`).
    #[test]
    fn rejects_bad_parameters() {
        let ok = (0.5, 0.3, 0.4, 15.0, 0.8, 0.06);
        let cases: [(usize, f64, &str); 14] = [
            (0, -0.1, "w"),
            (0, 1.1, "w"),
            (1, 1.0, "b"),
            (1, -0.2, "b"),
            (2, 1.5, "c"),
            (2, -0.5, "c"),
            (3, 90.0, "theta"),
            (3, -1.0, "theta"),
            (4, 1.2, "B_0"),
            (4, -0.1, "B_0"),
            (5, 1.5, "h"),
            (5, -0.01, "h"),
            (0, f64::INFINITY, "w"),
            (5, f64::NEG_INFINITY, "h"),
        ];
        let build = |k: usize, v: f64| {
            let mut a = [ok.0, ok.1, ok.2, ok.3, ok.4, ok.5];
            a[k] = v;
            Hapke::new(a[0], a[1], a[2], a[3], a[4], a[5])
        };
        for &(k, v, name) in &cases {
            let e = build(k, v).unwrap_err().to_string();
            assert!(e.contains(&format!("`{name}`")), "{e}");
        }
        for (k, name) in ["w", "b", "c", "theta", "B_0", "h"].iter().enumerate() {
            let e = build(k, f64::NAN).unwrap_err().to_string();
            assert!(e.contains(&format!("`{name}`")), "{e}");
        }
        assert_eq!(
            build(3, 95.0).unwrap_err().to_string(),
            "`theta` = 95 deg must lie in [0, 90)"
        );
        assert!(Hapke::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0).is_ok());
        assert!(Hapke::new(1.0, 0.99, 1.0, 89.0, 1.0, 1.0).is_ok());
    }
}
