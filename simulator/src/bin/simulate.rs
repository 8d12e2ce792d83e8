//! `simulate`: run Monte Carlo radiative-transfer experiments.
//!
//! Exit codes: 0 success; 2 bad input (experiment file unreadable or invalid); 1 any other
//! failure (an output that cannot be written, an internal error).
//!
//! Logging (stderr): INFO by default; `-q` warnings and errors only (and no progress bar), `-v`
//! debug, `-vv` trace; `RUST_LOG` (e.g. `RUST_LOG=engine=debug,simulator=debug`: the engine's and the application's logs) overrides all three.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context;
use clap::{Parser, Subcommand};

use engine::config::Experiment;
use engine::error::ConfigError;
use simulator::products;

#[derive(Parser)]
#[command(
    name = "simulate",
    version,
    about = "Monte Carlo radiative transfer for Earth-observation scenes"
)]
struct Cli {
    #[command(flatten)]
    verbosity: Verbosity,
    #[command(subcommand)]
    command: Command,
}

/// Log level flags, accepted before or after the subcommand.
#[derive(clap::Args)]
struct Verbosity {
    /// Quiet: only warnings and errors on stderr, and no progress bar.
    #[arg(short, long, global = true, conflicts_with = "verbose")]
    quiet: bool,
    /// More log output: -v debug, -vv trace (RUST_LOG, if set, overrides -q and -v).
    #[arg(short, long, global = true, action = clap::ArgAction::Count)]
    verbose: u8,
}

