//! A bundle's polygonal area of interest (manifest `[area]`, written by scenegen from a region's
//! `[area] polygon`) in the scene's local frame (m), and what measures ask of it: whether a
//! point lies inside (`geo` containment, boundary outside) and which share of a rectangle does.
//!
//! Use: the target area of a 3D `mdistant` measure is the intersection of its rectangle
//! (`target_m`, default the scene extent) with the polygon; its sample points are drawn
//! uniformly in the rectangle and redrawn until inside (sensor.rs), so the result is the mean
//! over the masked area. Ortho images are not masked (their pixels cover the window).

use geo::{Contains, Coord, LineString, MultiPolygon, Point, Polygon};

/// The polygon, local frame, with its bounding box.
#[derive(Clone, Debug)]
pub struct AreaMask {
    polygon: MultiPolygon<f64>,
    bbox: [f64; 4],
}

impl AreaMask {
    /// From the bundle's polygons (working-CRS metres) and the local frame's origin.
    pub fn new(polygons: &[bundle::PolygonRings], origin: [f64; 2]) -> AreaMask {
        let ring = |r: &Vec<[f64; 2]>| {
            LineString(
                r.iter()
                    .map(|p| Coord {
                        x: p[0] - origin[0],
                        y: p[1] - origin[1],
                    })
                    .collect(),
            )
        };
        let polys: Vec<Polygon<f64>> = polygons
            .iter()
            .filter(|rings| !rings.is_empty())
            .map(|rings| Polygon::new(ring(&rings[0]), rings[1..].iter().map(ring).collect()))
            .collect();
        let mut bbox = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
        for p in polys.iter().flat_map(|p| p.exterior().0.iter()) {
            bbox = [
                bbox[0].min(p.x),
                bbox[1].min(p.y),
                bbox[2].max(p.x),
                bbox[3].max(p.y),
            ];
        }
        AreaMask {
            polygon: MultiPolygon(polys),
            bbox,
        }
    }

    /// Whether the local point (x, y) lies inside.
    pub fn contains(&self, x: f64, y: f64) -> bool {
        let b = self.bbox;
        x > b[0] && x < b[2] && y > b[1] && y < b[3] && self.polygon.contains(&Point::new(x, y))
    }

    /// Share of a 128 × 128 grid of cell centres of `rect` that lies inside (an estimate of
    /// the inside share of the rectangle's area).
    pub fn share_inside(&self, rect: [f64; 4]) -> f64 {
        const N: usize = 128;
        let mut n = 0usize;
        for j in 0..N {
            for i in 0..N {
                let x = rect[0] + (i as f64 + 0.5) / N as f64 * (rect[2] - rect[0]);
                let y = rect[1] + (j as f64 + 0.5) / N as f64 * (rect[3] - rect[1]);
                n += self.contains(x, y) as usize;
            }
        }
        n as f64 / (N * N) as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rationale: containment in the local frame (origin subtracted), holes excluded, and the
    /// inside share of a rectangle close to the area ratio.
    #[test]
    fn containment_and_share() {
        let sq = |a: f64, b: f64| vec![[a, a], [b, a], [b, b], [a, b], [a, a]];
        let m = AreaMask::new(&[vec![sq(100.0, 200.0), sq(140.0, 160.0)]], [100.0, 100.0]);
        assert!(m.contains(10.0, 10.0));
        assert!(!m.contains(50.0, 50.0)); // in the hole
        assert!(!m.contains(150.0, 50.0));
        // Inside share of [0, 200]²: (100² − 20²) / 200².
        let s = m.share_inside([0.0, 0.0, 200.0, 200.0]);
        assert!((s - 0.24).abs() < 0.01, "{s}");
    }
}
