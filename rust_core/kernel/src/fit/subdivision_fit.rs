//! Fitting a subdivision cage: move the cage so that its subdivided (limit) surface lies on the
//! target, one Gauss–Newton round at a time.
//!
//! A round finds, for every fine point `p_i = S_i x + o_i` (`S` the [`SubdivisionStencils`], `o`
//! an optional offset per fine point: what the caller's exact subdivision adds to the stencils),
//! the closest target point `c_i`, trusts it when it is within the match distance, not on a border
//! of the target (a hole's rim) and the target's normal there faces the fine surface's, and solves
//!
//! `min Σ_trusted w (S_i x + o_i − c_i)² + μ Σ_v |L_v (x − x_prev)|² + ε |x − x_prev|²`
//!
//! with `L` the cage's umbrella Laplacian, the fixed cage vertices eliminated. An *anchored* cage
//! vertex `a` has its own limit point (fine vertex `a`: the cage's vertices come first) pulled to
//! its anchor's point `t_a` by a term `w_anchor |S_a x + o_a − t_a|²` instead of its closest point:
//! the anchor holds where the subdivided surface passes, not the cage vertex (a cage vertex held on
//! the target would dimple the surface around it). The data weight
//! `w = 4^−levels` makes each cage vertex's data about one, whatever the level. The smoothness
//! term asks the *displacement* to be smooth: it vanishes at a fixed point, so it only steers the
//! steps, and cage vertices with no trusted fine point near them (over holes) follow their
//! neighbours' displacement as a thin plate would. One sparse Cholesky factorization a round
//! ([`LinearSystem`], shared by x, y and z).

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::error::KernelError;
use crate::fit::catmull_clark::SubdivisionStencils;
use crate::mesh::{NO_TRIANGLE, TargetMesh};
use crate::wrap::linear_system::{LinearSystem, Stencils};

/// Closest-point queries between two cancellation checks of [`SubdivisionFit::round_until`]: a
/// few milliseconds.
pub const POINTS_PER_CHECK: usize = 1 << 16;

/// One cage vertex's row of the data's normal equations: its diagonal, its pairs with the later
/// vertices, its right-hand side.
type NormalRow = (f64, Vec<(u32, f64)>, DVec3);

/// The fit's parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SubdivisionFitSettings {
    /// `μ`: how strongly each step's displacement is kept smooth, relative to the data (≥ 0).
    pub smoothness: f64,
    /// A fine point farther than this from its closest target point is not matched (world units,
    /// > 0; infinite: no limit).
    pub max_distance: f32,
    /// A match is trusted only when the target's normal there and the fine surface's have at
    /// least this cosine (−1 … 1).
    pub min_facing: f32,
    /// `ε`: the pull of each cage vertex towards where it was (≥ 0, relative to the data weight of
    /// one cage vertex); keeps a cage part with no match and no fixed vertex where it is.
    pub damping: f64,
    /// `w_anchor`: the weight of an anchor's pull on its vertex's limit point, relative to the data
    /// weight of one cage vertex (> 0).
    pub anchor_weight: f64,
}

impl Default for SubdivisionFitSettings {
    fn default() -> Self {
        Self {
            smoothness: 0.1,
            max_distance: f32::INFINITY,
            min_facing: 0.5,
            damping: 1e-6,
            anchor_weight: 100.0,
        }
    }
}

impl SubdivisionFitSettings {
    fn check(&self) -> Result<(), KernelError> {
        let invalid = |name, reason: &str| {
            Err(KernelError::InvalidArgument {
                name,
                reason: reason.to_owned(),
            })
        };
        if !(self.smoothness.is_finite() && self.smoothness >= 0.0) {
            return invalid("smoothness", "must be a finite number >= 0");
        }
        if self.max_distance.is_nan() || self.max_distance <= 0.0 {
            return invalid("max_distance", "must be > 0 (infinite for no limit)");
        }
        if !(-1.0..=1.0).contains(&self.min_facing) {
            return invalid("min_facing", "must be a cosine from -1 to 1");
        }
        if !(self.damping.is_finite() && self.damping >= 0.0) {
            return invalid("damping", "must be a finite number >= 0");
        }
        if !(self.anchor_weight.is_finite() && self.anchor_weight > 0.0) {
            return invalid("anchor_weight", "must be a finite number > 0");
        }
        Ok(())
    }
}

