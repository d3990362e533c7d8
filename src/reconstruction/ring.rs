//! The reconstructor's deep buffer: the `N` most recent samples in push order, stored
//! as a struct of arrays.
//!
//! A refresh reads every live sample's hit point, velocity and time to reproject it,
//! and the color of only those that pass the temporal cull (about a third on the
//! bench fixture). One array per field lets the reprojection read dense lanes in
//! vector code, and a culled sample costs no load of its color; a ring of 56-byte
//! structs made every sample cost a whole cache line's worth of scattered fields.
//!
//! The ring also keeps the running largest time at the end of every block of 256
//! pushes, so that the prefix of samples too old to count anywhere is found by binary
//! search (`Ring::live_start`).

use std::collections::VecDeque;

use glam::Vec3;

use super::RingSample;
use crate::trace::Anchor;

/// Pushes per block of the ring's running largest time (see [`Ring::live_start`]).
pub(crate) const TIME_BLOCK: u64 = 256;

/// Samples per run of [`Ring::extend`]: a run's samples stay in the first-level cache
/// while each of their fields is written.
pub(super) const EXTEND_CHUNK: usize = 256;

/// Field indices of [`Ring::f`].
pub(crate) mod field {
    /// Sub-pixel position where the sample was traced.
    pub const X: usize = 0;
    pub const Y: usize = 1;
    /// Color.
    pub const R: usize = 2;
    pub const G: usize = 3;
    pub const B: usize = 4;
    /// Hit point.
    pub const HX: usize = 5;
    pub const HY: usize = 6;
    pub const HZ: usize = 7;
    /// Velocity of the hit point.
    pub const VX: usize = 8;
    pub const VY: usize = 9;
    pub const VZ: usize = 10;
    /// Number of f32 fields.
    pub const COUNT: usize = 11;

    /// The f32 fields of `s`, by index.
    pub(super) fn of(s: &super::RingSample) -> [f32; COUNT] {
        let mut v = [0f32; COUNT];
        v[X] = s.x;
        v[Y] = s.y;
        [v[R], v[G], v[B]] = s.color.to_array();
        [v[HX], v[HY], v[HZ]] = s.hit_point.to_array();
        [v[VX], v[VY], v[VZ]] = s.velocity.to_array();
        v
    }
}

/// A fixed-capacity ring of samples, oldest first (see the module doc).
#[derive(Clone, Debug)]
pub struct Ring {
    capacity: usize,
    /// Samples held.
    len: usize,
    /// The f32 fields, indexed by [`field`] and then by physical index (each
    /// `capacity` long from the start: zeroed allocations cost no memory until
    /// written, and a push is then only stores).
    pub(crate) f: [Vec<f32>; field::COUNT],
    /// Times, by physical index.
    pub(crate) t: Vec<f64>,
    /// The samples fixed to moving things, oldest first: `(push index, anchor)` (the
    /// static world's samples, usually most, take no room here).
    pub(crate) moving: VecDeque<(u64, Anchor)>,
    /// Physical index of the oldest sample (0 until the ring is full).
    head: usize,
    /// Samples ever pushed.
    pub(crate) pushed: u64,
    /// Largest time pushed so far (NaN counts as +∞).
    max_t: f64,
    /// `max_t` at the end of each block of `TIME_BLOCK` pushes, from block
    /// `first_block` on (the last entry is for the block being filled): non-decreasing
    /// whatever the order samples come in, so the stale prefix of the ring is found by
    /// binary search even when several sampling threads interleave their batches.
    pub(crate) block_max_t: VecDeque<f64>,
    pub(crate) first_block: u64,
}

impl Ring {
    /// An empty ring holding at most `capacity` (at least 1) samples.
    pub fn new(capacity: usize) -> Self {
        let capacity = capacity.max(1);
        Self {
            capacity,
            len: 0,
            f: std::array::from_fn(|_| vec![0.0; capacity]),
            t: vec![0.0; capacity],
            moving: VecDeque::new(),
            head: 0,
            pushed: 0,
            max_t: f64::NEG_INFINITY,
            block_max_t: VecDeque::new(),
            first_block: 0,
        }
    }

    /// Back every field with memory now (see [`super::Reconstructor::prepare`]).
    pub(crate) fn prepare(&mut self) {
        self.f.iter_mut().for_each(|f| super::lanes::touch(f));
        super::lanes::touch(&mut self.t);
    }

    /// Most samples held.
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// Samples held.
    pub fn len(&self) -> usize {
        self.len
    }

    /// The time of the newest sample ever pushed (`−∞` before any, `+∞` after a NaN
    /// time).
    pub(crate) fn newest_time(&self) -> f64 {
        self.max_t
    }

