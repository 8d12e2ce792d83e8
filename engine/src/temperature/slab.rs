//! One-dimensional heat conduction through a layered slab under a surface energy balance: the
//! model of a surface's kinetic temperature through a diurnal cycle.
//!
//! **Model.** `ρc ∂T/∂t = ∂/∂z (k ∂T/∂z)`, z downwards from the surface, through layers of
//! thickness `L` (m), conductivity `k` (W m⁻¹ K⁻¹), density `ρ` (kg m⁻³) and specific heat `c`
//! (J kg⁻¹ K⁻¹). At the surface the net flux into the slab is `F(T_s, t)` (W m⁻², given by the
//! caller: absorbed sunlight and sky light, absorbed longwave, emission, convection;
//! `balance.rs`); at the bottom either no flux (adiabatic) or a fixed temperature.
//!
//! **Discretisation.** Nodes at the surface, at every layer interface and between them, spaced
//! geometrically (finest at the surface, where the diurnal wave is steepest), so each segment
//! between two nodes lies in one layer. Finite volumes around the nodes: node `i` holds the heat
//! capacity of the half segments beside it, `C_i = Σ ρc·h/2` (J m⁻² K⁻¹), and segment `j`
//! conducts `G_j = k_j/h_j` (W m⁻² K⁻¹). The θ-scheme in time (`θ = 1`, backward Euler, by
//! default: unconditionally free of the oscillations Crank–Nicolson (`θ = ½`) shows at the thin
//! surface nodes when the forcing jumps, e.g. at a shadow's edge), the surface flux linearised
//! and iterated (Newton) to `NEWTON_TOL` K; each step eliminates the tridiagonal system from
//! the bottom up to one equation in the surface temperature ([`Slab::step`]).
//!
//! **Energy.** The scheme is conservative: over any run the heat stored
//! (`Σ C_i ΔT_i`) equals the θ-weighted surface and bottom fluxes times the steps, to the Newton
//! tolerance; [`Slab::step`] returns both sides so callers (and tests) can close the budget.
//!
//! **Reference.** The periodic steady state under sinusoidal surface forcing of a homogeneous
//! half-space (Carslaw & Jaeger 1959, §2.6): a surface temperature `T̄ + A sin ωt` reaches depth
//! `z` as `A e^{−z/d} sin(ωt − z/d)`, `d = √(2κ/ω)`, `κ = k/(ρc)`; a surface flux
//! `G₀ sin ωt` gives `T_s = T̄ + G₀d/(k√2) · sin(ωt − π/4)`. Tests below.

/// One homogeneous layer of a slab (SI units).
#[derive(Clone, Copy, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct Layer {
    /// m.
    pub thickness_m: f64,
    /// W m⁻¹ K⁻¹.
    pub conductivity: f64,
    /// kg m⁻³.
    pub density: f64,
    /// J kg⁻¹ K⁻¹.
    pub heat_capacity: f64,
}

impl Layer {
    /// Thermal diffusivity κ = k/(ρc), m² s⁻¹.
    pub fn diffusivity(&self) -> f64 {
        self.conductivity / (self.density * self.heat_capacity)
    }
}

/// What holds the slab's bottom.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Bottom {
    /// No heat crosses it.
    Adiabatic,
    /// A fixed temperature, K.
    Fixed(f64),
}

/// Newton iterations on the surface flux stop when the surface temperature moves less than this
/// (K).
pub const NEWTON_TOL: f64 = 1e-9;
const NEWTON_MAX: usize = 50;

/// A discretised slab and its temperatures.
#[derive(Clone, Debug)]
pub struct Slab {
    /// Node depths, m (node 0 at the surface).
    pub depth: Vec<f64>,
    /// Heat capacity per node, J m⁻² K⁻¹.
    capacity: Vec<f64>,
    /// Conductance of the segment below each node, W m⁻² K⁻¹ (one fewer than nodes).
    conductance: Vec<f64>,
    bottom: Bottom,
    /// Time weighting (1: backward Euler, ½: Crank–Nicolson).
    pub theta: f64,
    /// Node temperatures, K.
    pub t: Vec<f64>,
    /// The surface flux at the last state (W m⁻²), for the θ-scheme's explicit part.
    last_flux: Option<f64>,
    /// The implicit system's elimination for the last step length.
    elim: Elimination,
    /// The surface cannot warm past this (K): the heat beyond it melts (snow, ice; an
    /// unlimited supply that stays at its melting point).
    pub melting_point: Option<f64>,
}

