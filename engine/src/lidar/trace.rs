//! Photon paths from the laser, with next-event estimates towards the receiver (the module
//! header of `lidar/mod.rs` gives the estimator). One shot at a time: [`trace_shot`].

use glam::DVec3;
use rayon::prelude::*;

use super::air::Air;
use super::{Lidar, C_M_PER_NS};
use crate::frame::{basis_around, rotate_about};
use crate::rng::Stream;
use crate::scene::material::SurfaceModel;
use crate::scene::world::BLACK;
use crate::scene::Scene;

/// The parts a waveform is split into.
pub const NCOMP: usize = 6;
/// All orders.
pub const TOTAL: usize = 0;
/// Exactly one scattering event between the laser and the receiver.
pub const FIRST: usize = 1;
/// Two or more.
pub const MULTIPLE: usize = 2;
/// First order from objects (leaves, trunks, buildings), from the ground (terrain, ground
/// plane, 1D surface), from the air.
pub const FIRST_CANOPY: usize = 3;
pub const FIRST_GROUND: usize = 4;
pub const FIRST_AIR: usize = 5;
/// Names of the parts in the products.
pub const COMP_NAMES: [&str; NCOMP] = [
    "total",
    "first_order",
    "multiple",
    "first_order_canopy",
    "first_order_ground",
    "first_order_air",
];

/// Photons per block: the unit of parallel work and of deterministic merging (a multiple of
/// [`REPLICATES`]).
const BLOCK: u64 = 8192;
/// Independently scrambled Sobol sequences of footprint points per shot: photon `i` belongs to
/// replicate `i mod R` and takes point `i div R` of its sequence. The footprint integral is
/// smooth over flat and sloped ground, where Sobol points make its error fall almost as 1/N,
/// and the replicates' means are independent, so the standard error is their spread
/// (`√(Σ(m_r − m)²/(R(R−1)))`, R − 1 = 31 degrees of freedom). A third dimension places the
/// first flight's forced collision in the air. Shots are traced in whole
/// cycles of R photons (`spp` rounded up).
pub const REPLICATES: u64 = 32;
/// Sobol points per scrambled sequence before a new scrambling (`sobol_burley` indices).
const SOBOL_POINTS: u64 = 1 << 16;
/// Blocks traced at once before merging (bounds the memory of per-block accumulators).
const CHUNK: usize = 32;
/// Russian roulette: paths of weight below this survive a scattering with probability
/// `w / RR_WEIGHT` and carry `RR_WEIGHT`.
const RR_WEIGHT: f64 = 0.2;
/// Stream tag of lidar photons.
const LIDAR_STREAM: u64 = 0x11DA_4000;

/// A mean over the photons of a shot and the standard error of that mean.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stat {
    pub mean: f64,
    pub stderr: f64,
}

/// One shot's waveform in normalised energy `e` (see `lidar/mod.rs`).
#[derive(Clone, Debug)]
pub struct ShotWaveform {
    pub photons: u64,
    /// Per bin, per part ([`TOTAL`] … [`FIRST_AIR`]).
    pub bins: Vec<[Stat; NCOMP]>,
    /// Whole returns (every delay, inside the bins or not), per part.
    pub totals: [Stat; NCOMP],
    /// GEDI-like metrics of the waveform (`metrics.rs`) and their standard errors (NaN when a
    /// replicate has no ground return); `None` without a ground return.
    pub metrics: Option<(super::metrics::Metrics, super::metrics::Metrics)>,
}

/// Running sums over photons, per replicate (see [`REPLICATES`]).
#[derive(Clone)]
struct Acc {
    n: u64,
    /// [replicate][bin][part].
    sum: Vec<f64>,
    /// [replicate][part].
    tsum: Vec<f64>,
}

impl Acc {
    fn new(nbins: usize) -> Self {
        Self {
            n: 0,
            sum: vec![0.0; REPLICATES as usize * nbins * NCOMP],
            tsum: vec![0.0; REPLICATES as usize * NCOMP],
        }
    }

    /// Replicate means of bin `b`, part `c` (`per` photons per replicate).
    fn bin_means(&self, nbins: usize, b: usize, c: usize, per: f64) -> Vec<f64> {
        let stride = nbins * NCOMP;
        (0..REPLICATES as usize)
            .map(|r| self.sum[r * stride + b * NCOMP + c] / per)
            .collect()
    }

