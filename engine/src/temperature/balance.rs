//! The surface energy balance of a facet through a day, and its periodic steady state.
//!
//! Net flux into the surface (W m⁻², positive downwards into the slab of `slab.rs`):
//!
//! ```text
//! F(T_s, t) = (1 − α)·[E_b(t)·max(0, n·s(t))·lit(t) + E_d(t)·V + α_g·E_g(t)·(1 − V)]
//!           + ε·[V·L_sky(t) + (1 − V)·σT_a(t)⁴] − ε·σ·T_s⁴ − h(u)·(T_s − T_a(t))
//!           − β·h(u)·(e_s(T_s) − e_a(t))/γ
//! ```
//!
//! * `E_b` direct solar irradiance normal to the beam and `E_d` diffuse sky irradiance on a
//!   horizontal plane (broadband, W m⁻²; the simulator computes them through the run's
//!   atmosphere), `E_g = E_b·cos θ_s + E_d` the global irradiance, `s` the Sun's direction, `n`
//!   the facet's normal, `lit` whether the facet sees the Sun (shadow rays), `V` the facet's
//!   sky-view factor (cosine-weighted fraction of its hemisphere open to the sky), `α_g` the
//!   surroundings' albedo (what the hidden part of the hemisphere reflects);
//! * `α` shortwave albedo, `ε` thermal emissivity of the facet's material;
//! * `L_sky = ε_a σ T_a⁴`, the clear-sky emissivity of Brutsaert (1975),
//!   `ε_a = 1.24 (e_a/T_a)^{1/7}` with the vapour pressure `e_a` in hPa (Magnus formula over
//!   water, Alduchov & Eskridge 1996); the hidden part of the hemisphere radiates as a black
//!   body at the air temperature;
//! * convection `h = 5.7 + 3.8 u` W m⁻² K⁻¹ for a wind speed `u` (m s⁻¹) (McAdams 1954, as in
//!   Watmuff et al. 1977);
//! * evaporation: the latent heat flux by the Lewis analogy with the convection (the same
//!   transfer coefficient for vapour as for heat), scaled by the surface's wetness `β` ∈ [0, 1]
//!   (1 open water, about 0.3 transpiring vegetation, 0 dry and sealed surfaces; Monteith &
//!   Unsworth 2013, ch. 13): `e_s` the saturation vapour pressure at the surface (Magnus, kPa),
//!   `e_a` the air's, `γ = c_p·p/(0.622·L_v) = 0.0665 kPa K⁻¹` the psychrometric constant at
//!   sea-level pressure; negative (dew) where `e_s(T_s) < e_a`;
//! * the air temperature follows a cosine between the day's minimum and maximum, highest at
//!   `hour_of_max` local solar time.
//!
//! [`periodic_day`] repeats the same day until the surface temperature at the day's end moves
//! less than the tolerance from one day to the next (the periodic steady state of a site under
//! fair, repeating weather), and returns the last day.

use glam::DVec3;

use super::slab::{Budget, Slab};

/// Stefan–Boltzmann constant, W m⁻² K⁻⁴ (CODATA 2018).
pub const SIGMA: f64 = 5.670_374_419e-8;

/// Psychrometric constant at sea-level pressure, kPa K⁻¹.
pub const GAMMA: f64 = 0.0665;

/// Saturation vapour pressure over water (kPa) at `t` (K), and its derivative (kPa K⁻¹)
/// (Magnus formula, Alduchov & Eskridge 1996).
pub fn saturation_vapour_pressure(t: f64) -> (f64, f64) {
    let c = t - 273.15;
    let e = 0.61094 * (17.625 * c / (c + 243.04)).exp();
    (e, e * 17.625 * 243.04 / ((c + 243.04) * (c + 243.04)))
}

/// Clear-sky atmospheric emissivity (Brutsaert 1975) at air temperature `t_air` (K) and
/// relative humidity `rh` (0–1).
pub fn sky_emissivity(t_air: f64, rh: f64) -> f64 {
    // e_a in hPa.
    let e_a = (rh * saturation_vapour_pressure(t_air).0 * 10.0).max(1e-6);
    1.24 * (e_a / t_air).powf(1.0 / 7.0)
}

/// Convective heat-transfer coefficient (W m⁻² K⁻¹) at wind speed `u` (m s⁻¹).
pub fn convection(u: f64) -> f64 {
    5.7 + 3.8 * u
}

