//! Spherical shells over the ground sphere, in planet-centred coordinates (m).
//!
//! Flights cross shells exactly ([`SphericalShell::fly`]); the Sun's transmittance to a point
//! is the exact chord sum through the shells, zero when the Sun is below the local horizon of
//! the ray (Earth's shadow), so points lit at twilight (SZA > 90° at the target) are handled.
//! The expected estimate of a flight's next collision has no closed form here: it is estimated
//! from [`NEE_STRATA`](super::NEE_STRATA) stratified collision points
//! (`super::stratified_estimate`). The ground's normal is the local
//! vertical; BRDFs are evaluated in its frame.

use glam::DVec3;

use super::{stratified_estimate, Event, Geometry, Light, Split};
use crate::atmosphere::spherical::{ShellEnd, SphericalShell};
use crate::bsdf::Bsdf;
use crate::frame::Frame;
use crate::integrator::surface::SurfaceAt;
use crate::integrator::weight::Weight;
use crate::rng::Stream;

pub struct Shells<'a> {
    pub shell: &'a SphericalShell,
    pub surface: &'a Bsdf,
    /// Unit vector towards the Sun, planet frame.
    pub sun: DVec3,
    /// cos SZA at the target (1 when the Sun is down): normalises samples to BRF.
    pub mu_norm: f64,
    /// The ground's radiometry solver.
    pub solver: crate::integrator::solver::SolverSpec,
    /// The ground's thermal emission, if any.
    pub surface_emission: Option<&'a crate::bsdf::SurfaceEmission>,
    /// Whether the Sun shines (false: thermal emission only).
    pub shines: bool,
}

impl<W: Weight> Geometry<W> for Shells<'_> {
    type Pos = (DVec3, usize);
    /// The ground point.
    type Hit = DVec3;

    fn light(&self) -> Light {
        Light::new(self.sun, self.mu_norm)
    }

    #[inline]
    fn sun_shines(&self) -> bool {
        self.shines
    }

    /// The shells' emission over the flight ([`SphericalShell::emission_along`], one random
    /// number) plus, where the flight reaches the ground, its `ε(μ)·B(T_s)` times the
    /// transmittance (μ against the local vertical).
    fn flight_emission(&self, (p, l): (DVec3, usize), d: DVec3, _: &W, rng: &mut Stream) -> f64 {
        let shell = self.shell;
        if !shell.emits() && self.surface_emission.is_none() {
            return 0.0;
        }
        let (mut e, t_ground) = shell.emission_along(p, l, d, rng.next_f64());
        if let (Some(s), Some(t)) = (self.surface_emission, t_ground) {
            // The ground point: where the ray meets the ground sphere.
            let r0 = shell.ground_radius();
            let b = p.dot(d);
            let disc = b * b - (p.length_squared() - r0 * r0);
            if disc > 0.0 {
                let q = p + d * (-b - disc.sqrt()).max(0.0);
                let mu = -d.dot(q / q.length());
                if mu > 0.0 {
                    e += t * s.radiance(mu);
                }
            }
        }
        e
    }

    #[inline]
    fn flight(
        &self,
        (p, l): (DVec3, usize),
        d: DVec3,
        _: &mut W,
        acc: Option<&mut W::Phase>,
        rng: &mut Stream,
    ) -> Event<'_, (DVec3, usize), DVec3> {
        let shell = self.shell;
        if let Some(acc) = acc {
            let tau_exit = shell.optical_depth_within(p, l, d, f64::INFINITY);
            let seen = |q: DVec3, lq: usize| shell.transmittance_to_space(q, lq, self.sun);
            stratified_estimate::<W>(shell, p, l, d, tau_exit, self.sun, acc, rng, seen);
        }
        let s = -rng.next_f64_open0().ln();
        match shell.fly(p, l, d, s) {
            ShellEnd::Escape => Event::Escape,
            ShellEnd::Surface(q) => Event::Surface(q),
            ShellEnd::Collision(q, lq) => Event::Collision {
                pos: (q, lq),
                omega: shell.albedo(lq),
                phase: shell.phase(lq),
            },
        }
    }

    /// The collision probability is `1 − e^{−τ}` over the whole flight (to the ground or to
    /// space); the forced collision's optical path is drawn from the truncated exponential and
    /// flown; the uncollided end is the same flight with an infinite optical path.
    fn flight_split(
        &self,
        (p, l): (DVec3, usize),
        d: DVec3,
        _: &mut W,
        acc: Option<&mut W::Phase>,
        rng: &mut Stream,
    ) -> Option<Split<'_, (DVec3, usize), DVec3>> {
        let shell = self.shell;
        let tau_exit = shell.optical_depth_within(p, l, d, f64::INFINITY);
        let seen = |q: DVec3, lq: usize| shell.transmittance_to_space(q, lq, self.sun);
        let end = || match shell.fly(p, l, d, f64::INFINITY) {
            ShellEnd::Surface(g) => Event::Surface(g),
            _ => Event::Escape,
        };
        split_flight::<W, _>(shell, (p, l), d, tau_exit, self.sun, seen, end, acc, rng)
    }

    #[inline]
    fn sun_at(&self, (p, l): (DVec3, usize)) -> f64 {
        self.shell.transmittance_to_space(p, l, self.sun)
    }
    #[inline]
    fn surface(&self, q: &DVec3) -> SurfaceAt<'_> {
        SurfaceAt::Flat {
            bsdf: self.surface,
            frame: Some(Frame::around(*q / q.length())),
        }
    }
    #[inline]
    fn sun_at_surface(&self, q: &DVec3) -> f64 {
        if self.sun.dot(*q) > 0.0 {
            self.shell.transmittance_to_space(*q, 0, self.sun)
        } else {
            0.0
        }
    }
    #[inline]
    fn leave(&self, q: &DVec3, _: DVec3) -> (DVec3, usize) {
        (*q, 0)
    }
    #[inline]
    fn solver(&self, _: &Self::Hit) -> crate::integrator::solver::SolverSpec {
        self.solver
    }
}

