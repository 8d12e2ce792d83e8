//! Thermal emission of plane-parallel layers: the expected emitted radiance a backward path
//! gathers along one flight.
//!
//! Each layer emits `(1 − ω)·B(τ)` per unit optical path, with `B` the Planck radiance
//! (`planck.rs`) varying **linearly in optical depth** inside the layer between `B(T_top)` at
//! its top and `B(T_bottom)` at its bottom (DISORT's convention, Stamnes et al. 2000, §3.3; an
//! isothermal layer has `B_top = B_bottom`). The sources are stored per layer in the units of
//! the path tally (radiance divided by the irradiance that normalises the run, see
//! `docs/transport.md`, "Thermal emission").
//!
//! A flight from optical depth `τ_a` with vertical cosine `dz` collides at optical path `x`
//! (along the ray) with density `e^{−x}`. The collision estimator of emission scores
//! `(1 − ω)·B` at the collision; its expectation over the flight is
//! `E = Σ_layers ∫ e^{−x} (1 − ω_L) B(x) dx`, which for `B` linear in `x` over a segment
//! `[x₁, x₁ + D]` with end values `S₁`, `S₂` is, exactly,
//! `e^{−x₁}·[S₁·(1 − e^{−D}) + (S₂ − S₁)·g(D)]`, `g(D) = (1 − e^{−D}(1 + D))/D`.
//! Scoring `E` at every flight (instead of at sampled collisions) removes the variance of the
//! collision position; survival biasing (the weight times ω at scatterings) then accounts for
//! the `(1 − ω)` share exactly once (Marchuk et al. 1980, ch. 2, for expected estimates).

use super::PlaneParallel;

/// `(1 − e^{−D}(1 + D))/D` for `D ≥ 0`, to ~1e-12 relative: below D = 0.01 by its series
/// `Σ_{k≥2} (−1)^k (k − 1) D^{k−1}/k!` (to k = 7), above by the closed form.
fn g(d: f64) -> f64 {
    if d < 1e-2 {
        d * (1.0 / 2.0
            - d * (1.0 / 3.0 - d * (1.0 / 8.0 - d * (1.0 / 30.0 - d * (1.0 / 144.0 - d / 840.0)))))
    } else {
        // 1 − e^{−D}(1 + D) = −expm1(−D) − D·e^{−D}
        (-(-d).exp_m1() - d * (-d).exp()) / d
    }
}

/// `∫₀^D e^{−y}·(s1 + (s2 − s1)·y/D) dy` times `e^{−x1}`.
#[inline]
fn segment(x1: f64, d: f64, s1: f64, s2: f64) -> f64 {
    (-x1).exp() * (s1 * (-(-d).exp_m1()) + (s2 - s1) * g(d))
}

impl PlaneParallel {
    /// Set the layers' thermal sources: `f(top, bottom)` (altitudes of the layer's boundaries,
    /// m) returns the source `[at top, at bottom]` in tally units.
    pub fn set_sources(&mut self, f: impl Fn(f64, f64) -> [f64; 2]) {
        self.source = (0..self.albedo.len())
            .map(|i| f(self.z[i], self.z[i + 1]))
            .collect();
    }

    /// Multiply the layers' sources by `scale`, one factor per layer **from the ground up**
    /// (the order of the resolver's layer grid; the layers are stored top down).
    pub fn scale_sources(&mut self, scale: &[f64]) {
        debug_assert_eq!(scale.len(), self.source.len());
        for (src, k) in self.source.iter_mut().rev().zip(scale) {
            src[0] *= k;
            src[1] *= k;
        }
    }

    /// Layer `l`'s source `[at its top, at its bottom]` (tally units; zeros without emission).
    pub fn source(&self, l: usize) -> [f64; 2] {
        self.source.get(l).copied().unwrap_or([0.0, 0.0])
    }

    /// Whether any layer emits.
    pub fn emits(&self) -> bool {
        self.source.iter().any(|s| s[0] > 0.0 || s[1] > 0.0)
    }

    /// The source (tally units) at optical depth `tau` inside layer `l`.
    fn source_at(&self, l: usize, tau: f64) -> f64 {
        let [top, bottom] = self.source[l];
        let d = self.tau[l + 1] - self.tau[l];
        if d <= 0.0 {
            return top;
        }
        top + (bottom - top) * ((tau - self.tau[l]) / d).clamp(0.0, 1.0)
    }

