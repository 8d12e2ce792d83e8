//! Monte Carlo integrators for plane-parallel atmospheres over a flat surface.
//!
//! * [`forward`]: photons leave the Sun; at every interaction a *local estimate* (next-event
//!   estimation towards the sensor) is added for **every** direction of a distant measure, so one
//!   walk serves all directions at once (the method of MYSTIC and SMART-G). Used for `mdistant`
//!   and `distant_flux`.
//! * [`backward`]: paths leave the sensor; at every interaction a local estimate towards the Sun
//!   is added (next-event estimation). Used for `radiancemeter`, and for distant measures when
//!   asked for (a cross-check of the forward walk: two independent estimators of one quantity).
//!
//! Both produce samples of the *normalised radiance* `π·L/(E0·cos SZA)` (the BRF for a TOA
//! measure) or, for fluxes, of `F↑/(E0·cos SZA)`; each sample is split into its single-scattering
//! part (paths with one interaction, at the surface or in the atmosphere) and the rest.
//!
//! Weights: absorption multiplies the weight by the single-scattering albedo (survival biasing);
//! Russian roulette starts at scattering order `rr_depth` and only touches weights below
//! [`RR_THRESHOLD`], so it is unbiased and costs little variance.

pub mod backward;
pub mod backward_alis;
pub mod backward_pol;
pub mod backward_sph;
pub mod forward;
pub mod forward_pol;
pub mod scene_walk;
pub mod scene_walk_sph;
pub mod settings;

/// Weight below which Russian roulette plays (after `rr_depth` interactions).
pub const RR_THRESHOLD: f64 = 0.25;

pub use crate::accum::{Accum, MULTIPLE, Q, SINGLE, TOTAL, U, V};

/// The scores of one scalar path split by scattering order: the first interaction is single
/// scattering, every later one multiple.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct OrderSplit {
    single: f64,
    multiple: f64,
}

impl OrderSplit {
    #[inline]
    pub(crate) fn add(&mut self, order: u32, v: f64) {
        if order == 1 {
            self.single += v;
        } else {
            self.multiple += v;
        }
    }

    /// (single, multiple), each multiplied by `k`.
    #[inline]
    pub(crate) fn scaled(&self, k: f64) -> (f64, f64) {
        (self.single * k, self.multiple * k)
    }
}

/// A new propagation direction after scattering along `d`: cos Θ from the phase function, a
/// uniform azimuth about `d` (two random numbers).
#[inline]
pub(crate) fn sample_scattered(
    phase: &crate::phase::PhaseFunction,
    d: glam::DVec3,
    rng: &mut crate::rng::Stream,
) -> glam::DVec3 {
    let mu = phase.sample_cos(rng.next_f64());
    let phi = std::f64::consts::TAU * rng.next_f64();
    crate::frame::rotate_about(d, mu, phi)
}

/// Russian roulette on a weight: returns false when the path dies.
#[inline]
pub(crate) fn roulette(w: &mut f64, u: f64) -> bool {
    if *w >= RR_THRESHOLD {
        return true;
    }
    let p = *w / RR_THRESHOLD;
    if u < p {
        *w = RR_THRESHOLD;
        true
    } else {
        false
    }
}
