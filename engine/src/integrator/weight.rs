//! The weight a path carries, as a type: the estimators ([`forward`](super::forward),
//! [`backward`](super::backward)) are generic over it and monomorphised, so polarization costs
//! nothing in scalar runs and needs no walk of its own.
//!
//! | type | estimator | state | tally per cell |
//! |---|---|---|---|
//! | [`Scalar`] | both | `w` (intensity weight) | (single, multiple) |
//! | [`StokesPhoton`] | forward | Stokes vector `S` and its frame axis `e1` | (I single, I multiple, Q, U, V) |
//! | [`MuellerPath`] | backward | 4×4 path matrix `T` and the segment's frame axis `e1` | (I single, I multiple, Q, U, V) |
//!
//! Conventions (Stokes frames, phase matrices) are those of [`crate::stokes`]. The scalar weight
//! draws a new direction after a collision from the phase function `a1 = P11` and a uniform
//! azimuth, and multiplies itself by `ω`. The polarized weights draw (Θ, φ) jointly from the
//! density of the scattered intensity, `(F·S)_I/4π` ([`super::stokes_sampling`]), and multiply
//! themselves by `ω·F/(F·S)_I·I`: their intensity weight is multiplied by exactly ω, as the
//! scalar one (no compounding polarization factor in thick media). Surface bounces draw from the
//! surface's sampler: depolarizing surfaces keep the intensity only, polarizing ones (the ocean)
//! apply their reflection matrix in the plane of incidence, weighted by the sampler's
//! `f·cos/pdf` over `a1` (an intensity factor in [0, 2] per bounce).
//!
//! The *sun* is unpolarized: next-event estimates scatter `(1, 0, 0, 0)` into the path.
//!
//! Each weight also says what an expected estimate accumulates along a flight
//! ([`Weight::Phase`]): `ω·P(cos Θ)` (scalar, one phase-function evaluation) or `ω·F(Θ)` (a phase
//! matrix), each times the geometry's transmittance integral.

use glam::{DMat4, DVec3, DVec4};

use super::peak_sampling::PeakSampling;
use super::stokes_sampling::{self, sample_scattered};
use super::surface::SurfaceAt;
use super::RR_THRESHOLD;
use crate::accum::Accum;
use crate::phase::PhaseFunction;
use crate::rng::Stream;
use crate::stokes::{any_perpendicular, rotate_to, scatter, PhaseMatrix};

/// 1/(4π).
pub(crate) const INV_4PI: f64 = 0.25 * std::f64::consts::FRAC_1_PI;

/// What every path weight does: scatter, reflect, die by roulette, and say how a flight's
/// expected estimate accumulates phase functions.
pub trait Weight: Sized {
    /// Per-flight accumulation of `ω·P` (or `ω·F`) times transmittance integrals.
    type Phase: Copy;
    /// One path's scores for one cell.
    type Tally: Copy;

    fn zero_phase() -> Self::Phase;
    fn zero_tally() -> Self::Tally;
    /// `acc += ω·P(cos)·k` (scalar) or `ω·F(cos)·k`.
    fn accumulate(acc: &mut Self::Phase, phase: &PhaseFunction, cos: f64, omega: f64, k: f64);
    /// The intensity part of an accumulation (> 0 when there is something to score).
    fn phase_intensity(acc: &Self::Phase) -> f64;

    /// The path's intensity weight (roulette acts on it).
    fn intensity(&self) -> f64;
    /// Scale the weight so that its intensity becomes `target` (it is `i` now).
    fn rescale_to(&mut self, target: f64, i: f64);

    /// Scatter at a collision along `d` with single-scattering albedo `omega`: returns the new
    /// direction (two random numbers, three where `peak` is active: [`PeakSampling`]).
    fn scatter(
        &mut self,
        phase: &PhaseFunction,
        omega: f64,
        d: DVec3,
        peak: &PeakSampling,
        rng: &mut Stream,
    ) -> DVec3;

    /// Bounce off `surface` arriving along `d`: returns the new direction, `None` when the
    /// surface absorbs the path.
    fn reflect(&mut self, surface: &SurfaceAt, d: DVec3, rng: &mut Stream) -> Option<DVec3>;

    /// A copy of this weight for splitting (`split_count`); `None`: never split (ALIS).
    fn splittable(&self) -> Option<Self> {
        None
    }

