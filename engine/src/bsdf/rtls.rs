//! Ross-Thick Li-Sparse-Reciprocal (RTLS) kernel-driven model, as in the MODIS BRDF/albedo
//! product (MCD43) with the fixed crown shape `h/b = 2`, `b/r = 1`.
//!
//! Ranges are those of the shared table `bundle::BRDF_PARAM_RANGES`, which [`Rtls::new`] checks.
//!
//! | parameter | unit | range  | meaning                                                     |
//! |-----------|------|--------|-------------------------------------------------------------|
//! | `f_iso`   | —    | [0, 2] | isotropic kernel weight (the BRF at nadir/nadir)            |
//! | `f_vol`   | —    | [−1, 1] | Ross-Thick volumetric kernel weight                        |
//! | `f_geo`   | —    | [−1, 1] | Li-Sparse-Reciprocal geometric-optical kernel weight       |
//!
//! Fitted kernel weights can be slightly negative (e.g. RAMI4ATM's `rli` surface has
//! f_vol = −0.002886); the BRF is clamped at 0 where the sum is negative.
//!
//! **BRF vs BRDF.** As in MODIS, the kernel model gives the *BRF* (reflectance factor)
//!
//! ```text
//! R(θi, θo, Δφ) = f_iso + f_vol K_vol + f_geo K_geo
//! K_vol = [(π/2 − ξ) cos ξ + sin ξ] / (cos θi + cos θo) − π/4
//! K_geo = O − sec θi − sec θo + ½ (1 + cos ξ) sec θi sec θo
//! O     = (1/π) (t − sin t cos t) (sec θi + sec θo)
//! cos t = (h/b) √(D² + (tan θi tan θo sin Δφ)²) / (sec θi + sec θo),  clamped to [−1, 1]
//! D²    = tan² θi + tan² θo − 2 tan θi tan θo cos Δφ
//! cos ξ = cos θi cos θo + sin θi sin θo cos Δφ
//! ```
//!
//! (with `b/r = 1` the primed angles of the ATBD equal the true ones), and [`Rtls::eval`]
//! returns `f_r = max(R, 0)/π` (sr⁻¹). Both kernels vanish at nadir/nadir, so `R(0, 0) = f_iso`.
//!
//! **Clamp.** `K_geo ≤ 0` over most of the hemisphere and `K_vol` dips below 0 near nadir, so
//! `R` can go negative for some weight sets at some angles (a fitted kernel model is not a
//! physical BRDF everywhere). `eval` clamps the BRF at 0: the surface then reflects nothing in
//! those directions, which keeps the Monte Carlo weights non-negative.
//!
//! **Energy.** As for any fitted kernel model, the weight ranges do not guarantee a
//! directional albedo ≤ 1 (e.g. `f_iso = f_vol = 1`); MODIS-like weights stay well below.
//!
//! **Angle conventions.** `Δφ = φi − φo` is the relative azimuth of the outgoing vectors `wi`
//! (towards the Sun) and `wo` (towards the viewer); the absolute azimuth origin (clockwise from
//! North in this crate) cancels. `Δφ = 0`: viewer on the Sun's side (backscattering), where the
//! hot spot lies (θi = θo). `ξ` is the phase angle between `wi` and `wo` (`cos ξ = wi·wo`,
//! `ξ = 0` at the hot spot). Only `cos Δφ` and `sin² Δφ` enter, so the sign of `Δφ` is moot.
//!
//! References: W. Lucht, C. B. Schaaf, A. H. Strahler (2000), *An algorithm for the retrieval of
//! albedo from space using semiempirical BRDF models*, IEEE TGRS 38(2), 977–998; W. Wanner,
//! X. Li, A. H. Strahler (1995), *On the derivation of kernels for kernel-driven models of
//! bidirectional reflectance*, J. Geophys. Res. 100(D10), 21077–21089; A. H. Strahler et al.
//! (1999), MODIS BRDF/Albedo Product ATBD v5.0.

use glam::DVec3;
use std::f64::consts::{FRAC_1_PI, FRAC_PI_2, FRAC_PI_4};

use super::error::{check_param, BrdfError};
use super::TableSampler;

