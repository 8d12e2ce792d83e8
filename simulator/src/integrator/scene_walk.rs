//! Backward walk through a 3D scene inside the plane-parallel atmosphere.
//!
//! Positions are metres in the scene's local frame (x east, y north, z = altitude); the
//! atmosphere is horizontally homogeneous, so the free path of a ray is sampled exactly by
//! marching its layers ([`PlaneParallel::march`]) and the Sun's transmittance to a point at
//! altitude z is `exp(−τ(z)/μ_s)`. A path starts at the sensor (or at the top of the atmosphere
//! for distant measures) and looks along `d`:
//!
//! 1. it draws an optical path and the distance `t_c` of its next collision in the atmosphere
//!    (∞ if it leaves first); the scene is queried for the closest hit before `t_c` (only when
//!    the ray can reach the scene's top before `t_c`);
//! 2. at a surface hit with normal `n` (facing the arriving path) and material model `M`, the
//!    next-event estimate towards the Sun is `w·M.eval_cos(n, s, −d)·T_sun(z)·V`, with `V` = 1
//!    when a shadow ray from the (offset) hit point towards the Sun meets no geometry; the path
//!    continues in a direction sampled from `M` (weight `f·|cos|/pdf`);
//! 3. at an atmospheric collision the estimate is `w·ω·P(s·d)/(4π)·T_sun(z)·V` (V only needed
//!    below the scene's top) and the path continues along a direction drawn from the phase
//!    function, with weight `w·ω`;
//! 4. it ends when it leaves through the top, falls below the atmosphere without meeting any
//!    geometry (lost), meets a black surface, or by Russian roulette after `rr_depth` orders.
//!
//! A sample is `π·L/(E0·μ_s)`, split into single (first interaction) and multiple parts like
//! the 1D walks.
//!
//! Atmospheric estimates (default, `local_estimate = "expected"`): instead of scoring at the
//! sampled collision, every flight scores the expectation of that estimate over its collision
//! point — exactly, layer by layer, for the part of the flight above the scene's top (no
//! geometry can shadow it), and by one forced collision with its shadow ray for the part below
//! the top (see [`expected_atmospheric`]). `local_estimate = "collision"` scores at sampled
//! collisions (a cross-check; both are unbiased, the first has far less variance).

use glam::DVec3;

use super::{roulette, sample_scattered, OrderSplit};
use crate::atmosphere::PlaneParallel;
use crate::bsdf::{Bsdf, Lambertian};
use super::settings::IntegratorSettings;
use crate::rng::Stream;
use crate::scene::material::SurfaceModel;
use crate::scene::world::BLACK;
use crate::scene::{Scene, SurfaceHit};
use std::borrow::Cow;

/// Everything a walk needs at one wavelength.
pub struct SceneContext<'a> {
    pub atmosphere: &'a PlaneParallel,
    pub scene: &'a Scene,
    /// Material models at this wavelength, indexed by material id.
    pub models: &'a [SurfaceModel],
    /// Unit vector towards the Sun (`z > 0`).
    pub sun: DVec3,
    /// nm (for reflectance textures).
    pub wavelength: f64,
}

impl SceneContext<'_> {
    /// Direct solar transmittance from altitude `z` to TOA.
    #[inline]
    fn t_sun(&self, z: f64) -> f64 {
        (-self.atmosphere.tau_at_altitude(z) / self.sun.z).exp()
    }

    /// Altitude above which a path starts so that it sees the whole scene and atmosphere.
    pub fn start_altitude(&self) -> f64 {
        self.atmosphere.toa().max(self.scene.z_range[1] + 1.0)
    }
}

/// One path from `o` along unit `d`; returns the (single, multiple) parts of `π·L/(E0 μ_s)`.
pub fn walk(
    ctx: &SceneContext,
    o: DVec3,
    d: DVec3,
    settings: &IntegratorSettings,
    rng: &mut Stream,
) -> (f64, f64) {
    let scene = ctx.scene;
    let atm = ctx.atmosphere;
    let sun = ctx.sun;
    let top = scene.z_range[1];
    let tau_top = atm.tau_at_altitude(top);
    let has_atm = atm.total_tau() > 0.0;
    let inv_4pi = 0.25 * std::f64::consts::FRAC_1_PI;
    let mut split = OrderSplit::default();
    let mut p = o;
    let mut d = d;
    let mut w = 1.0_f64;
    let mut order: u32 = 1;
    while order <= settings.max_depth {
        // Distance at which the ray comes down to the scene's top (0 if already below).
        let reach = if p.z <= top {
            0.0
        } else if d.z < 0.0 {
            (p.z - top) / -d.z
        } else {
            f64::INFINITY
        };
        let hit = if reach.is_finite() {
            scene.intersect(p, d, f64::INFINITY)
        } else {
            None
        };
        let t_hit = hit.map_or(f64::INFINITY, |h| h.t);
        let mut score = 0.0;
        if settings.expected_local_estimate && has_atm {
            score += w * expected_atmospheric(ctx, p, d, reach, t_hit, top, tau_top, rng) * inv_4pi;
        }
        let s = -rng.next_f64_open0().ln();
        let t_coll = if has_atm {
            atm.march(p.z, d.z, s, t_hit)
        } else {
            None
        };
        if let Some(t) = t_coll {
            p = scene.wrap_point(p + d * t);
            let layer = atm.layer_at_altitude(p.z);
            let omega = atm.albedo(layer);
            let phase = atm.phase(layer);
            if !settings.expected_local_estimate {
                let f = omega * phase.eval(sun.dot(d)) * inv_4pi;
                if f > 0.0 && (p.z > top || !scene.occluded(p, sun, f64::INFINITY)) {
                    score += w * f * ctx.t_sun(p.z);
                }
            }
            w *= omega;
            d = sample_scattered(phase, d, rng);
        } else if let Some(h) = hit {
            let model = surface_model(scene, ctx.models, ctx.wavelength, &h);
            let model = model.as_ref();
            let wo = -d;
            let n = h.normal;
            let f = model.eval_cos(n, sun, wo);
            if f > 0.0 {
                let start = scene.offset(h.point, n, sun);
                if !scene.occluded(start, sun, f64::INFINITY) {
                    score += w * f * ctx.t_sun(h.point.z);
                }
            }
            match model.sample(n, wo, [rng.next_f64(), rng.next_f64(), rng.next_f64()]) {
                Some(smp) => {
                    w *= smp.weight;
                    d = smp.wi;
                    p = scene.offset(h.point, n, d);
                }
                None => w = 0.0,
            }
        } else {
            split.add(order, score);
            break;
        }
        split.add(order, score);
        order += 1;
        if w <= 0.0 {
            break;
        }
        if order > settings.rr_depth && !roulette(&mut w, rng.next_f64()) {
            break;
        }
    }
    let k = std::f64::consts::PI / sun.z;
    split.scaled(k)
}

