//! The spring forces, each a displacement computed from a snapshot of the positions.
//!
//! Krishnamurthy & Levoy (1996) relax spring meshes with a fairness force (straighten grid lines)
//! and an arc-length force (even spacing along them). Here both act on the layout's line
//! triples; vertices on no grid line use the umbrella operator instead; space-points also feel a
//! thin-plate force (minus the umbrella applied twice), which makes a free region continue the
//! curvature of the surface around it instead of flattening.
//!
//! **Rest shape.** Straight lines and even spacing are K&L's rest state ([`SpringRest::Even`]).
//! A retargeting template has its own: edge loops circle an eye, spacing is dense on the face and
//! sparse on the back. Straightening those loops shrinks them and evening the spacing slides the
//! whole layout, so by default ([`SpringRest::Template`]) each force aims at the template's own
//! second differences instead: a line's rest bend `midpoint - vertex` (whose part along the line
//! is its spacing ratio, whose part across it is its curvature) is turned and scaled by the
//! similarity that best maps the vertex's rest edges onto its current edges (a per-vertex
//! Procrustes fit, as in as-rigid-as-possible deformation), so a posed, resized or morphed target
//! is not resisted, only distortion of the template's local shape.

use glam::{Mat3, Quat, Vec3};
use rayon::prelude::*;

use crate::layout::LayoutStructure;

/// What the spring forces consider relaxed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SpringRest {
    /// The template's own shape: its grid lines' bends and spacing ratios (the default).
    #[default]
    Template,
    /// Krishnamurthy & Levoy's springs: straight grid lines, equal spacing.
    Even,
}

/// How a vertex's neighbourhood is turned and scaled from rest to now.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Similarity {
    /// The rotation from rest to now.
    pub rotation: Quat,
    /// The scale from rest to now.
    pub scale: f32,
}

impl Similarity {
    /// No turn, no scale.
    pub const IDENTITY: Self = Self {
        rotation: Quat::IDENTITY,
        scale: 1.0,
    };

    fn apply(self, vector: Vec3) -> Vec3 {
        self.rotation * vector * self.scale
    }

    /// The median of the positive, finite scales of `fits`; `None` when there is none.
    #[must_use]
    pub fn median_scale(fits: &[Self]) -> Option<f32> {
        let mut scales: Vec<f32> = fits
            .iter()
            .map(|fit| fit.scale)
            .filter(|scale| *scale > 0.0 && scale.is_finite())
            .collect();
        if scales.is_empty() {
            return None;
        }
        let middle = scales.len() / 2;
        Some(*scales.select_nth_unstable_by(middle, f32::total_cmp).1)
    }
}

/// Rotation-fit refinements per iteration, warm-started from the last fit (Müller et al. 2016,
/// "A robust method to extract the rotational part of deformations").
const ROTATION_REFINEMENTS: usize = 1;
/// Refinements for the first fit, from the identity.
const FIRST_ROTATION_REFINEMENTS: usize = 40;

/// The springs of a layout: its line triples grouped by middle vertex, with their rest shape.
#[derive(Debug, Clone, Default)]
pub struct Springs {
    kind: SpringRest,
    offsets: Vec<u32>,
    ends: Vec<(u32, u32)>,
    /// Per line: its rest bend `midpoint - vertex` (template rest only).
    rest_bends: Vec<Vec3>,
    /// Per vertex: its rest position (template rest only).
    rest: Vec<Vec3>,
    /// Per vertex: its rest umbrella (template rest only).
    rest_umbrellas: Vec<Vec3>,
}

