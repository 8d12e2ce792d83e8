//! Polarized backward walk (plane-parallel), with next-event estimation towards the Sun.
//!
//! The adjoint of the polarized forward walk. The path carries `T`, the 4×4 product of
//! rotation and phase matrices that maps a Stokes vector of light arriving along the current
//! path segment (in that segment's frame, first axis `e1`) to the Stokes vector measured by the
//! sensor (meridian frame of the direction towards the sensor, `stokes.rs`). At a collision along
//! `d` the new path direction `d'` is drawn from `a1 = P11` (as in the scalar walk), and
//! `T ← T · R(l_out → e1) · F(Θ) · ω / a1(Θ)`, where the scattering-plane frame is that of light
//! going from `−d'` to `−d`; the new segment's frame is `l_in`. Next-event estimation scatters the
//! unpolarized solar beam the same way: `T · R · F(Θ_sun) · (1, 0, 0, 0) · ω/(4π) · T_sun`,
//! integrated exactly along each flight as in the scalar walk. Depolarizing surfaces have a
//! Mueller matrix with only the (I, I) element, so after a reflection only `T`'s first column
//! survives; polarizing surfaces (the ocean) act like a scattering in the plane of incidence.
//!
//! A sample is the Stokes vector `π·(I, Q, U, V)/(E0 μ_s)`.

use glam::{DMat4, DVec3, DVec4};

use super::{sample_scattered, RR_THRESHOLD};
use crate::atmosphere::spherical::{ShellEnd, SphericalShell};
use crate::atmosphere::FlightEnd;
use crate::bsdf::Bsdf;
use super::settings::IntegratorSettings;
use crate::frame::basis_around;
use crate::optics::OpticalState;
use crate::phase::PhaseFunction;
use crate::rng::Stream;
use crate::stokes::{any_perpendicular, PhaseMatrix};

/// Mueller matrix of a phase matrix (row-major layout in the docs; glam is column-major).
#[inline]
fn mueller(f: &PhaseMatrix) -> DMat4 {
    DMat4::from_cols(
        DVec4::new(f.a1, f.b1, 0.0, 0.0),
        DVec4::new(f.b1, f.a2, 0.0, 0.0),
        DVec4::new(0.0, 0.0, f.a3, -f.b2),
        DVec4::new(0.0, 0.0, f.b2, f.a4),
    )
}

/// Rotation of Stokes vectors from first axis `from` to first axis `to` (both ⊥ `w`).
#[inline]
fn rotation(w: DVec3, from: DVec3, to: DVec3) -> DMat4 {
    let (c, s) = (to.dot(from), to.dot(w.cross(from)));
    let (c2, s2) = (c * c - s * s, 2.0 * c * s);
    DMat4::from_cols(
        DVec4::new(1.0, 0.0, 0.0, 0.0),
        DVec4::new(0.0, c2, -s2, 0.0),
        DVec4::new(0.0, s2, c2, 0.0),
        DVec4::new(0.0, 0.0, 0.0, 1.0),
    )
}

/// Scattering-plane frame for light going from propagation direction `w_in` to `w_out`:
/// (perpendicular axis r, parallel axis of the incoming light, parallel axis of the outgoing).
#[inline]
fn plane(w_in: DVec3, w_out: DVec3, fallback: DVec3) -> (DVec3, DVec3, DVec3) {
    let mut r = w_in.cross(w_out);
    let len = r.length();
    if len < 1e-12 {
        r = w_out.cross(fallback).normalize();
    } else {
        r /= len;
    }
    (r, r.cross(w_in), r.cross(w_out))
}

/// Add a Stokes contribution to (I single, I multiple, Q, U, V).
#[inline]
fn add_score(out: &mut [f64; 5], order: u32, s: DVec4) {
    out[if order == 1 { 0 } else { 1 }] += s.x;
    out[2] += s.y;
    out[3] += s.z;
    out[4] += s.w;
}

/// Scatter the path at a collision along `d`: draw `d'` from P11, and multiply `T` by the
/// rotation into the scattering plane and `F(Θ)·ω/a1` (light arrives along −d', leaves along −d).
/// Returns the new `T`, direction and segment frame axis.
#[inline]
fn scatter_path(
    t: &DMat4,
    d: DVec3,
    e1: DVec3,
    phase: &PhaseFunction,
    omega: f64,
    rng: &mut Stream,
) -> (DMat4, DVec3, DVec3) {
    let d2 = sample_scattered(phase, d, rng);
    let f = phase.matrix(d.dot(d2));
    let (_, l_in, l_out) = plane(-d2, -d, e1);
    (
        *t * rotation(-d, l_out, e1) * mueller(&f) * (omega / f.a1),
        d2,
        l_in,
    )
}

