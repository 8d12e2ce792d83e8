//! `landcover`: land-cover schemes as TOML tables — class code → material (a BRDF of the scene
//! bundle with its parameters and source) and the default tile population rules — and the
//! mapping of a class-code raster to the bundle's 8-bit material-index raster.
//!
//! Shipped schemes (`data/`): `esa_worldcover` (codes 10–100, no data 0), `nlcd` (USGS NLCD codes
//! 11–95, no data 0) and `corine` (CLC
//! raster grid codes 1–44, no data 48). Materials live in `data/materials.toml`, shared by the
//! schemes; each states its source (RAMI-V measured spectra for soil, leaves and bark; values
//! marked "illustrative" elsewhere). Spectra: wavelengths in nm, reflectances in [0, 1].
//!
//! A class code with no mapping is an error listing every such code with its pixel count, unless
//! a fallback material is given.
//!
//! BRDF parameters are checked against the one range table of the bundle format
//! (`bundle::BRDF_PARAM_RANGES`, also used by `simulate`), so a scheme cannot hold a material the
//! simulator would refuse. This crate depends on `bundle` only (no GDAL, no netCDF).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use bundle::{BrdfSpec, Material, NO_MATERIAL};
use serde::Deserialize;

const MATERIALS_TOML: &str = include_str!("../data/materials.toml");
const BUILTIN: &[(&str, &str)] = &[
    (
        "esa_worldcover",
        include_str!("../data/esa_worldcover.toml"),
    ),
    ("corine", include_str!("../data/corine.toml")),
    ("nlcd", include_str!("../data/nlcd.toml")),
];

/// Errors naming the scheme file (or built-in name) and the key.
#[derive(Debug, thiserror::Error)]
pub enum SchemeError {
    #[error("unknown land-cover scheme `{name}` (built-in: {known}); give a path to a scheme TOML file instead")]
    UnknownScheme { name: String, known: String },
    #[error("cannot read scheme file {}: {source}", path.display())]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{}: {message}", path.display())]
    Parse { path: PathBuf, message: String },
    #[error("{}: `{key}`: {message}", path.display())]
    Invalid {
        path: PathBuf,
        key: String,
        message: String,
    },
    /// Class codes present in the raster without a material; pixel counts per code.
    #[error("{}: {} class code(s) have no material in scheme `{scheme}`: {}; add them to the scheme or set `landcover.fallback_material`",
        path.display(), codes.len(), format_counts(codes))]
    UnknownCodes {
        path: PathBuf,
        scheme: String,
        codes: Vec<(i64, u64)>,
    },
    #[error("too many materials ({count}); the material raster holds at most 255")]
    TooManyMaterials { count: usize },
}

fn format_counts(codes: &[(i64, u64)]) -> String {
    let mut s: Vec<String> = codes
        .iter()
        .take(20)
        .map(|(c, n)| {
            if *c == NODATA_CODE {
                format!("no data ({n} px)")
            } else {
                format!("{c} ({n} px)")
            }
        })
        .collect();
    if codes.len() > 20 {
        s.push(format!("… and {} more", codes.len() - 20));
    }
    s.join(", ")
}

/// The pseudo-code under which no-data pixels are counted in [`SchemeError::UnknownCodes`].
pub const NODATA_CODE: i64 = i64::MIN;

/// A material definition as written in TOML.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MaterialDef {
    pub brdf: BrdfSpec,
    #[serde(default)]
    pub source: String,
    /// The material's radiometry solver (absent: the default `generic` solver).
    #[serde(default)]
    pub solver: Option<bundle::SolverSpec>,
    /// The material's temperature, K, for thermal emission (absent: none in the bundle).
    #[serde(default)]
    pub temperature: Option<f64>,
}

/// One land-cover class.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ClassDef {
    pub code: i64,
    pub name: String,
    /// Name of a material in the material library.
    pub material: String,
}

/// Which template goes on which classes, how densely, with what random scale.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PopulationRule {
    /// Class codes the rule applies to.
    pub classes: Vec<i64>,
    /// Template name in the catalogue (`tiles`).
    pub template: String,
    /// Mean instances per hectare (10 000 m²) of land-cover tile with one of the classes.
    pub density_per_ha: f64,
    /// Uniform random scale factor range [min, max]; default [1, 1].
    #[serde(default = "unit_range")]
    pub scale: [f64; 2],
    /// Uniform random rotation about the vertical; default true.
    #[serde(default = "yes")]
    pub random_rotation: bool,
}

