//! The safeguard: no corner of a layout face turns past the schedule's least alignment from its rest normal
//! (turned by the layout's mean rotation); steps that would are halved, up to zero.

use super::*;

impl EnergySolver {
    /// +1 when the layout's faces wind as the target's where they are close, -1 when the other
    /// way (most layouts agree; a mirrored copy does not). A vote of at most
    /// [`ORIENTATION_SAMPLES`] vertices evenly spread over the layout's numbering (every vertex
    /// of a layout that small): on a million-point grid the vote of every vertex took a second
    /// of closest-point queries to say what a sample says.
    pub(super) fn measure_orientation(&self) -> f32 {
        let reach = self.mean_edge_length * 2.0;
        let stride = self.positions.len().div_ceil(ORIENTATION_SAMPLES).max(1);
        let agreement: f32 = ordered_sum(self.positions.len().div_ceil(stride), |sample| {
            let vertex = sample * stride;
            let normal = self
                .structure
                .normal_at(&self.positions, vertex as u32)
                .normalize_or_zero();
            if normal == Vec3::ZERO {
                return 0.0;
            }
            self.target
                .closest_point(self.positions[vertex], reach)
                .map_or(0.0, |hit| normal.dot(self.smoothed_normal(hit.face_point)))
        });
        if agreement < 0.0 { -1.0 } else { 1.0 }
    }

    /// Unit layout normals at `positions`.
    pub(super) fn layout_normals(&self, positions: &[Vec3]) -> Vec<Vec3> {
        (0..positions.len() as u32)
            .into_par_iter()
            .with_min_len(2048)
            .map(|vertex| {
                self.structure
                    .normal_at(positions, vertex)
                    .normalize_or_zero()
            })
            .collect()
    }

    /// Per corner (a vertex and one face around it, in `structure.wedges` order), the cosine
    /// between its normal and its rest normal turned by the layout's frame (0 when degenerate).
    pub(super) fn corner_orientations(&self, positions: &[Vec3]) -> Vec<f32> {
        let structure = &self.structure;
        (0..positions.len() as u32)
            .into_par_iter()
            .with_min_len(1024)
            .flat_map_iter(|vertex| {
                structure
                    .wedge_range(vertex)
                    .map(move |corner| self.corner_alignment(vertex, corner, positions))
            })
            .collect()
    }

    /// The cosine between corner `corner` (of vertex `owner`) at `positions` and its rest
    /// normal turned by the layout's frame (0 when degenerate).
    pub(super) fn corner_alignment(&self, owner: u32, corner: usize, positions: &[Vec3]) -> f32 {
        let (previous, next) = self.structure.wedges[corner];
        let here = positions[owner as usize];
        (positions[next as usize] - here)
            .cross(positions[previous as usize] - here)
            .normalize_or_zero()
            .dot(self.frame * self.rest_corner_normals[corner])
    }

    /// The vertices of corners that turn away from their frame at `positions`: below
    /// the schedule's least alignment and less aligned than in `before`.
    pub(super) fn turned_corners(&self, before: &[f32], positions: &[Vec3]) -> Vec<u32> {
        let structure = &self.structure;
        // In parallel, vertex by vertex, collected in the vertices' order.
        let mut vertices: Vec<u32> = (0..positions.len() as u32)
            .into_par_iter()
            .with_min_len(1024)
            .flat_map_iter(|vertex| {
                structure
                    .wedge_range(vertex)
                    .filter(move |&corner| {
                        let after = self.corner_alignment(vertex, corner, positions);
                        turned(before[corner], after, self.min_alignment)
                    })
                    .flat_map(move |corner| {
                        let (previous, next) = structure.wedges[corner];
                        [vertex, previous, next]
                    })
            })
            .collect();
        vertices.sort_unstable();
        vertices.dedup();
        vertices
    }

