//! Particle (aerosol) layers of the molecular atmosphere: vertical distributions and the
//! single-scattering datasets that give their spectral optics.
//!
//! | config key (`[[atmosphere.particle_layers]]`) | unit | default | meaning |
//! |---|---|---|---|
//! | `bottom`, `top` | km | required | altitude range holding the particles (within ground…TOA) |
//! | `optical_thickness` | — | required, ≥ 0 | column extinction optical thickness at `reference_wavelength` |
//! | `reference_wavelength` | nm | `550.0` | where `optical_thickness` is given (inside the dataset's range) |
//! | `distribution` | table | `{ type = "uniform" }` | vertical shape, see [`Distribution`] |
//! | `dataset` | path | required | Eradiate Aer-Core v2 netCDF or libRadtran `*.mie.cdf` file |
//! | `size_index` | — | `0` | libRadtran files only: index along `reff`/`hum` |
//!
//! **Vertical distributions** (densities in altitude z, truncated to [bottom, top] and
//! normalised to 1 there): uniform; exponential `e^{−(z−bottom)/H}` (H = `scale_height` > 0);
//! gaussian `e^{−(z−μ)²/2σ²}` (`mean` μ, `std` σ > 0, both km). The fraction of the particles in
//! a computational layer [a, b] is the **exact** integral of the normalised density over
//! [a, b] ∩ [bottom, top] (closed forms: thickness ratio, differences of exponentials, of erf),
//! so the fractions of layers tiling [bottom, top] sum to 1 up to rounding.
//!
//! **Spectral optics**: `τ(λ) = τ_ref · ext(λ)/ext(λ_ref)`, `ω(λ)` and the phase function at λ,
//! with ext and ω interpolated **linearly in wavelength** between the dataset's wavelengths and
//! the phase function mixed linearly between the two bracketing tables (as
//! `phase::Tabulated::load_libradtran` does); a node within 1e-3 nm is used as is. A wavelength
//! outside the dataset's range is an error naming the range (never an extrapolation or NaN).
//! Only ratios of `ext` matter, so its unit is irrelevant.
//!
//! **Aer-Core v2** (Eradiate, `*-aer_core_v2.nc`): `w(w)` wavelength (unit from its `units`
//! attribute: nm, µm or m), `ext(w)`, `ssa(w)`, `phase(phamat, w, iangle)` on `mu(w, iangle)`
//! (cosine of the scattering angle) with `nangles(w)` valid entries, `phamat(phamat)` naming the
//! components ("11", "12", "22", "33", "34", "44"; P22 = P11 and P44 = P33 when absent). Each
//! table goes through `phase::Tabulated::from_matrix_table` (linear in scattering angle,
//! renormalised to mean 1 over 4π), so polarized runs use the file's matrix, in the libRadtran
//! sign convention of `stokes.rs` (assumed: Aer-Core v2 files are converted from libRadtran-style
//! Mie output). **libRadtran** (`*.mie.cdf`): `wavelen` (µm), `ext(nlam, nreff)`,
//! `ssa(nlam, nreff)` at `size_index`; the phase function is `Tabulated::load_libradtran`'s.
//!
//! References: Eradiate data guide "Aer-Core v2" format; Emde et al. (2016) libRadtran, GMD
//! 9:1647.

use crate::phase::Tabulated;
use std::path::{Path, PathBuf};

/// Vertical shape of a particle layer; lengths in metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Distribution {
    Uniform,
    Exponential { scale_height: f64 },
    Gaussian { mean: f64, std: f64 },
}

/// A distribution over [bottom, top] (m), checked and ready to integrate.
#[derive(Clone, Copy, Debug)]
pub struct VerticalProfile {
    pub bottom: f64,
    pub top: f64,
    pub shape: Distribution,
    /// Unnormalised mass of [bottom, top].
    total: f64,
}

/// erf(x) to ~1e-16 (series with positive terms below 2.5, continued fraction for erfc above).
pub fn erf(x: f64) -> f64 {
    if x < 0.0 {
        -erf(-x)
    } else if x < 2.5 {
        erf_series(x)
    } else {
        1.0 - erfc_cf(x)
    }
}

/// erfc(x) = 1 − erf(x), accurate in the upper tail.
pub fn erfc(x: f64) -> f64 {
    if x < 0.0 {
        2.0 - erfc(-x)
    } else if x < 2.5 {
        1.0 - erf_series(x)
    } else {
        erfc_cf(x)
    }
}

/// erf(x) = 2/√π e^{−x²} Σ 2ⁿ x^{2n+1} / (1·3·…·(2n+1)), x ≥ 0 (no cancellation).
fn erf_series(x: f64) -> f64 {
    let x2 = x * x;
    let (mut term, mut sum) = (x, x);
    for n in 0..200 {
        term *= 2.0 * x2 / (2 * n + 3) as f64;
        sum += term;
        if term < 1e-17 * sum {
            break;
        }
    }
    sum * 2.0 / std::f64::consts::PI.sqrt() * (-x2).exp()
}

