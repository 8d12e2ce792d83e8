//! A 3D scene inside plane-parallel layers with a gridded cloud field
//! ([`PlacedClouds`]) among them.
//!
//! The medium's extinction is the layers' plus the cloud's. A flight's collision is sampled by
//! *competing risks*: one free path through the layers (their exact march, up to the first
//! surface hit) and one through the cloud grid (its exact DDA march, up to the layers'
//! collision or the hit); the nearer wins and the collision takes that medium's albedo and
//! phase function. For independent exponential optical paths this is exact: the first of two
//! Poisson processes is a Poisson process of the summed rate, and each wins in proportion to
//! its local extinction.
//!
//! Next-event estimates carry the cloud's transmittance to the Sun (one DDA per shadow ray) on
//! top of the layers' and the scene's visibility. A flight's expected next-event estimate has
//! two parts, each unbiased: for the layers' collisions, one point forced from their collision
//! density (over the whole flight when it starts below the scene's top, over its part above
//! the top otherwise), weighted by the probability of a layer collision there and by the
//! cloud's transmittance up to the point; for the cloud's collisions and the layers' beyond
//! that part, the collision estimate at the sampled one. (The exact layer integrals
//! [`SceneInLayers`] uses above the scene's top assume a cloud-free path to the Sun.) A flight
//! above the top asks the scene for its closest hit only if it gets below the top without
//! colliding: inside a cloud above the terrain most flights collide first. A field
//! without any extinction runs [`SceneInLayers`] itself, random numbers included, so it gives
//! the clear run bit for bit.

use glam::DVec3;

use super::scene_layers::SceneInLayers;
use super::{Event, Geometry, Light};
use crate::clouds::config::PlacedClouds;
use crate::integrator::surface::SurfaceAt;
use crate::integrator::weight::Weight;
use crate::phase::PhaseFunction;
use crate::rng::Stream;
use crate::scene::SurfaceHit;

pub struct SceneCloudsInLayers<'a> {
    pub base: SceneInLayers<'a>,
    pub clouds: &'a PlacedClouds,
    /// The cloud's phase functions at this wavelength.
    pub phases: &'a [PhaseFunction],
}

impl SceneCloudsInLayers<'_> {
    /// The cloud's transmittance from scene point `p` along `d` (unbounded).
    #[inline]
    fn cloud_t(&self, p: DVec3, d: DVec3) -> f64 {
        let tau = self
            .clouds
            .grid
            .optical_depth(self.clouds.local(p), d, f64::INFINITY);
        (-tau).exp()
    }

    /// Add the forced-point estimate of the layers' collisions on the flight from `p` along
    /// `d` up to `end` (its hit `hit`, if it ends there): one point drawn from the layers'
    /// collision density on it (one random number), scored with the Sun's transmittance (layers,
    /// scene, cloud) and weighted by the probability of a layer collision on the segment and the
    /// cloud's transmittance from `p` to the point.
    fn forced_layer_point<W: Weight>(
        &self,
        p: DVec3,
        d: DVec3,
        end: f64,
        hit: Option<SurfaceHit>,
        acc: &mut W::Phase,
        rng: &mut Stream,
    ) {
        if !self.base.can_split(d) {
            return;
        }
        let Some(f) = self.base.split_ending(p, d, 0.0, hit, end) else {
            return;
        };
        let atm = self.base.atmosphere;
        let t = self.base.forced_distance(p, d, &f, rng);
        let q = p + d * t;
        let l = atm.layer_at_altitude(q.z);
        let omega = atm.albedo(l);
        if omega <= 0.0 {
            return;
        }
        let sun = Geometry::<W>::sun_at(self, q);
        if sun > 0.0 {
            let survive = (-self.clouds.grid.optical_depth(self.clouds.local(p), d, t)).exp();
            W::accumulate(
                acc,
                atm.phase(l),
                self.base.sun.dot(d),
                omega,
                sun * f.p_collision * survive,
            );
        }
    }

    /// A collision in cloud cell `cell` at scene point `q`.
    #[inline]
    fn cloud_collision(&self, q: DVec3, cell: usize) -> Event<'_, DVec3, SurfaceHit> {
        let g = &self.clouds.grid;
        Event::Collision {
            pos: self.base.scene.wrap_point(q),
            omega: f64::from(g.albedo.at(cell)),
            phase: &self.phases[usize::from(g.phase_index.at(cell))],
        }
    }
}

