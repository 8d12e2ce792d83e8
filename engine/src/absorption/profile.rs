//! Thermophysical profiles in the joseki / axsdb netCDF format.
//!
//! ## Format
//! One dimension `z` and the variables (each with a `units` attribute, converted to SI here):
//!
//! | variable  | unit in file | here        | meaning                                   |
//! |-----------|--------------|-------------|-------------------------------------------|
//! | `z`       | km           | m           | altitude of the level                     |
//! | `p`       | Pa           | Pa          | air pressure                              |
//! | `t`       | K            | K           | air temperature                           |
//! | `n`       | m ** -3      | m⁻³         | air number density (optional)             |
//! | `x_<SP>`  | dimensionless| —           | mole (volume) fraction of species `<SP>`  |
//!
//! `shared/data/ckd/axsdb/afgl_1986-us_standard.nc` is the AFGL 1986 US-standard atmosphere
//! (Anderson et al. 1986, AFGL-TR-86-0110) interpolated by joseki 2.6.1 on a 1 km grid,
//! 0–120 km (121 levels), species H2O, O3, N2O, CO, CH4, CO2, O2. Its `n` equals p / k_B T
//! within 0.4 % up to 50 km and within 4.5 % above (joseki interpolates n and p separately).
//!
//! The values are **levels** (not layer means). [`integrate_piecewise_linear`] integrates a
//! quantity that is linear in z between levels (the trapezoid rule, exact for that
//! representation); it is how column optical thicknesses are computed from absorption
//! coefficients evaluated at the levels.

use std::path::Path;

use super::axsdb::ThermoState;
use super::{
    is_dimensionless, is_kelvin, metre_factor, open_nc, pascal_factor, per_cubic_metre_factor,
    read_f64, read_scaled, units_of, AbsorptionError, Result,
};

/// Altitudes that are not strictly monotonic ([`AtmosphereProfile::make_ascending`]): `level`
/// (0-based, after putting the levels in ascending order) does not lie above the one below.
#[derive(Debug, thiserror::Error)]
#[error("altitudes are not strictly monotonic")]
pub struct AltitudeOrderError {
    pub level: usize,
    pub altitude_m: f64,
}

/// A profile on levels, ascending in altitude.
#[derive(Clone, Debug)]
pub struct AtmosphereProfile {
    pub path: String,
    pub altitude_m: Vec<f64>,
    pub pressure_pa: Vec<f64>,
    pub temperature_k: Vec<f64>,
    /// Air number density [m⁻³], when the file has `n`.
    pub number_density_m3: Option<Vec<f64>>,
    /// (species without the `x_` prefix, mole fraction per level).
    pub mole_fractions: Vec<(String, Vec<f64>)>,
}

/// One level, ready to build a [`ThermoState`].
#[derive(Clone, Debug)]
pub struct ProfileLevel<'a> {
    pub altitude_m: f64,
    pub pressure_pa: f64,
    pub temperature_k: f64,
    pub number_density_m3: Option<f64>,
    pub mole_fractions: Vec<(&'a str, f64)>,
}

impl ProfileLevel<'_> {
    /// The thermodynamic state of the level.
    pub fn state(&self) -> ThermoState<'_> {
        ThermoState {
            pressure_pa: self.pressure_pa,
            temperature_k: self.temperature_k,
            mole_fractions: &self.mole_fractions,
        }
    }
}