/// erfc(x) for x ≥ 2.5 by the Laplace continued fraction (modified Lentz).
fn erfc_cf(x: f64) -> f64 {
    // erfc(x) = e^{−x²}/√π · 1/(x + (1/2)/(x + 1/(x + (3/2)/(x + 2/(x + …))))).
    let tiny = 1e-300;
    let mut f = x;
    let mut c = x;
    let mut d = 0.0;
    for k in 1..500 {
        let a = k as f64 * 0.5;
        d = x + a * d;
        d = if d.abs() < tiny { tiny } else { d };
        c = x + a / c;
        c = if c.abs() < tiny { tiny } else { c };
        d = 1.0 / d;
        let delta = c * d;
        f *= delta;
        if (delta - 1.0).abs() < 1e-16 {
            break;
        }
    }
    (-x * x).exp() / std::f64::consts::PI.sqrt() / f
}

impl VerticalProfile {
    /// Check the shape on [bottom, top] (m); the message names the offending key (relative to
    /// the particle layer: `top`, `distribution.scale_height`, …).
    pub fn new(bottom: f64, top: f64, shape: Distribution) -> Result<Self, (String, String)> {
        if !(bottom.is_finite() && top.is_finite()) || top <= bottom {
            return Err((
                "top".into(),
                format!(
                    "{} km must be above bottom = {} km",
                    top / 1e3,
                    bottom / 1e3
                ),
            ));
        }
        match shape {
            Distribution::Uniform => {}
            Distribution::Exponential { scale_height } => {
                if !(scale_height.is_finite() && scale_height > 0.0) {
                    return Err((
                        "distribution.scale_height".into(),
                        format!("{} km must be positive", scale_height / 1e3),
                    ));
                }
            }
            Distribution::Gaussian { mean, std } => {
                if !mean.is_finite() {
                    return Err((
                        "distribution.mean".into(),
                        format!("{} km is not finite", mean / 1e3),
                    ));
                }
                if !(std.is_finite() && std > 0.0) {
                    return Err((
                        "distribution.std".into(),
                        format!("{} km must be positive", std / 1e3),
                    ));
                }
            }
        }
        let mut p = Self {
            bottom,
            top,
            shape,
            total: 1.0,
        };
        let total = p.mass(bottom, top);
        if !(total.is_finite() && total > 0.0) {
            return Err((
                "distribution".into(),
                format!(
                    "puts no particles within {}..{} km (the gaussian lies too far outside it)",
                    bottom / 1e3,
                    top / 1e3
                ),
            ));
        }
        p.total = total;
        Ok(p)
    }

    /// Unnormalised ∫ density over [a, b] ⊂ [bottom, top], a ≤ b, in stable closed forms.
    fn mass(&self, a: f64, b: f64) -> f64 {
        match self.shape {
            Distribution::Uniform => b - a,
            Distribution::Exponential { scale_height: h } => {
                // ∫_a^b e^{−(z−bottom)/h} dz / h = e^{−(a−bottom)/h}·(1 − e^{−(b−a)/h}).
                (-(a - self.bottom) / h).exp() * -(-(b - a) / h).exp_m1()
            }
            Distribution::Gaussian { mean, std } => {
                let s = std * std::f64::consts::SQRT_2;
                let (x1, x2) = ((a - mean) / s, (b - mean) / s);
                // ½(erf(x2) − erf(x1)), from the tail where both lie in one.
                if x1 >= 0.0 {
                    0.5 * (erfc(x1) - erfc(x2))
                } else if x2 <= 0.0 {
                    0.5 * (erfc(-x2) - erfc(-x1))
                } else {
                    0.5 * (erf(x2) - erf(x1))
                }
            }
        }
    }

    /// Fraction of the layer's particles in [a, b] (m): the exact integral of the normalised
    /// density over [a, b] ∩ [bottom, top].
    pub fn fraction(&self, a: f64, b: f64) -> f64 {
        let (lo, hi) = (a.max(self.bottom), b.min(self.top));
        if hi <= lo {
            return 0.0;
        }
        (self.mass(lo, hi) / self.total).clamp(0.0, 1.0)
    }

    /// Fractions in each of the computational layers `(bottom, top)` (m).
    pub fn fractions(&self, layers: &[(f64, f64)]) -> Vec<f64> {
        layers.iter().map(|&(a, b)| self.fraction(a, b)).collect()
    }
}

#[derive(Debug, thiserror::Error)]
pub enum DatasetError {
    #[error("cannot read particle dataset {path}: {source}")]
    Netcdf { path: String, source: netcdf::Error },
    #[error("particle dataset {path}: variable `{var}`: {msg}")]
    Variable {
        path: String,
        var: String,
        msg: String,
    },
    #[error("particle dataset {path}: {msg}")]
    Content { path: String, msg: String },
}