    /// Replicate means of the whole return's part `c`.
    fn total_means(&self, c: usize, per: f64) -> Vec<f64> {
        (0..REPLICATES as usize)
            .map(|r| self.tsum[r * NCOMP + c] / per)
            .collect()
    }

    fn merge(&mut self, o: &Acc) {
        self.n += o.n;
        for (a, b) in self.sum.iter_mut().zip(&o.sum) {
            *a += b;
        }
        for (a, b) in self.tsum.iter_mut().zip(&o.tsum) {
            *a += b;
        }
    }
}

/// The mean of independent replicate values and the standard error of that mean, from their
/// spread (`√(Σ(m_r − m)²/(n(n − 1)))`): every error of a shot (bins, totals, metrics, the
/// peak's target).
fn spread(values: &[f64]) -> Stat {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|m| (m - mean) * (m - mean)).sum::<f64>() / (n * (n - 1.0));
    Stat {
        mean,
        stderr: var.sqrt(),
    }
}

/// One photon's scores before they are added to the sums (sparse over the bins).
struct Scratch {
    cur: Vec<f64>,
    touched: Vec<usize>,
    tot: [f64; NCOMP],
}

impl Scratch {
    fn add(&mut self, idx: usize, v: f64) {
        if self.cur[idx] == 0.0 {
            self.touched.push(idx);
        }
        self.cur[idx] += v;
    }

    /// Add the photon's scores to replicate `r` of `acc`.
    fn flush(&mut self, acc: &mut Acc, r: usize) {
        acc.n += 1;
        let base = r * self.cur.len();
        for &i in &self.touched {
            acc.sum[base + i] += self.cur[i];
            self.cur[i] = 0.0;
        }
        self.touched.clear();
        for c in 0..NCOMP {
            acc.tsum[r * NCOMP + c] += self.tot[c];
            self.tot[c] = 0.0;
        }
    }
}

/// Where a lidar's photons travel: the air, and the scene or the 1D ground.
pub struct World<'a> {
    pub atmosphere: Air<'a>,
    /// Whether the air has any extinction at the lidar's wavelength.
    pub has_air: bool,
    pub scene: Option<&'a Scene>,
    /// Scene materials at the lidar's wavelength (indexed by material id).
    pub models: &'a [SurfaceModel],
    /// The 1D ground (without a scene).
    pub ground: SurfaceModel,
    /// The 1D ground's altitude, m.
    pub ground_z: f64,
}

struct Hit<'m> {
    t: f64,
    normal: DVec3,
    model: &'m SurfaceModel,
    ground: bool,
    /// The scene's material id (None: the 1D ground).
    material: Option<u16>,
}

/// The first surface seen along a ray ([`World::first_surface`]).
pub struct SurfaceSeen<'m> {
    pub point: DVec3,
    /// Unit normal facing the ray's origin.
    pub normal: DVec3,
    pub model: &'m SurfaceModel,
    /// Terrain, ground plane or 1D ground.
    pub ground: bool,
    /// The scene's material id (None: the 1D ground).
    pub material: Option<u16>,
    /// Distance from the ray's origin, m.
    pub distance: f64,
}

const BLACK_MODEL: SurfaceModel = SurfaceModel::Black;

