//! The template catalogue: TOML entries naming a procedural generator or a mesh file, with the
//! file's unit (metres per file unit) and up axis, and the map from the template's own material
//! names to library materials. Keys and defaults are documented in `docs/region.md`
//! (`[[templates]]`), which uses the same entries.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::procedural::ProceduralSpec;
use crate::{load, Template, TileError};

/// The up axis of a mesh file (defined beside the loader that turns it to +z).
pub use crate::load::UpAxis;

const BUILTIN: &str = include_str!("../data/catalogue.toml");

/// One catalogue entry.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TemplateSpec {
    pub name: String,
    /// A generator and its parameters (exclusive with `file`).
    #[serde(default)]
    pub procedural: Option<ProceduralSpec>,
    /// OBJ, glTF or GLB file (relative to the file that names it).
    #[serde(default)]
    pub file: Option<PathBuf>,
    /// More mesh files merged into the same template (same `unit_m` and `up_axis`), e.g. a
    /// tree's foliage and trunk.
    #[serde(default)]
    pub parts: Vec<PathBuf>,
    /// Metres per file unit; default 1.
    #[serde(default = "one")]
    pub unit_m: f64,
    /// The file's up axis; default "y" (glTF's convention, and most OBJ exporters').
    #[serde(default = "y_up")]
    pub up_axis: UpAxis,
    /// Template material name → library material name.
    #[serde(default)]
    pub materials: BTreeMap<String, String>,
    /// Library material for template materials not in `materials`.
    #[serde(default)]
    pub default_material: Option<String>,
    /// Lamps carried by every instance (streetlights): `[[lights]]` tables of the simulator's
    /// experiment with `position_m` (and `direction`) in the template frame; checked by the
    /// simulator when an experiment turns them on (`scene.lamps = true`).
    #[serde(default)]
    pub lamps: Vec<toml::Table>,
}

fn one() -> f64 {
    1.0
}
fn y_up() -> UpAxis {
    UpAxis::Y
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CatalogueFile {
    templates: Vec<TemplateSpec>,
}

/// Catalogue entries with the directory their relative paths start from.
#[derive(Clone, Debug, Default)]
pub struct Catalogue {
    pub entries: Vec<(TemplateSpec, PathBuf)>,
}

impl Catalogue {
    /// The built-in catalogue (procedural templates only).
    pub fn builtin() -> Catalogue {
        let f: CatalogueFile =
            toml::from_str(BUILTIN).expect("built-in catalogue is valid (checked by a unit test)");
        Catalogue {
            entries: f
                .templates
                .into_iter()
                .map(|t| (t, PathBuf::from(".")))
                .collect(),
        }
    }

    /// Add (or replace, by name) entries whose relative paths start at `base_dir`.
    pub fn extend(&mut self, specs: &[TemplateSpec], base_dir: &Path) {
        for s in specs {
            self.entries.retain(|(e, _)| e.name != s.name);
            self.entries.push((s.clone(), base_dir.to_path_buf()));
        }
    }

    pub fn get(&self, name: &str) -> Option<&(TemplateSpec, PathBuf)> {
        self.entries.iter().find(|(e, _)| e.name == name)
    }

    pub fn names(&self) -> Vec<String> {
        self.entries.iter().map(|(e, _)| e.name.clone()).collect()
    }
}

impl TemplateSpec {
    /// Check the entry; `origin` (the file naming it) and `key` (its key path) go into errors.
    pub fn validate(&self, origin: &Path, key: &str) -> Result<(), TileError> {
        let inv = |k: &str, message: String| TileError::Invalid {
            path: origin.into(),
            key: format!("{key}.{k}"),
            message,
        };
        match (&self.procedural, &self.file) {
            (Some(_), Some(_)) => {
                return Err(inv(
                    "file",
                    "give either `file` or `procedural`, not both".into(),
                ))
            }
            (None, None) => {
                return Err(inv(
                    "file",
                    "give `file` (OBJ, PLY, glTF, GLB) or `procedural`".into(),
                ))
            }
            (Some(p), None) => p
                .validate()
                .map_err(|(k, m)| inv(&format!("procedural.{k}"), m))?,
            (None, Some(_)) => {}
        }
        if !self.parts.is_empty() && self.file.is_none() {
            return Err(inv("parts", "`parts` needs `file`".into()));
        }
        if !(self.unit_m.is_finite() && self.unit_m > 0.0) {
            return Err(inv(
                "unit_m",
                format!("{} must be > 0 (metres per file unit)", self.unit_m),
            ));
        }
        Ok(())
    }

    /// Build the template: generate it or load and normalise its file.
    pub fn build(&self, base_dir: &Path) -> Result<Template, TileError> {
        let mut t = match (&self.procedural, &self.file) {
            (Some(p), _) => p.generate(),
            (None, Some(f)) => {
                let mut t = load::load_mesh(&base_dir.join(f), self.unit_m, self.up_axis)?;
                for part in &self.parts {
                    let p = load::load_mesh(&base_dir.join(part), self.unit_m, self.up_axis)?;
                    t.merge(p);
                }
                t
            }
            (None, None) => {
                return Err(TileError::Invalid {
                    path: base_dir.into(),
                    key: self.name.clone(),
                    message: "no file or procedural".into(),
                })
            }
        };
        t.name = self.name.clone();
        t.recentre();
        Ok(t)
    }

    /// Library material for a template material name.
    pub fn library_material<'a>(&'a self, template_material: &'a str) -> Option<&'a str> {
        self.materials
            .get(template_material)
            .map(|s| s.as_str())
            .or(self.default_material.as_deref())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rationale: the built-in catalogue is data; every entry must validate and build, and
    /// every template material must map to a library material name.
    #[test]
    fn builtin_catalogue_builds() {
        let c = Catalogue::builtin();
        assert!(c.get("tree").is_some() && c.get("house").is_some());
        for (s, dir) in &c.entries {
            s.validate(Path::new("catalogue.toml"), &s.name).unwrap();
            let t = s.build(dir).unwrap();
            assert!(!t.indices.is_empty(), "{}", s.name);
            for m in &t.material_names {
                assert!(s.library_material(m).is_some(), "{}: {m}", s.name);
            }
            let (lo, _) = t.bounds();
            assert!(lo[2].abs() < 1e-6, "{} sits on the ground", s.name);
        }
    }
}
