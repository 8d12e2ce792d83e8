//! Sensors: where the paths of every measure start, and the polarization frame they score in.
//! A *cell* is one output value of a measure (a direction of a distant measure, a pixel of an
//! image, the one value of a radiancemeter or flux); each sample of a cell draws its start here
//! (random numbers: 2 for area, pixel and hemisphere sampling, none otherwise) and the
//! estimators score into that cell.
//!
//! Polarization frames: a backward path scores Stokes vectors in the meridian frame of the
//! direction towards the sensor (`stokes.rs`); for a vertical view the meridian plane is fixed by
//! [`frame_azimuth`] (the view azimuth of distant and ortho measures, the radiancemeter's stated
//! azimuth, the azimuth of a camera's `up` axis).

use glam::DVec3;

use crate::atmosphere::spherical::SphericalShell;
use crate::frame::sample_cosine_hemisphere;
use crate::integrator::geometry::scene_layers::SceneInLayers;
use crate::integrator::geometry::scene_shells::SceneInShells;
use crate::measure::{FluxDirection, Measure, MeasureKind};
use crate::optics::OpticalState;
use crate::rng::Stream;
use crate::scene::Scene;

/// Azimuth (radians, clockwise from North) fixing the Stokes meridian plane of a vertical
/// view in cell `cell` of `m`.
pub fn frame_azimuth(m: &Measure, cell: usize) -> f64 {
    match &m.kind {
        MeasureKind::Distant { vaa, .. } => vaa[cell].to_radians(),
        MeasureKind::Radiancemeter { frame_azimuth, .. } => *frame_azimuth,
        MeasureKind::DistantFlux { .. } => 0.0,
        MeasureKind::Hdrf { vaa, .. } => vaa.get(cell).map_or(0.0, |a| a.to_radians()),
        MeasureKind::Ortho(g) => g.vaa.to_radians(),
        MeasureKind::Perspective(c) => c.up.x.atan2(c.up.y),
    }
}

/// What a forward walk of a 1D distant or flux measure scores: the directions, the flux
/// level's optical depth with its direction, and the azimuths of the directions' Stokes frames
/// (radians).
pub fn forward_targets(
    m: &Measure,
    opt: &OpticalState,
) -> (Vec<DVec3>, Option<(f64, FluxDirection)>, Vec<f64>) {
    match &m.kind {
        MeasureKind::Distant {
            directions, vaa, ..
        } => (
            directions.clone(),
            None,
            vaa.iter().map(|a| a.to_radians()).collect(),
        ),
        MeasureKind::DistantFlux {
            altitude,
            direction,
        } => (
            Vec::new(),
            Some((opt.atmosphere.tau_at_altitude(*altitude), *direction)),
            Vec::new(),
        ),
        MeasureKind::Radiancemeter { .. }
        | MeasureKind::Hdrf { .. }
        | MeasureKind::Ortho(_)
        | MeasureKind::Perspective(_) => {
            unreachable!("radiancemeters and HDRFs are backward measures; images use scenes")
        }
    }
}

/// Starting point, shell and path direction of a backward sample in a spherical shell (planet
/// centred; the target point is at (0, 0, R_ground)); `None` when the line of sight misses the
/// atmosphere.
pub fn spherical_start(
    shell: &SphericalShell,
    m: &Measure,
    cell: usize,
    rng: &mut Stream,
) -> Option<(DVec3, usize, DVec3)> {
    let rg = shell.ground_radius();
    let target = DVec3::new(0.0, 0.0, rg);
    let (p, d) = match &m.kind {
        MeasureKind::Distant { directions, .. } => {
            // The line of sight through the target, entered from TOA.
            let v = directions[cell];
            let r = shell.toa_radius();
            let b = target.dot(v);
            let t = -b + (b * b - (rg * rg - r * r)).sqrt();
            (target + v * t, -v)
        }
        MeasureKind::Radiancemeter { origin, look, .. } => {
            let p = DVec3::new(origin.x, origin.y, shell.planet_radius + origin.z);
            (shell.entry_point(p, *look)?, *look)
        }
        MeasureKind::DistantFlux {
            altitude,
            direction,
        } => {
            let d = flux_path_direction(*direction, rng);
            (DVec3::new(0.0, 0.0, shell.planet_radius + altitude), d)
        }
        MeasureKind::Hdrf {
            directions,
            altitude,
            ..
        } => {
            let d = hdrf_path_direction(directions, cell, rng);
            (DVec3::new(0.0, 0.0, shell.planet_radius + altitude), d)
        }
        MeasureKind::Ortho(_) | MeasureKind::Perspective(_) => unreachable!("scene walk"),
    };
    let l = shell.shell_at(p.length()).min(shell.shell_count() - 1);
    Some((p, l, d))
}

