//! The `build` pipeline: region file → scene bundle.
//!
//! Stages (each with a progress bar on a terminal): working frame; scheme, materials and
//! templates (cheap checks first, so that a typo fails before any raster is read); DEM onto the
//! node grid; land cover onto the material grid and through the scheme; error-bounded TIN;
//! terrain tiles; instances per land-cover tile; checksums; atomic bundle write.
//!
//! The local frame's origin is the DEM node nearest to the centre of the area, at height 0:
//! local = working CRS − origin (metres).

use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use bundle::{Bundle, Manifest, TemplateMesh};
use indicatif::{ProgressBar, ProgressStyle};
use landcover::{MaterialDef, MaterialMap, Scheme};
use rayon::prelude::*;
use sha2::{Digest, Sha256};
use tiles::{Catalogue, PlacedInstance, PlacementRule};

use crate::error::{input, ScenegenError};
use crate::raster::{self, Grid, WorkingFrame};
use crate::region::{LandcoverInput, Region};
use crate::tin::{self, HeightField, SurfaceHeight};

/// Options of a build.
#[derive(Clone, Debug, Default)]
pub struct BuildOptions {
    /// Replace an existing output directory.
    pub force: bool,
    /// Show progress bars (on a terminal).
    pub progress: bool,
}

/// What a build did, for the CLI and the benchmark.
#[derive(Clone, Debug)]
pub struct BuildReport {
    pub manifest: Manifest,
    pub dem_width: usize,
    pub dem_height: usize,
    pub filled_pixels: u64,
    pub stages: Vec<(&'static str, Duration)>,
    /// The buildings extruded from footprints, one record per prism.
    pub buildings: Vec<crate::buildings::BuildingRecord>,
    /// Footprints skipped (id, reason).
    pub buildings_skipped: Vec<(String, String)>,
    /// The city objects read from CityJSON models.
    pub city_objects: Vec<crate::cityjson::CityObjectRecord>,
    /// Trees detected from canopy height, per `[[trees]]` entry.
    pub trees: Vec<Vec<crate::trees::TreeTop>>,
}

/// Add `meshes` as templates, each with one unrotated instance at its origin (working-CRS
/// x, y; the meshes' heights are absolute).
fn place_once(
    meshes: Vec<TemplateMesh>,
    origins: &[[f64; 2]],
    origin: [f64; 3],
    templates: &mut Vec<TemplateMesh>,
    instances: &mut Vec<bundle::Instance>,
) {
    for (mesh, o) in meshes.into_iter().zip(origins) {
        instances.push(bundle::Instance {
            translation: [o[0] - origin[0], o[1] - origin[1], 0.0],
            linear: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            template: templates.len() as u32,
        });
        templates.push(mesh);
    }
}

/// Detect the trees of every `[[trees]]` entry and add their instances (on the terrain TIN,
/// scaled to height and crown, random yaw keyed by the region's seed and the entry).
#[allow(clippy::too_many_arguments)]
fn place_trees(
    region: &Region,
    frame: &WorkingFrame,
    lidar: Option<&crate::pointcloud::PointCloud>,
    dem: &raster::DemData,
    tin: &tin::Tin,
    population: &Population,
    origin: [f64; 3],
    instances: &mut Vec<bundle::Instance>,
) -> Result<Vec<Vec<crate::trees::TreeTop>>, ScenegenError> {
    let mut all = Vec::new();
    let grid = &dem.grid;
    for (i, spec) in region.trees.iter().enumerate() {
        let (chm, cgrid, src) = crate::trees::load_chm(spec, frame, lidar, |x, y| {
            crate::buildings::ground_at(grid, &dem.heights, x, y)
        })?;
        let tops = crate::trees::detect(&chm, &cgrid, spec.min_height_m, spec.window_m);
        if tops.is_empty() {
            return Err(input(
                &src,
                format!(
                    "no tree of at least {} m in the canopy heights (trees[{i}].min_height_m)",
                    spec.min_height_m
                ),
            ));
        }
        let id = population.ids[&spec.template];
        let tm = &population.templates[id as usize];
        let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
        for p in &tm.positions {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let th = hi[2] as f64;
        let tw = ((hi[0] - lo[0]).max(hi[1] - lo[1])) as f64;
        let surf = SurfaceHeight::new(tin, grid);
        let mut rng = tiles::SplitMix64::keyed(region.seed, 0x7EE5_0000 + i as u64);
        let mut placed = Vec::with_capacity(tops.len());
        let mut outside = 0;
        for top in tops {
            let Some(z) = surf.at(top.x, top.y) else {
                outside += 1;
                continue;
            };
            let sz = top.height / th;
            let sxy = if spec.keep_proportions {
                sz
            } else {
                spec.crown_scale * top.crown / tw
            };
            let yaw = rng.uniform() * std::f64::consts::TAU;
            let (sn, cs) = yaw.sin_cos();
            instances.push(bundle::Instance {
                translation: [top.x - origin[0], top.y - origin[1], z],
                linear: [
                    (cs * sxy) as f32,
                    (sn * sxy) as f32,
                    0.0,
                    (-sn * sxy) as f32,
                    (cs * sxy) as f32,
                    0.0,
                    0.0,
                    0.0,
                    sz as f32,
                ],
                template: id,
            });
            placed.push(top);
        }
        tracing::info!(
            "trees[{i}]: {} trees of `{}` from {} ({} × {} cells of {} m; {outside} tops beyond the terrain skipped)",
            placed.len(),
            spec.template,
            src.display(),
            cgrid.width,
            cgrid.height,
            cgrid.dx
        );
        all.push(placed);
    }
    Ok(all)
}

fn bar(opts: &BuildOptions, msg: &str) -> ProgressBar {
    let pb = if opts.progress && std::io::IsTerminal::is_terminal(&std::io::stderr()) {
        ProgressBar::new_spinner()
    } else {
        ProgressBar::hidden()
    };
    pb.set_style(
        ProgressStyle::with_template("{spinner} [{elapsed_precise}] {msg}")
            .expect("static template"),
    );
    pb.set_message(msg.to_string());
    pb.enable_steady_tick(Duration::from_millis(200));
    pb
}

fn sha256_file(path: &Path) -> Result<(u64, String), ScenegenError> {
    let mut f = std::fs::File::open(path).map_err(|e| input(path, format!("cannot read: {e}")))?;
    let mut h = Sha256::new();
    let mut buf = vec![0u8; 1 << 20];
    let mut n = 0u64;
    loop {
        let k = f
            .read(&mut buf)
            .map_err(|e| input(path, format!("cannot read: {e}")))?;
        if k == 0 {
            break;
        }
        n += k as u64;
        h.update(&buf[..k]);
    }
    Ok((n, h.finalize().iter().map(|b| format!("{b:02x}")).collect()))
}

/// Templates and placement rules resolved against the catalogue and the material table.
struct Population {
    templates: Vec<TemplateMesh>,
    template_files: Vec<PathBuf>,
    /// Class code → rules.
    rules: BTreeMap<i64, Vec<PlacementRule>>,
    /// Template name → id, for every template built.
    ids: BTreeMap<String, u32>,
}

/// Build catalogue template `name` into `pop` (once) and return its id; `key` names the region
/// key that asked for it.
fn template_id(
    name: &str,
    key: (&Path, String),
    region: &Region,
    catalogue: &Catalogue,
    library: &BTreeMap<String, MaterialDef>,
    materials: &mut MaterialMap,
    pop: &mut Population,
) -> Result<u32, ScenegenError> {
    if let Some(&id) = pop.ids.get(name) {
        return Ok(id);
    }
    let (spec, dir) = catalogue.get(name).ok_or_else(|| ScenegenError::Region {
        path: key.0.into(),
        key: key.1.clone(),
        message: format!(
            "unknown template `{name}` (known: {})",
            catalogue.names().join(", ")
        ),
    })?;
    let t = spec.build(dir)?;
    let mut mats = Vec::with_capacity(t.material_names.len());
    for m in &t.material_names {
        let lib_name = spec.library_material(m).ok_or_else(|| ScenegenError::Region {
            path: region.path.clone(),
            key: format!("templates.{}.materials", spec.name),
            message: format!("template material `{m}` maps to no library material (add it to `materials` or set `default_material`)"),
        })?;
        let def = library.get(lib_name).ok_or_else(|| ScenegenError::Region {
            path: region.path.clone(),
            key: format!("templates.{}.materials.{m}", spec.name),
            message: format!("unknown library material `{lib_name}`"),
        })?;
        mats.push(materials.add_material(lib_name, def)?);
    }
    if let Some(f) = &spec.file {
        pop.template_files.push(dir.join(f));
        pop.template_files
            .extend(spec.parts.iter().map(|p| dir.join(p)));
    }
    pop.templates.push(TemplateMesh {
        name: spec.name.clone(),
        source: t.source.clone(),
        materials: t
            .triangle_materials
            .iter()
            .map(|&m| mats[m as usize])
            .collect(),
        positions: t.positions,
        indices: t.indices,
        lamps: spec.lamps.clone(),
    });
    let id = (pop.templates.len() - 1) as u32;
    pop.ids.insert(name.to_string(), id);
    Ok(id)
}

fn resolve_population(
    region: &Region,
    scheme: &Scheme,
    materials: &mut MaterialMap,
) -> Result<Population, ScenegenError> {
    let mut catalogue = Catalogue::builtin();
    catalogue.extend(&region.templates, &region.base_dir());
    let (rules_src, key_root, rules_file): (&[landcover::PopulationRule], &str, PathBuf) =
        match &region.population {
            Some(r) => (r, "population", region.path.clone()),
            None => (
                &scheme.population,
                "population (scheme default)",
                scheme.origin.clone(),
            ),
        };
    let mut library: BTreeMap<String, MaterialDef> = scheme.materials.clone();
    library.extend(region.materials.clone());
    let mut pop = Population {
        templates: Vec::new(),
        template_files: Vec::new(),
        rules: BTreeMap::new(),
        ids: BTreeMap::new(),
    };
    for (i, r) in rules_src.iter().enumerate() {
        let id = template_id(
            &r.template,
            (&rules_file, format!("{key_root}[{i}].template")),
            region,
            &catalogue,
            &library,
            materials,
            &mut pop,
        )?;
        for &c in &r.classes {
            pop.rules.entry(c).or_default().push(PlacementRule {
                template: id,
                density_per_ha: r.density_per_ha,
                scale: r.scale,
                random_rotation: r.random_rotation,
            });
        }
    }
    for (i, t) in region.trees.iter().enumerate() {
        template_id(
            &t.template,
            (&region.path, format!("trees[{i}].template")),
            region,
            &catalogue,
            &library,
            materials,
            &mut pop,
        )?;
    }
    Ok(pop)
}

/// Build the bundle of `region` into `out`.
pub fn build(
    region: &Region,
    out: &Path,
    opts: &BuildOptions,
) -> Result<BuildReport, ScenegenError> {
    // Before any work: an existing output is refused, and `--force` replaces only a bundle.
    if out.exists() && !opts.force {
        return Err(bundle::BundleError::Exists { path: out.into() }.into());
    }
    bundle::check_replaceable(out)?;
    let mut stages = Vec::new();
    let mut t = Instant::now();
    let mut stage = |name: &'static str, t: &mut Instant| {
        stages.push((name, t.elapsed()));
        tracing::info!("{name}: {:.2} s", t.elapsed().as_secs_f64());
        *t = Instant::now();
    };

    // Cheap checks first.
    let frame = WorkingFrame::new(region)?;
    let scheme = Scheme::load(&region.scheme).map_err(|e| match e {
        landcover::SchemeError::UnknownScheme { .. } => ScenegenError::Region {
            path: region.path.clone(),
            key: "landcover.scheme".into(),
            message: e.to_string(),
        },
        other => other.into(),
    })?;
    let mut materials = MaterialMap::new(
        &scheme,
        &region.class_materials,
        &region.materials,
        region.fallback_material.as_deref(),
    )
    .map_err(|e| match e {
        landcover::SchemeError::Invalid { key, message, .. } => ScenegenError::Region {
            path: region.path.clone(),
            key,
            message,
        },
        other => other.into(),
    })?;
    let pb = bar(opts, "templates");
    let population = resolve_population(region, &scheme, &mut materials)?;
    pb.finish_and_clear();
    stage("templates", &mut t);

    let lidar = match &region.lidar {
        Some(l) => {
            let pb = bar(opts, "lidar: reading points");
            let pc = crate::pointcloud::read(&l.files, l.crs.as_deref(), &frame)?;
            pb.finish_and_clear();
            stage("lidar", &mut t);
            Some(pc)
        }
        None => None,
    };
    let pb = bar(opts, "DEM: reading and warping");
    let dem = if let Some(h) = region.dem_flat_m {
        let grid = Grid::dem_nodes(frame.extent, region.dem_spacing_m.expect("checked"));
        raster::DemData {
            grid,
            heights: vec![h as f32; grid.width * grid.height],
            filled: 0,
        }
    } else if region.dem_from_lidar {
        let (l, pc) = (
            region.lidar.as_ref().expect("checked"),
            lidar.as_ref().expect("read"),
        );
        let grid = Grid::dem_nodes(frame.extent, region.dem_spacing_m.expect("checked"));
        let (heights, filled) =
            crate::pointcloud::grid_heights(pc, &l.ground_classes, &grid, &l.files[0])?;
        tracing::info!(
            "DEM from {} lidar ground points (classes {:?}): {} × {} nodes at {} m, {filled} empty cells filled",
            pc.class.iter().filter(|c| l.ground_classes.contains(c)).count(),
            l.ground_classes,
            grid.width,
            grid.height,
            grid.dx
        );
        raster::DemData {
            grid,
            heights,
            filled: filled as u64,
        }
    } else {
        // A mesh DEM becomes a temporary GeoTIFF, removed when `_mesh_dem` drops.
        let (rasterised, _mesh_dem) = crate::mesh_region::with_rasterised_mesh(region)?;
        raster::load_dem(&rasterised, &frame)?
    };
    pb.finish_and_clear();
    let grid = dem.grid;
    stage("dem", &mut t);

    let pb = bar(opts, "land cover: reading, warping, mapping");
    let mgrid = Grid::cells_over(&grid, region.lc_tile_m);
    let (codes, resampling) = crate::landcover_vector::load(region, &frame, &mgrid, scheme.nodata)?;
    let lc_name = match &region.landcover {
        LandcoverInput::File(p) => p.clone(),
        LandcoverInput::Uniform(_) => region.path.clone(),
        LandcoverInput::None => region
            .landcover_vectors
            .first()
            .map_or_else(|| region.path.clone(), |v| v.file.clone()),
    };
    let material_raster = materials.map_raster(&codes, &lc_name, &scheme.name)?;
    pb.finish_and_clear();
    check_instance_budget(
        region,
        &mgrid,
        &codes,
        (grid.width * grid.height) as u64,
        available_memory(),
    )?;
    stage("landcover", &mut t);

    let pb = bar(opts, "terrain: triangulating");
    let field = HeightField {
        width: grid.width,
        height: grid.height,
        h: &dem.heights,
    };
    let tin = tin::build_tin(&field, region.tolerance_m, |round, n| {
        pb.set_message(format!("terrain: round {round}, {n} vertices"))
    });
    pb.finish_and_clear();
    stage("tin", &mut t);

    let cx = 0.5 * (frame.extent[0] + frame.extent[2]);
    let cy = 0.5 * (frame.extent[1] + frame.extent[3]);
    let origin = [
        (cx / grid.dx).round() * grid.dx,
        (cy / grid.dx).round() * grid.dx,
        0.0,
    ];
    let tile_nodes = ((region.terrain_tile_m / grid.dx).round() as u32).max(1);
    let mgt = mgrid.geotransform();
    let (mw, mh) = (
        mgrid.width as f64 * mgrid.dx,
        mgrid.height as f64 * mgrid.dx,
    );
    let pb = bar(opts, "terrain: tiles");
    let tiles_mesh = tin::split_tiles(&tin, &grid, tile_nodes, origin, |x, y| {
        [((x - mgt[0]) / mw) as f32, ((mgt[3] - y) / mh) as f32]
    });
    pb.finish_and_clear();
    stage("tiles", &mut t);

    let pb = bar(opts, "instances");
    let mut instances = place_all(
        &tin,
        &grid,
        &mgrid,
        &codes,
        &population.rules,
        region.seed,
        origin,
    );
    let trees = place_trees(
        region,
        &frame,
        lidar.as_ref(),
        &dem,
        &tin,
        &population,
        origin,
        &mut instances,
    )?;
    // A polygonal area: instances only inside it (the terrain covers its bounding box).
    if let Some(m) = &frame.mask {
        instances
            .retain(|i| m.contains(i.translation[0] + origin[0], i.translation[1] + origin[1]));
    }
    pb.finish_and_clear();
    stage("instances", &mut t);

    let mut templates = population.templates.clone();
    let mut building_inputs = Vec::new();
    let (mut building_records, mut buildings_skipped) = (Vec::new(), Vec::new());
    let mut city_records = Vec::new();
    let mut library: BTreeMap<String, MaterialDef> = scheme.materials.clone();
    library.extend(region.materials.clone());
    let mut material_index = |name: &str| -> Result<u8, ScenegenError> {
        let def = library.get(name).ok_or_else(|| ScenegenError::Region {
            path: region.path.clone(),
            key: "roof_material / wall_material".into(),
            message: format!(
                "unknown material `{name}` (library: {})",
                library.keys().cloned().collect::<Vec<_>>().join(", ")
            ),
        })?;
        Ok(materials.add_material(name, def)?)
    };
    if !region.buildings.is_empty() {
        let pb = bar(opts, "buildings: extruding footprints");
        let out = crate::buildings::build(
            &region.buildings,
            &crate::buildings::Ground {
                frame: &frame,
                grid: &grid,
                heights: &dem.heights,
                lidar: lidar.as_ref(),
                tile_m: region.terrain_tile_m,
                tolerance_m: region.tolerance_m,
            },
            &mut material_index,
        )?;
        place_once(
            out.templates,
            &out.origins,
            origin,
            &mut templates,
            &mut instances,
        );
        building_inputs = out.inputs;
        building_records = out.records;
        buildings_skipped = out.skipped;
        pb.finish_and_clear();
        stage("buildings", &mut t);
    }
    if !region.city_models.is_empty() {
        let pb = bar(opts, "city models: reading CityJSON");
        let out = crate::cityjson::build(
            &region.city_models,
            &frame,
            region.terrain_tile_m,
            &mut material_index,
        )?;
        place_once(
            out.templates,
            &out.origins,
            origin,
            &mut templates,
            &mut instances,
        );
        building_inputs.extend(out.inputs);
        city_records = out.records;
        pb.finish_and_clear();
        stage("city models", &mut t);
    }

    // Provenance.
    let mut inputs = Vec::new();
    let mut add_input = |role: &str, p: &Path| -> Result<(), ScenegenError> {
        let (bytes, sha256) = sha256_file(p)?;
        inputs.push(bundle::InputFile {
            role: role.into(),
            path: p.display().to_string(),
            bytes,
            sha256,
        });
        Ok(())
    };
    match &region.dem_mesh {
        Some(m) => add_input("dem_mesh", &m.path)?,
        None => {
            for p in &region.dem_files {
                add_input("dem", p)?;
            }
        }
    }
    if let LandcoverInput::File(p) = &region.landcover {
        add_input("landcover", p)?;
    }
    for v in &region.landcover_vectors {
        add_input("landcover_vector", &v.file)?;
    }
    for p in &building_inputs {
        add_input("buildings", p)?;
    }
    for t in &region.trees {
        match &t.source {
            crate::trees::ChmSource::Chm(p) => add_input("canopy_height", p)?,
            crate::trees::ChmSource::DsmMinusDtm { dsm, dtm } => {
                add_input("dsm", dsm)?;
                add_input("dtm", dtm)?;
            }
            crate::trees::ChmSource::Lidar { .. } => {}
        }
    }
    if let Some(l) = &region.lidar {
        for p in &l.files {
            add_input("lidar", p)?;
        }
    }
    if region.scheme.ends_with(".toml") {
        add_input("scheme", Path::new(&region.scheme))?;
    }
    for p in &population.template_files {
        add_input("template", p)?;
    }

    let hmin = dem.heights.iter().copied().fold(f32::INFINITY, f32::min) as f64;
    let hmax = dem
        .heights
        .iter()
        .copied()
        .fold(f32::NEG_INFINITY, f32::max) as f64;
    let manifest = Manifest {
        format: bundle::FORMAT_NAME.into(),
        format_version: bundle::FORMAT_VERSION,
        crs: bundle::Crs {
            wkt: frame.wkt.clone(),
            epsg: frame.epsg,
            proj: frame.proj.clone(),
        },
        frame: bundle::LocalFrame {
            kind: "projected_enu".into(),
            origin,
            centre_lon_lat: frame.centre_lon_lat,
            vertical_datum: "as the DEM (not converted)".into(),
        },
        extent: bundle::Extent {
            min: [grid.x0, grid.y(grid.height - 1)],
            max: [grid.x(grid.width - 1), grid.y0],
            height_range: [hmin, hmax],
            lon_lat_bbox: frame.lon_lat_bbox,
        },
        terrain: bundle::Terrain {
            file: String::new(),
            tolerance_m: region.tolerance_m,
            dem_spacing_m: grid.dx,
            dem_samples: (grid.width * grid.height) as u64,
            vertex_count: 0,
            triangle_count: 0,
            tiles: vec![],
        },
        material_raster: bundle::MaterialRaster {
            file: String::new(),
            width: mgrid.width as u32,
            height: mgrid.height as u32,
            geotransform: mgt,
            resampling: resampling.into(),
            histogram: vec![],
        },
        materials: materials.materials.clone(),
        templates: vec![],
        instances: bundle::Instances {
            file: String::new(),
            count: 0,
            per_template: vec![],
        },
        area: frame.mask.as_ref().map(|m| bundle::AreaPolygon {
            wkt: m.wkt(),
            area_m2: crate::area_polygon::area_m2(&m.polygon),
            source: match &region.area {
                crate::region::Area::Polygon { path, .. } => path.display().to_string(),
                _ => String::new(),
            },
        }),
        provenance: bundle::Provenance {
            generator: "scenegen".into(),
            generator_version: env!("CARGO_PKG_VERSION").into(),
            seed: region.seed,
            region_toml: region.text.clone(),
            inputs,
            files: vec![],
        },
    };
    let b = Bundle {
        manifest,
        terrain: tiles_mesh
            .into_iter()
            .map(|m| bundle::TerrainTile {
                id: m.id,
                origin: m.origin,
                positions: m.positions,
                uvs: m.uvs,
                indices: m.indices,
            })
            .collect(),
        templates,
        instances,
        material_raster,
    };
    drop(tin);
    let pb = bar(opts, "writing the bundle");
    let manifest = b.write(out, opts.force)?;
    pb.finish_and_clear();
    stage("write", &mut t);
    Ok(BuildReport {
        manifest,
        dem_width: grid.width,
        dem_height: grid.height,
        filled_pixels: dem.filled,
        stages,
        buildings: building_records,
        buildings_skipped,
        city_objects: city_records,
        trees,
    })
}

/// Place instances on every land-cover tile (rows in parallel, each with its own surface
/// interpolator; the order of the result does not depend on the thread count).
/// Most instances a bundle may hold: 64 bytes each on disk, about 200 bytes each in the
/// renderer's memory with its instance BVH, so 10⁸ instances need some 20 GiB.
pub const MAX_INSTANCES: f64 = 1.0e8;

/// Build memory per instance placed (bytes): 64-byte records, the placement's working copies
/// and the write buffer; measured 138 B from 1.27·10⁶ to 5.07·10⁶ instances on Grenoble.
const BUILD_BYTES_PER_INSTANCE: f64 = 150.0;
/// Build memory per DEM sample (heights, the TIN's vertices and triangles, tiles).
const BUILD_BYTES_PER_DEM_SAMPLE: f64 = 80.0;
/// Build memory per land-cover cell (codes, the material raster).
const BUILD_BYTES_PER_CELL: f64 = 16.0;
/// Build memory of the program and its libraries.
const BUILD_BASE_BYTES: f64 = 64.0 * (1u64 << 20) as f64;

/// Memory this machine can give without swapping (`MemAvailable` of `/proc/meminfo`, bytes),
/// or `$EOSIM_MEMORY_LIMIT` (bytes) where set.
fn available_memory() -> Option<u64> {
    if let Some(v) = std::env::var("EOSIM_MEMORY_LIMIT")
        .ok()
        .and_then(|v| v.trim().parse().ok())
    {
        return Some(v);
    }
    bundle::meminfo_bytes("MemAvailable:")
}

/// Refuse, before placing anything, a build whose memory (instances, DEM, land cover; an
/// estimate) exceeds what the machine has available, or a population whose expected instance
/// count (density ×
/// area of the land-cover cells of its classes) exceeds [`MAX_INSTANCES`], naming the rule that
/// places the most and the memory it would take.
fn check_instance_budget(
    region: &Region,
    mgrid: &Grid,
    codes: &[Option<i64>],
    dem_samples: u64,
    memory: Option<u64>,
) -> Result<(), ScenegenError> {
    let no_rules = Vec::new();
    let rules = region.population.as_ref().unwrap_or(&no_rules);
    let mut cells: BTreeMap<i64, u64> = BTreeMap::new();
    for c in codes.iter().flatten() {
        *cells.entry(*c).or_default() += 1;
    }
    let cell_ha = mgrid.dx * mgrid.dx / 1.0e4;
    let per_rule: Vec<f64> = rules
        .iter()
        .map(|r| {
            let n: u64 = r
                .classes
                .iter()
                .map(|c| cells.get(c).copied().unwrap_or(0))
                .sum();
            n as f64 * cell_ha * r.density_per_ha
        })
        .collect();
    let total: f64 = per_rule.iter().sum();
    let heaviest = per_rule
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1));
    // Memory the build will need (measured, BENCHMARKS.md "scenegen"): per instance placed,
    // per DEM sample, per land-cover cell, and a base; refused above what the machine has.
    let need = BUILD_BASE_BYTES
        + BUILD_BYTES_PER_INSTANCE * total
        + BUILD_BYTES_PER_DEM_SAMPLE * dem_samples as f64
        + BUILD_BYTES_PER_CELL * codes.len() as f64;
    if let Some(limit) = memory.filter(|&m| need > m as f64) {
        let gib = |b: f64| b / (1u64 << 30) as f64;
        let (key, what) = match heaviest {
            Some((k, most)) if BUILD_BYTES_PER_INSTANCE * most > 0.5 * need => (
                format!("population[{k}].density_per_ha"),
                format!("{total:.3e} instances, this rule {most:.3e}"),
            ),
            _ => (
                "dem.spacing_m".to_string(),
                format!(
                    "{dem_samples} DEM samples, {} land-cover cells",
                    codes.len()
                ),
            ),
        };
        return Err(ScenegenError::Region {
            path: region.path.clone(),
            key,
            message: format!(
                "the build would need about {:.1} GiB of memory ({what}), more than the {:.1} GiB this machine has available: lower the densities, coarsen the grids or shrink the area",
                gib(need),
                gib(limit as f64)
            ),
        });
    }
    if total <= MAX_INSTANCES {
        return Ok(());
    }
    let (k, most) = heaviest.expect("a rule places instances");
    Err(ScenegenError::Region {
        path: region.path.clone(),
        key: format!("population[{k}].density_per_ha"),
        message: format!(
            "the population would place about {total:.3e} instances ({:.0} GiB to render; this rule alone {most:.3e}), more than the {MAX_INSTANCES:.0e} a bundle may hold: lower the densities or the area",
            total * 200.0 / (1u64 << 30) as f64
        ),
    })
}

