//! `tiles`: the catalogue of 3D tile templates and their placement on the terrain.
//!
//! * [`catalogue`]: the TOML catalogue (`data/catalogue.toml` built in, more from region files);
//! * [`load`]: OBJ (`tobj`) and glTF/GLB (`gltf`) loading with unit and up-axis normalisation;
//! * [`procedural`]: generated templates — trees and shrubs made of individual leaves, a building;
//! * [`place`]: deterministic placement of instances per land-cover tile from a seed.
//!
//! Template frame (every template, after normalisation): metres, x east, y north, z up, origin at
//! the centre of the footprint's bounding box on the ground (lowest point at z = 0). Instanced
//! geometry is stored once; an instance is (template id, transform).

pub mod catalogue;
pub mod load;
pub mod place;
pub mod procedural;
mod rng;

pub use catalogue::{Catalogue, TemplateSpec};
pub use place::{place_instances, PlacedInstance, PlacementRule};
pub use rng::SplitMix64;

use std::path::PathBuf;

/// A template mesh in its own frame, with its own material names.
#[derive(Clone, Debug, PartialEq)]
pub struct Template {
    pub name: String,
    /// File path or generator description.
    pub source: String,
    pub positions: Vec<[f32; 3]>,
    pub indices: Vec<[u32; 3]>,
    /// Per triangle, an index into `material_names`.
    pub triangle_materials: Vec<u16>,
    /// The template's own material names (mapped to library materials by the catalogue).
    pub material_names: Vec<String>,
}

impl Template {
    /// Axis-aligned bounds (min, max).
    pub fn bounds(&self) -> ([f32; 3], [f32; 3]) {
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for p in &self.positions {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        (lo, hi)
    }

    /// Move the origin to the centre of the footprint on the ground (min z = 0).
    pub fn recentre(&mut self) {
        if self.positions.is_empty() {
            return;
        }
        let (lo, hi) = self.bounds();
        let c = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), lo[2]];
        for p in &mut self.positions {
            for k in 0..3 {
                p[k] -= c[k];
            }
        }
    }

    /// Append `other`'s triangles; materials with the same name are shared.
    pub fn merge(&mut self, other: Template) {
        let base = self.positions.len() as u32;
        let remap: Vec<u16> = other
            .material_names
            .iter()
            .map(|n| match self.material_names.iter().position(|m| m == n) {
                Some(i) => i as u16,
                None => {
                    self.material_names.push(n.clone());
                    (self.material_names.len() - 1) as u16
                }
            })
            .collect();
        self.positions.extend(other.positions);
        self.indices
            .extend(other.indices.iter().map(|t| t.map(|i| i + base)));
        self.triangle_materials
            .extend(other.triangle_materials.iter().map(|&m| remap[m as usize]));
        self.source = format!("{} + {}", self.source, other.source);
    }

    /// Radius of the footprint (max horizontal distance from the origin), metres.
    pub fn footprint_radius(&self) -> f32 {
        self.positions
            .iter()
            .map(|p| (p[0] * p[0] + p[1] * p[1]).sqrt())
            .fold(0.0, f32::max)
    }
}

/// Errors naming the file (catalogue, mesh) and what is wrong.
#[derive(Debug, thiserror::Error)]
pub enum TileError {
    #[error("cannot read {}: {source}", path.display())]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{}: {message}", path.display())]
    Parse { path: PathBuf, message: String },
    #[error("{}: `{key}`: {message}", path.display())]
    Invalid {
        path: PathBuf,
        key: String,
        message: String,
    },
    #[error("cannot load template mesh {}: {message}", path.display())]
    Mesh { path: PathBuf, message: String },
}
