//! Where the Sun cannot be blocked: for one direction towards the Sun, the height over each cell
//! of a horizontal grid above which no geometry lies on the way to the Sun (a *horizon map* for
//! one direction, as in height-field shadowing: Max 1988, "Horizon mapping: shadows for
//! bump-mapped surfaces", here over boxes of any geometry).
//!
//! **What for.** Most shadow rays of a 3D render start in the air, at a collision of the
//! atmosphere below the scene's top (the expected next-event estimate of every flight that
//! comes down into the scene): on Grenoble about 3 of the 5.5 shadow rays per sample. A point
//! higher than its cell's clearance sees the Sun: [`SunClearance::clear`] answers that with one
//! lookup, without the BVHs (which cost 0.3–0.7 µs per ray, mostly waiting on memory).
//! Anything else (points near the surfaces, outside the grid) is left to the shadow ray.
//!
//! **Construction.** Tops: the highest `hi.z` of the boxes (terrain triangles, the instance
//! BVH's leaf boxes) over each cell, widened by a margin, then dilated to the 8 neighbours.
//! The clearance of cell `c` is the highest `top'(c') − k·s(c')` over the cells `c'` that the
//! Sun-ward ray from `c`'s centre crosses (`s` the horizontal distance where it enters `c'`,
//! `k = tan(elevation)` the ray's rise per metre), starting with `top'(c)` itself; the walk stops
//! once no higher top is left within reach.
//!
//! **Why it is conservative.** Let `p` (height `z`) be in cell `c`, and let its Sun-ward ray meet
//! a box `B` at the point `q`, horizontal distance `s` from `p`, so `hi.z(B) ≥ z + k·s`. The
//! point `q₀` of the centre's parallel ray at the same horizontal distance is within half a
//! cell of `q` along each axis, so its cell `c''` is a neighbour of `q`'s cell `c'` (or `c'`):
//! `top'(c'') ≥ top(c') ≥ hi.z(B)`, and the centre ray enters `c''` at `s'' ≤ s`. Hence
//! `clearance(c) ≥ top'(c'') − k·s'' ≥ z + k·s − k·s = z`: a point strictly above its cell's
//! clearance meets no box. The margin (1 mm + 10⁻⁶ × the scene's size, m) covers the rounding
//! of the walk and of the cell lookup; `tests` compare with the scene's shadow rays.
//!
//! **Cost.** About 65 536 cells (Grenoble: 157 m), 4 bytes each; the build walks each cell's
//! ray until nothing higher is within reach (a Sun 30° above the horizon over 2.6 km of relief:
//! under 20 km, ~100 cells), a few tens of ms.

use glam::DVec3;

/// Cells over the geometry's horizontal box (about: the cells are square).
const TARGET_CELLS: f64 = 65536.0;

/// Heights above which the Sun, in one direction, is not blocked (module header).
#[derive(Debug)]
pub struct SunClearance {
    /// The unit direction towards the Sun this map is for.
    pub dir: DVec3,
    x0: f64,
    y0: f64,
    cell: f64,
    nx: usize,
    ny: usize,
    /// Clearance per cell, row-major from the south (`iy * nx + ix`), m; −∞: nothing.
    clear: Vec<f32>,
    /// Above this height nothing can block any ray going up (the highest top), m.
    zmax: f64,
}

/// `x` rounded to an f32 that is not below it.
fn up32(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) < x {
        f + f.abs() * f32::EPSILON + f32::MIN_POSITIVE
    } else {
        f
    }
}

