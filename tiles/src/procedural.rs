//! Procedural templates, in metres in the template frame (z up, origin on the ground).
//!
//! * `tree`: a hexagonal trunk (material `bark`) and an ellipsoidal crown of individual square
//!   leaves (material `leaf`, two triangles each) with uniformly distributed centres and
//!   isotropic (uniform on the sphere) normals — the turbid-medium-like canopy of RAMI scenes.
//! * `conifer`: the same with a conical crown (radius falling linearly to zero at the top).
//! * `building`: a closed box of walls (material `wall`) with a gable roof (material `roof`),
//!   ridge along x.
//!
//! Generation is deterministic: the same parameters and `seed` give the same mesh.

use std::f64::consts::PI;

use serde::Deserialize;

use crate::{SplitMix64, Template};

/// A generator and its parameters (metres).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum ProceduralSpec {
    Tree {
        height: f64,
        trunk_height: f64,
        trunk_radius: f64,
        crown_radius: f64,
        leaves: u32,
        leaf_size: f64,
        #[serde(default)]
        seed: u64,
    },
    Conifer {
        height: f64,
        trunk_height: f64,
        trunk_radius: f64,
        crown_radius: f64,
        leaves: u32,
        leaf_size: f64,
        #[serde(default)]
        seed: u64,
    },
    Building {
        width: f64,
        depth: f64,
        wall_height: f64,
        roof_height: f64,
    },
}

impl ProceduralSpec {
    /// Range checks; returns (key, message).
    pub fn validate(&self) -> Result<(), (String, String)> {
        let pos = |k: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err((k.to_string(), format!("{v} must be > 0 m")))
            }
        };
        match self {
            ProceduralSpec::Tree {
                height,
                trunk_height,
                trunk_radius,
                crown_radius,
                leaves,
                leaf_size,
                ..
            }
            | ProceduralSpec::Conifer {
                height,
                trunk_height,
                trunk_radius,
                crown_radius,
                leaves,
                leaf_size,
                ..
            } => {
                pos("height", *height)?;
                pos("trunk_radius", *trunk_radius)?;
                pos("crown_radius", *crown_radius)?;
                pos("leaf_size", *leaf_size)?;
                if !(*trunk_height >= 0.0 && trunk_height < height) {
                    return Err((
                        "trunk_height".into(),
                        format!("{trunk_height} must be in [0, height = {height}) m"),
                    ));
                }
                if *leaves == 0 || *leaves > 10_000_000 {
                    return Err(("leaves".into(), format!("{leaves} must be in 1..=10000000")));
                }
                Ok(())
            }
            ProceduralSpec::Building {
                width,
                depth,
                wall_height,
                roof_height,
            } => {
                pos("width", *width)?;
                pos("depth", *depth)?;
                pos("wall_height", *wall_height)?;
                if !(*roof_height >= 0.0 && roof_height.is_finite()) {
                    return Err(("roof_height".into(), format!("{roof_height} must be ≥ 0 m")));
                }
                Ok(())
            }
        }
    }

    pub fn generate(&self) -> Template {
        match self {
            ProceduralSpec::Tree {
                height,
                trunk_height,
                trunk_radius,
                crown_radius,
                leaves,
                leaf_size,
                seed,
            } => tree(
                *height,
                *trunk_height,
                *trunk_radius,
                *crown_radius,
                *leaves,
                *leaf_size,
                *seed,
                false,
            ),
            ProceduralSpec::Conifer {
                height,
                trunk_height,
                trunk_radius,
                crown_radius,
                leaves,
                leaf_size,
                seed,
            } => tree(
                *height,
                *trunk_height,
                *trunk_radius,
                *crown_radius,
                *leaves,
                *leaf_size,
                *seed,
                true,
            ),
            ProceduralSpec::Building {
                width,
                depth,
                wall_height,
                roof_height,
            } => building(*width, *depth, *wall_height, *roof_height),
        }
    }
}

struct MeshBuilder {
    t: Template,
}

