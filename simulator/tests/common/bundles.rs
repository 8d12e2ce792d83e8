//! Synthetic scene bundles for the 3D tests: planar terrains (optionally tilted, far from the
//! frame origin) with a material raster, written with the bundle writer.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use bundle::*;

pub fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("sim-scene-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A planar terrain `z = h0 + sx·x + sy·y` (local frame) over [x0, x0+size] × [y0, y0+size],
/// split into `tiles`² tiles of `n`² quads each, with a material raster of `raster.len()` =
/// `rw²` cells over the same square and the given materials.
pub struct PlaneSpec {
    pub x0: f64,
    pub y0: f64,
    pub size: f64,
    pub h0: f64,
    pub sx: f64,
    pub sy: f64,
    pub tiles: usize,
    pub n: usize,
    pub raster_width: usize,
    pub raster: Vec<u8>,
    pub materials: Vec<(String, BrdfSpec)>,
    /// Working-CRS coordinates of the local origin.
    pub frame_origin: [f64; 3],
    pub wkt: String,
}

pub fn lambertian(r: f64) -> BrdfSpec {
    BrdfSpec::Lambertian(LambertianSpec {
        reflectance: Spectrum::Constant(r),
    })
}

/// A flat square terrain of one Lambertian material `reflectance` at height `h0`, `size` m wide
/// from `x0` (y centred on the origin), 2×2 tiles of 4×4 quads, frame origin (500 000, 4 000 000).
pub fn flat_plane(size: f64, h0: f64, x0: f64, reflectance: f64) -> PlaneSpec {
    PlaneSpec {
        x0,
        y0: -0.5 * size,
        size,
        h0,
        sx: 0.0,
        sy: 0.0,
        tiles: 2,
        n: 4,
        raster_width: 2,
        raster: vec![0; 4],
        materials: vec![("soil".to_string(), lambertian(reflectance))],
        frame_origin: [500_000.0, 4_000_000.0, 0.0],
        wkt: String::new(),
    }
}

/// WKT of UTM 31N (EPSG:32631), written by hand (no GDAL needed to build the bundle).
pub const UTM31N_EPSG: u32 = 32631;

/// The spectral image experiment of the above-scene and first-order-splitting tests: a
/// [`write_two_material_slope`] bundle in `dir` (grass of Lambertian reflectance 0.04 at 440 nm
/// to 0.12 at 660 nm, slope 0.2 / −0.1) under the molecular atmosphere at 440/550/660 nm, the
/// Sun at 40° zenith, walked over wavelength groups with the `[integrator]` lines `integrator`
/// added, and an ortho image `img` of `pixel` m viewed from 10° zenith, `spp` samples.
pub fn spectral_slope_image(
    dir: &Path,
    seed: u64,
    integrator: &str,
    pixel: f64,
    spp: u64,
) -> String {
    let grass = BrdfSpec::Lambertian(LambertianSpec {
        reflectance: Spectrum::Table {
            wavelengths_nm: vec![440.0, 660.0],
            values: vec![0.04, 0.12],
        },
    });
    let b = write_two_material_slope(dir, grass, 0.2, -0.1, 8);
    format!(
        "seed = {seed}\n[spectral]\nwavelengths = [440.0, 550.0, 660.0]\n\
         [atmosphere]\ntype = \"molecular\"\n\
         [illumination]\ntype = \"directional\"\nzenith = 40.0\nazimuth = 30.0\n\
         [integrator]\nspectral_walk = \"alis\"\n{integrator}\
         [scene]\ntype = \"bundle\"\npath = \"{}\"\n\
         [[measures]]\nid = \"img\"\ntype = \"ortho\"\npixel_size_m = {pixel}\nzenith = 10.0\nazimuth = 60.0\nspp = {spp}\n",
        b.display()
    )
}

/// A 2 km sloped plane (`sx`, `sy`; `n` nodes per tile side, 2 × 2 tiles) at 150 m, 500 km /
/// 4000 km from the frame origin, of two spectral materials in a 4 × 4 pattern: `grass` and a
/// soil of Lambertian reflectance 0.12 at 440 nm to 0.35 at 660 nm (the spectral scene tests).
pub fn write_two_material_slope(
    dir: &Path,
    grass: BrdfSpec,
    sx: f64,
    sy: f64,
    n: usize,
) -> PathBuf {
    let soil = BrdfSpec::Lambertian(LambertianSpec {
        reflectance: Spectrum::Table {
            wavelengths_nm: vec![440.0, 660.0],
            values: vec![0.12, 0.35],
        },
    });
    write_plane(
        dir,
        &PlaneSpec {
            x0: -1000.0,
            y0: -1000.0,
            size: 2000.0,
            h0: 150.0,
            sx,
            sy,
            tiles: 2,
            n,
            raster_width: 4,
            raster: vec![0, 1, 0, 1, 1, 0, 1, 0, 0, 0, 1, 1, 1, 1, 0, 0],
            materials: vec![("grass".into(), grass), ("soil".into(), soil)],
            frame_origin: [500_000.0, 4_000_000.0, 0.0],
            wkt: String::new(),
        },
    )
}

pub fn write_plane(dir: &Path, p: &PlaneSpec) -> PathBuf {
    let indices: Vec<u8> = (0..p.materials.len() as u8).collect();
    write_plane_with_indices(dir, p, &indices)
}

/// [`write_plane`] with the manifest `index` of each material given (the ids the raster
/// holds), e.g. non-contiguous ones.
pub fn write_plane_with_indices(dir: &Path, p: &PlaneSpec, indices: &[u8]) -> PathBuf {
    assert_eq!(indices.len(), p.materials.len());
    let h = |x: f64, y: f64| p.h0 + p.sx * x + p.sy * y;
    let tsize = p.size / p.tiles as f64;
    let mut terrain = Vec::new();
    let mut zmin = f64::INFINITY;
    let mut zmax = f64::NEG_INFINITY;
    for tj in 0..p.tiles {
        for ti in 0..p.tiles {
            let ox = p.x0 + ti as f64 * tsize;
            let oy = p.y0 + tj as f64 * tsize;
            let oz = h(ox, oy);
            let step = tsize / p.n as f64;
            let mut positions = Vec::new();
            let mut uvs = Vec::new();
            for j in 0..=p.n {
                for i in 0..=p.n {
                    let (x, y) = (ox + i as f64 * step, oy + j as f64 * step);
                    let z = h(x, y);
                    zmin = zmin.min(z);
                    zmax = zmax.max(z);
                    positions.push([(x - ox) as f32, (y - oy) as f32, (z - oz) as f32]);
                    uvs.push([
                        ((x - p.x0) / p.size) as f32,
                        ((p.y0 + p.size - y) / p.size) as f32,
                    ]);
                }
            }
            let mut indices = Vec::new();
            for j in 0..p.n {
                for i in 0..p.n {
                    let a = (j * (p.n + 1) + i) as u32;
                    let (b, c, d) = (a + 1, a + (p.n + 1) as u32, a + (p.n + 2) as u32);
                    indices.push([a, b, d]);
                    indices.push([a, d, c]);
                }
            }
            terrain.push(TerrainTile {
                id: [ti as u32, tj as u32],
                origin: [ox, oy, oz],
                positions,
                uvs,
                indices,
            });
        }
    }
    let fo = p.frame_origin;
    let rw = p.raster_width;
    assert_eq!(p.raster.len(), rw * rw);
    let px = p.size / rw as f64;
    let mut histogram = vec![0u64; 256];
    for &v in &p.raster {
        histogram[v as usize] += 1;
    }
    let manifest = Manifest {
        format: FORMAT_NAME.into(),
        format_version: FORMAT_VERSION,
        crs: Crs {
            wkt: p.wkt.clone(),
            epsg: None,
            proj: None,
        },
        frame: LocalFrame {
            kind: "projected_enu".into(),
            origin: fo,
            centre_lon_lat: [3.0, 45.0],
            vertical_datum: "test".into(),
        },
        extent: Extent {
            min: [p.x0 + fo[0], p.y0 + fo[1]],
            max: [p.x0 + p.size + fo[0], p.y0 + p.size + fo[1]],
            height_range: [zmin, zmax],
            lon_lat_bbox: [2.9, 44.9, 3.1, 45.1],
        },
        terrain: Terrain {
            file: String::new(),
            tolerance_m: 0.0,
            dem_spacing_m: tsize / p.n as f64,
            dem_samples: 0,
            vertex_count: 0,
            triangle_count: 0,
            tiles: vec![],
        },
        material_raster: MaterialRaster {
            file: String::new(),
            width: rw as u32,
            height: rw as u32,
            geotransform: [p.x0 + fo[0], px, 0.0, p.y0 + p.size + fo[1], 0.0, -px],
            resampling: "nearest".into(),
            histogram,
        },
        materials: p
            .materials
            .iter()
            .enumerate()
            .map(|(i, (name, brdf))| Material {
                index: indices[i],
                name: name.clone(),
                brdf: brdf.clone(),
                class_codes: vec![i as u32],
                source: "test".into(),
                solver: None,
                temperature: None,
            })
            .collect(),
        templates: vec![],
        instances: Instances {
            file: String::new(),
            count: 0,
            per_template: vec![],
        },
        area: None,
        provenance: Provenance {
            generator: "test".into(),
            generator_version: "0".into(),
            seed: 0,
            region_toml: String::new(),
            inputs: vec![],
            files: vec![],
        },
    };
    let b = Bundle {
        manifest,
        terrain,
        templates: vec![],
        instances: vec![],
        material_raster: p.raster.clone(),
    };
    let out = dir.join("bundle");
    b.write(&out, true).unwrap();
    out
}

/// Record the current size and SHA-256 of every buffer in the manifest, as a writer would:
/// tests that damage a buffer's content on purpose call it so that the checks behind the digest
/// (material ids, vertices) are reached.
pub fn reseal(dir: &Path) {
    use sha2::{Digest, Sha256};
    let mut m = Bundle::read_manifest(dir).unwrap();
    for d in &mut m.provenance.files {
        let bytes = std::fs::read(dir.join(&d.file)).unwrap();
        d.bytes = bytes.len() as u64;
        d.sha256 = Sha256::digest(&bytes)
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect();
    }
    std::fs::write(dir.join("manifest.toml"), toml::to_string(&m).unwrap()).unwrap();
}

/// Add a material of manifest id `index` (no land-cover classes) to `b`.
fn push_material(
    b: &mut Bundle,
    index: u8,
    name: &str,
    brdf: BrdfSpec,
    solver: Option<SolverSpec>,
) {
    b.manifest.materials.push(Material {
        index,
        name: name.into(),
        brdf,
        class_codes: vec![],
        source: "test".into(),
        solver,
        temperature: None,
    });
}

/// A copy of the bundle `src` in `out` with one more material (`index`, `name`, `brdf`,
/// `solver`) and a horizontal square plate of it, `2·half` m wide, centred on (`cx`, `cy`) at
/// height `z` (local frame), as one instanced template.
#[allow(clippy::too_many_arguments)]
pub fn with_plate(
    src: &Path,
    out: &Path,
    centre: (f64, f64, f64),
    half: f32,
    index: u8,
    name: &str,
    brdf: BrdfSpec,
    solver: Option<SolverSpec>,
) -> PathBuf {
    const IDENTITY: [f32; 9] = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    with_plate_turned(src, out, centre, half, IDENTITY, index, name, brdf, solver)
}

/// [`with_plate`] with the plate turned by the instance's linear part `linear` (column-major).
#[allow(clippy::too_many_arguments)]
pub fn with_plate_turned(
    src: &Path,
    out: &Path,
    (cx, cy, z): (f64, f64, f64),
    half: f32,
    linear: [f32; 9],
    index: u8,
    name: &str,
    brdf: BrdfSpec,
    solver: Option<SolverSpec>,
) -> PathBuf {
    let mut b = Bundle::open(src).unwrap();
    push_material(&mut b, index, name, brdf, solver);
    b.templates.push(TemplateMesh {
        name: "plate".into(),
        source: "test".into(),
        positions: vec![
            [-half, -half, 0.0],
            [half, -half, 0.0],
            [half, half, 0.0],
            [-half, half, 0.0],
        ],
        indices: vec![[0, 1, 2], [0, 2, 3]],
        materials: vec![index; 2],
        lamps: Vec::new(),
    });
    b.instances.push(Instance {
        translation: [cx, cy, z],
        linear,
        template: (b.templates.len() - 1) as u32,
    });
    b.write(out, true).unwrap();
    out.to_path_buf()
}

/// A leaf file (`x y z nx ny nz r`) of `n` discs of radius `r`, centres uniform in
/// [−h, h]² × [z0, z1], normals isotropic, from a seeded stream.
pub fn write_random_leaves(
    path: &std::path::Path,
    seed: u64,
    n: usize,
    h: f64,
    z: [f64; 2],
    r: f64,
) {
    let mut rng = engine::rng::Stream::new(seed, [0, 0, 0, 0]);
    let mut leaves = String::from("# x y z nx ny nz r\n");
    for _ in 0..n {
        let nv = engine::frame::direction_from_angles(
            (rng.next_f64() * 2.0 - 1.0).acos(),
            std::f64::consts::TAU * rng.next_f64(),
        );
        leaves.push_str(&format!(
            "{} {} {} {} {} {} {r}\n",
            2.0 * h * rng.next_f64() - h,
            2.0 * h * rng.next_f64() - h,
            z[0] + (z[1] - z[0]) * rng.next_f64(),
            nv.x,
            nv.y,
            nv.z
        ));
    }
    std::fs::write(path, leaves).unwrap();
}

/// A copy of the bundle `src` in `out` with rows of box buildings: one template, a box
/// `width` (x) × `length` (y) × `height` m on the ground (z ≥ 0), its four walls of material
/// `wall` (id 7) and its roof of `roof` (id 8), placed with its footprint centred on (x, 0) for
/// every x of `rows`: parallel street canyons running along y.
pub fn with_building_rows(
    src: &Path,
    out: &Path,
    rows: &[f64],
    (width, length, height): (f32, f32, f32),
    wall: BrdfSpec,
    roof: BrdfSpec,
) -> PathBuf {
    let mut b = Bundle::open(src).unwrap();
    push_material(&mut b, 7, "wall", wall, None);
    push_material(&mut b, 8, "roof", roof, None);
    let (hx, hy) = (0.5 * width, 0.5 * length);
    // Corners 0–3 at the ground, 4–7 at the top, counter-clockwise seen from above.
    let mut positions = Vec::new();
    for z in [0.0, height] {
        positions.extend([[-hx, -hy, z], [hx, -hy, z], [hx, hy, z], [-hx, hy, z]]);
    }
    let mut indices = Vec::new();
    let mut materials = Vec::new();
    for k in 0..4u32 {
        let (a, b2) = (k, (k + 1) % 4);
        indices.push([a, b2, b2 + 4]);
        indices.push([a, b2 + 4, a + 4]);
        materials.extend([7, 7]);
    }
    indices.push([4, 5, 6]);
    indices.push([4, 6, 7]);
    materials.extend([8, 8]);
    b.templates.push(TemplateMesh {
        name: "building".into(),
        source: "test".into(),
        positions,
        indices,
        materials,
        lamps: Vec::new(),
    });
    let template = (b.templates.len() - 1) as u32;
    for &x in rows {
        b.instances.push(Instance {
            translation: [x, 0.0, 0.0],
            linear: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            template,
        });
    }
    b.write(out, true).unwrap();
    out.to_path_buf()
}
