//! One backward walk for several wavelengths of a 3D scene in plane-parallel layers
//! (`integrator.spectral_walk = "alis"` with a scene): the spectral ALIS walk of
//! [`backward_alis`](super::backward_alis) (Emde, Buras & Mayer 2011) carried into
//! [`SceneInLayers`]. The scene's rays (closest hits and shadow rays), which cost most of a 3D
//! render, are cast once per sample for every wavelength of the group instead of once per
//! wavelength.
//!
//! **The walk.** As in `backward_alis.rs`: free paths and collisions are sampled in the group's
//! *reference* atmosphere (its central wavelength's scattering, the group's least absorption),
//! new directions from the reference phase function; every channel (wavelength) c carries a
//! path factor `e_c`, multiplied along each flight of length ℓ by `exp(−(τ_c − τ_ref))`
//! (`Layers::carry`) and at a collision in layer i by `(σ_c,i/σ_ref,i)·P_c,i/P_ref,i`. What is
//! new here:
//!
//! * **Surfaces.** A hit's material has its own model per wavelength (and a texture its own
//!   reflectance). The direction is drawn from a density `p` positive wherever any channel's
//!   BRDF is, and channel c's weight is `q_c = f_c·|cos θ_i|/p`: all-Lambertian hits draw the
//!   cosine density (`q_c = ρ_c`, exact: a pure reflectance ratio); hits with leaves draw the
//!   side in proportion to the channels' summed reflectance and transmittance (so a side any
//!   channel scatters into is drawn; an opaque channel there, possible only where a texture
//!   covers some wavelengths of a leaf material, counts as a reflectance of 1), then the cosine
//!   density; other opaque models draw the reference channel's BRDF sampler,
//!   whose density is positive over the upper hemisphere (`bsdf/mod.rs`; as the 1D walk).
//!   The common weight takes `r` (the reference channel's `q`, or the largest where that is 0)
//!   and `e_c` takes `q_c/r`.
//! * **Next-event estimates.** A shadow ray's visibility `V` is shared; the Sun's transmittance
//!   `exp(−τ_c(z)/μ_s)`, the BRDF and the phase function are each channel's. The expected
//!   estimate of a flight is integrated exactly per channel above the scene's top (in the
//!   channel's own atmosphere, as [`SceneInLayers`] does, times `e_c`) and, below it, estimated at one collision point drawn
//!   from the *reference* collision density restricted to the segment (probability `p_seg`),
//!   scored per channel as `p_seg·ω_ref·(σ_c/σ_ref)·P_c·e_c·e^{−(S_c − S_ref)}·T_c·V`: the
//!   density ratio of channel c's collision integrand to the reference's sampling density, so
//!   unbiased per channel as the scalar geometry's forced point is.
//! * **Forced first collisions** ([`Geometry::flight_split`]): the reference's split (collided
//!   branch with probability `p`, uncollided `1 − p`), with each branch's own path factors: the
//!   uncollided branch's `e_c` carried to the flight's end, the collided copy's to its collision
//!   point ([`Weight::take_collision_branch`]).
//!
//! Unbiased per channel for the reasons given in `backward_alis.rs` (the same importance
//! weights, the reference's densities positive wherever a channel's integrand is: checked for
//! scattering by `IntegratorSettings::check_spectral_groups`, for surfaces by the choice of
//! sampler above). Not built here (refused by the resolver, naming the key): thermal emission,
//! polarization, spherical shells, per-material solvers other than the default.
//!
//! Cost and variance: per flight one closest-hit query and at most one shadow ray, whatever the
//! number of channels; per channel a few exponentials per layer crossed above the scene. The
//! path factors are not bounded by 1 (a channel scattering more than the reference gains
//! `σ_c/σ_ref` per collision, e.g. 2.4 at 440 nm for a 550 nm Rayleigh reference), so the
//! channels far from the reference have larger errors than independent walks of the same count;
//! BENCHMARKS.md measures the net gain.

use std::cell::RefCell;

use glam::DVec3;

