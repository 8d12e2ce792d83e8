//! Monochromatic polarized transport through the O2 A-band against ARTDECO's line-by-line
//! benchmark (32-stream doubling-adding, I, Q, U at the top of the atmosphere), as used by the
//! SMART-G validation (shared data `artdeco_o2a/`, MANIFEST §4; origin hygeos/smartg
//! `smartg/validation/` @acd4fb98). Needs the shared data folder (`../shared/data` beside the
//! repository, or `SIMULATOR_SHARED_DATA`); skips with a message when it is absent.
//!
//! Case: Rayleigh scattering without depolarization + O2 absorption, black surface, plane-parallel
//! atmosphere 0–120 km in the 49 layers of the files (levels 120 → 0 km; each layer's optical
//! thicknesses are the differences of the cumulative ones, homogeneous in the layer, as in
//! doubling-adding), 1089 wavelengths 765.0–768.0 nm. Sun at zenith 30°, view zenith 20° at TOA.
//!
//! Azimuth. SMART-G's local estimate uses φ = 180°. In SMART-G (`smartg/src/device.cu`) the
//! photons of a forward run start along the rotation of +z by θ = 180° − SZA about y, then by
//! φ = 0 + 180° about z, i.e. they travel along (−sin SZA, 0, −cos SZA): the Sun is towards +x
//! (azimuth 0), and the local-estimate direction (cos φ sin θ, sin φ sin θ, cos θ) with φ = 180°
//! points towards −x. The view (target → sensor) is thus opposite to the Sun's azimuth: our
//! relative azimuth raa = φ_view − φ_sun = 180°, the forward-scattering side (docs/conventions.md);
//! here Sun azimuth 0, view azimuth 180. The scattering angle is Θ = 180° − (30° + 20°) = 130°,
//! whose single-scattering Rayleigh polarization −sin²Θ/(1 + cos²Θ) = −0.41525 is what ARTDECO
//! gives in the optically deep line cores (−0.41522, single scattering only); raa = 0 would give
//! Θ = 170° and −0.015. (The sense in which azimuths turn is immaterial in the principal plane.)
//!
//! Normalization and signs. ARTDECO's values are π·(I, Q, U)/(μ0·E⊥): our BRF and the BRF-like
//! `brf_q`, `brf_u` (π·Q/(E0 cos SZA)), compared directly. Q: in the principal plane single-
//! scattered Rayleigh light has Q < 0 in our meridian frame, and ARTDECO's Q < 0 too: no sign
//! change (unlike Natraj 2009). U vanishes by mirror symmetry about the principal plane (ARTDECO
//! prints 0 exactly), so its sign convention (which differs for IPRT) is untestable here; ours is
//! checked to be 0 within noise.
//!
//! Statistical test: as `common::check_all`, |ours − ARTDECO| ≤ K·σ + floor with K = 4.5 and σ
//! our standard error, but floor = max(ABS_FLOOR, REF_REL·|ARTDECO|), ABS_FLOOR = 1e-8 (BRF units;
//! the smallest reference value is 1.5e-5 and ARTDECO prints 9 digits, so it only matters for U,
//! whose reference is 0) and REF_REL = 1e-3, the precision granted to the 32-stream
//! discrete-ordinate reference. Our single-scattering part equals the analytic one to < 1e-6
//! (checked below, for every point). In the continuum the multiple-scattering parts (4 % of I)
//! agree to < 0.1 % of themselves; in the line cores, where single scattering is everything,
//! ARTDECO agrees with us to ≤ 1e-4 in I and ≤ 2e-4 in Q. But in the line wings (column gas τ ≈ 1–90) ARTDECO's
//! multiple-scattering part exceeds ours by 1–4 % in I and is 7–17 % smaller in |Q| (medians per
//! τ range over the 1089 wavelengths), i.e. up to ≈ 3e-4 of I and ≈ 1e-3 of Q, with the same signs
//! (I higher, Q less negative) as ARTDECO's evident error in the three deepest cores (below); our
//! forward and backward walks agree with each other there (checked once at 765.10, 765.12,
//! 766.81 and 767.38 nm: ≤ 1.7σ apart, both 5–10σ from ARTDECO in Q without the floor). The
//! common floor 1e-5 is not used: it is 60 % of the deepest cores.
//!
//! Reference anomaly: at the three deepest cores (765.112, 765.222, 765.225 nm, column gas τ
//! 98–110) ARTDECO's I is 5.7–6.8 % above the exact single-scattering value and its Q/I is
//! −0.27 … −0.29 instead of −0.415, although the single-scattering albedo is 1e-4 … 1e-3 in every
//! layer light reaches (above absorption optical depth 10), so multiple scattering is ~1e-4 of I
//! (in our runs, and in ARTDECO's own next-deepest cores, τ 50–82): the reference is not
//! self-consistent at those points. A reference point is flagged
//! when the column gas τ exceeds 20 (single scattering dominates) and its Q/I departs from the
//! single-scattering value by more than 5 % (all other such points are within 0.2 %); flagged
//! points are checked against the analytic single scattering instead (our I at most 0.1 % above
//! it, our Q/I within 0.1 % of −0.41525).
//!
//! Wavelengths compared (deterministic): every 27th of the 1089 (continuum and wings), the
//! wavelengths whose column gas τ is closest (in log) to 0.3, 1, 3, 10, 30 (line wings), and the
//! 10 deepest cores. Fixed seed; `target_rel_stderr` stops the line cores early (they are almost
//! noise-free: single scattering is estimated exactly along each flight).
//!
//! `cargo test --release -p simulator --test artdeco_o2a -- --nocapture` prints the table;
//! `-- --ignored` runs all 1089 wavelengths and writes `validation/artdeco_o2a/comparison.csv`
//! (plotted by `tools/plots/artdeco_plot.py`).