/// Heat budget of one step (J m⁻²): what the surface and the bottom let in, and what the slab
/// stored.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Budget {
    pub surface_in: f64,
    pub bottom_in: f64,
    pub stored: f64,
    /// Heat spent melting at the surface (a slab with a melting point), J m⁻²: stored =
    /// surface_in + bottom_in − melted.
    pub melted: f64,
}

impl std::ops::AddAssign for Budget {
    fn add_assign(&mut self, o: Budget) {
        self.surface_in += o.surface_in;
        self.bottom_in += o.bottom_in;
        self.stored += o.stored;
        self.melted += o.melted;
    }
}

/// Why a slab cannot be built.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SlabError {
    #[error("a slab needs at least one layer")]
    NoLayers,
    #[error("layer {layer}: {what} must be a positive finite number (got {value})")]
    BadLayer {
        layer: usize,
        what: &'static str,
        value: f64,
    },
    #[error("the first node's thickness must be positive and finite (got {0} m)")]
    BadSpacing(f64),
    #[error("the initial temperature must be positive and finite (got {0} K)")]
    BadTemperature(f64),
}

impl Slab {
    /// A slab of `layers` at the uniform temperature `t0` (K), its first node `first_m` thick
    /// and each next one `growth` times thicker (capped so a layer holds at least two
    /// segments), `bottom` held as given.
    pub fn new(
        layers: &[Layer],
        first_m: f64,
        growth: f64,
        bottom: Bottom,
        t0: f64,
    ) -> Result<Slab, SlabError> {
        if layers.is_empty() {
            return Err(SlabError::NoLayers);
        }
        for (i, l) in layers.iter().enumerate() {
            for (what, value) in [
                ("thickness_m", l.thickness_m),
                ("conductivity", l.conductivity),
                ("density", l.density),
                ("heat_capacity", l.heat_capacity),
            ] {
                if !(value.is_finite() && value > 0.0) {
                    return Err(SlabError::BadLayer {
                        layer: i,
                        what,
                        value,
                    });
                }
            }
        }
        if !(first_m.is_finite() && first_m > 0.0) {
            return Err(SlabError::BadSpacing(first_m));
        }
        if !(t0.is_finite() && t0 > 0.0) {
            return Err(SlabError::BadTemperature(t0));
        }
        let growth = growth.max(1.0);
        let mut depth = vec![0.0];
        let mut seg_layer = Vec::new();
        let mut h = first_m;
        let mut top = 0.0;
        for (i, l) in layers.iter().enumerate() {
            let bottom_z = top + l.thickness_m;
            // Segments of size h growing, at least two per layer, ending on the interface.
            let mut z = top;
            let n_min: usize = 2;
            let mut count = 0;
            while bottom_z - z > 1e-12 {
                let left = bottom_z - z;
                let mut step = h.min(left / n_min.saturating_sub(count).max(1) as f64);
                if left - step < 0.5 * step {
                    step = left;
                }
                z += step;
                depth.push(z.min(bottom_z));
                seg_layer.push(i);
                count += 1;
                h *= growth;
            }
            top = bottom_z;
        }
        let n = depth.len();
        let mut capacity = vec![0.0; n];
        let mut conductance = Vec::with_capacity(n - 1);
        for j in 0..n - 1 {
            let l = &layers[seg_layer[j]];
            let hj = depth[j + 1] - depth[j];
            let half = 0.5 * l.density * l.heat_capacity * hj;
            capacity[j] += half;
            capacity[j + 1] += half;
            conductance.push(l.conductivity / hj);
        }
        let mut t = vec![t0; n];
        if let Bottom::Fixed(tb) = bottom {
            t[n - 1] = tb;
        }
        Ok(Slab {
            depth,
            capacity,
            conductance,
            bottom,
            theta: 1.0,
            t,
            last_flux: None,
            elim: Elimination {
                dt: f64::NAN,
                ..Default::default()
            },
            melting_point: None,
        })
    }

