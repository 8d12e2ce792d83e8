//! Forward (photon) walk with local estimates towards many directions at once.
//!
//! A photon enters at TOA along the solar beam carrying weight 1, which stands for the power
//! `E0·cos SZA / N` per unit horizontal area. Contributions to the BRF in direction `v`
//! (`μ_v = v_z > 0`):
//! * collision at optical depth τ in a layer of albedo ω: `w·ω·P(cos Θ)·e^{−τ/μ_v} / (4 μ_v)`,
//!   with cos Θ = d·v (d the photon's direction before scattering);
//! * reflection at the ground, for a photon arriving along `d`: `w·π·f_r(−d, v)·e^{−τ*/μ_v}`.
//!
//! Variance reduction: by default (`integrator.local_estimate = "expected"`) the local estimate
//! of the next collision is replaced by its expectation over the collision position along the
//! flight, integrated exactly layer by layer ([`PlaneParallel::flight_integrals`]); the walk then
//! samples the collision as usual but scores nothing there. Single scattering thus carries no
//! Monte Carlo noise at all, and higher orders lose the noise of the last flight. With
//! `"collision"` the classic point estimate at the sampled collision is used (a cross-check).
//! Likewise the ground contribution is added as its expected value at each downward
//! flight, `w·e^{−(τ*−τ)/|d_z|}·π f_r·e^{−τ*/μ_v}`, instead of only when the sampled flight
//! reaches the ground (unbiased since E[1_hit·X] = P(hit)·X); likewise the upward flux through a
//! level is the expected crossing `w·e^{−(τ−τ_L)/d_z}` of every upward flight from below it.
//! Derivation: Marchuk et al. (1980), "The Monte Carlo methods in atmospheric optics", ch. 2;
//! Mayer (2009), "Radiative transfer in the cloudy atmosphere", EPJ Conf. 1, 75–99.

use glam::DVec3;

use super::{roulette, sample_scattered, Accum};
use crate::atmosphere::FlightEnd;
#[allow(unused_imports)]
use crate::atmosphere::PlaneParallel;
use super::settings::IntegratorSettings;
use crate::optics::OpticalState;
use crate::rng::Stream;

/// What a forward walk scores.
pub struct ForwardTargets<'a> {
    /// Directions towards the sensor (`z > 0`), one cell each.
    pub directions: &'a [DVec3],
    /// Optical depth of a flux level (one cell), if the measure is a flux.
    pub flux_tau: Option<f64>,
    /// Azimuth (radians) fixing the meridian plane of zenith directions (polarized runs).
    pub azimuth_hints: &'a [f64],
}

/// Scratch buffers of one walk (per direction: single and multiple parts), reused across walks.
pub struct Scratch {
    single: Vec<f64>,
    multiple: Vec<f64>,
    inv_mu: Vec<f64>,
    /// e^{−τ*/μ_v}·π: ground-to-TOA transmittance factor per direction.
    t_ground: Vec<f64>,
}

impl Scratch {
    pub fn new(opt: &OpticalState, targets: &ForwardTargets) -> Self {
        let n = targets.directions.len().max(1);
        let inv_mu: Vec<f64> = targets.directions.iter().map(|v| 1.0 / v.z).collect();
        let tt = opt.atmosphere.total_tau();
        let t_ground = inv_mu
            .iter()
            .map(|im| (-tt * im).exp() * std::f64::consts::PI)
            .collect();
        Self {
            single: vec![0.0; n],
            multiple: vec![0.0; n],
            inv_mu,
            t_ground,
        }
    }
}

