//! The non-image measures of `results.nc` as one table, like `results.csv`: a `direction`
//! dimension with one entry per (measure, direction) — a `distant_flux` measure has one entry,
//! with NaN angles — and a `measure` dimension listing the measures.
//!
//! The number of netCDF variables and dimensions does not depend on the number of measures, so
//! writing 1000 radiancemeters costs about as much as one measure of 1000 directions
//! (BENCHMARKS.md, "netCDF writing cost"). The earlier layout gave every measure a dimension and
//! 11 variables (11 000 HDF5 datasets for 1000 radiancemeters) and wrote each variable's data
//! right after defining it, so netCDF-4 left and re-entered define mode once per variable; its
//! cost grew about quadratically with the measure count (1000: 61 s, 110 MB). Which of the two
//! dominated was not isolated; the table removes both.
//!
//! Variables (units in `docs/conventions.md`):
//! * on `measure`: `measure_id` (string), `measure_type` (string, as in the CSV `type` column),
//!   `measure_direction_count` (int, CF contiguous ragged array: `sample_dimension = "direction"`,
//!   the measures' directions are consecutive in the `direction` dimension, in measure order),
//!   `flux_altitude` (m, NaN for other measures), `flux_direction` ("up"/"down", empty for other
//!   measures; runs with a `distant_flux` measure);
//! * on `direction`: `vza`, `vaa` (degrees, target → sensor), `direction_measure` (int index into
//!   `measure`) and `direction_measure_id` (string), all four named in each data variable's
//!   `coordinates` attribute;
//! * on `(wavelength, direction)`: `brf`, `radiance`, `brf_single`, `brf_multiple` with their
//!   `_stderr` (when the run has a directional measure), `albedo`, `flux`, `flux_direct`,
//!   `flux_diffuse` and `_stderr` (when it has a `distant_flux` measure), polarized runs `brf_q`, `brf_u`, `brf_v`, `dolp` and `_stderr`;
//!   `n_samples` (int64). Entries that do not apply to a measure (a BRF of a flux measure) are NaN.
//! * band runs (`spectral.srf`), on `direction`: `band_brf`, `band_radiance`, `band_albedo`,
//!   `band_flux`, `band_flux_direct`, `band_flux_diffuse`, `band_brightness_temperature` (thermal runs) and `_stderr` (those with a
//!   finite value), attribute `band_irradiance`;
//! * thermal runs (`emission = true`): `brightness_temperature` (K) and its `_stderr` on
//!   `(wavelength, direction)`;
//! * runs with an `hdrf` measure: `hdrf` and its `_stderr` on `(wavelength, direction)` (NaN
//!   for other measures).

use std::collections::HashMap;

use crate::products::{BandRow, Row};
use engine::config::resolve::Experiment;
use engine::measure::Measure;

/// The `direction` layout: the non-image measures and the offset of each one's first entry.
struct Layout<'a> {
    measures: Vec<&'a Measure>,
    /// Measure id → (first entry in `direction`, number of entries).
    offsets: HashMap<&'a str, (usize, usize)>,
    len: usize,
}

impl<'a> Layout<'a> {
    fn new(exp: &'a Experiment) -> Self {
        let measures: Vec<&Measure> = exp.measures.iter().filter(|m| !m.is_image()).collect();
        let mut offsets = HashMap::new();
        let mut len = 0;
        for m in &measures {
            offsets.insert(m.id.as_str(), (len, m.row_count()));
            len += m.row_count();
        }
        Layout {
            measures,
            offsets,
            len,
        }
    }
}

/// A `(wavelength, direction)` quantity: name, getter, units, long name.
type Quantity = (
    &'static str,
    fn(&Row) -> Option<(f64, f64)>,
    &'static str,
    &'static str,
);

const DIRECTIONAL: [Quantity; 4] = [
    (
        "brf",
        |r| r.brf,
        "1",
        "bidirectional reflectance factor pi L / (E0 cos SZA)",
    ),
    (
        "brf_single",
        |r| r.brf_single,
        "1",
        "single-scattering part of brf",
    ),
    (
        "brf_multiple",
        |r| r.brf_multiple,
        "1",
        "multiple-scattering part of brf",
    ),
    ("radiance", |r| r.radiance, "W m-2 sr-1 nm-1", "radiance"),
];

