//! A gridded cloud field and exact tracking through it.
//!
//! **Model.** The field is a set of `nx × ny` columns of `dx × dy` metres over the rectangle
//! `[0, nx·dx) × [0, ny·dy)` of its own frame (x, y horizontal, z up, metres). Each column is
//! cut vertically into cells, either on shared levels (`Vertical::Levels`: `nz + 1` ascending
//! altitudes, regular or stretched) or as one box of its own (`Vertical::Boxes`: a base and a
//! top per column, the I3RC Landsat layout). A cell holds an extinction coefficient σ (1/m),
//! uniform inside it, a single-scattering albedo ϖ and the index of its phase function.
//! Laterally the field repeats (`Lateral::Periodic`) or is empty outside its rectangle
//! (`Lateral::Open`); above and below its cells it is empty.
//!
//! **Tracking.** Extinction is constant per cell, so transmittance is exact, cell by cell: a ray
//! is walked through the columns it crosses by a 2D DDA (Amanatides & Woo 1987, "A fast voxel
//! traversal algorithm for ray tracing"), and through each column's cells by its levels.
//! [`CloudGrid::optical_depth`] sums `σ·Δt`; [`CloudGrid::march`] finds the distance at which
//! the optical path reaches a drawn value (free-path sampling by inversion, unbiased, no
//! majorant and no null collisions). Memory: 4 bytes of extinction per cell, plus 4 of albedo
//! and 1 of phase index when they vary per cell (`PerCell`).
//!
//! Units: metres and 1/m. Indices: cell `(ix, iy, iz)` is `(iz·ny + iy)·nx + ix` (`Boxes`:
//! `iz = 0`).

use glam::DVec3;

use crate::phase::PhaseFunction;

/// What lies beyond the field's rectangle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lateral {
    /// The field repeats in x and y (I3RC, IPRT phase B).
    Periodic,
    /// Clear outside the rectangle.
    Open,
}

/// The vertical cut of the columns.
#[derive(Clone, Debug)]
pub enum Vertical {
    /// `nz + 1` ascending altitudes (m) shared by every column.
    Levels(Vec<f64>),
    /// One cell per column from `base[c]` to `top[c]` (m), `c = iy·nx + ix`.
    Boxes { base: Vec<f64>, top: Vec<f64> },
}

/// A quantity uniform over the field or given per cell.
#[derive(Clone, Debug)]
pub enum PerCell<T> {
    Uniform(T),
    Cell(Vec<T>),
}

impl<T: Copy> PerCell<T> {
    #[inline]
    pub fn at(&self, cell: usize) -> T {
        match self {
            PerCell::Uniform(v) => *v,
            PerCell::Cell(v) => v[cell],
        }
    }
}

/// Why a grid cannot be built.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum GridError {
    #[error("cloud grid: {0}")]
    Shape(String),
    #[error("cloud grid: {what} of cell (ix {ix}, iy {iy}, iz {iz}) is {value}, {must}")]
    Value {
        what: &'static str,
        ix: usize,
        iy: usize,
        iz: usize,
        value: f64,
        must: &'static str,
    },
}

/// A gridded cloud field (module doc).
#[derive(Clone, Debug)]
pub struct CloudGrid {
    pub nx: usize,
    pub ny: usize,
    pub dx: f64,
    pub dy: f64,
    pub vertical: Vertical,
    pub lateral: Lateral,
    /// σ per cell (1/m).
    pub extinction: Vec<f32>,
    pub albedo: PerCell<f32>,
    pub phase_index: PerCell<u8>,
    pub phases: Vec<PhaseFunction>,
    /// Lowest cell bottom and highest cell top (m).
    z_lo: f64,
    z_hi: f64,
}

/// Longest walk of a ray that never leaves the field's slab (an exactly horizontal ray in a
/// periodic field), in field widths: it is treated as leaving there.
const HORIZONTAL_WIDTHS: f64 = 1000.0;

