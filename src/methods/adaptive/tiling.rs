//! The sampler's K-D tree tiling: a flat `Vec` of nodes with `u32` links; the current
//! tiles are the leaves (a cut across the tree). Each tile carries the statistics of
//! its block (the deep-buffer samples inside its rectangle), and the root those of the
//! whole image; merging two tiles adds theirs, and splitting one needs a scan of one
//! child only.

pub use crate::tiles::Rect;
use crate::{
    methods::MethodError,
    tiles::{TileGradients, TilingSnapshot},
};

/// Marks "no node".
pub const NONE: u32 = u32::MAX;

/// Additive statistics of a block of the deep buffer.
///
/// Weights are `exp(decay·(t − t_ref))`: proportional to the paper's
/// `exp(−decay·age)` with one common factor for all samples, so ratios (weighted
/// means, variances) are exact and sums stay additive as time passes.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TileStats {
    /// Σ crosshair weights.
    pub wc: f64,
    /// Σ weight · luminance over the five samples of every crosshair.
    pub wl: f64,
    /// Σ weight · luminance².
    pub wl2: f64,
    /// Σ weight · Gx.
    pub wgx: f64,
    /// Σ weight · Gy.
    pub wgy: f64,
    /// Σ weight · Gt.
    pub wgt: f64,
    /// Number of crosshairs.
    pub count: f64,
    /// Σ crosshair times (for the mean age).
    pub sum_t: f64,
    /// Σ weight · crosshair time (for the age-weighted mean age).
    pub wt: f64,
    /// Σ weights of occlusion events.
    pub occl: f64,
}

impl TileStats {
    /// Add `o` (or subtract it with `sign = −1`).
    #[inline]
    pub fn add(&mut self, o: &TileStats, sign: f64) {
        self.wc += sign * o.wc;
        self.wl += sign * o.wl;
        self.wl2 += sign * o.wl2;
        self.wgx += sign * o.wgx;
        self.wgy += sign * o.wgy;
        self.wgt += sign * o.wgt;
        self.count += sign * o.count;
        self.sum_t += sign * o.sum_t;
        self.wt += sign * o.wt;
        self.occl += sign * o.occl;
    }

    /// Multiply every weighted sum by `f` (rebasing the weight reference time).
    pub fn scale_weights(&mut self, f: f64) {
        self.wc *= f;
        self.wl *= f;
        self.wl2 *= f;
        self.wgx *= f;
        self.wgy *= f;
        self.wgt *= f;
        self.wt *= f;
        self.occl *= f;
    }

    /// Age-weighted luminance variance of the block's samples.
    pub fn variance(&self) -> f64 {
        let ws = 5.0 * self.wc;
        if ws <= 1e-300 {
            return 0.0;
        }
        let m = self.wl / ws;
        (self.wl2 / ws - m * m).max(0.0)
    }

    /// Age-weighted mean age of the block's crosshairs at time `now`.
    pub fn weighted_age(&self, now: f64) -> f64 {
        if self.wc <= 1e-300 {
            return 0.0;
        }
        (now - self.wt / self.wc).max(0.0)
    }

    /// Age-weighted mean gradients `(Gx, Gy, Gt)`.
    pub fn gradients(&self) -> (f64, f64, f64) {
        if self.wc <= 1e-300 {
            return (0.0, 0.0, 0.0);
        }
        (self.wgx / self.wc, self.wgy / self.wc, self.wgt / self.wc)
    }

    fn approx_eq(&self, o: &TileStats, tol: f64) -> bool {
        let close = |a: f64, b: f64| (a - b).abs() <= tol * (1.0 + a.abs().max(b.abs()));
        close(self.wc, o.wc)
            && close(self.wl, o.wl)
            && close(self.wl2, o.wl2)
            && close(self.wgx, o.wgx)
            && close(self.wgy, o.wgy)
            && close(self.wgt, o.wgt)
            && close(self.count, o.count)
            && close(self.sum_t, o.sum_t)
            && close(self.wt, o.wt)
            && close(self.occl, o.occl)
    }
}

/// A crosshair initiated on a tile's previous visit, waiting to be completed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pending {
    /// Sub-pixel position.
    pub x: f32,
    /// Sub-pixel position.
    pub y: f32,
    /// Time of the initiating sample.
    pub t: f64,
    /// Its luminance.
    pub lum: f32,
    /// Its hit point (far point for a miss) and the hit's velocity: where the same
    /// surface point is later.
    pub hit_point: glam::Vec3,
    /// See `hit_point`.
    pub velocity: glam::Vec3,
    /// What the hit point is fixed to: where it is later, exactly.
    pub anchor: crate::trace::Anchor,
}

