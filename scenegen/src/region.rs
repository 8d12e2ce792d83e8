//! The region file (`region.toml`): raw serde types (`deny_unknown_fields`) and their
//! validation into a [`Region`] whose values are in range and whose paths are resolved against
//! the region file's folder. Every key, its unit and default: `docs/region.md`.
//! Errors name the region file and the key path (e.g. `terrain.tolerance_m`).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use landcover::{MaterialDef, PopulationRule};
use serde::Deserialize;
use tiles::TemplateSpec;

use crate::error::ScenegenError;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RegionFile {
    #[serde(default)]
    seed: u64,
    #[serde(default = "local")]
    crs: String,
    area: AreaConfig,
    dem: DemConfig,
    #[serde(default)]
    terrain: TerrainConfig,
    landcover: LandcoverConfig,
    #[serde(default)]
    materials: BTreeMap<String, MaterialDef>,
    #[serde(default)]
    templates: Vec<TemplateSpec>,
    #[serde(default)]
    population: Option<Vec<PopulationRule>>,
    #[serde(default)]
    lidar: Option<LidarConfig>,
    #[serde(default)]
    buildings: Vec<BuildingsConfig>,
    #[serde(default)]
    city_models: Vec<CityModelConfig>,
    #[serde(default)]
    trees: Vec<TreesConfig>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct TreesConfig {
    #[serde(default)]
    chm: Option<PathBuf>,
    #[serde(default)]
    dsm: Option<PathBuf>,
    #[serde(default)]
    dtm: Option<PathBuf>,
    #[serde(default)]
    from_lidar: bool,
    #[serde(default)]
    vegetation_classes: Option<Vec<u8>>,
    #[serde(default)]
    exclude_classes: Option<Vec<u8>>,
    template: String,
    #[serde(default = "default_min_tree")]
    min_height_m: f64,
    #[serde(default)]
    window_m: Option<f64>,
    #[serde(default)]
    cell_m: Option<f64>,
    #[serde(default = "one")]
    crown_scale: f64,
    #[serde(default)]
    keep_proportions: bool,
}

fn default_min_tree() -> f64 {
    2.0
}
fn one() -> f64 {
    1.0
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct CityModelConfig {
    file: PathBuf,
    #[serde(default)]
    crs: Option<String>,
    #[serde(default = "default_city_types")]
    types: Vec<String>,
    #[serde(default)]
    lod: Option<String>,
    #[serde(default = "default_roof")]
    roof_material: String,
    #[serde(default = "default_wall")]
    wall_material: String,
}

fn default_city_types() -> Vec<String> {
    vec!["Building".into(), "BuildingPart".into()]
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct LidarConfig {
    files: Vec<PathBuf>,
    #[serde(default)]
    crs: Option<String>,
    #[serde(default = "default_ground_classes")]
    ground_classes: Vec<u8>,
}

fn default_ground_classes() -> Vec<u8> {
    vec![2, 9]
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct BuildingsConfig {
    file: PathBuf,
    #[serde(default)]
    layer: Option<String>,
    #[serde(default)]
    filter: Option<String>,
    #[serde(default)]
    crs: Option<String>,
    #[serde(default)]
    id_attribute: Option<String>,
    #[serde(default)]
    height_attribute: Option<String>,
    #[serde(default)]
    levels_attribute: Option<String>,
    #[serde(default)]
    storey_height_m: Option<f64>,
    #[serde(default)]
    height_m: Option<f64>,
    #[serde(default)]
    height_from_lidar: bool,
    #[serde(default)]
    height_from_dsm: Option<PathBuf>,
    #[serde(default)]
    roof_shape: Option<String>,
    #[serde(default)]
    roof_shape_attribute: Option<String>,
    #[serde(default)]
    roof_pitch_deg: Option<f64>,
    #[serde(default)]
    roof_classes: Option<Vec<u8>>,
    #[serde(default)]
    roof_percentile: Option<f64>,
    #[serde(default)]
    default_height_m: Option<f64>,
    #[serde(default = "default_roof")]
    roof_material: String,
    #[serde(default = "default_wall")]
    wall_material: String,
}

fn default_roof() -> String {
    "roof".into()
}
fn default_wall() -> String {
    "wall".into()
}

fn local() -> String {
    "local".into()
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct AreaConfig {
    /// [west, south, east, north], degrees.
    #[serde(default)]
    bbox: Option<[f64; 4]>,
    /// [lon, lat], degrees.
    #[serde(default)]
    centre: Option<[f64; 2]>,
    /// Side (square) or [east-west, north-south], km.
    #[serde(default)]
    size_km: Option<SizeKm>,
    /// A polygon file (WKT, GeoJSON or any OGR vector file).
    #[serde(default)]
    polygon: Option<PathBuf>,
    /// The polygon's CRS (default: the file's own, else WGS 84 lon/lat).
    #[serde(default)]
    polygon_crs: Option<String>,
}

#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(untagged)]
enum SizeKm {
    Square(f64),
    Rect([f64; 2]),
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct DemConfig {
    #[serde(default)]
    files: Vec<PathBuf>,
    /// A gridded terrain mesh (PLY or OBJ) instead of `files`.
    #[serde(default)]
    mesh: Option<PathBuf>,
    /// [lon, lat] of the mesh's (0, 0), degrees.
    #[serde(default)]
    mesh_origin: Option<[f64; 2]>,
    #[serde(default)]
    spacing_m: Option<f64>,
    #[serde(default = "default_fill")]
    max_fill_pixels: u64,
    /// The DEM is the `[lidar]` ground points gridded at `spacing_m`.
    #[serde(default)]
    from_lidar: bool,
    /// A flat terrain at this height (m) where no DEM exists.
    #[serde(default)]
    flat_m: Option<f64>,
}

fn default_fill() -> u64 {
    64
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct TerrainConfig {
    #[serde(default = "default_tol")]
    tolerance_m: f64,
    #[serde(default = "default_terrain_tile")]
    tile_size_m: f64,
}

impl Default for TerrainConfig {
    fn default() -> Self {
        TerrainConfig {
            tolerance_m: default_tol(),
            tile_size_m: default_terrain_tile(),
        }
    }
}

fn default_tol() -> f64 {
    1.0
}
fn default_terrain_tile() -> f64 {
    5000.0
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct LandcoverConfig {
    #[serde(default)]
    file: Option<PathBuf>,
    /// One class code everywhere, instead of `file`.
    #[serde(default)]
    class: Option<i64>,
    scheme: String,
    #[serde(default = "default_lc_tile")]
    tile_size_m: f64,
    #[serde(default)]
    resampling: Resampling,
    #[serde(default)]
    fallback_material: Option<String>,
    #[serde(default)]
    class_materials: BTreeMap<String, String>,
    /// Polygon layers burnt over the raster (or alone).
    #[serde(default)]
    vector: Vec<VectorConfig>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct VectorConfig {
    file: PathBuf,
    #[serde(default)]
    layer: Option<String>,
    #[serde(default)]
    filter: Option<String>,
    #[serde(default)]
    crs: Option<String>,
    #[serde(default)]
    attribute: Option<String>,
    #[serde(default)]
    class: Option<i64>,
    #[serde(default)]
    values: BTreeMap<String, i64>,
}

fn default_lc_tile() -> f64 {
    100.0
}

/// Resampling of the land cover onto the material grid.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum Resampling {
    /// `mode` when a material cell covers more than one source pixel, else `nearest`.
    #[default]
    Auto,
    /// Most frequent class among the source pixels in the cell.
    Mode,
    /// The source pixel at the cell centre.
    Nearest,
}

/// The area of interest.
#[derive(Clone, Debug, PartialEq)]
pub enum Area {
    /// West, south, east, north, degrees.
    BBox([f64; 4]),
    /// Centre lon, lat (degrees) and size east-west, north-south (metres).
    Centre { lon_lat: [f64; 2], size_m: [f64; 2] },
    /// A polygon read from `path`, in WGS 84 longitude/latitude (degrees).
    Polygon {
        path: PathBuf,
        lon_lat: geo::MultiPolygon<f64>,
    },
}

impl Area {
    pub fn centre(&self) -> [f64; 2] {
        match self {
            Area::BBox(b) => [0.5 * (b[0] + b[2]), 0.5 * (b[1] + b[3])],
            Area::Centre { lon_lat, .. } => *lon_lat,
            Area::Polygon { lon_lat, .. } => {
                let b = crate::area_polygon::bbox(lon_lat);
                [0.5 * (b[0] + b[2]), 0.5 * (b[1] + b[3])]
            }
        }
    }
}

/// Where the land-cover classes come from.
#[derive(Clone, Debug, PartialEq)]
pub enum LandcoverInput {
    /// A raster (any GDAL format and CRS).
    File(PathBuf),
    /// One class code over the whole area (`landcover.class`).
    Uniform(i64),
    /// No raster: only `[[landcover.vector]]` polygons (no data elsewhere).
    None,
}

/// A gridded terrain mesh given as the DEM (`dem.mesh`), rasterised at build time.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshDem {
    pub path: PathBuf,
    /// Longitude and latitude of the mesh's (0, 0), degrees.
    pub origin: [f64; 2],
}

/// A validated region.
#[derive(Clone, Debug)]
pub struct Region {
    pub path: PathBuf,
    pub text: String,
    pub seed: u64,
    /// "local" or a CRS definition for GDAL (EPSG:n, WKT, PROJ).
    pub crs: String,
    pub area: Area,
    /// DEM rasters; empty when the DEM is a mesh (`dem_mesh`) until the build rasterises it.
    pub dem_files: Vec<PathBuf>,
    pub dem_mesh: Option<MeshDem>,
    pub dem_spacing_m: Option<f64>,
    pub max_fill_pixels: u64,
    pub tolerance_m: f64,
    pub terrain_tile_m: f64,
    pub landcover: LandcoverInput,
    /// Polygon layers burnt over `landcover`, in order.
    pub landcover_vectors: Vec<crate::inputs::VectorLandcover>,
    pub scheme: String,
    pub lc_tile_m: f64,
    pub resampling: Resampling,
    pub fallback_material: Option<String>,
    pub class_materials: BTreeMap<i64, String>,
    pub materials: BTreeMap<String, MaterialDef>,
    pub templates: Vec<TemplateSpec>,
    pub population: Option<Vec<PopulationRule>>,
    /// The region's airborne lidar (`[lidar]`).
    pub lidar: Option<LidarSpec>,
    /// The DEM is gridded from the lidar's ground points (`dem.from_lidar`).
    pub dem_from_lidar: bool,
    /// A flat terrain at this height (`dem.flat_m`).
    pub dem_flat_m: Option<f64>,
    pub buildings: Vec<crate::inputs::BuildingsSpec>,
    pub city_models: Vec<crate::inputs::CityModelSpec>,
    pub trees: Vec<crate::inputs::TreesSpec>,
}

/// `[lidar]`: point-cloud files (LAS/LAZ), paths resolved.
#[derive(Clone, Debug, PartialEq)]
pub struct LidarSpec {
    pub files: Vec<PathBuf>,
    pub crs: Option<String>,
    pub ground_classes: Vec<u8>,
}

impl Region {
    pub fn load(path: &Path) -> Result<Region, ScenegenError> {
        let text = std::fs::read_to_string(path).map_err(|source| ScenegenError::ReadRegion {
            path: path.into(),
            source,
        })?;
        Self::from_str(&text, path)
    }

    pub fn from_str(text: &str, path: &Path) -> Result<Region, ScenegenError> {
        let parse = |message: String| ScenegenError::Region {
            path: path.into(),
            key: String::new(),
            message,
        };
        let de = toml::Deserializer::parse(text)
            .map_err(|e| parse(e.to_string().trim_end().to_string()))?;
        let raw: RegionFile =
            serde_path_to_error::deserialize(de).map_err(|e| ScenegenError::Region {
                path: path.into(),
                key: e.path().to_string(),
                message: e.inner().to_string().trim_end().to_string(),
            })?;
        let inv = |key: &str, message: String| ScenegenError::Region {
            path: path.into(),
            key: key.into(),
            message,
        };
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();

        if raw.area.polygon_crs.is_some() && raw.area.polygon.is_none() {
            return Err(inv("area.polygon_crs", "only with `polygon`".into()));
        }
        let a = &raw.area;
        let area = match (a.bbox, a.centre, a.size_km.as_ref(), a.polygon.as_ref()) {
            (None, None, None, Some(file)) => {
                let file = base.join(file);
                let lon_lat =
                    crate::area_polygon::read_lon_lat(&file, raw.area.polygon_crs.as_deref())
                        .map_err(|e| inv("area.polygon", e.to_string()))?;
                Area::Polygon {
                    path: file,
                    lon_lat,
                }
            }
            (_, _, _, Some(_)) => {
                return Err(inv(
                    "area.polygon",
                    "give either `polygon`, `bbox`, or `centre` and `size_km`".into(),
                ))
            }
            (Some(b), None, None, None) => {
                if !(b.iter().all(|v| v.is_finite())
                    && b[0] < b[2]
                    && b[1] < b[3]
                    && b[0] >= -180.0
                    && b[2] <= 180.0
                    && b[1] >= -90.0
                    && b[3] <= 90.0)
                {
                    return Err(inv(
                        "area.bbox",
                        format!("{b:?} must be [west, south, east, north] in degrees with west < east, south < north"),
                    ));
                }
                Area::BBox(b)
            }
            (None, Some(c), Some(s), None) => {
                if !(c[0].abs() <= 180.0 && c[1].abs() < 89.0) {
                    return Err(inv(
                        "area.centre",
                        format!("{c:?} must be [lon, lat] in degrees (|lat| < 89)"),
                    ));
                }
                let s = match *s {
                    SizeKm::Square(v) => [v, v],
                    SizeKm::Rect(v) => v,
                };
                if !(s.iter().all(|v| v.is_finite() && *v > 0.0 && *v <= 1000.0)) {
                    return Err(inv(
                        "area.size_km",
                        format!("{s:?} must be in (0, 1000] km"),
                    ));
                }
                Area::Centre {
                    lon_lat: c,
                    size_m: [s[0] * 1e3, s[1] * 1e3],
                }
            }
            _ => {
                return Err(inv(
                    "area",
                    "give either `bbox`, both `centre` and `size_km`, or `polygon`".into(),
                ))
            }
        };
        let lidar = match &raw.lidar {
            Some(l) => {
                if l.files.is_empty() {
                    return Err(inv("lidar.files", "give at least one LAS/LAZ file".into()));
                }
                Some(LidarSpec {
                    files: l.files.iter().map(|f| base.join(f)).collect(),
                    crs: l.crs.clone(),
                    ground_classes: l.ground_classes.clone(),
                })
            }
            None => None,
        };
        if let Some(h) = raw.dem.flat_m {
            if !(h.is_finite() && (-500.0..=9000.0).contains(&h)) {
                return Err(inv("dem.flat_m", format!("{h} must be in [-500, 9000] m")));
            }
            if !raw.dem.files.is_empty() || raw.dem.mesh.is_some() || raw.dem.from_lidar {
                return Err(inv(
                    "dem.flat_m",
                    "give either `files`, `mesh`, `from_lidar` or `flat_m`".into(),
                ));
            }
            if raw.dem.spacing_m.is_none() {
                return Err(inv(
                    "dem.spacing_m",
                    "required with `flat_m` (the terrain grid's step, e.g. 10)".into(),
                ));
            }
        }
        if raw.dem.from_lidar {
            if lidar.is_none() {
                return Err(inv(
                    "dem.from_lidar",
                    "needs a `[lidar]` table with the point-cloud files".into(),
                ));
            }
            if !raw.dem.files.is_empty() || raw.dem.mesh.is_some() {
                return Err(inv(
                    "dem.from_lidar",
                    "give either `files`, `mesh` or `from_lidar`".into(),
                ));
            }
            if raw.dem.spacing_m.is_none() {
                return Err(inv(
                    "dem.spacing_m",
                    "required with `from_lidar` (the DTM's cell size, e.g. 1.0)".into(),
                ));
            }
        }
        let dem_mesh = match (&raw.dem.mesh, raw.dem.mesh_origin, raw.dem.files.is_empty()) {
            (None, None, _) if raw.dem.from_lidar || raw.dem.flat_m.is_some() => None,
            (None, None, false) => None,
            (None, None, true) => return Err(inv(
                "dem",
                "give `files` (DEM rasters), `mesh` and `mesh_origin` (a gridded terrain mesh), `from_lidar = true` or `flat_m`"
                    .into(),
            )),
            (Some(_), _, false) => {
                return Err(inv(
                    "dem.mesh",
                    "give either `files` or `mesh`, not both".into(),
                ))
            }
            (None, Some(_), _) => {
                return Err(inv(
                    "dem.mesh_origin",
                    "only with `mesh` (the mesh's origin)".into(),
                ))
            }
            (Some(_), None, true) => {
                return Err(inv(
                    "dem.mesh_origin",
                    "a mesh carries no georeference: give [lon, lat] of its (0, 0)".into(),
                ))
            }
            (Some(m), Some(o), true) => {
                if !(o[0].abs() <= 180.0 && o[1].abs() < 89.0) {
                    return Err(inv(
                        "dem.mesh_origin",
                        format!("{o:?} must be [lon, lat] in degrees (|lat| < 89)"),
                    ));
                }
                Some(MeshDem {
                    path: base.join(m),
                    origin: o,
                })
            }
        };
        if let Some(s) = raw.dem.spacing_m {
            if !(s.is_finite() && (0.1..=10_000.0).contains(&s)) {
                return Err(inv(
                    "dem.spacing_m",
                    format!("{s} must be in [0.1, 10000] m"),
                ));
            }
        }
        let t = &raw.terrain;
        if !(t.tolerance_m.is_finite() && t.tolerance_m >= 0.01 && t.tolerance_m <= 1000.0) {
            return Err(inv(
                "terrain.tolerance_m",
                format!("{} must be in [0.01, 1000] m", t.tolerance_m),
            ));
        }
        if !(t.tile_size_m.is_finite() && (100.0..=100_000.0).contains(&t.tile_size_m)) {
            return Err(inv(
                "terrain.tile_size_m",
                format!("{} must be in [100, 100000] m", t.tile_size_m),
            ));
        }
        let lc = &raw.landcover;
        if !(lc.tile_size_m.is_finite() && (0.1..=10_000.0).contains(&lc.tile_size_m)) {
            return Err(inv(
                "landcover.tile_size_m",
                format!("{} must be in [0.1, 10000] m", lc.tile_size_m),
            ));
        }
        let landcover = match (&lc.file, lc.class) {
            (Some(f), None) => LandcoverInput::File(base.join(f)),
            (None, Some(c)) => LandcoverInput::Uniform(c),
            (None, None) if !lc.vector.is_empty() => LandcoverInput::None,
            _ => return Err(inv(
                "landcover",
                "give either `file` (a land-cover raster), `class` (one class code everywhere) or `[[landcover.vector]]` polygon layers"
                    .into(),
            )),
        };
        let mut landcover_vectors = Vec::with_capacity(lc.vector.len());
        for (i, v) in lc.vector.iter().enumerate() {
            use crate::inputs::{CodeSource, VectorLandcover};
            let key = |k: &str| format!("landcover.vector[{i}].{k}");
            let code = match (&v.attribute, v.class) {
                (Some(a), None) => CodeSource::Attribute {
                    name: a.clone(),
                    values: v.values.clone(),
                },
                (None, Some(c)) => {
                    if !v.values.is_empty() {
                        return Err(inv(&key("values"), "only with `attribute`".into()));
                    }
                    CodeSource::Class(c)
                }
                _ => {
                    return Err(inv(
                        &format!("landcover.vector[{i}]"),
                        "give either `attribute` (the field holding each polygon's class) or `class` (one code for the layer)".into(),
                    ))
                }
            };
            landcover_vectors.push(VectorLandcover {
                file: base.join(&v.file),
                layer: v.layer.clone(),
                crs: v.crs.clone(),
                filter: v.filter.clone(),
                code,
            });
        }
        let mut class_materials = BTreeMap::new();
        for (k, v) in &lc.class_materials {
            let code: i64 = k.parse().map_err(|_| {
                inv(
                    &format!("landcover.class_materials.{k}"),
                    "keys must be integer class codes".into(),
                )
            })?;
            class_materials.insert(code, v.clone());
        }
        for (name, m) in &raw.materials {
            landcover::validate_brdf(&m.brdf)
                .map_err(|(k, msg)| inv(&format!("materials.{name}.brdf.{k}"), msg))?;
        }
        for (i, s) in raw.templates.iter().enumerate() {
            s.validate(path, &format!("templates[{i}]"))
                .map_err(|e| match e {
                    tiles::TileError::Invalid { key, message, .. } => inv(&key, message),
                    other => inv(&format!("templates[{i}]"), other.to_string()),
                })?;
        }
        if let Some(rules) = &raw.population {
            for (i, r) in rules.iter().enumerate() {
                landcover::validate_rule(r)
                    .map_err(|(k, m)| inv(&format!("population[{i}].{k}"), m))?;
            }
        }
        let mut buildings = Vec::with_capacity(raw.buildings.len());
        for (i, b) in raw.buildings.iter().enumerate() {
            use crate::inputs::{BuildingsSpec, HeightSource};
            let key = |k: &str| format!("buildings[{i}].{k}");
            let positive = |k: &str, v: Option<f64>| -> Result<(), ScenegenError> {
                match v {
                    Some(x) if !(x.is_finite() && x > 0.0 && x <= 1000.0) => {
                        Err(inv(&key(k), format!("{x} must be in (0, 1000] m")))
                    }
                    _ => Ok(()),
                }
            };
            positive("storey_height_m", b.storey_height_m)?;
            positive("height_m", b.height_m)?;
            positive("default_height_m", b.default_height_m)?;
            let given = [
                b.height_attribute.is_some(),
                b.levels_attribute.is_some(),
                b.height_m.is_some(),
                b.height_from_lidar,
                b.height_from_dsm.is_some(),
            ];
            if given.iter().filter(|&&g| g).count() != 1 {
                return Err(inv(
                    &format!("buildings[{i}]"),
                    "give exactly one height source: `height_attribute`, `levels_attribute`, `height_m`, `height_from_lidar = true` or `height_from_dsm`".into(),
                ));
            }
            if b.storey_height_m.is_some() && b.levels_attribute.is_none() {
                return Err(inv(
                    &key("storey_height_m"),
                    "only with `levels_attribute`".into(),
                ));
            }
            if b.roof_classes.is_some() && !b.height_from_lidar {
                return Err(inv(
                    &key("roof_classes"),
                    "only with `height_from_lidar = true`".into(),
                ));
            }
            if b.roof_percentile.is_some() && !b.height_from_lidar && b.height_from_dsm.is_none() {
                return Err(inv(
                    &key("roof_percentile"),
                    "only with `height_from_lidar = true` or `height_from_dsm`".into(),
                ));
            }
            if b.height_from_lidar && lidar.is_none() {
                return Err(inv(
                    &key("height_from_lidar"),
                    "needs a `[lidar]` table with the point-cloud files".into(),
                ));
            }
            let percentile = b.roof_percentile.unwrap_or(50.0);
            if !(0.0..=100.0).contains(&percentile) {
                return Err(inv(
                    &key("roof_percentile"),
                    format!("{percentile} must be in [0, 100]"),
                ));
            }
            let height = if let Some(a) = &b.height_attribute {
                HeightSource::Attribute(a.clone())
            } else if let Some(a) = &b.levels_attribute {
                HeightSource::Levels {
                    attribute: a.clone(),
                    storey_m: b.storey_height_m.unwrap_or(3.0),
                }
            } else if let Some(h) = b.height_m {
                HeightSource::Constant(h)
            } else if let Some(p) = &b.height_from_dsm {
                HeightSource::Dsm {
                    path: base.join(p),
                    percentile,
                }
            } else {
                HeightSource::Lidar {
                    classes: b.roof_classes.clone().unwrap_or_else(|| vec![6]),
                    percentile,
                }
            };
            let gabled = match b.roof_shape.as_deref() {
                None | Some("flat") => false,
                Some("gabled") => true,
                Some(other) => {
                    return Err(inv(
                        &key("roof_shape"),
                        format!("`{other}`: the shapes are \"flat\" and \"gabled\""),
                    ))
                }
            };
            let pitch = b.roof_pitch_deg.unwrap_or(30.0);
            if !(pitch.is_finite() && pitch > 0.0 && pitch <= 75.0) {
                return Err(inv(
                    &key("roof_pitch_deg"),
                    format!("{pitch} must be in (0, 75] degrees"),
                ));
            }
            if b.roof_pitch_deg.is_some() && !gabled && b.roof_shape_attribute.is_none() {
                return Err(inv(
                    &key("roof_pitch_deg"),
                    "only with `roof_shape = \"gabled\"` or `roof_shape_attribute`".into(),
                ));
            }
            buildings.push(BuildingsSpec {
                roof: crate::inputs::RoofSpec {
                    gabled,
                    attribute: b.roof_shape_attribute.clone(),
                    pitch_deg: pitch,
                },
                file: base.join(&b.file),
                layer: b.layer.clone(),
                crs: b.crs.clone(),
                filter: b.filter.clone(),
                id_attribute: b.id_attribute.clone(),
                height,
                default_height_m: b.default_height_m,
                roof_material: b.roof_material.clone(),
                wall_material: b.wall_material.clone(),
            });
        }
        let mut trees = Vec::with_capacity(raw.trees.len());
        for (i, t) in raw.trees.iter().enumerate() {
            use crate::inputs::{ChmSource, TreesSpec};
            let key = |k: &str| format!("trees[{i}].{k}");
            let source = match (&t.chm, &t.dsm, &t.dtm, t.from_lidar) {
                (Some(c), None, None, false) => ChmSource::Chm(base.join(c)),
                (None, Some(s), Some(d), false) => ChmSource::DsmMinusDtm {
                    dsm: base.join(s),
                    dtm: base.join(d),
                },
                (None, None, None, true) => {
                    if lidar.is_none() {
                        return Err(inv(
                            &key("from_lidar"),
                            "needs a `[lidar]` table with the point-cloud files".into(),
                        ));
                    }
                    ChmSource::Lidar {
                        classes: t.vegetation_classes.clone().unwrap_or_else(|| vec![3, 4, 5]),
                        exclude: t.exclude_classes.clone().unwrap_or_else(|| vec![6]),
                    }
                }
                _ => {
                    return Err(inv(
                        &format!("trees[{i}]"),
                        "give the canopy heights as `chm`, as `dsm` and `dtm`, or as `from_lidar = true`".into(),
                    ))
                }
            };
            if t.vegetation_classes.is_some() && !t.from_lidar {
                return Err(inv(
                    &key("vegetation_classes"),
                    "only with `from_lidar = true`".into(),
                ));
            }
            if t.exclude_classes.is_some() && !t.from_lidar {
                return Err(inv(
                    &key("exclude_classes"),
                    "only with `from_lidar = true`".into(),
                ));
            }
            for (k, v, lo, hi) in [
                ("min_height_m", Some(t.min_height_m), 0.0, 200.0),
                ("window_m", t.window_m, 0.1, 100.0),
                ("cell_m", t.cell_m, 0.05, 100.0),
                ("crown_scale", Some(t.crown_scale), 0.01, 100.0),
            ] {
                if let Some(v) = v {
                    if !(v.is_finite() && v >= lo && v <= hi) {
                        return Err(inv(&key(k), format!("{v} must be in [{lo}, {hi}]")));
                    }
                }
            }
            trees.push(TreesSpec {
                source,
                template: t.template.clone(),
                min_height_m: t.min_height_m.max(1e-3),
                window_m: t.window_m,
                cell_m: t.cell_m,
                crown_scale: t.crown_scale,
                keep_proportions: t.keep_proportions,
            });
        }
        Ok(Region {
            path: path.into(),
            text: text.into(),
            seed: raw.seed,
            crs: raw.crs,
            area,
            dem_files: raw.dem.files.iter().map(|f| base.join(f)).collect(),
            dem_mesh,
            dem_spacing_m: raw.dem.spacing_m,
            max_fill_pixels: raw.dem.max_fill_pixels,
            tolerance_m: t.tolerance_m,
            terrain_tile_m: t.tile_size_m,
            landcover,
            landcover_vectors,
            scheme: if lc.scheme.ends_with(".toml") {
                base.join(&lc.scheme).display().to_string()
            } else {
                lc.scheme.clone()
            },
            lc_tile_m: lc.tile_size_m,
            resampling: lc.resampling,
            fallback_material: lc.fallback_material.clone(),
            class_materials,
            materials: raw.materials,
            templates: raw.templates,
            population: raw.population,
            lidar,
            dem_from_lidar: raw.dem.from_lidar,
            dem_flat_m: raw.dem.flat_m,
            buildings,
            city_models: raw
                .city_models
                .iter()
                .map(|c| crate::inputs::CityModelSpec {
                    file: base.join(&c.file),
                    crs: c.crs.clone(),
                    types: c.types.clone(),
                    lod: c.lod.clone(),
                    roof_material: c.roof_material.clone(),
                    wall_material: c.wall_material.clone(),
                })
                .collect(),
            trees,
        })
    }

    /// Override the terrain tolerance (metres), with the same range check as the file's key.
    pub fn set_tolerance(&mut self, t: f64) -> Result<(), ScenegenError> {
        if !(t.is_finite() && (0.01..=1000.0).contains(&t)) {
            return Err(ScenegenError::Region {
                path: self.path.clone(),
                key: "terrain.tolerance_m (--tolerance-m)".into(),
                message: format!("{t} must be in [0.01, 1000] m"),
            });
        }
        self.tolerance_m = t;
        Ok(())
    }

    /// Folder that relative paths of the region file start from.
    pub fn base_dir(&self) -> PathBuf {
        self.path
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const OK: &str = r#"
seed = 3
[area]
centre = [5.7, 45.2]
size_km = 10
[dem]
files = ["dem.tif"]
[landcover]
file = "lc.tif"
scheme = "corine"
"#;

    /// Rationale: defaults documented in docs/region.md must be the ones applied.
    #[test]
    fn defaults_are_applied() {
        let r = Region::from_str(OK, Path::new("/x/region.toml")).unwrap();
        assert_eq!(r.tolerance_m, 1.0);
        assert_eq!(r.lc_tile_m, 100.0);
        assert_eq!(r.terrain_tile_m, 5000.0);
        assert_eq!(r.max_fill_pixels, 64);
        assert_eq!(r.crs, "local");
        assert_eq!(r.dem_files, vec![PathBuf::from("/x/dem.tif")]);
        assert_eq!(r.landcover, LandcoverInput::File("/x/lc.tif".into()));
        assert_eq!(
            r.area,
            Area::Centre {
                lon_lat: [5.7, 45.2],
                size_m: [10_000.0, 10_000.0]
            }
        );
    }

    /// Rationale: misspelt and out-of-range keys must be errors naming the file and key path.
    #[test]
    fn bad_keys_name_the_key_path() {
        let p = Path::new("region.toml");
        let e = Region::from_str(
            &OK.replace("[dem]", "[terrain]\ntolerance_metres = 2\n[dem]"),
            p,
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("region.toml") && e.contains("tolerance_metres"),
            "{e}"
        );
        let e = Region::from_str(
            &OK.replace("[dem]", "[terrain]\ntolerance_m = -1\n[dem]"),
            p,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("terrain.tolerance_m"), "{e}");
        let e = Region::from_str(&OK.replace("size_km = 10", "size_km = 0"), p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("area.size_km"), "{e}");
        let e = Region::from_str(
            &OK.replace(
                "scheme = \"corine\"",
                "scheme = \"corine\"\ntile_size_m = \"big\"",
            ),
            p,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("landcover.tile_size_m"), "{e}");
        let e = Region::from_str(
            &format!(
                "{OK}\n[[population]]\nclasses = [1]\ntemplate = \"tree\"\ndensity_per_ha = -3\n"
            ),
            p,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("population[0].density_per_ha"), "{e}");
        let e = Region::from_str(
            &format!("{OK}\n[[templates]]\nname = \"t\"\nunit_m = 1\n"),
            p,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("templates[0].file"), "{e}");
    }

    /// Rationale: a mesh DEM needs its georeference, excludes `files`, and its path and the
    /// uniform land cover are taken as given; wrong combinations name the key.
    #[test]
    fn mesh_dem_and_uniform_landcover() {
        let p = Path::new("/x/region.toml");
        let mesh = OK
            .replace(
                "files = [\"dem.tif\"]",
                "mesh = \"t.ply\"\nmesh_origin = [23.39, 28.55]",
            )
            .replace("file = \"lc.tif\"", "class = 60");
        let r = Region::from_str(&mesh, p).unwrap();
        assert_eq!(
            r.dem_mesh,
            Some(MeshDem {
                path: "/x/t.ply".into(),
                origin: [23.39, 28.55]
            })
        );
        assert!(r.dem_files.is_empty());
        assert_eq!(r.landcover, LandcoverInput::Uniform(60));
        let cases = [
            (
                mesh.replace("mesh_origin = [23.39, 28.55]", ""),
                "dem.mesh_origin",
            ),
            (
                mesh.replace("[23.39, 28.55]", "[23.39, 95]"),
                "dem.mesh_origin",
            ),
            (
                mesh.replace("[dem]", "[dem]\nfiles = [\"d.tif\"]"),
                "dem.mesh",
            ),
            (mesh.replace("mesh = \"t.ply\"", ""), "dem.mesh_origin"),
            (mesh.replace("class = 60", ""), "`landcover`"),
            (
                mesh.replace("class = 60", "class = 60\nfile = \"lc.tif\""),
                "`landcover`",
            ),
        ];
        for (text, key) in cases {
            let e = Region::from_str(&text, p).unwrap_err().to_string();
            assert!(e.contains("region.toml") && e.contains(key), "{key}: {e}");
        }
        let e = Region::from_str(&OK.replace("files = [\"dem.tif\"]", ""), p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("`dem`"), "{e}");
    }
}
