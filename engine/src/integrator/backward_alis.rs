//! One backward walk for several spectral channels at once: the g-points of a CKD bin, or a
//! group of neighbouring wavelengths in monochromatic runs (the ALIS idea: Emde, Buras & Mayer
//! 2011, "ALIS: An efficient method to compute high spectral resolution polarized solar
//! radiances using the Monte Carlo approach", JQSRT 112, 1622–1631). Plane-parallel, scalar, 1D
//! surface; positions are altitudes (m), coefficients in m⁻¹, scores are `π·L/(E0 μ_s)`.
//!
//! **The walk.** Free paths, collisions and new directions are sampled in a *reference* process
//! (extinction k_ref, scattering σ_ref, albedo ω_ref = σ_ref/k_ref carried in the common weight
//! `w`, phase function P_ref, surface sampled by the reference BRDF). Every channel c carries a
//! multiplicative path factor `e_c`, updated
//! * along each flight of length ℓ: `× exp(−(τ_c − τ_ref))` (optical paths along the flight,
//!   exact for any direction, from the optical depths at both ends: `Layers::carry`);
//! * at a scattering event in layer i, new direction at cos Θ drawn from P_ref:
//!   `× (σ_c,i/σ_ref,i)·(P_c,i(cos Θ)/P_ref,i(cos Θ))`;
//! * at a surface bounce: the reference surface draws `wi` with its own density `pdf_ref`
//!   ([`Bsdf::sample`]; models sample differently, `bsdf/mod.rs`), and channel c's own weight is
//!   `q_c = f_c·cos θ_i/pdf_ref` ([`Bsdf::weight_of`]); the common weight takes `r` (the
//!   reference surface's `q`, or max_c q_c where that is 0) and `e_c × q_c/r`.
//!
//! **Why each channel's estimate is unbiased.** Write channel c's scalar radiance as the Neumann
//! series over paths x = (x_1, d_1, x_2, …) from the sensor: the integrand is a product, per
//! flight, of the transport kernel `σ_c(x_j)·e^{−τ_c(flight)}·P_c(cos Θ_j)/(4π)` (at the ground:
//! `e^{−τ_c(flight)}·f_c cos θ_i`) times the next-event score of each vertex, with c's own σ_c,
//! P_c, BRDF and solar transmittance `exp(−τ_c(z)/μ_s)`. The walk draws the same path from the
//! reference density `k_ref e^{−τ_ref}·P_ref/(4π)` per flight (at the ground: `e^{−τ_ref}` times
//! the reference surface's sampling density). The ratio of kernel to density at every step is
//! exactly the factor above (`ω_ref` in `w` times `e_c`'s update, or `q_c` = `r`·(q_c/r) at the
//! ground), so `w·e_c·score_c` has the expectation of channel c's series (importance sampling; the
//! reference's walk is the same for every c, only the weights differ): unbiased whenever the
//! reference density is positive where channel c's is (σ_ref,i > 0 wherever some σ_c,i > 0, checked
//! by the resolver; P_ref > 0, true of every phase model here; the reference surface's sampling
//! density is positive wherever a channel's BRDF is: the tabulated samplers include the cosine
//! density, the ocean's facet density is positive everywhere above the horizon). Russian roulette
//! and `max_depth` act on the common weight and the order, identically for every channel, so they
//! keep each channel unbiased. With the default expected local estimate, the next-event score of
//! the next flight is replaced by its expectation over the reference's collision point,
//! `∫ σ_c P_c/(4π) e_c e^{−S_c(ℓ)} e^{−τ_c(z(ℓ))/μ_s} dℓ` (S_c: c's optical path along the
//! flight; the reference densities cancel), integrated exactly layer by layer for every channel
//! (`expected`).
//!
//! **CKD g-points** ([`Kind::GPoints`]): the channels share scattering, phase functions and the
//! surface, the reference is the bin's atmosphere without gas absorption (particle absorption
//! stays in ω_ref), so the scattering ratio is 1, `e_g` is a pure gas transmittance ≤ 1, and the
//! walk scores the bin mean `Σ_g w_g·(estimate_g)` (quadrature weights w_g). Without expected
//! estimates (`local_estimate = "collision"`) saturated bands, whose signal comes from rare
//! scattering high in the atmosphere (1380 nm), need orders of magnitude more walks.
//!
//! **Monochromatic groups** ([`Kind::Wavelengths`], `integrator.spectral_walk = "alis"`): up to
//! [`MAX_CHANNELS`] neighbouring wavelengths (`alis_group`, consecutive in the sorted list) with
//! their own absorption, scattering (Rayleigh ∝ λ⁻⁴, aerosol extinction and phase functions) and
//! surfaces; one score per wavelength. The reference ([`group_reference`]) has the scattering
//! coefficients and phase functions of the group's central wavelength and, per layer, the
//! smallest absorption of the group: absorption common to all wavelengths is survival weight
//! (ω_ref), and `e_c` carries only the wavelength's excess absorption, so in a continuum the
//! walk behaves like an independent one (a reference without any absorption doubled the
//! standard errors in the O2 A-band, whose continuum absorbs 7× more than it scatters). The
//! surface is sampled with the central wavelength's BRDF. Weight variance: `e_c` is not bounded
//! by 1. Along a flight `e_c` gains `exp(−(k_c − k_ref)ℓ)` and at a collision `σ_c/σ_ref`;
//! where σ_c > σ_ref (the blue end of a group) the product over n scatterings grows like
//! (σ_c/σ_ref)^n while the flights' factors compensate only on average, so the variance grows
//! with the scattering order and the group's spectral width. For groups a few nm wide (σ ratios
//! within a few %) it is benign; the tests use a 40 nm group (σ_s ratio 1.45 for Rayleigh) at
//! τ ≈ 0.5 without trouble, but groups tens of nm wide in an optically thick scattering
//! atmosphere can be noisier than independent walks. A wavelength absorbing much more than the
//! group's least absorbing one gets long paths of small weight: its relative error is larger than
//! an independent walk's of equal count, which the shared walk usually more than repays. In deep
//! line cores this concerns the multiple scattering most: it comes from scattering high in the
//! atmosphere, where the reference rarely collides, so its estimate is heavy-tailed and its
//! standard error unreliable with few walks (O2 A-band, 765.618 nm, column τ_gas ≈ 100: with
//! 8192 walks the multiple part, 1.3e-4 of the BRF, came out 4.6e-9 low with a reported σ of
//! 1e-10; 4·10⁶ walks agree with independent walks). The total is unaffected at any practical
//! precision there (single scattering, exact along the first flight, is the rest).
//!
//! Cost: per flight and per wavelength one exponential per layer crossed (the expected
//! estimate, vectorized over the wavelengths with `exp_fast`) and one phase evaluation per
//! flight and distinct phase function (equal phase functions, in any layer or wavelength, share
//! one: `PhaseCache`).

use glam::DVec3;