impl AtmosphereProfile {
    pub fn open(path: &Path) -> Result<AtmosphereProfile> {
        let _session = crate::netcdf_session();
        let ps = path.display().to_string();
        let file = open_nc(path)?;
        let z = read_scaled(&file, &ps, "z", "a length (km)", metre_factor)?;
        let p = read_scaled(&file, &ps, "p", "a pressure (Pa)", pascal_factor)?;
        let tv = super::variable(&file, &ps, "t")?;
        let tu = units_of(&tv).unwrap_or_default();
        if !is_kelvin(&tu) {
            return Err(AbsorptionError::Units {
                path: ps,
                variable: "t".into(),
                units: tu,
                expected: "K",
            });
        }
        let t = read_f64(&tv, &ps)?;
        let n = match file.variable("n") {
            Some(_) => Some(read_scaled(
                &file,
                &ps,
                "n",
                "a number density (m^-3)",
                per_cubic_metre_factor,
            )?),
            None => None,
        };
        let mut x = Vec::new();
        for v in file.variables() {
            let name = v.name();
            if let Some(sp) = name.strip_prefix("x_") {
                let u = units_of(&v).unwrap_or_default();
                if !is_dimensionless(&u) {
                    return Err(AbsorptionError::Units {
                        path: ps,
                        variable: name,
                        units: u,
                        expected: "a dimensionless mole fraction",
                    });
                }
                x.push((sp.to_string(), read_f64(&v, &ps)?));
            }
        }
        let len = z.len();
        // Values must be finite; all but altitudes non-negative.
        let check = |name: &str, v: &[f64]| -> Result<()> {
            if v.len() != len {
                return Err(AbsorptionError::Format {
                    path: ps.clone(),
                    variable: name.to_string(),
                    message: format!("{} values for {len} altitudes", v.len()),
                });
            }
            if let Some((index, &value)) = v
                .iter()
                .enumerate()
                .find(|(_, v)| !v.is_finite() || (name != "z" && **v < 0.0))
            {
                return Err(AbsorptionError::BadValue {
                    path: ps.clone(),
                    variable: name.to_string(),
                    value,
                    index,
                });
            }
            Ok(())
        };
        check("z", &z)?;
        check("p", &p)?;
        check("t", &t)?;
        if let Some(n) = &n {
            check("n", n)?;
        }
        for (sp, v) in &x {
            check(&format!("x_{sp}"), v)?;
        }
        if len < 2 {
            return Err(AbsorptionError::Format {
                path: ps,
                variable: "z".into(),
                message: "needs at least 2 levels".into(),
            });
        }
        let mut prof = AtmosphereProfile {
            path: ps,
            altitude_m: z,
            pressure_pa: p,
            temperature_k: t,
            number_density_m3: n,
            mole_fractions: x,
        };
        prof.make_ascending().map_err(|e| AbsorptionError::Format {
            path: prof.path.clone(),
            variable: "z".into(),
            message: e.to_string(),
        })?;
        Ok(prof)
    }

    /// Put the levels in ascending altitude (reversing every per-level array of a descending
    /// profile); an error if the altitudes are then not strictly increasing.
    pub fn make_ascending(&mut self) -> std::result::Result<(), AltitudeOrderError> {
        if self.altitude_m.len() >= 2 && self.altitude_m[0] > self.altitude_m[1] {
            self.altitude_m.reverse();
            self.pressure_pa.reverse();
            self.temperature_k.reverse();
            if let Some(n) = &mut self.number_density_m3 {
                n.reverse();
            }
            for (_, v) in &mut self.mole_fractions {
                v.reverse();
            }
        }
        if let Some(i) = self.altitude_m.windows(2).position(|w| w[1] <= w[0]) {
            return Err(AltitudeOrderError {
                level: i + 1,
                altitude_m: self.altitude_m[i + 1],
            });
        }
        Ok(())
    }

    /// Number of levels.
    pub fn len(&self) -> usize {
        self.altitude_m.len()
    }

    pub fn is_empty(&self) -> bool {
        self.altitude_m.is_empty()
    }

    /// Mole fractions of `species` (`"O3"` or `"x_O3"`) at the levels.
    pub fn mole_fraction(&self, species: &str) -> Option<&[f64]> {
        let sp = species.strip_prefix("x_").unwrap_or(species);
        self.mole_fractions
            .iter()
            .find(|(n, _)| n == sp)
            .map(|(_, v)| v.as_slice())
    }

