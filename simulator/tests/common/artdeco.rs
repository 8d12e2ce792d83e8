//! The ARTDECO O2 A-band case (shared data `artdeco_o2a/`, MANIFEST §4): cumulative optical
//! depth files, per-layer optical thicknesses and the analytic single-scattering BRF, shared by
//! `artdeco_o2a.rs` and `mono_alis.rs`.

use std::path::{Path, PathBuf};

/// The shared data folder `artdeco_o2a` (`../shared/data` beside the repository, or
/// `SIMULATOR_SHARED_DATA`), if present.
pub fn shared_dir() -> Option<PathBuf> {
    let p = std::env::var_os("SIMULATOR_SHARED_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data"))
        .join("artdeco_o2a");
    p.join("artdeco_lbl_nstr_32_ray_O2.dat")
        .exists()
        .then_some(p)
}

/// A cumulative optical-depth file: `cum[level][wavelength]`, levels from TOA (120 km) down.
pub struct Cumulative {
    pub wavelengths: Vec<f64>,
    pub altitudes: Vec<f64>,
    pub cum: Vec<Vec<f64>>,
}

pub fn read_cumulative(path: &Path) -> Cumulative {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text
        .lines()
        .filter(|l| !l.trim_start().starts_with('#') && !l.trim().is_empty());
    let mut next_numbers = || -> Vec<f64> {
        lines
            .next()
            .unwrap_or_else(|| panic!("{}: truncated", path.display()))
            .split_whitespace()
            .map(|x| x.parse().unwrap())
            .collect()
    };
    let nwl = next_numbers()[0] as usize;
    let nalt = next_numbers()[0] as usize;
    let wavelengths = next_numbers();
    assert_eq!(wavelengths.len(), nwl, "{}", path.display());
    let (mut altitudes, mut cum) = (Vec::new(), Vec::new());
    for _ in 0..nalt {
        let row = next_numbers();
        assert_eq!(row.len(), nwl + 1, "{}", path.display());
        altitudes.push(row[0]);
        cum.push(row[1..].to_vec());
    }
    Cumulative {
        wavelengths,
        altitudes,
        cum,
    }
}

/// Optical thickness of layer `l` (0 = the top one) at wavelength index `k`.
pub fn layer(od: &Cumulative, l: usize, k: usize) -> f64 {
    let d = od.cum[l + 1][k] - od.cum[l][k];
    assert!(d > -1e-12, "negative layer optical thickness {d}");
    d.max(0.0)
}

/// Analytic single-scattering BRF of Rayleigh (depolarization 0) + gas layers over a black
/// surface (exact for homogeneous layers), at wavelength index `k`; angles in degrees.
pub fn single_scattering(
    gas: &Cumulative,
    ray: &Cumulative,
    k: usize,
    sza: f64,
    vza: f64,
    raa: f64,
) -> f64 {
    let (mu0, mu) = (sza.to_radians().cos(), vza.to_radians().cos());
    let sun = engine::frame::direction_from_angles(sza.to_radians(), 0.0);
    let view = engine::frame::direction_from_angles(vza.to_radians(), raa.to_radians());
    // Incident propagation direction −sun, scattered along view.
    let c = -sun.dot(view);
    let phase = 0.75 * (1.0 + c * c);
    let m = 1.0 / mu0 + 1.0 / mu;
    let (mut above, mut sum) = (0.0, 0.0);
    for l in 0..gas.altitudes.len() - 1 {
        let (s, a) = (layer(ray, l, k), layer(gas, l, k));
        let e = s + a;
        if e > 0.0 {
            sum += s / e * (-above * m).exp() * -(-e * m).exp_m1() / m;
        }
        above += e;
    }
    phase * sum / (4.0 * mu0 * mu)
}
