//! Building obvhs BVHs and the nearest-primitive traversal obvhs does not provide.
//!
//! Both trees of a [`crate::TargetMesh`] are obvhs `Bvh2`s: the face tree over triangle boxes
//! and the vertex tree over point boxes. obvhs traverses rays; closest-point search is the
//! classic best-first descent written here: visit the nearer child first and prune every
//! node whose box is farther than the best primitive found so far.

use std::time::Duration;

use glam::Vec3A;
use obvhs::{BvhBuildParams, aabb::Aabb, bvh2::Bvh2, bvh2::builder::build_bvh2};

/// Builds a binary BVH over boxes with the preset the kernel uses everywhere.
///
/// `fast_build` (PLOC with a small search radius, a little reinsertion) with at most 4 primitives
/// per leaf: measured on 1M triangles (`cargo bench`), leaves of 4 answer random-order closest
/// point queries a little faster than 8 or 1 and build as fast.
#[must_use]
pub fn build_bvh(boxes: &[Aabb]) -> Bvh2 {
    let params = BvhBuildParams {
        max_prims_per_leaf: 4,
        ..BvhBuildParams::fast_build()
    };
    let mut bvh = build_bvh2(boxes, params, &mut Duration::default());
    // Children next to their parent in depth-first order: fewer cache misses per descent.
    bvh.reorder_in_stack_traversal_order();
    bvh
}

/// Squared distance from `point` to the box (zero inside).
#[must_use]
#[inline(always)]
pub fn box_distance_squared(aabb: &Aabb, point: Vec3A) -> f32 {
    let outside = (aabb.min - point).max(point - aabb.max).max(Vec3A::ZERO);
    outside.length_squared()
}

/// Reusable traversal stack of `(node, squared distance to its box)`.
pub type NearestStack = Vec<(u32, f32)>;

/// Best-first search for the primitive nearest to `point` within `max_distance_squared`.
///
/// `distance_squared(slot, best)` receives a *BVH slot* (an index into `bvh.primitive_indices`, so that
/// callers can keep primitive data in BVH order) and returns the squared distance to that
/// primitive (it may return anything `>= best`, the best squared distance so far, when it can
/// tell cheaply that the primitive cannot win). `warm_start` is an optional known candidate `(slot, squared distance)`, typically
/// the answer of the previous, nearby query: its distance bounds the search from the start, so
/// most of the tree is pruned at once. Returns the best `(slot, squared distance)` strictly below
/// `max_distance_squared`, or `None`.
#[inline]
pub fn nearest_slot<F: FnMut(usize, f32) -> f32>(
    bvh: &Bvh2,
    point: Vec3A,
    max_distance_squared: f32,
    warm_start: Option<(usize, f32)>,
    stack: &mut NearestStack,
    mut distance_squared: F,
) -> Option<(usize, f32)> {
    let root = bvh.nodes.first()?;
    let mut best_distance_squared = max_distance_squared;
    let mut best_slot = None;
    if let Some((slot, slot_distance_squared)) = warm_start
        && slot_distance_squared < max_distance_squared
    {
        best_distance_squared = slot_distance_squared;
        best_slot = Some(slot);
    }
    stack.clear();
    stack.push((0, box_distance_squared(&root.aabb, point)));
    while let Some((node_index, node_distance_squared)) = stack.pop() {
        if node_distance_squared >= best_distance_squared {
            continue;
        }
        let node = &bvh.nodes[node_index as usize];
        if node.prim_count > 0 {
            let first = node.first_index as usize;
            for slot in first..first + node.prim_count as usize {
                let candidate = distance_squared(slot, best_distance_squared);
                if candidate < best_distance_squared {
                    best_distance_squared = candidate;
                    best_slot = Some(slot);
                }
            }
        } else {
            let left = node.first_index;
            let right = left + 1;
            let left_distance = box_distance_squared(&bvh.nodes[left as usize].aabb, point);
            let right_distance = box_distance_squared(&bvh.nodes[right as usize].aabb, point);
            // Push the farther child first so that the nearer one is popped next.
            let (near, near_distance, far, far_distance) = if left_distance <= right_distance {
                (left, left_distance, right, right_distance)
            } else {
                (right, right_distance, left, left_distance)
            };
            if far_distance < best_distance_squared {
                stack.push((far, far_distance));
            }
            if near_distance < best_distance_squared {
                stack.push((near, near_distance));
            }
        }
    }
    best_slot.map(|slot| (slot, best_distance_squared))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_point_matches_brute_force() {
        let points: Vec<Vec3A> = (0..500)
            .map(|index| {
                let x = index as f32;
                Vec3A::new(
                    (x * 0.37).sin() * 3.0,
                    (x * 0.11).cos() * 2.0,
                    (x * 0.07).sin(),
                )
            })
            .collect();
        let boxes: Vec<Aabb> = points.iter().map(|&p| Aabb::from_point(p)).collect();
        let bvh = build_bvh(&boxes);
        let mut stack = NearestStack::new();
        for query_index in 0..200 {
            let q = query_index as f32;
            let query = Vec3A::new((q * 0.9).cos() * 4.0, (q * 0.3).sin() * 3.0, q * 0.01 - 1.0);
            let (slot, distance_squared) =
                nearest_slot(&bvh, query, f32::INFINITY, None, &mut stack, |slot, _| {
                    points[bvh.primitive_indices[slot] as usize].distance_squared(query)
                })
                .unwrap();
            let brute = points
                .iter()
                .map(|p| p.distance_squared(query))
                .fold(f32::INFINITY, f32::min);
            assert_eq!(distance_squared, brute);
            assert_eq!(
                points[bvh.primitive_indices[slot] as usize].distance_squared(query),
                brute
            );
        }
    }

    #[test]
    fn nothing_within_the_limit_gives_none() {
        let boxes = [Aabb::from_point(Vec3A::ZERO)];
        let bvh = build_bvh(&boxes);
        let mut stack = NearestStack::new();
        let found = nearest_slot(&bvh, Vec3A::splat(10.0), 1.0, None, &mut stack, |_, _| {
            300.0
        });
        assert!(found.is_none());
    }
}
