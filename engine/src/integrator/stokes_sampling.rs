//! Stokes-aware sampling of the scattering direction (polarized runs).
//!
//! Light of Stokes vector `(I, Q, U, V)` travelling along `d` with frame axis `e1` (conventions
//! of [`crate::stokes`]) scatters into `d' = μ·d + sin Θ·(cos φ·e1 + sin φ·e2)`, `e2 = d × e1`,
//! with intensity `I' = a1(Θ)·I + b1(Θ)·(Q·cos 2φ + U·sin 2φ)`: the scattering plane's parallel
//! axis is `l = cos φ·e1 + sin φ·e2`, so `Q` rotated into it is `Q cos 2φ + U sin 2φ`. This file
//! draws `(Θ, φ)` from exactly that density,
//!
//! `p(μ, φ) = [a1(μ) + b1(μ)·(q cos 2φ + u sin 2φ)] / 4π`, with `q = Q/I`, `u = U/I`,
//!
//! so the scattered intensity weight is exactly `ω·I` (as in MYSTIC, Emde et al. 2010, and
//! SMART-G, Ramon et al. 2019): μ from the marginal `a1/2` (the phase function's own sampler,
//! one uniform number), then φ from the conditional `(1 + A cos 2(φ − φ0))/2π`,
//! `A = (b1/a1)·√(q² + u²) ∈ [−1, 1]`, `2φ0 = atan2(u, q)`, by inverting its CDF (a Kepler
//! equation `x + A sin x = c`, solved by safeguarded Newton iterations to 1e-14; one uniform
//! number). The old scheme (φ uniform, weight `ω·F/a1`) has an intensity factor in `[0, 2]` per
//! scattering that compounds with the order: heavy-tailed in thick media.
//!
//! The backward (adjoint) path matrix `T` uses the same density with `q = T01/T00`,
//! `u = −T02/T00` (its first row, see [`super::weight::MuellerPath`]): then `T00` is multiplied
//! by exactly ω.
//!
//! For depolarizing phase functions (`b1 = 0`) or unpolarized light, φ is uniform.
//!
//! References: Emde et al. (2010), JQSRT 111:1622 (MYSTIC polarization, §2.3); Ramon et al.
//! (2019), Front. Earth Sci. 7:155 (SMART-G).

use glam::DVec3;

use super::peak_sampling::PeakSampling;
use crate::phase::PhaseFunction;
use crate::rng::Stream;
use crate::stokes::PhaseMatrix;

/// A new propagation direction after scattering along `d`: cos Θ from the phase function, a
/// uniform azimuth about `d` (two random numbers).
#[inline]
pub(crate) fn sample_scattered(phase: &PhaseFunction, d: DVec3, rng: &mut Stream) -> DVec3 {
    let mu = phase.sample_cos(rng.next_f64());
    let phi = std::f64::consts::TAU * rng.next_f64();
    crate::frame::rotate_about(d, mu, phi)
}

/// A drawn scattering direction `d2` with the phase matrix at its angle and the sampling
/// density's numerator `norm = a1 + b1·(q cos 2φ + u sin 2φ)` (the density is `norm/4π`).
pub(crate) struct StokesSample {
    pub d2: DVec3,
    pub f: PhaseMatrix,
    pub norm: f64,
}

/// Draw a direction for light along `d` (frame axis `e1`) with relative Stokes parameters
/// `q`, `u` (`q² + u² ≤ 1`), from two uniform numbers.
#[inline]
pub(crate) fn sample(
    phase: &PhaseFunction,
    d: DVec3,
    e1: DVec3,
    q: f64,
    u: f64,
    rng: &mut Stream,
) -> StokesSample {
    let mu = phase.sample_cos(rng.next_f64());
    let f = phase.matrix(mu);
    let p = (q * q + u * u).sqrt();
    let a = if f.a1 > 0.0 && p > 0.0 {
        (f.b1 / f.a1 * p).clamp(-1.0, 1.0)
    } else {
        0.0
    };
    let phi = if a == 0.0 {
        std::f64::consts::TAU * rng.next_f64()
    } else {
        0.5 * u.atan2(q) + azimuth_offset(a, rng.next_f64())
    };
    let (sp, cp) = phi.sin_cos();
    let s = (1.0 - mu * mu).max(0.0).sqrt();
    let e2 = d.cross(e1);
    let d2 = (d * mu + (e1 * cp + e2 * sp) * s).normalize();
    let (s2, c2) = (2.0 * phi).sin_cos();
    let norm = f.a1 + f.b1 * (q * c2 + u * s2);
    StokesSample { d2, f, norm }
}

