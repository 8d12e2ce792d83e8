//! Photon counting (ICESat-2-like): Poisson statistics of the detected photons per shot from a
//! shot's waveform, simulated photon events (signal and solar background, with dead time), and
//! the solar background from the passive radiance of the footprint.
//!
//! Signal photons per shot are Poisson with mean `n̄ = K·e`, `K = E_T λ/(h c) · η · A_r/(π R0²)`
//! and `e` the shot's normalised energy (`trace.rs`): the detected photons are a thinning of
//! the emitted ones, each detected independently. So the count's mean and variance are both
//! `n̄`, `P(k) = e^{−n̄} n̄^k / k!`, and the counts from parts of the return (canopy, ground)
//! are independent Poisson variables of means `K·e_part`. Their standard errors follow from
//! the Monte Carlo error of `e` (`σ_n̄ = K σ_e`; `σ_P(k) = P(k)|k/n̄ − 1| σ_n̄`).
//!
//! Background photons per range gate are Poisson with mean
//! `L_bg · A_r · Ω · Δλ · gate · η · λ/(h c)`, `Ω = 2π(1 − cos fov)` the receiver's solid angle
//! and `L_bg` the passive radiance (W m⁻² sr⁻¹ nm⁻¹) the receiver sees, every order and the
//! air's path radiance included, from the run's own passive estimators (the application's
//! `lidar.rs`, `passive_radiance`: a radiancemeter at the sensor over a 1D ground, an `mdistant`
//! over the field of view's square in a scene).

use super::trace::{ShotWaveform, Stat, FIRST_CANOPY, FIRST_GROUND, TOTAL};
use super::{Lidar, C_M_PER_NS};
use crate::rng::Stream;

/// Poisson statistics of one shot location.
#[derive(Clone, Debug)]
pub struct CountingStats {
    /// Mean photons per shot `K` per unit normalised energy.
    pub photons_per_e: f64,
    pub mean: Stat,
    pub variance: Stat,
    /// `P(k)` for k = 0 … [`MAX_K`].
    pub p: Vec<Stat>,
    pub canopy_mean: Stat,
    pub ground_mean: Stat,
    pub ground_p0: Stat,
    /// Mean signal photons per shot in each bin.
    pub bins: Vec<Stat>,
    /// Mean background photons per range gate (0 without the Sun or a filter).
    pub background_per_gate: Stat,
}

/// The largest k of the reported `P(k)`.
pub const MAX_K: usize = 12;

/// The Poisson statistics of shot `k` from its waveform and background.
pub fn stats(lidar: &Lidar, w: &ShotWaveform, shot: usize, background: Stat) -> CountingStats {
    let k = lidar.pulse_energy_j
        * lidar.photons_per_joule()
        * lidar.efficiency
        * lidar.energy_scale(lidar.shots[shot]);
    let scaled = |s: Stat| Stat {
        mean: k * s.mean,
        stderr: k * s.stderr,
    };
    let mean = scaled(w.totals[TOTAL]);
    let mut pk = Vec::with_capacity(MAX_K + 1);
    let mut term = (-mean.mean).exp();
    for j in 0..=MAX_K {
        if j > 0 {
            term *= mean.mean / j as f64;
        }
        let deriv = if mean.mean > 0.0 {
            term * (j as f64 / mean.mean - 1.0)
        } else {
            0.0
        };
        pk.push(Stat {
            mean: term,
            stderr: (deriv * mean.stderr).abs(),
        });
    }
    let ground_mean = scaled(w.totals[FIRST_GROUND]);
    let g0 = (-ground_mean.mean).exp();
    CountingStats {
        photons_per_e: k,
        mean,
        variance: mean,
        p: pk,
        canopy_mean: scaled(w.totals[FIRST_CANOPY]),
        ground_mean,
        ground_p0: Stat {
            mean: g0,
            stderr: g0 * ground_mean.stderr,
        },
        bins: w.bins.iter().map(|b| scaled(b[TOTAL])).collect(),
        background_per_gate: background,
    }
}

