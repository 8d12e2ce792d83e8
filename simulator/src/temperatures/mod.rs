//! `simulate temperatures FILE.toml -o OUTDIR`: surface temperatures through a diurnal cycle
//! from the engine's heat-conduction energy balance (`engine::temperature`), written as LST
//! rasters that thermal runs read (`scene.land_surface_temperature`) and per-material tables.
//!
//! 1. **Sunlight and sky light** (`shortwave.rs`): our own 1D Monte Carlo runs of the file's
//!    atmosphere give the direct (normal to the beam) and diffuse (horizontal) irradiance at
//!    the ground for a grid of solar zeniths, integrated over `shortwave.wavelengths` and scaled
//!    to the total solar irradiance of the date; each time step interpolates them at its Sun.
//! 2. **The day**: the Sun's position every `step_minutes` (NREL SPA at the place), the air
//!    temperature's cosine, the sky's longwave and the convection (`engine::temperature::balance`).
//! 3. **Facets** (`facets.rs`): each LST pixel's terrain point, normal and material; its sky-view
//!    factor (rays over its hemisphere) and, at every step with the Sun up, a shadow ray through
//!    the whole scene (terrain, trees, buildings). Pixels with equal material, (quantised) normal,
//!    sky view and shadow pattern share one solve.
//! 4. **Solve** each distinct facet to its periodic day (in parallel), then write
//!    `lst_HHMM.tif` per requested local time (and its grey quicklook `lst_HHMM.png`), `materials.csv` (flat sunlit, flat shaded and
//!    terrain-mean temperatures per material and time), `diurnal.csv` (the drive and the flat
//!    sunlit temperature of every material at every step) and `temperatures_HHMM.csv` (one
//!    temperature per material, the `scene.temperature_table` of a thermal run).

pub mod config;
mod facets;
mod shortwave;

use std::path::{Path, PathBuf};

use anyhow::Context;
use engine::temperature::balance::{periodic_day, Day, Drive, Facet, SurfaceOptics};
use glam::DVec3;
use rayon::prelude::*;

use config::{parse_clock, Resolved, TemperatureConfig};

/// First node thickness (m) and growth of the slabs' node spacing.
const FIRST_NODE_M: f64 = 0.002;
const GROWTH: f64 = 1.15;

/// One step of the day: its times and the Sun.
#[derive(Clone, Debug)]
pub struct StepInfo {
    pub local: String,
    pub utc: String,
    pub sun_zenith_deg: f64,
    pub sun_azimuth_deg: f64,
}

/// What a run wrote and measured.
#[derive(Clone, Debug)]
pub struct Summary {
    pub files: Vec<PathBuf>,
    pub pixels: usize,
    pub distinct_facets: usize,
    pub days_max: usize,
    pub not_converged: usize,
}

/// Whether a parsed TOML document is a temperature-solver file (it has `weather` and
/// `times`, which experiments and site files do not).
pub fn is_solver_file(doc: &toml::Table) -> bool {
    doc.contains_key("weather") && doc.contains_key("times")
}

/// `simulate check` of a solver file: its keys, and a thermal model for every material of its
/// bundle (read from the manifest, no geometry loaded); returns a summary.
pub fn check(path: &Path) -> anyhow::Result<String> {
    let cfg = TemperatureConfig::load(path)?;
    let base = path.parent().unwrap_or(Path::new("."));
    let names: Vec<String> = match &cfg.scene {
        Some(s) => bundle::Bundle::read_manifest(&base.join(&s.path))
            .with_context(|| format!("{}: at key `scene.path`", path.display()))?
            .materials
            .iter()
            .map(|m| m.name.clone())
            .collect(),
        None => cfg.materials.keys().cloned().collect(),
    };
    for n in &names {
        cfg.material(path, n)?;
    }
    Ok(format!(
        "{} material(s) with thermal models, {} output time(s), {} steps a day",
        names.len(),
        cfg.times.len(),
        (1440.0 / cfg.step_minutes).round()
    ))
}