use super::backward::Adjoint;
use super::geometry::{Event, Geometry, Light};
use super::peak_sampling::PeakSampling;
use super::settings::IntegratorSettings;
use super::surface::SurfaceAt;
use super::weight::{OrderSplit, Weight};
use crate::accum::Accum;
use crate::atmosphere::{PlaneParallel, ZGrid};
use crate::bsdf::{Bsdf, SurfaceEmission};
use crate::error::{ConfigCtx, ConfigError};
use crate::phase::PhaseFunction;
use crate::rng::Stream;

/// The most channels (g-points or wavelengths) one walk carries (a limit of the settings).
pub use super::settings::MAX_CHANNELS;

/// What the channels of a walk are.
pub enum Kind<'a> {
    /// CKD g-points: shared scattering and surface, one score (the weighted bin mean). With
    /// thermal emission each g-point's atmosphere carries its layers' sources and
    /// `surface_emission` its surface's (one per g-point; empty without emission).
    GPoints {
        weights: &'a [f64],
        surface: &'a Bsdf,
        surface_emission: &'a [&'a SurfaceEmission],
    },
    /// Monochromatic wavelengths: own scattering, phase functions and surfaces, one score each.
    Wavelengths {
        surfaces: &'a [&'a Bsdf],
        reference_surface: &'a Bsdf,
    },
}

/// The channels of a walk: their atmospheres (same layer boundaries), the reference atmosphere
/// in which free paths are sampled, the layer tables and the kind.
pub struct Channels<'a> {
    pub atms: &'a [&'a PlaneParallel],
    pub reference: &'a PlaneParallel,
    /// Layer tables for the expected estimates (from [`Layers::new`] or [`Layers::spectral`]).
    pub layers: &'a Layers,
    pub kind: Kind<'a>,
}

impl Channels<'_> {
    /// Scores per walk: 1 for g-points (the bin mean), one per wavelength otherwise.
    pub fn outputs(&self) -> usize {
        match self.kind {
            Kind::GPoints { .. } => 1,
            Kind::Wavelengths { .. } => self.atms.len(),
        }
    }
}

/// Per-layer coefficients shared by the walks of a task: boundaries (top down), the reference
/// scattering coefficient σ_s (m⁻¹), and per channel the extinction coefficient k_c (m⁻¹) and
/// the optical depth τ_c at each boundary.
pub struct Layers {
    z: Vec<f64>,
    /// Altitude index over `z` (a bin, then a short scan, instead of a binary search).
    zgrid: ZGrid,
    sigma_s: Vec<f64>,
    k: Vec<Vec<f64>>,
    /// The same coefficients layer-major (`[i·nc + c]`), for the vectorized layer loop.
    k_lm: Vec<f64>,
    tau: Vec<Vec<f64>>,
    /// The reference atmosphere's extinction coefficient and optical depths.
    k_ref: Vec<f64>,
    tau_ref: Vec<f64>,
    /// Wavelength channels only: their own scattering.
    spectral: Option<Spectral>,
    /// Emitting channels (thermal CKD g-points): per layer and channel, `(1 − ω_c,i)` times
    /// the source at the layer's top and bottom, layer-major (`[(i·nc + c)·2 + {0, 1}]`).
    sources: Option<Vec<f64>>,
}

/// Per-channel scattering of wavelength channels, layer-major (`[i·nc + c]`).
struct Spectral {
    nc: usize,
    /// σ_s,c of layer i, m⁻¹.
    sigma: Vec<f64>,
    /// σ_s,c / σ_ref (0 where the reference does not scatter).
    ratio: Vec<f64>,
    /// Phase id of channel c in layer i: equal phase functions (in any layer and channel) share
    /// one id and so one evaluation per direction (often all of them: Rayleigh-only layers of
    /// one depolarization).
    pid: Vec<u32>,
    /// Per id, a (layer, channel) that has it.
    reps: Vec<(usize, usize)>,
}

/// Phase function values at one cos Θ, evaluated on demand per phase id; `next` starts a new
/// cos Θ (generation stamps, so nothing is cleared).
pub(crate) struct PhaseCache {
    val: Vec<f64>,
    stamp: Vec<u32>,
    generation: u32,
}

impl PhaseCache {
    pub(crate) fn new(ids: usize) -> Self {
        PhaseCache {
            val: vec![0.0; ids],
            stamp: vec![0; ids],
            generation: 0,
        }
    }

    fn next(&mut self) {
        self.generation = self.generation.wrapping_add(1);
        if self.generation == 0 {
            self.stamp.fill(0);
            self.generation = 1;
        }
    }
}

/// Scattering coefficient per layer of `t` (boundaries (z, τ) top down).
fn coef(t: &[(f64, f64)], i: usize) -> f64 {
    let dz = t[i].0 - t[i + 1].0;
    if dz > 0.0 {
        (t[i + 1].1 - t[i].1) / dz
    } else {
        0.0
    }
}

/// The reference atmosphere of a wavelength group: the scattering and phase functions of
/// `central` and, per layer, the smallest absorption optical thickness of the group (so that
/// absorption common to every wavelength acts as survival weight ω_ref, and each path factor
/// carries only its wavelength's excess absorption).
pub fn group_reference(central: &PlaneParallel, atms: &[&PlaneParallel]) -> PlaneParallel {
    let n = central.layer_count();
    let tau_abs: Vec<f64> = (0..n)
        .map(|i| {
            atms.iter()
                .map(|a| a.tau_abs(i))
                .fold(f64::INFINITY, f64::min)
                .max(0.0)
        })
        .collect();
    central.with_absorption(&tau_abs)
}

impl Layers {
    /// Tables for CKD g-points (the reference's scattering serves every channel).
    pub fn new(reference: &PlaneParallel, atms: &[&PlaneParallel]) -> Self {
        let b: Vec<(f64, f64)> = reference.boundaries().collect();
        let n = b.len() - 1;
        let z: Vec<f64> = b.iter().map(|x| x.0).collect();
        let sigma_s = (0..n).map(|i| reference.albedo(i) * coef(&b, i)).collect();
        let mut k = Vec::new();
        let mut tau = Vec::new();
        for a in atms {
            let t: Vec<(f64, f64)> = a.boundaries().collect();
            assert!(
                t.len() == b.len() && t.iter().zip(&b).all(|(x, y)| x.0 == y.0),
                "ALIS channels must share the reference's layer boundaries"
            );
            k.push((0..n).map(|i| coef(&t, i)).collect());
            tau.push(t.iter().map(|x| x.1).collect());
        }
        let k_ref = (0..n).map(|i| coef(&b, i)).collect();
        let tau_ref = b.iter().map(|x| x.1).collect();
        let k_lm = (0..n)
            .flat_map(|i| k.iter().map(move |kc: &Vec<f64>| kc[i]))
            .collect();
        let sources = atms.iter().any(|a| a.emits()).then(|| {
            let mut s = Vec::with_capacity(2 * n * atms.len());
            for i in 0..n {
                for a in atms {
                    let [top, bottom] = a.source(i);
                    let k = 1.0 - a.albedo(i);
                    s.push(k * top);
                    s.push(k * bottom);
                }
            }
            s
        });
        Layers {
            zgrid: ZGrid::new(&z),
            z,
            sigma_s,
            k,
            k_lm,
            tau,
            k_ref,
            tau_ref,
            spectral: None,
            sources,
        }
    }

