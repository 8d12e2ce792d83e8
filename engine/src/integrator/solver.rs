//! Per-material radiometry solvers (DIRSIG4's solvers, Schott et al., *DIRSIG4 radiometry*):
//! what the backward estimator does when a path reaches a surface, chosen per material
//! ([`SolverSpec`], stored in bundles and given in experiment files). The estimator applies
//! them in its one loop (`backward.rs`); a *generation* is a surface interaction of the path
//! (atmospheric scatterings do not count), the first one being generation 1.
//!
//! | solver | at the surface | unbiased? |
//! |---|---|---|
//! | `generic` (N, r, G) | next-event estimate of the Sun, then `n_g = max(1, round(N·r^(g−1)))` directions drawn from the BRDF's sampler, each continuing with weight `w/n_g`; no continuation after generation G | yes with G unset (N = 1, r = 1, no G: the default walk, bit for bit); G truncates the sum of generations (DIRSIG's maximum bounce count) |
//! | `classic` (n_θ, n_φ) | next-event estimate, then at the first generation a fixed quadrature of the reflected radiance: `n_θ × n_φ` directions at the centres of cells of equal projected solid angle (`sin²θ` uniform in `n_θ` bands, azimuth uniform in `n_φ` sectors about the normal, in the surface's tangent frame), each continuing with weight `w·f·π/(n_θ n_φ)`; later generations draw single directions as `generic` | no: the midpoint rule's error, O(1/n) for smooth skies; it converges to `generic` as the grid is refined |
//! | `simple` | next-event estimate of the Sun only; the path ends (no skylight, no interreflection) | it computes the first-order surface term exactly (a different quantity) |
//! | `mirror` (n, k) | no next-event estimate (a delta BRDF meets the Sun's direction with probability 0); the path continues in the mirror direction with the Fresnel reflectance `R(θ) = (|r_s|² + |r_p|²)/2` of the complex index `n + ik` (polarized runs: the Fresnel Mueller matrix). The sunlight it reflects reaches other surfaces as the Sun's image in its plane (`Geometry::sun_via_mirror` in 3D scenes; `docs/transport.md`) | yes, but for the relays listed as missing in `docs/transport.md` |
//! | `null` | nothing: the path passes through, as do shadow rays (`Scene::occluded`) | yes |
//!
//! Random numbers: `generic` with `n_g = 1` draws what the default walk draws; fan-out copies
//! draw theirs one after another on the same stream (like splitting), so results stay
//! independent of the thread count. Weights that cannot be copied (spectral ALIS channels)
//! continue as one sample.

pub use bundle::SolverSpec;
use glam::DVec3;

use crate::frame::Frame;
use crate::scene::material::SurfaceSample;
use crate::stokes::PhaseMatrix;

/// Directions drawn at generation `g` (1-based) by a `generic` solver.
#[inline]
pub fn generic_samples(first: u32, decay: f64, g: u32) -> u32 {
    let n = f64::from(first) * decay.powi(g.saturating_sub(1).min(1000) as i32);
    (n.round() as u32).max(1)
}

/// The grid `(a, b)`, `a·b = n`, whose cells stratify a fan of `n` directions: `a` the largest
/// divisor of `n` not above √n (zenith cells), `b = n/a` (azimuth cells); 4 → 2 × 2,
/// 8 → 2 × 4, a prime `n` → 1 × n.
pub fn fan_strata(n: u32) -> (u32, u32) {
    let n = n.max(1);
    let a = (1..=n)
        .take_while(|a| a * a <= n)
        .filter(|a| n % a == 0)
        .last()
        .unwrap_or(1);
    (a, n / a)
}

