//! The backward (adjoint) estimator: paths leave the sensor, and at every interaction the
//! radiance scattered towards the sensor by the directly transmitted sunlight is added
//! (next-event estimation). One function, generic over the path [`Weight`] (scalar or Mueller
//! matrix) and the [`Geometry`] (plane-parallel layers, spherical shells, a 3D scene inside
//! either), monomorphised for each pair.
//!
//! * collision with single-scattering albedo ω: `w·ω·P(s·d)/(4π)·T_sun·V` (polarized: the
//!   unpolarized sunlight scattered through `F` into the path's frame, [`Adjoint`]);
//! * surface hit: `w·f(s, −d)·cos θ_s·T_sun·V`;
//! * lamps (scene geometries of runs with `[[lights]]`, [`Geometry::lamps_at_surface`] and
//!   [`Geometry::lamps_along_flight`]): at every surface hit one lamp's `f·|cos|·I·T·V/r²`
//!   over its probability, and at every flight the expected `ω·P/(4π)·I·T·V/r²` of its next
//!   collision (equi-angular sampling along the flight);
//! * thermal emission (geometries that have it, [`Geometry::flight_emission`]): at every
//!   flight, `w` times the expected emission of the flight's next collision (`(1 − ω)·B`) and,
//!   where the flight reaches the ground, of the surface (`ε·B(T_s)` times the transmittance),
//!   both in closed form; without a Sun ([`Geometry::sun_shines`]) no next-event estimate is made.
//!
//! By default (`integrator.local_estimate = "expected"`) the collision's estimate is replaced by
//! its expectation over the next collision's position along each flight, which the geometry
//! provides ([`Geometry::flight`]); nothing is then scored at sampled collisions. `"collision"`
//! scores there instead (a cross-check; both are unbiased).
//!
//! The path continues in a direction drawn from the phase function (reciprocal; at peaked phase
//! functions mixed with draws about the Sun direction, [`PeakSampling`]) or the surface's
//! sampler. Absorption multiplies the weight by ω (survival biasing); Russian roulette after
//! `rr_depth` orders (`survives`), splitting of heavy weights (`split_count`); orders beyond
//! `max_depth` are not counted. A sample is
//! `π·L/(E0·μ)` split into single scattering (first interaction) and the rest. The sky has no
//! diffuse source above TOA and the direct solar beam (a delta in direction) is never seen.

use glam::DVec3;

use super::geometry::{Event, Geometry, Split};
use super::peak_sampling::PeakSampling;
use super::settings::IntegratorSettings;
use super::solver::{self, SolverSpec};
use super::surface::SurfaceAt;
use super::weight::{
    split_count, survives, MuellerPath, OrderSplit, Scalar, Weight, INV_4PI, MAX_SPLITS,
};
use crate::rng::Stream;

/// How a weight scores sunlight arriving at a path vertex.
pub trait Adjoint: Weight {
    /// Add `k·w·acc` for an accumulation of scattering `acc` (`ω·P·T`, or matrices) at a
    /// flight along `d`.
    fn see_sun_volume(
        &self,
        t: &mut Self::Tally,
        order: u32,
        acc: &Self::Phase,
        d: DVec3,
        sun: DVec3,
        k: f64,
    );
    /// Add the sunlight reflected by `surface` into the path arriving along `d`; `visible()`
    /// (the Sun's transmittance times visibility, possibly a shadow ray) is called only where
    /// the surface reflects sunlight at all.
    fn see_sun_surface(
        &self,
        t: &mut Self::Tally,
        order: u32,
        surface: &SurfaceAt,
        d: DVec3,
        sun: DVec3,
        visible: impl FnOnce() -> f64,
    );
    /// Add unpolarized (thermal) radiance `r` (tally units) reaching the path's current vertex
    /// along the path.
    fn see_emission(&self, t: &mut Self::Tally, order: u32, r: f64);
}