use super::above_scene::Part;
use super::backward::Adjoint;
use super::backward_alis::{channels, Channels, PhaseCache};
use super::geometry::scene_layers::{scene_surface, SceneInLayers};
use super::geometry::{Event, Geometry, Light, Split};
use super::peak_sampling::PeakSampling;
use super::surface::SurfaceAt;
use super::weight::{OrderSplit, Weight};
use crate::accum::Accum;
use crate::bsdf::Bsdf;
use crate::frame::{basis_around, sample_cosine_hemisphere};
use crate::phase::PhaseFunction;
use crate::rng::Stream;
use crate::scene::material::SurfaceModel;
use crate::scene::SurfaceHit;

/// The most wavelengths one walk through a 3D scene carries (`integrator.alis_group`).
pub const SCENE_CHANNELS: usize = 8;

/// A 3D scene in plane-parallel layers seen by a walk over the wavelengths of `channels`.
pub struct SceneChannels<'a> {
    /// The scene in the group's reference atmosphere (`channels.reference`) with the
    /// reference wavelength's materials: its hits, shadow rays and collision sampling.
    pub base: SceneInLayers<'a>,
    /// The wavelengths' atmospheres, the reference and the layer tables
    /// ([`Layers::spectral`](super::backward_alis::Layers::spectral)).
    pub channels: &'a Channels<'a>,
    /// Per channel, the material models at its wavelength.
    pub models: &'a [&'a [SurfaceModel]],
    /// Per channel, nm.
    pub wavelengths: &'a [f64],
    /// The channel whose wavelength is the reference's.
    pub reference_channel: usize,
    /// Which part of each walk's score is made (`above_scene.rs`; [`Part::Whole`] by
    /// default).
    pub part: Part,
    /// Phase-function values per cos Θ (the walks of a block run one after another).
    cache: RefCell<PhaseCache>,
}

