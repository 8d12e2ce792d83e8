//! Memory a run will need, estimated from the resolved experiment before any sample is drawn,
//! so that an absurd request (10⁷-pixel images at 100 wavelengths) is refused with the figure
//! and the key that drives it instead of aborting on allocation hours later.
//!
//! Estimate: every (wavelength, measure) result stays in memory until the products are
//! written. A result cell holds its accumulators ([`crate::accum::Accum`]: the count, sums and
//! sums of squares per Stokes component, cross products when polarized, third and fourth
//! powers and maximum of I): 80 bytes scalar, 152 polarized; products add half as much again;
//! images whose lamps come from forward photons hold an added estimate per cell (48 bytes)
//! and, while the photons run, their batch sums.
//! The scene is already loaded by the time this runs, and its own figure is added.
//! Refused above the machine's total memory (`/proc/meminfo`; no limit where it is unknown).

use crate::config::experiment::Experiment;
use crate::error::ConfigError;
use crate::measure::MeasureKind;

/// Bytes per result cell and wavelength: accumulators plus half again for the products.
fn cell_bytes(polarized: bool, replicates: bool) -> u64 {
    let mut acc: u64 = if polarized { 152 } else { 80 };
    if replicates {
        // Quasi-random runs: per replicate a count and the component sums (`accum.rs`).
        let ncomp: u64 = if polarized { 6 } else { 3 };
        acc += crate::accum::REPLICATES as u64 * 8 * (1 + ncomp);
    }
    acc + acc / 2
}

/// The estimate and the measure that weighs most.
#[derive(Clone, Debug, PartialEq)]
pub struct MemoryEstimate {
    pub results_bytes: u64,
    pub scene_bytes: u64,
    /// The key that sizes the heaviest measure (e.g. `measures[0].pixel_size_m`) and its bytes.
    pub heaviest: Option<(String, u64)>,
}

impl MemoryEstimate {
    pub fn total(&self) -> u64 {
        self.results_bytes.saturating_add(self.scene_bytes)
    }
}

/// The key of measure `k` that sets its number of cells.
fn size_key(k: usize, kind: &MeasureKind) -> String {
    match kind {
        MeasureKind::Ortho(_) => format!("measures[{k}].pixel_size_m"),
        MeasureKind::Perspective(_) => format!("measures[{k}].width"),
        MeasureKind::Distant { .. } => format!("measures[{k}].directions"),
        MeasureKind::Hdrf { .. } => format!("measures[{k}].zeniths"),
        MeasureKind::Radiancemeter { .. } | MeasureKind::DistantFlux { .. } => {
            format!("measures[{k}]")
        }
    }
}

pub fn estimate(exp: &Experiment) -> MemoryEstimate {
    let nw = exp.wavelengths.len() as u64;
    let per = cell_bytes(
        exp.polarized,
        exp.integrator.sampler == crate::integrator::settings::Sampler::Sobol,
    );
    let mut results: u64 = 0;
    let mut heaviest: Option<(String, u64)> = None;
    for (k, m) in exp.measures.iter().enumerate() {
        // Lamps by forward photons (`integrator/lamp_photons.rs`): the added estimate's means
        // and variances (48 B per cell and wavelength), and while a wavelength's photons run
        // its batch sums and a few batch images (about 128 B per cell).
        let photons: u64 = if exp.lamp_photon_pixels(m).is_some() {
            48
        } else {
            0
        };
        let b = (m.cell_count() as u64)
            .saturating_mul(nw)
            .saturating_mul(per + photons)
            .saturating_add((m.cell_count() as u64).saturating_mul(128 * (photons > 0) as u64));
        results = results.saturating_add(b);
        if heaviest.as_ref().is_none_or(|(_, h)| b > *h) {
            heaviest = Some((size_key(k, &m.kind), b));
        }
    }
    MemoryEstimate {
        results_bytes: results,
        // The scene's own figure plus a cloud field's cells (`[[clouds]]`).
        scene_bytes: exp.scene.as_ref().map_or(0, |s| s.memory_bytes as u64)
            + exp.clouds.as_ref().map_or(0, |c| c.bytes as u64),
        heaviest,
    }
}

/// Total memory of this machine, bytes (Linux), or None.
pub fn total_memory() -> Option<u64> {
    bundle::meminfo_bytes("MemTotal:")
}

/// Human-readable bytes (MiB or GiB).
pub fn human(bytes: u64) -> String {
    let mib = bytes as f64 / (1u64 << 20) as f64;
    if mib >= 1024.0 {
        format!("{:.1} GiB", mib / 1024.0)
    } else {
        format!("{mib:.1} MiB")
    }
}

/// Refuse an experiment whose estimate exceeds `limit` bytes (the machine's memory).
pub fn check(exp: &Experiment, limit: Option<u64>) -> Result<MemoryEstimate, ConfigError> {
    let e = estimate(exp);
    if let Some(limit) = limit {
        if e.total() > limit {
            let (key, b) = e.heaviest.clone().unwrap_or_else(|| ("measures".into(), 0));
            return Err(ConfigError::Invalid {
                path: exp.source_path.clone(),
                key,
                message: format!(
                    "the run would need about {} of memory ({} for results, this measure {} over {} wavelength(s); {} for the scene), more than this machine's {}: use larger pixels, a window, fewer pixels or fewer wavelengths",
                    human(e.total()),
                    human(e.results_bytes),
                    human(b),
                    exp.wavelengths.len(),
                    human(e.scene_bytes),
                    human(limit)
                ),
            });
        }
    }
    Ok(e)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn experiment(nw: usize, zeniths: usize) -> Experiment {
        let wl: Vec<String> = (0..nw).map(|k| format!("{}.0", 400 + k)).collect();
        let z: Vec<String> = (0..zeniths)
            .map(|k| format!("{:.3}", -80.0 + 160.0 * k as f64 / zeniths.max(2) as f64))
            .collect();
        let text = format!(
            "[spectral]\nwavelengths = [{}]\n[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = 0.1\nsingle_scattering_albedo = 1.0\nphase = {{ type = \"rayleigh\" }}\n[surface]\ntype = \"lambertian\"\nreflectance = 0.3\n[illumination]\ntype = \"directional\"\nzenith = 30.0\nazimuth = 0.0\n[[measures]]\nid = \"pp\"\ntype = \"mdistant\"\nconstruct = \"hplane\"\nazimuth = 0.0\nzeniths = [{}]\nspp = 10\n",
            wl.join(", "),
            z.join(", ")
        );
        Experiment::from_str(&text, Path::new("mem.toml")).unwrap()
    }

    /// The estimate is cells × wavelengths × bytes per cell, and a run above the limit is
    /// refused naming the file, the measure's sizing key and the figures.
    #[test]
    fn estimate_scales_and_refuses_above_the_limit() {
        let e = estimate(&experiment(3, 11));
        assert_eq!(e.results_bytes, 11 * 3 * cell_bytes(false, false));
        assert_eq!(e.heaviest.as_ref().unwrap().0, "measures[0].directions");
        let big = experiment(20, 101);
        assert!(check(&big, Some(u64::MAX)).is_ok());
        assert!(check(&big, None).is_ok());
        let msg = check(&big, Some(100_000)).unwrap_err().to_string();
        for n in [
            "mem.toml",
            "measures[0].directions",
            "20 wavelength(s)",
            "MiB",
        ] {
            assert!(msg.contains(n), "`{n}` not in {msg}");
        }
    }
}