    /// Turn this copy of a split flight's weight into the forced collision's branch
    /// ([`Geometry::flight_split`](super::geometry::Geometry::flight_split) leaves the weight
    /// as the uncollided branch's). Weights whose geometry multiplies them along the flight
    /// (the spectral channels of 3D scenes, `scene_alis.rs`) hold both branches' factors and
    /// switch here; the default has nothing to switch.
    fn take_collision_branch(&mut self) {}

    /// Add the tally of one path, each score times `k`, to `cell` of `acc`.
    fn record(acc: &mut Accum, cell: usize, t: &Self::Tally, k: f64);
    /// `t += ratio·other`, channel by channel (`ratio[c]` for the scores of accumulator cell
    /// `c`; weights with one cell use `ratio[0]`): a second source's path joins the sample of
    /// the first (the Moon with the Sun, `blocks/walks.rs`).
    fn add_tally(t: &mut Self::Tally, other: &Self::Tally, ratio: &[f64]);
    /// A fresh accumulator of `cells` cells for this weight.
    fn accum(cells: usize) -> Accum;
    /// First-order splitting (`integrator.first_order_splits`, `blocks/walks.rs`): replace `t`'s
    /// first-order (single-scattering) scores by their mean over `t` and the `k − 1`
    /// first-order walks whose tallies `others` sums; higher orders stay. Not for weights whose
    /// tally does not separate the orders (Stokes: the resolver refuses splitting there).
    fn mean_first_order(t: &mut Self::Tally, others: &Self::Tally, k: u32);
}

/// Russian roulette on the intensity: after `rr_depth` orders a path whose intensity is below
/// [`RR_THRESHOLD`] survives with probability `I/RR_THRESHOLD` and is rescaled to the threshold.
/// One random number per call (whatever the intensity), so scalar and polarized paths stay in
/// step. Returns false when the path ends.
#[inline]
pub(crate) fn survives<W: Weight>(w: &mut W, order: u32, rr_depth: u32, rng: &mut Stream) -> bool {
    let i = w.intensity();
    if i <= 0.0 {
        return false;
    }
    if order > rr_depth {
        let u = rng.next_f64();
        if i < RR_THRESHOLD {
            if u < i / RR_THRESHOLD {
                w.rescale_to(RR_THRESHOLD, i);
            } else {
                return false;
            }
        }
    }
    true
}

/// Paths whose intensity weight exceeds this are split (DDIS and BRDF weights can grow).
pub(crate) const SPLIT_ABOVE: f64 = 2.0;
/// At most this many copies per split, and this many splits per walk.
const MAX_COPIES: f64 = 8.0;
pub(crate) const MAX_SPLITS: u32 = 256;

/// Splitting, the counterpart of Russian roulette for heavy weights: a path whose intensity
/// weight `I` exceeds [`SPLIT_ABOVE`] continues as `n = ⌈I⌉` (at most 8) independent copies of
/// weight `I/n` each (unbiased: the copies' expected scores add up to the path's). Returns the
/// copy and `n`, or `None` (no split, a weight that does not split, or the walk's `budget` of
/// splits spent).
#[inline]
pub(crate) fn split_count<W: Weight>(w: &W, budget: &mut u32) -> Option<(W, usize)> {
    let i = w.intensity();
    if i <= SPLIT_ABOVE || *budget == 0 {
        return None;
    }
    let mut c = w.splittable()?;
    *budget -= 1;
    let n = i.ceil().min(MAX_COPIES);
    c.rescale_to(i / n, i);
    Some((c, n as usize))
}

/// Scores of a scalar path split by scattering order: the first interaction is single
/// scattering, every later one multiple.
#[derive(Clone, Copy, Debug, Default)]
pub struct OrderSplit {
    pub single: f64,
    pub multiple: f64,
}

impl OrderSplit {
    #[inline]
    pub fn add(&mut self, order: u32, v: f64) {
        if order == 1 {
            self.single += v;
        } else {
            self.multiple += v;
        }
    }

    /// `self += k·other`, part by part.
    #[inline]
    pub fn add_scaled(&mut self, other: &OrderSplit, k: f64) {
        self.single += k * other.single;
        self.multiple += k * other.multiple;
    }

