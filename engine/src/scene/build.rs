//! Building a [`Scene`] from a scene bundle or from a discrete-leaf canopy description.
//!
//! * Bundle: terrain tiles → one terrain BVH; the material raster → the selector; templates →
//!   bottom-level BVHs and instances → the top level (stored once each); the bundle's material
//!   table (optionally overridden by name) → the scene's. Around the terrain a background ground
//!   plane (default: at the lowest DEM height, with the raster's most frequent material) catches
//!   paths leaving the region; `background = "none"` loses them instead.
//! * Canopy: leaf clouds (discs) read from text files in the RAMI/ROMC layouts, copied at a list
//!   of positions and optionally padded (the whole set repeated on a (2p+1)² grid of cells), over
//!   a Lambertian ground square. See `docs/scenes.md` and `../shared/data/canopy/MANIFEST.md`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::{DVec3, Mat3};

use super::curvature::Curvature;
use super::error::SceneError;
use super::instances::{Disc, InstanceBvh, InstanceTransform, TemplateGeometry};
use super::world::{Georef, GroundPlane, MaterialRaster, Scene};
use super::TerrainBvh;
use bundle::{BrdfSpec, Bundle};

/// Where to put the background around a bundle's terrain.
#[derive(Clone, Debug)]
pub enum Background {
    None,
    Flat {
        /// m; None: the lowest terrain height.
        altitude: Option<f64>,
        /// None: the raster's most frequent material.
        brdf: Option<Box<BrdfSpec>>,
    },
}

/// A reflectance texture request: material name, raster file, wavelength of each band.
#[derive(Clone, Debug)]
pub struct TextureRequest {
    pub material: String,
    pub file: PathBuf,
    pub wavelengths: Vec<f64>,
}

/// The scene's materials in the manifest's order (with `overrides` applied), the map from the
/// manifest's material index to the scene's material id, and whether that map is the identity.
type SceneMaterials = (Vec<(String, BrdfSpec)>, [u8; 256], bool);

