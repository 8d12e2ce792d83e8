//! `simulate`: run Monte Carlo radiative-transfer experiments.
//!
//! Exit codes: 0 success; 2 bad input (experiment file unreadable or invalid); 1 any other
//! failure (an output that cannot be written, an internal error).

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context;
use clap::{Parser, Subcommand};

use simulator::config::Experiment;
use simulator::error::ConfigError;
use simulator::products;

#[derive(Parser)]
#[command(
    name = "simulate",
    version,
    about = "Monte Carlo radiative transfer for Earth-observation scenes"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run an experiment and write OUTDIR/results.nc and OUTDIR/results.csv.
    Run {
        /// Experiment file (TOML; keys in docs/experiment.md).
        experiment: PathBuf,
        /// Output folder (created if missing).
        #[arg(short, long, default_value = "out")]
        output: PathBuf,
        /// Worker threads (default: all cores). Results do not depend on it.
        #[arg(short = 'j', long)]
        threads: Option<usize>,
        /// No progress bar.
        #[arg(short, long)]
        quiet: bool,
        /// Ignore checkpoints of an earlier, interrupted run in OUTDIR/checkpoints.
        #[arg(long)]
        fresh: bool,
        /// Run only shard K of N (`K/N`, K from 0): its (wavelength, measure) tasks are written to
        /// OUTDIR/checkpoints; copy the checkpoints of all shards into one OUTDIR/checkpoints and
        /// run without --shard there to write the products (nothing is recomputed).
        #[arg(long)]
        shard: Option<String>,
        /// Replace every measure's `spp` by N (quick runs, e.g. the examples in CI);
        /// `target_rel_stderr` still applies.
        #[arg(long, value_name = "N")]
        spp: Option<u64>,
    },
    /// Simulated TOA reflectance of a calibration site for a list of acquisitions
    /// (time_utc,vza,vaa,srf); writes OUTDIR/pics.csv and OUTDIR/pics.nc.
    Pics {
        /// Acquisitions CSV.
        acquisitions: PathBuf,
        /// Site file (TOML; see the `pics` module docs / docs/pics.md).
        #[arg(long)]
        site: PathBuf,
        #[arg(short, long, default_value = "out")]
        output: PathBuf,
        #[arg(short = 'j', long)]
        threads: Option<usize>,
        #[arg(short, long)]
        quiet: bool,
    },
    /// Validate an experiment file without running it.
    Check { experiment: PathBuf },
    /// 3D-scene benchmark on a bundle: set-up time, memory, ray rates, time to render an ortho
    /// image to a median relative standard error (see BENCHMARKS.md).
    BenchScene {
        /// Scene bundle (from `scenegen build`).
        bundle: PathBuf,
        /// Ortho pixel size, m.
        #[arg(long, default_value_t = 1000.0)]
        pixel: f64,
        /// Target median relative standard error of the pixels.
        #[arg(long, default_value_t = 0.005)]
        target: f64,
        /// Primary rays to time (one thread).
        #[arg(long, default_value_t = 1_000_000)]
        rays: usize,
        #[arg(long)]
        threads: Option<usize>,
    },
    /// Thick polarized media: standard errors of the polarized walk against the scalar one and
    /// against the scatter over seeds (see BENCHMARKS.md).
    BenchPolarized {
        /// Walks per seed (per direction for the backward walk).
        #[arg(long, default_value_t = 20_000)]
        walks: u64,
        /// Seeds per case.
        #[arg(long, default_value_t = 30)]
        seeds: u64,
        /// Walk: forward, backward or both.
        #[arg(long, default_value = "both")]
        method: String,
        /// Optical thicknesses, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "8,16")]
        taus: Vec<f64>,
        #[arg(short = 'j', long)]
        threads: Option<usize>,
    },
    /// Time-to-precision benchmark on the reference workload (see BENCHMARKS.md).
    Bench {
        /// Target relative standard error in every direction.
        #[arg(long, default_value_t = 1e-3)]
        target: f64,
        /// Walk: forward, backward or both.
        #[arg(long, default_value = "both")]
        method: String,
        /// Polarized (Stokes) transport.
        #[arg(long)]
        polarized: bool,
        /// Spherical-shell geometry (Earth radius) instead of plane-parallel.
        #[arg(long)]
        spherical: bool,
        #[arg(short = 'j', long)]
        threads: Option<usize>,
    },
}

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()),
        )
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    let cli = Cli::parse();
    match dispatch(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            for cause in e.chain().skip(1) {
                eprintln!("  caused by: {cause}");
            }
            if e.chain().any(|c| c.downcast_ref::<ConfigError>().is_some()) {
                ExitCode::from(2)
            } else {
                ExitCode::from(1)
            }
        }
    }
}