impl Pending {
    /// The pending crosshair with a velocity that carries its hit point to where the
    /// point is at `now` in `state` (the scene at `now`), exactly rather than
    /// extrapolated; as it was for the static world, or when its object has gone.
    pub fn follow(mut self, state: &crate::trace::SceneState, now: f64) -> Self {
        let dt = (now - self.t) as f32;
        if let Some(q) = state.anchor_position(&self.anchor) {
            if dt > 0.0 {
                self.velocity = (q - self.hit_point) / dt;
            }
        }
        self
    }

    /// The pending crosshair at a position moved by `(dx, dy)` pixels (from one
    /// sampler region's coordinates to another's).
    pub fn moved(mut self, dx: f32, dy: f32) -> Self {
        self.x += dx;
        self.y += dy;
        self
    }
}

/// One node of the K-D tree.
#[derive(Clone, Debug)]
pub struct Node {
    /// The node's rectangle.
    pub rect: Rect,
    /// Parent node (`NONE` for the root).
    pub parent: u32,
    /// First of two adjacent children (`NONE` for a leaf, i.e. a tile).
    pub children: u32,
    /// Position in the leaf list (`NONE` unless a leaf).
    pub leaf_slot: u32,
    /// Statistics of the block.
    pub stats: TileStats,
    /// The crosshair this tile initiated on its last visit.
    pub pending: Option<Pending>,
}

/// The tiling.
#[derive(Clone, Debug)]
pub struct Tiling {
    nodes: Vec<Node>,
    free_pairs: Vec<u32>,
    leaves: Vec<u32>,
    /// The tile of each pixel, row by row: [`Tiling::leaf_at`] is one load instead of a
    /// descent of the tree (a cache miss per level, a dozen levels, on every sample the
    /// controller takes in). Rewritten over a tile's area when it is split or merged.
    leaf_of: Vec<u32>,
    width: u32,
    height: u32,
}

impl Tiling {
    /// One tile covering a `width × height` image.
    pub fn new(width: u32, height: u32) -> Self {
        let root = Node {
            rect: Rect {
                x0: 0,
                y0: 0,
                x1: width,
                y1: height,
            },
            parent: NONE,
            children: NONE,
            leaf_slot: 0,
            stats: TileStats::default(),
            pending: None,
        };
        Self {
            nodes: vec![root],
            free_pairs: Vec::new(),
            leaves: vec![0],
            leaf_of: vec![0; width as usize * height as usize],
            width,
            height,
        }
    }

    /// The node `i`.
    #[inline]
    pub fn node(&self, i: u32) -> &Node {
        &self.nodes[i as usize]
    }

    /// Ask the cache for node `i` ahead of its use.
    #[inline]
    pub fn prefetch_node(&self, i: u32) {
        crate::reconstruction::prefetch(&self.nodes, i as usize);
    }

    /// Mutable node `i`.
    #[inline]
    pub fn node_mut(&mut self, i: u32) -> &mut Node {
        &mut self.nodes[i as usize]
    }

    /// The current tiles (leaf node indices).
    pub fn leaves(&self) -> &[u32] {
        &self.leaves
    }