impl SunClearance {
    /// The map for the unit direction `dir` (towards the Sun) over the boxes `boxes()` (called
    /// twice: bounds, then the tops). `None` when the Sun is not above the horizontal
    /// (`dir.z ≤ 0`) or there is no finite box.
    pub fn new<I: Iterator<Item = (DVec3, DVec3)>>(
        dir: DVec3,
        boxes: impl Fn() -> I,
    ) -> Option<Self> {
        if !dir.is_finite() || dir.z <= 0.0 {
            return None;
        }
        let finite = |b: &(DVec3, DVec3)| b.0.is_finite() && b.1.is_finite();
        let (lo, hi) = boxes()
            .filter(finite)
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(a, b), (l, h)| {
                (a.min(l), b.max(h))
            });
        if lo.cmpgt(hi).any() {
            return None;
        }
        let margin = 1e-3 + 1e-6 * (lo.abs().max(hi.abs()).max_element() + (hi - lo).length());
        // One more cell all round, for the dilation.
        let (w, h) = (hi.x - lo.x + 2.0 * margin, hi.y - lo.y + 2.0 * margin);
        let cell = (w * h / TARGET_CELLS)
            .sqrt()
            .max(w.max(h) / 1024.0)
            .max(1e-6);
        let nx = (w / cell).ceil() as usize + 2;
        let ny = (h / cell).ceil() as usize + 2;
        let (x0, y0) = (lo.x - margin - cell, lo.y - margin - cell);
        let index = |x: f64, origin: f64, n: usize| {
            (((x - origin) / cell).floor().max(0.0) as usize).min(n - 1)
        };
        // Tops, widened by the margin.
        let mut top = vec![f32::NEG_INFINITY; nx * ny];
        let mut zmax = f64::NEG_INFINITY;
        for (l, h) in boxes().filter(finite) {
            let t = up32(h.z + margin);
            zmax = zmax.max(t as f64);
            let (ia, ib) = (index(l.x - margin, x0, nx), index(h.x + margin, x0, nx));
            let (ja, jb) = (index(l.y - margin, y0, ny), index(h.y + margin, y0, ny));
            for j in ja..=jb {
                for v in &mut top[j * nx + ia..=j * nx + ib] {
                    *v = v.max(t);
                }
            }
        }
        // Dilated to the 8 neighbours.
        let mut dil = vec![f32::NEG_INFINITY; nx * ny];
        for j in 0..ny {
            for i in 0..nx {
                let mut m = f32::NEG_INFINITY;
                for jj in j.saturating_sub(1)..=(j + 1).min(ny - 1) {
                    for ii in i.saturating_sub(1)..=(i + 1).min(nx - 1) {
                        m = m.max(top[jj * nx + ii]);
                    }
                }
                dil[j * nx + i] = m;
            }
        }
        drop(top);
        // The Sun-ward walk from each cell's centre.
        let horiz = (dir.x * dir.x + dir.y * dir.y).sqrt();
        let mut clear = vec![f32::NEG_INFINITY; nx * ny];
        for j in 0..ny {
            for i in 0..nx {
                let mut c = dil[j * nx + i] as f64;
                if horiz > 1e-12 {
                    let (ux, uy) = (dir.x / horiz, dir.y / horiz);
                    let k = dir.z / horiz;
                    let (cx, cy) = (x0 + (i as f64 + 0.5) * cell, y0 + (j as f64 + 0.5) * cell);
                    // Amanatides & Woo over the cells, in horizontal distance s.
                    let axis = |u: f64, i: usize, origin: f64, centre: f64| -> (isize, f64, f64) {
                        if u > 0.0 {
                            (1, (origin + (i + 1) as f64 * cell - centre) / u, cell / u)
                        } else if u < 0.0 {
                            (-1, (origin + i as f64 * cell - centre) / u, -cell / u)
                        } else {
                            (0, f64::INFINITY, f64::INFINITY)
                        }
                    };
                    let (sx, mut tx, dtx) = axis(ux, i, x0, cx);
                    let (sy, mut ty, dty) = axis(uy, j, y0, cy);
                    let (mut ci, mut cj) = (i, j);
                    loop {
                        let s = tx.min(ty);
                        // Nothing further can be higher than the highest top.
                        if zmax - k * s <= c {
                            break;
                        }
                        if tx <= ty {
                            tx += dtx;
                            match ci.checked_add_signed(sx) {
                                Some(n) if n < nx => ci = n,
                                _ => break,
                            }
                        } else {
                            ty += dty;
                            match cj.checked_add_signed(sy) {
                                Some(n) if n < ny => cj = n,
                                _ => break,
                            }
                        }
                        c = c.max(dil[cj * nx + ci] as f64 - k * s);
                    }
                }
                clear[j * nx + i] = up32(c + margin);
            }
        }
        Some(Self {
            dir,
            x0,
            y0,
            cell,
            nx,
            ny,
            clear,
            zmax: zmax + margin,
        })
    }

    /// Whether the ray from `p` towards the Sun ([`Self::dir`]) certainly meets no geometry.
    /// `false` means "not known": cast the shadow ray.
    #[inline]
    pub fn clear(&self, p: DVec3) -> bool {
        if p.z > self.zmax {
            return true;
        }
        let (fx, fy) = ((p.x - self.x0) / self.cell, (p.y - self.y0) / self.cell);
        // Outside the grid (or NaN): not known.
        if !(fx >= 0.0 && fy >= 0.0 && fx < self.nx as f64 && fy < self.ny as f64) {
            return false;
        }
        p.z > self.clear[fy as usize * self.nx + fx as usize] as f64
    }

    /// Memory of the map, bytes.
    pub fn memory_bytes(&self) -> usize {
        self.clear.len() * 4
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::direction_from_angles;
    use crate::rng::Stream;
    use crate::scene::clip;

    /// Random boxes far from the origin; random points and Sun directions: a point the map
    /// calls clear never has a box on its Sun-ward ray, and the map clears most points that
    /// are well above the boxes.
    #[test]
    fn clear_points_see_the_sun() {
        let mut rng = Stream::new(5, [0, 0, 0, 0]);
        let base = DVec3::new(-60_000.0, 25_000.0, 300.0);
        let mut boxes = Vec::new();
        for _ in 0..300 {
            let c = base
                + DVec3::new(
                    4000.0 * rng.next_f64(),
                    4000.0 * rng.next_f64(),
                    300.0 * rng.next_f64(),
                );
            let h = DVec3::new(
                100.0 * rng.next_f64(),
                100.0 * rng.next_f64(),
                80.0 * rng.next_f64(),
            );
            boxes.push((c - h, c + h));
        }
        let (mut cleared, mut free) = (0, 0);
        for k in 0..12 {
            // Zenith 0–85°, and one straight overhead.
            let zen = if k == 0 {
                0.0
            } else {
                85f64.to_radians() * rng.next_f64()
            };
            let sun = direction_from_angles(zen, std::f64::consts::TAU * rng.next_f64());
            let map = SunClearance::new(sun, || boxes.iter().copied()).unwrap();
            for _ in 0..5000 {
                let p = base
                    + DVec3::new(
                        -500.0 + 5000.0 * rng.next_f64(),
                        -500.0 + 5000.0 * rng.next_f64(),
                        -100.0 + 800.0 * rng.next_f64(),
                    );
                let blocked = boxes
                    .iter()
                    .any(|&(l, h)| clip(p, sun, l, h, 0.0, f64::INFINITY).is_some());
                if map.clear(p) {
                    assert!(!blocked, "sun {sun}: {p} called clear but blocked");
                    cleared += 1;
                }
                free += !blocked as usize;
            }
        }
        assert!(cleared as f64 > 0.5 * free as f64, "{cleared} of {free}");
        assert!(SunClearance::new(-DVec3::Z, || boxes.iter().copied()).is_none());
        assert!(SunClearance::new(DVec3::Z, std::iter::empty).is_none());
    }
}
