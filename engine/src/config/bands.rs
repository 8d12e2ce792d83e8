//! Resolving `[spectral] bands` (several sensor bands in one run, `spectral/bands.rs`): the
//! bands' nodes and sets from the optics of the union of their wavelengths, the checks that the
//! grouped walks carrying them can run, and the run's outputs turned into the bands.

use crate::atmosphere::PlaneParallel;
use crate::error::{ConfigCtx, ConfigError};
use crate::integrator::backward_alis::unsupported_group;
use crate::integrator::settings::IntegratorSettings;
use crate::optics::OpticalState;
use crate::spectral::bands::{BandCentre, BandDraws, MAX_NODES};
use crate::spectral::{wavelength_groups_of, Band};

/// A run's sensor bands: their nodes' optical states and how each sample draws them.
#[derive(Clone, Debug)]
pub struct BandWalks {
    /// Per node, the optical state its channel walks.
    pub nodes: Vec<OpticalState>,
    pub draws: BandDraws,
}

impl std::ops::Deref for BandWalks {
    type Target = BandDraws;
    fn deref(&self) -> &BandDraws {
        &self.draws
    }
}

/// The nodes and draws of `bands` over the run's `optics` (one per run wavelength; in CKD mode
/// each with its g-points), and per band its centre. `centres`: per band, its effective
/// wavelength and irradiance when its nodes are of equal share (mono mode: a node's share is
/// its weight over the sum); empty in CKD mode, where the shares are `w·g·E0` and the centres
/// come from the bins. `mu_sun`: cosine of the solar zenith. `Err`: a message (the caller
/// names the key).
fn build(
    bands: &[Band],
    centres: &[BandCentre],
    optics: &[OpticalState],
    mu_sun: f64,
) -> Result<(BandWalks, Vec<BandCentre>), String> {
    let mut nodes: Vec<OpticalState> = Vec::new();
    // Per run wavelength: its nodes (index, g-weight).
    let mut of_wavelength: Vec<Vec<(usize, f64)>> = Vec::with_capacity(optics.len());
    for (iw, o) in optics.iter().enumerate() {
        let used = bands.iter().any(|b| b.weights[iw] > 0.0);
        let mut here = Vec::new();
        if used {
            if o.g_states.is_empty() {
                here.push((nodes.len(), 1.0));
                nodes.push(o.clone());
            } else {
                for (gw, st) in &o.g_states {
                    let mut st = st.clone();
                    st.g_states.clear();
                    st.irradiance = o.irradiance;
                    here.push((nodes.len(), *gw));
                    nodes.push(st);
                }
            }
        }
        of_wavelength.push(here);
    }
    // Per node, the gas transmittance of a path down at the Sun's zenith and back up
    // vertically (what the draws favour, `spectral/bands.rs`).
    let path = 1.0 / mu_sun.max(0.05) + 1.0;
    let gas: Vec<f64> = nodes
        .iter()
        .map(|o| {
            let a = &o.atmosphere;
            let tau: f64 = (0..a.layer_count()).map(|i| a.tau_abs(i)).sum();
            (-tau * path).exp()
        })
        .collect();
    let equal = !centres.is_empty();
    let mut lists = Vec::new();
    let mut out = Vec::new();
    for (ib, b) in bands.iter().enumerate() {
        let (mut sw, mut swe, mut swl) = (0.0, 0.0, 0.0);
        let mut list: Vec<(usize, f64, f64)> = Vec::new();
        for (iw, &w) in b.weights.iter().enumerate() {
            if w <= 0.0 {
                continue;
            }
            let e0 = if equal { 1.0 } else { optics[iw].irradiance };
            sw += w;
            swe += w * e0;
            swl += w * optics[iw].wavelength;
            for &(n, gw) in &of_wavelength[iw] {
                if gw > 0.0 {
                    list.push((n, w * gw * e0, gas[n]));
                }
            }
        }
        if swe.is_nan() || swe <= 0.0 {
            return Err(format!(
                "band \"{}\" receives no sunlight (its weighted solar irradiance is 0)",
                b.name
            ));
        }
        if list.len() > MAX_NODES {
            return Err(format!(
                "band \"{}\" is sampled at {} nodes (bins × g-points): at most {MAX_NODES} (fewer `g_points`, or an absorption database with wider bins)",
                b.name,
                list.len()
            ));
        }
        for x in &mut list {
            x.1 /= swe;
        }
        lists.push(list);
        out.push(if equal {
            centres[ib]
        } else {
            BandCentre {
                wavelength: swl / sw,
                irradiance: swe / sw,
            }
        });
    }
    let names = bands.iter().map(|b| b.name.clone()).collect();
    Ok((
        BandWalks {
            nodes,
            draws: BandDraws::new(names, lists),
        },
        out,
    ))
}

/// The band walks of `bands` over `optics` (one per entry of `wavelengths`, the union of the
/// bands' wavelengths); then `wavelengths` and `optics` become one entry per band: its
/// effective wavelength, and a node's optical state carrying the band irradiance.
pub(super) fn resolve(
    ctx: &ConfigCtx,
    bands: &[Band],
    centres: &[BandCentre],
    wavelengths: &mut Vec<f64>,
    optics: &mut Vec<OpticalState>,
    integrator: &IntegratorSettings,
    sun_zenith_deg: f64,
) -> Result<BandWalks, ConfigError> {
    let Some(group) = integrator.spectral_alis else {
        return Err(ctx.err(
            "spectral.bands",
            "sensor bands are walked as channels of grouped (ALIS) walks, which this run cannot use: they need a scalar, plane-parallel, backward run without emission, lamps, cloud fields or per-material solvers, and integrator.spectral_walk \"auto\" or \"alis\"",
        ));
    };
    if integrator.alis {
        return Err(ctx.err(
            "integrator.ckd_walk",
            "\"alis\" is not used with `spectral.bands`: each band's g-points are sampled as its nodes",
        ));
    }
    let (walks, centres) = build(bands, centres, optics, sun_zenith_deg.to_radians().cos())
        .map_err(|m| ctx.err("spectral.bands", m))?;
    let centre_nm: Vec<f64> = centres.iter().map(|c| c.wavelength).collect();
    for g in wavelength_groups_of(&centre_nm, Some(group)) {
        for set in &walks.sets(&g).nodes {
            let atms: Vec<&PlaneParallel> =
                set.iter().map(|&n| &walks.nodes[n].atmosphere).collect();
            if let Some((i, _)) = unsupported_group(&atms, true) {
                return Err(ctx.err(
                    "spectral.bands",
                    format!(
                        "layer {i} (from the top) scatters at some node of the bands {} but not at the walk's reference; use smaller groups (integrator.alis_group)",
                        g.iter()
                            .map(|&b| format!("\"{}\"", walks.names[b]))
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                ));
            }
        }
    }
    *wavelengths = centre_nm;
    *optics = centres
        .iter()
        .enumerate()
        .map(|(b, c)| {
            let mut o = walks.nodes[walks.draws.draws[b][0].0].clone();
            o.wavelength = c.wavelength;
            o.irradiance = c.irradiance;
            o
        })
        .collect();
    Ok(walks)
}
