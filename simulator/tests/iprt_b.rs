//! IPRT phase A, multi-layer B-cases (Emde et al. 2015, JQSRT 164:8–36): a 30-layer standard
//! atmosphere, 0–30 km, layer optical thicknesses from `tests/data/iprt_b/tau_*.dat` (copies of
//! `shared/data/iprt_phase_a/inputs/`, see `tests/data/iprt_b/PROVENANCE.md`), Rayleigh
//! depolarization 0.03, polarized transport, outputs at 0, 1 and 30 km:
//! * B1: Rayleigh only, 450 nm, black surface, sza 60, saa 0;
//! * B2: Rayleigh + molecular absorption, 325 nm, black surface, sza 60, saa 0;
//! * B3: Rayleigh + molecular absorption + aerosol (`tau_aerosol.dat` extinction, total 0.2) with
//!   the optical properties of A4 — prolate spheroids, `fixtures/sizedistr_spheroid.cdf`, six
//!   phase-matrix elements, ω 0.78758 (IPRT wiki page of B3: "the same as in case A4
//!   (spheroidal particles)"; not the spherical `waso.mie.cdf` of A3) — 350 nm, black surface,
//!   sza 30, saa 0;
//! * B4: Rayleigh (800 nm) + a water cloud in 2–3 km (extinction τ = 5, `watercloud.mie.cdf`,
//!   r_eff 10 µm) over the A6 ocean (Cox–Munk, wind 2 m/s, n = 1.33, shadowing), sza 60, saa 0.
//!
//! The `layered` atmosphere takes one phase function per layer, so B1 and B2 are plain
//! `layered` experiments; in B3 (every layer) and B4 (the cloud layer) Rayleigh and particles
//! share a layer, and the test replaces the resolved layers' phase functions by
//! `Mixture::build([(τ_R, Rayleigh), (τ_p·ω_p, table)])` — what the `molecular` atmosphere builds
//! for its particle layers — after checking that the optical depths and albedos are unchanged
//! (`inject_mixtures`). The measures are the IPRT lines of sight: radiancemeters at 0, 1 and
//! 30 km (backward walk) looking along (vza, vaa), and at 30 km a forward `mdistant` with view
//! zenith 180 − vza and azimuth vaa + 180 (the mapping of `iprt_a.rs`).
//!
//! There are no B reference results in the shared data, so the tests check what can be checked
//! without one (each comparison: `common::check_all`, |diff| ≤ 4.5σ + max(1e-5, 2e-4·|ref|) in
//! BRF units, σ² the sum of both sides' squared standard errors, fixed seeds):
//! * `b1_layer_coupling`: B1 is conservative with the same phase matrix in every layer, so the
//!   radiance at 0 and 30 km depends only on the total optical depth, and at 1 km only on the
//!   optical depths above and below: the 30-layer results at 0 and 30 km must equal those of one
//!   homogeneous layer of the same τ, and at 1 km those of the two-layer split (0–1 km, 1–30 km)
//!   — full multiple scattering, I, Q, U, independently seeded runs; the backward walk at all
//!   three levels and the forward walk at 30 km. This tests the 30-layer bookkeeping of both
//!   walks (per-layer integrals of the expected local estimates, layer lookups, τ of the 1 km
//!   level). A 1 % change of the homogeneous τ fails it (max z 6.3).
//! * `single_scattering_analytic`: with `max_depth = 1`, the radiance is the closed-form sum over
//!   layers of (1/4μ0)·(τ_R·R(Θ) + τ_p·ω_p·P(Θ))/τ_ext · ∫ e^{−τ/μ0} e^{−|τ−τ_s|/μ} dτ/μ, written
//!   here independently of the simulator (Hansen & Travis Rayleigh matrix with Δ = (1−ρ)/(1+ρ/2);
//!   particle tables read from the netCDF files, linear in scattering angle, normalised by the
//!   exact integral of that interpolant). Checked for B1–B4 at the three levels: I, the linear
//!   polarization √(Q²+U²) = |Σ b1 terms|, in the principal plane Q (sign included) and U = 0,
//!   and V = 0. Both walks' single-scattering estimates are exact integrals along the first
//!   flight (expected local estimates: zero variance, the standard error is round-off), so the
//!   comparison is at the floor; agreement is 1e-13 (B1, B2) and < 1e-4 (B3, B4: tabulation).
//!   This validates per-layer absorption (Beer–Lambert along both legs), per-layer albedos, the
//!   Rayleigh+aerosol and Rayleigh+cloud mixtures and the Mie phase matrices inside the layered
//!   atmosphere; a depolarization of 0.029 instead of 0.03 in the closed form fails it. (B4: the
//!   single-order ocean reflection is below e^{−15} relative at 0 and 30 km and left out; the
//!   1 km downward views of B4, which see it, are not checked.)
//! * `b1_b2_b3_flux_at_1km`: the upwelling flux through 1 km from the forward walk
//!   (`distant_flux`) equals the hemispheric integral of the backward radiancemeters at 1 km
//!   looking down (Gauss–Legendre × trapezoid quadrature): the only check of multiple
//!   scattering seen from inside the atmosphere by a walk other than the backward one
//!   (precision ≈ 0.3 %).
//! * `b2_b3_forward_backward`: B2 and B3 at 30 km with full multiple scattering: forward
//!   `mdistant` vs backward radiancemeters (two independent estimators), I, Q, U; plus the B3
//!   experiment (mixtures injected) bit-identical with 1 and 2 threads.
//! * `b4_forward_backward`: the same for B4 at a few-% precision only: the cloud's diffraction
//!   peak makes both walks' local estimates heavy-tailed (the simulator has no peak truncation or
//!   VROOM-like variance reduction), so their standard errors are themselves uncertain.
//!
//! Sensitivity, tried once by breaking things: in a scratch copy of the simulator, an off-by-one
//! layer in the expected local estimate of downward flights (the layer above's ω and phase)
//! fails `single_scattering_analytic` (B2–B4, up to 5 %) and `b1_b2_b3_flux_at_1km` (B3, z 27),
//! but neither the walk agreement (both walks share that code) nor B1 (identical layers).
//!
//! Not independently validated: the multiple-scattering values of B2–B4 beyond walk agreement
//! (30 km) and the 1 km flux integral (B1–B3); upward-looking radiances at 0 and 1 km in
//! multiple scattering (backward walk only; B1: by the layer equivalence); B4's ocean coupling
//! and everything of B4 below the cloud. Those await a comparison with published results.
//!
//! `write_iprt_b_results` (ignored; `cargo test --release -p simulator --test iprt_b --
//! --ignored write_iprt_b_results --nocapture`) writes the full IPRT B grid of B1–B4 in the IPRT
//! results format to `validation/iprt_b/iprt_case_b{1,2,3,4}_ours.dat` (`IPRT_B_SCALE`
//! multiplies its sample counts, `IPRT_B_CASES=b1,b3` picks cases).
//!
//! IPRT conventions (MANIFEST §2, pinned by `iprt_a.rs`): radiance for F0 = 1 normal to the beam
//! (I = μ0·BRF/π); (vza, vaa) the line of sight (vza < 90 looks up), vaa clockwise, vaa = saa
//! looks towards the Sun; Q as ours, U of opposite sign. V: IPRT's frame is the mirror image of
//! ours (it follows the line of sight), which flips V as it flips U, so V_IPRT = −V_ours (V is
//! non-zero only in B3/B4, |V| ≲ 1e-4; no test pins its sign: the MYSTIC B3 results of the IPRT
//! wiki, not in the shared data, agree with this sign, χ²/n = 1.0 vs 38 for the other one — see
//! `validation/iprt_b/README.md`).

