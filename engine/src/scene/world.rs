//! A 3D scene ready for transport: terrain, instanced objects, a ground plane and the material
//! table, under one query interface (`intersect`, `occluded`).
//!
//! Frame: the scene's *local* frame in metres, x east, y north, z height (for bundles the
//! bundle's local frame, i.e. working-CRS coordinates minus `frame.origin`; for canopies the
//! canopy's own coordinates). The plane-parallel atmosphere shares the z axis: a point's altitude
//! is its z.
//!
//! Parts (each optional):
//! * terrain (bundle tiles, [`TerrainBvh`]) whose material comes from the material raster by
//!   nearest lookup of the hit's (x, y) — the *selector*. A terrain triangle seen from below is
//!   black (it can only happen beside the scene's edge, under the terrain skirt).
//! * instanced objects ([`InstanceBvh`]): template meshes and disc clouds, stored once.
//! * a horizontal ground plane `z = altitude` with one material, restricted to a rectangle
//!   (`inside`, a finite soil) and/or outside a rectangle (`outside`, the background around a
//!   bundle's terrain). Seen from below it is black.
//!
//! Self-intersection: a new ray leaving a surface starts at the hit point moved along the
//! geometric normal, to the side it leaves towards, by [`Scene::offset_distance`]: 10 µm plus
//! 10⁻⁶ × the distance from the render origin (f32 resolves 1.2·10⁻⁷ of it; the terrain and the
//! top-level BVH work in f32). It is tested on a terrain 40 km from the origin.

use glam::DVec3;

use super::curvature::Curvature;
use super::error::SceneError;
use super::instances::{InstanceBvh, InstanceHit};
use super::material::SurfaceModel;
use super::sun_clearance::SunClearance;
use super::TerrainBvh;
use bundle::BrdfSpec;

/// Material id of a black (absorbing) surface, outside the material table.
pub const BLACK: u16 = u16::MAX;

/// The material raster of a terrain, georeferenced in the local frame.
#[derive(Clone, Debug)]
pub struct MaterialRaster {
    pub width: usize,
    pub height: usize,
    /// GDAL geotransform in the **local** frame (working CRS minus the frame origin).
    pub geotransform: [f64; 6],
    /// Row-major from the north, raw 8-bit material indices (255: none, drawn black).
    pub data: Vec<u8>,
}

impl MaterialRaster {
    /// Material at local (x, y): nearest cell, clamped to the raster's edges.
    #[inline]
    pub fn lookup(&self, x: f64, y: f64) -> u16 {
        let g = &self.geotransform;
        let col = ((x - g[0]) / g[1]).floor();
        let row = ((y - g[3]) / g[5]).floor();
        let c = (col.max(0.0) as usize).min(self.width - 1);
        let r = (row.max(0.0) as usize).min(self.height - 1);
        match self.data[r * self.width + c] {
            bundle::NO_MATERIAL => BLACK,
            v => v as u16,
        }
    }
}

/// A horizontal plane with one material.
#[derive(Clone, Debug)]
pub struct GroundPlane {
    /// Height, m.
    pub altitude: f64,
    pub material: u16,
    /// It exists only inside this rectangle [xmin, ymin, xmax, ymax] (None: everywhere)…
    pub inside: Option<[f64; 4]>,
    /// …and only outside this one (None: no hole).
    pub outside: Option<[f64; 4]>,
    /// Bent scenes (spherical-shell atmospheres): the plane is the sphere of altitude
    /// `altitude` ([`super::curvature`]); the rectangles apply to its points' (x, y).
    pub sphere: Option<Curvature>,
}

fn in_rect(r: &[f64; 4], x: f64, y: f64) -> bool {
    x >= r[0] && x <= r[2] && y >= r[1] && y <= r[3]
}

