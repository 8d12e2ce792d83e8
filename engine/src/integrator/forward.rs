//! The forward (photon) estimator with local estimates towards many directions at once, in
//! plane-parallel layers over a flat surface; generic over the photon's [`Weight`] (scalar or
//! Stokes vector), monomorphised for each.
//!
//! A photon enters at TOA along the solar beam carrying weight 1, which stands for the power
//! `E0·cos SZA / N` per unit horizontal area. Contributions to the BRF in direction `v`
//! (`μ_v = v_z > 0`):
//! * collision at optical depth τ in a layer of albedo ω: `w·ω·P(cos Θ)·e^{−τ/μ_v} / (4 μ_v)`,
//!   with cos Θ = d·v (d the photon's direction before scattering); polarized: the photon's
//!   Stokes vector scattered through `F(Θ)` into `v` and rotated into `v`'s meridian frame;
//! * reflection at the ground, for a photon arriving along `d`: `w·π·f_r(−d, v)·e^{−τ*/μ_v}`
//!   (polarizing surfaces: their reflection matrix, like a scattering).
//!
//! Variance reduction: by default (`integrator.local_estimate = "expected"`) the local estimate
//! of the next collision is replaced by its expectation over the collision position along the
//! flight, integrated exactly layer by layer ([`PlaneParallel::flight_integrals`]; the frame and
//! Θ_v do not change along a flight, only the scalar factor does); the walk then samples the
//! collision as usual but scores nothing there. Single scattering thus carries no Monte Carlo
//! noise at all. `"collision"` scores at the sampled collision (a cross-check). Likewise the
//! ground contribution is added as its expected value at each downward flight,
//! `w·e^{−(τ*−τ)/|d_z|}·π f_r·e^{−τ*/μ_v}`, and the upward flux through a level as the expected
//! crossing `w·e^{−(τ−τ_L)/d_z}` of every upward flight from below it (intensity only); the
//! downwelling diffuse flux likewise from every downward flight from above it after the first
//! scattering (the direct beam is exact, `direct_flux.rs`).
//! Thermal emission (`emission = true`, directional measures): one emitted photon per sample
//! beside the solar one, drawn in proportion to the emitted power, and the directly
//! transmitted emission in closed form (`forward_emission.rs`).
//! Derivation: Marchuk et al. (1980), "The Monte Carlo methods in atmospheric optics", ch. 2;
//! Mayer (2009), "Radiative transfer in the cloudy atmosphere", EPJ Conf. 1, 75–99.

use glam::DVec3;

pub use super::forward_emission::ThermalSources;
use super::peak_sampling::PeakSampling;
use super::settings::IntegratorSettings;
use super::surface::SurfaceAt;
use super::weight::{
    split_count, survives, OrderSplit, Scalar, StokesPhoton, StokesTally, Toward, Weight,
    MAX_SPLITS,
};
use crate::accum::Accum;
use crate::atmosphere::{FlightEnd, PlaneParallel};
use crate::bsdf::Bsdf;
use crate::measure::FluxDirection;
use crate::rng::Stream;
use crate::stokes::meridian_axis;

/// What a forward walk scores.
pub struct ForwardTargets<'a> {
    /// Directions towards the sensor (`z > 0`), one cell each.
    pub directions: &'a [DVec3],
    /// Optical depth of a flux level (one cell) and the flux's direction, if the measure is a
    /// flux.
    pub flux: Option<(f64, FluxDirection)>,
    /// Azimuth (radians) fixing the meridian plane of zenith directions (polarized runs).
    pub azimuth_hints: &'a [f64],
}

