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
//! the 1D walks. The 1D walk's "expected local estimate" is not used here: the collision
//! estimator is exact in expectation and the shadow ray makes the expectation along a flight
//! geometry-dependent.

use glam::DVec3;

use super::{roulette, sample_scattered};
use crate::atmosphere::PlaneParallel;
use crate::config::resolve::IntegratorSettings;
use crate::rng::Stream;
use crate::scene::material::SurfaceModel;
use crate::scene::world::BLACK;
use crate::scene::Scene;

/// Everything a walk needs at one wavelength.
pub struct SceneContext<'a> {
    pub atmosphere: &'a PlaneParallel,
    pub scene: &'a Scene,
    /// Material models at this wavelength, indexed by material id.
    pub models: &'a [SurfaceModel],
    /// Unit vector towards the Sun (`z > 0`).
    pub sun: DVec3,
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
    let (mut single, mut multiple) = (0.0, 0.0);
    let mut p = o;
    let mut d = d;
    let mut w = 1.0_f64;
    let mut order: u32 = 1;
    while order <= settings.max_depth {
        let s = -rng.next_f64_open0().ln();
        let t_coll = atm.march(p.z, d.z, s, f64::INFINITY);
        let t_lim = t_coll.unwrap_or(f64::INFINITY);
        // Distance at which the ray comes down to the scene's top (0 if already below).
        let reach = if p.z <= top {
            0.0
        } else if d.z < 0.0 {
            (p.z - top) / -d.z
        } else {
            f64::INFINITY
        };
        let hit = if reach < t_lim {
            scene.intersect(p, d, t_lim)
        } else {
            None
        };
        let mut score = 0.0;
        if let Some(h) = hit {
            let model = if h.material == BLACK {
                &SurfaceModel::Black
            } else {
                ctx.models
                    .get(h.material as usize)
                    .unwrap_or(&SurfaceModel::Black)
            };
            let wo = -d;
            let n = h.normal;
            let f = model.eval_cos(n, sun, wo);
            if f > 0.0 {
                let start = scene.offset(h.point, n, sun);
                if !scene.occluded(start, sun, f64::INFINITY) {
                    score = w * f * ctx.t_sun(h.point.z);
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
        } else if let Some(t) = t_coll {
            p += d * t;
            let layer = atm.layer_at_altitude(p.z);
            let omega = atm.albedo(layer);
            let phase = atm.phase(layer);
            let f = omega * phase.eval(sun.dot(d)) * (0.25 * std::f64::consts::FRAC_1_PI);
            if f > 0.0 && (p.z > top || !scene.occluded(p, sun, f64::INFINITY)) {
                score = w * f * ctx.t_sun(p.z);
            }
            w *= omega;
            d = sample_scattered(phase, d, rng);
        } else {
            break;
        }
        if order == 1 {
            single += score;
        } else {
            multiple += score;
        }
        order += 1;
        if w <= 0.0 {
            break;
        }
        if order > settings.rr_depth && !roulette(&mut w, rng.next_f64()) {
            break;
        }
    }
    let k = std::f64::consts::PI / sun.z;
    (single * k, multiple * k)
}