    /// No sample held.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Physical index of logical index `i` (0 = oldest; `len`: the next slot).
    #[inline]
    pub(crate) fn phys(&self, i: usize) -> usize {
        let p = self.head + i;
        if p >= self.capacity {
            p - self.capacity
        } else {
            p
        }
    }

    /// The sample at physical index `p`.
    #[inline]
    pub(crate) fn at(&self, p: usize) -> RingSample {
        use field::*;
        let f = |k: usize| self.f[k][p];
        RingSample {
            x: f(X),
            y: f(Y),
            t: self.t[p],
            color: Vec3::new(f(R), f(G), f(B)),
            hit_point: Vec3::new(f(HX), f(HY), f(HZ)),
            velocity: Vec3::new(f(VX), f(VY), f(VZ)),
            anchor: self.anchor_at(p),
        }
    }

    /// Push index of the sample at logical index `i`.
    pub(crate) fn push_index(&self, i: usize) -> u64 {
        self.pushed - self.len as u64 + i as u64
    }

    /// The velocity of the `i`-th oldest sample's hit.
    pub(crate) fn velocity_of(&self, i: usize) -> Vec3 {
        use field::*;
        let p = self.phys(i);
        Vec3::new(self.f[VX][p], self.f[VY][p], self.f[VZ][p])
    }

    /// What the `i`-th oldest sample is fixed to.
    pub(crate) fn anchor_of(&self, i: usize) -> Anchor {
        let k = self.push_index(i);
        match self.moving.binary_search_by_key(&k, |m| m.0) {
            Ok(j) => self.moving[j].1,
            Err(_) => Anchor::Still,
        }
    }

    /// What the sample at physical index `p` is fixed to.
    fn anchor_at(&self, p: usize) -> Anchor {
        self.anchor_of((p + self.capacity - self.head) % self.capacity)
    }

    /// The `i`-th oldest sample.
    pub fn get(&self, i: usize) -> Option<RingSample> {
        (i < self.len()).then(|| self.at(self.phys(i)))
    }

    /// The oldest sample.
    pub fn front(&self) -> Option<RingSample> {
        self.get(0)
    }

    /// The newest sample.
    pub fn back(&self) -> Option<RingSample> {
        self.len().checked_sub(1).and_then(|i| self.get(i))
    }