impl GroundPlane {
    /// Distance to the plane along the ray, if the ray meets its existing part; returns the
    /// distance and whether the ray comes from above.
    #[inline]
    fn intersect(&self, o: DVec3, d: DVec3, tmax: f64) -> Option<(f64, bool)> {
        let (t, from_above) = match self.sphere {
            Some(c) => c.intersect_sphere(o, d, self.altitude, tmax)?,
            None => {
                if d.z == 0.0 {
                    return None;
                }
                let t = (self.altitude - o.z) / d.z;
                if !(t > 0.0 && t < tmax) {
                    return None;
                }
                (t, d.z < 0.0)
            }
        };
        let p = o + d * t;
        if self.inside.is_some_and(|r| !in_rect(&r, p.x, p.y))
            || self.outside.is_some_and(|r| in_rect(&r, p.x, p.y))
        {
            return None;
        }
        Some((t, from_above))
    }

    /// Unit normal at a point of the plane, on the side `from_above` says.
    #[inline]
    fn normal(&self, p: DVec3, from_above: bool) -> DVec3 {
        let up = match self.sphere {
            Some(c) => (p + DVec3::new(0.0, 0.0, c.radius)).normalize(),
            None => DVec3::Z,
        };
        if from_above {
            up
        } else {
            -up
        }
    }
}

/// The lamps of one bundle template (`[[lights]]` tables, template frame) and where its
/// instances stand (local translation, linear part).
#[derive(Clone, Debug)]
pub struct TemplateLamps {
    pub template: String,
    pub specs: Vec<toml::Table>,
    pub sites: Vec<(DVec3, glam::Mat3)>,
}

/// A hit on the scene.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceHit {
    pub t: f64,
    pub point: DVec3,
    /// Unit geometric normal on the side the ray comes from (`normal·dir < 0`).
    pub normal: DVec3,
    /// Index into the material table, or [`BLACK`].
    pub material: u16,
    /// Whether it is a terrain hit (textures apply to the terrain only).
    pub terrain: bool,
    /// Whether it is the ground: the terrain or the ground plane (not an object); lidar
    /// returns are split by it.
    pub ground: bool,
    /// Whether the ray meets the surface's front face: an object primitive's template normal
    /// side, the upper side of the terrain and of the ground plane. A `rough_dielectric`
    /// material's outside is its front.
    pub front: bool,
}

/// A plane mirror of a scene ([`Scene::mirror_planes`]): the surfaces of `material` with this
/// unit normal (up to sign) reflect sunlight onto other surfaces from one direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MirrorPlane {
    pub normal: DVec3,
    pub material: u16,
    /// The `mirror` solver's complex refractive index (n, k).
    pub index: (f64, f64),
}

impl MirrorPlane {
    /// The Sun's image in this plane seen from the lit side (`sun`: unit vector towards the
    /// Sun): `s − 2(s·n)n`; none for a Sun in the plane.
    pub fn image(&self, sun: DVec3) -> Option<DVec3> {
        let c = sun.dot(self.normal);
        (c.abs() > 1e-9).then(|| sun - 2.0 * c * self.normal)
    }
}

/// What a surface sees of a mirror plane towards the Sun's image in it ([`Scene::mirror_seen`]).
#[derive(Clone, Copy, Debug)]
pub struct MirrorPoint {
    /// The ray's start (off the surface) and the mirror hit.
    pub start: DVec3,
    pub hit: SurfaceHit,
    /// Cosine of the Sun's incidence on the mirror.
    pub cos: f64,
    /// Length of the ray from `start` to the hit, m.
    pub distance: f64,
}

/// Most distinct mirror planes a scene relays sunlight through (each costs one more ray per
/// surface next-event estimate).
pub const MAX_MIRROR_PLANES: usize = 16;

/// The id of the material named `name` in a scene's table, or an error listing the table.
pub fn material_id(materials: &[(String, BrdfSpec)], name: &str) -> Result<usize, SceneError> {
    materials
        .iter()
        .position(|(n, _)| n == name)
        .ok_or_else(|| SceneError::UnknownMaterial {
            name: name.to_string(),
            known: materials.iter().map(|(n, _)| n.clone()).collect(),
        })
}