impl<'a> SceneChannels<'a> {
    pub fn new(
        base: SceneInLayers<'a>,
        channels: &'a Channels<'a>,
        models: &'a [&'a [SurfaceModel]],
        wavelengths: &'a [f64],
        reference_channel: usize,
    ) -> Self {
        let nc = channels.atms.len();
        assert!(
            (1..=SCENE_CHANNELS).contains(&nc) && models.len() == nc && wavelengths.len() == nc,
            "a scene walk carries 1 to {SCENE_CHANNELS} channels, each with its models"
        );
        SceneChannels {
            base,
            channels,
            models,
            wavelengths,
            reference_channel,
            part: Part::Whole,
            cache: RefCell::new(PhaseCache::new(channels.layers.phase_ids())),
        }
    }

    /// The same geometry scoring only `part` of each walk (`above_scene.rs`).
    pub fn scoring(mut self, part: Part) -> Self {
        self.part = part;
        self
    }

    /// The scene's top, m.
    #[inline]
    fn top(&self) -> f64 {
        self.base.scene.z_range[1]
    }

    /// Distance from `p` (above the top) along `d` down to the top (∞ going up): where the
    /// flights of the pool's walks end.
    #[inline]
    fn to_top(&self, p: DVec3, d: DVec3) -> f64 {
        if d.z < 0.0 {
            (p.z - self.top()) / -d.z
        } else {
            f64::INFINITY
        }
    }

    fn nc(&self) -> usize {
        self.channels.atms.len()
    }

    /// Channel c's direct solar transmittance from altitude `z`.
    #[inline]
    fn t_sun(&self, c: usize, z: f64) -> f64 {
        (-self.channels.layers.tau_at(c, z) / self.base.sun.z).exp()
    }

    /// Per channel `(σ_c/σ_ref)·P_c(cos)` in reference layer `layer`.
    #[inline]
    fn ratio_phase(&self, layer: usize, cos: f64, out: &mut [f64; SCENE_CHANNELS]) {
        let nc = self.nc();
        self.channels.layers.ratio_phase(
            self.channels.atms,
            layer,
            cos,
            &mut self.cache.borrow_mut(),
            &mut out[..nc],
        );
    }

    /// Channel c's surface at hit `h`.
    #[inline]
    fn surface_of(&self, c: usize, h: &SurfaceHit) -> SurfaceAt<'a> {
        scene_surface(self.base.scene, self.models[c], self.wavelengths[c], h)
    }

    /// Add to `acc` (per channel) the expected next-event estimate of the flight from `p` along
    /// `d` carrying factors `e`, which comes below the scene's top at `reach` and hits the
    /// scene at `t_hit` (module header); `entered`: whether the path has been below the top
    /// before this flight (which part of it [`Self::part`] scores).
    #[allow(clippy::too_many_arguments)]
    fn expected_flight(
        &self,
        p: DVec3,
        d: DVec3,
        reach: f64,
        t_hit: f64,
        e: &[f64; SCENE_CHANNELS],
        acc: &mut [f64; SCENE_CHANNELS],
        rng: &mut Stream,
        entered: bool,
    ) {
        let nc = self.nc();
        let atm = self.base.atmosphere;
        let sun = self.base.sun;
        let top = self.top();
        let cos = sun.dot(d);
        // Above the top, exactly (see `SceneInLayers::expected_atmospheric` for the cases): the
        // part before the path's first entry below the top unless only what follows is scored.
        let exits_up = d.z > 0.0 && p.z <= top && t_hit == f64::INFINITY;
        if self.part.scores(entered) && (p.z > top || exits_up) {
            // Per channel as the scalar geometry does in its own atmosphere (runs of layers
            // with equal optics in one exponential), times the path factor.
            let b = 1.0 / sun.z;
            for (c, a) in self.channels.atms.iter().enumerate() {
                let mut sum = 0.0;
                a.flight_integrals_within(
                    a.tau_at_altitude(p.z),
                    d.z,
                    b,
                    0.0,
                    a.tau_at_altitude(top),
                    |l, i| sum += a.albedo(l) * a.phase(l).eval(cos) * i,
                );
                acc[c] += e[c] * sum;
            }
        }
        // Below the top (after the entry: not the pool's): one point of the reference's
        // collision density (as the scalar geometry draws it).
        if self.part == Part::BeforeEntry {
            return;
        }
        let Some((q, t, p_seg)) = self.base.forced_point_below_top(p, d, reach, t_hit, rng) else {
            return;
        };
        let l = atm.layer_at_altitude(q.z);
        let omega = atm.albedo(l);
        if omega <= 0.0 || !self.base.sees_sun(q) {
            return;
        }
        let mut f = *e;
        self.channels.layers.carry(&mut f[..nc], p.z, d.z, t);
        let mut rp = [0.0; SCENE_CHANNELS];
        self.ratio_phase(l, cos, &mut rp);
        for c in 0..nc {
            acc[c] += p_seg * omega * rp[c] * f[c] * self.t_sun(c, q.z);
        }
    }
}

/// The weight of a walk over the wavelengths of a scene: the common weight `w` and one path
/// factor per channel (module header).
#[derive(Clone)]
pub struct SceneChannelPath<'a> {
    w: f64,
    e: [f64; SCENE_CHANNELS],
    /// After a split flight: the collided branch's factors (`take_collision_branch`).
    e_coll: [f64; SCENE_CHANNELS],
    /// Whether the path has been below the scene's top (and, after a split flight, whether the
    /// collided branch has: `take_collision_branch`), for [`SceneChannels::part`].
    entered: bool,
    entered_coll: bool,
    /// Reference layer of the last collision (set by the flight, used by the scattering).
    layer: usize,
    /// The last surface hit (set by the flight, used by the reflection and its estimate).
    hit: Option<SurfaceHit>,
    g: &'a SceneChannels<'a>,
}

impl<'a> SceneChannelPath<'a> {
    /// A path of unit weight leaving the sensor.
    pub fn new(g: &'a SceneChannels<'a>) -> Self {
        SceneChannelPath {
            w: 1.0,
            e: [1.0; SCENE_CHANNELS],
            e_coll: [1.0; SCENE_CHANNELS],
            entered: false,
            entered_coll: false,
            layer: 0,
            hit: None,
            g,
        }
    }
}

