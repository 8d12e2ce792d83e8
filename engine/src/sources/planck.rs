//! Planck's law per unit wavelength, and its inverse (brightness temperature).
//!
//! | quantity | unit |
//! |---|---|
//! | wavelength λ | nm |
//! | temperature T | K |
//! | spectral radiance B_λ(T) | W m⁻² sr⁻¹ nm⁻¹ |
//!
//! `B_λ(T) = 2hc²/λ⁵ · 1/(exp(hc/(λ k T)) − 1)`, evaluated in SI (λ in m, W m⁻² sr⁻¹ m⁻¹) and
//! returned per nm (× 10⁻⁹). The inverse, `T = (hc/(λk)) / ln(1 + 2hc²/(λ⁵ B))`, is exact.
//! Constants: CODATA 2018 (exact SI values since the 2019 redefinition): h = 6.626 070 15e−34
//! J s, c = 299 792 458 m s⁻¹, k = 1.380 649e−23 J K⁻¹. Reference: e.g. Liou (2002), *An
//! Introduction to Atmospheric Radiation*, eq. 1.2.6.

/// Planck constant, J s (CODATA 2018, exact).
pub const H: f64 = 6.626_070_15e-34;
/// Speed of light in vacuum, m s⁻¹ (exact).
pub const C: f64 = 299_792_458.0;
/// Boltzmann constant, J K⁻¹ (CODATA 2018, exact).
pub const K_B: f64 = 1.380_649e-23;

/// First radiation constant for radiance, 2hc², W m² sr⁻¹.
const C1L: f64 = 2.0 * H * C * C;
/// Second radiation constant, hc/k, m K.
const C2: f64 = H * C / K_B;

/// Spectral radiance B_λ(T) in W m⁻² sr⁻¹ nm⁻¹ at `wavelength_nm` (nm) and `t` (K); 0 for
/// T ≤ 0.
pub fn radiance(wavelength_nm: f64, t: f64) -> f64 {
    if t <= 0.0 {
        return 0.0;
    }
    let l = wavelength_nm * 1e-9;
    C1L / l.powi(5) / (C2 / (l * t)).exp_m1() * 1e-9
}

/// The exponent `hc/(λkT)` above which B_λ(T) is below e^{−650} ≈ 10⁻²⁸² of its scale 2hc²/λ⁵:
/// near enough to the smallest normal f64 (10⁻³⁰⁸) that colder sources radiate nothing the run
/// can represent at every wavelength up to 1 mm (their radiance underflows to 0 and no
/// brightness temperature can be recovered from it).
const MAX_EXPONENT: f64 = 650.0;

/// The lowest temperature (K) whose Planck radiance at `wavelength_nm` is representable
/// (`hc/(λkT)` ≤ 650): about 2.2 K at 10 µm, 55 K at 400 nm. Thermal runs refuse colder
/// sources, naming the key (issue 43).
pub fn lowest_temperature(wavelength_nm: f64) -> f64 {
    C2 / (wavelength_nm * 1e-9 * MAX_EXPONENT)
}

/// Brightness temperature (K): the T with `radiance(wavelength_nm, T) = l`; NaN for `l ≤ 0` or
/// a non-finite `l`.
pub fn brightness_temperature(wavelength_nm: f64, l: f64) -> f64 {
    if !(l > 0.0 && l.is_finite()) {
        return f64::NAN;
    }
    let lm = wavelength_nm * 1e-9;
    let b_si = l * 1e9;
    // (C1L/λ⁵)/B rather than C1L/(λ⁵·B): λ⁵·B falls into subnormals for cold sources.
    C2 / (lm * (C1L / lm.powi(5) / b_si).ln_1p())
}

/// dB_λ/dT (W m⁻² sr⁻¹ nm⁻¹ K⁻¹) at `t`: the delta method's factor for the standard error of a
/// brightness temperature, σ_T = σ_L / (dB/dT).
pub fn derivative(wavelength_nm: f64, t: f64) -> f64 {
    if t <= 0.0 {
        return 0.0;
    }
    let l = wavelength_nm * 1e-9;
    let x = C2 / (l * t);
    // B = C1L/l⁵/(eˣ−1); dB/dT = B · x eˣ/(eˣ−1) / T.
    let b = radiance(wavelength_nm, t);
    b * x / t / (-(-x).exp_m1())
}