mod common;
use common::*;

use std::f64::consts::PI;
use std::sync::Arc;

use engine::atmosphere::{LayerOptics, PlaneParallel};
use engine::config::Experiment;
use engine::frame::direction_from_angles;
use engine::phase::{Mixture, PhaseFunction, Rayleigh, Tabulated};

/// Rayleigh depolarization factor of every case.
const DEPOL: f64 = 0.03;
/// Top of the atmosphere, km.
const TOA_KM: f64 = 30.0;
/// ncdump of `fixtures/sizedistr_spheroid.cdf` (350 nm) and `fixtures/watercloud.mie.cdf`
/// (800 nm), `ssa`.
const SPHEROID_SSA: f64 = 0.787580609321594;
const CLOUD_SSA: f64 = 0.999978830724981;
/// B4: extinction optical thickness of the cloud in 2–3 km.
const CLOUD_TAU: f64 = 5.0;

// ---------------------------------------------------------------------------------------------
// Inputs and cases

/// A `tau_*.dat` profile: per 1-km layer (bottom first) its bottom altitude (km) and optical
/// thickness. The files list boundaries from 30 km down to 0, each row holding the layer that
/// starts at that level (the 30 km row is the empty space above TOA and must be 0).
fn read_tau(name: &str) -> Vec<(f64, f64)> {
    let path = data_dir().join("iprt_b").join(name);
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut rows: Vec<(f64, f64)> = text
        .lines()
        .filter(|l| !l.trim_start().starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let f: Vec<f64> = l
                .split_whitespace()
                .map(|x| x.parse().unwrap_or_else(|e| panic!("{name}: {l:?}: {e}")))
                .collect();
            assert_eq!(f.len(), 2, "{name}: {l:?} must have 2 columns");
            (f[0], f[1])
        })
        .collect();
    assert_eq!(rows.first(), Some(&(TOA_KM, 0.0)), "{name}: first row");
    rows.remove(0);
    rows.reverse();
    assert_eq!(rows.len(), 30, "{name}: 30 layers");
    for (i, &(z, tau)) in rows.iter().enumerate() {
        assert_eq!(z, i as f64, "{name}: layer bottoms 0, 1, …, 29 km");
        assert!(tau.is_finite() && tau >= 0.0, "{name}: τ = {tau} at {z} km");
    }
    rows
}

/// Particles sharing a layer with the air: extinction τ, ω and the phase-matrix file.
#[derive(Clone, Copy, Debug)]
struct Particles {
    tau: f64,
    ssa: f64,
    file: &'static str,
    wavelength: f64,
}

/// One homogeneous layer (km): Rayleigh scattering, gas absorption, optional particles.
#[derive(Clone, Copy, Debug)]
struct Layer {
    bottom: f64,
    top: f64,
    tau_ray: f64,
    tau_gas: f64,
    particles: Option<Particles>,
}

impl Layer {
    fn tau_sca(&self) -> f64 {
        self.tau_ray + self.particles.map_or(0.0, |p| p.tau * p.ssa)
    }
    fn tau_abs(&self) -> f64 {
        self.tau_gas + self.particles.map_or(0.0, |p| p.tau * (1.0 - p.ssa))
    }
    fn tau_ext(&self) -> f64 {
        self.tau_sca() + self.tau_abs()
    }
}

struct Case {
    /// "b1" … "b4".
    id: &'static str,
    title: &'static str,
    wavelength: f64,
    sza: f64,
    saa: f64,
    /// Bottom first.
    layers: Vec<Layer>,
    /// The `[surface]` table's body.
    surface: &'static str,
}

const BLACK: &str = "type = \"lambertian\"\nreflectance = 0.0";
const OCEAN: &str = "type = \"ocean\"\nwind_speed = 2.0\nrefractive_index = 1.33";