/// Georeferencing of a scene built from a bundle.
#[derive(Clone, Debug)]
pub struct Georef {
    /// OGC WKT of the working CRS.
    pub wkt: String,
    /// Working-CRS coordinates of the local origin, m.
    pub origin: DVec3,
}

/// A scene: geometry, materials, extent.
pub struct Scene {
    pub name: String,
    pub terrain: Option<(TerrainBvh, MaterialRaster)>,
    pub objects: Option<InstanceBvh>,
    pub ground: Option<GroundPlane>,
    /// Sun clearance maps built so far, one per Sun direction ([`Scene::sun_clearance`]).
    pub(super) sun_maps: std::sync::Mutex<Vec<std::sync::Arc<SunClearance>>>,
    /// (name, model) per material id.
    pub materials: Vec<(String, BrdfSpec)>,
    /// The radiometry solver per material id (`integrator/solver.rs`; missing ids: the
    /// default); set only through [`Scene::set_solvers`] and [`Scene::set_solver`], which keep
    /// `has_null` in step.
    pub(super) solvers: Vec<bundle::SolverSpec>,
    /// Whether a material is `null` (pass-through): shadow rays then skip such surfaces.
    pub(super) has_null: bool,
    /// Whether a material is a pane (`thin_dielectric`), found on first use: shadow rays then
    /// cross panes ([`Scene::visibility`]).
    pub(super) panes: std::sync::OnceLock<bool>,
    /// The scene's plane mirrors, found on first use ([`Scene::mirror_planes`]; reset with
    /// the solvers).
    pub(super) mirror_planes: std::sync::OnceLock<Vec<MirrorPlane>>,
    pub georef: Option<Georef>,
    /// Horizontal extent of the scene's content [xmin, ymin, xmax, ymax] (local frame), m.
    pub extent: [f64; 4],
    /// Lowest and highest point of the geometry, m.
    pub z_range: [f64; 2],
    /// Mean terrain height (reference height of ortho projections), m.
    pub reference_height: f64,
    /// Where the f32 geometry is centred (local frame).
    pub render_origin: DVec3,
    /// Approximate memory of geometry and acceleration structures, bytes.
    pub memory_bytes: usize,
    /// Periodic scenes: the unit cell [xmin, ymin, xmax, ymax] (local frame); rays leaving it
    /// re-enter through the opposite wall.
    pub periodic: Option<[f64; 4]>,
    /// A bundle's polygonal area of interest (local frame), when it has one.
    pub area_mask: Option<std::sync::Arc<super::area_mask::AreaMask>>,
    /// Bent scenes (under spherical-shell atmospheres): the sphere the scene is bent onto; the
    /// scene's coordinates are then the bent frame of [`super::curvature`] and `z_range` holds
    /// bent heights.
    pub curvature: Option<Curvature>,
    /// Reflectance textures of terrain materials, and the texture of each material id.
    pub textures: Vec<super::texture::Texture>,
    pub texture_of: Vec<Option<usize>>,
    /// Kinetic temperature per material id, K (thermal emission; `None`: not given).
    pub temperatures: Vec<Option<f64>>,
    /// Land-surface temperature of terrain hits (`scene.land_surface_temperature`).
    pub lst: Option<super::texture::TemperatureMap>,
    /// Lamps that the bundle's templates carry (streetlights), with the instances that carry
    /// them; lit when the experiment sets `scene.lamps = true`.
    pub template_lamps: Vec<TemplateLamps>,
    /// Time to read the inputs and to build the BVHs, s.
    pub load_seconds: f64,
    pub build_seconds: f64,
}

impl std::fmt::Debug for Scene {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Scene")
            .field("name", &self.name)
            .field(
                "terrain_triangles",
                &self.terrain.as_ref().map(|t| t.0.triangle_count()),
            )
            .field(
                "instances",
                &self.objects.as_ref().map(|o| o.instance_count()),
            )
            .field("ground", &self.ground)
            .field("materials", &self.materials.len())
            .field("extent", &self.extent)
            .field("z_range", &self.z_range)
            .finish()
    }
}

