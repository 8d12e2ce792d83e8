//! Ross-Thick Li-Sparse-Reciprocal kernel model with the hot-spot factor of Maignan, Bréon &
//! Lacaze (2004) ("RTLS-H", also written RTLSR-HS): the model of [`super::Rtls`] whose
//! volumetric kernel peaks towards backscattering, as POLDER observations of every surface type
//! show.
//!
//! Ranges are those of the shared table `bundle::BRDF_PARAM_RANGES` (rows `rtls_hotspot.*`: the
//! kernel weights have RTLS's ranges), which [`RtlsHotspot::new`] checks.
//!
//! | parameter | unit | range    | meaning                                                    |
//! |-----------|------|----------|------------------------------------------------------------|
//! | `f_iso`   | —    | [0, 2]   | isotropic kernel weight                                    |
//! | `f_vol`   | —    | [−1, 1]  | weight of the Ross-Thick kernel with hot spot, MODIS scaling (see below) |
//! | `f_geo`   | —    | [−1, 1]  | Li-Sparse-Reciprocal geometric-optical kernel weight (h/b = 2, b/r = 1) |
//! | `xi0`     | deg  | (0, 90]  | characteristic phase angle ξ0 of the hot spot (Maignan et al.: 1.5°) |
//!
//! **BRF vs BRDF.** As for RTLS the kernels give the *BRF*
//!
//! ```text
//! R(θi, θo, Δφ) = f_iso + f_vol K_vol^H + f_geo K_geo
//! K_vol^H = [(π/2 − ξ) cos ξ + sin ξ] / (cos θi + cos θo) · H(ξ) − π/4
//! H(ξ)    = 1 + (1 + ξ/ξ0)^−1
//! ```
//!
//! with `ξ` the phase angle (`cos ξ = wi·wo`) and `K_geo` the Li-Sparse-Reciprocal kernel of
//! [`super::rtls`] (shared: [`super::Rtls::kernels`]); [`RtlsHotspot::eval`] returns
//! `f_r = max(R, 0)/π` (sr⁻¹), negative BRFs clamped as in RTLS.
//!
//! **The factor.** `H(0) = 2` at the hot spot (ξ = 0), `H(ξ0) = 3/2`, and `H → 1` for
//! `ξ ≫ ξ0`, where the model becomes RTLS; slowly: `H − 1 < ξ0/ξ`, so at ξ = 30° and
//! ξ0 = 1.5° the volumetric term still exceeds RTLS's by 4.8 %. Weights fitted with RTLS
//! therefore differ slightly from RTLS-H ones. `H` multiplies the scattering term of the Ross
//! kernel, not its constant −π/4 (as in the paper's equation), so at nadir/nadir (a hot spot
//! when the Sun is at zenith) `K_vol^H = π/4` and `R(0, 0) = f_iso + f_vol·π/4`, not `f_iso`.
//!
//! **Scaling of `f_vol`.** Maignan et al. write the kernel with the Roujean normalisation,
//! `F1 = 4/(3π) · 1/(cos θs + cos θv) · [(π/2 − ξ) cos ξ + sin ξ] · (1 + (1 + ξ/ξ0)^−1) − 1/3`,
//! so `K_vol^H = (3π/4)·F1`: their weight `k1` is `(3π/4)·f_vol` here (`f_vol = 4 k1/(3π)`);
//! `k0` and `k2` are `f_iso` and `f_geo`. MODIS scaling keeps `f_vol` comparable with RTLS's.
//!
//! **Angle conventions** as in [`super::rtls`]: `Δφ = 0` puts the viewer on the Sun's side;
//! the hot spot is at θi = θo, Δφ = 0. The model is reciprocal (ξ and both kernels are
//! symmetric in `wi`, `wo`).
//!
//! Reference: F. Maignan, F.-M. Bréon, R. Lacaze (2004), *Bidirectional reflectance of Earth
//! targets: evaluation of analytical models using a large set of spaceborne measurements with
//! emphasis on the Hot Spot*, Remote Sens. Environ. 90, 210–220.