impl World<'_> {
    /// A height above every part of the scene (rays from far away start their scene search
    /// there, where f32 geometry is precise).
    fn top(&self) -> f64 {
        self.scene.map_or(self.ground_z, |s| s.z_range[1]) + 1.0
    }

    /// The first surface along `o + t·d`, `t < tmax`.
    fn hit(&self, lidar: &Lidar, o: DVec3, d: DVec3, tmax: f64) -> Option<Hit<'_>> {
        match self.scene {
            Some(scene) => {
                let top = self.top();
                let mut t0 = 0.0;
                if o.z > top {
                    if d.z >= 0.0 {
                        return None;
                    }
                    t0 = (o.z - top) / -d.z;
                }
                if t0 >= tmax {
                    return None;
                }
                let h = scene.intersect(o + d * t0, d, tmax - t0)?;
                let model = if h.material == BLACK {
                    &BLACK_MODEL
                } else {
                    self.models.get(h.material as usize).unwrap_or(&BLACK_MODEL)
                };
                Some(Hit {
                    t: t0 + h.t,
                    normal: h.normal,
                    model,
                    ground: h.ground,
                    material: Some(h.material),
                })
            }
            None => {
                let n = lidar.slope.map_or(DVec3::Z, |s| s.normal);
                let dn = d.dot(n);
                if dn >= 0.0 {
                    return None;
                }
                let t = (DVec3::new(0.0, 0.0, self.ground_z) - o).dot(n) / dn;
                (t > 0.0 && t < tmax).then_some(Hit {
                    t,
                    normal: n,
                    model: &self.ground,
                    ground: true,
                    material: None,
                })
            }
        }
    }

    /// The first surface seen from `o` along `d`.
    pub fn first_surface(&self, lidar: &Lidar, o: DVec3, d: DVec3) -> Option<SurfaceSeen<'_>> {
        self.hit(lidar, o, d, 1e9).map(|h| SurfaceSeen {
            point: o + d * h.t,
            normal: h.normal,
            model: h.model,
            ground: h.ground,
            material: h.material,
            distance: h.t,
        })
    }

    /// Whether the line from `p` (leaving a surface of normal `n`, or in the air: `None`)
    /// upwards along `dir` is free of the scene over the distance `reach` (to the receiver:
    /// an airborne sensor may fly below the scene's highest point) or up to the scene's top.
    pub fn sees_up(&self, p: DVec3, n: Option<DVec3>, dir: DVec3, reach: f64) -> bool {
        let Some(scene) = self.scene else {
            return true;
        };
        let top = self.top();
        if p.z >= top {
            return true;
        }
        let o = match n {
            Some(n) => scene.offset(p, n, dir),
            None => p,
        };
        let t = if dir.z > 0.0 {
            ((top - o.z) / dir.z).min(reach)
        } else {
            reach
        };
        !scene.occluded(o, dir, t)
    }
}

/// The geometry of one shot.
pub(super) struct Shot {
    pub(super) sensor: DVec3,
    pub(super) r0: f64,
    /// Beam axis (from the sensor down), and two unit vectors across it.
    axis: DVec3,
    e1: DVec3,
    e2: DVec3,
    centre: DVec3,
    cos_fov: f64,
    parallel: bool,
}

impl Shot {
    /// The geometry of shot `k` of `lidar`.
    pub(super) fn new(lidar: &Lidar, k: usize) -> Self {
        let centre = lidar.shots[k];
        let axis = -lidar.to_sensor;
        let (e1, e2) = basis_around(axis);
        Shot {
            sensor: lidar.sensor(centre),
            r0: lidar.range0(centre),
            axis,
            e1,
            e2,
            centre,
            cos_fov: lidar.fov_half_angle.cos(),
            parallel: lidar.parallel,
        }
    }

    /// The ray of a photon through the footprint point `(fx, fy)` (m across the beam): from
    /// a point source at the sensor, or parallel to the beam from the plane through the
    /// sensor perpendicular to it. Its start and unit direction.
    pub(super) fn ray(&self, fx: f64, fy: f64) -> (DVec3, DVec3) {
        let target = self.centre + self.e1 * fx + self.e2 * fy;
        if self.parallel {
            (target - self.axis * self.r0, self.axis)
        } else {
            (self.sensor, (target - self.sensor).normalize())
        }
    }

    /// The unit direction from `p` towards the receiver and the distance the return travels:
    /// to the sensor's point, or with parallel rays along the beam axis to the sensor's plane.
    #[inline]
    pub(super) fn towards_receiver(&self, p: DVec3) -> (DVec3, f64) {
        if self.parallel {
            (-self.axis, (p - self.sensor).dot(self.axis))
        } else {
            let to_s = self.sensor - p;
            let dist = to_s.length();
            (to_s / dist, dist)
        }
    }
}

/// A return to score: its delay (ns), normalised energy, order and part.
#[inline]
fn score(lidar: &Lidar, s: &mut Scratch, t_ns: f64, e: f64, order: u32, first_part: usize) {
    if e.is_nan() || e <= 0.0 {
        return;
    }
    let parts: [usize; 2] = if order <= 1 {
        [FIRST, first_part]
    } else {
        [MULTIPLE, usize::MAX]
    };
    s.tot[TOTAL] += e;
    s.tot[parts[0]] += e;
    if parts[1] != usize::MAX {
        s.tot[parts[1]] += e;
    }
    lidar.bins.spread(t_ns, e, lidar.pulse_sigma_ns, |k, v| {
        s.add(k * NCOMP + TOTAL, v);
        s.add(k * NCOMP + parts[0], v);
        if parts[1] != usize::MAX {
            s.add(k * NCOMP + parts[1], v);
        }
    });
}

