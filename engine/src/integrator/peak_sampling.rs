//! Detector-directional importance sampling (DDIS; Buras & Mayer 2011) for forward-peaked
//! phase functions (clouds, large aerosols).
//!
//! The local (next-event) estimate of a collision is `ω·P(cos Θ_det)·T`: through a diffraction
//! peak it is huge for the rare paths that travel almost along the detector direction (the Sun
//! in a backward walk, a sensor direction in a forward one), so its samples are heavy-tailed.
//! DDIS draws the scattered direction from a mixture: with probability `1 − ε` from the phase
//! function about the current direction (as without DDIS), with probability `ε` from the
//! phase function about one of the `K` detector directions `v_k` (picked uniformly), and
//! weights the path by the ratio of the scattering density to the mixture's density,
//!
//! `p(d') = (1 − ε)·P(d·d')/4π + ε/K · Σ_k P(v_k·d')/4π` (scalar),
//!
//! with the Stokes-aware density `(F·S)_I/(4π·I)` in place of `P(d·d')/4π` in polarized runs
//! ([`super::stokes_sampling`]). Unbiased (the mixture covers every direction the scattering
//! reaches); the paths that approach a detector direction now come often and with small
//! weights, which bounds the product of weight and peak: `weight·P(v·d') ≤ ω·P(d·d')/ε·K`.
//!
//! DDIS acts only at collisions whose phase function has a peak `P(1) ≥` [`PEAK_MIN`] (100:
//! water clouds ~10³–10⁴, Henyey–Greenstein g = 0.9 gives 190; Rayleigh 1.5 and most aerosol
//! tables are left alone, so their runs draw the same random numbers as without DDIS). There it
//! draws one more uniform number per scattering (the mixture's choice). `ε` is
//! `integrator.detector_sampling` (default 0.1, 0 turns DDIS off).
//!
//! Reference: Buras, R. and Mayer, B. (2011), "Efficient unbiased variance reduction techniques
//! for Monte Carlo simulations of radiative transfer in cloudy atmospheres: The solution",
//! JQSRT 112:434–447, §3.2.

use glam::DVec3;

use crate::phase::PhaseFunction;
use crate::rng::Stream;

/// Phase functions whose forward peak `P(1)` reaches this value are sampled with DDIS.
pub const PEAK_MIN: f64 = 100.0;

/// The detector directions of a walk and the mixture weight `ε` (0: no DDIS).
#[derive(Clone, Copy, Debug)]
pub struct PeakSampling<'a> {
    pub eps: f64,
    /// The directions `v` whose local estimates evaluate `P(v·d)` at a flight along `d`.
    pub dirs: &'a [DVec3],
}

impl<'a> PeakSampling<'a> {
    pub const OFF: PeakSampling<'static> = PeakSampling {
        eps: 0.0,
        dirs: &[],
    };

    /// Whether scattering through `phase` uses the mixture.
    #[inline]
    pub fn active(&self, phase: &PhaseFunction) -> bool {
        self.eps > 0.0 && !self.dirs.is_empty() && phase.forward_peak() >= PEAK_MIN
    }

    /// Draw the mixture's choice (one uniform number): `Some(v_k)` to sample about a detector
    /// direction, `None` to sample about the current direction.
    #[inline]
    pub fn choose(&self, rng: &mut Stream) -> Option<DVec3> {
        let u = rng.next_f64();
        if u < self.eps {
            let k = ((u / self.eps) * self.dirs.len() as f64) as usize;
            Some(self.dirs[k.min(self.dirs.len() - 1)])
        } else {
            None
        }
    }

    /// `(1/K)·Σ_k P(v_k·d2)`: the detector part of the mixture density (times 4π).
    #[inline]
    pub fn detector_density(&self, phase: &PhaseFunction, d2: DVec3) -> f64 {
        let s: f64 = self.dirs.iter().map(|v| phase.eval(v.dot(d2))).sum();
        s / self.dirs.len() as f64
    }

    /// The mixture density (times 4π) given the main sampler's density `main` (times 4π) at
    /// the drawn direction `d2`.
    #[inline]
    pub fn mixture(&self, phase: &PhaseFunction, main: f64, d2: DVec3) -> f64 {
        (1.0 - self.eps) * main + self.eps * self.detector_density(phase, d2)
    }
}