    /// Emitted radiance per unit horizontal area and solid angle of layer `l`,
    /// `(1 − ω) Δτ (S_top + S_bot)/2` (times 4π: its emitted power), tally units.
    pub fn emitted_per_area(&self, l: usize) -> f64 {
        match self.source.get(l) {
            None => 0.0,
            Some([top, bottom]) => {
                (1.0 - self.albedo[l]) * (self.tau[l + 1] - self.tau[l]) * 0.5 * (top + bottom)
            }
        }
    }

    /// An optical depth in layer `l` drawn with density proportional to its source (linear
    /// in τ), from a uniform `u`.
    pub fn sample_emission_depth(&self, l: usize, u: f64) -> f64 {
        let [a, b] = self.source[l];
        // CDF of a + (b − a)x on [0, 1], normalised: solved for x in the rationalised form,
        // stable as b → a.
        let x = if a + b > 0.0 {
            u * (a + b) / (a + (a * a + (b - a) * u * (a + b)).max(0.0).sqrt())
        } else {
            u
        };
        self.tau[l] + x.clamp(0.0, 1.0) * (self.tau[l + 1] - self.tau[l])
    }

    /// Expected emission scored by the collision estimator over the next collision of a flight
    /// from `tau_a` along vertical cosine `dz` (> 0 up): `E[(1 − ω)·B(τ_c)·1{collision}]`, in
    /// tally units. 0 without sources.
    pub fn expected_emission(&self, tau_a: f64, dz: f64) -> f64 {
        if self.source.is_empty() || self.total_tau <= 0.0 {
            return 0.0;
        }
        let n = self.albedo.len();
        if dz.abs() < 1e-9 {
            // A horizontal flight collides where it is.
            if tau_a > 0.0 && tau_a < self.total_tau {
                let l = self.layer_at_tau(tau_a);
                return (1.0 - self.albedo[l]) * self.source_at(l, tau_a);
            }
            return 0.0;
        }
        let a = 1.0 / dz.abs();
        let mut sum = 0.0;
        for l in 0..n {
            let k = 1.0 - self.albedo[l];
            if k <= 0.0 {
                continue;
            }
            let (t1, t2) = if dz < 0.0 {
                (self.tau[l].max(tau_a), self.tau[l + 1])
            } else {
                (self.tau[l], self.tau[l + 1].min(tau_a))
            };
            if t2 <= t1 {
                continue;
            }
            let d = a * (t2 - t1);
            // Along the ray, the segment starts at the boundary nearest to tau_a.
            let (near, far) = if dz < 0.0 { (t1, t2) } else { (t2, t1) };
            let x1 = a * (near - tau_a).abs();
            sum += k * segment(x1, d, self.source_at(l, near), self.source_at(l, far));
        }
        sum
    }
}

#[cfg(test)]
mod tests {
    use super::super::LayerOptics;
    use super::*;
    use crate::phase::{HenyeyGreenstein, PhaseFunction};

    fn atm(layers: &[(f64, f64, f64, f64)]) -> PlaneParallel {
        let layers = layers
            .iter()
            .map(|&(bottom, top, tau_sca, tau_abs)| LayerOptics {
                bottom,
                top,
                tau_sca,
                tau_abs,
                phase: PhaseFunction::Hg(HenyeyGreenstein { g: 0.0 }),
            })
            .collect();
        PlaneParallel::new(layers, 0.0, 100.0)
    }

    /// Non-scattering isothermal layer seen from the top: B·(1 − e^{−τ/μ}).
    #[test]
    fn isothermal_absorbing_layer() {
        let mut a = atm(&[(0.0, 100.0, 0.0, 0.7)]);
        a.set_sources(|_, _| [2.0, 2.0]);
        for mu in [1.0, 0.5, 0.1] {
            let e = a.expected_emission(0.0, -mu);
            let want = 2.0 * (1.0 - (-0.7f64 / mu).exp());
            assert!((e - want).abs() < 1e-13, "{e} {want}");
        }
        // From the ground looking up: the same by symmetry.
        let e = a.expected_emission(0.7, 0.5);
        assert!((e - 2.0 * (1.0 - (-1.4f64).exp())).abs() < 1e-13);
    }