/// Run the solver of the file at `path` into `outdir`.
pub fn run(path: &Path, outdir: &Path, progress: bool) -> anyhow::Result<Summary> {
    let cfg = TemperatureConfig::load(path)?;
    let base = path.parent().unwrap_or(Path::new("."));
    let scene = match &cfg.scene {
        Some(s) => {
            let dir = base.join(&s.path);
            let scene = engine::scene::build::from_bundle(
                &dir,
                &engine::scene::build::Background::None,
                &[],
                &[],
                None,
            )
            .with_context(|| format!("{}: at key `scene.path`", path.display()))?;
            Some(scene)
        }
        None => None,
    };
    let (lat, lon) = place(&cfg, path, scene.as_ref())?;
    // Materials: the scene's (each must have a thermal description), else the file's.
    let names: Vec<String> = match &scene {
        Some(s) => s.materials.iter().map(|(n, _)| n.clone()).collect(),
        None => cfg.materials.keys().cloned().collect(),
    };
    if names.is_empty() {
        anyhow::bail!(
            "{}: no scene and no [materials]: nothing to compute temperatures for",
            path.display()
        );
    }
    let materials: Vec<Resolved> = names
        .iter()
        .map(|n| cfg.material(path, n))
        .collect::<Result<_, _>>()?;
    let table = shortwave::table(&cfg, path)?;
    let (day, steps) = build_day(&cfg, lat, lon, &table)?;
    std::fs::create_dir_all(outdir)
        .with_context(|| format!("cannot create output folder {}", outdir.display()))?;
    let n = day.steps.len();
    let flat = |lit: bool| Facet {
        normal: DVec3::Z,
        sky_view: 1.0,
        lit: day.steps.iter().map(|d| lit && d.sun.z > 0.0).collect(),
        air_offset: 0.0,
    };
    // Flat sunlit and flat shaded facets of every material.
    let flats: Vec<[engine::temperature::balance::PeriodicDay; 2]> = materials
        .par_iter()
        .map(|m| {
            [
                solve(&cfg, &day, &flat(true), m),
                solve(&cfg, &day, &flat(false), m),
            ]
        })
        .collect();
    let mut summary = Summary {
        files: vec![],
        pixels: 0,
        distinct_facets: 0,
        days_max: flats
            .iter()
            .flat_map(|f| f.iter().map(|p| p.days))
            .max()
            .unwrap_or(0),
        not_converged: flats
            .iter()
            .flat_map(|f| f.iter())
            .filter(|p| !p.converged)
            .count(),
    };
    let times: Vec<(String, u32)> = cfg
        .times
        .iter()
        .map(|t| (t.clone(), parse_clock(t).expect("checked")))
        .collect();
    let at_time = |series: &[f64], minutes: u32| {
        // Step k ends at (k + 1)·dt; midnight is the previous day's last step.
        let x = f64::from(minutes) * 60.0 / day.dt - 1.0;
        let x = if x < 0.0 { x + n as f64 } else { x };
        let k = x.floor() as usize % n;
        let f = x - x.floor();
        series[k] * (1.0 - f) + series[(k + 1) % n] * f
    };
    let mut terrain_means: Vec<Vec<(f64, usize)>> = vec![vec![(0.0, 0); names.len()]; times.len()];
    if let (Some(scene), Some(sref)) = (&scene, &cfg.scene) {
        let grid = facets::Grid::of(scene, sref.pixel_size_m)
            .with_context(|| format!("{}: at key `scene`", path.display()))?;
        let t0 = std::time::Instant::now();
        let origin_z = scene.georef.as_ref().map_or(0.0, |g| g.origin.z);
        let lapse = facets::Lapse {
            rate: cfg.weather.lapse_rate_k_per_km / 1000.0,
            reference_z: cfg
                .weather
                .reference_altitude_m
                .map_or(scene.reference_height, |z| z - origin_z),
        };
        tracing::info!(
            "the air temperatures hold at {:.0} m; {} K/km above and below",
            lapse.reference_z + origin_z,
            cfg.weather.lapse_rate_k_per_km
        );
        let found = facets::find(
            scene,
            &grid,
            &day,
            sref.sky_rays,
            lapse,
            &bar(progress, 0, "shadows and sky views"),
        );
        tracing::info!(
            "{} × {} pixels: shadows and sky views in {:.1} s",
            grid.width,
            grid.height,
            t0.elapsed().as_secs_f64()
        );
        let t0 = std::time::Instant::now();
        summary.pixels = found.pixel_facet.iter().filter(|f| f.is_some()).count();
        summary.distinct_facets = found.facets.len();
        let bar = bar(progress, found.facets.len() as u64, "solving facets");
        let solved: Vec<engine::temperature::balance::PeriodicDay> = found
            .facets
            .par_iter()
            .map(|(material, facet)| {
                let p = solve(&cfg, &day, facet, &materials[*material as usize]);
                bar.inc(1);
                p
            })
            .collect();
        bar.finish_and_clear();
        tracing::info!(
            "{} distinct facets solved in {:.1} s",
            solved.len(),
            t0.elapsed().as_secs_f64()
        );
        summary.days_max = summary
            .days_max
            .max(solved.iter().map(|p| p.days).max().unwrap_or(0));
        summary.not_converged += solved.iter().filter(|p| !p.converged).count();
        let georef = scene.georef.as_ref();
        let origin = georef.map_or(DVec3::ZERO, |g| g.origin);
        let g = grid.geotransform;
        let gt = [g[0] + origin.x, g[1], g[2], g[3] + origin.y, g[4], g[5]];
        let wkt = georef.map_or(String::new(), |g| g.wkt.clone());
        for (it, (label, minutes)) in times.iter().enumerate() {
            let values: Vec<f64> = found
                .pixel_facet
                .iter()
                .map(|f| match f {
                    Some(k) => at_time(&solved[*k].surface, *minutes),
                    None => f64::NAN,
                })
                .collect();
            for (f, v) in found.pixel_facet.iter().zip(&values) {
                if let Some(k) = f {
                    let m = found.facets[*k].0 as usize;
                    terrain_means[it][m].0 += v;
                    terrain_means[it][m].1 += 1;
                }
            }
            let file = outdir.join(format!("lst_{}.tif", label.replace(':', "")));
            let band = crate::products::image::ImageBand {
                name: "lst".into(),
                description: format!("land-surface (kinetic) temperature at {label} local time"),
                values: &values,
                unit: "K".into(),
                wavelength_nm: None,
                fwhm_nm: None,
            };
            let utc = local_to_utc(&cfg, *minutes)?;
            crate::products::image::write_geotiff(
                &file,
                grid.width,
                grid.height,
                gt,
                &wkt,
                &[band],
                &[
                    ("LOCAL_TIME".into(), format!("{} {label}", cfg.date)),
                    ("UTC_TIME".into(), utc),
                    ("SOFTWARE".into(), format!("simulate {}", crate::BUILD_ID)),
                ],
            )?;
            summary.files.push(file);
            let png = outdir.join(format!("lst_{}.png", label.replace(':', "")));
            let what = crate::products::image::write_stretched_png(
                &png,
                grid.width,
                grid.height,
                &values,
                &format!("land-surface temperature at {label}"),
                "K",
            )?;
            tracing::info!("{}: {what}", png.display());
            summary.files.push(png);
        }
    }
    // Tables.
    let mut csv = String::from(
        "material,source,albedo,emissivity,wetness,time_local,flat_sunlit_k,flat_shaded_k,terrain_mean_k,terrain_pixels\n",
    );
    for (it, (label, minutes)) in times.iter().enumerate() {
        for (m, name) in names.iter().enumerate() {
            let (sum, count) = terrain_means[it][m];
            let mean = if count > 0 {
                format!("{:.3}", sum / count as f64)
            } else {
                String::new()
            };
            csv += &format!(
                "{name},{},{},{},{},{label},{:.3},{:.3},{mean},{count}\n",
                materials[m].source.replace(',', ";"),
                materials[m].model.albedo,
                materials[m].model.emissivity,
                materials[m].model.wetness,
                at_time(&flats[m][0].surface, *minutes),
                at_time(&flats[m][1].surface, *minutes),
            );
        }
        // Each material's mean over its terrain pixels where it has some, else a flat sunlit
        // facet's: the `scene.temperature_table` of a thermal run.
        let mut table = String::from("material,temperature_k\n");
        for (m, name) in names.iter().enumerate() {
            let (sum, count) = terrain_means[it][m];
            let t = if count > 0 {
                sum / count as f64
            } else {
                at_time(&flats[m][0].surface, *minutes)
            };
            table += &format!("{name},{t:.2}\n");
        }
        let file = outdir.join(format!("temperatures_{}.csv", label.replace(':', "")));
        write_atomic(&file, &table)?;
        summary.files.push(file);
    }
    let file = outdir.join("materials.csv");
    write_atomic(&file, &csv)?;
    summary.files.push(file);
    let mut diurnal = String::from(
        "time_local,time_utc,sun_zenith_deg,sun_azimuth_deg,direct_normal_w_m2,diffuse_w_m2,air_temperature_k,sky_longwave_w_m2",
    );
    for name in &names {
        diurnal += &format!(",{name}_flat_sunlit_k");
    }
    diurnal.push('\n');
    for (k, (s, d)) in steps.iter().zip(&day.steps).enumerate() {
        diurnal += &format!(
            "{},{},{:.4},{:.4},{:.3},{:.3},{:.3},{:.3}",
            s.local,
            s.utc,
            s.sun_zenith_deg,
            s.sun_azimuth_deg,
            d.direct,
            d.diffuse,
            d.t_air,
            d.sky_longwave
        );
        for f in &flats {
            diurnal += &format!(",{:.3}", f[0].surface[k]);
        }
        diurnal.push('\n');
    }
    let file = outdir.join("diurnal.csv");
    write_atomic(&file, &diurnal)?;
    summary.files.push(file);
    if summary.not_converged > 0 {
        tracing::warn!(
            "{} facet(s) did not reach a periodic day within max_days = {} (tolerance_k = {}): raise max_days",
            summary.not_converged,
            cfg.max_days,
            cfg.tolerance_k
        );
    }
    Ok(summary)
}

