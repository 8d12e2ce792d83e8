//! Lidar: a pulsed laser and a co-located receiver (monostatic), time-resolved returns
//! (waveforms) and photon counting, over the same 1D surfaces, atmospheres and 3D scenes as the
//! passive measures (`[[measures]] type = "lidar"`, docs/experiment.md, "Lidar").
//!
//! **Model.** The laser sits at `S`, `R0 = (altitude − z_c)/cos θ` from the footprint centre
//! `C = (x, y, z_c)` of a shot, and fires a pulse of energy `E_T` along the beam axis `b`
//! (`C − S`, unit). The pulse's energy is spread across the beam in the plane through `C`
//! perpendicular to `b`: Gaussian, `F(r) = exp(−r²/2σ²)/(2πσ²)`, or uniform over a disc. Its
//! time profile is Gaussian (standard deviation `σ_t = FWHM/2.3548`) or a delta. The receiver
//! has an aperture `A_r` at `S` and sees the points within its field of view (a cone of
//! half-angle `fov` about `b`). With `rays = "parallel"` the photons leave the plane through `S`
//! perpendicular to `b` along `b`, and return along `−b` to that plane (the far-field limit:
//! every range is measured along the axis; a point source delays a return from `r` off the
//! axis by `r²/(R0 c)`, 0.2 ns at 500 km for `r` = 5.5 m).
//!
//! **Estimator** (`trace.rs`). Photon paths are traced *from the laser*: each starts at `S`
//! towards a point of the footprint drawn from `F`, and at every scattering vertex `p` (air,
//! leaf, ground, any surface) the energy that reaches the telescope is added by a next-event
//! estimate towards `S`:
//!
//! * surface: `e = w · π f(ω_in, ω_r) |n·ω_r| · (R0/D)² · T(p→S)`,
//! * air:     `e = w · ϖ P(Θ)/4 · (R0/D)² · T(p→S)`,
//!
//! with `w` the path's weight, `D = |S − p|`, `ω_r` the unit vector towards `S`, `P` the phase
//! function (mean 1 over the sphere), `T` the air's transmittance and the scene's visibility
//! along the return line, and `e` the **normalised energy** `E_R / (E_T · A_r / (π R0²))` (a
//! Lambertian plane of reflectance `ρ` seen at normal incidence gives `e = ρ`). A first-order
//! return goes back along the line it came in on, which it has just crossed: its return
//! transmittance through explicit geometry is 1 (the hot spot), found by tracing the return
//! ray rather than assumed; air (point scatterers) attenuates both ways. Every contribution
//! arrives at `t = (L − 2R0)/c`, `L` the true two-way path length, so multiple scattering
//! arrives later. The first flight is split into its uncollided part (weight `T`, on to the
//! first surface) and a forced collision in the air (weight `1 − T`, collision point drawn
//! from `β T`): first-order air returns then have little noise. Later flights are analog, and
//! Russian roulette ends paths of small weight after each scattering, without bias.
//!
//! **Pulse and bins** (`bins.rs`). Each contribution is spread over the time bins by the
//! pulse's exact integral over each bin (Gaussian: `Φ((b − t)/σ_t) − Φ((a − t)/σ_t)`), so the
//! pulse adds no noise. Bins are given in time or in apparent height `z = z_c − c t/2`.
//!
//! **Errors.** One sample is one photon path (both branches of its first flight together).
//! Footprint points (and the forced collision's optical depth) come from 32 independently
//! Owen-scrambled Sobol sequences (`trace.rs`, `REPLICATES`): every bin and total is the mean
//! over the shot's photons, with the standard error from the spread of the 32 replicates'
//! means. Gaussian footprints are sampled from a defensive mixture with bounded weights, so the
//! far tails are sampled too. Photons are traced in fixed blocks on streams keyed by the seed,
//! the measure, the shot and the block, and merged in block order: results do not depend on the
//! thread count.
//!
//! **Photon counting** (`counting.rs`). Detected signal photons per shot are Poisson with mean
//! `n̄ = E_T λ/(h c) · η · e · A_r/(π R0²)`; solar background photons per range gate are Poisson
//! with mean `L_bg · A_r · Ω · Δλ · gate · η · λ/(h c)`, `L_bg` the passive radiance the
//! receiver sees (every order, path radiance included, from the passive estimators).
//!
//! **Air** (`air.rs`): plane-parallel layers or spherical shells (a planet-centred point is the
//! scene's plus `(0, 0, R)`); a 1D ground stays the plane tangent at the origin.
//!
//! **Units.** Inside: m, s (times in ns where named), radians. Config: degrees, nm, ns, J, m².
//!
//! References: Measures, R. M. (1984), *Laser Remote Sensing*, Wiley, ch. 7 (the lidar
//! equation); Gardner, C. S. (1992), IEEE TGRS 30(5), 1061–1072 (slope and footprint broadening
//! of pulses); Hancock et al. (2019), *Earth Space Sci.* 6, 294–310 (GEDI waveform simulator);
//! Neumann et al. (2019), ICESat-2 ATL03 ATBD (photon counting).

