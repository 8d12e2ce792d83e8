//! GEDI-like waveform metrics, as the GEDI simulator's `gediMetric` defines its "true" ones
//! (Hancock et al. 2019, *Earth Space Sci.* 6, 294–310; the simulator's README): computed on
//! the noiseless simulated waveform, with the ground known from its own return.
//!
//! * **ground** (`true ground`): the centre of gravity of the first-order ground return's
//!   apparent heights, m above the footprint centre;
//! * **RH n** (`rhReal`): the height above that ground below which n % of the waveform's energy
//!   lies, the energy accumulated from the lowest bin upwards, spread evenly inside each bin;
//!   `top` is RH 99.9 (`true top`);
//! * **cover**: `E_c / (E_c + E_g ρ_v/ρ_g)`, `E_c` and `E_g` the first-order canopy and ground
//!   energies, `ρ_v = 0.57` and `ρ_g = 0.4` by default (gediMetric's).
//!
//! Each metric of a shot is computed on its mean waveform, with a standard error from the
//! spread of the same metric over the shot's 32 independent replicates (`trace.rs`), divided
//! by √32 (the replicates' waveforms are means of 1/32 of the photons each).

/// The RH percentiles reported.
pub const RH_PERCENTS: [f64; 8] = [10.0, 25.0, 50.0, 75.0, 90.0, 95.0, 98.0, 100.0];

/// Metrics of one waveform (heights in m above the footprint centre; RH above the ground).
#[derive(Clone, Debug, PartialEq)]
pub struct Metrics {
    pub ground: f64,
    /// RH at [`RH_PERCENTS`].
    pub rh: Vec<f64>,
    /// RH 99.9.
    pub top: f64,
    pub cover: f64,
}

/// A waveform as the metrics read it: per bin its centre height (any order), total energy and
/// first-order ground energy; the bins' width (m); the whole first-order canopy and ground
/// energies.
pub struct Profile<'a> {
    pub heights: &'a [f64],
    pub width: f64,
    pub total: &'a [f64],
    pub ground: &'a [f64],
    pub canopy_energy: f64,
    pub ground_energy: f64,
}

/// The metrics of a waveform with the cover's reflectances `rho_v`, `rho_g`; `None` when it
/// has no energy or no ground return.
pub fn metrics(p: &Profile, rho_v: f64, rho_g: f64) -> Option<Metrics> {
    let (heights, w, total, ground) = (p.heights, p.width, p.total, p.ground);
    let (canopy_energy, ground_energy) = (p.canopy_energy, p.ground_energy);
    let mut order: Vec<usize> = (0..heights.len()).collect();
    order.sort_by(|&a, &b| heights[a].total_cmp(&heights[b]));
    let gsum: f64 = ground.iter().sum();
    if gsum <= 0.0 {
        return None;
    }
    let g = ground.iter().zip(heights).map(|(e, z)| e * z).sum::<f64>() / gsum;
    let sum: f64 = total.iter().map(|e| e.max(0.0)).sum();
    if sum <= 0.0 {
        return None;
    }
    // The height below which a fraction f of the energy lies.
    let at = |f: f64| -> f64 {
        let want = f * sum;
        let mut acc = 0.0;
        let mut last = 0.0;
        for &i in &order {
            let e = total[i].max(0.0);
            if e > 0.0 {
                if acc + e >= want {
                    return heights[i] - 0.5 * w + w * ((want - acc) / e).clamp(0.0, 1.0);
                }
                last = heights[i] + 0.5 * w;
            }
            acc += e;
        }
        // Rounding left the sum just short of `want`: the top of the highest bin with energy.
        last
    };
    let rh = RH_PERCENTS.iter().map(|p| at(p / 100.0) - g).collect();
    let top = at(0.999) - g;
    let denom = canopy_energy + ground_energy * rho_v / rho_g;
    let cover = if denom > 0.0 {
        canopy_energy / denom
    } else {
        0.0
    };
    Some(Metrics {
        ground: g,
        rh,
        top,
        cover,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A waveform built so that its RH values are known: a ground return of energy 2 in one bin
    /// at 0 m and a canopy of energy 1, uniform from 10.5 to 20.5 m (ten 1 m bins).
    #[test]
    fn rh_of_a_waveform_built_for_it() {
        let heights: Vec<f64> = (0..25).map(|k| k as f64 - 2.0).collect(); // −2 … 22 m
        let mut total = vec![0.0; 25];
        let mut ground = vec![0.0; 25];
        total[2] = 2.0; // the bin [−0.5, 0.5]
        ground[2] = 2.0;
        // Canopy: bins centred at 11 … 20 (covering 10.5 … 20.5), 0.1 each.
        total[13..23].fill(0.1);
        let p = Profile {
            heights: &heights,
            width: 1.0,
            total: &total,
            ground: &ground,
            canopy_energy: 1.0,
            ground_energy: 2.0,
        };
        let m = metrics(&p, 0.57, 0.4).unwrap();
        assert!((m.ground - 0.0).abs() < 1e-12);
        // Energy 3 in all: 25 % (0.75) and 50 % (1.5) inside the ground bin, −0.5 + 0.375 and
        // −0.5 + 0.75; 75 % (2.25): 2.5 canopy bins up, 13 m; 90 % (2.7): 17.5 m; 100 %: the
        // canopy's top, 20.5 m; 99.9 % (2.997): 20.47 m.
        let rh = |p: f64| m.rh[RH_PERCENTS.iter().position(|&x| x == p).unwrap()];
        assert!((rh(25.0) + 0.125).abs() < 1e-12, "{}", rh(25.0));
        assert!((rh(50.0) - 0.25).abs() < 1e-12, "{}", rh(50.0));
        assert!((rh(75.0) - 13.0).abs() < 1e-9, "{}", rh(75.0));
        assert!((rh(90.0) - 17.5).abs() < 1e-9, "{}", rh(90.0));
        assert!((rh(100.0) - 20.5).abs() < 1e-9, "{}", rh(100.0));
        assert!((m.top - 20.47).abs() < 1e-9, "{}", m.top);
        // Cover: 1/(1 + 2·0.57/0.4).
        assert!((m.cover - 1.0 / (1.0 + 2.0 * 0.57 / 0.4)).abs() < 1e-12);
    }

    #[test]
    fn no_ground_no_metrics() {
        let p = Profile {
            heights: &[0.0, 1.0],
            width: 1.0,
            total: &[1.0, 1.0],
            ground: &[0.0, 0.0],
            canopy_energy: 1.0,
            ground_energy: 0.0,
        };
        assert!(metrics(&p, 0.57, 0.4).is_none());
    }
}