/// Russian roulette on `T`'s (I, I) element, the path's intensity weight (a product of Mueller
/// matrices has T00 ≥ |T0j|): false when the path ends.
#[inline]
fn survives(t: &mut DMat4, order: u32, settings: &IntegratorSettings, rng: &mut Stream) -> bool {
    let w = t.col(0).x;
    if w <= 0.0 {
        return false;
    }
    if order > settings.rr_depth && w < RR_THRESHOLD {
        if rng.next_f64() < w / RR_THRESHOLD {
            *t *= RR_THRESHOLD / w;
        } else {
            return false;
        }
    }
    true
}

/// One path from (τ₀, d₀) whose sensor frame has first axis `e1_sensor` (⊥ d₀); returns the
/// (I single, I multiple, Q, U, V) parts of `π·S/(E0 μ_s)`.
pub fn walk(
    opt: &OpticalState,
    sun_dir: DVec3,
    tau0: f64,
    d0: DVec3,
    e1_sensor: DVec3,
    settings: &IntegratorSettings,
    rng: &mut Stream,
) -> [f64; 5] {
    let atm = &opt.atmosphere;
    let total = atm.total_tau();
    let mu_s = sun_dir.z;
    let inv_mu_s = 1.0 / mu_s;
    let t_sun_ground = (-total * inv_mu_s).exp();
    let mut out = [0.0; 5];
    let mut score = |order: u32, s: DVec4| add_score(&mut out, order, s);
    let w_sun = -sun_dir;
    let mut d = d0;
    let mut e1 = e1_sensor;
    let mut tau = tau0;
    let mut t = DMat4::IDENTITY;
    let mut order: u32 = 1;
    let inv4pi = 0.25 * std::f64::consts::FRAC_1_PI;
    while order <= settings.max_depth {
        // Expected next-event estimate of the next collision (exact along the flight).
        let w_out = -d;
        let cos = sun_dir.dot(d);
        let mut m = PhaseMatrix {
            a1: 0.0,
            b1: 0.0,
            a2: 0.0,
            a3: 0.0,
            b2: 0.0,
            a4: 0.0,
        };
        atm.flight_integrals(tau, d.z, inv_mu_s, |l, i| {
            m.add(&atm.phase(l).matrix(cos).scaled(atm.albedo(l) * i));
        });
        if m.a1 > 0.0 {
            let (_, _, l_out) = plane(w_sun, w_out, e1);
            let sv = DVec4::new(m.a1, m.b1, 0.0, 0.0); // F · (1, 0, 0, 0)
            score(order, t * (rotation(w_out, l_out, e1) * sv) * inv4pi);
        }
        let s = -rng.next_f64_open0().ln();
        match atm.fly(tau, d.z, s) {
            FlightEnd::Escape => break,
            FlightEnd::Surface => {
                tau = total;
                let wo = -d;
                let (w_sun_l, wo_l, sun_l) = (w_sun, wo, sun_dir);
                (t, d, e1) = surface_event(
                    &opt.surface,
                    &mut t,
                    d,
                    e1,
                    (w_sun_l, wo_l, sun_l),
                    mu_s * t_sun_ground,
                    rng,
                    |s| score(order, s),
                );
            }
            FlightEnd::Collision(tc) => {
                tau = tc;
                let layer = atm.layer_at_tau(tc);
                let omega = atm.albedo(layer);
                let phase = atm.phase(layer);
                (t, d, e1) = scatter_path(&t, d, e1, phase, omega, rng);
            }
        }
        order += 1;
        if !survives(&mut t, order, settings, rng) {
            break;
        }
    }
    let k = std::f64::consts::PI / mu_s;
    out.map(|x| x * k)
}

