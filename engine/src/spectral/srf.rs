//! Sensor spectral response functions (SRF) and band weighting.
//!
//! `spectral.srf` names an embedded SRF as `<platform>-<instrument>-<band>` — Sentinel-2A/B MSI
//! (`sentinel_2a-msi-4`, bands 1–12 and 8a), Terra/Aqua MODIS (`terra-modis-1` … 36,
//! `aqua-modis-1` … 16), Landsat-8 OLI (`landsat_8-oli-4` or `landsat_8-oli-Red`; bands 1–9 =
//! CoastalAerosol, Blue, Green, Red, NIR, SWIR1, SWIR2, Pan, Cirrus) — or a CSV file with columns
//! `wavelength_nm,response`. Provenance: `engine/data/srf/PROVENANCE.md`.
//!
//! In monochromatic mode the band is sampled on a regular grid of `spectral.wavelength_step` nm
//! spanning the response's support (where it is > 0), and band quantities are trapezoid-rule
//! averages: the band radiance `L_b = Σ w_k L_k / Σ w_k` with `w_k = S(λ_k)·Δλ_k`, and the band
//! BRF `Σ w_k E0_k BRF_k / Σ w_k E0_k` (so that `BRF_b = π L_b / (E0_b cos SZA)` with the band
//! irradiance `E0_b = Σ w_k E0_k / Σ w_k`). Wavelengths are independent runs, so the standard
//! errors combine in quadrature.

use super::SpectrumError;

const FAMILIES: [(&str, &str); 5] = [
    (
        "sentinel_2a-msi",
        include_str!("../../data/srf/sentinel_2a-msi.csv"),
    ),
    (
        "sentinel_2b-msi",
        include_str!("../../data/srf/sentinel_2b-msi.csv"),
    ),
    (
        "terra-modis",
        include_str!("../../data/srf/terra-modis.csv"),
    ),
    ("aqua-modis", include_str!("../../data/srf/aqua-modis.csv")),
    (
        "landsat_8-oli",
        include_str!("../../data/srf/landsat_8-oli.csv"),
    ),
];

const OLI_BANDS: [&str; 9] = [
    "CoastalAerosol",
    "Blue",
    "Green",
    "Red",
    "NIR",
    "SWIR1",
    "SWIR2",
    "Pan",
    "Cirrus",
];

/// A spectral response: increasing wavelengths (nm) and responses (any scale, ≥ 0).
#[derive(Clone, Debug)]
pub struct Srf {
    pub name: String,
    pub wavelength: Vec<f64>,
    pub response: Vec<f64>,
}

impl Srf {
    /// An embedded SRF by name; `Err` lists what exists when the name is unknown.
    pub fn builtin(name: &str) -> Result<Option<Srf>, SpectrumError> {
        let Some((family, text)) = FAMILIES
            .iter()
            .find(|(f, _)| name.starts_with(&format!("{f}-")))
        else {
            return Ok(None);
        };
        let mut band = name[family.len() + 1..].to_string();
        if *family == "landsat_8-oli" {
            if let Ok(i) = band.parse::<usize>() {
                if (1..=9).contains(&i) {
                    band = OLI_BANDS[i - 1].to_string();
                }
            }
        }
        let (mut w, mut r) = (Vec::new(), Vec::new());
        let mut bands = Vec::new();
        for line in text.lines().skip(1) {
            let f: Vec<&str> = line.split(',').collect();
            if f.len() < 3 {
                continue;
            }
            if !bands.contains(&f[0]) {
                bands.push(f[0]);
            }
            if f[0].eq_ignore_ascii_case(&band) {
                let number = |v: &str| {
                    v.parse::<f64>()
                        .map_err(|source| SpectrumError::EmbeddedNumber {
                            family: family.to_string(),
                            value: v.to_string(),
                            source,
                        })
                };
                w.push(number(f[1])?);
                r.push(number(f[2])?);
            }
        }
        if w.is_empty() {
            return Err(SpectrumError::NoBand {
                family: family.to_string(),
                band,
                bands: bands.iter().map(|b| b.to_string()).collect(),
            });
        }
        Ok(Some(Srf {
            name: name.into(),
            wavelength: w,
            response: r,
        }))
    }

    /// Parse a `wavelength_nm,response` CSV (a header line is skipped).
    pub fn from_csv(name: &str, text: &str) -> Result<Srf, SpectrumError> {
        let s = crate::spectral::solar::Spectrum::from_csv(name, text)?;
        Ok(Srf {
            name: name.into(),
            wavelength: s.wavelength,
            response: s.value,
        })
    }

    /// The response at `nm` (linear between samples, 0 outside).
    pub fn at(&self, nm: f64) -> f64 {
        let w = &self.wavelength;
        if nm < w[0] || nm > w[w.len() - 1] {
            return 0.0;
        }
        let i = w.partition_point(|&x| x <= nm).clamp(1, w.len() - 1);
        let t = (nm - w[i - 1]) / (w[i] - w[i - 1]);
        self.response[i - 1] + t * (self.response[i] - self.response[i - 1])
    }

    /// ∫ S(λ) dλ over each spectral bin [lower, upper) nm (S linear between its samples; exact
    /// integration over the pieces). Used in `mode = "ckd"`, where the bins are the sampling.
    pub fn bin_weights(&self, bins: &[(f64, f64)]) -> Vec<f64> {
        bins.iter()
            .map(|&(lo, hi)| {
                // Breakpoints: the bin's ends and the SRF's samples inside it.
                let mut x: Vec<f64> = std::iter::once(lo)
                    .chain(
                        self.wavelength
                            .iter()
                            .copied()
                            .filter(|&w| w > lo && w < hi),
                    )
                    .chain(std::iter::once(hi))
                    .collect();
                x.dedup();
                x.windows(2)
                    .map(|p| 0.5 * (self.at(p[0]) + self.at(p[1])) * (p[1] - p[0]))
                    .sum()
            })
            .collect()
    }