/// What drives every facet at one time step (the step's end).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Drive {
    /// Unit vector towards the Sun (local frame, z up).
    pub sun: DVec3,
    /// Direct irradiance normal to the beam, W m⁻² (0 with the Sun down).
    pub direct: f64,
    /// Diffuse sky irradiance on a horizontal plane, W m⁻².
    pub diffuse: f64,
    /// Air temperature, K.
    pub t_air: f64,
    /// Downwelling longwave irradiance of the whole sky on a horizontal plane, W m⁻².
    pub sky_longwave: f64,
    /// Convective coefficient, W m⁻² K⁻¹.
    pub h: f64,
    /// The air's vapour pressure, kPa.
    pub vapour_pressure: f64,
}

impl Drive {
    /// A step's drive from the Sun's direction, the direct (normal) and diffuse (horizontal)
    /// irradiances (W m⁻²), the air temperature (K), relative humidity (0–1) and wind (m s⁻¹):
    /// the sky's longwave from Brutsaert's emissivity, the convection from the wind.
    pub fn new(sun: DVec3, direct: f64, diffuse: f64, t_air: f64, rh: f64, wind: f64) -> Drive {
        Drive {
            sun,
            direct,
            diffuse,
            t_air,
            sky_longwave: sky_emissivity(t_air, rh) * SIGMA * t_air.powi(4),
            h: convection(wind),
            vapour_pressure: rh * saturation_vapour_pressure(t_air).0,
        }
    }
}

/// A day of drives at equal steps.
#[derive(Clone, Debug)]
pub struct Day {
    /// Seconds per step.
    pub dt: f64,
    pub steps: Vec<Drive>,
    /// Albedo of the surroundings that fill the hidden part of a facet's hemisphere.
    pub surround_albedo: f64,
}

/// The surface properties the balance needs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceOptics {
    /// Broadband shortwave albedo, [0, 1].
    pub albedo: f64,
    /// Thermal emissivity, (0, 1].
    pub emissivity: f64,
    /// Wetness β ∈ [0, 1]: the fraction of the open-water evaporation the surface sustains.
    pub wetness: f64,
}

impl SurfaceOptics {
    /// Net flux into the surface (W m⁻²) at temperature `ts` (K), and its derivative, for a
    /// temperature-independent gain `gain` (absorbed shortwave and longwave) under drive `d`.
    #[inline]
    pub fn net_flux(&self, gain: f64, d: &Drive, ts: f64) -> (f64, f64) {
        let ts3 = ts * ts * ts;
        let eps = self.emissivity;
        let mut f = gain - eps * SIGMA * ts3 * ts - d.h * (ts - d.t_air);
        let mut df = -4.0 * eps * SIGMA * ts3 - d.h;
        if self.wetness > 0.0 {
            let (es, des) = saturation_vapour_pressure(ts);
            let k = self.wetness * d.h / GAMMA;
            f -= k * (es - d.vapour_pressure);
            df -= k * des;
        }
        (f, df)
    }
}

/// A facet: its normal, sky-view factor and whether it sees the Sun at each step.
#[derive(Clone, Debug, PartialEq)]
pub struct Facet {
    pub normal: DVec3,
    pub sky_view: f64,
    /// One per step of the day (false where the Sun is down or blocked).
    pub lit: Vec<bool>,
    /// The facet's air is this much warmer than the day's (K; a lapse rate times the height
    /// below the reference altitude).
    pub air_offset: f64,
}

impl Facet {
    /// The drive of step `k` at this facet's height: the air warmer by `air_offset`, the sky's
    /// longwave as from a sky of the same emissivity at that temperature, the vapour pressure
    /// kept.
    pub fn drive(&self, day: &Day, k: usize) -> Drive {
        let d = day.steps[k];
        if self.air_offset == 0.0 {
            return d;
        }
        let t = d.t_air + self.air_offset;
        Drive {
            t_air: t,
            sky_longwave: d.sky_longwave * (t / d.t_air).powi(4),
            ..d
        }
    }

    /// Shortwave irradiance absorbed at step `k` of `day` (W m⁻²).
    pub fn absorbed_shortwave(&self, day: &Day, k: usize, optics: &SurfaceOptics) -> f64 {
        let d = &day.steps[k];
        let cos_i = self.normal.dot(d.sun).max(0.0);
        let beam = if self.lit[k] { d.direct * cos_i } else { 0.0 };
        let global = d.direct * d.sun.z.max(0.0) + d.diffuse;
        (1.0 - optics.albedo)
            * (beam
                + d.diffuse * self.sky_view
                + day.surround_albedo * global * (1.0 - self.sky_view))
    }

    /// Longwave irradiance reaching the facet at step `k` (W m⁻²).
    pub fn incoming_longwave(&self, day: &Day, k: usize) -> f64 {
        self.longwave_under(&self.drive(day, k))
    }

