//! Nearest mesh vertex (the paper's fast vertex tree).

use glam::{Vec3, Vec3A};

use super::{QueryState, check_finite, check_max_distance, map_in_spatial_order};
use crate::bvh::{nearest_slot, search_slots};
use crate::error::KernelError;
use crate::face_point::{FacePoint, VertexHit};
use crate::mesh::TargetMesh;

impl TargetMesh {
    /// The vertex nearest to `point` at most `max_distance` away, among vertices used by a
    /// non-degenerate triangle, as a face-point at that vertex; or `None`.
    #[must_use]
    ///
    /// A point [`TargetMesh::nearest_vertices`] would refuse (NaN, infinite, beyond
    /// [`crate::MAX_COORDINATE`]) or a NaN or negative `max_distance` finds nothing.
    pub fn nearest_vertex(&self, point: Vec3, max_distance: f32) -> Option<VertexHit> {
        if !super::is_query(point, max_distance) {
            return None;
        }
        self.nearest_vertex_with_state(point.into(), max_distance, &mut QueryState::default())
    }

    /// [`TargetMesh::nearest_vertex`] for many points, in parallel.
    ///
    /// # Errors
    /// [`KernelError::NonFinite`] for a NaN or infinite point,
    /// [`KernelError::CoordinateOutOfRange`] for one beyond [`crate::MAX_COORDINATE`], [`KernelError::InvalidArgument`] for a
    /// negative or NaN `max_distance`.
    pub fn nearest_vertices(
        &self,
        points: &[Vec3],
        max_distance: f32,
    ) -> Result<Vec<Option<VertexHit>>, KernelError> {
        check_finite("point", points)?;
        check_max_distance(max_distance)?;
        self.vertex_tree();
        Ok(map_in_spatial_order(
            points,
            QueryState::default,
            |state, index| {
                self.nearest_vertex_with_state(points[index].into(), max_distance, state)
            },
        ))
    }

    fn nearest_vertex_with_state(
        &self,
        point: Vec3A,
        max_distance: f32,
        state: &mut QueryState,
    ) -> Option<VertexHit> {
        let vertex_tree = self.vertex_tree();
        let points = &vertex_tree.points;
        let warm_start = state
            .previous_slot
            .map(|slot| (slot, points[slot].distance_squared(point)));
        let (slot, distance_squared) = nearest_slot(
            &vertex_tree.tree,
            point,
            (max_distance * max_distance).next_up(),
            warm_start,
            &mut state.stack,
            search_slots(|slot, _| points[slot].distance_squared(point)),
        )?;
        state.previous_slot = Some(slot);
        let vertex = vertex_tree.vertices[slot];
        let (triangle, corner) = vertex_tree.vertex_triangle[vertex as usize];
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