/// The `classic` quadrature of a surface with unit normal `n` for light leaving along `wo`:
/// each node's direction towards the light and its weight `f·cos·ΔΩ = f·π/(n_θ n_φ)` as a
/// [`SurfaceSample`] (pdf `1/ΔΩ`), given the BRDF·cos evaluator `eval_cos(wi)`.
pub fn classic_nodes(
    n: DVec3,
    zeniths: u32,
    azimuths: u32,
    eval_cos: impl Fn(DVec3) -> f64,
) -> Vec<SurfaceSample> {
    let frame = Frame::around(n);
    let count = f64::from(zeniths * azimuths);
    let proj = std::f64::consts::PI / count;
    let mut out = Vec::with_capacity((zeniths * azimuths) as usize);
    for i in 0..zeniths {
        let s2 = (f64::from(i) + 0.5) / f64::from(zeniths);
        let (st, ct) = (s2.sqrt(), (1.0 - s2).sqrt());
        for j in 0..azimuths {
            let phi = std::f64::consts::TAU * (f64::from(j) + 0.5) / f64::from(azimuths);
            let wi = frame.world(DVec3::new(st * phi.cos(), st * phi.sin(), ct));
            let fc = eval_cos(wi);
            // ΔΩ = proj / cos θ; weight f·cos·ΔΩ = (f·cos)·proj/cos.
            let weight = fc * proj / ct;
            out.push(SurfaceSample {
                wi,
                weight,
                pdf: ct / proj,
            });
        }
    }
    out
}

/// `d` mirrored about the unit normal `n` (a path arriving along `d` leaves along it).
#[inline]
pub fn mirror(d: DVec3, n: DVec3) -> DVec3 {
    d - 2.0 * d.dot(n) * n
}

#[derive(Clone, Copy, Debug)]
struct C(f64, f64);

impl C {
    fn add(self, o: C) -> C {
        C(self.0 + o.0, self.1 + o.1)
    }
    fn sub(self, o: C) -> C {
        C(self.0 - o.0, self.1 - o.1)
    }
    fn mul(self, o: C) -> C {
        C(self.0 * o.0 - self.1 * o.1, self.0 * o.1 + self.1 * o.0)
    }
    fn div(self, o: C) -> C {
        let d = o.0 * o.0 + o.1 * o.1;
        C(
            (self.0 * o.0 + self.1 * o.1) / d,
            (self.1 * o.0 - self.0 * o.1) / d,
        )
    }
    fn norm2(self) -> f64 {
        self.0 * self.0 + self.1 * self.1
    }
    /// The principal square root (non-negative real part).
    fn sqrt(self) -> C {
        let r = self.norm2().sqrt();
        let re = ((r + self.0) / 2.0).max(0.0).sqrt();
        let im = ((r - self.0) / 2.0).max(0.0).sqrt();
        C(re, if self.1 < 0.0 { -im } else { im })
    }
}

/// Fresnel amplitudes `(r_s, r_p)` (complex, as `(re, im)`) for incidence cosine `cos_i` from
/// air onto a medium of complex refractive index `n + ik` (Born & Wolf §1.5 and §14.2):
/// `r_s = (cos i − ñ cos t)/(cos i + ñ cos t)`, `r_p = (ñ cos i − cos t)/(ñ cos i + cos t)`,
/// `ñ cos t = √(ñ² − sin² i)` (the root with non-negative real part), the same convention as
/// the ocean's (`bsdf/ocean.rs`).
fn amplitudes(n: f64, k: f64, cos_i: f64) -> (C, C) {
    let ci = C(cos_i, 0.0);
    let nn = C(n, k);
    let sin2 = C(1.0 - cos_i * cos_i, 0.0);
    let n_cos_t = nn.mul(nn).sub(sin2).sqrt();
    let rs = ci.sub(n_cos_t).div(ci.add(n_cos_t));
    // cos t = ñ cos t / ñ.
    let cos_t = n_cos_t.div(nn);
    let n_ci = nn.mul(ci);
    let rp = n_ci.sub(cos_t).div(n_ci.add(cos_t));
    (rs, rp)
}

/// Unpolarized Fresnel reflectance `(|r_s|² + |r_p|²)/2` at incidence cosine `cos_i`.
pub fn fresnel_reflectance(n: f64, k: f64, cos_i: f64) -> f64 {
    let (rs, rp) = amplitudes(n, k, cos_i.clamp(0.0, 1.0));
    0.5 * (rs.norm2() + rp.norm2())
}