/// The reflection model at a scene hit: black for [`BLACK`], a Lambertian from the texture
/// where one covers a terrain hit, else the material's model.
pub(crate) fn surface_model<'m>(
    scene: &Scene,
    models: &'m [SurfaceModel],
    wavelength: f64,
    h: &SurfaceHit,
) -> Cow<'m, SurfaceModel> {
    if h.material == BLACK {
        Cow::Owned(SurfaceModel::Black)
    } else if let Some(r) = scene.texture_reflectance(h, wavelength) {
        Cow::Owned(SurfaceModel::Opaque(Bsdf::Lambertian(Lambertian {
            reflectance: r,
        })))
    } else {
        models
            .get(h.material as usize)
            .map_or(Cow::Owned(SurfaceModel::Black), Cow::Borrowed)
    }
}

/// Expected value, over the next collision of the flight from `p` along `d`, of the
/// atmospheric next-event estimate `ω P(s·d) T_sun V` (without the 1/4π), for a flight whose
/// first geometry hit is at `t_hit` and which comes below the scene's top at `reach`:
/// * above the scene's top no geometry blocks the Sun, so that part of the flight is integrated
///   exactly, layer by layer (`flight_integrals_within`);
/// * below the top (until the geometry hit) one point is drawn from the collision density
///   restricted to that segment and scored with its shadow ray, weighted by the probability of a
///   collision in the segment (forced collision: unbiased, one shadow ray per flight).
#[allow(clippy::too_many_arguments)]
fn expected_atmospheric(
    ctx: &SceneContext,
    p: DVec3,
    d: DVec3,
    reach: f64,
    t_hit: f64,
    top: f64,
    tau_top: f64,
    rng: &mut Stream,
) -> f64 {
    let atm = ctx.atmosphere;
    let sun = ctx.sun;
    let cos = sun.dot(d);
    let mut acc = 0.0;
    // Part above the top: a flight starting above it, or one that climbs out of the scene
    // without hitting anything first.
    let exits_up = d.z > 0.0 && p.z <= top && t_hit >= (top - p.z) / d.z;
    if p.z > top || exits_up {
        let tau_p = atm.tau_at_altitude(p.z);
        atm.flight_integrals_within(tau_p, d.z, 1.0 / sun.z, 0.0, tau_top, |l, i| {
            acc += atm.albedo(l) * atm.phase(l).eval(cos) * i;
        });
    }
    // Part below the top: [t_a, t_b].
    if reach.is_finite() {
        let t_a = reach;
        let t_leave = if d.z > 0.0 && p.z <= top {
            (top - p.z) / d.z
        } else if d.z < 0.0 {
            (p.z - atm.ground()) / -d.z
        } else {
            f64::INFINITY
        };
        let t_b = t_hit.min(t_leave);
        if t_b > t_a {
            let s_a = atm.optical_path(p.z, d.z, t_a);
            let s_ab = if t_b.is_finite() {
                atm.optical_path(p.z + t_a * d.z, d.z, t_b - t_a)
            } else {
                f64::INFINITY
            };
            // Probability of a collision inside the segment.
            let p_seg = (-s_a).exp() * -(-s_ab).exp_m1();
            if p_seg > 0.0 {
                let u = rng.next_f64();
                let s_star = s_a - (-u * -(-s_ab).exp_m1()).ln_1p();
                if let Some(t) = atm.march(p.z, d.z, s_star, f64::INFINITY) {
                    let q = p + d * t.min(t_b);
                    let l = atm.layer_at_altitude(q.z);
                    let f = atm.albedo(l) * atm.phase(l).eval(cos);
                    if f > 0.0 && !ctx.scene.occluded(q, sun, f64::INFINITY) {
                        acc += p_seg * f * ctx.t_sun(q.z);
                    }
                }
            }
        }
    }
    acc
}
