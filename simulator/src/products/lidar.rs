//! The products of lidar measures (`engine::lidar`, traced by `crate::lidar`): `ID_waveform.csv`,
//! `ID_totals.csv`, `ID_metrics.csv`, for photon counting `ID_photon_stats.csv` and
//! `ID_photons.csv`, for discrete returns `ID.las`; columns in docs/experiment.md, "Lidar".

use std::fmt::Write as _;
use std::path::Path;

use engine::lidar::trace::{Stat, COMP_NAMES, NCOMP};
use engine::lidar::{LidarMode, LidarResult, C_M_PER_NS};

use crate::error::OutputError;

/// A number for the CSV products: plain for 10⁻³ ≤ |x| < 10⁷, else in exponent form (the
/// shortest text that reads back to the same f64 either way).
fn num(x: f64) -> String {
    if x == 0.0 {
        "0".into()
    } else if (1e-3..1e7).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// The text of `ID_waveform.csv`: one row per shot and bin.
pub fn waveform_csv(r: &LidarResult) -> String {
    let l = &r.lidar;
    let mut s = String::from("shot,x,y,time_ns,range_m,height_m");
    for name in ["energy"].iter().chain(COMP_NAMES[1..].iter()) {
        let _ = write!(s, ",{name},{name}_stderr");
    }
    s.push_str(",energy_j,energy_j_stderr\n");
    for (k, w) in r.shots.iter().enumerate() {
        let c = l.shots[k];
        let r0 = l.range0(c);
        let scale = l.pulse_energy_j * l.energy_scale(c);
        let [x, y] = l.shots_given[k];
        for (b, stats) in w.bins.iter().enumerate() {
            let t = l.bins.centre_ns(b);
            let _ = write!(
                s,
                "{k},{x},{y},{},{},{}",
                num(t),
                num(r0 + 0.5 * C_M_PER_NS * t),
                num(-0.5 * C_M_PER_NS * t)
            );
            for st in stats.iter().take(NCOMP) {
                let _ = write!(s, ",{},{}", num(st.mean), num(st.stderr));
            }
            let _ = writeln!(
                s,
                ",{},{}",
                num(stats[0].mean * scale),
                num(stats[0].stderr * scale)
            );
        }
    }
    s
}

/// The text of `ID_totals.csv`: one row per shot and part of the return.
pub fn totals_csv(r: &LidarResult) -> String {
    let l = &r.lidar;
    let mut s = String::from(
        "shot,x,y,part,energy,energy_stderr,energy_j,energy_j_stderr,photons_traced\n",
    );
    for (k, w) in r.shots.iter().enumerate() {
        let scale = l.pulse_energy_j * l.energy_scale(l.shots[k]);
        let [x, y] = l.shots_given[k];
        for (c, st) in w.totals.iter().enumerate() {
            let _ = writeln!(
                s,
                "{k},{x},{y},{},{},{},{},{},{}",
                COMP_NAMES[c],
                num(st.mean),
                num(st.stderr),
                num(st.mean * scale),
                num(st.stderr * scale),
                w.photons
            );
        }
    }
    s
}

/// The text of `ID_metrics.csv`: GEDI-like metrics per shot (engine::lidar::metrics), heights
/// in m (the ground above the footprint centre and as an elevation; RH above the ground), each
/// with its standard error; shots without a ground return are left out.
pub fn metrics_csv(r: &LidarResult) -> String {
    use engine::lidar::metrics::RH_PERCENTS;
    let mut s = String::from("shot,x,y,ground_m,ground_m_stderr,ground_elevation_m");
    for p in RH_PERCENTS {
        let _ = write!(s, ",rh{p},rh{p}_stderr");
    }
    s.push_str(",top_m,top_m_stderr,cover,cover_stderr\n");
    for (k, w) in r.shots.iter().enumerate() {
        let Some((m, e)) = &w.metrics else {
            continue;
        };
        let [x, y] = r.lidar.shots_given[k];
        let zc = r.lidar.shots[k].z;
        let _ = write!(
            s,
            "{k},{x},{y},{},{},{}",
            num(m.ground),
            num(e.ground),
            num(zc + m.ground)
        );
        for (v, se) in m.rh.iter().zip(&e.rh) {
            let _ = write!(s, ",{},{}", num(*v), num(*se));
        }
        let _ = writeln!(
            s,
            ",{},{},{},{}",
            num(m.top),
            num(e.top),
            num(m.cover),
            num(e.cover)
        );
    }
    s
}

/// The text of `ID_photon_stats.csv`: per location, each statistic with its standard error.
pub fn photon_stats_csv(r: &LidarResult) -> String {
    let mut s = String::from("location,x,y,statistic,value,stderr\n");
    for (k, st) in r.counting.iter().enumerate() {
        let [x, y] = r.lidar.shots_given[k];
        let mut row = |name: &str, v: Stat| {
            let _ = writeln!(s, "{k},{x},{y},{name},{},{}", num(v.mean), num(v.stderr));
        };
        row("mean", st.mean);
        row("variance", st.variance);
        for (j, p) in st.p.iter().enumerate() {
            row(&format!("p{j}"), *p);
        }
        row("canopy_mean", st.canopy_mean);
        row("ground_mean", st.ground_mean);
        row("ground_p0", st.ground_p0);
        row("background_per_gate", st.background_per_gate);
        // What the simulated shots gave (a check of the Poisson draws).
        let shots = r.lidar.shots_per_location as f64;
        let signal = r
            .events
            .iter()
            .filter(|e| e.location == k && e.signal)
            .count() as f64;
        row(
            "simulated_signal_mean",
            Stat {
                mean: signal / shots,
                stderr: (signal.max(1.0)).sqrt() / shots,
            },
        );
    }
    s
}

/// The text of `ID_photons.csv` (ATL03-like): one row per detected photon.
pub fn photons_csv(r: &LidarResult) -> String {
    let mut s = String::from("location,shot,time_ns,height_m,signal\n");
    for e in &r.events {
        let _ = writeln!(
            s,
            "{},{},{},{},{}",
            e.location,
            e.shot,
            num(e.time_ns),
            num(e.height_m),
            u8::from(e.signal)
        );
    }
    s
}

/// The points of a discrete-return run: position in the output CRS (the scene's working CRS,
/// or the local frame of a 1D run), and the return.
pub fn points(r: &LidarResult) -> Vec<([f64; 3], usize, engine::lidar::discrete::Return, u8)> {
    let l = &r.lidar;
    let origin = r.georef.as_ref().map_or(glam::DVec3::ZERO, |g| g.origin);
    let axis = -l.to_sensor;
    let mut out = Vec::new();
    for (k, rets) in r.returns.iter().enumerate() {
        let c = l.shots[k];
        let s = l.sensor(c);
        for (ret, class) in rets {
            let range = l.range0(c) + 0.5 * C_M_PER_NS * ret.time_ns;
            let p = s + axis * range + origin;
            out.push(([p.x, p.y, p.z], k, *ret, *class));
        }
    }
    out
}

/// Write the discrete returns of `r` as a LAS 1.4 point cloud (point format 6: GPS time,
/// return numbers up to 15; coordinates to the millimetre; the working CRS as a WKT VLR).
/// Intensity: the return's normalised energy × 65 535 (1 = a white Lambertian plane at normal
/// incidence), clipped; classification: the class of the surfaces whose first-order returns
/// carry most of the return's energy (`engine::lidar::discrete::class_of`: `las_classes`, else
/// ground 2, water 9, leaves 5, other objects 1), or by the ground share when no first-order
/// return falls in its window; GPS time: shot index / `pulse_rate_hz`; point source id: the shot index
/// (modulo 65 536).
pub fn write_las(path: &Path, r: &LidarResult) -> Result<(), OutputError> {
    let err = |e: las::Error| OutputError::Io {
        path: path.to_path_buf(),
        source: std::io::Error::other(e.to_string()),
    };
    let mut b = las::Builder::from((1, 4));
    b.point_format = las::point::Format::new(6).map_err(err)?;
    b.generating_software = "eo-simulate".into();
    b.system_identifier = "lidar simulation".into();
    let pts = points(r);
    let mut lo = [f64::INFINITY; 3];
    for (p, _, _, _) in &pts {
        for i in 0..3 {
            lo[i] = lo[i].min(p[i]);
        }
    }
    let offset = |i: usize| {
        if lo[i].is_finite() {
            lo[i].floor()
        } else {
            0.0
        }
    };
    b.transforms = las::Vector {
        x: las::Transform {
            scale: 0.001,
            offset: offset(0),
        },
        y: las::Transform {
            scale: 0.001,
            offset: offset(1),
        },
        z: las::Transform {
            scale: 0.001,
            offset: offset(2),
        },
    };
    let mut header = b.into_header().map_err(err)?;
    if let Some(g) = &r.georef {
        header
            .set_wkt_crs(g.wkt.clone().into_bytes())
            .map_err(err)?;
    }
    let mut w = las::Writer::from_path(path, header).map_err(err)?;
    for (p, k, ret, class) in pts {
        let point = las::Point {
            x: p[0],
            y: p[1],
            z: p[2],
            intensity: (ret.energy * 65535.0).round().clamp(0.0, 65535.0) as u16,
            return_number: ret.number,
            number_of_returns: ret.count,
            classification: las::point::Classification::new(class).map_err(err)?,
            gps_time: Some(k as f64 / r.lidar.pulse_rate_hz),
            point_source_id: (k % 65_536) as u16,
            ..Default::default()
        };
        w.write_point(point).map_err(err)?;
    }
    w.close().map_err(err)
}

/// Write every lidar product into `dir`.
pub fn write(dir: &Path, results: &[LidarResult]) -> Result<(), OutputError> {
    let put = |name: String, text: String| {
        let path = dir.join(name);
        std::fs::write(&path, text).map_err(|source| OutputError::Io { path, source })
    };
    for r in results {
        let id = &r.lidar.id;
        put(format!("{id}_waveform.csv"), waveform_csv(r))?;
        put(format!("{id}_totals.csv"), totals_csv(r))?;
        put(format!("{id}_metrics.csv"), metrics_csv(r))?;
        if r.lidar.mode == LidarMode::Discrete {
            write_las(&dir.join(format!("{id}.las")), r)?;
        }
        if r.lidar.mode == LidarMode::PhotonCounting {
            put(format!("{id}_photon_stats.csv"), photon_stats_csv(r))?;
            put(format!("{id}_photons.csv"), photons_csv(r))?;
        }
    }
    Ok(())
}