impl Scene {
    /// The [`SunClearance`] map of the unit direction `sun` (built on the first call for that
    /// direction, then shared); `None` for periodic scenes (their rays wrap around), a Sun not
    /// above the horizontal, or a scene without terrain and objects.
    pub fn sun_clearance(&self, sun: DVec3) -> Option<std::sync::Arc<SunClearance>> {
        if self.periodic.is_some() {
            return None;
        }
        let mut maps = self.sun_maps.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(m) = maps.iter().find(|m| m.dir == sun) {
            return Some(m.clone());
        }
        let terrain = self.terrain.as_ref().map(|(t, _)| t);
        let boxes = || {
            terrain
                .into_iter()
                .flat_map(|t| t.triangle_boxes())
                .chain(self.objects.iter().flat_map(|o| o.leaf_boxes()))
        };
        let t0 = std::time::Instant::now();
        let map = std::sync::Arc::new(SunClearance::new(sun, boxes)?);
        tracing::debug!(
            "Sun clearance map for {sun}: {} KiB in {:.3} s",
            map.memory_bytes() / 1024,
            t0.elapsed().as_secs_f64()
        );
        // A few directions at most per run (PICS acquisitions): keep the last 8.
        if maps.len() >= 8 {
            maps.remove(0);
        }
        maps.push(map.clone());
        Some(map)
    }

    /// Offset that moves a new ray off the surface it starts on (see the module header).
    #[inline]
    pub fn offset_distance(&self, p: DVec3) -> f64 {
        1e-5 + 1e-6 * (p - self.render_origin).abs().max_element()
    }

    /// The start of a ray leaving a surface at `p` with normal `n` towards `dir`.
    #[inline]
    pub fn offset(&self, p: DVec3, n: DVec3, dir: DVec3) -> DVec3 {
        let e = self.offset_distance(p);
        if n.dot(dir) >= 0.0 {
            p + n * e
        } else {
            p - n * e
        }
    }

    /// Closest hit of `o + t·d` with `0 < t < tmax` (`d` unit). In a periodic scene the ray
    /// is followed cell by cell (positions wrapped into the cell) and the hit point is returned
    /// in cell coordinates.
    pub fn intersect(&self, o: DVec3, d: DVec3, tmax: f64) -> Option<SurfaceHit> {
        match self.periodic {
            None => self.intersect_once(o, d, tmax),
            Some(cell) => {
                let mut hit = None;
                self.walk_cells(cell, o, d, tmax, |p, tacc, seg| {
                    if let Some(mut h) = self.intersect_once(p, d, seg) {
                        h.t += tacc;
                        hit = Some(h);
                        true
                    } else {
                        false
                    }
                });
                hit
            }
        }
    }

