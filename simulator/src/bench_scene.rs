//! The 3D-scene benchmark (issue 4, BENCHMARKS.md): for a bundle, the load and BVH build times,
//! peak memory, single-thread ray rates for primary (closest-hit) and shadow (any-hit) rays,
//! and the wall time to render a TOA ortho image to a median relative standard error.
//!
//! Rays: primary rays start 100 m above the scene's top at uniformly random horizontal positions
//! over the extent and go down at zenith angles up to 30° (uniform azimuth); shadow rays start
//! at their hits (offset) towards a Sun at 35° zenith. Render: US-standard molecular atmosphere
//! at 550 nm, SZA 35°, nadir ortho over the whole extent at `pixel_m`.

use std::path::Path;
use std::time::Instant;

use glam::DVec3;

use crate::config::Experiment;
use crate::frame::direction_from_angles;
use crate::scene::build::{from_bundle, Background};

pub use bundle::peak_rss_bytes;

fn peak_rss_mib() -> f64 {
    peak_rss_bytes().unwrap_or(0) as f64 / 1048576.0
}

pub fn run(bundle: &Path, pixel_m: f64, target: f64, rays: usize) -> anyhow::Result<()> {
    let t0 = Instant::now();
    let scene = from_bundle(
        bundle,
        &Background::Flat {
            altitude: None,
            brdf: None,
        },
        &[],
        &[],
        None,
    )
    .map_err(|e| anyhow::anyhow!(e))?;
    let t_scene = t0.elapsed().as_secs_f64();
    println!("bundle: {}", bundle.display());
    println!("{}", scene.summary());
    println!(
        "load {:.2} s, BVH build {:.2} s (total set-up {t_scene:.2} s), peak RSS after set-up {:.0} MiB",
        scene.load_seconds,
        scene.build_seconds,
        peak_rss_mib()
    );

    // Primary and shadow rays, one thread.
    let mut rng = crate::rng::Stream::new(1, [0, 0, 0, 0]);
    let e = scene.extent;
    let top = scene.z_range[1] + 100.0;
    let origins: Vec<(DVec3, DVec3)> = (0..rays)
        .map(|_| {
            let o = DVec3::new(
                e[0] + (e[2] - e[0]) * rng.next_f64(),
                e[1] + (e[3] - e[1]) * rng.next_f64(),
                top,
            );
            let zen = std::f64::consts::PI - (30f64.to_radians()) * rng.next_f64().sqrt();
            let d = direction_from_angles(zen, std::f64::consts::TAU * rng.next_f64());
            (o, d)
        })
        .collect();
    let t1 = Instant::now();
    let hits: Vec<_> = origins
        .iter()
        .map(|&(o, d)| scene.intersect(o, d, f64::INFINITY))
        .collect();
    let t_primary = t1.elapsed().as_secs_f64();
    let sun = direction_from_angles(35f64.to_radians(), 2.0);
    let starts: Vec<DVec3> = hits
        .iter()
        .flatten()
        .map(|h| scene.offset(h.point, h.normal, sun))
        .collect();
    let t2 = Instant::now();
    let shadowed = starts
        .iter()
        .filter(|&&p| scene.occluded(p, sun, f64::INFINITY))
        .count();
    let t_shadow = t2.elapsed().as_secs_f64();
    let n_hit = starts.len();
    println!(
        "primary rays: {rays} in {t_primary:.3} s = {:.3e} rays/s/core ({:.1} % hit)",
        rays as f64 / t_primary,
        100.0 * n_hit as f64 / rays as f64
    );
    println!(
        "shadow rays: {n_hit} in {t_shadow:.3} s = {:.3e} rays/s/core ({:.1} % in shadow)",
        n_hit as f64 / t_shadow,
        100.0 * shadowed as f64 / n_hit.max(1) as f64
    );
    drop(scene);

    // Render.
    let text = format!(
        r#"seed = 1
[spectral]
wavelengths = [550.0]
[atmosphere]
type = "molecular"
profile = "afgl_1986-us_standard"
layer_thickness = 1.0
[illumination]
type = "directional"
zenith = 35.0
azimuth = 120.0
[scene]
type = "bundle"
path = "{}"
[[measures]]
id = "toa"
type = "ortho"
pixel_size_m = {pixel_m}
spp = 100000
target_rel_stderr = {target}
"#,
        bundle.canonicalize()?.display()
    );
    let t3 = Instant::now();
    let exp = Experiment::from_str(&text, Path::new("bench-scene.toml"))?;
    let t_resolve = t3.elapsed().as_secs_f64();
    let t4 = Instant::now();
    let res = crate::run::run(&exp, false);
    let t_render = t4.elapsed().as_secs_f64();
    let acc = &res[0].acc;
    let m = &exp.measures[0];
    let spp = acc.n.iter().copied().min().unwrap_or(0);
    println!(
        "render: {} px of {pixel_m} m, target median rel. stderr {target}: reached {:.4} with {spp} samples/pixel in {t_render:.2} s on {} thread(s) (+ {t_resolve:.2} s scene set-up)",
        m.cell_count(),
        acc.median_rel_stderr(),
        rayon::current_num_threads()
    );
    println!("peak RSS {:.0} MiB", peak_rss_mib());
    Ok(())
}