    /// The sampling grid over the support (step `step` nm) and its trapezoid weights.
    pub fn grid(&self, step: f64) -> Result<(Vec<f64>, Vec<f64>), SpectrumError> {
        let first = self.response.iter().position(|&r| r > 0.0).ok_or_else(|| {
            SpectrumError::ZeroResponse {
                name: self.name.clone(),
            }
        })?;
        let last = self.response.iter().rposition(|&r| r > 0.0).unwrap();
        // The support includes the zero just outside the first and last positive samples.
        let lo = self.wavelength[first.saturating_sub(1)];
        let hi = self.wavelength[(last + 1).min(self.wavelength.len() - 1)];
        // Counted before the grid is built: a step of 1e-9 nm would otherwise allocate until
        // memory runs out.
        let count = ((hi - lo) / step).ceil().max(1.0) + 1.0;
        if count.is_nan() || count > super::MAX_SRF_WAVELENGTHS as f64 {
            return Err(SpectrumError::TooManyWavelengths {
                step,
                lo,
                hi,
                count,
            });
        }
        let n = count as usize - 1;
        let h = (hi - lo) / n as f64;
        let (mut wl, mut wt) = (Vec::new(), Vec::new());
        for k in 0..=n {
            let x = lo + h * k as f64;
            let r = self.at(x) * h * if k == 0 || k == n { 0.5 } else { 1.0 };
            if r > 0.0 {
                wl.push(x);
                wt.push(r);
            }
        }
        Ok((wl, wt))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rationale: CSV exports from spreadsheets start with a UTF-8 byte-order mark; an SRF file
    /// with one reads exactly as without it (issue 43 item 7), as do the other CSV readers
    /// (profiles, solar spectra, cross-sections and leaf tables strip it the same way).
    #[test]
    fn a_byte_order_mark_is_not_data() {
        let text = "wavelength_nm,response\n600,0\n650,1\n700,0\n";
        let plain = Srf::from_csv("band.csv", text).unwrap();
        let marked = Srf::from_csv("band.csv", &format!("\u{feff}{text}")).unwrap();
        assert_eq!(plain.wavelength, marked.wavelength);
        assert_eq!(plain.response, marked.response);
        let profile = "z,n\n0,2.5e19\n100,1e13\n";
        let plain = crate::atmosphere::molecular::Profile::from_csv("p.csv", profile).unwrap();
        let marked =
            crate::atmosphere::molecular::Profile::from_csv("p.csv", &format!("\u{feff}{profile}"))
                .unwrap();
        assert_eq!((plain.z, plain.n), (marked.z, marked.n));
    }

    /// Bin weights integrate the SRF exactly: over bins tiling the support they sum to the
    /// integral of S, and a bin outside the support weighs 0.
    #[test]
    fn bin_weights_integrate_the_response() {
        let s = Srf::builtin("sentinel_2a-msi-4").unwrap().unwrap();
        let bins: Vec<(f64, f64)> = (0..120)
            .map(|i| (600.0 + i as f64, 601.0 + i as f64))
            .collect();
        let w = s.bin_weights(&bins);
        let total: f64 = s
            .wavelength
            .windows(2)
            .zip(s.response.windows(2))
            .map(|(x, r)| 0.5 * (r[0] + r[1]) * (x[1] - x[0]))
            .sum();
        let sum: f64 = w.iter().sum();
        assert!((sum / total - 1.0).abs() < 1e-12);
        assert_eq!(w[0], 0.0);
        assert_eq!(s.bin_weights(&[(900.0, 910.0)])[0], 0.0);
    }

    /// Sentinel-2A B4 (red) spans ≈ 646–685 nm with its centroid near 665 nm; band names and
    /// numbers of Landsat-8 OLI agree; unknown bands list the existing ones.
    #[test]
    fn embedded_bands() {
        let s = Srf::builtin("sentinel_2a-msi-4").unwrap().unwrap();
        let (wl, wt) = s.grid(1.0).unwrap();
        let c: f64 = wl.iter().zip(&wt).map(|(a, b)| a * b).sum::<f64>() / wt.iter().sum::<f64>();
        assert!((c - 665.0).abs() < 3.0, "centroid {c}");
        assert!(wl[0] > 630.0 && *wl.last().unwrap() < 700.0);
        let a = Srf::builtin("landsat_8-oli-4").unwrap().unwrap();
        let b = Srf::builtin("landsat_8-oli-Red").unwrap().unwrap();
        assert_eq!(a.wavelength, b.wavelength);
        let e = Srf::builtin("sentinel_2a-msi-13").unwrap_err().to_string();
        assert!(e.contains("8a"), "{e}");
        assert!(Srf::builtin("my_file.csv").unwrap().is_none());
    }

    /// The trapezoid weights integrate the response: Σw ≈ ∫S dλ on a fine and a coarse grid.
    #[test]
    fn grid_integrates() {
        let s = Srf::builtin("terra-modis-1").unwrap().unwrap();
        let fine: f64 = s.grid(0.25).unwrap().1.iter().sum();
        let coarse: f64 = s.grid(5.0).unwrap().1.iter().sum();
        assert!((coarse / fine - 1.0).abs() < 0.03, "{coarse} vs {fine}");
    }
}
