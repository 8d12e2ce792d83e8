//! The results of one lidar measure (traced by the application's run driver, written by its
//! products): the shots' waveforms, photon-counting statistics and events, discrete returns.

use super::counting::{CountingStats, PhotonEvent};
use super::discrete::Return;
use super::trace::ShotWaveform;
use super::Lidar;
use crate::scene::world::Georef;

/// One lidar measure's results.
#[derive(Clone, Debug)]
pub struct LidarResult {
    pub lidar: Lidar,
    pub shots: Vec<ShotWaveform>,
    /// Photon counting: per shot location.
    pub counting: Vec<CountingStats>,
    pub events: Vec<PhotonEvent>,
    /// Discrete mode: the returns of each shot's waveform, each with its LAS class.
    pub returns: Vec<Vec<(Return, u8)>>,
    /// The working CRS (WKT) and the coordinates of the scene's local origin in it, for the
    /// point cloud (none for 1D runs: local coordinates).
    pub georef: Option<Georef>,
}
