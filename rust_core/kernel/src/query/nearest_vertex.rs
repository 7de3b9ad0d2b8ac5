//! Nearest mesh vertex (the paper's fast vertex tree).

use glam::{Vec3, Vec3A};
use rayon::prelude::*;

use super::{QUERIES_PER_TASK, check_finite, check_max_distance};
use crate::bvh::{NearestStack, nearest_slot};
use crate::error::KernelError;
use crate::face_point::{FacePoint, VertexHit};
use crate::mesh::TargetMesh;

impl TargetMesh {
    /// The vertex nearest to `point` closer than `max_distance`, among vertices used by a
    /// non-degenerate triangle, as a face-point at that vertex; or `None`.
    #[must_use]
    pub fn nearest_vertex(&self, point: Vec3, max_distance: f32) -> Option<VertexHit> {
        self.nearest_vertex_with_stack(point.into(), max_distance, &mut NearestStack::new())
    }

    /// [`TargetMesh::nearest_vertex`] for many points, in parallel.
    ///
    /// # Errors
    /// [`KernelError::NonFinite`] for a NaN or infinite point, [`KernelError::InvalidArgument`] for a
    /// negative or NaN `max_distance`.
    pub fn nearest_vertices(
        &self,
        points: &[Vec3],
        max_distance: f32,
    ) -> Result<Vec<Option<VertexHit>>, KernelError> {
        check_finite("point", points)?;
        check_max_distance(max_distance)?;
        Ok(points
            .par_iter()
            .with_min_len(QUERIES_PER_TASK)
            .map_init(NearestStack::new, |stack, &point| {
                self.nearest_vertex_with_stack(point.into(), max_distance, stack)
            })
            .collect())
    }

    fn nearest_vertex_with_stack(
        &self,
        point: Vec3A,
        max_distance: f32,
        stack: &mut NearestStack,
    ) -> Option<VertexHit> {
        let points = &self.vertex_tree_points;
        let (slot, distance_squared) = nearest_slot(
            &self.vertex_tree,
            point,
            max_distance * max_distance,
            stack,
            |slot| points[slot].distance_squared(point),
        )?;
        let vertex = self.vertex_tree_vertices[slot];
        let (triangle, corner) = self.vertex_triangle[vertex as usize];
        let mut barycentric = Vec3::ZERO;
        barycentric[usize::from(corner)] = 1.0;
        Some(VertexHit {
            vertex,
            face_point: FacePoint {
                triangle,
                barycentric,
            },
            position: points[slot].into(),
            distance: distance_squared.sqrt(),
        })
    }
}
