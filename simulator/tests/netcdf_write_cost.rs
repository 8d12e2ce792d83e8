//! Cost of writing `results.nc` against the number of measures (BENCHMARKS.md, "netCDF writing
//! cost"). Not a check: it only prints timings, and it is `#[ignore]`d so the suite never waits
//! on it. Run it with
//!
//! ```text
//! cargo test --release -p simulator --test netcdf_write_cost -- --ignored --nocapture
//! ```
//!
//! `NETCDF_BENCH_MEASURES` (default `300,666,1000`) lists the measure counts. Each case is an
//! experiment with that many radiancemeters and 3 wavelengths; the rows are synthetic (no
//! transport is run), so only `products::netcdf::write` is timed.

use std::path::Path;
use std::time::Instant;

use engine::config::resolve::Experiment;
use simulator::products::Row;

fn experiment(n: usize) -> Experiment {
    let mut text = String::from(
        "[spectral]\nwavelengths = [440.0, 550.0, 660.0]\n[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = 0.5\n[surface]\ntype = \"lambertian\"\nreflectance = 0.3\n[illumination]\ntype = \"directional\"\nzenith = 30.0\nazimuth = 0.0\n",
    );
    for i in 0..n {
        let x = i as f64 * 0.01;
        text.push_str(&format!(
            "[[measures]]\nid = \"rm{i}\"\ntype = \"radiancemeter\"\norigin = [{x}, 0.0, 100.0]\ndirection = [0.0, 0.1, -1.0]\nspp = 100\n"
        ));
    }
    Experiment::from_str(&text, Path::new("<netcdf-bench>")).expect("bench experiment")
}

/// One synthetic row per measure and wavelength, in (wavelength, measure) order like `rows`.
fn rows(exp: &Experiment) -> Vec<Row> {
    let mut out = Vec::new();
    for (k, &w) in exp.wavelengths.iter().enumerate() {
        for (i, m) in exp.measures.iter().enumerate() {
            let v = 0.1 + 1e-4 * i as f64 + 0.01 * k as f64;
            out.push(Row {
                measure: m.id.clone(),
                kind: m.type_name(),
                method: "backward",
                wavelength_nm: w,
                vza: Some(5.7),
                vaa: Some(180.0),
                radiance: Some((v * 50.0, v * 0.5)),
                brf: Some((v, v * 0.01)),
                brf_single: Some((v * 0.6, v * 0.006)),
                brf_multiple: Some((v * 0.4, v * 0.004)),
                albedo: None,
                flux: None,
                flux_direct: None,
                flux_diffuse: None,
                hdrf: None,
                brf_q: None,
                brf_u: None,
                brf_v: None,
                dolp: None,
                brightness_temperature: None,
                n_samples: 100,
            });
        }
    }
    out
}

#[test]
#[ignore = "benchmark: prints timings (BENCHMARKS.md)"]
fn netcdf_write_cost() {
    let counts = std::env::var("NETCDF_BENCH_MEASURES").unwrap_or_else(|_| "300,666,1000".into());
    let dir = std::env::temp_dir().join(format!("netcdf_write_cost_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    println!("measures,wavelengths,write_s,bytes");
    for n in counts
        .split(',')
        .map(|s| s.trim().parse::<usize>().unwrap())
    {
        let exp = experiment(n);
        let rows = rows(&exp);
        let path = dir.join(format!("results_{n}.nc"));
        let t = Instant::now();
        simulator::products::netcdf::write(&path, &exp, &rows, &[], &[]).unwrap();
        let s = t.elapsed().as_secs_f64();
        let bytes = std::fs::metadata(&path).unwrap().len();
        println!("{n},{},{s:.3},{bytes}", exp.wavelengths.len());
    }
    let _ = std::fs::remove_dir_all(&dir);
}