/// One facet of material `m` to its periodic day.
fn solve(
    cfg: &TemperatureConfig,
    day: &Day,
    facet: &Facet,
    m: &Resolved,
) -> engine::temperature::balance::PeriodicDay {
    let mean_air = 0.5 * (cfg.weather.air_temperature_k[0] + cfg.weather.air_temperature_k[1]);
    let mut slab = m
        .model
        .slab(FIRST_NODE_M, GROWTH, mean_air)
        .expect("materials are checked when the file is read");
    let optics = SurfaceOptics {
        albedo: m.model.albedo,
        emissivity: m.model.emissivity,
        wetness: m.model.wetness,
    };
    periodic_day(
        &mut slab,
        day,
        facet,
        &optics,
        cfg.tolerance_k,
        cfg.max_days,
    )
}

/// Latitude and longitude: the file's, else the bundle's centre.
fn place(
    cfg: &TemperatureConfig,
    path: &Path,
    scene: Option<&engine::scene::Scene>,
) -> anyhow::Result<(f64, f64)> {
    if let (Some(a), Some(b)) = (cfg.latitude, cfg.longitude) {
        return Ok((a, b));
    }
    let Some(g) = scene.and_then(|s| s.georef.as_ref()) else {
        anyhow::bail!(
            "{}: give `latitude` and `longitude` (no georeferenced scene to take them from)",
            path.display()
        );
    };
    let s = scene.expect("georef implies a scene");
    let cx = 0.5 * (s.extent[0] + s.extent[2]) + g.origin.x;
    let cy = 0.5 * (s.extent[1] + s.extent[3]) + g.origin.y;
    use gdal::spatial_ref::{AxisMappingStrategy, CoordTransform, SpatialRef};
    let mut src = SpatialRef::from_wkt(&g.wkt).context("the bundle's CRS")?;
    src.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
    let mut dst = SpatialRef::from_epsg(4326).context("EPSG:4326")?;
    dst.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
    let t = CoordTransform::new(&src, &dst).context("transform to longitude/latitude")?;
    let (mut x, mut y) = ([cx], [cy]);
    t.transform_coords(&mut x, &mut y, &mut [])
        .context("the bundle's centre in longitude/latitude")?;
    tracing::info!(
        "place from the bundle's centre: latitude {:.4}°, longitude {:.4}°",
        y[0],
        x[0]
    );
    Ok((y[0], x[0]))
}

