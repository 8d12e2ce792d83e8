//! Reader of eradiate's older (v0) precomputed CKD absorption file.
//!
//! ## Format (`shared/data/ckd/eradiate_v0_ckd/afgl1986-us_standard-10nm.nc`, eradiate-data;
//! `shared/data/MANIFEST.md` §8)
//! * `k(z, bd)` — volume absorption coefficient, `units = "km^-1"`,
//!   `standard_name = "volume_absorption_coefficient"`, of the AFGL-1986 US-standard
//!   atmosphere (all its absorbing gases), converted here to **m⁻¹**;
//! * `z(z)` — altitudes \[km\] of the **layer centres** (49 layers: 1 km thick from 0 to 25 km,
//!   2.5 km to 50 km, 5 km to 120 km), converted to m;
//! * `bd` — a flattened (bin, g-point) index with the coordinates `bin(bd)` (string, the bin's
//!   centre wavelength in nm, e.g. `"760"` for 755–765 nm; global attribute `bin_set = "10nm"`)
//!   and `index(bd)` (int, the g-point index 0…n−1 of an n-point **Gauss–Legendre** rule on
//!   g ∈ [0, 1], nodes ascending; n = 16 in this file). The file stores no weights: they are the
//!   Gauss–Legendre weights ([`super::axsdb::gauss_legendre_unit`]), which `bin_set_10nm.nc`
//!   confirms (`quadrature_type = "gauss_legendre"`, `quadrature_n = 16`).
//! * The optional bin-set file `bin_set_10nm.nc` gives `wmin(bin)`, `wmax(bin)` \[nm\] for the bin
//!   labels; without it the bounds are centre ± half the width named by `bin_set` ("10nm").
//!
//! Spectral coverage 395–2405 nm (201 bins "400" … "2400").
//!
//! **Content caveat** (from the data, see the tests): the k values are line absorption only
//! (HITRAN-type: H2O, O2, …). There is no ozone Chappuis continuum — the 550 nm bin has a
//! band-mean column τ ≈ 8e-4 and τ(g₀) ≈ 5e-6, where 346 DU of O3 alone would give ≈ 0.03 in
//! every g-point — so O3 cross-sections must be added separately when using this file.
//!
//! ## Layers and interpolation
//! The layer bounds are rebuilt from the centres: b₀ = c₀ − (c₁ − c₀)/2 (0 km here) and
//! b_{i+1} = 2cᵢ − bᵢ, which gives 0, 1, …, 25, 27.5, …, 50, 55, …, 120 km (checked to be
//! increasing with each centre inside its layer). The optical thickness of [z0, z1] ⊂ [b₀, b_N]
//! for one bin and g-point is ∫ k dz with, per [`V0Interpolation`],
//! * `Cells` (default): k constant in each layer — the layered atmosphere the data describe, so
//!   the whole-column τ is Σ kᵢ Δzᵢ exactly;
//! * `Linear`: k linear in z between layer centres, constant in the outer half-layers.
//!
//! A band-mean transmittance is Σ_g w_g exp(−τ_g). Reference: Eradiate's early CKD mode
//! (Rayference, <https://www.eradiate.eu>, data from eradiate-data); CKD method: Fu & Liou
//! (1992), J. Atmos. Sci. 49, 2139–2156.

use std::path::Path;

use super::axsdb::gauss_legendre_unit;
use super::{
    metre_factor, open_nc, per_metre_factor, read_f64, read_scaled, variable, AbsorptionError,
    Result,
};

/// How k varies between the layer values (see the module header).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum V0Interpolation {
    #[default]
    Cells,
    Linear,
}

/// One 10 nm bin: its quadrature and k(z) per g-point.
#[derive(Clone, Debug)]
pub struct V0Bin {
    /// Label as stored (`"760"`).
    pub label: String,
    /// Centre \[nm\] (the label's value).
    pub centre_nm: f64,
    /// Bounds \[nm\].
    pub lower_nm: f64,
    pub upper_nm: f64,
    /// g-points (ascending) and weights (sum 1).
    pub g: Vec<f64>,
    pub weights: Vec<f64>,
    /// k [m⁻¹] per g-point, at the layer centres.
    pub k: Vec<Vec<f64>>,
}

