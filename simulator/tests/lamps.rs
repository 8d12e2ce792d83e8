//! Lamps (`[[lights]]`, issue 39 item 1) against closed forms: a point lamp over a Lambertian
//! ground (exact, zero variance: one lamp, one next-event estimate per path), the inverse-square
//! law along a line of radiancemeters, a spot's cone cut-off, a lamp seen through an absorbing
//! layer, a plate's shadow in a bundle, and the light tree's one-lamp estimate against every
//! lamp's sum (z-test).

mod common;
use common::bundles::{flat_plane, lambertian, tmp, with_plate, with_plate_turned, write_plane};
use common::*;

const PI: f64 = std::f64::consts::PI;

/// Radiancemeters looking straight down at ground points `xs` (m, y = 0) from `h` m.
fn meters(xs: &[f64], h: f64, spp: u64) -> String {
    xs.iter()
        .enumerate()
        .map(|(i, x)| {
            format!(
                "[[measures]]\ntype = \"radiancemeter\"\nid = \"m{i}\"\norigin = [{}, 0.0, {}]\ndirection = [0.0, 0.0, -1.0]\nspp = {spp}\n",
                x / 1e3,
                h / 1e3
            )
        })
        .collect()
}

fn radiances(text: &str) -> Vec<(f64, f64)> {
    run_rows(&experiment(text))
        .iter()
        .map(|r| r.radiance.unwrap())
        .collect()
}

const NIGHT: &str =
    "seed = 3\n[spectral]\nwavelengths = [550.0]\n[illumination]\ntype = \"none\"\n";

#[test]
fn a_point_lamp_over_a_lambertian_ground_is_exact() {
    let (rho, i0, h) = (0.4, 250.0, 10.0);
    let xs = [0.0, 3.0, 10.0, 25.0];
    let text = format!(
        "{NIGHT}[surface]\ntype = \"lambertian\"\nreflectance = {rho}\n\
         [[lights]]\ntype = \"point\"\nposition_m = [0.0, 0.0, {h}]\nintensity = {i0}\n{}",
        meters(&xs, 50.0, 64)
    );
    for (x, (l, e)) in xs.iter().zip(radiances(&text)) {
        // E = I cos θ / r² at the ground point, L = ρE/π.
        let r2 = x * x + h * h;
        let want = rho / PI * i0 * (h / r2.sqrt()) / r2;
        println!("x = {x} m: L = {l:.6e} ± {e:.1e}, closed form {want:.6e}");
        assert!(
            (l - want).abs() < 1e-12 * want && e < 1e-9 * want,
            "{l} ± {e} vs {want}"
        );
    }
    // Inverse square: the point below lamps at 5, 10, 20, 40 m.
    for h in [5.0, 10.0, 20.0, 40.0] {
        let text = format!(
            "{NIGHT}[surface]\ntype = \"lambertian\"\nreflectance = {rho}\n\
             [[lights]]\ntype = \"point\"\nposition_m = [0.0, 0.0, {h}]\nintensity = {i0}\n{}",
            meters(&[0.0], 100.0, 16)
        );
        let l = radiances(&text)[0].0;
        let want = rho / PI * i0 / (h * h);
        println!("lamp at {h} m: L = {l:.6e}, closed form {want:.6e}");
        assert!((l - want).abs() < 1e-12 * want);
    }
}

