//! The spring forces, each a displacement computed from a snapshot of the positions.
//!
//! Krishnamurthy & Levoy (1996) relax spring meshes with a fairness force (straighten grid lines)
//! and an arc-length force (even spacing along them). Here both act on the layout's line
//! triples; vertices on no grid line use the umbrella operator instead; space-points also feel a
//! thin-plate force (minus the umbrella applied twice), which makes a free region continue the
//! curvature of the surface around it instead of flattening.

use glam::Vec3;

use crate::layout::LayoutStructure;

/// The line triples of a layout grouped by their middle vertex, for per-vertex evaluation.
#[derive(Debug, Clone, Default)]
pub struct LinesByVertex {
    offsets: Vec<u32>,
    ends: Vec<(u32, u32)>,
}

impl LinesByVertex {
    /// Groups `structure`'s line triples by vertex.
    #[must_use]
    pub fn new(structure: &LayoutStructure) -> Self {
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
        for triple in &structure.line_triples {
            let slot = &mut cursor[triple.vertex as usize];
            ends[*slot as usize] = (triple.previous, triple.next);
            *slot += 1;
        }
        Self { offsets, ends }
    }

    /// The `(previous, next)` ends of the grid lines through `vertex`.
    #[must_use]
    pub fn lines_of(&self, vertex: u32) -> &[(u32, u32)] {
        let start = self.offsets[vertex as usize] as usize;
        let end = self.offsets[vertex as usize + 1] as usize;
        &self.ends[start..end]
    }
}

/// Fairness and arc-length displacements of `vertex` from its grid lines, averaged over them;
/// `None` when no grid line passes through it.
///
/// For a line `previous, vertex, next` with unit direction `t` from `previous` to `next`:
/// fairness is the part of `midpoint - vertex` across `t` (it straightens the line), arc length
/// moves along `t` by half the difference of the two spans (it evens the spacing).
#[must_use]
pub fn line_forces(positions: &[Vec3], lines: &[(u32, u32)], vertex: u32) -> Option<(Vec3, Vec3)> {
    if lines.is_empty() {
        return None;
    }
    let here = positions[vertex as usize];
    let mut fairness = Vec3::ZERO;
    let mut arc_length = Vec3::ZERO;
    for &(previous, next) in lines {
        let before = positions[previous as usize];
        let after = positions[next as usize];
        let direction = (after - before).normalize_or_zero();
        let to_midpoint = (before + after) * 0.5 - here;
        fairness += to_midpoint - direction * to_midpoint.dot(direction);
        let imbalance = (after - here).length() - (here - before).length();
        arc_length += direction * (imbalance * 0.5);
    }
    let count = lines.len() as f32;
    Some((fairness / count, arc_length / count))
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

/// The thin-plate displacement of `vertex` given everyone's umbrella vectors: minus the umbrella
/// of the umbrella (a discrete bi-Laplacian flow step).
#[must_use]
pub fn thin_plate(umbrellas: &[Vec3], structure: &LayoutStructure, vertex: u32) -> Vec3 {
    -umbrella(umbrellas, structure, vertex)
}
