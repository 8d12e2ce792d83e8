//! PICS through the library: simulate the band TOA reflectance of a calibration site for two
//! acquisitions, as `simulate pics` does (docs/pics.md).
//!
//! ```sh
//! cargo run --release -p simulator --example pics
//! ```
//!
//! The site is the catalogued Libya-4 centre under a Rayleigh (AFGL US-standard) atmosphere
//! over an illustrative RPV surface, sampled coarsely so that the example runs in about a second;
//! the second acquisition gives its own Sun angles (`sza`, `saa`) and an offset time. It prints
//! `pics.csv` and writes `pics.nc` to a temporary folder. The test suite runs it
//! (`[[example]] test = true` in simulator/Cargo.toml).

use std::path::Path;

use simulator::pics;

/// A site file (keys in docs/pics.md).
const SITE: &str = r#"
catalogue = "libya4"
elevation = 118.0
spp = 2000
wavelength_step = 10.0
irradiance = "tsis_1"

[atmosphere]
type = "molecular"
profile = "afgl_1986-us_standard"

[surface]
type = "rpv"
rho_0 = 0.32
k = 0.85
g = -0.08
"#;

/// Acquisitions (columns in docs/pics.md): the second row gives the Sun's angles.
const ACQUISITIONS: &str = "\
time_utc,vza,vaa,srf,sza,saa
2026-06-15T09:45:00Z,5.2,103.0,sentinel_2a-msi-4,,
2026-12-15T11:45:00+02:00,5.2,103.0,sentinel_2a-msi-4,55.0,160.0
";

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = std::env::temp_dir().join(format!("simulator-example-pics-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let site = dir.join("site.toml");
    std::fs::write(&site, SITE)?;
    let acquisitions = pics::parse_acquisitions(ACQUISITIONS, Path::new("ACQUISITIONS"))?;
    let rows = pics::run(&site, &acquisitions, |k| {
        eprintln!("acquisition {k} of {} done", acquisitions.len())
    })?;
    print!("{}", pics::to_csv(&rows));
    let nc = dir.join("pics.nc");
    pics::write_netcdf(&nc, &site, &rows)?;
    println!("wrote {}", nc.display());
    for r in &rows {
        // A bright desert under a clear sky: the band reflectance lies well inside (0, 1).
        if !(r.reflectance.0 > 0.1 && r.reflectance.0 < 0.9) {
            return Err(format!("unexpected reflectance {:?}", r.reflectance).into());
        }
    }
    std::fs::remove_dir_all(&dir)?;
    Ok(())
}

/// The example runs (under `cargo test`, through `test = true`).
#[test]
fn example_runs() {
    main().unwrap();
}
