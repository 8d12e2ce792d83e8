//! What a reader checks beyond each file's size and SHA-256 (issue 43, "a bundle that cannot
//! lie"):
//!
//! * **Confinement.** Every file name the manifest gives (`terrain.file`, `instances.file`,
//!   `material_raster.file`, `provenance.files`, a `tabulated` material's `file`) is a relative
//!   path of plain components: no absolute path, no `..`, no `.`, nothing empty. Each file read
//!   must be a regular file whose real path (symbolic links resolved) lies inside the bundle
//!   folder; a FIFO or device is refused from its metadata, before any `open` could block.
//! * **Cross-checks.** The manifest's totals against its own tables (terrain vertex and triangle
//!   totals = the sums over tiles; instance count = the sum of `per_template`, one entry per
//!   template; template ids 0, 1, …), its byte layout against the files (tiles and templates
//!   contiguous from byte 0 to the file's end, as the writer lays them out), its summaries
//!   against the data (the raster's `histogram`, the instances per template, each template's
//!   bounds), and the raster's footprint against the extent (so a `width × height` or pixel size
//!   that still multiplies to the right byte count is caught).
//!
//! The digests say a file is the one the manifest describes; these checks say the description
//! is one the writer could have made.

use std::path::{Component, Path, PathBuf};

use super::manifest::Manifest;
use super::BundleError;

/// `name` as a path inside the bundle folder `dir`, refused (naming `key` of the manifest at
/// `manifest`) unless it is relative and made of plain components only.
pub(crate) fn confined(
    dir: &Path,
    name: &str,
    key: &str,
    manifest: &Path,
) -> Result<PathBuf, BundleError> {
    let p = Path::new(name);
    let plain = !name.is_empty()
        && !name.contains('\0')
        && p.components().all(|c| matches!(c, Component::Normal(_)));
    if !plain {
        return Err(BundleError::Manifest {
            path: manifest.to_path_buf(),
            message: format!(
                "`{key}` = {name:?} is not a file inside the bundle folder (absolute paths, `..`, `.` and empty names are refused)"
            ),
        });
    }
    Ok(dir.join(p))
}

/// Refuses `path` unless it is a regular file whose real location is inside `dir`: a missing
/// file is [`BundleError::Read`], a symbolic link that leaves the folder, a FIFO, a device or a
/// directory is [`BundleError::Corrupt`]. Only metadata is read, so a FIFO never blocks.
pub(crate) fn regular_inside(dir: &Path, path: &Path) -> Result<(), BundleError> {
    let read_err = |source| BundleError::Read {
        path: path.to_path_buf(),
        source,
    };
    let own = std::fs::symlink_metadata(path).map_err(read_err)?;
    let real = std::fs::canonicalize(path).map_err(read_err)?;
    let home = std::fs::canonicalize(dir).map_err(|source| BundleError::Read {
        path: dir.to_path_buf(),
        source,
    })?;
    if !real.starts_with(&home) {
        return Err(BundleError::Corrupt {
            path: path.to_path_buf(),
            message: format!(
                "{} to {}, outside the bundle folder; a bundle reads only files inside its folder",
                if own.file_type().is_symlink() {
                    "a symbolic link"
                } else {
                    "a path that leads (through a linked folder)"
                },
                real.display()
            ),
        });
    }
    let meta = std::fs::metadata(&real).map_err(read_err)?;
    if !meta.is_file() {
        let kind = meta.file_type();
        use std::os::unix::fs::FileTypeExt;
        let what = if kind.is_dir() {
            "a directory"
        } else if kind.is_fifo() {
            "a FIFO (named pipe)"
        } else if kind.is_block_device() || kind.is_char_device() {
            "a device"
        } else if kind.is_socket() {
            "a socket"
        } else {
            "not a regular file"
        };
        return Err(BundleError::Corrupt {
            path: path.to_path_buf(),
            message: format!("{what}; bundle files must be regular files"),
        });
    }
    Ok(())
}