/// Where a sample of a 3D-scene measure looks (`cell`: direction or pixel), in scene
/// coordinates (bent ones for bent scenes).
enum SceneAim {
    /// The ray through `point` coming from the sensor direction `view` (distant sensors).
    Through { point: DVec3, view: DVec3 },
    /// A ray from a camera at `origin` along `dir`.
    From { origin: DVec3, dir: DVec3 },
}

fn scene_aim(scene: &Scene, m: &Measure, cell: usize, rng: &mut Stream) -> SceneAim {
    // A point given by its altitude above local (x, y), in scene coordinates.
    let place = |p: DVec3| scene.curvature.map_or(p, |c| c.bend(p));
    match &m.kind {
        MeasureKind::Distant {
            directions, area, ..
        } => {
            let a = area.as_ref().expect("3D distant measures have an area");
            let draw = |rng: &mut Stream| {
                let (u1, u2) = (rng.next_f64(), rng.next_f64());
                DVec3::new(
                    a.rect[0] + u1 * (a.rect[2] - a.rect[0]),
                    a.rect[1] + u2 * (a.rect[3] - a.rect[1]),
                    a.height,
                )
            };
            let mut q = draw(rng);
            if let Some(m) = &a.mask {
                // Uniform in the rectangle's part inside the polygon: redraw outside points. At
                // least MIN_SHARE_INSIDE of the rectangle is inside (checked at resolve), so the
                // cap is reached with probability below e^-100.
                let cap = (100.0 / crate::measure::config::MIN_SHARE_INSIDE) as usize;
                for _ in 0..cap {
                    if m.contains(q.x, q.y) {
                        break;
                    }
                    q = draw(rng);
                }
            }
            SceneAim::Through {
                point: place(q),
                view: directions[cell],
            }
        }
        MeasureKind::Ortho(_) | MeasureKind::Perspective(_) => {
            let (u1, u2) = (rng.next_f64(), rng.next_f64());
            image_aim(scene, m, cell, u1, u2)
        }
        MeasureKind::Radiancemeter { origin, look, .. } => SceneAim::From {
            origin: scene.curvature.map_or(*origin, |c| c.bend(*origin)),
            dir: *look,
        },
        MeasureKind::DistantFlux { .. } | MeasureKind::Hdrf { .. } => unreachable!(
            "the resolver allows only distant, radiancemeter, ortho and perspective measures with a scene"
        ),
    }
}

/// The ray of an image measure through (`u1`, `u2`) ∈ [0, 1)² of pixel `cell`, as a ray
/// from far above (ortho: the first hit is the surface seen) or from the camera: origin and
/// unit direction, in scene coordinates. `None` for other measures.
pub fn image_ray(
    scene: &Scene,
    m: &Measure,
    cell: usize,
    u1: f64,
    u2: f64,
) -> Option<(DVec3, DVec3)> {
    if !m.is_image() {
        return None;
    }
    Some(match image_aim(scene, m, cell, u1, u2) {
        SceneAim::Through { point, view } => {
            let up = (scene.z_range[1] - point.z).max(0.0) + 1.0;
            (point + view * (up / view.z.max(1e-3)), -view)
        }
        SceneAim::From { origin, dir } => (origin, dir),
    })
}

fn image_aim(scene: &Scene, m: &Measure, cell: usize, u1: f64, u2: f64) -> SceneAim {
    let place = |p: DVec3| scene.curvature.map_or(p, |c| c.bend(p));
    match &m.kind {
        MeasureKind::Ortho(g) => {
            let (col, row) = (cell % g.width, cell / g.width);
            let x = g.geotransform[0] + (col as f64 + u1) * g.geotransform[1];
            let y = g.geotransform[3] + (row as f64 + u2) * g.geotransform[5];
            let point = match scene.ground_height(x, y) {
                Some(z) => DVec3::new(x, y, z),
                None => place(DVec3::new(x, y, scene.reference_height)),
            };
            SceneAim::Through {
                point,
                view: g.view,
            }
        }
        MeasureKind::Perspective(c) => {
            let (col, row) = (cell % c.width, cell / c.width);
            let x = (2.0 * (col as f64 + u1) / c.width as f64 - 1.0) * c.tan_x;
            let y = (2.0 * (row as f64 + u2) / c.height as f64 - 1.0) * c.tan_y;
            SceneAim::From {
                origin: place(c.origin),
                dir: (c.forward + c.right * x - c.up * y).normalize(),
            }
        }
        MeasureKind::Distant { .. }
        | MeasureKind::Radiancemeter { .. }
        | MeasureKind::DistantFlux { .. }
        | MeasureKind::Hdrf { .. } => unreachable!("image measures only"),
    }
}