/// Crown relative height `h/b` of the Li-Sparse kernel (MODIS value).
pub const H_OVER_B: f64 = 2.0;
/// Crown shape `b/r` of the Li-Sparse kernel (MODIS value: spherical crowns).
pub const B_OVER_R: f64 = 1.0;

#[derive(Clone, Debug)]
pub struct Rtls {
    pub f_iso: f64,
    pub f_vol: f64,
    pub f_geo: f64,
    /// Importance sampler built from this model (`table_sampler.rs`).
    pub(crate) sampler: TableSampler,
}

impl Rtls {
    /// RTLS model from its three kernel weights (dimensionless BRF weights: f_iso in [0, 2],
    /// f_vol and f_geo in [−1, 1]).
    pub fn new(f_iso: f64, f_vol: f64, f_geo: f64) -> Result<Self, BrdfError> {
        // Ranges from the shared table (`bundle::BRDF_PARAM_RANGES`, as above).
        for (name, v) in [("f_iso", f_iso), ("f_vol", f_vol), ("f_geo", f_geo)] {
            check_param("rtls", name, name, v)?;
        }
        let mut m = Self {
            f_iso,
            f_vol,
            f_geo,
            sampler: TableSampler::unbuilt(),
        };
        m.sampler = TableSampler::build(|wi, wo| m.eval(wi, wo));
        Ok(m)
    }

    /// The two kernels `(K_vol, K_geo)` for unit vectors `wi`, `wo` with `z > 0`.
    #[inline]
    pub fn kernels(wi: DVec3, wo: DVec3) -> (f64, f64) {
        let (ci, co) = (wi.z, wo.z);
        // Phase angle from atan2 of |wi×wo| and wi·wo: accurate near the hot spot, where
        // acos(wi·wo) would lose half the digits.
        let cos_xi = wi.dot(wo).clamp(-1.0, 1.0);
        let sin_xi = wi.cross(wo).length();
        let xi = sin_xi.atan2(cos_xi);
        let k_vol = ((FRAC_PI_2 - xi) * cos_xi + sin_xi) / (ci + co) - FRAC_PI_4;

        // Li-Sparse with b/r = 1: projected tangent vectors T = (tanθ cosφ, tanθ sinφ);
        // D² = |Ti − To|², tanθi tanθo sinΔφ = Ti × To (2-D cross product).
        let (ix, iy) = (wi.x / ci, wi.y / ci);
        let (ox, oy) = (wo.x / co, wo.y / co);
        let d2 = (ix - ox).powi(2) + (iy - oy).powi(2);
        let cross = ix * oy - iy * ox;
        let (sec_i, sec_o) = (1.0 / ci, 1.0 / co);
        let sec_sum = sec_i + sec_o;
        let cos_t = (H_OVER_B * (d2 + cross * cross).sqrt() / sec_sum).clamp(-1.0, 1.0);
        let t = cos_t.acos();
        let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
        let overlap = FRAC_1_PI * (t - sin_t * cos_t) * sec_sum;
        let k_geo = overlap - sec_sum + 0.5 * (1.0 + cos_xi) * sec_i * sec_o;
        (k_vol, k_geo)
    }

