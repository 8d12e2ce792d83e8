//! `simulate bench-image EXP.toml`: what an image of a scene costs at the sensor's resolution
//! (issue 45, BENCHMARKS.md, `docs/scaling.md`).
//!
//! Runs the experiment's first image measure at a fixed number of samples per pixel (its `spp`,
//! or `--spp`; `target_rel_stderr` is ignored so that every pixel gets the same budget) and
//! prints, per band:
//! * the median relative standard error σ at `n` samples, and the per-sample spread `σ·√n`
//!   (the relative standard deviation of one sample of the median pixel);
//! * the samples per pixel to reach `--target` at the median pixel, `n_t = (σ√n / target)²`
//!   (per band: `--target` times the band's target over the tightest when the measure lists
//!   per-band targets, `target_rel_stderr = [...]`);
//! * the CPU per sample of all bands together: `(CPU of the run − CPU of the set-up) / (pixels
//!   × n)`, process CPU (every thread), so the figure does not depend on the thread count;
//!
//! then the projection for a square tile of `--tile-km` at the measure's pixel size:
//! `core-hours = pixels × max_b n_t,b × CPU per sample / 3600` (the band that needs the most
//! samples sets them for all: one walk serves every band of a group). With `--native s2` it
//! adds the projection for Sentinel-2's native resolutions (10 m: 490, 560, 665, 842 nm; 20 m:
//! 705, 740, 783, 865, 1610, 2190 nm; 60 m: 443, 945, 1375 nm): each resolution class is its own
//! run of its bands at its pixel count and its worst band's `n_t`, with the CPU per sample
//! scaled by the class's share of the wavelength groups (`⌈bands/8⌉` walks per sample with
//! grouped walks, one per band otherwise); this scaling is an assumption, stated in the output.
//!
//! The per-sample spread and the CPU per sample are properties of the scene, the atmosphere and
//! the estimator at this pixel size; the projection assumes the tile looks like the measured
//! window (land-cover mix, relief), which the user chooses.

use std::path::Path;
use std::time::Instant;

use engine::config::Experiment;

/// Sentinel-2 MSI band centres (nm) by native resolution (m), for `--native s2`.
const S2_NATIVE: [(f64, &[f64]); 3] = [
    (10.0, &[490.0, 560.0, 665.0, 842.0]),
    (20.0, &[705.0, 740.0, 783.0, 865.0, 1610.0, 2190.0]),
    (60.0, &[443.0, 945.0, 1375.0]),
];

/// Sentinel-2 MSI band numbers by native resolution (m), for `--native s2` over runs with
/// sensor bands (`spectral.bands`, matched by name: `sentinel_2a-msi-8a` is band "8a").
const S2_NATIVE_BANDS: [(f64, &[&str]); 3] = [
    (10.0, &["2", "3", "4", "8"]),
    (20.0, &["5", "6", "7", "8a", "11", "12"]),
    (60.0, &["1", "9", "10"]),
];

/// One band's figures.
struct Band {
    /// The band's name in runs with sensor bands.
    name: Option<String>,
    wavelength: f64,
    /// Its target (`--target`, times its scale when the experiment lists per-band targets).
    target: f64,
    median_rel: f64,
    spread: f64,
    n_target: f64,
}