impl CloudGrid {
    /// Build and check a grid: every extinction finite and ≥ 0, albedos in [0, 1], phase
    /// indices within `phases`, levels strictly ascending, boxes with `base ≤ top`.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        (nx, ny): (usize, usize),
        (dx, dy): (f64, f64),
        vertical: Vertical,
        lateral: Lateral,
        extinction: Vec<f32>,
        albedo: PerCell<f32>,
        phase_index: PerCell<u8>,
        phases: Vec<PhaseFunction>,
    ) -> Result<Self, GridError> {
        let shape = |m: String| Err(GridError::Shape(m));
        if nx == 0 || ny == 0 {
            return shape(format!("{nx} × {ny} columns: need at least one"));
        }
        if !(dx.is_finite() && dx > 0.0 && dy.is_finite() && dy > 0.0) {
            return shape(format!(
                "column size {dx} × {dy} m must be positive and finite"
            ));
        }
        let (nz, z_lo, z_hi) = match &vertical {
            Vertical::Levels(z) => {
                if z.len() < 2 {
                    return shape(format!("{} levels: need at least 2", z.len()));
                }
                if let Some(k) = (0..z.len() - 1)
                    .find(|&k| z[k] >= z[k + 1] || !z[k].is_finite() || !z[k + 1].is_finite())
                {
                    return shape(format!(
                        "levels must ascend strictly: level {k} = {} m, level {} = {} m",
                        z[k],
                        k + 1,
                        z[k + 1]
                    ));
                }
                (z.len() - 1, z[0], z[z.len() - 1])
            }
            Vertical::Boxes { base, top } => {
                if base.len() != nx * ny || top.len() != nx * ny {
                    return shape(format!(
                        "boxes: {} bases and {} tops for {} columns",
                        base.len(),
                        top.len(),
                        nx * ny
                    ));
                }
                let mut lo = f64::INFINITY;
                let mut hi = f64::NEG_INFINITY;
                for c in 0..nx * ny {
                    let (b, t) = (base[c], top[c]);
                    if !(b.is_finite() && t.is_finite() && b <= t) {
                        return Err(GridError::Value {
                            what: "box top",
                            ix: c % nx,
                            iy: c / nx,
                            iz: 0,
                            value: t,
                            must: "must be finite and at or above the box base",
                        });
                    }
                    lo = lo.min(b);
                    hi = hi.max(t);
                }
                (1, lo, hi)
            }
        };
        let n = nx * ny * nz;
        if extinction.len() != n {
            return shape(format!(
                "{} extinction values for {nx} × {ny} × {nz} = {n} cells",
                extinction.len()
            ));
        }
        let at = |c: usize| (c % nx, (c / nx) % ny, c / (nx * ny));
        for (c, &s) in extinction.iter().enumerate() {
            if !(s.is_finite() && s >= 0.0) {
                let (ix, iy, iz) = at(c);
                return Err(GridError::Value {
                    what: "extinction",
                    ix,
                    iy,
                    iz,
                    value: f64::from(s),
                    must: "must be finite and ≥ 0",
                });
            }
        }
        let albedos: &[f32] = match &albedo {
            PerCell::Uniform(v) => std::slice::from_ref(v),
            PerCell::Cell(v) if v.len() == n => v,
            PerCell::Cell(v) => return shape(format!("{} albedos for {n} cells", v.len())),
        };
        for (c, &w) in albedos.iter().enumerate() {
            if !(0.0..=1.0).contains(&w) {
                let (ix, iy, iz) = at(c);
                return Err(GridError::Value {
                    what: "single-scattering albedo",
                    ix,
                    iy,
                    iz,
                    value: f64::from(w),
                    must: "must lie in [0, 1]",
                });
            }
        }
        let indices: &[u8] = match &phase_index {
            PerCell::Uniform(v) => std::slice::from_ref(v),
            PerCell::Cell(v) if v.len() == n => v,
            PerCell::Cell(v) => return shape(format!("{} phase indices for {n} cells", v.len())),
        };
        for (c, &k) in indices.iter().enumerate() {
            if usize::from(k) >= phases.len() {
                let (ix, iy, iz) = at(c);
                return Err(GridError::Value {
                    what: "phase-function index",
                    ix,
                    iy,
                    iz,
                    value: f64::from(k),
                    must: "must name one of the field's phase functions",
                });
            }
        }
        Ok(Self {
            nx,
            ny,
            dx,
            dy,
            vertical,
            lateral,
            extinction,
            albedo,
            phase_index,
            phases,
            z_lo,
            z_hi,
        })
    }

    /// Width and depth of the field's rectangle (m).
    pub fn size(&self) -> (f64, f64) {
        (self.nx as f64 * self.dx, self.ny as f64 * self.dy)
    }

    /// The altitude range its cells span (m).
    pub fn z_range(&self) -> (f64, f64) {
        (self.z_lo, self.z_hi)
    }

    /// Number of cells.
    pub fn cells(&self) -> usize {
        self.extinction.len()
    }

    /// Single-scattering albedo and phase function of a cell.
    #[inline]
    pub fn optics(&self, cell: usize) -> (f64, &PhaseFunction) {
        (
            f64::from(self.albedo.at(cell)),
            &self.phases[usize::from(self.phase_index.at(cell))],
        )
    }

    /// The column `iy·nx + ix` of a cell.
    #[inline]
    pub fn column_of_cell(&self, cell: usize) -> usize {
        cell % (self.nx * self.ny)
    }

    /// `p` moved into the field's rectangle (periodic fields; open ones leave it).
    #[inline]
    pub fn wrap(&self, p: DVec3) -> DVec3 {
        match self.lateral {
            Lateral::Open => p,
            Lateral::Periodic => {
                let (lx, ly) = self.size();
                DVec3::new(wrap1(p.x, lx), wrap1(p.y, ly), p.z)
            }
        }
    }

    /// The column optical depth (vertical) of column `(ix, iy)`.
    pub fn column_optical_depth(&self, ix: usize, iy: usize) -> f64 {
        let c = iy * self.nx + ix;
        match &self.vertical {
            Vertical::Levels(z) => (0..z.len() - 1)
                .map(|k| f64::from(self.extinction[k * self.nx * self.ny + c]) * (z[k + 1] - z[k]))
                .sum(),
            Vertical::Boxes { base, top } => f64::from(self.extinction[c]) * (top[c] - base[c]),
        }
    }

    /// Optical depth along `p + t·d`, `0 ≤ t ≤ t_max` (`d` a unit vector).
    pub fn optical_depth(&self, p: DVec3, d: DVec3, t_max: f64) -> f64 {
        let mut tau = 0.0;
        self.walk(p, d, t_max, |t0, t1, s, _| {
            tau += s * (t1 - t0);
            true
        });
        tau
    }

    /// The distance along `p + t·d` at which the optical path reaches `s`, and the cell there;
    /// `None` when it stays below `s` up to `t_max`.
    pub fn march(&self, p: DVec3, d: DVec3, s: f64, t_max: f64) -> Option<(f64, usize)> {
        let mut tau = 0.0;
        let mut found = None;
        self.walk(p, d, t_max, |t0, t1, sigma, cell| {
            let dtau = sigma * (t1 - t0);
            if tau + dtau >= s {
                found = Some(((t0 + (s - tau) / sigma).min(t1), cell));
                false
            } else {
                tau += dtau;
                true
            }
        });
        found
    }

    /// Visit, in order, the pieces `[t0, t1]` of `p + t·d` (`0 ≤ t ≤ t_max`) that lie in cells
    /// of non-zero extinction: `f(t0, t1, σ, cell)`, which returns whether to go on.
    pub fn walk(
        &self,
        p: DVec3,
        d: DVec3,
        t_max: f64,
        mut f: impl FnMut(f64, f64, f64, usize) -> bool,
    ) {
        // The slab of the cells.
        let (mut ta, mut tb) = (0.0_f64, t_max);
        if !clip(p.z, d.z, self.z_lo, self.z_hi, &mut ta, &mut tb) {
            return;
        }
        let (lx, ly) = self.size();
        match self.lateral {
            Lateral::Open => {
                if !clip(p.x, d.x, 0.0, lx, &mut ta, &mut tb)
                    || !clip(p.y, d.y, 0.0, ly, &mut ta, &mut tb)
                {
                    return;
                }
            }
            Lateral::Periodic => {
                tb = tb.min(ta + HORIZONTAL_WIDTHS * (lx + ly));
            }
        }
        if ta >= tb {
            return;
        }
        let q = p + d * ta;
        let (nx, ny) = (self.nx as i64, self.ny as i64);
        let mut ix = (q.x / self.dx).floor() as i64;
        let mut iy = (q.y / self.dy).floor() as i64;
        if self.lateral == Lateral::Open {
            ix = ix.clamp(0, nx - 1);
            iy = iy.clamp(0, ny - 1);
        }
        // DDA set-up: the distance to the next x and y column boundary and the spacing.
        let axis = |i: i64, o: f64, dir: f64, w: f64| -> (f64, f64, i64) {
            if dir > 0.0 {
                (ta + ((i + 1) as f64 * w - o) / dir, w / dir, 1)
            } else if dir < 0.0 {
                (ta + (i as f64 * w - o) / dir, -w / dir, -1)
            } else {
                (f64::INFINITY, f64::INFINITY, 0)
            }
        };
        let (mut tx, dtx, sx) = axis(ix, q.x, d.x, self.dx);
        let (mut ty, dty, sy) = axis(iy, q.y, d.y, self.dy);
        // The current level (shared levels only).
        let mut iz = match &self.vertical {
            Vertical::Levels(z) => level_below(z, q.z, d.z),
            Vertical::Boxes { .. } => 0,
        };
        let mut t0 = ta;
        loop {
            let t1 = tx.min(ty).min(tb);
            let cx = ix.rem_euclid(nx) as usize;
            let cy = iy.rem_euclid(ny) as usize;
            let column = cy * self.nx + cx;
            if t1 > t0 && !self.column_piece(column, p, d, t0, t1, &mut iz, &mut f) {
                return;
            }
            if t1 >= tb {
                return;
            }
            t0 = t1;
            if tx <= ty {
                ix += sx;
                tx += dtx;
            }
            if ty <= t1 {
                iy += sy;
                ty += dty;
            }
            if self.lateral == Lateral::Open && (!(0..nx).contains(&ix) || !(0..ny).contains(&iy)) {
                return;
            }
        }
    }

    /// The cells of `column` that `p + t·d`, `t0 ≤ t ≤ t1`, crosses; `iz` is the level the ray
    /// is in on entry and is left at the level it is in on exit. Returns `false` when `f` asked
    /// to stop.
    #[inline]
    #[allow(clippy::too_many_arguments)]
    fn column_piece(
        &self,
        column: usize,
        p: DVec3,
        d: DVec3,
        t0: f64,
        t1: f64,
        iz: &mut usize,
        f: &mut impl FnMut(f64, f64, f64, usize) -> bool,
    ) -> bool {
        match &self.vertical {
            Vertical::Boxes { base, top } => {
                let sigma = f64::from(self.extinction[column]);
                if sigma <= 0.0 {
                    return true;
                }
                let (mut a, mut b) = (t0, t1);
                if clip(p.z, d.z, base[column], top[column], &mut a, &mut b) && b > a {
                    return f(a, b, sigma, column);
                }
                true
            }
            Vertical::Levels(z) => {
                let stride = self.nx * self.ny;
                let nz = z.len() - 1;
                let mut a = t0;
                loop {
                    // Where the ray leaves level iz.
                    let t_z = if d.z > 0.0 {
                        (z[*iz + 1] - p.z) / d.z
                    } else if d.z < 0.0 {
                        (z[*iz] - p.z) / d.z
                    } else {
                        f64::INFINITY
                    };
                    let b = t_z.min(t1);
                    if b > a {
                        let cell = *iz * stride + column;
                        let sigma = f64::from(self.extinction[cell]);
                        if sigma > 0.0 && !f(a, b, sigma, cell) {
                            return false;
                        }
                    }
                    if t_z > t1 {
                        return true;
                    }
                    // Into the next level (none beyond the slab: the walk ends there).
                    if d.z > 0.0 {
                        if *iz + 1 >= nz {
                            return true;
                        }
                        *iz += 1;
                    } else {
                        if *iz == 0 {
                            return true;
                        }
                        *iz -= 1;
                    }
                    a = a.max(t_z);
                }
            }
        }
    }
}