/// Load a bundle into a scene. `overrides` replace materials by name (each name must exist).
pub fn from_bundle(
    dir: &Path,
    background: &Background,
    overrides: &[(String, BrdfSpec)],
    textures: &[TextureRequest],
    bend: Option<Curvature>,
) -> Result<Scene, SceneError> {
    let _returned = super::LargeBlocksReturned::new();
    let t0 = Instant::now();
    let mut bundle = Bundle::open(dir)?;
    // The buffers are moved out of the bundle (and freed) as soon as their acceleration
    // structures hold them, so the peak memory holds one copy of each.
    let m = &bundle.manifest;
    let origin = DVec3::from_array(m.frame.origin);
    let extent = [
        m.extent.min[0] - origin.x,
        m.extent.min[1] - origin.y,
        m.extent.max[0] - origin.x,
        m.extent.max[1] - origin.y,
    ];
    let (mut materials, scene_id, identity) = bundle_materials(m, dir, overrides)?;
    let (tex, texture_of) = read_textures(m, origin, &materials, textures)?;
    let t_load = t0.elapsed().as_secs_f64();

    let t1 = Instant::now();
    let terrain = TerrainBvh::new(&bundle, bend);
    drop(std::mem::take(&mut bundle.terrain));
    let render_origin = terrain.render_origin();
    let data = std::mem::take(&mut bundle.material_raster);
    let raster = material_raster(m, origin, data, &scene_id, identity)?;
    let template_lamps = template_lamps(&bundle.templates, &bundle.instances);
    let objects = instance_bvh(
        std::mem::take(&mut bundle.templates),
        std::mem::take(&mut bundle.instances),
        &scene_id,
        identity,
        bend,
        render_origin,
    )?;
    let t_bvh = t1.elapsed().as_secs_f64();

    let mut z_range = m.extent.height_range;
    if bend.is_some() && terrain.triangle_count() > 0 {
        // Bent heights: the terrain's box (padded by a metre at most) bounds them.
        let (lo, hi) = terrain.bounds();
        z_range = [lo.z, hi.z];
    }
    if let Some(o) = &objects {
        let (_, hi) = o.bounds();
        z_range[1] = z_range[1].max(hi.z);
    }
    let ground = match background {
        Background::None => None,
        Background::Flat { altitude, brdf } => {
            let material = background_material(m, brdf.as_deref(), &scene_id, &mut materials)?;
            let altitude = altitude.unwrap_or(m.extent.height_range[0]);
            z_range[0] = z_range[0].min(altitude);
            Some(GroundPlane {
                altitude,
                material,
                inside: None,
                outside: Some(extent),
                sphere: bend,
            })
        }
    };
    let memory_bytes = terrain.memory_bytes()
        + raster.data.len()
        + objects.as_ref().map_or(0, |o| o.memory_bytes());
    let reference_height = 0.5 * (m.extent.height_range[0] + m.extent.height_range[1]);
    // `Bundle::open` has checked that the polygon's WKT reads.
    let area_mask = match &m.area {
        Some(a) => Some(std::sync::Arc::new(super::area_mask::AreaMask::new(
            &a.polygons()
                .map_err(|message| SceneError::Area { message })?,
            [origin.x, origin.y],
        ))),
        None => None,
    };
    let mut temperatures: Vec<Option<f64>> = m.materials.iter().map(|x| x.temperature).collect();
    temperatures.resize(materials.len(), None);
    let mut solvers: Vec<bundle::SolverSpec> = m
        .materials
        .iter()
        .map(|x| x.solver.unwrap_or_default())
        .collect();
    solvers.resize(materials.len(), bundle::SolverSpec::default());
    let mut scene = Scene {
        name: dir.display().to_string(),
        terrain: Some((terrain, raster)),
        objects,
        ground,
        sun_maps: Default::default(),
        mirror_planes: Default::default(),
        materials,
        solvers: Vec::new(),
        has_null: false,
        panes: Default::default(),
        georef: Some(Georef {
            wkt: m.crs.wkt.clone(),
            origin,
        }),
        extent,
        z_range,
        reference_height,
        render_origin,
        memory_bytes: memory_bytes + tex.iter().map(|t| t.memory_bytes()).sum::<usize>(),
        periodic: None,
        area_mask,
        curvature: bend,
        textures: tex,
        texture_of,
        temperatures,
        lst: None,
        template_lamps,
        load_seconds: t_load,
        build_seconds: t_bvh,
    };
    scene.set_solvers(solvers);
    tracing::info!(
        "{} (load {t_load:.2} s, BVH build {t_bvh:.2} s)",
        scene.summary()
    );
    Ok(scene)
}

/// The bundle's materials with `overrides` applied, and the map from manifest index to scene id.
fn bundle_materials(
    m: &bundle::Manifest,
    dir: &Path,
    overrides: &[(String, BrdfSpec)],
) -> Result<SceneMaterials, SceneError> {
    // The scene's material ids are positions in the manifest's table; the raster and the
    // template triangles hold the manifest's `index` of each material (any unique 0–254, not
    // necessarily contiguous). `Bundle::open` has checked that every id used has a material and
    // that every BRDF is within `bundle::BRDF_PARAM_RANGES`.
    // Tables of tabulated BRDFs are files in the bundle's folder.
    let mut materials: Vec<(String, BrdfSpec)> = m
        .materials
        .iter()
        .map(|x| {
            (
                x.name.clone(),
                crate::scene::material::SurfaceModel::with_files_in(&x.brdf, dir),
            )
        })
        .collect();
    let mut scene_id = [u8::MAX; 256];
    for (pos, x) in m.materials.iter().enumerate() {
        scene_id[x.index as usize] = pos as u8; // ≤ 254: at most 255 distinct indices 0–254
    }
    scene_id[bundle::NO_MATERIAL as usize] = bundle::NO_MATERIAL;
    let identity = m
        .materials
        .iter()
        .enumerate()
        .all(|(pos, x)| x.index as usize == pos);
    for (name, spec) in overrides {
        spec.validate().map_err(|source| SceneError::Override {
            name: name.clone(),
            source,
        })?;
        let id = super::world::material_id(&materials, name)?;
        materials[id].1 = spec.clone();
    }
    Ok((materials, scene_id, identity))
}

