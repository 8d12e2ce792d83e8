//! Solar irradiance spectra and the Earth–Sun distance.
//!
//! | `illumination.irradiance` | meaning                                                          |
//! |---------------------------|------------------------------------------------------------------|
//! | number or list            | E0 in W m⁻² nm⁻¹ per wavelength (normal to the beam)             |
//! | `"tsis_1"`                | TSIS-1 HSRS v1, 1 nm resolution (Coddington et al. 2021), embedded |
//! | `"thuillier_2003"`        | Thuillier et al. (2003), embedded                               |
//! | a file path               | CSV with columns `wavelength_nm`, irradiance in W m⁻² nm⁻¹        |
//!
//! Spectra are given at 1 AU and interpolated linearly in wavelength at each monochromatic
//! wavelength; a wavelength outside a spectrum is an error. With `illumination.date`
//! (`"YYYY-MM-DD"`), E0 is scaled by `(r0/r)²` from Spencer's (1971) Fourier series
//! (Iqbal 1983, eq. 1.2.1; accuracy ≈ 1e-4):
//! `(r0/r)² = 1.000110 + 0.034221 cos Γ + 0.001280 sin Γ + 0.000719 cos 2Γ + 0.000077 sin 2Γ`,
//! `Γ = 2π (day_of_year − 1)/365`.

use super::SpectrumError;

/// A tabulated spectrum (nm, W m⁻² nm⁻¹), increasing wavelengths.
#[derive(Clone, Debug)]
pub struct Spectrum {
    pub name: String,
    pub wavelength: Vec<f64>,
    pub value: Vec<f64>,
}

const TSIS_1: &str = include_str!("../../data/solar/tsis1_hsrs_v1_1nm.csv");
const THUILLIER_2003: &str = include_str!("../../data/solar/thuillier_2003.csv");

impl Spectrum {
    /// A built-in spectrum by name, or `None` if the name is not one. Each embedded table is
    /// parsed once per process (PICS batches resolve one experiment per acquisition).
    pub fn builtin(name: &str) -> Option<Spectrum> {
        static TSIS: std::sync::OnceLock<Spectrum> = std::sync::OnceLock::new();
        static THUILLIER: std::sync::OnceLock<Spectrum> = std::sync::OnceLock::new();
        let (cell, text) = match name {
            "tsis_1" => (&TSIS, TSIS_1),
            "thuillier_2003" => (&THUILLIER, THUILLIER_2003),
            _ => return None,
        };
        Some(
            cell.get_or_init(|| Self::from_csv(name, text).expect("embedded spectra are valid"))
                .clone(),
        )
    }

    /// Parse a two-column CSV (`#` comment lines, a header line, then `wavelength_nm,value`).
    pub fn from_csv(name: &str, text: &str) -> Result<Spectrum, SpectrumError> {
        let text = crate::util::without_bom(text);
        let (mut w, mut v) = (Vec::new(), Vec::new());
        let mut header_allowed = true;
        for (i, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            // The first line that is not a comment may be a header.
            if std::mem::take(&mut header_allowed)
                && line.chars().next().is_some_and(|c| c.is_alphabetic())
            {
                continue;
            }
            let mut f = line.split(',').map(str::trim);
            let (a, b) = (f.next(), f.next());
            let parse = |x: Option<&str>| x.and_then(|s| s.parse::<f64>().ok());
            match (parse(a), parse(b)) {
                (Some(x), Some(y)) if x.is_finite() && y.is_finite() && y >= 0.0 => {
                    w.push(x);
                    v.push(y);
                }
                _ => {
                    return Err(SpectrumError::Row {
                        name: name.into(),
                        line: i + 1,
                    })
                }
            }
        }
        if w.len() < 2 || w.windows(2).any(|p| p[1] <= p[0]) {
            return Err(SpectrumError::TooFewRows { name: name.into() });
        }
        Ok(Spectrum {
            name: name.into(),
            wavelength: w,
            value: v,
        })
    }