/// Every file name of `m` confined to the bundle (see [`confined`]).
pub(crate) fn names_confined(m: &Manifest, dir: &Path, manifest: &Path) -> Result<(), BundleError> {
    confined(dir, &m.terrain.file, "terrain.file", manifest)?;
    confined(dir, &m.instances.file, "instances.file", manifest)?;
    confined(
        dir,
        &m.material_raster.file,
        "material_raster.file",
        manifest,
    )?;
    for (k, f) in m.provenance.files.iter().enumerate() {
        confined(
            dir,
            &f.file,
            &format!("provenance.files[{k}].file"),
            manifest,
        )?;
    }
    // The four buffers are four files.
    let buffers = [
        ("terrain.file", m.terrain.file.as_str()),
        ("templates", super::TEMPLATES_FILE),
        ("instances.file", m.instances.file.as_str()),
        ("material_raster.file", m.material_raster.file.as_str()),
    ];
    for (i, (key, name)) in buffers.iter().enumerate() {
        let same = buffers[..i]
            .iter()
            .find(|(_, n)| Path::new(n) == Path::new(name));
        if let Some((other, _)) = same {
            return Err(BundleError::Manifest {
                path: manifest.to_path_buf(),
                message: format!(
                    "`{key}` = {name:?} names the file of `{other}`; the terrain, templates, instances and material raster are four files"
                ),
            });
        }
    }
    for (k, name) in table_files(m) {
        confined(dir, name, &format!("materials[{k}].brdf.file"), manifest)?;
    }
    Ok(())
}

/// The files of `tabulated` materials, with the material's position in the table.
pub(crate) fn table_files(m: &Manifest) -> impl Iterator<Item = (usize, &str)> {
    m.materials
        .iter()
        .enumerate()
        .filter_map(|(k, mat)| match &mat.brdf {
            crate::BrdfSpec::Tabulated(t) => Some((k, t.file.as_str())),
            _ => None,
        })
}

/// `count × each` bytes, refused as impossibly large where it overflows.
fn bytes(count: u64, each: u64, what: &str, manifest: &Path) -> Result<u64, BundleError> {
    count.checked_mul(each).ok_or_else(|| BundleError::Corrupt {
        path: manifest.to_path_buf(),
        message: format!("{what}: count {count} is impossibly large"),
    })
}

/// Parts `(key, offset, bytes)` of `what` laid back to back from byte `at`: each must start
/// where the previous one ended. Returns the byte after the last.
fn back_to_back(mut at: u64, what: &str, parts: &[(&str, u64, u64)]) -> Result<u64, String> {
    for &(key, off, size) in parts {
        if off != at {
            return Err(format!(
                "{what}: `{key}` = {off}, where the layout puts byte {at}"
            ));
        }
        at = at.saturating_add(size);
    }
    Ok(at)
}

/// The layout of `what` ends at byte `at`, which must be the length `file_len` of `file`.
fn ends_at(at: u64, what: &str, file: &str, file_len: u64) -> Result<(), String> {
    if at == file_len {
        Ok(())
    } else {
        Err(format!(
            "the {what} describe {at} bytes, {file} has {file_len}"
        ))
    }
}