pub mod air;
pub mod bins;
pub mod config;
pub mod counting;
pub mod discrete;
pub mod metrics;
pub mod result;
pub mod trace;

use glam::DVec3;

pub use config::LidarConfig;
pub use counting::CountingStats;
pub use result::LidarResult;
pub use trace::{trace_shot, ShotWaveform};

/// Speed of light in vacuum, m/ns.
pub const C_M_PER_NS: f64 = 0.299_792_458;
/// Planck constant, J s.
pub const PLANCK: f64 = 6.626_070_15e-34;
/// Speed of light, m/s.
pub const C_M_PER_S: f64 = 299_792_458.0;

/// What a lidar measure records.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum LidarMode {
    /// Full waveforms (GEDI-like): energy per time bin.
    #[default]
    Waveform,
    /// Detected photons per shot (ICESat-2-like): Poisson statistics and photon events.
    PhotonCounting,
    /// Discrete returns (airborne laser scanning) found on each waveform, as a LAS point cloud.
    Discrete,
}

/// The energy distribution of the pulse across the beam.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Footprint {
    /// Gaussian with this standard deviation per axis, m.
    Gaussian { sigma: f64 },
    /// Uniform over a disc of this radius, m.
    TopHat { radius: f64 },
}

/// Gaussian footprints: the share of points drawn from the footprint itself; the rest come
/// from a Gaussian [`WIDE`] times wider (a defensive mixture, Hesterberg 1995). Weights
/// `F/q ≤ 1/SHARE` stay bounded, while the footprint's tails, which make the far tails of a
/// sloped or off-nadir waveform, get 10⁴–10⁵ times more points than from `F` alone: without
/// them the error of those bins is understated (no replicate sees a tail point).
const SHARE: f64 = 0.85;
const WIDE: f64 = 3.0;

impl Footprint {
    /// A point of the footprint (offsets along two axes perpendicular to the beam, m) from two
    /// uniform numbers, and its weight (the footprint's density over the sampling density).
    #[inline]
    pub fn sample(&self, u1: f64, u2: f64) -> (f64, f64, f64) {
        let phi = std::f64::consts::TAU * u2;
        let (r, w) = match *self {
            Footprint::Gaussian { sigma } => {
                let (u, s) = if u1 < SHARE {
                    (u1 / SHARE, sigma)
                } else {
                    ((u1 - SHARE) / (1.0 - SHARE), WIDE * sigma)
                };
                let r = s * (-2.0 * (1.0 - u).ln()).sqrt();
                // q/F = SHARE + (1 − SHARE)·F_wide/F.
                let x = 0.5 * (r / sigma).powi(2) * (1.0 - 1.0 / (WIDE * WIDE));
                let ratio = SHARE + (1.0 - SHARE) / (WIDE * WIDE) * x.exp();
                (r, 1.0 / ratio)
            }
            Footprint::TopHat { radius } => (radius * u1.sqrt(), 1.0),
        };
        let (s, c) = phi.sin_cos();
        (r * c, r * s, w)
    }
    /// A radius that holds the footprint's energy but for a negligible part (4σ or the disc).
    pub fn extent(&self) -> f64 {
        match *self {
            Footprint::Gaussian { sigma } => 4.0 * sigma,
            Footprint::TopHat { radius } => radius,
        }
    }
}

