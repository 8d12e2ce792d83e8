//! Molecular (Rayleigh) atmospheres from thermophysical profiles.
//!
//! | config key        | unit | default                 | meaning                                  |
//! |-------------------|------|-------------------------|------------------------------------------|
//! | `profile`         | —    | `"afgl_1986-us_standard"` | one of the six AFGL (1986) profiles     |
//! | `layer_thickness` | km   | 1.0                     | thickness of the computational layers    |
//!
//! Air number density `n(z)` is interpolated **exponentially** (log-linear) between the profile's
//! levels, and each layer's column `∫n dz` is integrated exactly. The Rayleigh scattering
//! cross-section of air is
//! `σ(λ) = 24π³ (n_s² − 1)² / (λ⁴ N_s² (n_s² + 2)²) · F_K(λ)`
//! with the refractive index of standard air `n_s` of Peck & Reeder (1972) (15 °C, 1013.25 hPa,
//! 300 ppm CO₂), `N_s = 2.546899·10²⁵ m⁻³` (Bodhaine et al. 1999, eqs. 2, 18), and the air King
//! correction factor `F_K` of Bates (1984, eq. 15) tabulated from 200 nm to 1 µm (linear
//! interpolation; constant beyond 1 µm). The depolarization factor follows from the King factor:
//! `ρ = 6(F_K − 1)/(3 + 7F_K)`. No gas absorption here (issue 6's CKD work adds it).
//!
//! References: Anderson et al. (1986) AFGL-TR-86-0110; Bates (1984) Planet. Space Sci. 32:785;
//! Peck & Reeder (1972) J. Opt. Soc. Am. 62:958; Bodhaine et al. (1999) J. Atmos. Ocean. Tech.
//! 16:1854.

use super::ProfileError;

/// The six AFGL 1986 profiles: (config name, CSV text).
pub const PROFILES: [(&str, &str); 6] = [
    (
        "afgl_1986-tropical",
        include_str!("../../data/afgl_1986/table_1a.csv"),
    ),
    (
        "afgl_1986-midlatitude_summer",
        include_str!("../../data/afgl_1986/table_1b.csv"),
    ),
    (
        "afgl_1986-midlatitude_winter",
        include_str!("../../data/afgl_1986/table_1c.csv"),
    ),
    (
        "afgl_1986-subarctic_summer",
        include_str!("../../data/afgl_1986/table_1d.csv"),
    ),
    (
        "afgl_1986-subarctic_winter",
        include_str!("../../data/afgl_1986/table_1e.csv"),
    ),
    (
        "afgl_1986-us_standard",
        include_str!("../../data/afgl_1986/table_1f.csv"),
    ),
];

/// Air King correction factor of Bates (1984, eq. 15) at 200 nm … 1 µm (Eradiate's tabulation
/// `bates_1984.nc`): (wavelength µm, F_K).
const KING: [(f64, f64); 36] = [
    (0.2, 1.08),
    (0.205, 1.077),
    (0.21, 1.074),
    (0.215, 1.072),
    (0.22, 1.07),
    (0.225, 1.068),
    (0.23, 1.066),
    (0.24, 1.064),
    (0.25, 1.062),
    (0.26, 1.06),
    (0.27, 1.059),
    (0.28, 1.057),
    (0.29, 1.056),
    (0.3, 1.055),
    (0.31, 1.055),
    (0.32, 1.054),
    (0.33, 1.053),
    (0.34, 1.053),
    (0.35, 1.052),
    (0.36, 1.052),
    (0.37, 1.052),
    (0.38, 1.051),
    (0.39, 1.051),
    (0.4, 1.051),
    (0.45, 1.05),
    (0.5, 1.049),
    (0.55, 1.049),
    (0.6, 1.048),
    (0.65, 1.048),
    (0.7, 1.048),
    (0.75, 1.048),
    (0.8, 1.047),
    (0.85, 1.047),
    (0.9, 1.047),
    (0.95, 1.047),
    (1.0, 1.047),
];