/// Start point and direction of a sample of a 3D-scene measure in a plane-parallel atmosphere.
pub fn scene_start(
    ctx: &SceneInLayers,
    m: &Measure,
    cell: usize,
    rng: &mut Stream,
) -> (DVec3, DVec3) {
    match scene_aim(ctx.scene, m, cell, rng) {
        SceneAim::Through { point: q, view: v } => {
            // Started at the altitude that sees the whole scene and atmosphere.
            let z0 = ctx.start_altitude();
            (q + v * ((z0 - q.z) / v.z), -v)
        }
        SceneAim::From { origin, dir } => (origin, dir),
    }
}

/// Start point (planet frame), shell and direction of a sample of a 3D-scene measure in a
/// spherical shell; `None` when the line of sight misses the atmosphere.
pub fn scene_start_sph(
    ctx: &SceneInShells,
    m: &Measure,
    cell: usize,
    rng: &mut Stream,
) -> Option<(DVec3, usize, DVec3)> {
    let shell = ctx.shell;
    let lift = DVec3::new(0.0, 0.0, shell.planet_radius);
    let (p, d) = match scene_aim(ctx.scene, m, cell, rng) {
        SceneAim::Through { point, view } => {
            // Back from the aimed point to where its line of sight enters the top sphere.
            let q = point + lift;
            let r = shell.toa_radius();
            let b = q.dot(view);
            let c = (q.length() - r) * (q.length() + r);
            (q + view * (-b + (b * b - c).max(0.0).sqrt()), -view)
        }
        SceneAim::From { origin, dir } => (shell.entry_point(origin + lift, dir)?, dir),
    };
    let l = shell.shell_at(p.length()).min(shell.shell_count() - 1);
    Some((p, l, d))
}

/// The direction a backward path of a flux cell travels: cosine-distributed about the downward
/// vertical for upwelling flux (the path looks down), about the upward one for downwelling flux.
/// Its mean BRF-normalised radiance is then the flux divided by E0·cos SZA. The direct solar
/// beam is a delta no sampled direction meets: downwelling flux adds it in closed form
/// ([`crate::measure::direct_flux`]).
fn flux_path_direction(direction: FluxDirection, rng: &mut Stream) -> DVec3 {
    let up = sample_cosine_hemisphere(rng.next_f64(), rng.next_f64());
    match direction {
        FluxDirection::Up => -up,
        FluxDirection::Down => up,
    }
}

/// The path direction of cell `cell` of an HDRF measure: looking down against a view
/// direction, or (the last cell) a downwelling-flux path.
fn hdrf_path_direction(directions: &[DVec3], cell: usize, rng: &mut Stream) -> DVec3 {
    match directions.get(cell) {
        Some(v) => -*v,
        None => flux_path_direction(FluxDirection::Down, rng),
    }
}

/// Starting altitude and path direction of a backward sample (distant measures start at TOA).
pub fn backward_start_altitude(
    toa: f64,
    m: &Measure,
    cell: usize,
    rng: &mut Stream,
) -> (f64, DVec3) {
    match &m.kind {
        MeasureKind::Distant { directions, .. } => (toa, -directions[cell]),
        MeasureKind::Radiancemeter { origin, look, .. } => (origin.z, *look),
        MeasureKind::DistantFlux {
            altitude,
            direction,
        } => (*altitude, flux_path_direction(*direction, rng)),
        MeasureKind::Hdrf {
            directions,
            altitude,
            ..
        } => (*altitude, hdrf_path_direction(directions, cell, rng)),
        MeasureKind::Ortho(_) | MeasureKind::Perspective(_) => unreachable!("scene walk"),
    }
}

/// Starting optical depth and path direction of a backward sample.
pub fn backward_start(
    opt: &OpticalState,
    m: &Measure,
    cell: usize,
    rng: &mut Stream,
) -> (f64, DVec3) {
    let (z, d) = backward_start_altitude(opt.atmosphere.toa(), m, cell, rng);
    (opt.atmosphere.tau_at_altitude(z), d)
}