#[test]
fn a_spot_lights_its_cone_only() {
    // A spot 10 m up pointing down with a 30° cone: ground points at 26.6° and 31° from its
    // axis; with a 20° fall-off the smoothstep between.
    let spot = |falloff: &str| {
        format!(
            "{NIGHT}[surface]\ntype = \"lambertian\"\nreflectance = 0.5\n\
             [[lights]]\ntype = \"spot\"\nposition_m = [0.0, 0.0, 10.0]\nintensity = 100.0\ncone_angle = 30.0\n{falloff}{}",
            meters(&[5.0, 6.0, 2.0], 50.0, 16)
        )
    };
    let l = radiances(&spot(""));
    let lit = |x: f64| 0.5 / PI * 100.0 * 10.0 / (x * x + 100.0f64).powf(1.5);
    assert!((l[0].0 - lit(5.0)).abs() < 1e-12 * lit(5.0), "{:?}", l[0]);
    assert_eq!(l[1].0, 0.0);
    let l = radiances(&spot("falloff_angle = 10.0\n"));
    // At 11.3° (x = 2 m): t = (cos 11.31° − cos 30°)/(cos 10° − cos 30°), smoothstep t²(3 − 2t).
    let c = (10.0f64 / 104.0f64.sqrt()).min(1.0);
    let (ci, co) = (10f64.to_radians().cos(), 30f64.to_radians().cos());
    let t = (c - co) / (ci - co);
    let want = lit(2.0) * t * t * (3.0 - 2.0 * t);
    assert!((l[2].0 - want).abs() < 1e-12 * want, "{:?} vs {want}", l[2]);
}

#[test]
fn a_lamp_seen_through_an_absorbing_layer() {
    // A purely absorbing layer (τ = 0.5 over 1 km): the lamp's light crosses h·k of it to the
    // ground point below, the radiancemeter sees the ground through its own height.
    let (h, hm, k) = (100.0, 30.0, 0.5 / 1000.0);
    let text = format!(
        "{NIGHT}[geometry]\ntype = \"plane_parallel\"\ntoa_altitude = 1.0\n[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = 0.5\nsingle_scattering_albedo = 0.0\n\
         [surface]\ntype = \"lambertian\"\nreflectance = 0.3\n\
         [[lights]]\ntype = \"point\"\nposition_m = [0.0, 0.0, {h}]\nintensity = 5000.0\n{}",
        meters(&[0.0], hm, 40_000)
    );
    let (l, e) = radiances(&text)[0];
    let want = 0.3 / PI * 5000.0 / (h * h) * (-k * h).exp() * (-k * hm).exp();
    println!("absorbing layer: L = {l:.6e} ± {e:.1e}, closed form {want:.6e}");
    assert!(
        (l - want).abs() < 4.0 * e + 1e-9 * want,
        "{l} ± {e} vs {want}"
    );
}

/// In-scattered lamp light: a radiancemeter at 1 m looking straight up through a thin
/// isotropic layer (σ = 10⁻⁵ m⁻¹ up to 1 km) over a black ground, a lamp 20 m aside at 10 m:
/// `L = ∫ σ/(4π)·e^{−σt}·I·e^{−σr}/r² dt` (single scattering, exact to O(τ²) = 10⁻⁴ of it),
/// by quadrature in the angle seen from the lamp (the integrand peaks where the line passes the
/// lamp); the walk samples the flight equi-angularly.
#[test]
fn lamp_light_scattered_by_the_air_matches_quadrature() {
    let (sigma, i0, top) = (1e-5, 1.0e4, 1000.0);
    let lamp = glam::DVec3::new(20.0, 0.0, 10.0);
    let text = format!(
        "{NIGHT}[geometry]\ntype = \"plane_parallel\"\ntoa_altitude = 1.0\n\
         [atmosphere]\ntype = \"homogeneous\"\noptical_thickness = {}\nphase = {{ type = \"isotropic\" }}\n\
         [surface]\ntype = \"lambertian\"\nreflectance = 0.0\n[integrator]\nmax_depth = 1\n\
         [[lights]]\ntype = \"point\"\nposition_m = [20.0, 0.0, 10.0]\nintensity = {i0}\n\
         [[measures]]\ntype = \"radiancemeter\"\nid = \"up\"\norigin = [0.0, 0.0, 0.001]\ndirection = [0.0, 0.0, 1.0]\nspp = 20000\n",
        sigma * top
    );
    let (l, e) = radiances(&text)[0];
    // t along the beam from z = 1 m; substitute t = Δ + h tan θ.
    let (h, delta) = (20.0f64, 9.0f64);
    let (ta, tb) = ((-delta / h).atan(), ((top - 1.0 - delta) / h).atan());
    let n = 200_000;
    let mut want = 0.0;
    for k in 0..n {
        let th = ta + (tb - ta) * (k as f64 + 0.5) / n as f64;
        let t = delta + h * th.tan();
        let x = glam::DVec3::new(0.0, 0.0, 1.0 + t);
        let r = (lamp - x).length();
        let dt = h / th.cos().powi(2) * (tb - ta) / n as f64;
        want += sigma / (4.0 * PI) * (-sigma * t).exp() * i0 * (-sigma * r).exp() / (r * r) * dt;
    }
    println!("air-scattered lamp light: L = {l:.6e} ± {e:.1e}, quadrature {want:.6e}");
    assert!(
        (l - want).abs() < 4.0 * e + 1e-4 * want,
        "{l} ± {e} vs {want}"
    );
    assert!(
        e < 0.01 * want,
        "equi-angular samples: relative error {}",
        e / want
    );
}