    /// Tables for wavelength channels: [`Layers::new`] plus each channel's scattering
    /// coefficient and phase ids.
    pub fn spectral(reference: &PlaneParallel, atms: &[&PlaneParallel]) -> Self {
        assert!(atms.len() <= MAX_CHANNELS);
        let mut l = Self::new(reference, atms);
        let n = l.sigma_s.len();
        let nc = atms.len();
        let mut sigma = Vec::with_capacity(n * nc);
        let mut ratio = Vec::with_capacity(n * nc);
        let mut pid = Vec::with_capacity(n * nc);
        let mut reps: Vec<(usize, usize)> = Vec::new();
        // Candidates by the values at three cosines (equal functions give equal keys), then
        // exact comparison.
        let mut by_key: std::collections::HashMap<[u64; 3], Vec<u32>> = Default::default();
        for i in 0..n {
            for (c, a) in atms.iter().enumerate() {
                let s = a.albedo(i) * l.k[c][i];
                sigma.push(s);
                let s_ref = l.sigma_s[i];
                ratio.push(if s_ref > 0.0 { s / s_ref } else { 0.0 });
                let p = a.phase(i);
                let key = [-0.71, 0.13, 0.92].map(|x| p.eval(x).to_bits());
                let bucket = by_key.entry(key).or_default();
                let id = match bucket
                    .iter()
                    .find(|&&id| atms[reps[id as usize].1].phase(reps[id as usize].0) == p)
                {
                    Some(&id) => id,
                    None => {
                        reps.push((i, c));
                        let id = (reps.len() - 1) as u32;
                        bucket.push(id);
                        id
                    }
                };
                pid.push(id);
            }
        }
        l.spectral = Some(Spectral {
            nc,
            sigma,
            ratio,
            pid,
            reps,
        });
        l
    }

    /// The first layer (index) where a channel scatters but the reference does not: a walk
    /// sampled in that reference would miss part of the channel's paths.
    pub fn unsupported_layer(reference: &PlaneParallel, atms: &[&PlaneParallel]) -> Option<usize> {
        let scattering = |a: &PlaneParallel| -> Vec<f64> {
            let t: Vec<(f64, f64)> = a.boundaries().collect();
            (0..t.len() - 1)
                .map(|i| a.albedo(i) * (t[i + 1].1 - t[i].1))
                .collect()
        };
        let r = scattering(reference);
        let channels: Vec<Vec<f64>> = atms.iter().map(|a| scattering(a)).collect();
        (0..r.len()).find(|&i| r[i] <= 0.0 && channels.iter().any(|c| c[i] > 0.0))
    }

    /// Channel `c`'s optical depth from TOA at altitude `z` (clamped to the atmosphere).
    pub(crate) fn tau_at(&self, c: usize, z: f64) -> f64 {
        let (i, f) = self.locate(z);
        let tau = &self.tau[c];
        tau[i] + f * (tau[i + 1] - tau[i])
    }

    /// Per channel `(σ_c,i/σ_ref,i)·P_c,i(cos)` in layer `i` into `out` (wavelength tables,
    /// [`Layers::spectral`], only; each distinct phase function evaluated once: `cache.next()`
    /// is called here).
    pub(crate) fn ratio_phase(
        &self,
        atms: &[&PlaneParallel],
        i: usize,
        cos: f64,
        cache: &mut PhaseCache,
        out: &mut [f64],
    ) {
        let sp = self
            .spectral
            .as_ref()
            .expect("wavelength channels need Layers::spectral");
        cache.next();
        sp.times_phase(&sp.ratio, atms, i, cos, cache, out);
    }

    /// The number of distinct phase functions of wavelength tables (the size of their
    /// [`PhaseCache`]), 0 for g-point tables.
    pub(crate) fn phase_ids(&self) -> usize {
        self.spectral.as_ref().map_or(0, |s| s.reps.len())
    }

    /// Layer index and fraction `f` (0 at the layer's top) of altitude `z`.
    fn locate(&self, z: f64) -> (usize, f64) {
        let n = self.sigma_s.len();
        let i = self.zgrid.boundaries_above(&self.z, z).clamp(1, n) - 1;
        (i, self.fraction(i, z))
    }

    /// Fraction (0 at the top, 1 at the bottom) of altitude `z` in layer `i`.
    fn fraction(&self, i: usize, z: f64) -> f64 {
        let (zt, zb) = (self.z[i], self.z[i + 1]);
        if zt > zb {
            ((zt - z) / (zt - zb)).clamp(0.0, 1.0)
        } else {
            0.0
        }
    }

    /// The layer a flight from altitude `z` with vertical component `dz` starts in (on a
    /// boundary: the one it moves into).
    fn start_layer(&self, z: f64, dz: f64) -> usize {
        let n = self.sigma_s.len();
        if dz < 0.0 {
            self.zgrid.boundaries_above(&self.z, z).clamp(1, n) - 1
        } else {
            self.zgrid.boundaries_at_or_above(&self.z, z).clamp(1, n) - 1
        }
    }

    /// Multiply each channel's path factor by `exp(−(τ_c − τ_ref))` over the flight of length
    /// `t` from altitude `z` along a direction of vertical component `dz` (optical paths from
    /// the optical depths at both ends: `|Δτ|/|dz|`; a horizontal flight stays in its layer).
    pub(crate) fn carry(&self, e: &mut [f64], z: f64, dz: f64, t: f64) {
        let (i0, f0) = self.locate(z);
        if dz.abs() < 1e-12 {
            for (k, ek) in e.iter_mut().enumerate() {
                *ek *= (-(self.k[k][i0] - self.k_ref[i0]) * t).exp();
            }
            return;
        }
        let (i1, f1) = self.locate(z + t * dz);
        let at = |tau: &[f64], i: usize, f: f64| tau[i] + f * (tau[i + 1] - tau[i]);
        let inv = 1.0 / dz.abs();
        let d_ref = (at(&self.tau_ref, i1, f1) - at(&self.tau_ref, i0, f0)).abs();
        for (k, ek) in e.iter_mut().enumerate() {
            let tau = &self.tau[k];
            let d = (at(tau, i1, f1) - at(tau, i0, f0)).abs();
            *ek *= (-(d - d_ref) * inv).exp();
        }
    }
}

