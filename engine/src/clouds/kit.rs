//! The 3D-cloud benchmark inputs of `shared/clouds` (I3RC Phase 1 cases 1–3, IPRT phase B
//! case C2) read into [`CloudGrid`]s, following that folder's README (layouts, units,
//! conventions: x along the solar photons' horizontal travel, z up, km in the files, m here).
//!
//! * Case 1, step cloud: 32 columns of 15.625 m, cloud from 0 to 250 m, column optical depth
//!   from `step_cloud_tau_32.txt` (2 then 18), HG g = 0.85.
//! * Case 2, MMCR: 640 × 54 cells of 50 m × 45 m; each value of the file is a cell's optical
//!   depth, first line the top layer; HG g = 0.85 or the tabulated Deirmendjian C.1.
//! * Case 3, Landsat: 128 × 128 columns of 30 m, one box per column from the cloud base (0.2 km,
//!   the README's choice) to base + dz; line j of the files is y, value i is x.
//! * IPRT C2: a 1 km cube of σ = 10 /km over 3–4 km × 3–4 km × 2–3 km in a 7 × 7 × 5 km
//!   domain; the `watercloud.mie.cdf` phase function at 800 nm, ϖ from the same file.
//!
//! Fields repeat laterally (2D cases are one column deep in y).

use std::path::{Path, PathBuf};

use super::grid::{CloudGrid, GridError, Lateral, PerCell, Vertical};
use crate::phase::{HenyeyGreenstein, PhaseFunction, Tabulated};

/// Why a kit file cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum KitError {
    #[error("cloud case file {}: {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("cloud case file {} line {line}: {message}", path.display())]
    Parse {
        path: PathBuf,
        line: usize,
        message: String,
    },
    #[error("cloud case file {}: {message}", path.display())]
    Phase { path: PathBuf, message: String },
    #[error(transparent)]
    Grid(#[from] GridError),
}

/// The phase function of an I3RC case-2 experiment.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CasePhase {
    /// Henyey–Greenstein, g = 0.85.
    Hg,
    /// Deirmendjian C.1, tabulated (`C.1_PF`).
    C1,
}

/// Read a whitespace-separated table of numbers, `rows` lines of `cols` values (lines starting
/// with `#` and blank lines skipped).
pub fn read_table(path: &Path, rows: usize, cols: usize) -> Result<Vec<Vec<f64>>, KitError> {
    let text = std::fs::read_to_string(path).map_err(|source| KitError::Io {
        path: path.into(),
        source,
    })?;
    let parse_err = |line: usize, message: String| KitError::Parse {
        path: path.into(),
        line,
        message,
    };
    let mut out = Vec::with_capacity(rows);
    for (k, line) in text.lines().enumerate() {
        let t = line.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        let vals: Vec<f64> = t
            .split_whitespace()
            .map(|v| {
                v.parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| parse_err(k + 1, format!("'{v}' is not a finite number")))
            })
            .collect::<Result<_, _>>()?;
        if vals.len() != cols {
            return Err(parse_err(
                k + 1,
                format!("{} values, expected {cols}", vals.len()),
            ));
        }
        out.push(vals);
    }
    if out.len() != rows {
        return Err(parse_err(
            text.lines().count(),
            format!("{} data lines, expected {rows}", out.len()),
        ));
    }
    Ok(out)
}

/// A periodic grid of uniform albedo `omega` and one phase function (every kit case).
fn periodic(
    columns: (usize, usize),
    size: (f64, f64),
    vertical: Vertical,
    ext: Vec<f32>,
    omega: f64,
    phase: PhaseFunction,
) -> Result<CloudGrid, KitError> {
    Ok(CloudGrid::new(
        columns,
        size,
        vertical,
        Lateral::Periodic,
        ext,
        PerCell::Uniform(omega as f32),
        PerCell::Uniform(0),
        vec![phase],
    )?)
}

fn hg() -> PhaseFunction {
    PhaseFunction::Hg(HenyeyGreenstein::new(0.85).expect("g = 0.85 is valid"))
}

/// The tabulated C.1 phase function (`C.1_PF`: angle in degrees, value).
pub fn c1_phase(kit: &Path) -> Result<PhaseFunction, KitError> {
    let path = kit.join("i3rc_phase1/case2/C.1_PF");
    let t = read_table(&path, 1801, 2)?;
    let theta: Vec<f64> = t.iter().map(|r| r[0]).collect();
    let vals: Vec<f64> = t.iter().map(|r| r[1]).collect();
    let table = Tabulated::from_table(&theta, &vals).map_err(|e| KitError::Phase {
        path: path.clone(),
        message: e.to_string(),
    })?;
    Ok(PhaseFunction::Tabulated(std::sync::Arc::new(table)))
}

/// I3RC case 1 with single-scattering albedo `omega`.
pub fn i3rc_case1(kit: &Path, omega: f64) -> Result<CloudGrid, KitError> {
    let t = read_table(&kit.join("i3rc_phase1/case1/step_cloud_tau_32.txt"), 32, 2)?;
    let h = 250.0;
    let ext: Vec<f32> = t.iter().map(|r| (r[1] / h) as f32).collect();
    periodic(
        (32, 1),
        (500.0 / 32.0, 500.0 / 32.0),
        Vertical::Levels(vec![0.0, h]),
        ext,
        omega,
        hg(),
    )
}

