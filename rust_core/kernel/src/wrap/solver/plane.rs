//! The plane constraint: layout vertices held on a plane (a mirrored layout's seam), walked onto it
//! along the target and kept there.

use super::*;

impl WrapSolver {
    /// Holds layout vertices on a plane (a mirrored layout's seam; paper, section 3): a held
    /// point moves within the plane (or, without sliding, a held face-point stays where it
    /// starts) and at the landing is walked onto the target's cross-section with the plane.
    /// Anchored vertices keep their anchors.
    ///
    /// # Errors
    /// [`KernelError::NonFinite`] or [`KernelError::CoordinateOutOfRange`] for the plane's point
    /// or normal, [`KernelError::BeyondReach`] for a plane that passes beyond the region the wrap
    /// can reach, [`KernelError::InvalidArgument`] for a zero normal, a vertex that does not
    /// exist, or a vertex also held by a curve constraint.
    pub fn with_plane_constraint(
        mut self,
        constraint: &PlaneConstraint,
    ) -> Result<Self, KernelError> {
        let plane = Plane::new(constraint.point, constraint.normal)?;
        // A plane that passes beyond the region the wrap can reach cannot hold anything.
        let (centre, reach) = self.reach;
        let distance = plane.distance(centre).abs();
        if distance > reach {
            return Err(KernelError::BeyondReach {
                what: "plane",
                index: 0,
                distance,
                reach,
            });
        }
        let mut on_plane = vec![false; self.points.len()];
        for &vertex in &constraint.vertices {
            let invalid = |reason: String| KernelError::InvalidArgument {
                name: "plane constraint",
                reason,
            };
            if vertex as usize >= self.points.len() {
                return Err(invalid(format!(
                    "vertex {vertex} does not exist (the layout has {} vertices)",
                    self.points.len()
                )));
            }
            if self.anchor_of_vertex[vertex as usize].is_some() {
                continue;
            }
            if self
                .curve_target_of_vertex
                .get(vertex as usize)
                .is_some_and(Option::is_some)
            {
                return Err(invalid(format!(
                    "vertex {vertex} is also held by a curve constraint"
                )));
            }
            on_plane[vertex as usize] = true;
        }
        // Held points start on the plane: the energy's first look at the seam is where it stays.
        for (vertex, _) in on_plane.iter().enumerate().filter(|(_, held)| **held) {
            let (point, position) = match self.points[vertex] {
                LayoutPoint::Face(face_point) => match self.walk_onto_plane(&plane, face_point) {
                    Some((face_point, position)) => (LayoutPoint::Face(face_point), position),
                    None => {
                        let position = plane.project(self.positions[vertex]);
                        (LayoutPoint::Space(position), position)
                    }
                },
                LayoutPoint::Space(position) => {
                    let position = plane.project(position);
                    (LayoutPoint::Space(position), position)
                }
            };
            self.points[vertex] = point;
            self.positions[vertex] = position;
        }
        self.plane = Some(plane);
        self.plane_slide = constraint.slide;
        self.on_plane = on_plane;
        Ok(self)
    }

    /// Whether `vertex` is held on the plane.
    pub(super) fn is_on_plane(&self, vertex: u32) -> bool {
        self.on_plane.get(vertex as usize).copied().unwrap_or(false)
    }

    /// Walks a face-point onto the plane along the surface (across the cross-section): `None`
    /// when the walk leaves the surface (a hole) or the surface runs along the plane there.
    pub(super) fn walk_onto_plane(
        &self,
        plane: &Plane,
        start: FacePoint,
    ) -> Option<(FacePoint, Vec3)> {
        let tolerance = ON_PLANE * self.layout_size;
        let mut face_point = start;
        let mut position = self
            .target
            .interpolate(face_point.triangle, face_point.barycentric);
        for _ in 0..PLANE_WALKS {
            let distance = plane.distance(position);
            if distance.abs() <= tolerance {
                return Some((face_point, position));
            }
            let normal = self.target.face_normals()[face_point.triangle as usize];
            // The steepest way across the plane on the surface; walking `across * t` changes the
            // distance by `t |across|²`.
            let across = plane.normal - normal * plane.normal.dot(normal);
            let rate = across.length_squared();
            if rate < PLANE_GRAZING {
                return None;
            }
            let step = across * (-distance / rate);
            let step = step.clamp_length_max(distance.abs() * 4.0 + self.landing_distance);
            match self.walk(face_point, step) {
                WalkEnd::OnSurface(moved) if !self.is_unreliable(moved.triangle) => {
                    face_point = moved;
                    position = self.target.interpolate(moved.triangle, moved.barycentric);
                }
                _ => return None,
            }
        }
        (plane.distance(position).abs() <= tolerance * 100.0).then_some((face_point, position))
    }

    /// Walks on the target, stopping at unreliable regions as at holes.
    fn walk(&self, start: FacePoint, displacement: Vec3) -> WalkEnd {
        match &self.walk_neighbors {
            Some(neighbors) => self.target.walk_on(neighbors, start, displacement),
            None => self.target.walk(start, displacement),
        }
    }

    /// Whether points on `triangle` must behave as space-points.
    fn is_unreliable(&self, triangle: u32) -> bool {
        self.unreliable
            .get(triangle as usize)
            .copied()
            .unwrap_or(false)
    }
}