/// Brightness temperature of radiance `l` with standard error `se`, and its standard error by
/// the delta method (NaN where the radiance is not positive).
pub fn brightness_temperature_stderr(wavelength_nm: f64, l: f64, se: f64) -> (f64, f64) {
    let t = brightness_temperature(wavelength_nm, l);
    if t.is_nan() {
        return (f64::NAN, f64::NAN);
    }
    (t, se / derivative(wavelength_nm, t))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Independent check: the per-wavenumber form, B_ν(T) = 2hc²ν³/(e^{hcν/kT} − 1) per m⁻¹,
    /// with B_λ = B_ν·ν² (|dν/dλ| = 1/λ²), at 10 µm and 300 K: 9.924 W m⁻² sr⁻¹ µm⁻¹ (the
    /// textbook value, e.g. Petty 2006 fig. 6.2 reads ~9.9).
    /// Rationale (issue 43): at the lowest accepted temperature the radiance is a positive
    /// normal f64 and inverts to that temperature at every wavelength from 400 nm to 100 µm;
    /// at half of it the radiance is 0 or subnormal.
    #[test]
    fn the_lowest_temperature_still_radiates_and_inverts() {
        for wl in [400.0, 550.0, 10_000.0, 100_000.0] {
            let t = lowest_temperature(wl);
            let b = radiance(wl, t);
            assert!(b.is_normal(), "{wl} nm at {t} K: {b}");
            assert!((brightness_temperature(wl, b) / t - 1.0).abs() < 1e-9);
            assert!(radiance(wl, 0.5 * t) < f64::MIN_POSITIVE, "{wl} nm");
        }
        assert!((lowest_temperature(10_000.0) - 2.2135).abs() < 0.001);
    }

    #[test]
    fn ten_microns_at_300_k() {
        let b = radiance(10_000.0, 300.0);
        let nu: f64 = 1.0 / 10e-6; // m⁻¹
        let b_nu = 2.0 * H * C * C * nu.powi(3) / ((H * C * nu / (K_B * 300.0)).exp() - 1.0);
        let b_lambda = b_nu * nu * nu * 1e-9;
        assert!((b / b_lambda - 1.0).abs() < 1e-12, "{b} {b_lambda}");
        assert!((b - 9.924e-3).abs() < 2e-6, "{b}");
    }

    /// Stefan–Boltzmann: π∫B_λ dλ = σT⁴ (σ = 5.670 374 419e−8 W m⁻² K⁻⁴).
    #[test]
    fn stefan_boltzmann() {
        let t = 288.0;
        // Midpoint rule in ln λ from 0.5 µm to 1 mm.
        let n = 200_000;
        let (a, b) = ((500.0f64).ln(), (1.0e6f64).ln());
        let h = (b - a) / n as f64;
        let sum: f64 = (0..n)
            .map(|i| {
                let l = (a + (i as f64 + 0.5) * h).exp();
                radiance(l, t) * l * h
            })
            .sum();
        let sigma = 5.670_374_419e-8;
        assert!((std::f64::consts::PI * sum / (sigma * t.powi(4)) - 1.0).abs() < 1e-4);
    }

    #[test]
    fn inverse_and_derivative() {
        for &(l, t) in &[
            (4000.0, 250.0),
            (10_000.0, 300.0),
            (15_000.0, 190.0),
            (500.0, 5800.0),
        ] {
            let b = radiance(l, t);
            assert!((brightness_temperature(l, b) - t).abs() < 1e-9 * t);
            let h = 1e-4;
            let fd = (radiance(l, t + h) - radiance(l, t - h)) / (2.0 * h);
            assert!((derivative(l, t) / fd - 1.0).abs() < 1e-6);
        }
        assert!(brightness_temperature(10_000.0, 0.0).is_nan());
        assert!(brightness_temperature(10_000.0, -1.0).is_nan());
        assert_eq!(radiance(10_000.0, 0.0), 0.0);
    }
}
