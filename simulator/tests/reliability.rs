//! Reliability of `simulate run` under a full disk and stale inputs (issue 15):
//! * a full disk while writing the products exits 1 naming the real cause, leaves the previous
//!   products byte-for-byte unchanged and no staging folder, and the run resumes once space is
//!   freed (a small tmpfs; needs root to mount one, otherwise the test says why it is skipped);
//! * checkpoints are keyed by the inputs, not only by the experiment text: a bundle rebuilt at
//!   the same path is not served from the old bundle's checkpoints.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::bundles::{flat_plane, tmp, write_plane};

fn simulate(args: &[&str]) -> (i32, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_simulate"))
        .args(args)
        .output()
        .unwrap();
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

fn rayleigh(dir: &Path, spp: u64) -> PathBuf {
    let p = dir.join(format!("rl{spp}.toml"));
    std::fs::write(
        &p,
        format!(
            "[spectral]\nwavelengths = [550.0]\n[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = 0.5\nsingle_scattering_albedo = 1.0\nphase = {{ type = \"rayleigh\" }}\n[surface]\ntype = \"lambertian\"\nreflectance = 0.3\n[illumination]\ntype = \"directional\"\nzenith = 30.0\nazimuth = 0.0\n[[measures]]\nid = \"pp\"\ntype = \"mdistant\"\nconstruct = \"hplane\"\nazimuth = 0.0\nzeniths = [-60.0, 0.0, 60.0]\nspp = {spp}\n"
        ),
    )
    .unwrap();
    p
}

fn listing(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .filter(|e| e.path().is_file())
        .map(|e| {
            (
                e.file_name().to_string_lossy().into_owned(),
                std::fs::read(e.path()).unwrap(),
            )
        })
        .collect();
    v.sort();
    v
}

#[test]
fn full_disk_keeps_previous_products_and_names_the_cause() {
    let uid = unsafe { libc::geteuid() };
    if uid != 0 {
        println!("SKIPPED: mounting a small tmpfs needs root (euid {uid})");
        return;
    }
    let mnt = tmp("fulldisk");
    let ok = Command::new("mount")
        .args(["-t", "tmpfs", "-o", "size=400k", "tmpfs"])
        .arg(&mnt)
        .status()
        .is_ok_and(|s| s.success());
    if !ok {
        println!("SKIPPED: `mount -t tmpfs` failed (no CAP_SYS_ADMIN in this container)");
        return;
    }
    let result = std::panic::catch_unwind(|| {
        let dir = tmp("fulldisk-exp");
        let out = mnt.join("out");
        let (code, _, err) = simulate(&[
            "run",
            "-q",
            rayleigh(&dir, 2000).to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{err}");
        let before = listing(&out);
        assert!(before.iter().any(|(n, _)| n == "results.nc"));
        // Fill the filesystem, leaving room for the checkpoints but not for the products.
        let free = simulator::products::staging::free_bytes(&mnt).unwrap();
        let fill = vec![0u8; (free as usize).saturating_sub(12 << 10)];
        std::fs::write(mnt.join("fill"), &fill).unwrap();
        let exp2 = rayleigh(&dir, 3000);
        let (code, _, err) = simulate(&[
            "run",
            "-q",
            exp2.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ]);
        assert_eq!(code, 1, "{err}");
        assert!(err.contains("No space left on device"), "{err}");
        assert!(!err.contains("panicked"), "{err}");
        let after: Vec<_> = listing(&out);
        assert_eq!(before, after, "the previous products changed");
        let hidden: Vec<_> = std::fs::read_dir(&out)
            .unwrap()
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with(".staging") || n.ends_with(".partial"))
            .collect();
        assert!(hidden.is_empty(), "{hidden:?}");
        // Space freed: the run completes (from its checkpoints) and replaces the products.
        std::fs::remove_file(mnt.join("fill")).unwrap();
        let (code, _, err) = simulate(&[
            "run",
            "-q",
            exp2.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{err}");
        assert_ne!(listing(&out), before);
        std::fs::remove_dir_all(&dir).unwrap();
    });
    let _ = Command::new("umount").arg(&mnt).status();
    let _ = std::fs::remove_dir_all(&mnt);
    if let Err(e) = result {
        std::panic::resume_unwind(e);
    }
}

#[test]
fn a_rebuilt_bundle_is_not_served_from_old_checkpoints() {
    let dir = tmp("stale");
    let bundle = dir.join("bundle");
    let spec = |r: f64| flat_plane(2000.0, 0.0, -1000.0, r);
    let b = write_plane(&bundle, &spec(0.1));
    let exp = dir.join("exp.toml");
    std::fs::write(
        &exp,
        format!(
            "[spectral]\nwavelengths = [550.0, 650.0]\n[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = 0.0\nsingle_scattering_albedo = 1.0\nphase = {{ type = \"rayleigh\" }}\n[scene]\ntype = \"bundle\"\npath = \"{}\"\n[illumination]\ntype = \"directional\"\nzenith = 30.0\nazimuth = 0.0\n[[measures]]\nid = \"nadir\"\ntype = \"mdistant\"\nconstruct = \"hplane\"\nazimuth = 0.0\nzeniths = [0.0]\nspp = 2000\ntarget_m = [499500.0, 3999500.0, 500500.0, 4000500.0]\n[integrator]\nspectral_walk = \"independent\"\n",
            b.display()
        ),
    )
    .unwrap();
    let out = dir.join("out");
    let (e, o) = (exp.to_str().unwrap(), out.to_str().unwrap());
    // Shard 0 of 2 stores its task (550 nm) and writes no products.
    let (code, _, err) = simulate(&["run", e, "-o", o, "--shard", "0/2"]);
    assert_eq!(code, 0, "{err}");
    // Same inputs: the full run resumes that task.
    let (code, _, err) = simulate(&["run", e, "-o", o, "--shard", "0/2"]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("resumed 1"), "{err}");
    // The bundle is rebuilt with another reflectance at the same path: nothing is resumed,
    // and the products show the new bundle.
    let b2 = write_plane(&bundle, &spec(0.5));
    assert_eq!(b, b2);
    let (code, _, err) = simulate(&["run", e, "-o", o]);
    assert_eq!(code, 0, "{err}");
    assert!(!err.contains("resumed"), "{err}");
    let csv = std::fs::read_to_string(out.join("results.csv")).unwrap();
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let k = header.iter().position(|h| *h == "brf").unwrap();
    for line in csv.lines().skip(1) {
        let brf: f64 = line.split(',').nth(k).unwrap().parse().unwrap();
        assert!(
            (brf - 0.5).abs() < 0.02,
            "BRF {brf} is not the rebuilt bundle's 0.5: {line}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