    /// Level `i` (panics if out of range).
    pub fn level(&self, i: usize) -> ProfileLevel<'_> {
        ProfileLevel {
            altitude_m: self.altitude_m[i],
            pressure_pa: self.pressure_pa[i],
            temperature_k: self.temperature_k[i],
            number_density_m3: self.number_density_m3.as_ref().map(|n| n[i]),
            mole_fractions: self
                .mole_fractions
                .iter()
                .map(|(n, v)| (n.as_str(), v[i]))
                .collect(),
        }
    }

    /// Air number density at the levels [m⁻³]: the file's `n`, else p / k_B T.
    pub fn air_number_density(&self) -> Vec<f64> {
        const K_B: f64 = 1.380_649e-23;
        match &self.number_density_m3 {
            Some(n) => n.clone(),
            None => self
                .pressure_pa
                .iter()
                .zip(&self.temperature_k)
                .map(|(p, t)| p / (K_B * t))
                .collect(),
        }
    }

    /// Vertical column of `species` [molecules m⁻²] over the whole profile, x·n linear in z
    /// between levels. (1 Dobson unit = 2.6868e20 m⁻².)
    pub fn column_density_m2(&self, species: &str) -> Option<f64> {
        let x = self.mole_fraction(species)?;
        let nx: Vec<f64> = self
            .air_number_density()
            .iter()
            .zip(x)
            .map(|(n, x)| n * x)
            .collect();
        let z = &self.altitude_m;
        Some(integrate_piecewise_linear(z, &nx, z[0], z[z.len() - 1]))
    }
}

/// ∫ f dz over [z0, z1] for f linear between the nodes (z ascending); the parts of [z0, z1]
/// outside [z\[0\], z\[last\]] contribute nothing. Negative if z1 < z0.
pub fn integrate_piecewise_linear(z: &[f64], f: &[f64], z0: f64, z1: f64) -> f64 {
    if z1 < z0 {
        return -integrate_piecewise_linear(z, f, z1, z0);
    }
    let mut sum = 0.0;
    for i in 0..z.len().saturating_sub(1) {
        let (za, zb) = (z[i], z[i + 1]);
        let (a, b) = (za.max(z0), zb.min(z1));
        if b <= a {
            continue;
        }
        let at = |x: f64| f[i] + (f[i + 1] - f[i]) * (x - za) / (zb - za);
        sum += 0.5 * (at(a) + at(b)) * (b - a);
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::super::test_data::shared;
    use super::*;

    #[test]
    fn piecewise_linear_integral() {
        let z = [0.0, 1.0, 3.0];
        let f = [0.0, 2.0, 2.0];
        assert_eq!(integrate_piecewise_linear(&z, &f, 0.0, 3.0), 1.0 + 4.0);
        assert_eq!(integrate_piecewise_linear(&z, &f, 0.5, 2.0), 0.75 + 2.0);
        assert_eq!(integrate_piecewise_linear(&z, &f, -1.0, 0.0), 0.0);
        assert_eq!(integrate_piecewise_linear(&z, &f, 2.0, 0.5), -2.75);
    }

    #[test]
    fn us_standard_profile() {
        let Some(p) = shared("ckd/axsdb/afgl_1986-us_standard.nc") else {
            return;
        };
        let prof = AtmosphereProfile::open(&p).unwrap();
        assert_eq!(prof.len(), 121);
        assert_eq!(prof.altitude_m[0], 0.0);
        assert_eq!(prof.altitude_m[120], 120e3);
        assert_eq!(prof.pressure_pa[0], 101_300.0);
        assert_eq!(prof.temperature_k[0], 288.2);
        let mut species: Vec<&str> = prof.mole_fractions.iter().map(|s| s.0.as_str()).collect();
        species.sort();
        assert_eq!(species, ["CH4", "CO", "CO2", "H2O", "N2O", "O2", "O3"]);
        // n = p / k_B T (ideal gas) within 0.5 % up to 50 km, 5 % above (joseki interpolates n
        // and p separately between the AFGL nodes).
        let n = prof.number_density_m3.as_ref().unwrap();
        for (i, &n) in n.iter().enumerate() {
            let ideal = prof.pressure_pa[i] / (1.380_649e-23 * prof.temperature_k[i]);
            let tol = if prof.altitude_m[i] <= 50e3 {
                5e-3
            } else {
                5e-2
            };
            assert!(
                (n / ideal - 1.0).abs() < tol,
                "level {i}: n / (p/kT) = {}",
                n / ideal
            );
        }
        let du = prof.column_density_m2("O3").unwrap() / 2.6868e20;
        println!("US-standard O3 column: {du:.1} DU");
        assert!((300.0..400.0).contains(&du));
        let l = prof.level(10);
        assert_eq!(l.state().pressure_pa, 26_500.0);
        assert_eq!(
            l.mole_fractions.iter().find(|m| m.0 == "O3").unwrap().1,
            1.31e-7
        );
    }
}