/// A path in flight.
#[derive(Clone, Copy)]
struct Path {
    p: DVec3,
    d: DVec3,
    w: f64,
    /// Path length so far, m.
    len: f64,
    /// Scattering events so far.
    order: u32,
    /// Whether the next flight is the first (from the laser).
    first_flight: bool,
    /// The uniform number that places the first flight's forced collision (a Sobol
    /// dimension: the air's first-order returns are then stratified in optical depth).
    u_force: f64,
}

/// Trace one photon (both branches of its first flight) through the footprint point of the
/// uniform numbers `u` and score it into `s`.
fn photon(
    lidar: &Lidar,
    world: &World,
    shot: &Shot,
    u: [f64; 3],
    rng: &mut Stream,
    s: &mut Scratch,
) {
    let (fx, fy, w0) = lidar.footprint.sample(u[0], u[1]);
    let (start, d) = shot.ray(fx, fy);
    let mut stack = [None, None];
    stack[0] = Some(Path {
        p: start,
        d,
        w: w0,
        len: 0.0,
        order: 0,
        first_flight: true,
        u_force: u[2],
    });
    let mut top = 1;
    while top > 0 {
        top -= 1;
        let Some(mut path) = stack[top].take() else {
            continue;
        };
        while let Flight::Continue(branch) = flight(lidar, world, shot, rng, s, &mut path) {
            if let Some(b) = branch {
                stack[top] = Some(b);
                top += 1;
            }
        }
    }
}

enum Flight {
    /// The path goes on (with, after the first flight, the forced-collision branch to trace).
    Continue(Option<Path>),
    End,
}

/// One flight of `path` and the event that ends it (scoring its next-event estimate).
fn flight(
    lidar: &Lidar,
    world: &World,
    shot: &Shot,
    rng: &mut Stream,
    s: &mut Scratch,
    path: &mut Path,
) -> Flight {
    let atm = world.atmosphere;
    let far = 1e9;
    let hit = world.hit(lidar, path.p, path.d, far);
    let t_end = hit.as_ref().map_or(far, |h| h.t);
    let mut branch = None;
    let has_air = world.has_air;
    // Where the flight collides in the air, if it does.
    let mut collision = None;
    if has_air {
        if path.first_flight {
            // Forced collision: the collided branch (weight 1 − T) goes on its own.
            let tau = atm.optical_path(path.p, path.d, t_end);
            let tr = (-tau).exp();
            if tau > 0.0 {
                let u = path.u_force;
                let tau_c = -(-u * (-(-tau).exp_m1())).ln_1p();
                if let Some(tc) = atm.march(path.p, path.d, tau_c, t_end) {
                    let mut b = *path;
                    b.w *= 1.0 - tr;
                    b.first_flight = false;
                    if air_event(lidar, world, shot, rng, s, &mut b, tc) {
                        branch = Some(b);
                    }
                }
            }
            path.w *= tr;
        } else {
            let u = rng.next_f64_open0();
            collision = atm.march(path.p, path.d, -u.ln(), t_end);
        }
    }
    path.first_flight = false;
    if let Some(tc) = collision {
        return if air_event(lidar, world, shot, rng, s, path, tc) {
            Flight::Continue(branch)
        } else {
            Flight::End
        };
    }
    let Some(h) = hit else {
        return match branch {
            Some(b) => {
                *path = b;
                Flight::Continue(None)
            }
            None => Flight::End,
        };
    };
    // A surface.
    path.p += path.d * h.t;
    path.len += h.t;
    path.order += 1;
    let (wr, dist) = shot.towards_receiver(path.p);
    let part = if h.ground { FIRST_GROUND } else { FIRST_CANOPY };
    if in_fov(shot, path.p) {
        let f = h.model.eval_cos(h.normal, wr, -path.d);
        if f > 0.0 && world.sees_up(path.p, Some(h.normal), wr, dist) {
            let tr = (-atm.optical_path(path.p, wr, dist)).exp();
            let ratio = shot.r0 / dist;
            let e = path.w * std::f64::consts::PI * f * ratio * ratio * tr;
            let t_ns = (path.len + dist - 2.0 * shot.r0) / C_M_PER_NS;
            score(lidar, s, t_ns, e, path.order, part);
        }
    }
    let go_on = path.order < lidar.max_order
        && h.model
            .sample(
                h.normal,
                -path.d,
                [rng.next_f64(), rng.next_f64(), rng.next_f64()],
            )
            .map(|smp| {
                path.w *= smp.weight;
                let n = h.normal;
                path.p = match world.scene {
                    Some(sc) => sc.offset(path.p, n, smp.wi),
                    None => path.p + n * (1e-9 * (1.0 + path.p.abs().max_element())),
                };
                path.d = smp.wi;
            })
            .is_some()
        && roulette(path, rng);
    if go_on {
        Flight::Continue(branch)
    } else {
        match branch {
            Some(b) => {
                *path = b;
                Flight::Continue(None)
            }
            None => Flight::End,
        }
    }
}

