//! The energy's shape terms (edges, lines, umbrellas) and the per-vertex factors of stiffness and flags.

use super::*;

/// The factor on the shape terms a vertex of this stiffness owns: 1 at
/// [`NEUTRAL_STIFFNESS`], [`STIFFNESS_RANGE`] at 1, its inverse at 0 (geometric in between).
pub(super) fn shape_factor(stiffness: f32) -> f64 {
    STIFFNESS_RANGE.powf(f64::from(stiffness - NEUTRAL_STIFFNESS) / f64::from(NEUTRAL_STIFFNESS))
}

/// The factor on the data term of a vertex of this stiffness: 1 up to [`NEUTRAL_STIFFNESS`],
/// falling linearly to 0 at 1 (a vertex that keeps the template's shape is not pulled).
pub(super) fn data_factor(stiffness: f32) -> f32 {
    ((1.0 - stiffness) / (1.0 - NEUTRAL_STIFFNESS)).clamp(0.0, 1.0)
}

/// Whether `triangle` is flagged in `flags` (empty: none is).
pub(super) fn is_flagged(flags: &[bool], triangle: u32) -> bool {
    flags.get(triangle as usize).copied().unwrap_or(false)
}

/// The energy's quadratic terms with their owners and rest vectors: one edge term per directed
/// edge, one line term per grid-line triple, one umbrella term per vertex on no line (corners
/// excepted: straightening them would cut them); `[edge, line, umbrella]` scale their weights.
pub(super) fn build_terms(
    structure: &LayoutStructure,
    rest: &[Vec3],
    [edge_scale, line_scale, umbrella_scale]: [f64; 3],
) -> (Stencils, Vec<u32>, Vec<DVec3>) {
    let mut stencils = Stencils::new();
    let mut owners = Vec::new();
    let mut rests = Vec::new();
    let rest: Vec<DVec3> = rest.iter().map(|p| p.as_dvec3()).collect();
    let mut on_line = vec![false; structure.vertex_count];
    for triple in &structure.line_triples {
        on_line[triple.vertex as usize] = true;
    }
    let mut is_corner = vec![false; structure.vertex_count];
    for &corner in &structure.corners {
        is_corner[corner as usize] = true;
    }
    for vertex in 0..structure.vertex_count as u32 {
        for &other in structure.neighbors_of(vertex) {
            stencils.push([(other, 1.0), (vertex, -1.0)], EDGE_WEIGHT * edge_scale);
            owners.push(vertex);
            rests.push(rest[other as usize] - rest[vertex as usize]);
        }
    }
    for triple in &structure.line_triples {
        stencils.push(
            [
                (triple.previous, 1.0),
                (triple.next, 1.0),
                (triple.vertex, -2.0),
            ],
            LINE_WEIGHT * line_scale,
        );
        owners.push(triple.vertex);
        rests.push(
            rest[triple.previous as usize] + rest[triple.next as usize]
                - rest[triple.vertex as usize] * 2.0,
        );
    }
    for vertex in 0..structure.vertex_count as u32 {
        let neighbors = structure.neighbors_of(vertex);
        if on_line[vertex as usize] || is_corner[vertex as usize] || neighbors.is_empty() {
            continue;
        }
        let share = 1.0 / neighbors.len() as f64;
        let mean: DVec3 = neighbors
            .iter()
            .map(|&other| rest[other as usize])
            .sum::<DVec3>()
            * share;
        stencils.push(
            neighbors
                .iter()
                .map(|&other| (other, share))
                .chain([(vertex, -1.0)]),
            LINE_WEIGHT * umbrella_scale,
        );
        owners.push(vertex);
        rests.push(mean - rest[vertex as usize]);
    }
    (stencils, owners, rests)
}