    /// The surface temperature, K.
    pub fn surface(&self) -> f64 {
        self.t[0]
    }

    /// Set every node (but a fixed bottom) to `t` (K).
    pub fn fill(&mut self, t: f64) {
        let n = self.t.len();
        for (i, v) in self.t.iter_mut().enumerate() {
            if !(i == n - 1 && matches!(self.bottom, Bottom::Fixed(_))) {
                *v = t;
            }
        }
        self.last_flux = None;
    }

    /// Heat held above the bottom, J m⁻² (relative to 0 K; differences are what matter).
    pub fn heat(&self) -> f64 {
        self.capacity
            .iter()
            .zip(&self.t)
            .take(self.free_nodes())
            .map(|(c, t)| c * t)
            .sum()
    }

    fn free_nodes(&self) -> usize {
        match self.bottom {
            Bottom::Adiabatic => self.t.len(),
            Bottom::Fixed(_) => self.t.len() - 1,
        }
    }

    /// Flux into the slab's free nodes through the bottom (W m⁻²) at temperatures `t`.
    fn bottom_flux(&self, t: &[f64]) -> f64 {
        match self.bottom {
            Bottom::Adiabatic => 0.0,
            Bottom::Fixed(tb) => {
                let n = t.len();
                self.conductance[n - 2] * (tb - t[n - 2])
            }
        }
    }

    /// Advance by `dt` seconds. `flux(T_s)` returns the net surface flux into the slab at the
    /// step's end (W m⁻²) and its derivative dF/dT_s (W m⁻² K⁻¹, normally ≤ 0); the θ-scheme
    /// weights it with the flux at the step's start (the last step's end value, or `flux` at
    /// the current surface temperature on the first step). Returns the step's heat budget.
    ///
    /// The implicit system is tridiagonal and only its first row holds the nonlinear flux, so
    /// it is eliminated from the bottom up (`T_i = a_i + b_i·T_{i−1}`; the `b_i` depend on `dt`
    /// only and are kept) down to one equation in the surface temperature, which Newton solves;
    /// the other nodes follow by substitution. One sweep each way per step, however many Newton
    /// iterations.
    pub fn step(&mut self, dt: f64, flux: impl Fn(f64) -> (f64, f64)) -> Budget {
        let n = self.t.len();
        let m = self.free_nodes();
        let th = self.theta;
        if self.elim.dt != dt || self.elim.theta != th {
            self.prepare(dt);
        }
        let f_old = self.last_flux.unwrap_or_else(|| flux(self.t[0]).0);
        let fb_old = self.bottom_flux(&self.t);
        let g = &self.conductance;
        let c = &self.capacity;
        let t = &self.t;
        // Right-hand side: C/dt·T + (1−θ)·R(T_old) (+ θ·G·T_b beside a fixed bottom), and the
        // upward elimination's a_i in one sweep from the bottom.
        let rhs = |i: usize| {
            let mut r = 0.0;
            if i > 0 {
                r += g[i - 1] * (t[i - 1] - t[i]);
            }
            if i + 1 < n {
                r += g[i] * (t[i + 1] - t[i]);
            }
            if i == 0 {
                r += f_old;
            }
            let mut v = c[i] / dt * t[i] + (1.0 - th) * r;
            if i + 1 == m {
                if let Bottom::Fixed(tb) = self.bottom {
                    v += th * g[i] * tb;
                }
            }
            v
        };
        let elim = &mut self.elim;
        // a[i] for i ≥ 1 (a[m] = 0 beyond the last free node).
        let mut a_next = 0.0;
        for i in (1..m).rev() {
            let upper = if i + 1 < m { -th * g[i] } else { 0.0 };
            let a = (rhs(i) - upper * a_next) / elim.den[i];
            elim.a[i] = a;
            a_next = a;
        }
        // Row 0: D·T0 − R = θ·F(T0).
        let (d0, r0) = if m > 1 {
            let upper = -th * g[0];
            (elim.den[0], rhs(0) - upper * elim.a[1])
        } else {
            (elim.den[0], rhs(0))
        };
        let mut ts = t[0];
        for _ in 0..NEWTON_MAX {
            let (f, df) = flux(ts);
            let next = (r0 + th * (f - df * ts)) / (d0 - th * df);
            let moved = (next - ts).abs();
            ts = next;
            if moved < NEWTON_TOL {
                break;
            }
        }
        let mut f_new = flux(ts).0;
        // Held at the melting point: row 0 then balances with a melt flux M taken out,
        // D·T_m − R = θ·(F(T_m) − M).
        let mut melted = 0.0;
        if let Some(tm) = self.melting_point {
            if ts > tm {
                ts = tm;
                f_new = flux(ts).0;
                let melt = f_new - (d0 * ts - r0) / th;
                melted = dt * th * melt;
                f_new -= melt;
            }
        }
        let mut stored = c[0] * (ts - t[0]);
        let mut prev = ts;
        self.t[0] = ts;
        for i in 1..m {
            let v = self.elim.a[i] + self.elim.b[i] * prev;
            stored += self.capacity[i] * (v - self.t[i]);
            self.t[i] = v;
            prev = v;
        }
        self.last_flux = Some(f_new);
        let fb_new = self.bottom_flux(&self.t);
        Budget {
            surface_in: dt * (th * f_new + (1.0 - th) * f_old) + melted,
            bottom_in: dt * (th * fb_new + (1.0 - th) * fb_old),
            stored,
            melted,
        }
    }