#[derive(Clone, Debug)]
enum PhaseSource {
    /// Aer-Core v2: per wavelength, P11 and the other elements on scattering angles (deg).
    AerCore {
        /// Per wavelength: θ (deg) and P11.
        p11: Vec<(Vec<f64>, Vec<f64>)>,
        /// Per wavelength: (b1, a2, a3, b2, a4) values on the same θ, when polarized.
        pol: Option<Vec<[Vec<f64>; 5]>>,
    },
    Libradtran {
        size_index: usize,
    },
}

/// Spectral single-scattering properties of one particle type.
#[derive(Clone, Debug)]
pub struct ParticleDataset {
    pub path: PathBuf,
    /// Ascending wavelengths, nm.
    pub wavelengths: Vec<f64>,
    /// Extinction (any unit: only ratios are used) and single-scattering albedo at them.
    pub ext: Vec<f64>,
    pub ssa: Vec<f64>,
    /// Which file layout ("Aer-Core v2" or "libRadtran").
    pub format: &'static str,
    phase: PhaseSource,
}

/// Bracketing nodes of `x` in ascending `xs`: (i, j, t) with x = (1−t)·xs[i] + t·xs[j]; a node
/// within 1e-3 of `x` gives (i, i, 0).
fn bracket(xs: &[f64], x: f64) -> Option<(usize, usize, f64)> {
    if let Some(i) = xs.iter().position(|&w| (w - x).abs() < 1e-3) {
        return Some((i, i, 0.0));
    }
    let j = xs.partition_point(|&w| w < x);
    if j == 0 || j >= xs.len() {
        return None;
    }
    let i = j - 1;
    Some((i, j, (x - xs[i]) / (xs[j] - xs[i])))
}

/// A wavelength converted to nm, rounded to 1e-9 nm (0.35 µm is 350 nm, not 350.00000000000006).
fn round_nm(w: f64) -> f64 {
    (w * 1e9).round() / 1e9
}

fn wavelength_factor(units: &str) -> Option<f64> {
    match units.trim().to_ascii_lowercase().as_str() {
        "nm" | "nanometer" | "nanometers" | "nanometre" | "nanometres" => Some(1.0),
        "µm" | "μm" | "um" | "micron" | "microns" | "micrometer" | "micrometers" | "micrometre"
        | "micrometres" => Some(1e3),
        "m" | "meter" | "meters" | "metre" | "metres" => Some(1e9),
        _ => None,
    }
}

impl ParticleDataset {
    /// Read a dataset, recognising its layout by its variables (`wavelen`: libRadtran; `w` and
    /// `ext`: Aer-Core v2). `size_index` applies to libRadtran files only.
    pub fn load(path: &Path, size_index: usize) -> Result<Self, DatasetError> {
        let ps = path.display().to_string();
        let _session = crate::netcdf_session();
        crate::util::nc_complete::check(path).map_err(|e| DatasetError::Content {
            path: ps.clone(),
            msg: e.to_string(),
        })?;
        let file = netcdf::open(path).map_err(|source| DatasetError::Netcdf {
            path: ps.clone(),
            source,
        })?;
        if file.variable("wavelen").is_some() {
            Self::load_libradtran(path, &file, size_index)
        } else if file.variable("w").is_some() && file.variable("ext").is_some() {
            Self::load_aer_core(path, &file)
        } else {
            Err(DatasetError::Content {
                path: ps,
                msg: "has neither `wavelen` (libRadtran) nor `w` and `ext` (Aer-Core v2): not a \
                      particle dataset"
                    .into(),
            })
        }
    }

    fn load_libradtran(
        path: &Path,
        file: &netcdf::File,
        size_index: usize,
    ) -> Result<Self, DatasetError> {
        let ps = path.display().to_string();
        let verr = |var: &str, msg: String| DatasetError::Variable {
            path: ps.clone(),
            var: var.into(),
            msg,
        };
        let read = |name: &str| -> Result<(Vec<f64>, Vec<usize>), DatasetError> {
            let v = file
                .variable(name)
                .ok_or_else(|| verr(name, "missing".into()))?;
            let dims = v.dimensions().iter().map(|d| d.len()).collect();
            let vals = v
                .get_values::<f64, _>(..)
                .map_err(|e| verr(name, e.to_string()))?;
            Ok((vals, dims))
        };
        let (wl_um, _) = read("wavelen")?;
        let nlam = wl_um.len();
        let (ext, ext_dims) = read("ext")?;
        let (ssa, ssa_dims) = read("ssa")?;
        for (name, dims) in [("ext", &ext_dims), ("ssa", &ssa_dims)] {
            if dims.len() != 2 || dims[0] != nlam {
                return Err(verr(
                    name,
                    format!("has shape {dims:?}, expected (nlam = {nlam}, nreff)"),
                ));
            }
            if size_index >= dims[1] {
                return Err(verr(
                    name,
                    format!(
                        "`size_index` = {size_index} but the file has {} size entries",
                        dims[1]
                    ),
                ));
            }
        }
        let n2 = ext_dims[1];
        let pick = |v: &[f64]| -> Vec<f64> { (0..nlam).map(|i| v[i * n2 + size_index]).collect() };
        let wl: Vec<f64> = wl_um.iter().map(|w| round_nm(w * 1e3)).collect();
        Self::finish(
            path,
            "libRadtran",
            ("wavelen", wl),
            pick(&ext),
            pick(&ssa),
            PhaseSource::Libradtran { size_index },
        )
    }

