//! Reader of eradiate/axsdb absorption databases (CKD or monochromatic).
//!
//! ## Format (axsdb 0.1, Rayference; the `nanockd_v1` / `nanomono_v1` samples in
//! `shared/data/ckd/axsdb/`, see `shared/data/MANIFEST.md` §8)
//!
//! A database is a directory holding
//! * `index.csv`: one row per netCDF file, columns `filename`, `wn_min [cm^-1]`,
//!   `wn_max [cm^-1]`, `wl_min [nm]`, `wl_max [nm]` (the spectral range of the file);
//! * `spectral.csv` (optional here): one row per spectral point, `filename`,
//!   `wavelength [nm]`, `wbound_lower [nm]`, `wbound_upper [nm]` — for a CKD database one row per
//!   bin (bounds filled), for a monochromatic one per wavelength (bounds empty). When it is
//!   absent, the CKD bins are read from the files' `w` and `wbounds`;
//! * `metadata.json` (optional): provenance and the grids, kept as [`AxsDatabase::metadata`];
//! * netCDF files with the variable `sigma_a(x_A, x_B, …, p, t, w[, g])` (any dimension order).
//!
//! The **kind** is detected from the first file: a `g` dimension makes a CKD database
//! (`sigma_a(…, w, g)` is the inverse cumulative k-distribution of the bin `w`), no `g` a
//! monochromatic one.
//!
//! ## What `sigma_a` is (evidence)
//! `sigma_a` is the **volume absorption coefficient** of the gas mixture at the node's state, in
//! the file's `units` (km⁻¹ in both samples: `units = "km^-1"` / `"kilometer^-1"`,
//! `standard_name = "volume_absorption_coefficient"`), *not* a cross-section: the number density
//! is implied by the node's pressure and temperature (ideal gas, n = p / k_B T), so a caller
//! needs no number density. The test `ckd_sigma_a_is_a_volume_coefficient` checks this on the
//! O₃-only bin 345–355 nm: at fixed T, g and x_O3, `sigma_a / p` is the same at every pressure
//! node (O₃ cross-sections do not depend on pressure), and `sigma_a / (x_O3 · p / k_B T)` is an
//! O₃ cross-section of the expected size (~1e-22 cm²). The `x_*` coordinates are volume (mole)
//! fractions, `p` in Pa, `t` in K, `g` ∈ [0, 1] the cumulative-probability (quantile) coordinate,
//! `w` in nm (a wavenumber `w` in cm⁻¹ is also accepted, as axsdb does). CKD files also hold
//! `wbounds(wbv, w)` \[nm\] (the bin bounds) and `error(w, ng)`: the relative error (absolute
//! value) of the band-mean top-to-bottom transmittance of the AFGL-1986 US-standard atmosphere
//! computed with an `ng`-point Gauss–Legendre quadrature of g on [0, 1], against a
//! monochromatic (line-by-line) reference integrated over the bin ( `error:comment`).
//! Everything returned here is converted to **m⁻¹** (SI) once, when a file is loaded.
//!
//! ## Interpolation (as axsdb `eval_sigma_a_*` does)
//! * **Linear** (not log-linear) in p, in T and in every mole fraction `x_*` whose coordinate
//!   has ≥ 2 values (axsdb's `interp_dataarray` is linear in every dimension); multilinear over
//!   all of them together.
//! * A `x_*` coordinate of a single value means the table was computed at that fixed mole
//!   fraction: the caller's value is not used (axsdb's `scalar` rule; e.g. x_O2 = 0.209476 in
//!   `nanomono_v1`). Species that the table does not list are ignored (the table has no
//!   dependence on them). A listed species with no value in the state is an error
//!   ([`AbsorptionError::MissingSpecies`]); give 0 to exclude it.
//! * CKD: the bin is selected (axsdb takes the nearest `w`), then **linear in g** between the
//!   file's g nodes. Monochromatic: linear in the file's spectral coordinate `w`.
//! * At a grid node the stored value is returned exactly (only one corner gets weight 1).
//!
//! ## Validity ranges and out-of-range states
//! The tables cover only their grids: `nanockd_v1` p ∈ [100, 105 000] Pa (16 nodes, geometric),
//! T ∈ [200, 340] K (8 nodes), x_H2O ∈ [0, 1], x_CO2 ∈ [0, 5e-4], x_O3 ∈ [0, 1e-5], 295–405 nm;
//! `nanomono_v1` p ∈ [0.3, 102 000] Pa, T ∈ [180, 300] K, x_CO2 ∈ [0, 4e-4], 345–355 nm. For the
//! US-standard profile, p < 100 Pa above ≈ 48 km. Per coordinate class (p, T, mole fractions) a
//! [`BoundsPolicy`] chooses [`OutOfRange::Error`] (the default: an error naming the coordinate,
//! the value and the range), [`OutOfRange::Clamp`] (the edge value of the grid) or
//! [`OutOfRange::Zero`] (absorption coefficient 0: axsdb's default for p and T, justified there by
//! the negligible absorption at the altitudes where it happens). Clamping or zero-filling logs one
//! `tracing::warn!` per coordinate and database. Note that clamping p keeps the number density
//! of the edge node (the coefficient is per volume), so below the lowest pressure it
//! *overestimates* absorption, by about p_min / p; `Zero` underestimates it (for the O₃ column
//! at 345–355 nm the two differ by 1.8 %). The spectral coordinates (bin, g ∈ [g_min, g_max],
//! monochromatic wavelength) are never clamped. The files store coordinates as float32
//! (x_O3 = 1e-5 is 9.99999975e-6), so a value within a relative 2.5e-7 of a grid edge counts as
//! the edge. Non-finite inputs are always errors; stored values must be finite (checked
//! on load; negative stored values are set to 0 with a warning), so no NaN or negative
//! coefficient is returned.
//!
//! ## What the sample databases contain (found while testing)
//! * `nanockd_v1` tables differ per bin: O₃ only for 295–365 nm, CO₂ + H₂O + O₃ for 365–395 nm,
//!   H₂O only for 395–405 nm. At x_O3 = 0 the 345–355 nm bin is exactly 0. The files
//!   375–385 and 385–395 nm hold 160 and 480 small negative values (down to −2.4e-4 km⁻¹,
//!   e.g. at x = 0, x_O3 = 1e-5, p = 100 Pa, T = 320 K, g = 0): artefacts, set to 0 on load.
//! * `nanomono_v1` (345–355 nm, 8165 points) has **no O₃**: only CO₂ (0, 4e-4) and the fixed
//!   O₂, CH₄, H₂, O, whose absorption there is < 3e-16 m⁻¹ (column τ ~ 1e-12). It cannot
//!   reproduce the CKD bin's O₃ absorption; see the consistency test for what is compared.
//!
//! ## Gauss–Legendre quadrature of g
//! [`gauss_legendre`] computes n-point nodes and weights on [−1, 1] (Newton iteration on the
//! Legendre recurrence), [`gauss_legendre_unit`] maps them to g ∈ [0, 1] (weights summing to 1).
//! The band-mean transmittance of a column is then Σᵢ wᵢ exp(−τ(gᵢ)), τ(g) from
//! [`AxsDatabase::absorption_coefficient`] at `SpectralPoint::Ckd { bin, g: gᵢ }` (linear in g
//! between the file's nodes).
//!
//! Reference: eradiate/axsdb 0.1 (Rayference, LGPL-3.0), <https://github.com/eradiate/axsdb> —
//! semantics read from its documentation and source (`core.py`, `error.py`,
//! `interpolation.py`); no code is copied. CKD method: Fu & Liou (1992), J. Atmos. Sci. 49,
//! 2139–2156.

use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use super::{
    is_dimensionless, is_kelvin, metre_factor, open_nc, pascal_factor, per_metre_factor, read_f64,
    units_of, variable, AbsorptionError, Result,
};

/// Most interpolated axes a table may have (species + p + T + spectral).
const MAX_AXES: usize = 16;

/// Relative tolerance at a grid's edges: the files store coordinates as float32 (x_O3 = 1e-5 is
/// stored as 9.99999975e-6), so a value within a few float32 roundings of an edge is at the edge.
const EDGE_TOLERANCE: f64 = 2.5e-7;

/// Monochromatic or correlated-k database.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DatabaseKind {
    Ckd,
    Mono,
}

impl DatabaseKind {
    fn name(self) -> &'static str {
        match self {
            DatabaseKind::Ckd => "CKD",
            DatabaseKind::Mono => "monochromatic",
        }
    }
}

/// What to do with a state outside a table's grid (`atmosphere.absorption_bounds` values:
/// `"error"`, `"clamp"`, `"zero"`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OutOfRange {
    /// Return [`AbsorptionError::OutOfRange`] (coordinate, value, range).
    #[default]
    Error,
    /// Use the grid's edge value (warns once per coordinate).
    Clamp,
    /// Absorption coefficient 0 (axsdb's default for p and T; warns once per coordinate).
    Zero,
}

/// One [`OutOfRange`] per coordinate class.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BoundsPolicy {
    pub pressure: OutOfRange,
    pub temperature: OutOfRange,
    pub mole_fraction: OutOfRange,
}

impl From<OutOfRange> for BoundsPolicy {
    fn from(o: OutOfRange) -> Self {
        BoundsPolicy {
            pressure: o,
            temperature: o,
            mole_fraction: o,
        }
    }
}

/// A thermodynamic state. Mole fractions are named by species (`"O3"`; `"x_O3"` is accepted
/// too). No number density: the tables are per volume at n = p / k_B T (see the module header).
#[derive(Clone, Copy, Debug)]
pub struct ThermoState<'a> {
    pub pressure_pa: f64,
    pub temperature_k: f64,
    pub mole_fractions: &'a [(&'a str, f64)],
}

impl ThermoState<'_> {
    fn mole_fraction(&self, species: &str) -> Option<f64> {
        self.mole_fractions
            .iter()
            .find(|(n, _)| n.strip_prefix("x_").unwrap_or(n) == species)
            .map(|&(_, x)| x)
    }
}

/// Where in the spectrum: a CKD bin (index into [`AxsDatabase::bins`]) and quantile g ∈ [0, 1],
/// or a monochromatic wavelength.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SpectralPoint {
    Ckd { bin: usize, g: f64 },
    Mono { wavelength_nm: f64 },
}