/// A tilted 1D ground (lidar tests on slopes): the plane through the 1D ground's origin with
/// this unit normal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Slope {
    pub normal: DVec3,
}

/// A resolved lidar measure (SI units; see the module header).
#[derive(Clone, Debug)]
pub struct Lidar {
    pub id: String,
    /// Index of this measure in `[[measures]]` (for streams and messages).
    pub index: usize,
    pub mode: LidarMode,
    /// nm, and its index among the run's wavelengths.
    pub wavelength: f64,
    pub iw: usize,
    /// Platform height above z = 0 of the scene's frame, m.
    pub altitude: f64,
    /// Unit vector from the footprint centre towards the sensor.
    pub to_sensor: DVec3,
    /// View zenith and azimuth of the beam, degrees (for the products).
    pub zenith_deg: f64,
    pub azimuth_deg: f64,
    pub footprint: Footprint,
    /// Standard deviation of the Gaussian pulse, ns (0: a delta pulse).
    pub pulse_sigma_ns: f64,
    pub pulse_energy_j: f64,
    pub receiver_area_m2: f64,
    /// Half-angle of the receiver's field of view, rad.
    pub fov_half_angle: f64,
    pub bins: bins::Bins,
    /// Footprint centres (x, y, z_c) in the local frame, m, and as given (the experiment's
    /// coordinates) for the products.
    pub shots: Vec<DVec3>,
    pub shots_given: Vec<[f64; 2]>,
    /// Parallel rays along the beam axis (the far-field limit: ranges measured along the axis)
    /// instead of a point source and receiver at the sensor.
    pub parallel: bool,
    /// Photon paths per shot (the most, with a target).
    pub spp: u64,
    /// Stop a shot once its waveform's highest bin has this relative standard error.
    pub target_rel_stderr: Option<f64>,
    /// Highest scattering order traced (1: first order only).
    pub max_order: u32,
    /// 1D ground only: a tilted plane.
    pub slope: Option<Slope>,
    /// Photon counting: detector efficiency, dead time (ns), shots simulated per footprint,
    /// the receiver's filter width (nm) and range gate (ns).
    pub efficiency: f64,
    pub dead_time_ns: f64,
    pub shots_per_location: u64,
    pub filter_width_nm: f64,
    pub gate_ns: f64,
    /// Leaf and ground reflectances of the canopy-cover metric (`metrics.rs`).
    pub cover_rho: (f64, f64),
    /// Discrete returns (`discrete.rs`): threshold (fraction of the peak), minimum separation
    /// (ns, two-way), most returns per shot, and the shots' rate (Hz) for the GPS time.
    pub detect_threshold: f64,
    pub min_separation_ns: f64,
    pub max_returns: usize,
    pub pulse_rate_hz: f64,
    /// Discrete returns: LAS classes of scene materials by name (`discrete::class_of`).
    pub las_classes: Vec<(String, u8)>,
}

impl Lidar {
    /// The sensor's position for the shot centred on `c`, m.
    pub fn sensor(&self, c: DVec3) -> DVec3 {
        c + self.to_sensor * self.range0(c)
    }

    /// `R0`: the distance from the sensor to the footprint centre `c`, m.
    pub fn range0(&self, c: DVec3) -> f64 {
        (self.altitude - c.z) / self.to_sensor.z
    }

    /// `A_r / (π R0²)`: normalised energy × this × `E_T` = received energy (J).
    pub fn energy_scale(&self, c: DVec3) -> f64 {
        let r0 = self.range0(c);
        self.receiver_area_m2 / (std::f64::consts::PI * r0 * r0)
    }

    /// Photons of the laser's wavelength per joule.
    pub fn photons_per_joule(&self) -> f64 {
        self.wavelength * 1e-9 / (PLANCK * C_M_PER_S)
    }
}
