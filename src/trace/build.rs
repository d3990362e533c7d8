//! A top-down binned-SAH builder for every BVH the tracer builds, feeding obvhs's
//! wide-BVH conversion.
//!
//! obvhs builds with PLOC, which merges only mutual nearest neighbours. Where many
//! neighbours cost the same or nest (copies of one triangle, a triangle fan from one
//! large polygon: every box contains the previous one) each node prefers a different
//! partner, about one pair merges per pass and the build turns quadratic: a one-line OBJ
//! polygon of 100k vertices took minutes. A top-down split costs O(n log n) whatever the
//! input, and falls back to a median split when SAH finds nothing to separate, which also
//! bounds the depth.

use glam::Vec3A;
use obvhs::{
    aabb::Aabb,
    bvh2::{node::Bvh2Node, Bvh2},
    cwbvh::{bvh2_to_cwbvh::bvh2_to_cwbvh, CwBvh},
};

/// SAH bins per axis.
const BINS: usize = 16;
/// Below this depth splits follow SAH; deeper ones split at the median, so no input can
/// make the tree deeper than this plus log2 of the primitive count (traversal stacks hold
/// 96 levels).
const SAH_DEPTH: usize = 40;
/// Primitives per wide-BVH leaf (obvhs's CwBvh allows at most 3).
const LEAF_PRIMS: u32 = 3;

/// A binary BVH over `boxes` with one primitive per leaf; `primitive_indices[i]` is the
/// box behind leaf slot `i`.
pub fn build_bvh2(boxes: &[Aabb]) -> Bvh2 {
    let n = boxes.len();
    let mut bvh = Bvh2::default();
    if n == 0 {
        return bvh;
    }
    let centroid = |i: u32| boxes[i as usize].center();
    let mut indices: Vec<u32> = (0..n as u32).collect();
    bvh.nodes.reserve(2 * n - 1);
    bvh.nodes.push(Bvh2Node::default());
    // (node, first, end, depth): the node covers indices[first..end].
    let mut stack = vec![(0usize, 0usize, n, 0usize)];
    let mut max_depth = 0;
    while let Some((node, first, end, depth)) = stack.pop() {
        max_depth = max_depth.max(depth);
        let range = &mut indices[first..end];
        let mut bounds = Aabb::empty();
        let mut cbounds = Aabb::empty();
        for &i in range.iter() {
            bounds = bounds.union(&boxes[i as usize]);
            cbounds.extend(centroid(i));
        }
        if range.len() == 1 {
            bvh.nodes[node] = Bvh2Node {
                aabb: bounds,
                prim_count: 1,
                first_index: first as u32,
                ..Default::default()
            };
            continue;
        }
        let split = if depth < SAH_DEPTH {
            sah_split(boxes, range, &cbounds)
        } else {
            None
        };
        let mid = match split {
            Some((axis, at)) => partition(range, |i| centroid(i)[axis] < at),
            None => 0,
        };
        let mid = if mid == 0 || mid == range.len() {
            // Nothing separates them: halve by centroid order on the widest axis (all
            // equal centroids: any halving will do).
            let axis = (cbounds.max - cbounds.min).max_position();
            let half = range.len() / 2;
            range.select_nth_unstable_by(half, |&a, &b| {
                centroid(a)[axis].total_cmp(&centroid(b)[axis])
            });
            half
        } else {
            mid
        };
        let left = bvh.nodes.len();
        bvh.nodes.push(Bvh2Node::default());
        bvh.nodes.push(Bvh2Node::default());
        bvh.nodes[node] = Bvh2Node {
            aabb: bounds,
            prim_count: 0,
            first_index: left as u32,
            ..Default::default()
        };
        stack.push((left + 1, first + mid, end, depth + 1));
        stack.push((left, first, first + mid, depth + 1));
    }
    bvh.primitive_indices = indices;
    // Children were pushed after their parents: refits can sweep backwards.
    bvh.children_are_ordered_after_parents = true;
    bvh.max_depth = bvh.max_depth.max(max_depth + 1);
    bvh
}