    /// The elimination's `b_i` and pivots for step `dt` (they depend on the matrix only).
    fn prepare(&mut self, dt: f64) {
        let n = self.t.len();
        let m = self.free_nodes();
        let th = self.theta;
        let g = &self.conductance;
        let mut den = vec![0.0; m];
        let mut b = vec![0.0; m];
        let mut b_next = 0.0;
        for i in (0..m).rev() {
            let mut diag = self.capacity[i] / dt;
            if i > 0 {
                diag += th * g[i - 1];
            }
            if i + 1 < n {
                diag += th * g[i];
            }
            let upper = if i + 1 < m { -th * g[i] } else { 0.0 };
            den[i] = diag + upper * b_next;
            let lower = if i > 0 { -th * g[i - 1] } else { 0.0 };
            b[i] = -lower / den[i];
            b_next = b[i];
        }
        self.elim = Elimination {
            dt,
            theta: th,
            den,
            b,
            a: vec![0.0; m],
        };
    }
}

/// The bottom-up elimination of the implicit system for one step length.
#[derive(Clone, Debug, Default)]
struct Elimination {
    dt: f64,
    theta: f64,
    /// Pivots: row i reads den_i·T_i = (rhs_i − upper_i·a_{i+1}) − lower_i·T_{i−1}.
    den: Vec<f64>,
    /// T_i = a_i + b_i·T_{i−1}.
    b: Vec<f64>,
    a: Vec<f64>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{PI, TAU};

    const DAY: f64 = 86_400.0;

    /// 5 cm of asphalt.
    fn asphalt() -> Layer {
        Layer {
            thickness_m: 0.05,
            conductivity: 0.75,
            density: 2360.0,
            heat_capacity: 920.0,
        }
    }

    fn soil() -> Layer {
        Layer {
            thickness_m: 1.0,
            conductivity: 1.0,
            density: 2000.0,
            heat_capacity: 1000.0,
        }
    }

    /// Amplitude and phase of the day-periodic signal `v` sampled at `n` equal steps (first
    /// Fourier harmonic), as `v ≈ mean + a sin(ωt + φ)`.
    fn harmonic(v: &[f64]) -> (f64, f64, f64) {
        let n = v.len() as f64;
        let mean = v.iter().sum::<f64>() / n;
        let (mut s, mut c) = (0.0, 0.0);
        for (i, x) in v.iter().enumerate() {
            let wt = TAU * (i + 1) as f64 / n;
            s += (x - mean) * wt.sin();
            c += (x - mean) * wt.cos();
        }
        let (s, c) = (2.0 * s / n, 2.0 * c / n);
        (mean, s.hypot(c), c.atan2(s))
    }