/// A CKD bin.
#[derive(Clone, Debug, PartialEq)]
pub struct CkdBin {
    /// File holding the bin.
    pub file: String,
    /// Bounds from `wbounds` / `spectral.csv` \[nm\].
    pub lower_nm: f64,
    pub upper_nm: f64,
    /// The bin's `w` coordinate \[nm\] (its representative wavelength; not always the midpoint,
    /// e.g. 349.9286 nm for 345–355 nm).
    pub wavelength_nm: f64,
    file_index: usize,
}

impl CkdBin {
    /// (lower + upper) / 2 \[nm\].
    pub fn centre_nm(&self) -> f64 {
        0.5 * (self.lower_nm + self.upper_nm)
    }
}

/// A row of `index.csv`.
#[derive(Clone, Debug, PartialEq)]
pub struct DataFile {
    pub name: String,
    pub wl_min_nm: f64,
    pub wl_max_nm: f64,
}

// ---- Gauss–Legendre ----------------------------------------------------------------------------

/// n-point Gauss–Legendre nodes and weights on [−1, 1], nodes ascending (empty for n = 0).
pub fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    let mut out = vec![(0.0, 0.0); n];
    let nf = n as f64;
    for i in 0..n.div_ceil(2) {
        // Initial guess (Tricomi): the i-th root counted from +1.
        let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (nf + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (mut p_prev, mut p) = (1.0, x);
            for k in 2..=n {
                let kf = k as f64;
                let p_next = ((2.0 * kf - 1.0) * x * p - (kf - 1.0) * p_prev) / kf;
                p_prev = p;
                p = p_next;
            }
            // P_n(x) = p, P_{n-1}(x) = p_prev; P_n' from the derivative identity.
            dp = nf * (x * p - p_prev) / (x * x - 1.0);
            let dx = p / dp;
            x -= dx;
            if dx.abs() <= 1e-16 * x.abs().max(1.0) {
                break;
            }
        }
        if n % 2 == 1 && i == n / 2 {
            x = 0.0;
        }
        // Weight from the derivative at the converged root.
        let (mut p_prev, mut p) = (1.0, x);
        for k in 2..=n {
            let kf = k as f64;
            let p_next = ((2.0 * kf - 1.0) * x * p - (kf - 1.0) * p_prev) / kf;
            p_prev = p;
            p = p_next;
        }
        if n > 0 {
            dp = nf * (x * p - p_prev) / (x * x - 1.0);
        }
        let w = 2.0 / ((1.0 - x * x) * dp * dp);
        out[n - 1 - i] = (x, w);
        out[i] = (-x, w);
    }
    out
}

/// n-point Gauss–Legendre rule on g ∈ [0, 1]: (g, weight) ascending in g, weights summing to 1.
pub fn gauss_legendre_unit(n: usize) -> Vec<(f64, f64)> {
    gauss_legendre(n)
        .into_iter()
        .map(|(x, w)| (0.5 * (x + 1.0), 0.5 * w))
        .collect()
}

// ---- axes and interpolation --------------------------------------------------------------------

/// One dimension of `sigma_a`: its nodes (ascending, in SI / nm / file spectral units), whether
/// the file stores them descending, and the stride of the dimension in the flat data.
#[derive(Clone, Debug)]
struct Axis {
    name: String,
    nodes: Vec<f64>,
    reversed: bool,
    stride: usize,
}

impl Axis {
    fn new(path: &str, name: &str, mut values: Vec<f64>, stride: usize) -> Result<Axis> {
        let bad = |message: String| AbsorptionError::Format {
            path: path.to_string(),
            variable: name.to_string(),
            message,
        };
        if let Some(v) = values.iter().find(|v| !v.is_finite()) {
            return Err(bad(format!("coordinate holds the non-finite value {v}")));
        }
        let reversed = values.len() > 1 && values[0] > values[1];
        if reversed {
            values.reverse();
        }
        if values.windows(2).any(|w| w[1] <= w[0]) {
            return Err(bad("coordinate values are not strictly monotonic".into()));
        }
        Ok(Axis {
            name: name.to_string(),
            nodes: values,
            reversed,
            stride,
        })
    }

    /// The species of a mole-fraction axis (`x_O3` → `O3`).
    fn species(&self) -> &str {
        self.name.strip_prefix("x_").unwrap_or(&self.name)
    }

    /// Index in the file of the i-th ascending node.
    fn file_index(&self, i: usize) -> usize {
        if self.reversed {
            self.nodes.len() - 1 - i
        } else {
            i
        }
    }

    fn min(&self) -> f64 {
        self.nodes[0]
    }

    fn max(&self) -> f64 {
        self.nodes[self.nodes.len() - 1]
    }
}

enum Located {
    /// Between ascending nodes i and i+1 with fraction f ∈ [0, 1) (f = 0: exactly node i).
    At(usize, f64),
    Below,
    Above,
    NotFinite,
}

fn locate(nodes: &[f64], v: f64) -> Located {
    if !v.is_finite() {
        return Located::NotFinite;
    }
    let n = nodes.len();
    if v < nodes[0] {
        return if v >= nodes[0] - EDGE_TOLERANCE * nodes[0].abs() {
            Located::At(0, 0.0)
        } else {
            Located::Below
        };
    }
    if v > nodes[n - 1] {
        return if v <= nodes[n - 1] + EDGE_TOLERANCE * nodes[n - 1].abs() {
            Located::At(n - 1, 0.0)
        } else {
            Located::Above
        };
    }
    let i = nodes.partition_point(|&x| x <= v) - 1; // nodes[i] <= v
    if i >= n - 1 {
        return Located::At(n - 1, 0.0);
    }
    let f = (v - nodes[i]) / (nodes[i + 1] - nodes[i]);
    Located::At(i, f)
}

/// Multilinear weights being assembled: a base offset and the active (f > 0) axes.
struct Corners {
    base: isize,
    steps: [(isize, f64); MAX_AXES],
    n: usize,
}

impl Corners {
    fn new() -> Self {
        Corners {
            base: 0,
            steps: [(0, 0.0); MAX_AXES],
            n: 0,
        }
    }

    /// Add axis `a` at ascending node `i` with fraction `f` towards node i+1.
    fn push(&mut self, a: &Axis, i: usize, f: f64) {
        self.base += (a.file_index(i) * a.stride) as isize;
        if f > 0.0 {
            let s = a.stride as isize;
            self.steps[self.n] = (if a.reversed { -s } else { s }, f);
            self.n += 1;
        }
    }

    fn eval(&self, data: &[f64]) -> f64 {
        let mut sum = 0.0;
        for mask in 0..(1usize << self.n) {
            let mut off = self.base;
            let mut w = 1.0;
            for (j, &(step, f)) in self.steps[..self.n].iter().enumerate() {
                if mask & (1 << j) != 0 {
                    off += step;
                    w *= f;
                } else {
                    w *= 1.0 - f;
                }
            }
            sum += w * data[off as usize];
        }
        sum
    }
}

/// Units of the spectral coordinate `w` of a file.
#[derive(Clone, Copy, Debug)]
enum WUnits {
    /// A wavelength; factor to nm.
    Wavelength(f64),
    /// A wavenumber; factor to m⁻¹.
    Wavenumber(f64),
}

impl WUnits {
    fn parse(units: &str) -> Option<WUnits> {
        if let Some(f) = metre_factor(units) {
            Some(WUnits::Wavelength(f * 1e9))
        } else {
            per_metre_factor(units).map(WUnits::Wavenumber)
        }
    }

    fn file_to_nm(self, w: f64) -> f64 {
        match self {
            WUnits::Wavelength(f) => w * f,
            WUnits::Wavenumber(f) => 1e9 / (w * f),
        }
    }

    fn nm_to_file(self, nm: f64) -> f64 {
        match self {
            WUnits::Wavelength(f) => nm / f,
            WUnits::Wavenumber(f) => 1e9 / nm / f,
        }
    }
}

// ---- one file ----------------------------------------------------------------------------------

/// The `sigma_a` table of one database file, in m⁻¹, with its grids.
#[derive(Debug)]
pub struct AbsorptionTable {
    path: String,
    kind: DatabaseKind,
    species: Vec<Axis>,
    fixed_species: Vec<(String, f64)>,
    p: Axis,
    t: Axis,
    w: Axis,
    w_units: WUnits,
    g: Option<Axis>,
    data: Vec<f64>,
    /// Per file `w` index: bin bounds [nm] (CKD).
    wbounds_nm: Vec<(f64, f64)>,
    /// `ng` values and `error(w, ng)` per file `w` index (CKD, when present).
    error: Option<(Vec<usize>, Vec<Vec<f64>>)>,
    warned: Arc<Mutex<HashSet<String>>>,
    /// Negative stored values, set to 0 on load.
    negatives_zeroed: usize,
}

/// The axes of a file's `sigma_a`, read from its dimensions and coordinates.
struct Axes {
    kind: DatabaseKind,
    species: Vec<Axis>,
    fixed_species: Vec<(String, f64)>,
    p: Axis,
    t: Axis,
    w: Axis,
    w_units: WUnits,
    g: Option<Axis>,
}

/// The CKD quadrature error table: the `ng` values and, per file `w` index, the error at each.
type ErrorTable = (Vec<usize>, Vec<Vec<f64>>);

/// An open database file with the readers of its variables (errors name the file).
struct TableFile<'f> {
    file: &'f netcdf::File,
    ps: &'f str,
}

