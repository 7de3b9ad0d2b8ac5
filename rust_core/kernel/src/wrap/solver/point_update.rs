//! One point's update: a face-point walks along the surface, a space-point moves in 3D, lands on
//! its anchor or nearby, or folds.

use super::*;

impl WrapSolver {
    /// Walks on the target, stopping at unreliable regions as at holes.
    pub(super) fn walk(&self, start: FacePoint, displacement: Vec3) -> WalkEnd {
        match &self.walk_neighbors {
            Some(neighbors) => self.target.walk_on(neighbors, start, displacement),
            None => self.target.walk(start, displacement),
        }
    }

    /// Whether points on `triangle` must behave as space-points.
    pub(super) fn is_unreliable(&self, triangle: u32) -> bool {
        self.unreliable
            .get(triangle as usize)
            .copied()
            .unwrap_or(false)
    }

    /// The new state and position of one point (reads only the snapshot).
    pub(super) fn update_point(
        &self,
        vertex: u32,
        deviations: &[Vec3],
        curve_target: Option<Vec3>,
    ) -> (LayoutPoint, Vec3, Event) {
        let weights = self.settings.weights;
        let index = vertex as usize;
        let here = self.positions[index];
        let anchor = self.anchor_of_vertex[index];
        if let Some((anchor_target, anchor_position)) = anchor {
            let pinned = match (self.points[index], anchor_target) {
                (LayoutPoint::Face(point), AnchorTarget::Face(target)) => point == target,
                (LayoutPoint::Space(_), AnchorTarget::Space(_)) => here == anchor_position,
                _ => false,
            };
            if pinned {
                // Anchors are constraints: once met, the point stays exactly there.
                return (self.points[index], here, Event::None);
            }
        }
        let constraint_target = anchor.map(|(_, position)| position).or(curve_target);
        let force = if let Some(target_position) = constraint_target {
            // Anchors and curve constraints are constraints: a constrained point heads straight
            // for its target (other forces would hold it at an equilibrium short of it); anchored
            // points are pinned once there.
            (target_position - here) * weights.constraint
        } else {
            let (fairness, arc_length) = self
                .springs
                .line_forces(&self.positions, vertex, self.similarities[index])
                .unwrap_or_else(|| {
                    // Straightening a corner would cut it and shrink the patch; holding it to its
                    // rest offset from its two neighbours does not.
                    if self.is_corner[index] && self.springs.kind() == SpringRest::Even {
                        (Vec3::ZERO, Vec3::ZERO)
                    } else {
                        (deviations[index], Vec3::ZERO)
                    }
                });
            let spring = fairness * weights.fairness + arc_length * weights.arc_length;
            // Adaptive restart: momentum only while the springs still pull the way the point was
            // going; carrying it against them overshoots, and overshoot is what flips quads.
            let velocity = self.velocities[index];
            if spring.dot(velocity) > 0.0 {
                spring + velocity * self.settings.momentum
            } else {
                spring
            }
        };
        if anchor.is_none()
            && self.is_on_plane(vertex)
            && let Some(plane) = &self.plane
        {
            return self.update_on_plane(plane, vertex, force, deviations);
        }
        match self.points[index] {
            LayoutPoint::Face(face_point) => {
                let normal = self.target.face_normals()[face_point.triangle as usize];
                if anchor.is_none() && curve_target.is_none() && self.is_inside_out(vertex, normal)
                {
                    // Pressed onto the surface inside out (a mouth bag snapped onto the lips): it
                    // lifts off, and the springs give the region its shape back.
                    return (LayoutPoint::Space(here), here, Event::Lifted);
                }
                let tangential = (force - normal * force.dot(normal)) * self.step_scales[index];
                match self.walk(face_point, tangential) {
                    WalkEnd::OnSurface(moved) => {
                        let position = self.target.interpolate(moved.triangle, moved.barycentric);
                        if let Some((AnchorTarget::Face(target), anchor_position)) = anchor
                            && anchor_position.distance(position) <= self.landing_distance
                        {
                            return (LayoutPoint::Face(target), anchor_position, Event::Landed);
                        }
                        if self.is_unreliable(moved.triangle) {
                            return (LayoutPoint::Space(position), position, Event::Lifted);
                        }
                        (LayoutPoint::Face(moved), position, Event::None)
                    }
                    WalkEnd::Lifted { position, .. } => {
                        (LayoutPoint::Space(position), position, Event::Lifted)
                    }
                }
            }
            LayoutPoint::Space(_) => {
                let moved = if constraint_target.is_some() {
                    here + force
                } else {
                    here + force
                        + thin_plate(deviations, &self.structure, vertex) * weights.thin_plate
                };
                if let Some((anchor_target, anchor_position)) = anchor
                    && anchor_position.distance(moved) <= self.landing_distance
                {
                    let landed = match anchor_target {
                        AnchorTarget::Face(face_point) => LayoutPoint::Face(face_point),
                        AnchorTarget::Space(_) => LayoutPoint::Space(anchor_position),
                    };
                    return (landed, anchor_position, Event::Landed);
                }
                if let Some(curve_position) = curve_target
                    && curve_position.distance(moved) <= self.landing_distance
                    && let Some(hit) = self
                        .target
                        .closest_point(curve_position, self.landing_distance * ON_CURVE)
                    && !self.is_unreliable(hit.face_point.triangle)
                {
                    // The target curve lies on the surface here: the point lands on it.
                    return (
                        LayoutPoint::Face(hit.face_point),
                        hit.position,
                        Event::Landed,
                    );
                }
                let scale = self.step_scales[index];
                let may_fold = weights.folding > 0.0
                    && constraint_target.is_none()
                    && self.iteration >= self.no_fold_until[index];
                if may_fold
                    && self.iteration.is_multiple_of(PROXIMITY_INTERVAL)
                    && let Some(landed) = self.land_nearby(vertex, moved)
                {
                    return landed;
                }
                if may_fold && let Some(outcome) = self.fold(vertex, moved) {
                    return match outcome {
                        (LayoutPoint::Space(rotated), _, event) => {
                            let scaled = here + (rotated - here) * scale;
                            (LayoutPoint::Space(scaled), scaled, event)
                        }
                        landed => landed,
                    };
                }
                let scaled = here + (moved - here) * scale;
                (LayoutPoint::Space(scaled), scaled, Event::None)
            }
        }
    }