/// The polarized backward walk in a spherical shell (see `backward_sph` for the geometry: exact
/// shell traversal, Earth's shadow, NEE at sampled collisions). `e1_sensor` ⊥ `d0` is the first
/// axis of the sensor's frame; a sample is `π·S/E0` divided by `mu_norm`.
#[allow(clippy::too_many_arguments)]
pub fn walk_spherical(
    shell: &SphericalShell,
    surface: &Bsdf,
    sun_dir: DVec3,
    mu_norm: f64,
    p0: DVec3,
    l0: usize,
    d0: DVec3,
    e1_sensor: DVec3,
    settings: &IntegratorSettings,
    rng: &mut Stream,
) -> [f64; 5] {
    let mut out = [0.0; 5];
    let mut score = |order: u32, s: DVec4| add_score(&mut out, order, s);
    let w_sun = -sun_dir;
    let (mut p, mut l, mut d, mut e1) = (p0, l0, d0, e1_sensor);
    let mut t = DMat4::IDENTITY;
    let mut order: u32 = 1;
    let inv4pi = 0.25 * std::f64::consts::FRAC_1_PI;
    while order <= settings.max_depth {
        let s = -rng.next_f64_open0().ln();
        match shell.fly(p, l, d, s) {
            ShellEnd::Escape => break,
            ShellEnd::Surface(q) => {
                p = q;
                l = 0;
                let n = q / q.length();
                let (a, b) = basis_around(n);
                let local = |v: DVec3| DVec3::new(v.dot(a), v.dot(b), v.dot(n));
                let cos_sun = sun_dir.dot(n);
                let tr = if cos_sun > 0.0 {
                    shell.transmittance_to_space(p, 0, sun_dir)
                } else {
                    0.0
                };
                let to_world = |v: DVec3| a * v.x + b * v.y + n * v.z;
                (t, d, e1) = surface_event_local(
                    surface,
                    &mut t,
                    d,
                    e1,
                    w_sun,
                    sun_dir,
                    cos_sun * tr,
                    &local,
                    &to_world,
                    rng,
                    |s| score(order, s),
                );
            }
            ShellEnd::Collision(q, lq) => {
                p = q;
                l = lq;
                let omega = shell.albedo(l);
                let phase = shell.phase(l);
                let w_out = -d;
                let tr = shell.transmittance_to_space(p, l, sun_dir);
                if tr > 0.0 {
                    let f = phase.matrix(sun_dir.dot(d));
                    let (_, _, l_out) = plane(w_sun, w_out, e1);
                    let sv = DVec4::new(f.a1, f.b1, 0.0, 0.0);
                    score(
                        order,
                        t * (rotation(w_out, l_out, e1) * sv) * (omega * inv4pi * tr),
                    );
                }
                (t, d, e1) = scatter_path(&t, d, e1, phase, omega, rng);
            }
        }
        order += 1;
        if !survives(&mut t, order, settings, rng) {
            break;
        }
    }
    let k = std::f64::consts::PI / mu_norm;
    out.map(|x| x * k)
}

/// A surface interaction of the plane-parallel walk (local frame = world frame). See
/// [`surface_event_local`].
#[allow(clippy::too_many_arguments)]
fn surface_event(
    surface: &Bsdf,
    t: &mut DMat4,
    d: DVec3,
    e1: DVec3,
    (w_sun, _wo, sun_dir): (DVec3, DVec3, DVec3),
    sun_factor: f64,
    rng: &mut Stream,
    score: impl FnMut(DVec4),
) -> (DMat4, DVec3, DVec3) {
    surface_event_local(
        surface,
        t,
        d,
        e1,
        w_sun,
        sun_dir,
        sun_factor,
        &|v| v,
        &|v| v,
        rng,
        score,
    )
}

/// A surface interaction: next-event estimate of the reflected sunlight (`sun_factor` =
/// cos θ_sun·T_sun at the point, 0 in shadow), then the new path direction and the updated `T`.
/// Depolarizing BRDFs keep only `T`'s first column; polarizing ones (ocean) multiply `T` by their
/// reflection matrix in the plane of incidence. `local`/`to_world` map world vectors to the
/// surface's frame (normal = z) and back.
#[allow(clippy::too_many_arguments)]
fn surface_event_local(
    surface: &Bsdf,
    t: &mut DMat4,
    d: DVec3,
    e1: DVec3,
    w_sun: DVec3,
    sun_dir: DVec3,
    sun_factor: f64,
    local: &dyn Fn(DVec3) -> DVec3,
    to_world: &dyn Fn(DVec3) -> DVec3,
    rng: &mut Stream,
    mut score: impl FnMut(DVec4),
) -> (DMat4, DVec3, DVec3) {
    let w_out = -d;
    let wo_l = local(w_out);
    if sun_factor > 0.0 {
        let sun_l = local(sun_dir);
        match surface.matrix(sun_l, wo_l) {
            Some(m) if m.a1 > 0.0 => {
                let (_, _, l_out) = plane(w_sun, w_out, e1);
                let sv = DVec4::new(m.a1, m.b1, 0.0, 0.0);
                score(*t * (rotation(w_out, l_out, e1) * sv) * sun_factor);
            }
            Some(_) => {}
            None => score(t.col(0) * (surface.eval(sun_l, wo_l) * sun_factor)),
        }
    }
    let smp = surface.sample(wo_l, rng.next_f64(), rng.next_f64());
    let d2 = to_world(smp.wi);
    match surface.matrix(smp.wi, wo_l) {
        Some(m) => {
            let (_, l_in, l_out) = plane(-d2, w_out, e1);
            let t2 = *t * rotation(w_out, l_out, e1) * mueller(&m) * (smp.wi.z / smp.pdf);
            (t2, d2, l_in)
        }
        None => {
            // Depolarizer: only the first column of T survives.
            let t2 = DMat4::from_cols(t.col(0) * smp.weight, DVec4::ZERO, DVec4::ZERO, DVec4::ZERO);
            (t2, d2, any_perpendicular(d2))
        }
    }
}