/// Per-channel scores of one path.
pub type SceneChannelTally = [OrderSplit; SCENE_CHANNELS];

impl Weight for SceneChannelPath<'_> {
    /// Per channel: the flight's expected `σ_c P_c e_c T_c V` (or at a collision).
    type Phase = [f64; SCENE_CHANNELS];
    type Tally = SceneChannelTally;

    #[inline]
    fn zero_phase() -> Self::Phase {
        [0.0; SCENE_CHANNELS]
    }
    #[inline]
    fn zero_tally() -> Self::Tally {
        [OrderSplit::default(); SCENE_CHANNELS]
    }
    /// Grey scattering (not used: [`SceneChannels`] accumulates each channel's own).
    #[inline]
    fn accumulate(acc: &mut Self::Phase, phase: &PhaseFunction, cos: f64, omega: f64, k: f64) {
        channels::accumulate_grey(acc, phase, cos, omega, k);
    }
    #[inline]
    fn phase_intensity(acc: &Self::Phase) -> f64 {
        channels::phase_intensity(acc)
    }
    #[inline]
    fn intensity(&self) -> f64 {
        self.w
    }
    #[inline]
    fn rescale_to(&mut self, target: f64, _: f64) {
        self.w = target;
    }
    /// A direction from the reference phase function (no detector-directional sampling: the
    /// channels share it); `e_c × (σ_c/σ_ref)·P_c(μ)/P_ref(μ)`.
    #[inline]
    fn scatter(
        &mut self,
        phase: &PhaseFunction,
        omega: f64,
        d: DVec3,
        _peak: &PeakSampling,
        rng: &mut Stream,
    ) -> DVec3 {
        self.w *= omega;
        let (mu, wi) = channels::reference_direction(phase, d, rng);
        let mut r = [0.0; SCENE_CHANNELS];
        self.g.ratio_phase(self.layer, mu, &mut r);
        let nc = self.g.nc();
        channels::times_phase_ratio(&mut self.e[..nc], &r, phase.eval(mu));
        wi
    }
    /// Three random numbers, whatever the models (module header for the sampler).
    fn reflect(&mut self, _: &SurfaceAt, d: DVec3, rng: &mut Stream) -> Option<DVec3> {
        let u = [rng.next_f64(), rng.next_f64(), rng.next_f64()];
        let h = self.hit?;
        let g = self.g;
        let nc = g.nc();
        let wo = -d;
        let n = h.normal;
        let surfaces: [Option<SurfaceAt>; SCENE_CHANNELS] =
            std::array::from_fn(|c| (c < nc).then(|| g.surface_of(c, &h)));
        let model = |c: usize| match &surfaces[c] {
            Some(SurfaceAt::Scene { model, .. }) => model.as_ref(),
            _ => &SurfaceModel::Black,
        };
        let mut q = [0.0; SCENE_CHANNELS];
        let lambertian = |m: &SurfaceModel| match m {
            SurfaceModel::Opaque(Bsdf::Lambertian(l)) => Some(l.reflectance),
            SurfaceModel::Black => Some(0.0),
            _ => None,
        };
        let leaf = |m: &SurfaceModel| match m {
            SurfaceModel::Leaf {
                reflectance,
                transmittance,
            } => Some((*reflectance, *transmittance)),
            SurfaceModel::Black => Some((0.0, 0.0)),
            _ => None,
        };
        let wi = if (0..nc).all(|c| lambertian(model(c)).is_some()) {
            let (t, b) = basis_around(n);
            let l = sample_cosine_hemisphere(u[0], u[1]);
            for (c, qc) in q[..nc].iter_mut().enumerate() {
                *qc = lambertian(model(c)).unwrap_or(0.0);
            }
            t * l.x + b * l.y + n * l.z
        } else if (0..nc).any(|c| matches!(model(c), SurfaceModel::Leaf { .. })) {
            // Leaves: a side drawn in proportion to the channels' summed reflectance and
            // transmittance (an opaque channel, possible only where a texture covers some
            // wavelengths of a leaf material, counts as a reflectance of 1), then the cosine
            // density on that side; q_c = f_c·|cos|/pdf for every channel.
            let (mut rm, mut tm) = (0.0, 0.0);
            for c in 0..nc {
                match leaf(model(c)) {
                    Some((r, t)) => {
                        rm += r;
                        tm += t;
                    }
                    None => rm += 1.0,
                }
            }
            let total = rm + tm;
            if total <= 0.0 {
                return None;
            }
            let reflect = u[2] * total < rm;
            let side = if reflect { n } else { -n };
            let share = if reflect { rm } else { tm };
            let (t, b) = basis_around(side);
            let l = sample_cosine_hemisphere(u[0], u[1]);
            if l.z <= 0.0 {
                return None;
            }
            let pdf = share / total * l.z * std::f64::consts::FRAC_1_PI;
            let wi = t * l.x + b * l.y + side * l.z;
            for (c, qc) in q[..nc].iter_mut().enumerate() {
                *qc = model(c).eval_cos(n, wi, wo) / pdf;
            }
            wi
        } else {
            // Opaque models: the reference channel's sampler (or the first opaque one), whose
            // density is positive over the upper hemisphere.
            let sampler = std::iter::once(g.reference_channel)
                .chain(0..nc)
                .find_map(|c| match model(c) {
                    SurfaceModel::Opaque(b) => Some(b),
                    _ => None,
                })?;
            let (t, b) = basis_around(n);
            let wo_l = DVec3::new(wo.dot(t), wo.dot(b), wo.dot(n));
            let s = sampler.sample(wo_l, u[0], u[1]);
            if s.pdf <= 0.0 {
                return None;
            }
            let wi = t * s.wi.x + b * s.wi.y + n * s.wi.z;
            for (c, qc) in q[..nc].iter_mut().enumerate() {
                *qc = model(c).eval_cos(n, wi, wo) / s.pdf;
            }
            wi
        };
        let q_max = q[..nc].iter().fold(0.0_f64, |a, &b| a.max(b));
        let r = if q[g.reference_channel] > 0.0 {
            q[g.reference_channel]
        } else {
            q_max
        };
        if r <= 0.0 {
            return None;
        }
        for (ek, qk) in self.e[..nc].iter_mut().zip(&q) {
            *ek *= qk / r;
        }
        self.w *= r;
        Some(wi)
    }
    #[inline]
    fn splittable(&self) -> Option<Self> {
        Some(self.clone())
    }
    #[inline]
    fn take_collision_branch(&mut self) {
        self.e = self.e_coll;
        self.entered = self.entered_coll;
    }
    /// One accumulator cell per channel (`cell` must be 0).
    fn record(acc: &mut Accum, cell: usize, t: &SceneChannelTally, k: f64) {
        channels::record(acc, cell, t, k);
    }
    fn add_tally(t: &mut SceneChannelTally, other: &SceneChannelTally, ratio: &[f64]) {
        channels::add_scaled(t, other, ratio);
    }
    fn mean_first_order(t: &mut SceneChannelTally, others: &SceneChannelTally, k: u32) {
        channels::mean_first_order(t, others, k);
    }
    fn accum(cells: usize) -> Accum {
        Accum::new(cells)
    }
}

