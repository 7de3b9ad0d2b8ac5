//! Triangle adjacency across edges, boundary edges and non-manifold edges.

use rayon::prelude::*;

/// Marks "no triangle" in adjacency tables: a boundary edge, a non-manifold edge, or a collapsed edge.
pub const NO_TRIANGLE: u32 = u32::MAX;

/// One edge of one triangle: edge `edge` of triangle `triangle` runs from corner `edge` to
/// corner `(edge + 1) % 3`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct TriangleEdge {
    /// The triangle.
    pub triangle: u32,
    /// The edge within it, 0, 1 or 2.
    pub edge: u8,
}

/// Edge connectivity of a triangle soup.
#[derive(Debug, Clone, Default)]
pub struct Topology {
    /// `neighbors[t][e]`: the triangle across edge `e` of `t`, or [`NO_TRIANGLE`].
    pub neighbors: Vec<[u32; 3]>,
    /// Edges used by exactly one triangle: holes and open borders.
    pub boundary_edges: Vec<TriangleEdge>,
    /// Number of undirected edges used by three or more triangles (they link no neighbors).
    pub non_manifold_edge_count: usize,
}

/// Computes adjacency by sorting the undirected edges of every triangle.
///
/// Edges whose two ends are the same vertex (triangles that repeat an index) connect nothing and
/// are neither boundaries nor neighbors.
#[must_use]
pub fn compute_topology(triangles: &[[u32; 3]]) -> Topology {
    let mut half_edges: Vec<(u64, u32)> = triangles
        .par_iter()
        .enumerate()
        .flat_map_iter(|(triangle, corners)| {
            (0..3).filter_map(move |edge| {
                let start = corners[edge];
                let end = corners[(edge + 1) % 3];
                (start != end).then(|| {
                    let key = (u64::from(start.min(end)) << 32) | u64::from(start.max(end));
                    (key, (triangle as u32) * 3 + edge as u32)
                })
            })
        })
        .collect();
    half_edges.par_sort_unstable();

    let mut neighbors = vec![[NO_TRIANGLE; 3]; triangles.len()];
    let mut boundary_edges = Vec::new();
    let mut non_manifold_edge_count = 0;
    let mut group_start = 0;
    while group_start < half_edges.len() {
        let key = half_edges[group_start].0;
        let mut group_end = group_start + 1;
        while group_end < half_edges.len() && half_edges[group_end].0 == key {
            group_end += 1;
        }
        let group = &half_edges[group_start..group_end];
        match group {
            [(_, only)] => boundary_edges.push(TriangleEdge {
                triangle: only / 3,
                edge: (only % 3) as u8,
            }),
            // A triangle that repeats a vertex has its two remaining edges on top of each other:
            // it is not its own neighbor.
            [(_, first), (_, second)] if first / 3 == second / 3 => {}
            [(_, first), (_, second)] => {
                neighbors[(first / 3) as usize][(first % 3) as usize] = second / 3;
                neighbors[(second / 3) as usize][(second % 3) as usize] = first / 3;
            }
            _ => non_manifold_edge_count += 1,
        }
        group_start = group_end;
    }
    boundary_edges.sort_unstable_by_key(|edge| (edge.triangle, edge.edge));
    Topology {
        neighbors,
        boundary_edges,
        non_manifold_edge_count,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_triangles_share_one_edge() {
        // 0---1
        // | / |
        // 2---3
        let topology = compute_topology(&[[0, 2, 1], [1, 2, 3]]);
        assert_eq!(topology.neighbors[0], [NO_TRIANGLE, 1, NO_TRIANGLE]);
        assert_eq!(topology.neighbors[1], [0, NO_TRIANGLE, NO_TRIANGLE]);
        assert_eq!(topology.boundary_edges.len(), 4);
        assert_eq!(topology.non_manifold_edge_count, 0);
    }

    #[test]
    fn three_triangles_on_one_edge_are_non_manifold() {
        let topology = compute_topology(&[[0, 1, 2], [1, 0, 3], [0, 1, 4]]);
        assert_eq!(topology.non_manifold_edge_count, 1);
        assert!(topology.neighbors.iter().all(|n| n[0] == NO_TRIANGLE));
        assert_eq!(topology.boundary_edges.len(), 6);
    }

    #[test]
    fn collapsed_edges_connect_nothing() {
        let topology = compute_topology(&[[0, 0, 1]]);
        assert_eq!(topology.neighbors[0], [NO_TRIANGLE; 3]);
        // Edges 1 and 2 are both (0, 1) of the same triangle: neither neighbors nor boundaries.
        assert_eq!(topology.boundary_edges.len(), 0);
    }
}