impl Adjoint for Scalar {
    #[inline]
    fn see_emission(&self, t: &mut OrderSplit, order: u32, r: f64) {
        t.add(order, self.0 * r);
    }
    #[inline]
    fn see_sun_volume(
        &self,
        t: &mut OrderSplit,
        order: u32,
        acc: &f64,
        _: DVec3,
        _: DVec3,
        k: f64,
    ) {
        t.add(order, self.0 * acc * k);
    }
    #[inline]
    fn see_sun_surface(
        &self,
        t: &mut OrderSplit,
        order: u32,
        surface: &SurfaceAt,
        d: DVec3,
        sun: DVec3,
        visible: impl FnOnce() -> f64,
    ) {
        let f = surface.eval_cos(sun, -d);
        if f > 0.0 {
            let v = visible();
            if v > 0.0 {
                t.add(order, self.0 * f * v);
            }
        }
    }
}

impl Adjoint for MuellerPath {
    #[inline]
    fn see_emission(&self, t: &mut [f64; 5], order: u32, r: f64) {
        self.see_unpolarized(t, order, r);
    }
    #[inline]
    fn see_sun_volume(
        &self,
        t: &mut [f64; 5],
        order: u32,
        acc: &crate::stokes::PhaseMatrix,
        d: DVec3,
        sun: DVec3,
        k: f64,
    ) {
        self.see_sun(t, order, acc, d, sun, k);
    }
    #[inline]
    fn see_sun_surface(
        &self,
        t: &mut [f64; 5],
        order: u32,
        surface: &SurfaceAt,
        d: DVec3,
        sun: DVec3,
        visible: impl FnOnce() -> f64,
    ) {
        let wo = -d;
        match surface.matrix(sun, wo) {
            Some(m) if m.a1 > 0.0 => {
                let c = surface.cos(sun);
                if c > 0.0 {
                    let v = visible();
                    if v > 0.0 {
                        self.see_sun(t, order, &m, d, sun, c * v);
                    }
                }
            }
            Some(_) => {}
            None => {
                let f = surface.eval_cos(sun, wo);
                if f > 0.0 {
                    let v = visible();
                    if v > 0.0 {
                        self.see_unpolarized(t, order, f * v);
                    }
                }
            }
        }
    }
}

/// The weight a backward path starts with at the sensor.
pub trait AtSensor: Weight {
    /// For a path leaving the sensor along `d0`; polarized weights take the meridian frame of
    /// `−d0`, fixed for vertical views by the azimuth `frame_azimuth()` (radians).
    fn at_sensor(d0: DVec3, frame_azimuth: impl Fn() -> f64) -> Self;
}

impl AtSensor for Scalar {
    #[inline]
    fn at_sensor(_: DVec3, _: impl Fn() -> f64) -> Self {
        Scalar(1.0)
    }
}

impl AtSensor for MuellerPath {
    #[inline]
    fn at_sensor(d0: DVec3, frame_azimuth: impl Fn() -> f64) -> Self {
        MuellerPath::at_sensor(crate::stokes::meridian_axis(-d0, frame_azimuth()))
    }
}

/// One path from `start` along `d0` carrying `w`; returns its tally, which times
/// [`Light::normalization`](super::geometry::Light) is `π·L/(E0·μ)`.
pub fn walk<G: Geometry<W>, W: Adjoint>(
    g: &G,
    start: G::Pos,
    d0: DVec3,
    w: W,
    settings: &IntegratorSettings,
    rng: &mut Stream,
) -> W::Tally {
    let sun = g.light().sun;
    // The Sun is the detector of the next-event estimates: P(sun·d) at a flight along d.
    let peak = PeakSampling {
        eps: settings.detector_sampling,
        dirs: std::slice::from_ref(&sun),
    };
    let mut tally = W::zero_tally();
    let mut budget = MAX_SPLITS;
    let state = State {
        pos: start,
        d: d0,
        w,
        order: 1,
        generation: 0,
        forced: 0,
    };
    walk_from(g, state, settings, &peak, rng, &mut tally, &mut budget);
    tally
}

/// Where a path (or a copy of a split path) continues from.
struct State<P, W> {
    pos: P,
    d: DVec3,
    w: W,
    /// Order of the next interaction (1 = first).
    order: u32,
    /// Surface interactions so far (the solvers' generations, `solver.rs`).
    generation: u32,
    /// Flights split so far on this path's line ([`IntegratorSettings::forced_flights`]).
    forced: u32,
}