    /// Run `days` days of `steps` steps under `flux(t, T_s)`; returns the last day's node
    /// temperatures at each step's end and the last day's budget.
    /// Set `slab` on the half-space's periodic answer to the surface flux `g0 sin ωt` at t = 0.
    fn start_on_flux_wave(slab: &mut Slab, g0: f64, l: &Layer) {
        let d = (2.0 * l.diffusivity() / (TAU / DAY)).sqrt();
        let a = g0 * d / (l.conductivity * 2f64.sqrt());
        for (t, z) in slab.t.iter_mut().zip(&slab.depth) {
            *t = 290.0 + a * (-z / d).exp() * (-z / d - PI / 4.0).sin();
        }
    }

    fn run(
        slab: &mut Slab,
        days: usize,
        steps: usize,
        flux: impl Fn(f64, f64) -> (f64, f64),
    ) -> (Vec<Vec<f64>>, Budget) {
        let dt = DAY / steps as f64;
        let mut last = Vec::new();
        let mut budget = Budget::default();
        for day in 0..days {
            for k in 0..steps {
                let t_end = (k + 1) as f64 * dt;
                let b = slab.step(dt, |ts| flux(t_end, ts));
                if day + 1 == days {
                    last.push(slab.t.clone());
                    budget += b;
                }
            }
        }
        (last, budget)
    }

    fn node_near(slab: &Slab, z: f64) -> usize {
        (0..slab.depth.len())
            .min_by(|&a, &b| {
                (slab.depth[a] - z)
                    .abs()
                    .total_cmp(&(slab.depth[b] - z).abs())
            })
            .unwrap()
    }

    #[test]
    fn surface_temperature_wave_damps_and_lags_as_carslaw_and_jaeger() {
        // A surface held at T̄ + A sin ωt (a stiff convective coupling to that air
        // temperature): depth z sees A e^{−z/d} with a lag z/d.
        let l = soil();
        let omega = TAU / DAY;
        let d = (2.0 * l.diffusivity() / omega).sqrt();
        let mut slab = Slab::new(&[l], 0.002, 1.08, Bottom::Adiabatic, 290.0).unwrap();
        let (a, h) = (10.0, 1e6);
        // Start on the periodic solution (a start at rest adds a slowly decaying transient).
        for (t, z) in slab.t.iter_mut().zip(&slab.depth) {
            *t = 290.0 + a * (-z / d).exp() * (-z / d).sin();
        }
        let (days, steps) = (6, 1440);
        let (temps, _) = run(&mut slab, days, steps, |t, ts| {
            (h * (290.0 + a * (omega * t).sin() - ts), -h)
        });
        for z in [0.0, 0.5 * d, d, 2.0 * d] {
            let i = node_near(&slab, z);
            let zi = slab.depth[i];
            let series: Vec<f64> = temps.iter().map(|t| t[i]).collect();
            let (mean, amp, phase) = harmonic(&series);
            let want_amp = a * (-zi / d).exp();
            let want_phase = -zi / d;
            assert!((mean - 290.0).abs() < 0.01, "z {zi}: mean {mean}");
            assert!(
                (amp / want_amp - 1.0).abs() < 0.01,
                "z {zi} m (d {d} m): amplitude {amp} vs {want_amp}"
            );
            let dphi = (phase - want_phase + PI).rem_euclid(TAU) - PI;
            assert!(dphi.abs() < 0.01, "z {zi}: phase {phase} vs {want_phase}");
        }
    }

    #[test]
    fn surface_flux_wave_gives_the_half_space_amplitude_and_an_eighth_cycle_lag() {
        let l = soil();
        let omega = TAU / DAY;
        let d = (2.0 * l.diffusivity() / omega).sqrt();
        let g0 = 200.0;
        let mut slab = Slab::new(&[l], 0.002, 1.08, Bottom::Adiabatic, 290.0).unwrap();
        start_on_flux_wave(&mut slab, g0, &l);
        let (temps, budget) = run(&mut slab, 6, 1440, |t, _| (g0 * (omega * t).sin(), 0.0));
        let series: Vec<f64> = temps.iter().map(|t| t[0]).collect();
        let (_, amp, phase) = harmonic(&series);
        let want = g0 * d / (l.conductivity * 2f64.sqrt());
        assert!((amp / want - 1.0).abs() < 0.01, "{amp} vs {want}");
        assert!((phase + PI / 4.0).abs() < 0.01, "phase {phase}");
        // Energy: what came in is what was stored (adiabatic bottom), to rounding.
        let scale = g0 * DAY / PI;
        assert!(
            (budget.surface_in + budget.bottom_in - budget.stored).abs() < 1e-9 * scale,
            "{budget:?}"
        );
    }

