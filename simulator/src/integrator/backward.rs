//! Backward (adjoint) walk from a sensor with next-event estimation towards the Sun.
//!
//! A path starts at the sensor's optical depth τ₀ travelling along the looking direction `d`
//! (opposite to the light). At every interaction the radiance scattered towards the sensor by
//! the directly transmitted sunlight is added:
//! * collision at τ in a layer of albedo ω: `w·ω·P(s·d)/(4π)·E0·e^{−τ/μ_s}` with `s` the unit
//!   vector towards the Sun (light propagating along −s scatters into −d: cos Θ = s·d);
//! * ground: `w·f_r(s, −d)·E0·μ_s·e^{−τ*/μ_s}`.
//!
//! By default the collision's estimate is replaced by its expectation over the collision
//! position along the flight (exact, layer by layer; see the forward walk), so nothing is scored
//! at the sampled collision; `integrator.local_estimate = "collision"` scores there instead.
//!
//! The path then continues in a direction drawn from the phase function (reciprocal) or the
//! BRDF sampler. A sample is `π·L/(E0 μ_s)`. The sky has no diffuse source above TOA and the
//! direct solar beam (a delta in direction) is never seen by the sensor.

use glam::DVec3;

use super::{roulette, sample_scattered, OrderSplit};
use crate::atmosphere::FlightEnd;
use super::settings::IntegratorSettings;
use crate::optics::OpticalState;
use crate::rng::Stream;

/// One path from (τ₀, d₀); returns the (single, multiple) parts of `π·L/(E0 μ_s)`.
pub fn walk(
    opt: &OpticalState,
    sun_dir: DVec3,
    tau0: f64,
    d0: DVec3,
    settings: &IntegratorSettings,
    rng: &mut Stream,
) -> (f64, f64) {
    let atm = &opt.atmosphere;
    let total = atm.total_tau();
    let mu_s = sun_dir.z;
    let t_sun_ground = (-total / mu_s).exp();
    let mut split = OrderSplit::default();
    let mut d = d0;
    let mut tau = tau0;
    let mut w = 1.0_f64;
    let mut order: u32 = 1;
    let inv_mu_s = 1.0 / mu_s;
    while order <= settings.max_depth {
        if settings.expected_local_estimate {
            // Expected next-event estimate of the next collision, exact along the flight.
            let cos = sun_dir.dot(d);
            let mut acc = 0.0;
            atm.flight_integrals(tau, d.z, inv_mu_s, |l, i| {
                acc += atm.albedo(l) * atm.phase(l).eval(cos) * i;
            });
            split.add(order, w * acc * (0.25 * std::f64::consts::FRAC_1_PI));
        }
        let s = -rng.next_f64_open0().ln();
        match atm.fly(tau, d.z, s) {
            FlightEnd::Escape => break,
            FlightEnd::Surface => {
                tau = total;
                let wo = -d;
                let f = opt.surface.eval(sun_dir, wo);
                split.add(order, w * f * mu_s * t_sun_ground);
                let smp = opt.surface.sample(wo, rng.next_f64(), rng.next_f64());
                w *= smp.weight;
                d = smp.wi;
            }
            FlightEnd::Collision(t) => {
                tau = t;
                let layer = atm.layer_at_tau(t);
                let omega = atm.albedo(layer);
                let phase = atm.phase(layer);
                if !settings.expected_local_estimate {
                    split.add(
                        order,
                        w * omega
                            * phase.eval(sun_dir.dot(d))
                            * (0.25 * std::f64::consts::FRAC_1_PI)
                            * (-tau / mu_s).exp(),
                    );
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
    let k = std::f64::consts::PI / mu_s;
    split.scaled(k)
}