    /// Longwave irradiance reaching the facet under its drive `d` ([`Facet::drive`]), W m⁻².
    fn longwave_under(&self, d: &Drive) -> f64 {
        self.sky_view * d.sky_longwave + (1.0 - self.sky_view) * SIGMA * d.t_air.powi(4)
    }
}

/// The periodic day of one facet: surface temperatures at each step's end (K), the budget of
/// the last day, and how many days it took.
#[derive(Clone, Debug)]
pub struct PeriodicDay {
    pub surface: Vec<f64>,
    pub budget: Budget,
    pub days: usize,
    /// Whether the day-to-day change fell below the tolerance within the allowed days.
    pub converged: bool,
}

/// Repeat `day` on `slab` (started at the day's mean air temperature) until the surface
/// temperature at the day's end changes by less than `tol` K from one day to the next, at most
/// `max_days` days; returns the last day.
pub fn periodic_day(
    slab: &mut Slab,
    day: &Day,
    facet: &Facet,
    optics: &SurfaceOptics,
    tol: f64,
    max_days: usize,
) -> PeriodicDay {
    let n = day.steps.len();
    let eps = optics.emissivity;
    let drives: Vec<Drive> = (0..n).map(|k| facet.drive(day, k)).collect();
    // What each step gains whatever the surface temperature.
    let gain: Vec<f64> = drives
        .iter()
        .enumerate()
        .map(|(k, d)| facet.absorbed_shortwave(day, k, optics) + eps * facet.longwave_under(d))
        .collect();
    // Start at the temperature whose day-mean balance is zero (with an adiabatic bottom the
    // periodic day's mean profile is close to uniform there): the deep nodes then need days,
    // not weeks, to settle.
    let start = equilibrium(facet, day, &drives, &gain, optics);
    slab.fill(start.min(slab.melting_point.unwrap_or(f64::INFINITY)));
    let mut surface = vec![0.0; n];
    let mut previous_end = f64::NAN;
    let mut budget = Budget::default();
    let mut days = 0;
    let mut converged = false;
    while days < max_days.max(1) {
        budget = Budget::default();
        for (k, (g, d)) in gain.iter().zip(&drives).enumerate() {
            budget += slab.step(day.dt, |ts| optics.net_flux(*g, d, ts));
            surface[k] = slab.surface();
        }
        days += 1;
        let end = surface[n - 1];
        if (end - previous_end).abs() < tol {
            converged = true;
            break;
        }
        previous_end = end;
    }
    PeriodicDay {
        surface,
        budget,
        days,
        converged,
    }
}