fn unit_range() -> [f64; 2] {
    [1.0, 1.0]
}
fn yes() -> bool {
    true
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SchemeFile {
    name: String,
    #[serde(default)]
    description: String,
    #[serde(default)]
    source: String,
    #[serde(default)]
    nodata: Option<i64>,
    classes: Vec<ClassDef>,
    #[serde(default)]
    population: Vec<PopulationRule>,
    #[serde(default)]
    materials: BTreeMap<String, MaterialDef>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MaterialsFile {
    materials: BTreeMap<String, MaterialDef>,
}

/// A validated scheme: classes, the material library they refer to, population rules.
#[derive(Clone, Debug)]
pub struct Scheme {
    pub name: String,
    pub description: String,
    pub source: String,
    /// Where it was loaded from ("built-in" or a path).
    pub origin: PathBuf,
    pub nodata: Option<i64>,
    pub classes: Vec<ClassDef>,
    pub population: Vec<PopulationRule>,
    /// Material library (shared `materials.toml` plus the scheme's own `[materials]`).
    pub materials: BTreeMap<String, MaterialDef>,
}

fn parse_toml<T: serde::de::DeserializeOwned>(text: &str, path: &Path) -> Result<T, SchemeError> {
    let de = toml::Deserializer::parse(text).map_err(|e| SchemeError::Parse {
        path: path.into(),
        message: e.to_string(),
    })?;
    serde_path_to_error::deserialize(de).map_err(|e| SchemeError::Parse {
        path: path.into(),
        message: format!(
            "at key `{}`: {}",
            e.path(),
            e.inner().to_string().trim_end()
        ),
    })
}

/// The shared material library.
pub fn material_library() -> BTreeMap<String, MaterialDef> {
    let f: MaterialsFile = parse_toml(MATERIALS_TOML, Path::new("landcover/data/materials.toml"))
        .expect("built-in materials.toml is valid (checked by a unit test)");
    f.materials
}

impl Scheme {
    /// Names of the built-in schemes.
    pub fn builtin_names() -> Vec<&'static str> {
        BUILTIN.iter().map(|(n, _)| *n).collect()
    }

    /// A built-in scheme by name, or a scheme TOML file if `name_or_path` ends in `.toml`.
    pub fn load(name_or_path: &str) -> Result<Scheme, SchemeError> {
        if name_or_path.ends_with(".toml") {
            let path = PathBuf::from(name_or_path);
            let text = std::fs::read_to_string(&path).map_err(|source| SchemeError::Read {
                path: path.clone(),
                source,
            })?;
            return Self::from_str(&text, &path);
        }
        let (_, text) = BUILTIN
            .iter()
            .find(|(n, _)| *n == name_or_path)
            .ok_or_else(|| SchemeError::UnknownScheme {
                name: name_or_path.into(),
                known: Self::builtin_names().join(", "),
            })?;
        Self::from_str(
            text,
            &PathBuf::from(format!("landcover/data/{name_or_path}.toml")),
        )
    }

    /// Parse and validate scheme text; `path` names it in errors.
    pub fn from_str(text: &str, path: &Path) -> Result<Scheme, SchemeError> {
        let f: SchemeFile = parse_toml(text, path)?;
        let mut materials = material_library();
        materials.extend(f.materials);
        let s = Scheme {
            name: f.name,
            description: f.description,
            source: f.source,
            origin: path.into(),
            nodata: f.nodata,
            classes: f.classes,
            population: f.population,
            materials,
        };
        s.validate()?;
        Ok(s)
    }

    fn validate(&self) -> Result<(), SchemeError> {
        let inv = |key: String, message: String| SchemeError::Invalid {
            path: self.origin.clone(),
            key,
            message,
        };
        let mut seen = BTreeMap::new();
        for (i, c) in self.classes.iter().enumerate() {
            if let Some(j) = seen.insert(c.code, i) {
                return Err(inv(
                    format!("classes[{i}].code"),
                    format!("code {} already given in classes[{j}]", c.code),
                ));
            }
            if !self.materials.contains_key(&c.material) {
                return Err(inv(
                    format!("classes[{i}].material"),
                    format!("unknown material `{}`", c.material),
                ));
            }
        }
        for (name, m) in &self.materials {
            validate_brdf(&m.brdf).map_err(|(param, message)| {
                let users: Vec<String> = self
                    .classes
                    .iter()
                    .filter(|c| c.material == *name)
                    .map(|c| format!("{} `{}`", c.code, c.name))
                    .collect();
                let used = if users.is_empty() {
                    format!("material `{name}`, used by no class")
                } else {
                    format!(
                        "material `{name}` of class{} {}",
                        if users.len() == 1 { "" } else { "es" },
                        users.join(", ")
                    )
                };
                inv(
                    format!("materials.{name}.brdf.{param}"),
                    format!("{message} ({used})"),
                )
            })?;
        }
        for (i, r) in self.population.iter().enumerate() {
            validate_rule(r).map_err(|(k, m)| inv(format!("population[{i}].{k}"), m))?;
        }
        Ok(())
    }
}

/// Checks a population rule; returns (key, message).
pub fn validate_rule(r: &PopulationRule) -> Result<(), (String, String)> {
    if !(r.density_per_ha.is_finite() && r.density_per_ha >= 0.0 && r.density_per_ha <= 1.0e5) {
        return Err((
            "density_per_ha".into(),
            format!("{} is outside [0, 100000] per hectare", r.density_per_ha),
        ));
    }
    if !(r.scale[0] > 0.0 && r.scale[1] >= r.scale[0] && r.scale[1].is_finite()) {
        return Err((
            "scale".into(),
            format!("{:?} must be [min, max] with 0 < min ≤ max", r.scale),
        ));
    }
    Ok(())
}

/// Checks a BRDF against the shared range table (`bundle::BRDF_PARAM_RANGES`, see
/// [`BrdfSpec::validate`]); returns (the first offending parameter, a message naming every
/// violation with its value and allowed range).
pub fn validate_brdf(b: &BrdfSpec) -> Result<(), (String, String)> {
    b.validate_stored().map_err(|e| {
        let param = e.violations.first().map_or("", |v| v.param());
        (param.to_string(), e.to_string())
    })
}

/// The material table of a scene and the code → index lookup.
#[derive(Clone, Debug)]
pub struct MaterialMap {
    /// Bundle materials in index order.
    pub materials: Vec<Material>,
    /// Class code → material index.
    pub code_to_index: BTreeMap<i64, u8>,
    /// Index used for unknown codes and no data, if a fallback was given.
    pub fallback: Option<u8>,
}

impl MaterialMap {
    /// Build the table for `scheme`: one material per distinct material name, in order of first
    /// use by the classes; `class_materials` remaps codes to other material names;
    /// `overrides` replaces or adds materials; `fallback` names the material for unmapped codes.
    pub fn new(
        scheme: &Scheme,
        class_materials: &BTreeMap<i64, String>,
        overrides: &BTreeMap<String, MaterialDef>,
        fallback: Option<&str>,
    ) -> Result<MaterialMap, SchemeError> {
        let mut lib = scheme.materials.clone();
        lib.extend(overrides.iter().map(|(k, v)| (k.clone(), v.clone())));
        let mut materials: Vec<Material> = Vec::new();
        let mut code_to_index = BTreeMap::new();
        let mut add = |name: &str, code: Option<i64>, key: &str| -> Result<u8, SchemeError> {
            if let Some(i) = materials.iter().position(|m| m.name == name) {
                if let Some(c) = code {
                    materials[i].class_codes.push(c as u32);
                }
                return Ok(i as u8);
            }
            let def = lib.get(name).ok_or_else(|| SchemeError::Invalid {
                path: scheme.origin.clone(),
                key: key.into(),
                message: format!(
                    "unknown material `{name}` (known: {})",
                    lib.keys().cloned().collect::<Vec<_>>().join(", ")
                ),
            })?;
            if materials.len() >= NO_MATERIAL as usize {
                return Err(SchemeError::TooManyMaterials {
                    count: materials.len() + 1,
                });
            }
            let index = materials.len() as u8;
            materials.push(Material {
                index,
                name: name.into(),
                brdf: def.brdf.clone(),
                class_codes: code.map(|c| vec![c as u32]).unwrap_or_default(),
                source: def.source.clone(),
                solver: def.solver,
                temperature: def.temperature,
            });
            Ok(index)
        };
        for c in &scheme.classes {
            let name = class_materials.get(&c.code).unwrap_or(&c.material);
            let i = add(
                name,
                Some(c.code),
                &format!("landcover.class_materials.{}", c.code),
            )?;
            code_to_index.insert(c.code, i);
        }
        for (code, name) in class_materials {
            if !code_to_index.contains_key(code) {
                let i = add(
                    name,
                    Some(*code),
                    &format!("landcover.class_materials.{code}"),
                )?;
                code_to_index.insert(*code, i);
            }
        }
        let fallback = match fallback {
            Some(name) => Some(add(name, None, "landcover.fallback_material")?),
            None => None,
        };
        Ok(MaterialMap {
            materials,
            code_to_index,
            fallback,
        })
    }

    /// Add a material not tied to a class (template materials); returns its index.
    pub fn add_material(&mut self, name: &str, def: &MaterialDef) -> Result<u8, SchemeError> {
        if let Some(m) = self.materials.iter().find(|m| m.name == name) {
            return Ok(m.index);
        }
        if self.materials.len() >= NO_MATERIAL as usize {
            return Err(SchemeError::TooManyMaterials {
                count: self.materials.len() + 1,
            });
        }
        let index = self.materials.len() as u8;
        self.materials.push(Material {
            index,
            name: name.into(),
            brdf: def.brdf.clone(),
            class_codes: vec![],
            source: def.source.clone(),
            solver: def.solver,
            temperature: def.temperature,
        });
        Ok(index)
    }

    /// Map a class-code raster (`None` = no data) to material indices. Unknown codes and no
    /// data go to the fallback, or make an error listing every such code with its pixel count.
    /// `path` and `scheme` name the input in the error.
    pub fn map_raster(
        &self,
        codes: &[Option<i64>],
        path: &Path,
        scheme: &str,
    ) -> Result<Vec<u8>, SchemeError> {
        // A dense lookup for the common small codes keeps this a table lookup per pixel.
        let mut lut = [u16::MAX; 256];
        for (&c, &i) in &self.code_to_index {
            if (0..256).contains(&c) {
                lut[c as usize] = i as u16;
            }
        }
        let mut unknown: BTreeMap<i64, u64> = BTreeMap::new();
        let mut out = Vec::with_capacity(codes.len());
        for c in codes {
            let idx = match c {
                Some(c) if (0..256).contains(c) && lut[*c as usize] != u16::MAX => {
                    Some(lut[*c as usize] as u8)
                }
                Some(c) => self.code_to_index.get(c).copied(),
                None => None,
            };
            match idx.or(self.fallback) {
                Some(i) => out.push(i),
                None => {
                    *unknown.entry(c.unwrap_or(NODATA_CODE)).or_default() += 1;
                    out.push(NO_MATERIAL);
                }
            }
        }
        if !unknown.is_empty() {
            return Err(SchemeError::UnknownCodes {
                path: path.into(),
                scheme: scheme.into(),
                codes: unknown.into_iter().collect(),
            });
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rationale: the shipped tables are data; a typo in them must fail here, not at a user's.
    #[test]
    fn builtin_schemes_load_and_every_class_has_a_material() {
        assert!(!material_library().is_empty());
        for name in Scheme::builtin_names() {
            let s = Scheme::load(name).unwrap();
            assert!(!s.classes.is_empty());
            let m = MaterialMap::new(&s, &BTreeMap::new(), &BTreeMap::new(), None).unwrap();
            for c in &s.classes {
                let i = m.code_to_index[&c.code] as usize;
                assert_eq!(m.materials[i].name, c.material);
                assert!(m.materials[i].class_codes.contains(&(c.code as u32)));
            }
        }
        assert_eq!(Scheme::load("corine").unwrap().classes.len(), 44);
        assert_eq!(Scheme::load("esa_worldcover").unwrap().classes.len(), 11);
        assert_eq!(Scheme::load("nlcd").unwrap().classes.len(), 20);
    }

    /// Rationale: the material raster must equal the scheme's mapping pixel by pixel on a
    /// hand-made raster, remaps included.
    #[test]
    fn hand_made_raster_maps_to_the_scheme() {
        let s = Scheme::load("esa_worldcover").unwrap();
        let remap = BTreeMap::from([(40, "grass".to_string())]);
        let m = MaterialMap::new(&s, &remap, &BTreeMap::new(), None).unwrap();
        let codes = [Some(10), Some(30), Some(40), Some(80), Some(10), Some(50)];
        let out = m
            .map_raster(&codes, Path::new("lc.tif"), "esa_worldcover")
            .unwrap();
        let name = |i: u8| m.materials[i as usize].name.as_str();
        let names: Vec<&str> = out.iter().map(|&i| name(i)).collect();
        assert_eq!(
            names,
            [
                "forest_floor",
                "grass",
                "grass",
                "water",
                "forest_floor",
                "urban"
            ]
        );
        assert_eq!(
            out[1], out[2],
            "remapped cropland shares grassland's material"
        );
    }

    /// Rationale: unknown codes must be listed with their pixel counts, and a fallback must
    /// absorb them instead.
    #[test]
    fn unknown_codes_are_listed_with_counts_or_fall_back() {
        let s = Scheme::load("corine").unwrap();
        let m = MaterialMap::new(&s, &BTreeMap::new(), &BTreeMap::new(), None).unwrap();
        let codes = [Some(12), Some(99), Some(99), None, Some(7)];
        let e = m
            .map_raster(&codes, Path::new("lc.tif"), "corine")
            .unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.contains("lc.tif") && msg.contains("99 (2 px)") && msg.contains("no data (1 px)"),
            "{msg}"
        );
        let m = MaterialMap::new(&s, &BTreeMap::new(), &BTreeMap::new(), Some("soil")).unwrap();
        let out = m.map_raster(&codes, Path::new("lc.tif"), "corine").unwrap();
        assert_eq!(m.materials[out[1] as usize].name, "soil");
        assert_eq!(out[1], out[3]);
    }

    /// Rationale: bad scheme files must name the file and key.
    #[test]
    fn bad_scheme_files_name_the_key() {
        let p = Path::new("my_scheme.toml");
        let e = Scheme::from_str(
            "name = \"x\"\nclasses = [{ code = 1, name = \"a\", material = \"nope\" }]\n",
            p,
        )
        .unwrap_err();
        assert!(
            e.to_string().contains("my_scheme.toml")
                && e.to_string().contains("classes[0].material"),
            "{e}"
        );
        let e = Scheme::from_str("name = \"x\"\nclasess = []\n", p).unwrap_err();
        assert!(e.to_string().contains("clasess"), "{e}");
        let e = Scheme::from_str(
            "name = \"x\"\nclasses = []\n[materials.m]\nbrdf = { type = \"lambertian\", reflectance = 1.5 }\n",
            p,
        )
        .unwrap_err();
        assert!(
            e.to_string().contains("materials.m.brdf.reflectance"),
            "{e}"
        );
        assert!(matches!(
            Scheme::load("worldcover"),
            Err(SchemeError::UnknownScheme { .. })
        ));
    }

    /// Rationale: schemes and `simulate` share one range table (`bundle::BRDF_PARAM_RANGES`);
    /// RPV k = 5 was accepted here (k ≤ 10) but refused by the simulator (k ≤ 2), so scenegen
    /// could write bundles that `simulate` refuses. The scheme must be refused at load, naming
    /// the file, the class, the material, the parameter, its value and the allowed range.
    #[test]
    fn rpv_k_outside_the_simulators_range_is_refused_naming_class_and_parameter() {
        let p = Path::new("crops.toml");
        let text = |k: f64| {
            format!(
                "name = \"crops\"\nclasses = [{{ code = 40, name = \"cropland\", material = \"crop\" }}]\n\
                 [materials.crop]\nbrdf = {{ type = \"rpv\", rho_0 = 0.1, k = {k}, g = -0.1 }}\n"
            )
        };
        let e = Scheme::from_str(&text(5.0), p).unwrap_err();
        let msg = e.to_string();
        for needle in [
            "crops.toml",
            "materials.crop.brdf.k",
            "class 40 `cropland`",
            "`k` = 5",
            "[0, 2]",
        ] {
            assert!(msg.contains(needle), "`{needle}` not in: {msg}");
        }
        // The upper end of the shared range is accepted.
        Scheme::from_str(&text(2.0), p).unwrap();
        // A tabulated spectrum is checked at every wavelength.
        let e = Scheme::from_str(
            &text(0.5).replace(
                "k = 0.5",
                "k = { wavelengths_nm = [400.0, 800.0], values = [0.9, 2.5] }",
            ),
            p,
        )
        .unwrap_err();
        assert!(e.to_string().contains("`k` = 2.5 at 800 nm"), "{e}");
    }
}
