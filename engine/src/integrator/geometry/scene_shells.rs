//! A 3D scene inside spherical shells.
//!
//! The scene has been bent onto the planet when it was built ([`crate::scene::curvature`]):
//! its coordinates are the planet-centred frame of [`SphericalShell`] shifted by the planet
//! radius R along z, so a path is one straight line in both and no mapping is needed beyond
//! adding or removing `(0, 0, R)`. Positions here are planet-centred (m, f64); the scene is
//! queried at `p − (0, 0, R)`. Each flight:
//!
//! 1. queries the scene for its closest hit (terrain, objects, the background sphere); the
//!    optical depth τ_e of the flight up to that hit, or to where it leaves the atmosphere, is
//!    summed exactly shell by shell;
//! 2. draws an optical path `s`; `s < τ_e` is a collision in the atmosphere
//!    ([`SphericalShell::fly`]), else the path reaches the hit (or leaves: through the top, or
//!    into the ground sphere outside all geometry, then it is lost, as under plane layers);
//! 3. next-event estimates use the exact chord transmittance through the shells (zero in the
//!    Earth's shadow) times the scene's visibility (a shadow ray).
//!
//! The expected estimate of a flight's next collision uses
//! [`NEE_STRATA`](super::NEE_STRATA) stratified collision points restricted to the flight before
//! its surface hit, each with its shadow ray, as in [`shells`](super::shells).
//!
//! Validation (`tests/scene_spherical.rs`): a flat one-material bundle with the same background
//! is a uniform sphere and equals the 1D spherical walk at every solar zenith angle.

use glam::DVec3;

use super::scene_layers::{mirror_reflectance, scene_surface};
use super::shells::split_flight;
use super::{stratified_estimate, Event, Geometry, Light, Split};
use crate::atmosphere::spherical::{ShellEnd, SphericalShell};
use crate::integrator::surface::SurfaceAt;
use crate::integrator::weight::Weight;
use crate::rng::Stream;
use crate::scene::material::SurfaceModel;
use crate::scene::{Scene, SurfaceHit};

pub struct SceneInShells<'a> {
    pub shell: &'a SphericalShell,
    /// A scene bent onto the shell's planet (`scene.curvature` is the planet radius).
    pub scene: &'a Scene,
    /// Material models at this wavelength, indexed by material id.
    pub models: &'a [SurfaceModel],
    /// Unit vector towards the Sun, planet frame.
    pub sun: DVec3,
    /// The scene's [`SunClearance`](crate::scene::sun_clearance::SunClearance) map for `sun`
    /// (`Scene::sun_clearance`, in the bent scene's frame): shadow rays from points above it
    /// are not cast.
    pub clearance: Option<std::sync::Arc<crate::scene::sun_clearance::SunClearance>>,
    /// cos SZA at the scene's origin (normalises samples to BRF), or 1 with the Sun below the
    /// horizon there (twilight: radiances only).
    pub mu_norm: f64,
    /// nm (for reflectance textures).
    pub wavelength: f64,
    /// The surfaces' thermal emission (`emission = true`; the shells' sources are in `shell`).
    pub emission: Option<&'a crate::scene::emission::SceneEmission>,
    /// Whether the Sun shines (false: thermal emission only).
    pub shines: bool,
}

impl SceneInShells<'_> {
    /// The planet frame's offset of the scene frame: `p_scene = p − lift`.
    #[inline]
    pub fn lift(&self) -> DVec3 {
        DVec3::new(0.0, 0.0, self.shell.planet_radius)
    }

    /// Direct solar transmittance times the scene's visibility from planet point `p` (shell
    /// `l`).
    #[inline]
    fn sun_seen(&self, p: DVec3, l: usize) -> f64 {
        let t = self.shell.transmittance_to_space(p, l, self.sun);
        let q = p - self.lift();
        if t <= 0.0 || self.clearance.as_ref().is_some_and(|c| c.clear(q)) {
            t
        } else {
            t * self
                .scene
                .visibility(q, self.sun, f64::INFINITY, self.models)
        }
    }

    /// The flight's first scene hit and its optical depth up to it (or to where it leaves the
    /// atmosphere).
    #[inline]
    fn to_hit(&self, p: DVec3, l: usize, d: DVec3) -> (Option<SurfaceHit>, f64) {
        let hit = self.scene.intersect(p - self.lift(), d, f64::INFINITY);
        let t_hit = hit.map_or(f64::INFINITY, |h| h.t);
        (hit, self.shell.optical_depth_within(p, l, d, t_hit))
    }

    /// Shell of a planet point reached through the scene (clamped to the atmosphere).
    #[inline]
    fn shell_of(&self, p: DVec3) -> usize {
        self.shell
            .shell_at(p.length())
            .min(self.shell.shell_count() - 1)
    }
}