/// What a round saw before it moved the cage, and what it did.
#[derive(Debug, Clone, PartialEq)]
pub struct FitRound {
    /// The new cage positions.
    pub positions: Vec<DVec3>,
    /// Per fine vertex, its distance to the target before the round (NaN off the surface or with
    /// no target point within the match distance).
    pub distances: Vec<f32>,
    /// Fine points whose closest-point match was trusted (anchored limit points not counted).
    pub trusted: usize,
}

/// A cage fit in progress: the stencils, the fixed cage vertices and the settings.
#[derive(Debug, Clone)]
pub struct SubdivisionFit {
    stencils: SubdivisionStencils,
    fixed: Vec<bool>,
    settings: SubdivisionFitSettings,
    /// Per cage vertex, its edge neighbours.
    neighbors: Vec<Vec<u32>>,
    /// Per cage vertex, the point its limit point is pulled to, if anchored.
    anchors: Vec<Option<DVec3>>,
    /// The stencils' transpose: per cage vertex, the fine vertices whose stencil has it, and the
    /// coefficient.
    columns: Vec<Vec<(u32, f64)>>,
}

impl SubdivisionFit {
    /// A fit of the cage of `stencils`, `fixed[v]` holding cage vertex `v` where it is (anchors,
    /// vertices left out). Cage vertices on no face are always held.
    ///
    /// # Errors
    /// [`KernelError::LengthMismatch`] when `fixed` has not one flag per cage vertex;
    /// [`KernelError::InvalidArgument`] for settings out of their domain.
    pub fn new(
        stencils: SubdivisionStencils,
        fixed: &[bool],
        settings: SubdivisionFitSettings,
    ) -> Result<Self, KernelError> {
        settings.check()?;
        let cage_vertex_count = stencils.cage_vertex_count();
        if fixed.len() != cage_vertex_count {
            return Err(KernelError::LengthMismatch {
                what: "fixed flags and cage vertices",
                first: fixed.len(),
                second: cage_vertex_count,
            });
        }
        let mut neighbors = vec![Vec::new(); cage_vertex_count];
        for &[a, b] in stencils.cage_edges() {
            neighbors[a as usize].push(b);
            neighbors[b as usize].push(a);
        }
        let fixed = fixed
            .iter()
            .zip(&neighbors)
            .map(|(&fixed, neighbors)| fixed || neighbors.is_empty())
            .collect();
        let mut columns = vec![Vec::new(); cage_vertex_count];
        let matrix = stencils.stencils();
        for fine_vertex in 0..matrix.len() {
            for (vertex, coefficient) in matrix.entries(fine_vertex) {
                columns[vertex as usize].push((fine_vertex as u32, coefficient));
            }
        }
        Ok(Self {
            stencils,
            fixed,
            settings,
            neighbors,
            anchors: vec![None; cage_vertex_count],
            columns,
        })
    }

    /// The fit with anchors: the limit point of cage vertex `vertices[k]` pulled to `points[k]`
    /// (replacing any earlier anchor of that vertex). Anchors of fixed vertices change nothing.
    ///
    /// # Errors
    /// [`KernelError::LengthMismatch`] when the arrays differ in length,
    /// [`KernelError::LayoutIndexOutOfRange`] for a vertex that is not a cage vertex,
    /// [`KernelError::NonFinite`] for a NaN or infinite point.
    pub fn with_anchors(mut self, vertices: &[u32], points: &[DVec3]) -> Result<Self, KernelError> {
        if vertices.len() != points.len() {
            return Err(KernelError::LengthMismatch {
                what: "anchor vertices and anchor points",
                first: vertices.len(),
                second: points.len(),
            });
        }
        for (index, (&vertex, point)) in vertices.iter().zip(points).enumerate() {
            if vertex as usize >= self.anchors.len() {
                return Err(KernelError::LayoutIndexOutOfRange {
                    element: "anchor",
                    index,
                    vertex,
                    vertex_count: self.anchors.len(),
                });
            }
            if !point.is_finite() {
                return Err(KernelError::NonFinite {
                    what: "anchor point",
                    index,
                });
            }
            self.anchors[vertex as usize] = Some(*point);
        }
        Ok(self)
    }