fn case(id: &str) -> Case {
    let column = |name: &str| {
        read_tau(name)
            .into_iter()
            .map(|(_, t)| t)
            .collect::<Vec<_>>()
    };
    let layers = |ray: &str, gas: Option<&str>, part: &dyn Fn(usize) -> Option<Particles>| {
        let ray = read_tau(ray);
        let gas = gas.map(column).unwrap_or_else(|| vec![0.0; ray.len()]);
        ray.iter()
            .zip(&gas)
            .enumerate()
            .map(|(i, (&(z, tr), &tg))| Layer {
                bottom: z,
                top: z + 1.0,
                tau_ray: tr,
                tau_gas: tg,
                particles: part(i),
            })
            .collect::<Vec<_>>()
    };
    match id {
        "b1" => Case {
            id: "b1",
            title: "Standard atmosphere without absorption (Rayleigh, 450 nm)",
            wavelength: 450.0,
            sza: 60.0,
            saa: 0.0,
            layers: layers("tau_rayleigh_450.dat", None, &|_| None),
            surface: BLACK,
        },
        "b2" => Case {
            id: "b2",
            title: "Standard atmosphere with molecular absorption (325 nm)",
            wavelength: 325.0,
            sza: 60.0,
            saa: 0.0,
            layers: layers("tau_rayleigh_325.dat", Some("tau_molabs_325.dat"), &|_| {
                None
            }),
            surface: BLACK,
        },
        "b3" => {
            let aer = column("tau_aerosol.dat");
            Case {
                id: "b3",
                title: "Standard atmosphere with aerosol profile (350 nm, A4 spheroids)",
                wavelength: 350.0,
                sza: 30.0,
                saa: 0.0,
                layers: layers("tau_rayleigh_350.dat", Some("tau_molabs_350.dat"), &|i| {
                    (aer[i] > 0.0).then_some(Particles {
                        tau: aer[i],
                        ssa: SPHEROID_SSA,
                        file: "sizedistr_spheroid.cdf",
                        wavelength: 350.0,
                    })
                }),
                surface: BLACK,
            }
        }
        "b4" => Case {
            id: "b4",
            title: "Standard atmosphere, water cloud 2-3 km (tau 5), ocean surface (800 nm)",
            wavelength: 800.0,
            sza: 60.0,
            saa: 0.0,
            layers: layers("tau_rayleigh_800.dat", None, &|i| {
                (i == 2).then_some(Particles {
                    tau: CLOUD_TAU,
                    ssa: CLOUD_SSA,
                    file: "watercloud.mie.cdf",
                    wavelength: 800.0,
                })
            }),
            surface: OCEAN,
        },
        _ => panic!("unknown case {id}"),
    }
}

// ---------------------------------------------------------------------------------------------
// Experiments

/// An IPRT line of sight at altitude `zout` (km): the sensor looks along zenith `va` (< 90 up),
/// azimuth `phi` (degrees, clockwise from North).
#[derive(Clone, Copy, Debug, PartialEq)]
struct View {
    zout: f64,
    va: f64,
    phi: f64,
}

impl View {
    fn label(&self) -> String {
        format!("z {} va {} phi {}", self.zout, self.va, self.phi)
    }
}

/// A Stokes vector in BRF units (π·S/μ0 for F0 = 1) with IPRT's signs (U and V negated), and
/// its standard errors.
#[derive(Clone, Copy, Debug)]
struct Stokes {
    v: [f64; 4],
    e: [f64; 4],
}

/// Replace the phase functions of the layers holding particles by the Rayleigh + particle
/// mixture, weighted by the scattering optical thicknesses — what `type = "molecular"` builds
/// for its particle layers; the `layered` config has one phase function per layer. The
/// optical depths and albedos resolved from the TOML must be unchanged.
fn inject_mixtures(exp: &mut Experiment, layers: &[Layer]) {
    let rayleigh = PhaseFunction::Rayleigh(Rayleigh::new(DEPOL).unwrap());
    let mut tables: Vec<(&str, PhaseFunction)> = Vec::new();
    let mut table = |p: &Particles| -> PhaseFunction {
        if let Some((_, t)) = tables.iter().find(|(f, _)| *f == p.file) {
            return t.clone();
        }
        let path = data_dir().join("fixtures").join(p.file);
        let t = PhaseFunction::Tabulated(Arc::new(
            Tabulated::load_libradtran(&path, p.wavelength, 0).unwrap(),
        ));
        tables.push((p.file, t.clone()));
        t
    };
    let optics: Vec<LayerOptics> = layers
        .iter()
        .map(|l| LayerOptics {
            bottom: l.bottom * 1e3,
            top: l.top * 1e3,
            tau_sca: l.tau_sca(),
            tau_abs: l.tau_abs(),
            phase: match &l.particles {
                None => rayleigh.clone(),
                Some(p) => Mixture::build(vec![
                    (l.tau_ray, rayleigh.clone()),
                    (p.tau * p.ssa, table(p)),
                ])
                .unwrap(),
            },
        })
        .collect();
    let old = &exp.optics[0].atmosphere;
    let new = PlaneParallel::new(optics, 0.0, TOA_KM * 1e3);
    assert_eq!(old.layer_count(), new.layer_count());
    assert!(old.boundaries().eq(new.boundaries()), "optical depths");
    for i in 0..new.layer_count() {
        assert_eq!(old.albedo(i), new.albedo(i), "albedo of layer {i}");
    }
    exp.optics[0].atmosphere = new;
}

/// The experiment of `case` with `layers` (the case's own or an equivalent set), its `[integrator]`
/// table `integrator` and `measures`.
fn build(case: &Case, layers: &[Layer], seed: u64, integrator: &str, measures: &str) -> Experiment {
    let mut atm = String::new();
    for l in layers {
        atm += &format!(
            "[[atmosphere.layers]]\nbottom = {:?}\ntop = {:?}\ntau_sca = {:?}\ntau_abs = {:?}\n\
             phase = {{ type = \"rayleigh\", depolarization = {DEPOL:?} }}\n",
            l.bottom,
            l.top,
            l.tau_sca(),
            l.tau_abs()
        );
    }
    let text = format!(
        "seed = {seed}\npolarized = true\n[spectral]\nwavelengths = [{:?}]\n\
         [geometry]\ntype = \"plane_parallel\"\ntoa_altitude = {TOA_KM:?}\nground_altitude = 0.0\n\
         [atmosphere]\ntype = \"layered\"\n{atm}[surface]\n{}\n\
         [illumination]\ntype = \"directional\"\nzenith = {:?}\nazimuth = {:?}\n\
         [integrator]\n{integrator}\n{measures}",
        case.wavelength, case.surface, case.sza, case.saa
    );
    let mut exp = experiment(&text);
    if layers.iter().any(|l| l.particles.is_some()) {
        inject_mixtures(&mut exp, layers);
    }
    exp
}