    #[test]
    fn heat_budget_closes_over_a_cycle_with_a_fixed_bottom_and_radiative_loss() {
        // A layered slab (asphalt on gravel on soil), a nonlinear surface flux (sunlight,
        // emission, convection) and a fixed deep temperature: stored = in, step by step.
        let layers = [
            asphalt(),
            Layer {
                thickness_m: 0.2,
                conductivity: 1.2,
                density: 2000.0,
                heat_capacity: 850.0,
            },
            soil(),
        ];
        let omega = TAU / DAY;
        for theta in [1.0, 0.5] {
            let mut slab = Slab::new(&layers, 0.002, 1.15, Bottom::Fixed(288.0), 288.0).unwrap();
            slab.theta = theta;
            let sigma = 5.670_374_419e-8;
            let (_, b) = run(&mut slab, 3, 144, |t, ts| {
                let sun = (800.0 * (omega * t - PI / 2.0).sin()).max(0.0);
                let f = 0.9 * sun + 0.95 * 320.0 - 0.95 * sigma * ts.powi(4) - 10.0 * (ts - 293.0);
                (f, -4.0 * 0.95 * sigma * ts.powi(3) - 10.0)
            });
            let throughput = b.surface_in.abs() + b.bottom_in.abs() + 1.0;
            let gap = (b.surface_in + b.bottom_in - b.stored).abs();
            assert!(gap < 1e-6 * throughput, "θ {theta}: {b:?}");
        }
    }