mod common;
use common::artdeco::{read_cumulative, shared_dir, Cumulative};
use common::{experiment, run_rows, Cmp, K};

use std::collections::BTreeSet;
use std::path::Path;

const SZA: f64 = 30.0;
const VZA: f64 = 20.0;
/// Our view azimuth with the Sun at azimuth 0 (SMART-G's φ = 180°, see the header).
const VAA: f64 = 180.0;
const ABS_FLOOR: f64 = 1e-8;
const REF_REL: f64 = 1e-3;

struct Case {
    gas: Cumulative,
    ray: Cumulative,
    /// ARTDECO's (I, Q, U) per wavelength.
    reference: Vec<[f64; 3]>,
}

impl Case {
    fn load(dir: &Path) -> Case {
        let gas = read_cumulative(&dir.join("cTauGas_ray_O2.dat"));
        let ray = read_cumulative(&dir.join("cTauRay_ray_O2.dat"));
        let text = std::fs::read_to_string(dir.join("artdeco_lbl_nstr_32_ray_O2.dat")).unwrap();
        let mut reference = Vec::new();
        for (k, l) in text
            .lines()
            .filter(|l| !l.trim_start().starts_with('#') && !l.trim().is_empty())
            .enumerate()
        {
            let f: Vec<f64> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            assert!((f[0] - gas.wavelengths[k]).abs() < 1e-6, "wavelength {k}");
            reference.push([f[1], f[2], f[3]]);
        }
        assert_eq!(reference.len(), gas.wavelengths.len());
        assert_eq!(gas.altitudes, ray.altitudes);
        assert_eq!(gas.wavelengths, ray.wavelengths);
        assert_eq!(gas.altitudes[0], 120.0);
        assert_eq!(*gas.altitudes.last().unwrap(), 0.0);
        Case {
            gas,
            ray,
            reference,
        }
    }

    fn n_layers(&self) -> usize {
        self.gas.altitudes.len() - 1
    }

    /// Optical thickness of layer `l` (0 = the top one) at wavelength index `k`.
    fn layer(od: &Cumulative, l: usize, k: usize) -> f64 {
        common::artdeco::layer(od, l, k)
    }