impl Spectral {
    /// `coef_c·P_c,i(cos)` per channel into `out` (`coef`: σ_c,i or σ_c,i/σ_ref,i, layer-major),
    /// each distinct phase function evaluated once per `cache` generation (one cos Θ).
    #[inline]
    fn times_phase(
        &self,
        coef: &[f64],
        atms: &[&PlaneParallel],
        i: usize,
        cos: f64,
        cache: &mut PhaseCache,
        out: &mut [f64],
    ) {
        let o = i * self.nc;
        for c in 0..self.nc {
            let id = self.pid[o + c] as usize;
            if cache.stamp[id] != cache.generation {
                let (li, ci) = self.reps[id];
                cache.val[id] = atms[ci].phase(li).eval(cos);
                cache.stamp[id] = cache.generation;
            }
            out[c] = coef[o + c] * cache.val[id];
        }
    }
}

/// `e^x` in straight-line arithmetic that the compiler can vectorize over the channels
/// (`f64::exp` is a library call): Cody–Waite reduction `x = n·ln 2 + r`, |r| ≤ ln 2/2, the
/// Taylor polynomial of degree 8 for `e^r` (truncation (ln 2/2)⁹/9! = 2.0e-10, at most 2.8e-10
/// relative to e^r for r < 0) and
/// `2^n` from the exponent bits. Degree 8 rather than 13 (a few ulp) saves 20 % of the ALIS run
/// time (hyperspectral benchmark: 4.2 → 3.3 s; results change by ≤ 1.4e-11); the error, ≤ 3e-8
/// after a hundred layers of products, is five orders of magnitude below the smallest Monte Carlo
/// standard error we report. `x` is clamped to [−708, 709] (e^−708 ≈ 3e−308 stands
/// for anything smaller: below any score's resolution).
#[inline(always)]
fn exp_fast(x: f64) -> f64 {
    const SHIFT: f64 = 6_755_399_441_055_744.0; // 1.5·2^52: adding it rounds to an integer
    const LN2_HI: f64 = 6.931_471_803_691_238e-1;
    const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;
    let x = x.clamp(-708.0, 709.0);
    let t = x * std::f64::consts::LOG2_E + SHIFT;
    let n = t - SHIFT;
    let r = (x - n * LN2_HI) - n * LN2_LO;
    // Horner on the coefficients 1/k!, k = 8 … 0.
    let mut p = INV_FACTORIAL[8];
    for c in INV_FACTORIAL[..8].iter().rev() {
        p = p * r + c;
    }
    let ni = (t.to_bits() as i64).wrapping_sub(SHIFT.to_bits() as i64);
    let scale = f64::from_bits(((ni + 1023) as u64) << 52);
    p * scale
}

/// 1/k!, k = 0 … 8.
const INV_FACTORIAL: [f64; 9] = [
    1.0,
    1.0,
    1.0 / 2.0,
    1.0 / 6.0,
    1.0 / 24.0,
    1.0 / 120.0,
    1.0 / 720.0,
    1.0 / 5040.0,
    1.0 / 40320.0,
];

/// `∫₀^len e^{−a ℓ} dℓ` and `e^{−a·len}` (len may be infinite: a horizontal flight).
#[inline]
fn layer_integral(a: f64, len: f64, finite: bool) -> (f64, f64) {
    let x = a * len;
    let decay = if finite { (-x).exp() } else { 0.0 };
    let integral = if !finite {
        if a > 0.0 {
            1.0 / a
        } else {
            0.0
        }
    } else if x.abs() < 1e-6 {
        // (1 − e^{−x})/a to second order (a < 0 going up towards the Sun).
        len * (1.0 - 0.5 * x)
    } else {
        (1.0 - decay) / a
    };
    (integral, decay)
}

/// One layer crossed over its whole length `len` for every wavelength: `out_c += sp_c·amp_c·
/// (1 − e^{−a_c len})/a_c` and `amp_c ×= e^{−a_c len}`, a_c = k_c·slant (the second-order form
/// where a_c·len is small, as [`layer_integral`]). Branch-free, so the compiler vectorizes it
/// with [`exp_fast`]; with AVX2 (detected at run time) four wavelengths at a time. No FMA
/// contraction either way, so the results do not depend on the instruction set.
#[inline]
fn layer_channels(k: &[f64], sp: &[f64], amp: &mut [f64], out: &mut [f64], slant: f64, len: f64) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above).
            unsafe { layer_channels_avx2(k, sp, amp, out, slant, len) };
            return;
        }
    }
    layer_channels_body(k, sp, amp, out, slant, len);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn layer_channels_avx2(
    k: &[f64],
    sp: &[f64],
    amp: &mut [f64],
    out: &mut [f64],
    slant: f64,
    len: f64,
) {
    layer_channels_body(k, sp, amp, out, slant, len);
}

#[inline(always)]
fn layer_channels_body(
    k: &[f64],
    sp: &[f64],
    amp: &mut [f64],
    out: &mut [f64],
    slant: f64,
    len: f64,
) {
    let n = k.len().min(sp.len()).min(amp.len()).min(out.len());
    let (k, sp, amp, out) = (&k[..n], &sp[..n], &mut amp[..n], &mut out[..n]);
    for c in 0..n {
        let a = k[c] * slant;
        let x = a * len;
        let decay = exp_fast(-x);
        // (No 0/0 in the unused lane: NaNs cost microcode assists.)
        let small = x.abs() < 1e-6;
        let a_safe = if small { 1.0 } else { a };
        let integral = if small {
            len * (1.0 - 0.5 * x)
        } else {
            (1.0 - decay) / a_safe
        };
        out[c] += sp[c] * amp[c] * integral;
        amp[c] *= decay;
    }
}

/// One layer crossed over length `len` by every channel: adds
/// `amp_c·(s_in,c·(1 − e^{−D_c}) + (s_out,c − s_in,c)·(1 − e^{−D_c}(1 + D_c))/D_c)` to `out_c`
/// and multiplies `amp_c` by `e^{−D_c}`, D_c = k_c·len (per-channel sums: a running scalar
/// sum would keep the loop from vectorizing). Branch-free with [`exp_fast`] (AVX2 when
/// the CPU has it, as [`layer_channels`]; no FMA contraction either way).
#[inline]
fn layer_emission(
    k: &[f64],
    s_in: &[f64],
    s_out: &[f64],
    amp: &mut [f64],
    out: &mut [f64],
    len: f64,
) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above).
            unsafe { layer_emission_avx2(k, s_in, s_out, amp, out, len) };
            return;
        }
    }
    layer_emission_body(k, s_in, s_out, amp, out, len)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn layer_emission_avx2(
    k: &[f64],
    s_in: &[f64],
    s_out: &[f64],
    amp: &mut [f64],
    out: &mut [f64],
    len: f64,
) {
    layer_emission_body(k, s_in, s_out, amp, out, len)
}