impl<W: Weight> Geometry<W> for SceneInShells<'_> {
    type Pos = (DVec3, usize);
    type Hit = SurfaceHit;

    fn light(&self) -> Light {
        Light::new(self.sun, self.mu_norm)
    }

    #[inline]
    fn sun_shines(&self) -> bool {
        self.shines
    }

    /// The shells' emission up to the first hit ([`SphericalShell::emission_within`], one
    /// random number) plus the hit surface's emission times the transmittance to it.
    fn flight_emission(&self, (p, l): (DVec3, usize), d: DVec3, _: &W, rng: &mut Stream) -> f64 {
        let Some(em) = self.emission else {
            return 0.0;
        };
        let hit = self.scene.intersect(p - self.lift(), d, f64::INFINITY);
        let t_hit = hit.map_or(f64::INFINITY, |h| h.t);
        let (e, t) = self.shell.emission_within(p, l, d, rng.next_f64(), t_hit);
        match hit {
            Some(h) => {
                e + t.total
                    * em.radiance(
                        self.scene,
                        &h,
                        -d,
                        crate::integrator::solver::fresnel_reflectance,
                    )
            }
            None => e,
        }
    }

    fn flight(
        &self,
        (p, l): (DVec3, usize),
        d: DVec3,
        _: &mut W,
        acc: Option<&mut W::Phase>,
        rng: &mut Stream,
    ) -> Event<'_, (DVec3, usize), SurfaceHit> {
        let shell = self.shell;
        let (hit, tau_end) = self.to_hit(p, l, d);
        if let Some(acc) = acc {
            let seen = |q: DVec3, lq: usize| self.sun_seen(q, lq);
            stratified_estimate::<W>(shell, p, l, d, tau_end, self.sun, acc, rng, seen);
        }
        let s = -rng.next_f64_open0().ln();
        if s < tau_end {
            // (Rounding at the very end of the flight: treated as reaching its end.)
            if let ShellEnd::Collision(q, lq) = shell.fly(p, l, d, s) {
                return Event::Collision {
                    pos: (q, lq),
                    omega: shell.albedo(lq),
                    phase: shell.phase(lq),
                };
            }
        }
        match hit {
            Some(h) => Event::Surface(h),
            // Leaves through the top, or into the ground sphere outside all geometry (lost).
            None => Event::Escape,
        }
    }

    /// As [`flight`](Self::flight), split: the collision probability `1 − e^{−τ_e}` up to the
    /// scene hit (or the flight's end), the forced collision drawn as in shells
    /// (`shells::split_flight`), the uncollided end the hit or an escape.
    fn flight_split(
        &self,
        (p, l): (DVec3, usize),
        d: DVec3,
        _: &mut W,
        acc: Option<&mut W::Phase>,
        rng: &mut Stream,
    ) -> Option<Split<'_, (DVec3, usize), SurfaceHit>> {
        let (hit, tau_end) = self.to_hit(p, l, d);
        let seen = |q: DVec3, lq: usize| self.sun_seen(q, lq);
        let end = || match hit {
            Some(h) => Event::Surface(h),
            None => Event::Escape,
        };
        split_flight::<W, _>(
            self.shell,
            (p, l),
            d,
            tau_end,
            self.sun,
            seen,
            end,
            acc,
            rng,
        )
    }

    #[inline]
    fn sun_at(&self, (p, l): (DVec3, usize)) -> f64 {
        self.sun_seen(p, l)
    }
    #[inline]
    fn surface(&self, h: &SurfaceHit) -> SurfaceAt<'_> {
        scene_surface(self.scene, self.models, self.wavelength, h)
    }
    #[inline]
    fn sun_at_surface(&self, h: &SurfaceHit) -> f64 {
        let q = self.scene.offset(h.point, h.normal, self.sun) + self.lift();
        self.sun_seen(q, self.shell_of(q))
    }
    #[inline]
    fn leave(&self, h: &SurfaceHit, d: DVec3) -> (DVec3, usize) {
        let p = self.scene.offset(h.point, h.normal, d) + self.lift();
        (p, self.shell_of(p))
    }
    #[inline]
    fn mirror_count(&self) -> usize {
        self.scene.mirror_planes().len()
    }

    fn mirror_image(&self, k: usize) -> Option<DVec3> {
        self.scene.mirror_planes()[k].image(self.sun)
    }

    /// As in plane-parallel layers, with the shells' optical depth along the ray and the Sun's
    /// transmittance and visibility from the mirror point (bent scenes turn no instance, so
    /// their mirror planes are the templates').
    fn sun_via_mirror(&self, h: &SurfaceHit, k: usize, image: DVec3) -> f64 {
        let Some(m) = self.scene.mirror_seen(h, k, image, self.sun) else {
            return 0.0;
        };
        let q = self.scene.offset(m.hit.point, m.hit.normal, self.sun) + self.lift();
        let sun = self.sun_seen(q, self.shell_of(q));
        if sun <= 0.0 {
            return 0.0;
        }
        let p = m.start + self.lift();
        let depth = self
            .shell
            .optical_depth_within(p, self.shell_of(p), image, m.distance);
        mirror_reflectance(self.scene, k, m.cos) * (-depth).exp() * sun
    }
    #[inline]
    fn solver(&self, h: &Self::Hit) -> crate::integrator::solver::SolverSpec {
        self.scene.solver(h.material)
    }
}
