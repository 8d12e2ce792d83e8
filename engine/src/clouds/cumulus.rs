//! A generated field of fair-weather cumulus: the cloud field of the README's cloudy example and
//! of tests that need a realistic 3D cloud without an LES run.
//!
//! **Model.** `count` clouds placed uniformly at random (seeded) over the rectangle; cloud k has
//! a radius `r_k` drawn uniformly in `radius_m` and a depth `h_k = aspect·r_k`, and fills the
//! half-ellipsoid `ρ² + ζ² ≤ 1` above the common base, with `ρ` the horizontal distance to its
//! centre over `r_k` and `ζ = (z − base)/h_k`. Its liquid water content grows with height above
//! the base as a sub-adiabatic parcel's, `LWC = f_ad·Γ_ad·(z − base)` (Γ_ad = 2 g m⁻³ km⁻¹, the
//! adiabatic rate near 10 °C), and the extinction of droplets of effective radius `r_eff` is
//! `σ = 3·LWC/(2·ρ_w·r_eff)` (Stephens 1978, JAS 35:2123: the geometric-optics limit, Q_ext = 2).
//! Overlapping clouds take the larger LWC. Cells take the value at their centre.
//!
//! Units: metres; extinction in 1/m.

use crate::rng::Stream;

/// Parameters of the field (module doc).
#[derive(Clone, Debug)]
pub struct Cumulus {
    /// Columns and their size (m).
    pub nx: usize,
    pub ny: usize,
    pub dx: f64,
    /// Cloud base altitude and the levels' spacing (m); the field spans base … base + max depth.
    pub base_m: f64,
    pub dz: f64,
    pub count: usize,
    pub radius_m: [f64; 2],
    /// Depth over radius.
    pub aspect: f64,
    /// Fraction of the adiabatic liquid water content.
    pub adiabatic_fraction: f64,
    /// Droplet effective radius (m).
    pub r_eff_m: f64,
    pub seed: u64,
}

/// Adiabatic liquid-water lapse rate, kg m⁻³ per m (2 g m⁻³ km⁻¹).
const GAMMA_AD: f64 = 2e-6;
/// Density of liquid water, kg m⁻³.
const RHO_W: f64 = 1000.0;

impl Cumulus {
    /// The clouds: centre x, y, radius and depth (m), drawn from the seed.
    pub fn clouds(&self) -> Vec<(f64, f64, f64, f64)> {
        let mut rng = Stream::new(self.seed, [0xC0_u64, 0, 0, 0]);
        let (lx, ly) = (self.nx as f64 * self.dx, self.ny as f64 * self.dx);
        (0..self.count)
            .map(|_| {
                let x = rng.next_f64() * lx;
                let y = rng.next_f64() * ly;
                let r = self.radius_m[0] + (self.radius_m[1] - self.radius_m[0]) * rng.next_f64();
                (x, y, r, self.aspect * r)
            })
            .collect()
    }

    /// The levels (m) and the extinction (1/m) per cell, `(iz·ny + iy)·nx + ix`.
    pub fn generate(&self) -> (Vec<f64>, Vec<f32>) {
        let clouds = self.clouds();
        let top = clouds.iter().map(|c| c.3).fold(0.0, f64::max);
        let nz = ((top / self.dz).ceil() as usize).max(1);
        let levels: Vec<f64> = (0..=nz).map(|k| self.base_m + k as f64 * self.dz).collect();
        let mut ext = vec![0.0_f32; self.nx * self.ny * nz];
        let k_ext = 1.5 / (RHO_W * self.r_eff_m);
        for &(cx, cy, r, h) in &clouds {
            // The columns the cloud covers.
            let i0 = ((cx - r) / self.dx).floor() as i64;
            let i1 = ((cx + r) / self.dx).ceil() as i64;
            let j0 = ((cy - r) / self.dx).floor() as i64;
            let j1 = ((cy + r) / self.dx).ceil() as i64;
            for j in j0.max(0)..j1.min(self.ny as i64) {
                for i in i0.max(0)..i1.min(self.nx as i64) {
                    let x = (i as f64 + 0.5) * self.dx;
                    let y = (j as f64 + 0.5) * self.dx;
                    let rho2 = ((x - cx).powi(2) + (y - cy).powi(2)) / (r * r);
                    if rho2 >= 1.0 {
                        continue;
                    }
                    let zeta_max = (1.0 - rho2).sqrt();
                    for k in 0..nz {
                        let dz = (k as f64 + 0.5) * self.dz;
                        if dz / h > zeta_max {
                            break;
                        }
                        let lwc = self.adiabatic_fraction * GAMMA_AD * dz;
                        let s = (k_ext * lwc) as f32;
                        let c = (k * self.ny + j as usize) * self.nx + i as usize;
                        ext[c] = ext[c].max(s);
                    }
                }
            }
        }
        (levels, ext)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_cloud_has_the_dome_and_the_adiabatic_profile() {
        let c = Cumulus {
            nx: 40,
            ny: 40,
            dx: 50.0,
            base_m: 1000.0,
            dz: 50.0,
            count: 1,
            radius_m: [500.0, 500.0],
            aspect: 1.0,
            adiabatic_fraction: 0.5,
            r_eff_m: 10e-6,
            seed: 1,
        };
        let (levels, ext) = c.generate();
        assert_eq!(levels.len(), 11);
        // Covered columns: exactly those whose centre lies within the dome at the lowest
        // level's centre (25 m above the base: ρ² < 1 − (25/h)²), from the drawn centre.
        let (cx, cy, r, h) = c.clouds()[0];
        for j in 0..40 {
            for i in 0..40 {
                let (x, y) = ((i as f64 + 0.5) * 50.0, (j as f64 + 0.5) * 50.0);
                let rho2 = ((x - cx).powi(2) + (y - cy).powi(2)) / (r * r);
                let inside = 1.0 - rho2 >= (25.0 / h).powi(2);
                assert_eq!(ext[j * 40 + i] > 0.0, inside, "column ({i}, {j})");
            }
        }
        // σ at the centre column, level k: 1.5·0.5·2e-6·(k + ½)·50 / (1000·1e-5).
        let max = ext.iter().cloned().fold(0.0_f32, f32::max) as f64;
        let top_cell = 0.5 * 2e-6 * 475.0 * 1.5 / 1e-2;
        assert!(
            (max - top_cell).abs() < 1e-6 * top_cell,
            "{max} vs {top_cell}"
        );
    }
}