impl Verbosity {
    /// The log filter: `RUST_LOG` when set, else the flags' level.
    fn filter(&self) -> tracing_subscriber::EnvFilter {
        let level = match (self.quiet, self.verbose) {
            (true, _) => "warn",
            (false, 0) => "info",
            (false, 1) => "debug",
            (false, _) => "trace",
        };
        tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| level.into())
    }
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
        /// Ignore checkpoints of an earlier, interrupted run in OUTDIR/checkpoints.
        #[arg(long)]
        fresh: bool,
        /// Run only shard K of N (`K/N`, K from 0): its work units ((wavelength, measure) tasks,
        /// or pixel tiles of images without a target) are written to OUTDIR/checkpoints; copy the
        /// checkpoints of all shards into one OUTDIR/checkpoints and run without --shard there to
        /// write the products (nothing is recomputed), or use `simulate plan` and `simulate merge`.
        #[arg(long)]
        shard: Option<String>,
        /// Replace every measure's `spp` by N (quick runs, e.g. the examples in CI);
        /// `target_rel_stderr` still applies.
        #[arg(long, value_name = "N")]
        spp: Option<u64>,
    },
    /// Split a run over a Slurm cluster: write OUTDIR/plan.toml and the job-array script
    /// OUTDIR/job.sh (submit it with sbatch; then `simulate merge OUTDIR`; docs/scaling.md).
    Plan {
        /// Experiment file (TOML; keys in docs/experiment.md).
        experiment: PathBuf,
        /// Number of shards (array tasks).
        #[arg(long)]
        shards: usize,
        /// Plan folder (created): manifest, script, and the shards' folders and logs.
        #[arg(short, long)]
        output: PathBuf,
        /// Replace every measure's `spp` by N in every shard (as `run --spp`).
        #[arg(long, value_name = "N")]
        spp: Option<u64>,
        /// CPUs of each array task (its `simulate` runs that many threads).
        #[arg(long, default_value_t = 4)]
        cpus_per_task: usize,
        /// Memory of each task in Slurm's syntax, e.g. 8G (default: measured, see docs/scaling.md).
        #[arg(long)]
        mem: Option<String>,
        /// Time limit of each task in Slurm's syntax, e.g. 02:00:00 (default: measured).
        #[arg(long)]
        time: Option<String>,
        /// Slurm partition.
        #[arg(long)]
        partition: Option<String>,
        /// Slurm account.
        #[arg(long)]
        account: Option<String>,
        /// Worker threads of the pilot that times the run (default: all cores).
        #[arg(short = 'j', long)]
        threads: Option<usize>,
    },
    /// Check that every shard of a plan is complete and consistent, and write the products
    /// into the plan folder (as `simulate run` writes them, bit for bit).
    Merge {
        /// Plan folder (from `simulate plan`).
        plan: PathBuf,
    },
    /// Write a generated field of fair-weather cumulus (netCDF, the `[[clouds]] file` format;
    /// model in engine/src/clouds/cumulus.rs) covering a rectangle of the scene's frame.
    CloudField {
        /// Output netCDF file.
        #[arg(short, long)]
        output: PathBuf,
        /// The rectangle, xmin,ymin,xmax,ymax (m, the scene's frame: a bundle's working CRS).
        #[arg(
            long,
            value_delimiter = ',',
            allow_negative_numbers = true,
            required = true
        )]
        extent: Vec<f64>,
        /// Column size (m).
        #[arg(long, default_value_t = 200.0)]
        dx: f64,
        /// Level spacing (m).
        #[arg(long, default_value_t = 100.0)]
        dz: f64,
        /// Cloud base altitude (m).
        #[arg(long, default_value_t = 3000.0)]
        base: f64,
        /// Number of clouds.
        #[arg(long, default_value_t = 60)]
        count: usize,
        /// Smallest and largest cloud radius (m).
        #[arg(long, value_delimiter = ',', default_values_t = [400.0, 1500.0])]
        radius: Vec<f64>,
        /// Cloud depth over radius.
        #[arg(long, default_value_t = 1.0)]
        aspect: f64,
        /// Fraction of the adiabatic liquid water content.
        #[arg(long, default_value_t = 0.5)]
        adiabatic_fraction: f64,
        /// Droplet effective radius (µm).
        #[arg(long, default_value_t = 10.0)]
        r_eff_um: f64,
        /// Seed of the clouds' positions and sizes.
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
    /// Surface temperatures through a diurnal cycle from a heat-conduction energy balance
    /// (keys in docs/temperatures.md): writes OUTDIR/lst_HHMM.tif for each local time (the
    /// `scene.land_surface_temperature` of thermal runs), OUTDIR/materials.csv,
    /// OUTDIR/diurnal.csv and OUTDIR/temperatures_HHMM.csv (a `scene.temperature_table`).
    Temperatures {
        /// Temperature-solver file (TOML; keys in docs/temperatures.md).
        config: PathBuf,
        /// Output folder (created if missing).
        #[arg(short, long, default_value = "out")]
        output: PathBuf,
        /// Worker threads (default: all cores). Results do not depend on it.
        #[arg(short = 'j', long)]
        threads: Option<usize>,
    },
    /// Simulated TOA reflectance of a calibration site for a list of acquisitions
    /// (columns time_utc,vza,vaa,srf and optionally sza,saa); writes OUTDIR/pics.csv and OUTDIR/pics.nc.
    Pics {
        /// Acquisitions CSV (columns in docs/pics.md).
        acquisitions: PathBuf,
        /// Site file (TOML; see the `pics` module docs / docs/pics.md).
        #[arg(long)]
        site: PathBuf,
        /// Output folder (created if missing).
        #[arg(short, long, default_value = "out")]
        output: PathBuf,
        /// Worker threads (default: all cores). Results do not depend on it.
        #[arg(short = 'j', long)]
        threads: Option<usize>,
    },
    /// Quick look at a scene before a run: for every image measure, the material-index
    /// GeoTIFF (colour table and class names), a shaded-relief PNG and the direct-Sun BRF
    /// without atmosphere (docs/scenes.md, "Preview").
    Preview {
        /// Experiment file with a `scene` table and at least one ortho or perspective measure.
        experiment: PathBuf,
        /// Output folder (created; existing preview files are replaced).
        #[arg(short, long)]
        output: PathBuf,
        /// Worker threads (default: all cores).
        #[arg(short = 'j', long)]
        threads: Option<usize>,
    },
    /// Validate an experiment file, a PICS site file (detected by its `latitude` or
    /// `catalogue` key) or a temperature-solver file (by its `weather` and `times` keys),
    /// without running it.
    Check {
        /// Experiment file, PICS site file or temperature-solver file (TOML).
        experiment: PathBuf,
        /// With a site file: also validate every acquisition of this CSV (default: one sample
        /// acquisition, Sentinel-2A B4 at nadir with the Sun at 30°).
        #[arg(long)]
        acquisitions: Option<PathBuf>,
    },
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
        /// Worker threads (default: all cores).
        #[arg(long)]
        threads: Option<usize>,
    },
    /// What an image of a scene costs at the sensor's resolution: per band, the median relative
    /// standard error, the per-sample spread and the samples per pixel for a target; the CPU
    /// per sample; the core-hours for a square tile (see BENCHMARKS.md, docs/scaling.md).
    BenchImage {
        /// Experiment file with an image measure (its first one is run).
        experiment: PathBuf,
        /// Samples per pixel to measure with (default: the measure's `spp`).
        #[arg(long)]
        spp: Option<u64>,
        /// Target median relative standard error of every band, for the projection.
        #[arg(long, default_value_t = 0.005)]
        target: f64,
        /// Side of the square tile of the projection, km.
        #[arg(long, default_value_t = 100.0)]
        tile_km: f64,
        /// Also project at a sensor's native resolutions per band ("s2": Sentinel-2 MSI).
        #[arg(long)]
        native: Option<String>,
        /// Worker threads (default: all cores).
        #[arg(short = 'j', long)]
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
        /// Worker threads (default: all cores).
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
        /// Worker threads (default: all cores).
        #[arg(short = 'j', long)]
        threads: Option<usize>,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    tracing_subscriber::fmt()
        .with_env_filter(cli.verbosity.filter())
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    match dispatch(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            for cause in e.chain().skip(1) {
                eprintln!("  caused by: {cause}");
            }
            let bad_input = |c: &(dyn std::error::Error + 'static)| {
                c.downcast_ref::<ConfigError>().is_some()
                    || matches!(
                        c.downcast_ref::<simulator::error::OutputError>(),
                        Some(simulator::error::OutputError::Checkpoint { .. })
                    )
            };
            if e.chain().any(bad_input) {
                ExitCode::from(2)
            } else if e.chain().any(|c| {
                matches!(
                    c.downcast_ref::<simulator::error::OutputError>(),
                    Some(simulator::error::OutputError::Netcdf { .. })
                )
            }) {
                // HDF5 keeps a file it could not flush (a full disk) open, and its exit handler
                // then crashes (SIGSEGV) closing it. Everything of value is already on disk
                // (checkpoints, the previous products) and staging folders are removed, so
                // leave without running the C library's exit handlers.
                use std::io::Write;
                let _ = std::io::stdout().flush();
                let _ = std::io::stderr().flush();
                // SAFETY: _exit ends the process at once; no Rust state needs unwinding.
                unsafe { libc::_exit(1) }
            } else {
                ExitCode::from(1)
            }
        }
    }
}

