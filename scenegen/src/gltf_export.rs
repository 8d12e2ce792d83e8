//! `scenegen export-gltf`: a bundle as one GLB (glTF 2.0 binary) for a standard 3D viewer.
//!
//! * Axes: the bundle is z-up (x east, y north); glTF is y-up. A root node rotates −90° about x,
//!   (x, y, z) → (x, z, −y), so north points to glTF −z.
//! * Terrain tiles: one mesh each, translated to the tile origin (metres from the local-frame
//!   origin), textured with the material raster drawn as a PNG (each material's colour is its
//!   reflectance at 650, 550 and 450 nm, gamma-encoded; nearest filtering).
//! * Templates: one mesh each (one primitive per material, double-sided so leaves show both
//!   faces). Instances use `EXT_mesh_gpu_instancing` (listed in `extensionsUsed`): one node per
//!   template that has instances, with `TRANSLATION` (VEC3), `ROTATION` (unit quaternion, VEC4)
//!   and `SCALE` (VEC3) float accessors, one entry per instance, so millions of instances cost
//!   40 bytes each and no node. The bundle's linear part is rotation × scale (`bundle::Instance`),
//!   which TRS holds exactly; a linear part with shear (not made by `scenegen`) is written as its
//!   nearest TRS and counted in a warning. Every instance is written unless `thin` > 1 asks for
//!   every `thin`-th (said on stderr and in `asset.extras`). A viewer without the extension shows
//!   each template once, at the origin.
//!
//! The GLB is written to a temporary file then renamed.

use std::io::Write;
use std::path::Path;

use bundle::{BrdfSpec, Bundle, NO_MATERIAL};
use image::ImageEncoder;
use serde_json::{json, Value};

use crate::ScenegenError;

fn material_rgb(b: &BrdfSpec) -> [f64; 3] {
    let s = match b {
        BrdfSpec::Ocean(_) => return [0.02, 0.05, 0.1],
        // A measured table: no colour without reading it; a neutral grey.
        _ => match b.reflectance_level() {
            Some(s) => s,
            None => return [0.2, 0.2, 0.2],
        },
    };
    [s.at(650.0), s.at(550.0), s.at(450.0)].map(|v| v.clamp(0.0, 1.0))
}

fn srgb(v: f64) -> u8 {
    (v.powf(1.0 / 2.2) * 255.0).round().clamp(0.0, 255.0) as u8
}