/// Read the reflectance textures, and which texture (if any) each material has.
fn read_textures(
    m: &bundle::Manifest,
    origin: DVec3,
    materials: &[(String, BrdfSpec)],
    textures: &[TextureRequest],
) -> Result<(Vec<super::texture::Texture>, Vec<Option<usize>>), SceneError> {
    let mut tex = Vec::new();
    let mut texture_of: Vec<Option<usize>> = vec![None; materials.len()];
    for r in textures {
        let Some(id) = materials.iter().position(|(n, _)| *n == r.material) else {
            return Err(SceneError::TextureMaterial {
                file: r.file.clone(),
                material: r.material.clone(),
            });
        };
        if !matches!(materials[id].1, BrdfSpec::Lambertian(_)) {
            return Err(SceneError::TextureNotLambertian {
                file: r.file.clone(),
                material: r.material.clone(),
            });
        }
        if texture_of[id].is_some() {
            return Err(SceneError::TwoTextures {
                material: r.material.clone(),
            });
        }
        texture_of[id] = Some(tex.len());
        tex.push(super::texture::Texture::read(
            &r.file,
            id as u16,
            &r.wavelengths,
            &m.crs.wkt,
            [origin.x, origin.y],
        )?);
    }
    Ok((tex, texture_of))
}

/// The material raster in the scene's frame, its pixels mapped to scene material ids.
fn material_raster(
    m: &bundle::Manifest,
    origin: DVec3,
    mut data: Vec<u8>,
    scene_id: &[u8; 256],
    identity: bool,
) -> Result<MaterialRaster, SceneError> {
    let gt = m.material_raster.geotransform;
    if !identity {
        for v in &mut data {
            *v = scene_id[*v as usize];
        }
    }
    let raster = MaterialRaster {
        width: m.material_raster.width as usize,
        height: m.material_raster.height as usize,
        geotransform: [
            gt[0] - origin.x,
            gt[1],
            gt[2],
            gt[3] - origin.y,
            gt[4],
            gt[5],
        ],
        data,
    };
    if raster.width == 0 || raster.height == 0 || raster.data.len() != raster.width * raster.height
    {
        return Err(SceneError::EmptyMaterialRaster {
            width: raster.width,
            height: raster.height,
            pixels: raster.data.len(),
        });
    }
    Ok(raster)
}

/// The lamps of templates that carry some, with their instances' transforms.
fn template_lamps(
    templates: &[bundle::TemplateMesh],
    instances: &[bundle::Instance],
) -> Vec<super::world::TemplateLamps> {
    let mut out: Vec<super::world::TemplateLamps> = Vec::new();
    let mut slot = vec![usize::MAX; templates.len()];
    for (i, t) in templates.iter().enumerate() {
        if !t.lamps.is_empty() {
            slot[i] = out.len();
            out.push(super::world::TemplateLamps {
                template: t.name.clone(),
                specs: t.lamps.clone(),
                sites: Vec::new(),
            });
        }
    }
    if out.is_empty() {
        return out;
    }
    for inst in instances {
        if let Some(&k) = slot.get(inst.template as usize) {
            if k != usize::MAX {
                let (_, tr) = InstanceTransform::from_bundle(inst);
                out[k].sites.push((tr.translation, tr.linear));
            }
        }
    }
    out
}

/// The instanced objects' BVH (none without instances); the template meshes are freed once
/// converted, and bent scenes stand each instance on the sphere.
fn instance_bvh(
    templates: Vec<bundle::TemplateMesh>,
    instances: Vec<bundle::Instance>,
    scene_id: &[u8; 256],
    identity: bool,
    bend: Option<Curvature>,
    render_origin: DVec3,
) -> Result<Option<InstanceBvh>, SceneError> {
    let geometry: Vec<TemplateGeometry> = templates
        .iter()
        .map(|t| {
            if identity {
                TemplateGeometry::from_mesh(t)
            } else {
                let mut t = t.clone();
                for v in &mut t.materials {
                    *v = scene_id[*v as usize];
                }
                TemplateGeometry::from_mesh(&t)
            }
        })
        .collect();
    drop(templates);
    let instances: Vec<(u32, InstanceTransform)> = super::map_freeing(instances, |inst| {
        let (k, mut tr) = InstanceTransform::from_bundle(&inst);
        // Bent scenes: each instance stands at its anchor's altitude above the sphere.
        if let Some(c) = bend {
            tr.translation = c.bend(tr.translation);
        }
        (k, tr)
    });
    Ok(if instances.is_empty() {
        None
    } else {
        Some(InstanceBvh::new(geometry, instances, render_origin)?)
    })
}