/// Run `views` on `layers` of `case`: views at 30 km by a forward `mdistant` (when `spp_fwd` is
/// given) or, like all others, by radiancemeters (backward walk, `spp_back` each). Returns one
/// Stokes vector per view.
fn run_views(
    case: &Case,
    layers: &[Layer],
    views: &[View],
    seed: u64,
    spp_back: u64,
    spp_fwd: Option<u64>,
    max_depth: Option<u32>,
) -> Vec<Stokes> {
    let forward = |v: &View| spp_fwd.is_some() && v.zout == TOA_KM;
    let mut measures = String::new();
    for (k, v) in views.iter().enumerate().filter(|(_, v)| !forward(v)) {
        let look = direction_from_angles(v.va.to_radians(), v.phi.to_radians());
        measures += &format!(
            "[[measures]]\nid = \"r{k}\"\ntype = \"radiancemeter\"\norigin = [0.0, 0.0, {:?}]\n\
             direction = [{:?}, {:?}, {:?}]\nframe_azimuth = {:?}\nspp = {spp_back}\n",
            v.zout,
            look.x,
            look.y,
            look.z,
            // Vertical views: the meridian plane of the IPRT azimuth (towards-the-sensor azimuth
            // phi + 180, as for the mdistant views), as in `iprt_a.rs`.
            (v.phi + 180.0).rem_euclid(360.0)
        );
    }
    let fwd: Vec<usize> = (0..views.len()).filter(|&k| forward(&views[k])).collect();
    if let (Some(spp), false) = (spp_fwd, fwd.is_empty()) {
        let vza: Vec<f64> = fwd.iter().map(|&k| 180.0 - views[k].va).collect();
        let vaa: Vec<f64> = fwd
            .iter()
            .map(|&k| (views[k].phi + 180.0).rem_euclid(360.0))
            .collect();
        measures += &mdistant_toml("toa", &vza, &vaa, spp);
    }
    let integrator = format!(
        "type = \"auto\"\n{}",
        max_depth.map_or(String::new(), |d| format!("max_depth = {d}\n"))
    );
    let exp = build(case, layers, seed, &integrator, &measures);
    let rows = run_rows(&exp);
    let mut out: Vec<Option<Stokes>> = vec![None; views.len()];
    let mut next_fwd = fwd.iter();
    for r in &rows {
        let k = if r.measure == "toa" {
            *next_fwd.next().unwrap()
        } else {
            r.measure[1..].parse::<usize>().unwrap()
        };
        let (i, q, u, v) = (
            r.brf.unwrap(),
            r.brf_q.unwrap(),
            r.brf_u.unwrap(),
            r.brf_v.unwrap(),
        );
        out[k] = Some(Stokes {
            v: [i.0, q.0, -u.0, -v.0],
            e: [i.1, q.1, u.1, v.1],
        });
    }
    out.into_iter().map(|s| s.unwrap()).collect()
}

/// Views on a grid: at 0 km the upward `va_up`, at 30 km the downward `va_down`, at 1 km both;
/// every view zenith at every azimuth in `phi`.
fn grid(va_up: &[f64], va_down: &[f64], phi: &[f64]) -> Vec<View> {
    let mut out = Vec::new();
    for (zout, vas) in [
        (0.0, va_up.to_vec()),
        (1.0, [va_up, va_down].concat()),
        (TOA_KM, va_down.to_vec()),
    ] {
        for &va in &vas {
            for &phi in phi {
                out.push(View { zout, va, phi });
            }
        }
    }
    out
}

/// The test grid: 5 view zeniths per hemisphere, 5 azimuths (16 × 5 views).
fn test_grid() -> Vec<View> {
    grid(
        &[0.0, 20.0, 40.0, 60.0, 80.0],
        &[100.0, 120.0, 140.0, 160.0, 180.0],
        &[0.0, 45.0, 90.0, 135.0, 180.0],
    )
}