/// Loschmidt-like number density of standard air (288.15 K, 1013.25 hPa), m⁻³.
pub const N_STANDARD_AIR: f64 = 2.546_899e25;

/// A thermophysical profile: altitudes (m, increasing) and air number densities (m⁻³).
#[derive(Clone, Debug)]
pub struct Profile {
    pub name: String,
    pub z: Vec<f64>,
    pub n: Vec<f64>,
}

impl Profile {
    /// One of the embedded profiles, by config name.
    pub fn builtin(name: &str) -> Result<Profile, ProfileError> {
        let (_, text) = PROFILES.iter().find(|(n, _)| *n == name).ok_or_else(|| {
            ProfileError::UnknownBuiltin {
                name: name.to_string(),
                known: PROFILES.iter().map(|p| p.0).collect(),
            }
        })?;
        Self::from_csv(name, text)
    }

    /// Parse AFGL-style CSV with columns `z` (km) and `n` (cm⁻³) among others.
    pub fn from_csv(name: &str, text: &str) -> Result<Profile, ProfileError> {
        let text = crate::util::without_bom(text);
        let mut lines = text.lines().filter(|l| !l.trim().is_empty());
        let header: Vec<&str> = lines
            .next()
            .ok_or_else(|| ProfileError::Empty { name: name.into() })?
            .split(',')
            .map(str::trim)
            .collect();
        let col = |c: &str| {
            header
                .iter()
                .position(|h| h.eq_ignore_ascii_case(c))
                .ok_or_else(|| ProfileError::NoColumn {
                    name: name.into(),
                    column: c.into(),
                })
        };
        let (iz, in_) = (col("z")?, col("n")?);
        let (mut z, mut n) = (Vec::new(), Vec::new());
        for (k, l) in lines.enumerate() {
            let f: Vec<&str> = l.split(',').collect();
            let parse = |i: usize| -> Result<f64, ProfileError> {
                f.get(i).and_then(|v| v.trim().parse().ok()).ok_or_else(|| {
                    ProfileError::BadNumber {
                        name: name.into(),
                        row: k + 2,
                        column: i + 1,
                    }
                })
            };
            z.push(parse(iz)? * 1e3);
            n.push(parse(in_)? * 1e6);
        }
        if z.len() < 2
            || z.windows(2).any(|w| w[1] <= w[0])
            || n.iter().any(|v| v.is_nan() || *v <= 0.0)
        {
            return Err(ProfileError::NotIncreasing { name: name.into() });
        }
        Ok(Profile {
            name: name.into(),
            z,
            n,
        })
    }

    /// Column number density `∫_a^b n dz` (m⁻²), exponential interpolation between levels.
    pub fn column(&self, a: f64, b: f64) -> f64 {
        let mut sum = 0.0;
        for i in 0..self.z.len() - 1 {
            let (z0, z1) = (self.z[i], self.z[i + 1]);
            let (lo, hi) = (a.max(z0), b.min(z1));
            if hi <= lo {
                continue;
            }
            let (n0, n1) = (self.n[i], self.n[i + 1]);
            let k = (n1 / n0).ln() / (z1 - z0); // n = n0 e^{k (z − z0)}
            let at = |z: f64| n0 * (k * (z - z0)).exp();
            sum += if k.abs() < 1e-15 {
                n0 * (hi - lo)
            } else {
                (at(hi) - at(lo)) / k
            };
        }
        sum
    }

    pub fn top(&self) -> f64 {
        *self.z.last().unwrap()
    }
}

/// Air King factor at `wavelength_nm` (linear interpolation; clamped outside 200–1000 nm).
pub fn king_factor(wavelength_nm: f64) -> f64 {
    let w = wavelength_nm * 1e-3;
    if w <= KING[0].0 {
        return KING[0].1;
    }
    for p in KING.windows(2) {
        let ((w0, f0), (w1, f1)) = (p[0], p[1]);
        if w <= w1 {
            return f0 + (f1 - f0) * (w - w0) / (w1 - w0);
        }
    }
    KING[KING.len() - 1].1
}