fn place_all(
    tin: &tin::Tin,
    grid: &Grid,
    mgrid: &Grid,
    codes: &[Option<i64>],
    rules: &BTreeMap<i64, Vec<PlacementRule>>,
    seed: u64,
    origin: [f64; 3],
) -> Vec<bundle::Instance> {
    if rules.is_empty() {
        return Vec::new();
    }
    // Land-cover tiles may reach past the DEM's last node by less than a cell: clamp heights
    // to the DEM's extent, and positions to it as well.
    let (xmin, xmax) = (grid.x0, grid.x(grid.width - 1));
    let (ymin, ymax) = (grid.y(grid.height - 1), grid.y0);
    let rows: Vec<Vec<bundle::Instance>> = (0..mgrid.height)
        .into_par_iter()
        .map(|row| {
            let surf = SurfaceHeight::new(tin, grid);
            let mut placed: Vec<PlacedInstance> = Vec::new();
            let mut out = Vec::new();
            for col in 0..mgrid.width {
                let Some(code) = codes[row * mgrid.width + col] else {
                    continue;
                };
                let Some(rs) = rules.get(&code) else { continue };
                let x0 = (mgrid.x(col) - 0.5 * mgrid.dx).max(xmin);
                let y0 = (mgrid.y(row) - 0.5 * mgrid.dx).max(ymin);
                let x1 = (mgrid.x(col) + 0.5 * mgrid.dx).min(xmax);
                let y1 = (mgrid.y(row) + 0.5 * mgrid.dx).min(ymax);
                if x1 <= x0 || y1 <= y0 {
                    continue;
                }
                let refs: Vec<&PlacementRule> = rs.iter().collect();
                placed.clear();
                let tile_index = (row * mgrid.width + col) as u64;
                tiles::place_instances(
                    tile_index,
                    [x0, y0],
                    [x1 - x0, y1 - y0],
                    &refs,
                    seed,
                    |x, y| surf.at(x, y).unwrap_or(f64::NAN),
                    &mut placed,
                );
                for p in &placed {
                    if !p.position[2].is_finite() {
                        continue; // outside the TIN's hull by rounding; never expected
                    }
                    out.push(bundle::Instance {
                        translation: [
                            p.position[0] - origin[0],
                            p.position[1] - origin[1],
                            p.position[2] - origin[2],
                        ],
                        linear: p.linear(),
                        template: p.template,
                    });
                }
            }
            out
        })
        .collect();
    rows.into_iter().flatten().collect()
}
