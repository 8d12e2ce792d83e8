//! One backward walk for all g-points of a CKD bin (the ALIS idea: Emde, Buras & Mayer 2011,
//! "ALIS: An efficient method to compute high spectral resolution polarized solar radiances
//! using the Monte Carlo approach", JQSRT 112, 1622–1631).
//!
//! The g-points of a bin share the scattering (Rayleigh, aerosols) and differ only in gas
//! absorption. The walk samples free paths and survival in a *reference* atmosphere (the bin's
//! atmosphere without gas absorption) and carries, for every g-point, the factor
//! `e_g = exp(−(τ_g − τ_ref))` accumulated along the path (optical paths along each flight,
//! exact for any direction, in metres). The density of scattering events of the g-point process
//! is `σ_s·e^{−τ_g}` and that of the reference process `σ_s·e^{−τ_ref}` (survival weight ω_ref
//! included), so `e_g` is exactly their ratio: each g-point's estimate is unbiased. At every
//! event the next-event estimate to the Sun uses each g-point's own transmittance
//! `exp(−τ_g(z)/μ_s)`; the walk scores the bin mean `Σ_g w_g·(estimate_g)` (quadrature weights
//! w_g). By default the atmospheric estimate is its expectation over the next collision,
//! integrated exactly layer by layer for every g-point ([`expected`]); without it (the collision
//! estimator, `local_estimate = "collision"`) saturated bands, whose signal comes from rare
//! scattering high in the atmosphere (1380 nm), need orders of magnitude more walks.
//! Plane-parallel, scalar, 1D surface; positions are altitudes.

use glam::DVec3;

use super::{roulette, sample_scattered, OrderSplit};
use crate::atmosphere::PlaneParallel;
use crate::bsdf::Bsdf;
use crate::config::resolve::IntegratorSettings;
use crate::rng::Stream;

/// The g-points of a bin: quadrature weights and atmospheres, and the reference atmosphere in
/// which free paths are sampled (absorbing at most as much as any g-point).
pub struct GPoints<'a> {
    pub weights: &'a [f64],
    pub atms: &'a [&'a PlaneParallel],
    pub reference: &'a PlaneParallel,
    /// Layer tables for the expected estimates (from [`Layers::new`]).
    pub layers: &'a Layers,
}

/// Per-layer coefficients shared by the walks of a block: boundaries (top down), the reference
/// scattering coefficient σ_s (m⁻¹), and per g-point the extinction coefficient k_g (m⁻¹) and
/// the optical depth τ_g at each boundary.
pub struct Layers {
    z: Vec<f64>,
    sigma_s: Vec<f64>,
    k: Vec<Vec<f64>>,
    tau: Vec<Vec<f64>>,
    /// The reference atmosphere's extinction coefficient and optical depths.
    k_ref: Vec<f64>,
    tau_ref: Vec<f64>,
}

impl Layers {
    pub fn new(reference: &PlaneParallel, atms: &[&PlaneParallel]) -> Self {
        let b: Vec<(f64, f64)> = reference.boundaries().collect();
        let n = b.len() - 1;
        let z: Vec<f64> = b.iter().map(|x| x.0).collect();
        let coef = |t: &[(f64, f64)], i: usize| {
            let dz = t[i].0 - t[i + 1].0;
            if dz > 0.0 {
                (t[i + 1].1 - t[i].1) / dz
            } else {
                0.0
            }
        };
        let sigma_s = (0..n).map(|i| reference.albedo(i) * coef(&b, i)).collect();
        let mut k = Vec::new();
        let mut tau = Vec::new();
        for a in atms {
            let t: Vec<(f64, f64)> = a.boundaries().collect();
            k.push((0..n).map(|i| coef(&t, i)).collect());
            tau.push(t.iter().map(|x| x.1).collect());
        }
        let k_ref = (0..n).map(|i| coef(&b, i)).collect();
        let tau_ref = b.iter().map(|x| x.1).collect();
        Layers {
            z,
            sigma_s,
            k,
            tau,
            k_ref,
            tau_ref,
        }
    }