    /// Per cage vertex, the point its limit point is pulled to, if anchored.
    #[must_use]
    pub fn anchors(&self) -> &[Option<DVec3>] {
        &self.anchors
    }

    /// The stencils.
    #[must_use]
    pub fn stencils(&self) -> &SubdivisionStencils {
        &self.stencils
    }

    /// Per cage vertex, whether the fit holds it.
    #[must_use]
    pub fn fixed(&self) -> &[bool] {
        &self.fixed
    }

    fn check_inputs(&self, cage: &[DVec3], offsets: Option<&[DVec3]>) -> Result<(), KernelError> {
        if let Some(index) = cage.iter().position(|point| !point.is_finite()) {
            return Err(KernelError::NonFinite {
                what: "cage position",
                index,
            });
        }
        if let Some(offsets) = offsets {
            if offsets.len() != self.stencils.fine_vertex_count() {
                return Err(KernelError::LengthMismatch {
                    what: "fine offsets and fine vertices",
                    first: offsets.len(),
                    second: self.stencils.fine_vertex_count(),
                });
            }
            if let Some(index) = offsets.iter().position(|offset| !offset.is_finite()) {
                return Err(KernelError::NonFinite {
                    what: "fine offset",
                    index,
                });
            }
        }
        Ok(())
    }

    /// The fine points of `cage` plus `offsets`.
    ///
    /// # Errors
    /// [`KernelError::LengthMismatch`] for arrays of the wrong length, [`KernelError::NonFinite`]
    /// for a NaN or infinite input.
    pub fn fine_points(
        &self,
        cage: &[DVec3],
        offsets: Option<&[DVec3]>,
    ) -> Result<Vec<DVec3>, KernelError> {
        let mut fine = self.stencils.apply(cage)?;
        self.check_inputs(cage, offsets)?;
        if let Some(offsets) = offsets {
            for (point, offset) in fine.iter_mut().zip(offsets) {
                *point += *offset;
            }
        }
        Ok(fine)
    }

    /// Per fine vertex, the distance of the fine point to the target (NaN off the surface, or with
    /// no target point within the match distance).
    ///
    /// # Errors
    /// As [`SubdivisionFit::fine_points`].
    pub fn distances(
        &self,
        target: &TargetMesh,
        cage: &[DVec3],
        offsets: Option<&[DVec3]>,
    ) -> Result<Vec<f32>, KernelError> {
        let fine = self.fine_points(cage, offsets)?;
        let points: Vec<Vec3> = fine.iter().map(|point| point.as_vec3()).collect();
        let hits = target.closest_points(&points, self.settings.max_distance)?;
        Ok(hits
            .iter()
            .zip(self.stencils.on_surface())
            .map(|(hit, &on_surface)| match hit {
                Some(hit) if on_surface => hit.distance,
                _ => f32::NAN,
            })
            .collect())
    }

    /// One Gauss–Newton round from `cage` (see the module's documentation).
    ///
    /// # Errors
    /// As [`SubdivisionFit::fine_points`]; [`KernelError::InvalidArgument`] when the linear system
    /// cannot be factored (out of memory).
    pub fn round(
        &self,
        target: &TargetMesh,
        cage: &[DVec3],
        offsets: Option<&[DVec3]>,
    ) -> Result<FitRound, KernelError> {
        self.round_until(target, cage, offsets, &|| false)
    }

