//! Thick polarized media benchmark (issue 14, BENCHMARKS.md): conservative Rayleigh layers of
//! optical thickness 8 and 16 over black and Lambertian 0.8 surfaces, SZA 0° and 60°, five TOA
//! directions. For each case and walk it runs the scalar and the polarized walk with `seeds`
//! seeds of `walks` walks (per direction for the backward walk) and reports:
//!
//! * `pol/scalar`: the polarized walk's standard error of I over the scalar walk's, at equal
//!   walk counts (reported errors averaged over the seeds, which the next column checks;
//!   median and maximum over the directions);
//! * `scatter/stderr` for I, Q and U: the empirical standard deviation of the seeds' estimates
//!   over their mean reported standard error (minimum and maximum over the directions). Honest
//!   errors give 1 ± √(1/(2(seeds−1))) (±0.13 at 30 seeds, ±0.07 at 100). In the forward walk
//!   one photon serves every direction, so the directions' ratios move together: with 30 seeds
//!   all five can sit 0.2 low or high by chance (seen: 0.65–0.78 for Q at 30 seeds, 0.95–1.10
//!   for the same case at 100).
//!

use std::path::Path;

use engine::accum::{Accum, Q, TOTAL, U};
use engine::config::Experiment;

/// The five view directions: (zenith, azimuth) in degrees.
const DIRECTIONS: [(f64, f64); 5] = [
    (0.0, 0.0),
    (30.0, 0.0),
    (60.0, 0.0),
    (30.0, 90.0),
    (60.0, 135.0),
];

fn experiment(
    tau: f64,
    albedo: f64,
    sza: f64,
    method: &str,
    polarized: bool,
    seed: u64,
    walks: u64,
) -> anyhow::Result<Experiment> {
    let z: Vec<String> = DIRECTIONS.iter().map(|d| format!("{:?}", d.0)).collect();
    let a: Vec<String> = DIRECTIONS.iter().map(|d| format!("{:?}", d.1)).collect();
    let text = format!(
        "seed = {seed}\npolarized = {polarized}\n[spectral]\nwavelengths = [550.0]\n\
         [atmosphere]\ntype = \"homogeneous\"\noptical_thickness = {tau:?}\nsingle_scattering_albedo = 1.0\n\
         phase = {{ type = \"rayleigh\" }}\n[surface]\ntype = \"lambertian\"\nreflectance = {albedo:?}\n\
         [illumination]\ntype = \"directional\"\nzenith = {sza:?}\nazimuth = 0.0\n\
         [integrator]\ntype = \"{method}\"\n\
         [[measures]]\nid = \"toa\"\ntype = \"mdistant\"\nconstruct = \"directions\"\n\
         zeniths = [{}]\nazimuths = [{}]\nspp = {walks}\n",
        z.join(", "),
        a.join(", ")
    );
    Ok(Experiment::from_str(&text, Path::new("<bench-polarized>"))?)
}

/// Per direction and component: the seeds' estimates and reported standard errors.
struct Seeds {
    values: Vec<Vec<[f64; 3]>>,
    errors: Vec<Vec<[f64; 3]>>,
}

fn run_seeds(
    tau: f64,
    albedo: f64,
    sza: f64,
    method: &str,
    polarized: bool,
    seeds: u64,
    walks: u64,
) -> anyhow::Result<Seeds> {
    let nd = DIRECTIONS.len();
    let mut out = Seeds {
        values: vec![Vec::new(); nd],
        errors: vec![Vec::new(); nd],
    };
    for seed in 1..=seeds {
        let exp = experiment(tau, albedo, sza, method, polarized, seed, walks)?;
        let res = crate::run::run(&exp, false);
        let acc: &Accum = &res[0].acc;
        for c in 0..nd {
            let comps = if polarized { [TOTAL, Q, U] } else { [TOTAL; 3] };
            let (mut v, mut e) = ([0.0; 3], [0.0; 3]);
            for (j, &k) in comps.iter().enumerate() {
                (v[j], e[j]) = acc.mean_stderr(c, k);
            }
            out.values[c].push(v);
            out.errors[c].push(e);
        }
    }
    Ok(out)
}

/// Empirical standard deviation of the seeds' estimates, and the mean reported error.
fn scatter(s: &Seeds, dir: usize, comp: usize) -> (f64, f64, f64) {
    let v: Vec<f64> = s.values[dir].iter().map(|x| x[comp]).collect();
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    let sd = (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    let e = s.errors[dir].iter().map(|x| x[comp]).sum::<f64>() / n;
    (m, sd, e)
}

pub fn run(walks: u64, seeds: u64, method: &str, taus: &[f64]) -> anyhow::Result<()> {
    let methods: Vec<&str> = match method {
        "both" => vec!["forward", "backward"],
        m @ ("forward" | "backward") => vec![m],
        other => anyhow::bail!("unknown --method {other} (forward, backward or both)"),
    };
    anyhow::ensure!(seeds >= 2, "--seeds must be at least 2");
    println!(
        "thick Rayleigh layers, omega = 1, {} directions; {seeds} seeds x {walks} walks; {} thread(s)",
        DIRECTIONS.len(),
        rayon::current_num_threads()
    );
    println!(
        "{:<9} {:>4} {:>4} {:>4} | {:>18} | {:>13} {:>13} {:>13} | {:>7}",
        "method",
        "tau",
        "rho",
        "sza",
        "pol/scalar med/max",
        "I scat/err",
        "Q scat/err",
        "U scat/err",
        "wall s"
    );
    for m in &methods {
        for &tau in taus {
            for albedo in [0.0, 0.8] {
                for sza in [0.0, 60.0] {
                    let t0 = std::time::Instant::now();
                    let sc = run_seeds(tau, albedo, sza, m, false, seeds, walks)?;
                    let po = run_seeds(tau, albedo, sza, m, true, seeds, walks)?;
                    let wall = t0.elapsed().as_secs_f64();
                    let mut ratio = Vec::new();
                    let mut sr: [Vec<f64>; 3] = Default::default();
                    for d in 0..DIRECTIONS.len() {
                        let (_, _, e_s) = scatter(&sc, d, 0);
                        let (_, _, e_p) = scatter(&po, d, 0);
                        ratio.push(e_p / e_s);
                        for (c, r) in sr.iter_mut().enumerate() {
                            let (_, sd, e) = scatter(&po, d, c);
                            if e > 0.0 {
                                r.push(sd / e);
                            }
                        }
                    }
                    ratio.sort_by(f64::total_cmp);
                    let range = |v: &[f64]| {
                        let lo = v.iter().cloned().fold(f64::INFINITY, f64::min);
                        let hi = v.iter().cloned().fold(0.0, f64::max);
                        format!("{lo:.2}-{hi:.2}")
                    };
                    println!(
                        "{:<9} {:>4} {:>4} {:>4} | {:>8.2} / {:>7.2} | {:>13} {:>13} {:>13} | {:>7.1}",
                        m,
                        tau,
                        albedo,
                        sza,
                        ratio[ratio.len() / 2],
                        ratio[ratio.len() - 1],
                        range(&sr[0]),
                        range(&sr[1]),
                        range(&sr[2]),
                        wall
                    );
                }
            }
        }
    }
    Ok(())
}