    /// The tiles' nodes in the order of [`Tiling::leaves`], each asked of the cache
    /// some tiles ahead: the tiles lie scattered over the node array, and passes over
    /// all of them (snapshots, the error sums) otherwise wait on one miss at a time.
    pub fn leaf_nodes(&self) -> impl Iterator<Item = (u32, &Node)> + '_ {
        const AHEAD: usize = 16;
        self.leaves.iter().enumerate().map(move |(k, &l)| {
            if let Some(&next) = self.leaves.get(k + AHEAD) {
                self.prefetch_node(next);
            }
            (l, &self.nodes[l as usize])
        })
    }

    /// Number of tiles.
    pub fn len(&self) -> usize {
        self.leaves.len()
    }

    /// The tiles and their gradients, as the reconstructor reads them.
    pub fn snapshot(&self) -> TilingSnapshot {
        TilingSnapshot {
            tiles: self
                .leaf_nodes()
                .map(|(_, n)| {
                    let (gx, gy, gt) = n.stats.gradients();
                    TileGradients {
                        rect: n.rect,
                        gx,
                        gy,
                        gt,
                    }
                })
                .collect(),
        }
    }

    /// Whether there are no tiles (never true).
    pub fn is_empty(&self) -> bool {
        self.leaves.is_empty()
    }

    /// Root statistics: the whole deep buffer.
    pub fn total(&self) -> &TileStats {
        &self.nodes[0].stats
    }

    /// Ask the cache for pixel `(x, y)`'s entry of the pixel → tile map.
    #[inline]
    pub fn prefetch_leaf_at(&self, x: u32, y: u32) {
        if x < self.width && y < self.height {
            crate::reconstruction::prefetch(&self.leaf_of, y as usize * self.width as usize + x as usize);
        }
    }

    /// The tile containing pixel `(x, y)`.
    #[inline]
    pub fn leaf_at(&self, x: u32, y: u32) -> u32 {
        if x < self.width && y < self.height {
            return self.leaf_of[y as usize * self.width as usize + x as usize];
        }
        self.descend(x, y)
    }

    /// [`Tiling::leaf_at`] by descending the tree (also for pixels off the image: the
    /// tile whose side they are on).
    fn descend(&self, x: u32, y: u32) -> u32 {
        let mut i = 0u32;
        loop {
            let n = &self.nodes[i as usize];
            if n.children == NONE {
                return i;
            }
            let c = n.children;
            i = if self.nodes[c as usize].rect.contains(x, y) {
                c
            } else {
                c + 1
            };
        }
    }

    /// Mark every pixel of `r` as belonging to tile `leaf`.
    fn claim(&mut self, r: Rect, leaf: u32) {
        let w = self.width as usize;
        for y in r.y0 as usize..r.y1 as usize {
            self.leaf_of[y * w + r.x0 as usize..y * w + r.x1 as usize].fill(leaf);
        }
    }

    /// Add `delta` (times `sign`) to tile `leaf` and to the whole image's sums.
    ///
    /// Only the tiles and the root keep statistics: an inner node's are needed only
    /// when it becomes a tile again, and are then formed from its two tiles
    /// ([`Tiling::merge`]). Walking every ancestor instead (a dozen levels at
    /// 1280×720) was a fifth of a live controller (docs/performance.md, session 34).
    #[inline]
    pub fn add_to_tile(&mut self, leaf: u32, delta: &TileStats, sign: f64) {
        self.nodes[leaf as usize].stats.add(delta, sign);
        if leaf != 0 {
            self.nodes[0].stats.add(delta, sign);
        }
    }

    /// Whether a tile may be split (both halves keep at least `min_side` pixels).
    pub fn splittable(&self, leaf: u32, min_side: u32) -> bool {
        let r = self.nodes[leaf as usize].rect;
        r.width().max(r.height()) >= 2 * min_side.max(1)
    }

    /// Split tile `leaf` across its longer side; `stats_of` computes a child's
    /// statistics from the deep buffer. Returns the two new tiles.
    pub fn split(&mut self, leaf: u32, stats_of: impl Fn(Rect) -> TileStats) -> (u32, u32) {
        let n = self.nodes[leaf as usize].clone();
        debug_assert_eq!(n.children, NONE);
        let r = n.rect;
        let (a, b) = if r.width() >= r.height() {
            let m = r.x0 + r.width() / 2;
            (Rect { x1: m, ..r }, Rect { x0: m, ..r })
        } else {
            let m = r.y0 + r.height() / 2;
            (Rect { y1: m, ..r }, Rect { y0: m, ..r })
        };
        let sa = stats_of(a);
        let mut sb = n.stats;
        sb.add(&sa, -1.0);
        let make = |rect: Rect, stats: TileStats, pending: Option<Pending>| Node {
            rect,
            parent: leaf,
            children: NONE,
            leaf_slot: NONE,
            stats,
            pending,
        };
        let pa = n.pending.filter(|p| a.contains(p.x as u32, p.y as u32));
        let pb = n.pending.filter(|p| b.contains(p.x as u32, p.y as u32));
        let c = match self.free_pairs.pop() {
            Some(c) => {
                self.nodes[c as usize] = make(a, sa, pa);
                self.nodes[c as usize + 1] = make(b, sb, pb);
                c
            }
            None => {
                let c = self.nodes.len() as u32;
                self.nodes.push(make(a, sa, pa));
                self.nodes.push(make(b, sb, pb));
                c
            }
        };
        let slot = n.leaf_slot;
        let parent = &mut self.nodes[leaf as usize];
        parent.children = c;
        parent.leaf_slot = NONE;
        parent.pending = None;
        if leaf != 0 {
            parent.stats = TileStats::default(); // kept by its tiles now
        }
        self.leaves[slot as usize] = c;
        self.nodes[c as usize].leaf_slot = slot;
        self.nodes[c as usize + 1].leaf_slot = self.leaves.len() as u32;
        self.leaves.push(c + 1);
        self.claim(a, c);
        self.claim(b, c + 1);
        (c, c + 1)
    }

    /// Whether `node`'s two children are both tiles (so they can be merged).
    pub fn mergeable(&self, node: u32) -> bool {
        let c = self.nodes[node as usize].children;
        c != NONE
            && self.nodes[c as usize].children == NONE
            && self.nodes[c as usize + 1].children == NONE
    }

    fn remove_leaf(&mut self, leaf: u32) {
        let slot = self.nodes[leaf as usize].leaf_slot as usize;
        let last = self.leaves.pop().expect("non-empty");
        if slot < self.leaves.len() {
            self.leaves[slot] = last;
            self.nodes[last as usize].leaf_slot = slot as u32;
        }
        self.nodes[leaf as usize].leaf_slot = NONE;
    }

    /// Merge the two tiles under `node` back into one tile.
    pub fn merge(&mut self, node: u32) {
        debug_assert!(self.mergeable(node));
        let c = self.nodes[node as usize].children;
        let pending = self.nodes[c as usize]
            .pending
            .or(self.nodes[c as usize + 1].pending);
        self.remove_leaf(c);
        self.remove_leaf(c + 1);
        self.free_pairs.push(c);
        let mut stats = self.nodes[c as usize].stats;
        stats.add(&self.nodes[c as usize + 1].stats, 1.0);
        let n = &mut self.nodes[node as usize];
        if node != 0 {
            n.stats = stats;
        }
        n.children = NONE;
        n.pending = pending;
        n.leaf_slot = self.leaves.len() as u32;
        let rect = n.rect;
        self.leaves.push(node);
        self.claim(rect, node);
    }

    /// Multiply all statistics' weights by `f`.
    pub fn scale_weights(&mut self, f: f64) {
        for n in &mut self.nodes {
            n.stats.scale_weights(f);
        }
    }

    /// Check every invariant: the tiles partition the image exactly, links are
    /// consistent, the root's statistics are the sum of the tiles' and other inner
    /// nodes keep none, and (with `stats_of`) each tile's statistics match the deep
    /// buffer within `tol`.
    pub fn validate(
        &self,
        stats_of: Option<&dyn Fn(Rect) -> TileStats>,
        tol: f64,
    ) -> Result<(), MethodError> {
        let mut covered = vec![0u8; (self.width * self.height) as usize];
        let mut stack = vec![0u32];
        let mut leaf_count = 0;
        if self.nodes[0].parent != NONE
            || self.nodes[0].rect
                != (Rect {
                    x0: 0,
                    y0: 0,
                    x1: self.width,
                    y1: self.height,
                })
        {
            return Err(inconsistent(
                "root must cover the image and have no parent".into(),
            ));
        }
        while let Some(i) = stack.pop() {
            let n = &self.nodes[i as usize];
            if n.rect.area() == 0 {
                return Err(inconsistent(format!("node {i} has an empty rectangle")));
            }
            if n.children == NONE {
                leaf_count += 1;
                self.validate_tile(i, &mut covered, stats_of, tol)?;
            } else {
                self.validate_split(i)?;
                stack.push(n.children);
                stack.push(n.children + 1);
            }
        }
        if leaf_count != self.leaves.len() {
            return Err(inconsistent(format!(
                "{} tiles reachable, {} listed",
                leaf_count,
                self.leaves.len()
            )));
        }
        if let Some(p) = covered.iter().position(|&c| c != 1) {
            return Err(inconsistent(format!(
                "pixel {p} covered {} times",
                covered[p]
            )));
        }
        let mut sum = TileStats::default();
        for &l in &self.leaves {
            sum.add(&self.nodes[l as usize].stats, 1.0);
        }
        if !self.nodes[0].stats.approx_eq(&sum, tol) {
            return Err(inconsistent(format!(
                "the root's statistics {:?} are not the sum of the tiles' {sum:?}",
                self.nodes[0].stats
            )));
        }
        Ok(())
    }

    /// [`Self::validate`] of the tile `i`: its slot, the pixels it maps (counted in
    /// `covered`), its pending crosshair and, with `stats_of`, its statistics.
    fn validate_tile(
        &self,
        i: u32,
        covered: &mut [u8],
        stats_of: Option<&dyn Fn(Rect) -> TileStats>,
        tol: f64,
    ) -> Result<(), MethodError> {
        let n = &self.nodes[i as usize];
        let slot = n.leaf_slot as usize;
        if self.leaves.get(slot) != Some(&i) {
            return Err(inconsistent(format!("leaf {i} not at its slot {slot}")));
        }
        for y in n.rect.y0..n.rect.y1 {
            for x in n.rect.x0..n.rect.x1 {
                let p = (y * self.width + x) as usize;
                covered[p] += 1;
                if self.leaf_of[p] != i {
                    return Err(inconsistent(format!(
                        "pixel ({x}, {y}) of tile {i} is mapped to tile {}",
                        self.leaf_of[p]
                    )));
                }
            }
        }
        if let Some(p) = n.pending {
            if !n.rect.contains(p.x as u32, p.y as u32) {
                return Err(inconsistent(format!(
                    "tile {i} holds a pending crosshair outside it"
                )));
            }
        }
        if let Some(f) = stats_of {
            let want = f(n.rect);
            if !n.stats.approx_eq(&want, tol) {
                return Err(inconsistent(format!(
                    "tile {i} statistics {:?} differ from the buffer's {want:?}",
                    n.stats
                )));
            }
        }
        Ok(())
    }

    /// [`Self::validate`] of the inner node `i`: its children point back, split it
    /// exactly in two, and (but for the root) it keeps no statistics of its own.
    fn validate_split(&self, i: u32) -> Result<(), MethodError> {
        let n = &self.nodes[i as usize];
        let (a, b) = (
            &self.nodes[n.children as usize],
            &self.nodes[n.children as usize + 1],
        );
        if a.parent != i || b.parent != i {
            return Err(inconsistent(format!("children of {i} do not point back")));
        }
        if n.leaf_slot != NONE || n.pending.is_some() {
            return Err(inconsistent(format!("inner node {i} is marked as a tile")));
        }
        let (ra, rb, r) = (a.rect, b.rect, n.rect);
        let vertical =
            ra.x1 == rb.x0 && ra.y0 == r.y0 && rb.y0 == r.y0 && ra.y1 == r.y1 && rb.y1 == r.y1;
        let horizontal =
            ra.y1 == rb.y0 && ra.x0 == r.x0 && rb.x0 == r.x0 && ra.x1 == r.x1 && rb.x1 == r.x1;
        let spans = if vertical {
            ra.x0 == r.x0 && rb.x1 == r.x1
        } else {
            ra.y0 == r.y0 && rb.y1 == r.y1
        };
        if !(vertical || horizontal) || !spans {
            return Err(inconsistent(format!(
                "children of {i} do not split it exactly"
            )));
        }
        if i != 0 && n.stats != TileStats::default() {
            return Err(inconsistent(format!(
                "inner node {i} keeps statistics its tiles keep"
            )));
        }
        Ok(())
    }
}