    /// [`SubdivisionFit::round`], asking `stop` (from any thread) between pieces of its long loops
    /// (every [`POINTS_PER_CHECK`] closest points, every cage vertex's normal-equation row, before
    /// the factorization): once it says true the round ends with [`KernelError::Cancelled`]
    /// within about a piece's time, and returns nothing.
    ///
    /// # Errors
    /// As [`SubdivisionFit::round`]; [`KernelError::Cancelled`] when `stop` said true.
    pub fn round_until(
        &self,
        target: &TargetMesh,
        cage: &[DVec3],
        offsets: Option<&[DVec3]>,
        stop: &(dyn Fn() -> bool + Sync),
    ) -> Result<FitRound, KernelError> {
        let cancelled = || {
            if stop() {
                Err(KernelError::Cancelled {
                    what: "subdivision fit round",
                })
            } else {
                Ok(())
            }
        };
        cancelled()?;
        let fine = self.fine_points(cage, offsets)?;
        let points: Vec<Vec3> = fine.iter().map(|point| point.as_vec3()).collect();
        let mut hits = Vec::with_capacity(points.len());
        for piece in points.chunks(POINTS_PER_CHECK) {
            cancelled()?;
            hits.extend(target.closest_points(piece, self.settings.max_distance)?);
        }
        cancelled()?;
        let normals = self.stencils.fine_normals(&fine);
        let target_normals = target.vertex_normals();
        let triangles = target.triangles();
        let neighbors = target.triangle_neighbors();
        let data_weight = 0.25f64.powi(self.stencils.levels() as i32);
        let matrix = self.stencils.stencils();
        let mut terms = Stencils::new();
        let mut targets: Vec<DVec3> = Vec::new();
        let mut distances = vec![f32::NAN; fine.len()];
        let mut trusted = 0;
        // Per fine vertex, its data weight (0: not trusted) and where it is asked to go.
        let mut fine_weights = vec![0.0f64; fine.len()];
        let mut fine_targets = vec![DVec3::ZERO; fine.len()];
        let offset_of =
            |fine_vertex: usize| offsets.map_or(DVec3::ZERO, |offsets| offsets[fine_vertex]);
        let anchor_weight = self.settings.anchor_weight;
        let anchored = self
            .anchors
            .iter()
            .enumerate()
            .filter_map(|(vertex, anchor)| anchor.map(|point| (vertex, point)));
        for (vertex, point) in anchored {
            if self.stencils.on_surface()[vertex] && !self.fixed[vertex] {
                terms.push(matrix.entries(vertex), anchor_weight);
                targets.push(point - offset_of(vertex));
            }
        }
        for (fine_vertex, hit) in hits.iter().enumerate() {
            if !self.stencils.on_surface()[fine_vertex] {
                continue;
            }
            let Some(hit) = hit else { continue };
            distances[fine_vertex] = hit.distance;
            if fine_vertex < self.anchors.len() && self.anchors[fine_vertex].is_some() {
                continue;
            }
            let triangle = hit.face_point.triangle as usize;
            let weights = hit.face_point.barycentric;
            let on_rim = (0..3).any(|edge| {
                neighbors[triangle][edge] == NO_TRIANGLE && weights[(edge + 2) % 3] <= 1e-6
            });
            if on_rim {
                continue;
            }
            let corners = triangles[triangle];
            let target_normal = (target_normals[corners[0] as usize] * weights.x
                + target_normals[corners[1] as usize] * weights.y
                + target_normals[corners[2] as usize] * weights.z)
                .normalize_or_zero();
            if target_normal.dot(normals[fine_vertex]) < self.settings.min_facing {
                continue;
            }
            fine_weights[fine_vertex] = data_weight;
            fine_targets[fine_vertex] = hit.position.as_dvec3() - offset_of(fine_vertex);
            trusted += 1;
        }
        // The smoothness of the step: L_v (x − x_prev) = 0, i.e. L_v x = L_v x_prev.
        if self.settings.smoothness > 0.0 {
            for (vertex, around) in self.neighbors.iter().enumerate() {
                if around.is_empty() {
                    continue;
                }
                let share = 1.0 / around.len() as f64;
                let entries = std::iter::once((vertex as u32, 1.0))
                    .chain(around.iter().map(|&neighbor| (neighbor, -share)));
                terms.push(entries, self.settings.smoothness);
                let laplacian = cage[vertex]
                    - around
                        .iter()
                        .map(|&neighbor| cage[neighbor as usize])
                        .sum::<DVec3>()
                        * share;
                targets.push(laplacian);
            }
        }
        // The data's normal matrix Sᵀ W S, row by row, written as stencils the linear system takes
        // as they are: (e_a + e_b) with weight A_ab per pair, e_a with the rest of the diagonal.
        cancelled()?;
        let (system_terms, data_right_hand_side) =
            self.data_normal_equations(&fine_weights, &fine_targets, stop);
        cancelled()?;
        let pair_count = system_terms.len();
        let mut all_terms = system_terms;
        for term in 0..terms.len() {
            all_terms.push(terms.entries(term), terms.weights[term]);
        }
        let fixed: Vec<Option<DVec3>> = self
            .fixed
            .iter()
            .zip(cage)
            .map(|(&fixed, &position)| fixed.then_some(position))
            .collect();
        let mut system = LinearSystem::new(&all_terms, cage.len(), &fixed, usize::MAX)?;
        let rows = system.rows();
        let mut right_hand_side: Vec<DVec3> = system
            .vertex_of_row()
            .iter()
            .map(|&vertex| data_right_hand_side[vertex as usize])
            .collect();
        debug_assert!(pair_count + terms.len() == all_terms.len());
        for (term, &wanted) in targets.iter().enumerate() {
            let weight = terms.weights[term];
            for (vertex, coefficient) in terms.entries(term) {
                if let Some(row) = system.row_of(vertex) {
                    right_hand_side[row as usize] += wanted * (weight * coefficient);
                }
            }
        }
        let damping = self.settings.damping.max(1e-12);
        for (row, &vertex) in system.vertex_of_row().iter().enumerate() {
            right_hand_side[row] += cage[vertex as usize] * damping;
        }
        cancelled()?;
        system.factor(&vec![damping; rows])?;
        let solution = system.solve(&right_hand_side)?;
        if let Some(row) = solution.iter().position(|point| !point.is_finite()) {
            return Err(KernelError::InvalidArgument {
                name: "subdivision fit",
                reason: format!(
                    "the round gave cage vertex {} a non-finite position",
                    system.vertex_of_row()[row]
                ),
            });
        }
        let mut positions = cage.to_vec();
        for (row, &vertex) in system.vertex_of_row().iter().enumerate() {
            positions[vertex as usize] = solution[row];
        }
        Ok(FitRound {
            positions,
            distances,
            trusted,
        })
    }