pub fn run(
    experiment: &Path,
    spp: Option<u64>,
    target: f64,
    tile_km: f64,
    native: Option<&str>,
) -> anyhow::Result<()> {
    let what = experiment.display().to_string();
    super::check_target(&what, target)?;
    super::check_positive(&what, "--tile-km", tile_km, "number of km")?;
    let cpu = || engine::util::cpu_time::process_seconds().unwrap_or(f64::NAN);
    let (c0, t0) = (cpu(), Instant::now());
    let mut exp = Experiment::load_with_spp(experiment, spp)?;
    let im = exp
        .measures
        .iter()
        .position(|m| m.is_image())
        .ok_or_else(|| {
            anyhow::anyhow!(
                "{}: bench-image needs an image measure (type \"ortho\" or \"perspective\")",
                experiment.display()
            )
        })?;
    // One measure, one fixed budget per pixel.
    exp.measures = vec![exp.measures.swap_remove(im)];
    exp.measures[0].target_rel_stderr = None;
    let (c_setup, t_setup) = (cpu() - c0, t0.elapsed().as_secs_f64());
    let (c1, t1) = (cpu(), Instant::now());
    let results = crate::run::run(&exp, false);
    let (c_run, t_run) = (cpu() - c1, t1.elapsed().as_secs_f64());
    let m = &exp.measures[0];
    let pixels = m.cell_count();
    let n = results
        .iter()
        .flat_map(|r| r.acc.n.iter().copied())
        .min()
        .unwrap_or(0);
    anyhow::ensure!(n > 0, "no samples were drawn");
    let pixel_m = match &m.kind {
        engine::measure::MeasureKind::Ortho(g) => Some(g.geotransform[1].abs()),
        _ => None,
    };
    let mut bands: Vec<Band> = results
        .iter()
        .map(|r| {
            let median_rel = r.acc.median_rel_stderr();
            let spread = median_rel * (n as f64).sqrt();
            // Per-band targets in the experiment (`target_rel_stderr` as a list) scale `target`
            // as they scale the tightest of them.
            let t = target * m.target_scale.get(r.wavelength).copied().unwrap_or(1.0);
            Band {
                name: exp.bands.as_ref().map(|b| b.names[r.wavelength].clone()),
                wavelength: exp.wavelengths[r.wavelength],
                median_rel,
                spread,
                target: t,
                n_target: (spread / t).powi(2),
            }
        })
        .collect();
    bands.sort_by(|a, b| a.wavelength.total_cmp(&b.wavelength));
    let us_per_sample = 1e6 * c_run / (pixels as f64 * n as f64);
    let groups =
        engine::spectral::wavelength_groups_of(&exp.wavelengths, exp.integrator.spectral_alis)
            .len();
    println!("experiment: {}", experiment.display());
    println!(
        "measure `{}`: {pixels} pixels{}, {n} samples per pixel, {} band(s) in {groups} walk(s) per sample ({})",
        m.id,
        pixel_m.map_or(String::new(), |p| format!(" of {p} m")),
        exp.wavelengths.len(),
        match exp.integrator.spectral_alis {
            Some(_) => "grouped ALIS walks",
            None => "independent walks",
        }
    );
    println!(
        "set-up {t_setup:.2} s wall ({c_setup:.2} CPU s); render {t_run:.2} s wall, {c_run:.2} CPU s on {} thread(s): {us_per_sample:.2} CPU µs per sample of all bands",
        rayon::current_num_threads()
    );
    println!(
        "\n{:>9} {:>12} {:>14} {:>9} {:>16}  band",
        "band nm", "median σ %", "spread σ√n", "target %", "spp for target"
    );
    for b in &bands {
        println!(
            "{:>9.1} {:>12.3} {:>14.4} {:>9.2} {:>16.0}  {}",
            b.wavelength,
            100.0 * b.median_rel,
            b.spread,
            100.0 * b.target,
            b.n_target.ceil(),
            b.name.as_deref().unwrap_or("")
        );
    }
    let worst = bands
        .iter()
        .max_by(|a, b| a.n_target.total_cmp(&b.n_target))
        .expect("at least one band");
    println!(
        "\nto {} at the median pixel of every band: {:.0} samples per pixel (set by {:.1} nm)",
        if m.target_scale.is_empty() {
            format!("{:.2} %", 100.0 * target)
        } else {
            "its target".to_string()
        },
        worst.n_target.ceil(),
        worst.wavelength
    );
    if let Some(p) = pixel_m {
        let tile_px = (tile_km * 1000.0 / p).powi(2);
        let hours = tile_px * worst.n_target * us_per_sample * 1e-6 / 3600.0;
        println!("a {tile_km} km tile at {p} m ({tile_px:.3e} pixels): {hours:.0} core-hours");
    }
    match native {
        None => {}
        Some("s2") => native_s2(&bands, us_per_sample, groups, tile_km, &exp),
        Some(other) => anyhow::bail!("--native: unknown sensor \"{other}\" (known: s2)"),
    }
    Ok(())
}

/// The projection at Sentinel-2's native resolutions (module header).
fn native_s2(bands: &[Band], us_per_sample: f64, groups: usize, tile_km: f64, exp: &Experiment) {
    let group = exp.integrator.spectral_alis;
    let mut total = 0.0;
    println!(
        "\nSentinel-2 native resolutions (assumption: CPU per sample ∝ walks per sample, {groups} here):"
    );
    for ((res, centres), (_, numbers)) in S2_NATIVE.iter().zip(S2_NATIVE_BANDS) {
        let members: Vec<&Band> = bands
            .iter()
            .filter(|b| match &b.name {
                // Sensor bands by name (their effective wavelengths are not the nominal centres).
                Some(n) => {
                    let number = n.rsplit('-').next().unwrap_or("");
                    n.starts_with("sentinel_2") && numbers.contains(&number)
                }
                None => centres.iter().any(|c| (c - b.wavelength).abs() < 1.0),
            })
            .collect();
        if members.is_empty() {
            println!("  {res} m: none of its bands is in the experiment");
            continue;
        }
        let class: Vec<f64> = members.iter().map(|b| b.wavelength).collect();
        let walks = engine::spectral::wavelength_groups_of(&class, group).len();
        let n_t = members.iter().map(|b| b.n_target).fold(0.0f64, f64::max);
        let px = (tile_km * 1000.0 / res).powi(2);
        let hours = px * n_t * us_per_sample * (walks as f64 / groups as f64) * 1e-6 / 3600.0;
        total += hours;
        println!(
            "  {res:>4} m: {} band(s), {walks} walk(s) per sample, {:.0} samples per pixel, {hours:.1} core-hours",
            members.len(),
            n_t.ceil()
        );
    }
    println!("  total for a {tile_km} km tile: {total:.0} core-hours");
}