/// The best binned-SAH split of `range` as (axis, centroid coordinate), or `None` when no
/// split beats leaving the boxes together or the centroids coincide.
fn sah_split(boxes: &[Aabb], range: &[u32], cbounds: &Aabb) -> Option<(usize, f32)> {
    let extent = cbounds.max - cbounds.min;
    let mut best: Option<(f32, usize, f32)> = None;
    for axis in 0..3 {
        if extent[axis].partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            continue;
        }
        let scale = BINS as f32 / extent[axis];
        let bin_of = |c: Vec3A| (((c[axis] - cbounds.min[axis]) * scale) as usize).min(BINS - 1);
        let mut bins = [(Aabb::empty(), 0u32); BINS];
        for &i in range {
            let b = &boxes[i as usize];
            let k = bin_of(b.center());
            bins[k].0 = bins[k].0.union(b);
            bins[k].1 += 1;
        }
        // Sweep from the right for suffix areas, then from the left.
        let mut right = [0.0f32; BINS];
        let (mut acc, mut count) = (Aabb::empty(), 0u32);
        for k in (1..BINS).rev() {
            acc = acc.union(&bins[k].0);
            count += bins[k].1;
            right[k] = if count > 0 {
                acc.half_area() * count as f32
            } else {
                0.0
            };
        }
        let (mut acc, mut count) = (Aabb::empty(), 0u32);
        for k in 0..BINS - 1 {
            acc = acc.union(&bins[k].0);
            count += bins[k].1;
            if count == 0 || count as usize == range.len() {
                continue;
            }
            let cost = acc.half_area() * count as f32 + right[k + 1];
            if cost.is_finite() && best.is_none_or(|(c, _, _)| cost < c) {
                let at = cbounds.min[axis] + (k + 1) as f32 / scale;
                best = Some((cost, axis, at));
            }
        }
    }
    best.map(|(_, axis, at)| (axis, at))
}

/// Reorder `range` so that the elements for which `left` holds come first; returns
/// their count.
fn partition(range: &mut [u32], left: impl Fn(u32) -> bool) -> usize {
    let mut mid = 0;
    for k in 0..range.len() {
        if left(range[k]) {
            range.swap(mid, k);
            mid += 1;
        }
    }
    mid
}

/// The wide BVH the tracer traverses: [`build_bvh2`] collapsed to 8-wide nodes. No
/// reinsertion pass: obvhs's search for better positions degrades the same way on
/// nested boxes (seconds for a 100k fan), and a binned-SAH tree does not need it.
pub fn build_cwbvh(boxes: &[Aabb]) -> CwBvh {
    let bvh2 = build_bvh2(boxes);
    bvh2_to_cwbvh(&bvh2, LEAF_PRIMS, true, false)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_box(c: Vec3A, r: f32) -> Aabb {
        Aabb {
            min: c - Vec3A::splat(r),
            max: c + Vec3A::splat(r),
        }
    }

    /// Every primitive sits in exactly one leaf, inside the bounds of every node above it;
    /// returns the tree's depth.
    fn check(bvh: &Bvh2, boxes: &[Aabb]) -> usize {
        let mut seen = vec![false; boxes.len()];
        let mut stack = vec![(0usize, 0usize)];
        let mut deepest = 0;
        while let Some((k, depth)) = stack.pop() {
            assert!(
                depth < bvh.max_depth,
                "depth {depth} beyond {}",
                bvh.max_depth
            );
            deepest = deepest.max(depth);
            let node = &bvh.nodes[k];
            if node.prim_count > 0 {
                for s in node.first_index..node.first_index + node.prim_count {
                    let p = bvh.primitive_indices[s as usize] as usize;
                    assert!(!seen[p], "primitive {p} twice");
                    seen[p] = true;
                    let b = &boxes[p];
                    assert!(node.aabb.min.cmple(b.min).all() && node.aabb.max.cmpge(b.max).all());
                }
            } else {
                for c in [node.first_index as usize, node.first_index as usize + 1] {
                    let cb = &bvh.nodes[c].aabb;
                    assert!(node.aabb.min.cmple(cb.min).all() && node.aabb.max.cmpge(cb.max).all());
                    stack.push((c, depth + 1));
                }
            }
        }
        assert!(seen.iter().all(|&s| s), "a primitive is in no leaf");
        deepest
    }

    #[test]
    fn scattered_identical_and_nested_boxes_build_valid_shallow_trees() {
        let scattered: Vec<Aabb> = (0..1000)
            .map(|i| {
                unit_box(
                    Vec3A::new((i * 37 % 101) as f32, (i * 53 % 89) as f32, 0.0),
                    0.3,
                )
            })
            .collect();
        let identical = vec![unit_box(Vec3A::ZERO, 1.0); 5000];
        // A fan: every box contains the previous one.
        let nested: Vec<Aabb> = (1..5000)
            .map(|i| Aabb {
                min: Vec3A::ZERO,
                max: Vec3A::new(1.0, i as f32, 0.0),
            })
            .collect();
        for boxes in [&scattered, &identical, &nested] {
            let bvh = build_bvh2(boxes);
            let depth = check(&bvh, boxes);
            // log2(5000) < 13: median splits below SAH_DEPTH finish within that.
            assert!(depth <= SAH_DEPTH + 13, "depth {depth}");
            let cw = build_cwbvh(boxes);
            let mut ids = cw.primitive_indices.clone();
            ids.sort_unstable();
            assert_eq!(ids, (0..boxes.len() as u32).collect::<Vec<_>>());
        }
    }
}