/// How a photon scores towards a direction `v` (frame axis `e_v`).
pub trait Photon: Weight {
    /// An unpolarized photon of unit weight entering along `d`.
    fn entering(d: DVec3) -> Self;
    /// `acc` (ω·P or ω·F times transmittance integrals) scattered into `to`, times `im/4`.
    fn local_estimate(
        &self,
        t: &mut Self::Tally,
        order: u32,
        acc: &Self::Phase,
        d: DVec3,
        to: Toward,
        im: f64,
    );
    /// Reflection at the ground into `to` of a photon arriving along `d`, reaching the ground
    /// with probability `p_hit`, seen through transmittance·π `t_ground`.
    #[allow(clippy::too_many_arguments)]
    fn ground_estimate(
        &self,
        t: &mut Self::Tally,
        order: u32,
        surface: &Bsdf,
        d: DVec3,
        to: Toward,
        p_hit: f64,
        t_ground: f64,
    );
    /// Add intensity `x` (flux measures).
    fn add_intensity(t: &mut Self::Tally, order: u32, x: f64);
    /// Add `k` times the tally `o`.
    fn add_scaled(t: &mut Self::Tally, o: &Self::Tally, k: f64);
}

impl Photon for Scalar {
    fn entering(_: DVec3) -> Self {
        Scalar(1.0)
    }
    #[inline]
    fn local_estimate(
        &self,
        t: &mut OrderSplit,
        order: u32,
        acc: &f64,
        _: DVec3,
        _: Toward,
        im: f64,
    ) {
        t.add(order, self.0 * 0.25 * im * acc);
    }
    #[inline]
    fn ground_estimate(
        &self,
        t: &mut OrderSplit,
        order: u32,
        surface: &Bsdf,
        d: DVec3,
        to: Toward,
        p_hit: f64,
        t_ground: f64,
    ) {
        let f = surface.eval(-d, to.v);
        if f > 0.0 {
            t.add(order, self.0 * p_hit * f * t_ground);
        }
    }
    #[inline]
    fn add_intensity(t: &mut OrderSplit, order: u32, x: f64) {
        t.add(order, x);
    }
    fn add_scaled(t: &mut OrderSplit, o: &OrderSplit, k: f64) {
        t.single += k * o.single;
        t.multiple += k * o.multiple;
    }
}

impl Photon for StokesPhoton {
    fn entering(d: DVec3) -> Self {
        StokesPhoton::unpolarized(d)
    }
    #[inline]
    fn local_estimate(
        &self,
        t: &mut StokesTally,
        order: u32,
        acc: &crate::stokes::PhaseMatrix,
        d: DVec3,
        to: Toward,
        im: f64,
    ) {
        self.send(t, order, acc, d, to, 0.25 * im);
    }
    #[inline]
    fn ground_estimate(
        &self,
        t: &mut StokesTally,
        order: u32,
        surface: &Bsdf,
        d: DVec3,
        to: Toward,
        p_hit: f64,
        t_ground: f64,
    ) {
        match surface.matrix(-d, to.v) {
            Some(m) if m.a1 > 0.0 => self.send(t, order, &m, d, to, p_hit * t_ground),
            Some(_) => {}
            None => {
                let f = surface.eval(-d, to.v);
                if f > 0.0 {
                    Self::add_intensity(t, order, self.s[0] * p_hit * f * t_ground);
                }
            }
        }
    }
    #[inline]
    fn add_intensity(t: &mut StokesTally, order: u32, x: f64) {
        t[if order == 1 { 0 } else { 1 }] += x;
    }
    fn add_scaled(t: &mut StokesTally, o: &StokesTally, k: f64) {
        for (a, b) in t.iter_mut().zip(o) {
            *a += k * b;
        }
    }
}

/// Per-direction constants and the scores of one walk, reused across walks.
pub struct Scratch<W: Weight> {
    tally: Vec<W::Tally>,
    inv_mu: Vec<f64>,
    /// e^{−τ*/μ_v}·π: ground-to-TOA transmittance factor per direction.
    t_ground: Vec<f64>,
    /// Meridian axis e_θ of each direction (polarized runs).
    e_theta: Vec<DVec3>,
}

