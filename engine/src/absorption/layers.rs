//! Gas absorption optical thickness of computational layers, from an absorption database and a
//! thermophysical profile.
//!
//! The absorption coefficient k(z) [m⁻¹] is evaluated at the thermodynamic state of a set of
//! altitudes — the profile's levels inside the atmosphere plus every layer boundary — and taken
//! linear in z between them (the representation of [`integrate_piecewise_linear`]); a layer's
//! optical thickness is the exact integral of that piecewise-linear k over the layer. Between
//! profile levels the state is interpolated as the atmosphere is: pressure exponentially (log-
//! linear in z), temperature and mole fractions linearly.
//!
//! A database's own interpolation in (p, T, x, g) and its out-of-range policy
//! ([`BoundsPolicy`]) apply at each altitude; an error names the altitude.

use super::axsdb::{AxsDatabase, BoundsPolicy, SpectralPoint, ThermoState};
use super::profile::{integrate_piecewise_linear, AtmosphereProfile};
use super::{AbsorptionError, Result};

/// An absorption coefficient that could not be evaluated at one of the altitudes of a layer
/// grid: the altitude, its interpolated state, and the database's error.
#[derive(Debug, thiserror::Error)]
#[error(
    "at {:.3} km (p = {:.4e} Pa, T = {:.2} K): {source}",
    .altitude_m / 1e3,
    .pressure_pa,
    .temperature_k
)]
pub struct LayerError {
    pub altitude_m: f64,
    pub pressure_pa: f64,
    pub temperature_k: f64,
    pub source: AbsorptionError,
}

/// The altitudes and states at which k is evaluated for a layer grid.
#[derive(Clone, Debug)]
pub struct GasColumns {
    z: Vec<f64>,
    p: Vec<f64>,
    t: Vec<f64>,
    species: Vec<String>,
    /// x[level][species]
    x: Vec<Vec<f64>>,
    grid: Vec<(f64, f64)>,
}

impl GasColumns {
    /// `grid`: the computational layers (bottom, top) \[m\], ascending and contiguous, within
    /// the profile's altitude range.
    pub fn new(prof: &AtmosphereProfile, grid: &[(f64, f64)]) -> GasColumns {
        let (lo, hi) = (grid[0].0, grid[grid.len() - 1].1);
        let mut z: Vec<f64> = prof
            .altitude_m
            .iter()
            .copied()
            .filter(|&z| z > lo && z < hi)
            .chain(grid.iter().map(|g| g.0))
            .chain(std::iter::once(hi))
            .collect();
        z.sort_by(f64::total_cmp);
        z.dedup_by(|a, b| (*a - *b).abs() < 1e-6);
        let species: Vec<String> = prof.mole_fractions.iter().map(|(s, _)| s.clone()).collect();
        let (mut p, mut t, mut x) = (Vec::new(), Vec::new(), Vec::new());
        let zs = &prof.altitude_m;
        for &zz in &z {
            // Level interval holding zz (clamped to the profile).
            let i = match zs.partition_point(|&a| a <= zz) {
                0 => 0,
                k => (k - 1).min(zs.len() - 2),
            };
            let f = ((zz - zs[i]) / (zs[i + 1] - zs[i])).clamp(0.0, 1.0);
            let lin = |a: f64, b: f64| a + (b - a) * f;
            let (pa, pb) = (prof.pressure_pa[i], prof.pressure_pa[i + 1]);
            p.push(if pa > 0.0 && pb > 0.0 {
                (pa.ln() + (pb.ln() - pa.ln()) * f).exp()
            } else {
                lin(pa, pb)
            });
            t.push(lin(prof.temperature_k[i], prof.temperature_k[i + 1]));
            x.push(
                prof.mole_fractions
                    .iter()
                    .map(|(_, v)| lin(v[i], v[i + 1]))
                    .collect(),
            );
        }
        GasColumns {
            z,
            p,
            t,
            species,
            x,
            grid: grid.to_vec(),
        }
    }

