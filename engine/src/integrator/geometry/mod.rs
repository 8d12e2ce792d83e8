//! The media a backward path crosses, as a type: the [`backward`](super::backward) estimator is
//! generic over [`Geometry`] and monomorphised for each.
//!
//! | geometry | position | surface |
//! |---|---|---|
//! | [`layers::Layers`] | optical depth τ from TOA (plane-parallel layers) | flat [`Bsdf`](crate::bsdf::Bsdf) |
//! | [`shells::Shells`] | planet-centred point and shell index (spherical shells) | the ground sphere's BRDF in the local vertical's frame |
//! | [`scene_layers::SceneInLayers`] | scene point (m) under plane-parallel layers | scene materials at BVH hits |
//! | [`scene_clouds::SceneCloudsInLayers`] | scene point (m) under layers with a gridded cloud field | scene materials at BVH hits |
//! | [`scene_shells::SceneInShells`] | planet-centred point and shell of a scene bent onto the planet | scene materials at BVH hits |
//!
//! A geometry samples flights exactly (optical depths summed layer by layer or shell by shell),
//! knows the Sun's transmittance (and the scene's visibility) from any point, and gives the
//! *expected* next-event estimate of a flight's next collision: exactly along the flight where
//! that has a closed form (layers above any geometry), otherwise by stratified or forced
//! collision points with their shadow rays (unbiased either way).

pub mod layers;
pub mod scene_clouds;
pub mod scene_layers;
pub mod scene_shells;
pub mod shells;

use glam::DVec3;

use super::surface::SurfaceAt;
use super::weight::Weight;
use crate::atmosphere::spherical::{ShellEnd, SphericalShell};
use crate::phase::PhaseFunction;
use crate::rng::Stream;

/// How a flight ends.
pub enum Event<'a, P, H> {
    /// The path leaves the medium (through its top, or is lost below it).
    Escape,
    /// A collision in the atmosphere at `pos`, in a layer of albedo `omega`.
    Collision {
        pos: P,
        omega: f64,
        phase: &'a PhaseFunction,
    },
    /// The path reaches a surface.
    Surface(H),
}

/// A flight split in two (forced collision with splitting, [`Geometry::flight_split`]): the
/// branch that collides before the flight's end, drawn from the collision density conditioned
/// on colliding, carries `p_collision`; the uncollided branch (`end`: the surface hit, or the
/// escape) carries `1 − p_collision`. Both are followed, so the path's choice between them is
/// no longer a source of variance.
pub struct Split<'a, P, H> {
    /// Probability that the flight collides before its end, in (0, 1) (0 only where a
    /// geometry could not place the collision: that branch then carries nothing).
    pub p_collision: f64,
    /// The forced collision (always [`Event::Collision`]).
    pub collision: Event<'a, P, H>,
    /// Where the uncollided flight ends ([`Event::Surface`] or [`Event::Escape`]).
    pub end: Event<'a, P, H>,
}

/// The Sun of a geometry: its direction and the normalization of scores.
#[derive(Clone, Copy, Debug)]
pub struct Light {
    /// Unit vector towards the Sun.
    pub sun: DVec3,
    /// The factor that turns a path's score into `π·L/(E0·μ)`: π/μ, μ the cosine of the solar
    /// zenith angle at the target (1 when the Sun is down there).
    pub normalization: f64,
}

impl Light {
    pub fn new(sun: DVec3, mu: f64) -> Self {
        Light {
            sun,
            normalization: std::f64::consts::PI / mu,
        }
    }
}

/// A medium with its surfaces, seen by the backward estimator carrying weight `W`. The
/// geometries of this folder serve every weight; a weight with its own medium (the spectral
/// channels of [`backward_alis`](super::backward_alis)) implements it for itself only.
pub trait Geometry<W: Weight> {
    /// A path position.
    type Pos: Copy;
    /// A surface hit.
    type Hit;

    /// The Sun as this geometry sees it.
    fn light(&self) -> Light;

    /// Sample the flight from `pos` along `d`: one random number for the free path, drawn
    /// after the expected estimate. With `acc`, first add to it the expected value over the
    /// flight's next collision of `ω·P(s·d)·T_sun·V` (without 1/4π), via
    /// [`Weight::accumulate`] (it may draw random numbers of its own). `w` is the path's weight
    /// (a geometry may carry weights along the flight).
    fn flight(
        &self,
        pos: Self::Pos,
        d: DVec3,
        w: &mut W,
        acc: Option<&mut W::Phase>,
        rng: &mut Stream,
    ) -> Event<'_, Self::Pos, Self::Hit>;

