//! Ray casts onto the surface (projection).

use glam::{Vec3, Vec3A};
use obvhs::ray::{Ray, RayHit};

use super::ray_triangle::intersect_ray_triangle;
use super::{check_finite, check_max_distance, map_in_spatial_order};
use crate::error::KernelError;
use crate::face_point::{FacePoint, SurfaceHit};
use crate::mesh::TargetMesh;

impl TargetMesh {
    /// The first surface point along `origin + t * direction` with `|t| <= max_distance`.
    ///
    /// `direction` is normalised first, so `t` is a distance; `direction` must be non-zero and
    /// everything finite and within [`crate::MAX_COORDINATE`] (else it finds nothing). With
    /// `both_directions` the ray is also cast backwards and the nearer hit
    /// wins (a tie goes forwards); the hit's `distance` is the signed `t`.
    #[must_use]
    pub fn ray_cast(
        &self,
        origin: Vec3,
        direction: Vec3,
        max_distance: f32,
        both_directions: bool,
    ) -> Option<SurfaceHit> {
        if !super::is_query(origin, max_distance) || !super::is_query(direction, 0.0) {
            return None;
        }
        let origin = Vec3A::from(origin);
        let direction = Vec3A::from(direction).normalize_or_zero();
        if direction == Vec3A::ZERO {
            return None;
        }
        let forward = self.first_hit(origin, direction, max_distance);
        let backward = if both_directions {
            let limit = forward.map_or(max_distance, |(t, _)| t);
            self.first_hit(origin, -direction, limit)
                .filter(|&(t, _)| forward.is_none_or(|(forward_t, _)| t < forward_t))
                .map(|(t, slot)| (-t, slot))
        } else {
            None
        };
        let (t, slot) = backward.or(forward)?;
        let [a, b, c] = self.face_tree_corners[slot];
        let sign = if t < 0.0 { -1.0 } else { 1.0 };
        let (_, barycentric) =
            intersect_ray_triangle(origin, direction * sign, 0.0, f32::INFINITY, a, b, c)
                .unwrap_or((t.abs(), Vec3A::splat(1.0 / 3.0)));
        let position = a * barycentric.x + b * barycentric.y + c * barycentric.z;
        Some(SurfaceHit {
            face_point: FacePoint {
                triangle: self.face_tree.primitive_indices[slot],
                barycentric: barycentric.into(),
            },
            position: position.into(),
            distance: t,
        })
    }

    /// [`TargetMesh::ray_cast`] for many rays, in parallel.
    ///
    /// # Errors
    /// [`KernelError::LengthMismatch`] if `origins` and `directions` differ in length,
    /// [`KernelError::NonFinite`] for a NaN or infinite origin or direction,
    /// [`KernelError::CoordinateOutOfRange`] for a coordinate beyond [`crate::MAX_COORDINATE`],
    /// [`KernelError::ZeroDirection`] for a zero direction, [`KernelError::InvalidArgument`] for a
    /// negative or NaN `max_distance`.
    pub fn ray_casts(
        &self,
        origins: &[Vec3],
        directions: &[Vec3],
        max_distance: f32,
        both_directions: bool,
    ) -> Result<Vec<Option<SurfaceHit>>, KernelError> {
        if origins.len() != directions.len() {
            return Err(KernelError::LengthMismatch {
                what: "ray origins and directions",
                first: origins.len(),
                second: directions.len(),
            });
        }
        check_finite("ray origin", origins)?;
        check_finite("ray direction", directions)?;
        if let Some(index) = directions
            .iter()
            .position(|direction| direction.normalize_or_zero() == Vec3::ZERO)
        {
            return Err(KernelError::ZeroDirection { index });
        }
        check_max_distance(max_distance)?;
        Ok(map_in_spatial_order(
            origins,
            || (),
            |(), index| {
                self.ray_cast(
                    origins[index],
                    directions[index],
                    max_distance,
                    both_directions,
                )
            },
        ))
    }

    /// Nearest hit `(t, slot)` along a unit direction with `t` in `[0, max_distance]`.
    fn first_hit(
        &self,
        origin: Vec3A,
        direction: Vec3A,
        max_distance: f32,
    ) -> Option<(f32, usize)> {
        let corners = &self.face_tree_corners;
        let degenerate = &self.face_tree_degenerate;
        let ray = Ray::new(origin, direction, 0.0, max_distance.next_up());
        let mut hit = RayHit::none();
        let found = self.face_tree.ray_traverse(ray, &mut hit, |ray, slot| {
            if degenerate[slot] {
                return f32::INFINITY;
            }
            let [a, b, c] = corners[slot];
            intersect_ray_triangle(ray.origin, ray.direction, ray.tmin, ray.tmax, a, b, c)
                .map_or(f32::INFINITY, |(t, _)| t)
        });
        found.then_some((hit.t, hit.primitive_id as usize))
    }
}
