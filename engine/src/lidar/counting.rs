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
//! and `L_bg` the radiance (W m⁻² sr⁻¹ nm⁻¹) the receiver sees, averaged over its field of
//! view: here the first order, the Sun reflected by the first surface along each line of sight
//! (shadowing by the scene and the air's transmittance on both legs). Light the air scatters
//! towards the receiver and interreflections are left out (a lower bound under an atmosphere;
//! exact over a bare surface without air).

use glam::DVec3;

use super::trace::{ShotWaveform, Stat, World, FIRST_CANOPY, FIRST_GROUND, TOTAL};
use super::{Lidar, C_M_PER_NS};
use crate::frame::basis_around;
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

/// The mean background photons per range gate of shot `k`: `L_bg` from `samples` lines of
/// sight spread uniformly over the field of view (module header). `sun_dir`: unit vector
/// towards the Sun; `e0`: its irradiance normal to the beam at the lidar's wavelength
/// (W m⁻² nm⁻¹).
pub fn background(
    lidar: &Lidar,
    world: &World,
    sun_dir: DVec3,
    e0: f64,
    seed: u64,
    k: usize,
    samples: u64,
) -> Stat {
    if lidar.filter_width_nm <= 0.0 || e0 <= 0.0 || sun_dir.z <= 0.0 {
        return Stat::default();
    }
    let centre = lidar.shots[k];
    let sensor = lidar.sensor(centre);
    let r0 = lidar.range0(centre);
    let axis = -lidar.to_sensor;
    let (e1, e2) = basis_around(axis);
    let radius = r0 * lidar.fov_half_angle.tan();
    let mut rng = Stream::new(seed, [0x11DA_B000, lidar.index as u64, k as u64, 0]);
    let atm = world.atmosphere;
    let (mut sum, mut sq) = (0.0, 0.0);
    for _ in 0..samples {
        let r = radius * rng.next_f64().sqrt();
        let phi = std::f64::consts::TAU * rng.next_f64();
        let target = centre + e1 * (r * phi.cos()) + e2 * (r * phi.sin());
        let d = (target - sensor).normalize();
        let mut l = 0.0;
        if let Some(seen) = world.first_surface(lidar, sensor, d) {
            let (p, n, model) = (seen.point, seen.normal, seen.model);
            let f = model.eval_cos(n, sun_dir, -d);
            if f > 0.0 && world.sees_up(p, Some(n), sun_dir, f64::INFINITY) {
                let t_sun = (-atm.optical_path(p, sun_dir, 1e9)).exp();
                let dist = (sensor - p).length();
                let t_view = (-atm.optical_path(p, -d, dist)).exp();
                l = e0 * f * t_sun * t_view;
            }
        }
        sum += l;
        sq += l * l;
    }
    let n = samples as f64;
    let mean = sum / n;
    let var = ((sq / n - mean * mean) * n / (n - 1.0)).max(0.0);
    let omega = std::f64::consts::TAU * (1.0 - lidar.fov_half_angle.cos());
    let scale = lidar.receiver_area_m2
        * omega
        * lidar.filter_width_nm
        * lidar.gate_ns
        * 1e-9
        * lidar.efficiency
        * lidar.photons_per_joule();
    Stat {
        mean: mean * scale,
        stderr: (var / n).sqrt() * scale,
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
