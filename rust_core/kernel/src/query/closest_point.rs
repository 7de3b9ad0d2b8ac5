//! Exact closest point on the surface (the face tree).

use glam::{Vec3, Vec3A, Vec4};

use super::point_triangle::{closest_point_on_degenerate_triangle, closest_point_on_triangle};
use rayon::prelude::*;

use super::{QUERIES_PER_TASK, QueryState, check_finite, check_max_distance, map_in_spatial_order};
use crate::bvh::nearest_slot;
use crate::error::KernelError;
use crate::face_point::{FacePoint, SurfaceHit};
use crate::mesh::TargetMesh;

impl TargetMesh {
    /// The surface point nearest to `point` at most `max_distance` away, or `None`.
    ///
    /// Exact: the same answer as testing every triangle (ties between equidistant triangles may
    /// pick either). A point [`TargetMesh::closest_points`] would refuse (NaN, infinite, beyond
    /// [`crate::MAX_COORDINATE`]) or a NaN or negative `max_distance` finds nothing.
    #[must_use]
    pub fn closest_point(&self, point: Vec3, max_distance: f32) -> Option<SurfaceHit> {
        if !super::is_query(point, max_distance) {
            return None;
        }
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
    /// [`KernelError::NonFinite`] for a NaN or infinite point,
    /// [`KernelError::CoordinateOutOfRange`] for one beyond [`crate::MAX_COORDINATE`], [`KernelError::InvalidArgument`] for a
    /// negative or NaN `max_distance`.
    pub fn closest_points(
        &self,
        points: &[Vec3],
        max_distance: f32,
    ) -> Result<Vec<Option<SurfaceHit>>, KernelError> {
        check_finite("point", points)?;
        check_max_distance(max_distance)?;
        self.closest_tree();
        Ok(map_in_spatial_order(
            points,
            QueryState::default,
            |state, index| self.closest_point_with_state(points[index].into(), max_distance, state),
        ))
    }

    /// [`TargetMesh::closest_point`] for many points, each started from `near[i]`, a triangle
    /// likely close to its answer (the previous answer for a point that moved a little, as in the
    /// wrap solver): the same answers as [`TargetMesh::closest_points`], in the caller's order
    /// (no spatial sort: a caller with warm starts already knows where to look). A `near` that is
    /// not a triangle index (such as [`crate::NO_TRIANGLE`]) means no warm start.
    ///
    /// # Errors
    /// As [`TargetMesh::closest_points`], and [`KernelError::LengthMismatch`] when `near` and
    /// `points` differ in length.
    pub fn closest_points_near(
        &self,
        points: &[Vec3],
        max_distance: f32,
        near: &[u32],
    ) -> Result<Vec<Option<SurfaceHit>>, KernelError> {
        check_finite("point", points)?;
        check_max_distance(max_distance)?;
        if near.len() != points.len() {
            return Err(KernelError::LengthMismatch {
                what: "points and near triangles",
                first: points.len(),
                second: near.len(),
            });
        }
        self.closest_tree();
        Ok((0..points.len())
            .into_par_iter()
            .with_min_len(QUERIES_PER_TASK)
            .map_init(QueryState::default, |state, index| {
                self.closest_point_near(points[index], max_distance, near[index], state)
            })
            .collect())
    }

    /// Closest point on the triangle in BVH slot `slot`, and its barycentric coordinates.
    #[inline]
    fn closest_point_in_slot(&self, point: Vec3A, slot: usize) -> (Vec3A, Vec3A) {
        let [a, b, c] = self.slot_corners(slot);
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
        // The closest point and barycentric coordinates on the best triangle so far, kept so
        // that the answer needs no second exact test.
        let mut best_hit = (Vec3A::ZERO, Vec3A::ZERO);
        let warm_start = state.previous_slot.map(|slot| {
            best_hit = self.closest_point_in_slot(point, slot);
            (slot, best_hit.0.distance_squared(point))
        });
        // The SIMD estimates may differ from the exact test by rounding: a triangle is tested
        // exactly when its estimate is within this margin of the best distance so far.
        let margin = 64.0 * f32::EPSILON * (point.abs().max_element() + self.coordinate_scale);
        let reach = |best_distance_squared: f32| {
            let distance = best_distance_squared.sqrt() + margin;
            distance * distance
        };
        let (x, y, z) = (
            Vec4::splat(point.x),
            Vec4::splat(point.y),
            Vec4::splat(point.z),
        );
        let closest_tree = self.closest_tree();
        let (slot, distance_squared) = nearest_slot(
            &closest_tree.tree,
            point,
            (max_distance * max_distance).next_up(),
            warm_start,
            &mut state.stack,
            |first, count, mut best_distance_squared| {
                let mut found = None;
                for packet in &closest_tree.packets[first..first + count] {
                    let estimates = packet.distances_squared(x, y, z);
                    let mut candidates = estimates
                        .cmplt(Vec4::splat(reach(best_distance_squared)))
                        .bitmask();
                    while candidates != 0 {
                        let lane = candidates.trailing_zeros() as usize;
                        candidates &= candidates - 1;
                        if estimates[lane] >= reach(best_distance_squared) {
                            continue;
                        }
                        let slot = packet.first_slot as usize + lane;
                        let hit = self.closest_point_in_slot(point, slot);
                        let exact = hit.0.distance_squared(point);
                        if exact < best_distance_squared {
                            best_distance_squared = exact;
                            best_hit = hit;
                            found = Some((slot, exact));
                        }
                    }
                }
                found
            },
        )?;
        state.previous_slot = Some(slot);
        let (closest, barycentric) = best_hit;
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