#[test]
fn a_plate_shades_the_ground_from_a_lamp_in_a_bundle() {
    let dir = tmp("lamp-plate");
    let plane = write_plane(&dir, &flat_plane(1000.0, 0.0, -500.0, 0.3));
    // A black 20 m plate 5 m up centred 30 m east; a lamp 10 m above the origin. The ground at
    // 60 m east is behind the plate from the lamp; at 30 m west it is lit.
    let b = with_plate(
        &plane,
        &dir.join("b"),
        (30.0, 0.0, 5.0),
        10.0,
        7,
        "plate",
        lambertian(0.0),
        None,
    );
    let text = format!(
        "{NIGHT}[scene]\ntype = \"bundle\"\npath = \"{}\"\n\
         [[lights]]\ntype = \"point\"\nposition_m = [500000.0, 4000000.0, 10.0]\nintensity = 100.0\n\
         [[measures]]\ntype = \"radiancemeter\"\nid = \"shade\"\norigin = [500.060, 4000.0, 0.002]\ndirection = [0.0, 0.0, -1.0]\nspp = 16\n\
         [[measures]]\ntype = \"radiancemeter\"\nid = \"lit\"\norigin = [499.970, 4000.0, 0.002]\ndirection = [0.0, 0.0, -1.0]\nspp = 16\n",
        b.display()
    );
    let l = radiances(&text);
    let want = 0.3 / PI * 100.0 * 10.0 / (30.0f64 * 30.0 + 100.0).powf(1.5);
    println!("shaded {:?}, lit {:?} (closed form {want})", l[0], l[1]);
    assert_eq!(l[0].0, 0.0);
    assert!((l[1].0 - want).abs() < 1e-9 * want);
    let _ = std::fs::remove_dir_all(&dir);
}

/// 400 lamps of three kinds over a Rayleigh-like scattering layer and a Lambertian ground:
/// one lamp drawn from the light tree per estimate against every lamp at every estimate
/// (`integrator.lamp_sampling = "all"`), at six radiancemeters; both are Monte Carlo (the
/// air scatters), compared by z on their difference.
#[test]
fn the_light_tree_agrees_with_every_lamp() {
    let mut lamps = String::new();
    let mut s = 12345u64;
    let mut next = || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    for i in 0..400 {
        let (x, y) = (next() * 600.0 - 300.0, next() * 600.0 - 300.0);
        let kind = match i % 3 {
            0 => "type = \"point\"\nintensity = 40.0",
            1 => "type = \"spot\"\nintensity = 120.0\ncone_angle = 60.0\nfalloff_angle = 40.0",
            _ => "type = \"point\"\nintensity = \"led_4000k\"\nluminous_intensity_cd = 800\nprofile = { type = \"cosine_power\", exponent = 1 }",
        };
        lamps += &format!("[[lights]]\nposition_m = [{x}, {y}, 8.0]\n{kind}\n");
    }
    let xs = [-120.0, -10.0, 0.0, 35.0, 140.0, 290.0];
    let text = |sampling: &str, seed: u64| {
        format!(
            "seed = {seed}\n[spectral]\nwavelengths = [550.0]\n[illumination]\ntype = \"none\"\n\
             [integrator]\nlamp_sampling = \"{sampling}\"\n\
             [geometry]\ntype = \"plane_parallel\"\ntoa_altitude = 2.0\n[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = 0.2\nphase = {{ type = \"rayleigh\" }}\n\
             [surface]\ntype = \"lambertian\"\nreflectance = 0.25\n{lamps}{}",
            meters(&xs, 40.0, 6000)
        )
    };
    let tree = radiances(&text("tree", 1));
    let all = radiances(&text("all", 2));
    let mut zs = Vec::new();
    for ((a, ea), (b, eb)) in tree.iter().zip(&all) {
        let z = (a - b) / (ea * ea + eb * eb).sqrt();
        println!("tree {a:.5e} ± {ea:.1e}, all {b:.5e} ± {eb:.1e}: z = {z:+.2}");
        assert!(z.abs() < 4.0, "z = {z}");
        zs.push(z);
    }
}

