//! 3D scenes under spherical-shell atmospheres (`integrator/geometry/scene_shells.rs`, the scene bent
//! onto the planet by `scene/curvature.rs`).
//!
//! Statistical comparisons use `common::check_all` (|diff| ≤ 4.5σ + max(1e-5, 2e-4·ref), σ the
//! combined standard error of two independent runs with different seeds).

mod common;

use common::bundles::{flat_plane, lambertian, tmp, write_plane, PlaneSpec};
use common::{compare_brf_rows, experiment, mdistant_toml, run_rows};
use engine::scene::build::{from_bundle, Background};
use engine::scene::curvature::Curvature;
use glam::DVec3;

/// A bent terrain lies on the sphere: rays hit a flat (constant-altitude) bundle 30 km from the
/// origin at its altitude above the planet (within the chord error e²/(8R) of its 250 m quads),
/// the background sphere at its altitude, and the normals are the local verticals.
#[test]
fn bent_geometry_lies_on_the_sphere() {
    let dir = tmp("bent-geometry");
    let b = write_plane(&dir, &flat_plane(2000.0, 120.0, 29_000.0, 0.3));
    let c = Curvature {
        radius: 6_378_100.0,
    };
    let scene = from_bundle(
        &b,
        &Background::Flat {
            altitude: Some(80.0),
            brdf: Some(Box::new(lambertian(0.1))),
        },
        &[],
        &[],
        Some(c),
    )
    .unwrap();
    // Chord error of the quads' triangles (250 m sides, 354 m diagonals).
    let chord = 2.0 * 250f64.powi(2) / (8.0 * c.radius);
    let mut rng = engine::rng::Stream::new(7, [0, 0, 0, 0]);
    for k in 0..200 {
        // Rays from 5 km above, straight down the local vertical, inside and outside the
        // terrain's square.
        let x = 26_000.0 + 8_000.0 * rng.next_f64();
        let y = -4_000.0 + 8_000.0 * rng.next_f64();
        let top = c.bend(DVec3::new(x, y, 5_000.0));
        let down = -(top + DVec3::new(0.0, 0.0, c.radius)).normalize();
        let h = scene.intersect(top, down, f64::INFINITY).unwrap();
        let inside = (29_000.0..31_000.0).contains(&h.point.x) && (-1000.0..1000.0).contains(&y);
        let (alt, expect_tol) = if inside {
            (120.0, chord + 1e-6)
        } else {
            (80.0, 1e-6)
        };
        let got = c.altitude(h.point);
        assert!(
            (got - alt).abs() <= expect_tol,
            "ray {k} at ({x:.0}, {y:.0}): altitude {got} (expected {alt})"
        );
        assert!(
            h.normal.dot(-down) > 1.0 - 1e-8,
            "ray {k}: normal {:?} is not the local vertical {:?}",
            h.normal,
            -down
        );
    }
}

/// A flat one-material bundle whose background has the same material and height is a uniform
/// sphere under the bent-scene walk: its area TOA BRF equals the 1D spherical walk's over a
/// Lambertian surface, at small and grazing solar zenith angles, on the Earth (a 2 km terrain)
/// and on a small planet (R = 300 km, a 20 km terrain bent by up to 0.33 km: were the terrain
/// not bent, its edges would float above the background sphere and cast shadows on it).
#[test]
fn flat_bundle_on_the_sphere_equals_1d_spherical() {
    let small = write_plane(
        &tmp("flat-sphere-2km"),
        &flat_plane(2000.0, 0.0, -1000.0, 0.3),
    );
    let large = write_plane(
        &tmp("flat-sphere-20km"),
        &flat_plane(20_000.0, 0.0, -10_000.0, 0.3),
    );
    let vza = [0.0, 40.0, 65.0, 30.0];
    let vaa = [0.0, 90.0, 180.0, 300.0];
    let mut errs = Vec::new();
    for (planet, b, sza, spp) in [
        ("planet_radius = 6378.1", &small, 30.0, 60_000u64),
        ("planet_radius = 6378.1", &small, 84.0, 400_000),
        (
            "planet_radius = 300.0\ntoa_altitude = 50.0",
            &large,
            70.0,
            100_000,
        ),
    ] {
        let head = |seed: u64| {
            format!(
                "seed = {seed}\n[spectral]\nwavelengths = [550.0]\n\
                 [geometry]\ntype = \"spherical_shell\"\n{planet}\n\
                 [atmosphere]\ntype = \"homogeneous\"\noptical_thickness = 0.3\nphase = {{ type = \"hg\", g = 0.6 }}\n\
                 [illumination]\ntype = \"directional\"\nzenith = {sza:?}\nazimuth = 30.0\n"
            )
        };
        let m = mdistant_toml("toa", &vza, &vaa, spp);
        let e3 = experiment(&format!(
            "{}[scene]\ntype = \"bundle\"\npath = \"{}\"\n{m}target_m = [499000.0, 3999000.0, 501000.0, 4001000.0]\n",
            head(11),
            b.display(),
        ));
        let e1 = experiment(&format!(
            "{}[surface]\ntype = \"lambertian\"\nreflectance = 0.3\n{m}",
            head(12)
        ));
        let (r3, r1) = (run_rows(&e3), run_rows(&e1));
        let case = format!("flat bundle on the sphere = 1D ({planet}, sza {sza})");
        if let Err(e) = compare_brf_rows(&case, &r3, &r1) {
            errs.push(e);
        }
    }
    assert!(errs.is_empty(), "{}", errs.join("\n"));
}

