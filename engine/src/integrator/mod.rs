//! The transport core: two estimators, generic over what a path carries and where it travels.
//!
//! * [`backward`]: paths leave the sensor; at every interaction the sunlight scattered into the
//!   path is added (next-event estimation). Generic over the [`weight`] (scalar radiance, or a
//!   Mueller matrix for polarized runs) and the [`geometry`] (plane-parallel layers, spherical
//!   shells, a 3D scene inside either): radiancemeters, 3D scenes, spherical shells, and distant
//!   measures when asked for.
//! * [`forward`]: photons leave the Sun; at every interaction a *local estimate* towards
//!   **every** direction of a distant measure is added, so one walk serves all directions at
//!   once (the method of MYSTIC and SMART-G). Generic over the weight (scalar, or a Stokes
//!   vector); plane-parallel layers. Used for `mdistant` and `distant_flux` in 1D.
//! * [`lamp_photons`]: photons leave the lamps (`[[lights]]`) and score, at every surface and
//!   along every flight, the radiance they send up to the pixel of a nadir ortho image under
//!   them (light tracing with local estimates): the lamps' part of such images.
//! * [`backward_alis`]: the backward estimator for many spectral channels at once (CKD g-points,
//!   or neighbouring wavelengths): one path sampled in a reference atmosphere, one weight per
//!   channel (Emde et al. 2011); [`scene_alis`] carries its wavelength walk into 3D scenes.
//!
//! Per-material radiometry solvers ([`solver`]: generic with per-generation sample counts,
//! classic quadrature, simple, mirror, null) act in the backward estimator's one loop.
//!
//! What lives once: Russian roulette and the weights' scattering and reflection
//! ([`weight`]), the surfaces seen by paths ([`surface`]), the expected-value and stratified
//! next-event estimates ([`geometry`]), and the single/multiple split of scores (the first
//! interaction is single scattering).
//!
//! Samples are the *normalised radiance* `π·L/(E0·cos SZA)` (the BRF for a TOA measure) or, for
//! fluxes, `F↑/(E0·cos SZA)`. Absorption multiplies the weight by the single-scattering albedo
//! (survival biasing); Russian roulette starts at scattering order `rr_depth` and only touches
//! weights below [`RR_THRESHOLD`], so it is unbiased and costs little variance.

pub mod above_scene;
pub mod backward;
pub mod backward_alis;
pub mod forward;
pub mod forward_emission;
pub mod geometry;
pub mod lamp_photons;
pub mod peak_sampling;
pub mod scene_alis;
pub mod settings;
pub mod solver;
pub mod stokes_sampling;
pub mod surface;
pub mod weight;

/// Weight below which Russian roulette plays (after `rr_depth` interactions).
pub const RR_THRESHOLD: f64 = 0.25;

pub use crate::accum::{Accum, MULTIPLE, Q, SINGLE, TOTAL, U, V};