/// The manifest's totals and layout against its own tables and the file sizes `len(name)`.
pub(crate) fn totals_and_layout(
    m: &Manifest,
    manifest: &Path,
    len: impl Fn(&str) -> u64,
) -> Result<(), BundleError> {
    let bad = |message: String| BundleError::Manifest {
        path: manifest.to_path_buf(),
        message,
    };
    let t = &m.terrain;
    let (nv, nt) = t.tiles.iter().fold((0u64, 0u64), |(v, n), x| {
        (
            v.saturating_add(x.vertex_count),
            n.saturating_add(x.triangle_count),
        )
    });
    if nv != t.vertex_count || nt != t.triangle_count {
        return Err(bad(format!(
            "`terrain.vertex_count` = {} and `terrain.triangle_count` = {} disagree with the tiles' sums ({nv} vertices, {nt} triangles)",
            t.vertex_count, t.triangle_count
        )));
    }
    // Terrain tiles: positions, uvs, indices, back to back from byte 0.
    let mut at = 0u64;
    for x in &t.tiles {
        let what = format!("terrain tile {:?}", x.id);
        let parts = [
            (
                "positions_offset",
                x.positions_offset,
                bytes(x.vertex_count, 12, &what, manifest)?,
            ),
            (
                "uvs_offset",
                x.uvs_offset,
                bytes(x.vertex_count, 8, &what, manifest)?,
            ),
            (
                "indices_offset",
                x.indices_offset,
                bytes(x.triangle_count, 12, &what, manifest)?,
            ),
        ];
        at = back_to_back(at, &what, &parts).map_err(bad)?;
    }
    ends_at(at, "terrain tiles", &t.file, len(&t.file)).map_err(bad)?;
    // Templates: ids in order, contiguous, each padded to 4 bytes.
    let mut at = 0u64;
    for (k, x) in m.templates.iter().enumerate() {
        if x.id as usize != k {
            return Err(bad(format!(
                "`templates[{k}].id` = {}; template ids are their positions 0, 1, …",
                x.id
            )));
        }
        let what = format!("template {k} ({})", x.name);
        let parts = [
            (
                "positions_offset",
                x.positions_offset,
                bytes(x.vertex_count, 12, &what, manifest)?,
            ),
            (
                "indices_offset",
                x.indices_offset,
                bytes(x.triangle_count, 12, &what, manifest)?,
            ),
            ("materials_offset", x.materials_offset, x.triangle_count),
        ];
        at = back_to_back(at, &what, &parts).map_err(bad)?;
        at = at.saturating_add((4 - at % 4) % 4);
    }
    let file = super::TEMPLATES_FILE;
    ends_at(at, "templates", file, len(file)).map_err(bad)?;
    // Instances: one count per template, summing to the total.
    let i = &m.instances;
    if i.per_template.len() != m.templates.len() {
        return Err(bad(format!(
            "`instances.per_template` has {} entries for {} templates",
            i.per_template.len(),
            m.templates.len()
        )));
    }
    let sum = i
        .per_template
        .iter()
        .fold(0u64, |a, &b| a.saturating_add(b));
    if sum != i.count {
        return Err(bad(format!(
            "`instances.count` = {} but `instances.per_template` sums to {sum}",
            i.count
        )));
    }
    footprint(m, manifest)
}

/// The material raster's footprint (`width × height` pixels of the geotransform) against the
/// extent: the writer starts it at the extent's north-west corner and makes it exceed the
/// extent by less than one pixel in each direction (`scenegen`'s `Grid::cells_over`), so a
/// raster declared with another shape or pixel size (same byte count) is refused.
fn footprint(m: &Manifest, manifest: &Path) -> Result<(), BundleError> {
    let r = &m.material_raster;
    let gt = r.geotransform;
    let (pw, ph) = (gt[1], -gt[5]);
    let (w, h) = (f64::from(r.width) * pw, f64::from(r.height) * ph);
    let (min, max) = (m.extent.min, m.extent.max);
    let (ew, eh) = (max[0] - min[0], max[1] - min[1]);
    // Rounding of coordinates of up to 10⁷ m and of sums of many pixels.
    let tol = 1e-3 + 1e-9 * (min[0].abs() + max[1].abs() + w.abs() + h.abs());
    let fits = (gt[0] - min[0]).abs() <= tol
        && (gt[3] - max[1]).abs() <= tol
        && (-tol..pw + tol).contains(&(w - ew))
        && (-tol..ph + tol).contains(&(h - eh));
    if !fits {
        return Err(BundleError::Manifest {
            path: manifest.to_path_buf(),
            message: format!(
                "the material raster ({} × {} pixels of {pw} × {ph} m from ({}, {}), {w} × {h} m) does not match the extent ({ew} × {eh} m from ({}, {})): it must start at the extent's north-west corner and exceed it by less than one pixel",
                r.width, r.height, gt[0], gt[3], min[0], max[1]
            ),
        });
    }
    Ok(())
}

/// The raster's recorded `histogram` against its pixels (entries beyond the list count 0).
pub(crate) fn histogram(m: &Manifest, manifest: &Path, raster: &[u8]) -> Result<(), BundleError> {
    let got = pixel_counts(raster);
    let rec = &m.material_raster.histogram;
    if rec.len() > 256 {
        return Err(BundleError::Manifest {
            path: manifest.to_path_buf(),
            message: format!(
                "`material_raster.histogram` has {} entries; ids are 0–255",
                rec.len()
            ),
        });
    }
    if let Some(id) = (0..256).find(|&i| rec.get(i).copied().unwrap_or(0) != got[i]) {
        return Err(BundleError::Manifest {
            path: manifest.to_path_buf(),
            message: format!(
                "`material_raster.histogram` counts {} pixels of id {id}, {} holds {}",
                rec.get(id).copied().unwrap_or(0),
                m.material_raster.file,
                got[id]
            ),
        });
    }
    Ok(())
}