/// The split of a flight in shells (from `p` in shell `l` along `d`, optical depth `tau_end` to
/// its end): `None` where it cannot collide; else the flight's expected next-event estimate
/// (`stratified_estimate`, with `seen` the Sun's transmittance and visibility at a point), then
/// the forced collision, its optical path drawn from the truncated exponential and flown, and the
/// uncollided branch's event `end()`. The collided branch's probability is `1 − e^{−tau_end}`, or
/// 0 where no collision can be placed (a vanishing optical depth; the split cannot be undone once
/// `acc` and `rng` are used). Serves [`Shells`] and `SceneInShells` (truncated at the scene hit).
#[allow(clippy::too_many_arguments)]
pub(super) fn split_flight<'a, W: Weight, H>(
    shell: &'a SphericalShell,
    (p, l): (DVec3, usize),
    d: DVec3,
    tau_end: f64,
    sun: DVec3,
    seen: impl Fn(DVec3, usize) -> f64,
    end: impl FnOnce() -> Event<'a, (DVec3, usize), H>,
    acc: Option<&mut W::Phase>,
    rng: &mut Stream,
) -> Option<Split<'a, (DVec3, usize), H>> {
    let p_coll = -(-tau_end).exp_m1();
    if p_coll.is_nan() || p_coll <= 0.0 {
        return None;
    }
    if let Some(acc) = acc {
        stratified_estimate::<W>(shell, p, l, d, tau_end, sun, acc, rng, seen);
    }
    let mut s = -(-rng.next_f64() * p_coll).ln_1p();
    // Rounding may carry `s` just past the flight's optical depth: pull it back inside.
    let mut collision = None;
    for _ in 0..8 {
        if s < tau_end {
            if let ShellEnd::Collision(q, lq) = shell.fly(p, l, d, s) {
                collision = Some((q, lq));
                break;
            }
        }
        s = s.min(tau_end) * (1.0 - 1e-9);
    }
    let (p_collision, (q, lq)) = match collision {
        Some(c) => (p_coll, c),
        None => (0.0, (p, l)),
    };
    Some(Split {
        p_collision,
        collision: Event::Collision {
            pos: (q, lq),
            omega: shell.albedo(lq),
            phase: shell.phase(lq),
        },
        end: end(),
    })
}
