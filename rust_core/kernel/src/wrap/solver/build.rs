//! Building a wrap: the layout, its points and anchors, the settings, the rest shape, per-vertex
//! stiffness, free vertices, soft pairs, unreliable triangles and curve constraints.

use super::*;

impl WrapSolver {
    /// Prepares a wrap of the layout (`structure`, one point per vertex) onto `target`.
    ///
    /// # Errors
    /// [`KernelError::LengthMismatch`] (points vs. layout vertices),
    /// [`KernelError::TriangleIndexOutOfRange`], [`KernelError::NonFinite`] or
    /// [`KernelError::CoordinateOutOfRange`] for a bad point or anchor target (see
    /// [`crate::validate`]), [`KernelError::BeyondReach`] for a space anchor beyond the region the
    /// wrap can reach, [`KernelError::InvalidArgument`] for a layout without edges, a zero-length
    /// edge, a barycentric weight out of range, an anchor on a vertex that does not exist or on
    /// the same vertex twice, or a setting out of range.
    pub fn new(
        target: Arc<TargetMesh>,
        structure: LayoutStructure,
        points: Vec<LayoutPoint>,
        anchors: &[Anchor],
        settings: WrapSettings,
    ) -> Result<Self, KernelError> {
        Self::with_rest_shape(target, structure, points, None, anchors, settings)
    }