    fn load_aer_core(path: &Path, file: &netcdf::File) -> Result<Self, DatasetError> {
        let ps = path.display().to_string();
        let verr = |var: &str, msg: String| DatasetError::Variable {
            path: ps.clone(),
            var: var.into(),
            msg,
        };
        let var = |name: &str| {
            file.variable(name)
                .ok_or_else(|| verr(name, "missing (not an Aer-Core v2 file?)".into()))
        };
        let vals = |name: &str| -> Result<Vec<f64>, DatasetError> {
            var(name)?
                .get_values::<f64, _>(..)
                .map_err(|e| verr(name, e.to_string()))
        };
        let wv = var("w")?;
        let units = match wv.attribute_value("units") {
            Some(Ok(netcdf::AttributeValue::Str(s))) => s,
            Some(Ok(netcdf::AttributeValue::Strs(v))) if !v.is_empty() => v[0].clone(),
            _ => return Err(verr("w", "has no `units` attribute".into())),
        };
        let factor = wavelength_factor(&units)
            .ok_or_else(|| verr("w", format!("unknown wavelength unit \"{units}\"")))?;
        let wl: Vec<f64> = vals("w")?.iter().map(|w| round_nm(w * factor)).collect();
        let nw = wl.len();
        let ext = vals("ext")?;
        let ssa = vals("ssa")?;
        let phase_v = var("phase")?;
        let pdims: Vec<usize> = phase_v.dimensions().iter().map(|d| d.len()).collect();
        if pdims.len() != 3 || pdims[1] != nw {
            return Err(verr(
                "phase",
                format!("has shape {pdims:?}, expected (phamat, w = {nw}, iangle)"),
            ));
        }
        let (nphamat, nangle) = (pdims[0], pdims[2]);
        let phase = phase_v
            .get_values::<f64, _>(..)
            .map_err(|e| verr("phase", e.to_string()))?;
        let mu = vals("mu")?;
        if mu.len() != nw * nangle {
            return Err(verr(
                "mu",
                format!(
                    "has {} values, expected w × iangle = {}",
                    mu.len(),
                    nw * nangle
                ),
            ));
        }
        let nangles: Vec<usize> = match file.variable("nangles") {
            Some(v) => v
                .get_values::<i32, _>(..)
                .map_err(|e| verr("nangles", e.to_string()))?
                .iter()
                .map(|&n| n.max(0) as usize)
                .collect(),
            None => vec![nangle; nw],
        };
        if nangles.len() != nw || nangles.iter().any(|&n| n < 2 || n > nangle) {
            return Err(verr(
                "nangles",
                format!("values must lie in 2..={nangle}, one per wavelength"),
            ));
        }
        // Component names; default to the usual order.
        let mut names = Vec::new();
        if let Some(v) = file.variable("phamat") {
            for k in 0..nphamat {
                names.push(
                    v.get_string(k)
                        .map_err(|e| verr("phamat", e.to_string()))?
                        .trim()
                        .to_string(),
                );
            }
        } else if nphamat == 1 {
            names.push("11".into());
        } else {
            return Err(verr(
                "phamat",
                "missing (needed with several components)".into(),
            ));
        }
        let find = |c: &str| names.iter().position(|n| n == c);
        let i11 = find("11").ok_or_else(|| verr("phamat", format!("no \"11\" among {names:?}")))?;
        let polarized = nphamat > 1;
        let (i12, i33, i34) = (find("12"), find("33"), find("34"));
        if polarized && (i12.is_none() || i33.is_none() || i34.is_none()) {
            return Err(verr(
                "phamat",
                format!("{names:?}: a phase matrix needs \"11\", \"12\", \"33\" and \"34\""),
            ));
        }
        let (i22, i44) = (find("22").unwrap_or(i11), find("44").or(i33));
        let mut p11 = Vec::with_capacity(nw);
        let mut pol = Vec::with_capacity(nw);
        for iw in 0..nw {
            let n = nangles[iw];
            let mut theta = Vec::with_capacity(n);
            for (k, &m) in mu[iw * nangle..iw * nangle + n].iter().enumerate() {
                if !m.is_finite() || m.abs() > 1.0 + 1e-9 {
                    return Err(verr(
                        "mu",
                        format!("value {m} at w index {iw}, angle {k} is not a cosine"),
                    ));
                }
                theta.push(m.clamp(-1.0, 1.0).acos().to_degrees());
            }
            let elem = |c: usize| -> Result<Vec<f64>, DatasetError> {
                let o = (c * nw + iw) * nangle;
                let v = phase[o..o + n].to_vec();
                if let Some(k) = v.iter().position(|x| !x.is_finite()) {
                    return Err(verr(
                        "phase",
                        format!(
                            "component \"{}\" is not finite at w index {iw}, angle {k}",
                            names[c]
                        ),
                    ));
                }
                Ok(v)
            };
            p11.push((theta, elem(i11)?));
            if polarized {
                pol.push([
                    elem(i12.expect("checked"))?,
                    elem(i22)?,
                    elem(i33.expect("checked"))?,
                    elem(i34.expect("checked"))?,
                    elem(i44.expect("checked"))?,
                ]);
            }
        }
        let (ext, ssa) = (ext, ssa);
        Self::finish(
            path,
            "Aer-Core v2",
            ("w", wl),
            ext,
            ssa,
            PhaseSource::AerCore {
                p11,
                pol: polarized.then_some(pol),
            },
        )
    }