fn walk_from<G: Geometry<W>, W: Adjoint>(
    g: &G,
    state: State<G::Pos, W>,
    settings: &IntegratorSettings,
    peak: &PeakSampling,
    rng: &mut Stream,
    tally: &mut W::Tally,
    budget: &mut u32,
) {
    let sun = g.light().sun;
    let expected = settings.expected_local_estimate;
    let shines = g.sun_shines();
    let State {
        mut pos,
        mut d,
        mut w,
        mut order,
        mut generation,
        mut forced,
    } = state;
    // A path crossing `null` surfaces: at most this many in a row before it is dropped.
    let mut pass_through = 0u32;
    while order <= settings.max_depth {
        let mut acc = W::zero_phase();
        // Lamps' light scattered along the flight, in expectation (unpolarized).
        let lamp = g.lamps_along_flight(pos, d, rng);
        if lamp > 0.0 {
            w.see_emission(tally, order, lamp);
        }
        let emitted = g.flight_emission(pos, d, &w, rng);
        if emitted > 0.0 {
            w.see_emission(tally, order, emitted);
        }
        let want = (expected && shines).then_some(&mut acc);
        let split = if forced < settings.forced_flights && w.splittable().is_some() {
            g.flight_split(pos, d, &mut w, want, rng)
        } else {
            None
        };
        let (event, split) = match split {
            Some(Split {
                p_collision,
                collision,
                end,
            }) => (end, Some((p_collision, collision))),
            None => {
                let want = (expected && shines).then_some(&mut acc);
                (g.flight(pos, d, &mut w, want, rng), None)
            }
        };
        if expected && shines && W::phase_intensity(&acc) > 0.0 {
            w.see_sun_volume(tally, order, &acc, d, sun, INV_4PI);
        }
        if let Some((p, collision)) = split {
            // Forced collision with splitting: the collided branch (weight × p) is walked to
            // its end first, then this path goes on uncollided (weight × (1 − p)).
            forced += 1;
            let i = w.intensity();
            if let (
                Event::Collision {
                    pos: q,
                    omega,
                    phase,
                },
                Some(mut c),
            ) = (collision, w.splittable())
            {
                c.take_collision_branch();
                c.rescale_to(i * p, i);
                let d2 = collide(
                    g, q, omega, phase, d, &mut c, order, settings, peak, rng, tally,
                );
                let next = State {
                    pos: q,
                    d: d2,
                    w: c,
                    order: order + 1,
                    generation,
                    forced,
                };
                walk_on(g, next, settings, peak, rng, tally, budget);
            }
            w.rescale_to(i * (1.0 - p), i);
            // A flight of optical depth beyond ~37 leaves the uncollided branch no weight in
            // f64 (1 − p rounds to 0): whatever it would score is 0 × its factors. Stop it
            // there: walking on costs time, and a spectral walk's path factors along a long
            // flight, exp(τ_ref − τ_c), can overflow, which would make those zeros 0·∞ = NaN.
            // (The rounding itself drops a spectral channel's exp(−τ_c) where τ_c ≪ τ_ref, as
            // it did before this stop; carrying exp(−s_end) instead of 1 − p would keep it.)
            if w.intensity() == 0.0 {
                break;
            }
        }
        match event {
            Event::Escape => break,
            Event::Collision {
                pos: p,
                omega,
                phase,
            } => {
                pos = p;
                pass_through = 0;
                d = collide(
                    g, p, omega, phase, d, &mut w, order, settings, peak, rng, tally,
                );
            }
            Event::Surface(h) => {
                let solver = g.solver(&h);
                if let SolverSpec::Null {} = solver {
                    // Pass-through: the same flight goes on beyond the surface (memoryless,
                    // so a fresh free path is unbiased); no interaction is counted.
                    pass_through += 1;
                    if pass_through > MAX_PASS_THROUGH {
                        break;
                    }
                    pos = g.leave(&h, d);
                    continue;
                }
                pass_through = 0;
                generation += 1;
                let base = g.surface(&h);
                let mirror = match solver {
                    SolverSpec::Mirror {
                        refractive_index,
                        absorption_index,
                    } => Some(SurfaceAt::Mirror {
                        n: base.normal(),
                        index: (refractive_index, absorption_index),
                    }),
                    _ => None,
                };
                let surface = mirror.as_ref().unwrap_or(&base);
                if mirror.is_none() {
                    let lamp = g.lamps_at_surface(&h, surface, -d, rng);
                    if lamp > 0.0 {
                        w.see_emission(tally, order, lamp);
                    }
                }
                if shines && mirror.is_none() {
                    w.see_sun_surface(tally, order, surface, d, sun, || g.sun_at_surface(&h));
                    // Sunlight relayed by plane mirrors arrives from the Sun's images in them.
                    for k in 0..g.mirror_count() {
                        if let Some(image) = g.mirror_image(k) {
                            w.see_sun_surface(tally, order, surface, d, image, || {
                                g.sun_via_mirror(&h, k, image)
                            });
                        }
                    }
                }
                // How many directions continue the path from this surface.
                let fan = match solver {
                    SolverSpec::Simple {} => break,
                    SolverSpec::Generic {
                        max_generations: Some(gmax),
                        ..
                    } if generation >= gmax => break,
                    SolverSpec::Generic {
                        first_bounce_samples,
                        decay,
                        ..
                    } => Fan::Sampled(solver::generic_samples(
                        first_bounce_samples,
                        decay,
                        generation,
                    )),
                    SolverSpec::Classic { zeniths, azimuths } if generation == 1 => {
                        Fan::Classic(zeniths, azimuths)
                    }
                    _ => Fan::Sampled(1),
                };
                if fan.is_fan() && w.splittable().is_some() {
                    // Fan out: each copy continues on the same stream, one after another.
                    fan_out(
                        g, &h, surface, &w, d, order, generation, forced, fan, settings, peak, rng,
                        tally, budget,
                    );
                    return;
                }
                match w.reflect(surface, d, rng) {
                    Some(d2) => {
                        pos = g.leave(&h, d2);
                        d = d2;
                    }
                    None => break,
                }
            }
        }
        order += 1;
        if !survives(&mut w, order, settings.rr_depth, rng) {
            break;
        }
        if let Some((copy, n)) = split_count(&w, budget) {
            for _ in 0..n {
                let next = State {
                    pos,
                    d,
                    w: copy.splittable().expect("a split weight copies"),
                    order,
                    generation,
                    forced,
                };
                walk_from(g, next, settings, peak, rng, tally, budget);
            }
            return;
        }
    }
}

