//! The sampler's temporally deep buffer: per pixel a queue of the `b` newest crosshairs.

use glam::Vec3;

use crate::reconstruction::{prefetch, prefetch_addr};

/// Five co-temporal samples: a center at sub-pixel `(x, y)` and its neighbours one pixel
/// away in ±x and ±y, with the gradients they measure.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Crosshair {
    /// Current sub-pixel position of the center (moves when reprojected).
    pub x: f32,
    /// Current sub-pixel position of the center.
    pub y: f32,
    /// Time the samples were traced.
    pub t: f64,
    /// Luminances: center, +x, −x, +y, −y.
    pub lum: [f32; 5],
    /// World-space hit points, same order.
    pub p: [Vec3; 5],
    /// World-space velocity of the center's hit point.
    pub velocity: Vec3,
    /// Spatial gradient in x (mean absolute luminance difference per pixel).
    pub gx: f32,
    /// Spatial gradient in y.
    pub gy: f32,
    /// Temporal gradient (luminance per second).
    pub gt: f32,
}

/// Per-pixel queues of crosshairs, newest first.
pub struct DeepBuffer {
    width: u32,
    depth: usize,
    slots: Vec<Crosshair>,
    len: Vec<u8>,
    head: Vec<u8>,
    total: usize,
}

impl DeepBuffer {
    /// Bytes a `width × height` buffer of `depth` crosshairs per pixel takes.
    pub fn bytes(width: u32, height: u32, depth: usize) -> u64 {
        let n = width as u64 * height as u64;
        n * depth as u64 * std::mem::size_of::<Crosshair>() as u64 + 2 * n
    }

    /// Check that a buffer for a `width × height` display of `depth` crosshairs per pixel
    /// fits the run budgets ([`crate::limits`]) before it is allocated.
    pub fn check_budget(
        width: u32,
        height: u32,
        depth: usize,
    ) -> Result<(), crate::limits::LimitError> {
        crate::limits::check_display(width, height)?;
        crate::limits::check_buffer(
            "adaptive sampler's deep buffer",
            Self::bytes(width, height, depth),
            &format!("{width}x{height} pixels × {depth} crosshairs"),
        )
    }

    /// An empty buffer for a `width × height` image, `depth` crosshairs per pixel.
    pub fn new(width: u32, height: u32, depth: usize) -> Self {
        let n = (width * height) as usize;
        Self {
            width,
            depth,
            slots: vec![Crosshair::default(); n * depth],
            len: vec![0; n],
            head: vec![0; n],
            total: 0,
        }
    }

    /// Crosshairs per pixel at most.
    pub fn depth(&self) -> usize {
        self.depth
    }

    /// Crosshairs stored in all.
    pub fn total(&self) -> usize {
        self.total
    }

    #[inline]
    fn index(&self, x: u32, y: u32) -> usize {
        (y * self.width + x) as usize
    }

    /// Number of crosshairs at pixel `(x, y)`.
    #[inline]
    pub fn len_at(&self, x: u32, y: u32) -> usize {
        self.len[self.index(x, y)] as usize
    }

    #[inline]
    fn slot(&self, p: usize, k: usize) -> usize {
        p * self.depth + (self.head[p] as usize + k) % self.depth
    }

