//! A built-in catalogue of desert pseudo-invariant calibration sites (PICS), so that
//! `simulate pics … --site libya4` can name a site instead of a site file.
//!
//! The catalogue is `data/pics/sites.toml`, embedded at build time. Every number in it carries a
//! citation (`sources`); values no readable source gives are left out (`elevation`, `roi_km`,
//! `surface` are optional). No site has a published BRDF in the catalogue yet, so a run needs a
//! `[surface]` from the user (see `site_table`). The table of sites and their sources is in
//! `docs/pics_sites.md`.
//!
//! Names are matched forgivingly: case, spaces, hyphens and underscores are ignored, so
//! `libya4`, `Libya-4`, `LIBYA_4` and `libya 4` all find the same site.

const CATALOGUE: &str = include_str!("../../data/pics/sites.toml");

/// One catalogue site.
#[derive(Clone, Debug, PartialEq)]
pub struct Site {
    /// Catalogue key: lower case, letters and digits only (e.g. `libya4`).
    pub key: String,
    /// Display name (e.g. `Libya-4`).
    pub name: String,
    /// Centre latitude, degrees north (WGS84).
    pub latitude: f64,
    /// Centre longitude, degrees east (WGS84).
    pub longitude: f64,
    /// Height above sea level (m), when a source gives it.
    pub elevation: Option<f64>,
    /// Side of the square region of interest (km), when a source gives it.
    pub roi_km: Option<f64>,
    /// One citation (with URL) per value.
    pub sources: Vec<String>,
    /// The site's BRDF as an experiment `[surface]` table, when a published one is catalogued.
    pub surface: Option<toml::Table>,
    /// Citation of `surface`.
    pub surface_source: Option<String>,
}

/// Lower case, letters and digits only: the form keys are compared in.
fn normalize(name: &str) -> String {
    name.chars()
        .filter(|c| c.is_ascii_alphanumeric())
        .map(|c| c.to_ascii_lowercase())
        .collect()
}

fn number(t: &toml::Table, key: &str, site: &str) -> Result<Option<f64>, String> {
    match t.get(key) {
        None => Ok(None),
        Some(v) => v
            .as_float()
            .or_else(|| v.as_integer().map(|i| i as f64))
            .filter(|x| x.is_finite())
            .map(Some)
            .ok_or_else(|| format!("site `{site}`: `{key}` must be a finite number")),
    }
}