/// Build the global pool for `-j N`. More threads than the cores this process may use only
/// cost start-up time (quadratic in rayon: `-j 100000` took minutes) and memory, and results do
/// not depend on the count, so N is capped at the cores, with a note.
fn set_threads(threads: Option<usize>) -> anyhow::Result<()> {
    if let Some(n) = threads {
        let cores = std::thread::available_parallelism().map_or(1, |c| c.get());
        let n = n.max(1);
        if n > cores {
            tracing::warn!(
                "-j {n}: this process may use {cores} core(s); running {cores} thread(s) (results do not depend on the count)"
            );
        }
        rayon::ThreadPoolBuilder::new()
            .num_threads(n.min(cores))
            .build_global()
            .context("thread pool")?;
    }
    Ok(())
}

fn dispatch(cli: Cli) -> anyhow::Result<()> {
    let quiet = cli.verbosity.quiet;
    match cli.command {
        Command::CloudField {
            output,
            extent,
            dx,
            dz,
            base,
            count,
            radius,
            aspect,
            adiabatic_fraction,
            r_eff_um,
            seed,
        } => {
            let [x0, y0, x1, y1] = extent[..] else {
                anyhow::bail!("--extent takes four numbers: xmin,ymin,xmax,ymax");
            };
            let checks = [
                (
                    x1 > x0 && y1 > y0 && [x0, y0, x1, y1].iter().all(|v| v.is_finite()),
                    "--extent must have xmin < xmax and ymin < ymax",
                ),
                (dx.is_finite() && dx > 0.0, "--dx must be positive"),
                (dz.is_finite() && dz > 0.0, "--dz must be positive"),
                (base.is_finite(), "--base must be finite"),
                (
                    radius.len() == 2
                        && radius[0] > 0.0
                        && radius[0] <= radius[1]
                        && radius[1].is_finite(),
                    "--radius must be min,max with 0 < min ≤ max",
                ),
                (
                    aspect.is_finite() && aspect > 0.0,
                    "--aspect must be positive",
                ),
                (
                    (0.0..=1.0).contains(&adiabatic_fraction),
                    "--adiabatic-fraction must lie in [0, 1]",
                ),
                (
                    r_eff_um.is_finite() && r_eff_um > 0.0,
                    "--r-eff-um must be positive",
                ),
            ];
            if let Some((_, m)) = checks.iter().find(|(ok, _)| !ok) {
                anyhow::bail!("{m}");
            }
            let nx = ((x1 - x0) / dx).ceil() as usize;
            let ny = ((y1 - y0) / dx).ceil() as usize;
            if nx * ny * ((radius[1] * aspect / dz).ceil() as usize) > 500_000_000 {
                anyhow::bail!("{nx} × {ny} columns at --dx {dx} m is too large a field (over 2 GB): raise --dx or --dz");
            }
            let c = engine::clouds::cumulus::Cumulus {
                nx,
                ny,
                dx,
                base_m: base,
                dz,
                count,
                radius_m: [radius[0], radius[1]],
                aspect,
                adiabatic_fraction,
                r_eff_m: r_eff_um * 1e-6,
                seed,
            };
            let (cells, cover) = simulator::cloud_field::write(&output, &c, [x0, y0])?;
            println!(
                "wrote {} ({nx} × {ny} columns of {dx} m, {cells} cells, cloud cover {:.1} %)",
                output.display(),
                100.0 * cover
            );
            Ok(())
        }
        Command::Preview {
            experiment,
            output,
            threads,
        } => {
            set_threads(threads)?;
            let t0 = Instant::now();
            let exp = Experiment::load(&experiment)?;
            let t_load = t0.elapsed().as_secs_f64();
            let previews = simulator::preview::render(&exp).map_err(|message| {
                anyhow::Error::new(ConfigError::Invalid {
                    path: experiment.clone(),
                    key: "measures".into(),
                    message,
                })
            })?;
            std::fs::create_dir_all(&output)
                .with_context(|| format!("cannot create output folder {}", output.display()))?;
            let names: Vec<String> = exp
                .scene
                .as_ref()
                .map(|s| s.materials.iter().map(|(n, _)| n.clone()).collect())
                .unwrap_or_default();
            for p in &previews {
                for f in simulator::preview::write(&output, &exp, p, &names)? {
                    println!("{:<16} wrote {}", p.id, f.display());
                }
            }
            tracing::info!(
                "preview done in {:.2} s (scene loaded in {t_load:.2} s)",
                t0.elapsed().as_secs_f64()
            );
            Ok(())
        }
        Command::Temperatures {
            config,
            output,
            threads,
        } => {
            set_threads(threads)?;
            let t0 = Instant::now();
            let s = simulator::temperatures::run(&config, &output, !quiet)?;
            if s.pixels > 0 {
                println!(
                    "{} terrain pixel(s), {} distinct facet(s), periodic within {} day(s), in {:.1} s",
                    s.pixels,
                    s.distinct_facets,
                    s.days_max,
                    t0.elapsed().as_secs_f64()
                );
            } else {
                println!(
                    "flat facets only (no scene), periodic within {} day(s), in {:.1} s",
                    s.days_max,
                    t0.elapsed().as_secs_f64()
                );
            }
            for f in &s.files {
                println!("wrote {}", f.display());
            }
            Ok(())
        }
        Command::Check {
            experiment,
            acquisitions,
        } => {
            let doc = std::fs::read_to_string(&experiment)
                .ok()
                .and_then(|t| t.parse::<toml::Table>().ok());
            if doc
                .as_ref()
                .is_some_and(simulator::temperatures::is_solver_file)
            {
                let what = simulator::temperatures::check(&experiment)?;
                println!(
                    "{}: valid temperature-solver file ({what})",
                    experiment.display()
                );
                return Ok(());
            }
            if let Some(n) = check_site(&experiment, acquisitions.as_deref())? {
                println!("{}: valid PICS site file ({n})", experiment.display());
                return Ok(());
            }
            if let Some(a) = &acquisitions {
                return Err(ConfigError::Invalid {
                    path: a.clone(),
                    key: "--acquisitions".into(),
                    message: format!(
                        "is for PICS site files; {} is an experiment file",
                        experiment.display()
                    ),
                }
                .into());
            }
            let exp = Experiment::load(&experiment)?;
            println!(
                "{}: valid ({} wavelength(s), {} measure(s))",
                experiment.display(),
                exp.wavelengths.len(),
                exp.measures.len()
            );
            let mem = engine::config::memory::estimate(&exp);
            println!(
                "  memory: about {} (results {}, scene {})",
                engine::config::memory::human(mem.total()),
                engine::config::memory::human(mem.results_bytes),
                engine::config::memory::human(mem.scene_bytes)
            );
            // What the surfaces have to say beyond their parameters (tabulated BRDFs: file,
            // grids, reciprocity error), once each.
            let mut infos: Vec<String> = Vec::new();
            for o in &exp.optics {
                let scene = o.scene_models.iter().filter_map(|m| match m {
                    engine::scene::material::SurfaceModel::Opaque(b) => Some(b),
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
            fresh,
            shard,
            spp,
        } => {
            set_threads(threads)?;
            let exp = Experiment::load_with_spp(&experiment, spp)?;
            std::fs::create_dir_all(&output)
                .with_context(|| format!("cannot create output folder {}", output.display()))?;
            // One run per output folder (shards share theirs by design).
            let sharded = shard.is_some();
            let _lock = match shard {
                None => Some(simulator::products::output_lock::lock(&output)?),
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
            tracing::debug!(
                "products in {}, checkpoints in {}{}",
                output.display(),
                ckpt.display(),
                if fresh {
                    " (discarded first: --fresh)"
                } else {
                    ""
                }
            );
            if fresh {
                simulator::run::checkpoint::clear(&ckpt);
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
            let (csv, nc) = write_products(&exp, &results, &output, !quiet)?;
            // Products are complete: the checkpoints are no longer needed, except those of an
            // explicit shard (`--shard 0/1`, a one-shard plan), which `simulate merge` reads.
            if !sharded {
                simulator::run::checkpoint::clear(&ckpt);
            }
            tracing::info!(
                "done in {:.2} s: wrote {} and {}",
                t0.elapsed().as_secs_f64(),
                csv.display(),
                nc.display()
            );
            Ok(())
        }
        Command::Plan {
            experiment,
            shards,
            output,
            spp,
            cpus_per_task,
            mem,
            time,
            partition,
            account,
            threads,
        } => {
            set_threads(threads)?;
            plan_command(
                &experiment,
                &output,
                simulator::cluster::plan::Options {
                    shards,
                    spp,
                    cpus_per_task,
                    mem,
                    time,
                    partition,
                    account,
                    simulate: std::env::current_exe()
                        .and_then(|p| p.canonicalize())
                        .context("the path of this simulate executable")?,
                },
            )
        }
        Command::Merge { plan } => merge_command(&plan),
        Command::Pics {
            acquisitions,
            site,
            output,
            threads,
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
            simulator::bench::scene::run(&bundle, pixel, target, rays)
        }
        Command::BenchImage {
            experiment,
            spp,
            target,
            tile_km,
            native,
            threads,
        } => {
            set_threads(threads)?;
            simulator::bench::image::run(&experiment, spp, target, tile_km, native.as_deref())
        }
        Command::BenchPolarized {
            walks,
            seeds,
            method,
            taus,
            threads,
        } => {
            set_threads(threads)?;
            simulator::bench::polarized::run(walks, seeds, &method, &taus)
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

/// `simulate plan`: the plan, and what to do next.
fn plan_command(
    experiment: &std::path::Path,
    output: &std::path::Path,
    options: simulator::cluster::plan::Options,
) -> anyhow::Result<()> {
    std::fs::create_dir_all(output)
        .with_context(|| format!("cannot create output folder {}", output.display()))?;
    let out = output
        .canonicalize()
        .with_context(|| format!("cannot resolve {}", output.display()))?;
    let plan = simulator::cluster::plan::plan(experiment, &out, &options)?;
    let e = &plan.estimate;
    println!(
        "plan: {} work unit(s) over {} shard(s) ({} to {} per shard)",
        plan.units,
        plan.shards,
        plan.units_per_shard.iter().min().unwrap_or(&0),
        plan.units_per_shard.iter().max().unwrap_or(&0)
    );
    println!(
        "pilot: load {:.1} s, peak memory {:.0} MiB; projected {:.0} CPU s in all, {:.0} CPU s for the heaviest shard",
        e.load_seconds, e.peak_rss_mib, e.total_cpu_seconds, e.max_shard_cpu_seconds
    );
    let r = &plan.resources;
    println!(
        "each task: --cpus-per-task={} --mem={} --time={}",
        r.cpus_per_task, r.mem, r.time
    );
    if plan.shards > 1000 {
        println!(
            "note: {} array tasks exceed Slurm's default MaxArraySize (1001); ask your centre, or submit in parts with --array=A-B",
            plan.shards
        );
    }
    let script = out.join(simulator::cluster::SCRIPT_FILE);
    println!(
        "wrote {} and {}",
        out.join(simulator::cluster::PLAN_FILE).display(),
        script.display()
    );
    println!(
        "next: sbatch {}; then simulate merge {}",
        script.display(),
        out.display()
    );
    Ok(())
}

/// `simulate merge`: check the shards of a plan and write the products into its folder.
fn merge_command(plan_dir: &std::path::Path) -> anyhow::Result<()> {
    use simulator::cluster::{manifest::Plan, merge};
    let t0 = Instant::now();
    let out = plan_dir.canonicalize().map_err(|e| ConfigError::Parse {
        path: plan_dir.to_path_buf(),
        message: format!("{e} (the plan folder `simulate plan` wrote)"),
    })?;
    let plan = Plan::read(&out)?;
    if plan.simulator_version != simulator::BUILD_ID {
        anyhow::bail!(
            "{}: planned with simulator {}, this is {}: merge with the build that ran the shards",
            out.join(simulator::cluster::PLAN_FILE).display(),
            plan.simulator_version,
            simulator::BUILD_ID
        );
    }
    // The experiment is read from the folder the plan was made in, as the tasks read it (the
    // products then name it exactly as an unsplit run from there does).
    std::env::set_current_dir(&plan.workdir).with_context(|| {
        format!(
            "the plan's working folder {} (workdir in {})",
            plan.workdir.display(),
            out.join(simulator::cluster::PLAN_FILE).display()
        )
    })?;
    let exp = Experiment::load_with_spp(&plan.experiment, plan.spp)?;
    let _lock = simulator::products::output_lock::lock(&out)?;
    let now = simulator::run::checkpoint::experiment_hash(&exp);
    if now != plan.experiment_hash {
        anyhow::bail!(
            "{} or an input file it names changed since the plan was written (hash {} then, {now} now): the shards ran another experiment; restore it, or plan and run again",
            plan.experiment_path().display(),
            plan.experiment_hash
        );
    }
    let parts = merge::collect(&out, &plan, &exp)
        .map_err(|bad| anyhow::anyhow!(merge::report(&out, &bad, plan.shards)))?;
    let results: Option<Vec<_>> = simulator::run::gather(&exp, parts).into_iter().collect();
    let results = results.context("the shards' units do not cover every (wavelength, measure): was the plan written for another shard count?")?;
    crate::heavy_tail_warn(&exp, &results);
    let (csv, nc) = write_products(&exp, &results, &out, false)?;
    tracing::info!(
        "merged {} shard(s) in {:.2} s: wrote {} and {}",
        plan.shards,
        t0.elapsed().as_secs_f64(),
        csv.display(),
        nc.display()
    );
    Ok(())
}

/// Heavy-tail warnings of merged results (as a run gives them).
fn heavy_tail_warn(exp: &Experiment, results: &[simulator::run::MeasureResult]) {
    simulator::heavy_tail::warn(exp, results.iter());
}

/// Write every product of `results` into `output` through a staging folder (a failure leaves
/// the previous products as they were) and print what was written; the paths of
/// `results.csv` and `results.nc`.
fn write_products(
    exp: &Experiment,
    results: &[simulator::run::MeasureResult],
    output: &std::path::Path,
    progress: bool,
) -> anyhow::Result<(PathBuf, PathBuf)> {
    let rows = products::rows(exp, results);
    let band = products::band_rows(exp, &rows);
    let images = products::imagery::image_products(exp, results);
    // Lidar measures are traced here, once the passive tasks (checkpointed, sharded) are done:
    // they are short, deterministic and written with the rest.
    let lidars = simulator::lidar::run_all(exp, progress);
    // Every product goes to a staging folder and is moved in only when all are
    // written: a failure (a full disk) leaves the previous products as they were.
    let written =
        products::write_all(output, exp, &rows, &band, &images, &lidars).map_err(|e| {
            match e.step {
                products::WriteStep::Write => explain_write_error(*e.error, output),
                products::WriteStep::Stage | products::WriteStep::Commit => {
                    anyhow::Error::new(*e.error)
                }
            }
        })?;
    let csv = output.join("results.csv");
    let nc = output.join("results.nc");
    let (committed, looks) = (written.files, written.quicklooks);
    for (img, what) in images.iter().zip(&looks) {
        for f in committed.iter().filter(|f| {
            f.file_name().is_some_and(|n| {
                let n = n.to_string_lossy();
                n.starts_with(&format!("{}_", img.id)) || n.starts_with(&format!("{}.", img.id))
            }) && !f.to_string_lossy().ends_with(".aux.xml")
        }) {
            println!("{:<16} wrote {}", img.id, f.display());
        }
        println!(
            "{:<16} {} × {} px, quicklook: {what}",
            img.id, img.width, img.height
        );
        let quantity = if img.has_brf { "BRF" } else { "radiance" };
        for (i, (w, (b, e, s))) in exp
            .wavelengths
            .iter()
            .zip(products::imagery::medians(img))
            .enumerate()
        {
            let band = exp
                .bands
                .as_ref()
                .map_or(String::new(), |bw| format!(" ({})", bw.names[i]));
            println!(
                "{:<16} {w:>8.2} nm{band}: median {quantity} {}, median rel. stderr {:.3}%, median single-scattering fraction {:.3}",
                img.id,
                summary_value(b),
                100.0 * e,
                s
            );
        }
    }
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
    print_summary(&rows);
    Ok((csv, nc))
}

/// `simulate check` of a PICS site file: `None` when `path` is not one (an experiment, or TOML
/// that does not parse, left to the experiment loader's errors); else what was validated.
fn check_site(
    path: &std::path::Path,
    acquisitions: Option<&std::path::Path>,
) -> anyhow::Result<Option<String>> {
    let Ok(text) = std::fs::read_to_string(path) else {
        return Ok(None);
    };
    let Ok(doc) = text.parse::<toml::Table>() else {
        return Ok(None);
    };
    if !simulator::pics::is_site_file(&doc) {
        return Ok(None);
    }
    let acqs = acquisitions
        .map(simulator::pics::read_acquisitions)
        .transpose()?;
    simulator::pics::check_site(path, acqs.as_deref())?;
    Ok(Some(match (&acqs, acquisitions) {
        (Some(a), Some(p)) => format!("{} acquisition(s) of {}", a.len(), p.display()),
        _ => "with a sample acquisition; add --acquisitions CSV to check yours".into(),
    }))
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

/// A value of the summary table: five decimals, or five significant digits in scientific
/// notation where that would lose them (night and twilight radiances are ~1e-6).
fn summary_value(v: f64) -> String {
    if v != 0.0 && (v.abs() < 0.01 || v.abs() >= 1e6) {
        format!("{v:<.4e}")
    } else {
        format!("{v:<.5}")
    }
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
        let (name, (v, e)) = match (r.hdrf, r.brf, r.albedo, r.radiance, r.flux) {
            (Some(h), _, _, _, _) => ("hdrf", h),
            (None, Some(b), _, _, _) => ("brf", b),
            (None, None, Some(a), _, _) => ("albedo", a),
            (None, None, None, Some(l), _) => ("radiance", l),
            (None, None, None, None, Some(f)) => ("flux", f),
            _ => continue,
        };
        // Downwelling fluxes: the direct share.
        let direct = match (r.flux, r.flux_direct) {
            (Some((f, _)), Some((d, _))) if d > 0.0 && f > 0.0 => {
                format!("  direct {:.1} %", 100.0 * d / f)
            }
            _ => String::new(),
        };
        let ang = |x: Option<f64>| {
            x.map(|a| format!("{a:8.2}"))
                .unwrap_or_else(|| format!("{:>8}", "-"))
        };
        // Thermal runs: the brightness temperature and its standard error, K.
        let bt = r
            .brightness_temperature
            .filter(|(t, _)| t.is_finite())
            .map(|(t, se)| format!("  BT={t:.3} K ± {se:.3}"))
            .unwrap_or_default();
        println!(
            "{:<16} {:>9.2} {} {} {:>8}={} {:>9.3}%{bt}{direct}",
            r.measure,
            r.wavelength_nm,
            ang(r.vza),
            ang(r.vaa),
            name,
            summary_value(v),
            100.0 * e / v.abs().max(1e-300)
        );
    }
}

/// A product write error with its real cause: when the output's filesystem is (nearly) full,
/// say so (HDF5 reports a full disk as "HDF error"). The previous products are intact.
fn explain_write_error(
    e: simulator::error::OutputError,
    output: &std::path::Path,
) -> anyhow::Error {
    let free = products::staging::free_bytes(output);
    let full = free.is_some_and(|f| f < 4 << 20);
    let e = anyhow::Error::new(e);
    if full {
        e.context(format!(
            "No space left on device: the filesystem of {} has {} bytes free; the previous products there are unchanged (free some space and run again: completed tasks resume from the checkpoints)",
            output.display(),
            free.unwrap_or(0)
        ))
    } else {
        e.context(format!(
            "products were not written; the previous products in {} are unchanged",
            output.display()
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::Cli;
    use clap::CommandFactory;

    /// Every argument of every subcommand says what it does in `--help`.
    #[test]
    fn every_argument_has_help() {
        fn walk(cmd: &clap::Command, path: &str, missing: &mut Vec<String>) {
            for a in cmd.get_arguments() {
                let id = a.get_id().as_str();
                if id != "help" && id != "version" && a.get_help().is_none() {
                    missing.push(format!("{path} {id}"));
                }
            }
            for sub in cmd.get_subcommands() {
                walk(sub, &format!("{path} {}", sub.get_name()), missing);
            }
        }
        let cmd = Cli::command();
        cmd.clone().debug_assert();
        let mut missing = Vec::new();
        walk(&cmd, "simulate", &mut missing);
        assert!(missing.is_empty(), "arguments without help: {missing:?}");
    }
}