impl TableFile<'_> {
    /// A format error naming the file and `variable`.
    fn fmt(&self, variable: &str, message: String) -> AbsorptionError {
        AbsorptionError::Format {
            path: self.ps.to_string(),
            variable: variable.to_string(),
            message,
        }
    }

    /// The values of a coordinate variable.
    fn coord(&self, name: &str) -> Result<Vec<f64>> {
        read_f64(&variable(self.file, self.ps, name)?, self.ps)
    }

    /// The `units` attribute of a variable (required).
    fn units(&self, name: &str) -> Result<String> {
        units_of(&variable(self.file, self.ps, name)?).ok_or_else(|| AbsorptionError::Missing {
            path: self.ps.to_string(),
            what: "attribute",
            name: format!("{name}:units"),
        })
    }

    /// A units error: `name` has units `u`, `expected` others.
    fn wrong_units(&self, name: &str, u: String, expected: &'static str) -> AbsorptionError {
        AbsorptionError::Units {
            path: self.ps.to_string(),
            variable: name.to_string(),
            units: u,
            expected,
        }
    }

    /// The axes of `sigma_a` (species, p, T, spectral, g) from its dimensions, in SI units.
    fn axes(&self, sig: &netcdf::Variable<'_>) -> Result<Axes> {
        let ps = self.ps;
        let dims: Vec<(String, usize)> = sig
            .dimensions()
            .iter()
            .map(|d| (d.name(), d.len()))
            .collect();
        if dims.len() > MAX_AXES {
            return Err(self.fmt(
                "sigma_a",
                format!("{} dimensions, at most {MAX_AXES} supported", dims.len()),
            ));
        }
        let mut strides = vec![1usize; dims.len()];
        for i in (0..dims.len().saturating_sub(1)).rev() {
            strides[i] = strides[i + 1] * dims[i + 1].1;
        }

        let (mut species, mut fixed_species) = (Vec::new(), Vec::new());
        let (mut p, mut t, mut w, mut g) = (None, None, None, None);
        let mut w_units = WUnits::Wavelength(1.0);
        for (k, (name, len)) in dims.iter().enumerate() {
            let values = self.coord(name)?;
            if values.len() != *len {
                return Err(self.fmt(
                    name,
                    format!("{} values for a dimension of {len}", values.len()),
                ));
            }
            match name.as_str() {
                "p" => {
                    let u = self.units("p")?;
                    let f = pascal_factor(&u)
                        .ok_or_else(|| self.wrong_units("p", u, "a pressure (Pa)"))?;
                    p = Some(Axis::new(
                        ps,
                        "p",
                        values.iter().map(|v| v * f).collect(),
                        strides[k],
                    )?);
                }
                "t" => {
                    let u = self.units("t")?;
                    if !is_kelvin(&u) {
                        return Err(self.wrong_units("t", u, "K"));
                    }
                    t = Some(Axis::new(ps, "t", values, strides[k])?);
                }
                "w" => {
                    let u = self.units("w")?;
                    w_units = WUnits::parse(&u).ok_or_else(|| {
                        self.wrong_units("w", u, "a wavelength (nm) or wavenumber (cm^-1)")
                    })?;
                    w = Some(Axis::new(ps, "w", values, strides[k])?);
                }
                "g" => {
                    g = Some(Axis::new(ps, "g", values, strides[k])?);
                }
                x if x.starts_with("x_") => {
                    if let Ok(u) = self.units(x) {
                        if !is_dimensionless(&u) {
                            return Err(self.wrong_units(x, u, "a dimensionless mole fraction"));
                        }
                    }
                    let sp = x["x_".len()..].to_string();
                    if values.len() == 1 {
                        fixed_species.push((sp, values[0]));
                    } else {
                        species.push(Axis::new(ps, x, values, strides[k])?);
                    }
                }
                other => {
                    return Err(self.fmt(
                        "sigma_a",
                        format!("unknown dimension `{other}` (expected x_*, p, t, w, g)"),
                    ))
                }
            }
        }
        let need = |a: Option<Axis>, name: &str| {
            a.ok_or_else(|| AbsorptionError::Missing {
                path: ps.to_string(),
                what: "dimension of sigma_a",
                name: name.to_string(),
            })
        };
        let (p, t, w) = (need(p, "p")?, need(t, "t")?, need(w, "w")?);
        for a in [&p, &t] {
            if a.nodes.len() < 2 {
                return Err(self.fmt(&a.name, "needs at least 2 nodes to interpolate".into()));
            }
        }
        let kind = if g.is_some() {
            DatabaseKind::Ckd
        } else {
            DatabaseKind::Mono
        };
        Ok(Axes {
            kind,
            species,
            fixed_species,
            p,
            t,
            w,
            w_units,
            g,
        })
    }

    /// The `sigma_a` data in m⁻¹ (negative values set to 0, with a warning) and how many were
    /// negative.
    fn sigma_a(&self, sig: &netcdf::Variable<'_>) -> Result<(Vec<f64>, usize)> {
        let ps = self.ps;
        let u = units_of(sig).ok_or_else(|| AbsorptionError::Missing {
            path: ps.to_string(),
            what: "attribute",
            name: "sigma_a:units".into(),
        })?;
        let factor = per_metre_factor(&u).ok_or_else(|| {
            self.wrong_units("sigma_a", u, "an absorption coefficient (km^-1 or m^-1)")
        })?;
        let mut data = read_f64(sig, ps)?;
        let (mut negatives, mut most_negative) = (0usize, 0.0f64);
        for (index, v) in data.iter_mut().enumerate() {
            if !v.is_finite() {
                return Err(AbsorptionError::BadValue {
                    path: ps.to_string(),
                    variable: "sigma_a".into(),
                    value: *v,
                    index,
                });
            }
            if *v < 0.0 {
                negatives += 1;
                most_negative = most_negative.min(*v);
                *v = 0.0;
            }
            *v *= factor;
        }
        if negatives > 0 {
            tracing::warn!(
                "{ps}: {negatives} negative `sigma_a` values (down to {most_negative:e} in the \
                 file's units) set to 0"
            );
        }
        Ok((data, negatives))
    }

    /// The CKD bin bounds [nm] per `w` index (`wbounds`, in its own units or those of `w`).
    fn wbounds(&self, nw: usize, w_units: WUnits) -> Result<Vec<(f64, f64)>> {
        let wb = variable(self.file, self.ps, "wbounds")?;
        let wb_dims: Vec<String> = wb.dimensions().iter().map(|d| d.name()).collect();
        let vals = read_f64(&wb, self.ps)?;
        if vals.len() != 2 * nw {
            return Err(self.fmt(
                "wbounds",
                format!("{} values, expected 2 × {nw}", vals.len()),
            ));
        }
        let wbu = units_of(&wb)
            .map(|u| WUnits::parse(&u))
            .unwrap_or(Some(w_units));
        let wbu = wbu.ok_or_else(|| self.fmt("wbounds", "unknown units".into()))?;
        let w_first = wb_dims.first().map(|d| d == "w").unwrap_or(false);
        let mut wbounds_nm = Vec::new();
        for j in 0..nw {
            let (a, b) = if w_first {
                (vals[2 * j], vals[2 * j + 1])
            } else {
                (vals[j], vals[nw + j])
            };
            let (a, b) = (wbu.file_to_nm(a), wbu.file_to_nm(b));
            if !a.is_finite() || !b.is_finite() {
                return Err(self.fmt("wbounds", format!("non-finite bound at w index {j}")));
            }
            wbounds_nm.push((a.min(b), a.max(b)));
        }
        Ok(wbounds_nm)
    }

    /// The CKD quadrature error table (`ng` values and `error(w, ng)` per `w` index), when the
    /// file has one.
    fn error_table(&self, nw: usize) -> Result<Option<ErrorTable>> {
        let (Some(ev), Some(ngv)) = (self.file.variable("error"), self.file.variable("ng")) else {
            return Ok(None);
        };
        let ng: Vec<usize> = ngv
            .get_values::<i64, _>(..)
            .map_err(|source| AbsorptionError::Netcdf {
                path: self.ps.to_string(),
                variable: "ng".into(),
                source,
            })?
            .into_iter()
            .map(|v| v.max(0) as usize)
            .collect();
        let e_dims: Vec<String> = ev.dimensions().iter().map(|d| d.name()).collect();
        let e = read_f64(&ev, self.ps)?;
        if e.len() != nw * ng.len() {
            return Err(self.fmt(
                "error",
                format!("{} values, expected {nw} × {}", e.len(), ng.len()),
            ));
        }
        let w_first = e_dims.first().map(|d| d == "w").unwrap_or(true);
        let per_w = (0..nw)
            .map(|j| {
                (0..ng.len())
                    .map(|k| {
                        if w_first {
                            e[j * ng.len() + k]
                        } else {
                            e[k * nw + j]
                        }
                    })
                    .collect()
            })
            .collect();
        Ok(Some((ng, per_w)))
    }
}

impl AbsorptionTable {
    /// Load one axsdb netCDF file (both kinds).
    pub fn open(path: &Path) -> Result<AbsorptionTable> {
        Self::open_with(path, Arc::new(Mutex::new(HashSet::new())))
    }

    fn open_with(path: &Path, warned: Arc<Mutex<HashSet<String>>>) -> Result<AbsorptionTable> {
        let _session = crate::netcdf_session();
        let ps = path.display().to_string();
        let file = open_nc(path)?;
        let r = TableFile {
            file: &file,
            ps: &ps,
        };
        let sig = variable(&file, &ps, "sigma_a")?;
        let axes = r.axes(&sig)?;
        let (data, negatives) = r.sigma_a(&sig)?;

        // CKD extras: bin bounds and the quadrature error table.
        let nw = axes.w.nodes.len();
        let mut wbounds_nm = Vec::new();
        let mut error = None;
        if axes.kind == DatabaseKind::Ckd {
            wbounds_nm = r.wbounds(nw, axes.w_units)?;
            error = r.error_table(nw)?;
        }
        Ok(AbsorptionTable {
            path: ps,
            kind: axes.kind,
            species: axes.species,
            fixed_species: axes.fixed_species,
            p: axes.p,
            t: axes.t,
            w: axes.w,
            w_units: axes.w_units,
            g: axes.g,
            data,
            wbounds_nm,
            error,
            warned,
            negatives_zeroed: negatives,
        })
    }

    /// How many negative `sigma_a` values the file held (set to 0 on load, with a warning; e.g.
    /// 160 in `nanockd_v1-375_385.nc`, down to −2.4e-4 km⁻¹).
    pub fn negatives_zeroed(&self) -> usize {
        self.negatives_zeroed
    }

    /// The file.
    pub fn path(&self) -> &str {
        &self.path
    }

    pub fn kind(&self) -> DatabaseKind {
        self.kind
    }