    /// The crosshairs at a pixel, newest first.
    pub fn iter_at(&self, x: u32, y: u32) -> impl Iterator<Item = &Crosshair> + '_ {
        let p = self.index(x, y);
        (0..self.len[p] as usize).map(move |k| &self.slots[self.slot(p, k)])
    }

    /// The newest crosshair at a pixel.
    pub fn newest(&self, x: u32, y: u32) -> Option<&Crosshair> {
        self.iter_at(x, y).next()
    }

    /// Insert as the newest; returns the oldest if it had to make room.
    pub fn push_front(&mut self, x: u32, y: u32, c: Crosshair) -> Option<Crosshair> {
        let p = self.index(x, y);
        let d = self.depth;
        let mut evicted = None;
        if self.len[p] as usize == d {
            evicted = Some(self.slots[self.slot(p, d - 1)]);
            self.len[p] -= 1;
            self.total -= 1;
        }
        self.head[p] = ((self.head[p] as usize + d - 1) % d) as u8;
        let s = self.slot(p, 0);
        self.slots[s] = c;
        self.len[p] += 1;
        self.total += 1;
        evicted
    }

    /// Ask the cache for pixel `(x, y)`'s queue length and head: the first of two steps
    /// ahead of a [`DeepBuffer::push_front`] there.
    #[inline]
    pub fn prefetch_queue(&self, x: u32, y: u32) {
        let p = self.index(x, y);
        prefetch(&self.len, p);
        prefetch(&self.head, p);
    }

    /// Ask the cache for the slot a [`DeepBuffer::push_front`] at `(x, y)` writes (and,
    /// with the queue full, evicts from): the second step, once the head is at hand.
    #[inline]
    pub fn prefetch_front_slot(&self, x: u32, y: u32) {
        let p = self.index(x, y);
        if p >= self.head.len() {
            return;
        }
        // The new front goes where the back is now: `push_front` moves the head back one.
        let Some(slot) = self.slots.get(self.slot(p, self.depth - 1)) else {
            return;
        };
        // A slot spans two or three cache lines: ask for its first and last bytes.
        let first = (slot as *const Crosshair).cast::<u8>();
        prefetch_addr(first);
        prefetch_addr(first.wrapping_add(std::mem::size_of::<Crosshair>() - 1));
    }

    /// Insert as the oldest if there is room; returns the crosshair back if not.
    pub fn push_back(&mut self, x: u32, y: u32, c: Crosshair) -> Result<(), Crosshair> {
        let p = self.index(x, y);
        if self.len[p] as usize == self.depth {
            return Err(c);
        }
        let s = self.slot(p, self.len[p] as usize);
        self.slots[s] = c;
        self.len[p] += 1;
        self.total += 1;
        Ok(())
    }

    /// Remove and return the oldest crosshair at a pixel.
    pub fn pop_back(&mut self, x: u32, y: u32) -> Option<Crosshair> {
        let p = self.index(x, y);
        if self.len[p] == 0 {
            return None;
        }
        let s = self.slot(p, self.len[p] as usize - 1);
        self.len[p] -= 1;
        self.total -= 1;
        Some(self.slots[s])
    }

    /// Remove and return the newest crosshair at a pixel.
    pub fn pop_front(&mut self, x: u32, y: u32) -> Option<Crosshair> {
        let p = self.index(x, y);
        if self.len[p] == 0 {
            return None;
        }
        let s = self.slot(p, 0);
        self.head[p] = ((self.head[p] as usize + 1) % self.depth) as u8;
        self.len[p] -= 1;
        self.total -= 1;
        Some(self.slots[s])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn c(t: f64) -> Crosshair {
        Crosshair {
            t,
            ..Default::default()
        }
    }

    #[test]
    fn prefetches_leave_the_queues_alone() {
        let mut b = DeepBuffer::new(3, 2, 2);
        for k in 0..5 {
            b.push_front(2, 1, c(k as f64));
        }
        for (x, y) in [(0, 0), (2, 1), (1, 1)] {
            b.prefetch_queue(x, y);
            b.prefetch_front_slot(x, y);
        }
        let ts: Vec<f64> = b.iter_at(2, 1).map(|c| c.t).collect();
        assert_eq!(ts, vec![4.0, 3.0]);
        assert_eq!(b.total(), 2);
    }

    #[test]
    fn queue_semantics() {
        let mut b = DeepBuffer::new(2, 2, 3);
        assert!(b.push_front(1, 1, c(1.0)).is_none());
        assert!(b.push_front(1, 1, c(2.0)).is_none());
        assert!(b.push_front(1, 1, c(3.0)).is_none());
        // Full: the oldest (t = 1) is evicted.
        assert_eq!(b.push_front(1, 1, c(4.0)).unwrap().t, 1.0);
        let ts: Vec<f64> = b.iter_at(1, 1).map(|c| c.t).collect();
        assert_eq!(ts, vec![4.0, 3.0, 2.0]);
        assert!(b.push_back(1, 1, c(0.5)).is_err());
        assert_eq!(b.pop_front(1, 1).unwrap().t, 4.0);
        assert!(b.push_back(1, 1, c(0.5)).is_ok());
        let ts: Vec<f64> = b.iter_at(1, 1).map(|c| c.t).collect();
        assert_eq!(ts, vec![3.0, 2.0, 0.5]);
        assert_eq!(b.pop_back(1, 1).unwrap().t, 0.5);
        assert_eq!(b.total(), 2);
        assert_eq!(b.len_at(0, 0), 0);
        assert!(b.newest(0, 0).is_none());
    }
}
