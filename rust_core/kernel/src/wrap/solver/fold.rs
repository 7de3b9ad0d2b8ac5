//! Folding a space-point around its face-point neighbours onto the surface.

use super::*;

impl WrapSolver {
    /// Folding of a space-point at `position` around its face-point neighbours (the seeds):
    /// `None` when it has none.
    ///
    /// Each seed gives a fold: land (the marched point is within the tolerance) or a rotation.
    /// The point lands by the seed with the smallest angle; otherwise it moves to the mean of the
    /// rotated positions. Using every seed keeps the fold continuous: with only the nearest one it
    /// jumps when two neighbours swap places, and the point rocks between two positions.
    pub(super) fn fold(&self, vertex: u32, position: Vec3) -> Option<(LayoutPoint, Vec3, Event)> {
        let layout_normal = self
            .structure
            .normal_at(&self.positions, vertex)
            .normalize_or_zero();
        let mut seeds = 0usize;
        let mut best_landing: Option<(f32, FacePoint, Vec3)> = None;
        let mut rotated_sum = Vec3::ZERO;
        for &other in self.structure.neighbors_of(vertex) {
            let LayoutPoint::Face(seed) = self.points[other as usize] else {
                continue;
            };
            seeds += 1;
            match self.fold_from(
                seed,
                self.positions[other as usize],
                position,
                layout_normal,
            ) {
                Fold::Land {
                    angle,
                    face_point,
                    position: landed,
                } => {
                    if best_landing.is_none_or(|(best, _, _)| angle < best) {
                        best_landing = Some((angle, face_point, landed));
                    }
                    rotated_sum += landed;
                }
                Fold::Rotate(rotated) => rotated_sum += rotated,
                Fold::Stay => rotated_sum += position,
            }
        }
        if seeds == 0 {
            return None;
        }
        if let Some((_, face_point, landed)) = best_landing {
            return Some((LayoutPoint::Face(face_point), landed, Event::Folded));
        }
        let rotated = rotated_sum / seeds as f32;
        Some((LayoutPoint::Space(rotated), rotated, Event::FoldCandidate))
    }

    /// The fold of a space-point at `position` around one seed (paper, section 2.5): its offset
    /// from the seed, projected on the seed's tangent plane, is marched along the surface.
    fn fold_from(
        &self,
        seed: FacePoint,
        seed_position: Vec3,
        position: Vec3,
        layout_normal: Vec3,
    ) -> Fold {
        let offset = position - seed_position;
        let length = offset.length();
        let normal = self.target.face_normals()[seed.triangle as usize];
        // A vertex of no face (a loose curve) has no facing to check.
        if layout_normal != Vec3::ZERO
            && self.orientation != 0.0
            && layout_normal.dot(normal) * self.orientation < FOLD_MIN_FACING
        {
            return Fold::Stay;
        }
        let along = (offset - normal * offset.dot(normal)).normalize_or_zero();
        if length == 0.0 || along == Vec3::ZERO {
            return Fold::Stay;
        }
        let (folded_point, folded_position) = match self.walk(seed, along * length) {
            WalkEnd::OnSurface(face_point) => (
                // Never land on unreliable data: the fold target then only guides the rotation.
                (!self.is_unreliable(face_point.triangle)).then_some(face_point),
                self.target
                    .interpolate(face_point.triangle, face_point.barycentric),
            ),
            // A hole on the way: the fold target floats in space (paper, section 2.5).
            WalkEnd::Lifted { position, .. } => (None, position),
        };
        // A march that did not move at all (it can happen exactly along an edge through vertices)
        // says nothing: the exact closest surface point is the fold target instead.
        let (folded_point, folded_position) =
            if folded_position.distance_squared(seed_position) <= (length * 1e-6).powi(2) {
                match self.target.closest_point(position, length) {
                    Some(hit) if !self.is_unreliable(hit.face_point.triangle) => {
                        (Some(hit.face_point), hit.position)
                    }
                    _ => return Fold::Stay,
                }
            } else {
                (folded_point, folded_position)
            };
        let folded_offset = folded_position - seed_position;
        let angle = offset.angle_between(folded_offset);
        if !angle.is_finite() || angle > FOLD_MAX_ANGLE {
            // Farther than this from the surface's way, the layout turns away from the target on
            // purpose (a mouth bag, an eye socket, a nostril the target has no surface for):
            // folding it flat would crush the region around it.
            return Fold::Stay;
        }
        if angle <= self.fold_tolerance
            && let Some(face_point) = folded_point
        {
            return Fold::Land {
                angle,
                face_point,
                position: folded_position,
            };
        }
        let axis = offset.cross(folded_offset).normalize_or_zero();
        if axis == Vec3::ZERO {
            return Fold::Stay;
        }
        let rotation = Quat::from_axis_angle(axis, angle * self.settings.weights.folding);
        Fold::Rotate(seed_position + rotation * offset)
    }
}

/// What folding around one seed proposes.
enum Fold {
    /// Land there, on the surface (the angle was within the tolerance).
    Land {
        angle: f32,
        face_point: FacePoint,
        position: Vec3,
    },
    /// Rotate toward the fold target, to this position.
    Rotate(Vec3),
    /// No fold: the offset or the march says nothing.
    Stay,
}