/// `x` wrapped into `[0, l)`.
#[inline]
fn wrap1(x: f64, l: f64) -> f64 {
    let w = x.rem_euclid(l);
    if w >= l {
        0.0
    } else {
        w
    }
}

/// Clip `[ta, tb]` to the part of `o + t·dir` inside `[lo, hi]`; whether anything is left.
#[inline]
fn clip(o: f64, dir: f64, lo: f64, hi: f64, ta: &mut f64, tb: &mut f64) -> bool {
    if dir == 0.0 {
        return (lo..=hi).contains(&o) && ta <= tb;
    }
    let (a, b) = ((lo - o) / dir, (hi - o) / dir);
    let (a, b) = if a <= b { (a, b) } else { (b, a) };
    *ta = ta.max(a);
    *tb = tb.min(b);
    ta < tb
}

/// The level of `levels` holding altitude `z`, a ray moving along `dz` (on a level boundary:
/// the level it moves into), clamped to the levels.
fn level_below(levels: &[f64], z: f64, dz: f64) -> usize {
    let nz = levels.len() - 1;
    let k = levels.partition_point(|&l| l <= z);
    // levels[k-1] ≤ z < levels[k]
    let mut iz = k.saturating_sub(1);
    if dz < 0.0 && iz > 0 && levels[iz] == z {
        iz -= 1;
    }
    iz.min(nz - 1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phase::HenyeyGreenstein;

    fn hg() -> Vec<PhaseFunction> {
        vec![PhaseFunction::Hg(HenyeyGreenstein::new(0.85).unwrap())]
    }

    /// One cube of σ inside a 3×3×3 grid of 1 m cells.
    fn cube(lateral: Lateral, sigma: f32) -> CloudGrid {
        let mut ext = vec![0.0_f32; 27];
        ext[13] = sigma;
        CloudGrid::new(
            (3, 3),
            (1.0, 1.0),
            Vertical::Levels(vec![0.0, 1.0, 2.0, 3.0]),
            lateral,
            ext,
            PerCell::Uniform(1.0),
            PerCell::Uniform(0),
            hg(),
        )
        .unwrap()
    }

    /// Exact chord of the ray through the unit cube [1,2]³, by slab clipping.
    fn chord(p: DVec3, d: DVec3) -> f64 {
        let (mut a, mut b) = (0.0, f64::INFINITY);
        for k in 0..3 {
            if !clip(p[k], d[k], 1.0, 2.0, &mut a, &mut b) {
                return 0.0;
            }
        }
        (b - a).max(0.0)
    }

    #[test]
    fn slanted_rays_through_a_box_have_the_closed_form_optical_depth() {
        let g = cube(Lateral::Open, 2.5);
        let mut rng = crate::rng::Stream::new(7, [0; 4]);
        for _ in 0..2000 {
            let p = DVec3::new(
                rng.next_f64() * 3.0,
                rng.next_f64() * 3.0,
                rng.next_f64() * 3.0,
            );
            let d = crate::frame::rotate_about(
                DVec3::Z,
                2.0 * rng.next_f64() - 1.0,
                std::f64::consts::TAU * rng.next_f64(),
            );
            let want = 2.5 * chord(p, d);
            let got = g.optical_depth(p, d, 10.0);
            assert!((got - want).abs() < 1e-9, "{p} {d}: {got} vs {want}");
            // march inverts it
            if want > 1e-6 {
                let s = want * 0.37;
                let (t, cell) = g.march(p, d, s, 10.0).unwrap();
                assert_eq!(cell, 13);
                assert!((g.optical_depth(p, d, t) - s).abs() < 1e-9);
                assert!(g.march(p, d, want * 1.0001, 10.0).is_none());
            }
        }
    }

    #[test]
    fn periodic_fields_repeat_the_cube() {
        let g = cube(Lateral::Periodic, 1.0);
        // Along x at the cube's middle height and y: one cube per 3 m period.
        let p = DVec3::new(0.2, 1.5, 1.5);
        let tau = g.optical_depth(p, DVec3::X, 30.0);
        assert!((tau - 10.0).abs() < 1e-9, "{tau}");
        let back = g.optical_depth(DVec3::new(-0.2, 1.5, 1.5), -DVec3::X, 30.0);
        assert!((back - 10.0).abs() < 1e-9, "{back}");
        // Diagonal in x and z: leaves the slab after 3 m of height.
        let d = DVec3::new(1.0, 0.0, 1.0).normalize();
        let tau = g.optical_depth(DVec3::new(0.0, 1.5, 0.0), d, 100.0);
        assert!((tau - 2f64.sqrt()).abs() < 1e-9, "{tau}");
        assert_eq!(
            g.wrap(DVec3::new(-0.5, 7.25, 1.0)),
            DVec3::new(2.5, 1.25, 1.0)
        );
    }

    #[test]
    fn stretched_levels_and_boxes() {
        // Two columns; levels 0, 10, 100 m; σ per cell.
        let g = CloudGrid::new(
            (2, 1),
            (50.0, 50.0),
            Vertical::Levels(vec![0.0, 10.0, 100.0]),
            Lateral::Periodic,
            vec![0.1, 0.2, 0.01, 0.02],
            PerCell::Uniform(1.0),
            PerCell::Uniform(0),
            hg(),
        )
        .unwrap();
        assert!((g.column_optical_depth(0, 0) - (1.0 + 0.9)).abs() < 1e-6);
        let down = g.optical_depth(DVec3::new(60.0, 5.0, 100.0), -DVec3::Z, 1e9);
        assert!((down - (0.2 * 10.0 + 0.02 * 90.0)).abs() < 1e-5, "{down}");
        let b = CloudGrid::new(
            (2, 1),
            (50.0, 50.0),
            Vertical::Boxes {
                base: vec![200.0, 200.0],
                top: vec![300.0, 500.0],
            },
            Lateral::Periodic,
            vec![0.01, 0.02],
            PerCell::Uniform(1.0),
            PerCell::Uniform(0),
            hg(),
        )
        .unwrap();
        assert_eq!(b.z_range(), (200.0, 500.0));
        // Slanted 45° through both boxes from (0, 0, 600) going +x and down.
        let d = DVec3::new(1.0, 0.0, -1.0).normalize();
        let tau = b.optical_depth(DVec3::new(0.0, 0.0, 600.0), d, 1e9);
        // Against a fine midpoint sum along the ray (it crosses six periods).
        let mut fine = 0.0;
        let n = 200_000;
        let len = 600.0 * 2f64.sqrt();
        for k in 0..n {
            let t = (k as f64 + 0.5) / n as f64 * len;
            let q = b.wrap(DVec3::new(0.0, 0.0, 600.0) + d * t);
            let c = (q.x / 50.0) as usize;
            let (lo, hi) = (200.0, if c == 0 { 300.0 } else { 500.0 });
            if q.z >= lo && q.z <= hi {
                fine += [0.01, 0.02][c] * len / n as f64;
            }
        }
        assert!((tau - fine).abs() < 1e-3, "{tau} vs {fine}");
    }

    #[test]
    fn bad_cells_are_named() {
        let e = CloudGrid::new(
            (2, 1),
            (1.0, 1.0),
            Vertical::Levels(vec![0.0, 1.0]),
            Lateral::Open,
            vec![0.0, f32::NAN],
            PerCell::Uniform(1.0),
            PerCell::Uniform(0),
            hg(),
        )
        .unwrap_err();
        assert!(
            e.to_string()
                .contains("extinction of cell (ix 1, iy 0, iz 0)"),
            "{e}"
        );
        let e = CloudGrid::new(
            (1, 1),
            (1.0, 1.0),
            Vertical::Levels(vec![0.0, 1.0, 1.0]),
            Lateral::Open,
            vec![0.0, 0.0],
            PerCell::Uniform(1.0),
            PerCell::Uniform(0),
            hg(),
        )
        .unwrap_err();
        assert!(e.to_string().contains("ascend"), "{e}");
    }
}