/// A collision in the air `tc` metres along the path: absorption, the next-event estimate and
/// the new direction; false when the path ends.
fn air_event(
    lidar: &Lidar,
    world: &World,
    shot: &Shot,
    rng: &mut Stream,
    s: &mut Scratch,
    path: &mut Path,
    tc: f64,
) -> bool {
    let atm = world.atmosphere;
    path.p += path.d * tc;
    path.len += tc;
    path.order += 1;
    let (albedo, phase) = atm.at(path.p);
    path.w *= albedo;
    if path.w.is_nan() || path.w <= 0.0 {
        return false;
    }
    let (wr, dist) = shot.towards_receiver(path.p);
    if in_fov(shot, path.p) && world.sees_up(path.p, None, wr, dist) {
        let tr = (-atm.optical_path(path.p, wr, dist)).exp();
        let ratio = shot.r0 / dist;
        let e = path.w * phase.eval(path.d.dot(wr)) * 0.25 * ratio * ratio * tr;
        let t_ns = (path.len + dist - 2.0 * shot.r0) / C_M_PER_NS;
        score(lidar, s, t_ns, e, path.order, FIRST_AIR);
    }
    if path.order >= lidar.max_order {
        return false;
    }
    let mu = phase.sample_cos(rng.next_f64());
    let phi = std::f64::consts::TAU * rng.next_f64();
    path.d = rotate_about(path.d, mu, phi);
    roulette(path, rng)
}

/// Russian roulette once a path has scattered (its next-event estimate made); false when the
/// path ends. It ends most forced-collision branches in thin air at once (their weight is
/// `1 − T`), and dark surfaces' paths, without bias.
#[inline]
fn roulette(path: &mut Path, rng: &mut Stream) -> bool {
    if path.order < 1 || path.w >= RR_WEIGHT {
        return true;
    }
    if rng.next_f64() * RR_WEIGHT < path.w {
        path.w = RR_WEIGHT;
        true
    } else {
        false
    }
}

#[inline]
fn in_fov(shot: &Shot, p: DVec3) -> bool {
    let v = p - shot.sensor;
    v.dot(shot.axis) >= shot.cos_fov * v.length()
}

/// Trace `lidar.spp` photons of shot `k` over `world` (`seed`: the run's).
pub fn trace_shot(lidar: &Lidar, world: &World, seed: u64, k: usize) -> ShotWaveform {
    let shot = Shot::new(lidar, k);
    let nbins = lidar.bins.count;
    let spp = lidar.spp.div_ceil(REPLICATES) * REPLICATES;
    let nblocks = spp.div_ceil(BLOCK);
    let mut acc = Acc::new(nbins);
    // Rounds of blocks: CHUNK at a time, or with a target on the peak 2, 4, … up to CHUNK,
    // checked after each round (the stop depends only on the results: thread-independent).
    let mut next = 0u64;
    let mut round = if lidar.target_rel_stderr.is_some() {
        2
    } else {
        CHUNK as u64
    };
    while next < nblocks {
        let end = (next + round).min(nblocks);
        let parts: Vec<Acc> = (next..end)
            .into_par_iter()
            .map(|b| {
                let mut rng = Stream::new(seed, [LIDAR_STREAM, lidar.index as u64, k as u64, b]);
                let mut a = Acc::new(nbins);
                let mut s = Scratch {
                    cur: vec![0.0; nbins * NCOMP],
                    touched: Vec::new(),
                    tot: [0.0; NCOMP],
                };
                for i in b * BLOCK..(b * BLOCK + BLOCK).min(spp) {
                    let r = i % REPLICATES;
                    let j = i / REPLICATES;
                    let scramble = crate::rng::mix64(
                        seed ^ crate::rng::mix64(
                            (lidar.index as u64) << 40
                                ^ (k as u64) << 8
                                ^ r
                                ^ (j / SOBOL_POINTS) << 48,
                        ),
                    ) as u32;
                    let idx = (j % SOBOL_POINTS) as u32;
                    let u = [
                        f64::from(sobol_burley::sample(idx, 0, scramble)),
                        f64::from(sobol_burley::sample(idx, 1, scramble)),
                        f64::from(sobol_burley::sample(idx, 2, scramble)),
                    ];
                    photon(lidar, world, &shot, u, &mut rng, &mut s);
                    s.flush(&mut a, r as usize);
                }
                a
            })
            .collect();
        for p in &parts {
            acc.merge(p);
        }
        next = end;
        if let Some(t) = lidar.target_rel_stderr {
            if peak_meets(&acc, nbins, (next * BLOCK).min(spp), t) {
                break;
            }
            round = (round * 2).min(CHUNK as u64);
        }
    }
    let spp = (next * BLOCK).min(spp);
    // Replicate r holds spp / R photons.
    let per = (spp / REPLICATES) as f64;
    let bins = (0..nbins)
        .map(|b| std::array::from_fn(|c| spread(&acc.bin_means(nbins, b, c, per))))
        .collect();
    let totals = std::array::from_fn(|c| spread(&acc.total_means(c, per)));
    let metrics = shot_metrics(lidar, &acc, per);
    ShotWaveform {
        photons: acc.n,
        bins,
        totals,
        metrics,
    }
}