    /// Follow the ray `o + t·d`, `t < tmax`, through the periodic cell `cell`: `f(p, t0, len)`
    /// gets each straight piece inside the cell (start `p` in cell coordinates, distance `t0`
    /// already travelled, length `len`) and returns true to stop. Pieces start once the ray is
    /// within the geometry's heights and end when it leaves them for good.
    fn walk_cells(
        &self,
        cell: [f64; 4],
        o: DVec3,
        d: DVec3,
        tmax: f64,
        mut f: impl FnMut(DVec3, f64, f64) -> bool,
    ) {
        let (zlo, zhi) = (self.z_range[0], self.z_range[1]);
        let mut t = 0.0;
        // Come down (or up) to the geometry's slab first, stopping a hair short of it: a
        // piece must not start on a surface lying in the slab's boundary plane (a flat ground
        // alone makes a slab of zero thickness, which a piece starting on it would never hit).
        let margin = 1e-6 * (1.0 + zhi.abs().max(zlo.abs()));
        if o.z > zhi {
            if d.z >= 0.0 {
                return;
            }
            t = ((o.z - zhi - margin) / -d.z).max(0.0);
        } else if o.z < zlo {
            if d.z <= 0.0 {
                return;
            }
            t = ((zlo - margin - o.z) / d.z).max(0.0);
        }
        let mut p = self.wrap(cell, o + d * t);
        let (w, h) = (cell[2] - cell[0], cell[3] - cell[1]);
        for _ in 0..100_000 {
            if t >= tmax {
                return;
            }
            let ex = if d.x > 0.0 {
                (cell[2] - p.x) / d.x
            } else if d.x < 0.0 {
                (cell[0] - p.x) / d.x
            } else {
                f64::INFINITY
            };
            let ey = if d.y > 0.0 {
                (cell[3] - p.y) / d.y
            } else if d.y < 0.0 {
                (cell[1] - p.y) / d.y
            } else {
                f64::INFINITY
            };
            let exit = ex.min(ey).max(0.0);
            let len = exit.min(tmax - t);
            if f(p, t, len) {
                return;
            }
            if exit >= tmax - t || !exit.is_finite() {
                return;
            }
            t += exit;
            p += d * exit;
            if (d.z >= 0.0 && p.z > zhi + margin) || (d.z <= 0.0 && p.z < zlo - margin) {
                return;
            }
            // Re-enter through the opposite wall.
            if ex <= ey {
                p.x += if d.x > 0.0 { -w } else { w };
            }
            if ey <= ex {
                p.y += if d.y > 0.0 { -h } else { h };
            }
        }
        tracing::warn!("a ray crossed 100 000 periodic cells without leaving the scene; stopped");
    }

    /// `p` wrapped into the periodic cell (unchanged in non-periodic scenes).
    #[inline]
    pub fn wrap_point(&self, p: DVec3) -> DVec3 {
        match self.periodic {
            Some(cell) => self.wrap(cell, p),
            None => p,
        }
    }

    #[inline]
    fn wrap(&self, cell: [f64; 4], p: DVec3) -> DVec3 {
        let (w, h) = (cell[2] - cell[0], cell[3] - cell[1]);
        DVec3::new(
            cell[0] + (p.x - cell[0]).rem_euclid(w),
            cell[1] + (p.y - cell[1]).rem_euclid(h),
            p.z,
        )
    }

    fn intersect_once(&self, o: DVec3, d: DVec3, tmax: f64) -> Option<SurfaceHit> {
        let mut best: Option<SurfaceHit> = None;
        let mut tbest = tmax;
        if let Some((bvh, raster)) = &self.terrain {
            if let Some(h) = bvh.intersect_within(o, d, tbest) {
                {
                    tbest = h.t;
                    let p = o + d * h.t;
                    // The normal faces the ray: pointing down means the ray came from below.
                    let material = if h.normal.z < 0.0 {
                        BLACK
                    } else {
                        raster.lookup(p.x, p.y)
                    };
                    best = Some(SurfaceHit {
                        t: h.t,
                        point: p,
                        normal: h.normal,
                        material,
                        terrain: true,
                        ground: true,
                        front: h.normal.z >= 0.0,
                    });
                }
            }
        }
        if let Some(obj) = &self.objects {
            if let Some(InstanceHit {
                t,
                normal,
                material,
                front,
                ..
            }) = obj.intersect(o, d, 0.0, tbest)
            {
                tbest = t;
                best = Some(SurfaceHit {
                    t,
                    point: o + d * t,
                    normal,
                    material,
                    terrain: false,
                    ground: false,
                    front,
                });
            }
        }
        if let Some(g) = &self.ground {
            if let Some((t, from_above)) = g.intersect(o, d, tbest) {
                let point = o + d * t;
                best = Some(SurfaceHit {
                    t,
                    point,
                    normal: g.normal(point, from_above),
                    material: if from_above { g.material } else { BLACK },
                    terrain: false,
                    ground: true,
                    front: from_above,
                });
            }
        }
        best
    }

    /// Whether a material of the scene is a pane (`thin_dielectric`).
    pub fn has_panes(&self) -> bool {
        *self.panes.get_or_init(|| {
            self.materials
                .iter()
                .any(|(_, s)| matches!(s, BrdfSpec::ThinDielectric(_)))
        })
    }

