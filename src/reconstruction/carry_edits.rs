//! What one refresh's carry did to the accumulators, listed for a GPU that kept the
//! sums of its last refresh: with the list it carries them itself (`gpu/carry.wgsl`),
//! and the sums need not come up from the CPU again. The list is short where the view
//! holds: a factor per tile, the pixels whose sums moved with moving surfaces, and
//! the pixels new samples cut; a view that moved, or sums started afresh, are not
//! listed (the whole sums go up then).

/// The carry of one refresh, as the GPU replays it: the decay, then the takes and
/// landings of the moving pixels' sums, then the cuts (the CPU's order).
#[derive(Clone, Debug, Default, PartialEq)]
pub(super) struct CarryEdits {
    /// Whether the list is all the carry did: the sums decayed in place from the
    /// previous refresh's.
    pub(super) complete: bool,
    /// Seconds since the previous refresh (the weighted age grows by it).
    pub(super) dt: f32,
    /// Per tile of this refresh: the decay of the sums and of the coverage.
    pub(super) decay: Vec<[f32; 2]>,
    /// Pixels whose sums were taken out to move, in order.
    pub(super) takes: Vec<u32>,
    /// Where taken sums landed, in order: the index into `takes`, the pixel, and
    /// whether they were added to what it held (else they replaced it).
    pub(super) lands: Vec<(u32, u32, bool)>,
    /// Pixels emptied because a new sample came in front (in any order; a pixel may
    /// be listed more than once).
    pub(super) cuts: Vec<u32>,
    /// Pixels whose geometry new samples set, in any order, each with its front
    /// depth after this carry (infinite: none). Not replayed (the GPU keeps no
    /// geometry): with the takes, landings and cuts, they are where the carried front
    /// depths may have changed ([`super::gpu::carried`]); found where the cut has the
    /// pixel at hand, their fronts cost no second visit.
    pub(super) settled: Vec<(u32, f32)>,
}

impl CarryEdits {
    /// Nothing listed, and not complete (until a carry in place says so).
    pub(super) fn clear(&mut self) {
        self.complete = false;
        self.dt = 0.0;
        self.decay.clear();
        self.takes.clear();
        self.lands.clear();
        self.cuts.clear();
        self.settled.clear();
    }

    /// The takes, the landings (three words each) and the cuts, one after another:
    /// the GPU's edit list.
    #[cfg_attr(not(feature = "gpu"), allow(dead_code))]
    pub(super) fn words(&self, out: &mut Vec<u32>) {
        out.clear();
        out.extend_from_slice(&self.takes);
        for &(i, q, merge) in &self.lands {
            out.extend_from_slice(&[i, q, merge as u32]);
        }
        out.extend_from_slice(&self.cuts);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_words_list_takes_then_landings_then_cuts() {
        let e = CarryEdits {
            complete: true,
            dt: 0.5,
            decay: vec![[0.5, 0.9]],
            takes: vec![7, 9],
            lands: vec![(1, 3, true), (0, 4, false)],
            cuts: vec![2],
            settled: vec![(5, 1.5)],
        };
        let mut w = vec![99];
        e.words(&mut w);
        assert_eq!(w, [7, 9, 1, 3, 1, 0, 4, 0, 2]);
        let mut c = e.clone();
        c.clear();
        assert_eq!(c, CarryEdits::default());
    }
}
