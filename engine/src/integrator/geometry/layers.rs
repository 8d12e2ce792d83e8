//! Plane-parallel layers over a flat surface; positions are optical depths τ from TOA.
//!
//! Flights are sampled exactly ([`PlaneParallel::fly`]); the Sun's transmittance to depth τ is
//! `exp(−τ/μ_s)`; the expected estimate of a flight's next collision is integrated exactly,
//! layer by layer ([`PlaneParallel::flight_integrals`]: Marchuk et al. 1980, ch. 2). Thermal
//! emission of the layers and the surface is gathered in expectation at every flight
//! ([`PlaneParallel::expected_emission`], the ground's `ε·B(T_s)·e^{−Δτ/|μ|}`).

use glam::DVec3;

use super::{Event, Geometry, Light, Split};
use crate::atmosphere::{FlightEnd, PlaneParallel};
use crate::bsdf::{Bsdf, SurfaceEmission};
use crate::integrator::surface::SurfaceAt;
use crate::integrator::weight::Weight;
use crate::rng::Stream;

pub struct Layers<'a> {
    atmosphere: &'a PlaneParallel,
    surface: &'a Bsdf,
    /// Unit vector towards the Sun (`z > 0`).
    sun: DVec3,
    /// The Sun's transmittance to the ground, `exp(−τ*/μ_s)`.
    t_sun_ground: f64,
    /// Whether the Sun shines (false: thermal emission only).
    shines: bool,
    /// The surface's thermal emission, if any.
    surface_emission: Option<&'a SurfaceEmission>,
    /// The surface's radiometry solver.
    solver: crate::integrator::solver::SolverSpec,
    /// A `mirror` surface: the Sun's image below it, as (unit vector towards the image,
    /// `R(μ_s)·e^{−2τ*/μ_s}`): the specularly reflected beam lights the layers from below with
    /// transmittance `R·e^{−(2τ* − τ)/μ_s}` at depth τ. Next-event estimates add it, since no
    /// sampled direction meets a delta-reflected beam.
    image_sun: Option<(DVec3, f64)>,
}

impl<'a> Layers<'a> {
    pub fn new(atmosphere: &'a PlaneParallel, surface: &'a Bsdf, sun: DVec3) -> Self {
        Layers {
            atmosphere,
            surface,
            sun,
            t_sun_ground: (-atmosphere.total_tau() / sun.z).exp(),
            shines: true,
            surface_emission: None,
            solver: Default::default(),
            image_sun: None,
        }
    }

    /// With the surface's radiometry solver (`solver.rs`).
    pub fn with_solver(mut self, solver: crate::integrator::solver::SolverSpec) -> Self {
        self.solver = solver;
        if let crate::integrator::solver::SolverSpec::Mirror {
            refractive_index,
            absorption_index,
        } = solver
        {
            let mu = self.sun.z;
            let r = crate::integrator::solver::fresnel_reflectance(
                refractive_index,
                absorption_index,
                mu,
            );
            let k = r * (-2.0 * self.atmosphere.total_tau() / mu).exp();
            self.image_sun = Some((DVec3::new(self.sun.x, self.sun.y, -self.sun.z), k));
        }
        self
    }

    /// With thermal emission: the surface's (`None`: it does not emit), and whether the Sun
    /// shines as well.
    pub fn with_emission(
        mut self,
        surface_emission: Option<&'a SurfaceEmission>,
        shines: bool,
    ) -> Self {
        self.surface_emission = surface_emission;
        self.shines = shines;
        self
    }
}

impl Layers<'_> {
    /// Add the flight's expected next-event estimate to `acc` (exact, layer by layer; the
    /// mirror image of the Sun too).
    #[inline]
    fn expected<W: Weight>(&self, tau: f64, d: DVec3, acc: Option<&mut W::Phase>) {
        let atm = self.atmosphere;
        if let Some(acc) = acc {
            let cos = self.sun.dot(d);
            atm.flight_integrals(tau, d.z, 1.0 / self.sun.z, |l, i| {
                W::accumulate(acc, atm.phase(l), cos, atm.albedo(l), i);
            });
            if let Some((image, k)) = self.image_sun {
                // Transmittance k·e^{+τ/μ_s}: b = −1/μ_s.
                let cos = image.dot(d);
                atm.flight_integrals(tau, d.z, -1.0 / self.sun.z, |l, i| {
                    W::accumulate(acc, atm.phase(l), cos, atm.albedo(l), k * i);
                });
            }
        }
    }

    /// A collision at optical depth `t`.
    #[inline]
    fn collision(&self, t: f64) -> Event<'_, f64, ()> {
        let layer = self.atmosphere.layer_at_tau(t);
        Event::Collision {
            pos: t,
            omega: self.atmosphere.albedo(layer),
            phase: self.atmosphere.phase(layer),
        }
    }
}