    /// Like [`WrapSolver::new`], with the template's shape (the energy's rest shape) given apart from the starting
    /// points: `rest` (one position per layout vertex, in any placement, size and orientation: only
    /// the shape matters) is the template as the artist made it, for a layout that was snapped or
    /// projected since. `None` rests at the starting positions.
    ///
    /// # Errors
    /// As [`WrapSolver::new`]; the zero-length edge check applies to the rest shape, and a rest
    /// shape of the wrong length or with a NaN is refused.
    pub fn with_rest_shape(
        target: Arc<TargetMesh>,
        structure: LayoutStructure,
        points: Vec<LayoutPoint>,
        rest: Option<Vec<Vec3>>,
        anchors: &[Anchor],
        settings: WrapSettings,
    ) -> Result<Self, KernelError> {
        settings.validate()?;
        if points.len() != structure.vertex_count {
            return Err(KernelError::LengthMismatch {
                what: "layout points and layout vertices",
                first: points.len(),
                second: structure.vertex_count,
            });
        }
        if structure.neighbors.is_empty() {
            return Err(KernelError::InvalidArgument {
                name: "layout",
                reason: "it has no edges: there is nothing to wrap".to_owned(),
            });
        }
        let positions = resolve_positions(&target, &points)?;
        let rest = match rest {
            None => positions.clone(),
            Some(rest) => {
                if rest.len() != structure.vertex_count {
                    return Err(KernelError::LengthMismatch {
                        what: "rest positions and layout vertices",
                        first: rest.len(),
                        second: structure.vertex_count,
                    });
                }
                validate::check_coordinates("rest position", &rest)?;
                rest
            }
        };
        for vertex in 0..structure.vertex_count as u32 {
            for &other in structure.neighbors_of(vertex) {
                if other > vertex && rest[vertex as usize] == rest[other as usize] {
                    return Err(KernelError::InvalidArgument {
                        name: "layout",
                        reason: format!(
                            "the edge between vertices {vertex} and {other} has zero length"
                        ),
                    });
                }
            }
        }
        // The landing distance is a fraction of the mean edge length where the points are now
        // (snapping may have made a few edges zero: they do not count).
        let mut edge_length_sum = 0.0f64;
        let mut edge_count = 0usize;
        for vertex in 0..structure.vertex_count as u32 {
            for &other in structure.neighbors_of(vertex) {
                let length = positions[vertex as usize].distance(positions[other as usize]);
                if other > vertex && length > 0.0 {
                    edge_length_sum += f64::from(length);
                    edge_count += 1;
                }
            }
        }
        if edge_count == 0 {
            return Err(KernelError::InvalidArgument {
                name: "layout",
                reason: "all its points are at one place".to_owned(),
            });
        }
        let mean_edge_length = (edge_length_sum / edge_count as f64) as f32;
        // The region the points may reach; constraints beyond it are refused now.
        let reach = {
            let bounds = target.bounds;
            let centre = Vec3::from((bounds.min + bounds.max) * 0.5);
            let target_size = Vec3::from(bounds.max - bounds.min).length();
            let start_size = positions
                .iter()
                .map(|position| position.distance(centre))
                .fold(0.0f32, f32::max);
            (centre, REACH_FACTOR * target_size.max(start_size))
        };
        let anchor_of_vertex = resolve_anchors(&target, structure.vertex_count, anchors, reach)?;
        let (min, max) = positions
            .iter()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(min, max), &p| {
                (min.min(p), max.max(p))
            });
        let layout_size = (max - min).length().max(f32::MIN_POSITIVE);
        let _ = target.face_normals(); // built now rather than inside the first iteration
        Ok(Self {
            target,
            settings,
            landing_distance: settings.landing_distance * mean_edge_length,
            layout_size,
            structure,
            points,
            positions,
            anchor_of_vertex,
            unreliable: Vec::new(),
            walk_neighbors: None,
            curve_target_of_vertex: Vec::new(),
            plane: None,
            on_plane: Vec::new(),
            plane_slide: true,
            total_iterations: 0,
            rest,
            mean_edge_length,
            stiffness: Vec::new(),
            free: Vec::new(),
            soft_pairs: Vec::new(),
            energy: None,
            profile: None,
            reach,
            failed: None,
            settled_start: false,
            region_restart: false,
        })
    }

    /// Says whether the starting points are a wrap's own result, unchanged since, wrapped again with the same
    /// rest shape and target: the wrap then re-settles them from the schedule's last level (no warm-up, no
    /// stiffer levels, which would first undo the fit) when they lie on the target with the anchors and curve
    /// targets met, without a plane or soft pairs, and keeps the whole schedule otherwise, or when the first
    /// iteration moves them far (see `wrap::energy_solver`'s re-settle). Off by default: a layout snapped or
    /// projected onto the target lies on it too, far from settled.
    #[must_use]
    pub fn with_settled_start(mut self, settled: bool) -> Self {
        self.settled_start = settled;
        self
    }

    /// Says whether the wrap re-settles a region of a settled layout started again (every other vertex held where
    /// it is, by anchors): the global-to-local schedule then starts at its second level (the held ring already
    /// places the region as a whole), and a point the safeguard holds back there keeps no data term for the rest of
    /// the wrap (see `wrap::energy_solver`'s region restart); the local schedule runs as without it. Off by default.
    #[must_use]
    pub fn with_region_restart(mut self, restart: bool) -> Self {
        self.region_restart = restart;
        self
    }

    /// Sets how firmly each vertex keeps the template's shape: 0 follows the target freely, 0.5
    /// is the wrap's own balance, 1 keeps the template's shape (no pull toward the target; the
    /// shape terms it owns weigh 100 times more). One value per layout vertex, in [0, 1].
    ///
    /// # Errors
    /// [`KernelError::LengthMismatch`] unless there is one value per layout vertex,
    /// [`KernelError::InvalidArgument`] for a value outside [0, 1] or NaN.
    pub fn with_vertex_stiffness(mut self, stiffness: Vec<f32>) -> Result<Self, KernelError> {
        if stiffness.len() != self.structure.vertex_count {
            return Err(KernelError::LengthMismatch {
                what: "stiffness values and layout vertices",
                first: stiffness.len(),
                second: self.structure.vertex_count,
            });
        }
        if let Some(vertex) = stiffness
            .iter()
            .position(|value| !(0.0..=1.0).contains(value))
        {
            return Err(KernelError::InvalidArgument {
                name: "stiffness",
                reason: format!(
                    "vertex {vertex} has stiffness {}; it must be within 0 … 1",
                    stiffness[vertex]
                ),
            });
        }
        self.stiffness = stiffness;
        Ok(self)
    }

    /// Marks layout vertices as free: no pull toward the target (eye and mouth sockets, teeth,
    /// a region the target does not have); they follow their neighbours by the template's shape
    /// and stay space-points. One flag per layout vertex.
    ///
    /// # Errors
    /// [`KernelError::LengthMismatch`] unless there is one flag per layout vertex.
    pub fn with_free_vertices(mut self, free: Vec<bool>) -> Result<Self, KernelError> {
        if free.len() != self.structure.vertex_count {
            return Err(KernelError::LengthMismatch {
                what: "free vertex flags and layout vertices",
                first: free.len(),
                second: self.structure.vertex_count,
            });
        }
        self.free = free;
        Ok(self)
    }

    /// Adds soft pairs (see [`crate::wrap::soft_pair`]): each pulls its vertex toward its point
    /// in proportion to its confidence during the warm-up and the stiff levels, and lets go
    /// before the local fit, with the global-to-local schedule (the local one leaves them out).
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] for a pair on a vertex that does not exist, that is
    /// anchored or that has another pair, or with a confidence outside (0, 1];
    /// [`KernelError::NonFinite`], [`KernelError::CoordinateOutOfRange`] or
    /// [`KernelError::BeyondReach`] for a bad point.
    pub fn with_soft_pairs(mut self, pairs: &[SoftPair]) -> Result<Self, KernelError> {
        let mut of_vertex = vec![None; self.structure.vertex_count];
        for (index, pair) in pairs.iter().enumerate() {
            let invalid = |reason: String| KernelError::InvalidArgument {
                name: "soft pairs",
                reason,
            };
            let slot = of_vertex.get_mut(pair.vertex as usize).ok_or_else(|| {
                invalid(format!(
                    "soft pair {index} is on vertex {}, but the layout has {} vertices",
                    pair.vertex, self.structure.vertex_count
                ))
            })?;
            if slot.is_some() || self.anchor_of_vertex[pair.vertex as usize].is_some() {
                return Err(invalid(format!(
                    "vertex {} has an anchor or another soft pair already",
                    pair.vertex
                )));
            }
            if !(pair.confidence > 0.0 && pair.confidence <= 1.0) {
                return Err(invalid(format!(
                    "soft pair {index} has confidence {}; it must be within (0, 1]",
                    pair.confidence
                )));
            }
            validate::check_coordinate("soft pair target", index, pair.target)?;
            validate::check_within_reach("soft pair target", index, pair.target, self.reach)?;
            *slot = Some((pair.target, pair.confidence));
        }
        self.soft_pairs = if pairs.is_empty() {
            Vec::new()
        } else {
            of_vertex
        };
        Ok(self)
    }

    /// Marks target triangles as unreliable (noisy or untrusted data, paper 2.5): points there
    /// behave as space-points. Face-points on them are detached now; nothing is drawn onto them
    /// or lands on them. Holes need no marking.
    ///
    /// # Errors
    /// [`KernelError::LengthMismatch`] unless there is one flag per target triangle.
    pub fn with_unreliable_triangles(mut self, unreliable: Vec<bool>) -> Result<Self, KernelError> {
        let triangle_count = self.target.triangles().len();
        if unreliable.len() != triangle_count {
            return Err(KernelError::LengthMismatch {
                what: "unreliable triangle flags and target triangles",
                first: unreliable.len(),
                second: triangle_count,
            });
        }
        for (point, &position) in self.points.iter_mut().zip(&self.positions) {
            if let LayoutPoint::Face(face_point) = point
                && unreliable[face_point.triangle as usize]
            {
                *point = LayoutPoint::Space(position);
            }
        }
        let walk_neighbors = self
            .target
            .triangle_neighbors()
            .iter()
            .map(|neighbors| {
                neighbors.map(|neighbor| {
                    if neighbor != NO_TRIANGLE && unreliable[neighbor as usize] {
                        NO_TRIANGLE
                    } else {
                        neighbor
                    }
                })
            })
            .collect();
        self.walk_neighbors = Some(walk_neighbors);
        self.unreliable = unreliable;
        Ok(self)
    }

    /// Holds layout chains to target curves, matched by arc length (paper, section 2.4): each
    /// chain vertex is pulled to the target point at the same fraction of the curve's length as it
    /// has along the chain *now* (the template's spacing is kept; matching on the moving positions
    /// would feed back on itself), or at the fraction the constraint gives it, and lands on the surface when that point lies on it. Anchored
    /// vertices keep their anchors.
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] for a chain shorter than 2 vertices, a vertex that does not
    /// exist, a vertex in two constraints, a target curve with fewer than 2 points or zero
    /// length, or fractions that are not one per chain vertex from 0 to 1; [`KernelError::NonFinite`], [`KernelError::CoordinateOutOfRange`] or
    /// [`KernelError::BeyondReach`] for a curve point (numbered through all the constraints'
    /// curves, as the binding's `curve_points` rows are).
    pub fn with_curve_constraints(
        mut self,
        constraints: &[CurveConstraint],
    ) -> Result<Self, KernelError> {
        let mut owner: Vec<Option<usize>> = vec![None; self.points.len()];
        let mut targets = vec![None; self.points.len()];
        let mut first_point = 0;
        for (index, constraint) in constraints.iter().enumerate() {
            let invalid = |reason: String| KernelError::InvalidArgument {
                name: "curve constraints",
                reason: format!("curve constraint {index}: {reason}"),
            };
            if constraint.layout_vertices.len() < 2 {
                return Err(invalid(format!(
                    "the layout chain needs at least 2 vertices, it has {}",
                    constraint.layout_vertices.len()
                )));
            }
            for &vertex in &constraint.layout_vertices {
                let slot = owner.get_mut(vertex as usize).ok_or_else(|| {
                    invalid(format!(
                        "vertex {vertex} does not exist (the layout has {} vertices)",
                        self.points.len()
                    ))
                })?;
                if self.anchor_of_vertex[vertex as usize].is_some() {
                    continue;
                }
                if self.is_on_plane(vertex) {
                    return Err(invalid(format!(
                        "vertex {vertex} is also held on the plane constraint"
                    )));
                }
                if let Some(other) = *slot
                    && other != index
                {
                    return Err(invalid(format!(
                        "vertex {vertex} is also in curve constraint {other}"
                    )));
                }
                *slot = Some(index);
            }
            let curve = ArcLengthCurve::new(index, first_point, &constraint.target, self.reach)?;
            first_point += constraint.target.len();
            let chain = &constraint.layout_vertices;
            let fractions = vertex_fractions(index, constraint, &self.positions)?;
            for (&vertex, fraction) in chain.iter().zip(fractions) {
                if self.anchor_of_vertex[vertex as usize].is_none() {
                    targets[vertex as usize] = Some(curve.point_at(fraction));
                }
            }
        }
        self.curve_target_of_vertex = targets;
        Ok(self)
    }
}