    /// [`Self::flight`] split in two ([`Split`]): the same expected estimate into `acc`, then one
    /// random number for the forced collision's optical path. `None` (touching neither `acc`
    /// nor `rng`) where the geometry cannot split this flight (the default; flights that cannot
    /// collide, horizontal ones); the caller then calls [`Self::flight`].
    fn flight_split(
        &self,
        _pos: Self::Pos,
        _d: DVec3,
        _w: &mut W,
        _acc: Option<&mut W::Phase>,
        _rng: &mut Stream,
    ) -> Option<Split<'_, Self::Pos, Self::Hit>> {
        None
    }

    /// Add to `acc` the next-event estimate (`ω·P(s·d)·T_sun·V`, without 1/4π) of a sampled
    /// collision at `pos` (used with `local_estimate = "collision"`).
    fn collision_estimate(
        &self,
        pos: Self::Pos,
        omega: f64,
        phase: &PhaseFunction,
        d: DVec3,
        _w: &mut W,
        acc: &mut W::Phase,
    ) {
        let t = self.sun_at(pos);
        if t > 0.0 {
            W::accumulate(acc, phase, self.light().sun.dot(d), omega, t);
        }
    }

    /// How many plane mirrors relay sunlight to this geometry's surfaces (scene geometries;
    /// none by default).
    fn mirror_count(&self) -> usize {
        0
    }

    /// The direction from which mirror `k` relays sunlight to the surfaces (the Sun's image in
    /// it), when the Sun lights its face.
    fn mirror_image(&self, _k: usize) -> Option<DVec3> {
        None
    }

    /// The sunlight mirror `k` relays to the surface hit `h` from direction `image`, in units of
    /// the Sun's irradiance: the mirror's Fresnel reflectance times the Sun's transmittance to
    /// the mirror point and on to `h`, 0 when `image` does not meet that mirror first or the Sun
    /// does not reach it.
    fn sun_via_mirror(&self, _h: &Self::Hit, _k: usize, _image: DVec3) -> f64 {
        0.0
    }

    /// Whether the Sun shines (false: `illumination.type = "none"`, thermal emission only: the
    /// estimator then makes no next-event estimate).
    fn sun_shines(&self) -> bool {
        true
    }

    /// Thermal emission a flight from `pos` along `d` gathers in expectation, in tally units:
    /// the volume sources' `(1 − ω)·B` at its next collision, and the surface's `ε·B(T_s)` when
    /// it reaches the ground, each times the probability of that end (0 for geometries without
    /// emission). `w` is the path's weight (a geometry whose weights carry per-channel factors
    /// weighs the channels' emissions by them; the estimator then scores `w`'s common part
    /// times the result). A geometry without a closed form may estimate it without bias from
    /// random numbers of `rng` (drawn only when it emits).
    fn flight_emission(&self, _pos: Self::Pos, _d: DVec3, _w: &W, _rng: &mut Stream) -> f64 {
        0.0
    }

    /// Lamps' light that the air scatters into a path along its next flight from `pos` along
    /// `d`, in expectation over the flight's next collision (the expected value of
    /// `ω·P(l̂·d)/(4π)·I·T·V/r²` there), in tally units: one lamp drawn from the run's light
    /// tree and one point of the flight drawn in proportion to that lamp's 1/r² (equi-angular
    /// sampling; a collision-point estimate would have infinite variance near a point lamp),
    /// from random numbers of `rng` (`sources/lamps/`). 0, drawing nothing, for geometries
    /// and runs without lamps.
    fn lamps_along_flight(&self, _pos: Self::Pos, _d: DVec3, _rng: &mut Stream) -> f64 {
        0.0
    }

    /// Lamps' light that `surface` at hit `h` sends towards `wo`: `f·|cos|·I·T·V/r²` in tally
    /// units, one lamp drawn as in [`Geometry::lamps_along_flight`].
    fn lamps_at_surface(
        &self,
        _h: &Self::Hit,
        _surface: &SurfaceAt,
        _wo: DVec3,
        _rng: &mut Stream,
    ) -> f64 {
        0.0
    }

    /// The Sun's transmittance times the scene's visibility at an atmospheric point.
    fn sun_at(&self, pos: Self::Pos) -> f64;
    /// The surface at a hit.
    fn surface(&self, hit: &Self::Hit) -> SurfaceAt<'_>;
    /// The Sun's transmittance times visibility (a shadow ray) at a hit.
    fn sun_at_surface(&self, hit: &Self::Hit) -> f64;
    /// Where a path leaving a hit along `d` starts.
    fn leave(&self, hit: &Self::Hit, d: DVec3) -> Self::Pos;

    /// The radiometry solver of the surface at a hit (`solver.rs`; default: `generic`, one
    /// direction per bounce).
    fn solver(&self, _hit: &Self::Hit) -> super::solver::SolverSpec {
        super::solver::SolverSpec::default()
    }
}

/// Collision points per flight of the stratified next-event estimate in spherical shells.
pub const NEE_STRATA: usize = 4;

/// Stratified estimate of the next collision's next-event estimate along the flight from `p`
/// (shell `l`) along `d`, for a collision within optical depth `tau_end` of the start: K =
/// [`NEE_STRATA`] collision points drawn by stratified inversion of the optical depth (one
/// random number), each weighted by P(collision within `tau_end`)/K. Unbiased for the
/// expectation the collision NEE estimates. `seen(q, lq)` is the Sun's transmittance (times
/// any visibility) from a point. Adds `P/K·Σ ω·P(s·d)·seen` to `acc` (nothing, and no random
/// number, when the flight cannot collide).
#[allow(clippy::too_many_arguments)]
pub(crate) fn stratified_estimate<W: Weight>(
    shell: &SphericalShell,
    p: DVec3,
    l: usize,
    d: DVec3,
    tau_end: f64,
    sun: DVec3,
    acc: &mut W::Phase,
    rng: &mut Stream,
    seen: impl Fn(DVec3, usize) -> f64,
) {
    let p_coll = -(-tau_end).exp_m1();
    if p_coll <= 0.0 {
        return;
    }
    let xi = rng.next_f64();
    let cos = sun.dot(d);
    let k = p_coll / NEE_STRATA as f64;
    for j in 0..NEE_STRATA {
        let u = (j as f64 + xi) / NEE_STRATA as f64;
        let s_j = -(-u * p_coll).ln_1p();
        if let ShellEnd::Collision(q, lq) = shell.fly(p, l, d, s_j) {
            let omega = shell.albedo(lq);
            if omega > 0.0 {
                let t = seen(q, lq);
                if t > 0.0 {
                    W::accumulate(acc, shell.phase(lq), cos, omega, t * k);
                }
            }
        }
    }
}
