//! Heavy-tail warnings: a standard error cannot be trusted when a few walks carry much of the
//! estimate (peaked phase functions seen through a local estimate, glints, starved runs). For
//! every (measure, wavelength) this checks each cell with at least
//! [`TAIL_MIN_SAMPLES`](engine::accum::TAIL_MIN_SAMPLES) samples: the relative variance of its
//! variance estimate (VOV, [`Accum::tail`](engine::accum::Accum::tail)) must stay below
//! [`VOV_LIMIT`] (MCNP's statistical check, X-5 Monte Carlo Team 2003). Cells with fewer samples
//! (image pixels at a few hundred samples) are not judged.
//!
//! The warning names the measure, the wavelength, how many cells failed, the worst VOV and the
//! largest single-walk share of the sum there.

use engine::accum::{MeasureResult, VOV_LIMIT};
use engine::config::Experiment;

/// One (measure, wavelength) whose standard errors cannot be trusted.
#[derive(Clone, Debug, PartialEq)]
pub struct HeavyTail {
    pub measure: String,
    pub wavelength_nm: f64,
    /// Cells over the limit, and cells judged.
    pub failed: usize,
    pub judged: usize,
    /// The worst cell's index, VOV and largest single-walk share.
    pub worst_cell: usize,
    pub vov: f64,
    pub max_share: f64,
}

impl std::fmt::Display for HeavyTail {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "measure \"{}\" at {} nm: the standard error cannot be trusted in {} of {} cells \
             (heavy-tailed samples: worst cell {} has a relative variance of the variance of {:.3} > {VOV_LIMIT}, \
             and its largest single walk is {:.1} % of its sum); run more samples or use a \
             variance-reduction option",
            self.measure,
            self.wavelength_nm,
            self.failed,
            self.judged,
            self.worst_cell,
            self.vov,
            100.0 * self.max_share
        )
    }
}

/// The (measure, wavelength) pairs of `results` that fail the check.
pub fn check<'a>(
    exp: &Experiment,
    results: impl IntoIterator<Item = &'a MeasureResult>,
) -> Vec<HeavyTail> {
    let mut out = Vec::new();
    for r in results {
        let acc = &r.acc;
        let (mut failed, mut judged) = (0, 0);
        let mut worst: Option<(usize, engine::accum::Tail)> = None;
        for c in 0..acc.n.len() {
            let Some(t) = acc.tail(c) else { continue };
            judged += 1;
            if !t.trusted() {
                failed += 1;
            }
            if worst.is_none_or(|(_, w)| t.vov > w.vov) {
                worst = Some((c, t));
            }
        }
        if let Some((c, t)) = worst.filter(|_| failed > 0) {
            out.push(HeavyTail {
                measure: exp.measures[r.measure].id.clone(),
                wavelength_nm: exp.wavelengths[r.wavelength],
                failed,
                judged,
                worst_cell: c,
                vov: t.vov,
                max_share: t.max_share,
            });
        }
    }
    out
}

/// [`check`], each failure logged as a warning.
pub fn warn<'a>(exp: &Experiment, results: impl IntoIterator<Item = &'a MeasureResult>) {
    for h in check(exp, results) {
        tracing::warn!("{h}");
    }
}
