//! Per-pixel exclusion between sampling threads: a thread that finds a pixel taken
//! samples a different one, as the OptiX adaptive frameless renderer does.
//!
//! One `AtomicBool` per pixel; taking a pixel is a `compare_exchange(false → true)`,
//! so it never blocks: a thread that loses the race gets `None` and picks other work.
//! Guards release on drop, so a panic in a sampling thread cannot leave a pixel held.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

/// Exclusion flags for a `width × height` image.
pub struct PixelLocks {
    flags: Vec<AtomicBool>,
    width: u32,
    height: u32,
    conflicts: AtomicU64,
}

/// Pixels held by one thread until dropped (at most five: a crosshair).
pub struct PixelGuard<'a> {
    locks: &'a PixelLocks,
    held: [u32; 5],
    n: usize,
}

impl PixelLocks {
    /// All pixels free.
    pub fn new(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        Self {
            flags: (0..n).map(|_| AtomicBool::new(false)).collect(),
            width,
            height,
            conflicts: AtomicU64::new(0),
        }
    }

    /// Image size.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Attempts that found a pixel taken, so far.
    pub fn conflicts(&self) -> u64 {
        self.conflicts.load(Ordering::Relaxed)
    }

    /// Take one pixel, or `None` if another thread holds it (or it is off-image).
    pub fn try_lock(&self, x: u32, y: u32) -> Option<PixelGuard<'_>> {
        self.try_lock_many(&[(x as i64, y as i64)])
    }

    /// Take every on-image pixel of `pixels` (off-image ones are ignored, duplicates
    /// taken once), all or nothing; at most five pixels.
    pub fn try_lock_many(&self, pixels: &[(i64, i64)]) -> Option<PixelGuard<'_>> {
        assert!(pixels.len() <= 5, "at most five pixels per guard");
        let mut g = PixelGuard {
            locks: self,
            held: [0; 5],
            n: 0,
        };
        for &(x, y) in pixels {
            if x < 0 || y < 0 || x >= self.width as i64 || y >= self.height as i64 {
                continue;
            }
            let i = (y as u64 * self.width as u64 + x as u64) as u32;
            if g.held[..g.n].contains(&i) {
                continue;
            }
            // Acquire pairs with the Release in `drop`: whatever the previous holder
            // did before letting go happens-before our work on the pixel.
            if self.flags[i as usize]
                .compare_exchange(false, true, Ordering::Acquire, Ordering::Relaxed)
                .is_err()
            {
                self.conflicts.fetch_add(1, Ordering::Relaxed);
                return None; // `g` drops here and releases what it took
            }
            g.held[g.n] = i;
            g.n += 1;
        }
        Some(g)
    }
}

impl PixelGuard<'_> {
    /// Linear indices of the pixels held.
    pub fn pixels(&self) -> &[u32] {
        &self.held[..self.n]
    }
}

impl Drop for PixelGuard<'_> {
    fn drop(&mut self) {
        for &i in &self.held[..self.n] {
            self.locks.flags[i as usize].store(false, Ordering::Release);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exclusive_and_released_on_drop() {
        let l = PixelLocks::new(4, 4);
        let a = l.try_lock(1, 1).unwrap();
        assert!(l.try_lock(1, 1).is_none());
        assert!(l.try_lock_many(&[(2, 2), (1, 1)]).is_none());
        // All or nothing: (2, 2) was released when (1, 1) failed.
        assert!(l.try_lock(2, 2).is_some());
        drop(a);
        let b = l.try_lock_many(&[(1, 1), (-1, 1), (1, 1), (4, 0)]).unwrap();
        assert_eq!(b.pixels(), &[5]);
        assert_eq!(l.conflicts(), 2);
    }
}