use glam::DVec3;
use std::f64::consts::{FRAC_1_PI, FRAC_PI_4};

use super::error::{check_param, BrdfError};
use super::{Rtls, TableSampler};

/// ξ0 of Maignan et al. (2004), degrees (the spec's default).
pub use bundle::DEFAULT_XI0_DEG;

#[derive(Clone, Debug)]
pub struct RtlsHotspot {
    pub f_iso: f64,
    pub f_vol: f64,
    pub f_geo: f64,
    /// ξ0, degrees.
    pub xi0_deg: f64,
    /// 1/ξ0, rad⁻¹.
    inv_xi0: f64,
    /// Importance sampler built from this model (`table_sampler.rs`).
    pub(crate) sampler: TableSampler,
}

impl RtlsHotspot {
    /// RTLS-H from its kernel weights and ξ0 in degrees (ranges in the module header; NaN
    /// fails).
    pub fn new(f_iso: f64, f_vol: f64, f_geo: f64, xi0_deg: f64) -> Result<Self, BrdfError> {
        // Ranges from the shared table (`bundle::BRDF_PARAM_RANGES`).
        for (name, v) in [
            ("f_iso", f_iso),
            ("f_vol", f_vol),
            ("f_geo", f_geo),
            ("xi0", xi0_deg),
        ] {
            check_param("rtls_hotspot", name, name, v)?;
        }
        let mut m = Self {
            f_iso,
            f_vol,
            f_geo,
            xi0_deg,
            inv_xi0: 1.0 / xi0_deg.to_radians(),
            sampler: TableSampler::unbuilt(),
        };
        m.sampler = TableSampler::build(|wi, wo| m.eval(wi, wo));
        Ok(m)
    }

    /// The hot-spot factor `H(ξ) = 1 + (1 + ξ/ξ0)^−1` at the phase angle `xi` (radians).
    #[inline]
    pub fn hot_spot_factor(&self, xi: f64) -> f64 {
        1.0 + 1.0 / (1.0 + xi * self.inv_xi0)
    }

    /// The kernels `(K_vol^H, K_geo)` for unit vectors `wi`, `wo` with `z > 0`.
    #[inline]
    pub fn kernels(&self, wi: DVec3, wo: DVec3) -> (f64, f64) {
        let (k_vol, k_geo) = Rtls::kernels(wi, wo);
        // The phase angle as RTLS takes it: atan2 keeps its digits near the hot spot.
        let xi = wi.cross(wo).length().atan2(wi.dot(wo).clamp(-1.0, 1.0));
        // K_vol + π/4 is the Ross scattering term that the factor multiplies.
        let k_vol_h = (k_vol + FRAC_PI_4) * self.hot_spot_factor(xi) - FRAC_PI_4;
        (k_vol_h, k_geo)
    }