/// Twilight over a 3D scene: with the Sun 5° below the horizon only the shells' sunlit air
/// lights the ground, and the flat bundle of the test above (background of the same material)
/// gives the 1D spherical walk's radiances (no BRF without the Sun above the horizon: the rows
/// have none). E0 = 1000 so that the radiances sit far above the test's absolute floor.
#[test]
fn twilight_over_a_flat_bundle_equals_1d_spherical() {
    let b = write_plane(&tmp("twilight-2km"), &flat_plane(2000.0, 0.0, -1000.0, 0.3));
    let head = |seed: u64| {
        format!(
            "seed = {seed}\n[spectral]\nwavelengths = [550.0]\n\
             [geometry]\ntype = \"spherical_shell\"\n\
             [atmosphere]\ntype = \"homogeneous\"\noptical_thickness = 0.3\n\
             [illumination]\ntype = \"directional\"\nzenith = 95.0\nazimuth = 30.0\nirradiance = 1000.0\n"
        )
    };
    let m = mdistant_toml("toa", &[0.0, 40.0, 60.0], &[0.0, 30.0, 210.0], 100_000);
    let e3 = experiment(&format!(
        "{}[scene]\ntype = \"bundle\"\npath = \"{}\"\n{m}target_m = [499000.0, 3999000.0, 501000.0, 4001000.0]\n",
        head(21),
        b.display(),
    ));
    let e1 = experiment(&format!(
        "{}[surface]\ntype = \"lambertian\"\nreflectance = 0.3\n{m}",
        head(22)
    ));
    let (r3, r1) = (run_rows(&e3), run_rows(&e1));
    let cmps: Vec<common::Cmp> = r3
        .iter()
        .zip(&r1)
        .map(|(x, y)| {
            assert!(x.brf.is_none() && y.brf.is_none(), "no BRF in twilight");
            let (va, ea) = x.radiance.unwrap();
            let (vb, eb) = y.radiance.unwrap();
            common::Cmp {
                label: format!("vza {:?} vaa {:?}", x.vza, x.vaa),
                reference: vb,
                value: va,
                stderr: (ea * ea + eb * eb).sqrt(),
            }
        })
        .collect();
    if let Err(e) = common::check_all("twilight: flat bundle on the sphere = 1D", &cmps) {
        panic!("{e}");
    }
}

