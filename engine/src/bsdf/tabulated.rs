//! Tabulated (measured) BRDF: values of `f_r` on a grid of angles per wavelength, read from a
//! netCDF file, interpolated, and importance-sampled by a table built from it.
//!
//! | key          | unit | default | meaning                                                    |
//! |--------------|------|---------|------------------------------------------------------------|
//! | `file`       | —    | —       | netCDF table, relative to the experiment file (or bundle)  |
//! | `symmetrize` | bool | false   | evaluate `½[F(θi, θr, Δφ) + F(θr, θi, Δφ)]` (reciprocal)   |
//!
//! **File layout** (netCDF-3 or -4; names fixed; `docs/experiment.md`):
//!
//! ```text
//! dimensions: wavelength = W, theta_i = I, theta_r = R, dphi = P   (each ≥ 1)
//! double wavelength(wavelength)                  nm, strictly increasing, > 0
//! double theta_i(theta_i)                        degree, strictly increasing, in [0, 90]
//! double theta_r(theta_r)                        degree, strictly increasing, in [0, 90]
//! double dphi(dphi)                              degree, strictly increasing, in [0, 180]
//! double brdf(wavelength, theta_i, theta_r, dphi)  sr-1, finite and ≥ 0
//! ```
//!
//! `theta_i` is the zenith of the direction towards the light (the Sun), `theta_r` that of the
//! direction towards the viewer, `dphi` the relative azimuth φ_r − φ_i of the two directions
//! (both pointing away from the surface), folded into [0°, 180°] (the BRDF is isotropic): **0° is
//! backscattering** (the viewer on the Sun's side, hot spot at θr = θi), 180° the forward
//! (specular) side, as the relative azimuth `raa` of `docs/conventions.md` and RPV's Δφ.
//! `brdf` is the BRDF `f_r` in sr⁻¹ (a BRF table divided by π). Units attributes are optional;
//! where present they must say degrees and sr⁻¹ (`rad` or `1` are refused).
//!
//! **Interpolation**: trilinear in (θi, θr, Δφ) in degrees, linear in wavelength; beyond a
//! grid's ends the value at the end (constant, as bundle spectra are beyond their wavelengths).
//!
//! **Reciprocity**: `f(θi, θr, Δφ) = f(θr, θi, Δφ)` for a physical BRDF; measured tables break
//! it by noise. The table is accepted either way; [`BrdfTable::reciprocity`] is the largest
//! relative difference `|F(i, r) − F(r, i)|/max(F(i, r), F(r, i))` over the grid points (the
//! swapped value interpolated; points where both values are below 10⁻³ of the table's maximum,
//! or where the swapped angles fall outside the grid, are skipped), logged when the file is
//! read and printed by `simulate check`. With `symmetrize = true` the model is reciprocal.
//!
//! **Sampling**: the factored table sampler of `table_sampler.rs` built from this model at each
//! wavelength (marginal over the sampled zenith, conditional over Δφ, per view-zenith node, as
//! DIRSIG's tabulated-BRDF sampler), mixed with the cosine density.
//!
//! Files are read once per process while a model uses them (a cache by path).

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, Weak};

use glam::DVec3;

use super::error::BrdfError;
use super::TableSampler;

/// The largest reciprocity error of a table, and where (degrees, nm).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reciprocity {
    /// `|F(i, r) − F(r, i)|/max(F(i, r), F(r, i))`.
    pub error: f64,
    pub wavelength_nm: f64,
    pub theta_i: f64,
    pub theta_r: f64,
    pub dphi: f64,
}

/// A BRDF table as read from a file (see the module header).
#[derive(Debug)]
pub struct BrdfTable {
    pub path: PathBuf,
    pub wavelengths: Vec<f64>,
    pub theta_i: Vec<f64>,
    pub theta_r: Vec<f64>,
    pub dphi: Vec<f64>,
    /// `[wavelength][theta_i][theta_r][dphi]`, sr⁻¹.
    values: Vec<f64>,
    /// The largest reciprocity error over all wavelengths (`None`: no pair comparable).
    pub reciprocity: Option<Reciprocity>,
}

