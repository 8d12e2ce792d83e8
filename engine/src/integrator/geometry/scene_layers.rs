//! A 3D scene inside plane-parallel layers.
//!
//! Positions are metres in the scene's local frame (x east, y north, z = altitude); the
//! atmosphere is horizontally homogeneous, so the free path of a ray is sampled exactly by
//! marching its layers ([`PlaneParallel::march`]) and the Sun's transmittance to a point at
//! altitude z is `exp(−τ(z)/μ_s)`. Each flight:
//!
//! 1. queries the scene for its closest hit (only when the ray can reach the scene's top);
//! 2. draws an optical path; a collision before the hit is an atmospheric event, else the path
//!    reaches the hit, or leaves through the top, or falls below the atmosphere without meeting
//!    any geometry (lost);
//! 3. next-event estimates at atmospheric points below the scene's top and at surfaces need a
//!    shadow ray (visibility `V`).
//!
//! Expected estimate of a flight's next collision (`expected_atmospheric`): exact, layer by
//! layer, for the part of the flight above the scene's top (no geometry can shadow it), and one
//! forced collision with its shadow ray for the part below the top (unbiased, one shadow ray per
//! flight).

use std::borrow::Cow;

use glam::DVec3;

use super::{Event, Geometry, Light, Split};
use crate::atmosphere::PlaneParallel;
use crate::bsdf::{Bsdf, Lambertian};
use crate::integrator::surface::SurfaceAt;
use crate::integrator::weight::Weight;
use crate::rng::Stream;
use crate::scene::material::SurfaceModel;
use crate::scene::world::BLACK;
use crate::scene::{Scene, SurfaceHit};

/// A flight that a forced collision splits ([`SceneInLayers::flight_to_split`]).
pub(crate) struct FlightToSplit {
    /// Where the flight comes down to the scene's top (0 if it starts below, ∞ if never).
    pub reach: f64,
    /// Its first surface hit, and that hit's distance (∞ without one).
    pub hit: Option<SurfaceHit>,
    pub t_hit: f64,
    /// The probability of a collision before the flight's end.
    pub p_collision: f64,
}

pub struct SceneInLayers<'a> {
    pub atmosphere: &'a PlaneParallel,
    pub scene: &'a Scene,
    /// Material models at this wavelength, indexed by material id.
    pub models: &'a [SurfaceModel],
    /// Unit vector towards the Sun (`z > 0`).
    pub sun: DVec3,
    /// The scene's [`SunClearance`](crate::scene::sun_clearance::SunClearance) map for `sun`
    /// (`Scene::sun_clearance`): shadow rays from points above it are not cast.
    pub clearance: Option<std::sync::Arc<crate::scene::sun_clearance::SunClearance>>,
    /// nm (for reflectance textures).
    pub wavelength: f64,
    /// The surfaces' thermal emission (`emission = true`; the layers' sources are in
    /// `atmosphere`).
    pub emission: Option<&'a crate::scene::emission::SceneEmission>,
    /// Whether the Sun shines (false: thermal emission only).
    pub shines: bool,
    /// The top of a cloud field among the layers (m; −∞ without one): paths start above it.
    pub clouds_top: f64,
    /// The run's lamps at this wavelength, if it has any (the Sun's walks only).
    pub lamps: Option<LampLight<'a>>,
}

/// Lamps as one wavelength's walks see them.
#[derive(Clone, Copy)]
pub struct LampLight<'a> {
    pub lamps: &'a crate::sources::lamps::Lamps,
    /// Run wavelength index.
    pub iw: usize,
    /// 1/E0: lamp radiances in tally units.
    pub scale: f64,
    /// Whether the walks estimate the point lamps (false where forward photons carry them,
    /// `integrator/lamp_photons.rs`: only emitting materials are then seen here).
    pub points: bool,
}

impl SceneInLayers<'_> {
    /// Direct solar transmittance from altitude `z` to TOA.
    #[inline]
    pub(crate) fn t_sun(&self, z: f64) -> f64 {
        (-self.atmosphere.tau_at_altitude(z) / self.sun.z).exp()
    }

    /// Altitude above which a path starts so that it sees the whole scene and atmosphere.
    pub fn start_altitude(&self) -> f64 {
        self.atmosphere
            .toa()
            .max(self.scene.z_range[1] + 1.0)
            .max(self.clouds_top + 1.0)
    }
}