    fn column_gas(&self, k: usize) -> f64 {
        *self.gas.cum.last().unwrap().get(k).unwrap()
    }

    /// Analytic single-scattering BRF (exact for homogeneous layers over a black surface).
    fn single_scattering(&self, k: usize) -> f64 {
        common::artdeco::single_scattering(&self.gas, &self.ray, k, SZA, VZA, VAA)
    }

    /// ARTDECO's point is not self-consistent (see the header).
    fn reference_inconsistent(&self, k: usize) -> bool {
        let [i, q, _] = self.reference[k];
        self.column_gas(k) > 20.0 && (q / i / rayleigh_polarization() - 1.0).abs() > 0.05
    }

    fn experiment_text(&self, idx: &[usize], seed: u64, spp: u64, target: f64) -> String {
        let list = |v: Vec<f64>| {
            v.iter()
                .map(|x| format!("{x:?}"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let mut t = format!(
            "seed = {seed}\npolarized = true\n[spectral]\nwavelengths = [{}]\n\
             [geometry]\ntype = \"plane_parallel\"\ntoa_altitude = 120.0\n\
             [atmosphere]\ntype = \"layered\"\n",
            list(idx.iter().map(|&k| self.gas.wavelengths[k]).collect())
        );
        for l in 0..self.n_layers() {
            t += &format!(
                "[[atmosphere.layers]]\nbottom = {:?}\ntop = {:?}\nphase = {{ type = \"rayleigh\", depolarization = 0.0 }}\n\
                 tau_sca = [{}]\ntau_abs = [{}]\n",
                self.gas.altitudes[l + 1],
                self.gas.altitudes[l],
                list(idx.iter().map(|&k| Self::layer(&self.ray, l, k)).collect()),
                list(idx.iter().map(|&k| Self::layer(&self.gas, l, k)).collect()),
            );
        }
        t += &format!(
            "[surface]\ntype = \"lambertian\"\nreflectance = 0.0\n\
             [illumination]\ntype = \"directional\"\nzenith = {SZA:?}\nazimuth = 0.0\n\
             [[measures]]\nid = \"toa\"\ntype = \"mdistant\"\nconstruct = \"directions\"\n\
             zeniths = [{VZA:?}]\nazimuths = [{VAA:?}]\nspp = {spp}\ntarget_rel_stderr = {target:?}\n"
        );
        t
    }

    /// Our (value, stderr) of I, Q, U and of the single-scattering I, per index of `idx`.
    fn run(&self, idx: &[usize], seed: u64, spp: u64, target: f64) -> Vec<Ours> {
        let rows = run_rows(&experiment(&self.experiment_text(idx, seed, spp, target)));
        idx.iter()
            .map(|&k| {
                let w = self.gas.wavelengths[k];
                let r = rows
                    .iter()
                    .find(|r| (r.wavelength_nm - w).abs() < 1e-9)
                    .unwrap_or_else(|| panic!("no row at {w} nm"));
                Ours {
                    k,
                    iqu: [r.brf.unwrap(), r.brf_q.unwrap(), r.brf_u.unwrap()],
                    single: r.brf_single.unwrap(),
                }
            })
            .collect()
    }
}

struct Ours {
    k: usize,
    iqu: [(f64, f64); 3],
    single: (f64, f64),
}

fn cos_scattering_angle() -> f64 {
    let sun = engine::frame::direction_from_angles(SZA.to_radians(), 0.0);
    let view = engine::frame::direction_from_angles(VZA.to_radians(), VAA.to_radians());
    // Incident propagation direction −sun, scattered along view.
    -sun.dot(view)
}

/// Q/I of single-scattered Rayleigh light (depolarization 0) in our meridian frame.
fn rayleigh_polarization() -> f64 {
    let c = cos_scattering_angle();
    -(1.0 - c * c) / (1.0 + c * c)
}

/// The wavelength indices compared by the regular test (see the header).
fn subset(case: &Case) -> Vec<usize> {
    let n = case.gas.wavelengths.len();
    let mut set: BTreeSet<usize> = (0..n).step_by(27).collect();
    let col: Vec<f64> = (0..n).map(|k| case.column_gas(k)).collect();
    for target in [0.3f64, 1.0, 3.0, 10.0, 30.0] {
        let k = (0..n)
            .min_by(|&a, &b| {
                let d = |k: usize| (col[k].ln() - target.ln()).abs();
                d(a).total_cmp(&d(b))
            })
            .unwrap();
        set.insert(k);
    }
    let mut by_depth: Vec<usize> = (0..n).collect();
    by_depth.sort_by(|&a, &b| col[b].total_cmp(&col[a]));
    set.extend(by_depth.into_iter().take(10));
    set.into_iter().collect()
}

/// `common::check_all`'s test with this reference's floor (see the header):
/// pass when |value − reference| ≤ K·stderr + max(ABS_FLOOR, REF_REL·|reference|).
fn check(case: &str, cmps: &[Cmp]) -> Result<(), String> {
    let (mut worst_rel, mut worst_z) = (0.0_f64, 0.0_f64);
    let mut failures = Vec::new();
    for c in cmps {
        let diff = (c.value - c.reference).abs();
        let tol = K * c.stderr + ABS_FLOOR.max(REF_REL * c.reference.abs());
        if c.reference != 0.0 {
            worst_rel = worst_rel.max(diff / c.reference.abs());
        }
        if c.stderr > 0.0 {
            worst_z = worst_z.max(diff / c.stderr);
        }
        #[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN must fail
        if !(diff <= tol) {
            failures.push(format!(
                "  {}: value {:.6e} ± {:.1e}, reference {:.6e}, |diff| {:.2e} > tol {:.2e} (z = {:.1})",
                c.label,
                c.value,
                c.stderr,
                c.reference,
                diff,
                tol,
                diff / c.stderr
            ));
        }
    }
    println!(
        "{case}: {} comparisons, max |rel diff| = {worst_rel:.3e}, max z = {worst_z:.2}",
        cmps.len()
    );
    if failures.is_empty() {
        Ok(())
    } else {
        Err(format!(
            "{case}: {} of {} comparisons failed:\n{}",
            failures.len(),
            cmps.len(),
            failures.join("\n")
        ))
    }
}

/// Prints the table and checks every point; returns the failures.
fn compare(case: &Case, ours: &[Ours], print_table: bool) -> Result<(), String> {
    let mut cmps = Vec::new();
    let mut errs = Vec::new();
    let pol = rayleigh_polarization();
    if print_table {
        println!(
            "{:>10} {:>8} | {:>23} {:>11} {:>7} | {:>23} {:>12} {:>7} | {:>5}",
            "λ [nm]",
            "τ_gas",
            "I ours ± σ",
            "I ARTDECO",
            "z_I",
            "Q ours ± σ",
            "Q ARTDECO",
            "z_Q",
            "z_U"
        );
    }
    let (mut max_rel_i, mut max_z_i) = (0.0_f64, 0.0_f64);
    for o in ours {
        let k = o.k;
        let w = case.gas.wavelengths[k];
        let r = case.reference[k];
        let z = |c: usize| (o.iqu[c].0 - r[c]) / o.iqu[c].1;
        let flagged = case.reference_inconsistent(k);
        if print_table {
            println!(
                "{w:10.6} {:8.3} | {:11.5e} ± {:9.2e} {:11.5e} {:7.1} | {:11.5e} ± {:9.2e} {:12.5e} {:7.1} | {:5.1}{}",
                case.column_gas(k),
                o.iqu[0].0,
                o.iqu[0].1,
                r[0],
                z(0),
                o.iqu[1].0,
                o.iqu[1].1,
                r[1],
                z(1),
                z(2),
                if flagged {
                    "  ARTDECO inconsistent: vs single scattering"
                } else {
                    ""
                }
            );
        }
        // Our single-scattering part against the analytic value.
        let ss = case.single_scattering(k);
        let (s, es) = o.single;
        #[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN must fail
        if !((s - ss).abs() <= K * es + 1e-6 * ss) {
            errs.push(format!(
                "  {w} nm: single scattering {s:.8e} ± {es:.1e}, analytic {ss:.8e}"
            ));
        }
        if flagged {
            let (i, q) = (o.iqu[0].0, o.iqu[1].0);
            let ms = i / ss - 1.0;
            let dp = q / i / pol - 1.0;
            #[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN must fail
            if !((-1e-6..1e-3).contains(&ms) && dp.abs() < 1e-3) {
                errs.push(format!(
                    "  {w} nm (deep core): I/I_ss − 1 = {ms:.2e}, (Q/I)/(Q/I)_ss − 1 = {dp:.2e}"
                ));
            }
            continue;
        }
        max_rel_i = max_rel_i.max((o.iqu[0].0 / r[0] - 1.0).abs());
        max_z_i = max_z_i.max(z(0).abs());
        for (c, name) in ["I", "Q", "U"].iter().enumerate() {
            cmps.push(Cmp {
                label: format!("{name} {w} nm"),
                reference: r[c],
                value: o.iqu[c].0,
                stderr: o.iqu[c].1,
            });
        }
    }
    println!("I alone: max |rel diff| = {max_rel_i:.3e}, max |z| = {max_z_i:.2} (without floor)");
    if let Err(e) = check("ARTDECO O2 A-band I, Q, U", &cmps) {
        errs.push(e);
    }
    if errs.is_empty() {
        Ok(())
    } else {
        Err(errs.join("\n"))
    }
}

#[test]
fn artdeco_o2a_band() {
    let Some(dir) = shared_dir() else {
        eprintln!("skipped: shared data folder artdeco_o2a not found");
        return;
    };
    let case = Case::load(&dir);
    let idx = subset(&case);
    assert!(idx.len() >= 50, "{} wavelengths", idx.len());
    let t = std::time::Instant::now();
    let ours = case.run(&idx, 17, 400_000, 2e-4);
    println!(
        "{} wavelengths simulated in {:.1} s",
        idx.len(),
        t.elapsed().as_secs_f64()
    );
    compare(&case, &ours, true).unwrap();
}

/// All 1089 wavelengths; writes `validation/artdeco_o2a/comparison.csv` (≈ 5 min on 2 cores with
/// the default 200 000 samples per wavelength, which `ARTDECO_SPP` overrides), then applies the
/// same checks as `artdeco_o2a_band`.
#[test]
#[ignore]
fn artdeco_o2a_full_spectrum_csv() {
    let Some(dir) = shared_dir() else {
        eprintln!("skipped: shared data folder artdeco_o2a not found");
        return;
    };
    let case = Case::load(&dir);
    let spp: u64 = std::env::var("ARTDECO_SPP")
        .ok()
        .map_or(200_000, |s| s.parse().unwrap());
    let idx: Vec<usize> = (0..case.gas.wavelengths.len()).collect();
    let t = std::time::Instant::now();
    let ours = case.run(&idx, 18, spp, 2e-4);
    println!(
        "{} wavelengths simulated in {:.1} s",
        idx.len(),
        t.elapsed().as_secs_f64()
    );
    let mut csv = String::from(
        "wavelength_nm,tau_gas_column,i,i_stderr,i_ref,q,q_stderr,q_ref,u,u_stderr,u_ref,i_single_analytic,ref_inconsistent\n",
    );
    for o in &ours {
        let k = o.k;
        let r = case.reference[k];
        csv += &format!(
            "{},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{}\n",
            case.gas.wavelengths[k],
            case.column_gas(k),
            o.iqu[0].0,
            o.iqu[0].1,
            r[0],
            o.iqu[1].0,
            o.iqu[1].1,
            r[1],
            o.iqu[2].0,
            o.iqu[2].1,
            r[2],
            case.single_scattering(k),
            u8::from(case.reference_inconsistent(k))
        );
    }
    let out = Path::new(env!("CARGO_MANIFEST_DIR")).join("../validation/artdeco_o2a");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("comparison.csv"), csv).unwrap();
    compare(&case, &ours, false).unwrap();
}
