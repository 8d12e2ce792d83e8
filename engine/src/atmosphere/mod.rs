//! One-dimensional atmospheres: a stack of layers, each homogeneous inside, built from
//! homogeneous, layered or molecular configurations (Rayleigh air of a thermophysical profile
//! with gas absorption from CKD, monochromatic or cross-section data, and particle layers:
//! [`molecular`], [`particles`], [`thermo`]), used as plane-parallel layers ([`PlaneParallel`])
//! or as spherical shells ([`spherical`]).
//!
//! Optical depth τ is counted **downwards from the top of the atmosphere** (τ = 0 at TOA,
//! τ = τ_total at the ground), in f64. In a plane-parallel medium the radiation field depends on
//! height only, so the integrators move photons in τ: a flight of optical path `s` in direction
//! `d` changes τ by `−s·d_z`. Free paths are therefore sampled analytically and transmittances are
//! exact, whatever the layering (each layer is homogeneous, so τ is linear in altitude inside it).
//!
//! Layer optics per wavelength: scattering optical thickness `tau_sca`, absorption optical
//! thickness `tau_abs` (both vertical, dimensionless) and a phase function. The single-scattering
//! albedo is `tau_sca / (tau_sca + tau_abs)`.

pub mod config;
pub mod emission;
pub mod molecular;
pub mod particles;
pub mod spherical;
pub mod thermo;

use std::path::PathBuf;

use crate::absorption::AbsorptionError;
use crate::phase::PhaseFunction;

/// Why a thermophysical profile (`atmosphere.profile`: embedded AFGL table, joseki netCDF or
/// user CSV; `molecular.rs`, `thermo.rs`) cannot be loaded.
#[derive(Debug, thiserror::Error)]
pub enum ProfileError {
    /// Not one of the embedded profiles (`Profile::builtin`); `known` lists them.
    #[error("unknown profile \"{name}\" (known: {})", .known.join(", "))]
    UnknownBuiltin {
        name: String,
        known: Vec<&'static str>,
    },
    /// Neither an embedded name nor a `.nc` or `.csv` file (`thermo::load`).
    #[error(
        "unknown profile \"{spec}\" (known: {}; or a joseki netCDF `.nc` or a `.csv` table)",
        .known.join(", ")
    )]
    UnknownSpec {
        spec: String,
        known: Vec<&'static str>,
    },
    /// An embedded AFGL table without its species tables.
    #[error("unknown profile \"{name}\"")]
    UnknownEmbedded { name: String },
    /// An AFGL-style table (`Profile::from_csv`) without a header line.
    #[error("empty profile")]
    Empty { name: String },
    #[error("no column `{column}`")]
    NoColumn { name: String, column: String },
    /// `row` counts the header as row 1; `column` is 1-based.
    #[error("row {row}: bad number in column {column}")]
    BadNumber {
        name: String,
        row: usize,
        column: usize,
    },
    #[error("altitudes must increase and number densities be positive")]
    NotIncreasing { name: String },
    /// An embedded table that does not parse (the table's own message).
    #[error("{source}")]
    EmbeddedTable {
        name: String,
        source: thermo::TableError,
    },
    #[error("embedded {name}: no column {column}")]
    EmbeddedColumn { name: String, column: String },
    #[error("embedded {name}: tables 1 and 2a have different levels")]
    EmbeddedLevels { name: String },
    /// A joseki / Eradiate netCDF profile.
    #[error(transparent)]
    Netcdf(AbsorptionError),
    #[error("{}: cannot read: {source}", path.display())]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    /// A user CSV table that is refused.
    #[error("{}: {source}", path.display())]
    UserTable {
        path: PathBuf,
        source: thermo::TableError,
    },
    /// `path`: the profile's path as it records it.
    #[error(
        "{path}: the air number density must be positive at every level (a level has p = 0 or n = 0)"
    )]
    NonPositiveDensity { path: String },
}

/// One homogeneous layer's optics at one wavelength.
#[derive(Clone, Debug)]
pub struct LayerOptics {
    /// Bottom and top altitude, m.
    pub bottom: f64,
    pub top: f64,
    pub tau_sca: f64,
    pub tau_abs: f64,
    pub phase: PhaseFunction,
}

