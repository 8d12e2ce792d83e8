//! Backward walk in a spherical-shell atmosphere, with next-event estimation towards the Sun.
//!
//! As the plane-parallel [`backward`](super::backward) walk, but in planet-centred coordinates:
//! flights cross shells exactly ([`SphericalShell::fly`]) and the solar transmittance to each
//! interaction is the exact chord sum through the shells, zero when the Sun is below the local
//! horizon of the ray (Earth's shadow), so points lit at twilight (SZA > 90° at the target) are
//! handled. By default (`local_estimate = "expected"`) the next collision's NEE is estimated
//! along each flight from `NEE_STRATA` stratified collision points (the along-flight expectation
//! of the plane-parallel walk has no closed form here); with `"collision"` it is scored at the
//! sampled collision. The ground's normal is the local
//! vertical; BRDFs are evaluated in the local frame there.
//!
//! A sample is `π·L/E0` divided by `mu_norm` (cos SZA at the target when the Sun is up, else 1).

use glam::DVec3;

use super::{roulette, sample_scattered, OrderSplit};
use crate::atmosphere::spherical::{ShellEnd, SphericalShell};
use crate::bsdf::Bsdf;
use super::settings::IntegratorSettings;
use crate::frame::basis_around;
use crate::rng::Stream;

/// Collision points per flight of the stratified next-event estimate.
pub const NEE_STRATA: usize = 4;

/// Stratified estimate of the next collision's next-event estimate along the flight from `p`
/// (shell `l`) along `d`, for a collision within optical depth `tau_end` of the start: K =
/// [`NEE_STRATA`] collision points drawn by stratified inversion of the optical depth, each
/// weighted by P(collision within `tau_end`)/K. Unbiased for the expectation the collision NEE
/// estimates. `seen(q, lq)` is the Sun's transmittance (times any visibility) from a point.
/// Returns `w·P/K·Σ ω·P(s·d)·seen/(4π)` (0 if the flight cannot collide).
#[allow(clippy::too_many_arguments)]
pub(crate) fn stratified_estimate(
    shell: &SphericalShell,
    p: DVec3,
    l: usize,
    d: DVec3,
    tau_end: f64,
    sun_dir: DVec3,
    w: f64,
    rng: &mut Stream,
    seen: impl Fn(DVec3, usize) -> f64,
) -> f64 {
    let p_coll = -(-tau_end).exp_m1();
    if p_coll <= 0.0 {
        return 0.0;
    }
    let xi = rng.next_f64();
    let cos = sun_dir.dot(d);
    let mut acc = 0.0;
    for k in 0..NEE_STRATA {
        let u = (k as f64 + xi) / NEE_STRATA as f64;
        let s_k = -(-u * p_coll).ln_1p();
        if let ShellEnd::Collision(q, lq) = shell.fly(p, l, d, s_k) {
            let f = shell.albedo(lq) * shell.phase(lq).eval(cos);
            if f > 0.0 {
                acc += f * seen(q, lq);
            }
        }
    }
    let inv4pi = 0.25 * std::f64::consts::FRAC_1_PI;
    w * p_coll / NEE_STRATA as f64 * acc * inv4pi
}

/// One path from `p0` (in shell `l0`) along `d0`; returns the (single, multiple) parts.
#[allow(clippy::too_many_arguments)]
pub fn walk(
    shell: &SphericalShell,
    surface: &Bsdf,
    sun_dir: DVec3,
    mu_norm: f64,
    p0: DVec3,
    l0: usize,
    d0: DVec3,
    settings: &IntegratorSettings,
    rng: &mut Stream,
) -> (f64, f64) {
    let mut split = OrderSplit::default();
    let (mut p, mut l, mut d) = (p0, l0, d0);
    let mut w = 1.0_f64;
    let mut order: u32 = 1;
    let inv4pi = 0.25 * std::f64::consts::FRAC_1_PI;
    while order <= settings.max_depth {
        if settings.expected_local_estimate {
            let tau_exit = shell.optical_depth_within(p, l, d, f64::INFINITY);
            let seen = |q: DVec3, lq: usize| shell.transmittance_to_space(q, lq, sun_dir);
            split.add(
                order,
                stratified_estimate(shell, p, l, d, tau_exit, sun_dir, w, rng, seen),
            );
        }
        let s = -rng.next_f64_open0().ln();
        match shell.fly(p, l, d, s) {
            ShellEnd::Escape => break,
            ShellEnd::Surface(q) => {
                p = q;
                l = 0;
                let n = q / q.length();
                let (a, b) = basis_around(n);
                let local = |v: DVec3| DVec3::new(v.dot(a), v.dot(b), v.dot(n));
                let wo = local(-d);
                let cos_sun = sun_dir.dot(n);
                if cos_sun > 0.0 {
                    let t = shell.transmittance_to_space(p, 0, sun_dir);
                    if t > 0.0 {
                        split.add(order, w * surface.eval(local(sun_dir), wo) * cos_sun * t);
                    }
                }
                let smp = surface.sample(wo, rng.next_f64(), rng.next_f64());
                w *= smp.weight;
                d = a * smp.wi.x + b * smp.wi.y + n * smp.wi.z;
            }
            ShellEnd::Collision(q, lq) => {
                p = q;
                l = lq;
                let omega = shell.albedo(l);
                let phase = shell.phase(l);
                if !settings.expected_local_estimate {
                    let t = shell.transmittance_to_space(p, l, sun_dir);
                    if t > 0.0 {
                        split.add(order, w * omega * phase.eval(sun_dir.dot(d)) * inv4pi * t);
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
    let k = std::f64::consts::PI / mu_norm;
    split.scaled(k)
}