/// The mean background photons per range gate from the radiance `l_bg` (W m⁻² sr⁻¹ nm⁻¹, with
/// its standard error) the receiver sees.
pub fn background_from_radiance(lidar: &Lidar, l_bg: Stat) -> Stat {
    let omega = std::f64::consts::TAU * (1.0 - lidar.fov_half_angle.cos());
    let scale = lidar.receiver_area_m2
        * omega
        * lidar.filter_width_nm
        * lidar.gate_ns
        * 1e-9
        * lidar.efficiency
        * lidar.photons_per_joule();
    Stat {
        mean: l_bg.mean * scale,
        stderr: l_bg.stderr * scale,
    }
}

/// One detected photon of a simulated shot (the ATL03-like table).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhotonEvent {
    /// Shot index within the location, and the location (footprint) index.
    pub shot: u64,
    pub location: usize,
    /// Two-way delay after `2 R0 / c`, ns, and apparent height above the footprint centre, m.
    pub time_ns: f64,
    pub height_m: f64,
    /// Signal (laser) or solar background.
    pub signal: bool,
}

/// A Poisson variate of mean `m` (exact: sums of inversions of means ≤ 16).
pub fn poisson(rng: &mut Stream, mut m: f64) -> u64 {
    let mut n = 0;
    while m > 0.0 {
        let part = m.min(16.0);
        m -= part;
        let mut p = (-part).exp();
        let mut cdf = p;
        let u = rng.next_f64();
        let mut k = 0u64;
        while u >= cdf && k < 1000 {
            k += 1;
            p *= part / k as f64;
            cdf += p;
        }
        n += k;
    }
    n
}

/// Simulate `lidar.shots_per_location` shots at location `loc`: signal photons drawn from the
/// expected waveform (`stats.bins`, each photon uniform inside its bin), background photons
/// uniform over the range gate (centred on the bins), then the detector's dead time (a photon
/// within `dead_time_ns` after a detected one is lost).
pub fn simulate_shots(
    lidar: &Lidar,
    stats: &CountingStats,
    seed: u64,
    loc: usize,
) -> Vec<PhotonEvent> {
    let weights: Vec<f64> = stats.bins.iter().map(|b| b.mean.max(0.0)).collect();
    let n_in_bins: f64 = weights.iter().sum();
    let mut cdf = Vec::with_capacity(weights.len());
    let mut acc = 0.0;
    for w in &weights {
        acc += w;
        cdf.push(acc / n_in_bins.max(f64::MIN_POSITIVE));
    }
    let b = &lidar.bins;
    let span_mid = b.first_ns + 0.5 * (b.count as f64 - 1.0) * b.width_ns;
    let zc = 0.0;
    let mut events = Vec::new();
    let mut shot_events = Vec::new();
    for s in 0..lidar.shots_per_location {
        let mut rng = Stream::new(seed, [0x11DA_C000, lidar.index as u64, loc as u64, s]);
        shot_events.clear();
        let ns = poisson(&mut rng, n_in_bins);
        for _ in 0..ns {
            let u = rng.next_f64();
            let k = cdf.partition_point(|&c| c <= u).min(b.count - 1);
            let t = b.centre_ns(k) + (rng.next_f64() - 0.5) * b.width_ns;
            shot_events.push((t, true));
        }
        let nb = poisson(&mut rng, stats.background_per_gate.mean);
        for _ in 0..nb {
            let t = span_mid + (rng.next_f64() - 0.5) * lidar.gate_ns;
            shot_events.push((t, false));
        }
        shot_events.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut last = f64::NEG_INFINITY;
        for &(t, signal) in &shot_events {
            if t - last < lidar.dead_time_ns {
                continue;
            }
            last = t;
            events.push(PhotonEvent {
                shot: s,
                location: loc,
                time_ns: t,
                height_m: zc - 0.5 * C_M_PER_NS * t,
                signal,
            });
        }
    }
    events
}
