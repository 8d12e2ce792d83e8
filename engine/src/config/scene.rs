//! The `[scene]` table of an experiment (raw serde types) and the resolution of scenes; the
//! measures see a built scene through its [`frame`]. Coordinates in the experiment file are the
//! scene's own: a bundle's working CRS (easting, northing, height in m), a canopy's frame (m).

use std::collections::BTreeMap;
use std::path::Path;

use glam::DVec3;
use serde::Deserialize;

use crate::bundle::{BrdfSpec, Spectrum};
use crate::measure::config::SceneFrame;
use crate::scene::build::{self, Background, CanopyGround, LeafCloud, LeafColumns};
use crate::scene::curvature::Curvature;
use crate::scene::Scene;

#[derive(Clone, Debug, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
#[allow(clippy::large_enum_variant)] // one per experiment
pub enum SceneConfig {
    /// A scene bundle written by `scenegen build`.
    Bundle {
        /// The bundle directory (relative to the experiment file).
        path: String,
        /// What surrounds the terrain (default: a flat plane at the lowest terrain height with the
        /// most frequent material).
        #[serde(default)]
        background: Option<BackgroundConfig>,
        /// Replace materials of the bundle by name: `[scene.materials.grass] type = "rpv" …`.
        #[serde(default)]
        materials: BTreeMap<String, BrdfSpec>,
        /// Spatially varying reflectance of Lambertian materials on the terrain.
        #[serde(default)]
        textures: Vec<TextureConfig>,
        /// Radiometry solvers of materials by name (`[scene.solvers.water] type = "mirror" …`),
        /// replacing the bundle's (`integrator/solver.rs`).
        #[serde(default)]
        solvers: BTreeMap<String, bundle::SolverSpec>,
        /// Kinetic temperatures of materials by name, K (`[scene.temperatures] grass = 295.0`),
        /// replacing the bundle's (thermal emission).
        #[serde(default)]
        temperatures: BTreeMap<String, f64>,
        /// A land-surface-temperature raster (K, one band, the bundle's CRS) for terrain hits.
        #[serde(default)]
        land_surface_temperature: Option<String>,
        /// A CSV of kinetic temperatures by material (`material,temperature_k`, e.g. from
        /// `simulate temperatures`); `temperatures` entries win over its rows.
        #[serde(default)]
        temperature_table: Option<String>,
        /// Light the lamps the bundle's templates carry (streetlights; `[[lights]]`).
        #[serde(default)]
        lamps: bool,
        /// Emitting materials by name (lit windows, screens): their surfaces' radiance,
        /// W m⁻² sr⁻¹ nm⁻¹, the same in every direction (`[scene.emitters] window = 0.002`).
        #[serde(default)]
        emitters: BTreeMap<String, crate::spectral::Spectrum>,
    },
    /// Discrete-leaf canopy (RAMI / ROMC layouts).
    Canopy {
        #[serde(default)]
        objects: Vec<LeafCloudConfig>,
        /// Generated trees (trunk + conical crown), e.g. RAMI HET06.
        #[serde(default)]
        cone_trees: Vec<ConeTreesConfig>,
        #[serde(default)]
        ground: Option<CanopyGroundConfig>,
        #[serde(default)]
        padding: Option<PaddingConfig>,
        /// A periodic unit cell [xmin, ymin, xmax, ymax] (m): the scene repeats it without end.
        #[serde(default)]
        periodic_m: Option<[f64; 4]>,
        /// Radiometry solvers of materials by name (a leaf cloud's `name`, `trunk`, `crown`,
        /// `ground`), as for bundles (`integrator/solver.rs`).
        #[serde(default)]
        solvers: BTreeMap<String, bundle::SolverSpec>,
    },
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TextureConfig {
    /// The bundle material it applies to (must be Lambertian).
    pub material: String,
    /// Raster (GeoTIFF…) in the bundle's CRS; its pixels are reflectances in [0, 1].
    pub file: String,
    /// nm, one per band (default: one band, used at every wavelength).
    #[serde(default)]
    pub wavelengths_nm: Option<Vec<f64>>,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum BackgroundConfig {
    /// Paths leaving the terrain's extent downwards are lost.
    None,
    Flat {
        /// m (default: the lowest terrain height).
        #[serde(default)]
        altitude_m: Option<f64>,
        /// default: the material raster's most frequent material.
        #[serde(default)]
        brdf: Option<Box<BrdfSpec>>,
    },
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LeafCloudConfig {
    #[serde(default)]
    pub name: Option<String>,
    /// Leaf file: one disc per line.
    pub leaves: String,
    /// "r x y z nx ny nz" (default for `.def` files) or "x y z nx ny nz r" (default otherwise).
    #[serde(default)]
    pub columns: Option<ColumnsConfig>,
    /// File of `x y z` translations of the copies (default: one copy at the origin).
    #[serde(default)]
    pub positions: Option<String>,
    /// Bi-Lambertian leaf optics.
    pub reflectance: Spectrum,
    pub transmittance: Spectrum,
}

/// Column order of a leaf file.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
pub enum ColumnsConfig {
    #[serde(rename = "r x y z nx ny nz")]
    RadiusFirst,
    #[serde(rename = "x y z nx ny nz r")]
    RadiusLast,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConeTreesConfig {
    /// File of `x y z` tree base positions.
    pub positions: String,
    /// m.
    pub trunk_radius_m: f64,
    /// m, relative to the tree base: [bottom, top].
    pub trunk_m: [f64; 2],
    pub trunk_brdf: BrdfSpec,
    /// m: the crown cone's height and base radius (its base at the trunk's top).
    pub crown_height_m: f64,
    pub crown_radius_m: f64,
    /// Leaves per crown and their radius (m).
    pub leaves: usize,
    pub leaf_radius_m: f64,
    /// Goel–Strebel leaf inclination parameters: density of x = 2θ/π ∝ (1 − x)^(mu−1)·x^(nu−1),
    /// i.e. x ~ Beta(nu, mu) (`scene::build::goel_strebel_inclination`).
    #[serde(default = "default_mu")]
    pub mu: f64,
    #[serde(default = "default_nu")]
    pub nu: f64,
    pub reflectance: Spectrum,
    pub transmittance: Spectrum,
    /// Number of different crowns generated (assigned to the trees in turn).
    #[serde(default = "default_variants")]
    pub variants: usize,
    #[serde(default)]
    pub seed: u64,
}

fn default_mu() -> f64 {
    1.066
}
fn default_nu() -> f64 {
    1.853
}
fn default_variants() -> usize {
    16
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CanopyGroundConfig {
    /// m.
    #[serde(default)]
    pub altitude_m: f64,
    /// [xmin, ymin, xmax, ymax], m (default: infinite).
    #[serde(default)]
    pub extent_m: Option<[f64; 4]>,
    pub brdf: BrdfSpec,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PaddingConfig {
    /// m: size of the unit cell.
    pub cell_m: [f64; 2],
    /// Copies on each side (the cell is repeated (2p+1)² times).
    pub copies: u32,
}

/// A (key, message) error of scene resolution; the caller adds the file.
pub type SceneErr = (String, String);

/// An experiment's own material, its table file (tabulated BRDFs) taken from the experiment's
/// folder.
fn here(spec: &BrdfSpec, base: &Path) -> BrdfSpec {
    crate::scene::material::SurfaceModel::with_files_in(spec, base)
}

fn check_spec(key: &str, spec: &BrdfSpec) -> Result<(), SceneErr> {
    // A list with one value per run wavelength: every value checked here, its length against
    // the run's wavelengths by `Scene::check_spectra`.
    if spec.params().iter().any(|(_, s)| s.is_per_wavelength()) {
        return spec
            .validate()
            .map_err(|e| (key.to_string(), e.to_string()));
    }
    // Validate at a few wavelengths: spectra are checked for shape, models for ranges.
    for w in [400.0, 550.0, 700.0, 1000.0, 2000.0] {
        crate::scene::material::SurfaceModel::from_spec(spec, 0, w)
            .map_err(|m| (key.to_string(), m.to_string()))?;
    }
    Ok(())
}

/// Scenes built in this process, by configuration: experiments with the same `[scene]` table
/// (e.g. the acquisitions of a calibration-site batch, or the bands of one study) share one
/// scene while any of them holds it. Files changed on disk meanwhile are not re-read.
static CACHE: std::sync::Mutex<Vec<(String, std::sync::Weak<Scene>)>> =
    std::sync::Mutex::new(Vec::new());

/// [`build_scene`], reusing a scene built from the same configuration that is still alive.
pub fn build_scene_shared(
    cfg: &SceneConfig,
    base: &Path,
    bend: Option<Curvature>,
) -> Result<std::sync::Arc<Scene>, SceneErr> {
    let key = format!("{}|{cfg:?}|{bend:?}", base.display());
    {
        let mut cache = CACHE.lock().unwrap_or_else(|e| e.into_inner());
        cache.retain(|(_, w)| w.strong_count() > 0);
        if let Some(s) = cache
            .iter()
            .find(|(k, _)| *k == key)
            .and_then(|(_, w)| w.upgrade())
        {
            tracing::debug!("reusing the scene built for an earlier experiment");
            return Ok(s);
        }
    }
    let s = std::sync::Arc::new(build_scene(cfg, base, bend)?);
    CACHE
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .push((key, std::sync::Arc::downgrade(&s)));
    Ok(s)
}

/// Build the scene of `cfg`; relative paths are taken from `base`. `bend`: bend it onto a
/// sphere (spherical-shell atmospheres; bundles only).
pub fn build_scene(
    cfg: &SceneConfig,
    base: &Path,
    bend: Option<Curvature>,
) -> Result<Scene, SceneErr> {
    if bend.is_some() && !matches!(cfg, SceneConfig::Bundle { .. }) {
        return Err((
            "scene.type".into(),
            "under a spherical-shell atmosphere only bundle scenes are supported (canopies are plane-parallel; use geometry.type = \"plane_parallel\")".into(),
        ));
    }
    match cfg {
        SceneConfig::Bundle {
            path,
            background,
            materials,
            textures,
            solvers,
            temperatures,
            land_surface_temperature,
            temperature_table,
            lamps: _,
            emitters: _,
        } => {
            validate_solvers(solvers)?;
            let bg = bundle_background(background.as_ref(), base)?;
            let mut overrides = Vec::new();
            for (name, spec) in materials {
                let spec = here(spec, base);
                check_spec(&format!("scene.materials.{name}"), &spec)?;
                overrides.push((name.clone(), spec));
            }
            let reqs: Vec<build::TextureRequest> = textures
                .iter()
                .map(|t| build::TextureRequest {
                    material: t.material.clone(),
                    file: base.join(&t.file),
                    wavelengths: t.wavelengths_nm.clone().unwrap_or_else(|| vec![550.0]),
                })
                .collect();
            let dir = base.join(path);
            let mut scene =
                build::from_bundle(&dir, &bg, &overrides, &reqs, bend).map_err(|e| {
                    // The key by the message, as before the error was typed (a bundle whose
                    // path holds "texture " is reported at `scene.textures`).
                    let m = e.to_string();
                    let key = if m.starts_with("texture")
                        || m.contains("two textures")
                        || m.contains("texture ")
                    {
                        "scene.textures"
                    } else {
                        "scene.path"
                    };
                    (key.into(), m)
                })?;
            set_solvers(&mut scene, solvers)?;
            if let Some(file) = temperature_table {
                let table = read_temperature_table(&base.join(file))
                    .map_err(|m| ("scene.temperature_table".to_string(), m))?;
                for (name, t) in table {
                    scene.set_temperature(&name, t).map_err(|m| {
                        (
                            "scene.temperature_table".to_string(),
                            format!("{}: {m}", base.join(file).display()),
                        )
                    })?;
                }
            }
            set_temperatures(&mut scene, temperatures)?;
            if let Some(file) = land_surface_temperature {
                set_land_surface_temperature(&mut scene, &base.join(file))?;
            }
            Ok(scene)
        }
        SceneConfig::Canopy {
            objects,
            cone_trees,
            ground,
            padding,
            periodic_m,
            solvers,
        } => {
            validate_solvers(solvers)?;
            if let Some(c) = periodic_m {
                if !(c.iter().all(|v| v.is_finite()) && c[0] < c[2] && c[1] < c[3]) {
                    return Err((
                        "scene.periodic_m".into(),
                        "must be [xmin, ymin, xmax, ymax] with min < max".into(),
                    ));
                }
                if padding.is_some() {
                    return Err((
                        "scene.padding".into(),
                        "is not used with `periodic_m` (a periodic cell repeats without end)"
                            .into(),
                    ));
                }
            }
            // A ground alone is a flat (periodic) scene: the floor of cloud-field runs.
            if objects.is_empty() && cone_trees.is_empty() && ground.is_none() {
                return Err((
                    "scene.objects".into(),
                    "a canopy needs at least one leaf cloud (`objects`), `cone_trees` or a `ground`".into(),
                ));
            }
            let mut trees = Vec::new();
            for (i, t) in cone_trees.iter().enumerate() {
                trees.push(cone_trees_of(i, t, base)?);
            }
            let mut clouds = Vec::new();
            for (i, o) in objects.iter().enumerate() {
                clouds.push(leaf_cloud_of(i, o, base)?);
            }
            let ground = match ground {
                None => None,
                Some(g) => Some(canopy_ground_of(g, base)?),
            };
            let pad = match padding {
                None => None,
                Some(p) => {
                    if !(p.cell_m[0] > 0.0 && p.cell_m[1] > 0.0) {
                        return Err((
                            "scene.padding.cell_m".into(),
                            "cell sizes must be > 0".into(),
                        ));
                    }
                    Some((p.cell_m, p.copies))
                }
            };
            let mut scene = build::canopy(&clouds, &trees, ground.as_ref(), pad, *periodic_m)
                .map_err(|m| ("scene.objects".to_string(), m.to_string()))?;
            set_solvers(&mut scene, solvers)?;
            Ok(scene)
        }
    }
}

/// Check the settings of every `[scene.solvers]` entry.
fn validate_solvers(solvers: &BTreeMap<String, bundle::SolverSpec>) -> Result<(), SceneErr> {
    for (name, spec) in solvers {
        spec.validate()
            .map_err(|(k, m)| (format!("scene.solvers.{name}.{k}"), m))?;
    }
    Ok(())
}

/// Give the scene's materials their `[scene.solvers]`.
fn set_solvers(
    scene: &mut Scene,
    solvers: &BTreeMap<String, bundle::SolverSpec>,
) -> Result<(), SceneErr> {
    for (name, spec) in solvers {
        scene
            .set_solver(name, *spec)
            .map_err(|m| (format!("scene.solvers.{name}"), m.to_string()))?;
    }
    Ok(())
}

/// What surrounds a bundle's terrain (`scene.background`), checked.
fn bundle_background(
    background: Option<&BackgroundConfig>,
    base: &Path,
) -> Result<Background, SceneErr> {
    Ok(match background {
        None => Background::Flat {
            altitude: None,
            brdf: None,
        },
        Some(BackgroundConfig::None) => Background::None,
        Some(BackgroundConfig::Flat { altitude_m, brdf }) => {
            if let Some(a) = altitude_m {
                if !a.is_finite() {
                    return Err((
                        "scene.background.altitude_m".into(),
                        format!("{a} is not a finite number"),
                    ));
                }
            }
            let brdf = brdf.as_deref().map(|b| here(b, base));
            if let Some(b) = &brdf {
                check_spec("scene.background.brdf", b)?;
            }
            Background::Flat {
                altitude: *altitude_m,
                brdf: brdf.map(Box::new),
            }
        }
    })
}

/// Give the scene's materials their `[scene.temperatures]` (K), checked.
fn set_temperatures(
    scene: &mut Scene,
    temperatures: &BTreeMap<String, f64>,
) -> Result<(), SceneErr> {
    for (name, &t) in temperatures {
        let key = format!("scene.temperatures.{name}");
        if !(t > 0.0 && t <= 10_000.0) {
            return Err((key, format!("{t} K must lie in (0, 10000] K")));
        }
        scene
            .set_temperature(name, t)
            .map_err(|m| (key, m.to_string()))?;
    }
    Ok(())
}

/// The rows of a `material,temperature_k` CSV (header first); errors name the file and line.
fn read_temperature_table(file: &Path) -> Result<Vec<(String, f64)>, String> {
    let text = std::fs::read_to_string(file)
        .map_err(|e| format!("cannot read {}: {e}", file.display()))?;
    let text = crate::util::without_bom(&text);
    let mut lines = text.lines().enumerate();
    match lines.next() {
        Some((_, h)) if h.trim().replace(' ', "") == "material,temperature_k" => {}
        _ => {
            return Err(format!(
                "{}: the first line must be the header `material,temperature_k`",
                file.display()
            ))
        }
    }
    let mut out = Vec::new();
    for (i, line) in lines {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let bad = |m: &str| format!("{} line {}: {m} (\"{line}\")", file.display(), i + 1);
        let (name, t) = line
            .split_once(',')
            .ok_or_else(|| bad("expected `material,temperature_k`"))?;
        let t: f64 = t
            .trim()
            .parse()
            .map_err(|_| bad("the temperature is not a number"))?;
        if !(t > 0.0 && t <= 10_000.0) {
            return Err(bad("the temperature must lie in (0, 10000] K"));
        }
        out.push((name.trim().to_string(), t));
    }
    Ok(out)
}

/// Read the land-surface temperature map `file` into the scene (in the bundle's frame).
fn set_land_surface_temperature(scene: &mut Scene, file: &Path) -> Result<(), SceneErr> {
    let key = "scene.land_surface_temperature".to_string();
    let (wkt, origin) = match &scene.georef {
        Some(g) => (g.wkt.clone(), [g.origin.x, g.origin.y]),
        None => (String::new(), [0.0, 0.0]),
    };
    let map = crate::scene::texture::TemperatureMap::read(file, &wkt, origin)
        .map_err(|m| (key, m.to_string()))?;
    scene.memory_bytes += map.memory_bytes();
    scene.lst = Some(map);
    Ok(())
}

/// The `i`-th `[[scene.cone_trees]]` entry, checked, with its positions read.
fn cone_trees_of(i: usize, t: &ConeTreesConfig, base: &Path) -> Result<build::ConeTrees, SceneErr> {
    let key = format!("scene.cone_trees[{i}]");
    let positions: Vec<DVec3> = build::read_table(&base.join(&t.positions), 3)
        .map_err(|m| (format!("{key}.positions"), m.to_string()))?
        .into_iter()
        .map(|r| DVec3::new(r[0], r[1], r[2]))
        .collect();
    let pos_ok = |v: f64| v.is_finite() && v > 0.0;
    for (name, v) in [
        ("trunk_radius_m", t.trunk_radius_m),
        ("crown_height_m", t.crown_height_m),
        ("crown_radius_m", t.crown_radius_m),
        ("leaf_radius_m", t.leaf_radius_m),
        ("mu", t.mu),
        ("nu", t.nu),
    ] {
        if !pos_ok(v) {
            return Err((format!("{key}.{name}"), format!("{v} must be > 0")));
        }
    }
    if t.trunk_m[0].partial_cmp(&t.trunk_m[1]) != Some(std::cmp::Ordering::Less) {
        return Err((
            format!("{key}.trunk_m"),
            "must be [bottom, top] with bottom < top".into(),
        ));
    }
    if t.leaves == 0 || t.variants == 0 || t.variants > 1024 {
        return Err((
            format!("{key}.leaves"),
            "leaves must be ≥ 1 and variants in 1..=1024".into(),
        ));
    }
    let trunk_brdf = here(&t.trunk_brdf, base);
    check_spec(&format!("{key}.trunk_brdf"), &trunk_brdf)?;
    let leaf_brdf = BrdfSpec::BiLambertian(bundle::BiLambertianSpec {
        reflectance: t.reflectance.clone(),
        transmittance: t.transmittance.clone(),
    });
    check_spec(&key, &leaf_brdf)?;
    Ok(build::ConeTrees {
        positions,
        trunk_radius: t.trunk_radius_m,
        trunk_bottom: t.trunk_m[0],
        trunk_top: t.trunk_m[1],
        trunk_brdf,
        crown_height: t.crown_height_m,
        crown_radius: t.crown_radius_m,
        leaves: t.leaves,
        leaf_radius: t.leaf_radius_m,
        mu: t.mu,
        nu: t.nu,
        leaf_brdf,
        variants: t.variants,
        seed: t.seed,
    })
}

/// The `i`-th `[[scene.objects]]` leaf cloud, checked, with its positions read.
fn leaf_cloud_of(i: usize, o: &LeafCloudConfig, base: &Path) -> Result<LeafCloud, SceneErr> {
    let key = format!("scene.objects[{i}]");
    let leaves = base.join(&o.leaves);
    let columns = match o.columns {
        Some(ColumnsConfig::RadiusFirst) => LeafColumns::RadiusFirst,
        Some(ColumnsConfig::RadiusLast) => LeafColumns::RadiusLast,
        None if o.leaves.ends_with(".def") => LeafColumns::RadiusFirst,
        None => LeafColumns::RadiusLast,
    };
    let positions = match &o.positions {
        None => Vec::new(),
        Some(p) => build::read_table(&base.join(p), 3)
            .map_err(|m| (format!("{key}.positions"), m.to_string()))?
            .into_iter()
            .map(|r| DVec3::new(r[0], r[1], r[2]))
            .collect(),
    };
    let brdf = BrdfSpec::BiLambertian(bundle::BiLambertianSpec {
        reflectance: o.reflectance.clone(),
        transmittance: o.transmittance.clone(),
    });
    check_spec(&key, &brdf)?;
    Ok(LeafCloud {
        name: o.name.clone().unwrap_or_else(|| format!("leaves{i}")),
        leaves,
        columns,
        positions,
        brdf,
    })
}

/// The canopy's ground (`scene.ground`), checked.
fn canopy_ground_of(g: &CanopyGroundConfig, base: &Path) -> Result<CanopyGround, SceneErr> {
    let brdf = here(&g.brdf, base);
    check_spec("scene.ground.brdf", &brdf)?;
    if let Some(e) = g.extent_m {
        if !(e[0] < e[2] && e[1] < e[3]) {
            return Err((
                "scene.ground.extent_m".into(),
                "must be [xmin, ymin, xmax, ymax] with min < max".into(),
            ));
        }
    }
    Ok(CanopyGround {
        altitude: g.altitude_m,
        extent: g.extent_m,
        brdf,
    })
}

/// What the measures need of a built scene (`measure/config.rs`): its extent and top in the
/// local frame, and where the experiment file's coordinates have their origin.
pub fn frame(scene: &Scene) -> SceneFrame {
    SceneFrame {
        extent: scene.extent,
        top: scene.z_range[1],
        origin: scene.georef.as_ref().map(|g| (g.origin.x, g.origin.y)),
        mask: scene.area_mask.clone(),
    }
}