/// The whole file.
#[derive(Clone, Debug)]
pub struct EradiateV0Ckd {
    path: String,
    z_centres_m: Vec<f64>,
    z_bounds_m: Vec<f64>,
    bins: Vec<V0Bin>,
}

fn string_at(var: &netcdf::Variable<'_>, path: &str, i: usize) -> Result<String> {
    var.get_string([i])
        .map_err(|source| AbsorptionError::Netcdf {
            path: path.to_string(),
            variable: var.name(),
            source,
        })
}

impl EradiateV0Ckd {
    /// Read the k file and, optionally, its bin-set file (for the bin bounds).
    pub fn open(path: &Path, bin_set: Option<&Path>) -> Result<EradiateV0Ckd> {
        let _session = crate::netcdf_session();
        let ps = path.display().to_string();
        let fmt = |variable: &str, message: String| AbsorptionError::Format {
            path: ps.clone(),
            variable: variable.to_string(),
            message,
        };
        let file = open_nc(path)?;
        let z = read_scaled(&file, &ps, "z", "a length (km)", metre_factor)?;
        let k = read_scaled(
            &file,
            &ps,
            "k",
            "an absorption coefficient (km^-1)",
            per_metre_factor,
        )?;
        let kv = variable(&file, &ps, "k")?;
        let kdims: Vec<String> = kv.dimensions().iter().map(|d| d.name()).collect();
        if kdims != ["z", "bd"] {
            return Err(fmt(
                "k",
                format!("dimensions {kdims:?}, expected [\"z\", \"bd\"]"),
            ));
        }
        let binv = variable(&file, &ps, "bin")?;
        let nbd = binv.len();
        let index: Vec<i64> = variable(&file, &ps, "index")?
            .get_values::<i64, _>(..)
            .map_err(|source| AbsorptionError::Netcdf {
                path: ps.clone(),
                variable: "index".into(),
                source,
            })?;
        let nz = z.len();
        if k.len() != nz * nbd || index.len() != nbd {
            return Err(fmt("k", format!("{} values for {nz} × {nbd}", k.len())));
        }
        if let Some((i, &v)) = k
            .iter()
            .enumerate()
            .find(|(_, v)| !v.is_finite() || **v < 0.0)
        {
            return Err(AbsorptionError::BadValue {
                path: ps.clone(),
                variable: "k".into(),
                value: v,
                index: i,
            });
        }

        // Layer bounds from the centres.
        if nz < 2 || z.windows(2).any(|w| w[1] <= w[0]) {
            return Err(fmt(
                "z",
                "needs ≥ 2 strictly increasing layer centres".into(),
            ));
        }
        let mut b = vec![z[0] - 0.5 * (z[1] - z[0])];
        for (i, &c) in z.iter().enumerate() {
            let next = 2.0 * c - b[i];
            if next <= c {
                return Err(fmt(
                    "z",
                    format!(
                        "layer centres do not define layers (centre {} m, lower bound {} m)",
                        c, b[i]
                    ),
                ));
            }
            b.push(next);
        }

        // Bin width from the `bin_set` attribute ("10nm"), for bounds without a bin-set file.
        let width = match file.attribute("bin_set").map(|a| a.value()) {
            Some(Ok(netcdf::AttributeValue::Str(s))) => {
                s.trim_end_matches("nm").parse::<f64>().ok()
            }
            _ => None,
        };
        let set_bounds: Option<Vec<(String, f64, f64)>> =
            match bin_set {
                Some(bp) => {
                    let bps = bp.display().to_string();
                    let bf = open_nc(bp)?;
                    match bf.attribute("quadrature_type").map(|a| a.value()) {
                        Some(Ok(netcdf::AttributeValue::Str(s))) if s == "gauss_legendre" => {}
                        _ => return Err(AbsorptionError::Format {
                            path: bps,
                            variable: "quadrature_type".into(),
                            message:
                                "expected the global attribute quadrature_type = \"gauss_legendre\""
                                    .into(),
                        }),
                    }
                    let lo = read_f64(&variable(&bf, &bps, "wmin")?, &bps)?;
                    let hi = read_f64(&variable(&bf, &bps, "wmax")?, &bps)?;
                    let lv = variable(&bf, &bps, "bin")?;
                    let mut out = Vec::new();
                    for i in 0..lv.len().min(lo.len()).min(hi.len()) {
                        out.push((string_at(&lv, &bps, i)?, lo[i], hi[i]));
                    }
                    Some(out)
                }
                None => None,
            };

        // Group the bd entries by bin label, in file order.
        let mut labels: Vec<String> = Vec::new();
        let mut members: Vec<Vec<(usize, usize)>> = Vec::new(); // (g index, bd)
        for (bd, &gi) in index.iter().enumerate() {
            let label = string_at(&binv, &ps, bd)?;
            let slot = match labels.iter().position(|l| *l == label) {
                Some(s) => s,
                None => {
                    labels.push(label);
                    members.push(Vec::new());
                    labels.len() - 1
                }
            };
            members[slot].push((gi.max(0) as usize, bd));
        }
        let mut bins = Vec::with_capacity(labels.len());
        for (label, mut m) in labels.into_iter().zip(members) {
            m.sort();
            let n = m.len();
            if m.iter().enumerate().any(|(i, &(gi, _))| gi != i) {
                return Err(fmt(
                    "index",
                    format!("bin `{label}`: g indices are not 0…{}", n - 1),
                ));
            }
            let centre_nm: f64 = label
                .trim()
                .parse()
                .map_err(|_| fmt("bin", format!("label `{label}` is not a wavelength in nm")))?;
            let (lower_nm, upper_nm) = match &set_bounds {
                Some(s) => match s.iter().find(|e| e.0 == label) {
                    Some(e) => (e.1, e.2),
                    None => {
                        return Err(AbsorptionError::Missing {
                            path: bin_set.map(|p| p.display().to_string()).unwrap_or_default(),
                            what: "bin",
                            name: label,
                        })
                    }
                },
                None => match width {
                    Some(w) => (centre_nm - 0.5 * w, centre_nm + 0.5 * w),
                    None => (f64::NAN, f64::NAN),
                },
            };
            let quad = gauss_legendre_unit(n);
            let k = m
                .iter()
                .map(|&(_, bd)| (0..nz).map(|iz| k[iz * nbd + bd]).collect())
                .collect();
            bins.push(V0Bin {
                label,
                centre_nm,
                lower_nm,
                upper_nm,
                g: quad.iter().map(|q| q.0).collect(),
                weights: quad.iter().map(|q| q.1).collect(),
                k,
            });
        }
        Ok(EradiateV0Ckd {
            path: ps,
            z_centres_m: z,
            z_bounds_m: b,
            bins,
        })
    }