    /// `A = Sᵀ W S` over the cage (`W`: the fine vertices' data weights) as stencils whose sum of
    /// `weight · s sᵀ` is `A` (a pair term `e_a + e_b` of weight `A_ab` for each `a < b` sharing a
    /// fine point, a term `e_a` with what the pairs leave of `A_aa`), and `Sᵀ W t` per cage vertex.
    /// Pairs of two fixed vertices are left out (they change nothing). Rows in parallel, each with
    /// a dense scratch row (Gustavson's product).
    fn data_normal_equations(
        &self,
        fine_weights: &[f64],
        fine_targets: &[DVec3],
        stop: &(dyn Fn() -> bool + Sync),
    ) -> (Stencils, Vec<DVec3>) {
        let cage_vertex_count = self.columns.len();
        let matrix = self.stencils.stencils();
        let rows: Vec<NormalRow> = (0..cage_vertex_count)
            .into_par_iter()
            .map_init(
                || (vec![0.0f64; cage_vertex_count], Vec::<u32>::new()),
                |(scratch, touched), vertex| {
                    let mut diagonal = 0.0;
                    let mut right_hand_side = DVec3::ZERO;
                    touched.clear();
                    if stop() {
                        return (diagonal, Vec::new(), right_hand_side); // the caller sees the stop
                    }
                    for &(fine_vertex, coefficient) in &self.columns[vertex] {
                        let weight = fine_weights[fine_vertex as usize];
                        if weight == 0.0 {
                            continue;
                        }
                        let scaled = weight * coefficient;
                        right_hand_side += fine_targets[fine_vertex as usize] * scaled;
                        for (other, other_coefficient) in matrix.entries(fine_vertex as usize) {
                            let other_index = other as usize;
                            if other_index == vertex {
                                diagonal += scaled * other_coefficient;
                            } else if other_index > vertex
                                && !(self.fixed[vertex] && self.fixed[other_index])
                            {
                                if scratch[other_index] == 0.0 {
                                    touched.push(other);
                                }
                                scratch[other_index] += scaled * other_coefficient;
                                if scratch[other_index] == 0.0 {
                                    scratch[other_index] = f64::MIN_POSITIVE;
                                }
                            }
                        }
                    }
                    let pairs = touched
                        .iter()
                        .map(|&other| (other, std::mem::take(&mut scratch[other as usize])))
                        .collect();
                    (diagonal, pairs, right_hand_side)
                },
            )
            .collect();
        let mut diagonal: Vec<f64> = rows.iter().map(|row| row.0).collect();
        let mut terms = Stencils::new();
        for (vertex, (_, pairs, _)) in rows.iter().enumerate() {
            for &(other, value) in pairs {
                terms.push([(vertex as u32, 1.0), (other, 1.0)], value);
                diagonal[vertex] -= value;
                diagonal[other as usize] -= value;
            }
        }
        for (vertex, &value) in diagonal.iter().enumerate() {
            if value != 0.0 && !self.fixed[vertex] {
                terms.push([(vertex as u32, 1.0)], value);
            }
        }
        let right_hand_side = rows.into_iter().map(|row| row.2).collect();
        (terms, right_hand_side)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::catmull_clark::BoundaryRule;

    /// The stencils of the data's normal equations add up to `Sᵀ W S` (pairs of two fixed vertices
    /// aside), and the right-hand side is `Sᵀ W t`, against a dense sum over the fine points.
    #[test]
    fn the_normal_equations_are_the_dense_sum_over_the_fine_points() {
        // A grid of 3 × 2 quads (4 × 3 vertices), open on every side.
        let corners = [
            0, 1, 5, 4, 1, 2, 6, 5, 2, 3, 7, 6, 4, 5, 9, 8, 5, 6, 10, 9, 6, 7, 11, 10,
        ];
        let sizes = [4; 6];
        let stencils =
            SubdivisionStencils::new(12, &corners, &sizes, 2, BoundaryRule::default()).unwrap();
        let fine_count = stencils.fine_vertex_count();
        let fixed: Vec<bool> = (0..12).map(|vertex| vertex % 5 == 0).collect();
        let fit = SubdivisionFit::new(stencils, &fixed, SubdivisionFitSettings::default()).unwrap();
        let weights: Vec<f64> = (0..fine_count)
            .map(|i| {
                if i % 7 == 3 {
                    0.0
                } else {
                    0.5 + (i % 4) as f64
                }
            })
            .collect();
        let targets: Vec<DVec3> = (0..fine_count)
            .map(|i| DVec3::new(i as f64, (i * i % 13) as f64, -(i as f64)))
            .collect();
        let (terms, right_hand_side) = fit.data_normal_equations(&weights, &targets, &|| false);
        let mut assembled = vec![vec![0.0f64; 12]; 12];
        for term in 0..terms.len() {
            let entries: Vec<(u32, f64)> = terms.entries(term).collect();
            for &(a, ca) in &entries {
                for &(b, cb) in &entries {
                    assembled[a as usize][b as usize] += terms.weights[term] * ca * cb;
                }
            }
        }
        let matrix = fit.stencils().stencils();
        let mut dense = vec![vec![0.0f64; 12]; 12];
        let mut expected_right = vec![DVec3::ZERO; 12];
        for fine_vertex in 0..fine_count {
            let entries: Vec<(u32, f64)> = matrix.entries(fine_vertex).collect();
            for &(a, ca) in &entries {
                expected_right[a as usize] += targets[fine_vertex] * (weights[fine_vertex] * ca);
                for &(b, cb) in &entries {
                    dense[a as usize][b as usize] += weights[fine_vertex] * ca * cb;
                }
            }
        }
        for a in 0..12 {
            assert!(right_hand_side[a].distance(expected_right[a]) < 1e-9);
            for b in 0..12 {
                if fixed[a] && fixed[b] {
                    continue;
                }
                assert!(
                    (assembled[a][b] - dense[a][b]).abs() < 1e-12,
                    "({a}, {b}): {} against {}",
                    assembled[a][b],
                    dense[a][b]
                );
            }
        }
    }
}