/// The Fresnel reflectance of the scene's mirror plane `k` for the Sun's incidence cosine `cos`.
pub(crate) fn mirror_reflectance(scene: &Scene, k: usize, cos: f64) -> f64 {
    let (n, k_abs) = scene.mirror_planes()[k].index;
    crate::integrator::solver::fresnel_reflectance(n, k_abs, cos)
}

/// The surface at a scene hit: black for [`BLACK`], a Lambertian from the texture where one
/// covers a terrain hit, else the material's model (a dielectric seen from the side the path
/// arrives from: flipped for hits on its back, [`SurfaceHit::front`]).
pub(crate) fn scene_surface<'m>(
    scene: &Scene,
    models: &'m [SurfaceModel],
    wavelength: f64,
    h: &SurfaceHit,
) -> SurfaceAt<'m> {
    let model = if h.material == BLACK {
        Cow::Owned(SurfaceModel::Black)
    } else if let Some(r) = scene.texture_reflectance(h, wavelength) {
        Cow::Owned(SurfaceModel::Opaque(Bsdf::Lambertian(Lambertian {
            reflectance: r,
        })))
    } else {
        match models.get(h.material as usize) {
            // A dielectric interface met from its inside: the index ratio inverts.
            Some(SurfaceModel::Dielectric(d)) if !h.front => {
                Cow::Owned(SurfaceModel::Dielectric(d.flipped()))
            }
            Some(m) => Cow::Borrowed(m),
            None => Cow::Owned(SurfaceModel::Black),
        }
    };
    SurfaceAt::Scene { model, n: h.normal }
}