/// Tables in use, by path (each read once while alive).
static CACHE: Mutex<Vec<(PathBuf, Weak<BrdfTable>)>> = Mutex::new(Vec::new());

/// `(i0, i1, t)`: the grid cell around `x` and the weight of `i1`; clamped at the ends.
#[inline]
fn locate(grid: &[f64], x: f64) -> (usize, usize, f64) {
    let n = grid.len();
    if n == 1 || x <= grid[0] {
        return (0, 0, 0.0);
    }
    if x >= grid[n - 1] {
        return (n - 1, n - 1, 0.0);
    }
    let i = grid.partition_point(|&g| g <= x) - 1;
    (i, i + 1, (x - grid[i]) / (grid[i + 1] - grid[i]))
}

impl BrdfTable {
    /// The table of `path`, from the cache or read (and logged, with its reciprocity error).
    /// Errors name the file and the variable.
    pub fn load(path: &Path) -> Result<Arc<BrdfTable>, BrdfError> {
        let mut cache = CACHE.lock().unwrap_or_else(|e| e.into_inner());
        cache.retain(|(_, w)| w.strong_count() > 0);
        if let Some(t) = cache
            .iter()
            .find(|(p, _)| p == path)
            .and_then(|(_, w)| w.upgrade())
        {
            return Ok(t);
        }
        let t = Arc::new(Self::read(path)?);
        tracing::info!("{}", t.summary());
        cache.push((path.to_path_buf(), Arc::downgrade(&t)));
        Ok(t)
    }

