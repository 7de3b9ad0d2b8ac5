//! Exact closest point on the surface (the face tree).

use glam::{Vec3, Vec3A};

use super::point_triangle::{closest_point_on_degenerate_triangle, closest_point_on_triangle};
use super::{QueryState, check_finite, check_max_distance, map_in_spatial_order};
use crate::bvh::{box_distance_squared, nearest_slot};
use crate::error::KernelError;
use crate::face_point::{FacePoint, SurfaceHit};
use crate::mesh::TargetMesh;
use obvhs::aabb::Aabb;

impl TargetMesh {
    /// The surface point nearest to `point` at most `max_distance` away, or `None`.
    ///
    /// Exact: the same answer as testing every triangle (ties between equidistant triangles may
    /// pick either). `point` must be finite.
    #[must_use]
    pub fn closest_point(&self, point: Vec3, max_distance: f32) -> Option<SurfaceHit> {
        self.closest_point_with_state(point.into(), max_distance, &mut QueryState::default())
    }

    /// [`TargetMesh::closest_point`] starting from `near`, a triangle likely close to the answer
    /// (the last answer for a point that moved a little): the same answer, found faster. `state`
    /// is reused between queries of one thread.
    pub(crate) fn closest_point_near(
        &self,
        point: Vec3,
        max_distance: f32,
        near: u32,
        state: &mut QueryState,
    ) -> Option<SurfaceHit> {
        state.previous_slot = self
            .face_tree_slots
            .get(near as usize)
            .map(|&slot| slot as usize);
        self.closest_point_with_state(point.into(), max_distance, state)
    }

    /// [`TargetMesh::closest_point`] for many points, in parallel.
    ///
    /// # Errors
    /// [`KernelError::NonFinite`] for a NaN or infinite point, [`KernelError::InvalidArgument`] for a
    /// negative or NaN `max_distance`.
    pub fn closest_points(
        &self,
        points: &[Vec3],
        max_distance: f32,
    ) -> Result<Vec<Option<SurfaceHit>>, KernelError> {
        check_finite("point", points)?;
        check_max_distance(max_distance)?;
        Ok(map_in_spatial_order(
            points,
            QueryState::default,
            |state, index| self.closest_point_with_state(points[index].into(), max_distance, state),
        ))
    }

    /// Closest point on the triangle in BVH slot `slot`, and its barycentric coordinates.
    #[inline]
    fn closest_point_in_slot(&self, point: Vec3A, slot: usize) -> (Vec3A, Vec3A) {
        let [a, b, c] = self.face_tree_corners[slot];
        if self.face_tree_degenerate[slot] {
            closest_point_on_degenerate_triangle(point, a, b, c)
        } else {
            closest_point_on_triangle(point, a, b, c)
        }
    }

    fn closest_point_with_state(
        &self,
        point: Vec3A,
        max_distance: f32,
        state: &mut QueryState,
    ) -> Option<SurfaceHit> {
        let warm_start = state.previous_slot.map(|slot| {
            (
                slot,
                self.closest_point_in_slot(point, slot)
                    .0
                    .distance_squared(point),
            )
        });
        let (slot, distance_squared) = nearest_slot(
            &self.face_tree,
            point,
            (max_distance * max_distance).next_up(),
            warm_start,
            &mut state.stack,
            |slot, best_distance_squared| {
                // The triangle's own box is a cheap, branch-free lower bound: skip the exact
                // test when it cannot win (a third of the tests on a 1M-triangle mesh).
                let [a, b, c] = self.face_tree_corners[slot];
                let lower_bound =
                    box_distance_squared(&Aabb::new(a.min(b).min(c), a.max(b).max(c)), point);
                if lower_bound >= best_distance_squared {
                    return f32::INFINITY;
                }
                self.closest_point_in_slot(point, slot)
                    .0
                    .distance_squared(point)
            },
        )?;
        state.previous_slot = Some(slot);
        let (closest, barycentric) = self.closest_point_in_slot(point, slot);
        Some(SurfaceHit {
            face_point: FacePoint {
                triangle: self.face_tree.primitive_indices[slot],
                barycentric: barycentric.into(),
            },
            position: closest.into(),
            distance: distance_squared.sqrt(),
        })
    }
}