/// [`sample`], or where `peak` is active the DDIS mixture ([`PeakSampling`]): then `norm` is the
/// mixture's density (times 4π) relative to `I`, `(1 − ε)·norm_at(d2) + ε·detector density`.
#[inline]
pub(crate) fn sample_with(
    phase: &PhaseFunction,
    d: DVec3,
    e1: DVec3,
    q: f64,
    u: f64,
    peak: &PeakSampling,
    rng: &mut Stream,
) -> StokesSample {
    if !peak.active(phase) {
        return sample(phase, d, e1, q, u, rng);
    }
    // The main sampler's density at its own draw is known; at a detector draw it is evaluated.
    let main = match peak.choose(rng) {
        Some(axis) => {
            let d2 = sample_scattered(phase, axis, rng);
            let f = phase.matrix(d.dot(d2));
            StokesSample {
                norm: norm_at(&f, d, e1, q, u, d2),
                d2,
                f,
            }
        }
        None => sample(phase, d, e1, q, u, rng),
    };
    StokesSample {
        norm: peak.mixture(phase, main.norm, main.d2),
        ..main
    }
}

/// The numerator `a1 + b1·(q cos 2φ + u sin 2φ)` of [`sample`]'s density at a given `d2`
/// (φ its azimuth about `d` from `e1` towards `d × e1`; `f` the phase matrix at `d·d2`).
#[inline]
pub(crate) fn norm_at(f: &PhaseMatrix, d: DVec3, e1: DVec3, q: f64, u: f64, d2: DVec3) -> f64 {
    let (x, y) = (d2.dot(e1), d2.dot(d.cross(e1)));
    let r2 = x * x + y * y;
    if r2 < 1e-300 {
        return f.a1;
    }
    f.a1 + f.b1 * (q * (x * x - y * y) + u * 2.0 * x * y) / r2
}

/// ψ ∈ [0, 2π) with density `(1 + A cos 2ψ)/2π` from one uniform number `v`: the half of the
/// circle from the first bit of `v`, then `x = 2ψ mod 2π` from `(x + A sin x)/2π = v'`.
#[inline]
pub(crate) fn azimuth_offset(a: f64, v: f64) -> f64 {
    let (half, v) = if v < 0.5 {
        (0.0, 2.0 * v)
    } else {
        (std::f64::consts::PI, 2.0 * v - 1.0)
    };
    0.5 * solve_kepler(a, std::f64::consts::TAU * v) + half
}

/// The root `x ∈ [0, 2π]` of `x + a·sin x = c` (`|a| ≤ 1`, `c ∈ [0, 2π]`): the left side is
/// non-decreasing, so Newton steps kept inside a shrinking bracket converge.
fn solve_kepler(a: f64, c: f64) -> f64 {
    let (mut lo, mut hi) = (0.0_f64, std::f64::consts::TAU);
    let mut x = c;
    for _ in 0..60 {
        let (s, co) = x.sin_cos();
        let g = x + a * s - c;
        if g > 0.0 {
            hi = x;
        } else {
            lo = x;
        }
        let dg = 1.0 + a * co;
        let mut next = if dg > 1e-300 { x - g / dg } else { lo - 1.0 };
        if !(next > lo && next < hi) {
            next = 0.5 * (lo + hi);
        }
        if (next - x).abs() < 1e-14 {
            return next;
        }
        x = next;
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The inverse CDF solves its equation and its histogram matches the density (χ², 50
    /// bins, 200 000 draws, 0.1 % quantile 86.7 for 49 dof) for several A, including ±1.
    #[test]
    fn azimuth_density() {
        let mut rng = Stream::new(3, [1, 4, 1, 5]);
        for &a in &[0.0, 0.3, -0.7, 1.0, -1.0] {
            for k in 0..100 {
                let c = std::f64::consts::TAU * (k as f64 + 0.5) / 100.0;
                let x = solve_kepler(a, c);
                assert!((x + a * x.sin() - c).abs() < 1e-12, "a {a} c {c}");
            }
            let nb = 50;
            let n = 200_000;
            let mut counts = vec![0.0; nb];
            for _ in 0..n {
                let psi = azimuth_offset(a, rng.next_f64());
                assert!((0.0..std::f64::consts::TAU).contains(&psi));
                counts[((psi / std::f64::consts::TAU * nb as f64) as usize).min(nb - 1)] += 1.0;
            }
            let mut chi2 = 0.0;
            for (i, c) in counts.iter().enumerate() {
                let (x0, x1) = (
                    std::f64::consts::TAU * i as f64 / nb as f64,
                    std::f64::consts::TAU * (i + 1) as f64 / nb as f64,
                );
                // ∫(1 + A cos 2ψ)/2π dψ over the bin.
                let e = ((x1 - x0) + 0.5 * a * ((2.0 * x1).sin() - (2.0 * x0).sin()))
                    / std::f64::consts::TAU
                    * n as f64;
                chi2 += (c - e) * (c - e) / e;
            }
            assert!(chi2 < 86.7, "A = {a}: chi2 {chi2}");
        }
    }
}