    /// BRDF (sr⁻¹) = max(BRF, 0)/π for `wi` (towards the light) and `wo` (towards the viewer),
    /// both with `z > 0` (the caller, [`crate::bsdf::Bsdf::eval`], handles the horizon).
    #[inline]
    pub fn eval(&self, wi: DVec3, wo: DVec3) -> f64 {
        let (k_vol, k_geo) = self.kernels(wi, wo);
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

    /// The BRF written out from the paper in angles (θs, θv, relative azimuth φ in radians; ξ0
    /// in degrees), sharing no code with the model: Maignan et al.'s F1 (Roujean normalisation,
    /// weight k1 = (3π/4)·f_vol) and the Li-Sparse-Reciprocal kernel of the MODIS ATBD (Lucht et
    /// al. 2000) with h/b = 2, b/r = 1 (so the primed angles are the true ones). The phase angle
    /// comes from the haversine form sin²(ξ/2) = sin²((θs − θv)/2) + sin θs sin θv sin²(φ/2),
    /// accurate at small ξ where the hot spot lives.
    fn brf_angles(p: (f64, f64, f64, f64), ts: f64, tv: f64, phi: f64) -> f64 {
        let (f_iso, f_vol, f_geo, xi0_deg) = p;
        let xi0 = xi0_deg * PI / 180.0;
        let hav = ((ts - tv) / 2.0).sin().powi(2) + ts.sin() * tv.sin() * (phi / 2.0).sin().powi(2);
        let xi = 2.0 * hav.sqrt().min(1.0).asin();
        let f1 = 4.0 / (3.0 * PI) / (ts.cos() + tv.cos())
            * ((PI / 2.0 - xi) * xi.cos() + xi.sin())
            * (1.0 + 1.0 / (1.0 + xi / xi0))
            - 1.0 / 3.0;
        let k1 = 3.0 * PI / 4.0 * f_vol;
        let (tan_s, tan_v) = (ts.tan(), tv.tan());
        let (sec_s, sec_v) = (1.0 / ts.cos(), 1.0 / tv.cos());
        let d2 = (tan_s * tan_s + tan_v * tan_v - 2.0 * tan_s * tan_v * phi.cos()).max(0.0);
        let cos_t = (2.0 * (d2 + (tan_s * tan_v * phi.sin()).powi(2)).sqrt() / (sec_s + sec_v))
            .clamp(-1.0, 1.0);
        let t = cos_t.acos();
        let overlap = (t - t.sin() * cos_t) * (sec_s + sec_v) / PI;
        let k_geo = overlap - sec_s - sec_v + 0.5 * (1.0 + xi.cos()) * sec_s * sec_v;
        f_iso + k1 * f1 + f_geo * k_geo
    }

    fn dirs(ts: f64, tv: f64, phi: f64) -> (DVec3, DVec3) {
        (
            direction_from_angles(ts, 1.1),
            direction_from_angles(tv, 1.1 - phi),
        )
    }

    const P: (f64, f64, f64, f64) = (0.25, 0.12, 0.04, 1.5);

    fn model(p: (f64, f64, f64, f64)) -> RtlsHotspot {
        RtlsHotspot::new(p.0, p.1, p.2, p.3).unwrap()
    }

    /// π·f_r equals the paper's formula over a grid of geometries, including the hot spot
    /// itself, phase angles of a fraction of ξ0 to a few ξ0 around it, and forward scattering.
    #[test]
    fn eval_matches_the_paper() {
        let m = model(P);
        let xi0 = P.3.to_radians();
        let mut geometries = Vec::new();
        for &ts in &[0.0, 0.3, 0.7, 1.1, 1.4] {
            for &tv in &[0.0, 0.2, 0.7, 1.2, 1.5] {
                for &phi in &[0.0, 0.5, 1.6, 2.7, PI] {
                    geometries.push((ts, tv, phi));
                }
            }
            for &dv in &[0.0, 0.2 * xi0, xi0, 3.0 * xi0, 10.0 * xi0] {
                if ts + dv < 1.5 {
                    geometries.push((ts, ts + dv, 0.0));
                }
            }
        }
        for (ts, tv, phi) in geometries {
            let (wi, wo) = dirs(ts, tv, phi);
            let want = brf_angles(P, ts, tv, phi).max(0.0);
            let got = PI * m.eval(wi, wo);
            assert!(
                (got - want).abs() < 1e-9 * (1.0 + want.abs()),
                "θs {ts} θv {tv} φ {phi}: {got} vs {want}"
            );
        }
    }

    /// Hand values. Nadir/nadir is a hot spot (ξ = 0, H = 2): K_vol^H = (π/2)·2/2 − π/4 = π/4,
    /// K_geo = 0. At the hot spot θi = θo = θ: K_vol^H = (π/2)·2/(2 cos θ) − π/4 =
    /// (π/4)(2 sec θ − 1) and K_geo = sec²θ − sec θ (as for RTLS).
    #[test]
    fn hand_values() {
        let m = model(P);
        let want = P.0 + P.1 * PI / 4.0;
        assert!((PI * m.eval(DVec3::Z, DVec3::Z) - want).abs() < 1e-14);
        for &th in &[0.2f64, 0.8, 1.3] {
            let w = direction_from_angles(th, 4.0);
            let sec = 1.0 / th.cos();
            let want = P.0 + P.1 * PI / 4.0 * (2.0 * sec - 1.0) + P.2 * (sec * sec - sec);
            let got = PI * m.eval(w, w);
            assert!((got - want).abs() < 1e-7 * want, "{th}: {got} vs {want}");
        }
    }

    /// The factor is 2 at the hot spot, 3/2 at ξ = ξ0 and tends to 1 for ξ ≫ ξ0 (H − 1 < ξ0/ξ).
    #[test]
    fn factor_limits() {
        let m = model(P);
        let xi0 = P.3.to_radians();
        assert_eq!(m.hot_spot_factor(0.0), 2.0);
        assert!((m.hot_spot_factor(xi0) - 1.5).abs() < 1e-15);
        let mut last = 2.0;
        for k in 1..=200 {
            let xi = xi0 * k as f64;
            let h = m.hot_spot_factor(xi);
            assert!(h < last && h > 1.0 && h - 1.0 < xi0 / xi);
            last = h;
        }
        assert!((m.hot_spot_factor(100.0 * xi0) - (1.0 + 1.0 / 101.0)).abs() < 1e-15);
    }

    /// Away from the hot spot RTLS-H is RTLS: the excess BRF is exactly f_vol·(K_vol + π/4)·
    /// (H − 1), which is below f_vol·(K_vol + π/4)·ξ0/ξ; with ξ0 = 10⁻⁷ degrees the two models
    /// agree to 10⁻⁸ at these geometries (ξ from 5.7° to 150°). At the hot spot the excess is
    /// the whole Ross scattering term (H = 2).
    #[test]
    fn reduces_to_rtls_away_from_the_hot_spot() {
        let rtls = Rtls::new(P.0, P.1, P.2).unwrap();
        let m = model(P);
        let tiny = model((P.0, P.1, P.2, 1e-7));
        for &(ts, tv, phi) in &[
            (0.5, 0.6, 0.0),
            (0.5, 0.9, 0.0),
            (0.3, 1.2, 1.0),
            (1.0, 0.2, 2.0),
            (0.7, 0.7, PI),
            (1.4, 1.4, 0.3),
        ] {
            let (wi, wo) = dirs(ts, tv, phi);
            let xi = wi.dot(wo).clamp(-1.0, 1.0).acos();
            let ross = Rtls::kernels(wi, wo).0 + PI / 4.0;
            let excess = PI * (m.eval(wi, wo) - rtls.eval(wi, wo));
            let h = m.hot_spot_factor(xi);
            assert!(
                (excess - P.1 * ross * (h - 1.0)).abs() < 1e-12,
                "{ts} {tv} {phi}"
            );
            assert!(excess > 0.0 && excess < P.1 * ross * P.3.to_radians() / xi);
            let d = PI * (tiny.eval(wi, wo) - rtls.eval(wi, wo));
            assert!(xi > 5f64.to_radians() && d > 0.0 && d < 1e-8, "{xi} {d}");
        }
        let w = direction_from_angles(0.6, 2.0);
        let excess = PI * (m.eval(w, w) - rtls.eval(w, w));
        let ross = Rtls::kernels(w, w).0 + PI / 4.0;
        assert!((excess - P.1 * ross).abs() < 1e-12);
    }

    /// Reciprocity f(wi, wo) = f(wo, wi), near the hot spot and away from it.
    #[test]
    fn reciprocity() {
        let m = model(P);
        for &(a, b, c, d) in &[
            (0.2, 0.3, 1.0, 2.5),
            (1.3, 0.0, 0.1, 4.0),
            (0.7, 5.0, 1.45, 0.2),
            (0.5, 1.0, 0.51, 1.0),
            (0.9, 2.0, 0.9, 2.01),
        ] {
            let (wi, wo) = (direction_from_angles(a, b), direction_from_angles(c, d));
            let (x, y) = (m.eval(wi, wo), m.eval(wo, wi));
            assert!((x - y).abs() <= 1e-13 * x, "{x} vs {y}");
        }
    }

    /// f_vol = f_geo = 0: exactly a Lambertian of reflectance f_iso, whatever ξ0.
    #[test]
    fn degenerate_is_lambertian() {
        let m = Bsdf::RtlsHotspot(RtlsHotspot::new(0.37, 0.0, 0.0, 2.0).unwrap());
        let l = Bsdf::Lambertian(Lambertian::new(0.37).unwrap());
        for &(a, b, c, d) in &[
            (0.0, 0.0, 0.0, 0.0),
            (0.4, 0.3, 0.4, 0.3),
            (0.4, 0.3, 1.2, 2.0),
            (1.5, 1.0, 1.5, 1.0),
        ] {
            let (wi, wo) = (direction_from_angles(a, b), direction_from_angles(c, d));
            assert_eq!(m.eval(wi, wo), l.eval(wi, wo));
        }
    }

    /// Energy: the directional-hemispherical albedo stays ≤ 1 for MODIS-like weights, at
    /// incidences whose hot spot lies in the hemisphere (all of them), and exceeds RTLS's.
    #[test]
    fn albedo_at_most_one() {
        for &(i, v, g) in &[
            (0.2, 0.05, 0.03),
            (0.209741, 0.081384, 0.004140),
            (0.5, 0.3, 0.05),
            (0.7, 0.2, 0.1),
        ] {
            let m = Bsdf::RtlsHotspot(RtlsHotspot::new(i, v, g, DEFAULT_XI0_DEG).unwrap());
            let r = Bsdf::Rtls(Rtls::new(i, v, g).unwrap());
            for &z in &[0.0, 0.6, 1.2, 1.5] {
                let wi = direction_from_angles(z, 0.0);
                let a = m.directional_albedo(wi, 200);
                assert!(
                    a > 0.0 && a <= 1.0,
                    "({i}, {v}, {g}) zenith {z}: albedo {a}"
                );
                assert!(a > r.directional_albedo(wi, 200));
            }
        }
    }

    /// χ² of the model's sampler (`Bsdf::sample`, its table) against its pdf, with the shared
    /// helper, next to the hot spot of the fixed view (the weight of every draw is checked in
    /// `bsdf/mod.rs`).
    #[test]
    fn chi2_sampling() {
        let m = Bsdf::RtlsHotspot(model(P));
        let wo = direction_from_angles(0.5, 0.3);
        let chart = crate::bsdf::test_support::Chart::hemisphere(12, 24, 4);
        crate::bsdf::test_support::assert_chi2("RTLS-H", &m, wo, &chart, 100_000);
    }

    /// Constructors reject out-of-range and NaN parameters, naming them.
    #[test]
    fn rejects_bad_parameters() {
        for &(i, v, g, x, name) in &[
            (2.5, 0.0, 0.0, 1.5, "f_iso"),
            (0.2, -1.01, 0.0, 1.5, "f_vol"),
            (0.2, 0.1, f64::NAN, 1.5, "f_geo"),
            (0.2, 0.1, 0.0, 0.0, "xi0"),
            (0.2, 0.1, 0.0, -1.0, "xi0"),
            (0.2, 0.1, 0.0, 91.0, "xi0"),
            (0.2, 0.1, 0.0, f64::NAN, "xi0"),
        ] {
            let e = RtlsHotspot::new(i, v, g, x).unwrap_err().to_string();
            assert!(e.contains(&format!("`{name}`")), "{e}");
        }
        assert_eq!(
            RtlsHotspot::new(0.2, 0.1, 0.0, 0.0)
                .unwrap_err()
                .to_string(),
            "`xi0` = 0 deg must lie in (0, 90]"
        );
        assert!(RtlsHotspot::new(0.0, 0.0, 0.0, 90.0).is_ok());
    }
}