struct Bin {
    data: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Bin {
    fn align(&mut self) {
        while self.data.len() % 4 != 0 {
            self.data.push(0);
        }
    }
    fn view(&mut self, bytes: &[u8], target: Option<u32>) -> usize {
        self.align();
        let off = self.data.len();
        self.data.extend_from_slice(bytes);
        let mut v = json!({"buffer": 0, "byteOffset": off, "byteLength": bytes.len()});
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        self.views.push(v);
        self.views.len() - 1
    }
    fn vec3(&mut self, p: &[[f32; 3]]) -> usize {
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        let mut bytes = Vec::with_capacity(p.len() * 12);
        for q in p {
            for k in 0..3 {
                lo[k] = lo[k].min(q[k]);
                hi[k] = hi[k].max(q[k]);
                bytes.extend_from_slice(&q[k].to_le_bytes());
            }
        }
        let v = self.view(&bytes, Some(34962));
        self.accessors.push(
            json!({"bufferView": v, "componentType": 5126, "count": p.len(), "type": "VEC3", "min": lo, "max": hi}),
        );
        self.accessors.len() - 1
    }
    fn vec2(&mut self, p: &[[f32; 2]]) -> usize {
        let bytes: Vec<u8> = p.iter().flatten().flat_map(|x| x.to_le_bytes()).collect();
        let v = self.view(&bytes, Some(34962));
        self.accessors.push(
            json!({"bufferView": v, "componentType": 5126, "count": p.len(), "type": "VEC2"}),
        );
        self.accessors.len() - 1
    }
    /// A per-instance attribute of `EXT_mesh_gpu_instancing`: float vectors of N components,
    /// in a buffer view without a target (not vertex data).
    fn instance_attr<const N: usize>(&mut self, p: &[[f32; N]]) -> usize {
        let bytes: Vec<u8> = p.iter().flatten().flat_map(|x| x.to_le_bytes()).collect();
        let v = self.view(&bytes, None);
        let ty = match N {
            3 => "VEC3",
            _ => "VEC4",
        };
        self.accessors
            .push(json!({"bufferView": v, "componentType": 5126, "count": p.len(), "type": ty}));
        self.accessors.len() - 1
    }
    fn indices(&mut self, t: &[[u32; 3]]) -> usize {
        let bytes: Vec<u8> = t.iter().flatten().flat_map(|x| x.to_le_bytes()).collect();
        let v = self.view(&bytes, Some(34963));
        self.accessors.push(
            json!({"bufferView": v, "componentType": 5125, "count": t.len() * 3, "type": "SCALAR"}),
        );
        self.accessors.len() - 1
    }
}

/// Scale and rotation (unit quaternion x, y, z, w) of a column-major 3×3 rotation × scale, and
/// whether they reproduce it (no shear) to 1e-4 of its largest column.
fn scale_rotation(l: &[f32; 9]) -> ([f32; 3], [f32; 4], bool) {
    let m = glam::Mat3::from_cols_array(l);
    let (s, r, _) = glam::Mat4::from_mat3(m).to_scale_rotation_translation();
    let r = r.normalize();
    let back = glam::Mat3::from_quat(r) * glam::Mat3::from_diagonal(s);
    let size = m
        .x_axis
        .length()
        .max(m.y_axis.length())
        .max(m.z_axis.length());
    let err = (back - m)
        .to_cols_array()
        .iter()
        .fold(0f32, |a, x| a.max(x.abs()));
    let exact = err <= 1e-4 * size.max(f32::MIN_POSITIVE);
    let ok = r.is_finite() && s.is_finite();
    let (s, r) = if ok {
        (s, r)
    } else {
        (glam::Vec3::ONE, glam::Quat::IDENTITY)
    };
    (s.to_array(), r.to_array(), exact && ok)
}

/// What was exported.
pub struct ExportReport {
    pub tiles: usize,
    pub templates: usize,
    pub instances_exported: usize,
    pub instances_total: usize,
    pub bytes: u64,
}

/// Write `bundle_dir` as a GLB at `out`, with every `thin`-th instance (1 or 0: all).
pub fn export(bundle_dir: &Path, out: &Path, thin: usize) -> Result<ExportReport, ScenegenError> {
    let b = Bundle::open(bundle_dir)?;
    let mut bin = Bin {
        data: Vec::new(),
        views: Vec::new(),
        accessors: Vec::new(),
    };
    let mut materials: Vec<Value> = Vec::new();
    let mut meshes: Vec<Value> = Vec::new();
    let mut nodes: Vec<Value> = vec![
        json!({"name": "bundle (z-up to y-up)", "rotation": [-std::f64::consts::FRAC_1_SQRT_2, 0.0, 0.0, std::f64::consts::FRAC_1_SQRT_2], "children": []}),
    ];
    let mut children: Vec<usize> = Vec::new();

    // Material raster as a PNG texture.
    let r = &b.manifest.material_raster;
    let mut palette = [[255u8, 0, 255]; 256];
    for m in &b.manifest.materials {
        palette[m.index as usize] = material_rgb(&m.brdf).map(srgb);
    }
    palette[NO_MATERIAL as usize] = [0, 0, 0];
    let rgb: Vec<u8> = b
        .material_raster
        .iter()
        .flat_map(|&i| palette[i as usize])
        .collect();
    let mut png = Vec::new();
    image::codecs::png::PngEncoder::new(&mut png)
        .write_image(&rgb, r.width, r.height, image::ExtendedColorType::Rgb8)
        .map_err(|e| {
            ScenegenError::Internal(format!("PNG encoding of the material raster: {e}"))
        })?;
    let png_view = bin.view(&png, None);
    materials.push(json!({"name": "terrain", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0, "roughnessFactor": 1.0}}));

    for t in &b.terrain {
        let pos = bin.vec3(&t.positions);
        let uv = bin.vec2(&t.uvs);
        let idx = bin.indices(&t.indices);
        meshes.push(json!({"name": format!("terrain {:?}", t.id), "primitives": [{"attributes": {"POSITION": pos, "TEXCOORD_0": uv}, "indices": idx, "material": 0}]}));
        nodes.push(json!({"name": format!("terrain {:?}", t.id), "mesh": meshes.len() - 1, "translation": t.origin}));
        children.push(nodes.len() - 1);
    }

