//! Writes `validation/clouds/i3rc.csv`: the I3RC Phase 1 cases 1–3 and the IPRT phase B C2
//! cube (vacuum run, intensity) from the inputs of `shared/clouds`, in the format of that
//! folder's README (§6), by the forward column estimator (`engine::clouds::columns`).
//!
//! ```text
//! cargo run --release -p simulator --example cloud_cases -- ../shared/clouds validation/clouds/i3rc.csv [--scale S] [--only CASE]
//! ```
//! `--scale` multiplies every run's photon count (1 = the committed budgets); `--only` runs one
//! case (`1`, `2`, `3`, `iprt_c2`). Prints each run's domain means, median relative standard
//! error and wall time.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use engine::clouds::columns::{self, ColumnSetup};
use engine::clouds::kit::{self, CasePhase};
use engine::clouds::CloudGrid;
use glam::DVec3;

/// Photons per run at `--scale 1`.
const CASE1_PHOTONS: u64 = 4_000_000;
const CASE2_PHOTONS: u64 = 6_000_000;
const CASE3_PHOTONS: u64 = 12_000_000;
const IPRT_PHOTONS: u64 = 20_000_000;
const BATCHES: usize = 32;

struct Row {
    case: String,
    exp: u32,
    quantity: &'static str,
    index: usize,
    value: f64,
    stderr: f64,
}

fn sun(sza: f64) -> DVec3 {
    let s = sza.to_radians();
    DVec3::new(s.sin(), 0.0, -s.cos())
}

fn median_rel(v: &columns::Estimate) -> f64 {
    let mut r: Vec<f64> = v
        .value
        .iter()
        .zip(&v.stderr)
        .filter(|(x, _)| **x > 0.0)
        .map(|(x, e)| e / x)
        .collect();
    if r.is_empty() {
        return 0.0;
    }
    r.sort_by(f64::total_cmp);
    r[r.len() / 2]
}

/// One I3RC experiment: every output of the case, one row per column.
#[allow(clippy::too_many_arguments)]
fn i3rc(
    rows: &mut Vec<Row>,
    case: &str,
    exp: u32,
    grid: &CloudGrid,
    top: f64,
    sza: f64,
    albedo: f64,
    slanted: bool,
    photons: u64,
) -> anyhow::Result<()> {
    let s60 = 60f64.to_radians();
    let mut dirs = vec![("Iu", DVec3::Z), ("Id", -DVec3::Z)];
    if slanted {
        dirs.push(("I601", DVec3::new(s60.sin(), 0.0, s60.cos())));
        dirs.push(("I602", DVec3::new(-s60.sin(), 0.0, s60.cos())));
    }
    let px = (grid.nx, grid.ny);
    let setup = ColumnSetup {
        top,
        surface_albedo: albedo,
        sun: sun(sza),
        flux_pixels: px,
        radiance_pixels: px,
        radiances: dirs.iter().map(|d| d.1).collect(),
        photons,
        batches: BATCHES,
        seed: 2026 + u64::from(exp) * 17 + case.len() as u64,
        ddis: columns::DDIS_SHARE,
    };
    let t0 = Instant::now();
    let r = columns::run(grid, &setup)?;
    let [(rm, re), (tm, te), (am, ae)] = r.domain;
    eprintln!(
        "case {case} exp {exp}: R {rm:.5}±{re:.1e} T {tm:.5}±{te:.1e} A {am:.5}±{ae:.1e}; median rel. stderr R {:.2}% T {:.2}% Iu {:.2}%; {:.1} collisions/photon; {:.1} s",
        100.0 * median_rel(&r.r),
        100.0 * median_rel(&r.t),
        100.0 * median_rel(&r.radiance[0]),
        r.collisions_per_photon,
        t0.elapsed().as_secs_f64()
    );
    let omega = grid.albedo.at(0);
    let mut push = |q: &'static str, e: &columns::Estimate| {
        for (k, (&v, &se)) in e.value.iter().zip(&e.stderr).enumerate() {
            rows.push(Row {
                case: case.into(),
                exp,
                quantity: q,
                index: k + 1,
                value: v,
                stderr: se,
            });
        }
    };
    push("R", &r.r);
    push("T", &r.t);
    if omega < 1.0 {
        push("A", &r.a);
    }
    for (k, (q, _)) in dirs.iter().enumerate() {
        push(q, &r.radiance[k]);
    }
    Ok(())
}