/// A plane-parallel atmosphere at one wavelength, ready for transport.
#[derive(Clone, Debug)]
pub struct PlaneParallel {
    /// Altitudes of the layer boundaries, m, from the top down (len = layers + 1).
    z: Vec<f64>,
    /// τ at those boundaries (from TOA), non-decreasing.
    tau: Vec<f64>,
    /// Per layer, top to bottom.
    albedo: Vec<f64>,
    phase: Vec<PhaseFunction>,
    total_tau: f64,
    /// Thermal source per layer, top to bottom: the Planck radiance at the layer's top and
    /// bottom boundary, in the units of the path tally (`emission.rs`); empty without emission.
    source: Vec<[f64; 2]>,
    /// Runs of consecutive layers with the same albedo and phase function
    /// ([`PlaneParallel::flight_integrals_within`] integrates over a run at once).
    runs: Vec<Run>,
    /// Altitude index for [`PlaneParallel::bottoms_above`]: equal altitude bins from the
    /// ground up, each with the count for its top.
    zgrid: ZGrid,
}

/// Equal altitude bins over the atmosphere, each holding the number of layer bottoms above its
/// top, so that a lookup scans a layer or two instead of a binary search.
#[derive(Clone, Debug, Default)]
pub(crate) struct ZGrid {
    ground: f64,
    inv_h: f64,
    start: Vec<u32>,
}

impl ZGrid {
    /// The grid over the boundaries `z` (top first, descending).
    pub(crate) fn new(z: &[f64]) -> Self {
        let n = z.len() - 1;
        let (toa, ground) = (z[0], z[n]);
        if toa.partial_cmp(&ground) != Some(std::cmp::Ordering::Greater) {
            return ZGrid::default();
        }
        let bins = (8 * n).clamp(16, 4096);
        let h = (toa - ground) / bins as f64;
        let start = (0..bins)
            .map(|k| {
                let top = ground + (k + 1) as f64 * h;
                z[1..].partition_point(|&b| b > top) as u32
            })
            .collect();
        ZGrid {
            ground,
            inv_h: 1.0 / h,
            start,
        }
    }

    /// `z[1..].partition_point(|&b| b > zq)` for the boundaries `z` the grid was made from (the
    /// number of layer bottoms above `zq`): the grid's bin, then a short scan.
    #[inline]
    pub(crate) fn bottoms_above(&self, z: &[f64], zq: f64) -> usize {
        let n = z.len() - 1;
        let mut i = if self.start.is_empty() || !zq.is_finite() {
            return z[1..].partition_point(|&b| b > zq);
        } else {
            let k = ((zq - self.ground) * self.inv_h).max(0.0) as usize;
            self.start[k.min(self.start.len() - 1)] as usize
        };
        // Bottoms z[1..][j] = z[j + 1] descend: move to the first one not above zq.
        while i > 0 && z[i] <= zq {
            i -= 1;
        }
        while i < n && z[i + 1] > zq {
            i += 1;
        }
        i
    }

    /// `z.partition_point(|&b| b > zq)`: boundaries (top included) above `zq`.
    #[inline]
    pub(crate) fn boundaries_above(&self, z: &[f64], zq: f64) -> usize {
        if z[0] > zq {
            1 + self.bottoms_above(z, zq)
        } else {
            0
        }
    }

    /// `z.partition_point(|&b| b >= zq)`: boundaries (top included) at or above `zq`.
    #[inline]
    pub(crate) fn boundaries_at_or_above(&self, z: &[f64], zq: f64) -> usize {
        let mut i = self.boundaries_above(z, zq);
        while i < z.len() && z[i] >= zq {
            i += 1;
        }
        i
    }
}

/// Layers `lo..hi` (top down) with one albedo and phase function; `rep` is the first of them
/// with a non-zero thickness (or `lo`).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Run {
    rep: usize,
    lo: usize,
    hi: usize,
}

/// The runs of layers with equal optics (zero-thickness layers join the run they are in).
fn runs_of(tau: &[f64], albedo: &[f64], phase: &[PhaseFunction]) -> Vec<Run> {
    let mut runs: Vec<Run> = Vec::new();
    for l in 0..albedo.len() {
        let thick = tau[l + 1] > tau[l];
        match runs.last_mut() {
            Some(r) if !thick => r.hi = l + 1,
            Some(r) if tau[r.rep + 1] <= tau[r.rep] => {
                // The run so far has no thickness: this layer gives it its optics.
                r.rep = l;
                r.hi = l + 1;
            }
            Some(r) if albedo[r.rep] == albedo[l] && phase[r.rep] == phase[l] => r.hi = l + 1,
            _ => runs.push(Run {
                rep: l,
                lo: l,
                hi: l + 1,
            }),
        }
    }
    runs
}