    fn read(path: &Path) -> Result<BrdfTable, BrdfError> {
        let p = || path.to_path_buf();
        let _session = crate::netcdf_session();
        crate::util::nc_complete::check(path)
            .map_err(|source| BrdfError::Truncated { path: p(), source })?;
        let file = netcdf::open(path).map_err(|source| BrdfError::Open { path: p(), source })?;
        let get = |name: &'static str, what: &'static str, unit_ok: &dyn Fn(&str) -> bool| {
            let v = file
                .variable(name)
                .ok_or_else(|| BrdfError::MissingVariable {
                    path: p(),
                    variable: name,
                    what,
                })?;
            // Look the attribute up by listing (asking HDF5 for an absent one prints errors).
            if let Some(u) = v
                .attributes()
                .find(|a| a.name() == "units")
                .and_then(|a| a.value().ok())
                .and_then(|a| String::try_from(a).ok())
            {
                if !unit_ok(u.trim()) {
                    return Err(BrdfError::Units {
                        path: p(),
                        variable: name,
                        units: u,
                        what,
                    });
                }
            }
            let dims: Vec<(String, usize)> =
                v.dimensions().iter().map(|d| (d.name(), d.len())).collect();
            let values = v
                .get_values::<f64, _>(..)
                .map_err(|source| BrdfError::ReadVariable {
                    path: p(),
                    variable: name,
                    source,
                })?;
            Ok((dims, values))
        };
        let deg = |u: &str| matches!(u, "degree" | "degrees" | "deg" | "degree_zenith");
        let one_dimension = |name: &'static str, dims: &[(String, usize)]| {
            if dims.len() != 1 || dims[0].0 != name {
                return Err(BrdfError::AxisDimensions {
                    path: p(),
                    variable: name,
                });
            }
            Ok(())
        };
        let axis = |name: &'static str, what: &'static str| -> Result<Vec<f64>, BrdfError> {
            let (dims, v) = get(name, what, &deg)?;
            one_dimension(name, &dims)?;
            Ok(v)
        };
        let theta_i = axis(
            "theta_i",
            "zenith of the direction towards the light, degrees",
        )?;
        let theta_r = axis(
            "theta_r",
            "zenith of the direction towards the viewer, degrees",
        )?;
        let dphi = axis("dphi", "relative azimuth, degrees, 0 = backscattering")?;
        let (wdims, wavelengths) = get("wavelength", "nm", &|u| {
            matches!(u, "nm" | "nanometer" | "nanometers")
        })?;
        one_dimension("wavelength", &wdims)?;
        let (bdims, values) = get("brdf", "BRDF, sr-1", &|u| {
            matches!(u, "sr-1" | "sr^-1" | "1/sr" | "sr**-1")
        })?;
        let want = ["wavelength", "theta_i", "theta_r", "dphi"];
        if bdims.len() != 4 || bdims.iter().zip(want).any(|((n, _), w)| n != w) {
            return Err(BrdfError::BrdfDimensions {
                path: p(),
                found: bdims.into_iter().map(|(n, _)| n).collect(),
            });
        }
        Self::new(path, wavelengths, theta_i, theta_r, dphi, values)
    }

    /// A table from its grids and values (`[wavelength][theta_i][theta_r][dphi]`), checked as a
    /// file would be; `path` names it in messages.
    pub fn new(
        path: &Path,
        wavelengths: Vec<f64>,
        theta_i: Vec<f64>,
        theta_r: Vec<f64>,
        dphi: Vec<f64>,
        values: Vec<f64>,
    ) -> Result<BrdfTable, BrdfError> {
        let p = || path.to_path_buf();
        for (name, g, lo, hi) in [
            ("wavelength", &wavelengths, f64::MIN_POSITIVE, f64::INFINITY),
            ("theta_i", &theta_i, 0.0, 90.0),
            ("theta_r", &theta_r, 0.0, 90.0),
            ("dphi", &dphi, 0.0, 180.0),
        ] {
            if g.is_empty() {
                return Err(BrdfError::EmptyAxis {
                    path: p(),
                    variable: name,
                });
            }
            if let Some(x) = g.iter().find(|x| !(**x >= lo && **x <= hi)) {
                return Err(BrdfError::AxisRange {
                    path: p(),
                    variable: name,
                    value: *x,
                    lo,
                    hi,
                });
            }
            if let Some(w) = g.windows(2).find(|w| w[1] <= w[0]) {
                return Err(BrdfError::NotIncreasing {
                    path: p(),
                    variable: name,
                    previous: w[0],
                    next: w[1],
                });
            }
        }
        let (nw, ni, nr, np) = (wavelengths.len(), theta_i.len(), theta_r.len(), dphi.len());
        if values.len() != nw * ni * nr * np {
            return Err(BrdfError::ValueCount {
                path: p(),
                found: values.len(),
                shape: [nw, ni, nr, np],
            });
        }
        if let Some(k) = values.iter().position(|v| !(v.is_finite() && *v >= 0.0)) {
            let (w, rest) = (k / (ni * nr * np), k % (ni * nr * np));
            let (i, rest) = (rest / (nr * np), rest % (nr * np));
            let (r, q) = (rest / np, rest % np);
            return Err(BrdfError::BadValue {
                path: p(),
                value: values[k],
                wavelength_nm: wavelengths[w],
                theta_i: theta_i[i],
                theta_r: theta_r[r],
                dphi: dphi[q],
            });
        }
        let mut t = BrdfTable {
            path: path.to_path_buf(),
            wavelengths,
            theta_i,
            theta_r,
            dphi,
            values,
            reciprocity: None,
        };
        t.reciprocity = t.reciprocity_error();
        Ok(t)
    }

    /// Trilinear interpolation in wavelength slice `w` (angles in degrees).
    #[inline]
    fn lookup(&self, w: usize, ti: f64, tr: f64, dp: f64) -> f64 {
        let (ni, nr, np) = (self.theta_i.len(), self.theta_r.len(), self.dphi.len());
        let (i0, i1, a) = locate(&self.theta_i, ti);
        let (r0, r1, b) = locate(&self.theta_r, tr);
        let (q0, q1, c) = locate(&self.dphi, dp);
        let at = |i: usize, r: usize, q: usize| self.values[((w * ni + i) * nr + r) * np + q];
        let lerp = |x: f64, y: f64, t: f64| x + t * (y - x);
        let plane = |i: usize| {
            lerp(
                lerp(at(i, r0, q0), at(i, r0, q1), c),
                lerp(at(i, r1, q0), at(i, r1, q1), c),
                b,
            )
        };
        lerp(plane(i0), plane(i1), a)
    }

    fn reciprocity_error(&self) -> Option<Reciprocity> {
        let peak = self.values.iter().cloned().fold(0.0, f64::max);
        let (ilo, ihi) = (self.theta_i[0], *self.theta_i.last().unwrap());
        let (rlo, rhi) = (self.theta_r[0], *self.theta_r.last().unwrap());
        let mut worst: Option<Reciprocity> = None;
        for (w, &wl) in self.wavelengths.iter().enumerate() {
            for &ti in &self.theta_i {
                for &tr in &self.theta_r {
                    if !(ti >= rlo && ti <= rhi && tr >= ilo && tr <= ihi) {
                        continue;
                    }
                    for &dp in &self.dphi {
                        let (a, b) = (self.lookup(w, ti, tr, dp), self.lookup(w, tr, ti, dp));
                        let m = a.max(b);
                        if m <= 1e-3 * peak {
                            continue;
                        }
                        let error = (a - b).abs() / m;
                        if worst.is_none_or(|x| error > x.error) {
                            worst = Some(Reciprocity {
                                error,
                                wavelength_nm: wl,
                                theta_i: ti,
                                theta_r: tr,
                                dphi: dp,
                            });
                        }
                    }
                }
            }
        }
        worst
    }

    /// One line for logs and `simulate check`: the file, its grids and the reciprocity error.
    pub fn summary(&self) -> String {
        let range = |g: &[f64]| format!("{}…{} ({})", g[0], g[g.len() - 1], g.len());
        let rec = match &self.reciprocity {
            Some(r) => format!(
                "max reciprocity error |f(i,r) − f(r,i)|/max = {:.2} % (at {} nm, theta_i {}°, theta_r {}°, dphi {}°)",
                100.0 * r.error,
                r.wavelength_nm,
                r.theta_i,
                r.theta_r,
                r.dphi
            ),
            None => "reciprocity not checked (the theta_i and theta_r grids do not overlap)".into(),
        };
        format!(
            "BRDF table {}: wavelength {} nm, theta_i {}°, theta_r {}°, dphi {}°; {rec}",
            self.path.display(),
            range(&self.wavelengths),
            range(&self.theta_i),
            range(&self.theta_r),
            range(&self.dphi)
        )
    }
}