impl Springs {
    /// The springs of `structure` relaxed at `rest` (one position per layout vertex; ignored for
    /// [`SpringRest::Even`], whose lines rest straight and evenly spaced).
    #[must_use]
    pub fn new(structure: &LayoutStructure, rest: &[Vec3], kind: SpringRest) -> Self {
        let mut counts = vec![0u32; structure.vertex_count + 1];
        for triple in &structure.line_triples {
            counts[triple.vertex as usize + 1] += 1;
        }
        for index in 1..counts.len() {
            counts[index] += counts[index - 1];
        }
        let offsets = counts.clone();
        let mut cursor = counts;
        let mut ends = vec![(0, 0); structure.line_triples.len()];
        let mut rest_bends = Vec::new();
        if kind == SpringRest::Template {
            rest_bends = vec![Vec3::ZERO; structure.line_triples.len()];
        }
        for triple in &structure.line_triples {
            let slot = &mut cursor[triple.vertex as usize];
            ends[*slot as usize] = (triple.previous, triple.next);
            if kind == SpringRest::Template {
                rest_bends[*slot as usize] =
                    (rest[triple.previous as usize] + rest[triple.next as usize]) * 0.5
                        - rest[triple.vertex as usize];
            }
            *slot += 1;
        }
        let (rest, rest_umbrellas) = match kind {
            SpringRest::Template => (
                rest.to_vec(),
                (0..structure.vertex_count as u32)
                    .map(|vertex| umbrella(rest, structure, vertex))
                    .collect(),
            ),
            SpringRest::Even => (Vec::new(), Vec::new()),
        };
        Self {
            kind,
            offsets,
            ends,
            rest_bends,
            rest,
            rest_umbrellas,
        }
    }

    /// What these springs rest in.
    #[must_use]
    pub fn kind(&self) -> SpringRest {
        self.kind
    }

    /// The `(previous, next)` ends of the grid lines through `vertex`.
    #[must_use]
    pub fn lines_of(&self, vertex: u32) -> &[(u32, u32)] {
        let start = self.offsets[vertex as usize] as usize;
        let end = self.offsets[vertex as usize + 1] as usize;
        &self.ends[start..end]
    }

    /// The similarity that best maps `vertex`'s rest edges onto its current ones, refined from
    /// `previous` (the last fit, or [`Similarity::IDENTITY`] with `first`);
    /// [`Similarity::IDENTITY`] for [`SpringRest::Even`].
    #[must_use]
    pub fn fit(
        &self,
        positions: &[Vec3],
        structure: &LayoutStructure,
        vertex: u32,
        previous: Similarity,
        first: bool,
    ) -> Similarity {
        if self.kind == SpringRest::Even {
            return Similarity::IDENTITY;
        }
        let index = vertex as usize;
        let (here, rest_here) = (positions[index], self.rest[index]);
        // A = sum of now ⊗ rest over the edges: the rotation maximising tr(Rᵀ A) maps rest to now.
        let mut covariance = Mat3::ZERO;
        let mut rest_norm = 0.0f32;
        for &other in structure.neighbors_of(vertex) {
            let now = positions[other as usize] - here;
            let rest = self.rest[other as usize] - rest_here;
            covariance += Mat3::from_cols(now * rest.x, now * rest.y, now * rest.z);
            rest_norm += rest.length_squared();
        }
        if rest_norm <= 0.0 {
            return previous;
        }
        let refinements = if first {
            FIRST_ROTATION_REFINEMENTS
        } else {
            ROTATION_REFINEMENTS
        };
        let rotation = refine_rotation(covariance, previous.rotation, refinements);
        // The least-squares scale: tr(Rᵀ A) / Σ|rest|².
        let turned = Mat3::from_quat(rotation);
        let aligned = turned.x_axis.dot(covariance.x_axis)
            + turned.y_axis.dot(covariance.y_axis)
            + turned.z_axis.dot(covariance.z_axis);
        let scale = (aligned / rest_norm).max(0.0);
        Similarity { rotation, scale }
    }

    /// [`Springs::fit`] for every vertex, in parallel, each refined from its `previous` fit.
    #[must_use]
    pub fn fit_all(
        &self,
        positions: &[Vec3],
        structure: &LayoutStructure,
        previous: &[Similarity],
        first: bool,
    ) -> Vec<Similarity> {
        (0..positions.len() as u32)
            .into_par_iter()
            .with_min_len(1024)
            .map(|vertex| {
                self.fit(
                    positions,
                    structure,
                    vertex,
                    previous[vertex as usize],
                    first,
                )
            })
            .collect()
    }