impl PlaneParallel {
    /// Build from layers given in any order; they must tile [ground, toa] without gaps or
    /// overlaps (checked by the config resolver, which names the offending layer).
    pub fn new(mut layers: Vec<LayerOptics>, ground: f64, toa: f64) -> Self {
        layers.sort_by(|a, b| b.top.total_cmp(&a.top));
        let mut z = vec![toa];
        let mut tau = vec![0.0];
        let mut albedo = Vec::new();
        let mut phase = Vec::new();
        for l in &layers {
            let ext = l.tau_sca + l.tau_abs;
            z.push(l.bottom);
            tau.push(tau.last().unwrap() + ext);
            albedo.push(if ext > 0.0 { l.tau_sca / ext } else { 1.0 });
            phase.push(l.phase.clone());
        }
        if layers.is_empty() {
            // No atmosphere: one empty layer keeps the indexing uniform.
            z.push(ground);
            tau.push(0.0);
            albedo.push(1.0);
            phase.push(PhaseFunction::Hg(crate::phase::HenyeyGreenstein { g: 0.0 }));
        }
        let total_tau = *tau.last().unwrap();
        Self {
            runs: runs_of(&tau, &albedo, &phase),
            zgrid: ZGrid::new(&z),
            z,
            tau,
            albedo,
            phase,
            total_tau,
            source: Vec::new(),
        }
    }

    /// The same layers and scattering with the absorption optical thickness of layer i (top
    /// down) replaced by `tau_abs[i]` (the reference process of spectral ALIS walks); same
    /// phase functions.
    pub fn with_absorption(&self, tau_abs: &[f64]) -> PlaneParallel {
        assert_eq!(tau_abs.len(), self.albedo.len());
        let mut tau = vec![0.0];
        let mut albedo = Vec::with_capacity(self.albedo.len());
        for (i, a) in self.albedo.iter().enumerate() {
            let sca = (self.tau[i + 1] - self.tau[i]) * a;
            let ext = sca + tau_abs[i];
            tau.push(tau[i] + ext);
            albedo.push(if ext > 0.0 { sca / ext } else { 1.0 });
        }
        let total_tau = *tau.last().unwrap();
        PlaneParallel {
            runs: runs_of(&tau, &albedo, &self.phase),
            zgrid: self.zgrid.clone(),
            z: self.z.clone(),
            tau,
            albedo,
            phase: self.phase.clone(),
            total_tau,
            source: self.source.clone(),
        }
    }

    /// Absorption optical thickness of layer `i`.
    pub fn tau_abs(&self, i: usize) -> f64 {
        (self.tau[i + 1] - self.tau[i]) * (1.0 - self.albedo[i])
    }

    /// Vertical optical thickness of the whole atmosphere.
    #[inline]
    pub fn total_tau(&self) -> f64 {
        self.total_tau
    }

    /// Altitude of the top of the atmosphere and of the ground, m.
    pub fn toa(&self) -> f64 {
        self.z[0]
    }
    pub fn ground(&self) -> f64 {
        *self.z.last().unwrap()
    }

    /// Index of the layer that holds optical depth `tau` (a collision point).
    #[inline]
    pub fn layer_at_tau(&self, tau: f64) -> usize {
        // First boundary strictly below tau... boundaries are tau[0..=n]; the layer i spans
        // [tau[i], tau[i+1]]; pick the one whose span contains tau with non-zero thickness.
        let i = self.tau.partition_point(|&t| t < tau);
        let n = self.albedo.len();
        let mut i = i.clamp(1, n) - 1;
        // Skip zero-thickness layers (no collision can happen in them).
        while i + 1 < n && self.tau[i + 1] <= self.tau[i] {
            i += 1;
        }
        i
    }

    /// Single-scattering albedo of layer `i`.
    #[inline]
    pub fn albedo(&self, i: usize) -> f64 {
        self.albedo[i]
    }

    #[inline]
    pub fn phase(&self, i: usize) -> &PhaseFunction {
        &self.phase[i]
    }

    /// Optical depth from TOA at altitude `z` (m), clamped to the atmosphere.
    pub fn tau_at_altitude(&self, z: f64) -> f64 {
        if z >= self.z[0] {
            return 0.0;
        }
        // The first layer i with z ≥ its bottom z[i+1] (boundaries descend).
        let i = self.bottoms_above(z);
        if i >= self.albedo.len() {
            return self.total_tau;
        }
        let (zt, zb) = (self.z[i], self.z[i + 1]);
        let f = if zt > zb { (zt - z) / (zt - zb) } else { 0.0 };
        self.tau[i] + f * (self.tau[i + 1] - self.tau[i])
    }