const FLUX: [Quantity; 4] = [
    (
        "albedo",
        |r| r.albedo,
        "1",
        "hemispherical flux / (E0 cos SZA), upwelling or downwelling (flux_direction)",
    ),
    (
        "flux",
        |r| r.flux,
        "W m-2 nm-1",
        "hemispherical flux, upwelling or downwelling (flux_direction)",
    ),
    (
        "flux_direct",
        |r| r.flux_direct,
        "W m-2 nm-1",
        "direct solar beam's part of flux (exact; 0 upwelling)",
    ),
    (
        "flux_diffuse",
        |r| r.flux_diffuse,
        "W m-2 nm-1",
        "scattered light's part of flux",
    ),
];

const POLARIZED: [Quantity; 4] = [
    (
        "brf_q",
        |r| r.brf_q,
        "1",
        "Stokes Q normalised like brf (meridian frame of the view direction)",
    ),
    (
        "brf_u",
        |r| r.brf_u,
        "1",
        "Stokes U normalised like brf (meridian frame of the view direction)",
    ),
    ("brf_v", |r| r.brf_v, "1", "Stokes V normalised like brf"),
    (
        "dolp",
        |r| r.dolp,
        "1",
        "degree of linear polarization sqrt(Q^2+U^2)/I",
    ),
];

const HDRF: [Quantity; 1] = [(
    "hdrf",
    |r| r.hdrf,
    "1",
    "hemispherical-directional reflectance factor pi L_up / E_down at the measure's level",
)];

const THERMAL: [Quantity; 1] = [(
    "brightness_temperature",
    |r| r.brightness_temperature,
    "K",
    "brightness temperature: inverse Planck function of the radiance at the wavelength",
)];

const COORDINATES: &str = "vza vaa direction_measure direction_measure_id";

/// Write the table of the non-image measures (nothing when there are none).
pub(super) fn write(
    f: &mut netcdf::FileMut,
    exp: &Experiment,
    rows: &[Row],
) -> Result<(), netcdf::Error> {
    let lay = Layout::new(exp);
    if lay.measures.is_empty() {
        return Ok(());
    }
    let (nm, nd, nw) = (lay.measures.len(), lay.len, exp.wavelengths.len());
    f.add_dimension("measure", nm)?;
    f.add_dimension("direction", nd)?;

    // Where each row goes: rows of one measure come in (wavelength, direction) order.
    let mut seen: HashMap<&str, usize> = HashMap::new();
    let mut at: Vec<usize> = Vec::with_capacity(rows.len());
    for r in rows {
        let Some(&(off, nc)) = lay.offsets.get(r.measure.as_str()) else {
            at.push(usize::MAX);
            continue;
        };
        let k = seen.entry(r.measure.as_str()).or_insert(0);
        let (iw, c) = (*k / nc.max(1), *k % nc.max(1));
        *k += 1;
        at.push(if iw < nw {
            iw * nd + off + c
        } else {
            usize::MAX
        });
    }

    write_measures(f, &lay)?;
    write_directions(f, &lay, rows, &at)?;

    let has_dir = lay.measures.iter().any(|m| !m.is_flux());
    let has_flux = lay.measures.iter().any(|m| m.is_flux());
    let mut quantities: Vec<&Quantity> = Vec::new();
    if has_dir {
        quantities.extend(&DIRECTIONAL);
    }
    if has_flux {
        quantities.extend(&FLUX);
    }
    if rows.iter().any(|r| r.brf_q.is_some()) {
        quantities.extend(&POLARIZED);
    }
    if rows.iter().any(|r| r.brightness_temperature.is_some()) {
        quantities.extend(&THERMAL);
    }
    if rows.iter().any(|r| r.hdrf.is_some()) {
        quantities.extend(&HDRF);
    }
    let dims = ["wavelength", "direction"];
    for (name, get, units, long) in quantities {
        let mut val = vec![f64::NAN; nw * nd];
        let mut err = vec![f64::NAN; nw * nd];
        for (r, &i) in rows.iter().zip(&at) {
            if let (Some((v, e)), true) = (get(r), i < val.len()) {
                val[i] = v;
                err[i] = e;
            }
        }
        let stderr_long = format!("standard error of {name}");
        for (n, data, l) in [
            (name.to_string(), val, *long),
            (format!("{name}_stderr"), err, stderr_long.as_str()),
        ] {
            let mut v = f.add_variable::<f64>(&n, &dims)?;
            v.put_attribute("units", *units)?;
            v.put_attribute("long_name", l)?;
            v.put_attribute("coordinates", COORDINATES)?;
            v.put_values(&data, ..)?;
        }
    }
    let mut n = vec![0i64; nw * nd];
    for (r, &i) in rows.iter().zip(&at) {
        if i < n.len() {
            n[i] = r.n_samples as i64;
        }
    }
    let mut v = f.add_variable::<i64>("n_samples", &dims)?;
    v.put_attribute("long_name", "Monte Carlo samples")?;
    v.put_attribute("coordinates", COORDINATES)?;
    v.put_values(&n, ..)?;
    Ok(())
}

