//! `mdistant` with `construct = "hemisphere"` (issue 17 item 5, part): every zenith at every
//! azimuth, zenith-major; over a Lambertian ground with no atmosphere the BRF is the
//! reflectance in every direction (the closed form), and the construct's keys are checked.

mod common;

use std::path::Path;

use common::{experiment, run_rows};
use engine::config::Experiment;

const HEAD: &str = "[spectral]\nwavelengths = [550.0]\n[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = 0.0\nsingle_scattering_albedo = 1.0\nphase = { type = \"rayleigh\" }\n[surface]\ntype = \"lambertian\"\nreflectance = 0.3\n[illumination]\ntype = \"directional\"\nzenith = 40.0\nazimuth = 10.0\n[[measures]]\nid = \"hemi\"\ntype = \"mdistant\"\nspp = 64\n";

#[test]
fn hemispherical_grid_of_directions() {
    let exp = experiment(&format!(
        "{HEAD}construct = \"hemisphere\"\nzeniths = [0.0, 30.0, 60.0]\nazimuths = [0.0, 90.0, 180.0, 270.0, 400.0]\n"
    ));
    let rows = run_rows(&exp);
    assert_eq!(rows.len(), 15);
    for (k, r) in rows.iter().enumerate() {
        let (z, a) = (
            [0.0, 30.0, 60.0][k / 5],
            [0.0, 90.0, 180.0, 270.0, 40.0][k % 5],
        );
        assert_eq!((r.vza.unwrap(), r.vaa.unwrap()), (z, a), "row {k}");
        let (brf, _) = r.brf.unwrap();
        assert!((brf - 0.3).abs() < 1e-9, "row {k}: BRF {brf}");
    }
    let err = |extra: &str| {
        Experiment::from_str(&format!("{HEAD}{extra}"), Path::new("h.toml"))
            .unwrap_err()
            .to_string()
    };
    let e = err("construct = \"hemisphere\"\nzeniths = [0.0]\n");
    assert!(
        e.contains("measures[0].azimuths") && e.contains("hemisphere"),
        "{e}"
    );
    let e = err("construct = \"hemisphere\"\nzeniths = [95.0]\nazimuths = [0.0]\n");
    assert!(e.contains("measures[0].zeniths[0]"), "{e}");
    let e = err("construct = \"hemisphere\"\nazimuth = 0.0\nzeniths = [0.0]\nazimuths = [0.0]\n");
    assert!(e.contains("measures[0].azimuth"), "{e}");
}