    /// Linear interpolation at `nm`; `None` outside the tabulated range.
    pub fn at(&self, nm: f64) -> Option<f64> {
        let w = &self.wavelength;
        if !(nm >= w[0] && nm <= w[w.len() - 1]) {
            return None;
        }
        let i = w.partition_point(|&x| x <= nm).clamp(1, w.len() - 1);
        let (x0, x1) = (w[i - 1], w[i]);
        let (y0, y1) = (self.value[i - 1], self.value[i]);
        Some(y0 + (y1 - y0) * (nm - x0) / (x1 - x0))
    }
}

/// Day of year (1–366) of a `YYYY-MM-DD` date.
pub fn day_of_year(date: &str) -> Result<u32, SpectrumError> {
    let bad = || SpectrumError::BadDate {
        value: date.to_string(),
    };
    let p: Vec<&str> = date.split('-').collect();
    if p.len() != 3 || p[0].len() != 4 || p[1].len() != 2 || p[2].len() != 2 {
        return Err(bad());
    }
    let (y, m, d): (i64, u32, u32) = (
        p[0].parse().map_err(|_| bad())?,
        p[1].parse().map_err(|_| bad())?,
        p[2].parse().map_err(|_| bad())?,
    );
    let leap = (y % 4 == 0 && y % 100 != 0) || y % 400 == 0;
    let days = [
        31,
        if leap { 29 } else { 28 },
        31,
        30,
        31,
        30,
        31,
        31,
        30,
        31,
        30,
        31,
    ];
    if !(1..=12).contains(&m) || d < 1 || d > days[(m - 1) as usize] {
        return Err(bad());
    }
    Ok(days[..(m - 1) as usize].iter().sum::<u32>() + d)
}

/// `(r0/r)²`: the factor on the 1 AU irradiance for a day of the year (Spencer 1971).
pub fn earth_sun_factor(day_of_year: u32) -> f64 {
    let g = std::f64::consts::TAU * (day_of_year as f64 - 1.0) / 365.0;
    1.000110
        + 0.034221 * g.cos()
        + 0.001280 * g.sin()
        + 0.000719 * (2.0 * g).cos()
        + 0.000077 * (2.0 * g).sin()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The spectra integrate to the total solar irradiance (TSIS-1 HSRS: 1360.8 W m⁻² over the
    /// whole spectrum; 202–2730 nm holds ≈ 97 %), and values at 550 nm are near 1.86 W m⁻² nm⁻¹.
    #[test]
    fn spectra() {
        for name in ["tsis_1", "thuillier_2003"] {
            let s = Spectrum::builtin(name).unwrap();
            let e = s.at(550.0).unwrap();
            assert!((1.75..1.95).contains(&e), "{name}: {e}");
            let total: f64 = s
                .wavelength
                .windows(2)
                .zip(s.value.windows(2))
                .map(|(w, v)| 0.5 * (v[0] + v[1]) * (w[1] - w[0]))
                .sum();
            println!("{name}: E(550) = {e:.4}, integral = {total:.1} W/m2");
            assert!((1250.0..1361.0).contains(&total), "{name}: {total}");
        }
        assert!(Spectrum::builtin("tsis_1").unwrap().at(100.0).is_none());
        assert!(Spectrum::builtin("sun").is_none());
    }

    /// Earth–Sun distance: perihelion (early January) gives ≈ +3.4 %, aphelion (early July)
    /// ≈ −3.3 %; the yearly mean of (r0/r)² is 1.00011 by construction.
    #[test]
    fn distance() {
        assert!((earth_sun_factor(day_of_year("2024-01-03").unwrap()) - 1.0342).abs() < 1e-3);
        assert!((earth_sun_factor(day_of_year("2024-07-04").unwrap()) - 0.9673).abs() < 1e-3);
        let mean: f64 = (1..=365).map(earth_sun_factor).sum::<f64>() / 365.0;
        assert!((mean - 1.00011).abs() < 1e-5);
        assert_eq!(day_of_year("2024-12-31").unwrap(), 366);
        assert!(day_of_year("2023-02-29").is_err() && day_of_year("21-06-2024").is_err());
    }
}