    // Template materials: one glTF material per bundle material used by templates.
    let mut gl_mat = std::collections::HashMap::new();
    let mut template_mesh = Vec::new();
    for t in &b.templates {
        let pos = bin.vec3(&t.positions);
        let mut prims = Vec::new();
        let mut used: Vec<u8> = t.materials.clone();
        used.sort_unstable();
        used.dedup();
        for m in used {
            let tris: Vec<[u32; 3]> = t
                .indices
                .iter()
                .zip(&t.materials)
                .filter(|(_, &mm)| mm == m)
                .map(|(tri, _)| *tri)
                .collect();
            let idx = bin.indices(&tris);
            let gm = *gl_mat.entry(m).or_insert_with(|| {
                let mat = b.manifest.materials.iter().find(|x| x.index == m);
                let c = mat.map(|x| material_rgb(&x.brdf)).unwrap_or([1.0, 0.0, 1.0]);
                materials.push(json!({"name": mat.map(|x| x.name.clone()).unwrap_or_default(), "doubleSided": true,
                    "pbrMetallicRoughness": {"baseColorFactor": [c[0], c[1], c[2], 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0}}));
                materials.len() - 1
            });
            prims.push(json!({"attributes": {"POSITION": pos}, "indices": idx, "material": gm}));
        }
        meshes.push(json!({"name": t.name, "primitives": prims}));
        template_mesh.push(meshes.len() - 1);
    }

    let n = b.instances.len();
    let thin = thin.max(1);
    let kept: Vec<&bundle::Instance> = b.instances.iter().step_by(thin).collect();
    let exported = kept.len();
    let mut sheared = 0usize;
    for (k, &mesh) in template_mesh.iter().enumerate() {
        let mine: Vec<&&bundle::Instance> =
            kept.iter().filter(|i| i.template as usize == k).collect();
        if mine.is_empty() {
            continue;
        }
        let mut tr = Vec::with_capacity(mine.len());
        let mut rot = Vec::with_capacity(mine.len());
        let mut sc = Vec::with_capacity(mine.len());
        for inst in mine {
            let (s, r, exact) = scale_rotation(&inst.linear);
            sheared += usize::from(!exact);
            tr.push(inst.translation.map(|x| x as f32));
            rot.push(r);
            sc.push(s);
        }
        let t = bin.instance_attr(&tr);
        let r = bin.instance_attr(&rot);
        let s = bin.instance_attr(&sc);
        nodes.push(json!({"name": format!("{} instances", b.templates[k].name), "mesh": mesh,
            "extensions": {"EXT_mesh_gpu_instancing": {"attributes": {"TRANSLATION": t, "ROTATION": r, "SCALE": s}}}}));
        children.push(nodes.len() - 1);
    }
    if thin > 1 {
        tracing::warn!("exported {exported} of {n} instances (every {thin}-th, as --thin asked)");
    }
    if sheared > 0 {
        tracing::warn!(
            "{sheared} instance(s) have a sheared linear part, which glTF's TRS cannot hold: written as their nearest rotation and scale"
        );
    }
    nodes[0]["children"] = json!(children);
    bin.align();
    let doc = json!({
        "asset": {"version": "2.0", "generator": format!("scenegen {}", env!("CARGO_PKG_VERSION")),
                  "extras": {"bundle": bundle_dir.display().to_string(), "instances_total": n, "instances_exported": exported, "thin": thin}},
        "extensionsUsed": ["EXT_mesh_gpu_instancing"],
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"magFilter": 9728, "minFilter": 9728}],
        "images": [{"bufferView": png_view, "mimeType": "image/png"}],
        "accessors": bin.accessors,
        "bufferViews": bin.views,
        "buffers": [{"byteLength": bin.data.len()}],
    });
    let mut json_bytes =
        serde_json::to_vec(&doc).map_err(|e| ScenegenError::Internal(e.to_string()))?;
    while json_bytes.len() % 4 != 0 {
        json_bytes.push(b' ');
    }
    let total = 12 + 8 + json_bytes.len() + 8 + bin.data.len();
    let tmp = out.with_extension("glb.tmp");
    let write = || -> std::io::Result<()> {
        let mut f = std::io::BufWriter::new(std::fs::File::create(&tmp)?);
        f.write_all(b"glTF")?;
        f.write_all(&2u32.to_le_bytes())?;
        f.write_all(&(total as u32).to_le_bytes())?;
        f.write_all(&(json_bytes.len() as u32).to_le_bytes())?;
        f.write_all(b"JSON")?;
        f.write_all(&json_bytes)?;
        f.write_all(&(bin.data.len() as u32).to_le_bytes())?;
        f.write_all(b"BIN\0")?;
        f.write_all(&bin.data)?;
        f.into_inner().map_err(|e| e.into_error())?.sync_all()?;
        std::fs::rename(&tmp, out)
    };
    if total > u32::MAX as usize {
        return Err(ScenegenError::Internal(format!(
            "GLB would be {total} bytes, over the format's 4 GiB; use --thin N or export a smaller region"
        )));
    }
    write().map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        ScenegenError::Bundle(bundle::BundleError::Write {
            path: out.into(),
            source: e,
        })
    })?;
    Ok(ExportReport {
        tiles: b.terrain.len(),
        templates: b.templates.len(),
        instances_exported: exported,
        instances_total: n,
        bytes: total as u64,
    })
}

#[cfg(test)]
mod tests {
    use super::scale_rotation;

    /// The instance linear parts scenegen makes, Rz(yaw) · diag(s), come back exactly as a
    /// quaternion and a scale (glTF applies T · R · S); a sheared matrix is flagged.
    #[test]
    fn rotation_times_scale_is_decomposed_exactly() {
        for (yaw, s) in [
            (0.0f32, [1.0f32, 1.0, 1.0]),
            (1.3, [0.8, 0.8, 1.7]),
            (-2.9, [2.0, 0.5, 1.1]),
        ] {
            let m = glam::Mat3::from_rotation_z(yaw) * glam::Mat3::from_diagonal(s.into());
            let (sc, q, exact) = scale_rotation(&m.to_cols_array());
            assert!(exact);
            let back = glam::Mat3::from_quat(glam::Quat::from_array(q))
                * glam::Mat3::from_diagonal(sc.into());
            assert!(back.abs_diff_eq(m, 1e-5), "{back} vs {m}");
            assert!((glam::Quat::from_array(q).length() - 1.0).abs() < 1e-6);
        }
        let shear = glam::Mat3::from_cols_array(&[1.0, 0.0, 0.0, 0.5, 1.0, 0.0, 0.0, 0.0, 1.0]);
        assert!(!scale_rotation(&shear.to_cols_array()).2);
    }
}