/// The ground plane's material: `brdf` appended as the material `background`, or else the most
/// frequent material of the raster.
fn background_material(
    m: &bundle::Manifest,
    brdf: Option<&BrdfSpec>,
    scene_id: &[u8; 256],
    materials: &mut Vec<(String, BrdfSpec)>,
) -> Result<u16, SceneError> {
    Ok(match brdf {
        Some(spec) => {
            spec.validate()
                .map_err(|source| SceneError::Background { source })?;
            materials.push(("background".into(), spec.clone()));
            (materials.len() - 1) as u16
        }
        None => {
            // The most frequent material of the raster (the histogram counts pixels
            // per manifest index); the first material if the raster has none.
            let h = &m.material_raster.histogram;
            (0..h.len().min(255))
                .filter(|&i| scene_id[i] != u8::MAX && h[i] > 0)
                .max_by_key(|&i| h[i])
                .map_or(0, |i| scene_id[i]) as u16
        }
    })
}

/// One leaf cloud of a canopy.
#[derive(Clone, Debug)]
pub struct LeafCloud {
    pub name: String,
    pub leaves: PathBuf,
    /// Column order of the leaf file.
    pub columns: LeafColumns,
    /// Translations of the copies; empty: one copy at the origin.
    pub positions: Vec<DVec3>,
    pub brdf: BrdfSpec,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LeafColumns {
    /// `radius x y z nx ny nz` (ROMC `.def` files).
    RadiusFirst,
    /// `x y z nx ny nz radius`.
    RadiusLast,
}

/// A Lambertian (or any) ground of a canopy.
#[derive(Clone, Debug)]
pub struct CanopyGround {
    pub altitude: f64,
    /// [xmin, ymin, xmax, ymax]; None: infinite.
    pub extent: Option<[f64; 4]>,
    pub brdf: BrdfSpec,
}

/// Read whitespace-separated numbers, `columns` per line; `#` starts a comment. Errors name the
/// file and line.
pub fn read_table(path: &Path, columns: usize) -> Result<Vec<Vec<f64>>, SceneError> {
    let text = std::fs::read_to_string(path).map_err(|source| SceneError::TableRead {
        path: path.to_path_buf(),
        source,
    })?;
    let text = crate::util::without_bom(&text);
    let mut rows = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let vals: Result<Vec<f64>, _> = line.split_whitespace().map(str::parse::<f64>).collect();
        match vals {
            Ok(v) if v.len() == columns && v.iter().all(|x| x.is_finite()) => rows.push(v),
            Ok(v) => {
                return Err(SceneError::TableColumns {
                    path: path.to_path_buf(),
                    line: i + 1,
                    columns,
                    found: v.len(),
                })
            }
            Err(source) => {
                return Err(SceneError::TableNumber {
                    path: path.to_path_buf(),
                    line: i + 1,
                    source,
                })
            }
        }
    }
    if rows.is_empty() {
        return Err(SceneError::TableEmpty {
            path: path.to_path_buf(),
        });
    }
    Ok(rows)
}

/// Read a leaf file into discs.
pub fn read_leaves(path: &Path, columns: LeafColumns) -> Result<Vec<Disc>, SceneError> {
    let rows = read_table(path, 7)?;
    rows.iter()
        .enumerate()
        .map(|(i, r)| {
            let (rad, c, n) = match columns {
                LeafColumns::RadiusFirst => (r[0], [r[1], r[2], r[3]], [r[4], r[5], r[6]]),
                LeafColumns::RadiusLast => (r[6], [r[0], r[1], r[2]], [r[3], r[4], r[5]]),
            };
            let nv = DVec3::from_array(n);
            if rad <= 0.0 || nv.length() < 1e-6 {
                return Err(SceneError::Leaf {
                    path: path.to_path_buf(),
                    leaf: i + 1,
                    radius: rad,
                });
            }
            let nv = nv.normalize();
            Ok(Disc {
                centre: [c[0] as f32, c[1] as f32, c[2] as f32],
                normal: [nv.x as f32, nv.y as f32, nv.z as f32],
                radius: rad as f32,
            })
        })
        .collect()
}