fn parse_site(key: &str, value: &toml::Value) -> Result<Site, String> {
    let t = value
        .as_table()
        .ok_or_else(|| format!("site `{key}` must be a table"))?;
    let known = [
        "name",
        "latitude",
        "longitude",
        "elevation",
        "roi_km",
        "sources",
        "surface",
        "surface_source",
    ];
    if let Some(k) = t.keys().find(|k| !known.contains(&k.as_str())) {
        return Err(format!("site `{key}`: unknown key `{k}`"));
    }
    if normalize(key) != key {
        return Err(format!(
            "site key `{key}` must be lower case letters and digits only"
        ));
    }
    let name = t
        .get("name")
        .and_then(|v| v.as_str())
        .ok_or_else(|| format!("site `{key}`: `name` (string) is required"))?
        .to_string();
    let latitude = number(t, "latitude", key)?
        .ok_or_else(|| format!("site `{key}`: `latitude` is required"))?;
    let longitude = number(t, "longitude", key)?
        .ok_or_else(|| format!("site `{key}`: `longitude` is required"))?;
    let sources = t
        .get("sources")
        .and_then(|v| v.as_array())
        .ok_or_else(|| format!("site `{key}`: `sources` (array of strings) is required"))?
        .iter()
        .map(|s| {
            s.as_str()
                .map(str::to_string)
                .ok_or_else(|| format!("site `{key}`: `sources` must hold strings"))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let mut surface = match t.get("surface") {
        None => None,
        Some(v) => Some(
            v.as_table()
                .cloned()
                .ok_or_else(|| format!("site `{key}`: `surface` must be a table"))?,
        ),
    };
    // `surface_source` may sit beside the surface table or inside it; it never reaches the
    // experiment (whose [surface] rejects unknown keys).
    let inner_source = surface.as_mut().and_then(|s| s.remove("surface_source"));
    let surface_source = match t.get("surface_source").or(inner_source.as_ref()) {
        None => None,
        Some(v) => Some(
            v.as_str()
                .ok_or_else(|| format!("site `{key}`: `surface_source` must be a string"))?
                .to_string(),
        ),
    };
    if surface.is_some() && surface_source.is_none() {
        return Err(format!(
            "site `{key}`: a catalogued surface needs its `surface_source`"
        ));
    }
    Ok(Site {
        key: key.to_string(),
        name,
        latitude,
        longitude,
        elevation: number(t, "elevation", key)?,
        roi_km: number(t, "roi_km", key)?,
        sources,
        surface,
        surface_source,
    })
}

fn parse(text: &str) -> Result<Vec<Site>, String> {
    let doc: toml::Table = text.parse().map_err(|e: toml::de::Error| e.to_string())?;
    let sites = doc
        .get("sites")
        .and_then(|v| v.as_table())
        .ok_or("the catalogue needs a [sites] table")?;
    sites.iter().map(|(k, v)| parse_site(k, v)).collect()
}

/// Every catalogued site (in the file's order where the `toml` crate keeps table order, else by
/// key). Panics only if the embedded catalogue is malformed (a build-time asset, checked by
/// this module's tests).
pub fn sites() -> Vec<Site> {
    parse(CATALOGUE).unwrap_or_else(|e| panic!("data/pics/sites.toml: {e}"))
}

/// The site called `name` (its key or its display name; case, spaces, `-` and `_` ignored). The
/// error lists the catalogued sites.
pub fn find(name: &str) -> Result<Site, String> {
    let wanted = normalize(name);
    let all = sites();
    if !wanted.is_empty() {
        if let Some(s) = all
            .iter()
            .find(|s| s.key == wanted || normalize(&s.name) == wanted)
        {
            return Ok(s.clone());
        }
    }
    let known: Vec<String> = all
        .iter()
        .map(|s| format!("{} ({})", s.key, s.name))
        .collect();
    Err(format!(
        "unknown calibration site `{name}`; catalogued sites: {}",
        known.join(", ")
    ))
}

/// A site-file table (`docs/pics.md`) for `site`: `name`, `latitude`, `longitude`, `elevation`
/// (when catalogued) and `surface` (when catalogued), then every key of `overrides` on top (user
/// keys win, whole values: a user `[surface]` replaces the catalogued one rather than merging
/// into it, so that two BRDF models are never mixed). Sources and `roi_km` stay out: they are not
/// site-file keys.
pub fn site_table(site: &Site, overrides: &toml::Table) -> toml::Table {
    let mut t = toml::Table::new();
    t.insert("name".into(), toml::Value::String(site.name.clone()));
    t.insert("latitude".into(), toml::Value::Float(site.latitude));
    t.insert("longitude".into(), toml::Value::Float(site.longitude));
    if let Some(e) = site.elevation {
        t.insert("elevation".into(), toml::Value::Float(e));
    }
    if let Some(s) = &site.surface {
        t.insert("surface".into(), toml::Value::Table(s.clone()));
    }
    for (k, v) in overrides {
        t.insert(k.clone(), v.clone());
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn catalogue_parses() {
        let all = sites();
        assert!(all.len() >= 5, "{} sites", all.len());
        let mut keys: Vec<&str> = all.iter().map(|s| s.key.as_str()).collect();
        keys.sort_unstable();
        keys.dedup();
        assert_eq!(keys.len(), all.len(), "duplicate keys");
        for s in &all {
            assert_eq!(normalize(&s.key), s.key);
            assert!(!s.name.is_empty());
        }
    }

    #[test]
    fn every_site_is_in_range_and_sourced() {
        for s in sites() {
            assert!(
                (-90.0..=90.0).contains(&s.latitude),
                "{}: {}",
                s.key,
                s.latitude
            );
            assert!(
                (-180.0..=180.0).contains(&s.longitude),
                "{}: {}",
                s.key,
                s.longitude
            );
            assert!(!s.sources.is_empty(), "{} has no source", s.key);
            assert!(
                s.sources.iter().all(|x| x.contains("http")),
                "{}: every source needs a URL",
                s.key
            );
            if let Some(r) = s.roi_km {
                assert!(r > 0.0, "{}: roi_km {r}", s.key);
            }
            if let Some(e) = s.elevation {
                assert!((-500.0..=9000.0).contains(&e), "{}: elevation {e}", s.key);
            }
            assert_eq!(s.surface.is_some(), s.surface_source.is_some(), "{}", s.key);
        }
    }

    #[test]
    fn find_is_forgiving() {
        for name in [
            "libya4",
            "Libya-4",
            "LIBYA_4",
            " libya 4 ",
            "Libya4",
            "LIBYA-4",
        ] {
            assert_eq!(find(name).unwrap().key, "libya4", "{name}");
        }
        assert_eq!(find("Mauritania-2").unwrap().key, "mauritania2");
        assert_eq!(find("algeria_3").unwrap().name, "Algeria-3");
    }

    #[test]
    fn find_lists_the_sites_on_error() {
        for bad in ["atlantis", "", "libya-99"] {
            let e = find(bad).unwrap_err();
            assert!(e.contains("unknown calibration site"), "{e}");
            for s in sites() {
                assert!(e.contains(&s.key), "{e} lacks {}", s.key);
            }
        }
    }

    /// The CEOS centre of Libya-4 (Remote Sens. 2024, 16(8), 1406, section 2.1).
    #[test]
    fn libya4_is_the_ceos_centre() {
        let s = find("libya4").unwrap();
        assert_eq!(s.name, "Libya-4");
        assert_eq!(s.latitude, 28.55);
        assert_eq!(s.longitude, 23.39);
    }

    #[test]
    fn site_table_merges_overrides() {
        let s = find("Libya-2").unwrap();
        let t = site_table(&s, &toml::Table::new());
        assert_eq!(t["name"].as_str(), Some("Libya-2"));
        assert_eq!(t["latitude"].as_float(), Some(25.05));
        assert_eq!(t["longitude"].as_float(), Some(20.48));
        assert!(!t.contains_key("sources") && !t.contains_key("roi_km"));

        let overrides: toml::Table = r#"
            elevation = 150.0
            name = "my Libya-2"
            spp = 1000
            [surface]
            type = "lambertian"
            reflectance = 0.4
        "#
        .parse()
        .unwrap();
        let t = site_table(&s, &overrides);
        assert_eq!(t["elevation"].as_float(), Some(150.0));
        assert_eq!(t["name"].as_str(), Some("my Libya-2"));
        assert_eq!(t["spp"].as_integer(), Some(1000));
        assert_eq!(t["latitude"].as_float(), Some(25.05));
        assert_eq!(t["surface"]["type"].as_str(), Some("lambertian"));
    }

    #[test]
    fn user_surface_replaces_a_catalogued_one() {
        let mut s = find("libya4").unwrap();
        s.surface = Some(
            r#"
            type = "rpv"
            rho_0 = 0.3
            k = 0.8
            g = -0.1
        "#
            .parse()
            .unwrap(),
        );
        let base = site_table(&s, &toml::Table::new());
        assert_eq!(base["surface"]["type"].as_str(), Some("rpv"));
        let overrides: toml::Table = "surface = { type = \"lambertian\", reflectance = 0.3 }"
            .parse()
            .unwrap();
        let t = site_table(&s, &overrides);
        let surf = t["surface"].as_table().unwrap();
        assert_eq!(surf["type"].as_str(), Some("lambertian"));
        assert!(!surf.contains_key("rho_0"), "no mixing of two BRDFs");
    }

    /// A catalogue site plus a user surface is a valid `simulate pics` site: every key is one
    /// `pics::experiment_text` knows, and the experiment resolves.
    #[test]
    fn site_table_makes_a_valid_pics_experiment() {
        for s in sites() {
            let overrides: toml::Table = "surface = { type = \"lambertian\", reflectance = 0.35 }"
                .parse()
                .unwrap();
            let t = site_table(&s, &overrides);
            let acq = crate::pics::Acquisition {
                time_utc: "2020-06-21T10:00:00Z".into(),
                vza: 10.0,
                vaa: 100.0,
                srf: "sentinel_2a-msi-4".into(),
                sun: None,
            };
            let text = crate::pics::experiment_text(&t, &acq, 0)
                .unwrap_or_else(|e| panic!("{}: {e}", s.key));
            engine::config::Experiment::from_str(&text, std::path::Path::new("catalogue"))
                .unwrap_or_else(|e| panic!("{}: {e}\n{text}", s.key));
        }
    }

    #[test]
    fn malformed_catalogues_are_rejected() {
        let bad = [
            "[sites.x]\nname = \"X\"\nlatitude = 1.0\nsources = [\"a http\"]\n",
            "[sites.Libya4]\nname = \"X\"\nlatitude = 1.0\nlongitude = 2.0\nsources = [\"http\"]\n",
            "[sites.x]\nname = \"X\"\nlatitude = 1.0\nlongitude = 2.0\nsources = [\"http\"]\nheight = 3\n",
            "[sites.x]\nname = \"X\"\nlatitude = 1.0\nlongitude = 2.0\nsources = [\"http\"]\n[sites.x.surface]\ntype = \"lambertian\"\nreflectance = 0.3\n",
        ];
        for text in bad {
            assert!(parse(text).is_err(), "{text}");
        }
        let ok = parse(
            "[sites.x]\nname = \"X\"\nlatitude = 1\nlongitude = 2.0\nsources = [\"http\"]\n\
             [sites.x.surface]\ntype = \"lambertian\"\nreflectance = 0.3\nsurface_source = \"s\"\n",
        )
        .unwrap();
        assert_eq!(ok[0].latitude, 1.0);
        assert_eq!(ok[0].surface_source.as_deref(), Some("s"));
        assert!(!ok[0]
            .surface
            .as_ref()
            .unwrap()
            .contains_key("surface_source"));
    }
}