    /// The fraction of a shadow ray's light that travels from `o + tmax·d` to `o` (`d` unit):
    /// 0 when an opaque surface is in the way, else the product of the transmittances of the
    /// panes it crosses (`models`: the materials at the run wavelength; a thin slab does not
    /// deviate the beam, `bsdf/thin_dielectric.rs`); `null` surfaces are crossed. Without
    /// panes this is `occluded` as 0 or 1.
    pub fn visibility(&self, o: DVec3, d: DVec3, tmax: f64, models: &[SurfaceModel]) -> f64 {
        if !self.has_panes() {
            return if self.occluded(o, d, tmax) { 0.0 } else { 1.0 };
        }
        let (mut o, mut left, mut v) = (o, tmax, 1.0);
        for _ in 0..1024 {
            let Some(h) = self.intersect(o, d, left) else {
                return v;
            };
            if !matches!(self.solver(h.material), bundle::SolverSpec::Null {}) {
                match models
                    .get(h.material as usize)
                    .and_then(|m| m.pane_transmittance(h.normal, d))
                {
                    Some(t) if t > 0.0 => v *= t,
                    _ => return 0.0,
                }
            }
            left -= h.t;
            o = self.offset(h.point, h.normal, d);
        }
        0.0
    }

    /// Whether anything blocks `o + t·d` for `0 < t < tmax` (shadow rays).
    pub fn occluded(&self, o: DVec3, d: DVec3, tmax: f64) -> bool {
        if self.has_null {
            return self.occluded_by_non_null(o, d, tmax);
        }
        match self.periodic {
            None => self.occluded_once(o, d, tmax),
            Some(cell) => {
                let mut blocked = false;
                self.walk_cells(cell, o, d, tmax, |p, _, seg| {
                    blocked = self.occluded_once(p, d, seg);
                    blocked
                });
                blocked
            }
        }
    }

    /// The solver of material id `material` (the default for ids without a material).
    #[inline]
    pub fn solver(&self, material: u16) -> bundle::SolverSpec {
        self.solvers
            .get(material as usize)
            .copied()
            .unwrap_or_default()
    }

    /// Set the solver of every material id (missing ones: the default).
    pub fn set_solvers(&mut self, solvers: Vec<bundle::SolverSpec>) {
        self.has_null = solvers
            .iter()
            .any(|s| matches!(s, bundle::SolverSpec::Null {}));
        self.solvers = solvers;
        self.mirror_planes = Default::default();
    }

    /// The plane mirrors of the scene (surfaces of `mirror` solvers): the flat ground, if it is
    /// one, and every distinct plane of mirror triangles and discs of the objects. Empty when
    /// there are more than [`MAX_MIRROR_PLANES`] (a warning says so once); the terrain's mirrors
    /// and a bent scene's ground (a sphere) are not listed, so their sunlight is not relayed
    /// (`Geometry::sun_via_mirror` of the scene geometries). Bent scenes turn no instance, so
    /// their objects' planes are the templates'.
    pub fn mirror_planes(&self) -> &[MirrorPlane] {
        self.mirror_planes.get_or_init(|| {
            let index = |m: u16| match self.solver(m) {
                bundle::SolverSpec::Mirror {
                    refractive_index,
                    absorption_index,
                } => Some((refractive_index, absorption_index)),
                _ => None,
            };
            if !self.solvers.iter().any(|s| matches!(s, bundle::SolverSpec::Mirror { .. })) {
                return Vec::new();
            }
            let mut planes = Vec::new();
            if let Some(g) = self.ground.as_ref().filter(|g| g.sphere.is_none()) {
                if index(g.material).is_some() {
                    planes.push((DVec3::Z, g.material));
                }
            }
            if let Some(o) = &self.objects {
                let room = MAX_MIRROR_PLANES - planes.len();
                match o.mirror_planes(|m| index(m).is_some(), room) {
                    Some(p) => planes.extend(p),
                    None => {
                        tracing::warn!(
                            "scene `{}`: more than {MAX_MIRROR_PLANES} distinct mirror planes; the sunlight the mirrors reflect onto other surfaces is not estimated (they still reflect what the paths meet)",
                            self.name
                        );
                        return Vec::new();
                    }
                }
            }
            planes
                .into_iter()
                .map(|(normal, material)| MirrorPlane {
                    normal,
                    material,
                    index: index(material).expect("a mirror material"),
                })
                .collect()
        })
    }