impl MeshBuilder {
    fn new(name: &str, source: String, materials: &[&str]) -> Self {
        MeshBuilder {
            t: Template {
                name: name.into(),
                source,
                positions: vec![],
                indices: vec![],
                triangle_materials: vec![],
                material_names: materials.iter().map(|s| s.to_string()).collect(),
            },
        }
    }
    fn vertex(&mut self, p: [f64; 3]) -> u32 {
        self.t
            .positions
            .push([p[0] as f32, p[1] as f32, p[2] as f32]);
        (self.t.positions.len() - 1) as u32
    }
    fn tri(&mut self, a: u32, b: u32, c: u32, m: u16) {
        self.t.indices.push([a, b, c]);
        self.t.triangle_materials.push(m);
    }
    /// Quad a-b-c-d counter-clockwise seen from the side it faces.
    fn quad(&mut self, p: [[f64; 3]; 4], m: u16) {
        let v: Vec<u32> = p.iter().map(|&q| self.vertex(q)).collect();
        self.tri(v[0], v[1], v[2], m);
        self.tri(v[0], v[2], v[3], m);
    }
}

#[allow(clippy::too_many_arguments)]
fn tree(
    height: f64,
    trunk_height: f64,
    trunk_r: f64,
    crown_r: f64,
    leaves: u32,
    leaf: f64,
    seed: u64,
    conical: bool,
) -> Template {
    let kind = if conical { "conifer" } else { "tree" };
    let mut b = MeshBuilder::new(
        kind,
        format!("procedural {kind}: height {height} m, crown radius {crown_r} m, {leaves} leaves of {leaf} m"),
        &["leaf", "bark"],
    );
    // Trunk: 6-sided prism up to the middle of the crown, so that it does not float.
    let top = trunk_height + 0.5 * (height - trunk_height);
    let n = 6;
    for i in 0..n {
        let a0 = 2.0 * PI * i as f64 / n as f64;
        let a1 = 2.0 * PI * (i + 1) as f64 / n as f64;
        let (x0, y0, x1, y1) = (
            trunk_r * a0.cos(),
            trunk_r * a0.sin(),
            trunk_r * a1.cos(),
            trunk_r * a1.sin(),
        );
        b.quad(
            [[x0, y0, 0.0], [x1, y1, 0.0], [x1, y1, top], [x0, y0, top]],
            1,
        );
    }
    let mut rng = SplitMix64::keyed(seed, 0x7EE);
    let half = 0.5 * (height - trunk_height);
    let zc = trunk_height + half;
    let s = 0.5 * leaf;
    for _ in 0..leaves {
        // Centre uniform in the crown volume (rejection from the bounding box).
        let c = loop {
            let x = (2.0 * rng.uniform() - 1.0) * crown_r;
            let y = (2.0 * rng.uniform() - 1.0) * crown_r;
            let z = trunk_height + rng.uniform() * (height - trunk_height);
            let inside = if conical {
                let r_at = crown_r * (height - z) / (height - trunk_height);
                x * x + y * y <= r_at * r_at
            } else {
                (x * x + y * y) / (crown_r * crown_r) + (z - zc) * (z - zc) / (half * half) <= 1.0
            };
            if inside {
                break [x, y, z];
            }
        };
        // Normal uniform on the sphere, then an orthonormal basis of the leaf plane.
        let cz = 2.0 * rng.uniform() - 1.0;
        let phi = 2.0 * PI * rng.uniform();
        let sz = (1.0 - cz * cz).max(0.0).sqrt();
        let nrm = [sz * phi.cos(), sz * phi.sin(), cz];
        let helper = if nrm[2].abs() < 0.9 {
            [0.0, 0.0, 1.0]
        } else {
            [1.0, 0.0, 0.0]
        };
        let u = normalize(cross(helper, nrm));
        let v = cross(nrm, u);
        let corner = |a: f64, bb: f64| {
            [
                c[0] + s * (a * u[0] + bb * v[0]),
                c[1] + s * (a * u[1] + bb * v[1]),
                c[2] + s * (a * u[2] + bb * v[2]),
            ]
        };
        b.quad(
            [
                corner(-1.0, -1.0),
                corner(1.0, -1.0),
                corner(1.0, 1.0),
                corner(-1.0, 1.0),
            ],
            0,
        );
    }
    b.t
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn normalize(a: [f64; 3]) -> [f64; 3] {
    let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    [a[0] / l, a[1] / l, a[2] / l]
}

fn building(w: f64, d: f64, h: f64, roof: f64) -> Template {
    let mut b = MeshBuilder::new(
        "building",
        format!("procedural building: {w} m × {d} m, walls {h} m, roof {roof} m"),
        &["wall", "roof"],
    );
    let (x0, x1, y0, y1) = (-0.5 * w, 0.5 * w, -0.5 * d, 0.5 * d);
    // Walls, counter-clockwise seen from outside.
    b.quad([[x0, y0, 0.0], [x1, y0, 0.0], [x1, y0, h], [x0, y0, h]], 0); // south
    b.quad([[x1, y1, 0.0], [x0, y1, 0.0], [x0, y1, h], [x1, y1, h]], 0); // north
    b.quad([[x1, y0, 0.0], [x1, y1, 0.0], [x1, y1, h], [x1, y0, h]], 0); // east
    b.quad([[x0, y1, 0.0], [x0, y0, 0.0], [x0, y0, h], [x0, y1, h]], 0); // west
    let top = h + roof;
    // Gables (east and west) and the two roof slopes; ridge along x at y = 0.
    let e = [
        b.vertex([x1, y0, h]),
        b.vertex([x1, y1, h]),
        b.vertex([x1, 0.0, top]),
    ];
    b.tri(e[0], e[1], e[2], 0);
    let wv = [
        b.vertex([x0, y1, h]),
        b.vertex([x0, y0, h]),
        b.vertex([x0, 0.0, top]),
    ];
    b.tri(wv[0], wv[1], wv[2], 0);
    b.quad(
        [[x0, y0, h], [x1, y0, h], [x1, 0.0, top], [x0, 0.0, top]],
        1,
    );
    b.quad(
        [[x1, y1, h], [x0, y1, h], [x0, 0.0, top], [x1, 0.0, top]],
        1,
    );
    // Floor, facing down, closes the volume.
    b.quad(
        [[x0, y0, 0.0], [x0, y1, 0.0], [x1, y1, 0.0], [x1, y0, 0.0]],
        0,
    );
    b.t
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rationale: a tree "made of leaves" must have the requested leaf count (two triangles
    /// each) inside its crown, and be reproducible from its seed.
    #[test]
    fn tree_has_its_leaves_in_the_crown_and_is_deterministic() {
        let spec = ProceduralSpec::Tree {
            height: 10.0,
            trunk_height: 4.0,
            trunk_radius: 0.2,
            crown_radius: 2.0,
            leaves: 500,
            leaf_size: 0.1,
            seed: 9,
        };
        let t = spec.generate();
        let leaf_tris = t.triangle_materials.iter().filter(|&&m| m == 0).count();
        assert_eq!(leaf_tris, 1000);
        assert_eq!(t, spec.generate());
        let (lo, hi) = t.bounds();
        assert!(lo[2] >= 0.0 && hi[2] <= 10.0 + 0.1 && hi[0] <= 2.0 + 0.1);
    }

    /// Rationale: the building is closed (every edge shared by exactly two triangles), so a
    /// ray cannot leak into it; and its winding gives outward normals (positive volume).
    #[test]
    fn building_is_closed_with_outward_normals() {
        let t = ProceduralSpec::Building {
            width: 10.0,
            depth: 8.0,
            wall_height: 6.0,
            roof_height: 3.0,
        }
        .generate();
        let key = |p: [f32; 3]| (p[0].to_bits(), p[1].to_bits(), p[2].to_bits());
        let mut edges = std::collections::HashMap::new();
        let mut vol = 0.0f64;
        for tri in &t.indices {
            let p: Vec<[f32; 3]> = tri.iter().map(|&i| t.positions[i as usize]).collect();
            for k in 0..3 {
                let (a, b) = (key(p[k]), key(p[(k + 1) % 3]));
                *edges
                    .entry(if a < b { (a, b) } else { (b, a) })
                    .or_insert(0) += 1;
            }
            let (a, b, c) = (
                p[0].map(f64::from),
                p[1].map(f64::from),
                p[2].map(f64::from),
            );
            vol += (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                + a[2] * (b[0] * c[1] - b[1] * c[0]))
                / 6.0;
        }
        assert!(
            edges.values().all(|&n| n == 2),
            "open edges: {:?}",
            edges.iter().filter(|(_, &n)| n != 2).count()
        );
        let expected = 10.0 * 8.0 * 6.0 + 0.5 * 8.0 * 3.0 * 10.0;
        assert!((vol - expected).abs() < 1e-3, "volume {vol} vs {expected}");
    }
}