impl<W: Weight> Scratch<W> {
    pub fn new(atmosphere: &PlaneParallel, targets: &ForwardTargets) -> Self {
        let n = targets.directions.len().max(1);
        let inv_mu: Vec<f64> = targets.directions.iter().map(|v| 1.0 / v.z).collect();
        let tt = atmosphere.total_tau();
        let t_ground = inv_mu
            .iter()
            .map(|im| (-tt * im).exp() * std::f64::consts::PI)
            .collect();
        let e_theta = targets
            .directions
            .iter()
            .enumerate()
            .map(|(k, v)| meridian_axis(*v, targets.azimuth_hints.get(k).copied().unwrap_or(0.0)))
            .collect();
        Self {
            tally: vec![W::zero_tally(); n],
            inv_mu,
            t_ground,
            e_theta,
        }
    }
}

/// Run photons `samples` of one stream family and add one sample per cell per photon to `acc`
/// (made by [`Weight::accum`]).
#[allow(clippy::too_many_arguments)]
pub fn run_block<W: Photon>(
    atmosphere: &PlaneParallel,
    surface: &Bsdf,
    sun_dir: DVec3,
    targets: &ForwardTargets,
    settings: &IntegratorSettings,
    seed: u64,
    ids: [u64; 3],
    samples: std::ops::Range<u64>,
    acc: &mut Accum,
    thermal: Option<&ThermalSources>,
    sun_shines: bool,
) {
    let mut scratch = Scratch::<W>::new(atmosphere, targets);
    let mut emitted = thermal
        .filter(|t| t.emits())
        .map(|_| Scratch::<W>::new(atmosphere, targets));
    let sobol = settings.sampler == super::settings::Sampler::Sobol;
    if settings.replicates {
        acc.enable_replicates();
    }
    for s in samples {
        let mut rng = Stream::for_sample(seed, [ids[0], ids[1], ids[2], s], sobol);
        acc.begin_sample(s);
        if sun_shines {
            walk::<W>(
                atmosphere,
                surface,
                sun_dir,
                targets,
                settings,
                &mut rng,
                &mut scratch,
            );
        } else {
            scratch.tally.iter_mut().for_each(|x| *x = W::zero_tally());
        }
        if let (Some(th), Some(em)) = (thermal, emitted.as_mut()) {
            // One emitted photon (after the solar one, on the same stream), its score scaled
            // by the emitted power, and the directly transmitted emission in closed form.
            em.tally.iter_mut().for_each(|x| *x = W::zero_tally());
            let (tau, d, k) = th.start(atmosphere, &mut rng);
            let state = State {
                tau,
                d,
                w: W::entering(d),
                order: 1,
            };
            let mut budget = MAX_SPLITS;
            walk_from(
                atmosphere,
                surface,
                targets,
                settings,
                &mut rng,
                em,
                state,
                &mut budget,
            );
            for (c, (t, e)) in scratch.tally.iter_mut().zip(&em.tally).enumerate() {
                W::add_scaled(t, e, th.scale * k);
                W::add_intensity(t, 1, th.direct[c]);
            }
        }
        for (c, t) in scratch.tally.iter().enumerate() {
            W::record(acc, c, t, 1.0);
        }
    }
}

/// One photon history; results in `scratch.tally`.
pub fn walk<W: Photon>(
    atm: &PlaneParallel,
    surface: &Bsdf,
    sun_dir: DVec3,
    targets: &ForwardTargets,
    settings: &IntegratorSettings,
    rng: &mut Stream,
    scratch: &mut Scratch<W>,
) {
    scratch.tally.iter_mut().for_each(|x| *x = W::zero_tally());
    let d = -sun_dir;
    let mut budget = MAX_SPLITS;
    let state = State {
        tau: 0.0,
        d,
        w: W::entering(d),
        order: 1,
    };
    walk_from(
        atm,
        surface,
        targets,
        settings,
        rng,
        scratch,
        state,
        &mut budget,
    );
}

/// Where a photon (or a copy of a split photon) continues from.
struct State<W> {
    /// Optical depth from the top.
    tau: f64,
    d: DVec3,
    w: W,
    /// Order of the next interaction (1 = first).
    order: u32,
}