#[test]
fn lamps_where_they_are_not_built_are_refused() {
    let base = format!(
        "[spectral]\nwavelengths = [550.0]\n[illumination]\ntype = \"directional\"\nzenith = 30.0\n\
         [surface]\ntype = \"lambertian\"\nreflectance = 0.3\n\
         [[lights]]\ntype = \"point\"\nposition_m = [0.0, 0.0, 10.0]\nintensity = 1.0\n{}",
        meters(&[0.0], 10.0, 16)
    );
    for (extra, says) in [
        ("polarized = true\n", "polarized"),
        ("[geometry]\ntype = \"spherical_shell\"\n", "spherical"),
    ] {
        let e = engine::config::Experiment::from_str(
            &format!("{extra}{base}"),
            &data_dir().join("test.toml"),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("lights") && e.contains(says), "{extra}: {e}");
    }
    // With the Sun too, the lamps add to the sunlit radiance.
    let with = radiances(&format!("seed = 1\n{base}"));
    let without = radiances(&format!(
        "seed = 1\n{}",
        base.replace(
            "[[lights]]\ntype = \"point\"\nposition_m = [0.0, 0.0, 10.0]\nintensity = 1.0\n",
            ""
        )
    ));
    let lamp = 0.3 / PI * 1.0 / 100.0;
    assert!(
        (with[0].0 - without[0].0 - lamp).abs() < 1e-9,
        "{with:?} {without:?}"
    );
}

