//! 3D scenes: geometry (the terrain BVH in `terrain`, instanced objects in `instances`),
//! materials, the assembled [`Scene`] and its builders (bundle, canopy). Each geometry module's
//! header states its precision scheme: f32 traversal in a render frame centred on the scene,
//! every hit decided in f64.

pub mod area_mask;
pub mod build;
pub mod curvature;
pub mod instances;
pub mod material;
pub mod terrain;
pub mod texture;
pub mod world;

pub use terrain::{TerrainBvh, TerrainHit};
pub use world::{Scene, SurfaceHit};