/// The constant surface temperature (K) at which the day's mean net flux is zero under the
/// facet's `drives` and `gain`s (Newton from the day's mean air temperature at the facet).
fn equilibrium(
    facet: &Facet,
    day: &Day,
    drives: &[Drive],
    gain: &[f64],
    optics: &SurfaceOptics,
) -> f64 {
    let n = gain.len() as f64;
    let mut t = day.steps.iter().map(|d| d.t_air).sum::<f64>() / n + facet.air_offset;
    for _ in 0..50 {
        let (mut f, mut df) = (0.0, 0.0);
        for (g, d) in gain.iter().zip(drives) {
            let (a, b) = optics.net_flux(*g, d, t);
            f += a;
            df += b;
        }
        let step = f / df;
        t = (t - step).clamp(150.0, 400.0);
        if step.abs() < 1e-6 {
            break;
        }
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::temperature::slab::{Bottom, Layer};
    use std::f64::consts::{PI, TAU};

    fn day(steps: usize) -> Day {
        let dt = 86_400.0 / steps as f64;
        Day {
            dt,
            surround_albedo: 0.2,
            steps: (0..steps)
                .map(|k| {
                    // Sun rising at 6 h, setting at 18 h, 60° high at noon, in the south.
                    let hour = (k + 1) as f64 * dt / 3600.0;
                    let elev = (60f64.to_radians()) * ((hour - 6.0) / 12.0 * PI).sin();
                    let sun = DVec3::new(0.0, -elev.cos(), elev.sin()).normalize();
                    let up = elev > 0.0;
                    let t_air = 293.0 + 5.0 * ((hour - 15.0) / 24.0 * TAU).cos();
                    let (direct, diffuse) = if up { (850.0, 100.0) } else { (0.0, 0.0) };
                    Drive::new(sun, direct, diffuse, t_air, 0.6, 2.0)
                })
                .collect(),
        }
    }

    fn asphalt() -> Vec<Layer> {
        vec![
            Layer {
                thickness_m: 0.1,
                conductivity: 0.75,
                density: 2360.0,
                heat_capacity: 920.0,
            },
            Layer {
                thickness_m: 0.9,
                conductivity: 1.0,
                density: 1800.0,
                heat_capacity: 1100.0,
            },
        ]
    }

    #[test]
    fn brutsaert_emissivity_and_convection_have_their_published_values() {
        // 20 °C, 50 %: e_a = 11.7 hPa → ε_a = 1.24·(11.7/293.15)^{1/7} ≈ 0.784.
        let e = sky_emissivity(293.15, 0.5);
        assert!((e - 0.784).abs() < 0.003, "{e}");
        assert_eq!(convection(0.0), 5.7);
        // Magnus: 2.3388 kPa at 20 °C in the WMO tables (Magnus within 0.4 % over
        // −40…50 °C), its slope 0.1448 kPa/K.
        let (e, de) = saturation_vapour_pressure(293.15);
        assert!(
            (e / 2.3388 - 1.0).abs() < 0.004 && (de / 0.1448 - 1.0).abs() < 0.004,
            "{e} {de}"
        );
        assert!((convection(2.0) - 13.3).abs() < 1e-12);
    }

    #[test]
    fn a_shaded_facet_is_cooler_by_what_its_missing_sunlight_predicts() {
        let d = day(144);
        let optics = SurfaceOptics {
            albedo: 0.1,
            emissivity: 0.95,
            wetness: 0.0,
        };
        let lit = |on: bool| Facet {
            normal: DVec3::Z,
            sky_view: 1.0,
            lit: d.steps.iter().map(|s| on && s.sun.z > 0.0).collect(),
            air_offset: 0.0,
        };
        let run = |f: &Facet| {
            let mut slab = Slab::new(&asphalt(), 0.002, 1.15, Bottom::Adiabatic, 290.0).unwrap();
            periodic_day(&mut slab, &d, f, &optics, 1e-3, 60)
        };
        let (sunny, shaded) = (run(&lit(true)), run(&lit(false)));
        assert!(sunny.converged && shaded.converged);
        // The difference is the response of the linearised balance to the missing beam: a
        // linear system, so the difference of the two runs equals a run driven by the beam
        // alone with the balance linearised about the shaded temperatures, to second order.
        let noon = 72 - 1;
        let diff = sunny.surface[noon] - shaded.surface[noon];
        assert!(diff > 10.0, "sunlit − shaded at noon: {diff} K");
        // Daily means: with an adiabatic bottom all absorbed energy leaves through the
        // surface, so ⟨ΔS⟩ = ⟨Δ(εσT⁴) + hΔT⟩ over the day, exactly (periodic state).
        let n = d.steps.len();
        let (mut ds, mut dloss) = (0.0, 0.0);
        let shaded_f = lit(false);
        let sunny_f = lit(true);
        for k in 0..n {
            ds += sunny_f.absorbed_shortwave(&d, k, &optics)
                - shaded_f.absorbed_shortwave(&d, k, &optics);
            let loss = |t: f64| optics.emissivity * SIGMA * t.powi(4) + d.steps[k].h * t;
            dloss += loss(sunny.surface[k]) - loss(shaded.surface[k]);
        }
        assert!(
            (ds - dloss).abs() < 2e-3 * ds,
            "absorbed difference {ds} vs loss difference {dloss} (sums over steps)"
        );
    }

    #[test]
    fn the_periodic_day_closes_its_heat_budget() {
        let d = day(144);
        let optics = SurfaceOptics {
            albedo: 0.2,
            emissivity: 0.9,
            wetness: 0.3,
        };
        let f = Facet {
            normal: DVec3::new(0.3, -0.2, 0.9).normalize(),
            sky_view: 0.8,
            lit: d.steps.iter().map(|s| s.sun.z > 0.0).collect(),
            air_offset: -1.5,
        };
        let mut slab = Slab::new(&asphalt(), 0.002, 1.15, Bottom::Fixed(291.0), 290.0).unwrap();
        let p = periodic_day(&mut slab, &d, &f, &optics, 1e-4, 200);
        assert!(p.converged, "{} days", p.days);
        let b = p.budget;
        // Periodic: the heat stored over the day is below 0.1 % of the day's gross absorbed
        // shortwave, and what the surface lets in equals what is stored plus what leaves at
        // the bottom, to rounding.
        let gross: f64 = (0..d.steps.len())
            .map(|k| f.absorbed_shortwave(&d, k, &optics) * d.dt)
            .sum();
        assert!(b.stored.abs() < 1e-3 * gross, "{b:?}, gross {gross}");
        assert!(
            (b.surface_in + b.bottom_in - b.stored).abs() < 1e-9 * gross,
            "{b:?}"
        );
    }
}