#[allow(clippy::too_many_arguments)]
fn walk_from<W: Photon>(
    atm: &PlaneParallel,
    surface: &Bsdf,
    targets: &ForwardTargets,
    settings: &IntegratorSettings,
    rng: &mut Stream,
    scratch: &mut Scratch<W>,
    state: State<W>,
    budget: &mut u32,
) {
    let total = atm.total_tau();
    let dirs = targets.directions;
    let State {
        mut tau,
        mut d,
        mut w,
        mut order,
    } = state;
    let ground = SurfaceAt::Flat {
        bsdf: surface,
        frame: None,
    };
    // The sensor directions are the detectors of the local estimates.
    let peak = PeakSampling {
        eps: settings.detector_sampling,
        dirs,
    };
    loop {
        if order <= settings.max_depth && !dirs.is_empty() {
            // Expected-value scores of this flight.
            if d.z < 0.0 {
                let p_hit = (-(total - tau) / (-d.z)).exp();
                for (k, v) in dirs.iter().enumerate() {
                    let to = Toward {
                        v: *v,
                        e_v: scratch.e_theta[k],
                    };
                    let tg = scratch.t_ground[k];
                    w.ground_estimate(&mut scratch.tally[k], order, surface, d, to, p_hit, tg);
                }
            }
            if settings.expected_local_estimate {
                // Expected value of the next collision's local estimates (exact along the flight).
                for (k, v) in dirs.iter().enumerate() {
                    let im = scratch.inv_mu[k];
                    let cos = d.dot(*v);
                    let mut acc = W::zero_phase();
                    atm.flight_integrals(tau, d.z, im, |l, i| {
                        W::accumulate(&mut acc, atm.phase(l), cos, atm.albedo(l), i);
                    });
                    if W::phase_intensity(&acc) > 0.0 {
                        let to = Toward {
                            v: *v,
                            e_v: scratch.e_theta[k],
                        };
                        w.local_estimate(&mut scratch.tally[k], order, &acc, d, to, im);
                    }
                }
            }
        }
        if let Some((tl, dir)) = targets.flux {
            // The expected crossing of the level by this flight. Downwelling: only scattered
            // light (order > 1); the direct beam is added in closed form by the products.
            let crosses = match dir {
                FluxDirection::Up => d.z > 0.0 && tau >= tl,
                FluxDirection::Down => d.z < 0.0 && tau <= tl,
            };
            if crosses && order > 1 {
                let x = w.intensity() * (-(tau - tl).abs() / d.z.abs()).exp();
                W::add_intensity(&mut scratch.tally[0], order - 1, x);
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
                match w.reflect(&ground, d, rng) {
                    Some(d2) => d = d2,
                    None => break,
                }
            }
            FlightEnd::Collision(t) => {
                tau = t;
                let layer = atm.layer_at_tau(t);
                let omega = atm.albedo(layer);
                let phase = atm.phase(layer);
                if !settings.expected_local_estimate && order <= settings.max_depth {
                    for (k, v) in dirs.iter().enumerate() {
                        let im = scratch.inv_mu[k];
                        let mut acc = W::zero_phase();
                        W::accumulate(&mut acc, phase, d.dot(*v), omega, (-tau * im).exp());
                        let to = Toward {
                            v: *v,
                            e_v: scratch.e_theta[k],
                        };
                        w.local_estimate(&mut scratch.tally[k], order, &acc, d, to, im);
                    }
                }
                d = w.scatter(phase, omega, d, &peak, rng);
            }
        }
        order += 1;
        if !survives(&mut w, order, settings.rr_depth, rng) {
            break;
        }
        if let Some((copy, n)) = split_count(&w, budget) {
            for _ in 0..n {
                let next = State {
                    tau,
                    d,
                    w: copy.splittable().expect("a split weight copies"),
                    order,
                };
                walk_from(atm, surface, targets, settings, rng, scratch, next, budget);
            }
            return;
        }
    }
}