/// The strings of a one-dimensional string variable, entry by entry.
fn put_strings(v: &mut netcdf::VariableMut, values: &[&str]) -> Result<(), netcdf::Error> {
    for (i, s) in values.iter().enumerate() {
        v.put_string(s, i)?;
    }
    Ok(())
}

fn write_measures(f: &mut netcdf::FileMut, lay: &Layout) -> Result<(), netcdf::Error> {
    let ids: Vec<&str> = lay.measures.iter().map(|m| m.id.as_str()).collect();
    let types: Vec<&str> = lay.measures.iter().map(|m| m.type_name()).collect();
    let mut v = f.add_string_variable("measure_id", &["measure"])?;
    v.put_attribute("long_name", "measure id (the experiment's measures.id)")?;
    v.put_attribute("cf_role", "timeseries_id")?;
    put_strings(&mut v, &ids)?;
    let mut v = f.add_string_variable("measure_type", &["measure"])?;
    v.put_attribute("long_name", "measure type")?;
    put_strings(&mut v, &types)?;
    let counts: Vec<i32> = lay.measures.iter().map(|m| m.row_count() as i32).collect();
    let mut v = f.add_variable::<i32>("measure_direction_count", &["measure"])?;
    v.put_attribute(
        "long_name",
        "number of consecutive direction entries of the measure",
    )?;
    v.put_attribute("sample_dimension", "direction")?;
    v.put_values(&counts, ..)?;
    let alt: Vec<f64> = lay
        .measures
        .iter()
        .map(|m| match m.kind {
            engine::measure::MeasureKind::DistantFlux { altitude, .. } => altitude,
            _ => f64::NAN,
        })
        .collect();
    let mut v = f.add_variable::<f64>("flux_altitude", &["measure"])?;
    v.put_attribute("units", "m")?;
    v.put_attribute("long_name", "altitude of a distant_flux measure's level")?;
    v.put_values(&alt, ..)?;
    if lay.measures.iter().any(|m| m.is_flux()) {
        let dirs: Vec<&str> = lay
            .measures
            .iter()
            .map(|m| match m.kind {
                engine::measure::MeasureKind::DistantFlux { direction, .. } => direction.name(),
                _ => "",
            })
            .collect();
        let mut v = f.add_string_variable("flux_direction", &["measure"])?;
        v.put_attribute(
            "long_name",
            "hemisphere of a distant_flux measure: up (upwelling) or down (downwelling); empty for other measures",
        )?;
        put_strings(&mut v, &dirs)?;
    }
    Ok(())
}