    /// The samples, oldest first.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = RingSample> + '_ {
        (0..self.len()).map(|i| self.at(self.phys(i)))
    }

    /// Append samples in order, as [`Ring::push`] each would: a run of them at a
    /// time, each field of the run written in one stream.
    pub fn extend(&mut self, ss: &[RingSample]) {
        let chunk = EXTEND_CHUNK.min(self.capacity);
        let mut fields = [[0f32; field::COUNT]; EXTEND_CHUNK];
        for part in ss.chunks(chunk) {
            for (v, s) in fields.iter_mut().zip(part) {
                *v = field::of(s);
            }
            let p0 = self.phys(self.len);
            let first = part.len().min(self.capacity - p0);
            for (p, j0, n) in [(p0, 0, first), (0, first, part.len() - first)] {
                let run = &fields[j0..j0 + n];
                for (k, f) in self.f.iter_mut().enumerate() {
                    for (d, v) in f[p..p + n].iter_mut().zip(run) {
                        *d = v[k];
                    }
                }
                for (d, s) in self.t[p..p + n].iter_mut().zip(&part[j0..j0 + n]) {
                    *d = s.t;
                }
            }
            for s in part {
                self.note(s);
            }
        }
    }

    /// Append a sample, dropping the oldest once the ring is full.
    pub fn push(&mut self, s: &RingSample) {
        // The slot after the newest: a free one until the ring is full, then the
        // oldest's.
        let p = self.phys(self.len);
        for (f, v) in self.f.iter_mut().zip(field::of(s)) {
            f[p] = v;
        }
        self.t[p] = s.t;
        self.note(s);
    }

    /// The bookkeeping of a push of `s`, whose fields are in the slot after the newest.
    fn note(&mut self, s: &RingSample) {
        // Written so that a NaN time also lands here.
        #[allow(clippy::neg_cmp_op_on_partial_ord)]
        if !(s.t <= self.max_t) {
            self.max_t = if s.t.is_nan() { f64::INFINITY } else { s.t };
        }
        let p = self.phys(self.len);
        if s.anchor != Anchor::Still {
            self.moving.push_back((self.pushed, s.anchor));
        }
        if self.len < self.capacity {
            self.len += 1;
        } else {
            self.head = if p + 1 == self.capacity { 0 } else { p + 1 };
            // The oldest sample is now the one after the overwritten one.
            let front = self.pushed + 1 - self.len() as u64;
            while self.moving.front().is_some_and(|m| m.0 < front) {
                self.moving.pop_front();
            }
            while (self.first_block + 1) * TIME_BLOCK <= front {
                self.block_max_t.pop_front();
                self.first_block += 1;
            }
        }
        let block = self.pushed / TIME_BLOCK;
        if block >= self.first_block + self.block_max_t.len() as u64 {
            self.block_max_t.push_back(self.max_t);
        } else if let Some(b) = self.block_max_t.back_mut() {
            *b = self.max_t;
        }
        self.pushed += 1;
    }

    /// Logical index from which samples may be as recent as `cutoff`: every sample
    /// before it was pushed in a block whose largest time so far is below `cutoff`.
    pub(crate) fn live_start(&self, cutoff: f64) -> usize {
        if !cutoff.is_finite() {
            return 0;
        }
        let j = self.block_max_t.partition_point(|&m| m < cutoff) as u64;
        let front = self.pushed - self.len() as u64;
        (((self.first_block + j) * TIME_BLOCK).saturating_sub(front) as usize).min(self.len())
    }

    /// The physical index ranges holding the logical range `start..len`, in ring order
    /// (the second is empty unless the range wraps).
    pub(crate) fn runs(&self, start: usize) -> [std::ops::Range<usize>; 2] {
        let n = self.len();
        let start = start.min(n);
        let p = self.phys(start);
        let live = n - start;
        let first = live.min(self.capacity - p);
        [p..p + first, 0..live - first]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(t: f64) -> RingSample {
        RingSample {
            x: t as f32,
            y: -t as f32,
            t,
            color: Vec3::new(1.0, 2.0, 3.0) * t as f32,
            hit_point: Vec3::new(4.0, 5.0, 6.0) * t as f32,
            velocity: Vec3::new(7.0, 8.0, 9.0) * t as f32,
            anchor: Default::default(),
        }
    }

    proptest::proptest! {
        /// Extending by a slice leaves the ring as pushing each sample does: its
        /// samples and anchors, its time blocks and its stale prefix, across the wrap
        /// and the runs of `extend`.
        #[test]
        fn extending_is_pushing_each(
            capacity in 1usize..700,
            before in 0usize..900,
            times in proptest::collection::vec(
                proptest::prop_oneof![8 => 0.0..50.0f64, 1 => proptest::strategy::Just(f64::NAN)],
                0..1200,
            ),
        ) {
            let anchored = |k: usize, t: f64| RingSample {
                anchor: if k % 5 == 1 {
                    Anchor::Instance { group: k as u32, local: Vec3::splat(t as f32) }
                } else {
                    Anchor::Still
                },
                ..sample(t)
            };
            let ss: Vec<RingSample> = times.iter().enumerate().map(|(k, &t)| anchored(k, t)).collect();
            let (mut pushed, mut extended) = (Ring::new(capacity), Ring::new(capacity));
            for k in 0..before {
                pushed.push(&anchored(k, k as f64 * 0.1));
                extended.push(&anchored(k, k as f64 * 0.1));
            }
            for s in &ss {
                pushed.push(s);
            }
            extended.extend(&ss);
            let same = |r: &Ring| {
                let samples: Vec<String> = r.iter().map(|s| format!("{s:?}")).collect();
                (samples, r.len, r.head, r.pushed, r.max_t.to_bits(), r.first_block,
                 r.block_max_t.iter().map(|m| m.to_bits()).collect::<Vec<_>>(),
                 format!("{:?}", r.moving))
            };
            proptest::prop_assert_eq!(same(&pushed), same(&extended));
            for cutoff in [0.0, 1.0, 25.0, 49.0, f64::INFINITY] {
                proptest::prop_assert_eq!(pushed.live_start(cutoff), extended.live_start(cutoff));
            }
        }
    }

    #[test]
    fn keeps_the_newest_in_order_and_runs_cover_the_live_range() {
        let mut r = Ring::new(7);
        for k in 0..40 {
            r.push(&sample(k as f64));
            let n = r.len();
            assert_eq!(n, (k + 1).min(7));
            let all: Vec<RingSample> = r.iter().collect();
            let want: Vec<RingSample> = (k + 1 - n..=k).map(|i| sample(i as f64)).collect();
            assert_eq!(all, want);
            assert_eq!(r.front(), want.first().copied());
            assert_eq!(r.back(), want.last().copied());
            for start in 0..=n {
                let got: Vec<RingSample> = r
                    .runs(start)
                    .into_iter()
                    .flat_map(|run| run.map(|p| r.at(p)))
                    .collect();
                assert_eq!(got, want[start..], "push {k}, start {start}");
            }
        }
    }
}