#[inline(always)]
fn layer_emission_body(
    k: &[f64],
    s_in: &[f64],
    s_out: &[f64],
    amp: &mut [f64],
    out: &mut [f64],
    len: f64,
) {
    let n = k
        .len()
        .min(s_in.len())
        .min(s_out.len())
        .min(amp.len())
        .min(out.len());
    let (k, s_in, s_out, amp, out) = (
        &k[..n],
        &s_in[..n],
        &s_out[..n],
        &mut amp[..n],
        &mut out[..n],
    );
    for c in 0..n {
        let d = k[c] * len;
        let decay = exp_fast(-d);
        let small = d < 1e-3;
        let d_safe = if small { 1.0 } else { d };
        let lin = if small {
            d * (0.5 - d * (1.0 / 3.0 - d / 8.0))
        } else {
            (1.0 - decay * (1.0 + d)) / d_safe
        };
        out[c] += amp[c] * (s_in[c] * (1.0 - decay) + (s_out[c] - s_in[c]) * lin);
        amp[c] *= decay;
    }
}

/// Thermal emission over the flight from altitude `z` along `d`, per channel in its own
/// atmosphere, summed with the factors `amp` (on entry `w_c·e_c`; on return times each
/// channel's transmittance to the flight's end): `Σ_c amp_c·∫ k_c e^{−S_c(ℓ)} (1 − ω_c) B_c(ℓ)
/// dℓ` to the ground or the top, the expectation of the collision estimator of emission
/// (`atmosphere/emission.rs`). Inside a layer the source is linear in the distance (linear in
/// optical depth in a homogeneous layer), so each layer crossed adds, per channel,
/// `S_in·(1 − e^{−D}) + (S_out − S_in)·(1 − e^{−D}(1 + D))/D` with D = k_c·length. A
/// horizontal flight collides in its layer: `(1 − ω_c)·S_c(z)`. Without sources only the
/// transmittances are applied (for the surface's emission). One traversal of the layers
/// crossed, vectorized over the channels ([`layer_emission`]; `exp_fast`'s ≤ 3e-8 relative
/// error over a hundred layers, as for the next-event estimate).
fn emission_along(l: &Layers, amp: &mut [f64], z: f64, d: DVec3) -> f64 {
    const NONE: [f64; 0] = [];
    let src: &[f64] = l.sources.as_deref().unwrap_or(&NONE);
    let n = l.sigma_s.len();
    let nc = amp.len();
    let (toa, ground) = (l.z[0], l.z[n]);
    let dz = d.z;
    let z = z.min(toa);
    if z < ground || (z >= toa && dz >= 0.0) {
        amp.fill(0.0);
        return 0.0;
    }
    let mut i = l.start_layer(z, dz);
    // The source of channel c at fraction f (0 at the top) of layer i.
    let at = |i: usize, c: usize, f: f64| -> f64 {
        let o = (i * nc + c) * 2;
        match src.get(o..o + 2) {
            Some(s) => s[0] + (s[1] - s[0]) * f,
            None => 0.0,
        }
    };
    let frac = |i: usize, z: f64| l.fraction(i, z);
    let mut sum = 0.0;
    let mut out = [0.0_f64; MAX_CHANNELS];
    let (mut s_in, mut s_out) = ([0.0_f64; MAX_CHANNELS], [0.0_f64; MAX_CHANNELS]);
    let mut z = z;
    loop {
        let (zt, zb) = (l.z[i], l.z[i + 1]);
        let kl = &l.k_lm[i * nc..(i + 1) * nc];
        if dz == 0.0 {
            let f = frac(i, z);
            for c in 0..nc {
                if kl[c] > 0.0 {
                    sum += amp[c] * at(i, c, f);
                }
                amp[c] = 0.0;
            }
            break;
        }
        let (len, z_out) = if dz > 0.0 {
            ((zt - z) / dz, zt)
        } else {
            ((z - zb) / -dz, zb)
        };
        let (f_in, f_out) = (frac(i, z), frac(i, z_out));
        for c in 0..nc {
            s_in[c] = at(i, c, f_in);
            s_out[c] = at(i, c, f_out);
        }
        layer_emission(kl, &s_in[..nc], &s_out[..nc], amp, &mut out[..nc], len);
        if dz > 0.0 {
            if i == 0 {
                break;
            }
            i -= 1;
        } else {
            if i + 1 >= n {
                break;
            }
            i += 1;
        }
        z = z_out;
    }
    sum + out[..nc].iter().sum::<f64>()
}

/// Expected value over the next (reference) collision of the flight from altitude `z` along `d`
/// of the next-event estimates, integrated exactly layer by layer (every factor is exponential in
/// the distance inside a layer): per channel `∫ σ_c,L P_c,L e_c e^{−S_c(ℓ)} e^{−τ_c(z(ℓ))/μ_s} dℓ
/// /(4π)` over the flight to the ground or the top (`S_c`: the channel's optical path from the
/// flight's start), without the 1/(4π) (the estimator applies it). Writes the bin mean
/// (`Σ_g w_g·…`, g-points) into `out[0]` or one value per wavelength into `out`; `out` holds one
/// entry per channel (work space for g-points).
fn expected(
    g: &Channels,
    e: &[f64],
    z: f64,
    d: DVec3,
    sun: DVec3,
    cache: &mut PhaseCache,
    out: &mut [f64],
) {
    out.fill(0.0);
    cache.next();
    let l = g.layers;
    let n = l.sigma_s.len();
    let (toa, ground) = (l.z[0], l.z[n]);
    let mu_s = sun.z;
    let cos = sun.dot(d);
    let dz = d.z;
    let z = z.min(toa);
    if z < ground || (z >= toa && dz >= 0.0) {
        return;
    }
    let mut i = l.start_layer(z, dz);
    let nc = g.atms.len();
    let weights = match g.kind {
        Kind::GPoints { weights, .. } => Some(weights),
        Kind::Wavelengths { .. } => None,
    };
    // amp[k] = (w_g·)e_c·e^{−S_c(ℓ)}·e^{−τ_c(z(ℓ))/μ_s} at the current point of the flight.
    // Inside a layer it decays as e^{−a_c ℓ} with a_c = k_c·(1 − d_z/μ_s), so the layer's
    // integral is amp·(1 − e^{−a_c·len})/a_c and one exponential per channel and layer carries
    // it on.
    let mut amp = [0.0_f64; MAX_CHANNELS];
    let amp = &mut amp[..nc];
    {
        let (zt, zb) = (l.z[i], l.z[i + 1]);
        let f = if zt > zb { (zt - z) / (zt - zb) } else { 0.0 };
        for k in 0..nc {
            let tau_z = l.tau[k][i] + f * (l.tau[k][i + 1] - l.tau[k][i]);
            amp[k] = match weights {
                Some(w) => w[k] * e[k] * (-tau_z / mu_s).exp(),
                None => e[k] * (-tau_z / mu_s).exp(),
            };
        }
    }
    let slant = 1.0 - dz / mu_s;
    let mut sp = [0.0_f64; MAX_CHANNELS];
    let mut z = z;
    loop {
        let (zt, zb) = (l.z[i], l.z[i + 1]);
        let len = if dz > 0.0 {
            (zt - z) / dz
        } else if dz < 0.0 {
            (z - zb) / -dz
        } else {
            f64::INFINITY
        };
        let finite = len.is_finite();
        match &l.spectral {
            None => {
                // Shared scattering: one σ_s·P per layer for every g-point; the per-g-point
                // integrals are summed into `out` (weights are in `amp`) and added up at the end.
                let sig = l.sigma_s[i];
                let sp_i = if sig > 0.0 {
                    sig * g.reference.phase(i).eval(cos)
                } else {
                    0.0
                };
                let kl = &l.k_lm[i * nc..(i + 1) * nc];
                if finite {
                    sp[..nc].fill(sp_i);
                    layer_channels(kl, &sp[..nc], amp, &mut out[..nc], slant, len);
                } else {
                    for (c, ak) in amp.iter_mut().enumerate() {
                        let (integral, decay) = layer_integral(kl[c] * slant, len, finite);
                        out[c] += sp_i * *ak * integral;
                        *ak *= decay;
                    }
                }
            }
            Some(s) => {
                s.times_phase(&s.sigma, g.atms, i, cos, cache, &mut sp);
                let kl = &l.k_lm[i * nc..(i + 1) * nc];
                if finite {
                    layer_channels(kl, &sp[..nc], amp, &mut out[..nc], slant, len);
                } else {
                    for (c, ak) in amp.iter_mut().enumerate() {
                        let (integral, decay) = layer_integral(kl[c] * slant, len, finite);
                        out[c] += sp[c] * *ak * integral;
                        *ak *= decay;
                    }
                }
            }
        }
        if !finite {
            break;
        }
        if dz > 0.0 {
            if i == 0 {
                break;
            }
            z = zt;
            i -= 1;
        } else {
            if i + 1 >= n {
                break;
            }
            z = zb;
            i += 1;
        }
    }
    if l.spectral.is_none() {
        let total: f64 = out[..nc].iter().sum();
        out[0] = total;
    }
}

