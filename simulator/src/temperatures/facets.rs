//! The facets of a scene's terrain for the temperature solver: one per LST pixel (its centre's
//! terrain point, normal and material), its sky-view factor (the cosine-weighted fraction of
//! `sky_rays` stratified rays over its hemisphere that leave the scene upwards) and whether it
//! sees the Sun at every step of the day (a shadow ray through terrain and objects), and its
//! air's offset from the day's air temperature (the lapse rate times its height). Pixels with
//! the same material, normal (quantised to 0.01 in its horizontal components), sky view, shadow
//! pattern and air offset (to 0.1 K) share one facet, so a flat open field is solved once.

use std::collections::HashMap;

use engine::scene::Scene;
use engine::temperature::balance::{Day, Facet};
use glam::DVec3;
use rayon::prelude::*;

/// The LST pixel grid (local frame).
#[derive(Clone, Debug)]
pub struct Grid {
    pub width: usize,
    pub height: usize,
    /// GDAL geotransform in the local frame (north-up).
    pub geotransform: [f64; 6],
}

impl Grid {
    /// The bundle's material raster's grid, or one of `pixel_m` over the same extent.
    pub fn of(scene: &Scene, pixel_m: Option<f64>) -> anyhow::Result<Grid> {
        let Some((_, raster)) = &scene.terrain else {
            anyhow::bail!("the bundle has no terrain to give temperatures to");
        };
        let g = raster.geotransform;
        if g[2] != 0.0 || g[4] != 0.0 || g[5] >= 0.0 {
            anyhow::bail!("the bundle's material raster is not north-up");
        }
        let Some(p) = pixel_m else {
            return Ok(Grid {
                width: raster.width,
                height: raster.height,
                geotransform: g,
            });
        };
        let (w, h) = (raster.width as f64 * g[1], raster.height as f64 * -g[5]);
        let (width, height) = ((w / p).ceil() as usize, (h / p).ceil() as usize);
        if width.saturating_mul(height) > 50_000_000 {
            anyhow::bail!(
                "pixel_size_m = {p} gives {width} × {height} pixels (more than 5·10⁷): choose larger pixels"
            );
        }
        Ok(Grid {
            width: width.max(1),
            height: height.max(1),
            geotransform: [g[0], p, 0.0, g[3], 0.0, -p],
        })
    }

    fn centre(&self, k: usize) -> (f64, f64) {
        let (c, r) = ((k % self.width) as f64 + 0.5, (k / self.width) as f64 + 0.5);
        let g = &self.geotransform;
        (g[0] + c * g[1], g[3] + r * g[5])
    }
}

/// The distinct facets (material id, facet) and each pixel's facet (None: no terrain there).
pub struct Found {
    pub facets: Vec<(u16, Facet)>,
    pub pixel_facet: Vec<Option<usize>>,
}

#[derive(Hash, PartialEq, Eq)]
struct Key {
    material: u16,
    nx: i32,
    ny: i32,
    sky: u32,
    lit: Vec<u64>,
    /// Air-temperature offset in tenths of a kelvin.
    air: i32,
}

/// Stratified cosine-weighted directions about +z (`n` of them, on a √n × √n grid).
fn hemisphere(n: usize) -> Vec<DVec3> {
    let a = (n as f64).sqrt().ceil() as usize;
    let b = n.div_ceil(a);
    let mut out = Vec::with_capacity(a * b);
    for i in 0..a {
        for j in 0..b {
            let u = (i as f64 + 0.5) / a as f64;
            let v = (j as f64 + 0.5) / b as f64;
            let r = u.sqrt();
            let phi = std::f64::consts::TAU * v;
            out.push(DVec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u).sqrt()));
        }
    }
    out
}

/// How the air temperature changes with height: `offset(z)` K at local height `z`.
#[derive(Clone, Copy, Debug)]
pub struct Lapse {
    /// K per m (positive: cooler upwards).
    pub rate: f64,
    /// Local height where the offset is 0, m.
    pub reference_z: f64,
}

impl Lapse {
    fn offset(&self, z: f64) -> f64 {
        -self.rate * (z - self.reference_z)
    }
}