    /// First-order splitting: the single part becomes the mean over this path's and the
    /// `k − 1` single parts that `others` sums.
    #[inline]
    pub fn mean_first_order(&mut self, others: &OrderSplit, k: u32) {
        self.single = (self.single + others.single) / f64::from(k);
    }

    /// (single, multiple), each multiplied by `k`.
    #[inline]
    pub fn scaled(&self, k: f64) -> (f64, f64) {
        (self.single * k, self.multiple * k)
    }
}

/// The scalar weight (unpolarized transport).
#[derive(Clone, Copy, Debug)]
pub struct Scalar(pub f64);

impl Weight for Scalar {
    type Phase = f64;
    type Tally = OrderSplit;

    #[inline]
    fn zero_phase() -> f64 {
        0.0
    }
    #[inline]
    fn zero_tally() -> OrderSplit {
        OrderSplit::default()
    }
    #[inline]
    fn accumulate(acc: &mut f64, phase: &PhaseFunction, cos: f64, omega: f64, k: f64) {
        *acc += omega * phase.eval(cos) * k;
    }
    #[inline]
    fn phase_intensity(acc: &f64) -> f64 {
        *acc
    }
    #[inline]
    fn splittable(&self) -> Option<Self> {
        Some(*self)
    }
    #[inline]
    fn intensity(&self) -> f64 {
        self.0
    }
    #[inline]
    fn rescale_to(&mut self, target: f64, _: f64) {
        self.0 = target;
    }
    #[inline]
    fn scatter(
        &mut self,
        phase: &PhaseFunction,
        omega: f64,
        d: DVec3,
        peak: &PeakSampling,
        rng: &mut Stream,
    ) -> DVec3 {
        if !peak.active(phase) {
            self.0 *= omega;
            return sample_scattered(phase, d, rng);
        }
        let axis = peak.choose(rng).unwrap_or(d);
        let d2 = sample_scattered(phase, axis, rng);
        let p = phase.eval(d.dot(d2));
        let mix = peak.mixture(phase, p, d2);
        self.0 *= if mix > 0.0 { omega * p / mix } else { 0.0 };
        d2
    }
    #[inline]
    fn reflect(&mut self, surface: &SurfaceAt, d: DVec3, rng: &mut Stream) -> Option<DVec3> {
        let s = surface.sample(-d, rng)?;
        self.0 *= s.weight;
        Some(s.wi)
    }
    #[inline]
    fn record(acc: &mut Accum, cell: usize, t: &OrderSplit, k: f64) {
        acc.add(cell, t.single * k, t.multiple * k);
    }
    fn add_tally(t: &mut OrderSplit, other: &OrderSplit, ratio: &[f64]) {
        t.add_scaled(other, ratio[0]);
    }
    fn mean_first_order(t: &mut OrderSplit, others: &OrderSplit, k: u32) {
        t.mean_first_order(others, k);
    }
    fn accum(cells: usize) -> Accum {
        Accum::new(cells)
    }
}

/// (I single, I multiple, Q, U, V) of one polarized path.
pub type StokesTally = [f64; 5];

/// The parts of [`Weight`] shared by both polarized weights: phase matrices accumulate, Stokes
/// tallies record.
macro_rules! polarized_phase {
    () => {
        type Phase = PhaseMatrix;
        type Tally = StokesTally;

        #[inline]
        fn zero_phase() -> PhaseMatrix {
            ZERO_MATRIX
        }
        #[inline]
        fn zero_tally() -> StokesTally {
            [0.0; 5]
        }
        #[inline]
        fn accumulate(acc: &mut PhaseMatrix, phase: &PhaseFunction, cos: f64, omega: f64, k: f64) {
            acc.add(&phase.matrix(cos).scaled(omega * k));
        }
        #[inline]
        fn phase_intensity(acc: &PhaseMatrix) -> f64 {
            acc.a1
        }
    };
}

macro_rules! polarized_tally {
    () => {
        fn record(acc: &mut Accum, cell: usize, t: &StokesTally, k: f64) {
            let x = t.map(|v| v * k);
            acc.add_stokes(cell, x[0], x[1], x[2], x[3], x[4]);
        }
        fn add_tally(t: &mut StokesTally, other: &StokesTally, ratio: &[f64]) {
            for (a, b) in t.iter_mut().zip(other) {
                *a += ratio[0] * b;
            }
        }
        fn mean_first_order(_: &mut StokesTally, _: &StokesTally, _: u32) {
            unreachable!("the resolver refuses integrator.first_order_splits with polarization")
        }
        fn accum(cells: usize) -> Accum {
            Accum::new_polarized(cells)
        }
    };
}