    /// [`Self::turned_corners`] among the corners that a vertex of `moved` belongs to (its own
    /// and its neighbours'), in the same order; every corner when `moved` is a large share of
    /// the layout.
    pub(super) fn turned_corners_around(
        &self,
        before: &[f32],
        positions: &[Vec3],
        moved: &[u32],
    ) -> Vec<u32> {
        if moved.len() * MOVED_SHARE_FOR_ALL > positions.len() {
            return self.turned_corners(before, positions);
        }
        let structure = &self.structure;
        let mut owners: Vec<u32> = moved
            .iter()
            .flat_map(|&vertex| {
                std::iter::once(vertex).chain(structure.neighbors_of(vertex).iter().copied())
            })
            .collect();
        owners.sort_unstable();
        owners.dedup();
        let mut vertices = Vec::new();
        for owner in owners {
            for corner in structure.wedge_range(owner) {
                let after = self.corner_alignment(owner, corner, positions);
                if turned(before[corner], after, self.min_alignment) {
                    let (previous, next) = structure.wedges[corner];
                    vertices.extend([owner, previous, next]);
                }
            }
        }
        vertices.sort_unstable();
        vertices.dedup();
        vertices
    }

    /// Whether `positions` turn a corner (as [`Self::turned_corners`] judges against `before`)
    /// among the corners that `vertex` belongs to: its own and its neighbours'.
    pub(super) fn turns_corner_around(
        &self,
        vertex: u32,
        before: &[f32],
        positions: &[Vec3],
    ) -> bool {
        let structure = &self.structure;
        let turns = |owner: u32, corner: usize| {
            turned(
                before[corner],
                self.corner_alignment(owner, corner, positions),
                self.min_alignment,
            )
        };
        let own = structure
            .wedge_range(vertex)
            .any(|corner| turns(vertex, corner));
        own || structure.neighbors_of(vertex).iter().any(|&other| {
            structure.wedge_range(other).any(|corner| {
                let (previous, next) = structure.wedges[corner];
                (previous == vertex || next == vertex) && turns(other, corner)
            })
        })
    }

    /// The proposed positions with the steps of vertices around turning corners halved until
    /// none turns (after [`BACKTRACK_HALVINGS`] halvings a step is not taken at all); and how many
    /// vertices were held back. Only a corner turned by constrained vertices alone can remain.
    pub(super) fn safeguard(&self, proposed: &[Vec3]) -> (Vec<Vec3>, usize) {
        let before = self.corner_orientations(&self.positions);
        let mut fractions = vec![1.0f32; proposed.len()];
        let mut candidate = proposed.to_vec();
        // The first round looks at every corner; a later one only at the corners around the
        // vertices the round before moved. The others kept their alignment, and a turned one
        // among them has no step left to shorten (its vertices are fixed or already at zero), so
        // the rounds shorten exactly the steps that looking at every corner would.
        let mut turned = self.turned_corners(&before, &candidate);
        for round in 0.. {
            let mut moved = Vec::new();
            for vertex in turned {
                let vertex = vertex as usize;
                if self.fixed[vertex].is_some() || fractions[vertex] == 0.0 {
                    continue;
                }
                fractions[vertex] = if round >= BACKTRACK_HALVINGS {
                    0.0
                } else {
                    fractions[vertex] * 0.5
                };
                candidate[vertex] = self.positions[vertex]
                    + (proposed[vertex] - self.positions[vertex]) * fractions[vertex];
                moved.push(vertex as u32);
            }
            if moved.is_empty() {
                break;
            }
            turned = self.turned_corners_around(&before, &candidate, &moved);
        }
        let held_back = fractions.iter().filter(|&&fraction| fraction < 1.0).count();
        (candidate, held_back)
    }
}

/// A safeguard round looks at every corner again once more than one vertex in this many moved in
/// the round before (collecting their neighbourhoods would then cost more than it saves).
const MOVED_SHARE_FOR_ALL: usize = 8;

/// Whether a corner aligned `before` with its frame has turned at `after`: beyond
/// `min_alignment` and further from its frame than it was.
fn turned(before: f32, after: f32, min_alignment: f32) -> bool {
    after < min_alignment && after < before
}

/// Per corner (a vertex and one face around it, in `structure.wedges` order), its normal at
/// `positions` (twice the corner triangle's area long; the faces' winding).
pub(super) fn corner_normals(structure: &LayoutStructure, positions: &[Vec3]) -> Vec<Vec3> {
    (0..positions.len())
        .into_par_iter()
        .with_min_len(1024)
        .flat_map_iter(|vertex| {
            let here = positions[vertex];
            structure.wedges[structure.wedge_range(vertex as u32)]
                .iter()
                .map(move |&(previous, next)| {
                    (positions[next as usize] - here).cross(positions[previous as usize] - here)
                })
        })
        .collect()
}
