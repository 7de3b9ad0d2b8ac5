//! Exact closest point on the surface (the face tree).

use glam::{Vec3, Vec3A};
use rayon::prelude::*;

use super::point_triangle::{closest_point_on_degenerate_triangle, closest_point_on_triangle};
use super::{QUERIES_PER_TASK, check_finite, check_max_distance};
use crate::bvh::{NearestStack, nearest_slot};
use crate::error::KernelError;
use crate::face_point::{FacePoint, SurfaceHit};
use crate::mesh::TargetMesh;

impl TargetMesh {
    /// The surface point nearest to `point` closer than `max_distance`, or `None`.
    ///
    /// Exact: the same answer as testing every triangle (ties between equidistant triangles may
    /// pick either). `point` must be finite.
    #[must_use]
    pub fn closest_point(&self, point: Vec3, max_distance: f32) -> Option<SurfaceHit> {
        self.closest_point_with_stack(point.into(), max_distance, &mut NearestStack::new())
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
        Ok(points
            .par_iter()
            .with_min_len(QUERIES_PER_TASK)
            .map_init(NearestStack::new, |stack, &point| {
                self.closest_point_with_stack(point.into(), max_distance, stack)
            })
            .collect())
    }

    fn closest_point_with_stack(
        &self,
        point: Vec3A,
        max_distance: f32,
        stack: &mut NearestStack,
    ) -> Option<SurfaceHit> {
        let corners = &self.face_tree_corners;
        let degenerate = &self.face_tree_degenerate;
        let (slot, distance_squared) = nearest_slot(
            &self.face_tree,
            point,
            max_distance * max_distance,
            stack,
            |slot| {
                let [a, b, c] = corners[slot];
                let (closest, _) = if degenerate[slot] {
                    closest_point_on_degenerate_triangle(point, a, b, c)
                } else {
                    closest_point_on_triangle(point, a, b, c)
                };
                closest.distance_squared(point)
            },
        )?;
        let [a, b, c] = corners[slot];
        let (closest, barycentric) = if degenerate[slot] {
            closest_point_on_degenerate_triangle(point, a, b, c)
        } else {
            closest_point_on_triangle(point, a, b, c)
        };
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