    /// Fairness and arc-length displacements of `vertex` from its grid lines, averaged over them;
    /// `None` when no grid line passes through it.
    ///
    /// For a line `previous, vertex, next` with unit direction `t` from `previous` to `next`, the
    /// gap between its bend `midpoint - vertex` and its wanted bend (the rest bend under
    /// `similarity`; zero for [`SpringRest::Even`]) splits into fairness (across `t`: the line
    /// takes its rest curvature, or straightens) and arc length (along `t`: the vertex divides the
    /// line in its rest ratio; for `Even`, K&L's halving of the two spans' difference).
    #[must_use]
    pub fn line_forces(
        &self,
        positions: &[Vec3],
        vertex: u32,
        similarity: Similarity,
    ) -> Option<(Vec3, Vec3)> {
        let index = vertex as usize;
        let start = self.offsets[index] as usize;
        let end = self.offsets[index + 1] as usize;
        if start == end {
            return None;
        }
        let here = positions[index];
        let mut fairness = Vec3::ZERO;
        let mut arc_length = Vec3::ZERO;
        for line in start..end {
            let (previous, next) = self.ends[line];
            let before = positions[previous as usize];
            let after = positions[next as usize];
            let direction = (after - before).normalize_or_zero();
            let bend = (before + after) * 0.5 - here;
            match self.kind {
                SpringRest::Template => {
                    let gap = bend - similarity.apply(self.rest_bends[line]);
                    let along = direction * gap.dot(direction);
                    fairness += gap - along;
                    arc_length += along;
                }
                SpringRest::Even => {
                    fairness += bend - direction * bend.dot(direction);
                    let imbalance = (after - here).length() - (here - before).length();
                    arc_length += direction * (imbalance * 0.5);
                }
            }
        }
        let count = (end - start) as f32;
        Some((fairness / count, arc_length / count))
    }

    /// The umbrella of `vertex` (see [`umbrella`]) minus its rest umbrella under `similarity`
    /// (nothing for [`SpringRest::Even`]): what the umbrella fallback and the thin plate act on.
    #[must_use]
    pub fn umbrella_deviation(
        &self,
        positions: &[Vec3],
        structure: &LayoutStructure,
        vertex: u32,
        similarity: Similarity,
    ) -> Vec3 {
        let offset = umbrella(positions, structure, vertex);
        match self.kind {
            SpringRest::Template => offset - similarity.apply(self.rest_umbrellas[vertex as usize]),
            SpringRest::Even => offset,
        }
    }
}

/// Refines `rotation` toward the rotation part of `matrix` (the rotation `R` maximising
/// `tr(Rᵀ matrix)`): Müller, Bender, Chentanez & Macklin 2016, robust where the matrix is
/// degenerate or reflected, warm-started.
fn refine_rotation(matrix: Mat3, rotation: Quat, iterations: usize) -> Quat {
    let mut rotation = rotation;
    for _ in 0..iterations {
        let turned = Mat3::from_quat(rotation);
        let torque = turned.x_axis.cross(matrix.x_axis)
            + turned.y_axis.cross(matrix.y_axis)
            + turned.z_axis.cross(matrix.z_axis);
        let alignment = turned.x_axis.dot(matrix.x_axis)
            + turned.y_axis.dot(matrix.y_axis)
            + turned.z_axis.dot(matrix.z_axis);
        let omega = torque / (alignment.abs() + 1e-9);
        let angle = omega.length();
        if angle.is_nan() || angle <= 1e-7 {
            break;
        }
        rotation = (Quat::from_axis_angle(omega / angle, angle) * rotation).normalize();
    }
    rotation
}

/// The umbrella operator: the mean of the edge neighbours minus the vertex (zero when alone).
#[must_use]
pub fn umbrella(positions: &[Vec3], structure: &LayoutStructure, vertex: u32) -> Vec3 {
    let neighbors = structure.neighbors_of(vertex);
    if neighbors.is_empty() {
        return Vec3::ZERO;
    }
    let sum: Vec3 = neighbors
        .iter()
        .map(|&other| positions[other as usize])
        .sum();
    sum / neighbors.len() as f32 - positions[vertex as usize]
}

/// The thin-plate displacement of `vertex` given everyone's umbrella deviations: minus the
/// umbrella of them (a discrete bi-Laplacian flow step toward the rest shape).
#[must_use]
pub fn thin_plate(deviations: &[Vec3], structure: &LayoutStructure, vertex: u32) -> Vec3 {
    -umbrella(deviations, structure, vertex)
}
