//! The reference benchmark (issue 2, BENCHMARKS.md): a homogeneous Rayleigh layer τ = 0.5 over a
//! Lambertian surface of reflectance 0.3, SZA 30°, 35 principal-plane directions (−85°…85° by
//! 5°); figure of merit: wall time until every direction has a relative standard error ≤ target.

pub mod image;
pub mod polarized;
pub mod scene;

use std::path::Path;
use std::time::Instant;

use engine::config::Experiment;

/// The workload as an experiment file; `{integrator}` and `{target}` are filled in.
pub const WORKLOAD: &str = r#"
mode = "mono"
[spectral]
wavelengths = [550.0]
[atmosphere]
type = "homogeneous"
optical_thickness = 0.5
phase = { type = "rayleigh" }
[surface]
type = "lambertian"
reflectance = 0.3
[illumination]
type = "directional"
zenith = 30.0
[integrator]
type = "{integrator}"
[[measures]]
id = "pp"
type = "mdistant"
azimuth = 0.0
zeniths = [-85.0, -80.0, -75.0, -70.0, -65.0, -60.0, -55.0, -50.0, -45.0, -40.0, -35.0, -30.0,
           -25.0, -20.0, -15.0, -10.0, -5.0, 0.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 35.0, 40.0,
           45.0, 50.0, 55.0, 60.0, 65.0, 70.0, 75.0, 80.0, 85.0]
spp = 100000000
target_rel_stderr = {target}
"#;

/// A bad command-line value of a bench command (`what`: the command or the file it reads):
/// bad input, exit 2, the flag named.
pub(crate) fn flag_error(what: &str, flag: &str, message: String) -> anyhow::Error {
    anyhow::Error::new(engine::error::ConfigError::Invalid {
        path: what.into(),
        key: flag.into(),
        message,
    })
}

/// `--target`: a relative standard error in (0, 1).
pub(crate) fn check_target(what: &str, target: f64) -> anyhow::Result<()> {
    if !(target > 0.0 && target < 1.0) {
        return Err(flag_error(
            what,
            "--target",
            format!("{target} must be a relative standard error in (0, 1), e.g. 0.005"),
        ));
    }
    Ok(())
}

/// A flag that must be a positive finite number (`unit` completes the message).
pub(crate) fn check_positive(what: &str, flag: &str, value: f64, unit: &str) -> anyhow::Result<()> {
    if !(value > 0.0 && value.is_finite()) {
        return Err(flag_error(
            what,
            flag,
            format!("{value} must be a positive {unit}"),
        ));
    }
    Ok(())
}

pub fn run(target: f64, method: &str, polarized: bool, spherical: bool) -> anyhow::Result<()> {
    check_target("simulate bench", target)?;
    let methods: Vec<&str> = match method {
        "both" => vec!["forward", "backward"],
        m @ ("forward" | "backward") => vec![m],
        other => {
            return Err(flag_error(
                "simulate bench",
                "--method",
                format!("unknown method \"{other}\" (forward, backward or both)"),
            ))
        }
    };
    let threads = rayon::current_num_threads();
    println!(
        "workload: Rayleigh tau=0.5, Lambertian 0.3, SZA 30, 35 principal-plane directions, {}",
        if polarized {
            "polarized (I, Q, U, V)"
        } else {
            "scalar"
        }
    );
    if spherical {
        println!("geometry: spherical shell, planet radius 6378.1 km, TOA 100 km");
    }
    println!(
        "target: max relative standard error <= {target:e} in every direction; {threads} thread(s)"
    );
    println!(
        "{:<9} {:>10} {:>14} {:>16} {:>18} {:>12}",
        "method", "wall [s]", "walks", "walks/s/core", "dir-samples/s", "max rel.err"
    );
    for m in methods {
        if spherical && m == "forward" {
            println!("{m:<9} (spherical shells use the backward walk)");
            continue;
        }
        let mut text = WORKLOAD
            .replace("{integrator}", m)
            .replace("{target}", &format!("{target:e}"));
        if polarized {
            text = format!("polarized = true\n{text}");
        }
        if spherical {
            text = format!("[geometry]\ntype = \"spherical_shell\"\n{text}");
            // The geometry table must come before other tables: move `mode` etc. first.
            text = text.replace("\nmode = \"mono\"", "");
        }
        let exp = Experiment::from_str(&text, Path::new("<bench workload>"))?;
        let t0 = Instant::now();
        let res = crate::run::run(&exp, false);
        let wall = t0.elapsed().as_secs_f64();
        let acc = &res[0].acc;
        let cells = acc.n.len() as f64;
        // A forward walk serves every direction; a backward walk one.
        let walks: u64 = if m == "forward" {
            acc.n[0]
        } else {
            acc.n.iter().sum()
        };
        let dir_samples: f64 = acc.n.iter().map(|&n| n as f64).sum();
        println!(
            "{:<9} {:>10.2} {:>14} {:>16.3e} {:>18.3e} {:>12.3e}",
            m,
            wall,
            walks,
            walks as f64 / wall / threads as f64,
            dir_samples / wall,
            acc.max_rel_stderr()
        );
        let _ = cells;
    }
    Ok(())
}