/// Accumulated phase matrices start at zero.
const ZERO_MATRIX: PhaseMatrix = PhaseMatrix {
    a1: 0.0,
    b1: 0.0,
    a2: 0.0,
    a3: 0.0,
    b2: 0.0,
    a4: 0.0,
};

/// A direction a forward photon scores towards: `v` (towards the sensor) and the first axis
/// `e_v` of its Stokes frame.
#[derive(Clone, Copy, Debug)]
pub struct Toward {
    pub v: DVec3,
    pub e_v: DVec3,
}

/// A photon's Stokes vector `S` (its first component is the intensity weight) travelling with
/// frame axis `e1` (forward estimator).
#[derive(Clone, Copy, Debug)]
pub struct StokesPhoton {
    pub s: [f64; 4],
    pub e1: DVec3,
}

impl StokesPhoton {
    /// An unpolarized photon of unit weight travelling along `d`.
    pub fn unpolarized(d: DVec3) -> Self {
        StokesPhoton {
            s: [1.0, 0.0, 0.0, 0.0],
            e1: any_perpendicular(d),
        }
    }

    /// Add `k·(F·S scattered from d into to.v, in to.v's frame with axis to.e_v)` to `t`.
    #[inline]
    pub fn send(
        &self,
        t: &mut StokesTally,
        order: u32,
        f: &PhaseMatrix,
        d: DVec3,
        to: Toward,
        k: f64,
    ) {
        let (sv, lv) = scatter(self.s, d, self.e1, to.v, f);
        let sm = rotate_to(sv, to.v, lv, to.e_v);
        add_stokes(t, order, [sm[0] * k, sm[1] * k, sm[2] * k, sm[3] * k]);
    }
}

#[inline]
fn add_stokes(t: &mut StokesTally, order: u32, s: [f64; 4]) {
    t[if order == 1 { 0 } else { 1 }] += s[0];
    t[2] += s[1];
    t[3] += s[2];
    t[4] += s[3];
}

impl Weight for StokesPhoton {
    polarized_phase!();
    #[inline]
    fn splittable(&self) -> Option<Self> {
        Some(*self)
    }
    #[inline]
    fn intensity(&self) -> f64 {
        self.s[0]
    }
    #[inline]
    fn rescale_to(&mut self, target: f64, i: f64) {
        let k = target / i;
        self.s = self.s.map(|x| x * k);
    }
    #[inline]
    fn scatter(
        &mut self,
        phase: &PhaseFunction,
        omega: f64,
        d: DVec3,
        peak: &PeakSampling,
        rng: &mut Stream,
    ) -> DVec3 {
        let i = self.s[0];
        let (q, u) = (self.s[1] / i, self.s[2] / i);
        let smp = stokes_sampling::sample_with(phase, d, self.e1, q, u, peak, rng);
        let (s2, l2) = scatter(self.s, d, self.e1, smp.d2, &smp.f);
        // The density is ∝ the scattered intensity (S'₀ = ω·I), or a DDIS mixture.
        let k = if smp.norm > 0.0 {
            omega / smp.norm
        } else {
            0.0
        };
        self.s = s2.map(|x| x * k);
        self.e1 = l2;
        smp.d2
    }
    #[inline]
    fn reflect(&mut self, surface: &SurfaceAt, d: DVec3, rng: &mut Stream) -> Option<DVec3> {
        let smp = surface.sample(-d, rng)?;
        // Light goes from −(−d) = d into wi: `matrix(towards the light, outgoing)`.
        match surface.matrix(-d, smp.wi) {
            Some(m) if m.a1 > 0.0 => {
                // Light arrives along d, leaves along wi (forward: the photon's own direction).
                let (s2, l2) = scatter(self.s, d, self.e1, smp.wi, &m);
                let k = smp.weight / m.a1;
                self.s = s2.map(|x| x * k);
                self.e1 = l2;
            }
            Some(_) => return None,
            None => {
                self.s = [self.s[0] * smp.weight, 0.0, 0.0, 0.0];
                self.e1 = any_perpendicular(smp.wi);
            }
        }
        Some(smp.wi)
    }
    polarized_tally!();
}