fn write_directions(
    f: &mut netcdf::FileMut,
    lay: &Layout,
    rows: &[Row],
    at: &[usize],
) -> Result<(), netcdf::Error> {
    let nd = lay.len;
    let (mut vza, mut vaa) = (vec![f64::NAN; nd], vec![f64::NAN; nd]);
    // The angles of the first wavelength's rows (the same at every wavelength).
    for (r, &i) in rows.iter().zip(at) {
        if i < nd {
            vza[i] = r.vza.unwrap_or(f64::NAN);
            vaa[i] = r.vaa.unwrap_or(f64::NAN);
        }
    }
    let mut owner = Vec::with_capacity(nd);
    let mut owner_id = Vec::with_capacity(nd);
    for (k, m) in lay.measures.iter().enumerate() {
        for _ in 0..m.row_count() {
            owner.push(k as i32);
            owner_id.push(m.id.as_str());
        }
    }
    for (name, data, long) in [
        ("vza", vza, "viewing zenith angle (target to sensor)"),
        (
            "vaa",
            vaa,
            "viewing azimuth angle, clockwise from North (target to sensor)",
        ),
    ] {
        let mut v = f.add_variable::<f64>(name, &["direction"])?;
        v.put_attribute("units", "degree")?;
        v.put_attribute("long_name", long)?;
        v.put_values(&data, ..)?;
    }
    let mut v = f.add_variable::<i32>("direction_measure", &["direction"])?;
    v.put_attribute(
        "long_name",
        "index of the entry's measure in the measure dimension",
    )?;
    v.put_values(&owner, ..)?;
    let mut v = f.add_string_variable("direction_measure_id", &["direction"])?;
    v.put_attribute("long_name", "id of the entry's measure")?;
    put_strings(&mut v, &owner_id)?;
    Ok(())
}

/// Band-weighted variables on `direction` (see the module documentation).
pub(super) fn write_band(
    f: &mut netcdf::FileMut,
    exp: &Experiment,
    band: &[BandRow],
) -> Result<(), netcdf::Error> {
    let Some(b) = &exp.band else { return Ok(()) };
    f.add_attribute("srf", b.name.as_str())?;
    let lay = Layout::new(exp);
    if lay.measures.is_empty() {
        return Ok(());
    }
    let nd = lay.len;
    let mut seen: HashMap<&str, usize> = HashMap::new();
    let at: Vec<usize> = band
        .iter()
        .map(|r| match lay.offsets.get(r.measure.as_str()) {
            Some(&(off, _)) => {
                let k = seen.entry(r.measure.as_str()).or_insert(0);
                *k += 1;
                off + *k - 1
            }
            None => usize::MAX,
        })
        .collect();
    type Get = fn(&BandRow) -> Option<(f64, f64)>;
    let sets: [(&str, Get, &str); 7] = [
        ("band_brf", |r| r.brf, "1"),
        ("band_radiance", |r| r.radiance, "W m-2 sr-1 nm-1"),
        ("band_albedo", |r| r.albedo, "1"),
        ("band_flux", |r| r.flux, "W m-2 nm-1"),
        ("band_flux_direct", |r| r.flux_direct, "W m-2 nm-1"),
        ("band_flux_diffuse", |r| r.flux_diffuse, "W m-2 nm-1"),
        (
            "band_brightness_temperature",
            |r| r.brightness_temperature,
            "K",
        ),
    ];
    let irradiance = band.first().map_or(f64::NAN, |r| r.irradiance);
    for (name, get, units) in sets {
        let mut val = vec![f64::NAN; nd];
        let mut err = vec![f64::NAN; nd];
        for (r, &i) in band.iter().zip(&at) {
            if let (Some((v, e)), true) = (get(r), i < nd) {
                val[i] = v;
                err[i] = e;
            }
        }
        if val.iter().all(|v| v.is_nan()) {
            continue;
        }
        for (n, data) in [(name.to_string(), val), (format!("{name}_stderr"), err)] {
            let mut v = f.add_variable::<f64>(&n, &["direction"])?;
            v.put_attribute("units", units)?;
            v.put_attribute(
                "long_name",
                format!("{n} weighted by the spectral response {}", b.name).as_str(),
            )?;
            v.put_attribute("band_irradiance", irradiance)?;
            v.put_attribute("coordinates", COORDINATES)?;
            v.put_values(&data, ..)?;
        }
    }
    Ok(())
}
