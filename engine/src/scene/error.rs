//! Errors of building 3D scenes: the bundle and its materials, reflectance textures and
//! land-surface-temperature rasters, leaf and position tables, instanced geometry, and the
//! top-level tree's disk cache. Each variant names what is wrong and where (material, file and
//! line or pixel, template, instance); the messages are those users and tests match.

use std::path::PathBuf;

use glam::DVec3;

use crate::bsdf::BrdfError;

/// What went wrong building a scene or one of its parts.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The bundle cannot be opened (its own error names the file).
    #[error(transparent)]
    Bundle(#[from] bundle::BundleError),
    /// A material name that is not in the scene's table (`known`: the table's names).
    #[error("material `{name}` is not in the bundle (its materials: {})", known.join(", "))]
    UnknownMaterial { name: String, known: Vec<String> },
    /// A material whose model cannot be built at a wavelength.
    #[error("material `{name}`: {source}")]
    Material { name: String, source: BrdfError },
    /// An experiment's replacement for a bundle material that is not a valid BRDF.
    #[error("material `{name}` (override): {source}")]
    Override {
        name: String,
        source: bundle::BrdfError,
    },
    /// The background ground's material is not a valid BRDF.
    #[error("background material: {source}")]
    Background { source: bundle::BrdfError },
    /// The bundle's area polygon cannot be read (`message`: the WKT reader's).
    #[error("{message}")]
    Area { message: String },
    /// The bundle's material raster has no pixels (or fewer than its size says).
    #[error("the material raster is empty")]
    EmptyMaterialRaster {
        width: usize,
        height: usize,
        pixels: usize,
    },
    /// A texture for a material the bundle does not have.
    #[error("texture {}: material `{material}` is not in the bundle", file.display())]
    TextureMaterial { file: PathBuf, material: String },
    /// A texture for a material that is not Lambertian.
    #[error(
        "texture {}: material `{material}` is not Lambertian (only Lambertian materials take reflectance textures)",
        file.display()
    )]
    TextureNotLambertian { file: PathBuf, material: String },
    /// A material given two textures.
    #[error("material `{material}` has two textures")]
    TwoTextures { material: String },
    /// A georeferenced raster (`what`: "texture", "land-surface temperature") that is absent.
    #[error("{what} {}: file not found", path.display())]
    RasterNotFound { what: &'static str, path: PathBuf },
    /// A raster GDAL cannot open.
    #[error("{what} {}: GDAL cannot open it as a raster ({source})", path.display())]
    RasterOpen {
        what: &'static str,
        path: PathBuf,
        source: gdal::errors::GdalError,
    },
    /// A raster without bands or pixels.
    #[error("{what} {} has no pixels", path.display())]
    RasterEmpty { what: &'static str, path: PathBuf },
    /// A raster without a geotransform.
    #[error("{what} {} has no geotransform: {source}", path.display())]
    RasterGeotransform {
        what: &'static str,
        path: PathBuf,
        source: gdal::errors::GdalError,
    },
    /// A raster that is not north-up.
    #[error(
        "{what} {} must be north-up (geotransform {geotransform:?} is rotated or flipped)",
        path.display()
    )]
    RasterRotated {
        what: &'static str,
        path: PathBuf,
        geotransform: [f64; 6],
    },
    /// A raster without a CRS.
    #[error("{what} {} has no CRS: {source}", path.display())]
    RasterNoCrs {
        what: &'static str,
        path: PathBuf,
        source: gdal::errors::GdalError,
    },
    /// The bundle's CRS (WKT) that GDAL cannot parse, met while checking a raster's.
    #[error("the bundle's CRS cannot be parsed: {source}")]
    BundleCrs { source: gdal::errors::GdalError },
    /// A raster in another CRS than the bundle's (`target`: the bundle's, as PROJ.4 or "the
    /// bundle's WKT").
    #[error(
        "{what} {} is not in the bundle's CRS (reproject it, e.g. with gdalwarp -t_srs, to: {target})",
        path.display()
    )]
    RasterCrs {
        what: &'static str,
        path: PathBuf,
        target: String,
    },
    /// A band (from 1) GDAL cannot open.
    #[error("{what} {} band {band}: {source}", path.display())]
    RasterBand {
        what: &'static str,
        path: PathBuf,
        band: usize,
        source: gdal::errors::GdalError,
    },
    /// A band (from 1) GDAL cannot read.
    #[error("cannot read {what} {} band {band}: {source}", path.display())]
    RasterRead {
        what: &'static str,
        path: PathBuf,
        band: usize,
        source: gdal::errors::GdalError,
    },
    /// A texture whose band count differs from its list of wavelengths.
    #[error(
        "texture {} has {bands} band(s) but `wavelengths_nm` lists {wavelengths}",
        path.display()
    )]
    TextureBands {
        path: PathBuf,
        bands: usize,
        wavelengths: usize,
    },
    /// A texture whose wavelengths do not increase.
    #[error("texture {}: `wavelengths_nm` must increase", path.display())]
    TextureWavelengths { path: PathBuf },
    /// A texture pixel that is not a reflectance in [0, 1] (`band` from 1).
    #[error(
        "texture {}: pixel (row {row}, column {column}) of band {band} is {value}, not a reflectance in [0, 1]",
        path.display()
    )]
    TexturePixel {
        path: PathBuf,
        row: usize,
        column: usize,
        band: usize,
        value: f32,
    },
    /// A land-surface-temperature raster with other than one band.
    #[error(
        "land-surface temperature {} has {bands} bands; it needs one (K)",
        path.display()
    )]
    TemperatureBands { path: PathBuf, bands: usize },
    /// A land-surface-temperature pixel that is not a temperature in (0, 10000] K.
    #[error(
        "land-surface temperature {}: pixel (row {row}, column {column}) is {value}, not a temperature in (0, 10000] K",
        path.display()
    )]
    TemperaturePixel {
        path: PathBuf,
        row: usize,
        column: usize,
        value: f32,
    },
    /// A table file (leaves, positions) that cannot be read.
    #[error("cannot read {}: {source}", path.display())]
    TableRead {
        path: PathBuf,
        source: std::io::Error,
    },
    /// A table line (from 1) with `found` numbers instead of `columns` finite ones.
    #[error(
        "{}:{line}: expected {columns} finite numbers, found {found} values",
        path.display()
    )]
    TableColumns {
        path: PathBuf,
        line: usize,
        columns: usize,
        found: usize,
    },
    /// A table line (from 1) with a word that is not a number.
    #[error("{}:{line}: {source}", path.display())]
    TableNumber {
        path: PathBuf,
        line: usize,
        source: std::num::ParseFloatError,
    },
    /// A table without data lines.
    #[error("{}: no data rows", path.display())]
    TableEmpty { path: PathBuf },
    /// A leaf (from 1) with a radius ≤ 0 or a zero normal.
    #[error(
        "{}: leaf {leaf}: radius {radius} must be > 0 and the normal non-zero",
        path.display()
    )]
    Leaf {
        path: PathBuf,
        leaf: usize,
        radius: f64,
    },
    /// A canopy given both padding and a periodic cell.
    #[error("padding and a periodic cell exclude each other")]
    PaddingAndPeriodic,
    /// A render origin that is not finite.
    #[error("render origin {origin} is not finite")]
    RenderOrigin { origin: DVec3 },
    /// More instances than 32-bit ids hold.
    #[error("{count} instances: more than 2³² − 1")]
    TooManyInstances { count: usize },
    /// An instance naming a template that does not exist.
    #[error("instance {instance}: template {template} out of range ({templates} templates)")]
    TemplateOutOfRange {
        instance: usize,
        template: u32,
        templates: usize,
    },
    /// An instance whose translation is not finite.
    #[error("instance {instance}: translation {translation} is not finite")]
    Translation { instance: usize, translation: DVec3 },
    /// An instance whose linear part (columns) is singular or not finite.
    #[error("instance {instance}: linear part {linear:?} is singular or not finite")]
    SingularLinear { instance: usize, linear: [f32; 9] },
    /// An instance whose linear part has no finite f32 inverse.
    #[error("instance {instance}: linear part cannot be inverted in f32")]
    NotInvertible { instance: usize },
    /// A template whose material list is not one per primitive (`kind`: "triangles", "discs").
    #[error("template {template}: {materials} materials for {primitives} {kind}")]
    MaterialCount {
        template: usize,
        materials: usize,
        primitives: usize,
        kind: &'static str,
    },
    /// A template with more primitives than 32-bit ids hold.
    #[error("template {template}: too many {kind}")]
    TooManyPrimitives { template: usize, kind: &'static str },
    /// A triangle naming a vertex that does not exist.
    #[error(
        "template {template}: triangle {triangle} has vertex index {vertex} out of range ({positions} positions)"
    )]
    VertexIndex {
        template: usize,
        triangle: usize,
        vertex: u32,
        positions: usize,
    },
    /// A vertex that is not finite.
    #[error("template {template}: vertex {vertex} is not finite")]
    Vertex { template: usize, vertex: u32 },
    /// A disc with a non-finite centre or a zero or non-finite normal.
    #[error(
        "template {template}: disc {disc} has a non-finite centre or a zero/non-finite normal"
    )]
    DiscGeometry { template: usize, disc: usize },
    /// A disc whose radius is negative or not finite.
    #[error("template {template}: disc {disc} has radius {radius}")]
    DiscRadius {
        template: usize,
        disc: usize,
        radius: f32,
    },
    /// A top-level tree deeper than obvhs' traversal handles.
    #[error(
        "the top-level BVH over {instances} instances has {depth} levels, more than the {max} that obvhs' traversal handles"
    )]
    TlasTooDeep {
        instances: usize,
        depth: usize,
        max: usize,
    },
    /// A tree that cannot be written to the disk cache (logged; never stops a run).
    #[error("{}: {source}", path.display())]
    Cache {
        path: PathBuf,
        source: std::io::Error,
    },
}
