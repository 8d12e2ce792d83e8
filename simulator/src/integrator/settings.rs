//! Settings of the transport core that the resolver fills from `[integrator]` (the raw keys
//! are in `config/mod.rs`; their meanings in `docs/experiment.md`).

/// Which walk serves the measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IntegratorKind {
    /// Forward for `mdistant` and `distant_flux`, backward for `radiancemeter`.
    Auto,
    /// Photons from the Sun with local estimates towards every direction (1D distant measures).
    Forward,
    /// Paths from the sensor with next-event estimation towards the Sun.
    Backward,
}

#[derive(Clone, Debug)]
pub struct IntegratorSettings {
    pub kind: IntegratorKind,
    /// Maximum scattering order counted (u32::MAX: unlimited).
    pub max_depth: u32,
    pub rr_depth: u32,
    /// Score the expected local estimate along each flight (true) or at sampled collisions.
    pub expected_local_estimate: bool,
    /// CKD runs: one backward walk for all g-points of a bin (`integrator/backward_alis.rs`).
    pub alis: bool,
    /// Monochromatic runs with `spectral_walk = "alis"`: the wavelengths per group (one backward
    /// walk serves a group, `integrator/backward_alis.rs`); None: independent walks.
    pub spectral_alis: Option<usize>,
    /// Samples before the first precision check (None: 4 blocks).
    pub first_check_spp: Option<u64>,
}
