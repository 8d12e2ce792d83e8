//! Backward walk through a 3D scene inside a spherical-shell atmosphere.
//!
//! The scene has been bent onto the planet when it was built ([`crate::scene::curvature`]):
//! its coordinates are the planet-centred frame of [`SphericalShell`] shifted by the planet
//! radius R along z, so a path is one straight line in both and no mapping is needed beyond
//! adding or removing `(0, 0, R)`. Positions here are planet-centred (m, f64); the scene is
//! queried at `p − (0, 0, R)`.
//!
//! The walk is [`scene_walk`](super::scene_walk) with the spherical shell's transport
//! ([`backward_sph`](super::backward_sph)):
//!
//! 1. at the start of each flight the scene is queried for its closest hit (terrain, objects,
//!    the background sphere); the optical depth τ_e of the flight up to that hit, or to where
//!    it leaves the atmosphere, is summed exactly shell by shell;
//! 2. an optical path `s` is drawn; `s < τ_e` is a collision in the atmosphere
//!    ([`SphericalShell::fly`]), else the path reaches the surface hit (or leaves: through the
//!    top, or into the atmosphere's ground sphere outside all geometry, then it is lost, as in
//!    the plane-parallel scene walk);
//! 3. next-event estimates towards the Sun use the exact chord transmittance through the shells
//!    (zero in the Earth's shadow) times the scene's visibility `V` (a shadow ray; rays from
//!    above the scene's top going up skip it);
//! 4. with `local_estimate = "expected"` the atmospheric estimate of each flight is its
//!    expectation over the collision point, estimated from `NEE_STRATA` points stratified in
//!    the collision's optical path and restricted to the flight before its surface hit
//!    (weights P(collision before the hit)/K), each with its shadow ray: unbiased, as in
//!    [`backward_sph`](super::backward_sph); `"collision"` scores at the sampled collision.
//!
//! A sample is `π·L/E0` divided by `mu_norm` (cos SZA at the scene's origin), like the 1D
//! spherical walk; orders are split into single (first interaction) and multiple.
//!
//! Validation (`tests/scene_spherical.rs`): a flat one-material bundle with the same
//! background is a uniform sphere and equals the 1D spherical walk at every solar zenith angle.

use glam::DVec3;

use super::backward_sph::stratified_estimate;
use super::scene_walk::surface_model;
use super::{roulette, sample_scattered, OrderSplit};
use crate::atmosphere::spherical::{ShellEnd, SphericalShell};
use super::settings::IntegratorSettings;
use crate::rng::Stream;
use crate::scene::material::SurfaceModel;
use crate::scene::Scene;

/// Everything a walk needs at one wavelength.
pub struct SphereSceneContext<'a> {
    pub shell: &'a SphericalShell,
    /// A scene bent onto the shell's planet (`scene.curvature` is the planet radius).
    pub scene: &'a Scene,
    /// Material models at this wavelength, indexed by material id.
    pub models: &'a [SurfaceModel],
    /// Unit vector towards the Sun, planet frame.
    pub sun: DVec3,
    /// cos SZA at the scene's origin (normalises samples to BRF).
    pub mu_norm: f64,
    /// nm (for reflectance textures).
    pub wavelength: f64,
}

impl SphereSceneContext<'_> {
    /// The planet frame's offset of the scene frame: `p_scene = p − lift`.
    #[inline]
    fn lift(&self) -> DVec3 {
        DVec3::new(0.0, 0.0, self.shell.planet_radius)
    }

    /// Direct solar transmittance times the scene's visibility from planet point `p` (shell
    /// `l`).
    #[inline]
    fn sun_seen(&self, p: DVec3, l: usize) -> f64 {
        let t = self.shell.transmittance_to_space(p, l, self.sun);
        if t > 0.0
            && self
                .scene
                .occluded(p - self.lift(), self.sun, f64::INFINITY)
        {
            0.0
        } else {
            t
        }
    }

    /// Shell of a planet point reached through the scene (clamped to the atmosphere).
    #[inline]
    fn shell_of(&self, p: DVec3) -> usize {
        self.shell
            .shell_at(p.length())
            .min(self.shell.shell_count() - 1)
    }
}

/// One path from planet point `p0` (in shell `l0`) along unit `d0`; returns the (single,
/// multiple) parts of `π·L/(E0·mu_norm)`.
pub fn walk(
    ctx: &SphereSceneContext,
    p0: DVec3,
    l0: usize,
    d0: DVec3,
    settings: &IntegratorSettings,
    rng: &mut Stream,
) -> (f64, f64) {
    let shell = ctx.shell;
    let scene = ctx.scene;
    let sun = ctx.sun;
    let lift = ctx.lift();
    let inv_4pi = 0.25 * std::f64::consts::FRAC_1_PI;
    let mut split = OrderSplit::default();
    let (mut p, mut l, mut d) = (p0, l0, d0);
    let mut w = 1.0_f64;
    let mut order: u32 = 1;
    while order <= settings.max_depth {
        let hit = scene.intersect(p - lift, d, f64::INFINITY);
        let t_hit = hit.map_or(f64::INFINITY, |h| h.t);
        let tau_end = shell.optical_depth_within(p, l, d, t_hit);
        let mut score = 0.0;
        if settings.expected_local_estimate {
            let seen = |q: DVec3, lq: usize| ctx.sun_seen(q, lq);
            score += stratified_estimate(shell, p, l, d, tau_end, sun, w, rng, seen);
        }
        let s = -rng.next_f64_open0().ln();
        let collision = if s < tau_end {
            match shell.fly(p, l, d, s) {
                ShellEnd::Collision(q, lq) => Some((q, lq)),
                // Rounding at the very end of the flight: treat as reaching its end.
                _ => None,
            }
        } else {
            None
        };
        if let Some((q, lq)) = collision {
            p = q;
            l = lq;
            let omega = shell.albedo(l);
            let phase = shell.phase(l);
            if !settings.expected_local_estimate {
                let f = omega * phase.eval(sun.dot(d)) * inv_4pi;
                if f > 0.0 {
                    score += w * f * ctx.sun_seen(p, l);
                }
            }
            w *= omega;
            d = sample_scattered(phase, d, rng);
        } else if let Some(h) = hit {
            let model = surface_model(scene, ctx.models, ctx.wavelength, &h);
            let model = model.as_ref();
            let wo = -d;
            let n = h.normal;
            let f = model.eval_cos(n, sun, wo);
            if f > 0.0 {
                let start = scene.offset(h.point, n, sun);
                let q = start + lift;
                score += w * f * ctx.sun_seen(q, ctx.shell_of(q));
            }
            match model.sample(n, wo, [rng.next_f64(), rng.next_f64(), rng.next_f64()]) {
                Some(smp) => {
                    w *= smp.weight;
                    d = smp.wi;
                    p = scene.offset(h.point, n, d) + lift;
                    l = ctx.shell_of(p);
                }
                None => w = 0.0,
            }
        } else {
            // Leaves through the top, or into the ground sphere outside all geometry (lost).
            split.add(order, score);
            break;
        }
        split.add(order, score);
        order += 1;
        if w <= 0.0 {
            break;
        }
        if order > settings.rr_depth && !roulette(&mut w, rng.next_f64()) {
            break;
        }
    }
    split.scaled(std::f64::consts::PI / ctx.mu_norm)
}