    /// BRDF (sr⁻¹) = max(BRF, 0)/π for `wi` (towards the light) and `wo` (towards the viewer),
    /// both with `z > 0` (the caller, [`crate::bsdf::Bsdf::eval`], handles the horizon).
    #[inline]
    pub fn eval(&self, wi: DVec3, wo: DVec3) -> f64 {
        let (k_vol, k_geo) = Self::kernels(wi, wo);
        let brf = self.f_iso + self.f_vol * k_vol + self.f_geo * k_geo;
        brf.max(0.0) * FRAC_1_PI
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::{Bsdf, Lambertian};
    use crate::frame::direction_from_angles;
    use std::f64::consts::PI;

    /// Independent kernels written in angles (θi, θo, Δφ) exactly as printed in the MODIS ATBD
    /// (Lucht et al. 2000, eqs. for K_RossThick and K_LiSparseR), including the primed angles
    /// θ' = atan((b/r) tan θ) and the phase angle ξ' of the primed directions.
    fn kernels_angles(ti: f64, to: f64, phi: f64) -> (f64, f64) {
        let cos_xi = ti.cos() * to.cos() + ti.sin() * to.sin() * phi.cos();
        let xi = cos_xi.acos();
        let k_vol = ((PI / 2.0 - xi) * cos_xi + xi.sin()) / (ti.cos() + to.cos()) - PI / 4.0;
        let (hb, br) = (2.0, 1.0);
        let tip = (br * ti.tan()).atan();
        let top = (br * to.tan()).atan();
        let cos_xip = tip.cos() * top.cos() + tip.sin() * top.sin() * phi.cos();
        let d = (tip.tan().powi(2) + top.tan().powi(2) - 2.0 * tip.tan() * top.tan() * phi.cos())
            .max(0.0)
            .sqrt();
        let sec = |x: f64| 1.0 / x.cos();
        let cos_t = (hb * (d * d + (tip.tan() * top.tan() * phi.sin()).powi(2)).sqrt()
            / (sec(tip) + sec(top)))
        .clamp(-1.0, 1.0);
        let t = cos_t.acos();
        let o = (t - t.sin() * cos_t) * (sec(tip) + sec(top)) / PI;
        let k_geo = o - sec(tip) - sec(top) + 0.5 * (1.0 + cos_xip) * sec(tip) * sec(top);
        (k_vol, k_geo)
    }

    fn dirs(ti: f64, to: f64, phi: f64) -> (DVec3, DVec3) {
        (
            direction_from_angles(ti, 0.4),
            direction_from_angles(to, 0.4 - phi),
        )
    }

    /// Vector kernels equal the angle-form kernels over a grid of geometries (the two codings
    /// share no expression: tangent-plane vectors and a cross product vs tan/sin of angles).
    #[test]
    fn kernels_match_angle_formula() {
        for &ti in &[0.0, 0.2, 0.6, 1.0, 1.4] {
            for &to in &[0.0, 0.3, 0.8, 1.2, 1.5] {
                for &phi in &[0.0, 0.4, 1.6, 2.5, PI] {
                    let (wi, wo) = dirs(ti, to, phi);
                    let (v, g) = Rtls::kernels(wi, wo);
                    let (v2, g2) = kernels_angles(ti, to, phi);
                    let tol = 1e-9 * (1.0 + g2.abs());
                    assert!(
                        (v - v2).abs() < 1e-9 && (g - g2).abs() < tol,
                        "{ti} {to} {phi}: ({v}, {g}) vs ({v2}, {g2})"
                    );
                    let m = Rtls::new(0.3, 0.2, 0.05).unwrap();
                    let want = (0.3 + 0.2 * v2 + 0.05 * g2).max(0.0) / PI;
                    assert!((m.eval(wi, wo) - want).abs() < 1e-9);
                }
            }
        }
    }

    /// Hand-checked values. Nadir/nadir: ξ = 0, so K_vol = (π/2)/2 − π/4 = 0; D = 0 so
    /// cos t = 0, t = π/2, O = (1/π)(π/2)(2) = 1 and K_geo = 1 − 2 + ½·2·1 = 0.
    /// Hot spot (θi = θo = θ, Δφ = 0): K_vol = (π/4)(sec θ − 1), K_geo = sec²θ − sec θ;
    /// at θ = 45°: K_vol = 0.3253226..., K_geo = 2 − √2 = 0.585786...
    #[test]
    fn hand_values() {
        let (v, g) = Rtls::kernels(DVec3::Z, DVec3::Z);
        assert!(v.abs() < 1e-15 && g.abs() < 1e-15, "{v} {g}");
        let w = direction_from_angles(PI / 4.0, 2.0);
        let (v, g) = Rtls::kernels(w, w);
        assert!((v - 0.325_322_571_142_143_3).abs() < 1e-7, "{v}");
        assert!((g - (2.0 - 2f64.sqrt())).abs() < 1e-7, "{g}");
        for &th in &[0.1, 0.7, 1.3] {
            let w = direction_from_angles(th, 5.0);
            let (v, g) = Rtls::kernels(w, w);
            let sec = 1.0 / th.cos();
            assert!((v - PI / 4.0 * (sec - 1.0)).abs() < 1e-7 * sec);
            assert!((g - (sec * sec - sec)).abs() < 1e-7 * sec * sec);
        }
        let m = Rtls::new(0.2, 0.05, 0.03).unwrap();
        assert!((m.eval(DVec3::Z, DVec3::Z) - 0.2 / PI).abs() < 1e-15);
    }

    /// Negative BRF is clamped: with a large f_geo at a wide forward geometry K_geo ≪ 0.
    #[test]
    fn negative_brf_clamped() {
        let (wi, wo) = dirs(1.3, 1.3, PI);
        let (_, g) = Rtls::kernels(wi, wo);
        assert!(0.05 + 1.0 * g < 0.0, "{g}");
        let m = Rtls::new(0.05, 0.0, 1.0).unwrap();
        assert_eq!(m.eval(wi, wo), 0.0);
    }

    /// Reciprocity f(wi, wo) = f(wo, wi): both kernels are symmetric (Li-Sparse-*Reciprocal*).
    #[test]
    fn reciprocity() {
        let m = Rtls::new(0.2, 0.3, 0.1).unwrap();
        for &(a, b, c, d) in &[
            (0.2, 0.3, 1.0, 2.5),
            (1.3, 0.0, 0.1, 4.0),
            (0.7, 5.0, 1.45, 0.2),
        ] {
            let wi = direction_from_angles(a, b);
            let wo = direction_from_angles(c, d);
            let (x, y) = (m.eval(wi, wo), m.eval(wo, wi));
            assert!((x - y).abs() <= 1e-13 * x, "{x} vs {y}");
        }
    }

    /// Degenerate case f_vol = f_geo = 0: exactly a Lambertian of reflectance f_iso.
    #[test]
    fn degenerate_is_lambertian() {
        let m = Bsdf::Rtls(Rtls::new(0.37, 0.0, 0.0).unwrap());
        let l = Bsdf::Lambertian(Lambertian::new(0.37).unwrap());
        for &(a, b, c, d) in &[
            (0.0, 0.0, 0.0, 0.0),
            (0.4, 0.3, 1.2, 2.0),
            (1.5, 1.0, 1.5, 1.0),
        ] {
            let (wi, wo) = (direction_from_angles(a, b), direction_from_angles(c, d));
            assert_eq!(m.eval(wi, wo), l.eval(wi, wo));
        }
    }

    /// Energy: directional-hemispherical albedo ≤ 1 for MODIS-like weight sets, from a dark
    /// soil to a bright, strongly volumetric canopy (RAMI4ATM S2A band 8A weights included).
    #[test]
    fn albedo_at_most_one() {
        for &(i, v, g) in &[
            (0.2, 0.05, 0.03),
            (0.209741, 0.081384, 0.004140),
            (0.05, 0.02, 0.01),
            (0.5, 0.3, 0.05),
            (0.7, 0.2, 0.1),
        ] {
            let m = Bsdf::Rtls(Rtls::new(i, v, g).unwrap());
            for &z in &[0.0, 0.6, 1.2, 1.5] {
                let a = m.directional_albedo(direction_from_angles(z, 0.0), 200);
                assert!(
                    a > 0.0 && a <= 1.0,
                    "({i}, {v}, {g}) zenith {z}: albedo {a}"
                );
            }
        }
    }

    /// Constructors reject out-of-range and NaN weights, naming the parameter.
    #[test]
    fn rejects_bad_parameters() {
        for &(i, v, g, name) in &[
            (-0.1, 0.0, 0.0, "f_iso"),
            (2.5, 0.0, 0.0, "f_iso"),
            (f64::NAN, 0.0, 0.0, "f_iso"),
            (0.2, -1.01, 0.0, "f_vol"),
            (0.2, f64::NAN, 0.0, "f_vol"),
            (0.2, 0.1, 2.0, "f_geo"),
            (0.2, 0.1, f64::NAN, "f_geo"),
            (0.2, 0.1, f64::INFINITY, "f_geo"),
        ] {
            let e = Rtls::new(i, v, g).unwrap_err().to_string();
            assert!(e.contains(&format!("`{name}`")), "{e}");
        }
        assert_eq!(
            Rtls::new(0.2, 0.1, 2.0).unwrap_err().to_string(),
            "`f_geo` = 2 must lie in [-1, 1]"
        );
        assert!(Rtls::new(0.0, 0.0, 0.0).is_ok() && Rtls::new(1.0, 1.0, 1.0).is_ok());
        // RAMI4ATM's `rli` surface (negative f_vol) is accepted.
        assert!(Rtls::new(0.032171, -0.002886, 0.001949).is_ok());
    }
}
