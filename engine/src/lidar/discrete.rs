//! A discrete-return detector (airborne laser scanning): the returns of a waveform, as a
//! threshold-and-separation detector finds them on the noiseless simulated waveform.
//!
//! Parameters: `threshold` (a fraction of the waveform's highest bin), `min_separation_ns`
//! (two-way time between accepted returns), `max_returns`. A return is a bin at or above the
//! threshold that is a local maximum (≥ the bin before, > the bin after); candidates are
//! accepted from the strongest down while farther than the separation from every accepted
//! one, at most `max_returns`; they are then numbered in time order (first return first). Its
//! time is refined by the parabola through the peak bin and its neighbours; its energy is the
//! waveform's energy within half the separation on either side (clipped at the neighbouring
//! returns' midpoints); its ground share is the first-order ground energy's part of that.

use glam::DVec3;

use super::trace::{Shot, SurfaceSeen, World};
use super::{Lidar, C_M_PER_NS};
use crate::rng::Stream;
use crate::scene::material::SurfaceModel;

/// ASPRS LAS classes written by the point cloud.
pub const UNCLASSIFIED: u8 = 1;
pub const GROUND: u8 = 2;
pub const HIGH_VEGETATION: u8 = 5;
pub const WATER: u8 = 9;

/// One detected return.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Return {
    /// 1-based, in time order; and the shot's number of returns.
    pub number: u8,
    pub count: u8,
    /// Two-way delay after `2 R0 / c`, ns.
    pub time_ns: f64,
    /// Normalised energy of the return.
    pub energy: f64,
    /// Share of the return's energy from the first-order ground part.
    pub ground_share: f64,
    /// The delays (ns) the return's energy was summed over.
    pub window_ns: (f64, f64),
}

/// The returns of a waveform: `total[k]` and `ground[k]` per bin (time order), bins of width
/// `width_ns` with bin 0 centred at `first_ns`.
pub fn detect(
    total: &[f64],
    ground: &[f64],
    first_ns: f64,
    width_ns: f64,
    threshold: f64,
    min_separation_ns: f64,
    max_returns: usize,
) -> Vec<Return> {
    let n = total.len();
    let peak = total.iter().copied().fold(0.0, f64::max);
    if peak.is_nan() || peak <= 0.0 || n == 0 {
        return Vec::new();
    }
    let thr = threshold * peak;
    let mut cand: Vec<usize> = (0..n)
        .filter(|&k| {
            let v = total[k];
            v >= thr && v > 0.0 && (k == 0 || v >= total[k - 1]) && (k + 1 == n || v > total[k + 1])
        })
        .collect();
    cand.sort_by(|&a, &b| total[b].total_cmp(&total[a]).then(a.cmp(&b)));
    let sep_bins = min_separation_ns / width_ns;
    let mut kept: Vec<usize> = Vec::new();
    for k in cand {
        if kept.len() >= max_returns {
            break;
        }
        if kept
            .iter()
            .all(|&j| (j as f64 - k as f64).abs() >= sep_bins)
        {
            kept.push(k);
        }
    }
    kept.sort_unstable();
    let count = kept.len() as u8;
    let half = (0.5 * sep_bins).max(0.5);
    kept.iter()
        .enumerate()
        .map(|(i, &k)| {
            // Parabolic refinement of the peak's position (in bins).
            let d = if k > 0 && k + 1 < n {
                let (a, b, c) = (total[k - 1], total[k], total[k + 1]);
                let den = a - 2.0 * b + c;
                if den < 0.0 {
                    (0.5 * (a - c) / den).clamp(-0.5, 0.5)
                } else {
                    0.0
                }
            } else {
                0.0
            };
            // The window: ±half the separation, clipped at the neighbours' midpoints.
            let lo_lim = if i > 0 {
                0.5 * (kept[i - 1] + k) as f64
            } else {
                f64::NEG_INFINITY
            };
            let hi_lim = if i + 1 < kept.len() {
                0.5 * (kept[i + 1] + k) as f64
            } else {
                f64::INFINITY
            };
            let lo = (k as f64 - half).max(lo_lim).ceil().max(0.0) as usize;
            let hi = ((k as f64 + half).min(hi_lim).floor() as usize).min(n - 1);
            let e: f64 = total[lo..=hi].iter().sum();
            let g: f64 = ground[lo..=hi].iter().sum();
            Return {
                number: i as u8 + 1,
                count,
                time_ns: first_ns + (k as f64 + d) * width_ns,
                energy: e,
                ground_share: if e > 0.0 {
                    (g / e).clamp(0.0, 1.0)
                } else {
                    0.0
                },
                window_ns: (
                    first_ns + (lo as f64 - 0.5) * width_ns,
                    first_ns + (hi as f64 + 0.5) * width_ns,
                ),
            }
        })
        .collect()
}