    pub fn path(&self) -> &str {
        &self.path
    }

    pub fn bins(&self) -> &[V0Bin] {
        &self.bins
    }

    /// The bin of that label (`"760"`).
    pub fn bin(&self, label: &str) -> Result<&V0Bin> {
        self.bins
            .iter()
            .find(|b| b.label == label)
            .ok_or_else(|| AbsorptionError::NoSuchBin {
                path: self.path.clone(),
                bin: label.to_string(),
                count: self.bins.len(),
            })
    }

    /// The bin whose [lower, upper) holds `wavelength_nm`.
    pub fn bin_containing(&self, wavelength_nm: f64) -> Option<&V0Bin> {
        self.bins
            .iter()
            .find(|b| b.lower_nm <= wavelength_nm && wavelength_nm < b.upper_nm)
    }

    /// Layer centres \[m\].
    pub fn layer_centres_m(&self) -> &[f64] {
        &self.z_centres_m
    }

    /// Layer bounds \[m\] (one more than the centres).
    pub fn layer_bounds_m(&self) -> &[f64] {
        &self.z_bounds_m
    }

    /// Vertical optical thickness of [z0_m, z1_m] for `bin`'s g-point `g_index`.
    pub fn optical_thickness(
        &self,
        bin: &V0Bin,
        g_index: usize,
        z0_m: f64,
        z1_m: f64,
        interp: V0Interpolation,
    ) -> Result<f64> {
        let k = bin
            .k
            .get(g_index)
            .ok_or_else(|| AbsorptionError::NoSuchBin {
                path: self.path.clone(),
                bin: format!("{} g index {g_index}", bin.label),
                count: bin.k.len(),
            })?;
        let b = &self.z_bounds_m;
        let (bot, top) = (b[0], b[b.len() - 1]);
        let tol = 1e-9 * (top - bot);
        for v in [z0_m, z1_m] {
            if !v.is_finite() || v < bot - tol || v > top + tol {
                return Err(AbsorptionError::OutOfRange {
                    path: self.path.clone(),
                    coordinate: "z [m]".into(),
                    value: v,
                    min: bot,
                    max: top,
                });
            }
        }
        let (lo, hi, sign) = if z1_m >= z0_m {
            (z0_m, z1_m, 1.0)
        } else {
            (z1_m, z0_m, -1.0)
        };
        let tau = match interp {
            V0Interpolation::Cells => (0..k.len())
                .map(|i| {
                    let overlap = (b[i + 1].min(hi) - b[i].max(lo)).max(0.0);
                    k[i] * overlap
                })
                .sum(),
            V0Interpolation::Linear => {
                let c = &self.z_centres_m;
                let mut zs = Vec::with_capacity(c.len() + 2);
                let mut ks = Vec::with_capacity(c.len() + 2);
                zs.push(bot);
                ks.push(k[0]);
                zs.extend_from_slice(c);
                ks.extend_from_slice(k);
                zs.push(top);
                ks.push(k[k.len() - 1]);
                super::profile::integrate_piecewise_linear(&zs, &ks, lo, hi)
            }
        };
        Ok(sign * tau)
    }