/// Continue a branch (a forced collision's, or a surface fan's copy) from `state`, whose `order`
/// is its next interaction's, once it survives Russian roulette at that order.
fn walk_on<G: Geometry<W>, W: Adjoint>(
    g: &G,
    mut state: State<G::Pos, W>,
    settings: &IntegratorSettings,
    peak: &PeakSampling,
    rng: &mut Stream,
    tally: &mut W::Tally,
    budget: &mut u32,
) {
    if survives(&mut state.w, state.order, settings.rr_depth, rng) {
        walk_from(g, state, settings, peak, rng, tally, budget);
    }
}

/// A collision at `p` of a path arriving along `d`: the classic next-event estimate there
/// (with `local_estimate = "collision"`), then the scattering; returns the new direction.
#[allow(clippy::too_many_arguments)]
#[inline]
fn collide<G: Geometry<W>, W: Adjoint>(
    g: &G,
    p: G::Pos,
    omega: f64,
    phase: &crate::phase::PhaseFunction,
    d: DVec3,
    w: &mut W,
    order: u32,
    settings: &IntegratorSettings,
    peak: &PeakSampling,
    rng: &mut Stream,
    tally: &mut W::Tally,
) -> DVec3 {
    if !settings.expected_local_estimate && g.sun_shines() && omega > 0.0 {
        let mut a = W::zero_phase();
        g.collision_estimate(p, omega, phase, d, w, &mut a);
        if W::phase_intensity(&a) > 0.0 {
            w.see_sun_volume(tally, order, &a, d, g.light().sun, INV_4PI);
        }
    }

    w.scatter(phase, omega, d, peak, rng)
}

/// The largest f64 below 1.
const LAST_BELOW_ONE: f64 = 1.0 - f64::EPSILON / 2.0;