/// Every pixel's facet.
pub fn find(
    scene: &Scene,
    grid: &Grid,
    day: &Day,
    sky_rays: usize,
    lapse: Lapse,
    bar: &indicatif::ProgressBar,
) -> Found {
    let (bvh, raster) = scene
        .terrain
        .as_ref()
        .expect("Grid::of checked the terrain");
    let top = scene.z_range[1] + 10.0;
    let dirs = hemisphere(sky_rays);
    let nmat = scene.materials.len();
    let n = grid.width * grid.height;
    bar.set_length(n as u64);
    let keys: Vec<Option<Key>> = (0..n)
        .into_par_iter()
        .map(|k| {
            let (x, y) = grid.centre(k);
            let o = DVec3::new(x, y, top);
            let hit = bvh.intersect(o, -DVec3::Z);
            if k % 4096 == 0 {
                bar.inc(4096.min(n - k) as u64);
            }
            let hit = hit?;
            let material = raster.lookup(x, y);
            if material as usize >= nmat {
                return None;
            }
            let p = o - DVec3::Z * hit.t;
            let nrm = if hit.normal.z < 0.0 {
                -hit.normal
            } else {
                hit.normal
            };
            // A frame about the normal for the sky rays.
            let helper = if nrm.z.abs() < 0.9 {
                DVec3::Z
            } else {
                DVec3::X
            };
            let t1 = helper.cross(nrm).normalize();
            let t2 = nrm.cross(t1);
            let mut open = 0u32;
            for d in &dirs {
                let w = t1 * d.x + t2 * d.y + nrm * d.z;
                if w.z > 0.0 && !scene.occluded(scene.offset(p, nrm, w), w, f64::INFINITY) {
                    open += 1;
                }
            }
            let mut lit = vec![0u64; day.steps.len().div_ceil(64)];
            for (s, d) in day.steps.iter().enumerate() {
                if d.sun.z > 0.0
                    && nrm.dot(d.sun) > 0.0
                    && !scene.occluded(scene.offset(p, nrm, d.sun), d.sun, f64::INFINITY)
                {
                    lit[s / 64] |= 1 << (s % 64);
                }
            }
            Some(Key {
                material,
                nx: (nrm.x * 100.0).round() as i32,
                ny: (nrm.y * 100.0).round() as i32,
                sky: open,
                lit,
                air: (lapse.offset(p.z) * 10.0).round() as i32,
            })
        })
        .collect();
    bar.finish_and_clear();
    let mut index: HashMap<Key, usize> = HashMap::new();
    let mut facets = Vec::new();
    let mut pixel_facet = Vec::with_capacity(n);
    for key in keys {
        let Some(key) = key else {
            pixel_facet.push(None);
            continue;
        };
        if let Some(&k) = index.get(&key) {
            pixel_facet.push(Some(k));
            continue;
        }
        let k = facets.len();
        let (nx, ny) = (f64::from(key.nx) / 100.0, f64::from(key.ny) / 100.0);
        let nz = (1.0 - nx * nx - ny * ny).max(1e-6).sqrt();
        facets.push((
            key.material,
            Facet {
                normal: DVec3::new(nx, ny, nz).normalize(),
                sky_view: f64::from(key.sky) / dirs.len() as f64,
                lit: (0..day.steps.len())
                    .map(|s| key.lit[s / 64] >> (s % 64) & 1 == 1)
                    .collect(),
                air_offset: f64::from(key.air) / 10.0,
            },
        ));
        index.insert(key, k);
        pixel_facet.push(Some(k));
    }
    Found {
        facets,
        pixel_facet,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hemisphere_directions_are_cosine_weighted() {
        let d = hemisphere(64);
        assert_eq!(d.len(), 64);
        assert!(d
            .iter()
            .all(|v| (v.length() - 1.0).abs() < 1e-12 && v.z > 0.0));
        // E[cos θ] under a cosine-weighted density is 2/3.
        let m = d.iter().map(|v| v.z).sum::<f64>() / 64.0;
        assert!((m - 2.0 / 3.0).abs() < 0.01, "{m}");
    }
}
