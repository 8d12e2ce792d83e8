//! `scenegen bench`: the scale benchmark of issue 3 (numbers go to BENCHMARKS.md, never into
//! tests). It writes a synthetic DEM (Float32 GeoTIFF, UTM 31N, `size_km` square at `spacing_m`)
//! and a synthetic CORINE land cover at 100 m (see [`crate::synth`]), then builds a bundle from
//! them at each tolerance in a child process (`scenegen build --stats-json`), and optionally a
//! given region file (e.g. the real Grenoble DEM) at the same tolerances, and prints a Markdown table: wall time, peak
//! resident memory of the build process, DEM samples, triangles, instances, bundle size, and
//! the time `Bundle::open` takes to load the bundle back (warm page cache).

use std::path::Path;
use std::process::Command;
use std::time::Instant;

use crate::error::ScenegenError;
use crate::info::human_bytes;
use crate::synth;

/// Peak resident memory of this process (VmHWM), bytes (shared with `simulate bench-scene`).
pub use bundle::peak_rss_bytes;

fn dir_size(p: &Path) -> u64 {
    std::fs::read_dir(p)
        .map(|rd| {
            rd.filter_map(|e| e.ok())
                .filter_map(|e| e.metadata().ok())
                .map(|m| m.len())
                .sum()
        })
        .unwrap_or(0)
}

struct Row {
    case: String,
    wall_s: f64,
    peak: u64,
    stats: serde_json::Value,
    size: u64,
    load_s: f64,
}

fn run_build(
    region: &Path,
    out: &Path,
    case: String,
    tolerance: Option<f64>,
) -> Result<Row, ScenegenError> {
    let exe = std::env::current_exe()
        .map_err(|e| ScenegenError::Internal(format!("current exe: {e}")))?;
    let t0 = Instant::now();
    let mut cmd = Command::new(exe);
    cmd.args(["build", "--quiet", "--stats-json", "--force", "-o"])
        .arg(out)
        .arg(region);
    if let Some(t) = tolerance {
        cmd.arg("--tolerance-m").arg(t.to_string());
    }
    let o = cmd
        .output()
        .map_err(|e| ScenegenError::Internal(format!("cannot run the build: {e}")))?;
    let wall_s = t0.elapsed().as_secs_f64();
    if !o.status.success() {
        return Err(ScenegenError::Internal(format!(
            "build of {} failed: {}",
            region.display(),
            String::from_utf8_lossy(&o.stderr)
        )));
    }
    let stdout = String::from_utf8_lossy(&o.stdout);
    let line = stdout
        .lines()
        .find(|l| l.starts_with('{'))
        .ok_or_else(|| ScenegenError::Internal("no stats line".into()))?;
    let stats: serde_json::Value =
        serde_json::from_str(line).map_err(|e| ScenegenError::Internal(e.to_string()))?;
    let peak = stats["peak_rss_bytes"].as_u64().unwrap_or(0);
    let t1 = Instant::now();
    bundle::Bundle::open(out)?;
    let load_s = t1.elapsed().as_secs_f64();
    Ok(Row {
        case,
        wall_s,
        peak,
        size: dir_size(out),
        stats,
        load_s,
    })
}