    /// Number of altitudes where k is evaluated.
    pub fn node_count(&self) -> usize {
        self.z.len()
    }

    /// Layer optical thicknesses from a coefficient function of the state (errors get the
    /// altitude prepended).
    pub fn layer_tau_with(
        &self,
        mut k: impl FnMut(&ThermoState<'_>) -> Result<f64>,
    ) -> std::result::Result<Vec<f64>, LayerError> {
        let mut ks = Vec::with_capacity(self.z.len());
        for j in 0..self.z.len() {
            let mf: Vec<(&str, f64)> = self
                .species
                .iter()
                .zip(&self.x[j])
                .map(|(s, &v)| (s.as_str(), v))
                .collect();
            let state = ThermoState {
                pressure_pa: self.p[j],
                temperature_k: self.t[j],
                mole_fractions: &mf,
            };
            let v = k(&state).map_err(|source| LayerError {
                altitude_m: self.z[j],
                pressure_pa: self.p[j],
                temperature_k: self.t[j],
                source,
            })?;
            ks.push(v.max(0.0));
        }
        Ok(self
            .grid
            .iter()
            .map(|&(b, t)| integrate_piecewise_linear(&self.z, &ks, b, t))
            .collect())
    }

    /// Layer optical thicknesses of a database at a spectral point.
    pub fn layer_tau(
        &self,
        db: &AxsDatabase,
        at: SpectralPoint,
        bounds: BoundsPolicy,
    ) -> std::result::Result<Vec<f64>, LayerError> {
        self.layer_tau_with(|s| db.absorption_coefficient(s, at, bounds))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two_level() -> AtmosphereProfile {
        AtmosphereProfile {
            path: "test".into(),
            altitude_m: vec![0.0, 10_000.0],
            pressure_pa: vec![100_000.0, 10_000.0],
            temperature_k: vec![300.0, 200.0],
            number_density_m3: None,
            mole_fractions: vec![("O3".into(), vec![1e-6, 3e-6])],
        }
    }

    /// With k proportional to the mole fraction (linear in z) the layer integrals are exact,
    /// and the interpolated states are log-linear in p, linear in T.
    #[test]
    fn integrals_and_states() {
        let prof = two_level();
        let grid = [(0.0, 2500.0), (2500.0, 7000.0), (7000.0, 10_000.0)];
        let cols = GasColumns::new(&prof, &grid);
        assert_eq!(cols.node_count(), 4);
        let tau = cols
            .layer_tau_with(|s| Ok(s.mole_fractions[0].1 * 1e3))
            .unwrap();
        // x(z) = 1e-6 + 2e-6 z/1e4 → ∫ 1e3·x dz.
        let exact = |a: f64, b: f64| 1e3 * (1e-6 * (b - a) + 1e-10 * (b * b - a * a));
        for (i, &(a, b)) in grid.iter().enumerate() {
            assert!((tau[i] / exact(a, b) - 1.0).abs() < 1e-12, "{i}");
        }
        let mut seen = Vec::new();
        cols.layer_tau_with(|s| {
            seen.push((s.pressure_pa, s.temperature_k));
            Ok(0.0)
        })
        .unwrap();
        let (p, t) = seen[1]; // z = 2500 m
        assert!((p - 100_000.0 * 0.1f64.powf(0.25)).abs() < 1e-6);
        assert!((t - 275.0).abs() < 1e-12);
    }

    #[test]
    fn errors_name_the_altitude() {
        let prof = two_level();
        let cols = GasColumns::new(&prof, &[(0.0, 10_000.0)]);
        let e = cols
            .layer_tau_with(|s| {
                if s.pressure_pa < 50_000.0 {
                    Err(super::super::AbsorptionError::Format {
                        path: "db".into(),
                        variable: "p".into(),
                        message: "low".into(),
                    })
                } else {
                    Ok(1.0)
                }
            })
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("at 10.000 km"), "{e}");
    }
}
