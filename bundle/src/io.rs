//! Reading and writing bundles. Writing is atomic: everything goes to a temporary directory
//! beside the destination (`.NAME.tmp-PID`), which is renamed onto the destination at the end,
//! so an interrupted or failed write (full disk included) never leaves a half bundle. Buffers are
//! little-endian; see the module doc of [`super`] for the layout.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

use super::checks;
use super::manifest::*;
use super::{BrdfSpec, BundleError, FORMAT_NAME, FORMAT_VERSION, NO_MATERIAL};

/// Bytes of one record of `instances.bin`: translation [f64; 3] (local frame, metres), linear
/// part [f32; 9] (column-major 3×3: rotation × scale, template frame → local frame), template id
/// u32.
pub const INSTANCE_RECORD_BYTES: usize = 64;

/// The largest distance (m) any point of a bundle's geometry may lie from the frame's origin:
/// 10 000 km, beyond any region on Earth. Farther coordinates (a template scaled 1e19, a vertex
/// at 3e38) are refused when the bundle is read, naming the tile, template or instance, before
/// any acceleration structure is built (issue 43: they used to panic inside the BVH builder).
pub const MAX_COORDINATE_M: f64 = 1e7;

/// The farthest of `positions` from the point `origin` is placed at (m): |origin| + max |v|.
fn reach(origin: [f64; 3], positions: &[[f32; 3]]) -> f64 {
    let far = positions
        .iter()
        .map(|p| {
            let [x, y, z] = p.map(f64::from);
            (x * x + y * y + z * z).sqrt()
        })
        .fold(0.0, f64::max);
    far + origin.iter().map(|c| c * c).sum::<f64>().sqrt()
}

/// A bound on an instance's farthest point: |M·v + t| ≤ ‖M‖_F·|v| + |t|, with `template_reach`
/// the template's farthest vertex.
fn instance_reach(linear: &[f32; 9], translation: [f64; 3], template_reach: f64) -> f64 {
    let frobenius = linear
        .iter()
        .map(|&a| f64::from(a) * f64::from(a))
        .sum::<f64>()
        .sqrt();
    frobenius * template_reach + translation.iter().map(|c| c * c).sum::<f64>().sqrt()
}

/// The message for part `what` of a bundle reaching `r` m, beyond [`MAX_COORDINATE_M`].
fn beyond_bound(what: &str, r: f64) -> String {
    format!(
        "{what}: geometry reaches {r:.3e} m from the frame's origin; coordinates are bounded by {MAX_COORDINATE_M:e} m"
    )
}

/// One terrain tile in memory.
#[derive(Clone, Debug, PartialEq)]
pub struct TerrainTile {
    pub id: [u32; 2],
    /// Working-CRS coordinates of the tile's origin, metres.
    pub origin: [f64; 3],
    /// Positions relative to `origin`, metres.
    pub positions: Vec<[f32; 3]>,
    pub uvs: Vec<[f32; 2]>,
    pub indices: Vec<[u32; 3]>,
}

/// One template mesh in memory (template frame: metres, z up, origin on the ground).
#[derive(Clone, Debug, PartialEq)]
pub struct TemplateMesh {
    pub name: String,
    pub source: String,
    pub positions: Vec<[f32; 3]>,
    pub indices: Vec<[u32; 3]>,
    /// Per triangle, a material id (the `index` of a manifest material).
    pub materials: Vec<u8>,
    /// Lamps every instance carries (the manifest's `Template::lamps`).
    pub lamps: Vec<toml::Table>,
}

/// One placed template: world = frame origin + translation + linear · p_template.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Instance {
    /// Relative to the bundle's local-frame origin, metres.
    pub translation: [f64; 3],
    /// Column-major 3×3 (rotation × scale).
    pub linear: [f32; 9],
    pub template: u32,
}

/// A whole bundle in memory. `manifest` holds the descriptive tables; [`Bundle::write`] fills in
/// file names, offsets, counts and digests from the buffers.
#[derive(Clone, Debug, PartialEq)]
pub struct Bundle {
    pub manifest: Manifest,
    pub terrain: Vec<TerrainTile>,
    pub templates: Vec<TemplateMesh>,
    pub instances: Vec<Instance>,
    /// Row-major, row 0 at the north, `manifest.material_raster.width × height` bytes.
    pub material_raster: Vec<u8>,
}

const TERRAIN_FILE: &str = "terrain.bin";
use super::TEMPLATES_FILE;
const INSTANCES_FILE: &str = "instances.bin";
const MATERIALS_FILE: &str = "materials.u8";
const MANIFEST_FILE: &str = "manifest.toml";
/// The folder of a bundle that holds its materials' tables (tabulated BRDFs).
const TABLES_DIR: &str = "brdf";

/// A file being written with its running SHA-256 and length.
struct HashedFile {
    path: PathBuf,
    out: BufWriter<File>,
    hasher: Sha256,
    len: u64,
}