/// A tabulated BRDF at one wavelength.
#[derive(Clone, Debug)]
pub struct Tabulated {
    pub table: Arc<BrdfTable>,
    pub wavelength_nm: f64,
    pub symmetrize: bool,
    /// Wavelength slices and the weight of the second.
    w0: usize,
    w1: usize,
    t: f64,
    /// Importance sampler built from this model (`table_sampler.rs`).
    pub(crate) sampler: TableSampler,
}

impl Tabulated {
    /// The model of `table` at `wavelength_nm` (linear between the table's wavelengths,
    /// constant beyond them).
    pub fn new(table: Arc<BrdfTable>, wavelength_nm: f64, symmetrize: bool) -> Self {
        let (w0, w1, t) = locate(&table.wavelengths, wavelength_nm);
        let mut m = Tabulated {
            table,
            wavelength_nm,
            symmetrize,
            w0,
            w1,
            t,
            sampler: TableSampler::unbuilt(),
        };
        m.sampler = TableSampler::build(|wi, wo| m.eval(wi, wo));
        m
    }

    #[inline]
    fn at(&self, ti: f64, tr: f64, dp: f64) -> f64 {
        let a = self.table.lookup(self.w0, ti, tr, dp);
        if self.t > 0.0 {
            a + self.t * (self.table.lookup(self.w1, ti, tr, dp) - a)
        } else {
            a
        }
    }

    /// BRDF (sr⁻¹) for unit vectors `wi` (towards the light) and `wo` (towards the viewer),
    /// both with `z > 0` (the caller, [`crate::bsdf::Bsdf::eval`], handles the horizon).
    #[inline]
    pub fn eval(&self, wi: DVec3, wo: DVec3) -> f64 {
        let ti = wi.z.clamp(-1.0, 1.0).acos().to_degrees();
        let tr = wo.z.clamp(-1.0, 1.0).acos().to_degrees();
        // Relative azimuth of the horizontal parts, in [0°, 180°]; 0 when either is vertical.
        let dot = wi.x * wo.x + wi.y * wo.y;
        let cross = (wi.x * wo.y - wi.y * wo.x).abs();
        let dp = if dot == 0.0 && cross == 0.0 {
            0.0
        } else {
            cross.atan2(dot).to_degrees()
        };
        let f = if self.symmetrize {
            0.5 * (self.at(ti, tr, dp) + self.at(tr, ti, dp))
        } else {
            self.at(ti, tr, dp)
        };
        f.max(0.0)
    }
}