/// A twilight image's products hold radiances only: `simulate run` writes the radiance
/// GeoTIFFs and a radiance quicklook, no BRF GeoTIFF, and `results.nc` keeps the BRF variable
/// (its layout unchanged) filled with NaN; the summary says "median radiance".
#[test]
fn twilight_images_hold_radiances_only() {
    let dir = tmp("twilight-image");
    let b = write_plane(&dir, &flat_plane(2000.0, 0.0, -1000.0, 0.3));
    let exp = dir.join("twilight.toml");
    std::fs::write(
        &exp,
        format!(
            "seed = 3\n[spectral]\nwavelengths = [550.0]\n\
             [geometry]\ntype = \"spherical_shell\"\n\
             [atmosphere]\ntype = \"homogeneous\"\noptical_thickness = 0.3\n\
             [illumination]\ntype = \"directional\"\nzenith = 95.0\nirradiance = 1000.0\n\
             [scene]\ntype = \"bundle\"\npath = \"{}\"\n\
             [[measures]]\nid = \"toa\"\ntype = \"ortho\"\npixel_size_m = 500.0\nspp = 64\n",
            b.display()
        ),
    )
    .unwrap();
    let out = dir.join("out");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_simulate"))
        .args(["run", exp.to_str().unwrap(), "-o", out.to_str().unwrap()])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(
        stdout.contains("median radiance") && stdout.contains("radiance"),
        "{stdout}"
    );
    assert!(out.join("toa_radiance.tif").exists() && out.join("toa.png").exists());
    assert!(!out.join("toa_brf.tif").exists() && !out.join("toa_brf_stderr.tif").exists());
    let nc = netcdf::open(out.join("results.nc")).unwrap();
    let brf: Vec<f64> = nc.variable("toa_brf").unwrap().get_values(..).unwrap();
    let rad: Vec<f64> = nc.variable("toa_radiance").unwrap().get_values(..).unwrap();
    assert_eq!(brf.len(), 16);
    assert!(brf.iter().all(|v| v.is_nan()), "{brf:?}");
    assert!(rad.iter().all(|v| v.is_finite() && *v > 0.0), "{rad:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Canopies stay plane-parallel: a clear error names the key.
#[test]
fn canopy_under_a_spherical_shell_is_refused() {
    let text = "[spectral]\nwavelengths = [550.0]\n[geometry]\ntype = \"spherical_shell\"\n\
        [illumination]\ntype = \"directional\"\nzenith = 30.0\n\
        [scene]\ntype = \"canopy\"\n[[scene.objects]]\nleaves = \"nowhere.txt\"\n\
        reflectance = 0.4\ntransmittance = 0.4\n\
        [[measures]]\nid = \"toa\"\ntype = \"mdistant\"\nconstruct = \"directions\"\nzeniths = [0.0]\nazimuths = [0.0]\nspp = 16\n";
    let err = engine::config::Experiment::from_str(text, std::path::Path::new("."))
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default();
    assert!(
        err.contains("scene.type") && err.contains("spherical"),
        "unexpected: {err}"
    );
}

/// The bent-terrain scene of the image tests: a 20 km flat Lambertian (0.3) terrain of 250 m
/// quads on a 300 km planet, no scattering (τ = 0), Sun at 60° from the east, no background;
/// `measure` is the `[[measures]]` table.
fn bent_scene(name: &str, seed: u64, measure: &str) -> engine::config::Experiment {
    // 250 m quads: a facet's normal is the local vertical at its centre, within 180 m/R = 6e-4
    // rad of any of its points (hence the 1e-3 tolerances of the tests).
    let b = write_plane(
        &tmp(name),
        &PlaneSpec {
            n: 40,
            ..flat_plane(20_000.0, 0.0, -10_000.0, 0.3)
        },
    );
    experiment(&format!(
        "seed = {seed}\n[spectral]\nwavelengths = [550.0]\n\
         [geometry]\ntype = \"spherical_shell\"\nplanet_radius = {}\ntoa_altitude = 10.0\n\
         [atmosphere]\ntype = \"homogeneous\"\noptical_thickness = 0.0\n\
         [illumination]\ntype = \"directional\"\nzenith = {BENT_SZA:?}\nazimuth = 90.0\n\
         [scene]\ntype = \"bundle\"\npath = \"{}\"\nbackground = {{ type = \"none\" }}\n{measure}",
        BENT_R / 1e3,
        b.display()
    ))
}

/// Planet radius (m) and solar zenith angle (°) of [`bent_scene`].
const BENT_R: f64 = 300_000.0;
const BENT_SZA: f64 = 60.0;

/// ρ·(n·s)/cos SZA of [`bent_scene`] at local (x, y): n the local vertical there.
fn bent_lambertian_brf(x: f64, y: f64) -> f64 {
    let c = Curvature { radius: BENT_R };
    let n = (c.bend(DVec3::new(x, y, 0.0)) + DVec3::new(0.0, 0.0, BENT_R)).normalize();
    let sun = engine::frame::direction_from_angles(BENT_SZA.to_radians(), 90f64.to_radians());
    0.3 * n.dot(sun) / BENT_SZA.to_radians().cos()
}

/// Ortho pixels on a bent terrain: no scattering (τ = 0), a 20 km flat Lambertian terrain on a
/// 300 km planet, Sun at 60° from the east at the origin. Every point sees the Sun at its own
/// local zenith angle, so a pixel's BRF is ρ·(n·s)/cos 60° with n the local vertical at the
/// pixel (its mean over the pixel equals the centre value to (pixel/R)² ≈ 4e-5; the terrain's
/// facets add ≤ 1e-3): the east side is brighter than the west by ~±7 %. ([`bent_scene`].) Exercises the ortho start (terrain height under the
/// pixel in the bent frame), the sphere's surface normals and the shells' Sun transmittance.
#[test]
fn ortho_pixels_see_the_local_sun() {
    let e = bent_scene(
        "ortho-sphere",
        2,
        "[[measures]]\nid = \"img\"\ntype = \"ortho\"\npixel_size_m = 2000.0\nspp = 256\n",
    );
    let res = simulator::run::run(&e, false);
    let img = &simulator::products::imagery::image_products(&e, &res)[0];
    let gt = img.geotransform.unwrap();
    let (mut lo, mut hi, mut worst) = (f64::INFINITY, 0.0_f64, 0.0_f64);
    for row in 0..img.height {
        for col in 0..img.width {
            let k = row * img.width + col;
            // Pixel centre in the local frame (the bundle's origin is 500 000, 4 000 000).
            let x = gt[0] + (col as f64 + 0.5) * gt[1] - 500_000.0;
            let y = gt[3] + (row as f64 + 0.5) * gt[5] - 4_000_000.0;
            let want = bent_lambertian_brf(x, y);
            let (got, se) = (img.brf[0][k], img.brf_stderr[0][k]);
            assert!(
                (got - want).abs() <= 4.5 * se + 1e-3 * want,
                "pixel ({col}, {row}) at x {x:.0} m: BRF {got} ± {se:.1e}, want {want}"
            );
            lo = lo.min(got);
            hi = hi.max(got);
            worst = worst.max((got / want - 1.0).abs());
        }
    }
    println!("ortho on a 300 km planet: BRF {lo:.4}..{hi:.4}, max |rel diff| {worst:.1e}");
    assert!(hi / lo > 1.1, "east–west contrast {lo}..{hi}");
}

/// A perspective camera over a bent terrain (same scene as [`ortho_pixels_see_the_local_sun`]):
/// 3 km above the ground 8 km east of the origin, looking down, 20° field of view. Its rays are
/// straight in the planet frame (down the origin's vertical, 1.5° off the local one there) and
/// meet the terrain near that point: the centre pixel's BRF is ρ·(n·s)/cos 60° with n the local
/// vertical 8 km east (±1e-3 for the facets and the ~80 m offset of the hit).
#[test]
fn perspective_camera_over_a_bent_terrain() {
    let e = bent_scene(
        "camera-sphere",
        3,
        "[[measures]]\nid = \"cam\"\ntype = \"perspective\"\n\
         origin_m = [508000.0, 4000000.0, 3000.0]\ntarget_m = [508000.0, 4000000.0, 0.0]\n\
         up = [0.0, 1.0, 0.0]\nfov = 20.0\nwidth = 9\nheight = 9\nspp = 64\n",
    );
    let res = simulator::run::run(&e, false);
    let img = &simulator::products::imagery::image_products(&e, &res)[0];
    let want = bent_lambertian_brf(8000.0, 0.0);
    let centre = img.brf[0][4 * 9 + 4];
    println!("camera over a bent terrain: centre BRF {centre:.5}, local-vertical value {want:.5}");
    assert!((centre / want - 1.0).abs() < 1e-3, "{centre} vs {want}");
    // Flat, unbent, it would be 0.3 exactly.
    assert!((centre - 0.3).abs() > 0.01);
    assert!(
        img.brf[0].iter().all(|v| (v / want - 1.0).abs() < 5e-3),
        "{:?}",
        img.brf[0]
    );
}