/// Positions of layout points; face-points are checked against the target.
fn resolve_positions(
    target: &TargetMesh,
    points: &[LayoutPoint],
) -> Result<Vec<Vec3>, KernelError> {
    for (index, point) in points.iter().enumerate() {
        match point {
            LayoutPoint::Face(face_point) => {
                validate::check_barycentric("barycentric", index, face_point.barycentric)?;
            }
            LayoutPoint::Space(position) => {
                validate::check_coordinate("layout point", index, *position)?;
            }
        }
    }
    let (layout_indices, face_points): (Vec<usize>, Vec<FacePoint>) = points
        .iter()
        .enumerate()
        .filter_map(|(index, point)| match point {
            LayoutPoint::Face(face_point) => Some((index, *face_point)),
            LayoutPoint::Space(_) => None,
        })
        .unzip();
    // Errors name the layout vertex, not the position among the face-points.
    let face_positions =
        target
            .face_point_positions(&face_points)
            .map_err(|error| match error {
                KernelError::TriangleIndexOutOfRange {
                    index,
                    triangle,
                    triangle_count,
                } => KernelError::TriangleIndexOutOfRange {
                    index: layout_indices[index],
                    triangle,
                    triangle_count,
                },
                KernelError::NonFinite { index, .. } => KernelError::NonFinite {
                    what: "barycentric",
                    index: layout_indices[index],
                },
                other => other,
            })?;
    let mut positions = Vec::with_capacity(points.len());
    let mut face_positions = face_positions.into_iter();
    for point in points {
        positions.push(match point {
            LayoutPoint::Face(_) => face_positions.next().unwrap_or(Vec3::ZERO),
            LayoutPoint::Space(position) => *position,
        });
    }
    Ok(positions)
}