    /// Layer index and fraction `f` (0 at the layer's top) of altitude `z`.
    fn locate(&self, z: f64) -> (usize, f64) {
        let n = self.sigma_s.len();
        let i = self.z.partition_point(|&b| b > z).clamp(1, n) - 1;
        let (zt, zb) = (self.z[i], self.z[i + 1]);
        let f = if zt > zb {
            ((zt - z) / (zt - zb)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (i, f)
    }

    /// Multiply each g-point's path factor by `exp(−(τ_g − τ_ref))` over the flight of length
    /// `t` from altitude `z` along a direction of vertical component `dz` (optical paths from
    /// the optical depths at both ends: `|Δτ|/|dz|`; a horizontal flight stays in its layer).
    fn carry(&self, e: &mut [f64], z: f64, dz: f64, t: f64) {
        let (i0, f0) = self.locate(z);
        if dz.abs() < 1e-12 {
            for (k, ek) in e.iter_mut().enumerate() {
                *ek *= (-(self.k[k][i0] - self.k_ref[i0]) * t).exp();
            }
            return;
        }
        let (i1, f1) = self.locate(z + t * dz);
        let at = |tau: &[f64], i: usize, f: f64| tau[i] + f * (tau[i + 1] - tau[i]);
        let inv = 1.0 / dz.abs();
        let d_ref = (at(&self.tau_ref, i1, f1) - at(&self.tau_ref, i0, f0)).abs();
        for (k, ek) in e.iter_mut().enumerate() {
            let tau = &self.tau[k];
            let d = (at(tau, i1, f1) - at(tau, i0, f0)).abs();
            *ek *= (-(d - d_ref) * inv).exp();
        }
    }
}

/// Expected value over the next (reference) collision of the flight from altitude `z` along `d`
/// of the bin-mean next-event estimate `Σ_g w_g·e_g·σ_s P/(4π)·T_g,sun / k_ref…`, integrated
/// exactly layer by layer (every factor is exponential in the distance inside a layer): per
/// g-point `∫ σ_s,L P_L e_g e^{−S_g(ℓ)} e^{−τ_g(z(ℓ))/μ_s} dℓ` over the flight to the ground or
/// the top (`S_g`: the g-point's optical path from the flight's start).
fn expected(g: &GPoints, e: &[f64], z: f64, d: DVec3, sun: DVec3) -> f64 {
    let l = g.layers;
    let n = l.sigma_s.len();
    let (toa, ground) = (l.z[0], l.z[n]);
    let mu_s = sun.z;
    let cos = sun.dot(d);
    let dz = d.z;
    let z = z.min(toa);
    if z < ground || (z >= toa && dz >= 0.0) {
        return 0.0;
    }
    let mut i = if dz < 0.0 {
        l.z.partition_point(|&b| b > z).clamp(1, n) - 1
    } else {
        l.z.partition_point(|&b| b >= z).clamp(1, n) - 1
    };
    let ng = g.weights.len();
    // amp[k] = w_g·e_g·e^{−S_g(ℓ)}·e^{−τ_g(z(ℓ))/μ_s} at the current point of the flight. Inside
    // a layer it decays as e^{−a_g ℓ} with a_g = k_g·(1 − d_z/μ_s), so the layer's integral is
    // amp·(1 − e^{−a_g·len})/a_g and one exponential per g-point and layer carries it on.
    let mut amp = [0.0_f64; 64];
    let amp = &mut amp[..ng];
    {
        let (zt, zb) = (l.z[i], l.z[i + 1]);
        let f = if zt > zb { (zt - z) / (zt - zb) } else { 0.0 };
        for k in 0..ng {
            let tau_z = l.tau[k][i] + f * (l.tau[k][i + 1] - l.tau[k][i]);
            amp[k] = g.weights[k] * e[k] * (-tau_z / mu_s).exp();
        }
    }
    let slant = 1.0 - dz / mu_s;
    let mut z = z;
    let mut total = 0.0;
    loop {
        let (zt, zb) = (l.z[i], l.z[i + 1]);
        let len = if dz > 0.0 {
            (zt - z) / dz
        } else if dz < 0.0 {
            (z - zb) / -dz
        } else {
            f64::INFINITY
        };
        let sig = l.sigma_s[i];
        let finite = len.is_finite();
        let mut acc = 0.0;
        for (ak, kg) in amp.iter_mut().zip(&l.k) {
            let a = kg[i] * slant;
            let x = a * len;
            let decay = if finite { (-x).exp() } else { 0.0 };
            if sig > 0.0 {
                let integral = if !finite {
                    if a > 0.0 {
                        1.0 / a
                    } else {
                        0.0
                    }
                } else if x.abs() < 1e-6 {
                    // (1 − e^{−x})/a to second order (a < 0 going up towards the Sun).
                    len * (1.0 - 0.5 * x)
                } else {
                    (1.0 - decay) / a
                };
                acc += *ak * integral;
            }
            *ak *= decay;
        }
        if sig > 0.0 {
            total += sig * g.reference.phase(i).eval(cos) * acc;
        }
        if !finite {
            break;
        }
        if dz > 0.0 {
            if i == 0 {
                break;
            }
            z = zt;
            i -= 1;
        } else {
            if i + 1 >= n {
                break;
            }
            z = zb;
            i += 1;
        }
    }
    total * (0.25 * std::f64::consts::FRAC_1_PI)
}

/// One path from altitude `z0` along `d0`; returns the (single, multiple) parts of the bin mean
/// of `π·L/(E0 μ_s)`.
pub fn walk(
    g: &GPoints,
    surface: &Bsdf,
    sun: DVec3,
    z0: f64,
    d0: DVec3,
    settings: &IntegratorSettings,
    rng: &mut Stream,
) -> (f64, f64) {
    let ng = g.atms.len();
    let reference = g.reference;
    let ground = reference.ground();
    let mu_s = sun.z;
    let inv_4pi = 0.25 * std::f64::consts::FRAC_1_PI;
    // Per g-point: the path factor e_g and the Sun's transmittance at the ground.
    let mut e = [1.0_f64; 64];
    let e = &mut e[..ng];
    let t_ground: Vec<f64> = g
        .atms
        .iter()
        .map(|a| (-a.total_tau() / mu_s).exp())
        .collect();
    let mut split = OrderSplit::default();
    let mut z = z0;
    let mut d = d0;
    let mut w = 1.0_f64;
    let mut order: u32 = 1;
    let update = |e: &mut [f64], z: f64, dz: f64, t: f64| g.layers.carry(e, z, dz, t);
    let expected_mode = settings.expected_local_estimate;
    while order <= settings.max_depth {
        let mut score = 0.0;
        if expected_mode {
            score += w * expected(g, e, z, d, sun);
        }
        let s = -rng.next_f64_open0().ln();
        match reference.march(z, d.z, s, f64::INFINITY) {
            Some(t) => {
                update(e, z, d.z, t);
                z += t * d.z;
                let layer = reference.layer_at_altitude(z);
                let omega = reference.albedo(layer);
                let phase = reference.phase(layer);
                if !expected_mode {
                    let common = w * omega * phase.eval(sun.dot(d)) * inv_4pi;
                    let acc: f64 = g
                        .atms
                        .iter()
                        .zip(g.weights)
                        .zip(e.iter())
                        .map(|((a, wk), ek)| wk * ek * (-a.tau_at_altitude(z) / mu_s).exp())
                        .sum();
                    score += common * acc;
                }
                w *= omega;
                d = sample_scattered(phase, d, rng);
            }
            None if d.z < 0.0 => {
                // Down to the ground without a collision.
                let t = (z - ground) / -d.z;
                update(e, z, d.z, t);
                z = ground;
                let wo = -d;
                let f = surface.eval(sun, wo) * mu_s;
                let acc: f64 = g
                    .weights
                    .iter()
                    .zip(e.iter())
                    .zip(&t_ground)
                    .map(|((wk, ek), tk)| wk * ek * tk)
                    .sum();
                score += w * f * acc;
                let smp = surface.sample(wo, rng.next_f64(), rng.next_f64());
                w *= smp.weight;
                d = smp.wi;
            }
            None => {
                // Leaves through the top: its expected estimate still counts.
                split.add(order, score);
                break;
            }
        }
        split.add(order, score);
        order += 1;
        if w <= 0.0 {
            break;
        }
        if order > settings.rr_depth && !roulette(&mut w, rng.next_f64()) {
            break;
        }
    }
    let k = std::f64::consts::PI / mu_s;
    split.scaled(k)
}