    /// Species whose mole fraction is interpolated, with their grids (ascending).
    pub fn species(&self) -> impl Iterator<Item = (&str, &[f64])> {
        self.species
            .iter()
            .map(|a| (a.species(), a.nodes.as_slice()))
    }

    /// Species at a fixed mole fraction (single-valued coordinates; the caller's value is not
    /// used).
    pub fn fixed_species(&self) -> &[(String, f64)] {
        &self.fixed_species
    }

    /// Pressure nodes \[Pa\], ascending.
    pub fn pressure_grid_pa(&self) -> &[f64] {
        &self.p.nodes
    }

    /// Temperature nodes \[K\], ascending.
    pub fn temperature_grid_k(&self) -> &[f64] {
        &self.t.nodes
    }

    /// g nodes (CKD), ascending.
    pub fn g_grid(&self) -> Option<&[f64]> {
        self.g.as_ref().map(|a| a.nodes.as_slice())
    }

    /// The spectral coordinate in nm, in file order of `w` index.
    pub fn wavelengths_nm(&self) -> Vec<f64> {
        // The file index of ascending node i is `file_index(i)`, an involution.
        (0..self.w.nodes.len())
            .map(|fi| self.w_units.file_to_nm(self.w.nodes[self.w.file_index(fi)]))
            .collect()
    }

    /// The file `w` index whose wavelength is nearest to `wavelength_nm` (axsdb's bin choice).
    pub fn w_index_nearest(&self, wavelength_nm: f64) -> usize {
        let wl = self.wavelengths_nm();
        let mut best = 0;
        for (i, &x) in wl.iter().enumerate() {
            if (x - wavelength_nm).abs() < (wl[best] - wavelength_nm).abs() {
                best = i;
            }
        }
        best
    }

    /// Bin bounds \[nm\] of file `w` index `w_index` (CKD).
    pub fn bin_bounds_nm(&self, w_index: usize) -> Option<(f64, f64)> {
        self.wbounds_nm.get(w_index).copied()
    }

    /// `(ng, relative error)` pairs of `error(w, ng)` for file `w` index `w_index` (CKD, when the
    /// file has them).
    pub fn quadrature_error(&self, w_index: usize) -> Option<Vec<(usize, f64)>> {
        let (ng, e) = self.error.as_ref()?;
        let row = e.get(w_index)?;
        Some(ng.iter().copied().zip(row.iter().copied()).collect())
    }

    fn out_of_range(&self, coordinate: &str, value: f64, a: &Axis) -> AbsorptionError {
        AbsorptionError::OutOfRange {
            path: self.path.clone(),
            coordinate: coordinate.to_string(),
            value,
            min: a.min(),
            max: a.max(),
        }
    }

    fn warn_once(&self, coordinate: &str, value: f64, a: &Axis, policy: OutOfRange) {
        let mut set = self.warned.lock().unwrap_or_else(|e| e.into_inner());
        if set.insert(coordinate.to_string()) {
            tracing::warn!(
                "{}: coordinate `{coordinate}` = {value} outside [{}, {}]: {} (warned once per \
                 coordinate)",
                self.path,
                a.min(),
                a.max(),
                match policy {
                    OutOfRange::Clamp => "clamped to the grid's edge",
                    _ => "absorption coefficient set to 0",
                }
            );
        }
    }

    /// (i, f) on `a` for `value` under `policy`; `None` means "absorption coefficient 0".
    fn resolve(
        &self,
        coordinate: &str,
        a: &Axis,
        value: f64,
        policy: OutOfRange,
    ) -> Result<Option<(usize, f64)>> {
        match locate(&a.nodes, value) {
            Located::At(i, f) => Ok(Some((i, f))),
            Located::NotFinite => Err(self.out_of_range(coordinate, value, a)),
            side => match policy {
                OutOfRange::Error => Err(self.out_of_range(coordinate, value, a)),
                OutOfRange::Clamp => {
                    self.warn_once(coordinate, value, a, policy);
                    let i = if matches!(side, Located::Below) {
                        0
                    } else {
                        a.nodes.len() - 1
                    };
                    Ok(Some((i, 0.0)))
                }
                OutOfRange::Zero => {
                    self.warn_once(coordinate, value, a, policy);
                    Ok(None)
                }
            },
        }
    }

    /// The thermodynamic part of the interpolation; `None` when a Zero policy applies.
    fn thermo_corners(
        &self,
        state: &ThermoState<'_>,
        bounds: BoundsPolicy,
    ) -> Result<Option<Corners>> {
        let mut c = Corners::new();
        let mut zero = false;
        for a in &self.species {
            let x = state.mole_fraction(a.species()).ok_or_else(|| {
                AbsorptionError::MissingSpecies {
                    path: self.path.clone(),
                    species: a.species().to_string(),
                }
            })?;
            match self.resolve(&a.name, a, x, bounds.mole_fraction)? {
                Some((i, f)) => c.push(a, i, f),
                None => zero = true,
            }
        }
        match self.resolve("p", &self.p, state.pressure_pa, bounds.pressure)? {
            Some((i, f)) => c.push(&self.p, i, f),
            None => zero = true,
        }
        match self.resolve("t", &self.t, state.temperature_k, bounds.temperature)? {
            Some((i, f)) => c.push(&self.t, i, f),
            None => zero = true,
        }
        Ok(if zero { None } else { Some(c) })
    }

    /// Absorption coefficient [m⁻¹] of the CKD bin at file `w` index `w_index`, quantile `g`.
    pub fn absorption_coefficient_ckd(
        &self,
        state: &ThermoState<'_>,
        w_index: usize,
        g: f64,
        bounds: BoundsPolicy,
    ) -> Result<f64> {
        let ga = self.g.as_ref().ok_or(AbsorptionError::WrongKind {
            path: self.path.clone(),
            operation: "absorption_coefficient_ckd",
            expected: "CKD",
            actual: self.kind.name(),
        })?;
        if w_index >= self.w.nodes.len() {
            return Err(AbsorptionError::NoSuchBin {
                path: self.path.clone(),
                bin: format!("w index {w_index}"),
                count: self.w.nodes.len(),
            });
        }
        let (gi, gf) = match locate(&ga.nodes, g) {
            Located::At(i, f) => (i, f),
            _ => return Err(self.out_of_range("g", g, ga)),
        };
        let Some(mut c) = self.thermo_corners(state, bounds)? else {
            return Ok(0.0);
        };
        c.base += (w_index * self.w.stride) as isize;
        c.push(ga, gi, gf);
        Ok(c.eval(&self.data))
    }

    /// Absorption coefficient [m⁻¹] at `wavelength_nm` (monochromatic table; linear in `w`).
    pub fn absorption_coefficient_mono(
        &self,
        state: &ThermoState<'_>,
        wavelength_nm: f64,
        bounds: BoundsPolicy,
    ) -> Result<f64> {
        if self.kind != DatabaseKind::Mono {
            return Err(AbsorptionError::WrongKind {
                path: self.path.clone(),
                operation: "absorption_coefficient_mono",
                expected: "monochromatic",
                actual: self.kind.name(),
            });
        }
        let wv = self.w_units.nm_to_file(wavelength_nm);
        let (wi, wf) = match locate(&self.w.nodes, wv) {
            Located::At(i, f) => (i, f),
            _ => {
                let (a, b) = (
                    self.w_units.file_to_nm(self.w.min()),
                    self.w_units.file_to_nm(self.w.max()),
                );
                return Err(AbsorptionError::OutOfRange {
                    path: self.path.clone(),
                    coordinate: "w [nm]".into(),
                    value: wavelength_nm,
                    min: a.min(b),
                    max: a.max(b),
                });
            }
        };
        let Some(mut c) = self.thermo_corners(state, bounds)? else {
            return Ok(0.0);
        };
        c.push(&self.w, wi, wf);
        Ok(c.eval(&self.data))
    }
}

// ---- the database ------------------------------------------------------------------------------

/// An axsdb database directory; files are loaded on first use and kept.
#[derive(Debug)]
pub struct AxsDatabase {
    dir: PathBuf,
    kind: DatabaseKind,
    files: Vec<DataFile>,
    bins: Vec<CkdBin>,
    metadata: Option<serde_json::Value>,
    tables: Mutex<Vec<Option<Arc<AbsorptionTable>>>>,
    warned: Arc<Mutex<HashSet<String>>>,
}

/// Rows of a small CSV file with a header: (header, rows of fields).
fn read_csv(path: &Path) -> Result<(Vec<String>, Vec<Vec<String>>)> {
    let text = std::fs::read_to_string(path).map_err(|source| AbsorptionError::Io {
        path: path.display().to_string(),
        source,
    })?;
    let mut lines = text.lines().filter(|l| !l.trim().is_empty());
    let header = lines
        .next()
        .map(|h| h.split(',').map(|s| s.trim().to_string()).collect())
        .unwrap_or_default();
    let rows = lines
        .map(|l| l.split(',').map(|s| s.trim().to_string()).collect())
        .collect();
    Ok((header, rows))
}

fn column(path: &Path, header: &[String], name: &str) -> Result<usize> {
    header
        .iter()
        .position(|h| h == name)
        .ok_or_else(|| AbsorptionError::Missing {
            path: path.display().to_string(),
            what: "column",
            name: name.to_string(),
        })
}

fn parse_field(path: &Path, col: &str, row: usize, s: &str) -> Result<f64> {
    s.parse::<f64>().map_err(|_| AbsorptionError::Format {
        path: path.display().to_string(),
        variable: col.to_string(),
        message: format!("row {}: `{s}` is not a number", row + 2),
    })
}