#[allow(clippy::too_many_arguments)]
/// Run photons `samples` of one stream family and add one sample per cell per photon to `acc`.
pub fn run_block(
    opt: &OpticalState,
    sun_dir: DVec3,
    targets: &ForwardTargets,
    settings: &IntegratorSettings,
    seed: u64,
    ids: [u64; 3],
    samples: std::ops::Range<u64>,
    acc: &mut Accum,
) {
    let mut scratch = Scratch::new(opt, targets);
    for s in samples {
        let mut rng = Stream::new(seed, [ids[0], ids[1], ids[2], s]);
        walk(opt, sun_dir, targets, settings, &mut rng, &mut scratch);
        let cells = scratch.single.len();
        for c in 0..cells {
            acc.add(c, scratch.single[c], scratch.multiple[c]);
        }
    }
}

#[inline]
fn score(scratch: &mut Scratch, order: u32, cell: usize, v: f64) {
    if order == 1 {
        scratch.single[cell] += v;
    } else {
        scratch.multiple[cell] += v;
    }
}

/// One photon history; results in `scratch.single` / `scratch.multiple`.
pub fn walk(
    opt: &OpticalState,
    sun_dir: DVec3,
    targets: &ForwardTargets,
    settings: &IntegratorSettings,
    rng: &mut Stream,
    scratch: &mut Scratch,
) {
    scratch.single.iter_mut().for_each(|x| *x = 0.0);
    scratch.multiple.iter_mut().for_each(|x| *x = 0.0);
    let atm = &opt.atmosphere;
    let total = atm.total_tau();
    let dirs = targets.directions;
    let mut d = -sun_dir;
    let mut tau = 0.0_f64;
    let mut w = 1.0_f64;
    // Order of the next interaction (1 = first).
    let mut order: u32 = 1;
    loop {
        // Expected-value scores of this flight.
        if d.z < 0.0 && !dirs.is_empty() && order <= settings.max_depth {
            let p_hit = (-(total - tau) / (-d.z)).exp();
            let wi = -d;
            for (k, v) in dirs.iter().enumerate() {
                let f = opt.surface.eval(wi, *v);
                if f > 0.0 {
                    score(scratch, order, k, w * p_hit * f * scratch.t_ground[k]);
                }
            }
        }
        if settings.expected_local_estimate && order <= settings.max_depth && !dirs.is_empty() {
            // Expected value of the next collision's local estimates (exact along the flight).
            for (k, v) in dirs.iter().enumerate() {
                let im = scratch.inv_mu[k];
                let cos = d.dot(*v);
                let mut acc = 0.0;
                atm.flight_integrals(tau, d.z, im, |l, i| {
                    acc += atm.albedo(l) * atm.phase(l).eval(cos) * i;
                });
                if acc > 0.0 {
                    score(scratch, order, k, w * 0.25 * im * acc);
                }
            }
        }
        if let Some(tl) = targets.flux_tau {
            if d.z > 0.0 && tau >= tl && order > 1 {
                let v = w * (-(tau - tl) / d.z).exp();
                score(scratch, order - 1, 0, v);
            }
        }
        if order > settings.max_depth {
            break;
        }
        let s = -rng.next_f64_open0().ln();
        match atm.fly(tau, d.z, s) {
            FlightEnd::Escape => break,
            FlightEnd::Surface => {
                tau = total;
                let smp = opt.surface.sample(-d, rng.next_f64(), rng.next_f64());
                w *= smp.weight;
                d = smp.wi;
            }
            FlightEnd::Collision(t) => {
                tau = t;
                let layer = atm.layer_at_tau(t);
                let omega = atm.albedo(layer);
                let phase = atm.phase(layer);
                if !settings.expected_local_estimate {
                    let c = w * omega * 0.25;
                    for (k, v) in dirs.iter().enumerate() {
                        let im = scratch.inv_mu[k];
                        score(
                            scratch,
                            order,
                            k,
                            c * phase.eval(d.dot(*v)) * (-tau * im).exp() * im,
                        );
                    }
                }
                w *= omega;
                d = sample_scattered(phase, d, rng);
            }
        }
        order += 1;
        if w <= 0.0 {
            break;
        }
        if order > settings.rr_depth && !roulette(&mut w, rng.next_f64()) {
            break;
        }
    }
}