impl<W: Weight> Geometry<W> for Layers<'_> {
    type Pos = f64;
    type Hit = ();

    fn light(&self) -> Light {
        Light::new(self.sun, self.sun.z)
    }

    #[inline]
    fn flight(
        &self,
        tau: f64,
        d: DVec3,
        _: &mut W,
        acc: Option<&mut W::Phase>,
        rng: &mut Stream,
    ) -> Event<'_, f64, ()> {
        self.expected::<W>(tau, d, acc);
        let s = -rng.next_f64_open0().ln();
        match self.atmosphere.fly(tau, d.z, s) {
            FlightEnd::Escape => Event::Escape,
            FlightEnd::Surface => Event::Surface(()),
            FlightEnd::Collision(t) => self.collision(t),
        }
    }

    /// The collision probability is `1 − e^{−Δτ/|μ|}` to the boundary the flight heads for; the
    /// forced collision's optical path is drawn from the truncated exponential.
    #[inline]
    fn flight_split(
        &self,
        tau: f64,
        d: DVec3,
        _: &mut W,
        acc: Option<&mut W::Phase>,
        rng: &mut Stream,
    ) -> Option<Split<'_, f64, ()>> {
        let atm = self.atmosphere;
        if d.z.abs() < 1e-6 {
            return None;
        }
        let (dtau, end) = if d.z < 0.0 {
            (atm.total_tau() - tau, Event::Surface(()))
        } else {
            (tau, Event::Escape)
        };
        // P(collision) = 1 − e^{−s_end}, s_end the optical path to the boundary.
        let p = -(-dtau / d.z.abs()).exp_m1();
        if p.is_nan() || p <= 0.0 {
            return None;
        }
        self.expected::<W>(tau, d, acc);
        let s = -(-rng.next_f64() * p).ln_1p();
        match atm.fly(tau, d.z, s) {
            FlightEnd::Collision(t) => Some(Split {
                p_collision: p,
                collision: self.collision(t),
                end,
            }),
            // Rounding at the boundary: the forced collision sits on it.
            _ => Some(Split {
                p_collision: p,
                collision: self.collision(if d.z < 0.0 {
                    atm.total_tau() * (1.0 - 1e-15)
                } else {
                    atm.total_tau() * 1e-15
                }),
                end,
            }),
        }
    }

    #[inline]
    fn sun_shines(&self) -> bool {
        self.shines
    }

    #[inline]
    fn flight_emission(&self, tau: f64, d: DVec3, _: &W, _: &mut Stream) -> f64 {
        let atm = self.atmosphere;
        let mut e = atm.expected_emission(tau, d.z);
        if let Some(s) = self.surface_emission {
            if d.z < 0.0 {
                // Reaching the ground: transmittance from tau along d.
                let t = if d.z.abs() < 1e-12 {
                    0.0
                } else {
                    ((atm.total_tau() - tau) / d.z).exp()
                };
                e += t * s.radiance(-d.z);
            }
        }
        e
    }

    #[inline]
    fn sun_at(&self, tau: f64) -> f64 {
        (-tau / self.sun.z).exp()
    }

    fn collision_estimate(
        &self,
        tau: f64,
        omega: f64,
        phase: &crate::phase::PhaseFunction,
        d: DVec3,
        _w: &mut W,
        acc: &mut W::Phase,
    ) {
        W::accumulate(
            acc,
            phase,
            self.sun.dot(d),
            omega,
            (-tau / self.sun.z).exp(),
        );
        if let Some((image, k)) = self.image_sun {
            W::accumulate(
                acc,
                phase,
                image.dot(d),
                omega,
                k * (tau / self.sun.z).exp(),
            );
        }
    }
    #[inline]
    fn surface(&self, _: &()) -> SurfaceAt<'_> {
        SurfaceAt::Flat {
            bsdf: self.surface,
            frame: None,
        }
    }
    #[inline]
    fn sun_at_surface(&self, _: &()) -> f64 {
        self.t_sun_ground
    }
    #[inline]
    fn leave(&self, _: &(), _: DVec3) -> f64 {
        self.atmosphere.total_tau()
    }
    #[inline]
    fn solver(&self, _: &Self::Hit) -> crate::integrator::solver::SolverSpec {
        self.solver
    }
}