/// Mueller matrix of a phase matrix (row-major layout in the docs; glam is column-major).
#[inline]
fn mueller(f: &PhaseMatrix) -> DMat4 {
    DMat4::from_cols(
        DVec4::new(f.a1, f.b1, 0.0, 0.0),
        DVec4::new(f.b1, f.a2, 0.0, 0.0),
        DVec4::new(0.0, 0.0, f.a3, -f.b2),
        DVec4::new(0.0, 0.0, f.b2, f.a4),
    )
}

/// Rotation of Stokes vectors from first axis `from` to first axis `to` (both ⊥ `w`).
#[inline]
fn rotation(w: DVec3, from: DVec3, to: DVec3) -> DMat4 {
    let (c, s) = (to.dot(from), to.dot(w.cross(from)));
    let (c2, s2) = (c * c - s * s, 2.0 * c * s);
    DMat4::from_cols(
        DVec4::new(1.0, 0.0, 0.0, 0.0),
        DVec4::new(0.0, c2, -s2, 0.0),
        DVec4::new(0.0, s2, c2, 0.0),
        DVec4::new(0.0, 0.0, 0.0, 1.0),
    )
}

/// Scattering-plane frame for light going from propagation direction `w_in` to `w_out`:
/// (perpendicular axis r, parallel axis of the incoming light, parallel axis of the outgoing).
#[inline]
fn plane(w_in: DVec3, w_out: DVec3, fallback: DVec3) -> (DVec3, DVec3, DVec3) {
    let mut r = w_in.cross(w_out);
    let len = r.length();
    if len < 1e-12 {
        r = w_out.cross(fallback).normalize();
    } else {
        r /= len;
    }
    (r, r.cross(w_in), r.cross(w_out))
}

/// The backward (adjoint) polarized weight: `T` maps a Stokes vector of light arriving along
/// the current path segment (in that segment's frame, first axis `e1`) to the Stokes vector
/// measured by the sensor (meridian frame of the direction towards the sensor). At a collision
/// along `d` the new path direction `d'` is drawn from `a1`, and `T ← T·R(l_out → e1)·F(Θ)·ω/a1`,
/// the scattering-plane frame being that of light going from `−d'` to `−d`; the new segment's
/// frame axis is `l_in`.
#[derive(Clone, Copy, Debug)]
pub struct MuellerPath {
    pub t: DMat4,
    pub e1: DVec3,
}

impl MuellerPath {
    /// A path leaving the sensor whose frame has first axis `e1` (⊥ the path direction).
    pub fn at_sensor(e1: DVec3) -> Self {
        MuellerPath {
            t: DMat4::IDENTITY,
            e1,
        }
    }

    /// Score `k·T·R·(F·(1,0,0,0))`: unpolarized sunlight arriving along `−sun` scattered through
    /// `f` into the path (which leaves the interaction along `−d`).
    #[inline]
    pub fn see_sun(
        &self,
        t: &mut StokesTally,
        order: u32,
        f: &PhaseMatrix,
        d: DVec3,
        sun: DVec3,
        k: f64,
    ) {
        let w_out = -d;
        let (_, _, l_out) = plane(-sun, w_out, self.e1);
        let sv = DVec4::new(f.a1, f.b1, 0.0, 0.0);
        let s = self.t * (rotation(w_out, l_out, self.e1) * sv) * k;
        add_stokes(t, order, [s.x, s.y, s.z, s.w]);
    }

    /// Score `k·T·(1,0,0,0)·i`: unpolarized light of intensity `i` arriving along the path.
    #[inline]
    pub fn see_unpolarized(&self, t: &mut StokesTally, order: u32, i: f64) {
        let s = self.t.col(0) * i;
        add_stokes(t, order, [s.x, s.y, s.z, s.w]);
    }
}