    /// Layer boundaries from the top down: (altitude m, optical depth from TOA).
    pub fn boundaries(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        self.z.iter().copied().zip(self.tau.iter().copied())
    }

    /// Distance along a straight ray to its collision, for a sampled optical path `s`.
    ///
    /// The ray starts at altitude `z0` (m) with vertical direction cosine `dz` (> 0 up) and
    /// travels at most `tmax` metres. Layers are homogeneous, so the extinction coefficient
    /// (m⁻¹) is constant inside each and the optical path is exact whatever the direction,
    /// horizontal included. A ray starting above the top or below the bottom enters there
    /// (there is no air outside). Returns the distance of the collision, or `None` when the
    /// ray reaches `tmax` or leaves the atmosphere (through the top, or below the ground)
    /// first.
    /// Used by the 3D walks, whose positions are metres rather than optical depths. Rays with
    /// |dz| ≥ 10⁻³ find the collision by a binary search over the boundaries' optical depths
    /// (the optical path is |Δτ|/|dz| in a plane-parallel atmosphere); flatter rays walk the
    /// layers one by one (|Δτ|/|dz| would lose precision).
    pub fn march(&self, z0: f64, dz: f64, mut s: f64, tmax: f64) -> Option<f64> {
        let n = self.albedo.len();
        let (toa, ground) = (self.z[0], self.z[n]);
        let mut t = 0.0;
        // Enter the atmosphere from above, or from below: a 3D scene may reach under the
        // atmosphere's bottom, where there is no air (the resolver warns), and a ray going up
        // from there meets the air at the bottom (as `optical_path` counts it).
        if z0 >= toa {
            if dz >= 0.0 {
                return None;
            }
            t = (z0 - toa) / -dz;
        } else if z0 < ground {
            if dz <= 0.0 {
                return None;
            }
            t = (ground - z0) / dz;
        }
        if t >= tmax {
            return None;
        }
        let z = (z0 + t * dz).clamp(ground, toa);
        // Not too close to horizontal: the optical path from z is |τ(z) − τ(z')| / |dz|, so the
        // collision is where τ reaches τ(z) ± s·|dz|: a binary search over the boundaries' τ
        // instead of a walk through every layer crossed (τ is linear in z inside a layer).
        if dz.abs() >= 1e-3 {
            let target = self.tau_at_altitude(z) + s * -dz;
            if target.is_nan() || target <= 0.0 || target >= self.total_tau {
                return None;
            }
            // The layer i with τ[i] ≤ target < τ[i+1] (layers without extinction are skipped).
            let i = (self.tau.partition_point(|&x| x <= target).max(1) - 1).min(n - 1);
            let (zt, zb) = (self.z[i], self.z[i + 1]);
            let dtau = self.tau[i + 1] - self.tau[i];
            let zc = if dtau > 0.0 {
                zt - (target - self.tau[i]) / dtau * (zt - zb)
            } else {
                zb
            };
            let tc = t + ((zc - z) / dz).max(0.0);
            return (tc < tmax).then_some(tc);
        }
        // Layer i spans [z[i+1], z[i]]; pick the one holding z (the lower one on a boundary
        // when going down, the upper one when going up).
        let mut i = if dz < 0.0 {
            self.boundaries_above(z).clamp(1, n) - 1
        } else {
            self.z.partition_point(|&b| b >= z).clamp(1, n) - 1
        };
        loop {
            let (zt, zb) = (self.z[i], self.z[i + 1]);
            let zi = z0 + t * dz;
            let to_edge = if dz > 0.0 {
                ((zt - zi) / dz).max(0.0)
            } else if dz < 0.0 {
                ((zi - zb) / -dz).max(0.0)
            } else {
                f64::INFINITY
            };
            let seg = to_edge.min(tmax - t);
            let k = if zt > zb {
                (self.tau[i + 1] - self.tau[i]) / (zt - zb)
            } else {
                0.0
            };
            if k > 0.0 && s <= k * seg {
                return Some(t + s / k);
            }
            s -= k * seg;
            t += seg;
            if t >= tmax || !to_edge.is_finite() {
                return None;
            }
            if dz > 0.0 {
                if i == 0 {
                    return None;
                }
                i -= 1;
            } else {
                if i + 1 >= n {
                    return None;
                }
                i += 1;
            }
        }
    }