/// The UTC time (RFC 3339) of local clock minute `minutes` of the file's date.
fn local_to_utc(cfg: &TemperatureConfig, minutes: u32) -> anyhow::Result<String> {
    let t = midnight(cfg)? + chrono::Duration::minutes(i64::from(minutes));
    Ok(engine::sources::sun_position::format_utc(
        &t.with_timezone(&chrono::Utc),
    ))
}

/// Local midnight of the file's date, with the local clock's offset.
fn midnight(cfg: &TemperatureConfig) -> anyhow::Result<chrono::DateTime<chrono::FixedOffset>> {
    let text = format!("{}T00:00:00{}", cfg.date, cfg.utc_offset);
    chrono::DateTime::parse_from_rfc3339(&text).map_err(|e| {
        anyhow::anyhow!(
            "`date` = \"{}\" with `utc_offset` = \"{}\": \"{text}\" is not an RFC 3339 time ({e})",
            cfg.date,
            cfg.utc_offset
        )
    })
}

/// The day's drives at every step's end, and the steps' times and Sun.
fn build_day(
    cfg: &TemperatureConfig,
    lat: f64,
    lon: f64,
    table: &shortwave::Table,
) -> anyhow::Result<(Day, Vec<StepInfo>)> {
    let dt = cfg.step_minutes * 60.0;
    let n = (86_400.0 / dt).round() as usize;
    let local = midnight(cfg)?;
    let offset_h = f64::from(local.offset().local_minus_utc()) / 3600.0;
    let start = local.with_timezone(&chrono::Utc);
    let w = &cfg.weather;
    let (t_mean, t_amp) = (
        0.5 * (w.air_temperature_k[0] + w.air_temperature_k[1]),
        0.5 * (w.air_temperature_k[1] - w.air_temperature_k[0]),
    );
    let mut drives = Vec::with_capacity(n);
    let mut info = Vec::with_capacity(n);
    for k in 0..n {
        let secs = (k + 1) as f64 * dt;
        let t = start + chrono::Duration::milliseconds((secs * 1000.0).round() as i64);
        let utc = engine::sources::sun_position::format_utc(&t);
        let p = engine::sources::sun_position::sun_position(&utc, lat, lon, 0.0, None)
            .with_context(|| format!("the Sun's position at {utc}"))?;
        let sun =
            engine::frame::direction_from_angles(p.zenith.to_radians(), p.azimuth.to_radians());
        let (direct, diffuse) = if p.zenith < 90.0 {
            table.at(p.zenith)
        } else {
            (0.0, 0.0)
        };
        // Local solar hour (the clock hour, less the zone's offset, plus the longitude's).
        let solar_hour = secs / 3600.0 - offset_h + lon / 15.0;
        let t_air =
            t_mean + t_amp * ((solar_hour - w.hour_of_max) / 24.0 * std::f64::consts::TAU).cos();
        drives.push(Drive::new(
            sun,
            direct,
            diffuse,
            t_air,
            w.relative_humidity,
            w.wind_speed_m_s,
        ));
        let minutes = ((secs / 60.0).round() as u32) % 1440;
        info.push(StepInfo {
            local: format!("{:02}:{:02}", minutes / 60, minutes % 60),
            utc,
            sun_zenith_deg: p.zenith,
            sun_azimuth_deg: p.azimuth,
        });
    }
    Ok((
        Day {
            dt,
            steps: drives,
            surround_albedo: cfg.shortwave.surround_albedo,
        },
        info,
    ))
}

fn write_atomic(path: &Path, text: &str) -> anyhow::Result<()> {
    let part = path.with_extension("part");
    std::fs::write(&part, text).with_context(|| format!("cannot write {}", part.display()))?;
    std::fs::rename(&part, path)
        .with_context(|| format!("cannot move {} to {}", part.display(), path.display()))
}

fn bar(progress: bool, len: u64, what: &str) -> indicatif::ProgressBar {
    if !progress {
        return indicatif::ProgressBar::hidden();
    }
    let b = indicatif::ProgressBar::new(len);
    if let Ok(style) = indicatif::ProgressStyle::with_template(
        "{msg:24} [{elapsed_precise}] {wide_bar} {pos}/{len} (eta {eta})",
    ) {
        b.set_style(style);
    }
    b.set_message(what.to_string());
    b
}