fn set_threads(threads: Option<usize>) -> anyhow::Result<()> {
    if let Some(n) = threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n.max(1))
            .build_global()
            .context("thread pool")?;
    }
    Ok(())
}

fn dispatch(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Check { experiment } => {
            let exp = Experiment::load(&experiment)?;
            println!(
                "{}: valid ({} wavelength(s), {} measure(s))",
                experiment.display(),
                exp.wavelengths.len(),
                exp.measures.len()
            );
            // What the surfaces have to say beyond their parameters (tabulated BRDFs: file,
            // grids, reciprocity error), once each.
            let mut infos: Vec<String> = Vec::new();
            for o in &exp.optics {
                let scene = o.scene_models.iter().filter_map(|m| match m {
                    simulator::scene::material::SurfaceModel::Opaque(b) => Some(b),
                    _ => None,
                });
                for b in std::iter::once(&o.surface).chain(scene) {
                    if let Some(i) = b.info().filter(|i| !infos.contains(i)) {
                        infos.push(i);
                    }
                }
            }
            for i in infos {
                println!("  {i}");
            }
            Ok(())
        }
        Command::Run {
            experiment,
            output,
            threads,
            quiet,
            fresh,
            shard,
            spp,
        } => {
            set_threads(threads)?;
            let exp = Experiment::load_with_spp(&experiment, spp)?;
            std::fs::create_dir_all(&output)
                .with_context(|| format!("cannot create output folder {}", output.display()))?;
            // One run per output folder (shards share theirs by design).
            let _lock = match shard {
                None => Some(simulator::output_lock::lock(&output)?),
                Some(_) => None,
            };
            let t0 = Instant::now();
            tracing::info!(
                "running {} ({} wavelength(s), {} measure(s)) on {} thread(s)",
                experiment.display(),
                exp.wavelengths.len(),
                exp.measures.len(),
                rayon::current_num_threads()
            );
            let ckpt = output.join("checkpoints");
            if fresh {
                let _ = std::fs::remove_dir_all(&ckpt);
            }
            let (shard, shards) = match &shard {
                None => (0, 1),
                Some(s) => parse_shard(s).map_err(|m| {
                    anyhow::Error::new(ConfigError::Invalid {
                        path: experiment.clone(),
                        key: "--shard".into(),
                        message: m,
                    })
                })?,
            };
            let (results, resumed) = simulator::run::run_shard(&exp, !quiet, &ckpt, shard, shards)?;
            if resumed > 0 {
                tracing::info!(
                    "resumed {resumed} completed task(s) from {}",
                    ckpt.display()
                );
            }
            let missing = results.iter().filter(|r| r.is_none()).count();
            if missing > 0 {
                tracing::info!(
                    "shard {shard}/{shards} done: its tasks are in {}; {missing} task(s) of other shards are still missing, \
                     so no products were written",
                    ckpt.display()
                );
                return Ok(());
            }
            let results: Vec<_> = results.into_iter().flatten().collect();
            let rows = products::rows(&exp, &results);
            let csv = output.join("results.csv");
            let nc = output.join("results.nc");
            products::csv::write(&csv, &rows)?;
            let band = products::band_rows(&exp, &rows);
            let images = products::imagery::image_products(&exp, &results);
            products::netcdf::write(&nc, &exp, &rows, &band, &images)?;
            for img in &images {
                let (files, what) = products::imagery::write_files(&output, &exp, img)?;
                for f in &files {
                    println!("{:<16} wrote {}", img.id, f.display());
                }
                println!(
                    "{:<16} {} × {} px, quicklook: {what}",
                    img.id, img.width, img.height
                );
                for (w, (b, e, s)) in exp.wavelengths.iter().zip(products::imagery::medians(img)) {
                    println!(
                        "{:<16} {w:>8.2} nm: median BRF {b:.5}, median rel. stderr {:.3}%, median single-scattering fraction {:.3}",
                        img.id,
                        100.0 * e,
                        s
                    );
                }
            }
            if !band.is_empty() {
                let path = output.join("results_band.csv");
                products::csv::write_band(&path, &band)?;
                for b in &band {
                    if let Some((v, e)) = b.brf.or(b.albedo) {
                        println!(
                            "{:<16} band {:<22} vza {:>8} BRF/albedo {v:.5} ± {e:.1e}",
                            b.measure,
                            b.band,
                            b.vza.map(|z| format!("{z:.2}")).unwrap_or("-".into())
                        );
                    }
                }
            }
            print_summary(&rows);
            // Products are complete: the checkpoints are no longer needed.
            let _ = std::fs::remove_dir_all(&ckpt);
            tracing::info!(
                "done in {:.2} s: wrote {} and {}",
                t0.elapsed().as_secs_f64(),
                csv.display(),
                nc.display()
            );
            Ok(())
        }
        Command::Pics {
            acquisitions,
            site,
            output,
            threads,
            quiet,
        } => {
            set_threads(threads)?;
            let acqs = simulator::pics::read_acquisitions(&acquisitions)?;
            std::fs::create_dir_all(&output)
                .with_context(|| format!("cannot create output folder {}", output.display()))?;
            let bar = if quiet {
                indicatif::ProgressBar::hidden()
            } else {
                indicatif::ProgressBar::new(acqs.len() as u64)
            };
            let rows = simulator::pics::run(&site, &acqs, |k| bar.set_position(k as u64))?;
            bar.finish_and_clear();
            let csv = output.join("pics.csv");
            products::write_atomic(&csv, simulator::pics::to_csv(&rows).as_bytes())?;
            simulator::pics::write_netcdf(&output.join("pics.nc"), &site, &rows)?;
            for r in &rows {
                println!(
                    "{}  {:<20} sza {:6.2} vza {:5.1}  reflectance {:.5} ± {:.1e}",
                    r.acquisition.time_utc,
                    r.acquisition.srf,
                    r.sza,
                    r.acquisition.vza,
                    r.reflectance.0,
                    r.reflectance.1
                );
            }
            tracing::info!(
                "wrote {} and {}",
                csv.display(),
                output.join("pics.nc").display()
            );
            Ok(())
        }
        Command::BenchScene {
            bundle,
            pixel,
            target,
            rays,
            threads,
        } => {
            set_threads(threads)?;
            simulator::bench_scene::run(&bundle, pixel, target, rays)
        }
        Command::BenchPolarized {
            walks,
            seeds,
            method,
            taus,
            threads,
        } => {
            set_threads(threads)?;
            simulator::bench_polarized::run(walks, seeds, &method, &taus)
        }
        Command::Bench {
            target,
            method,
            polarized,
            spherical,
            threads,
        } => {
            set_threads(threads)?;
            simulator::bench::run(target, &method, polarized, spherical)
        }
    }
}