impl<W: Weight> Geometry<W> for SceneInLayers<'_> {
    type Pos = DVec3;
    type Hit = SurfaceHit;

    /// Equi-angular sampling (Kulla & Fajardo 2012, *Importance sampling techniques for path
    /// tracing in participating media*, EGSR): on the flight's segment up to its first hit (or
    /// the atmosphere's boundary), for the lamp drawn at the segment's lower end,
    /// a point `t` with density ∝ 1/(h² + (t − Δ)²), h the lamp's distance from the line and Δ
    /// its projection: the estimate `σ_s(t)·e^{−τ(0,t)}·P/(4π)·I·T_l·V/r²/pdf(t)/P_lamp` is
    /// then bounded where the collision estimate's 1/r² is not.
    fn lamps_along_flight(&self, p: DVec3, d: DVec3, rng: &mut Stream) -> f64 {
        let Some(l) = &self.lamps else {
            return 0.0;
        };
        if l.lamps.lamps.is_empty() || !l.points {
            return 0.0;
        }
        let (u0, u1) = (rng.next_f64(), rng.next_f64());
        let atm = self.atmosphere;
        if atm.total_tau() <= 0.0 {
            return 0.0;
        }
        // The segment: to the first hit, else to where the flight leaves the layers.
        let t_hit = self
            .scene
            .intersect(p, d, f64::INFINITY)
            .map_or(f64::INFINITY, |h| h.t);
        let t_end = self.flight_end(p, d, t_hit);
        if t_end <= 0.0 {
            return 0.0;
        }
        // The lamp is drawn for the segment's lower end (lamps stand on the ground, and the
        // light scattered near them dominates).
        let low = if d.z < 0.0 { p + d * t_end } else { p };
        l.lamps
            .draw(low, None, u0, |lamp: &crate::sources::lamps::Lamp| {
                let c = lamp.position;
                let delta = (c - p).dot(d);
                let h = (c - p - d * delta).length();
                if h < 1e-9 {
                    return 0.0;
                }
                let (ta, tb) = ((-delta / h).atan(), ((t_end - delta) / h).atan());
                if tb <= ta {
                    return 0.0;
                }
                let th = ta + u1 * (tb - ta);
                let t = delta + h * th.tan();
                let pdf = h / ((tb - ta) * (h * h + (t - delta) * (t - delta)));
                let x = p + d * t;
                let sigma = atm.extinction_at_altitude(x.z);
                if sigma <= 0.0 || pdf <= 0.0 {
                    return 0.0;
                }
                let layer = atm.layer_at_altitude(x.z);
                let omega = atm.albedo(layer);
                let v = c - x;
                let r2 = v.length_squared();
                let r = r2.sqrt();
                let lh = v / r;
                let i = lamp.intensity[l.iw] * lamp.shape(-lh);
                if i <= 0.0 || omega <= 0.0 {
                    return 0.0;
                }
                let t_in = (-atm.optical_path(p.z, d.z, t)).exp();
                let seen = self.lamp_seen(x, lh, r);
                if seen <= 0.0 {
                    return 0.0;
                }
                sigma
                    * omega
                    * t_in
                    * atm.phase(layer).eval(lh.dot(d))
                    * crate::integrator::weight::INV_4PI
                    * i
                    * seen
                    / (r2 * pdf)
            })
            * l.scale
    }

    fn lamps_at_surface(
        &self,
        h: &SurfaceHit,
        surface: &SurfaceAt,
        wo: DVec3,
        rng: &mut Stream,
    ) -> f64 {
        let Some(l) = &self.lamps else {
            return 0.0;
        };
        // An emitting material's own radiance (both faces, every direction).
        let own = l
            .lamps
            .emitters
            .get(h.material as usize)
            .and_then(|e| e.get(l.iw))
            .copied()
            .unwrap_or(0.0);
        if l.lamps.lamps.is_empty() || !l.points {
            return own * l.scale;
        }
        // One-sided surfaces take light from the viewer's side only (leaves and dielectrics
        // from both).
        let normal = match surface {
            SurfaceAt::Scene { model, n } if matches!(**model, SurfaceModel::Opaque(_)) => Some(*n),
            _ => None,
        };
        // `lamp_samples` lamps drawn independently, averaged.
        let k = l.lamps.samples.max(1);
        let mut sum = 0.0;
        for _ in 0..k {
            let u = rng.next_f64();
            sum += l.lamps.gather(
                l.iw,
                h.point,
                normal,
                u,
                |dir| surface.eval_cos(dir, wo),
                |dir, r| self.lamp_seen(self.scene.offset(h.point, h.normal, dir), dir, r),
            );
        }
        (sum / k as f64 + own) * l.scale
    }

    fn light(&self) -> Light {
        Light::new(self.sun, self.sun.z)
    }

    #[inline]
    fn sun_shines(&self) -> bool {
        self.shines
    }

    /// The layers' expected emission up to the flight's first hit, exactly: the plane-parallel
    /// expectation from the start (`PlaneParallel::expected_emission`) minus the transmittance
    /// to the hit times the same expectation from the hit on (the emission along a line is
    /// additive); plus the hit surface's emission towards the path (`SceneEmission`) times
    /// that transmittance. (One more closest-hit query per flight, as `flight` makes.)
    fn flight_emission(&self, p: DVec3, d: DVec3, _: &W, _: &mut Stream) -> f64 {
        let Some(em) = self.emission else {
            return 0.0;
        };
        let atm = self.atmosphere;
        let top = self.scene.z_range[1];
        let can_reach = p.z <= top || d.z < 0.0;
        let hit = if can_reach {
            self.scene.intersect(p, d, f64::INFINITY)
        } else {
            None
        };
        let emits = atm.emits();
        let from_p = if emits {
            atm.expected_emission(atm.tau_at_altitude(p.z), d.z)
        } else {
            0.0
        };
        let Some(h) = hit else {
            return from_p;
        };
        let t = (-atm.optical_path(p.z, d.z, h.t)).exp();
        let from_hit = if emits {
            atm.expected_emission(atm.tau_at_altitude(h.point.z), d.z)
        } else {
            0.0
        };
        (from_p - t * from_hit).max(0.0)
            + t * em.radiance(
                self.scene,
                &h,
                -d,
                crate::integrator::solver::fresnel_reflectance,
            )
    }

    fn flight(
        &self,
        p: DVec3,
        d: DVec3,
        _: &mut W,
        acc: Option<&mut W::Phase>,
        rng: &mut Stream,
    ) -> Event<'_, DVec3, SurfaceHit> {
        let atm = self.atmosphere;
        let has_atm = atm.total_tau() > 0.0;
        let (reach, hit) = self.first_hit(p, d);
        let t_hit = hit.map_or(f64::INFINITY, |h| h.t);
        if let (Some(acc), true) = (acc, has_atm) {
            self.expected_atmospheric::<W>(p, d, reach, t_hit, acc, rng);
        }
        let s = -rng.next_f64_open0().ln();
        let t_coll = if has_atm {
            atm.march(p.z, d.z, s, t_hit)
        } else {
            None
        };
        if let Some(t) = t_coll {
            self.collision_at(p + d * t)
        } else if let Some(h) = hit {
            Event::Surface(h)
        } else {
            Event::Escape
        }
    }

    /// The flight's end is its first hit, or the top or bottom of the atmosphere; the forced
    /// collision's optical path is drawn from the exponential truncated there and marched to.
    fn flight_split(
        &self,
        p: DVec3,
        d: DVec3,
        _: &mut W,
        acc: Option<&mut W::Phase>,
        rng: &mut Stream,
    ) -> Option<Split<'_, DVec3, SurfaceHit>> {
        let f = self.flight_to_split(p, d)?;
        let (hit, t_hit) = (f.hit, f.t_hit);
        if let Some(acc) = acc {
            self.expected_atmospheric::<W>(p, d, f.reach, t_hit, acc, rng);
        }
        let t = self.forced_distance(p, d, &f, rng);
        Some(Split {
            p_collision: f.p_collision,
            collision: self.collision_at(p + d * t),
            end: match hit {
                Some(h) => Event::Surface(h),
                None => Event::Escape,
            },
        })
    }

    #[inline]
    fn sun_at(&self, p: DVec3) -> f64 {
        if p.z > self.scene.z_range[1] {
            self.t_sun(p.z)
        } else {
            self.sun_visibility(p) * self.t_sun(p.z)
        }
    }
    #[inline]
    fn surface(&self, h: &SurfaceHit) -> SurfaceAt<'_> {
        scene_surface(self.scene, self.models, self.wavelength, h)
    }
    #[inline]
    fn sun_at_surface(&self, h: &SurfaceHit) -> f64 {
        let start = self.scene.offset(h.point, h.normal, self.sun);
        self.sun_visibility(start) * self.t_sun(h.point.z)
    }
    #[inline]
    fn leave(&self, h: &SurfaceHit, d: DVec3) -> DVec3 {
        self.scene.offset(h.point, h.normal, d)
    }
    #[inline]
    fn solver(&self, h: &Self::Hit) -> crate::integrator::solver::SolverSpec {
        self.scene.solver(h.material)
    }

    #[inline]
    fn mirror_count(&self) -> usize {
        self.scene.mirror_planes().len()
    }

    fn mirror_image(&self, k: usize) -> Option<DVec3> {
        self.scene.mirror_planes()[k].image(self.sun)
    }

    /// The mirror point seen towards the image (`Scene::mirror_seen`) must see the Sun.
    /// Transmittances: the layers' along the ray and the Sun's to the mirror point.
    fn sun_via_mirror(&self, h: &SurfaceHit, k: usize, image: DVec3) -> f64 {
        let Some(m) = self.scene.mirror_seen(h, k, image, self.sun) else {
            return 0.0;
        };
        let y = m.hit.point;
        let v = self.sun_visibility(self.scene.offset(y, m.hit.normal, self.sun));
        if v <= 0.0 {
            return 0.0;
        }
        let path = self.atmosphere.optical_path(m.start.z, image.z, m.distance);
        mirror_reflectance(self.scene, k, m.cos) * (-path).exp() * self.t_sun(y.z) * v
    }
}