impl AxsDatabase {
    /// Open a database directory: reads `index.csv`, `spectral.csv` (CKD bins) and
    /// `metadata.json`, and the header of the first file to tell the kind. No table is loaded.
    pub fn open(dir: impl AsRef<Path>) -> Result<AxsDatabase> {
        let dir = dir.as_ref().to_path_buf();
        let index_path = dir.join("index.csv");
        if !index_path.is_file() {
            return Err(AbsorptionError::Missing {
                path: dir.display().to_string(),
                what: "file",
                name: "index.csv".into(),
            });
        }
        let (header, rows) = read_csv(&index_path)?;
        let (cf, c0, c1) = (
            column(&index_path, &header, "filename")?,
            column(&index_path, &header, "wl_min [nm]")?,
            column(&index_path, &header, "wl_max [nm]")?,
        );
        let mut files = Vec::new();
        for (r, row) in rows.iter().enumerate() {
            let get = |c: usize| row.get(c).map(String::as_str).unwrap_or("");
            let (a, b) = (
                parse_field(&index_path, "wl_min [nm]", r, get(c0))?,
                parse_field(&index_path, "wl_max [nm]", r, get(c1))?,
            );
            files.push(DataFile {
                name: get(cf).to_string(),
                wl_min_nm: a.min(b),
                wl_max_nm: a.max(b),
            });
        }
        if files.is_empty() {
            return Err(AbsorptionError::Format {
                path: index_path.display().to_string(),
                variable: "filename".into(),
                message: "the index lists no file".into(),
            });
        }
        files.sort_by(|a, b| a.wl_min_nm.total_cmp(&b.wl_min_nm));

        // Kind, from the first file's dimensions.
        let first = dir.join(&files[0].name);
        let kind = {
            let f = open_nc(&first)?;
            let has = |d: &str| f.dimension(d).is_some();
            if !has("w") {
                return Err(AbsorptionError::Missing {
                    path: first.display().to_string(),
                    what: "dimension",
                    name: "w".into(),
                });
            }
            if has("g") {
                DatabaseKind::Ckd
            } else {
                DatabaseKind::Mono
            }
        };

        let metadata = match std::fs::read_to_string(dir.join("metadata.json")) {
            Ok(s) => Some(
                serde_json::from_str(&s).map_err(|e| AbsorptionError::Format {
                    path: dir.join("metadata.json").display().to_string(),
                    variable: "(json)".into(),
                    message: e.to_string(),
                })?,
            ),
            Err(_) => None,
        };

        let warned = Arc::new(Mutex::new(HashSet::new()));
        let mut bins = Vec::new();
        if kind == DatabaseKind::Ckd {
            let file_index = |name: &str, at: &Path| {
                files
                    .iter()
                    .position(|f| f.name == name)
                    .ok_or_else(|| AbsorptionError::Format {
                        path: at.display().to_string(),
                        variable: "filename".into(),
                        message: format!("`{name}` is not in index.csv"),
                    })
            };
            let spectral = dir.join("spectral.csv");
            if spectral.is_file() {
                let (h, rows) = read_csv(&spectral)?;
                let (cf, cw, cl, cu) = (
                    column(&spectral, &h, "filename")?,
                    column(&spectral, &h, "wavelength [nm]")?,
                    column(&spectral, &h, "wbound_lower [nm]")?,
                    column(&spectral, &h, "wbound_upper [nm]")?,
                );
                for (r, row) in rows.iter().enumerate() {
                    let get = |c: usize| row.get(c).map(String::as_str).unwrap_or("");
                    let (lo, up) = (
                        parse_field(&spectral, "wbound_lower [nm]", r, get(cl))?,
                        parse_field(&spectral, "wbound_upper [nm]", r, get(cu))?,
                    );
                    bins.push(CkdBin {
                        file: get(cf).to_string(),
                        lower_nm: lo.min(up),
                        upper_nm: lo.max(up),
                        wavelength_nm: parse_field(&spectral, "wavelength [nm]", r, get(cw))?,
                        file_index: file_index(get(cf), &spectral)?,
                    });
                }
            } else {
                for (i, f) in files.iter().enumerate() {
                    let t = AbsorptionTable::open_with(&dir.join(&f.name), warned.clone())?;
                    for (j, wl) in t.wavelengths_nm().into_iter().enumerate() {
                        let (lo, up) = t.bin_bounds_nm(j).unwrap_or((wl, wl));
                        bins.push(CkdBin {
                            file: f.name.clone(),
                            lower_nm: lo,
                            upper_nm: up,
                            wavelength_nm: wl,
                            file_index: i,
                        });
                    }
                }
            }
            bins.sort_by(|a, b| a.wavelength_nm.total_cmp(&b.wavelength_nm));
        }
        let n = files.len();
        Ok(AxsDatabase {
            dir,
            kind,
            files,
            bins,
            metadata,
            tables: Mutex::new(vec![None; n]),
            warned,
        })
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }

    pub fn kind(&self) -> DatabaseKind {
        self.kind
    }

    /// `metadata.json`, when present.
    pub fn metadata(&self) -> Option<&serde_json::Value> {
        self.metadata.as_ref()
    }

    /// The files of `index.csv`, ascending in wavelength.
    pub fn files(&self) -> &[DataFile] {
        &self.files
    }

    /// Spectral range covered \[nm\].
    pub fn spectral_range_nm(&self) -> (f64, f64) {
        let lo = self
            .files
            .iter()
            .map(|f| f.wl_min_nm)
            .fold(f64::INFINITY, f64::min);
        let hi = self
            .files
            .iter()
            .map(|f| f.wl_max_nm)
            .fold(f64::NEG_INFINITY, f64::max);
        (lo, hi)
    }

    /// CKD bins, ascending in wavelength (empty for a monochromatic database).
    pub fn bins(&self) -> &[CkdBin] {
        &self.bins
    }

    /// Index of the bin whose [lower, upper) holds `wavelength_nm` (the last bin includes its
    /// upper bound).
    pub fn bin_containing(&self, wavelength_nm: f64) -> Option<usize> {
        let n = self.bins.len();
        self.bins
            .iter()
            .position(|b| b.lower_nm <= wavelength_nm && wavelength_nm < b.upper_nm)
            .or_else(|| (n > 0 && wavelength_nm == self.bins[n - 1].upper_nm).then_some(n - 1))
    }

    fn table(&self, file_index: usize) -> Result<Arc<AbsorptionTable>> {
        let mut tables = self.tables.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(t) = &tables[file_index] {
            return Ok(t.clone());
        }
        let path = self.dir.join(&self.files[file_index].name);
        let t = Arc::new(AbsorptionTable::open_with(&path, self.warned.clone())?);
        tables[file_index] = Some(t.clone());
        Ok(t)
    }

    /// Load (once) every file overlapping [wmin_nm, wmax_nm]; returns them.
    pub fn load_range(&self, wmin_nm: f64, wmax_nm: f64) -> Result<Vec<Arc<AbsorptionTable>>> {
        (0..self.files.len())
            .filter(|&i| self.files[i].wl_max_nm >= wmin_nm && self.files[i].wl_min_nm <= wmax_nm)
            .map(|i| self.table(i))
            .collect()
    }

    fn bin(&self, bin: usize) -> Result<&CkdBin> {
        if self.kind != DatabaseKind::Ckd {
            return Err(AbsorptionError::WrongKind {
                path: self.dir.display().to_string(),
                operation: "bins",
                expected: "CKD",
                actual: self.kind.name(),
            });
        }
        self.bins
            .get(bin)
            .ok_or_else(|| AbsorptionError::NoSuchBin {
                path: self.dir.display().to_string(),
                bin: bin.to_string(),
                count: self.bins.len(),
            })
    }

    /// The table of a CKD bin and the bin's `w` index in it.
    pub fn table_for_bin(&self, bin: usize) -> Result<(Arc<AbsorptionTable>, usize)> {
        let b = self.bin(bin)?;
        let t = self.table(b.file_index)?;
        let j = t.w_index_nearest(b.wavelength_nm);
        Ok((t, j))
    }

    /// The table of a monochromatic database that covers `wavelength_nm`.
    pub fn table_for_wavelength(&self, wavelength_nm: f64) -> Result<Arc<AbsorptionTable>> {
        let (lo, hi) = self.spectral_range_nm();
        let i = self
            .files
            .iter()
            .position(|f| f.wl_min_nm <= wavelength_nm && wavelength_nm <= f.wl_max_nm)
            .ok_or_else(|| AbsorptionError::OutOfRange {
                path: self.dir.display().to_string(),
                coordinate: "w [nm]".into(),
                value: wavelength_nm,
                min: lo,
                max: hi,
            })?;
        self.table(i)
    }

    /// g nodes of a CKD bin's table.
    pub fn g_grid(&self, bin: usize) -> Result<Vec<f64>> {
        let (t, _) = self.table_for_bin(bin)?;
        Ok(t.g_grid().unwrap_or_default().to_vec())
    }

    /// `(ng, relative error)` of the bin's `error(w, ng)` variable, when the file has it.
    pub fn quadrature_error(&self, bin: usize) -> Result<Option<Vec<(usize, f64)>>> {
        let (t, j) = self.table_for_bin(bin)?;
        Ok(t.quadrature_error(j))
    }

    /// Gauss–Legendre rule of `n` points on g ∈ [0, 1] (see [`gauss_legendre_unit`]).
    pub fn g_quadrature(&self, n: usize) -> Vec<(f64, f64)> {
        gauss_legendre_unit(n)
    }

    /// Monochromatic spectral points \[nm\] in [wmin_nm, wmax_nm], ascending (loads the files).
    pub fn spectral_points(&self, wmin_nm: f64, wmax_nm: f64) -> Result<Vec<f64>> {
        if self.kind != DatabaseKind::Mono {
            return Err(AbsorptionError::WrongKind {
                path: self.dir.display().to_string(),
                operation: "spectral_points",
                expected: "monochromatic",
                actual: self.kind.name(),
            });
        }
        let mut out: Vec<f64> = self
            .load_range(wmin_nm, wmax_nm)?
            .iter()
            .flat_map(|t| t.wavelengths_nm())
            .filter(|&w| w >= wmin_nm && w <= wmax_nm)
            .collect();
        out.sort_by(f64::total_cmp);
        Ok(out)
    }

