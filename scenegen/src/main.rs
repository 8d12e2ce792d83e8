//! `scenegen`: build scene bundles from a region file, summarise them, export them to glTF.
//!
//! Exit codes: 0 success; 2 bad input (region file, input rasters or meshes, an existing output
//! without `--force`); 1 any other failure (disk full, internal error).
//!
//! Logging (stderr): INFO by default; `-q` warnings and errors only (and no progress bars), `-v`
//! debug, `-vv` trace; `RUST_LOG` (e.g. `RUST_LOG=scenegen=debug`) overrides all three.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::{Parser, Subcommand};

use scenegen::{BuildOptions, Region, ScenegenError};

#[derive(Parser)]
#[command(
    name = "scenegen",
    version,
    about = "Scene generator: DEM and land cover to a scene bundle"
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
    /// Quiet: only warnings and errors on stderr, and no progress bars.
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
    /// Build a bundle from a region file (keys in docs/region.md).
    Build {
        /// Region file (TOML).
        region: PathBuf,
        /// Output bundle directory (must not exist unless --force, which replaces only a bundle
        /// or an empty directory).
        #[arg(short, long)]
        output: PathBuf,
        /// Replace an existing output directory (after the new bundle is complete).
        #[arg(long)]
        force: bool,
        /// Worker threads (default: all cores). The bundle does not depend on it.
        #[arg(short = 'j', long)]
        threads: Option<usize>,
        /// Override `terrain.tolerance_m` of the region file (metres).
        #[arg(long)]
        tolerance_m: Option<f64>,
        /// Print one JSON line of statistics (counts, stage times, peak memory) on stdout.
        #[arg(long, hide = true)]
        stats_json: bool,
    },
    /// Validate a region file without reading any raster.
    Check {
        /// Region file (TOML).
        region: PathBuf,
    },
    /// Summarise a bundle: extent, CRS, counts, materials and their pixel shares, memory.
    Info {
        /// Scene bundle directory.
        bundle: PathBuf,
        /// Also recompute and compare the SHA-256 of every bundle file.
        #[arg(long)]
        verify: bool,
    },
    /// Export a bundle to a GLB file for a standard 3D viewer (instances with
    /// EXT_mesh_gpu_instancing).
    ExportGltf {
        /// Scene bundle directory.
        bundle: PathBuf,
        /// Output GLB file.
        output: PathBuf,
        /// Export every N-th instance only (default: all of them).
        #[arg(long, value_name = "N", default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..))]
        thin: u64,
    },
    /// A gridded terrain mesh (PLY or OBJ, x east / y north / z up in metres around a site) to a
    /// GeoTIFF DEM in the site's local transverse Mercator CRS, for a region file's `[dem]`.
    MeshToDem {
        /// Terrain mesh (PLY).
        mesh: PathBuf,
        /// Longitude and latitude (degrees) of the mesh's origin, e.g. `23.39,28.55`.
        #[arg(
            long,
            value_delimiter = ',',
            num_args = 1,
            allow_hyphen_values = true,
            required = true
        )]
        centre: Vec<f64>,
        /// Output DEM (GeoTIFF).
        #[arg(short, long)]
        output: PathBuf,
        /// Also write a land-cover raster of this one class code on the same grid.
        #[arg(long, requires = "landcover_output")]
        landcover_code: Option<u8>,
        /// Where to write that land-cover raster (GeoTIFF).
        #[arg(long)]
        landcover_output: Option<PathBuf>,
    },
    /// Scale benchmark: synthetic DEM and land cover of SIZE km at SPACING m (see BENCHMARKS.md).
    Bench {
        /// Side of the synthetic square region, km.
        #[arg(long, default_value_t = 100.0)]
        size_km: f64,
        /// DEM and land-cover pixel spacing, m.
        #[arg(long, default_value_t = 30.0)]
        spacing_m: f64,
        /// Terrain tolerances to build with, metres.
        #[arg(long, value_delimiter = ',', default_values_t = vec![5.0, 1.0])]
        tolerance: Vec<f64>,
        /// Work directory (inputs and bundles; removed at the end unless --keep).
        #[arg(long, default_value = "target/scenegen-bench")]
        workdir: PathBuf,
        /// Also build this region file (e.g. examples/grenoble/region.toml).
        #[arg(long)]
        region: Option<PathBuf>,
        /// Keep the work directory.
        #[arg(long)]
        keep: bool,
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
            if e.chain().any(|c| {
                c.downcast_ref::<ScenegenError>()
                    .is_some_and(|s| s.is_bad_input())
            }) {
                ExitCode::from(2)
            } else {
                ExitCode::from(1)
            }
        }
    }
}