    /// Extinction coefficient at altitude `z`, m⁻¹ (0 outside the atmosphere).
    pub fn extinction_at_altitude(&self, z: f64) -> f64 {
        let n = self.albedo.len();
        if n == 0 || z > self.z[0] || z < self.z[n] {
            return 0.0;
        }
        let i = self.layer_at_altitude(z);
        let (zt, zb) = (self.z[i], self.z[i + 1]);
        if zt > zb {
            (self.tau[i + 1] - self.tau[i]) / (zt - zb)
        } else {
            0.0
        }
    }

    /// Optical path (extinction) along the straight ray from altitude `z0` with vertical cosine
    /// `dz` over the distance `t` (m).
    pub fn optical_path(&self, z0: f64, dz: f64, t: f64) -> f64 {
        if dz.abs() > 1e-12 {
            (self.tau_at_altitude(z0) - self.tau_at_altitude(z0 + t * dz)).abs() / dz.abs()
        } else {
            let n = self.albedo.len();
            if z0 >= self.z[0] || z0 < self.z[n] {
                return 0.0;
            }
            let i = self.layer_at_altitude(z0);
            let (zt, zb) = (self.z[i], self.z[i + 1]);
            if zt > zb {
                (self.tau[i + 1] - self.tau[i]) / (zt - zb) * t
            } else {
                0.0
            }
        }
    }

    /// Index of the layer holding altitude `z` (clamped to the atmosphere).
    pub fn layer_at_altitude(&self, z: f64) -> usize {
        let n = self.albedo.len();
        self.boundaries_above(z).clamp(1, n) - 1
    }

    /// The number of layer bottoms above `z` (`z[1..].partition_point(|&b| b > z)`), found from
    /// the altitude grid and a short scan.
    #[inline]
    pub(crate) fn bottoms_above(&self, z: f64) -> usize {
        self.zgrid.bottoms_above(&self.z, z)
    }

    /// `self.z.partition_point(|&b| b > z)`: boundaries (top included) above `z`.
    #[inline]
    fn boundaries_above(&self, z: f64) -> usize {
        self.zgrid.boundaries_above(&self.z, z)
    }

    /// Layer count (including an empty placeholder when there is no atmosphere).
    pub fn layer_count(&self) -> usize {
        self.albedo.len()
    }
}

/// Where a flight ends.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FlightEnd {
    /// Collision at optical depth τ.
    Collision(f64),
    /// Reaches the ground (τ = τ_total).
    Surface,
    /// Leaves through the top.
    Escape,
}

impl PlaneParallel {
    /// End of a flight of optical path `s` (sampled as −ln u) from `tau` along a direction with
    /// vertical cosine `dz` (> 0 upwards).
    #[inline]
    pub fn fly(&self, tau: f64, dz: f64, s: f64) -> FlightEnd {
        if dz.abs() < 1e-12 {
            // Horizontal flight in a plane-parallel layer: collides if the layer is not empty.
            if self.total_tau > 0.0 && tau > 0.0 && tau < self.total_tau {
                return FlightEnd::Collision(tau);
            }
            return if dz >= 0.0 {
                FlightEnd::Escape
            } else {
                FlightEnd::Surface
            };
        }
        let t = tau - s * dz;
        if t <= 0.0 {
            FlightEnd::Escape
        } else if t >= self.total_tau {
            FlightEnd::Surface
        } else {
            FlightEnd::Collision(t)
        }
    }
}

/// `(expm1(x), expm1(x)/x)`, the second continuous at 0.
#[inline]
fn expm1_rel(x: f64) -> (f64, f64) {
    let m = x.exp_m1();
    (m, if x.abs() < 1e-8 { 1.0 + 0.5 * x } else { m / x })
}