/// Trees made of a cylindrical trunk and a conical leaf cloud (RAMI HET06), generated with a
/// seeded generator: `variants` different crowns, assigned to the trees in turn.
#[derive(Clone, Debug)]
pub struct ConeTrees {
    pub positions: Vec<DVec3>,
    /// Trunk: radius, bottom and top heights (m, relative to the tree base), BRDF.
    pub trunk_radius: f64,
    pub trunk_bottom: f64,
    pub trunk_top: f64,
    pub trunk_brdf: BrdfSpec,
    /// Crown: a cone with its base at the trunk's top, apex up (m).
    pub crown_height: f64,
    pub crown_radius: f64,
    pub leaves: usize,
    pub leaf_radius: f64,
    /// Goel–Strebel leaf inclination (see [`goel_strebel_inclination`]): 2θ/π ~ Beta(nu, mu);
    /// azimuth uniform.
    pub mu: f64,
    pub nu: f64,
    pub leaf_brdf: BrdfSpec,
    pub variants: usize,
    pub seed: u64,
}

/// A Beta(a, b) number by Jöhnk's method (Ross & Marshak 1991, appendix 1).
fn beta_johnk(a: f64, b: f64, rng: &mut crate::rng::Stream) -> f64 {
    loop {
        let x = rng.next_f64().powf(1.0 / a);
        let y = rng.next_f64().powf(1.0 / b);
        if x + y <= 1.0 && x + y > 0.0 {
            return x / (x + y);
        }
    }
}

/// A leaf inclination θ (rad, of the normal from the vertical) from the Goel–Strebel
/// inverse-beta distribution (Goel & Strebel 1984, "Simple beta distribution representation of
/// leaf orientation in vegetation canopies", Agron. J. 76:800–802), with the parameter names of
/// RAMI-IV and Eradiate: x = 2θ/π has the density
///
/// f(x) = (1 − x)^(μ−1) · x^(ν−1) / B(μ, ν), 0 ≤ x ≤ 1,
///
/// i.e. x ~ Beta(ν, μ), mean ν/(μ + ν). In this convention the planophile set of the paper has
/// μ > ν (2.770, 1.172) and the spherical one μ 1.101, ν 1.930 (mean θ ≈ 57°); RAMI's μ = 1.066,
/// ν = 1.853 (HET06) give mean x 0.635, close to spherical. Beta(μ, ν) would be the mirror image
/// (mean 0.365, planophile). `tests/leaf_angles.rs` checks the moments against a leaf cloud
/// made by another generator (`../shared/data/canopy/hom/hom_leaves.txt`).
pub fn goel_strebel_inclination(mu: f64, nu: f64, rng: &mut crate::rng::Stream) -> f64 {
    std::f64::consts::FRAC_PI_2 * beta_johnk(nu, mu, rng)
}

impl ConeTrees {
    /// The crown of variant `k`: discs uniform in the cone's volume.
    pub fn crown(&self, k: usize) -> Vec<Disc> {
        let mut rng = crate::rng::Stream::new(self.seed, [0x7ee5, k as u64, 0, 0]);
        (0..self.leaves)
            .map(|_| {
                // Height above the cone's base: density ∝ (1 − h/H)².
                let h = self.crown_height * (1.0 - (1.0 - rng.next_f64()).cbrt());
                let rmax = self.crown_radius * (1.0 - h / self.crown_height);
                let r = rmax * rng.next_f64().sqrt();
                let phi = std::f64::consts::TAU * rng.next_f64();
                let theta = goel_strebel_inclination(self.mu, self.nu, &mut rng);
                let az = std::f64::consts::TAU * rng.next_f64();
                let n = crate::frame::direction_from_angles(theta, az);
                Disc {
                    centre: [
                        (r * phi.cos()) as f32,
                        (r * phi.sin()) as f32,
                        (self.trunk_top + h) as f32,
                    ],
                    normal: [n.x as f32, n.y as f32, n.z as f32],
                    radius: self.leaf_radius as f32,
                }
            })
            .collect()
    }