    /// Whole-column optical thickness per g-point of `bin` (cells).
    pub fn column_optical_thickness(&self, bin: &V0Bin) -> Vec<f64> {
        let b = &self.z_bounds_m;
        bin.k
            .iter()
            .map(|k| {
                k.iter()
                    .zip(b.windows(2))
                    .map(|(k, w)| k * (w[1] - w[0]))
                    .sum()
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_data::shared;
    use super::*;

    fn open() -> Option<EradiateV0Ckd> {
        let p = shared("ckd/eradiate_v0_ckd/afgl1986-us_standard-10nm.nc")?;
        let s = shared("ckd/eradiate_v0_ckd/bin_set_10nm.nc")?;
        Some(EradiateV0Ckd::open(&p, Some(&s)).unwrap())
    }

    #[test]
    fn layout_weights_and_layers() {
        let Some(db) = open() else { return };
        assert_eq!(db.bins().len(), 201);
        assert_eq!(db.bins()[0].label, "400");
        let b = db.layer_bounds_m();
        assert_eq!(b.len(), 50);
        assert!(b[0].abs() < 1e-9 && (b[49] - 120e3).abs() < 1e-6);
        assert!(
            (b[25] - 25e3).abs() < 1e-6
                && (b[26] - 27.5e3).abs() < 1e-6
                && (b[35] - 50e3).abs() < 1e-6
        );
        for bin in db.bins() {
            assert_eq!(bin.g.len(), 16);
            let s: f64 = bin.weights.iter().sum();
            assert!((s - 1.0).abs() < 1e-13, "bin {}: Σw = {s}", bin.label);
            assert!((bin.upper_nm - bin.lower_nm - 10.0).abs() < 1e-9);
        }
        let a = db.bin("760").unwrap();
        assert_eq!((a.lower_nm, a.upper_nm), (755.0, 765.0));
        assert_eq!(db.bin_containing(761.0).unwrap().label, "760");
        assert!(db.bin("345").is_err());
        // Without the bin-set file, bounds come from the `bin_set = "10nm"` attribute.
        let p = shared("ckd/eradiate_v0_ckd/afgl1986-us_standard-10nm.nc").unwrap();
        let bare = EradiateV0Ckd::open(&p, None).unwrap();
        let a = bare.bin("760").unwrap();
        assert_eq!((a.lower_nm, a.upper_nm), (755.0, 765.0));
    }

    #[test]
    fn o2_a_band_is_monotone_in_g() {
        let Some(db) = open() else { return };
        let bin = db.bin("760").unwrap();
        let tau = db.column_optical_thickness(bin);
        println!(
            "760 nm column τ per g-point: {:?}",
            tau.iter().map(|t| format!("{t:.4e}")).collect::<Vec<_>>()
        );
        assert!(tau.windows(2).all(|w| w[1] >= w[0]), "not monotone in g");
        assert!(tau[0] < 0.05, "low g: {}", tau[0]);
        assert!(tau[15] > 10.0, "high g: {}", tau[15]);
        let t: f64 = bin
            .weights
            .iter()
            .zip(&tau)
            .map(|(w, t)| w * (-t).exp())
            .sum();
        println!(
            "760 nm band-mean column transmittance {t:.4} (effective τ {:.4})",
            -t.ln()
        );
        // Layers add up, both interpolations agree on the column (within 1 % at g = 8).
        let whole = db
            .optical_thickness(bin, 8, 0.0, 120e3, V0Interpolation::Cells)
            .unwrap();
        let parts = db
            .optical_thickness(bin, 8, 0.0, 10e3, V0Interpolation::Cells)
            .unwrap()
            + db.optical_thickness(bin, 8, 10e3, 120e3, V0Interpolation::Cells)
                .unwrap();
        assert!((whole - parts).abs() <= 1e-12 * whole && (whole - tau[8]).abs() <= 1e-12 * whole);
        let lin = db
            .optical_thickness(bin, 8, 0.0, 120e3, V0Interpolation::Linear)
            .unwrap();
        println!("760 nm g-point 8: τ cells {whole:.5} linear {lin:.5}");
        assert!((lin / whole - 1.0).abs() < 0.01);
        for (z0, z1) in [(0.0, 1e3), (1e3, 2e3), (0.0, 10e3)] {
            let t = db
                .optical_thickness(bin, 15, z0, z1, V0Interpolation::Cells)
                .unwrap();
            println!(
                "760 nm g-point 15: τ({}–{} km) = {t:.4}",
                z0 / 1e3,
                z1 / 1e3
            );
        }
        let e = db
            .optical_thickness(bin, 0, 0.0, 130e3, V0Interpolation::Cells)
            .unwrap_err();
        assert!(e.to_string().contains("`z [m]`"), "{e}");
    }

    #[test]
    fn window_bin_550_is_small_positive_and_has_no_ozone_continuum() {
        let Some(db) = open() else { return };
        let bin = db.bin("550").unwrap();
        let tau = db.column_optical_thickness(bin);
        println!(
            "550 nm column τ per g-point: {:?}",
            tau.iter().map(|t| format!("{t:.4e}")).collect::<Vec<_>>()
        );
        assert!(tau.iter().all(|&t| t > 0.0));
        let t: f64 = bin
            .weights
            .iter()
            .zip(&tau)
            .map(|(w, t)| w * (-t).exp())
            .sum();
        let eff = -t.ln();
        let mean: f64 = bin.weights.iter().zip(&tau).map(|(w, t)| w * t).sum();
        println!("550 nm: band-mean transmittance {t:.5}, effective τ {eff:.4}, mean τ {mean:.4}");
        // A smooth O3 Chappuis continuum (σ ≈ 3e-21 cm² at 550 nm, 5e-21 at 600 nm; 346 DU
        // → τ ≈ 0.03–0.05) would be a floor under every g-point. There is none: the lowest
        // g-points stay far below it and the bin-to-bin variation is that of line absorption
        // (H2O, O2). This file carries no ozone cross-sections; they must be added separately.
        for l in ["500", "520", "550", "560", "600", "620"] {
            let b = db.bin(l).unwrap();
            let tau = db.column_optical_thickness(b);
            let t: f64 = b
                .weights
                .iter()
                .zip(&tau)
                .map(|(w, t)| w * (-t).exp())
                .sum();
            println!(
                "{l} nm: effective τ {:.3e}, τ(g₀) {:.3e}, τ(g₁₅) {:.3e}",
                -t.ln(),
                tau[0],
                tau[15]
            );
            assert!(tau[0] < 1e-3, "{l} nm: τ(g₀) = {}", tau[0]);
        }
        assert!(eff > 0.0 && eff < 0.01, "{eff}");
    }
}