/// Depolarization factor of air consistent with the King factor.
pub fn depolarization(wavelength_nm: f64) -> f64 {
    let f = king_factor(wavelength_nm);
    6.0 * (f - 1.0) / (3.0 + 7.0 * f)
}

/// Refractive index of standard air (Peck & Reeder 1972; Bodhaine et al. 1999 eq. 18).
pub fn refractive_index_standard_air(wavelength_nm: f64) -> f64 {
    let s2 = (1e3 / wavelength_nm).powi(2); // σ² in µm⁻²
    1.0 + 1e-8 * (8060.51 + 2_480_990.0 / (132.274 - s2) + 17_455.7 / (39.329_57 - s2))
}

/// Rayleigh scattering cross-section of air, m² per molecule.
pub fn rayleigh_cross_section(wavelength_nm: f64) -> f64 {
    let n = refractive_index_standard_air(wavelength_nm);
    let lam = wavelength_nm * 1e-9;
    let r = (n * n - 1.0) / (n * n + 2.0);
    24.0 * std::f64::consts::PI.powi(3) * r * r / (lam.powi(4) * N_STANDARD_AIR * N_STANDARD_AIR)
        * king_factor(wavelength_nm)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cross-section at 550 nm against Bodhaine et al. (1999) (4.513e-27 cm², 300 ppm CO2,
    /// their King factor within 0.1 % of Bates'), to 0.5 %; and its spectral shape: λ⁻⁴ times
    /// the dispersion of (n_s − 1)² and of F_K, between 400 and 550 nm.
    #[test]
    fn cross_sections() {
        let s550 = rayleigh_cross_section(550.0);
        assert!((s550 / 4.513e-31 - 1.0).abs() < 5e-3, "{s550:e}");
        let shape =
            |w: f64| (refractive_index_standard_air(w) - 1.0).powi(2) * king_factor(w) / w.powi(4);
        let ratio = rayleigh_cross_section(400.0) / s550;
        assert!(
            (ratio / (shape(400.0) / shape(550.0)) - 1.0).abs() < 1e-3,
            "{ratio}"
        );
    }

    /// The Rayleigh optical thickness of the US standard atmosphere at 550 nm is about 0.097
    /// (Bodhaine et al. 1999: 0.0973 at sea level, 1013.25 hPa); the column of air is
    /// p0/(m g) ≈ 2.15e29 m⁻² (Bodhaine: 2.1520e25 cm⁻²).
    #[test]
    fn us_standard_optical_thickness() {
        let p = Profile::builtin("afgl_1986-us_standard").unwrap();
        let col = p.column(0.0, p.top());
        assert!((col / 2.152e29 - 1.0).abs() < 0.01, "column {col:e}");
        let tau = col * rayleigh_cross_section(550.0);
        println!("US standard Rayleigh tau(550 nm) = {tau:.5}");
        assert!((tau - 0.0973).abs() < 0.001, "tau = {tau}");
        // Splitting the column into layers changes nothing.
        let layered: f64 = (0..120)
            .map(|k| p.column(k as f64 * 1e3, (k + 1) as f64 * 1e3))
            .sum();
        assert!((layered / col - 1.0).abs() < 1e-12);
    }

    /// Depolarization and King factor are consistent: F_K = (6 + 3ρ)/(6 − 7ρ) (Bates 1984); at
    /// 550 nm Bates' F_K = 1.049 gives ρ = 0.0284.
    #[test]
    fn depolarization_value() {
        let r = depolarization(550.0);
        assert!(((6.0 + 3.0 * r) / (6.0 - 7.0 * r) - king_factor(550.0)).abs() < 1e-12);
        assert!((r - 0.0284).abs() < 1e-4, "{r}");
        assert!(Profile::builtin("nope")
            .unwrap_err()
            .to_string()
            .contains("afgl_1986-us_standard"));
    }
}