/// Pixels per material id of a raster (the manifest's `histogram`, before truncation).
pub(crate) fn pixel_counts(raster: &[u8]) -> [u64; 256] {
    let mut n = [0u64; 256];
    for &v in raster {
        n[v as usize] += 1;
    }
    n
}

/// Axis-aligned bounds of a template's vertices (zeros for a template without any), as the
/// manifest records them.
pub(crate) fn bounds(positions: &[[f32; 3]]) -> ([f32; 3], [f32; 3]) {
    if positions.is_empty() {
        return ([0.0; 3], [0.0; 3]);
    }
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for p in positions {
        for j in 0..3 {
            lo[j] = lo[j].min(p[j]);
            hi[j] = hi[j].max(p[j]);
        }
    }
    (lo, hi)
}

/// Instances counted per template against `per_template`.
pub(crate) fn instances_per_template(
    m: &Manifest,
    manifest: &Path,
    templates_of: impl Iterator<Item = u32>,
) -> Result<(), BundleError> {
    let mut got = vec![0u64; m.templates.len()];
    for t in templates_of {
        if let Some(c) = got.get_mut(t as usize) {
            *c += 1;
        }
    }
    if let Some(k) = (0..got.len()).find(|&k| got[k] != m.instances.per_template[k]) {
        return Err(BundleError::Manifest {
            path: manifest.to_path_buf(),
            message: format!(
                "`instances.per_template[{k}]` = {}, {} holds {} instances of template {k}",
                m.instances.per_template[k], m.instances.file, got[k]
            ),
        });
    }
    Ok(())
}