impl PlaneParallel {
    /// Expected value, over the next collision of a flight, of `e^{−b·τ_c}` per layer.
    ///
    /// A flight starts at optical depth `tau_a` with vertical direction cosine `dz` (> 0 up); its
    /// collision depth τ_c has density `a·e^{−a|τ−τ_a|}` (a = 1/|dz|) on the path towards the
    /// boundary it is heading to (no collision when it leaves first). For every layer `L` the
    /// flight crosses, `f(L, I_L)` receives `I_L = ∫_L a e^{−a|τ−τ_a|} e^{−bτ} dτ`, so that
    /// `Σ_L g_L·I_L` is the expectation of `g_{L(τ_c)}·e^{−bτ_c}·1{collision}`. With `b = 1/μ_v`
    /// this turns the local estimate at the next collision into its expected value (exact
    /// integration along the flight: no variance from the collision position).
    ///
    /// Consecutive layers with the same albedo and phase function are one *run* (a molecular
    /// atmosphere without absorption is a single run): `f` is called once per run crossed,
    /// with the run's first layer of non-zero thickness and the integral over the whole run, so
    /// `g_L` must depend on the layer only through its albedo and phase function (as every
    /// next-event estimate does). That is one exponential per run instead of two per layer.
    #[inline]
    pub fn flight_integrals(&self, tau_a: f64, dz: f64, b: f64, f: impl FnMut(usize, f64)) {
        self.flight_integrals_within(tau_a, dz, b, 0.0, self.total_tau, f)
    }