    /// The trunk: a 16-sided prism with a top cap.
    pub fn trunk(&self) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        let k = 16u32;
        let mut pos = Vec::new();
        for i in 0..k {
            let a = std::f64::consts::TAU * i as f64 / k as f64;
            let (x, y) = (self.trunk_radius * a.cos(), self.trunk_radius * a.sin());
            pos.push([x as f32, y as f32, self.trunk_bottom as f32]);
            pos.push([x as f32, y as f32, self.trunk_top as f32]);
        }
        pos.push([0.0, 0.0, self.trunk_top as f32]);
        let c = 2 * k;
        let mut idx = Vec::new();
        for i in 0..k {
            let j = (i + 1) % k;
            let (b0, t0, b1, t1) = (2 * i, 2 * i + 1, 2 * j, 2 * j + 1);
            idx.push([b0, b1, t1]);
            idx.push([b0, t1, t0]);
            idx.push([t0, t1, c]);
        }
        (pos, idx)
    }
}

/// Build a canopy scene. `padding`: (cell size x, y in m, copies p): every copy is repeated at
/// offsets (i·cx, j·cy), |i|, |j| ≤ p.
/// `periodic`: the unit cell [xmin, ymin, xmax, ymax]; the scene repeats it in x and y (every
/// object is also copied into the 8 neighbouring cells so that parts sticking out of a cell are
/// seen from the next one; the ground is infinite).
pub fn canopy(
    clouds: &[LeafCloud],
    trees: &[ConeTrees],
    ground: Option<&CanopyGround>,
    padding: Option<([f64; 2], u32)>,
    periodic: Option<[f64; 4]>,
) -> Result<Scene, SceneError> {
    let t0 = Instant::now();
    let mut templates = Vec::new();
    let mut instances = Vec::new();
    let mut materials: Vec<(String, BrdfSpec)> = Vec::new();
    let offsets: Vec<DVec3> = match (padding, periodic) {
        (Some(_), Some(_)) => return Err(SceneError::PaddingAndPeriodic),
        (None, Some(c)) => {
            let (w, h) = (c[2] - c[0], c[3] - c[1]);
            let mut v = Vec::new();
            for j in -1..=1 {
                for i in -1..=1 {
                    v.push(DVec3::new(i as f64 * w, j as f64 * h, 0.0));
                }
            }
            v
        }
        (None, None) => vec![DVec3::ZERO],
        (Some((cell, p)), None) => {
            let p = p as i64;
            let mut v = Vec::new();
            for j in -p..=p {
                for i in -p..=p {
                    v.push(DVec3::new(i as f64 * cell[0], j as f64 * cell[1], 0.0));
                }
            }
            v
        }
    };
    for (k, c) in clouds.iter().enumerate() {
        let discs = read_leaves(&c.leaves, c.columns)?;
        let n = discs.len();
        materials.push((c.name.clone(), c.brdf.clone()));
        templates.push(TemplateGeometry::Discs {
            discs,
            materials: vec![k as u16; n],
        });
        let pos = if c.positions.is_empty() {
            vec![DVec3::ZERO]
        } else {
            c.positions.clone()
        };
        for o in &offsets {
            for p in &pos {
                instances.push((
                    k as u32,
                    InstanceTransform {
                        translation: *p + *o,
                        linear: Mat3::IDENTITY,
                    },
                ));
            }
        }
    }
    for t in trees {
        let trunk_mat = materials.len() as u16;
        materials.push(("trunk".into(), t.trunk_brdf.clone()));
        let leaf_mat = materials.len() as u16;
        materials.push(("crown".into(), t.leaf_brdf.clone()));
        let (positions, indices) = t.trunk();
        let trunk_tpl = templates.len() as u32;
        let ntri = indices.len();
        templates.push(TemplateGeometry::Triangles {
            positions,
            indices,
            materials: vec![trunk_mat; ntri],
        });
        let first_crown = templates.len() as u32;
        let variants = t.variants.max(1);
        for k in 0..variants {
            templates.push(TemplateGeometry::Discs {
                discs: t.crown(k),
                materials: vec![leaf_mat; t.leaves],
            });
        }
        for o in &offsets {
            for (i, p) in t.positions.iter().enumerate() {
                let tr = InstanceTransform {
                    translation: *p + *o,
                    linear: Mat3::IDENTITY,
                };
                instances.push((trunk_tpl, tr));
                instances.push((first_crown + (i % variants) as u32, tr));
            }
        }
    }
    let objects = InstanceBvh::new(templates, instances, DVec3::ZERO)?;
    let (lo, hi) = objects.bounds();
    let mut extent = [lo.x, lo.y, hi.x, hi.y];
    let mut z_range = [lo.z, hi.z];
    let ground = ground.map(|g| {
        materials.push(("ground".into(), g.brdf.clone()));
        if let Some(e) = g.extent {
            extent = [
                extent[0].min(e[0]),
                extent[1].min(e[1]),
                extent[2].max(e[2]),
                extent[3].max(e[3]),
            ];
        }
        z_range[0] = z_range[0].min(g.altitude);
        z_range[1] = z_range[1].max(g.altitude);
        GroundPlane {
            altitude: g.altitude,
            material: (materials.len() - 1) as u16,
            inside: if periodic.is_some() { None } else { g.extent },
            outside: None,
            sphere: None,
        }
    });
    if let Some(c) = periodic {
        extent = c;
    }
    let memory_bytes = objects.memory_bytes();
    let scene = Scene {
        name: "canopy".into(),
        terrain: None,
        objects: Some(objects),
        sun_maps: Default::default(),
        mirror_planes: Default::default(),
        reference_height: ground.as_ref().map_or(z_range[0], |g| g.altitude),
        ground,
        materials,
        solvers: Vec::new(),
        has_null: false,
        panes: Default::default(),
        georef: None,
        extent,
        z_range,
        render_origin: DVec3::ZERO,
        memory_bytes,
        area_mask: None,
        periodic,
        curvature: None,
        textures: Vec::new(),
        texture_of: Vec::new(),
        temperatures: Vec::new(),
        lst: None,
        template_lamps: Vec::new(),
        load_seconds: 0.0,
        build_seconds: t0.elapsed().as_secs_f64(),
    };
    tracing::info!(
        "{} (built in {:.2} s)",
        scene.summary(),
        t0.elapsed().as_secs_f64()
    );
    Ok(scene)
}