/// The reference atmosphere of a walk over channels `g`, as a geometry of the backward
/// estimator: positions are altitudes (m); free paths are sampled in the reference
/// ([`PlaneParallel::march`]); every flight carries the channels' path factors
/// (`Layers::carry`) and records the layer of its collision in the weight; the expected
/// estimate is integrated per channel (`expected`).
pub struct ReferenceLayers<'a> {
    channels: &'a Channels<'a>,
    /// Unit vector towards the Sun (`z > 0`).
    sun: DVec3,
    /// Whether the Sun shines (false: thermal emission only, no next-event estimates).
    shines: bool,
    /// Whether the g-points emit (their atmospheres' sources and surfaces).
    emits: bool,
    /// Per channel, the Sun's transmittance to the ground `exp(−τ*_c/μ_s)`.
    t_ground: Vec<f64>,
}

impl<'a> ReferenceLayers<'a> {
    pub fn new(channels: &'a Channels<'a>, sun: DVec3) -> Self {
        let t_ground = channels
            .atms
            .iter()
            .map(|a| (-a.total_tau() / sun.z).exp())
            .collect();
        let emits = match channels.kind {
            Kind::GPoints {
                surface_emission, ..
            } => !surface_emission.is_empty() || channels.atms.iter().any(|a| a.emits()),
            Kind::Wavelengths { .. } => false,
        };
        ReferenceLayers {
            channels,
            sun,
            shines: true,
            emits,
            t_ground,
        }
    }

    /// Whether the Sun shines (false: `illumination.type = "none"`, thermal emission only).
    pub fn with_sun_shining(mut self, shines: bool) -> Self {
        self.shines = shines;
        self
    }
}

/// The weight of a walk over channels: the common weight `w` (reference albedos, surface weights,
/// roulette) and one path factor `e_c` per channel.
pub struct ChannelPath<'a> {
    w: f64,
    e: [f64; MAX_CHANNELS],
    g: &'a Channels<'a>,
    /// Per channel, the Sun's transmittance to the ground.
    t_ground: &'a [f64],
    /// Layer of the last collision (set by the flight, used by the scattering).
    layer: usize,
    cache: PhaseCache,
}

impl<'a> ChannelPath<'a> {
    /// A path of unit weight leaving the sensor, in the reference geometry `r`.
    pub fn new(r: &'a ReferenceLayers<'a>) -> Self {
        let g = r.channels;
        assert!(g.atms.len() <= MAX_CHANNELS);
        ChannelPath {
            w: 1.0,
            e: [1.0; MAX_CHANNELS],
            g,
            t_ground: &r.t_ground,
            layer: 0,
            cache: PhaseCache::new(g.layers.spectral.as_ref().map_or(0, |s| s.reps.len())),
        }
    }
}

/// Per-output scores (the bin mean, or one per wavelength) of one path.
pub type ChannelTally = [OrderSplit; MAX_CHANNELS];

impl Weight for ChannelPath<'_> {
    /// Per output: the flight's expected `Σ σ_c P_c e_c T_c` (or at a collision).
    type Phase = [f64; MAX_CHANNELS];
    type Tally = ChannelTally;

    #[inline]
    fn zero_phase() -> Self::Phase {
        [0.0; MAX_CHANNELS]
    }
    #[inline]
    fn zero_tally() -> ChannelTally {
        [OrderSplit::default(); MAX_CHANNELS]
    }
    /// Grey scattering (the same `ω·P·k` in every output); the channels' own scattering is
    /// accumulated by [`ReferenceLayers`].
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
    #[inline]
    /// ALIS walks do not use detector-directional sampling (`_peak`): their channels share
    /// one path drawn from the reference phase function.
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
        let g = self.g;
        if let Some(sp) = &g.layers.spectral {
            let mut r = [0.0_f64; MAX_CHANNELS];
            self.cache.next();
            sp.times_phase(&sp.ratio, g.atms, self.layer, mu, &mut self.cache, &mut r);
            channels::times_phase_ratio(&mut self.e[..g.atms.len()], &r, phase.eval(mu));
        }
        wi
    }
    #[inline]
    fn reflect(&mut self, surface: &SurfaceAt, d: DVec3, rng: &mut Stream) -> Option<DVec3> {
        let wo = -d;
        // The reference surface draws with its density pdf_ref; channel c's own weight is
        // q_c = f_c·cos θ_i/pdf_ref.
        let smp = surface.sample(wo, rng)?;
        match self.g.kind {
            Kind::GPoints { .. } => self.w *= smp.weight,
            Kind::Wavelengths {
                surfaces,
                reference_surface,
            } => {
                let mut q = [0.0_f64; MAX_CHANNELS];
                let mut q_max = 0.0_f64;
                for (qk, sf) in q.iter_mut().zip(surfaces.iter()) {
                    *qk = sf.weight_of(smp.wi, wo, smp.pdf, reference_surface);
                    q_max = q_max.max(*qk);
                }
                let r = if smp.weight > 0.0 { smp.weight } else { q_max };
                if r > 0.0 {
                    for (ek, qk) in self.e[..surfaces.len()].iter_mut().zip(&q) {
                        *ek *= qk / r;
                    }
                }
                self.w *= r;
            }
        }
        Some(smp.wi)
    }
    /// ALIS accumulators have one cell per output (`cell` must be 0).
    fn record(acc: &mut Accum, cell: usize, t: &ChannelTally, k: f64) {
        channels::record(acc, cell, t, k);
    }
    fn add_tally(t: &mut ChannelTally, other: &ChannelTally, ratio: &[f64]) {
        channels::add_scaled(t, other, ratio);
    }
    fn mean_first_order(t: &mut ChannelTally, others: &ChannelTally, k: u32) {
        channels::mean_first_order(t, others, k);
    }
    fn accum(cells: usize) -> Accum {
        Accum::new(cells)
    }
}