/// `K/N` with 0 ≤ K < N.
fn parse_shard(s: &str) -> Result<(usize, usize), String> {
    let (k, n) = s
        .split_once('/')
        .ok_or_else(|| format!("\"{s}\" must be K/N, e.g. 0/4"))?;
    let k: usize = k
        .trim()
        .parse()
        .map_err(|_| format!("\"{s}\": K is not a number"))?;
    let n: usize = n
        .trim()
        .parse()
        .map_err(|_| format!("\"{s}\": N is not a number"))?;
    if n == 0 || k >= n {
        return Err(format!("\"{s}\": need 0 <= K < N"));
    }
    Ok((k, n))
}

fn print_summary(rows: &[products::Row]) {
    if rows.is_empty() {
        return;
    }
    println!(
        "{:<16} {:>9} {:>8} {:>8} {:>12} {:>10}",
        "measure", "wl [nm]", "vza", "vaa", "value", "rel.err"
    );
    for r in rows {
        let (name, (v, e)) = match (r.brf, r.albedo, r.radiance, r.flux) {
            (Some(b), _, _, _) => ("brf", b),
            (None, Some(a), _, _) => ("albedo", a),
            (None, None, Some(l), _) => ("radiance", l),
            (None, None, None, Some(f)) => ("flux", f),
            _ => continue,
        };
        let ang = |x: Option<f64>| {
            x.map(|a| format!("{a:8.2}"))
                .unwrap_or_else(|| format!("{:>8}", "-"))
        };
        println!(
            "{:<16} {:>9.2} {} {} {:>8}={:<.5} {:>9.3}%",
            r.measure,
            r.wavelength_nm,
            ang(r.vza),
            ang(r.vaa),
            name,
            v,
            100.0 * e / v.abs().max(1e-300)
        );
    }
}