    /// [`Self::flight_integrals`] restricted to collisions with optical depth in
    /// `[tau_lo, tau_hi]` (the collision density is still that of the whole flight from
    /// `tau_a`): the 3D walk integrates exactly over the part of a flight above the scene.
    pub fn flight_integrals_within(
        &self,
        tau_a: f64,
        dz: f64,
        b: f64,
        tau_lo: f64,
        tau_hi: f64,
        mut f: impl FnMut(usize, f64),
    ) {
        if self.total_tau <= 0.0 {
            return;
        }
        if dz.abs() < 1e-9 {
            // Horizontal: the collision happens at tau_a (if inside the medium).
            if tau_a > 0.0 && tau_a < self.total_tau && tau_a >= tau_lo && tau_a <= tau_hi {
                f(self.layer_at_tau(tau_a), (-b * tau_a).exp());
            }
            return;
        }
        let a = 1.0 / dz.abs();
        // Runs of layers with equal optics: in optical depth the integrand does not see the
        // boundaries between them, so one integral serves the run. The integrand's value at a
        // run's start comes from the previous run's end when they meet (one `expm1` per run,
        // not an `exp` and an `expm1`: atmospheres with absorption have a run per layer).
        let tau = &self.tau;
        if dz < 0.0 {
            // Downwards: runs from the one holding tau_a to the bottom. e(t) = e^{−a(t−τa)−bt}.
            let k = a + b;
            let mut carried: Option<(f64, f64)> = None; // (t, e(t)) at the last run's end
            for r in &self.runs {
                let (t1, t2) = (tau[r.lo].max(tau_a).max(tau_lo), tau[r.hi].min(tau_hi));
                if t2 <= t1 {
                    continue;
                }
                let d = t2 - t1;
                let e1 = match carried {
                    Some((t, e)) if t == t1 => e,
                    _ => (-a * (t1 - tau_a) - b * t1).exp(),
                };
                let (m, rel) = expm1_rel(-k * d);
                f(r.rep, a * e1 * d * rel);
                carried = Some((t2, e1 * (1.0 + m)));
            }
        } else {
            // Upwards: runs from the one holding tau_a to the top, ∫_{t1}^{t2} a e^{−a(τa−τ)}
            // e^{−bτ} dτ. With a > b the integrand grows with τ: anchored at each run's lower
            // end (t2), carried upwards through the runs in decreasing τ; otherwise at t1.
            let k = a - b;
            let mut carried: Option<(f64, f64)> = None;
            let run = |r: &Run| (tau[r.lo].max(tau_lo), tau[r.hi].min(tau_a).min(tau_hi));
            let mut visit = |r: &Run, f: &mut dyn FnMut(usize, f64)| {
                let (t1, t2) = run(r);
                if t2 <= t1 {
                    return;
                }
                let d = t2 - t1;
                let (anchor, other, x) = if a > b {
                    (t2, t1, -k * d)
                } else {
                    (t1, t2, k * d)
                };
                let e = match carried {
                    Some((t, e)) if t == anchor => e,
                    _ => (-a * (tau_a - anchor) - b * anchor).exp(),
                };
                let (m, rel) = expm1_rel(x);
                f(r.rep, a * e * d * rel);
                carried = Some((other, e * (1.0 + m)));
            };
            if a > b {
                for r in self.runs.iter().rev() {
                    visit(r, &mut f);
                }
            } else {
                for r in &self.runs {
                    visit(r, &mut f);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phase::{PhaseFunction, Rayleigh};

    fn ray() -> PhaseFunction {
        PhaseFunction::Rayleigh(Rayleigh::new(0.0).unwrap())
    }

    /// 0–2 km τ 0.3 + 0.1 absorbing, 2–10 km empty, 10–100 km τ 0.1.
    fn three_layers() -> PlaneParallel {
        let layer = |bottom: f64, top: f64, tau_sca: f64, tau_abs: f64| LayerOptics {
            bottom,
            top,
            tau_sca,
            tau_abs,
            phase: ray(),
        };
        let layers = vec![
            layer(0.0, 2000.0, 0.3, 0.1),
            layer(2000.0, 10_000.0, 0.0, 0.0),
            layer(10_000.0, 100_000.0, 0.1, 0.0),
        ];
        PlaneParallel::new(layers, 0.0, 100_000.0)
    }

    #[test]
    fn layering_and_lookup() {
        let a = three_layers();
        assert!((a.total_tau() - 0.5).abs() < 1e-15);
        assert_eq!(a.layer_at_tau(0.05), 0);
        // τ = 0.1 is the boundary with the empty layer: the collision belongs to a real layer.
        assert_eq!(a.layer_at_tau(0.2), 2);
        assert!((a.albedo(2) - 0.75).abs() < 1e-15);
        assert!((a.tau_at_altitude(55_000.0) - 0.05).abs() < 1e-12);
        assert!((a.tau_at_altitude(5_000.0) - 0.1).abs() < 1e-12);
        assert!((a.tau_at_altitude(1_000.0) - 0.3).abs() < 1e-12);
        assert_eq!(a.fly(0.1, -0.5, 1.0), FlightEnd::Surface);
        assert_eq!(a.fly(0.1, 0.5, 1.0), FlightEnd::Escape);
        assert_eq!(a.fly(0.1, -0.5, 0.2), FlightEnd::Collision(0.2));
    }

    /// The altitude grid gives the binary search's answers, on and between boundaries, outside
    /// the atmosphere and with zero-thickness layers.
    #[test]
    fn altitude_grid_matches_binary_search() {
        let layer = |bottom: f64, top: f64| LayerOptics {
            bottom,
            top,
            tau_sca: 0.01,
            tau_abs: 0.0,
            phase: ray(),
        };
        let mut edges = vec![
            0.0, 7.0, 1000.0, 1000.5, 2000.0, 2500.0, 30_000.0, 100_000.0,
        ];
        edges.sort_by(f64::total_cmp);
        let layers: Vec<LayerOptics> = edges.windows(2).map(|w| layer(w[0], w[1])).collect();
        let atm = PlaneParallel::new(layers, 0.0, 100_000.0);
        let mut rng = crate::rng::Stream::new(5, [0, 0, 0, 0]);
        let mut zs: Vec<f64> = edges.clone();
        zs.extend(
            edges
                .iter()
                .flat_map(|&e| [e * (1.0 + 1e-15), e * (1.0 - 1e-15), e + 1e-9]),
        );
        zs.extend((0..20_000).map(|_| 110_000.0 * rng.next_f64() - 5_000.0));
        zs.extend([f64::INFINITY, f64::NEG_INFINITY, -1e300, 1e300]);
        for z in zs {
            let want = atm.z[1..].partition_point(|&b| b > z);
            assert_eq!(atm.bottoms_above(z), want, "z = {z}");
            assert_eq!(
                atm.boundaries_above(z),
                atm.z.partition_point(|&b| b > z),
                "z = {z}"
            );
            assert_eq!(
                atm.zgrid.boundaries_at_or_above(&atm.z, z),
                atm.z.partition_point(|&b| b >= z),
                "z = {z}"
            );
        }
    }

    /// Runs merge equal neighbours only; zero-thickness layers join a run.
    #[test]
    fn runs_merge_equal_layers() {
        let run = |rep, lo, hi| Run { rep, lo, hi };
        let atm = three_layers();
        // Top down: 10–100 km (albedo 1), 2–10 km empty (joins it), 0–2 km (albedo 0.75).
        assert_eq!(atm.runs, vec![run(0, 0, 2), run(2, 2, 3)]);
        // Two equal layers merge; a different phase function does not.
        let rayleigh = |bottom: f64, top: f64| LayerOptics {
            bottom,
            top,
            tau_sca: 0.1,
            tau_abs: 0.0,
            phase: ray(),
        };
        let hg = LayerOptics {
            phase: PhaseFunction::Hg(crate::phase::HenyeyGreenstein { g: 0.7 }),
            ..rayleigh(0.0, 1000.0)
        };
        let atm = PlaneParallel::new(
            vec![hg, rayleigh(1000.0, 2000.0), rayleigh(2000.0, 3000.0)],
            0.0,
            3000.0,
        );
        assert_eq!(atm.runs, vec![run(0, 0, 2), run(2, 2, 3)]);
    }

    /// `flight_integrals` against direct quadrature of its defining integral, both directions,
    /// across layers, including a = b (upward flight with b = 1/dz).
    #[test]
    fn flight_integrals_match_quadrature() {
        let atm = three_layers();
        for &(tau_a, dz, b) in &[
            (0.0, -0.7, 2.0),
            (0.05, -0.3, 1.2),
            (0.5, 0.6, 1.0 / 0.6),
            (0.3, 0.2, 3.0),
            (0.45, 0.9, 1.1),
        ] {
            let mut got = [0.0; 3];
            atm.flight_integrals(tau_a, dz, b, |l, i| got[l] += i);
            let a = 1.0 / f64::abs(dz);
            let mut want = [0.0; 3];
            let n = 200_000;
            let (lo, hi) = if dz < 0.0 { (tau_a, 0.5) } else { (0.0, tau_a) };
            for k in 0..n {
                let t = lo + (hi - lo) * (k as f64 + 0.5) / n as f64;
                let l = atm.layer_at_tau(t);
                want[l] += a * (-a * (t - tau_a).abs() - b * t).exp() * (hi - lo) / n as f64;
            }
            for l in 0..3 {
                assert!(
                    (got[l] - want[l]).abs() < 2e-5,
                    "tau_a {tau_a} dz {dz} layer {l}: {} vs {}",
                    got[l],
                    want[l]
                );
            }
        }
    }

    /// The empty atmosphere: every downward flight reaches the ground.
    #[test]
    fn no_atmosphere() {
        let a = PlaneParallel::new(vec![], 0.0, 100_000.0);
        assert_eq!(a.total_tau(), 0.0);
        assert_eq!(a.fly(0.0, -0.3, 0.001), FlightEnd::Surface);
    }
    /// `march` (metres) agrees with `fly` (optical depth): the optical depth between start and
    /// collision equals s·|dz|, layer crossings included, on both of its paths; rays from
    /// below the ground going up enter there; horizontal rays collide at s/k; `tmax` and
    /// leaving the atmosphere give `None`.
    #[test]
    fn march_agrees_with_fly() {
        let atm = three_layers();
        let mut rng = crate::rng::Stream::new(3, [0, 0, 0, 0]);
        for k in 0..4000 {
            let z0 = 120_000.0 * rng.next_f64() - 1_000.0;
            // Every fourth ray close to horizontal (the layer-by-layer path, |dz| < 10⁻³), the
            // others through the binary search on τ, near its 10⁻³ switch included.
            let dz = match k % 4 {
                0 => 2e-3 * (rng.next_f64() - 0.5),
                1 => 4e-3 * (rng.next_f64() - 0.5),
                _ => 2.0 * rng.next_f64() - 1.0,
            };
            let s = -rng.next_f64_open0().ln();
            let tau0 = atm.tau_at_altitude(z0);
            // Below the ground (a scene reaching under it) only upward rays enter the air.
            let expect = if z0 < atm.ground() && dz <= 0.0 {
                None
            } else {
                match atm.fly(tau0, dz, s) {
                    FlightEnd::Collision(t) => Some(t),
                    _ => None,
                }
            };
            match (atm.march(z0, dz, s, f64::INFINITY), expect) {
                (Some(t), Some(tau_c)) => {
                    let zc = z0 + t * dz;
                    let got = atm.tau_at_altitude(zc);
                    assert!(
                        (got - tau_c).abs() < 1e-9 * (1.0 + tau_c),
                        "{got} vs {tau_c}"
                    );
                    // A shorter tmax stops it.
                    assert_eq!(atm.march(z0, dz, s, 0.999 * t), None);
                }
                (None, None) => {}
                (a, b) => panic!("march {a:?} vs fly {b:?} (z0 {z0}, dz {dz}, s {s})"),
            }
        }
        // Horizontal at 1 km: layer 0-2 km has k = 0.4 / 2000 m.
        let t = atm.march(1_000.0, 0.0, 0.2, f64::INFINITY).unwrap();
        assert!((t - 0.2 / (0.4 / 2_000.0)).abs() < 1e-6, "{t}");
        // Horizontal in the empty layer: never.
        assert_eq!(atm.march(5_000.0, 0.0, 0.2, f64::INFINITY), None);
    }
}