    /// A linear source split into many thin layers equals the same source in one layer, and a
    /// midpoint quadrature of ∫ e^{−x} (1−ω) B dx.
    #[test]
    fn linear_source_against_quadrature() {
        let (bt, bb, tau, omega, mu) = (1.0, 3.0, 2.0, 0.4, 0.6);
        let mut one = atm(&[(0.0, 100.0, tau * omega, tau * (1.0 - omega))]);
        one.set_sources(|_, _| [bt, bb]);
        let n = 50;
        let thin: Vec<_> = (0..n)
            .map(|i| {
                let dz = 100.0 / n as f64;
                (
                    i as f64 * dz,
                    (i + 1) as f64 * dz,
                    tau * omega / n as f64,
                    tau * (1.0 - omega) / n as f64,
                )
            })
            .collect();
        let mut many = atm(&thin);
        // B linear in τ = linear in altitude here (a homogeneous layer).
        many.set_sources(|top, bottom| {
            [
                bt + (bb - bt) * (100.0 - top) / 100.0,
                bt + (bb - bt) * (100.0 - bottom) / 100.0,
            ]
        });
        for (t0, dz) in [(0.0, -mu), (tau, mu), (0.8, -mu), (0.8, mu)] {
            let e1 = one.expected_emission(t0, dz);
            let e2 = many.expected_emission(t0, dz);
            // Quadrature along the ray.
            let m = 200_000;
            let end = if dz < 0.0 { tau } else { 0.0 };
            let xmax = (end - t0).abs() / mu;
            let h = xmax / m as f64;
            let q: f64 = (0..m)
                .map(|i| {
                    let x = (i as f64 + 0.5) * h;
                    let t = t0 - x * dz.signum() * mu;
                    (-x).exp() * (1.0 - omega) * (bt + (bb - bt) * t / tau) * h
                })
                .sum();
            assert!((e1 - q).abs() < 1e-9, "{e1} {q}");
            assert!((e2 - q).abs() < 1e-9, "{e2} {q}");
        }
    }

    /// The depth sampler follows the linear source: histogram against the density.
    #[test]
    fn emission_depths_follow_the_source() {
        let mut a = atm(&[(0.0, 100.0, 0.0, 2.0)]);
        a.set_sources(|_, _| [1.0, 3.0]);
        let n = 200_000;
        let mut bins = [0usize; 4];
        for i in 0..n {
            let t = a.sample_emission_depth(0, (i as f64 + 0.5) / n as f64);
            bins[((t / 2.0 * 4.0) as usize).min(3)] += 1;
        }
        for (k, &c) in bins.iter().enumerate() {
            // ∫ over the bin of (1 + 2x)/2 dx, x in [k/4, (k+1)/4].
            let (x0, x1) = (k as f64 / 4.0, (k + 1) as f64 / 4.0);
            let want = ((x1 + x1 * x1) - (x0 + x0 * x0)) / 2.0;
            assert!((c as f64 / n as f64 - want).abs() < 1e-4, "{k}: {c}");
        }
        assert!((a.emitted_per_area(0) - 2.0 * 2.0).abs() < 1e-15);
    }

    #[test]
    fn small_segments_are_accurate() {
        // Series d/2 − d²/3 + d³/8 − d⁴/30 near 0, the closed form further out, and the two
        // branches agree where they meet.
        for d in [1e-9, 1e-6, 1e-4, 5e-3] {
            let want = d * (0.5 - d / 3.0 + d * d / 8.0 - d * d * d / 30.0);
            assert!((g(d) / want - 1.0).abs() < 1e-10, "{d}");
        }
        for d in [1e-2, 0.1, 5.0, 800.0f64] {
            let want = (1.0 - (-d).exp() * (1.0 + d)) / d;
            assert!((g(d) / want - 1.0).abs() < 1e-9, "{d}");
        }
        let (a, b) = (g(1e-2 * (1.0 - 1e-12)), g(1e-2));
        assert!((a / b - 1.0).abs() < 1e-11, "{a} {b}");
    }
}
