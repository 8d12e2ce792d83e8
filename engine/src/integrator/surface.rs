//! The surface a path meets, seen by the estimators: one type for the flat lower boundary of 1D
//! atmospheres (a [`Bsdf`] in the frame of the local vertical) and the materials of 3D scenes (a
//! [`SurfaceModel`] at a hit with normal `n`).
//!
//! Directions are world unit vectors: `wo` towards the viewer (the side the path arrives from),
//! `wi` towards the light. Random numbers: a flat surface draws two per bounce, a scene material
//! three (leaves choose their side with the third), as the walks always did.

use std::borrow::Cow;

use glam::DVec3;

use crate::bsdf::Bsdf;
use crate::frame::Frame;
use crate::rng::Stream;
use crate::scene::material::{SurfaceModel, SurfaceSample};
use crate::stokes::PhaseMatrix;

/// A surface at a path vertex.
pub enum SurfaceAt<'a> {
    /// The lower boundary of a 1D atmosphere; `frame` None: the world frame is the local one
    /// (plane-parallel), else the frame of the local vertical (spherical shells).
    Flat {
        bsdf: &'a Bsdf,
        frame: Option<Frame>,
    },
    /// A scene material at a hit whose normal `n` faces the arriving path.
    Scene {
        model: Cow<'a, SurfaceModel>,
        n: DVec3,
    },
    /// A perfect mirror with the Fresnel reflectance of the complex index `n + ik` (the
    /// `mirror` solver, `solver.rs`): a delta BRDF, so `eval_cos` is 0 and `sample` returns the
    /// mirror direction with weight `R(θ)`.
    Mirror { n: DVec3, index: (f64, f64) },
    /// `base` with one fixed sample (the `classic` solver's quadrature nodes): `sample` returns
    /// it and draws no random number; everything else is `base`'s.
    Forced {
        base: &'a SurfaceAt<'a>,
        sample: SurfaceSample,
    },
}

impl SurfaceAt<'_> {
    /// `f(wi, wo)·cos θ_i` (0 for light from below the surface; leaves: either side).
    #[inline]
    pub fn eval_cos(&self, wi: DVec3, wo: DVec3) -> f64 {
        match self {
            SurfaceAt::Flat { bsdf, frame: None } => {
                if wi.z <= 0.0 {
                    return 0.0;
                }
                bsdf.eval(wi, wo) * wi.z
            }
            SurfaceAt::Flat {
                bsdf,
                frame: Some(f),
            } => {
                let ci = wi.dot(f.n);
                if ci <= 0.0 {
                    return 0.0;
                }
                bsdf.eval(f.local(wi), f.local(wo)) * ci
            }
            SurfaceAt::Scene { model, n } => model.eval_cos(*n, wi, wo),
            SurfaceAt::Mirror { .. } => 0.0,
            SurfaceAt::Forced { base, .. } => base.eval_cos(wi, wo),
        }
    }

    /// The unit normal on the side paths arrive from.
    #[inline]
    pub fn normal(&self) -> DVec3 {
        match self {
            SurfaceAt::Flat { frame: None, .. } => DVec3::Z,
            SurfaceAt::Flat { frame: Some(f), .. } => f.n,
            SurfaceAt::Scene { n, .. } | SurfaceAt::Mirror { n, .. } => *n,
            SurfaceAt::Forced { base, .. } => base.normal(),
        }
    }

    /// The reflection matrix of a polarizing surface (ocean) in the scattering-plane frame of
    /// light going from `−wi` to `wo`, times nothing (its `a1` is the BRDF); `None` for
    /// depolarizing surfaces.
    #[inline]
    pub fn matrix(&self, wi: DVec3, wo: DVec3) -> Option<PhaseMatrix> {
        match self {
            SurfaceAt::Flat { bsdf, frame: None } => bsdf.matrix(wi, wo),
            SurfaceAt::Flat {
                bsdf,
                frame: Some(f),
            } => bsdf.matrix(f.local(wi), f.local(wo)),
            SurfaceAt::Scene { model, n } => match model.as_ref() {
                SurfaceModel::Opaque(b @ Bsdf::Ocean(_)) => {
                    let f = Frame::around(*n);
                    b.matrix(f.local(wi), f.local(wo))
                }
                _ => None,
            },
            SurfaceAt::Mirror { n, index } => Some(super::solver::fresnel_matrix(
                index.0,
                index.1,
                wi.dot(*n).abs(),
            )),
            SurfaceAt::Forced { base, .. } => base.matrix(wi, wo),
        }
    }

    /// The cosine of `wi` with the surface normal (the factor [`SurfaceAt::matrix`] lacks).
    #[inline]
    pub fn cos(&self, wi: DVec3) -> f64 {
        match self {
            SurfaceAt::Flat { frame: None, .. } => wi.z,
            SurfaceAt::Flat { frame: Some(f), .. } => wi.dot(f.n),
            SurfaceAt::Scene { n, .. } | SurfaceAt::Mirror { n, .. } => wi.dot(*n),
            SurfaceAt::Forced { base, .. } => base.cos(wi),
        }
    }

    /// Draw the next direction towards the light given `wo`; `None` when the surface absorbs
    /// (a scene material's weight is 0, or a flat surface drew a direction below its horizon,
    /// pdf 0). A flat surface may return weight 0 with a valid direction (reflectance 0): ALIS
    /// walks still weigh that direction for their other channels.
    #[inline]
    pub fn sample(&self, wo: DVec3, rng: &mut Stream) -> Option<SurfaceSample> {
        let u = match self {
            SurfaceAt::Flat { .. } => [rng.next_f64(), rng.next_f64(), 0.0],
            SurfaceAt::Scene { .. } => [rng.next_f64(), rng.next_f64(), rng.next_f64()],
            SurfaceAt::Mirror { .. } | SurfaceAt::Forced { .. } => [0.0; 3],
        };
        self.sample_at(wo, u)
    }

    /// [`SurfaceAt::sample`] from the given uniform numbers `u` in [0, 1): a flat surface uses
    /// the first two, a scene material all three, a mirror or a forced sample none. The
    /// `generic` solver's fan stratifies the first two (`backward.rs`).
    #[inline]
    pub fn sample_at(&self, wo: DVec3, u: [f64; 3]) -> Option<SurfaceSample> {
        match self {
            SurfaceAt::Flat { bsdf, frame } => {
                let wo_l = frame.map_or(wo, |f| f.local(wo));
                let s = bsdf.sample(wo_l, u[0], u[1]);
                (s.pdf > 0.0).then(|| SurfaceSample {
                    wi: frame.map_or(s.wi, |f| f.world(s.wi)),
                    weight: s.weight,
                    pdf: s.pdf,
                })
            }
            SurfaceAt::Scene { model, n } => model.sample(*n, wo, u),
            SurfaceAt::Mirror { n, index } => {
                let c = wo.dot(*n);
                (c > 0.0).then(|| SurfaceSample {
                    wi: super::solver::mirror(-wo, *n),
                    weight: super::solver::fresnel_reflectance(index.0, index.1, c),
                    pdf: 1.0,
                })
            }
            SurfaceAt::Forced { sample, .. } => Some(*sample),
        }
    }
}
