//! The data term: each vertex's closest target point, trusted or not (facing, not on a hole's border or an
//! unreliable triangle), its tangent-plane projection and robust weight; the target's smoothed normals.

use super::*;

impl EnergySolver {
    /// Per free vertex, its correspondence, or `None`; the closest-point queries start from each
    /// vertex's last hit (and record the new one). `stop` is asked before each batch of
    /// [`QUERIES_PER_CHECK`] queries.
    pub(super) fn correspondences(
        &mut self,
        normals: &[Vec3],
        width: f32,
        stop: Stop<'_>,
    ) -> Result<Vec<Option<Correspondence>>, KernelError> {
        if width <= 0.0 {
            return Ok(vec![None; self.positions.len()]); // folding off: nothing is drawn on
        }
        let mut found: Vec<(Option<Correspondence>, u32)> =
            Vec::with_capacity(self.positions.len());
        for batch in (0..self.positions.len()).step_by(QUERIES_PER_CHECK) {
            check(stop, WRAP_STEP)?;
            let end = (batch + QUERIES_PER_CHECK).min(self.positions.len());
            found.extend(self.correspondence_batch(normals, width, batch..end));
        }
        let mut correspondences = Vec::with_capacity(found.len());
        for (vertex, (correspondence, triangle)) in found.into_iter().enumerate() {
            if triangle != NO_TRIANGLE {
                self.last_hits[vertex] = triangle;
            }
            correspondences.push(correspondence);
        }
        Ok(correspondences)
    }

    /// The correspondences of the vertices in `vertices`, each with its hit's triangle.
    fn correspondence_batch(
        &self,
        normals: &[Vec3],
        width: f32,
        vertices: std::ops::Range<usize>,
    ) -> Vec<(Option<Correspondence>, u32)> {
        vertices
            .into_par_iter()
            .with_min_len(256)
            .map_init(QueryState::default, |state, vertex| {
                if self.fixed[vertex].is_some() || self.data_factors[vertex] == 0.0 {
                    return (None, NO_TRIANGLE);
                }
                let position = self.positions[vertex];
                let Some(hit) = self.target.closest_point_near(
                    position,
                    width * 3.0,
                    self.last_hits[vertex],
                    state,
                ) else {
                    return (None, NO_TRIANGLE);
                };
                let triangle = hit.face_point.triangle;
                if !self.correspondence_trusted(&hit, normals[vertex]) {
                    return (None, triangle);
                }
                let normal = self.smoothed_normal(hit.face_point);
                let weight = (-(hit.distance * hit.distance) / (2.0 * width * width)).exp()
                    * self.data_factors[vertex]
                    * self.facing_weight(normals[vertex], normal);
                let face_normal = self.target.face_normals()[triangle as usize];
                // The tangent plane of the triangle itself: the point is pulled onto the surface,
                // not onto a smoothed plane beside it.
                let plane_normal = if face_normal == Vec3::ZERO {
                    normal
                } else {
                    face_normal
                };
                let mut projected =
                    position - plane_normal * plane_normal.dot(position - hit.position);
                if let Some(plane) = self.plane
                    && self.on_plane.get(vertex).copied().unwrap_or(false)
                {
                    projected = plane.project(projected);
                }
                (Some((weight, projected)), triangle)
            })
            .collect()
    }

    /// Whether a closest-point hit may pull or receive a point whose layout normal is `normal`:
    /// not on an unreliable triangle, not on a boundary edge (a hole), and facing the way of the
    /// target's smoothed normal there.
    pub(super) fn correspondence_trusted(&self, hit: &SurfaceHit, normal: Vec3) -> bool {
        self.surface_trusted(hit, normal, MIN_FACING)
    }

    /// [`Self::correspondence_trusted`] with the facing cosine `min_facing`.
    pub(super) fn surface_trusted(&self, hit: &SurfaceHit, normal: Vec3, min_facing: f32) -> bool {
        let triangle = hit.face_point.triangle;
        if is_flagged(&self.unreliable, triangle) {
            return false;
        }
        let neighbors = self.target.triangle_neighbors()[triangle as usize];
        let barycentric = hit.face_point.barycentric.to_array();
        // Edge e runs from corner e to corner e + 1: on it, the weight of corner e + 2 is 0.
        if (0..3).any(|edge| neighbors[edge] == NO_TRIANGLE && barycentric[(edge + 2) % 3] <= 1e-5)
        {
            return false;
        }
        if normal == Vec3::ZERO {
            return true;
        }
        let surface_normal = self.smoothed_normal(hit.face_point);
        normal.dot(surface_normal) * self.orientation >= min_facing
    }