/// Most `null` surfaces a path crosses in a row before it is dropped (a guard against a ray
/// caught between coincident pass-through surfaces).
pub(crate) const MAX_PASS_THROUGH: u32 = 64;

/// How a surface continues a path: `n` directions drawn from its sampler, or the `classic`
/// quadrature's `n_θ × n_φ` fixed nodes.
#[derive(Clone, Copy)]
enum Fan {
    Sampled(u32),
    Classic(u32, u32),
}

impl Fan {
    fn is_fan(self) -> bool {
        !matches!(self, Fan::Sampled(1))
    }
}

/// Continue the path `w` (arriving along `d` at hit `h` of `surface`) in every direction of
/// `fan`: each copy reflects (a sampled direction with weight `1/n`, or a quadrature node with
/// its own weight) and walks on from there, before the next copy starts.
#[allow(clippy::too_many_arguments)]
fn fan_out<G: Geometry<W>, W: Adjoint>(
    g: &G,
    h: &G::Hit,
    surface: &SurfaceAt,
    w: &W,
    d: DVec3,
    order: u32,
    generation: u32,
    forced: u32,
    fan: Fan,
    settings: &IntegratorSettings,
    peak: &PeakSampling,
    rng: &mut Stream,
    tally: &mut W::Tally,
    budget: &mut u32,
) {
    let continue_from =
        |c: W, d2: DVec3, rng: &mut Stream, tally: &mut W::Tally, budget: &mut u32| {
            let next = State {
                pos: g.leave(h, d2),
                d: d2,
                w: c,
                order: order + 1,
                generation,
                forced,
            };
            walk_on(g, next, settings, peak, rng, tally, budget);
        };
    match fan {
        Fan::Sampled(n) => {
            // Stratified: copy j draws its sampler's two numbers from cell j of an a × b grid
            // of [0, 1)² (cells of equal area, copies of weight 1/n: the sum is unbiased), so
            // together they cover the hemisphere evenly (a cosine sampler's first number sets
            // the zenith, the second the azimuth). With the `sobol` sampler the sample's first
            // fan takes its numbers from points of a Sobol sequence instead
            // (`Stream::take_fan`), each copy then uniform on its own; the sample's own
            // quasi-random state is put back after the fan.
            let (a, b) = solver::fan_strata(n);
            let qmc = rng.take_fan(n);
            let saved = qmc.map(|_| rng.qmc_state());
            // (x + r)/m can round up to 1 when r is Philox's largest value.
            let cell =
                |x: u32, m: u32, r: f64| ((f64::from(x) + r) / f64::from(m)).min(LAST_BELOW_ONE);
            let k = 1.0 / f64::from(n);
            for j in 0..n {
                let u = match &qmc {
                    Some(points) => {
                        points.enter(j, rng);
                        [rng.next_f64(), rng.next_f64(), rng.next_f64()]
                    }
                    None => [
                        cell(j / b, a, rng.next_f64()),
                        cell(j % b, b, rng.next_f64()),
                        rng.next_f64(),
                    ],
                };
                let Some(sample) = surface.sample_at(-d, u) else {
                    continue;
                };
                let drawn = SurfaceAt::Forced {
                    base: surface,
                    sample,
                };
                let mut c = w.splittable().expect("fan-out weights copy");
                let i = c.intensity();
                if i > 0.0 {
                    c.rescale_to(i * k, i);
                }
                if let Some(d2) = c.reflect(&drawn, d, rng) {
                    continue_from(c, d2, rng, tally, budget);
                }
            }
            if let Some(saved) = saved {
                rng.restore_qmc(saved);
            }
        }
        Fan::Classic(nz, na) => {
            let wo = -d;
            let nodes =
                solver::classic_nodes(surface.normal(), nz, na, |wi| surface.eval_cos(wi, wo));
            for node in nodes {
                if node.weight <= 0.0 {
                    continue;
                }
                let forced = SurfaceAt::Forced {
                    base: surface,
                    sample: node,
                };
                let mut c = w.splittable().expect("fan-out weights copy");
                if let Some(d2) = c.reflect(&forced, d, rng) {
                    continue_from(c, d2, rng, tally, budget);
                }
            }
        }
    }
}