    /// Whether the layout around `vertex` faces against the surface normal `normal` (by more than
    /// [`INSIDE_OUT`]), once the layout's orientation on the target is known.
    fn is_inside_out(&self, vertex: u32, normal: Vec3) -> bool {
        if self.orientation == 0.0 {
            return false;
        }
        let layout_normal = self
            .structure
            .normal_at(&self.positions, vertex)
            .normalize_or_zero();
        layout_normal != Vec3::ZERO && layout_normal.dot(normal) * self.orientation < INSIDE_OUT
    }

    /// A space-point already lying on the surface, facing the way the layout does there, lands
    /// on it at once (the paper: space-points land once close enough): within a tenth of its mean
    /// edge length of the surface, and turned less than 45 degrees from it. Folding alone would
    /// take the points from the anchors one ring at a time; a template aligned on its target is
    /// mostly touching it already.
    fn land_nearby(&self, vertex: u32, position: Vec3) -> Option<(LayoutPoint, Vec3, Event)> {
        if self.orientation == 0.0 {
            return None;
        }
        let neighbors = self.structure.neighbors_of(vertex);
        if neighbors.is_empty() {
            return None;
        }
        let reach = neighbors
            .iter()
            .map(|&other| self.positions[other as usize].distance(position))
            .sum::<f32>()
            / neighbors.len() as f32
            * PROXIMITY_REACH;
        let normal = self
            .structure
            .normal_at(&self.positions, vertex)
            .normalize_or_zero();
        if normal == Vec3::ZERO || reach.is_nan() || reach <= 0.0 {
            return None;
        }
        let hit = self.target.closest_point(position, reach)?;
        let triangle = hit.face_point.triangle;
        if self.is_unreliable(triangle)
            || normal.dot(self.target.face_normals()[triangle as usize]) * self.orientation
                < PROXIMITY_FACING
        {
            return None;
        }
        Some((
            LayoutPoint::Face(hit.face_point),
            hit.position,
            Event::Folded,
        ))
    }
}
