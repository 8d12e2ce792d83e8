//! The 3D-scene benchmark (issue 4, BENCHMARKS.md): for a bundle, the load and BVH build times,
//! peak memory, single-thread ray rates for primary (closest-hit) and shadow (any-hit) rays,
//! and the wall time to render a TOA ortho image to a median relative standard error.
//!
//! Rays: primary rays start 100 m above the scene's top at uniformly random horizontal positions
//! over the extent and go down at zenith angles up to 30° (uniform azimuth); shadow rays start
//! at their hits (offset) towards a Sun at 35° zenith. The primary rays are timed in random
//! order, then sorted into 200 m rows (coherent, as an image's rays come). Render: US-standard
//! molecular atmosphere at 550 nm, SZA 35°, nadir ortho over the whole extent at `pixel_m`.

use std::path::Path;
use std::time::Instant;

use glam::DVec3;

use engine::config::Experiment;
use engine::frame::direction_from_angles;
use engine::scene::build::{from_bundle, Background};

pub use bundle::peak_rss_bytes;

/// CPU time of this thread ([`engine::util::cpu_time`]): ray rates are per CPU-second of one thread,
/// so a busy machine slows them less than wall time would; NaN where it cannot be read.
fn thread_cpu_seconds() -> f64 {
    engine::util::cpu_time::thread_seconds().unwrap_or(f64::NAN)
}

/// Rays per CPU-second of `f` applied to every ray (one thread), and how many returned true.
fn rate(rays: &[(DVec3, DVec3)], f: impl Fn(DVec3, DVec3) -> bool) -> (f64, usize) {
    let t = thread_cpu_seconds();
    let n = rays.iter().filter(|&&(o, d)| f(o, d)).count();
    (rays.len() as f64 / (thread_cpu_seconds() - t), n)
}

fn peak_rss_mib() -> f64 {
    peak_rss_bytes().unwrap_or(0) as f64 / 1048576.0
}

pub fn run(bundle: &Path, pixel_m: f64, target: f64, rays: usize) -> anyhow::Result<()> {
    let what = bundle.display().to_string();
    super::check_target(&what, target)?;
    super::check_positive(&what, "--pixel", pixel_m, "pixel size in m")?;
    if rays == 0 {
        return Err(super::flag_error(
            &what,
            "--rays",
            "must be at least 1".into(),
        ));
    }
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
    let mut rng = engine::rng::Stream::new(1, [0, 0, 0, 0]);
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
    let t1 = thread_cpu_seconds();
    let hits: Vec<_> = origins
        .iter()
        .map(|&(o, d)| scene.intersect(o, d, f64::INFINITY))
        .collect();
    let t_primary = thread_cpu_seconds() - t1;
    let sun = direction_from_angles(35f64.to_radians(), 2.0);
    let starts: Vec<(DVec3, DVec3)> = hits
        .iter()
        .flatten()
        .map(|h| (scene.offset(h.point, h.normal, sun), sun))
        .collect();
    let (shadow_rate, shadowed) = rate(&starts, |p, d| scene.occluded(p, d, f64::INFINITY));
    let n_hit = starts.len();
    println!(
        "primary rays: {rays} in {t_primary:.3} s = {:.3e} rays/s/core ({:.1} % hit)",
        rays as f64 / t_primary,
        100.0 * n_hit as f64 / rays as f64
    );
    println!(
        "shadow rays: {n_hit} = {shadow_rate:.3e} rays/s/core ({:.1} % in shadow)",
        100.0 * shadowed as f64 / n_hit.max(1) as f64
    );
    // The same rays in a coherent order (sorted into 200 m rows, as an image's rays come): the
    // random order above is bound by memory latency (BENCHMARKS.md, 2026-11-27).
    let mut sorted = origins.clone();
    let row = |v: f64, lo: f64| ((v - lo) / 200.0).floor() as i64;
    sorted.sort_by_key(|(o, _)| (row(o.y, e[1]), row(o.x, e[0])));
    let (r, _) = rate(&sorted, |o, d| {
        scene.intersect(o, d, f64::INFINITY).is_some()
    });
    println!("  the same primary rays sorted into 200 m rows: {r:.3e} rays/s/core");
    // The same rays against each part alone (where the time goes).
    if let Some((terrain, _)) = &scene.terrain {
        let (r, n) = rate(&origins, |o, d| terrain.intersect(o, d).is_some());
        let (rs, ns) = rate(&starts, |o, d| terrain.occluded(o, d, f64::INFINITY));
        println!("  terrain alone: primary {r:.3e} rays/s/core ({n} hits), shadow {rs:.3e} ({ns})");
    }
    if let Some(objects) = &scene.objects {
        let (r, n) = rate(&origins, |o, d| {
            objects.intersect(o, d, 0.0, f64::INFINITY).is_some()
        });
        let (rs, ns) = rate(&starts, |o, d| objects.occluded(o, d, 0.0, f64::INFINITY));
        println!(
            "  instances alone (no terrain to cut the rays short): primary {r:.3e} rays/s/core ({n} hits), shadow {rs:.3e} ({ns})"
        );
    }
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