    /// The factor on a correspondence's weight for how the layout normal `normal` faces the
    /// target's smoothed normal `surface_normal` there: their cosine in the global-to-local
    /// schedule (1 when either is degenerate), 1 in the local schedule.
    ///
    /// With few anchors on a heavy body the quads that end flipped against the true layout lie in
    /// the creases under the chest and the belly, where the true surface turns 60 to 90 degrees
    /// from the template's: the wrap leaves them about two edges off their true place, on a part
    /// of the crease that faces 100 to 120 degrees from their true normal, nearly perpendicular to
    /// the truth, and the strong local levels' full pull onto that tilted surface turns them past
    /// it (they face the target where they lie: no test against the target's normals sees them).
    /// A pull weighted by how well the layout faces the surface there tilts them less. Measured
    /// with 6 anchors (`benchmarks/retarget`'s `Springwrap wrap`, global to local, one run each
    /// way; mean % of the diagonal and flipped quads on the heavy, heavy-old, old-male and
    /// young-female bodies): from 0.243, 0.473, 0.447, 0.347 and 7, 4, 0, 3 flipped to 0.241,
    /// 0.465, 0.441, 0.348 and 7, 2, 0, 3 (p95 of young-female 1.198 to 1.147; an earlier kernel:
    /// heavy 8 to 6 flipped, with 4 anchors old-male 1.044 to 0.983). The
    /// square of the cosine, a hard cut at 0.7 instead of 0.5, or a test against the hit
    /// triangle's own normal were worse; in the local schedule (24 anchors) the weighting was
    /// worse on every body but heavy (old-male 0.348 to 0.357, 1 to 12 flipped), so it has none.
    ///
    /// What is left on the heavy body with 6 anchors (`benchmarks/flip_diagnosis.py`): 7 quads
    /// flipped against the truth where the aligned template flips 4. Two are flipped by the
    /// template too (true quads 17 times smaller than the wrap's, facing 169 degrees from the
    /// target). The other five, two under the chest and three in the fold below the belly, lie
    /// flat on the surface (2 to 23 degrees from the target's normal, 4 to 36 from the template's
    /// quad) 0.5 to 0.8 % of the diagonal from their true place; their true quads straddle the
    /// crease, 57 to 77 degrees from the target under them, with corners 0.1 to 0.32 % of the
    /// diagonal inside the target (the morph's crease folds into itself, the voxel remesh fills
    /// it; over the whole truth the mean distance is 0.06 %). The truth's corners moved to their
    /// closest target points keep those five (it flips 50 others, small quads elsewhere): they
    /// flip because the wrap slides them about two edges along the crease, not because they lie
    /// on the surface, and they face the target and their template where they end, so no test
    /// of the wrap's own normals sees them. Measured and not kept (one run
    /// each; heavy and heavy-old mean % and flipped, from 0.241, 0.465 and 7, 2): the local
    /// levels' least alignment 0.3 or 0 (0.241, 0.472 to 0.476 and 9, 7 to 22); a landing
    /// refused where a corner turns past 60 or 90 degrees from where it stood (unchanged); no
    /// landing at all (0.240, 0.465 and 7, 1); a facing cut of 0.2 in the local levels (0.268,
    /// 0.473 and 8, 2); no pull where the hit triangle's normal is more than 30 to 70 degrees
    /// from the smoothed one (heavy 6 to 7 flipped, heavy-old 0.454 to 0.475, old-male 0 to 6
    /// flipped at the cut that helped heavy-old); the local levels' last iterations, data weight
    /// or scale smoothing changed (0.240 to 0.241, 0.465 to 0.466 and 7 to 8, 1 to 4).
    pub(super) fn facing_weight(&self, normal: Vec3, surface_normal: Vec3) -> f32 {
        if self.stretches.is_none() || normal == Vec3::ZERO || surface_normal == Vec3::ZERO {
            return 1.0;
        }
        (normal.dot(surface_normal) * self.orientation).clamp(0.0, 1.0)
    }

    /// The target's smoothed normal at a face-point.
    pub(super) fn smoothed_normal(&self, face_point: FacePoint) -> Vec3 {
        let corners = self.target.triangles()[face_point.triangle as usize];
        let weights = face_point.barycentric;
        (self.smoothed_normals[corners[0] as usize] * weights.x
            + self.smoothed_normals[corners[1] as usize] * weights.y
            + self.smoothed_normals[corners[2] as usize] * weights.z)
            .normalize_or_zero()
    }
}

/// The target's vertex normals averaged over a neighbourhood about `radius` wide (rounds of
/// vertex → triangle → vertex averaging, as many as `(radius / mean target edge)²`).
pub(super) fn smoothed_vertex_normals(target: &TargetMesh, radius: f32) -> Vec<Vec3> {
    let vertices = target.vertices();
    let triangles = target.triangles();
    let mut normals = target.vertex_normals().to_vec();
    let edge_sum: f64 = ordered_sum(triangles.len(), |triangle| {
        let corners = triangles[triangle];
        f64::from(vertices[corners[0] as usize].distance(vertices[corners[1] as usize]))
    });
    let target_edge = (edge_sum / triangles.len().max(1) as f64) as f32;
    let ratio = if target_edge > 0.0 {
        radius / target_edge
    } else {
        1.0
    };
    let rounds =
        ((ratio * ratio) as usize).clamp(NORMAL_SMOOTHING_ROUNDS.0, NORMAL_SMOOTHING_ROUNDS.1);
    let mut triangle_normals = vec![Vec3::ZERO; triangles.len()];
    for _ in 0..rounds {
        triangle_normals
            .par_iter_mut()
            .with_min_len(4096)
            .zip(triangles.par_iter())
            .for_each(|(normal, corners)| {
                *normal = corners.iter().map(|&corner| normals[corner as usize]).sum();
            });
        let mut sums = vec![Vec3::ZERO; vertices.len()];
        for (corners, normal) in triangles.iter().zip(&triangle_normals) {
            for &corner in corners {
                sums[corner as usize] += *normal;
            }
        }
        normals = sums
            .into_iter()
            .zip(&normals)
            .map(|(sum, old)| {
                let smoothed = sum.normalize_or_zero();
                if smoothed == Vec3::ZERO {
                    *old
                } else {
                    smoothed
                }
            })
            .collect();
    }
    normals
}