    /// Check sizes and values, sort by wavelength.
    fn finish(
        path: &Path,
        format: &'static str,
        (wname, wl): (&str, Vec<f64>),
        ext: Vec<f64>,
        ssa: Vec<f64>,
        phase: PhaseSource,
    ) -> Result<Self, DatasetError> {
        let ps = path.display().to_string();
        let verr = |var: &str, msg: String| DatasetError::Variable {
            path: ps.clone(),
            var: var.into(),
            msg,
        };
        let n = wl.len();
        if n == 0 {
            return Err(verr(wname, "is empty".into()));
        }
        for (name, v) in [("ext", &ext), ("ssa", &ssa)] {
            if v.len() != n {
                return Err(verr(
                    name,
                    format!("has {} values for {n} wavelengths", v.len()),
                ));
            }
        }
        for i in 0..n {
            if !(wl[i].is_finite() && wl[i] > 0.0) {
                return Err(verr(wname, format!("value {} is not a wavelength", wl[i])));
            }
            if !(ext[i].is_finite() && ext[i] >= 0.0) {
                return Err(verr(
                    "ext",
                    format!("{} at {} nm is not finite and ≥ 0", ext[i], wl[i]),
                ));
            }
            if !(ssa[i].is_finite() && (0.0..=1.0).contains(&ssa[i])) {
                return Err(verr(
                    "ssa",
                    format!("{} at {} nm is outside [0, 1]", ssa[i], wl[i]),
                ));
            }
        }
        // A wavelength axis must run one way (either way): a zigzag is a damaged or
        // hand-edited file, refused rather than silently sorted (issue 43).
        let up = wl.windows(2).all(|p| p[1] > p[0]);
        let down = wl.windows(2).all(|p| p[1] < p[0]);
        if n > 1 && !up && !down {
            let k = wl
                .windows(3)
                .position(|p| (p[1] - p[0]) * (p[2] - p[1]) <= 0.0)
                .map_or(1, |k| k + 1);
            return Err(verr(
                wname,
                format!(
                    "is not monotonic: value {} at index {k} breaks the order of {}, {}, {} (wavelengths must increase or decrease strictly)",
                    wl[k], wl[k - 1], wl[k], wl.get(k + 1).map_or(String::new(), |v| v.to_string())
                ),
            ));
        }
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| wl[a].total_cmp(&wl[b]));
        let phase = match phase {
            PhaseSource::AerCore { p11, pol } => PhaseSource::AerCore {
                p11: order.iter().map(|&i| p11[i].clone()).collect(),
                pol: pol.map(|p| order.iter().map(|&i| p[i].clone()).collect()),
            },
            other => other,
        };
        Ok(Self {
            path: path.to_path_buf(),
            wavelengths: order.iter().map(|&i| wl[i]).collect(),
            ext: order.iter().map(|&i| ext[i]).collect(),
            ssa: order.iter().map(|&i| ssa[i]).collect(),
            format,
            phase,
        })
    }

    fn range_error(&self, wavelength: f64) -> DatasetError {
        DatasetError::Content {
            path: self.path.display().to_string(),
            msg: format!(
                "wavelength {wavelength} nm is outside the dataset's range {}..{} nm",
                self.wavelengths[0],
                self.wavelengths[self.wavelengths.len() - 1]
            ),
        }
    }

    fn interp(&self, v: &[f64], wavelength: f64) -> Result<f64, DatasetError> {
        let (i, j, t) =
            bracket(&self.wavelengths, wavelength).ok_or_else(|| self.range_error(wavelength))?;
        Ok(if i == j {
            v[i]
        } else {
            v[i] + (v[j] - v[i]) * t
        })
    }

    /// Extinction at `wavelength` (nm), in the file's unit (linear interpolation).
    pub fn extinction(&self, wavelength: f64) -> Result<f64, DatasetError> {
        self.interp(&self.ext, wavelength)
    }

    /// Single-scattering albedo at `wavelength` (nm) (linear interpolation).
    pub fn albedo(&self, wavelength: f64) -> Result<f64, DatasetError> {
        self.interp(&self.ssa, wavelength)
    }

    /// `ext(λ)/ext(λ_ref)`: the factor from the optical thickness at the reference wavelength to
    /// the one at `wavelength`.
    pub fn extinction_ratio(&self, wavelength: f64, reference: f64) -> Result<f64, DatasetError> {
        let e_ref = self.extinction(reference)?;
        if e_ref <= 0.0 {
            return Err(DatasetError::Variable {
                path: self.path.display().to_string(),
                var: "ext".into(),
                msg: format!("is zero at the reference wavelength {reference} nm"),
            });
        }
        Ok(self.extinction(wavelength)? / e_ref)
    }

    /// The (normalised) phase function at `wavelength` (nm): the table at a node, else the
    /// linear mixture of the two bracketing tables.
    pub fn phase(&self, wavelength: f64) -> Result<Tabulated, DatasetError> {
        let ps = self.path.display().to_string();
        match &self.phase {
            PhaseSource::Libradtran { size_index } => {
                Tabulated::load_libradtran(&self.path, wavelength, *size_index).map_err(|e| {
                    DatasetError::Variable {
                        path: ps,
                        var: "phase".into(),
                        msg: e.to_string(),
                    }
                })
            }
            PhaseSource::AerCore { p11, pol } => {
                let (i, j, t) = bracket(&self.wavelengths, wavelength)
                    .ok_or_else(|| self.range_error(wavelength))?;
                let table = |k: usize| -> Result<Tabulated, DatasetError> {
                    let (th, p) = &p11[k];
                    let r = match pol {
                        None => Tabulated::from_table(th, p),
                        Some(e) => Tabulated::from_matrix_table(
                            th,
                            p,
                            [
                                (th, &e[k][0]),
                                (th, &e[k][1]),
                                (th, &e[k][2]),
                                (th, &e[k][3]),
                                (th, &e[k][4]),
                            ],
                        ),
                    };
                    r.map_err(|m| DatasetError::Variable {
                        path: ps.clone(),
                        var: "phase".into(),
                        msg: format!("at {} nm: {m}", self.wavelengths[k]),
                    })
                };
                if i == j {
                    table(i)
                } else {
                    Ok(Tabulated::mix(&table(i)?, &table(j)?, t))
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phase::{test_support::mean_over_sphere, PhaseFunction};
    use std::sync::Arc;

    #[test]
    fn erf_values() {
        // Reference values: Python's math.erf / math.erfc (C library, correctly rounded to ~1 ulp).
        for (x, e) in [
            (0.1, 0.112_462_916_018_284_9),
            (0.5, 0.520_499_877_813_046_5),
            (1.0, 0.842_700_792_949_714_9),
            (2.0, 0.995_322_265_018_952_7),
            (2.6, 0.999_763_965_583_470_7),
            (3.0, 0.999_977_909_503_001_4),
        ] {
            assert!((erf(x) - e).abs() < 1e-15, "erf({x}) = {} vs {e}", erf(x));
            assert!((erf(-x) + e).abs() < 1e-15);
        }
        for (x, e) in [
            (2.0, 4.677_734_981_047_266e-3),
            (3.0, 2.209_049_699_858_544e-5),
            (5.0, 1.537_459_794_428_035e-12),
            (10.0, 2.088_487_583_762_545e-45),
        ] {
            assert!(
                (erfc(x) / e - 1.0).abs() < 1e-13,
                "erfc({x}) = {} vs {e}",
                erfc(x)
            );
        }
    }

    fn grid(lo: f64, hi: f64, dz: f64) -> Vec<(f64, f64)> {
        let mut v = Vec::new();
        let mut z = lo;
        while z < hi - 1e-9 {
            v.push((z, (z + dz).min(hi)));
            z += dz;
        }
        v
    }

    /// Fractions over a grid that covers the particle layer sum to 1; uniform ∝ thickness;
    /// exponential and gaussian match the closed forms / a fine midpoint quadrature.
    #[test]
    fn distribution_fractions() {
        let layers = grid(0.0, 10e3, 1e3);
        let uni = VerticalProfile::new(500.0, 2500.0, Distribution::Uniform).unwrap();
        let f = uni.fractions(&layers);
        println!("uniform 0.5-2.5 km: {:?}", &f[..4]);
        assert_eq!(f[0], 0.25);
        assert_eq!(f[1], 0.5);
        assert_eq!(f[2], 0.25);
        assert!(f[3..].iter().all(|&x| x == 0.0));

        let h = 1.0e3;
        let exp =
            VerticalProfile::new(0.0, 2e3, Distribution::Exponential { scale_height: h }).unwrap();
        let f = exp.fractions(&layers);
        let norm = 1.0 - (-2.0f64).exp();
        let want = [
            (1.0 - (-1.0f64).exp()) / norm,
            ((-1.0f64).exp() - (-2.0f64).exp()) / norm,
        ];
        println!(
            "exponential H = 1 km on 0-2 km: {:?} (closed form {want:?})",
            &f[..2]
        );
        for k in 0..2 {
            assert!((f[k] - want[k]).abs() < 1e-15);
        }
        assert!((f.iter().sum::<f64>() - 1.0).abs() < 1e-15);

        let gau = VerticalProfile::new(
            0.0,
            8e3,
            Distribution::Gaussian {
                mean: 3e3,
                std: 1.5e3,
            },
        )
        .unwrap();
        let f = gau.fractions(&layers);
        assert!((f.iter().sum::<f64>() - 1.0).abs() < 1e-14);
        let dens = |z: f64| (-(z - 3e3f64).powi(2) / (2.0 * 1.5e3f64.powi(2))).exp();
        let quad = |a: f64, b: f64| {
            let n = 20_000;
            (0..n)
                .map(|i| dens(a + (b - a) * (i as f64 + 0.5) / n as f64))
                .sum::<f64>()
                * (b - a)
                / n as f64
        };
        let total = quad(0.0, 8e3);
        for (k, &(a, b)) in layers.iter().enumerate().take(8) {
            let q = quad(a, b) / total;
            assert!((f[k] - q).abs() < 1e-9, "layer {k}: {} vs {q}", f[k]);
        }
        // A layer grid that only partly covers the particle layer: the outside is lost.
        let part = exp.fractions(&grid(0.0, 1e3, 1e3));
        assert!((part[0] - want[0]).abs() < 1e-15);
        // A far-away gaussian tail is still a proper (normalised) distribution.
        let tail = VerticalProfile::new(
            0.0,
            2e3,
            Distribution::Gaussian {
                mean: 20e3,
                std: 1e3,
            },
        )
        .unwrap();
        let f = tail.fractions(&layers);
        assert!(
            (f.iter().sum::<f64>() - 1.0).abs() < 1e-12 && f[1] > f[0],
            "{f:?}"
        );
        // Bad parameters name their key.
        let bad = |d| VerticalProfile::new(0.0, 1e3, d).unwrap_err().0;
        assert_eq!(
            bad(Distribution::Exponential { scale_height: 0.0 }),
            "distribution.scale_height"
        );
        assert_eq!(
            bad(Distribution::Gaussian {
                mean: 0.0,
                std: -1.0
            }),
            "distribution.std"
        );
        assert_eq!(
            bad(Distribution::Gaussian {
                mean: 1e9,
                std: 1.0
            }),
            "distribution"
        );
        assert_eq!(
            VerticalProfile::new(1e3, 1e3, Distribution::Uniform)
                .unwrap_err()
                .0,
            "top"
        );
    }

    /// Rationale (issue 43): a wavelength axis that zigzags (a damaged or hand-edited file)
    /// is refused naming the variable and the index; one that decreases is accepted and read
    /// in increasing order; repeated wavelengths are refused.
    #[test]
    fn wavelength_axes_must_run_one_way() {
        let fin = |wl: Vec<f64>| {
            let n = wl.len();
            ParticleDataset::finish(
                Path::new("aer.nc"),
                "libRadtran",
                ("wavelen", wl),
                (0..n).map(|i| 1.0 + i as f64).collect(),
                vec![0.9; n],
                PhaseSource::Libradtran { size_index: 0 },
            )
        };
        let e = fin(vec![400.0, 600.0, 500.0]).unwrap_err().to_string();
        assert!(
            e.contains("aer.nc")
                && e.contains("wavelen")
                && e.contains("not monotonic")
                && e.contains("index 1"),
            "{e}"
        );
        assert!(fin(vec![400.0, 400.0, 500.0]).is_err());
        assert!(fin(vec![400.0, 400.0]).is_err());
        let d = fin(vec![600.0, 500.0, 400.0]).unwrap();
        assert_eq!(d.wavelengths, vec![400.0, 500.0, 600.0]);
        assert_eq!(d.ext, vec![3.0, 2.0, 1.0]);
        assert!(fin(vec![550.0]).is_ok());
    }

    fn eradiate(name: &str) -> PathBuf {
        // Same lookup as the absorption tests: `$SIMULATOR_SHARED_DATA`, else the workspace's
        // sibling `shared/data`.
        std::env::var_os("SIMULATOR_SHARED_DATA")
            .map(PathBuf::from)
            .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data"))
            .join("eradiate/aerosol")
            .join(name)
    }

    /// The Aer-Core v2 desert dataset: documented values at 550 nm (ncdump: ext = 0.031535548
    /// km⁻¹, ssa = 0.931394184112482), linear interpolation between 550 and 590 nm, normalised
    /// phase functions, and an error naming the range outside 350…3750 nm.
    #[test]
    fn aer_core_desert() {
        let path = eradiate("govaerts_2021-desert-aer_core_v2.nc");
        if !path.exists() {
            eprintln!("skipping: {} not found", path.display());
            return;
        }
        let d = ParticleDataset::load(&path, 0).unwrap();
        assert_eq!(d.format, "Aer-Core v2");
        assert_eq!(d.wavelengths.len(), 20);
        let (e, w) = (d.extinction(550.0).unwrap(), d.albedo(550.0).unwrap());
        let p = d.phase(550.0).unwrap();
        println!(
            "desert @550 nm: ext = {e} km^-1, ssa = {w}, g = {:.5}, P(0°) = {:.4}, P(180°) = {:.4}",
            p.asymmetry(),
            p.eval(1.0),
            p.eval(-1.0)
        );
        assert!((e - 0.031535548).abs() < 1e-12);
        assert!((w - 0.931394184112482).abs() < 1e-15);
        let (e2, w2) = (d.extinction(570.0).unwrap(), d.albedo(570.0).unwrap());
        println!("desert @570 nm (interpolated): ext = {e2}, ssa = {w2}");
        assert!((e2 - 0.5 * (0.031535548 + 0.030306005)).abs() < 1e-12);
        assert!((w2 - 0.5 * (0.931394184112482 + 0.933288633721271)).abs() < 1e-15);
        let r = d.extinction_ratio(570.0, 550.0).unwrap();
        assert!((r - e2 / e).abs() < 1e-15);
        // Phase: normalised, forward-peaked, and the mixture halfway at 570 nm.
        let p570 = d.phase(570.0).unwrap();
        let p590 = d.phase(590.0).unwrap();
        for mu in [-1.0, -0.5, 0.0, 0.7, 0.99, 1.0] {
            let mid = 0.5 * (p.eval(mu) + p590.eval(mu));
            assert!((p570.eval(mu) - mid).abs() < 1e-9 * mid, "mu {mu}");
        }
        let g = p.asymmetry();
        assert!(g > 0.5 && g < 0.9, "g = {g}");
        let pf = PhaseFunction::Tabulated(Arc::new(p));
        assert!((mean_over_sphere(&pf) - 1.0).abs() < 1e-6);
        for bad in [300.0, 4000.0] {
            let err = d.albedo(bad).unwrap_err().to_string();
            assert!(err.contains("350..3750 nm"), "{err}");
            assert!(err.contains("govaerts_2021-desert"), "{err}");
            assert!(d.phase(bad).is_err());
        }
    }

    /// Aer-Core v2 files with a polarized phase matrix and wavelengths in µm.
    #[test]
    fn aer_core_polarized_micrometres() {
        let path = eradiate("soot.mie-aer_core_v2.nc");
        if !path.exists() {
            eprintln!("skipping: {} not found", path.display());
            return;
        }
        let d = ParticleDataset::load(&path, 0).unwrap();
        assert!((d.wavelengths[0] - 250.0).abs() < 1e-9);
        let p = d.phase(550.0).unwrap();
        assert!(p.is_polarized());
        let m = p.matrix(0.0);
        println!(
            "soot @550 nm: ext = {}, ssa = {}, g = {:.4}, M(90°) = {m:?}",
            d.extinction(550.0).unwrap(),
            d.albedo(550.0).unwrap(),
            p.asymmetry()
        );
        assert!(m.b1.abs() <= m.a1 && m.a1 > 0.0);
    }

    /// The libRadtran waso file (one wavelength, 350 nm): ext and ssa at size_index 0, the
    /// phase function of `Tabulated::load_libradtran`, and errors naming file and variable.
    #[test]
    fn libradtran_waso() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../simulator/tests/data/fixtures/waso.mie.cdf");
        let d = ParticleDataset::load(&path, 0).unwrap();
        assert_eq!(d.format, "libRadtran");
        println!(
            "waso @350 nm: ext = {}, ssa = {}",
            d.extinction(350.0).unwrap(),
            d.albedo(350.0).unwrap()
        );
        assert!((d.albedo(350.0).unwrap() - 0.975682810500885).abs() < 1e-15);
        assert!((d.extinction_ratio(350.0, 350.0).unwrap() - 1.0).abs() < 1e-15);
        let direct = Tabulated::load_libradtran(&path, 350.0, 0).unwrap();
        assert_eq!(d.phase(350.0).unwrap().eval(0.3), direct.eval(0.3));
        let err = d.albedo(550.0).unwrap_err().to_string();
        assert!(
            err.contains("350..350 nm") && err.contains("waso.mie.cdf"),
            "{err}"
        );
        let err = ParticleDataset::load(&path, 3).unwrap_err().to_string();
        assert!(err.contains("`ext`") && err.contains("size_index"), "{err}");
        let err = ParticleDataset::load(Path::new("/nonexistent/x.nc"), 0)
            .unwrap_err()
            .to_string();
        assert!(err.contains("/nonexistent/x.nc"), "{err}");
    }
}
