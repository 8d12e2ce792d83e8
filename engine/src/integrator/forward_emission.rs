//! Thermal sources for the forward estimator: where an emitted photon starts, in proportion to
//! the emitted power, and the directly transmitted emission, added in closed form.
//!
//! Sources (tally units, `atmosphere/emission.rs`, `bsdf/emissivity.rs`), powers per unit
//! horizontal area:
//! * layer `l`: `P_l = 4π (1 − ω_l) Δτ_l (S_top + S_bot)/2` (isotropic emission, source linear
//!   in optical depth); the depth is drawn from the linear density, the direction uniformly;
//! * ground: `P_s = π ε̄ S_s`, `ε̄ = 2∫ε(μ)μ dμ` the hemispherical emissivity; the direction is
//!   drawn from the cosine density and the photon's score is multiplied by `ε(μ)/ε̄`.
//!
//! One emitted photon per sample, drawn from source `i` with probability `P_i/P`, scores
//! `P/μ_n` times what a unit photon scores (μ_n: the cosine that normalises the tallies, 1
//! without a Sun), which is unbiased for the BRF-normalised radiance of everything the
//! emission becomes after its first flight (scattered, reflected). Its first flight itself,
//! the directly transmitted emission, is added exactly to every sample:
//! `(π/μ_n)·[E(0, −v) + ε(μ_v) S_s e^{−τ*/μ_v}]` (`PlaneParallel::expected_emission`), so it
//! carries no variance. The photon's own weight stays 1 (the power is applied to its tally),
//! so Russian roulette and splitting see the same weights as for solar photons.

use std::f64::consts::PI;

use glam::DVec3;

use crate::atmosphere::PlaneParallel;
use crate::bsdf::SurfaceEmission;
use crate::rng::Stream;

/// The thermal sources of one optical state, seen by forward photons.
pub struct ThermalSources<'a> {
    surface: Option<&'a SurfaceEmission>,
    /// Cumulative powers: layers top to bottom, then the ground; last = total.
    cumulative: Vec<f64>,
    /// Hemispherical emissivity ε̄ of the ground.
    eps_bar: f64,
    /// `P/μ_n`: the score factor of an emitted photon.
    pub scale: f64,
    /// Directly transmitted emission per direction, BRF units.
    pub direct: Vec<f64>,
}

impl<'a> ThermalSources<'a> {
    /// `dirs`: the directions towards the sensor (`z > 0`); `mu_norm`: the cosine that
    /// normalises the tallies.
    pub fn new(
        atm: &PlaneParallel,
        surface: Option<&'a SurfaceEmission>,
        dirs: &[DVec3],
        mu_norm: f64,
    ) -> Self {
        let mut cumulative = Vec::with_capacity(atm.layer_count() + 1);
        let mut sum = 0.0;
        for l in 0..atm.layer_count() {
            sum += 4.0 * PI * atm.emitted_per_area(l);
            cumulative.push(sum);
        }
        // ε̄ = 2∫ε μ dμ, midpoint rule (ε is piecewise linear in μ: 256 nodes are ample).
        let n = 256;
        let eps_bar = surface.map_or(0.0, |s| {
            2.0 * (0..n)
                .map(|i| {
                    let mu = (i as f64 + 0.5) / n as f64;
                    s.emissivity(mu) * mu
                })
                .sum::<f64>()
                / n as f64
        });
        sum += surface.map_or(0.0, |s| PI * eps_bar * s.source);
        cumulative.push(sum);
        let t = atm.total_tau();
        let direct = dirs
            .iter()
            .map(|v| {
                let ground = surface.map_or(0.0, |s| s.radiance(v.z) * (-t / v.z).exp());
                PI / mu_norm * (atm.expected_emission(0.0, -v.z) + ground)
            })
            .collect();
        ThermalSources {
            surface,
            cumulative,
            eps_bar,
            scale: sum / mu_norm,
            direct,
        }
    }

    /// Whether anything emits.
    pub fn emits(&self) -> bool {
        self.scale > 0.0
    }

    /// Draw an emitted photon: its optical depth, direction and the factor its score takes
    /// beyond [`Self::scale`] (`ε(μ)/ε̄` at the ground, 1 in a layer). Four random numbers.
    pub fn start(&self, atm: &PlaneParallel, rng: &mut Stream) -> (f64, DVec3, f64) {
        let total = *self.cumulative.last().expect("ground entry");
        let u = rng.next_f64() * total;
        let i = self.cumulative.partition_point(|&c| c <= u);
        let (u1, u2, u3) = (rng.next_f64(), rng.next_f64(), rng.next_f64());
        let phi = 2.0 * PI * u2;
        if i + 1 >= self.cumulative.len() {
            // The ground: cosine-weighted upward direction.
            let mu = u1.sqrt().max(1e-12);
            let s = (1.0 - mu * mu).max(0.0).sqrt();
            let d = DVec3::new(s * phi.cos(), s * phi.sin(), mu);
            let e = self.surface.map_or(0.0, |s| s.emissivity(mu));
            (atm.total_tau(), d, e / self.eps_bar)
        } else {
            let z = 2.0 * u1 - 1.0;
            let s = (1.0 - z * z).max(0.0).sqrt();
            let d = DVec3::new(s * phi.cos(), s * phi.sin(), z);
            (atm.sample_emission_depth(i, u3), d, 1.0)
        }
    }
}