/// The error of a broken tiling invariant.
fn inconsistent(why: String) -> MethodError {
    MethodError::Inconsistent {
        what: "tiling",
        why,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    #[test]
    fn long_random_split_merge_sequences_keep_invariants() {
        // Statistics: one unit of "count" per pixel, so every node's count is its area.
        let unit = |r: Rect| TileStats {
            count: r.area() as f64,
            wc: r.area() as f64 * 0.5,
            ..Default::default()
        };
        let mut t = Tiling::new(61, 37);
        t.node_mut(0).stats = unit(t.node(0).rect);
        let mut rng = Rng::new(&[42]);
        for step in 0..20_000 {
            let leaves = t.leaves().to_vec();
            if rng.uniform() < 0.55 {
                let l = leaves[rng.below(leaves.len() as u32) as usize];
                if t.splittable(l, 1) {
                    t.split(l, unit);
                }
            } else {
                let l = leaves[rng.below(leaves.len() as u32) as usize];
                let p = t.node(l).parent;
                if p != NONE && t.mergeable(p) {
                    t.merge(p);
                }
            }
            if step % 997 == 0 {
                t.validate(Some(&unit), 1e-9).unwrap();
            }
        }
        t.validate(Some(&unit), 1e-9).unwrap();
        assert!(t.len() > 1);
        // Every pixel maps to the tile that contains it.
        for y in 0..37 {
            for x in 0..61 {
                assert!(t.node(t.leaf_at(x, y)).rect.contains(x, y));
            }
        }
    }

    #[test]
    fn validate_catches_broken_statistics() {
        let unit = |r: Rect| TileStats {
            count: r.area() as f64,
            ..Default::default()
        };
        let mut t = Tiling::new(8, 8);
        t.node_mut(0).stats = unit(t.node(0).rect);
        let (a, _) = t.split(0, unit);
        t.node_mut(a).stats.count += 1.0;
        assert!(t.validate(Some(&unit), 1e-9).is_err());
    }
}