impl Adjoint for SceneChannelPath<'_> {
    /// Emission is refused with spectral walks in scenes (the resolver).
    #[inline]
    fn see_emission(&self, _: &mut SceneChannelTally, _: u32, _: f64) {}
    #[inline]
    fn see_sun_volume(
        &self,
        t: &mut SceneChannelTally,
        order: u32,
        acc: &Self::Phase,
        _: DVec3,
        _: DVec3,
        k: f64,
    ) {
        let nc = self.g.nc();
        for (tc, a) in t[..nc].iter_mut().zip(acc) {
            tc.add(order, self.w * a * k);
        }
    }
    /// Each channel's surface and solar transmittance at the last hit; `visible` is the shared
    /// visibility (0 or 1, [`SceneChannels`]' `sun_at_surface`), asked only when some channel
    /// reflects sunlight.
    fn see_sun_surface(
        &self,
        t: &mut SceneChannelTally,
        order: u32,
        _: &SurfaceAt,
        d: DVec3,
        sun: DVec3,
        visible: impl FnOnce() -> f64,
    ) {
        let Some(h) = self.hit else {
            return;
        };
        let g = self.g;
        let nc = g.nc();
        let wo = -d;
        let mut f = [0.0; SCENE_CHANNELS];
        let mut any = false;
        for (c, fc) in f[..nc].iter_mut().enumerate() {
            *fc = g.surface_of(c, &h).eval_cos(sun, wo);
            any |= *fc > 0.0;
        }
        if !any {
            return;
        }
        let v = visible();
        if v <= 0.0 {
            return;
        }
        for c in 0..nc {
            if f[c] > 0.0 {
                t[c].add(order, self.w * self.e[c] * f[c] * g.t_sun(c, h.point.z) * v);
            }
        }
    }
}

