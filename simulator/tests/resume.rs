//! Interrupted runs resume from checkpoints, and resuming changes nothing: a run that reuses
//! stored tasks gives bit-identical sums to an uninterrupted run. Checkpoints of another
//! experiment are ignored.

mod common;
use common::*;

const EXP: &str = r#"
[spectral]
wavelengths = [500.0, 600.0]
[atmosphere]
type = "homogeneous"
optical_thickness = [0.3, 0.2]
[surface]
type = "lambertian"
reflectance = 0.2
[illumination]
type = "directional"
zenith = 20.0
[[measures]]
id = "a"
type = "mdistant"
azimuth = 0.0
zeniths = [-30.0, 0.0, 30.0]
spp = 5000
[[measures]]
id = "f"
type = "distant_flux"
spp = 5000
"#;

#[test]
fn resume_is_exact() {
    let dir = std::env::temp_dir().join(format!("simulate-resume-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let exp = experiment(EXP);
    let (full, resumed) = simulator::run::run_resumable(&exp, false, &dir).unwrap();
    assert_eq!(resumed, 0);
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 4);
    // "Interrupt": lose the last two tasks.
    std::fs::remove_file(dir.join("w001_m000.json")).unwrap();
    std::fs::remove_file(dir.join("w001_m001.json")).unwrap();
    let (again, resumed) = simulator::run::run_resumable(&exp, false, &dir).unwrap();
    assert_eq!(resumed, 2);
    for (x, y) in full.iter().zip(&again) {
        assert_eq!(x.acc, y.acc);
    }
    // A different experiment does not pick up these checkpoints.
    let other = experiment(&EXP.replace("reflectance = 0.2", "reflectance = 0.25"));
    let (_, resumed) = simulator::run::run_resumable(&other, false, &dir).unwrap();
    assert_eq!(resumed, 0);
    let _ = std::fs::remove_dir_all(&dir);
}