/// I, Q, U comparisons of two independent estimates (σ² = σ_a² + σ_b²).
fn compare_iqu(views: &[View], a: &[Stokes], b: &[Stokes], out: &mut Vec<Cmp>) {
    for ((v, x), y) in views.iter().zip(a).zip(b) {
        for (c, name) in ["I", "Q", "U"].iter().enumerate() {
            out.push(Cmp {
                label: format!("{name} {}", v.label()),
                reference: y.v[c],
                value: x.v[c],
                stderr: x.e[c].hypot(y.e[c]),
            });
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Closed-form single scattering

/// A libRadtran / MOPSMAP phase-matrix file at its single wavelength: P11 and P12 (the first two
/// elements for 4 and 6 elements alike) on their angle grids (degrees), interpolated linearly in
/// scattering angle, normalised so that P11 has mean 1 over the sphere (the exact integral of
/// the interpolant).
struct ParticleTable {
    theta: Vec<Vec<f64>>,
    value: Vec<Vec<f64>>,
    norm: f64,
}

impl ParticleTable {
    fn load(file: &str) -> Self {
        let path = data_dir().join("fixtures").join(file);
        let nc = netcdf::open(&path).unwrap();
        let get = |name: &str| -> Vec<f64> {
            nc.variable(name)
                .unwrap_or_else(|| panic!("{file}: no `{name}`"))
                .get_values::<f64, _>(..)
                .unwrap()
        };
        assert_eq!(get("wavelen").len(), 1, "{file}: one wavelength");
        let dims: Vec<usize> = nc
            .variable("theta")
            .unwrap()
            .dimensions()
            .iter()
            .map(|d| d.len())
            .collect();
        let (nphamat, nmax) = (dims[2], dims[3]);
        assert!(nphamat == 4 || nphamat == 6, "{file}: P11, P12, … expected");
        let (theta, phase) = (get("theta"), get("phase"));
        let ntheta: Vec<i32> = nc
            .variable("ntheta")
            .unwrap()
            .get_values::<i32, _>(..)
            .unwrap();
        let mut t = Vec::new();
        let mut p = Vec::new();
        for k in 0..2 {
            let n = ntheta[k] as usize;
            let (th, val) = (
                &theta[k * nmax..k * nmax + n],
                &phase[k * nmax..k * nmax + n],
            );
            let mut pairs: Vec<(f64, f64)> = th.iter().copied().zip(val.iter().copied()).collect();
            pairs.sort_by(|a, b| a.0.partial_cmp(&b.0).unwrap());
            t.push(pairs.iter().map(|x| x.0).collect());
            p.push(pairs.iter().map(|x| x.1).collect());
        }
        // ∫ P sin θ dθ of the piecewise-linear P(θ), exactly; the mean over the sphere is half.
        let (th, val): (&Vec<f64>, &Vec<f64>) = (&t[0], &p[0]);
        let mut integral = 0.0;
        for i in 0..th.len() - 1 {
            let (t0, t1) = (th[i].to_radians(), th[i + 1].to_radians());
            let s = (val[i + 1] - val[i]) / (t1 - t0);
            integral +=
                val[i] * (t0.cos() - t1.cos()) + s * (-(t1 - t0) * t1.cos() + t1.sin() - t0.sin());
        }
        Self {
            theta: t,
            value: p,
            norm: 2.0 / integral,
        }
    }

    /// Element k (0: P11, 1: P12) at scattering angle `deg`.
    fn elem(&self, k: usize, deg: f64) -> f64 {
        let (th, val) = (&self.theta[k], &self.value[k]);
        let i = th.partition_point(|&t| t <= deg).clamp(1, th.len() - 1);
        let f = (deg - th[i - 1]) / (th[i] - th[i - 1]);
        (val[i - 1] + f * (val[i] - val[i - 1])) * self.norm
    }
}

/// (a1, b1) of the Rayleigh matrix with depolarization ρ (Hansen & Travis 1974):
/// a1 = Δ·¾(1 + cos²Θ) + 1 − Δ, b1 = −Δ·¾ sin²Θ, Δ = (1 − ρ)/(1 + ρ/2).
fn rayleigh_a1_b1(cos: f64) -> (f64, f64) {
    let delta = (1.0 - DEPOL) / (1.0 + 0.5 * DEPOL);
    (
        delta * 0.75 * (1.0 + cos * cos) + 1.0 - delta,
        -delta * 0.75 * (1.0 - cos * cos),
    )
}

/// ∫_0^L e^{−kx} dx.
fn exp_integral(k: f64, l: f64) -> f64 {
    if (k * l).abs() < 1e-12 {
        l
    } else {
        -(-k * l).exp_m1() / k
    }
}

/// Single-scattered (I, b) in BRF units at `view`: I and the Q that the view would have in the
/// scattering plane's frame (b1 terms; √(Q²+U²) = |b|, and in the principal plane Q = b, U = 0).
/// Surface reflection is not included.
fn single_scattering(case: &Case, tables: &[(&str, ParticleTable)], view: &View) -> (f64, f64) {
    let mu0 = case.sza.to_radians().cos();
    let sun = direction_from_angles(case.sza.to_radians(), case.saa.to_radians());
    let look = direction_from_angles(view.va.to_radians(), view.phi.to_radians());
    // Light arrives along −sun and leaves towards the sensor along −look.
    let cos = sun.dot(look).clamp(-1.0, 1.0);
    let deg = cos.acos().to_degrees();
    let mu = look.z.abs();
    let (ra, rb) = rayleigh_a1_b1(cos);
    // Optical depth of the sensor's level, from the top.
    let tau_s: f64 = case
        .layers
        .iter()
        .filter(|l| l.bottom >= view.zout)
        .map(|l| l.tau_ext())
        .sum();
    let (mut i_sum, mut b_sum) = (0.0, 0.0);
    let mut top = 0.0; // optical depth of the layer's top
    for l in case.layers.iter().rev() {
        let (a, b) = (top, top + l.tau_ext());
        top = b;
        // The part of the layer on the side the sensor looks at, and ∫ e^{−τ/μ0} e^{−|τ−τ_s|/μ} dτ/μ.
        let g = if look.z < 0.0 {
            let a = a.max(tau_s);
            if b <= a {
                continue;
            }
            (-a / mu0 - (a - tau_s) / mu).exp() * exp_integral(1.0 / mu0 + 1.0 / mu, b - a) / mu
        } else {
            let b = b.min(tau_s);
            if b <= a {
                continue;
            }
            (-a / mu0 - (tau_s - a) / mu).exp() * exp_integral(1.0 / mu0 - 1.0 / mu, b - a) / mu
        };
        let (mut wa, mut wb) = (l.tau_ray * ra, l.tau_ray * rb);
        if let Some(p) = &l.particles {
            let t = &tables.iter().find(|(f, _)| *f == p.file).unwrap().1;
            wa += p.tau * p.ssa * t.elem(0, deg);
            wb += p.tau * p.ssa * t.elem(1, deg);
        }
        i_sum += wa / l.tau_ext() * g;
        b_sum += wb / l.tau_ext() * g;
    }
    let k = 0.25 / mu0;
    (k * i_sum, k * b_sum)
}

/// Comparisons of simulated single scattering with the closed form: I, √(Q²+U²), and in the
/// principal plane Q and U.
fn compare_single(case: &Case, views: &[View], sim: &[Stokes], out: &mut Vec<Cmp>) {
    let mut tables: Vec<(&str, ParticleTable)> = Vec::new();
    for l in &case.layers {
        if let Some(p) = l.particles {
            if !tables.iter().any(|(f, _)| *f == p.file) {
                tables.push((p.file, ParticleTable::load(p.file)));
            }
        }
    }
    for (v, s) in views.iter().zip(sim) {
        let (i, b) = single_scattering(case, &tables, v);
        // Both walks integrate single scattering exactly along the first flight: their standard
        // errors are round-off (B4: plus the e^{−15} ocean term), shown as 0 for a readable z
        // (the test's tolerance is then its floor).
        let s = &Stokes {
            v: s.v,
            e: s.e.map(|e| if e < 1e-7 * s.v[0].abs() { 0.0 } else { e }),
        };
        let lab = |n: &str| format!("{} {n} {}", case.id, v.label());
        out.push(Cmp {
            label: lab("I"),
            reference: i,
            value: s.v[0],
            stderr: s.e[0],
        });
        let pol = s.v[1].hypot(s.v[2]);
        out.push(Cmp {
            label: lab("sqrt(Q2+U2)"),
            reference: b.abs(),
            value: pol,
            stderr: s.e[1].max(s.e[2]),
        });
        if v.phi == case.saa || v.phi == (case.saa + 180.0).rem_euclid(360.0) {
            out.push(Cmp {
                label: lab("Q (principal plane)"),
                reference: b,
                value: s.v[1],
                stderr: s.e[1],
            });
            out.push(Cmp {
                label: lab("U (principal plane)"),
                reference: 0.0,
                value: s.v[2],
                stderr: s.e[2],
            });
        }
        // Unpolarized sunlight scattered once has no circular polarization.
        out.push(Cmp {
            label: lab("V"),
            reference: 0.0,
            value: s.v[3],
            stderr: s.e[3],
        });
    }
}

// ---------------------------------------------------------------------------------------------
// Tests

#[test]
fn tau_files_parse() {
    let b1 = case("b1");
    let total: f64 = b1.layers.iter().map(|l| l.tau_ext()).sum();
    // Sums of the files' columns (awk).
    assert!((total - 0.218807).abs() < 1e-6, "B1 τ = {total}");
    let b3 = case("b3");
    let aer: f64 = b3
        .layers
        .iter()
        .map(|l| l.particles.map_or(0.0, |p| p.tau))
        .sum();
    assert!((aer - 0.2).abs() < 1e-6, "B3 aerosol τ = {aer}");
    let b4 = case("b4");
    assert_eq!(b4.layers[2].bottom, 2.0);
    assert_eq!(b4.layers[2].particles.unwrap().tau, CLOUD_TAU);
    assert!(b4.layers.iter().filter(|l| l.particles.is_some()).count() == 1);
}

/// B1: the 30-layer atmosphere vs one homogeneous layer (0 and 30 km) and the two-layer split
/// at 1 km (see the file header).
#[test]
fn b1_layer_coupling() {
    let b1 = case("b1");
    let views = test_grid();
    let total: f64 = b1.layers.iter().map(|l| l.tau_ext()).sum();
    let below = b1.layers[0].tau_ext();
    let air = |bottom: f64, top: f64, tau: f64| Layer {
        bottom,
        top,
        tau_ray: tau,
        tau_gas: 0.0,
        particles: None,
    };
    let homogeneous = [air(0.0, TOA_KM, total)];
    let split = [air(0.0, 1.0, below), air(1.0, TOA_KM, total - below)];
    let spp = 196_608;
    let layered = run_views(&b1, &b1.layers, &views, 101, spp, None, None);
    let (edge, mid): (Vec<usize>, Vec<usize>) =
        (0..views.len()).partition(|&k| views[k].zout != 1.0);
    let pick = |idx: &[usize], v: &[View]| idx.iter().map(|&k| v[k]).collect::<Vec<_>>();
    let (views_edge, views_mid) = (pick(&edge, &views), pick(&mid, &views));
    let hom = run_views(&b1, &homogeneous, &views_edge, 102, spp, None, None);
    let two = run_views(&b1, &split, &views_mid, 103, spp, None, None);
    let mut cmps = Vec::new();
    let sub = |idx: &[usize]| idx.iter().map(|&k| layered[k]).collect::<Vec<_>>();
    compare_iqu(&views_edge, &sub(&edge), &hom, &mut cmps);
    compare_iqu(&views_mid, &sub(&mid), &two, &mut cmps);
    let mut errs: Vec<String> = check_all(
        "IPRT B1 [backward]: 30 layers vs homogeneous (0, 30 km) and 2 layers (1 km)",
        &cmps,
    )
    .err()
    .into_iter()
    .collect();
    // The forward walk's layer crossing: the 30-layer TOA views vs the homogeneous layer's.
    let top: Vec<usize> = (0..views_edge.len())
        .filter(|&k| views_edge[k].zout == TOA_KM)
        .collect();
    let views_top: Vec<View> = top.iter().map(|&k| views_edge[k]).collect();
    let fwd = run_views(&b1, &b1.layers, &views_top, 104, 2, Some(300_000), None);
    let hom_top: Vec<Stokes> = top.iter().map(|&k| hom[k]).collect();
    let mut cmps = Vec::new();
    compare_iqu(&views_top, &fwd, &hom_top, &mut cmps);
    errs.extend(
        check_all(
            "IPRT B1 [forward, 30 km]: 30 layers vs homogeneous [backward]",
            &cmps,
        )
        .err(),
    );
    assert!(errs.is_empty(), "{}", errs.join("\n"));
}

/// B1–B4 single scattering (`max_depth = 1`) against the closed form, backward at 0, 1, 30 km
/// and forward at 30 km.
#[test]
fn single_scattering_analytic() {
    let mut errs = Vec::new();
    for id in ["b1", "b2", "b3", "b4"] {
        let c = case(id);
        // B4 below 2 km looking down sees the ocean's single reflection: not in the closed form.
        let views: Vec<View> = test_grid()
            .into_iter()
            .filter(|v| !(id == "b4" && v.zout == 1.0 && v.va > 90.0))
            .collect();
        let back = run_views(&c, &c.layers, &views, 201, 256, None, Some(1));
        let mut cmps = Vec::new();
        compare_single(&c, &views, &back, &mut cmps);
        if let Err(e) = check_all(&format!("IPRT {id} single scattering [backward]"), &cmps) {
            errs.push(e);
        }
        let toa: Vec<View> = views.iter().copied().filter(|v| v.zout == TOA_KM).collect();
        let fwd = run_views(&c, &c.layers, &toa, 202, 256, Some(4096), Some(1));
        let mut cmps = Vec::new();
        compare_single(&c, &toa, &fwd, &mut cmps);
        if let Err(e) = check_all(&format!("IPRT {id} single scattering [forward]"), &cmps) {
            errs.push(e);
        }
    }
    assert!(errs.is_empty(), "{}", errs.join("\n"));
}

/// Thread-count independence of a run with injected mixtures (B3): 1 and 2 threads, bit-identical.
fn thread_independence(c: &Case) {
    let views: Vec<View> = test_grid().into_iter().step_by(7).collect();
    let run = |threads: usize| {
        with_threads(threads, || {
            run_views(c, &c.layers, &views, 301, 4096, Some(4096), None)
        })
    };
    let (a, b) = (run(1), run(2));
    for ((v, x), y) in views.iter().zip(&a).zip(&b) {
        assert_eq!(x.v, y.v, "{}: thread count changed the result", v.label());
        assert_eq!(x.e, y.e, "{}", v.label());
    }
}

/// Forward `mdistant` vs backward radiancemeters at 30 km, full multiple scattering.
fn forward_backward(id: &str, spp_fwd: u64, spp_back: u64) -> Result<(), String> {
    let c = case(id);
    let toa: Vec<View> = test_grid()
        .into_iter()
        .filter(|v| v.zout == TOA_KM)
        .collect();
    let fwd = run_views(&c, &c.layers, &toa, 401, 2, Some(spp_fwd), None);
    let back = run_views(&c, &c.layers, &toa, 402, spp_back, None, None);
    if std::env::var("IPRT_B_DEBUG").is_ok() {
        for ((v, f), b) in toa.iter().zip(&fwd).zip(&back) {
            println!(
                "{id} {} I fwd {:.5}±{:.5} back {:.5}±{:.5} | Q {:.5}±{:.5} {:.5}±{:.5}",
                v.label(),
                f.v[0],
                f.e[0],
                b.v[0],
                b.e[0],
                f.v[1],
                f.e[1],
                b.v[1],
                b.e[1]
            );
        }
    }
    let mut cmps = Vec::new();
    compare_iqu(&toa, &fwd, &back, &mut cmps);
    check_all(&format!("IPRT {id} at 30 km: forward vs backward"), &cmps)
}

#[test]
fn b2_b3_forward_backward() {
    thread_independence(&case("b3"));
    let errs: Vec<String> = [("b2", 200_000, 65_536), ("b3", 200_000, 65_536)]
        .into_iter()
        .filter_map(|(id, f, b)| forward_backward(id, f, b).err())
        .collect();
    assert!(errs.is_empty(), "{}", errs.join("\n"));
}

#[test]
fn b4_forward_backward() {
    forward_backward("b4", 60_000, 131_072).unwrap();
}

/// Gauss–Legendre nodes and weights on (0, 1).
fn gauss_legendre_01(n: usize) -> Vec<(f64, f64)> {
    (1..=n)
        .map(|i| {
            // Newton's method on P_n from the Chebyshev-like first guess.
            let mut x = (std::f64::consts::PI * (i as f64 - 0.25) / (n as f64 + 0.5)).cos();
            let mut dp = 0.0;
            for _ in 0..100 {
                let (mut p0, mut p1) = (1.0, x);
                for k in 2..=n {
                    let k = k as f64;
                    (p0, p1) = (p1, ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k);
                }
                dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
                let dx = p1 / dp;
                x -= dx;
                if dx.abs() < 1e-15 {
                    break;
                }
            }
            (0.5 * (1.0 + x), 1.0 / ((1.0 - x * x) * dp * dp))
        })
        .collect()
}

/// The upwelling flux through 1 km two ways: the forward walk's `distant_flux` (albedo
/// F↑/(E0 μ0)) and the backward radiancemeters at 1 km looking down, integrated over the
/// hemisphere, (1/π)∫ BRF μ dΩ = (2/π) Σ w_μ μ Σ w_φ BRF (Gauss–Legendre in μ, 8 nodes;
/// trapezoid in azimuth over 0–180°, 13 nodes, the field being symmetric about the principal
/// plane). An independent check of the radiancemeters inside the atmosphere looking down
/// (multiple scattering included), which no other test covers.
#[test]
fn b1_b2_b3_flux_at_1km() {
    let mut errs = Vec::new();
    for (id, seed) in [("b1", 501), ("b2", 502), ("b3", 503)] {
        let c = case(id);
        let mus = gauss_legendre_01(8);
        let nphi = 12;
        let mut views = Vec::new();
        let mut weights = Vec::new();
        for &(mu, wmu) in &mus {
            for j in 0..=nphi {
                let phi = 180.0 * j as f64 / nphi as f64;
                let wphi = if j == 0 || j == nphi { 0.5 } else { 1.0 } * PI / nphi as f64;
                views.push(View {
                    zout: 1.0,
                    va: 180.0 - mu.acos().to_degrees(),
                    phi,
                });
                weights.push(2.0 / PI * wmu * mu * wphi);
            }
        }
        let res = run_views(&c, &c.layers, &views, seed, 24_576, None, None);
        let (mut a, mut var) = (0.0, 0.0);
        for (w, s) in weights.iter().zip(&res) {
            a += w * s.v[0];
            var += (w * s.e[0]).powi(2);
        }
        let measures =
            "[[measures]]\nid = \"flux\"\ntype = \"distant_flux\"\naltitude = 1.0\nspp = 8000000\n";
        let exp = build(&c, &c.layers, seed + 10, "type = \"auto\"", measures);
        let (f, fe) = run_rows(&exp)[0].albedo.unwrap();
        let cmp = Cmp {
            label: format!("{id} F_up(1 km)/(E0 mu0)"),
            reference: f,
            value: a,
            stderr: fe.hypot(var.sqrt()),
        };
        println!("{id}: upwelling flux at 1 km: forward {f:.6} ± {fe:.1e}, radiance integral {a:.6} ± {:.1e}", var.sqrt());
        if let Err(e) = check_all(&format!("IPRT {id}: flux at 1 km"), &[cmp]) {
            errs.push(e);
        }
    }
    assert!(errs.is_empty(), "{}", errs.join("\n"));
}

// ---------------------------------------------------------------------------------------------
// Full-grid results in the IPRT format

/// The IPRT B output grid (wiki case pages B1–B4): at 0 km vza 0–85, at 1 km 0–180 without 90,
/// at 30 km 95–180, all in 5° steps; vaa 0–180 in 5° steps.
fn iprt_grid() -> Vec<View> {
    let up: Vec<f64> = (0..=17).map(|i| 5.0 * i as f64).collect();
    let down: Vec<f64> = (19..=36).map(|i| 5.0 * i as f64).collect();
    let phi: Vec<f64> = (0..=36).map(|i| 5.0 * i as f64).collect();
    grid(&up, &down, &phi)
}

/// `x` as `d.ddddde±XX` (6 significant digits, two-digit exponent, like the IPRT files).
fn sci(x: f64) -> String {
    let s = format!("{x:.5e}");
    let (m, e) = s.split_once('e').unwrap();
    let e: i32 = e.parse().unwrap();
    format!("{m}e{}{:02}", if e < 0 { '-' } else { '+' }, e.abs())
}

/// Median and maximum of the relative standard errors of I over `idx`.
fn rel_stderr_summary(res: &[Stokes], idx: impl Iterator<Item = usize>) -> (f64, f64) {
    let mut r: Vec<f64> = idx.map(|k| res[k].e[0] / res[k].v[0].abs()).collect();
    r.sort_by(|a, b| a.total_cmp(b));
    (r[r.len() / 2], r[r.len() - 1])
}

#[test]
#[ignore = "writes validation/iprt_b/iprt_case_b{1,2,3,4}_ours.dat (about 10 min on 2 cores)"]
fn write_iprt_b_results() {
    let scale: f64 = std::env::var("IPRT_B_SCALE")
        .map(|s| s.parse().expect("IPRT_B_SCALE must be a number"))
        .unwrap_or(1.0);
    let n = |x: u64| ((x as f64 * scale).round() as u64).max(2);
    let only = std::env::var("IPRT_B_CASES").unwrap_or_else(|_| "b1,b2,b3,b4".into());
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../validation/iprt_b");
    std::fs::create_dir_all(&dir).unwrap();
    let views = iprt_grid();
    // (case, samples per radiancemeter direction, forward photons at 30 km, seed).
    for (id, spp_back, spp_fwd, seed) in [
        ("b1", 16_384, 96_000, 1001),
        ("b2", 12_288, 72_000, 1002),
        ("b3", 8_192, 48_000, 1003),
        ("b4", 8_192, 12_000, 1004),
    ] {
        if !only.split(',').any(|c| c.trim() == id) {
            continue;
        }
        let c = case(id);
        let (spp_back, spp_fwd) = (n(spp_back), n(spp_fwd));
        let t = std::time::Instant::now();
        let res = run_views(&c, &c.layers, &views, seed, spp_back, Some(spp_fwd), None);
        let secs = t.elapsed().as_secs_f64();
        let k = c.sza.to_radians().cos() / PI;
        let summary: Vec<String> = [0.0, 1.0, TOA_KM]
            .iter()
            .map(|&z| {
                let (med, max) =
                    rel_stderr_summary(&res, (0..views.len()).filter(|&i| views[i].zout == z));
                format!("{z} km median {med:.1e} max {max:.1e}")
            })
            .collect();
        let max_pol_se = res
            .iter()
            .flat_map(|s| s.e[1..].iter().copied())
            .fold(0.0, f64::max)
            * k;
        let mut text = format!(
            "# IPRT case {} - {}\n\
             # RT model: simulator (this repository), Monte Carlo, polarized; written by\n\
             #   cargo test --release -p simulator --test iprt_b -- --ignored write_iprt_b_results\n\
             #   (simulator/tests/iprt_b.rs, IPRT_B_SCALE = {scale}); bit-identical for any thread count\n\
             # Setup: 30 layers 0-30 km from the IPRT tau_*.dat inputs, Rayleigh depolarization {DEPOL},\n\
             #   surface: {}; sza {} saa {}; {} nm\n\
             # Walks: 0 and 1 km: backward radiancemeters, {spp_back} samples per direction;\n\
             #   30 km: forward mdistant, {spp_fwd} photons (seed {seed})\n\
             # Units: Stokes radiance for an extraterrestrial irradiance F0 = 1 normal to the beam (sr^-1)\n\
             # Conventions (IPRT): (vza, vaa) = line of sight (vza < 90 looks up), vaa clockwise,\n\
             #   vaa = saa looks towards the Sun; Q, U in the meridian frame of the line of sight\n\
             #   (U, V of opposite sign to the simulator's own outputs)\n\
             # Istd..Vstd: standard errors of the mean (1 sigma). Relative stderr of I: {};\n\
             #   largest stderr of Q, U, V: {}\n\
             # depol zout sza saa vza vaa I Q U V Istd Qstd Ustd Vstd\n",
            id.to_uppercase(),
            c.title,
            c.surface.replace('\n', ", ").replace('"', ""),
            c.sza,
            c.saa,
            c.wavelength,
            summary.join("; "),
            sci(max_pol_se),
        );
        for (v, s) in views.iter().zip(&res) {
            // (+ 0.0: no "-0" for the exact zeros of V.)
            let vals: Vec<String> = s.v.iter().chain(&s.e).map(|x| sci(x * k + 0.0)).collect();
            text += &format!(
                "{DEPOL:.2} {:5.1} {:5.1} {:5.1} {:6.1} {:6.1} {}\n",
                v.zout,
                c.sza,
                c.saa,
                v.va,
                v.phi,
                vals.join(" ")
            );
        }
        let path = dir.join(format!("iprt_case_{id}_ours.dat"));
        std::fs::write(&path, text).unwrap();
        println!(
            "{id}: {} rows in {secs:.0} s -> {}; relative stderr of I: {}",
            views.len(),
            path.display(),
            summary.join("; ")
        );
    }
}