impl Adjoint for ChannelPath<'_> {
    /// `r` is the g-points' emission already weighted by `w_g·e_g`
    /// ([`ReferenceLayers`]' `flight_emission`): the common weight scores it into the bin mean.
    /// (Wavelength channels carry no emission: the resolver refuses `emission = true` with
    /// `spectral_walk = "alis"`, and their geometry gathers none.)
    #[inline]
    fn see_emission(&self, t: &mut ChannelTally, order: u32, r: f64) {
        t[0].add(order, self.w * r);
    }
    #[inline]
    fn see_sun_volume(
        &self,
        t: &mut ChannelTally,
        order: u32,
        acc: &Self::Phase,
        _: DVec3,
        _: DVec3,
        k: f64,
    ) {
        for (tc, a) in t[..self.g.outputs()].iter_mut().zip(acc) {
            tc.add(order, self.w * a * k);
        }
    }
    /// Each channel's own surface and solar transmittance (`surface` is the reference one,
    /// `visible` the reference's transmittance: not used).
    fn see_sun_surface(
        &self,
        t: &mut ChannelTally,
        order: u32,
        _: &SurfaceAt,
        d: DVec3,
        sun: DVec3,
        _: impl FnOnce() -> f64,
    ) {
        let wo = -d;
        let mu_s = sun.z;
        let g = self.g;
        match g.kind {
            Kind::GPoints {
                weights, surface, ..
            } => {
                let f = surface.eval(sun, wo) * mu_s;
                let acc: f64 = weights
                    .iter()
                    .zip(self.e.iter())
                    .zip(self.t_ground)
                    .map(|((wk, ek), tk)| wk * ek * tk)
                    .sum();
                t[0].add(order, self.w * f * acc);
            }
            Kind::Wavelengths { surfaces, .. } => {
                for (k, (sf, tg)) in surfaces.iter().zip(self.t_ground).enumerate() {
                    t[k].add(order, self.w * sf.eval(sun, wo) * mu_s * self.e[k] * tg);
                }
            }
        }
    }
}

impl<'a> Geometry<ChannelPath<'a>> for ReferenceLayers<'a> {
    type Pos = f64;
    type Hit = ();

    fn light(&self) -> Light {
        Light::new(self.sun, self.sun.z)
    }

    #[inline]
    fn sun_shines(&self) -> bool {
        self.shines
    }

    /// `Σ_g w_g·e_g·E_g`: each g-point's expected emission over the flight in its own
    /// atmosphere (`PlaneParallel::expected_emission` from its optical depth at `z`, plus its
    /// surface's `ε·B` times its transmittance to the ground), weighted by its quadrature
    /// weight and path factor. Unbiased per g-point: given the vertex and direction, `E_g` is
    /// the expectation of g's collision estimator of emission over the flight, and `w·e_g` is
    /// g's importance weight of the vertex (module header).
    fn flight_emission(&self, z: f64, d: DVec3, w: &ChannelPath<'a>, _: &mut Stream) -> f64 {
        if !self.emits {
            return 0.0;
        }
        let g = self.channels;
        let Kind::GPoints {
            weights,
            surface_emission,
            ..
        } = g.kind
        else {
            return 0.0;
        };
        let nc = g.atms.len();
        let mut amp = [0.0_f64; MAX_CHANNELS];
        for (a, (wk, ek)) in amp[..nc].iter_mut().zip(weights.iter().zip(&w.e[..nc])) {
            *a = wk * ek;
        }
        let mut sum = emission_along(g.layers, &mut amp[..nc], z, d);
        if !surface_emission.is_empty() && d.z < -1e-12 {
            // `amp` now holds each channel's factor times its transmittance to the ground.
            let mu = -d.z;
            for (a, s) in amp[..nc].iter().zip(surface_emission) {
                sum += a * s.radiance(mu);
            }
        }
        sum
    }

    fn flight(
        &self,
        z: f64,
        d: DVec3,
        w: &mut ChannelPath<'a>,
        acc: Option<&mut [f64; MAX_CHANNELS]>,
        rng: &mut Stream,
    ) -> Event<'_, f64, ()> {
        let g = self.channels;
        let nc = g.atms.len();
        if let Some(acc) = acc {
            let mut tmp = [0.0_f64; MAX_CHANNELS];
            expected(
                g,
                &w.e[..nc],
                z,
                d,
                self.sun,
                &mut w.cache,
                &mut tmp[..nc.max(g.outputs())],
            );
            acc[..g.outputs()].copy_from_slice(&tmp[..g.outputs()]);
        }
        let reference = g.reference;
        let s = -rng.next_f64_open0().ln();
        match reference.march(z, d.z, s, f64::INFINITY) {
            Some(t) => {
                g.layers.carry(&mut w.e[..nc], z, d.z, t);
                let z2 = z + t * d.z;
                let layer = reference.layer_at_altitude(z2);
                w.layer = layer;
                Event::Collision {
                    pos: z2,
                    omega: reference.albedo(layer),
                    phase: reference.phase(layer),
                }
            }
            None if d.z < 0.0 => {
                // Down to the ground without a collision.
                let t = (z - reference.ground()) / -d.z;
                g.layers.carry(&mut w.e[..nc], z, d.z, t);
                Event::Surface(())
            }
            None => Event::Escape,
        }
    }

    /// Per output: `ω_ref·(σ_c/σ_ref)·P_c·e_c·T_c,sun` (wavelengths) or
    /// `ω·P·Σ_g w_g·e_g·T_g,sun` (g-points) at altitude `z`.
    fn collision_estimate(
        &self,
        z: f64,
        omega: f64,
        phase: &PhaseFunction,
        d: DVec3,
        w: &mut ChannelPath<'a>,
        acc: &mut [f64; MAX_CHANNELS],
    ) {
        let g = self.channels;
        let mu_s = self.sun.z;
        let cos = self.sun.dot(d);
        match (&g.kind, &g.layers.spectral) {
            (Kind::GPoints { weights, .. }, _) => {
                let s: f64 = g
                    .atms
                    .iter()
                    .zip(weights.iter())
                    .zip(w.e.iter())
                    .map(|((a, wk), ek)| wk * ek * (-a.tau_at_altitude(z) / mu_s).exp())
                    .sum();
                acc[0] = omega * phase.eval(cos) * s;
            }
            (Kind::Wavelengths { .. }, Some(sp)) => {
                let mut tmp = [0.0_f64; MAX_CHANNELS];
                w.cache.next();
                sp.times_phase(&sp.ratio, g.atms, w.layer, cos, &mut w.cache, &mut tmp);
                for (k, a) in g.atms.iter().enumerate() {
                    acc[k] = omega * tmp[k] * w.e[k] * (-a.tau_at_altitude(z) / mu_s).exp();
                }
            }
            (Kind::Wavelengths { .. }, None) => {
                unreachable!("wavelength channels need Layers::spectral")
            }
        }
    }

    #[inline]
    fn sun_at(&self, z: f64) -> f64 {
        (-self.channels.reference.tau_at_altitude(z) / self.sun.z).exp()
    }
    #[inline]
    fn surface(&self, _: &()) -> SurfaceAt<'_> {
        let bsdf = match self.channels.kind {
            Kind::GPoints { surface, .. } => surface,
            Kind::Wavelengths {
                reference_surface, ..
            } => reference_surface,
        };
        SurfaceAt::Flat { bsdf, frame: None }
    }
    #[inline]
    fn sun_at_surface(&self, _: &()) -> f64 {
        (-self.channels.reference.total_tau() / self.sun.z).exp()
    }
    #[inline]
    fn leave(&self, _: &(), _: DVec3) -> f64 {
        self.channels.reference.ground()
    }
}