/// Write a table in the file layout of the module header (netCDF-3, 64-bit offsets):
/// `f(wavelength, theta_i, theta_r, dphi)` in sr⁻¹ at every grid point, angles in degrees. For
/// tests and for turning a model into a table; the grids must satisfy the layout's rules.
pub fn write_table(
    path: &Path,
    wavelengths: &[f64],
    theta_i: &[f64],
    theta_r: &[f64],
    dphi: &[f64],
    f: impl Fn(f64, f64, f64, f64) -> f64,
) -> Result<(), netcdf::Error> {
    let _session = crate::netcdf_session();
    // netCDF-3 (64-bit offset): read from test threads, a netCDF-4 file makes HDF5 print its
    // (harmless) attribute probes, whose printing is switched off in one thread only.
    let mut nc = netcdf::create_with(path, netcdf::Options::_64BIT_OFFSET)?;
    let axes = [
        ("wavelength", wavelengths, "nm"),
        ("theta_i", theta_i, "degree"),
        ("theta_r", theta_r, "degree"),
        ("dphi", dphi, "degree"),
    ];
    // Classic files: everything defined first, then the data.
    for (name, g, unit) in axes {
        nc.add_dimension(name, g.len())?;
        let mut v = nc.add_variable::<f64>(name, &[name])?;
        v.put_attribute("units", unit)?;
    }
    let mut v = nc.add_variable::<f64>("brdf", &["wavelength", "theta_i", "theta_r", "dphi"])?;
    v.put_attribute("units", "sr-1")?;
    nc.enddef()?;
    for (name, g, _) in axes {
        nc.variable_mut(name)
            .expect("defined above")
            .put_values(g, ..)?;
    }
    let mut vals =
        Vec::with_capacity(wavelengths.len() * theta_i.len() * theta_r.len() * dphi.len());
    for &w in wavelengths {
        for &i in theta_i {
            for &r in theta_r {
                for &p in dphi {
                    vals.push(f(w, i, r, p));
                }
            }
        }
    }
    nc.variable_mut("brdf")
        .expect("defined above")
        .put_values(&vals, ..)?;
    Ok(())
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::bsdf::{Bsdf, Rpv};
    use crate::frame::direction_from_angles;

    pub(crate) fn grid(lo: f64, hi: f64, step: f64) -> Vec<f64> {
        let n = ((hi - lo) / step).round() as usize;
        (0..=n).map(|k| lo + step * k as f64).collect()
    }

    /// RPV's BRDF at angles in degrees (the file's convention: Δφ = 0 backscattering).
    pub(crate) fn rpv_at(m: &Rpv, ti: f64, tr: f64, dp: f64) -> f64 {
        let wi = direction_from_angles(ti.to_radians(), 0.0);
        let wo = direction_from_angles(tr.to_radians(), dp.to_radians());
        m.eval(wi, wo)
    }

    fn tmp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("tabulated_brdf_{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d.join(name)
    }

    /// A table written from RPV (two wavelengths with different ρ₀) reproduces RPV at its
    /// nodes, interpolates between them, blends wavelengths linearly, keeps the Δφ convention
    /// (0 = backscattering: the hot spot), and is reciprocal to rounding; its sampler passes
    /// χ² and its pdf integrates to 1.
    #[test]
    fn table_from_rpv() {
        let a = Rpv::new(0.1, 0.8, -0.2, 0.3).unwrap();
        let b = Rpv::new(0.3, 0.8, -0.2, 0.3).unwrap();
        let path = tmp("rpv.nc");
        let (ti, tr, dp) = (
            grid(0.0, 88.0, 2.0),
            grid(0.0, 88.0, 2.0),
            grid(0.0, 180.0, 5.0),
        );
        write_table(&path, &[500.0, 700.0], &ti, &tr, &dp, |w, i, r, p| {
            rpv_at(if w < 600.0 { &a } else { &b }, i, r, p)
        })
        .unwrap();
        let table = BrdfTable::load(&path).unwrap();
        assert!(
            Arc::ptr_eq(&table, &BrdfTable::load(&path).unwrap()),
            "cached"
        );
        let rec = table.reciprocity.unwrap();
        assert!(rec.error < 1e-12, "{rec:?}");
        let m500 = Tabulated::new(table.clone(), 500.0, false);
        let m600 = Tabulated::new(table.clone(), 600.0, false);
        // At nodes: exact (Δφ = φo − φi, here with φi = 0.4 rad).
        for &(i, r, p) in &[(30.0, 40.0, 0.0), (0.0, 60.0, 90.0), (50.0, 50.0, 180.0)] {
            let wi = direction_from_angles(f64::to_radians(i), 0.4);
            let wo = direction_from_angles(f64::to_radians(r), 0.4 + f64::to_radians(p));
            let want = a.eval(wi, wo);
            assert!((m500.eval(wi, wo) / want - 1.0).abs() < 1e-9, "{i} {r} {p}");
            let mid = 0.5 * (want + b.eval(wi, wo));
            assert!((m600.eval(wi, wo) / mid - 1.0).abs() < 1e-9);
            // The other sign of Δφ is the same value (isotropic).
            let wo2 = direction_from_angles(f64::to_radians(r), 0.4 - f64::to_radians(p));
            assert!((m500.eval(wi, wo2) / want - 1.0).abs() < 1e-9);
        }
        // Between nodes: close to RPV (2° and 5° cells).
        for &(i, r, p) in &[(31.0, 47.3, 12.5), (65.2, 10.1, 133.0), (45.0, 44.0, 2.5)] {
            let want = rpv_at(&a, i, r, p);
            let got = m500.eval(
                direction_from_angles(f64::to_radians(i), 0.0),
                direction_from_angles(f64::to_radians(r), f64::to_radians(p)),
            );
            assert!(
                (got / want - 1.0).abs() < 0.01,
                "{i} {r} {p}: {got} vs {want}"
            );
        }
        // The sampler, against its own pdf.
        let m = Bsdf::Tabulated(m500);
        let chart = crate::bsdf::test_support::Chart::hemisphere(12, 24, 4);
        for z in [0.0, 0.7, 1.45] {
            let wo = direction_from_angles(z, 2.0);
            crate::bsdf::test_support::assert_chi2("tabulated", &m, wo, &chart, 100_000);
            let total: f64 = crate::bsdf::test_support::Chart::hemisphere(48, 96, 2)
                .expected(wo, &|wi| m.pdf(wi, wo))
                .iter()
                .sum();
            assert!((total - 1.0).abs() < 1e-9, "{total}");
        }
        let _ = std::fs::remove_file(&path);
    }

    /// A non-reciprocal table is accepted and its error reported; `symmetrize` makes the model
    /// reciprocal.
    #[test]
    fn reciprocity_error_and_symmetrize() {
        let path = tmp("skew.nc");
        let g = grid(0.0, 80.0, 10.0);
        // f = 0.1·(1 + 0.2·θi/80): 20 % larger at θi = 80° than at θr = 80°.
        write_table(&path, &[550.0], &g, &g, &[0.0, 180.0], |_, i, _, _| {
            0.1 * (1.0 + 0.2 * i / 80.0)
        })
        .unwrap();
        let t = BrdfTable::load(&path).unwrap();
        let r = t.reciprocity.unwrap();
        assert!((r.error - 0.2 / 1.2).abs() < 1e-12, "{r:?}");
        assert!(t.summary().contains("16.67 %"), "{}", t.summary());
        let (wi, wo) = (
            direction_from_angles(1.2, 0.0),
            direction_from_angles(0.2, 1.0),
        );
        let asym = Tabulated::new(t.clone(), 550.0, false);
        assert!((asym.eval(wi, wo) - asym.eval(wo, wi)).abs() > 1e-3);
        let sym = Tabulated::new(t, 550.0, true);
        assert!((sym.eval(wi, wo) - sym.eval(wo, wi)).abs() < 1e-15);
        let _ = std::fs::remove_file(&path);
    }

    /// Bad files: each error names the file and the variable.
    #[test]
    fn bad_tables_are_refused_with_the_variable_named() {
        let g = grid(0.0, 80.0, 20.0);
        let p = [0.0, 90.0, 180.0];
        type Writer<'a> = Box<dyn Fn(&Path) + 'a>;
        let cases: Vec<(&str, Writer, &str)> = vec![
            (
                "nan.nc",
                Box::new(|path: &Path| {
                    write_table(path, &[550.0], &g, &g, &p, |_, i, _, _| {
                        if i == 40.0 {
                            f64::NAN
                        } else {
                            0.1
                        }
                    })
                    .unwrap()
                }),
                "variable `brdf` is NaN at wavelength 550 nm, theta_i 40°",
            ),
            (
                "negative.nc",
                Box::new(|path: &Path| {
                    write_table(path, &[550.0], &g, &g, &p, |_, _, _, q| {
                        if q == 180.0 {
                            -0.5
                        } else {
                            0.1
                        }
                    })
                    .unwrap()
                }),
                "variable `brdf` is -0.5 at wavelength 550 nm, theta_i 0°, theta_r 0°, dphi 180°",
            ),
            (
                "order.nc",
                Box::new(|path: &Path| {
                    write_table(path, &[550.0], &[0.0, 40.0, 20.0], &g, &p, |_, _, _, _| 0.1)
                        .unwrap()
                }),
                "variable `theta_i` must increase strictly (40 then 20)",
            ),
            (
                "range.nc",
                Box::new(|path: &Path| {
                    write_table(path, &[550.0], &g, &g, &[0.0, 360.0], |_, _, _, _| 0.1).unwrap()
                }),
                "variable `dphi` has the value 360 outside [0, 180]",
            ),
        ];
        for (name, write, want) in cases {
            let path = tmp(name);
            write(&path);
            let e = BrdfTable::load(&path).unwrap_err().to_string();
            assert!(
                e.contains(&path.display().to_string()) && e.contains(want),
                "{name}: {e}"
            );
            let _ = std::fs::remove_file(&path);
        }
        // A missing variable, and radians.
        let path = tmp("missing.nc");
        {
            let _session = crate::netcdf_session();
            let mut nc = netcdf::create_with(&path, netcdf::Options::_64BIT_OFFSET).unwrap();
            nc.add_dimension("theta_i", 2).unwrap();
            let mut v = nc.add_variable::<f64>("theta_i", &["theta_i"]).unwrap();
            v.put_attribute("units", "rad").unwrap();
            nc.enddef().unwrap();
            let mut v = nc.variable_mut("theta_i").unwrap();
            v.put_values(&[0.0, 1.0], ..).unwrap();
        }
        let e = BrdfTable::load(&path).unwrap_err().to_string();
        assert!(e.contains("`theta_i` has units \"rad\""), "{e}");
        let path2 = tmp("missing2.nc");
        {
            let _session = crate::netcdf_session();
            let mut nc = netcdf::create_with(&path2, netcdf::Options::_64BIT_OFFSET).unwrap();
            nc.add_dimension("theta_i", 2).unwrap();
            nc.add_variable::<f64>("theta_i", &["theta_i"]).unwrap();
            nc.enddef().unwrap();
            let mut v = nc.variable_mut("theta_i").unwrap();
            v.put_values(&[0.0, 10.0], ..).unwrap();
        }
        let e = BrdfTable::load(&path2).unwrap_err().to_string();
        assert!(e.contains("missing variable `theta_r`"), "{e}");
        assert!(BrdfTable::load(&tmp("absent.nc"))
            .unwrap_err()
            .to_string()
            .contains("cannot read BRDF table"));
        let _ = std::fs::remove_file(&path);
        let _ = std::fs::remove_file(&path2);
    }
}