fn dispatch(cli: Cli) -> anyhow::Result<()> {
    let quiet = cli.verbosity.quiet;
    match cli.command {
        Command::Check { region } => {
            let r = Region::load(&region)?;
            let dem = match &r.dem_mesh {
                Some(m) => format!("DEM from mesh {}", m.path.display()),
                None => format!("{} DEM file(s)", r.dem_files.len()),
            };
            let lc = match &r.landcover {
                scenegen::region::LandcoverInput::File(p) => p.display().to_string(),
                scenegen::region::LandcoverInput::Uniform(c) => format!("class {c} everywhere"),
                scenegen::region::LandcoverInput::None => "from polygons only".into(),
            };
            let lc = if r.landcover_vectors.is_empty() {
                lc
            } else {
                format!("{lc} + {} polygon layer(s)", r.landcover_vectors.len())
            };
            println!(
                "{}: valid ({dem}, land cover {lc}, scheme {})",
                region.display(),
                r.scheme
            );
            Ok(())
        }
        Command::Build {
            region,
            output,
            force,
            threads,
            stats_json,
            tolerance_m,
        } => {
            if let Some(n) = threads {
                // More threads than cores only cost start-up time and memory (the bundle does
                // not depend on the count): capped, with a note.
                let cores = std::thread::available_parallelism().map_or(1, |c| c.get());
                let n = n.max(1);
                if n > cores {
                    tracing::warn!(
                        "-j {n}: this process may use {cores} core(s); running {cores} thread(s)"
                    );
                }
                rayon::ThreadPoolBuilder::new()
                    .num_threads(n.min(cores))
                    .build_global()
                    .context("thread pool")?;
            }
            let mut r = Region::load(&region)?;
            if let Some(t) = tolerance_m {
                r.set_tolerance(t)?;
            }
            let t0 = std::time::Instant::now();
            let rep = scenegen::build(
                &r,
                &output,
                &BuildOptions {
                    force,
                    progress: !quiet,
                },
            )?;
            let m = &rep.manifest;
            println!(
                "{}: {} × {} DEM nodes → {} terrain triangles in {} tiles; {} materials; {} templates, {} instances; {:.1} s",
                output.display(),
                rep.dem_width,
                rep.dem_height,
                m.terrain.triangle_count,
                m.terrain.tiles.len(),
                m.materials.len(),
                m.templates.len(),
                m.instances.count,
                t0.elapsed().as_secs_f64()
            );
            if stats_json {
                let stages: serde_json::Map<String, serde_json::Value> = rep
                    .stages
                    .iter()
                    .map(|(k, d)| (k.to_string(), serde_json::json!(d.as_secs_f64())))
                    .collect();
                println!(
                    "{}",
                    serde_json::json!({
                        "wall_s": t0.elapsed().as_secs_f64(),
                        "peak_rss_bytes": scenegen::bench::peak_rss_bytes(),
                        "dem_samples": m.terrain.dem_samples,
                        "triangles": m.terrain.triangle_count,
                        "vertices": m.terrain.vertex_count,
                        "instances": m.instances.count,
                        "stages": stages,
                    })
                );
            }
            Ok(())
        }
        Command::Info { bundle, verify } => {
            print!("{}", scenegen::info::summary(&bundle)?);
            if verify {
                bundle::Bundle::verify(&bundle).map_err(ScenegenError::from)?;
                println!("verify: every file matches its SHA-256");
            }
            Ok(())
        }
        Command::ExportGltf {
            bundle,
            output,
            thin,
        } => {
            // A fresh tree has no `out/…` folders: create the output's parents.
            if let Some(parent) = output.parent().filter(|p| !p.as_os_str().is_empty()) {
                std::fs::create_dir_all(parent)
                    .with_context(|| format!("cannot create folder {}", parent.display()))?;
            }
            let thin = usize::try_from(thin).unwrap_or(usize::MAX);
            let r = scenegen::gltf_export::export(&bundle, &output, thin)?;
            println!(
                "{}: {} terrain tiles, {} templates, {} of {} instances, {}",
                output.display(),
                r.tiles,
                r.templates,
                r.instances_exported,
                r.instances_total,
                scenegen::info::human_bytes(r.bytes)
            );
            Ok(())
        }
        Command::MeshToDem {
            mesh,
            centre,
            output,
            landcover_code,
            landcover_output,
        } => {
            if centre.len() != 2 {
                anyhow::bail!("--centre takes LON,LAT (two numbers), got {centre:?}");
            }
            let lc = landcover_code.zip(landcover_output);
            let g = scenegen::mesh_dem::mesh_to_dem(
                &mesh,
                centre[0],
                centre[1],
                &output,
                lc.as_ref().map(|(c, p)| (*c, p.as_path())),
            )?;
            println!(
                "{}: {} x {} nodes at {} m x {} m -> {}",
                mesh.display(),
                g.width,
                g.height,
                g.dx,
                g.dy,
                output.display()
            );
            Ok(())
        }
        Command::Bench {
            size_km,
            spacing_m,
            tolerance,
            workdir,
            region,
            keep,
        } => {
            scenegen::bench::run(
                size_km,
                spacing_m,
                &tolerance,
                &workdir,
                region.as_deref(),
                keep,
            )?;
            Ok(())
        }
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
        walk(&cmd, "scenegen", &mut missing);
        assert!(missing.is_empty(), "arguments without help: {missing:?}");
    }
}