/// The first layer (from the top) where some channel of a walk over `atms` scatters but the
/// walk's reference does not, and the reference's member, if any: such a walk would miss
/// paths. `scene`: the reference is chosen as 3D scene walks choose it.
pub fn unsupported_group(atms: &[&PlaneParallel], scene: bool) -> Option<(usize, usize)> {
    let member = IntegratorSettings::reference_member(atms, scene);
    let reference = group_reference(atms[member], atms);
    Layers::unsupported_layer(&reference, atms).map(|i| (i, member))
}

/// Spectral ALIS (`integrator.spectral_walk = "alis"`): each group's reference (its central wavelength's scattering) must scatter
/// wherever one of its wavelengths does, or the walks would miss paths. `atmospheres` holds
/// the atmosphere of every run wavelength.
pub fn check_spectral_groups(
    settings: &IntegratorSettings,
    ctx: &ConfigCtx,
    wavelengths: &[f64],
    atmospheres: &[&PlaneParallel],
    scene: bool,
) -> Result<(), ConfigError> {
    let Some(n) = settings.spectral_alis else {
        return Ok(());
    };
    for group in crate::spectral::wavelength_groups_of(wavelengths, Some(n)) {
        let atms: Vec<&PlaneParallel> = group.iter().map(|&iw| atmospheres[iw]).collect();
        if let Some((i, member)) = unsupported_group(&atms, scene) {
            let central = group[member];
            return Err(ctx.err(
                "integrator.spectral_walk",
                format!(
                    "layer {i} (from the top) scatters at some wavelength of the group {}–{} nm but not at its reference wavelength {} nm; use smaller groups (integrator.alis_group) or \"independent\"",
                    wavelengths[group[0]],
                    wavelengths[group[group.len() - 1]],
                    wavelengths[central]
                ),
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    #[test]
    fn exp_fast_matches_exp() {
        let mut worst = 0.0_f64;
        for i in 0..=200_000 {
            let x = -700.0 + 710.0 * i as f64 / 200_000.0;
            let (a, b) = (super::exp_fast(x), x.exp());
            worst = worst.max((a / b - 1.0).abs());
        }
        assert!(worst < 3e-10, "max relative error {worst:e}");
        assert!(super::exp_fast(-1e6) >= 0.0 && super::exp_fast(-1e6) < 1e-300);
        assert_eq!(super::exp_fast(0.0), 1.0);
    }
}

/// What the weights of walks that carry several channels along one path (this module's
/// [`ChannelPath`], and `scene_alis.rs`'s `SceneChannelPath`) do alike.
pub(crate) mod channels {
    use glam::DVec3;

    use crate::accum::Accum;
    use crate::integrator::weight::OrderSplit;
    use crate::phase::PhaseFunction;
    use crate::rng::Stream;

    /// Grey scattering: the same `ω·P(cos)·k` added to every channel (the channels' own
    /// scattering is accumulated by their geometries).
    #[inline]
    pub(crate) fn accumulate_grey(
        acc: &mut [f64],
        phase: &PhaseFunction,
        cos: f64,
        omega: f64,
        k: f64,
    ) {
        let x = omega * phase.eval(cos) * k;
        acc.iter_mut().for_each(|a| *a += x);
    }

    /// 1 if any channel scores, else 0 (the walk's cut-off only asks whether the estimate is
    /// zero).
    #[inline]
    pub(crate) fn phase_intensity(acc: &[f64]) -> f64 {
        if acc.iter().any(|x| *x != 0.0) {
            1.0
        } else {
            0.0
        }
    }

    /// A new direction from the reference phase function, rotated from `d` (two random
    /// numbers: μ, then φ): (μ, direction).
    #[inline]
    pub(crate) fn reference_direction(
        phase: &PhaseFunction,
        d: DVec3,
        rng: &mut Stream,
    ) -> (f64, DVec3) {
        let mu = phase.sample_cos(rng.next_f64());
        let phi = std::f64::consts::TAU * rng.next_f64();
        (mu, crate::frame::rotate_about(d, mu, phi))
    }

    /// The path factors after a scattering drawn from the reference: `e_c × r_c / P_ref(μ)`
    /// with `r_c = (σ_c/σ_ref)·P_c(μ)` (0 where the reference's phase function is 0).
    #[inline]
    pub(crate) fn times_phase_ratio(e: &mut [f64], r: &[f64], p_ref: f64) {
        let inv = if p_ref > 0.0 { 1.0 / p_ref } else { 0.0 };
        for (ek, rk) in e.iter_mut().zip(r) {
            *ek *= rk * inv;
        }
    }

    /// One accumulator cell per channel (`cell` must be 0): each channel's scores.
    pub(crate) fn record(acc: &mut Accum, cell: usize, t: &[OrderSplit], k: f64) {
        debug_assert_eq!(cell, 0);
        for (c, tc) in t.iter().take(acc.n.len()).enumerate() {
            let (a, b) = tc.scaled(k);
            acc.add(c, a, b);
        }
    }

    /// `t[c] += ratio[c]·other[c]` for the channels with an accumulator cell (`ratio` has one
    /// entry per cell).
    pub(crate) fn add_scaled(t: &mut [OrderSplit], other: &[OrderSplit], ratio: &[f64]) {
        for ((tc, oc), r) in t.iter_mut().zip(other).zip(ratio) {
            tc.add_scaled(oc, *r);
        }
    }

    /// [`Weight::mean_first_order`], channel by channel.
    pub(crate) fn mean_first_order(t: &mut [OrderSplit], others: &[OrderSplit], k: u32) {
        for (tc, oc) in t.iter_mut().zip(others) {
            tc.mean_first_order(oc, k);
        }
    }
}
