//! Spectral bookkeeping shared by the resolver and the run driver: which wavelengths one walk
//! serves together (spectral ALIS groups).

/// The wavelength groups of a wavelength list and group size (None: one wavelength each).
pub fn wavelength_groups_of(wavelengths: &[f64], group: Option<usize>) -> Vec<Vec<usize>> {
    match group {
        None => (0..wavelengths.len()).map(|iw| vec![iw]).collect(),
        Some(n) => {
            let mut order: Vec<usize> = (0..wavelengths.len()).collect();
            order.sort_by(|&a, &b| wavelengths[a].total_cmp(&wavelengths[b]).then(a.cmp(&b)));
            order.chunks(n.max(1)).map(|c| c.to_vec()).collect()
        }
    }
}