    /// Absorption coefficient [m⁻¹] of the state at a spectral point (loads the file if needed).
    pub fn absorption_coefficient(
        &self,
        state: &ThermoState<'_>,
        at: SpectralPoint,
        bounds: BoundsPolicy,
    ) -> Result<f64> {
        match (at, self.kind) {
            (SpectralPoint::Ckd { bin, g }, DatabaseKind::Ckd) => {
                let (t, j) = self.table_for_bin(bin)?;
                t.absorption_coefficient_ckd(state, j, g, bounds)
            }
            (SpectralPoint::Mono { wavelength_nm }, DatabaseKind::Mono) => self
                .table_for_wavelength(wavelength_nm)?
                .absorption_coefficient_mono(state, wavelength_nm, bounds),
            (_, kind) => Err(AbsorptionError::WrongKind {
                path: self.dir.display().to_string(),
                operation: "absorption_coefficient",
                expected: match at {
                    SpectralPoint::Ckd { .. } => "CKD",
                    SpectralPoint::Mono { .. } => "monochromatic",
                },
                actual: kind.name(),
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gauss_legendre_known_values() {
        let close = |a: f64, b: f64| (a - b).abs() < 1e-14;
        let r1 = gauss_legendre(1);
        assert!(close(r1[0].0, 0.0) && close(r1[0].1, 2.0));
        let r2 = gauss_legendre(2);
        let x = 1.0 / 3f64.sqrt();
        assert!(close(r2[0].0, -x) && close(r2[1].0, x), "{r2:?}");
        assert!(close(r2[0].1, 1.0) && close(r2[1].1, 1.0));
        let r3 = gauss_legendre(3);
        let x = (3.0f64 / 5.0).sqrt();
        assert!(
            close(r3[0].0, -x) && close(r3[1].0, 0.0) && close(r3[2].0, x),
            "{r3:?}"
        );
        assert!(
            close(r3[0].1, 5.0 / 9.0) && close(r3[1].1, 8.0 / 9.0) && close(r3[2].1, 5.0 / 9.0)
        );
        let r5 = gauss_legendre(5);
        let a = (5.0 - 2.0 * (10.0f64 / 7.0).sqrt()).sqrt() / 3.0;
        let b = (5.0 + 2.0 * (10.0f64 / 7.0).sqrt()).sqrt() / 3.0;
        let wa = (322.0 + 13.0 * 70f64.sqrt()) / 900.0;
        let wb = (322.0 - 13.0 * 70f64.sqrt()) / 900.0;
        let expect = [(-b, wb), (-a, wa), (0.0, 128.0 / 225.0), (a, wa), (b, wb)];
        for (got, want) in r5.iter().zip(expect) {
            assert!(close(got.0, want.0) && close(got.1, want.1), "{r5:?}");
        }
        // Exactness for polynomials of degree 2n−1 and unit-interval mapping, up to n = 64.
        for n in [4usize, 7, 16, 32, 64] {
            let r = gauss_legendre_unit(n);
            assert!((r.iter().map(|p| p.1).sum::<f64>() - 1.0).abs() < 1e-13);
            let d = 2 * n - 1;
            let integral: f64 = r.iter().map(|&(g, w)| w * g.powi(d as i32)).sum();
            assert!((integral - 1.0 / (d as f64 + 1.0)).abs() < 1e-12, "n = {n}");
            assert!(r.windows(2).all(|p| p[0].0 < p[1].0));
        }
        assert!(gauss_legendre(0).is_empty());
    }

    #[test]
    fn locate_and_corners() {
        let nodes = [1.0, 2.0, 4.0];
        assert!(matches!(locate(&nodes, 1.0), Located::At(0, f) if f == 0.0));
        assert!(matches!(locate(&nodes, 4.0), Located::At(2, f) if f == 0.0));
        assert!(matches!(locate(&nodes, 3.0), Located::At(1, f) if f == 0.5));
        assert!(matches!(locate(&nodes, 0.5), Located::Below));
        assert!(matches!(locate(&nodes, 5.0), Located::Above));
        assert!(matches!(locate(&nodes, f64::NAN), Located::NotFinite));
        // A reversed axis addresses the file's descending storage.
        let a = Axis::new("mem", "w", vec![4.0, 2.0, 1.0], 1).unwrap();
        assert!(a.reversed && a.nodes == vec![1.0, 2.0, 4.0]);
        let data = [40.0, 20.0, 10.0]; // values at w = 4, 2, 1
        let mut c = Corners::new();
        c.push(&a, 1, 0.5); // halfway between w = 2 and 4
        assert_eq!(c.eval(&data), 30.0);
    }
}

#[cfg(test)]
mod data_tests {
    //! Tests against `shared/data/ckd/axsdb` (skipped when absent).
    use super::super::profile::{integrate_piecewise_linear, AtmosphereProfile, ProfileLevel};
    use super::super::test_data::shared;
    use super::*;

    const K_B: f64 = 1.380_649e-23;

    fn ckd() -> Option<AxsDatabase> {
        shared("ckd/axsdb/nanockd_v1").map(|p| AxsDatabase::open(p).unwrap())
    }

    fn mono() -> Option<AxsDatabase> {
        shared("ckd/axsdb/nanomono_v1").map(|p| AxsDatabase::open(p).unwrap())
    }

    /// Raw `sigma_a` of a file and its dimension (name, values) list, read independently.
    /// (dimension name, coordinate values) in file order.
    type Dims = Vec<(String, Vec<f64>)>;

    fn raw(path: &Path) -> (Vec<f64>, Dims, String) {
        let f = netcdf::open(path).unwrap();
        let v = f.variable("sigma_a").unwrap();
        let dims: Vec<(String, Vec<f64>)> = v
            .dimensions()
            .iter()
            .map(|d| {
                let n = d.name();
                let c = f.variable(&n).unwrap().get_values::<f64, _>(..).unwrap();
                (n, c)
            })
            .collect();
        let units = units_of(&v).unwrap();
        (v.get_values::<f64, _>(..).unwrap(), dims, units)
    }

    fn flat(dims: &[(String, Vec<f64>)], idx: &[usize]) -> usize {
        let mut off = 0;
        for (k, (_, c)) in dims.iter().enumerate() {
            off = off * c.len() + idx[k];
        }
        off
    }

    #[test]
    fn ckd_database_layout() {
        let Some(db) = ckd() else { return };
        assert_eq!(db.kind(), DatabaseKind::Ckd);
        assert_eq!(db.bins().len(), 11);
        let b = db.bin_containing(350.0).unwrap();
        let bin = &db.bins()[b];
        assert!((bin.lower_nm - 345.0).abs() < 1e-9 && (bin.upper_nm - 355.0).abs() < 1e-9);
        assert!((bin.wavelength_nm - 349.9286).abs() < 1e-4);
        let g = db.g_grid(b).unwrap();
        assert_eq!(g.len(), 32);
        assert_eq!((g[0], g[31]), (0.0, 1.0));
        let (t, _) = db.table_for_bin(b).unwrap();
        let sp: Vec<&str> = t.species().map(|s| s.0).collect();
        assert_eq!(sp, ["O3"]);
        let e = db.quadrature_error(b).unwrap().unwrap();
        assert_eq!(e.len(), 32);
        assert_eq!(e[0].0, 1);
        let b375 = db.bin_containing(370.0).unwrap();
        let (t, _) = db.table_for_bin(b375).unwrap();
        let mut sp: Vec<&str> = t.species().map(|s| s.0).collect();
        sp.sort();
        assert_eq!(sp, ["CO2", "H2O", "O3"]);
        assert!(db.metadata().is_some());
        // Lazy loading: only what was asked for is loaded.
        let loaded = db
            .tables
            .lock()
            .unwrap()
            .iter()
            .filter(|t| t.is_some())
            .count();
        assert_eq!(loaded, 2);
        println!(
            "nanockd_v1: {} bins {:.1}–{:.1} nm; p grid {:?} Pa; T grid {:?} K",
            db.bins().len(),
            db.spectral_range_nm().0,
            db.spectral_range_nm().1,
            t.pressure_grid_pa(),
            t.temperature_grid_k()
        );
    }

    /// Without `spectral.csv` the bins are read from the files' `w` and `wbounds`.
    #[test]
    fn ckd_bins_without_spectral_csv() {
        let Some(db) = ckd() else { return };
        let tmp = std::env::temp_dir().join(format!("axsdb_nospectral_{}", std::process::id()));
        std::fs::create_dir_all(&tmp).unwrap();
        std::fs::copy(db.dir().join("index.csv"), tmp.join("index.csv")).unwrap();
        for f in db.files() {
            std::fs::copy(db.dir().join(&f.name), tmp.join(&f.name)).unwrap();
        }
        let scanned = AxsDatabase::open(&tmp);
        let scanned = scanned.unwrap();
        // Every file was read: the negative artefacts were zeroed, not rejected.
        let negatives: usize = scanned
            .load_range(295.0, 405.0)
            .unwrap()
            .iter()
            .map(|t| t.negatives_zeroed())
            .sum();
        std::fs::remove_dir_all(&tmp).unwrap();
        assert_eq!(negatives, 160 + 480);
        assert!(scanned.metadata().is_none());
        assert_eq!(scanned.bins().len(), db.bins().len());
        for (a, b) in scanned.bins().iter().zip(db.bins()) {
            assert_eq!(a.file, b.file);
            assert!(
                (a.lower_nm - b.lower_nm).abs() < 1e-6 && (a.upper_nm - b.upper_nm).abs() < 1e-6
            );
            assert!(
                (a.wavelength_nm - b.wavelength_nm).abs() < 1e-4,
                "{a:?} vs {b:?}"
            );
        }
        assert!(matches!(
            AxsDatabase::open(db.dir().join("absent")),
            Err(AbsorptionError::Missing { what: "file", .. })
        ));
    }

    #[test]
    fn ckd_node_values_are_exact_and_midpoints_linear() {
        let Some(db) = ckd() else { return };
        let b = db.bin_containing(370.0).unwrap(); // sigma_a(x_CO2, x_H2O, x_O3, p, t, w, g)
        let (t, j) = db.table_for_bin(b).unwrap();
        let (data, dims, units) = raw(Path::new(t.path()));
        assert_eq!(units, "km^-1");
        let names: Vec<&str> = dims.iter().map(|d| d.0.as_str()).collect();
        assert_eq!(names, ["x_CO2", "x_H2O", "x_O3", "p", "t", "w", "g"]);
        let c = |k: usize, i: usize| dims[k].1[i];
        let at = |idx: [usize; 7]| data[flat(&dims, &idx)] * 1e-3;
        let bp = BoundsPolicy::default();
        for idx in [
            [1, 2, 1, 9, 3, 0, 20],
            [0, 1, 1, 15, 7, 0, 31],
            [1, 0, 0, 0, 0, 0, 0],
        ] {
            let mf = [
                ("CO2", c(0, idx[0])),
                ("x_H2O", c(1, idx[1])),
                ("O3", c(2, idx[2])),
            ];
            let s = ThermoState {
                pressure_pa: c(3, idx[3]),
                temperature_k: c(4, idx[4]),
                mole_fractions: &mf,
            };
            let got = t
                .absorption_coefficient_ckd(&s, j, c(6, idx[6]), bp)
                .unwrap();
            assert_eq!(got, at(idx), "node {idx:?}");
        }
        // Halfway between two p nodes, and between two T nodes.
        let mf = [("CO2", c(0, 1)), ("H2O", c(1, 2)), ("O3", c(2, 1))];
        let (i, k, gi) = (9, 3, 20);
        let p = 0.5 * (c(3, i) + c(3, i + 1));
        let s = ThermoState {
            pressure_pa: p,
            temperature_k: c(4, k),
            mole_fractions: &mf,
        };
        let f = (p - c(3, i)) / (c(3, i + 1) - c(3, i));
        let (a, bb) = (at([1, 2, 1, i, k, 0, gi]), at([1, 2, 1, i + 1, k, 0, gi]));
        let want = a * (1.0 - f) + bb * f;
        let got = t.absorption_coefficient_ckd(&s, j, c(6, gi), bp).unwrap();
        assert!(
            (got - want).abs() <= 1e-13 * want.abs(),
            "p midpoint {got} vs {want}"
        );
        let tm = 0.5 * (c(4, k) + c(4, k + 1));
        let s = ThermoState {
            pressure_pa: c(3, i),
            temperature_k: tm,
            mole_fractions: &mf,
        };
        let want = 0.5 * (at([1, 2, 1, i, k, 0, gi]) + at([1, 2, 1, i, k + 1, 0, gi]));
        let got = t.absorption_coefficient_ckd(&s, j, c(6, gi), bp).unwrap();
        assert!(
            (got - want).abs() <= 1e-13 * want.abs(),
            "T midpoint {got} vs {want}"
        );
        println!("p midpoint: {got:.6e} m^-1 (nodes {a:.6e}, {bb:.6e})");
    }

    #[test]
    fn ckd_out_of_range_error_clamp_zero() {
        let Some(db) = ckd() else { return };
        let b = db.bin_containing(350.0).unwrap();
        let (t, j) = db.table_for_bin(b).unwrap();
        let pmin = t.pressure_grid_pa()[0];
        let mf = [("O3", 5e-6)];
        let s = |p: f64| ThermoState {
            pressure_pa: p,
            temperature_k: 250.0,
            mole_fractions: &mf,
        };
        let err = t
            .absorption_coefficient_ckd(&s(50.0), j, 0.5, OutOfRange::Error.into())
            .unwrap_err();
        let msg = err.to_string();
        println!("{msg}");
        assert!(
            matches!(&err, AbsorptionError::OutOfRange { coordinate, value, .. }
            if coordinate == "p" && *value == 50.0)
        );
        assert!(msg.contains("`p`") && msg.contains("50") && msg.contains("nanockd_v1-345_355.nc"));
        let edge = t
            .absorption_coefficient_ckd(&s(pmin), j, 0.5, OutOfRange::Error.into())
            .unwrap();
        let clamped = t
            .absorption_coefficient_ckd(&s(50.0), j, 0.5, OutOfRange::Clamp.into())
            .unwrap();
        assert!(edge > 0.0);
        assert_eq!(clamped, edge);
        let zero = t
            .absorption_coefficient_ckd(&s(50.0), j, 0.5, OutOfRange::Zero.into())
            .unwrap();
        assert_eq!(zero, 0.0);
        // Clamping and zero-filling were logged (once) for `p`.
        assert!(t.warned.lock().unwrap().contains("p"));
        // Above the top: clamped to the highest-pressure node.
        let pmax = *t.pressure_grid_pa().last().unwrap();
        let top = t
            .absorption_coefficient_ckd(&s(pmax), j, 0.5, BoundsPolicy::default())
            .unwrap();
        let c = t
            .absorption_coefficient_ckd(&s(2e5), j, 0.5, OutOfRange::Clamp.into())
            .unwrap();
        assert_eq!(c, top);
        // Mole fraction out of range, non-finite input, g outside [0, 1], missing species.
        let hi = [("O3", 2e-5)];
        let st = ThermoState {
            pressure_pa: 1e4,
            temperature_k: 250.0,
            mole_fractions: &hi,
        };
        let e = t
            .absorption_coefficient_ckd(&st, j, 0.5, BoundsPolicy::default())
            .unwrap_err();
        assert!(e.to_string().contains("`x_O3`"), "{e}");
        let nan = t.absorption_coefficient_ckd(&s(f64::NAN), j, 0.5, OutOfRange::Clamp.into());
        assert!(nan.is_err());
        let e = t
            .absorption_coefficient_ckd(&s(1e4), j, 1.5, BoundsPolicy::default())
            .unwrap_err();
        assert!(e.to_string().contains("`g`"), "{e}");
        let none = ThermoState {
            pressure_pa: 1e4,
            temperature_k: 250.0,
            mole_fractions: &[],
        };
        let e = t
            .absorption_coefficient_ckd(&none, j, 0.5, BoundsPolicy::default())
            .unwrap_err();
        assert!(
            matches!(e, AbsorptionError::MissingSpecies { ref species, .. } if species == "O3")
        );
        // Wrong kind of spectral point.
        let e = db.absorption_coefficient(
            &s(1e4),
            SpectralPoint::Mono {
                wavelength_nm: 350.0,
            },
            BoundsPolicy::default(),
        );
        assert!(matches!(e, Err(AbsorptionError::WrongKind { .. })));
    }

    /// Evidence that `sigma_a` is a volume absorption coefficient at n = p / k_B T.
    #[test]
    fn ckd_sigma_a_is_a_volume_coefficient() {
        let Some(db) = ckd() else { return };
        let b = db.bin_containing(350.0).unwrap();
        let (t, j) = db.table_for_bin(b).unwrap();
        let x = 1e-5;
        let mf = [("O3", x)];
        let temp = 220.0;
        let quad = gauss_legendre_unit(16);
        let mut ratios = Vec::new();
        for &p in t.pressure_grid_pa() {
            let s = ThermoState {
                pressure_pa: p,
                temperature_k: temp,
                mole_fractions: &mf,
            };
            let k: f64 = quad
                .iter()
                .map(|&(g, w)| {
                    w * t
                        .absorption_coefficient_ckd(&s, j, g, BoundsPolicy::default())
                        .unwrap()
                })
                .sum();
            ratios.push(k / p);
        }
        let (lo, hi) = ratios
            .iter()
            .fold((f64::INFINITY, 0.0f64), |a, &r| (a.0.min(r), a.1.max(r)));
        println!(
            "band-mean k/p over the 16 pressure nodes at 220 K: {lo:.6e} … {hi:.6e} m^-1 Pa^-1"
        );
        assert!(hi / lo - 1.0 < 1e-3, "k/p not constant: {lo} … {hi}");
        let n_o3 = x * 1e4 / (K_B * temp);
        let sigma_cm2 = ratios[0] * 1e4 / n_o3 * 1e4;
        println!("implied band-mean O3 cross-section, 345–355 nm, 220 K: {sigma_cm2:.3e} cm^2");
        assert!((3e-23..1e-21).contains(&sigma_cm2), "{sigma_cm2}");
    }

    #[test]
    fn mono_node_values_and_wavelength_interpolation() {
        let Some(db) = mono() else { return };
        assert_eq!(db.kind(), DatabaseKind::Mono);
        assert!(db.bins().is_empty());
        let w = db.spectral_points(345.0, 355.0).unwrap();
        assert_eq!(w.len(), 8165);
        let t = db.table_for_wavelength(350.0).unwrap();
        let sp: Vec<&str> = t.species().map(|s| s.0).collect();
        assert_eq!(sp, ["CO2"]);
        let fixed: Vec<&str> = t.fixed_species().iter().map(|s| s.0.as_str()).collect();
        assert_eq!(fixed, ["O2", "CH4", "H2", "O"]);
        let (data, dims, units) = raw(Path::new(t.path()));
        assert_eq!(units, "kilometer^-1");
        // The file node with the largest value, at its wavelength: exact.
        let (imax, _) = data
            .iter()
            .enumerate()
            .fold((0, 0.0), |a, (i, &v)| if v > a.1 { (i, v) } else { a });
        let mut idx = vec![0usize; dims.len()];
        let mut r = imax;
        for k in (0..dims.len()).rev() {
            idx[k] = r % dims[k].1.len();
            r /= dims[k].1.len();
        }
        let c = |name: &str| {
            let k = dims.iter().position(|d| d.0 == name).unwrap();
            dims[k].1[idx[k]]
        };
        let mf = [("CO2", c("x_CO2")), ("O2", 0.2), ("CH4", 0.0)];
        let s = ThermoState {
            pressure_pa: c("p"),
            temperature_k: c("t"),
            mole_fractions: &mf,
        };
        let got = db
            .absorption_coefficient(
                &s,
                SpectralPoint::Mono {
                    wavelength_nm: c("w"),
                },
                BoundsPolicy::default(),
            )
            .unwrap();
        assert_eq!(got, data[imax] * 1e-3);
        println!(
            "largest nanomono_v1 value: {:.4e} m^-1 at {:.4} nm, p = {} Pa, T = {} K",
            got,
            c("w"),
            c("p"),
            c("t")
        );
        // Halfway between two spectral points (w is stored descending).
        let kw = dims.iter().position(|d| d.0 == "w").unwrap();
        let i = idx[kw].min(dims[kw].1.len() - 2);
        let (w0, w1) = (dims[kw].1[i], dims[kw].1[i + 1]);
        let mut i0 = idx.clone();
        i0[kw] = i;
        let mut i1 = idx.clone();
        i1[kw] = i + 1;
        let wm = 0.5 * (w0 + w1);
        let f = (wm - w0) / (w1 - w0);
        let want = (data[flat(&dims, &i0)] * (1.0 - f) + data[flat(&dims, &i1)] * f) * 1e-3;
        let got = t
            .absorption_coefficient_mono(&s, wm, BoundsPolicy::default())
            .unwrap();
        assert!(
            (got - want).abs() <= 1e-12 * want.abs().max(1e-300),
            "{got} vs {want}"
        );
        let e = t
            .absorption_coefficient_mono(&s, 360.0, BoundsPolicy::default())
            .unwrap_err();
        assert!(e.to_string().contains("`w [nm]`"), "{e}");
    }

    /// Band-mean transmittance of the vertical path 0–`z1_m` through the profile's levels:
    /// Σ_q w_q exp(−τ_q), τ_q = ∫ k dz with k evaluated at the levels by `k_at(level, q)` and
    /// linear in z between them (trapezoid).
    fn band_transmittance(
        profile: &AtmosphereProfile,
        weights: &[f64],
        z1_m: f64,
        k_at: &dyn Fn(usize, usize) -> f64,
    ) -> f64 {
        let norm: f64 = weights.iter().sum();
        weights
            .iter()
            .enumerate()
            .map(|(q, w)| {
                let k: Vec<f64> = (0..profile.len()).map(|i| k_at(i, q)).collect();
                w * (-integrate_piecewise_linear(&profile.altitude_m, &k, 0.0, z1_m)).exp()
            })
            .sum::<f64>()
            / norm
    }

    /// CKD (nanockd_v1) vs line-by-line (nanomono_v1) band-mean transmittance, 345–355 nm, for a
    /// vertical column of the US-standard profile; and the CKD against the line-by-line
    /// reference behind its own `error` variable.
    #[test]
    fn ckd_consistency_with_monochromatic_345_355() {
        let (Some(ck), Some(mo), Some(pp)) =
            (ckd(), mono(), shared("ckd/axsdb/afgl_1986-us_standard.nc"))
        else {
            return;
        };
        let profile = AtmosphereProfile::open(&pp).unwrap();
        let b = ck.bin_containing(350.0).unwrap();
        let (tab, j) = ck.table_for_bin(b).unwrap();
        let errors = tab.quadrature_error(j).unwrap();
        let error_of = |n: usize| errors.iter().find(|e| e.0 == n).unwrap().1;
        let mono_tab = mo.table_for_wavelength(350.0).unwrap();
        let ckd_species: Vec<String> = tab.species().map(|s| s.0.to_string()).collect();
        let mono_species: Vec<String> = mono_tab
            .species()
            .map(|s| s.0.to_string())
            .chain(mono_tab.fixed_species().iter().map(|s| s.0.clone()))
            .collect();
        let common: Vec<String> = ckd_species
            .iter()
            .filter(|s| mono_species.contains(s))
            .cloned()
            .collect();
        println!("species: CKD bin {ckd_species:?}, mono {mono_species:?}, common {common:?}");
        // axsdb's default for p and T outside the grids: absorption 0 (above ≈ 48 km for the CKD
        // table, ≈ 86 km for the mono table); mole fractions must stay inside their grids.
        let bounds = BoundsPolicy {
            pressure: OutOfRange::Zero,
            temperature: OutOfRange::Zero,
            mole_fraction: OutOfRange::Error,
        };
        let levels: Vec<_> = (0..profile.len()).map(|i| profile.level(i)).collect();
        // Per level mole fractions, the species for which `keep` is false set to 0.
        let filtered = |keep: &dyn Fn(&str) -> bool| -> Vec<Vec<(&str, f64)>> {
            levels
                .iter()
                .map(|l| {
                    l.mole_fractions
                        .iter()
                        .map(|&(n, x)| (n, if keep(n) { x } else { 0.0 }))
                        .collect()
                })
                .collect()
        };
        fn state<'a>(l: &ProfileLevel<'_>, mf: &'a [(&'a str, f64)]) -> ThermoState<'a> {
            ThermoState {
                pressure_pa: l.pressure_pa,
                temperature_k: l.temperature_k,
                mole_fractions: mf,
            }
        }
        let ckd_t = |mfs: &[Vec<(&str, f64)>], ng: usize, z1: f64, bounds: BoundsPolicy| {
            let quad = gauss_legendre_unit(ng);
            let w: Vec<f64> = quad.iter().map(|q| q.1).collect();
            band_transmittance(&profile, &w, z1, &|i, q| {
                tab.absorption_coefficient_ckd(&state(&levels[i], &mfs[i]), j, quad[q].0, bounds)
                    .unwrap()
            })
        };
        let wl = mo.spectral_points(345.0, 355.0).unwrap();
        let mono_t = |mfs: &[Vec<(&str, f64)>], z1: f64| {
            band_transmittance(&profile, &vec![1.0; wl.len()], z1, &|i, q| {
                mono_tab
                    .absorption_coefficient_mono(&state(&levels[i], &mfs[i]), wl[q], bounds)
                    .unwrap()
            })
        };
        let ng = 16;
        let e16 = error_of(ng);

        // 1. Like with like: only the species both databases model — none in this bin (the CKD
        //    bin is O3 only, the mono database has no O3) — the others at 0 where the grid
        //    allows it (x_O3 = 0 and x_CO2 = 0 are grid nodes; the mono table's fixed species O2,
        //    CH4, H2, O cannot be removed).
        let only_common = filtered(&|n: &str| common.iter().any(|c| c == n));
        for z1_km in [1.0, 10.0, 120.0] {
            let (tc, tm) = (
                ckd_t(&only_common, ng, z1_km * 1e3, bounds),
                mono_t(&only_common, z1_km * 1e3),
            );
            println!(
                "like with like, 0–{z1_km} km: CKD {tc:.12} LBL {tm:.12} diff {:.3e} (tolerance error[{ng}] = {e16:.3e})",
                tc - tm
            );
            assert!((tc - tm).abs() <= e16 * tm, "0–{z1_km} km");
        }

        // 2. Each database with all its species from the profile (not like with like): the
        //    difference is the O3 absorption, which nanomono_v1 lacks.
        let all = filtered(&|_| true);
        for z1_km in [1.0, 10.0, 120.0] {
            let (tc, tm) = (
                ckd_t(&all, ng, z1_km * 1e3, bounds),
                mono_t(&all, z1_km * 1e3),
            );
            println!(
                "all species, 0–{z1_km} km: CKD (O3 only) {tc:.9} LBL (no O3) {tm:.12} diff {:.3e}",
                tc - tm
            );
        }
        let o3_du = profile.column_density_m2("O3").unwrap() / 2.686_8e20;
        let tau_o3 = -ckd_t(&all, ng, 120e3, bounds).ln();
        let tau_clamp = -ckd_t(&all, ng, 120e3, OutOfRange::Clamp.into()).ln();
        println!(
            "O3 column {o3_du:.1} DU; CKD O3 optical thickness {tau_o3:.5e} (p < 100 Pa clamped \
             instead of zero: {tau_clamp:.5e}); effective cross-section {:.3e} cm^2",
            tau_o3 / (o3_du * 2.686_8e20) * 1e4
        );

        // 3. CKD against the line-by-line reference of its own `error` variable, which is
        //    |T_ng / T_ref − 1| for this very profile (top to bottom). Two consequences, up to an
        //    allowance δ for our vertical discretisation (levels, trapezoid, zero above 48 km)
        //    and the linear-in-g reading of the 32 g nodes:
        //    (a) |T_1 / T_32 − 1| ∈ [e_1 − e_32 − δ, e_1 + e_32 + δ]: the g-quadrature spread,
        //        proportional to the column τ, matches — a check of units and of the column;
        //    (b) some T_ref satisfies |T_ng / T_ref − 1| ≤ e_ng + δ for every ng = 1…32.
        let delta = 2e-6;
        let t_ng: Vec<(usize, f64, f64)> = errors
            .iter()
            .map(|&(n, e)| (n, ckd_t(&all, n, 120e3, bounds), e))
            .collect();
        let t32 = t_ng.iter().find(|x| x.0 == 32).unwrap().1;
        for &(n, t, e) in t_ng
            .iter()
            .filter(|x| [1, 2, 3, 4, 5, 8, 16, 32].contains(&x.0))
        {
            println!(
                "ng = {n:2}: T_ckd = {t:.9}  stated error {e:.3e}  |T/T_32 − 1| = {:.3e}",
                (t / t32 - 1.0).abs()
            );
        }
        let (e1, e32) = (error_of(1), error_of(32));
        let spread = (t_ng[0].1 / t32 - 1.0).abs();
        println!(
            "(a) |T_1/T_32 − 1| = {spread:.4e}; stated e_1 = {e1:.4e} ± e_32 = {e32:.2e} → [{:.4e}, {:.4e}]",
            e1 - e32,
            e1 + e32
        );
        assert!(
            (spread - e1).abs() <= e32 + delta,
            "(a) {spread} vs {e1} ± {e32}"
        );
        let clamp: BoundsPolicy = OutOfRange::Clamp.into();
        let spread_clamp =
            (ckd_t(&all, 1, 120e3, clamp) / ckd_t(&all, 32, 120e3, clamp) - 1.0).abs();
        println!("    (with p < 100 Pa clamped instead of zero: {spread_clamp:.4e})");
        let bound = |widen: f64| {
            let lo = t_ng
                .iter()
                .map(|&(_, t, e)| t / (1.0 + e + widen))
                .fold(f64::NEG_INFINITY, f64::max);
            let hi = t_ng
                .iter()
                .map(|&(_, t, e)| t / (1.0 - e - widen))
                .fold(f64::INFINITY, f64::min);
            (lo, hi)
        };
        let (lo0, hi0) = bound(0.0);
        let (lo, hi) = bound(delta);
        println!(
            "(b) T_ref consistent with every stated error: [{lo0:.9}, {hi0:.9}] (gap {:.1e}); \
             with δ = {delta:.0e}: [{lo:.9}, {hi:.9}]",
            (lo0 - hi0).max(0.0)
        );
        assert!(lo <= hi, "(b) no T_ref within e_ng + δ of every T_ng");
        let t_ref = 0.5 * (lo + hi);
        let t16 = t_ng.iter().find(|x| x.0 == 16).unwrap().1;
        println!(
            "CKD (16 g) {t16:.9} vs LBL reference implied by `error` {t_ref:.9}: diff {:.2e} (stated error {e16:.2e})",
            t16 - t_ref
        );
    }
}