    #[test]
    fn steady_state_matches_the_series_resistance_balance() {
        // Constant forcing, fixed bottom: the slab relaxes to the temperature where the
        // surface balance equals the conduction (T_s − T_b)/Σ(L/k). Two absorbed irradiances
        // (a sunlit and a shaded facet) differ by exactly what that balance predicts.
        let layers = [asphalt(), soil()];
        let r: f64 = layers.iter().map(|l| l.thickness_m / l.conductivity).sum();
        let (tb, ta, h, eps, sky) = (285.0, 295.0, 12.0, 0.95, 330.0);
        let sigma = 5.670_374_419e-8;
        let balance = |s: f64, ts: f64| {
            s + eps * sky - eps * sigma * ts.powi(4) - h * (ts - ta) - (ts - tb) / r
        };
        let exact = |s: f64| {
            let (mut lo, mut hi) = (200.0, 400.0);
            for _ in 0..200 {
                let mid = 0.5 * (lo + hi);
                if balance(s, mid) > 0.0 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            0.5 * (lo + hi)
        };
        let mut got = Vec::new();
        for s in [600.0, 80.0] {
            let mut slab = Slab::new(&layers, 0.005, 1.2, Bottom::Fixed(tb), 290.0).unwrap();
            for _ in 0..40 * 24 {
                slab.step(3600.0, |ts| {
                    (
                        s + eps * sky - eps * sigma * ts.powi(4) - h * (ts - ta),
                        -4.0 * eps * sigma * ts.powi(3) - h,
                    )
                });
            }
            let want = exact(s);
            assert!(
                (slab.surface() - want).abs() < 1e-4,
                "{s} W m-2: {} vs {want}",
                slab.surface()
            );
            got.push(slab.surface());
        }
        let predicted = exact(600.0) - exact(80.0);
        assert!(((got[0] - got[1]) - predicted).abs() < 2e-4);
        assert!(predicted > 5.0, "sunlit − shaded {predicted} K");
    }

    #[test]
    fn converges_in_time_step_and_node_count() {
        // The surface-flux wave's error (amplitude and phase) shrinks as the step and the
        // nodes shrink (backward Euler: first order in time).
        let l = soil();
        let omega = TAU / DAY;
        let d = (2.0 * l.diffusivity() / omega).sqrt();
        let want = 200.0 * d / (l.conductivity * 2f64.sqrt());
        let err = |steps: usize, first: f64, growth: f64| {
            let mut slab = Slab::new(&[l], first, growth, Bottom::Adiabatic, 290.0).unwrap();
            start_on_flux_wave(&mut slab, 200.0, &l);
            let (temps, _) = run(&mut slab, 6, steps, |t, _| (200.0 * (omega * t).sin(), 0.0));
            let series: Vec<f64> = temps.iter().map(|t| t[0]).collect();
            // Complex error of the harmonic (amplitude and phase together).
            let (_, a, phi) = harmonic(&series);
            let (re, im) = (
                a * phi.cos() - want * (-PI / 4.0).cos(),
                a * phi.sin() - want * (-PI / 4.0).sin(),
            );
            re.hypot(im) / want
        };
        let (e1, e2, e3) = (
            err(48, 0.002, 1.08),
            err(96, 0.002, 1.08),
            err(192, 0.002, 1.08),
        );
        assert!(e2 < 0.6 * e1 && e3 < 0.6 * e2, "time: {e1} {e2} {e3}");
        let (c1, c2) = (err(2880, 0.04, 1.3), err(2880, 0.01, 1.1));
        assert!(c2 < 0.5 * c1, "nodes: {c1} {c2}");
    }

    #[test]
    fn a_melting_surface_stays_at_its_melting_point_and_books_the_heat() {
        // Snow under strong sunlight: the surface reaches 273.15 K and stays there while the
        // excess melts; the budget closes with the melt term; at night it cools below again.
        let snow = Layer {
            thickness_m: 0.3,
            conductivity: 0.2,
            density: 300.0,
            heat_capacity: 2090.0,
        };
        let omega = TAU / DAY;
        for theta in [1.0, 0.5] {
            let mut slab =
                Slab::new(&[snow, soil()], 0.002, 1.15, Bottom::Adiabatic, 268.0).unwrap();
            slab.theta = theta;
            slab.melting_point = Some(273.15);
            let (temps, b) = run(&mut slab, 3, 144, |t, ts| {
                let sun = (600.0 * (omega * t - PI / 2.0).sin()).max(0.0);
                (
                    sun + 250.0 - 0.98 * 5.670_374_419e-8 * ts.powi(4) - 8.0 * (ts - 275.0),
                    -4.0 * 0.98 * 5.670_374_419e-8 * ts.powi(3) - 8.0,
                )
            });
            let surface: Vec<f64> = temps.iter().map(|t| t[0]).collect();
            let max = surface.iter().cloned().fold(f64::MIN, f64::max);
            let min = surface.iter().cloned().fold(f64::MAX, f64::min);
            assert!(
                max <= 273.15 + 1e-12 && (max - 273.15).abs() < 1e-9,
                "θ {theta}: max {max}"
            );
            assert!(min < 270.0, "θ {theta}: it cools at night ({min})");
            assert!(b.melted > 1e5, "θ {theta}: {b:?}");
            let gap = (b.surface_in + b.bottom_in - b.melted - b.stored).abs();
            assert!(
                gap < 1e-6 * b.surface_in.abs().max(b.melted),
                "θ {theta}: {b:?}"
            );
        }
    }

    #[test]
    fn bad_layers_are_named() {
        let mut l = soil();
        l.conductivity = 0.0;
        assert_eq!(
            Slab::new(&[soil(), l], 0.01, 1.1, Bottom::Adiabatic, 290.0).unwrap_err(),
            SlabError::BadLayer {
                layer: 1,
                what: "conductivity",
                value: 0.0
            }
        );
        assert_eq!(
            Slab::new(&[], 0.01, 1.1, Bottom::Adiabatic, 290.0).unwrap_err(),
            SlabError::NoLayers
        );
        assert!(Slab::new(&[soil()], 0.01, 1.1, Bottom::Adiabatic, f64::NAN).is_err());
    }

    #[test]
    fn nodes_fall_on_layer_interfaces() {
        let layers = [
            Layer {
                thickness_m: 0.05,
                ..soil()
            },
            Layer {
                thickness_m: 0.3,
                ..soil()
            },
        ];
        let s = Slab::new(&layers, 0.002, 1.2, Bottom::Adiabatic, 290.0).unwrap();
        assert!(s.depth.iter().any(|&z| (z - 0.05).abs() < 1e-12));
        assert!((s.depth.last().unwrap() - 0.35).abs() < 1e-12);
        assert!(s.depth.windows(2).all(|w| w[1] > w[0]));
    }
}