impl SceneInLayers<'_> {
    /// Where the flight from `p` along unit `d` whose first hit is at `t_hit` (∞: none) ends:
    /// at the hit, else where it leaves the layers (through the top, or 1 m below the lower of
    /// the scene and the ground); a horizontal one after 50 km (as far as lamps reach).
    #[inline]
    pub(crate) fn flight_end(&self, p: DVec3, d: DVec3, t_hit: f64) -> f64 {
        let atm = self.atmosphere;
        if t_hit.is_finite() {
            t_hit
        } else if d.z > 1e-12 {
            ((atm.toa() - p.z) / d.z).max(0.0)
        } else if d.z < -1e-12 {
            let bottom = self.scene.z_range[0].min(atm.ground()) - 1.0;
            ((bottom - p.z) / d.z).max(0.0)
        } else {
            5e4
        }
    }

    /// The transmittance from `p` over `r` m along unit `dir` to a lamp: the layers' along the
    /// segment times the scene's visibility (panes included) up to just short of the lamp (a
    /// lamp may sit on the geometry that holds it).
    #[inline]
    fn lamp_seen(&self, p: DVec3, dir: DVec3, r: f64) -> f64 {
        let t = (-self.atmosphere.optical_path(p.z, dir.z, r)).exp();
        if t <= 0.0 {
            return 0.0;
        }
        let reach = r * (1.0 - 1e-9) - 1e-3;
        if reach <= 0.0 {
            return t;
        }
        t * self.scene.visibility(p, dir, reach, self.models)
    }

    /// The fraction of sunlight the scene lets through to `p`: 1 above the clearance map, else
    /// a shadow ray's [`Scene::visibility`] (0 behind opaque surfaces, the transmittance of
    /// the panes crossed).
    #[inline]
    pub(crate) fn sun_visibility(&self, p: DVec3) -> f64 {
        if self.clearance.as_ref().is_some_and(|c| c.clear(p)) {
            1.0
        } else {
            self.scene
                .visibility(p, self.sun, f64::INFINITY, self.models)
        }
    }

    /// Whether nothing in the scene blocks the Sun from `p`: the clearance map first, then a
    /// shadow ray (spectral walks, whose scenes have no panes).
    #[inline]
    pub(crate) fn sees_sun(&self, p: DVec3) -> bool {
        self.clearance.as_ref().is_some_and(|c| c.clear(p))
            || !self.scene.occluded(p, self.sun, f64::INFINITY)
    }

    /// The flight from `p` along `d` that a forced collision splits: its first hit and the
    /// probability of a collision before it ends. `None` (no random number used) when it cannot
    /// collide: nearly horizontal, a clear sky, or a zero optical path. Shared by the scalar
    /// walk here and the spectral one (`scene_alis.rs`).
    #[inline]
    pub(crate) fn flight_to_split(&self, p: DVec3, d: DVec3) -> Option<FlightToSplit> {
        if !self.can_split(d) {
            return None;
        }
        let (reach, hit) = self.first_hit(p, d);
        let t_hit = hit.map_or(f64::INFINITY, |h| h.t);
        self.split_ending(p, d, reach, hit, t_hit)
    }

    /// Whether a flight along `d` may be split (not nearly horizontal, not a clear sky).
    #[inline]
    pub(crate) fn can_split(&self, d: DVec3) -> bool {
        d.z.abs() >= 1e-6 && self.atmosphere.total_tau() > 0.0
    }

    /// The flight from `p` along `d` ending at `t_end` (its hit `hit`, `reach` as in
    /// [`FlightToSplit`]) as a flight to split: `None` for a zero optical path.
    #[inline]
    pub(crate) fn split_ending(
        &self,
        p: DVec3,
        d: DVec3,
        reach: f64,
        hit: Option<SurfaceHit>,
        t_end: f64,
    ) -> Option<FlightToSplit> {
        // Optical path to the flight's end (tau_at_altitude clamps beyond the atmosphere).
        let s_end = self.atmosphere.optical_path(p.z, d.z, t_end);
        let p_collision = -(-s_end).exp_m1();
        if p_collision.is_nan() || p_collision <= 0.0 {
            return None;
        }
        Some(FlightToSplit {
            reach,
            hit,
            t_hit: t_end,
            p_collision,
        })
    }

    /// The distance along the flight `f` (from `p` along `d`) of its forced collision: drawn
    /// from the collision density restricted to the flight (one random number). Rounding may
    /// carry the optical path just past the end: the collision then sits there.
    #[inline]
    pub(crate) fn forced_distance(
        &self,
        p: DVec3,
        d: DVec3,
        f: &FlightToSplit,
        rng: &mut Stream,
    ) -> f64 {
        let atm = self.atmosphere;
        let s = -(-rng.next_f64() * f.p_collision).ln_1p();
        atm.march(p.z, d.z, s, f.t_hit).unwrap_or_else(|| {
            let boundary = if d.z > 0.0 { atm.toa() } else { atm.ground() };
            f.t_hit.min((boundary - p.z) / d.z) * (1.0 - 1e-12)
        })
    }

    /// The distance at which the flight from `p` along `d` comes down to the scene's top (0 if
    /// it starts below, ∞ if it never does) and its first hit (queried only when it can reach
    /// the scene).
    #[inline]
    pub(crate) fn first_hit(&self, p: DVec3, d: DVec3) -> (f64, Option<SurfaceHit>) {
        let reach = self.reach(p, d);
        let hit = if reach.is_finite() {
            self.scene.intersect(p, d, f64::INFINITY)
        } else {
            None
        };
        (reach, hit)
    }

    /// The distance at which the flight from `p` along `d` comes down to the scene's top (0 if
    /// it starts below, ∞ if it never does).
    #[inline]
    pub(crate) fn reach(&self, p: DVec3, d: DVec3) -> f64 {
        let top = self.scene.z_range[1];
        if p.z <= top {
            0.0
        } else if d.z < 0.0 {
            (p.z - top) / -d.z
        } else {
            f64::INFINITY
        }
    }

    /// A collision at point `q` (wrapped into a periodic scene's cell), with its layer's optics.
    #[inline]
    pub(crate) fn collision_at(&self, q: DVec3) -> Event<'_, DVec3, SurfaceHit> {
        let q = self.scene.wrap_point(q);
        let layer = self.atmosphere.layer_at_altitude(q.z);
        Event::Collision {
            pos: q,
            omega: self.atmosphere.albedo(layer),
            phase: self.atmosphere.phase(layer),
        }
    }

    /// Expected value, over the next collision of the flight from `p` along `d`, of the
    /// atmospheric next-event estimate `ω P(s·d) T_sun V` (without the 1/4π), for a flight whose
    /// first geometry hit is at `t_hit` and which comes below the scene's top at `reach`:
    /// * above the scene's top no geometry blocks the Sun, so that part of the flight is
    ///   integrated exactly, layer by layer (`flight_integrals_within`);
    /// * below the top (until the geometry hit) one point is drawn from the collision density
    ///   restricted to that segment and scored with its shadow ray, weighted by the probability
    ///   of a collision in the segment (forced collision: unbiased, one shadow ray per flight).
    fn expected_atmospheric<W: Weight>(
        &self,
        p: DVec3,
        d: DVec3,
        reach: f64,
        t_hit: f64,
        acc: &mut W::Phase,
        rng: &mut Stream,
    ) {
        let atm = self.atmosphere;
        let sun = self.sun;
        let top = self.scene.z_range[1];
        let cos = sun.dot(d);
        // Part above the top: a flight starting above it, or one that climbs out of the scene
        // without hitting anything (all geometry lies at or below the top, so any hit ends the
        // flight there: a hit on the top plane itself, e.g. a `null` surface that the path then
        // crosses, must not count the part above twice).
        let exits_up = d.z > 0.0 && p.z <= top && t_hit == f64::INFINITY;
        if p.z > top || exits_up {
            let tau_p = atm.tau_at_altitude(p.z);
            let tau_top = atm.tau_at_altitude(top);
            atm.flight_integrals_within(tau_p, d.z, 1.0 / sun.z, 0.0, tau_top, |l, i| {
                W::accumulate(acc, atm.phase(l), cos, atm.albedo(l), i);
            });
        }
        // Part below the top.
        if let Some((q, _, p_seg)) = self.forced_point_below_top(p, d, reach, t_hit, rng) {
            let l = atm.layer_at_altitude(q.z);
            let omega = atm.albedo(l);
            if omega > 0.0 {
                let v = self.sun_visibility(q);
                if v > 0.0 {
                    W::accumulate(acc, atm.phase(l), cos, omega, p_seg * v * self.t_sun(q.z));
                }
            }
        }
    }

    /// The part of the flight from `p` along `d` below the scene's top (from `reach`, where it
    /// comes down to the top, to its first hit at `t_hit` or the atmosphere's boundary): one
    /// point drawn from the collision density restricted to that segment (one random number),
    /// with its distance `t` along the flight and the probability `p_seg` of a collision in
    /// the segment; `None` (no random number) when the segment is empty or cannot collide.
    /// The forced point of the expected estimate below the top, here and in `scene_alis.rs`.
    pub(crate) fn forced_point_below_top(
        &self,
        p: DVec3,
        d: DVec3,
        reach: f64,
        t_hit: f64,
        rng: &mut Stream,
    ) -> Option<(DVec3, f64, f64)> {
        if !reach.is_finite() {
            return None;
        }
        let atm = self.atmosphere;
        let top = self.scene.z_range[1];
        let t_a = reach;
        let t_leave = if d.z > 0.0 && p.z <= top {
            (top - p.z) / d.z
        } else if d.z < 0.0 {
            (p.z - atm.ground()) / -d.z
        } else {
            f64::INFINITY
        };
        let t_b = t_hit.min(t_leave);
        if t_b <= t_a {
            return None;
        }
        let s_a = atm.optical_path(p.z, d.z, t_a);
        let s_ab = if t_b.is_finite() {
            atm.optical_path(p.z + t_a * d.z, d.z, t_b - t_a)
        } else {
            f64::INFINITY
        };
        // Probability of a collision inside the segment.
        let p_seg = (-s_a).exp() * -(-s_ab).exp_m1();
        if p_seg <= 0.0 {
            return None;
        }
        let u = rng.next_f64();
        let s_star = s_a - (-u * -(-s_ab).exp_m1()).ln_1p();
        let t = atm.march(p.z, d.z, s_star, f64::INFINITY)?.min(t_b);
        Some((p + d * t, t, p_seg))
    }
}