/// A template's recorded bounds against its vertices (exactly: the writer computes them from
/// the same f32 values; a template without vertices records zeros).
pub(crate) fn template_bounds(
    m: &Manifest,
    manifest: &Path,
    k: usize,
    positions: &[[f32; 3]],
) -> Result<(), BundleError> {
    let (lo, hi) = bounds(positions);
    let t = &m.templates[k];
    if t.bounds_min != lo || t.bounds_max != hi {
        return Err(BundleError::Manifest {
            path: manifest.to_path_buf(),
            message: format!(
                "template {k} ({}): bounds {:?}–{:?} recorded, its vertices span {lo:?}–{hi:?}",
                t.name, t.bounds_min, t.bounds_max
            ),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::tests::sample;
    use crate::{BrdfSpec, Bundle, TabulatedSpec};

    fn fresh(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("bundle-checks-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        sample().write(&dir, false).unwrap();
        dir
    }

    fn edit(dir: &Path, from: &str, to: &str) {
        let p = dir.join("manifest.toml");
        let t = std::fs::read_to_string(&p).unwrap();
        assert!(t.contains(from), "manifest has no `{from}`:\n{t}");
        std::fs::write(&p, t.replacen(from, to, 1)).unwrap();
    }

    fn refused(dir: &Path, needles: &[&str]) {
        for (what, e) in [
            ("open", Bundle::open(dir).map(|_| ())),
            ("verify", Bundle::verify(dir)),
        ] {
            let msg = e
                .expect_err(&format!("{what} {}", dir.display()))
                .to_string();
            for n in needles {
                assert!(msg.contains(n), "{what}: `{n}` not in: {msg}");
            }
        }
    }

    /// Rationale (issue 43): manifest entries with an absolute path or `..` were read (with a
    /// matching hash); symbolic links leaving the bundle were followed; a FIFO in place of a
    /// buffer blocked forever. All are refused, naming the key or the file, without blocking.
    #[test]
    fn files_are_confined_to_the_bundle() {
        let dir = fresh("abs");
        edit(&dir, "file = \"terrain.bin\"", "file = \"/etc/passwd\"");
        refused(
            &dir,
            &[
                "terrain.file",
                "/etc/passwd",
                "not a file inside the bundle",
            ],
        );

        let dir = fresh("dotdot");
        let outside = dir
            .parent()
            .unwrap()
            .join(format!("outside-{}.bin", std::process::id()));
        std::fs::copy(dir.join("terrain.bin"), &outside).unwrap();
        let name = format!("../{}", outside.file_name().unwrap().to_string_lossy());
        let t = std::fs::read_to_string(dir.join("manifest.toml")).unwrap();
        std::fs::write(
            dir.join("manifest.toml"),
            t.replace("\"terrain.bin\"", &format!("{name:?}")),
        )
        .unwrap();
        refused(&dir, &["terrain.file", "../outside"]);

        // A symbolic link to an identical copy outside: the hash matches, the place does not.
        let dir = fresh("symlink");
        std::fs::remove_file(dir.join("terrain.bin")).unwrap();
        std::os::unix::fs::symlink(&outside, dir.join("terrain.bin")).unwrap();
        refused(
            &dir,
            &["terrain.bin", "symbolic link", "outside the bundle folder"],
        );
        // A link inside the folder is fine.
        let dir = fresh("symlink-inside");
        std::fs::rename(dir.join("terrain.bin"), dir.join("t.bin")).unwrap();
        std::os::unix::fs::symlink("t.bin", dir.join("terrain.bin")).unwrap();
        Bundle::open(&dir).unwrap();
        // The manifest itself.
        let dir = fresh("manifest-link");
        let copy = dir
            .parent()
            .unwrap()
            .join(format!("m-{}.toml", std::process::id()));
        std::fs::rename(dir.join("manifest.toml"), &copy).unwrap();
        std::os::unix::fs::symlink(&copy, dir.join("manifest.toml")).unwrap();
        let msg = Bundle::read_manifest(&dir).unwrap_err().to_string();
        assert!(msg.contains("outside the bundle folder"), "{msg}");
        let _ = std::fs::remove_file(&copy);
        let _ = std::fs::remove_file(&outside);

        // A FIFO is refused from its metadata (opening it would block).
        let dir = fresh("fifo");
        std::fs::remove_file(dir.join("materials.u8")).unwrap();
        let path = std::ffi::CString::new(dir.join("materials.u8").to_str().unwrap()).unwrap();
        // SAFETY: a valid NUL-terminated path; mkfifo only creates a directory entry.
        assert_eq!(unsafe { libc_mkfifo(path.as_ptr(), 0o644) }, 0);
        refused(&dir, &["materials.u8", "FIFO"]);
        let msg = Bundle::check_present(&dir, &Bundle::read_manifest(&dir).unwrap())
            .unwrap_err()
            .to_string();
        assert!(msg.contains("FIFO"), "{msg}");
    }

    extern "C" {
        #[link_name = "mkfifo"]
        fn libc_mkfifo(path: *const std::ffi::c_char, mode: u32) -> i32;
    }

    /// Rationale (issue 43): a tabulated material's table was not hashed (swapping it between a
    /// kill and a resume mixed two materials), and `../../etc/passwd` as its file was opened.
    /// The writer now copies the table into `brdf/` and hashes it; the reader refuses an
    /// unhashed, changed or escaping table, and `--force` replaces such a bundle whole.
    #[test]
    fn tabulated_tables_are_hashed_and_confined() {
        let root = std::env::temp_dir().join(format!("bundle-checks-tab-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        std::fs::create_dir_all(&root).unwrap();
        let table = root.join("sand.nc");
        std::fs::write(&table, b"not really netCDF, but bytes to hash").unwrap();
        let mut b = sample();
        b.manifest.materials[0].brdf = BrdfSpec::Tabulated(TabulatedSpec {
            file: table.to_string_lossy().into_owned(),
            symmetrize: false,
        });
        let dir = root.join("bundle");
        let m = b.write(&dir, false).unwrap();
        let BrdfSpec::Tabulated(t) = &m.materials[0].brdf else {
            panic!()
        };
        assert_eq!(t.file, "brdf/sand.nc");
        assert!(m.provenance.files.iter().any(|d| d.file == "brdf/sand.nc"));
        assert!(dir.join("brdf/sand.nc").is_file());
        Bundle::open(&dir).unwrap();
        Bundle::verify(&dir).unwrap();
        // Swapped after the build.
        std::fs::write(
            dir.join("brdf/sand.nc"),
            b"NOT REALLY NETCDF, BUT BYTES TO HASH",
        )
        .unwrap();
        refused(&dir, &["brdf/sand.nc", "SHA-256"]);
        // Forced rewrite replaces it; a user's file in brdf/ blocks that.
        b.write(&dir, true).unwrap();
        std::fs::write(dir.join("brdf/mine.txt"), b"x").unwrap();
        let msg = b.write(&dir, true).unwrap_err().to_string();
        assert!(msg.contains("brdf/mine.txt"), "{msg}");
        std::fs::remove_file(dir.join("brdf/mine.txt")).unwrap();
        // Not in the hashed list; escaping the folder.
        edit(
            &dir,
            "file = \"brdf/sand.nc\"\nbytes",
            "file = \"brdf/other.nc\"\nbytes",
        );
        refused(&dir, &["brdf/sand.nc", "no size and SHA-256"]);
        edit(
            &dir,
            "file = \"brdf/other.nc\"\nbytes",
            "file = \"brdf/sand.nc\"\nbytes",
        );
        Bundle::open(&dir).unwrap();
        edit(
            &dir,
            "file = \"brdf/sand.nc\"\nsymmetrize",
            "file = \"../../../../../etc/passwd\"\nsymmetrize",
        );
        refused(
            &dir,
            &["materials[0].brdf.file", "etc/passwd", "not a file inside"],
        );
        std::fs::remove_dir_all(&root).unwrap();
    }

    /// Rationale (issue 43): manifest numbers were not cross-checked: swapped terrain totals,
    /// a raster declared with another shape or pixel size of the same byte count, and wrong
    /// summaries all rendered. Each is refused naming the key.
    #[test]
    fn manifest_numbers_are_cross_checked() {
        let cases: [(&str, &str, &str, &[&str]); 8] = [
            (
                "totals",
                "dem_samples = 49\nvertex_count = 3\ntriangle_count = 1",
                "dem_samples = 49\nvertex_count = 1\ntriangle_count = 3",
                &["terrain.vertex_count", "tiles' sums"],
            ),
            (
                "shape",
                "width = 2\nheight = 2",
                "width = 4\nheight = 1",
                &["material raster", "4 × 1", "does not match the extent"],
            ),
            (
                "pixel",
                "geotransform = [-100.0, 100.0, 0.0, 100.0, 0.0, -100.0]",
                "geotransform = [-100.0, 50.0, 0.0, 100.0, 0.0, -100.0]",
                &["material raster", "50 × 100 m", "does not match the extent"],
            ),
            (
                "histogram",
                "histogram = [2, 1,",
                "histogram = [1, 2,",
                &["material_raster.histogram"],
            ),
            (
                "per-template",
                "per_template = [",
                "per_template = [0, ",
                &["instances.per_template", "2 entries for 1 templates"],
            ),
            (
                "same-file",
                "file = \"instances.bin\"",
                "file = \"terrain.bin\"",
                &["instances.file", "names the file of `terrain.file`"],
            ),
            (
                "count",
                "count = 2\nper_template",
                "count = 3\nper_template",
                &["instances.count", "sums to 2"],
            ),
            (
                "offset",
                "indices_offset = 36",
                "indices_offset = 40",
                &["template 0", "indices_offset", "layout"],
            ),
        ];
        for (name, from, to, needles) in cases {
            let dir = fresh(name);
            edit(&dir, from, to);
            refused(&dir, needles);
            std::fs::remove_dir_all(&dir).unwrap();
        }
        // Summaries that agree in number but not with the data.
        let dir = fresh("bounds");
        let t = std::fs::read_to_string(dir.join("manifest.toml")).unwrap();
        let at = t.find("bounds_max = [").unwrap();
        let end = at + t[at..].find(']').unwrap();
        std::fs::write(
            dir.join("manifest.toml"),
            format!("{}bounds_max = [9.0, 9.0, 9.0{}", &t[..at], &t[end..]),
        )
        .unwrap();
        refused(&dir, &["template 0", "bounds"]);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
