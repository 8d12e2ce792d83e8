//! Polarized forward walk: the [`forward`](super::forward) walk with Stokes vectors.
//!
//! The photon carries a Stokes vector `S` (its first component is the weight) and the first axis
//! `e1` of its frame (`stokes.rs` states the convention). At a collision the direction is drawn
//! from `a1 = P11` and a uniform azimuth, and `S ← ω·F(Θ)·S_rot / a1(Θ)` (rotation into the
//! scattering plane, then the phase matrix): unbiased, since the true density of the scattered
//! intensity is `(F·S_rot)_I / 4π` and the sampling density is `a1·I/4π`. The local estimate
//! towards a direction `v` sends `F(Θ_v)·S_rot(v)` and rotates it into `v`'s meridian frame; as in
//! the scalar walk it is integrated exactly over the next collision's position along the flight
//! (the frame and Θ_v do not change along a flight, only the scalar factor does). Depolarizing
//! surfaces reflect `I` only; polarizing ones (the ocean) apply their reflection matrix in the
//! plane of incidence like a scattering.
//!
//! Scores are BRF-normalised Stokes components `π·(I, Q, U, V)/(E0 cos SZA)` in the meridian
//! frame of each direction; flux measures score I only.

use glam::DVec3;

use super::forward::ForwardTargets;
use super::{sample_scattered, Accum, RR_THRESHOLD};
use crate::atmosphere::FlightEnd;
use super::settings::IntegratorSettings;
use crate::optics::OpticalState;
use crate::rng::Stream;
use crate::stokes::{any_perpendicular, meridian_axis, rotate_to, scatter, PhaseMatrix, Stokes};

/// Per-walk scores and per-direction constants.
pub struct Scratch {
    /// Per cell: (I single, I multiple, Q, U, V).
    score: Vec<[f64; 5]>,
    inv_mu: Vec<f64>,
    t_ground: Vec<f64>,
    /// Meridian axis e_θ of each direction.
    e_theta: Vec<DVec3>,
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
        let e_theta = targets
            .directions
            .iter()
            .enumerate()
            .map(|(k, v)| meridian_axis(*v, targets.azimuth_hints.get(k).copied().unwrap_or(0.0)))
            .collect();
        Self {
            score: vec![[0.0; 5]; n],
            inv_mu,
            t_ground,
            e_theta,
        }
    }
}

#[allow(clippy::too_many_arguments)]
/// Run photons `samples` and add one polarized sample per cell per photon to `acc`.
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
        for (c, x) in scratch.score.iter().enumerate() {
            acc.add_stokes(c, x[0], x[1], x[2], x[3], x[4]);
        }
    }
}

#[inline]
fn add(score: &mut [f64; 5], order: u32, s: Stokes, k: f64) {
    if order == 1 {
        score[0] += s[0] * k;
    } else {
        score[1] += s[0] * k;
    }
    score[2] += s[1] * k;
    score[3] += s[2] * k;
    score[4] += s[3] * k;
}

/// One photon history; results in `scratch.score`.
pub fn walk(
    opt: &OpticalState,
    sun_dir: DVec3,
    targets: &ForwardTargets,
    settings: &IntegratorSettings,
    rng: &mut Stream,
    scratch: &mut Scratch,
) {
    scratch.score.iter_mut().for_each(|x| *x = [0.0; 5]);
    let atm = &opt.atmosphere;
    let total = atm.total_tau();
    let dirs = targets.directions;
    let mut d = -sun_dir;
    let mut e1 = any_perpendicular(d);
    let mut st: Stokes = [1.0, 0.0, 0.0, 0.0];
    let mut tau = 0.0_f64;
    let mut order: u32 = 1;
    loop {
        if order <= settings.max_depth && !dirs.is_empty() {
            if d.z < 0.0 {
                // Expected ground reflection (depolarizing surfaces: I only).
                let p_hit = (-(total - tau) / (-d.z)).exp();
                for (k, v) in dirs.iter().enumerate() {
                    if let Some(m) = opt.surface.matrix(-d, *v) {
                        // Polarizing surface: reflect the Stokes vector like a scattering.
                        if m.a1 > 0.0 {
                            let (sv, lv) = scatter(st, d, e1, *v, &m);
                            let sm = rotate_to(sv, *v, lv, scratch.e_theta[k]);
                            add(
                                &mut scratch.score[k],
                                order,
                                sm,
                                p_hit * scratch.t_ground[k],
                            );
                        }
                        continue;
                    }
                    let f = opt.surface.eval(-d, *v);
                    if f > 0.0 {
                        let val = st[0] * p_hit * f * scratch.t_ground[k];
                        add(&mut scratch.score[k], order, [1.0, 0.0, 0.0, 0.0], val);
                    }
                }
            }
            // Expected local estimate of the next collision, with Stokes vectors.
            for (k, v) in dirs.iter().enumerate() {
                let im = scratch.inv_mu[k];
                let cos = d.dot(*v);
                let mut m = PhaseMatrix {
                    a1: 0.0,
                    b1: 0.0,
                    a2: 0.0,
                    a3: 0.0,
                    b2: 0.0,
                    a4: 0.0,
                };
                atm.flight_integrals(tau, d.z, im, |l, i| {
                    m.add(&atm.phase(l).matrix(cos).scaled(atm.albedo(l) * i));
                });
                if m.a1 > 0.0 {
                    let (sv, lv) = scatter(st, d, e1, *v, &m);
                    let sm = rotate_to(sv, *v, lv, scratch.e_theta[k]);
                    add(&mut scratch.score[k], order, sm, 0.25 * im);
                }
            }
        }
        if let Some(tl) = targets.flux_tau {
            if d.z > 0.0 && tau >= tl && order > 1 {
                let v = st[0] * (-(tau - tl) / d.z).exp();
                add(&mut scratch.score[0], order - 1, [1.0, 0.0, 0.0, 0.0], v);
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
                if let Some(m) = opt.surface.matrix(-d, smp.wi) {
                    let (s2, l2) = scatter(st, d, e1, smp.wi, &m);
                    let k = smp.wi.z / smp.pdf;
                    st = [s2[0] * k, s2[1] * k, s2[2] * k, s2[3] * k];
                    e1 = l2;
                } else {
                    st = [st[0] * smp.weight, 0.0, 0.0, 0.0];
                    e1 = any_perpendicular(smp.wi);
                }
                d = smp.wi;
            }
            FlightEnd::Collision(t) => {
                tau = t;
                let layer = atm.layer_at_tau(t);
                let omega = atm.albedo(layer);
                let phase = atm.phase(layer);
                let d2 = sample_scattered(phase, d, rng);
                let f = phase.matrix(d.dot(d2));
                let (s2, l2) = scatter(st, d, e1, d2, &f);
                let k = omega / f.a1;
                st = [s2[0] * k, s2[1] * k, s2[2] * k, s2[3] * k];
                d = d2;
                e1 = l2;
            }
        }
        order += 1;
        if st[0] <= 0.0 {
            break;
        }
        if order > settings.rr_depth && st[0] < RR_THRESHOLD {
            if rng.next_f64() < st[0] / RR_THRESHOLD {
                let k = RR_THRESHOLD / st[0];
                st = [st[0] * k, st[1] * k, st[2] * k, st[3] * k];
            } else {
                break;
            }
        }
    }
}
