//! Fixed-window latency statistics (no allocation after construction).

/// A ring of the last `N` samples with percentile queries.
#[derive(Debug, Clone)]
pub struct LatencyWindow {
    samples: Vec<f64>,
    scratch: Vec<f64>,
    next: usize,
    filled: usize,
    total: u64,
}

impl LatencyWindow {
    /// A window of `capacity` samples (at least 1).
    pub fn new(capacity: usize) -> Self {
        let capacity = capacity.max(1);
        Self {
            samples: vec![0.0; capacity],
            scratch: Vec::with_capacity(capacity),
            next: 0,
            filled: 0,
            total: 0,
        }
    }

    /// Record one sample.
    pub fn push(&mut self, v: f64) {
        self.samples[self.next] = v;
        self.next = (self.next + 1) % self.samples.len();
        self.filled = (self.filled + 1).min(self.samples.len());
        self.total += 1;
    }

    /// Samples recorded since creation.
    pub fn total(&self) -> u64 {
        self.total
    }

    /// Samples currently in the window.
    pub fn len(&self) -> usize {
        self.filled
    }

    /// `true` when no sample was recorded.
    pub fn is_empty(&self) -> bool {
        self.filled == 0
    }

    /// Percentiles `ps` (each in [0, 100]) of the window, nearest-rank; `None` when empty.
    pub fn percentiles<const K: usize>(&mut self, ps: [f64; K]) -> Option<[f64; K]> {
        if self.filled == 0 {
            return None;
        }
        self.scratch.clear();
        self.scratch.extend_from_slice(&self.samples[..self.filled]);
        self.scratch.sort_by(|a, b| a.total_cmp(b));
        let n = self.scratch.len();
        Some(ps.map(|p| {
            let rank = ((p / 100.0) * n as f64).ceil() as usize;
            self.scratch[rank.clamp(1, n) - 1]
        }))
    }

    /// Mean of the window; `None` when empty.
    pub fn mean(&self) -> Option<f64> {
        (self.filled > 0)
            .then(|| self.samples[..self.filled].iter().sum::<f64>() / self.filled as f64)
    }
}

/// Nearest-rank percentile of an unsorted slice (sorts a copy); `None` when empty.
pub fn percentile(values: &[f64], p: f64) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let mut v = values.to_vec();
    v.sort_by(|a, b| a.total_cmp(b));
    let rank = ((p / 100.0) * v.len() as f64).ceil() as usize;
    Some(v[rank.clamp(1, v.len()) - 1])
}

/// Mean and population standard deviation; `None` when empty.
pub fn mean_std(values: &[f64]) -> Option<(f64, f64)> {
    if values.is_empty() {
        return None;
    }
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n;
    Some((mean, var.sqrt()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn window_percentiles_are_nearest_rank() {
        let mut w = LatencyWindow::new(4);
        assert!(w.percentiles([50.0]).is_none());
        for v in [5.0, 1.0, 3.0, 2.0, 4.0] {
            w.push(v); // 5.0 falls out of the window
        }
        assert_eq!(w.len(), 4);
        assert_eq!(w.percentiles([50.0, 100.0]), Some([2.0, 4.0]));
        assert_eq!(w.mean(), Some(2.5));
        assert_eq!(percentile(&[3.0, 1.0, 2.0], 95.0), Some(3.0));
        assert_eq!(mean_std(&[1.0, 3.0]), Some((2.0, 1.0)));
    }
}
