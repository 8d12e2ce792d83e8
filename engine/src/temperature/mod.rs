//! Surface temperatures from a heat-conduction energy balance (DIRSIG's temperature solver,
//! issue 39): `slab.rs` conducts heat through a layered slab, `balance.rs` drives its surface
//! through a day by sunlight, sky light, longwave sky, emission and convection and finds the
//! periodic day. The application (`simulator/src/temperatures/`) computes the broadband
//! irradiances through the run's atmosphere, the facets' shadows and sky views in a scene, and
//! writes LST rasters that thermal runs read (`scene.land_surface_temperature`).
//!
//! Thermal properties per material come from the presets below or from the user (keys in
//! `docs/temperatures.md`). Preset values: soils, asphalt, concrete, brick and water from Oke
//! (1987), *Boundary Layer Climates*, Table 2.1; roof build-ups and albedos/emissivities from
//! common handbook values (ASHRAE Fundamentals 2017, ch. 26 and 33); wetness (the fraction of
//! open-water evaporation) from the ranges of Monteith & Unsworth (2013). Not modelled: stomatal
//! control (transpiration is a fixed fraction), snow running out (melting snow stays at
//! 273.15 K, its supply unlimited), the heat of
//! buildings' interiors (roofs sit on insulation over an adiabatic bottom), water's penetration
//! by sunlight and its currents (a 2 m mixed slab).

pub mod balance;
pub mod slab;

use slab::{Bottom, Layer};

/// A material's thermal description.
#[derive(Clone, Debug, PartialEq)]
pub struct ThermalMaterial {
    /// Layers from the surface down.
    pub layers: Vec<Layer>,
    /// Broadband shortwave albedo.
    pub albedo: f64,
    /// Thermal emissivity.
    pub emissivity: f64,
    /// Wetness β ∈ [0, 1] (the fraction of open-water evaporation; `balance.rs`).
    pub wetness: f64,
    pub bottom: Bottom,
    /// K: the surface melts rather than warm past this (snow, ice; `slab.rs`).
    pub melting_point: Option<f64>,
}

impl ThermalMaterial {
    /// A slab of this material at `t0` (K), nodes from `first_m` growing by `growth`.
    pub fn slab(&self, first_m: f64, growth: f64, t0: f64) -> Result<slab::Slab, slab::SlabError> {
        let mut s = slab::Slab::new(&self.layers, first_m, growth, self.bottom, t0)?;
        s.melting_point = self.melting_point;
        Ok(s)
    }
}

const fn layer(thickness_m: f64, conductivity: f64, density: f64, heat_capacity: f64) -> Layer {
    Layer {
        thickness_m,
        conductivity,
        density,
        heat_capacity,
    }
}

/// The preset names, with a line each for error messages and docs.
pub const PRESETS: &[(&str, &str)] = &[
    ("asphalt", "0.1 m asphalt over 0.9 m sandy soil"),
    ("concrete", "1 m dense concrete"),
    ("brick", "1 m brick"),
    ("dry_soil", "1 m dry sandy soil"),
    ("moist_soil", "1 m saturated sandy soil"),
    ("clay_soil", "1 m dry clay soil"),
    ("rock", "1 m rock (granite, limestone)"),
    (
        "grass",
        "moist soil with a grass albedo, transpiring (wetness 0.3)",
    ),
    (
        "forest",
        "moist soil with a forest albedo, transpiring (wetness 0.3)",
    ),
    ("water", "2 m of mixed water (eddy conductivity)"),
    ("roof_tile", "2 cm clay tiles over 10 cm insulation"),
    ("metal_roof", "1 mm galvanised steel over 10 cm insulation"),
    (
        "flat_roof",
        "2 cm bitumen membrane over 10 cm insulation and 15 cm concrete",
    ),
    (
        "snow",
        "30 cm of settled snow over dry soil (no melting: it can pass 273.15 K)",
    ),
    (
        "leaf",
        "a 0.3 mm leaf, its back adiabatic, transpiring (wetness 0.3)",
    ),
    ("bark", "10 cm of wood"),
];

/// The thermal material of preset `name`, if there is one.
pub fn preset(name: &str) -> Option<ThermalMaterial> {
    let sand_dry = layer(1.0, 0.30, 1600.0, 800.0);
    let sand_wet = layer(1.0, 2.20, 2000.0, 1480.0);
    let insulation = layer(0.10, 0.04, 30.0, 1400.0);
    let m = |layers: Vec<Layer>, albedo: f64, emissivity: f64, wetness: f64| ThermalMaterial {
        layers,
        albedo,
        emissivity,
        wetness,
        bottom: Bottom::Adiabatic,
        melting_point: None,
    };
    // Wetness: sealed and dry surfaces 0; moist soil 0.5, transpiring grass and forest 0.3,
    // open water 1 (docs/temperatures.md).
    let dry = 0.0;
    Some(match name {
        "asphalt" => m(
            vec![
                layer(0.1, 0.75, 2110.0, 920.0),
                layer(0.9, 0.30, 1600.0, 800.0),
            ],
            0.10,
            0.95,
            dry,
        ),
        "concrete" => m(vec![layer(1.0, 1.51, 2400.0, 880.0)], 0.30, 0.92, dry),
        "brick" => m(vec![layer(1.0, 0.83, 1970.0, 750.0)], 0.30, 0.93, dry),
        "dry_soil" => m(vec![sand_dry], 0.25, 0.92, 0.05),
        "moist_soil" => m(vec![sand_wet], 0.15, 0.95, 0.5),
        "clay_soil" => m(vec![layer(1.0, 0.25, 1600.0, 890.0)], 0.20, 0.95, 0.1),
        "rock" => m(vec![layer(1.0, 2.5, 2650.0, 800.0)], 0.25, 0.93, dry),
        "grass" => m(vec![sand_wet], 0.23, 0.98, 0.3),
        "forest" => m(vec![sand_wet], 0.12, 0.98, 0.3),
        "water" => m(vec![layer(2.0, 50.0, 1000.0, 4186.0)], 0.06, 0.98, 1.0),
        "roof_tile" => m(
            vec![layer(0.02, 0.84, 1900.0, 800.0), insulation],
            0.25,
            0.90,
            dry,
        ),
        "metal_roof" => m(
            vec![layer(0.001, 45.0, 7850.0, 460.0), insulation],
            0.35,
            0.30,
            dry,
        ),
        "flat_roof" => m(
            vec![
                layer(0.02, 0.17, 1050.0, 1000.0),
                insulation,
                layer(0.15, 1.51, 2400.0, 880.0),
            ],
            0.10,
            0.93,
            dry,
        ),
        "snow" => ThermalMaterial {
            melting_point: Some(273.15),
            ..m(
                vec![layer(0.3, 0.2, 300.0, 2090.0), sand_dry],
                0.70,
                0.98,
                dry,
            )
        },
        "leaf" => m(vec![layer(0.0003, 0.5, 800.0, 3500.0)], 0.30, 0.97, 0.3),
        "bark" => m(vec![layer(0.1, 0.15, 600.0, 1700.0)], 0.20, 0.95, dry),
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_preset_builds_a_slab() {
        for (name, _) in PRESETS {
            let m = preset(name).unwrap();
            assert!(m.slab(0.002, 1.15, 290.0).is_ok(), "{name}");
            assert!((0.0..1.0).contains(&m.albedo) && m.emissivity > 0.0 && m.emissivity <= 1.0);
            assert!((0.0..=1.0).contains(&m.wetness));
        }
        assert!(preset("lava").is_none());
    }
}