/// A template that carries a lamp (a streetlight's), instanced turned by 90° about z: the
/// lamp stands where the instance's transform puts it, and lights the ground in closed form
/// when `scene.lamps = true` (and not without it). A bad key in a template lamp is refused
/// naming the template.
#[test]
fn template_lamps_follow_their_instances() {
    let dir = tmp("template-lamp");
    let plane = write_plane(&dir, &flat_plane(1000.0, 0.0, -500.0, 0.3));
    // Rotation by +90° about z (column-major): x → y.
    let turn = [0.0, 1.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 1.0];
    let out = dir.join("b");
    with_plate_turned(
        &plane,
        &out,
        (0.0, 0.0, 5.0),
        0.05,
        turn,
        7,
        "post",
        lambertian(0.2),
        None,
    );
    let mut b = bundle::Bundle::open(&out).unwrap();
    let lamp = |key: &str| {
        format!("type = \"point\"\nposition_m = [3.0, 0.0, 5.0]\nintensity = 50.0\n{key}")
            .parse::<toml::Table>()
            .unwrap()
    };
    b.templates.last_mut().unwrap().lamps = vec![lamp("")];
    b.write(&out, true).unwrap();
    let text = |lamps: bool| {
        format!(
            "{NIGHT}[scene]\ntype = \"bundle\"\npath = \"{}\"\nlamps = {lamps}\n\
             [[lights]]\ntype = \"point\"\nposition_m = [500000.0, 3999000.0, 10.0]\nintensity = 1.0\n\
             [[measures]]\ntype = \"radiancemeter\"\nid = \"under\"\norigin = [500.0, 4000.003, 0.002]\ndirection = [0.0, 0.0, -1.0]\nspp = 16\n",
            out.display()
        )
    };
    // The instance puts the lamp at (0, 3, 10): straight above the meter's ground point (the
    // other lamp, 1 km south, adds 0.3/π·1·10/(1000² + 10²)^1.5).
    let far = 0.3 / PI * 10.0 / (1003.0f64.powi(2) + 100.0).powf(1.5);
    let l = radiances(&text(true))[0].0;
    let want = 0.3 / PI * 50.0 / 100.0 + far;
    println!("template lamp: L = {l:.6e}, closed form {want:.6e}");
    assert!((l - want).abs() < 1e-9 * want, "{l} vs {want}");
    let l = radiances(&text(false))[0].0;
    assert!((l - far).abs() < 1e-9 * far, "{l} vs {far}");
    b.templates.last_mut().unwrap().lamps = vec![lamp("colour = \"red\"\n")];
    b.write(&out, true).unwrap();
    let e = engine::config::Experiment::from_str(&text(true), &data_dir().join("test.toml"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("template `plate`") && e.contains("colour"),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Emitting materials (`scene.emitters`, lit windows): a black emitting plate seen from above
/// shows its radiance exactly; under a 4 km emitting ceiling 5 m up, a Lambertian floor of
/// reflectance ρ shows ρ·L_e (it receives π·L_e from the ceiling).
#[test]
fn emitting_materials_shine_in_closed_form() {
    let dir = tmp("emitters");
    let plane = write_plane(&dir, &flat_plane(1000.0, 0.0, -500.0, 0.3));
    let b = with_plate(
        &plane,
        &dir.join("b"),
        (0.0, 0.0, 5.0),
        2000.0,
        7,
        "window",
        lambertian(0.0),
        None,
    );
    let (le, rho) = (0.01, 0.3);
    let text = format!(
        "{NIGHT}[scene]\ntype = \"bundle\"\npath = \"{}\"\n[scene.emitters]\nwindow = {le}\n\
         [[measures]]\ntype = \"radiancemeter\"\nid = \"above\"\norigin = [500.0, 4000.0, 0.05]\ndirection = [0.0, 0.0, -1.0]\nspp = 16\n\
         [[measures]]\ntype = \"radiancemeter\"\nid = \"floor\"\norigin = [500.0, 4000.0, 0.002]\ndirection = [0.0, 0.0, -1.0]\nspp = 4000\n",
        b.display()
    );
    let l = radiances(&text);
    println!(
        "emitting plate {:?} (L_e {le}), floor under it {:?} (ρL_e {})",
        l[0],
        l[1],
        rho * le
    );
    assert!((l[0].0 - le).abs() < 1e-12 && l[0].1 < 1e-12);
    assert!(
        (l[1].0 - rho * le).abs() < 4.0 * l[1].1 + 1e-4 * rho * le,
        "{:?}",
        l[1]
    );
    let e = engine::config::Experiment::from_str(
        &text.replace("window = 0.01", "windw = 0.01"),
        &data_dir().join("test.toml"),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("scene.emitters.windw"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Nadir ortho images of a bundle take their lamps' light from forward photons
/// (`integrator/lamp_photons.rs`): per pixel mean, standard error and sample count.
fn image_cells(exp: &engine::config::Experiment) -> Vec<(f64, f64)> {
    let res = simulator::run::run(exp, false);
    let to_rad = exp.optics[0].irradiance * exp.mu_norm() / PI;
    let acc = &res[0].acc;
    (0..acc.n.len())
        .map(|c| {
            let (m, e) = acc.mean_stderr(c, engine::accum::TOTAL);
            (m * to_rad, e * to_rad)
        })
        .collect()
}

const WINDOW: &str = "window_m = [499950.0, 3999950.0, 500050.0, 4000050.0]";

/// One isotropic lamp 30 m over a Lambertian plane without air, a 100 m nadir image at 10 m:
/// every pixel against `ρ/(π·A)·∫ I h/r³ dA` over its square (midpoint quadrature), by the
/// forward photons' batch errors; the errors' scale against the residuals.
#[test]
fn forward_photons_match_the_closed_form_over_a_plane() {
    let dir = tmp("lamp-photons-plane");
    let (rho, i0, h) = (0.4, 250.0, 30.0);
    let plane = write_plane(&dir, &flat_plane(1000.0, 0.0, -500.0, rho));
    let text = format!(
        "{NIGHT}[scene]\ntype = \"bundle\"\npath = \"{}\"\n[integrator]\nlamp_photons = 131072\n\
         [[lights]]\ntype = \"point\"\nposition_m = [500000.0, 4000000.0, {h}]\nintensity = {i0}\n\
         [[measures]]\ntype = \"ortho\"\nid = \"img\"\npixel_size_m = 10.0\n{WINDOW}\nspp = 32\n",
        plane.display()
    );
    let exp = experiment(&text);
    assert!(exp.lamp_photon_pixels(&exp.measures[0]).is_some());
    let px = image_cells(&exp);
    assert_eq!(px.len(), 100);
    let (mut zs, mut worst) = (Vec::new(), 0.0f64);
    for (c, (l, e)) in px.iter().enumerate() {
        let (col, row) = ((c % 10) as f64, (c / 10) as f64);
        let (x0, y1) = (-50.0 + 10.0 * col, 50.0 - 10.0 * row);
        let n = 60;
        let mut sum = 0.0;
        for i in 0..n {
            for j in 0..n {
                let x = x0 + (i as f64 + 0.5) * 10.0 / n as f64;
                let y = y1 - (j as f64 + 0.5) * 10.0 / n as f64;
                let r2 = x * x + y * y + h * h;
                sum += i0 * h / (r2 * r2.sqrt());
            }
        }
        let want = rho / PI * sum / (n * n) as f64;
        let z = (l - want) / e;
        worst = worst.max(((l - want) / want).abs());
        assert!(
            (l - want).abs() <= K * e + 1e-9 * want,
            "pixel {c}: {l:.6e} ± {e:.1e} vs closed form {want:.6e} (z = {z:+.2})"
        );
        zs.push(z);
    }
    let mean = zs.iter().sum::<f64>() / zs.len() as f64;
    let rms = (zs.iter().map(|z| z * z).sum::<f64>() / zs.len() as f64).sqrt();
    println!("100 pixels against the closed form: z mean {mean:+.3}, RMS {rms:.3}, largest relative difference {worst:.2e}");
    assert!(
        mean.abs() < 0.5 && (0.6..1.5).contains(&rms),
        "z mean {mean}, RMS {rms}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A bundle with a reflecting plate, six lamps of three kinds and a scattering layer: the
/// nadir image by forward photons (the default) against the backward walks' next-event
/// estimates of every lamp (`lamp_estimator = "backward"`, `lamp_sampling = "all"`), pixel by
/// pixel (z on the difference); the forward image is the same on 1 and 2 threads; and over 16
/// seeds the forward errors are honest (scatter of the seeds' pixel values against the
/// reported errors).
#[test]
fn forward_photons_agree_with_backward_walks() {
    let dir = tmp("lamp-photons-plate");
    let plane = write_plane(&dir, &flat_plane(1000.0, 0.0, -500.0, 0.3));
    let b = with_plate(
        &plane,
        &dir.join("b"),
        (15.0, -10.0, 3.0),
        12.0,
        7,
        "plate",
        lambertian(0.6),
        None,
    );
    let lamps = "[[lights]]\ntype = \"point\"\nposition_m = [499970.0, 4000020.0, 8.0]\nintensity = 60.0\n\
         [[lights]]\ntype = \"point\"\nposition_m = [500035.0, 4000030.0, 8.0]\nintensity = 90.0\nprofile = { type = \"cosine_power\", exponent = 1.5 }\n\
         [[lights]]\ntype = \"spot\"\nposition_m = [500000.0, 3999960.0, 9.0]\nintensity = 150.0\ncone_angle = 50.0\nfalloff_angle = 30.0\n\
         [[lights]]\ntype = \"point\"\nposition_m = [499940.0, 3999990.0, 8.0]\nintensity = 40.0\n\
         [[lights]]\ntype = \"point\"\nposition_m = [500060.0, 3999970.0, 6.0]\nintensity = \"hps\"\nluminous_intensity_cd = 500\nprofile = { type = \"cosine_power\", exponent = 1 }\n\
         [[lights]]\ntype = \"point\"\nposition_m = [500010.0, 4000000.0, 10.0]\nintensity = 30.0\n";
    let text = |seed: u64, integrator: &str, spp: u64| {
        format!(
            "seed = {seed}\n[spectral]\nwavelengths = [590.0]\n[illumination]\ntype = \"none\"\n\
             [integrator]\n{integrator}\n\
             [geometry]\ntype = \"plane_parallel\"\ntoa_altitude = 2.0\n[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = 0.2\nphase = {{ type = \"rayleigh\" }}\n\
             [scene]\ntype = \"bundle\"\npath = \"{}\"\n{lamps}\
             [[measures]]\ntype = \"ortho\"\nid = \"img\"\npixel_size_m = 20.0\n{WINDOW}\nspp = {spp}\n",
            b.display()
        )
    };
    let fwd_exp = experiment(&text(1, "lamp_photons = 4096", 16));
    let fwd = image_cells(&fwd_exp);
    let back = image_cells(&experiment(&text(
        2,
        "lamp_estimator = \"backward\"\nlamp_sampling = \"all\"",
        16_000,
    )));
    let mut zs = Vec::new();
    for (c, ((a, ea), (b, eb))) in fwd.iter().zip(&back).enumerate() {
        let z = (a - b) / (ea * ea + eb * eb).sqrt();
        println!(
            "pixel {c:2}: forward {a:.5e} ± {ea:.1e}, backward {b:.5e} ± {eb:.1e}: z = {z:+.2}"
        );
        assert!(z.abs() < K, "pixel {c}: z = {z}");
        zs.push(z);
    }
    let n = zs.len() as f64;
    let mean = zs.iter().sum::<f64>() / n;
    let rms = (zs.iter().map(|z| z * z).sum::<f64>() / n).sqrt();
    println!("{n} pixels, forward against backward: z mean {mean:+.3}, RMS {rms:.3}");
    assert!(
        mean.abs() < 0.6 && (0.6..1.4).contains(&rms),
        "z mean {mean}, RMS {rms}"
    );

    // A target the first photons miss: more photon sets until the median pixel meets it.
    let median = |px: &[(f64, f64)]| {
        let mut rel: Vec<f64> = px
            .iter()
            .map(|&(l, e)| if l > 0.0 { e / l } else { f64::INFINITY })
            .collect();
        rel.sort_by(|a, b| a.total_cmp(b));
        rel[rel.len() / 2]
    };
    let first = median(&image_cells(&experiment(&text(
        5,
        "lamp_photons = 1024",
        64,
    ))));
    let aimed = median(&image_cells(&experiment(
        &text(5, "lamp_photons = 1024", 64)
            .replace("spp = 64\n", "spp = 64\ntarget_rel_stderr = 0.05\n"),
    )));
    println!("lamp_photons = 1024: median pixel {first:.4}; with a 5 % target {aimed:.4}");
    assert!(first > 0.05 && aimed <= 0.05, "{first} {aimed}");

    // Thread-count independence.
    let (one, two) = run_on_1_and_2_threads(&fwd_exp);
    assert_eq!(
        one[0].acc, two[0].acc,
        "the forward image depends on the thread count"
    );

    // Honest errors: 16 seeds at the default photon count.
    let seeds: Vec<Vec<(f64, f64)>> = (0..16)
        .map(|s| image_cells(&experiment(&text(100 + s, "", 16))))
        .collect();
    let (mut scatter2, mut reported2) = (0.0, 0.0);
    for c in 0..seeds[0].len() {
        let v: Vec<f64> = seeds.iter().map(|p| p[c].0).collect();
        let m = v.iter().sum::<f64>() / v.len() as f64;
        scatter2 += v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (v.len() - 1) as f64;
        reported2 += seeds.iter().map(|p| p[c].1 * p[c].1).sum::<f64>() / v.len() as f64;
    }
    let ratio = (scatter2 / reported2).sqrt();
    println!("16 seeds: scatter over seeds / reported error, pooled over pixels: {ratio:.3}");
    assert!((0.85..1.15).contains(&ratio), "scatter/reported {ratio}");
    let _ = std::fs::remove_dir_all(&dir);
}