/// I3RC case 2 with single-scattering albedo `omega` and phase function `phase`.
pub fn i3rc_case2(kit: &Path, omega: f64, phase: CasePhase) -> Result<CloudGrid, KitError> {
    let (nx, nz, dx, dz) = (640, 54, 50.0, 45.0);
    let t = read_table(&kit.join("i3rc_phase1/case2/mmcr_tau_32km_020898"), nz, nx)?;
    let mut ext = vec![0.0_f32; nx * nz];
    for (line, row) in t.iter().enumerate() {
        // The first line is the top layer.
        let iz = nz - 1 - line;
        for (ix, &tau) in row.iter().enumerate() {
            ext[iz * nx + ix] = (tau / dz) as f32;
        }
    }
    let levels = (0..=nz).map(|k| k as f64 * dz).collect();
    let pf = match phase {
        CasePhase::Hg => hg(),
        CasePhase::C1 => c1_phase(kit)?,
    };
    periodic((nx, 1), (dx, dx), Vertical::Levels(levels), ext, omega, pf)
}

/// I3RC case 3 with single-scattering albedo `omega` and the cloud base at `base_m`.
pub fn i3rc_case3(kit: &Path, omega: f64, base_m: f64) -> Result<CloudGrid, KitError> {
    let n = 128;
    let tau = read_table(&kit.join("i3rc_phase1/case3/scene43.tau.128x128"), n, n)?;
    let dz = read_table(&kit.join("i3rc_phase1/case3/scene43.dz.128x128"), n, n)?;
    let mut ext = vec![0.0_f32; n * n];
    let mut base = vec![base_m; n * n];
    let mut top = vec![base_m; n * n];
    for j in 0..n {
        for i in 0..n {
            let c = j * n + i;
            let h = dz[j][i] * 1000.0;
            if h > 0.0 && tau[j][i] > 0.0 {
                ext[c] = (tau[j][i] / h) as f32;
                top[c] = base_m + h;
            } else {
                base[c] = base_m;
            }
        }
    }
    periodic(
        (n, n),
        (30.0, 30.0),
        Vertical::Boxes { base, top },
        ext,
        omega,
        hg(),
    )
}

/// IPRT phase B C2: the cube, on 1 km cells (7 × 7 × 5), with the phase function and albedo of
/// `watercloud.mie.cdf`. Returns the grid and the cube's albedo.
pub fn iprt_c2(kit: &Path) -> Result<(CloudGrid, f64), KitError> {
    let path = kit.join("iprt_phaseB/watercloud.mie.cdf");
    let table = Tabulated::load_libradtran(&path, 800.0, 0).map_err(|e| KitError::Phase {
        path: path.clone(),
        message: e.to_string(),
    })?;
    let omega = 0.999979;
    let n = 7;
    let mut ext = vec![0.0_f32; n * n * 5];
    ext[(2 * n + 3) * n + 3] = 10.0e-3;
    let grid = periodic(
        (n, n),
        (1000.0, 1000.0),
        Vertical::Levels((0..=5).map(|k| k as f64 * 1000.0).collect()),
        ext,
        omega,
        PhaseFunction::Tabulated(std::sync::Arc::new(table)),
    )?;
    Ok((grid, omega))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kit() -> Option<PathBuf> {
        let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/clouds");
        p.exists().then_some(p)
    }

    #[test]
    fn kit_fields_have_the_readme_statistics() {
        let Some(k) = kit() else { return };
        let g = i3rc_case2(&k, 1.0, CasePhase::Hg).unwrap();
        let taus: Vec<f64> = (0..640).map(|i| g.column_optical_depth(i, 0)).collect();
        let mean = taus.iter().sum::<f64>() / 640.0;
        let (lo, hi) = taus
            .iter()
            .fold((f64::MAX, 0.0f64), |a, &t| (a.0.min(t), a.1.max(t)));
        assert!((mean - 19.5).abs() < 0.05, "{mean}");
        assert!(
            (lo - 6.5).abs() < 0.05 && (hi - 51.5).abs() < 0.05,
            "{lo} {hi}"
        );
        // The lowest 14 layers are empty: nothing below 630 m.
        let below = g.optical_depth(glam::DVec3::new(10.0, 0.0, 630.0), -glam::DVec3::Z, 1e9);
        assert_eq!(below, 0.0);
        let g3 = i3rc_case3(&k, 1.0, 200.0).unwrap();
        let mut sum = 0.0;
        let mut clear = 0;
        for iy in 0..128 {
            for ix in 0..128 {
                let t = g3.column_optical_depth(ix, iy);
                sum += t;
                clear += usize::from(t == 0.0);
            }
        }
        assert!((sum / 16384.0 - 10.06).abs() < 0.01, "{}", sum / 16384.0);
        assert_eq!(clear, 1897);
        assert!((g3.z_range().1 - 2580.0).abs() < 1.0);
        let c1 = c1_phase(&k).unwrap();
        assert!((c1.asymmetry() - 0.848).abs() < 2e-3, "{}", c1.asymmetry());
        let (c2, _) = iprt_c2(&k).unwrap();
        let tau = c2.optical_depth(
            glam::DVec3::new(3500.0, 3500.0, 5000.0),
            -glam::DVec3::Z,
            1e9,
        );
        assert!((tau - 10.0).abs() < 1e-5, "{tau}");
    }

    #[test]
    fn a_short_line_is_named() {
        let dir = std::env::temp_dir().join(format!("kit_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("t.txt");
        std::fs::write(&f, "1 2 3\n4 5\n").unwrap();
        let e = read_table(&f, 2, 3).unwrap_err().to_string();
        assert!(e.contains("t.txt line 2: 2 values, expected 3"), "{e}");
        std::fs::write(&f, "1 2 x\n").unwrap();
        let e = read_table(&f, 1, 3).unwrap_err().to_string();
        assert!(e.contains("'x' is not a finite number"), "{e}");
    }
}