    /// Give the material named `name` the solver `spec` (an error names the scene's materials
    /// when there is no such material).
    pub fn set_solver(&mut self, name: &str, spec: bundle::SolverSpec) -> Result<(), SceneError> {
        let id = material_id(&self.materials, name)?;
        let mut table = std::mem::take(&mut self.solvers);
        table.resize(self.materials.len(), bundle::SolverSpec::default());
        table[id] = spec;
        self.set_solvers(table);
        Ok(())
    }

    /// The mirror point of plane `k` ([`Scene::mirror_planes`]) that the surface hit `h` sees
    /// towards the Sun's `image` in it: the ray's start (offset off `h`), the mirror hit (first
    /// along the ray past `null` surfaces, of the plane's material and normal, its face towards
    /// the Sun), the cosine of the Sun's incidence there and the ray's length; `None` when the
    /// ray meets anything else first or nothing. The caller adds the Fresnel reflectance of the
    /// plane's `index`, the Sun's visibility and the transmittances.
    pub fn mirror_seen(
        &self,
        h: &SurfaceHit,
        k: usize,
        image: DVec3,
        sun: DVec3,
    ) -> Option<MirrorPoint> {
        let planes = self.mirror_planes();
        let start = self.offset(h.point, h.normal, image);
        let (mut o, mut distance) = (start, 0.0);
        for _ in 0..64 {
            let m = self.intersect(o, image, f64::INFINITY)?;
            // (`t` runs on across the cells of a periodic scene, where `m.point` is wrapped.)
            distance += m.t;
            if let bundle::SolverSpec::Null {} = self.solver(m.material) {
                o = self.offset(m.point, m.normal, image);
                continue;
            }
            // The hit must lie in plane k: of its material, its normal nearest to k's of all
            // the planes (nearly parallel planes are apart), and within the planes' tolerance.
            let nearest = planes
                .iter()
                .enumerate()
                .filter(|(_, p)| p.material == m.material)
                .map(|(i, p)| (i, m.normal.dot(p.normal).abs()))
                .max_by(|a, b| a.1.total_cmp(&b.1));
            // `m.normal` faces the ray, so the Sun must light that face.
            let cos = sun.dot(m.normal);
            return match nearest {
                Some((i, c)) if i == k && c > 1.0 - super::instances::SAME_PLANE && cos > 0.0 => {
                    Some(MirrorPoint {
                        start,
                        hit: m,
                        cos,
                        distance,
                    })
                }
                _ => None,
            };
        }
        None
    }

    /// Occlusion that looks through `null` materials: closest hits, stepping past each null
    /// surface (a scene with a null material pays a closest-hit search per shadow ray).
    fn occluded_by_non_null(&self, mut o: DVec3, d: DVec3, tmax: f64) -> bool {
        let mut left = tmax;
        for _ in 0..1024 {
            match self.intersect(o, d, left) {
                None => return false,
                Some(h) => {
                    if !matches!(self.solver(h.material), bundle::SolverSpec::Null {}) {
                        return true;
                    }
                    left -= h.t;
                    o = self.offset(h.point, h.normal, d);
                }
            }
        }
        true
    }

    fn occluded_once(&self, o: DVec3, d: DVec3, tmax: f64) -> bool {
        // Nothing above the scene's top can block a ray going up from above it.
        if d.z >= 0.0 && o.z > self.z_range[1] {
            return false;
        }
        if let Some(g) = &self.ground {
            if g.intersect(o, d, tmax).is_some() {
                return true;
            }
        }
        if let Some(obj) = &self.objects {
            if obj.occluded(o, d, 0.0, tmax) {
                return true;
            }
        }
        if let Some((bvh, _)) = &self.terrain {
            if bvh.occluded(o, d, tmax) {
                return true;
            }
        }
        false
    }