/// IPRT C2, vacuum run: intensity L/E0 of the 9 geometries on 70 × 70 pixels.
fn iprt(rows: &mut Vec<Row>, kit_dir: &Path, photons: u64) -> anyhow::Result<()> {
    let (grid, _) = kit::iprt_c2(kit_dir)?;
    let geoms: [(f64, f64, f64, f64); 9] = [
        (20.0, 0.0, 40.0, 0.0),
        (20.0, 0.0, 40.0, 60.0),
        (20.0, 0.0, 40.0, 120.0),
        (20.0, 0.0, 40.0, 180.0),
        (40.0, 5.0, 180.0, 0.0),
        (40.0, 5.0, 140.0, 0.0),
        (40.0, 5.0, 140.0, 60.0),
        (40.0, 5.0, 140.0, 120.0),
        (40.0, 5.0, 140.0, 180.0),
    ];
    for sza in [20.0, 40.0] {
        let chosen: Vec<(u32, DVec3)> = geoms
            .iter()
            .enumerate()
            .filter(|(_, g)| g.0 == sza)
            .map(|(k, &(_, _, th, ph))| {
                let (t, p) = (th.to_radians(), ph.to_radians());
                // Photons travel against the line of sight.
                let los = DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
                (k as u32 + 1, -los)
            })
            .collect();
        let setup = ColumnSetup {
            top: 5000.0,
            surface_albedo: 0.2,
            sun: sun(sza),
            flux_pixels: (7, 7),
            radiance_pixels: (70, 70),
            radiances: chosen.iter().map(|c| c.1).collect(),
            photons,
            batches: BATCHES,
            seed: 77 + sza as u64,
            ddis: columns::DDIS_SHARE,
        };
        let t0 = Instant::now();
        let r = columns::run(&grid, &setup)?;
        let mu0 = sza.to_radians().cos();
        for (k, &(g, _)) in chosen.iter().enumerate() {
            let e = &r.radiance[k];
            eprintln!(
                "iprt_c2 geometry {g}: mean I {:.5e}, median rel. stderr {:.2}%",
                e.mean() * mu0 / std::f64::consts::PI,
                100.0 * median_rel(e)
            );
            for iy in 0..70 {
                for ix in 0..70 {
                    let p = iy * 70 + ix;
                    // π·L/(E0·μ0) → L/E0.
                    let f = mu0 / std::f64::consts::PI;
                    rows.push(Row {
                        case: "iprt_c2".into(),
                        exp: g,
                        quantity: "I",
                        index: ix * 70 + iy + 1,
                        value: e.value[p] * f,
                        stderr: e.stderr[p] * f,
                    });
                }
            }
        }
        eprintln!("iprt_c2 sza {sza}: {:.1} s", t0.elapsed().as_secs_f64());
    }
    Ok(())
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut pos = Vec::new();
    let mut scale = 1.0_f64;
    let mut only: Option<String> = None;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--scale" => scale = it.next().and_then(|v| v.parse().ok()).unwrap_or(1.0),
            "--only" => only = it.next().cloned(),
            _ => pos.push(a.clone()),
        }
    }
    let [kit_dir, out] = pos.as_slice() else {
        anyhow::bail!("usage: cloud_cases KIT_DIR OUT.csv [--scale S] [--only 1|2|3|iprt_c2]");
    };
    let kit_dir = PathBuf::from(kit_dir);
    let n = |base: u64| ((base as f64 * scale) as u64).max(BATCHES as u64);
    let runs = |c: &str| only.as_deref().is_none_or(|o| o == c);
    let mut rows = Vec::new();
    let exps = [(0.0, 1.0), (60.0, 1.0), (0.0, 0.99), (60.0, 0.99)];
    if runs("1") {
        for (k, &(sza, w)) in exps.iter().enumerate() {
            let g = kit::i3rc_case1(&kit_dir, w)?;
            i3rc(
                &mut rows,
                "1",
                k as u32 + 1,
                &g,
                250.0,
                sza,
                0.0,
                true,
                n(CASE1_PHOTONS),
            )?;
        }
    }
    if runs("2") {
        let c2 = [
            (0.0, 1.0, 0.0, CasePhase::Hg),
            (60.0, 1.0, 0.0, CasePhase::Hg),
            (0.0, 0.99, 0.0, CasePhase::Hg),
            (60.0, 0.99, 0.0, CasePhase::Hg),
            (60.0, 1.0, 0.4, CasePhase::Hg),
            (0.0, 1.0, 0.0, CasePhase::C1),
            (60.0, 1.0, 0.0, CasePhase::C1),
            (60.0, 1.0, 0.4, CasePhase::C1),
        ];
        for (k, &(sza, w, alb, pf)) in c2.iter().enumerate() {
            let g = kit::i3rc_case2(&kit_dir, w, pf)?;
            i3rc(
                &mut rows,
                "2",
                k as u32 + 1,
                &g,
                2430.0,
                sza,
                alb,
                false,
                n(CASE2_PHOTONS),
            )?;
        }
    }
    if runs("3") {
        for (k, &(sza, w)) in exps.iter().enumerate() {
            let g = kit::i3rc_case3(&kit_dir, w, 200.0)?;
            i3rc(
                &mut rows,
                "3",
                k as u32 + 1,
                &g,
                2580.0,
                sza,
                0.0,
                false,
                n(CASE3_PHOTONS),
            )?;
        }
    }
    if runs("iprt_c2") {
        iprt(&mut rows, &kit_dir, n(IPRT_PHOTONS))?;
    }
    let tmp = PathBuf::from(format!("{out}.part"));
    {
        let mut f = std::io::BufWriter::new(std::fs::File::create(&tmp)?);
        writeln!(f, "case,exp,quantity,column_index,value,stderr")?;
        for r in &rows {
            writeln!(
                f,
                "{},{},{},{},{:.6e},{:.3e}",
                r.case, r.exp, r.quantity, r.index, r.value, r.stderr
            )?;
        }
        f.flush()?;
    }
    std::fs::rename(&tmp, out)?;
    eprintln!("wrote {} rows to {out}", rows.len());
    Ok(())
}