/// The Fresnel reflection matrix in the scattering-plane frame (the plane of incidence), the
/// layout of the ocean's matrix: `a1 = a2 = (|r_p|² + |r_s|²)/2`, `b1 = (|r_p|² − |r_s|²)/2`,
/// `a3 = a4 = Re(r_p r_s*)`, `b2 = Im(r_p r_s*)` (0 for dielectrics; its sign convention for
/// the circular polarization of metallic mirrors is not validated).
pub fn fresnel_matrix(n: f64, k: f64, cos_i: f64) -> PhaseMatrix {
    let (rs, rp) = amplitudes(n, k, cos_i.clamp(0.0, 1.0));
    let (s2, p2) = (rs.norm2(), rp.norm2());
    let x = rp.mul(C(rs.0, -rs.1));
    PhaseMatrix {
        a1: 0.5 * (p2 + s2),
        b1: 0.5 * (p2 - s2),
        a2: 0.5 * (p2 + s2),
        a3: x.0,
        b2: x.1,
        a4: x.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fan_strata_split_n_into_a_grid() {
        for (n, grid) in [
            (1, (1, 1)),
            (2, (1, 2)),
            (4, (2, 2)),
            (7, (1, 7)),
            (8, (2, 4)),
            (12, (3, 4)),
            (16, (4, 4)),
        ] {
            assert_eq!(fan_strata(n), grid, "{n}");
        }
    }

    #[test]
    fn fresnel_dielectric_closed_forms() {
        // Normal incidence: ((n − 1)/(n + 1))²; Brewster's angle: r_p = 0.
        let n = 1.5;
        let r0 = fresnel_reflectance(n, 0.0, 1.0);
        assert!((r0 - 0.04).abs() < 1e-12, "{r0}");
        let cb = (1.0 / (1.0 + n * n)).sqrt(); // cos of atan(n)
        let m = fresnel_matrix(n, 0.0, cb);
        assert!(
            (m.a1 + m.b1).abs() < 1e-12,
            "r_p² = a1 + b1 = {}",
            m.a1 + m.b1
        );
        // Grazing incidence reflects everything.
        assert!((fresnel_reflectance(n, 0.0, 1e-9) - 1.0).abs() < 1e-6);
        // A metal: normal incidence ((n−1)² + k²)/((n+1)² + k²); large k → 1.
        let (nm, km) = (0.2, 3.0);
        let want = ((nm - 1.0f64).powi(2) + km * km) / ((nm + 1.0f64).powi(2) + km * km);
        assert!((fresnel_reflectance(nm, km, 1.0) - want).abs() < 1e-12);
        assert!(fresnel_reflectance(1.0, 1e4, 0.5) > 1.0 - 1e-6);
        // Energy: the matrix's degree of polarization stays within [0, 1].
        for c in [0.1, 0.5, 0.9] {
            let m = fresnel_matrix(nm, km, c);
            assert!(m.b1.abs() <= m.a1 && (m.a3 * m.a3 + m.b2 * m.b2).sqrt() <= m.a1 + 1e-12);
        }
    }

    #[test]
    fn classic_nodes_integrate_a_lambertian_exactly() {
        // Σ f·cos·ΔΩ over the nodes = ρ for a Lambertian f = ρ/π, whatever the grid.
        let n = DVec3::new(0.3, -0.2, 0.93).normalize();
        for (a, b) in [(1, 1), (3, 5), (8, 16)] {
            let nodes = classic_nodes(n, a, b, |wi| 0.3 / std::f64::consts::PI * wi.dot(n));
            let sum: f64 = nodes.iter().map(|s| s.weight).sum();
            assert!((sum - 0.3).abs() < 1e-12, "{a}×{b}: {sum}");
            assert!(nodes.iter().all(|s| s.wi.dot(n) > 0.0));
        }
    }

    #[test]
    fn generation_counts() {
        assert_eq!(generic_samples(16, 0.5, 1), 16);
        assert_eq!(generic_samples(16, 0.5, 2), 8);
        assert_eq!(generic_samples(16, 0.5, 6), 1);
        assert_eq!(generic_samples(1, 1.0, 9), 1);
    }
}