    /// Height of the ground (terrain, else the ground plane) below (x, y): a vertical ray from
    /// above the scene, ignoring objects. `None` where there is no ground.
    pub fn ground_height(&self, x: f64, y: f64) -> Option<f64> {
        let top = self.z_range[1] + 10.0;
        let o = self.wrap_point(DVec3::new(x, y, top));
        if let Some((bvh, _)) = &self.terrain {
            if let Some(h) = bvh.intersect(o, -DVec3::Z) {
                return Some(top - h.t);
            }
        }
        self.ground
            .as_ref()
            .and_then(|g| g.intersect(o, -DVec3::Z, f64::INFINITY))
            .map(|(t, _)| top - t)
    }

    /// The temperature (K) of material id `material`, if it has one.
    #[inline]
    pub fn temperature(&self, material: u16) -> Option<f64> {
        self.temperatures.get(material as usize).copied().flatten()
    }

    /// Give the material named `name` the temperature `t` (K; an error names the scene's
    /// materials when there is no such material).
    pub fn set_temperature(&mut self, name: &str, t: f64) -> Result<(), SceneError> {
        let id = material_id(&self.materials, name)?;
        self.temperatures.resize(self.materials.len(), None);
        self.temperatures[id] = Some(t);
        Ok(())
    }

    /// The land-surface temperature (K) under a terrain hit, where the map has a pixel.
    #[inline]
    pub fn land_surface_temperature(&self, h: &SurfaceHit) -> Option<f64> {
        if !h.terrain {
            return None;
        }
        self.lst.as_ref()?.at(h.point.x, h.point.y)
    }

    /// The textured Lambertian reflectance at a terrain hit, if its material has a texture that
    /// covers the hit.
    #[inline]
    pub fn texture_reflectance(&self, h: &SurfaceHit, wavelength_nm: f64) -> Option<f64> {
        if !h.terrain {
            return None;
        }
        let k = (*self.texture_of.get(h.material as usize)?)?;
        self.textures[k].reflectance(h.point.x, h.point.y, wavelength_nm)
    }

    /// `Err` naming the material and parameter when a per-wavelength list (an experiment's own
    /// material) does not have one value for each of the `nw` run wavelengths.
    pub fn check_spectra(&self, nw: usize) -> Result<(), String> {
        for (name, spec) in &self.materials {
            for (param, s) in spec.params() {
                s.check_len(nw)
                    .map_err(|m| format!("material `{name}`: `{param}` {m}"))?;
            }
        }
        Ok(())
    }

    /// The material models at run wavelength `iw` (`wavelength_nm`), indexed by material id.
    pub fn models_at(
        &self,
        iw: usize,
        wavelength_nm: f64,
    ) -> Result<Vec<SurfaceModel>, SceneError> {
        self.materials
            .iter()
            .map(|(name, spec)| {
                SurfaceModel::from_spec(spec, iw, wavelength_nm).map_err(|source| {
                    SceneError::Material {
                        name: name.clone(),
                        source,
                    }
                })
            })
            .collect()
    }

    /// A one-paragraph summary for logs.
    pub fn summary(&self) -> String {
        format!(
            "scene `{}`: {} terrain triangles, {} instances of {} primitives, ground {}, {} materials, extent {:.0} × {:.0} m, heights {:.1}..{:.1} m, memory {:.1} MiB",
            self.name,
            self.terrain.as_ref().map_or(0, |t| t.0.triangle_count()),
            self.objects.as_ref().map_or(0, |o| o.instance_count()),
            self.objects.as_ref().map_or(0, |o| o.primitive_count()),
            if self.ground.is_some() { "yes" } else { "no" },
            self.materials.len(),
            self.extent[2] - self.extent[0],
            self.extent[3] - self.extent[1],
            self.z_range[0],
            self.z_range[1],
            self.memory_bytes as f64 / (1024.0 * 1024.0)
        )
    }
}