impl<'a> Geometry<SceneChannelPath<'a>> for SceneChannels<'a> {
    type Pos = DVec3;
    type Hit = SurfaceHit;

    fn light(&self) -> Light {
        Light::new(self.base.sun, self.base.sun.z)
    }

    #[inline]
    fn sun_shines(&self) -> bool {
        self.base.shines
    }

    fn flight(
        &self,
        p: DVec3,
        d: DVec3,
        w: &mut SceneChannelPath<'a>,
        acc: Option<&mut [f64; SCENE_CHANNELS]>,
        rng: &mut Stream,
    ) -> Event<'_, DVec3, SurfaceHit> {
        let nc = self.nc();
        let atm = self.base.atmosphere;
        let top = self.top();
        if self.part == Part::BeforeEntry {
            // The pool's walks stay above the top (they end where they first go below it), so
            // no flight of theirs can meet the scene.
            if let Some(acc) = acc {
                if atm.total_tau() > 0.0 {
                    let inf = f64::INFINITY;
                    self.expected_flight(p, d, inf, inf, &w.e, acc, rng, false);
                }
            }
            let s = -rng.next_f64_open0().ln();
            return match (atm.total_tau() > 0.0)
                .then(|| atm.march(p.z, d.z, s, self.to_top(p, d)))
                .flatten()
            {
                Some(t) => {
                    self.channels.layers.carry(&mut w.e[..nc], p.z, d.z, t);
                    let q = p + d * t;
                    w.layer = atm.layer_at_altitude(q.z);
                    self.base.collision_at(q)
                }
                None => Event::Escape,
            };
        }
        let (reach, hit) = self.base.first_hit(p, d);
        let t_hit = hit.map_or(f64::INFINITY, |h| h.t);
        if let Some(acc) = acc {
            if atm.total_tau() > 0.0 {
                self.expected_flight(p, d, reach, t_hit, &w.e, acc, rng, w.entered);
            }
        }
        let s = -rng.next_f64_open0().ln();
        let t_coll = if atm.total_tau() > 0.0 {
            atm.march(p.z, d.z, s, t_hit)
        } else {
            None
        };
        // A straight flight goes below the top iff one of its ends does.
        if let Some(t) = t_coll {
            self.channels.layers.carry(&mut w.e[..nc], p.z, d.z, t);
            let q = p + d * t;
            w.entered |= p.z < top || q.z < top;
            w.layer = atm.layer_at_altitude(q.z);
            self.base.collision_at(q)
        } else if let Some(h) = hit {
            self.channels.layers.carry(&mut w.e[..nc], p.z, d.z, h.t);
            w.entered = true;
            w.hit = Some(h);
            Event::Surface(h)
        } else {
            w.entered |= p.z < top;
            Event::Escape
        }
    }

    /// The reference's split (as [`SceneInLayers`]'), each branch with its own factors.
    fn flight_split(
        &self,
        p: DVec3,
        d: DVec3,
        w: &mut SceneChannelPath<'a>,
        acc: Option<&mut [f64; SCENE_CHANNELS]>,
        rng: &mut Stream,
    ) -> Option<Split<'_, DVec3, SurfaceHit>> {
        let nc = self.nc();
        let atm = self.base.atmosphere;
        let top = self.top();
        if self.part == Part::BeforeEntry {
            // The pool's walks split their flights too (or the before-part's variance per
            // walk is many times the pixels'): a flight ends at the top, where the walk ends,
            // or at TOA.
            if !self.base.can_split(d) {
                return None;
            }
            let inf = f64::INFINITY;
            let f = self.base.split_ending(p, d, inf, None, self.to_top(p, d))?;
            if let Some(acc) = acc {
                self.expected_flight(p, d, inf, inf, &w.e, acc, rng, false);
            }
            let t = self.base.forced_distance(p, d, &f, rng);
            let q = p + d * t;
            w.e_coll = w.e;
            self.channels.layers.carry(&mut w.e_coll[..nc], p.z, d.z, t);
            w.layer = atm.layer_at_altitude(q.z);
            return Some(Split {
                p_collision: f.p_collision,
                collision: self.base.collision_at(q),
                end: Event::Escape,
            });
        }
        let f = self.base.flight_to_split(p, d)?;
        let hit = f.hit;
        if let Some(acc) = acc {
            self.expected_flight(p, d, f.reach, f.t_hit, &w.e, acc, rng, w.entered);
        }
        let t = self.base.forced_distance(p, d, &f, rng);
        let q = p + d * t;
        w.e_coll = w.e;
        w.entered_coll = w.entered || p.z < top || q.z < top;
        self.channels.layers.carry(&mut w.e_coll[..nc], p.z, d.z, t);
        w.layer = atm.layer_at_altitude(q.z);
        let end = match hit {
            Some(h) => {
                self.channels.layers.carry(&mut w.e[..nc], p.z, d.z, h.t);
                w.entered = true;
                w.hit = Some(h);
                Event::Surface(h)
            }
            None => {
                w.entered |= p.z < top;
                Event::Escape
            }
        };
        Some(Split {
            p_collision: f.p_collision,
            collision: self.base.collision_at(q),
            end,
        })
    }

    /// Per channel `ω_ref·(σ_c/σ_ref)·P_c·e_c·T_c·V` at a sampled collision (`local_estimate =
    /// "collision"`).
    fn collision_estimate(
        &self,
        pos: DVec3,
        omega: f64,
        _: &PhaseFunction,
        d: DVec3,
        w: &mut SceneChannelPath<'a>,
        acc: &mut [f64; SCENE_CHANNELS],
    ) {
        if !self.part.scores(w.entered) || !(pos.z > self.top() || self.base.sees_sun(pos)) {
            return;
        }
        let mut rp = [0.0; SCENE_CHANNELS];
        self.ratio_phase(w.layer, self.base.sun.dot(d), &mut rp);
        for c in 0..self.nc() {
            acc[c] = omega * rp[c] * w.e[c] * self.t_sun(c, pos.z);
        }
    }

    /// The reference's transmittance times visibility (the channels' own transmittances are
    /// applied by the weight).
    #[inline]
    fn sun_at(&self, p: DVec3) -> f64 {
        Geometry::<super::weight::Scalar>::sun_at(&self.base, p)
    }
    #[inline]
    fn surface(&self, h: &SurfaceHit) -> SurfaceAt<'_> {
        Geometry::<super::weight::Scalar>::surface(&self.base, h)
    }
    /// The visibility of the Sun from a hit, 0 or 1 (a shadow ray; the channels' solar
    /// transmittances are applied by the weight).
    #[inline]
    fn sun_at_surface(&self, h: &SurfaceHit) -> f64 {
        let start = self.base.scene.offset(h.point, h.normal, self.base.sun);
        if self.base.sees_sun(start) {
            1.0
        } else {
            0.0
        }
    }
    #[inline]
    fn leave(&self, h: &SurfaceHit, d: DVec3) -> DVec3 {
        self.base.scene.offset(h.point, h.normal, d)
    }
    #[inline]
    fn solver(&self, h: &SurfaceHit) -> super::solver::SolverSpec {
        self.base.scene.solver(h.material)
    }
}