impl Weight for MuellerPath {
    polarized_phase!();
    #[inline]
    fn splittable(&self) -> Option<Self> {
        Some(*self)
    }
    #[inline]
    fn intensity(&self) -> f64 {
        // A product of Mueller matrices has T00 ≥ |T0j|: the path's intensity weight.
        self.t.col(0).x
    }
    #[inline]
    fn rescale_to(&mut self, target: f64, i: f64) {
        self.t *= target / i;
    }
    #[inline]
    fn scatter(
        &mut self,
        phase: &PhaseFunction,
        omega: f64,
        d: DVec3,
        peak: &PeakSampling,
        rng: &mut Stream,
    ) -> DVec3 {
        // Light arrives along −d; its frame axis e1 is the path segment's (see the module of
        // `stokes_sampling`: q = T01/T00, u = −T02/T00 make T00 scale by exactly ω).
        let t00 = self.t.col(0).x;
        let (q, u) = (self.t.col(1).x / t00, -self.t.col(2).x / t00);
        let smp = stokes_sampling::sample_with(phase, d, self.e1, q, u, peak, rng);
        let d2 = smp.d2;
        let (_, l_in, l_out) = plane(-d2, -d, self.e1);
        let k = if smp.norm > 0.0 {
            omega / smp.norm
        } else {
            0.0
        };
        self.t = self.t * rotation(-d, l_out, self.e1) * mueller(&smp.f) * k;
        self.e1 = l_in;
        d2
    }
    #[inline]
    fn reflect(&mut self, surface: &SurfaceAt, d: DVec3, rng: &mut Stream) -> Option<DVec3> {
        let w_out = -d;
        let smp = surface.sample(w_out, rng)?;
        let d2 = smp.wi;
        match surface.matrix(d2, w_out) {
            Some(m) if m.a1 > 0.0 => {
                let (_, l_in, l_out) = plane(-d2, w_out, self.e1);
                self.t =
                    self.t * rotation(w_out, l_out, self.e1) * mueller(&m) * (smp.weight / m.a1);
                self.e1 = l_in;
            }
            Some(_) => return None,
            None => {
                // Depolarizer: only the first column of T survives.
                self.t = DMat4::from_cols(
                    self.t.col(0) * smp.weight,
                    DVec4::ZERO,
                    DVec4::ZERO,
                    DVec4::ZERO,
                );
                self.e1 = any_perpendicular(d2);
            }
        }
        Some(d2)
    }
    polarized_tally!();
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phase::Rayleigh;

    /// Stokes-aware sampling: after a scattering the intensity weight is exactly ω times the
    /// previous one, for forward photons and backward path matrices in any polarization state
    /// (which also pins the frame algebra of `stokes_sampling` to `stokes::scatter` and to the
    /// backward rotation), and |Q|, |U| stay ≤ I.
    #[test]
    fn polarized_scattering_multiplies_intensity_by_omega() {
        let phase = PhaseFunction::Rayleigh(Rayleigh::new(0.03).unwrap());
        let mut rng = Stream::new(11, [2, 7, 1, 8]);
        let omega = 0.9;
        let mut p = StokesPhoton::unpolarized(DVec3::new(0.3, -0.4, -0.866).normalize());
        let mut d = DVec3::new(0.3, -0.4, -0.866).normalize();
        let mut b = MuellerPath::at_sensor(any_perpendicular(d));
        let mut db = d;
        for order in 0..200 {
            let i0 = p.s[0];
            d = p.scatter(&phase, omega, d, &PeakSampling::OFF, &mut rng);
            assert!((p.s[0] - omega * i0).abs() < 1e-12 * i0, "order {order}");
            let pol = (p.s[1].powi(2) + p.s[2].powi(2) + p.s[3].powi(2)).sqrt();
            assert!(pol <= p.s[0] * (1.0 + 1e-9), "order {order}: {:?}", p.s);
            p.rescale_to(1.0, p.s[0]);
            assert!((p.e1.dot(d)).abs() < 1e-9 && (p.e1.length() - 1.0).abs() < 1e-9);

            let t0 = b.t.col(0).x;
            db = b.scatter(&phase, omega, db, &PeakSampling::OFF, &mut rng);
            let t1 = b.t.col(0).x;
            assert!(
                (t1 - omega * t0).abs() < 1e-12 * t0,
                "order {order}: {t0} → {t1}"
            );
            let row = (b.t.col(1).x.powi(2) + b.t.col(2).x.powi(2)).sqrt();
            assert!(row <= t1 * (1.0 + 1e-9), "order {order}");
            b.rescale_to(1.0, t1);
        }
    }
}
