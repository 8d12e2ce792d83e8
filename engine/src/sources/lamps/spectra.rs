//! Spectral shapes of named lamp types and the photopic luminosity function that scales them.
//!
//! | name | model (sums of Gaussians, nm) |
//! |---|---|
//! | `"hps"` | high-pressure sodium: the self-reversed, pressure-broadened D lines (583 and 596 nm, σ 5 nm, either side of the 589 nm dip) with the 569, 616 and 819 nm sodium lines and a weak 498 nm line |
//! | `"led_3000k"` | phosphor-converted white LED: blue pump 450 nm (σ 10 nm, relative height 0.35) and phosphor 605 nm (σ 55 nm) |
//! | `"led_4000k"` | the same with a stronger pump (0.6) and the phosphor at 585 nm (σ 55 nm) |
//! | `"metal_halide"` | mercury 405, 436, 546, 578 nm, thallium 535 nm, sodium 589 nm, indium 451 nm lines (σ 3 nm) over a continuum (σ 90 nm about 560 nm) |
//!
//! These are **shape models** with the features that matter for broad bands (where the lamp's
//! energy lies relative to the photopic curve, the sodium and blue-pump peaks), not measured
//! spectra: give a table (`intensity = { wavelengths_nm = […], values = […] }`) for narrow-band
//! work. A named type is scaled so that its luminous intensity is `luminous_intensity_cd` (cd,
//! 1 cd = 1/683 W sr⁻¹ at 555 nm): `I_v = 683·∫ I_e(λ) V(λ) dλ` (trapezoid over 360–830 nm,
//! 0.5 nm steps), with `V(λ)` the photopic luminosity function in the multi-lobe Gaussian fit of
//! Wyman, Sloan & Shirley (2013), *Simple analytic approximations to the CIE XYZ colour matching
//! functions*, JCGT 2(2), eq. 2 (ȳ; within 1 % of CIE 1931 at its peak).

/// The lamp types that `intensity = "…"` names.
pub const NAMES: &[&str] = &["hps", "led_3000k", "led_4000k", "metal_halide"];

/// Luminous efficacy of radiation at 555 nm, lm W⁻¹.
pub const KM: f64 = 683.0;

/// Piecewise Gaussian of Wyman et al. (2013): σ1 left of μ, σ2 right of it.
fn g(l: f64, mu: f64, s1: f64, s2: f64) -> f64 {
    let s = if l < mu { s1 } else { s2 };
    (-0.5 * ((l - mu) / s).powi(2)).exp()
}

/// The photopic luminosity function V(λ) (peak ≈ 1 at 555–560 nm).
pub fn photopic(l: f64) -> f64 {
    0.821 * g(l, 568.8, 46.9, 40.5) + 0.286 * g(l, 530.9, 16.3, 31.1)
}

/// Unnormalized shape of lamp type `name` at `l` nm (`None`: unknown name).
fn raw(name: &str, l: f64) -> Option<f64> {
    let gauss = |mu: f64, s: f64, a: f64| a * (-0.5 * ((l - mu) / s).powi(2)).exp();
    Some(match name {
        "hps" => {
            gauss(583.0, 5.0, 1.0)
                + gauss(596.0, 5.0, 1.0)
                + gauss(568.8, 2.0, 0.25)
                + gauss(615.4, 2.0, 0.3)
                + gauss(819.0, 2.5, 0.35)
                + gauss(498.0, 2.0, 0.06)
        }
        "led_3000k" => gauss(450.0, 10.0, 0.35) + gauss(605.0, 55.0, 1.0),
        "led_4000k" => gauss(450.0, 10.0, 0.6) + gauss(585.0, 55.0, 1.0),
        "metal_halide" => {
            gauss(560.0, 90.0, 0.25)
                + gauss(404.7, 3.0, 0.3)
                + gauss(435.8, 3.0, 0.6)
                + gauss(451.1, 3.0, 0.4)
                + gauss(535.0, 3.0, 0.9)
                + gauss(546.1, 3.0, 0.8)
                + gauss(578.0, 3.0, 0.5)
                + gauss(589.0, 3.0, 0.7)
        }
        _ => return None,
    })
}

/// Spectral intensity (W sr⁻¹ nm⁻¹) of lamp type `name` at wavelengths `nm`, scaled to a
/// luminous intensity of `candela`; `None` for an unknown name.
pub fn intensity(name: &str, nm: &[f64], candela: f64) -> Option<Vec<f64>> {
    raw(name, 550.0)?;
    let (lo, hi, h) = (360.0, 830.0, 0.5);
    let n = ((hi - lo) / h) as usize;
    let lum: f64 = (0..=n)
        .map(|i| {
            let l = lo + i as f64 * h;
            let w = if i == 0 || i == n { 0.5 } else { 1.0 };
            w * h * raw(name, l).unwrap_or(0.0) * photopic(l)
        })
        .sum::<f64>()
        * KM;
    let k = candela / lum;
    Some(
        nm.iter()
            .map(|&l| k * raw(name, l).unwrap_or(0.0))
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn photopic_peaks_near_555_and_scaling_holds() {
        let (mut best, mut at) = (0.0, 0.0);
        for i in 0..500 {
            let l = 400.0 + i as f64;
            if photopic(l) > best {
                best = photopic(l);
                at = l;
            }
        }
        assert!(
            (best - 1.0).abs() < 0.03 && (at - 557.0).abs() < 6.0,
            "{best} at {at}"
        );
        // A monochromatic 555 nm source of 1 W/sr is 683 cd: a narrow line scaled to 683 cd
        // has ∫I dλ ≈ 1/V(555) W/sr.
        for name in NAMES {
            let nm: Vec<f64> = (0..=940).map(|i| 360.0 + 0.5 * i as f64).collect();
            let i = intensity(name, &nm, 1000.0).unwrap();
            let lum: f64 = i
                .iter()
                .zip(&nm)
                .map(|(v, l)| v * photopic(*l) * 0.5)
                .sum::<f64>()
                * KM;
            assert!((lum - 1000.0).abs() < 2.0, "{name}: {lum} cd");
            assert!(i.iter().all(|v| *v >= 0.0));
        }
        assert!(intensity("candle", &[550.0], 1.0).is_none());
        // Sodium light is yellow: more at 590 than at 450 nm; an LED has its blue pump.
        let hps = intensity("hps", &[450.0, 590.0], 1.0).unwrap();
        assert!(hps[1] > 50.0 * hps[0]);
        let led = intensity("led_4000k", &[450.0, 500.0], 1.0).unwrap();
        assert!(led[0] > led[1]);
    }
}
