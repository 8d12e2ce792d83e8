//! `scenegen info`: a summary of a bundle from its manifest and file sizes — extent, CRS,
//! terrain and instance counts, materials with their pixel shares, memory on disk and the
//! memory the simulator needs to hold the geometry.

use std::fmt::Write as _;
use std::path::Path;

use bundle::{Bundle, NO_MATERIAL};

use crate::ScenegenError;

/// Human-readable bytes.
pub fn human_bytes(b: u64) -> String {
    let units = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut v = b as f64;
    let mut k = 0;
    while v >= 1024.0 && k + 1 < units.len() {
        v /= 1024.0;
        k += 1;
    }
    if k == 0 {
        format!("{b} B")
    } else {
        format!("{v:.1} {}", units[k])
    }
}

/// The summary text of the bundle in `dir`.
pub fn summary(dir: &Path) -> Result<String, ScenegenError> {
    let m = Bundle::read_manifest(dir)?;
    Bundle::check_present(dir, &m)?;
    let mut s = String::new();
    let w = &mut s;
    let e = &m.extent;
    let _ = writeln!(
        w,
        "bundle {} (format {} v{})",
        dir.display(),
        m.format,
        m.format_version
    );
    let _ = writeln!(
        w,
        "generator: {} {}, seed {}",
        m.provenance.generator, m.provenance.generator_version, m.provenance.seed
    );
    let crs = match (&m.crs.epsg, &m.crs.proj) {
        (Some(c), _) => format!("EPSG:{c}"),
        (None, Some(p)) => p.clone(),
        (None, None) => m.crs.wkt.chars().take(60).collect(),
    };
    let _ = writeln!(w, "CRS: {crs}");
    let _ = writeln!(
        w,
        "local frame: {}, origin ({:.3}, {:.3}, {:.3}) m, centre lon {:.5}°, lat {:.5}°",
        m.frame.kind,
        m.frame.origin[0],
        m.frame.origin[1],
        m.frame.origin[2],
        m.frame.centre_lon_lat[0],
        m.frame.centre_lon_lat[1]
    );
    let _ = writeln!(
        w,
        "extent: {:.3} km × {:.3} km (x {:.1} … {:.1}, y {:.1} … {:.1} m); lon {:.4}° … {:.4}°, lat {:.4}° … {:.4}°; heights {:.1} … {:.1} m",
        (e.max[0] - e.min[0]) / 1e3, (e.max[1] - e.min[1]) / 1e3, e.min[0], e.max[0], e.min[1], e.max[1],
        e.lon_lat_bbox[0], e.lon_lat_bbox[2], e.lon_lat_bbox[1], e.lon_lat_bbox[3], e.height_range[0], e.height_range[1]
    );
    if let Some(a) = &m.area {
        let _ = writeln!(
            w,
            "area: polygon from {}: {:.3} km² ({:.0} m², planar in the working CRS; the extent is its bounding box)",
            a.source,
            a.area_m2 / 1e6,
            a.area_m2
        );
    }
    let t = &m.terrain;
    let _ = writeln!(
        w,
        "terrain: {} triangles, {} vertices in {} tiles, from {} DEM samples at {} m (tolerance {} m; {:.2} % of the samples are vertices)",
        t.triangle_count, t.vertex_count, t.tiles.len(), t.dem_samples, t.dem_spacing_m, t.tolerance_m,
        100.0 * t.vertex_count as f64 / t.dem_samples.max(1) as f64
    );
    let r = &m.material_raster;
    let _ = writeln!(
        w,
        "material raster: {} × {} cells of {} m ({} resampling)",
        r.width, r.height, r.geotransform[1], r.resampling
    );
    let total: u64 = r.histogram.iter().sum();
    let _ = writeln!(w, "materials ({}):", m.materials.len());
    for mat in &m.materials {
        let n = r.histogram.get(mat.index as usize).copied().unwrap_or(0);
        let kind = mat.brdf.type_name();
        let codes = if mat.class_codes.is_empty() {
            "template material".to_string()
        } else {
            format!("classes {:?}", mat.class_codes)
        };
        let _ = writeln!(
            w,
            "  {:>3} {:<14} {:<13} {:>6.2} % of pixels  {codes}",
            mat.index,
            mat.name,
            kind,
            100.0 * n as f64 / total.max(1) as f64
        );
    }
    if let Some(&n) = r.histogram.get(NO_MATERIAL as usize) {
        if n > 0 {
            let _ = writeln!(w, "  (no material: {n} pixels)");
        }
    }
    let _ = writeln!(
        w,
        "templates ({}), instances {}:",
        m.templates.len(),
        m.instances.count
    );
    for tpl in &m.templates {
        let n = m
            .instances
            .per_template
            .get(tpl.id as usize)
            .copied()
            .unwrap_or(0);
        let _ = writeln!(
            w,
            "  {:>3} {:<12} {:>8} triangles  {:>10} instances  ({})",
            tpl.id, tpl.name, tpl.triangle_count, n, tpl.source
        );
    }
    let disk: u64 = m.provenance.files.iter().map(|f| f.bytes).sum();
    let tpl_tris: u64 = m.templates.iter().map(|t| t.triangle_count).sum();
    let _ = writeln!(
        w,
        "memory: {} on disk; instanced scene = {} terrain + {} template triangles stored, {:.3e} triangles if flattened",
        human_bytes(disk),
        t.triangle_count,
        tpl_tris,
        t.triangle_count as f64 + m.templates.iter().map(|tp| tp.triangle_count as f64 * m.instances.per_template.get(tp.id as usize).copied().unwrap_or(0) as f64).sum::<f64>()
    );
    let _ = writeln!(w, "inputs:");
    for i in &m.provenance.inputs {
        let _ = writeln!(
            w,
            "  {:<9} {} ({}, sha256 {}…)",
            i.role,
            i.path,
            human_bytes(i.bytes),
            &i.sha256[..16.min(i.sha256.len())]
        );
    }
    Ok(s)
}