impl<W: Weight> Geometry<W> for SceneCloudsInLayers<'_> {
    type Pos = DVec3;
    type Hit = SurfaceHit;

    fn light(&self) -> Light {
        Geometry::<W>::light(&self.base)
    }

    #[inline]
    fn sun_shines(&self) -> bool {
        self.base.shines
    }

    fn flight(
        &self,
        p: DVec3,
        d: DVec3,
        w: &mut W,
        mut acc: Option<&mut W::Phase>,
        rng: &mut Stream,
    ) -> Event<'_, DVec3, SurfaceHit> {
        // A field without extinction is the clear run's, random numbers included.
        if !self.clouds.any_extinction {
            return Geometry::<W>::flight(&self.base, p, d, w, acc, rng);
        }
        let scene = self.base.scene;
        let local = self.clouds.local(p);
        let grid = &self.clouds.grid;
        let atm = self.base.atmosphere;
        let cos = self.base.sun.dot(d);
        // Where the flight comes down to the scene's top (0: it starts below; ∞: never). Above
        // the top nothing can be hit, so a flight that collides there (in a cloud above the
        // terrain, most of them) never needs the scene's closest hit: it is asked for only
        // when the flight starts below the top or gets there.
        let reach = self.base.reach(p, d);
        let mut hit = if reach == 0.0 {
            scene.intersect(p, d, f64::INFINITY)
        } else {
            None
        };
        let mut t_hit = hit.map_or(f64::INFINITY, |h| h.t);
        // The part of the flight whose layer collisions the forced point covers: all of it
        // when it starts below the top, else the part above the top.
        let covered = if reach == 0.0 { t_hit } else { reach };
        // Expected estimate of the layers' collisions on that part: one point forced from
        // their collision density there, weighted by the probability of a layer collision in
        // it and by the cloud's transmittance up to the point (the layers' collision density
        // in the combined medium).
        if let Some(acc) = acc.as_deref_mut() {
            self.forced_layer_point::<W>(p, d, covered, hit, acc, rng);
        }
        // Competing risks: one optical path through the layers, one through the cloud; first
        // up to the covered part's end, then (once the flight gets below the top) to its hit.
        let s_layers = -rng.next_f64_open0().ln();
        let s_cloud = -rng.next_f64_open0().ln();
        let has_atm = atm.total_tau() > 0.0;
        let sample = |end: f64| {
            let t_layers = if has_atm {
                atm.march(p.z, d.z, s_layers, end)
            } else {
                None
            };
            let cloud = grid.march(local, d, s_cloud, t_layers.unwrap_or(end));
            (t_layers, cloud)
        };
        let (mut t_layers, mut cloud) = sample(covered);
        let mut covered = covered;
        if t_layers.is_none() && cloud.is_none() && reach > 0.0 && reach.is_finite() {
            hit = scene.intersect(p, d, f64::INFINITY);
            t_hit = hit.map_or(f64::INFINITY, |h| h.t);
            // The flight got below the top without colliding: a forced point for the layers'
            // collisions on the rest (its weight leaves out the survival to the top, which the
            // flight's having got there carries in expectation).
            if let Some(acc) = acc.as_deref_mut() {
                let q = p + d * reach;
                let rest = hit.map(|mut h| {
                    h.t -= reach;
                    h
                });
                self.forced_layer_point::<W>(q, d, t_hit - reach, rest, acc, rng);
            }
            covered = t_hit;
            (t_layers, cloud) = sample(t_hit);
        }
        let event = match (cloud, t_layers, hit) {
            (Some((t, cell)), _, _) => self.cloud_collision(p + d * t, cell),
            (None, Some(t), _) => self.base.collision_at(p + d * t),
            (None, None, Some(h)) => return Event::Surface(h),
            (None, None, None) => return Event::Escape,
        };
        // The cloud's collisions, and the layers' beyond the covered part: the collision
        // estimate at the sampled one.
        let uncovered = cloud.is_some() || t_layers.is_some_and(|t| t > covered);
        if let (Some(acc), true, Event::Collision { pos, omega, phase }) = (acc, uncovered, &event)
        {
            if *omega > 0.0 {
                let sun = Geometry::<W>::sun_at(self, *pos);
                if sun > 0.0 {
                    W::accumulate(acc, phase, cos, *omega, sun);
                }
            }
        }
        event
    }

    /// The layers' own split where the field has no extinction (no split otherwise: the
    /// competing-risk flight has no closed-form collision probability to split on).
    fn flight_split(
        &self,
        p: DVec3,
        d: DVec3,
        w: &mut W,
        acc: Option<&mut W::Phase>,
        rng: &mut Stream,
    ) -> Option<super::Split<'_, DVec3, SurfaceHit>> {
        if self.clouds.any_extinction {
            None
        } else {
            Geometry::<W>::flight_split(&self.base, p, d, w, acc, rng)
        }
    }

    #[inline]
    fn sun_at(&self, p: DVec3) -> f64 {
        let t = Geometry::<W>::sun_at(&self.base, p);
        if t > 0.0 {
            t * self.cloud_t(p, self.base.sun)
        } else {
            0.0
        }
    }

    #[inline]
    fn surface(&self, h: &SurfaceHit) -> SurfaceAt<'_> {
        Geometry::<W>::surface(&self.base, h)
    }

    #[inline]
    fn sun_at_surface(&self, h: &SurfaceHit) -> f64 {
        let t = Geometry::<W>::sun_at_surface(&self.base, h);
        if t > 0.0 {
            t * self.cloud_t(h.point, self.base.sun)
        } else {
            0.0
        }
    }

    #[inline]
    fn leave(&self, h: &SurfaceHit, d: DVec3) -> DVec3 {
        Geometry::<W>::leave(&self.base, h, d)
    }

    #[inline]
    fn solver(&self, h: &Self::Hit) -> crate::integrator::solver::SolverSpec {
        Geometry::<W>::solver(&self.base, h)
    }

    #[inline]
    fn mirror_count(&self) -> usize {
        Geometry::<W>::mirror_count(&self.base)
    }

    fn mirror_image(&self, k: usize) -> Option<DVec3> {
        Geometry::<W>::mirror_image(&self.base, k)
    }

    /// The layers' relay times the cloud's transmittance along both legs: from the hit to the
    /// mirror point and from there to the Sun.
    fn sun_via_mirror(&self, h: &SurfaceHit, k: usize, image: DVec3) -> f64 {
        let t = Geometry::<W>::sun_via_mirror(&self.base, h, k, image);
        if t <= 0.0 {
            return 0.0;
        }
        let Some(m) = self.base.scene.mirror_seen(h, k, image, self.base.sun) else {
            return 0.0;
        };
        let grid = &self.clouds.grid;
        let leg1 = grid.optical_depth(self.clouds.local(m.start), image, m.distance);
        t * (-leg1).exp() * self.cloud_t(m.hit.point, self.base.sun)
    }
}