/// Whether the waveform's highest bin (all orders) has a relative standard error of at most
/// `target` after `traced` photons (a multiple of [`REPLICATES`]).
fn peak_meets(acc: &Acc, nbins: usize, traced: u64, target: f64) -> bool {
    let per = (traced / REPLICATES) as f64;
    let peak = (0..nbins)
        .map(|b| spread(&acc.bin_means(nbins, b, TOTAL, per)))
        .max_by(|a, b| a.mean.total_cmp(&b.mean));
    peak.is_some_and(|p| p.mean > 0.0 && p.stderr <= target * p.mean)
}

/// The metrics of the shot's mean waveform, and their standard errors from the replicates.
fn shot_metrics(
    lidar: &Lidar,
    acc: &Acc,
    per: f64,
) -> Option<(super::metrics::Metrics, super::metrics::Metrics)> {
    use super::metrics::{metrics, Metrics, Profile};
    let nbins = lidar.bins.count;
    let stride = nbins * NCOMP;
    let heights: Vec<f64> = (0..nbins)
        .map(|k| -0.5 * C_M_PER_NS * lidar.bins.centre_ns(k))
        .collect();
    let w = 0.5 * C_M_PER_NS * lidar.bins.width_ns;
    let (rv, rg) = lidar.cover_rho;
    let reps = REPLICATES as usize;
    // Replicate r's waveform, or (r = None) the mean of all.
    let of = |r: Option<usize>| -> Option<Metrics> {
        let (rs, scale) = match r {
            Some(r) => (r..r + 1, 1.0 / per),
            None => (0..reps, 1.0 / (per * reps as f64)),
        };
        let part = |c: usize| -> Vec<f64> {
            (0..nbins)
                .map(|b| {
                    rs.clone()
                        .map(|r| acc.sum[r * stride + b * NCOMP + c])
                        .sum::<f64>()
                        * scale
                })
                .collect()
        };
        let energy = |c: usize| rs.clone().map(|r| acc.tsum[r * NCOMP + c]).sum::<f64>() * scale;
        let (total, ground) = (part(TOTAL), part(FIRST_GROUND));
        let p = Profile {
            heights: &heights,
            width: w,
            total: &total,
            ground: &ground,
            canopy_energy: energy(FIRST_CANOPY),
            ground_energy: energy(FIRST_GROUND),
        };
        metrics(&p, rv, rg)
    };
    let full = of(None)?;
    let each: Vec<Option<Metrics>> = (0..reps).map(|r| of(Some(r))).collect();
    let err_of = |get: &dyn Fn(&Metrics) -> f64| -> f64 {
        let vals: Option<Vec<f64>> = each.iter().map(|m| m.as_ref().map(get)).collect();
        vals.map_or(f64::NAN, |v| spread(&v).stderr)
    };
    let err = Metrics {
        ground: err_of(&|m| m.ground),
        rh: (0..full.rh.len()).map(|i| err_of(&|m| m.rh[i])).collect(),
        top: err_of(&|m| m.top),
        cover: err_of(&|m| m.cover),
    };
    Some((full, err))
}