/// The uniform ground of a 1D run as a scene (runs with lamps, `[[lights]]`, whose light is not
/// horizontally uniform): an infinite horizontal plane at `altitude` (m) of material `brdf`
/// (solver `solver`), nothing else; `extent` is the area measures refer to by default.
pub fn flat_ground(
    brdf: BrdfSpec,
    solver: Option<bundle::SolverSpec>,
    temperature: Option<f64>,
    altitude: f64,
    extent: [f64; 4],
) -> Scene {
    let mut scene = Scene {
        name: "flat ground".into(),
        terrain: None,
        objects: None,
        sun_maps: Default::default(),
        mirror_planes: Default::default(),
        reference_height: altitude,
        ground: Some(GroundPlane {
            altitude,
            material: 0,
            inside: None,
            outside: None,
            sphere: None,
        }),
        materials: vec![("ground".into(), brdf)],
        solvers: Vec::new(),
        has_null: false,
        panes: Default::default(),
        georef: None,
        extent,
        z_range: [altitude, altitude],
        render_origin: DVec3::ZERO,
        memory_bytes: 0,
        area_mask: None,
        periodic: None,
        curvature: None,
        textures: Vec::new(),
        texture_of: Vec::new(),
        temperatures: vec![temperature],
        lst: None,
        template_lamps: Vec::new(),
        load_seconds: 0.0,
        build_seconds: 0.0,
    };
    if let Some(s) = solver {
        scene.set_solvers(vec![s]);
    }
    scene
}