/// Run the benchmark and print its table.
pub fn run(
    size_km: f64,
    spacing_m: f64,
    tolerances: &[f64],
    workdir: &Path,
    region: Option<&Path>,
    keep: bool,
) -> Result<(), ScenegenError> {
    std::fs::create_dir_all(workdir)
        .map_err(|e| ScenegenError::Internal(format!("{}: {e}", workdir.display())))?;
    let n = (size_km * 1000.0 / spacing_m).round() as usize + 1;
    // UTM 31N around 3° E, 45° N; the region asks for the centre and size, so it reprojects.
    let (e0, n0) = (
        500_000.0 - 0.5 * size_km * 1000.0 - 2000.0,
        4_983_000.0 - 0.5 * size_km * 1000.0 - 2000.0,
    );
    let margin_px = (4000.0 / spacing_m).ceil() as usize;
    let w = n + margin_px;
    let t0 = Instant::now();
    let dem = workdir.join("synthetic_dem.tif");
    let mut h = vec![0f32; w * w];
    for r in 0..w {
        for c in 0..w {
            let x = (c as f64 + 0.5) * spacing_m;
            let y = (w - 1 - r) as f64 * spacing_m + 0.5 * spacing_m;
            h[r * w + c] = synth::terrain_height(x, y) as f32;
        }
    }
    let heights_for_lc = |x: f64, y: f64| synth::terrain_height(x, y);
    synth::write_geotiff(
        &dem,
        w,
        w,
        Some([
            e0,
            spacing_m,
            0.0,
            n0 + w as f64 * spacing_m,
            0.0,
            -spacing_m,
        ]),
        Some("EPSG:32631"),
        Some(-9999.0),
        h,
    )?;
    let lc_px = 100.0;
    let lw = ((w as f64 * spacing_m) / lc_px).floor() as usize;
    let mut lc = vec![0u8; lw * lw];
    for r in 0..lw {
        for c in 0..lw {
            let x = (c as f64 + 0.5) * lc_px;
            let y = (lw - 1 - r) as f64 * lc_px + 0.5 * lc_px;
            lc[r * lw + c] = synth::landcover_code(x, y, heights_for_lc(x, y));
        }
    }
    let lcp = workdir.join("synthetic_corine.tif");
    synth::write_geotiff(
        &lcp,
        lw,
        lw,
        Some([e0, lc_px, 0.0, n0 + lw as f64 * lc_px, 0.0, -lc_px]),
        Some("EPSG:32631"),
        Some(255.0),
        lc,
    )?;
    eprintln!(
        "bench: wrote {} ({w} × {w}) and {} ({lw} × {lw}) in {:.1} s",
        dem.display(),
        lcp.display(),
        t0.elapsed().as_secs_f64()
    );

    let mut rows = Vec::new();
    for &tol in tolerances {
        let region_path = workdir.join(format!("region_tol{tol}.toml"));
        let text = format!(
            "seed = 1\n[area]\ncentre = [3.0, {lat}]\nsize_km = {size_km}\n[dem]\nfiles = [\"synthetic_dem.tif\"]\nspacing_m = {spacing_m}\n[terrain]\ntolerance_m = {tol}\n[landcover]\nfile = \"synthetic_corine.tif\"\nscheme = \"corine\"\n",
            lat = 45.0
        );
        std::fs::write(&region_path, text).map_err(|e| ScenegenError::Internal(e.to_string()))?;
        let out = workdir.join(format!("bundle_tol{tol}"));
        eprintln!("bench: building {} …", region_path.display());
        rows.push(run_build(
            &region_path,
            &out,
            format!("synthetic {size_km} km, {spacing_m} m, tolerance {tol} m"),
            None,
        )?);
    }
    if let Some(r) = region {
        for &tol in tolerances {
            let out = workdir.join(format!("bundle_region_tol{tol}"));
            eprintln!("bench: building {} at tolerance {tol} m …", r.display());
            rows.push(run_build(
                r,
                &out,
                format!("{}, tolerance {tol} m", r.display()),
                Some(tol),
            )?);
        }
    }
    println!("| case | wall [s] | peak RSS | DEM samples | triangles | vertices | instances | bundle size | load [s] | stages [s] |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for r in &rows {
        let s = &r.stats;
        let stages = s["stages"]
            .as_object()
            .map(|m| {
                m.iter()
                    .map(|(k, v)| format!("{k} {:.1}", v.as_f64().unwrap_or(0.0)))
                    .collect::<Vec<_>>()
                    .join(", ")
            })
            .unwrap_or_default();
        println!(
            "| {} | {:.1} | {} | {} | {} | {} | {} | {} | {:.2} | {} |",
            r.case,
            r.wall_s,
            human_bytes(r.peak),
            s["dem_samples"],
            s["triangles"],
            s["vertices"],
            s["instances"],
            human_bytes(r.size),
            r.load_s,
            stages
        );
    }
    if !keep {
        let _ = std::fs::remove_dir_all(workdir);
    }
    Ok(())
}