impl HashedFile {
    fn create(path: PathBuf) -> Result<Self, BundleError> {
        let f = File::create(&path).map_err(|source| BundleError::Write {
            path: path.clone(),
            source,
        })?;
        Ok(HashedFile {
            path,
            out: BufWriter::with_capacity(1 << 20, f),
            hasher: Sha256::new(),
            len: 0,
        })
    }
    fn put(&mut self, bytes: &[u8]) -> Result<(), BundleError> {
        self.hasher.update(bytes);
        self.len += bytes.len() as u64;
        self.out
            .write_all(bytes)
            .map_err(|source| BundleError::Write {
                path: self.path.clone(),
                source,
            })
    }
    fn put_f32s(&mut self, v: impl IntoIterator<Item = f32>) -> Result<(), BundleError> {
        let mut buf = Vec::with_capacity(4096);
        for x in v {
            buf.extend_from_slice(&x.to_le_bytes());
            if buf.len() >= 4096 {
                self.put(&buf)?;
                buf.clear();
            }
        }
        self.put(&buf)
    }
    fn put_u32s(&mut self, v: impl IntoIterator<Item = u32>) -> Result<(), BundleError> {
        self.put_f32s(v.into_iter().map(f32::from_bits))
    }
    fn finish(self, name: &str) -> Result<FileDigest, BundleError> {
        let path = self.path.clone();
        let f = self.out.into_inner().map_err(|e| BundleError::Write {
            path: path.clone(),
            source: e.into_error(),
        })?;
        f.sync_all()
            .map_err(|source| BundleError::Write { path, source })?;
        Ok(FileDigest {
            file: name.into(),
            bytes: self.len,
            sha256: hex(&self.hasher.finalize()),
        })
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Removes the temporary directory unless the write completed.
struct TmpDirGuard {
    path: PathBuf,
    done: bool,
}

impl Drop for TmpDirGuard {
    fn drop(&mut self) {
        if !self.done {
            let _ = std::fs::remove_dir_all(&self.path);
        }
    }
}

/// The files a bundle writer puts in a bundle folder (every other name is someone else's).
const BUNDLE_FILES: [&str; 5] = [
    MANIFEST_FILE,
    TERRAIN_FILE,
    TEMPLATES_FILE,
    INSTANCES_FILE,
    MATERIALS_FILE,
];

/// Whether `dir` may be replaced by a forced write: it does not exist, or it is an empty
/// directory, or one of our bundles: a `manifest.toml` that parses as TOML with `format =
/// "eo-scene-bundle"` and an integer `format_version`, and nothing in the folder but the files
/// a bundle holds. Anything else (a file, a symbolic link, another tool's folder, a bundle a
/// user has put files into) is refused with [`BundleError::NotABundle`] naming what is in the
/// way, so `--force` never deletes data it did not write.
pub fn check_replaceable(dir: &Path) -> Result<(), BundleError> {
    let not = |reason: String| BundleError::NotABundle {
        path: dir.to_path_buf(),
        reason,
    };
    let meta = match std::fs::symlink_metadata(dir) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(source) => {
            return Err(BundleError::Write {
                path: dir.to_path_buf(),
                source,
            })
        }
    };
    if !meta.is_dir() {
        return Err(not(if meta.file_type().is_symlink() {
            "a symbolic link".into()
        } else {
            "not a directory".into()
        }));
    }
    let entries = std::fs::read_dir(dir).map_err(|source| BundleError::Write {
        path: dir.to_path_buf(),
        source,
    })?;
    let mut foreign = Vec::new();
    let mut any = false;
    let mut tables = false;
    for e in entries {
        let e = e.map_err(|source| BundleError::Write {
            path: dir.to_path_buf(),
            source,
        })?;
        any = true;
        let name = e.file_name().to_string_lossy().into_owned();
        let kind = e.file_type().ok();
        if name == TABLES_DIR && kind.is_some_and(|t| t.is_dir()) {
            tables = true;
            continue;
        }
        if !(kind.is_some_and(|t| t.is_file()) && BUNDLE_FILES.contains(&name.as_str())) {
            foreign.push(name);
        }
    }
    if !any {
        return Ok(());
    }
    let manifest = dir.join(MANIFEST_FILE);
    let regular = std::fs::symlink_metadata(&manifest).is_ok_and(|m| m.is_file());
    let text = match regular.then(|| std::fs::read_to_string(&manifest)) {
        Some(Ok(text)) => text,
        _ => return Err(not("no manifest.toml".into())),
    };
    let table: toml::Table = text
        .parse()
        .map_err(|_| not("its manifest.toml is not TOML".into()))?;
    let format = table.get("format").and_then(|v| v.as_str());
    if format != Some(FORMAT_NAME) {
        return Err(not(match format {
            Some(f) => format!("its manifest.toml says format = \"{f}\", not \"{FORMAT_NAME}\""),
            None => format!("its manifest.toml has no format = \"{FORMAT_NAME}\""),
        }));
    }
    if !table.get("format_version").is_some_and(|v| v.is_integer()) {
        return Err(not("its manifest.toml has no integer format_version".into()));
    }
    if tables {
        // The tables folder holds only files the manifest lists (and hashes).
        let listed: Vec<&str> = table
            .get("provenance")
            .and_then(|p| p.get("files"))
            .and_then(|f| f.as_array())
            .map(|a| {
                a.iter()
                    .filter_map(|d| d.get("file").and_then(|f| f.as_str()))
                    .collect()
            })
            .unwrap_or_default();
        let d = dir.join(TABLES_DIR);
        let entries = std::fs::read_dir(&d).map_err(|source| BundleError::Write {
            path: d.clone(),
            source,
        })?;
        for e in entries {
            let e = e.map_err(|source| BundleError::Write {
                path: d.clone(),
                source,
            })?;
            let name = format!("{TABLES_DIR}/{}", e.file_name().to_string_lossy());
            if !(e.file_type().is_ok_and(|t| t.is_file()) && listed.contains(&name.as_str())) {
                foreign.push(name);
            }
        }
    }
    if !foreign.is_empty() {
        foreign.sort();
        return Err(not(format!(
            "it holds {} that a bundle does not ({}); move {} out of the folder first",
            if foreign.len() == 1 {
                "an entry"
            } else {
                "entries"
            },
            foreign.join(", "),
            if foreign.len() == 1 { "it" } else { "them" },
        )));
    }
    Ok(())
}

impl Bundle {
    /// Write the bundle to `dir` atomically. Refuses an existing `dir` unless `force`, in which
    /// case the old directory is replaced only after the new one is complete.
    /// Returns the manifest as written (offsets, counts and digests filled in).
    pub fn write(&self, dir: &Path, force: bool) -> Result<Manifest, BundleError> {
        if dir.exists() && !force {
            return Err(BundleError::Exists {
                path: dir.to_path_buf(),
            });
        }
        check_replaceable(dir)?;
        self.check_consistency(dir)?;
        let parent = match dir.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        std::fs::create_dir_all(&parent).map_err(|source| BundleError::Write {
            path: parent.clone(),
            source,
        })?;
        let name = dir
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "bundle".into());
        let tmp = parent.join(format!(".{name}.tmp-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&tmp);
        std::fs::create_dir(&tmp).map_err(|source| BundleError::Write {
            path: tmp.clone(),
            source,
        })?;
        let mut guard = TmpDirGuard {
            path: tmp.clone(),
            done: false,
        };

        let mut m = self.manifest.clone();
        m.format = FORMAT_NAME.into();
        m.format_version = FORMAT_VERSION;
        let mut digests = Vec::new();

        // Terrain: per tile positions, uvs, indices.
        let mut f = HashedFile::create(tmp.join(TERRAIN_FILE))?;
        m.terrain.file = TERRAIN_FILE.into();
        m.terrain.tiles.clear();
        let (mut nv, mut nt) = (0u64, 0u64);
        for t in &self.terrain {
            let positions_offset = f.len;
            f.put_f32s(t.positions.iter().flatten().copied())?;
            let uvs_offset = f.len;
            f.put_f32s(t.uvs.iter().flatten().copied())?;
            let indices_offset = f.len;
            f.put_u32s(t.indices.iter().flatten().copied())?;
            nv += t.positions.len() as u64;
            nt += t.indices.len() as u64;
            m.terrain.tiles.push(TerrainTileInfo {
                id: t.id,
                origin: t.origin,
                positions_offset,
                uvs_offset,
                indices_offset,
                vertex_count: t.positions.len() as u64,
                triangle_count: t.indices.len() as u64,
            });
        }
        m.terrain.vertex_count = nv;
        m.terrain.triangle_count = nt;
        digests.push(f.finish(TERRAIN_FILE)?);

        // Templates.
        let mut f = HashedFile::create(tmp.join(TEMPLATES_FILE))?;
        let old = std::mem::take(&mut m.templates);
        for (id, t) in self.templates.iter().enumerate() {
            let positions_offset = f.len;
            f.put_f32s(t.positions.iter().flatten().copied())?;
            let indices_offset = f.len;
            f.put_u32s(t.indices.iter().flatten().copied())?;
            let materials_offset = f.len;
            f.put(&t.materials)?;
            // Keep 4-byte alignment of the next template's floats.
            let pad = (4 - (f.len % 4) as usize) % 4;
            f.put(&[0u8; 4][..pad])?;
            let (lo, hi) = checks::bounds(&t.positions);
            m.templates.push(Template {
                id: id as u32,
                name: t.name.clone(),
                source: old
                    .get(id)
                    .map(|o| o.source.clone())
                    .unwrap_or_else(|| t.source.clone()),
                positions_offset,
                indices_offset,
                materials_offset,
                vertex_count: t.positions.len() as u64,
                triangle_count: t.indices.len() as u64,
                bounds_min: lo,
                bounds_max: hi,
                lamps: t.lamps.clone(),
            });
        }
        digests.push(f.finish(TEMPLATES_FILE)?);

        // Instances.
        let mut f = HashedFile::create(tmp.join(INSTANCES_FILE))?;
        let mut per_template = vec![0u64; self.templates.len()];
        let mut buf = Vec::with_capacity(INSTANCE_RECORD_BYTES * 1024);
        for inst in &self.instances {
            for x in inst.translation {
                buf.extend_from_slice(&x.to_le_bytes());
            }
            for x in inst.linear {
                buf.extend_from_slice(&x.to_le_bytes());
            }
            buf.extend_from_slice(&inst.template.to_le_bytes());
            per_template[inst.template as usize] += 1;
            if buf.len() >= INSTANCE_RECORD_BYTES * 1024 {
                f.put(&buf)?;
                buf.clear();
            }
        }
        f.put(&buf)?;
        m.instances = Instances {
            file: INSTANCES_FILE.into(),
            count: self.instances.len() as u64,
            per_template,
        };
        digests.push(f.finish(INSTANCES_FILE)?);

        // Material raster.
        let mut f = HashedFile::create(tmp.join(MATERIALS_FILE))?;
        f.put(&self.material_raster)?;
        m.material_raster.file = MATERIALS_FILE.into();
        let mut hist = checks::pixel_counts(&self.material_raster).to_vec();
        let last = hist.iter().rposition(|&c| c > 0).map_or(0, |i| i + 1);
        let table_end = m.materials.iter().map(|x| x.index as usize + 1).max();
        hist.truncate(last.max(table_end.unwrap_or(0)));
        m.material_raster.histogram = hist;
        digests.push(f.finish(MATERIALS_FILE)?);

        // Tabulated materials' tables: copied into `brdf/` and hashed like the buffers.
        let mut copied: Vec<(PathBuf, String)> = Vec::new();
        for mat in &mut m.materials {
            let BrdfSpec::Tabulated(t) = &mut mat.brdf else {
                continue;
            };
            let source = PathBuf::from(&t.file);
            if let Some((_, name)) = copied.iter().find(|(p, _)| *p == source) {
                t.file = name.clone();
                continue;
            }
            let base = source
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_else(|| "table".into());
            let mut name = format!("{TABLES_DIR}/{base}");
            let mut k = 2;
            while copied.iter().any(|(_, n)| *n == name) {
                name = format!("{TABLES_DIR}/{k}-{base}");
                k += 1;
            }
            let bytes = std::fs::read(&source).map_err(|source_err| BundleError::Read {
                path: source.clone(),
                source: source_err,
            })?;
            if copied.is_empty() {
                let d = tmp.join(TABLES_DIR);
                std::fs::create_dir(&d).map_err(|source| BundleError::Write { path: d, source })?;
            }
            let mut f = HashedFile::create(tmp.join(&name))?;
            f.put(&bytes)?;
            digests.push(f.finish(&name)?);
            t.file = name.clone();
            copied.push((source, name));
        }

        m.provenance.files = digests;
        let text = toml::to_string(&m).map_err(|e| BundleError::Manifest {
            path: tmp.join(MANIFEST_FILE),
            message: e.to_string(),
        })?;
        let mut f = HashedFile::create(tmp.join(MANIFEST_FILE))?;
        f.put(text.as_bytes())?;
        f.finish(MANIFEST_FILE)?;

        // Commit: move an existing destination aside, rename, then delete the old one.
        if dir.exists() {
            let trash = parent.join(format!(".{name}.old-{}", std::process::id()));
            std::fs::rename(dir, &trash).map_err(|source| BundleError::Write {
                path: dir.to_path_buf(),
                source,
            })?;
            std::fs::rename(&tmp, dir).map_err(|source| BundleError::Write {
                path: dir.to_path_buf(),
                source,
            })?;
            let _ = std::fs::remove_dir_all(&trash);
        } else {
            std::fs::rename(&tmp, dir).map_err(|source| BundleError::Write {
                path: dir.to_path_buf(),
                source,
            })?;
        }
        guard.done = true;
        Ok(m)
    }

    fn check_consistency(&self, dir: &Path) -> Result<(), BundleError> {
        let bad = |message: String| BundleError::Corrupt {
            path: dir.to_path_buf(),
            message,
        };
        let r = &self.manifest.material_raster;
        if self.material_raster.len() != r.width as usize * r.height as usize {
            return Err(bad(format!(
                "material raster has {} bytes, expected {} × {}",
                self.material_raster.len(),
                r.width,
                r.height
            )));
        }
        for t in &self.terrain {
            if t.uvs.len() != t.positions.len() {
                return Err(bad(format!(
                    "terrain tile {:?}: {} uvs for {} vertices",
                    t.id,
                    t.uvs.len(),
                    t.positions.len()
                )));
            }
            if let Some(tri) = t
                .indices
                .iter()
                .find(|tri| tri.iter().any(|&i| i as usize >= t.positions.len()))
            {
                return Err(bad(format!(
                    "terrain tile {:?}: triangle {tri:?} indexes past {} vertices",
                    t.id,
                    t.positions.len()
                )));
            }
        }
        for (k, t) in self.templates.iter().enumerate() {
            if t.materials.len() != t.indices.len() {
                return Err(bad(format!(
                    "template {k}: {} materials for {} triangles",
                    t.materials.len(),
                    t.indices.len()
                )));
            }
            if t.indices
                .iter()
                .flatten()
                .any(|&i| i as usize >= t.positions.len())
            {
                return Err(bad(format!(
                    "template {k}: an index points past {} vertices",
                    t.positions.len()
                )));
            }
        }
        if let Some(i) = self
            .instances
            .iter()
            .find(|i| i.template as usize >= self.templates.len())
        {
            return Err(bad(format!(
                "instance of template {} but only {} templates",
                i.template,
                self.templates.len()
            )));
        }
        // Refuse to write what a reader would refuse.
        if let Some(message) = self.beyond_bounds() {
            return Err(bad(message));
        }
        check_material_table(&self.manifest.materials, &dir.join(MANIFEST_FILE))?;
        check_material_ids(
            &self.manifest.materials,
            &self.material_raster,
            &self.templates,
            dir,
        )
    }

    /// The first part of the geometry that reaches beyond [`MAX_COORDINATE_M`] from the frame's
    /// origin, as the reader words it (terrain: tile origin + vertex; instance: |t| + ‖M‖_F ·
    /// the template's farthest vertex).
    fn beyond_bounds(&self) -> Option<String> {
        for t in &self.terrain {
            let r = reach(t.origin, &t.positions);
            if r > MAX_COORDINATE_M {
                return Some(beyond_bound(&format!("terrain tile {:?}", t.id), r));
            }
        }
        let template_reach: Vec<f64> = self
            .templates
            .iter()
            .map(|t| reach([0.0; 3], &t.positions))
            .collect();
        for (k, r) in template_reach.iter().enumerate() {
            if *r > MAX_COORDINATE_M {
                return Some(beyond_bound(&format!("template {k}"), *r));
            }
        }
        for (k, i) in self.instances.iter().enumerate() {
            let t = template_reach
                .get(i.template as usize)
                .copied()
                .unwrap_or(0.0);
            let r = instance_reach(&i.linear, i.translation, t);
            if r > MAX_COORDINATE_M {
                return Some(beyond_bound(&format!("instance {k}"), r));
            }
        }
        None
    }

    /// Read and validate `dir/manifest.toml` only (for summaries).
    pub fn read_manifest(dir: &Path) -> Result<Manifest, BundleError> {
        let path = dir.join(MANIFEST_FILE);
        checks::regular_inside(dir, &path)?;
        let text = std::fs::read_to_string(&path).map_err(|source| BundleError::Read {
            path: path.clone(),
            source,
        })?;
        // Check the version before the schema, so an old reader says "version" not "unknown key".
        let table: toml::Table =
            text.parse()
                .map_err(|e: toml::de::Error| BundleError::Manifest {
                    path: path.clone(),
                    message: e.to_string(),
                })?;
        if table.get("format").and_then(|v| v.as_str()) != Some(FORMAT_NAME) {
            return Err(BundleError::Manifest {
                path,
                message: format!("`format` is not \"{FORMAT_NAME}\""),
            });
        }
        match table.get("format_version").and_then(|v| v.as_integer()) {
            Some(v) if v == FORMAT_VERSION as i64 => {}
            Some(v) => return Err(BundleError::Version { path, found: v }),
            None => {
                return Err(BundleError::Manifest {
                    path,
                    message: "`format_version` is missing or not an integer".into(),
                })
            }
        }
        let de = toml::Deserializer::parse(&text).map_err(|e| BundleError::Manifest {
            path: path.clone(),
            message: e.to_string(),
        })?;
        let m: Manifest =
            serde_path_to_error::deserialize(de).map_err(|e| BundleError::Manifest {
                path: path.clone(),
                message: format!(
                    "at key `{}`: {}",
                    e.path(),
                    e.inner().to_string().trim_end()
                ),
            })?;
        if let Some(a) = &m.area {
            a.polygons().map_err(|message| BundleError::Manifest {
                path: path.clone(),
                message: format!("at key `area.wkt`: {message}"),
            })?;
        }
        checks::names_confined(&m, dir, &path)?;
        Ok(m)
    }

    /// Read a whole bundle: every binary file is checked against the size and SHA-256 the
    /// manifest records (the four files are read and hashed in parallel), and every offset,
    /// count, vertex, transform, geotransform and material id is checked before use.
    pub fn open(dir: &Path) -> Result<Bundle, BundleError> {
        let manifest = Self::read_manifest(dir)?;
        let mpath = dir.join(MANIFEST_FILE);
        check_georeference(&manifest, &mpath)?;
        // The four buffers, then every tabulated material's table (hashed like the buffers,
        // so a table swapped after the build is refused; its bytes are read by the simulator).
        let names = used_files(&manifest);
        let mut files = read_verified(dir, &manifest, &names)?;
        files.truncate(4);
        let lens: Vec<u64> = files.iter().map(|(_, b)| b.len() as u64).collect();
        checks::totals_and_layout(&manifest, &mpath, |name| {
            names[..4]
                .iter()
                .position(|n| *n == name)
                .map_or(0, |k| lens[k])
        })?;
        let mut read = |name: &str| -> Result<(PathBuf, Vec<u8>), BundleError> {
            let k = names
                .iter()
                .position(|n| *n == name)
                .expect("a listed file");
            Ok(std::mem::take(&mut files[k]))
        };
        let slice = |path: &Path,
                     bytes: &[u8],
                     off: u64,
                     len: u64,
                     what: &str|
         -> Result<std::ops::Range<usize>, BundleError> {
            let end = off
                .checked_add(len)
                .filter(|&e| e <= bytes.len() as u64)
                .ok_or_else(|| BundleError::Corrupt {
                    path: path.to_path_buf(),
                    message: format!(
                        "{what}: bytes {off}..{} beyond the file's {} bytes",
                        off.saturating_add(len),
                        bytes.len()
                    ),
                })?;
            Ok(off as usize..end as usize)
        };

        // Byte sizes from manifest counts, refusing counts whose size overflows.
        let size = |path: &Path, count: u64, each: u64, what: &str| -> Result<u64, BundleError> {
            count.checked_mul(each).ok_or_else(|| BundleError::Corrupt {
                path: path.to_path_buf(),
                message: format!("{what}: count {count} is impossibly large"),
            })
        };
        // Vertices must be finite (a NaN would poison the BVH and every ray near it).
        let finite = |path: &Path, positions: &[[f32; 3]], what: &str| -> Result<(), BundleError> {
            match positions
                .iter()
                .position(|p| !p.iter().all(|c| c.is_finite()))
            {
                None => Ok(()),
                Some(k) => Err(BundleError::Corrupt {
                    path: path.to_path_buf(),
                    message: format!(
                        "{what}: vertex {k} has a non-finite coordinate {:?}",
                        positions[k]
                    ),
                }),
            }
        };

        let too_far = |path: &Path, what: &str, r: f64| BundleError::Corrupt {
            path: path.to_path_buf(),
            message: beyond_bound(what, r),
        };

        let (path, bytes) = read(&manifest.terrain.file)?;
        let mut terrain = Vec::with_capacity(manifest.terrain.tiles.len());
        for t in &manifest.terrain.tiles {
            let what = format!("terrain tile {:?}", t.id);
            let p = slice(
                &path,
                &bytes,
                t.positions_offset,
                size(&path, t.vertex_count, 12, &what)?,
                &what,
            )?;
            let u = slice(
                &path,
                &bytes,
                t.uvs_offset,
                size(&path, t.vertex_count, 8, &what)?,
                &what,
            )?;
            let i = slice(
                &path,
                &bytes,
                t.indices_offset,
                size(&path, t.triangle_count, 12, &what)?,
                &what,
            )?;
            let indices: Vec<[u32; 3]> = u32s(&bytes[i])
                .chunks_exact(3)
                .map(|c| [c[0], c[1], c[2]])
                .collect();
            if indices
                .iter()
                .flatten()
                .any(|&k| k as u64 >= t.vertex_count)
            {
                return Err(BundleError::Corrupt {
                    path,
                    message: format!("{what}: a vertex index is out of range"),
                });
            }
            let positions: Vec<[f32; 3]> = f32s(&bytes[p])
                .chunks_exact(3)
                .map(|c| [c[0], c[1], c[2]])
                .collect();
            finite(&path, &positions, &what)?;
            if !t.origin.iter().all(|c| c.is_finite()) {
                return Err(BundleError::Corrupt {
                    path: dir.join(MANIFEST_FILE),
                    message: format!("{what}: non-finite origin {:?}", t.origin),
                });
            }
            let r = reach(t.origin, &positions);
            if r > MAX_COORDINATE_M {
                return Err(too_far(&path, &what, r));
            }
            terrain.push(TerrainTile {
                id: t.id,
                origin: t.origin,
                positions,
                uvs: f32s(&bytes[u])
                    .chunks_exact(2)
                    .map(|c| [c[0], c[1]])
                    .collect(),
                indices,
            });
        }

        drop(bytes); // each raw buffer is freed once parsed
        let (path, bytes) = read(TEMPLATES_FILE)?;
        let mut templates = Vec::with_capacity(manifest.templates.len());
        let mut template_reach: Vec<f64> = Vec::new();
        for t in &manifest.templates {
            let what = format!("template {} ({})", t.id, t.name);
            let p = slice(
                &path,
                &bytes,
                t.positions_offset,
                size(&path, t.vertex_count, 12, &what)?,
                &what,
            )?;
            let i = slice(
                &path,
                &bytes,
                t.indices_offset,
                size(&path, t.triangle_count, 12, &what)?,
                &what,
            )?;
            let mm = slice(&path, &bytes, t.materials_offset, t.triangle_count, &what)?;
            let indices: Vec<[u32; 3]> = u32s(&bytes[i])
                .chunks_exact(3)
                .map(|c| [c[0], c[1], c[2]])
                .collect();
            if indices
                .iter()
                .flatten()
                .any(|&k| k as u64 >= t.vertex_count)
            {
                return Err(BundleError::Corrupt {
                    path,
                    message: format!("{what}: a vertex index is out of range"),
                });
            }
            let positions: Vec<[f32; 3]> = f32s(&bytes[p])
                .chunks_exact(3)
                .map(|c| [c[0], c[1], c[2]])
                .collect();
            finite(&path, &positions, &what)?;
            let r = reach([0.0; 3], &positions);
            if r > MAX_COORDINATE_M {
                return Err(too_far(&path, &what, r));
            }
            template_reach.push(r);
            checks::template_bounds(&manifest, &mpath, templates.len(), &positions)?;
            templates.push(TemplateMesh {
                name: t.name.clone(),
                source: t.source.clone(),
                positions,
                indices,
                materials: bytes[mm].to_vec(),
                lamps: t.lamps.clone(),
            });
        }

        drop(bytes); // each raw buffer is freed once parsed
        let (path, bytes) = read(&manifest.instances.file)?;
        if Some(bytes.len() as u64)
            != manifest
                .instances
                .count
                .checked_mul(INSTANCE_RECORD_BYTES as u64)
        {
            return Err(BundleError::Corrupt {
                path,
                message: format!(
                    "{} bytes for {} instances of {INSTANCE_RECORD_BYTES} bytes",
                    bytes.len(),
                    manifest.instances.count
                ),
            });
        }
        let mut instances = Vec::with_capacity(manifest.instances.count as usize);
        for rec in bytes.chunks_exact(INSTANCE_RECORD_BYTES) {
            let f64at = |k: usize| f64::from_le_bytes(rec[k..k + 8].try_into().unwrap());
            let f32at = |k: usize| f32::from_le_bytes(rec[k..k + 4].try_into().unwrap());
            let mut linear = [0f32; 9];
            for (j, l) in linear.iter_mut().enumerate() {
                *l = f32at(24 + 4 * j);
            }
            let template = u32::from_le_bytes(rec[60..64].try_into().unwrap());
            if template as usize >= templates.len() {
                return Err(BundleError::Corrupt {
                    path,
                    message: format!(
                        "an instance names template {template} of {}",
                        templates.len()
                    ),
                });
            }
            let translation = [f64at(0), f64at(8), f64at(16)];
            if !translation.iter().all(|c| c.is_finite()) || !linear.iter().all(|c| c.is_finite()) {
                return Err(BundleError::Corrupt {
                    path,
                    message: format!(
                        "instance {}: non-finite transform (translation {translation:?}, linear part {linear:?})",
                        instances.len()
                    ),
                });
            }
            let r = instance_reach(&linear, translation, template_reach[template as usize]);
            if r > MAX_COORDINATE_M {
                return Err(too_far(&path, &format!("instance {}", instances.len()), r));
            }
            instances.push(Instance {
                translation,
                linear,
                template,
            });
        }

        drop(bytes);
        checks::instances_per_template(&manifest, &mpath, instances.iter().map(|i| i.template))?;
        let (path, material_raster) = read(&manifest.material_raster.file)?;
        let r = &manifest.material_raster;
        if material_raster.len() != r.width as usize * r.height as usize {
            return Err(BundleError::Corrupt {
                path,
                message: format!(
                    "{} bytes for a {} × {} raster",
                    material_raster.len(),
                    r.width,
                    r.height
                ),
            });
        }
        check_material_table(&manifest.materials, &mpath)?;
        check_material_ids(&manifest.materials, &material_raster, &templates, dir)?;
        checks::histogram(&manifest, &mpath, &material_raster)?;
        Ok(Bundle {
            manifest,
            terrain,
            templates,
            instances,
            material_raster,
        })
    }

    /// Checks, without reading them, that every file the manifest lists is present with its
    /// recorded size, and that the georeference is sane (for quick summaries).
    pub fn check_present(dir: &Path, m: &Manifest) -> Result<(), BundleError> {
        check_georeference(m, &dir.join(MANIFEST_FILE))?;
        for d in &m.provenance.files {
            let path = dir.join(&d.file);
            checks::regular_inside(dir, &path)?;
            let meta = std::fs::metadata(&path).map_err(|source| BundleError::Read {
                path: path.clone(),
                source,
            })?;
            if meta.len() != d.bytes {
                return Err(size_mismatch(path, meta.len(), d.bytes));
            }
        }
        Ok(())
    }

    /// Everything [`Bundle::open`] checks (every file's SHA-256, the manifest's cross-checks,
    /// every offset, vertex and material id), plus the digest of every other file
    /// `provenance.files` lists; the bundle read is dropped.
    pub fn verify(dir: &Path) -> Result<(), BundleError> {
        let m = Self::open(dir)?.manifest;
        // `open` hashed the files it uses; the digests of any others the manifest lists.
        let used = used_files(&m);
        let names: Vec<&str> = m
            .provenance
            .files
            .iter()
            .map(|d| d.file.as_str())
            .filter(|n| !used.contains(n))
            .collect();
        read_verified(dir, &m, &names).map(|_| ())
    }
}

/// The files `Bundle::open` reads and hashes: the four buffers (terrain, templates,
/// instances, material raster, in that order), then every tabulated material's table.
fn used_files(m: &Manifest) -> Vec<&str> {
    let mut names = vec![
        m.terrain.file.as_str(),
        TEMPLATES_FILE,
        m.instances.file.as_str(),
        m.material_raster.file.as_str(),
    ];
    for (_, f) in checks::table_files(m) {
        if !names.contains(&f) {
            names.push(f);
        }
    }
    names
}

/// A buffer whose size differs from the manifest's record.
fn size_mismatch(path: PathBuf, got: u64, recorded: u64) -> BundleError {
    BundleError::Corrupt {
        path,
        message: format!("{got} bytes, the manifest records {recorded} (truncated or replaced)"),
    }
}

/// Reads `names` (files of `dir`) in parallel, each checked against the byte count and SHA-256
/// that `manifest.provenance.files` records for it. A file the provenance does not list, a
/// missing file, a wrong size or a wrong digest is an error naming the file.
fn read_verified(
    dir: &Path,
    manifest: &Manifest,
    names: &[&str],
) -> Result<Vec<(PathBuf, Vec<u8>)>, BundleError> {
    std::thread::scope(|s| {
        let jobs: Vec<_> = names
            .iter()
            .map(|&name| {
                s.spawn(move || -> Result<(PathBuf, Vec<u8>), BundleError> {
                    let path = dir.join(name);
                    checks::regular_inside(dir, &path)?;
                    let expect = manifest
                        .provenance
                        .files
                        .iter()
                        .find(|d| d.file == name)
                        .ok_or_else(|| BundleError::Manifest {
                            path: dir.join(MANIFEST_FILE),
                            message: format!(
                                "`provenance.files` has no size and SHA-256 for `{name}` (every file a bundle uses is hashed)"
                            ),
                        })?;
                    let bytes = std::fs::read(&path).map_err(|source| BundleError::Read {
                        path: path.clone(),
                        source,
                    })?;
                    if bytes.len() as u64 != expect.bytes {
                        return Err(size_mismatch(path, bytes.len() as u64, expect.bytes));
                    }
                    let got = hex(&Sha256::digest(&bytes));
                    if got != expect.sha256 {
                        return Err(BundleError::Corrupt {
                            path,
                            message: format!(
                                "SHA-256 {got} differs from the manifest's {} (the file is damaged or was changed after the build)",
                                expect.sha256
                            ),
                        });
                    }
                    Ok((path, bytes))
                })
            })
            .collect();
        jobs.into_iter()
            .map(|j| j.join().expect("a reader thread does not panic"))
            .collect()
    })
}

/// Checks the manifest's georeference: a finite, non-degenerate, north-up material-raster
/// geotransform, a finite extent with min < max, and a finite frame origin.
fn check_georeference(m: &Manifest, path: &Path) -> Result<(), BundleError> {
    let bad = |message: String| BundleError::Manifest {
        path: path.to_path_buf(),
        message,
    };
    let gt = m.material_raster.geotransform;
    if !gt.iter().all(|v| v.is_finite()) || gt[1] <= 0.0 || gt[5] >= 0.0 {
        return Err(bad(format!(
            "`material_raster.geotransform` {gt:?} is not a north-up transform (finite, pixel width > 0, pixel height < 0)"
        )));
    }
    if gt[2] != 0.0 || gt[4] != 0.0 {
        return Err(bad(format!(
            "`material_raster.geotransform` {gt:?} is rotated; bundles are north-up"
        )));
    }
    let e = &m.extent;
    let finite = e
        .min
        .iter()
        .chain(&e.max)
        .chain(&e.height_range)
        .all(|v| v.is_finite());
    if !finite
        || e.min[0] >= e.max[0]
        || e.min[1] >= e.max[1]
        || e.height_range[0] > e.height_range[1]
    {
        return Err(bad(format!(
            "`extent` (min {:?}, max {:?}, height_range {:?}) is not finite or is inverted",
            e.min, e.max, e.height_range
        )));
    }
    if !m.frame.origin.iter().all(|v| v.is_finite()) {
        return Err(bad(format!(
            "`frame.origin` {:?} is not finite",
            m.frame.origin
        )));
    }
    Ok(())
}

/// Checks the material table of a manifest (`path` names it): indices unique and below
/// [`NO_MATERIAL`], every BRDF within [`crate::BRDF_PARAM_RANGES`].
pub(crate) fn check_material_table(materials: &[Material], path: &Path) -> Result<(), BundleError> {
    let mut seen: [Option<usize>; 256] = [None; 256];
    for (k, m) in materials.iter().enumerate() {
        if m.index == NO_MATERIAL {
            return Err(BundleError::Manifest {
                path: path.into(),
                message: format!(
                    "materials[{k}] (`{}`): index {NO_MATERIAL} is reserved for \"no material\" (use 0–254)",
                    m.name
                ),
            });
        }
        if let Some(j) = seen[m.index as usize].replace(k) {
            return Err(BundleError::Manifest {
                path: path.into(),
                message: format!(
                    "materials[{k}] (`{}`) and materials[{j}] (`{}`) have the same index {}",
                    m.name, materials[j].name, m.index
                ),
            });
        }
        m.brdf
            .validate_stored()
            .map_err(|source| BundleError::Brdf {
                path: path.into(),
                index: m.index,
                name: m.name.clone(),
                source,
            })?;
        if let Some(Err((key, message))) = m.solver.as_ref().map(|s| s.validate()) {
            return Err(BundleError::Manifest {
                path: path.into(),
                message: format!("materials[{k}] (`{}`): solver.{key}: {message}", m.name),
            });
        }
        if let Some(t) = m.temperature {
            if !(t > 0.0 && t <= 10_000.0) {
                return Err(BundleError::Manifest {
                    path: path.into(),
                    message: format!(
                        "materials[{k}] (`{}`): temperature {t} K must lie in (0, 10000] K",
                        m.name
                    ),
                });
            }
        }
    }
    Ok(())
}

/// Checks that every id of the material raster (but [`NO_MATERIAL`]) and of the template
/// triangles is the index of a material; the error names `dir/materials.u8` or
/// `dir/templates.bin` and counts the pixels or triangles of each unknown id.
pub(crate) fn check_material_ids(
    materials: &[Material],
    raster: &[u8],
    templates: &[TemplateMesh],
    dir: &Path,
) -> Result<(), BundleError> {
    let mut known = [false; 256];
    for m in materials {
        known[m.index as usize] = true;
    }
    let unknown = |counts: &[u64; 256], skip_no_material: bool| -> Vec<(u8, u64)> {
        (0..256)
            .filter(|&i| counts[i] > 0 && !known[i] && !(skip_no_material && i == 255))
            .map(|i| (i as u8, counts[i]))
            .collect()
    };
    let mut known_ids: Vec<u8> = materials.iter().map(|m| m.index).collect();
    known_ids.sort_unstable();
    let mut counts = [0u64; 256];
    for &v in raster {
        counts[v as usize] += 1;
    }
    let ids = unknown(&counts, true);
    if !ids.is_empty() {
        return Err(BundleError::UnknownMaterialIds {
            path: dir.join(MATERIALS_FILE),
            counted: "pixel",
            ids,
            known: known_ids,
        });
    }
    let mut counts = [0u64; 256];
    for t in templates {
        for &v in &t.materials {
            counts[v as usize] += 1;
        }
    }
    let ids = unknown(&counts, false);
    if !ids.is_empty() {
        return Err(BundleError::UnknownMaterialIds {
            path: dir.join(TEMPLATES_FILE),
            counted: "triangle",
            ids,
            known: known_ids,
        });
    }
    Ok(())
}

fn f32s(b: &[u8]) -> Vec<f32> {
    b.chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

fn u32s(b: &[u8]) -> Vec<u32> {
    b.chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Records the current size and SHA-256 of every binary file in the manifest, as a writer
    /// would: tests that damage a buffer's *content* call it so that the checks behind the
    /// digest (ids, vertices, counts) are reached.
    pub(crate) fn reseal(dir: &Path) {
        let mut m = Bundle::read_manifest(dir).unwrap();
        for d in &mut m.provenance.files {
            let bytes = std::fs::read(dir.join(&d.file)).unwrap();
            d.bytes = bytes.len() as u64;
            d.sha256 = hex(&Sha256::digest(&bytes));
        }
        std::fs::write(dir.join(MANIFEST_FILE), toml::to_string(&m).unwrap()).unwrap();
    }
    use crate::{BiLambertianSpec, BrdfSpec, LambertianSpec, RpvSpec, Spectrum};

    pub(crate) fn sample() -> Bundle {
        let manifest = Manifest {
            format: FORMAT_NAME.into(),
            format_version: FORMAT_VERSION,
            crs: Crs {
                wkt: "LOCAL_CS[\"test\"]".into(),
                epsg: None,
                proj: Some("+proj=aeqd".into()),
            },
            frame: LocalFrame {
                kind: "projected_enu".into(),
                origin: [0.0; 3],
                centre_lon_lat: [5.7, 45.2],
                vertical_datum: "unknown".into(),
            },
            extent: Extent {
                min: [-100.0, -100.0],
                max: [100.0, 100.0],
                height_range: [1.0, 2.0],
                lon_lat_bbox: [5.6, 45.1, 5.8, 45.3],
            },
            terrain: Terrain {
                file: String::new(),
                tolerance_m: 1.0,
                dem_spacing_m: 30.0,
                dem_samples: 49,
                vertex_count: 0,
                triangle_count: 0,
                tiles: vec![],
            },
            material_raster: MaterialRaster {
                file: String::new(),
                width: 2,
                height: 2,
                geotransform: [-100.0, 100.0, 0.0, 100.0, 0.0, -100.0],
                resampling: "mode".into(),
                histogram: vec![],
            },
            materials: vec![
                Material {
                    index: 0,
                    name: "grass".into(),
                    brdf: BrdfSpec::Lambertian(LambertianSpec {
                        reflectance: Spectrum::Constant(0.2),
                    }),
                    class_codes: vec![30],
                    source: "test".into(),
                    solver: None,
                    temperature: None,
                },
                Material {
                    index: 1,
                    name: "leaf".into(),
                    brdf: BrdfSpec::BiLambertian(BiLambertianSpec {
                        reflectance: Spectrum::Table {
                            wavelengths_nm: vec![400.0, 800.0],
                            values: vec![0.05, 0.45],
                        },
                        transmittance: Spectrum::Constant(0.4),
                    }),
                    class_codes: vec![],
                    source: "test".into(),
                    solver: None,
                    temperature: None,
                },
            ],
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
                seed: 7,
                region_toml: "a = 1\n".into(),
                inputs: vec![InputFile {
                    role: "dem".into(),
                    path: "x.tif".into(),
                    bytes: 3,
                    sha256: "00".into(),
                }],
                files: vec![],
            },
        };
        Bundle {
            manifest,
            terrain: vec![TerrainTile {
                id: [0, 0],
                origin: [-100.0, -100.0, 0.0],
                positions: vec![[0.0, 0.0, 1.0], [200.0, 0.0, 2.0], [0.0, 200.0, 1.5]],
                uvs: vec![[0.0, 1.0], [1.0, 1.0], [0.0, 0.0]],
                indices: vec![[0, 1, 2]],
            }],
            templates: vec![TemplateMesh {
                name: "tri".into(),
                source: "procedural".into(),
                positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
                indices: vec![[0, 1, 2]],
                materials: vec![1],
                lamps: Vec::new(),
            }],
            instances: vec![
                Instance {
                    translation: [1.5, -2.25, 1.0e5 + 0.125],
                    linear: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
                    template: 0,
                },
                Instance {
                    translation: [3.0, 4.0, 5.0],
                    linear: [0.0, 2.0, 0.0, -2.0, 0.0, 0.0, 0.0, 0.0, 2.0],
                    template: 0,
                },
            ],
            material_raster: vec![0, 1, 255, 0],
        }
    }

    /// Rationale (issue 43): coordinates beyond `MAX_COORDINATE_M` (an instance moved 1e300 m,
    /// a template scaled 1e19, a template vertex at 1e20, a terrain vertex at 3e38) used to pass
    /// every check and panic inside the BVH builder; the writer refuses to write them and the
    /// reader refuses them on open, naming the part.
    #[test]
    fn coordinates_beyond_the_bound_are_refused() {
        let dir = std::env::temp_dir().join(format!("bundle-far-{}", std::process::id()));
        type Damage = Box<dyn Fn(&mut Bundle)>;
        let cases: Vec<(Damage, &str)> = vec![
            (
                Box::new(|b| b.instances[0].translation[0] = 1e300),
                "instance 0",
            ),
            (
                Box::new(|b| {
                    b.instances[1].linear = [1e19, 0.0, 0.0, 0.0, 1e19, 0.0, 0.0, 0.0, 1e19]
                }),
                "instance 1",
            ),
            (
                Box::new(|b| b.templates[0].positions[1][0] = 1e20),
                "template",
            ),
            (Box::new(|b| b.terrain[0].positions[2][2] = 3e38), "tile"),
        ];
        // The writer refuses them (scenegen never writes such a bundle) ...
        for (damage, needle) in cases {
            let _ = std::fs::remove_dir_all(&dir);
            let mut b = sample();
            damage(&mut b);
            let e = b.write(&dir, false).unwrap_err().to_string();
            assert!(
                e.contains(needle) && e.contains("bounded by 1e7 m"),
                "write, {needle}: {e}"
            );
            assert!(!dir.exists());
        }
        // ... and the reader refuses a bundle edited after writing (resealed digests): an
        // instance moved 1e300 m, and one scaled 1e19.
        for (offset, bytes, needle) in [
            (0usize, 1e300f64.to_le_bytes().to_vec(), "instance 0"),
            (64 + 24, 1e19f32.to_le_bytes().to_vec(), "instance 1"),
        ] {
            let _ = std::fs::remove_dir_all(&dir);
            sample().write(&dir, false).unwrap();
            let path = dir.join(INSTANCES_FILE);
            let mut raw = std::fs::read(&path).unwrap();
            raw[offset..offset + bytes.len()].copy_from_slice(&bytes);
            std::fs::write(&path, raw).unwrap();
            reseal(&dir);
            let e = Bundle::open(&dir).unwrap_err().to_string();
            assert!(
                e.contains(needle) && e.contains("bounded by 1e7 m"),
                "open, {needle}: {e}"
            );
        }
        // The sample itself (an instance 100 km up) opens.
        let _ = std::fs::remove_dir_all(&dir);
        sample().write(&dir, false).unwrap();
        assert!(Bundle::open(&dir).is_ok());
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// Rationale: the bundle is the contract between two programs; everything written must come
    /// back bit for bit, and the manifest must carry the counts, offsets and digests.
    #[test]
    fn write_then_open_round_trips() {
        let dir = std::env::temp_dir().join(format!("bundle-rt-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let b = sample();
        let written = b.write(&dir, false).unwrap();
        let back = Bundle::open(&dir).unwrap();
        assert_eq!(back.manifest, written);
        assert_eq!(back.terrain, b.terrain);
        assert_eq!(back.templates, b.templates);
        assert_eq!(back.instances, b.instances);
        assert_eq!(back.material_raster, b.material_raster);
        assert_eq!(written.instances.per_template, vec![2]);
        assert_eq!(written.material_raster.histogram[0], 2);
        assert_eq!(written.material_raster.histogram[255], 1);
        assert_eq!(written.provenance.files.len(), 4);
        Bundle::verify(&dir).unwrap();
        // An existing directory is refused without force, replaced with it.
        assert!(matches!(
            b.write(&dir, false),
            Err(BundleError::Exists { .. })
        ));
        b.write(&dir, true).unwrap();
        // A flipped byte is caught by verify.
        let p = dir.join("materials.u8");
        std::fs::write(&p, [0u8, 1, 255, 1]).unwrap();
        assert!(matches!(
            Bundle::verify(&dir),
            Err(BundleError::Corrupt { .. })
        ));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Rationale: a reader must refuse a bundle of another version with a message saying so,
    /// and a truncated buffer with the file named, instead of misreading it.
    #[test]
    fn wrong_version_and_truncation_are_refused() {
        let dir = std::env::temp_dir().join(format!("bundle-bad-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        sample().write(&dir, false).unwrap();
        let mpath = dir.join("manifest.toml");
        let text = std::fs::read_to_string(&mpath).unwrap();
        std::fs::write(
            &mpath,
            text.replace("format_version = 1", "format_version = 99"),
        )
        .unwrap();
        let e = Bundle::open(&dir).unwrap_err();
        assert!(matches!(e, BundleError::Version { found: 99, .. }), "{e}");
        std::fs::write(&mpath, &text).unwrap();
        let t = dir.join("instances.bin");
        let bytes = std::fs::read(&t).unwrap();
        std::fs::write(&t, &bytes[..bytes.len() - 1]).unwrap();
        let e = Bundle::open(&dir).unwrap_err();
        assert!(e.to_string().contains("instances.bin"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Rationale: `--force` must never delete data that is not a bundle (issue 15): a directory
    /// of other files, or a file, is refused and left untouched; an empty directory and an
    /// existing bundle are replaced.
    #[test]
    fn force_replaces_only_bundles() {
        let parent = tmpdir("force");
        std::fs::create_dir_all(&parent).unwrap();
        let b = sample();
        // A folder of someone's data.
        let data = parent.join("thesis");
        std::fs::create_dir_all(&data).unwrap();
        std::fs::write(data.join("chapter1.tex"), "precious").unwrap();
        let e = b.write(&data, true).unwrap_err();
        assert!(matches!(e, BundleError::NotABundle { .. }), "{e}");
        assert!(
            e.to_string().contains("thesis") && e.to_string().contains("no manifest.toml"),
            "{e}"
        );
        assert_eq!(
            std::fs::read_to_string(data.join("chapter1.tex")).unwrap(),
            "precious"
        );
        // A file.
        let file = parent.join("notes.txt");
        std::fs::write(&file, "keep").unwrap();
        assert!(matches!(
            b.write(&file, true),
            Err(BundleError::NotABundle { .. })
        ));
        assert_eq!(std::fs::read_to_string(&file).unwrap(), "keep");
        // An empty directory and a bundle are replaced.
        let empty = parent.join("empty");
        std::fs::create_dir_all(&empty).unwrap();
        b.write(&empty, true).unwrap();
        b.write(&empty, true).unwrap();
        Bundle::verify(&empty).unwrap();
        // Nothing else was left in the parent (no temporary or trash directories).
        let mut names: Vec<String> = std::fs::read_dir(&parent)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        assert_eq!(names, ["empty", "notes.txt", "thesis"]);
        std::fs::remove_dir_all(&parent).unwrap();
    }

    /// Rationale: `--force` replaces only our own bundles, whole (issue 43 item 5): another
    /// tool's folder whose manifest has a `format_version` but another `format`, and a real
    /// bundle into which a user has put a file or a folder, are refused naming what is in the
    /// way, and nothing in them changes.
    #[test]
    fn force_refuses_other_formats_and_foreign_files() {
        let parent = tmpdir("force-foreign");
        std::fs::create_dir_all(&parent).unwrap();
        let b = sample();
        let other = parent.join("other-tool");
        std::fs::create_dir_all(other.join("photos")).unwrap();
        std::fs::write(
            other.join("manifest.toml"),
            "format = \"something-else\"\nformat_version = 3\n",
        )
        .unwrap();
        std::fs::write(other.join("thesis.txt"), "precious").unwrap();
        let e = b.write(&other, true).unwrap_err().to_string();
        assert!(e.contains("something-else"), "{e}");
        assert_eq!(
            std::fs::read_to_string(other.join("thesis.txt")).unwrap(),
            "precious"
        );
        assert!(other.join("photos").is_dir());
        std::fs::write(other.join("manifest.toml"), "not = [toml").unwrap();
        let e = b.write(&other, true).unwrap_err().to_string();
        assert!(e.contains("not TOML"), "{e}");

        let bundle = parent.join("bundle");
        b.write(&bundle, false).unwrap();
        std::fs::write(bundle.join("notes.txt"), "mine").unwrap();
        std::fs::create_dir_all(bundle.join("figures")).unwrap();
        let e = b.write(&bundle, true).unwrap_err().to_string();
        assert!(e.contains("figures, notes.txt"), "{e}");
        assert_eq!(
            std::fs::read_to_string(bundle.join("notes.txt")).unwrap(),
            "mine"
        );
        Bundle::verify(&bundle).unwrap();
        std::fs::remove_file(bundle.join("notes.txt")).unwrap();
        std::fs::remove_dir(bundle.join("figures")).unwrap();
        b.write(&bundle, true).unwrap();
        Bundle::verify(&bundle).unwrap();
        std::fs::remove_dir_all(&parent).unwrap();
    }

    /// Rationale: a failed write (here an inconsistent bundle) must leave neither the
    /// destination nor a temporary directory behind.
    #[test]
    fn failed_write_leaves_nothing() {
        let parent = std::env::temp_dir().join(format!("bundle-fail-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&parent);
        std::fs::create_dir_all(&parent).unwrap();
        let mut b = sample();
        b.material_raster.pop();
        let dir = parent.join("out");
        assert!(b.write(&dir, false).is_err());
        assert_eq!(std::fs::read_dir(&parent).unwrap().count(), 0);
        std::fs::remove_dir_all(&parent).unwrap();
    }

    fn tmpdir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("bundle-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        dir
    }

    /// `sample()` with the material indices 3 (grass) and 9 (leaf) instead of 0 and 1.
    fn sparse_sample() -> Bundle {
        let mut b = sample();
        b.manifest.materials[0].index = 3;
        b.manifest.materials[1].index = 9;
        b.material_raster = vec![3, 9, 255, 3];
        b.templates[0].materials = vec![9];
        b
    }

    /// Rationale: material ids are the manifest's `index`, not positions in its list; a table
    /// with gaps (3 and 9) must round-trip, with the histogram counted per index.
    #[test]
    fn non_contiguous_material_indices_round_trip() {
        let dir = tmpdir("sparse");
        let b = sparse_sample();
        let written = b.write(&dir, false).unwrap();
        let back = Bundle::open(&dir).unwrap();
        assert_eq!(back.material_raster, b.material_raster);
        assert_eq!(back.templates[0].materials, vec![9]);
        let h = &written.material_raster.histogram;
        assert_eq!((h[3], h[9], h[255]), (2, 1, 1));
        // Only the index counts: listing 9 before 3 changes nothing.
        let mut b2 = b.clone();
        b2.manifest.materials.reverse();
        b2.write(&dir, true).unwrap();
        Bundle::open(&dir).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Rationale: an id in materials.u8 or templates.bin without a `[[materials]]` entry would
    /// be drawn with some other material (or read past the table); readers must refuse it,
    /// naming the file, each unknown id and its pixel or triangle count, and the writer must
    /// not produce such a bundle.
    #[test]
    fn unknown_material_ids_are_refused_with_counts() {
        let dir = tmpdir("unknown-ids");
        sparse_sample().write(&dir, false).unwrap();
        // Raster: ids 7 (2 pixels) and 12 (1 pixel) have no material; 255 is "no material".
        std::fs::write(dir.join("materials.u8"), [3u8, 7, 7, 12]).unwrap();
        reseal(&dir);
        let e = Bundle::open(&dir).unwrap_err();
        match &e {
            BundleError::UnknownMaterialIds { path, ids, .. } => {
                assert_eq!(path, &dir.join("materials.u8"));
                assert_eq!(ids, &vec![(7, 2), (12, 1)]);
            }
            other => panic!("{other}"),
        }
        let msg = e.to_string();
        for needle in ["materials.u8", "7 (2 pixels)", "12 (1 pixel)", "ids 3, 9"] {
            assert!(msg.contains(needle), "`{needle}` not in: {msg}");
        }
        // Templates: flip the triangle's material byte to 4.
        std::fs::write(dir.join("materials.u8"), [3u8, 9, 255, 3]).unwrap();
        let m = Bundle::read_manifest(&dir).unwrap();
        let t = dir.join("templates.bin");
        let mut bytes = std::fs::read(&t).unwrap();
        bytes[m.templates[0].materials_offset as usize] = 4;
        std::fs::write(&t, bytes).unwrap();
        reseal(&dir);
        let msg = Bundle::open(&dir).unwrap_err().to_string();
        assert!(
            msg.contains("templates.bin") && msg.contains("4 (1 triangle)"),
            "{msg}"
        );
        // The writer refuses both.
        let mut b = sparse_sample();
        b.material_raster[1] = 0;
        let msg = b.write(&dir, true).unwrap_err().to_string();
        assert!(
            msg.contains("materials.u8") && msg.contains("0 (1 pixel)"),
            "{msg}"
        );
        let mut b = sparse_sample();
        b.templates[0].materials[0] = 255;
        let msg = b.write(&dir, true).unwrap_err().to_string();
        assert!(
            msg.contains("templates.bin") && msg.contains("255 (1 triangle)"),
            "{msg}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Rationale: the material table itself must be usable: unique indices below 255, and BRDF
    /// parameters within the shared range table (what `simulate` accepts).
    #[test]
    fn bad_material_tables_are_refused() {
        let dir = tmpdir("bad-table");
        let mut b = sparse_sample();
        b.manifest.materials[1].index = 3;
        let msg = b.write(&dir, false).unwrap_err().to_string();
        assert!(msg.contains("same index 3"), "{msg}");
        let mut b = sparse_sample();
        b.manifest.materials[0].index = 255;
        let msg = b.write(&dir, false).unwrap_err().to_string();
        assert!(msg.contains("reserved"), "{msg}");
        // A manifest edited to RPV k = 5 is refused at open, naming material and parameter.
        sparse_sample().write(&dir, false).unwrap();
        let mpath = dir.join("manifest.toml");
        let text = std::fs::read_to_string(&mpath).unwrap();
        let mut m: Manifest = toml::from_str(&text).unwrap();
        m.materials[0].brdf = BrdfSpec::Rpv(RpvSpec {
            rho_0: Spectrum::Constant(0.1),
            k: Spectrum::Constant(5.0),
            g: Spectrum::Constant(0.0),
            rho_c: None,
        });
        std::fs::write(&mpath, toml::to_string(&m).unwrap()).unwrap();
        let msg = Bundle::open(&dir).unwrap_err().to_string();
        assert!(
            msg.contains("manifest.toml")
                && msg.contains("material `grass` (index 3)")
                && msg.contains("`k` = 5 must lie in [0, 2]"),
            "{msg}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn spectrum_interpolates_and_clamps() {
        let s = Spectrum::Table {
            wavelengths_nm: vec![400.0, 500.0],
            values: vec![0.1, 0.3],
        };
        assert!((s.at(450.0) - 0.2).abs() < 1e-12);
        assert_eq!(s.at(300.0), 0.1);
        assert_eq!(s.at(900.0), 0.3);
        assert!(Spectrum::Table {
            wavelengths_nm: vec![500.0, 400.0],
            values: vec![0.1, 0.3]
        }
        .validate()
        .is_err());
    }
}

#[cfg(test)]
mod damaged_input_tests {
    use super::*;

    fn written(name: &str) -> (PathBuf, Manifest) {
        let dir =
            std::env::temp_dir().join(format!("bundle-damaged-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let m = tests::sample().write(&dir, false).unwrap();
        (dir, m)
    }

    /// Rationale (issue 15): a NaN vertex used to panic inside the BVH library, and a huge
    /// `vertex_count` overflowed the size check and panicked on an index. Both are refused at
    /// open with the file, the tile and the vertex named.
    #[test]
    fn nan_vertex_and_huge_counts_are_refused() {
        let (dir, m) = written("nan");
        let t = &m.terrain.tiles[0];
        let path = dir.join(&m.terrain.file);
        let mut bytes = std::fs::read(&path).unwrap();
        let at = t.positions_offset as usize + 12 + 8; // vertex 1, z
        bytes[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
        std::fs::write(&path, &bytes).unwrap();
        tests::reseal(&dir);
        let e = Bundle::open(&dir).unwrap_err();
        let msg = e.to_string();
        assert!(
            matches!(e, BundleError::Corrupt { .. })
                && msg.contains("vertex 1")
                && msg.contains("non-finite")
                && msg.contains(&m.terrain.file),
            "{msg}"
        );
        std::fs::remove_dir_all(&dir).unwrap();

        let (dir, m) = written("huge");
        let mpath = dir.join(MANIFEST_FILE);
        let text = std::fs::read_to_string(&mpath).unwrap();
        let line = format!("vertex_count = {}", m.terrain.tiles[0].vertex_count);
        assert!(text.contains(&line), "{text}");
        std::fs::write(
            &mpath,
            // Every count of 3 (the terrain total, the tile, the template) becomes one whose
            // byte size overflows u64.
            text.replace(&line, "vertex_count = 3074457345618258603"),
        )
        .unwrap();
        let e = Bundle::open(&dir).unwrap_err();
        assert!(
            matches!(e, BundleError::Corrupt { .. }) && e.to_string().contains("impossibly large"),
            "{e}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Rationale (issue 15): a flipped byte in a buffer rendered silently (digests were only
    /// checked by `info --verify`), and a deleted buffer was only noticed late. Open checks
    /// every file's size and SHA-256 and names the file.
    #[test]
    fn flipped_truncated_or_missing_buffers_are_refused_at_open() {
        for file in [
            "terrain.bin",
            "templates.bin",
            "instances.bin",
            "materials.u8",
        ] {
            let (dir, _) = written("flip");
            let path = dir.join(file);
            let mut bytes = std::fs::read(&path).unwrap();
            bytes[0] ^= 0x10;
            std::fs::write(&path, &bytes).unwrap();
            let msg = Bundle::open(&dir).unwrap_err().to_string();
            assert!(msg.contains(file) && msg.contains("SHA-256"), "{msg}");
            std::fs::write(&path, &bytes[..bytes.len() - 1]).unwrap();
            let msg = Bundle::open(&dir).unwrap_err().to_string();
            assert!(msg.contains(file) && msg.contains("truncated"), "{msg}");
            std::fs::remove_file(&path).unwrap();
            let e = Bundle::open(&dir).unwrap_err();
            assert!(
                matches!(e, BundleError::Read { .. }) && e.to_string().contains(file),
                "{e}"
            );
            assert!(Bundle::verify(&dir).is_err());
            std::fs::remove_dir_all(&dir).unwrap();
        }
    }

    /// Rationale (issue 15): a NaN or zero geotransform or an inverted extent rendered black
    /// pixels and wrong area averages without a word.
    #[test]
    fn bad_georeference_is_refused() {
        let (dir, m) = written("georef");
        let mpath = dir.join(MANIFEST_FILE);
        let good = m.clone();
        type Damage = Box<dyn Fn(&mut Manifest)>;
        let cases: Vec<(Damage, &str)> = vec![
            (
                Box::new(|m| m.material_raster.geotransform[1] = f64::NAN),
                "geotransform",
            ),
            (
                Box::new(|m| m.material_raster.geotransform = [0.0; 6]),
                "geotransform",
            ),
            (
                Box::new(|m| m.material_raster.geotransform[2] = 0.5),
                "rotated",
            ),
            (
                Box::new(|m| m.extent.max[0] = m.extent.min[0] - 1.0),
                "extent",
            ),
            (
                Box::new(|m| m.extent.height_range = [10.0, -10.0]),
                "extent",
            ),
            (
                Box::new(|m| m.frame.origin[2] = f64::INFINITY),
                "frame.origin",
            ),
        ];
        for (damage, needle) in cases {
            let mut m = good.clone();
            damage(&mut m);
            std::fs::write(&mpath, toml::to_string(&m).unwrap()).unwrap();
            let msg = Bundle::open(&dir).unwrap_err().to_string();
            assert!(
                msg.contains("manifest.toml") && msg.contains(needle),
                "{needle}: {msg}"
            );
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

#[cfg(test)]
#[path = "io_proptests.rs"]
mod proptests;