/// The LAS class of a surface the beam hits: the experiment's `las_classes` (material name →
/// class) first; then the ground (terrain, ground plane, 1D ground) is 2, or 9 when its
/// material is named `water`; a bi-Lambertian object material (leaves) is 5 (high vegetation);
/// any other object is 1 (unclassified).
pub fn class_of(lidar: &Lidar, world: &World, seen: &SurfaceSeen) -> u8 {
    let name = match (world.scene, seen.material) {
        (Some(sc), Some(m)) => sc.materials.get(m as usize).map(|(n, _)| n.as_str()),
        _ => None,
    };
    if let Some(c) = name.and_then(|n| lidar.las_classes.iter().find(|(k, _)| k == n)) {
        return c.1;
    }
    if seen.ground {
        if name == Some("water") {
            WATER
        } else {
            GROUND
        }
    } else if matches!(seen.model, SurfaceModel::Leaf { .. }) {
        HIGH_VEGETATION
    } else {
        UNCLASSIFIED
    }
}

/// The first-order returns of shot `k` by class, from `n` lines of sight through the footprint
/// (drawn as the tracer draws its photons): each first surface's first-order energy
/// (`π f |n·ω_r|`, its share of the footprint's weight) at its delay (ns), with its class.
/// Point clouds class a return by the class with the most energy within its window.
pub fn first_order_classes(
    lidar: &Lidar,
    world: &World,
    seed: u64,
    k: usize,
    n: u64,
) -> Vec<(f64, f64, u8)> {
    let shot = Shot::new(lidar, k);
    let mut rng = Stream::new(seed, [0x11DA_D000, lidar.index as u64, k as u64, 0]);
    let mut out = Vec::with_capacity(n as usize);
    for _ in 0..n {
        let (fx, fy, w) = lidar.footprint.sample(rng.next_f64(), rng.next_f64());
        let (start, d) = shot.ray(fx, fy);
        let Some(seen) = world.first_surface(lidar, start, d) else {
            continue;
        };
        let (_, back) = shot.towards_receiver(seen.point);
        let t = (seen.distance + back - 2.0 * shot.r0) / C_M_PER_NS;
        let wr: DVec3 = -d;
        let e = w * std::f64::consts::PI * seen.model.eval_cos(seen.normal, wr, -d);
        out.push((t, e / n as f64, class_of(lidar, world, &seen)));
    }
    out
}

/// The class with the most first-order energy inside a return's window (`samples` from
/// [`first_order_classes`]); `fallback` when none falls inside it.
pub fn class_in(samples: &[(f64, f64, u8)], window: (f64, f64), fallback: u8) -> u8 {
    let mut by: Vec<(u8, f64)> = Vec::new();
    for &(t, e, c) in samples {
        if t >= window.0 && t <= window.1 {
            match by.iter_mut().find(|(k, _)| *k == c) {
                Some(x) => x.1 += e,
                None => by.push((c, e)),
            }
        }
    }
    by.iter()
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map_or(fallback, |x| x.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two Gaussian returns (a canopy at 20 ns, a ground at 60 ns) on 1 ns bins: both found, in
    /// time order, at their centres, with their energies and ground shares.
    #[test]
    fn two_returns() {
        let n = 100;
        let g = |t: f64, c: f64, s: f64| (-(t - c).powi(2) / (2.0 * s * s)).exp();
        let total: Vec<f64> = (0..n)
            .map(|k| 0.3 * g(k as f64, 20.3, 3.0) + 0.5 * g(k as f64, 60.0, 3.0))
            .collect();
        let ground: Vec<f64> = (0..n).map(|k| 0.5 * g(k as f64, 60.0, 3.0)).collect();
        let r = detect(&total, &ground, 0.0, 1.0, 0.05, 15.0, 5);
        assert_eq!(r.len(), 2, "{r:?}");
        assert_eq!((r[0].number, r[0].count, r[1].number), (1, 2, 2));
        assert!((r[0].time_ns - 20.3).abs() < 0.05, "{}", r[0].time_ns);
        assert!((r[1].time_ns - 60.0).abs() < 1e-9, "{}", r[1].time_ns);
        assert!(r[0].ground_share < 1e-6 && r[1].ground_share > 0.999);
        // Each return's window holds its Gaussian's area (σ√(2π) per unit height).
        let area = 3.0 * (std::f64::consts::TAU).sqrt();
        assert!(
            (r[1].energy - 0.5 * area).abs() < 0.01 * area,
            "{}",
            r[1].energy
        );
        // A threshold above the weaker return keeps one; max_returns 1 keeps the strongest.
        assert_eq!(detect(&total, &ground, 0.0, 1.0, 0.7, 15.0, 5).len(), 1);
        let one = detect(&total, &ground, 0.0, 1.0, 0.05, 15.0, 1);
        assert_eq!((one.len(), one[0].count), (1, 1));
        assert!((one[0].time_ns - 60.0).abs() < 1e-9);
        // Closer than the separation: merged into the stronger.
        assert_eq!(detect(&total, &ground, 0.0, 1.0, 0.05, 50.0, 5).len(), 1);
        assert!(detect(&[0.0; 5], &[0.0; 5], 0.0, 1.0, 0.1, 1.0, 5).is_empty());
    }
}
