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

/// Computes adjacency by bucketing the half-edges by their lower vertex (a compressed table, 14
/// bytes per triangle while it runs) and grouping each bucket by the other vertex.
///
/// Edges whose two ends are the same vertex (triangles that repeat an index) connect nothing and
/// are neither boundaries nor neighbors.
#[must_use]
pub fn compute_topology(triangles: &[[u32; 3]]) -> Topology {
    // A half-edge is `triangle * 3 + edge`: from corner `edge` to corner `(edge + 1) % 3`.
    let ends = |half_edge: u32| {
        let corners = triangles[(half_edge / 3) as usize];
        let edge = (half_edge % 3) as usize;
        let (start, end) = (corners[edge], corners[(edge + 1) % 3]);
        (start.min(end), start.max(end))
    };
    let vertex_count = triangles
        .par_iter()
        .flat_map_iter(|corners| corners.iter().copied())
        .max()
        .map_or(0, |last| last as usize + 1);
    // offsets[v] .. offsets[v + 1]: the half-edges whose lower vertex is v (collapsed ones left out).
    let mut offsets = vec![0u32; vertex_count + 1];
    for corners in triangles {
        for edge in 0..3 {
            let (start, end) = (corners[edge], corners[(edge + 1) % 3]);
            if start != end {
                offsets[start.min(end) as usize + 1] += 1;
            }
        }
    }
    for vertex in 0..vertex_count {
        offsets[vertex + 1] += offsets[vertex];
    }
    let mut next = offsets.clone();
    let mut half_edges = vec![0u32; offsets[vertex_count] as usize];
    for (triangle, corners) in triangles.iter().enumerate() {
        for edge in 0..3 {
            let (start, end) = (corners[edge], corners[(edge + 1) % 3]);
            if start != end {
                let slot = &mut next[start.min(end) as usize];
                half_edges[*slot as usize] = (triangle as u32) * 3 + edge as u32;
                *slot += 1;
            }
        }
    }
    drop(next);

    let mut neighbors = vec![[NO_TRIANGLE; 3]; triangles.len()];
    let mut boundary_edges = Vec::new();
    let mut non_manifold_edge_count = 0;
    for vertex in 0..vertex_count {
        let bucket = &mut half_edges[offsets[vertex] as usize..offsets[vertex + 1] as usize];
        bucket.sort_unstable_by_key(|&half_edge| (ends(half_edge).1, half_edge));
        for group in bucket.chunk_by(|&first, &second| ends(first).1 == ends(second).1) {
            match *group {
                [only] => boundary_edges.push(TriangleEdge {
                    triangle: only / 3,
                    edge: (only % 3) as u8,
                }),
                // A triangle that repeats a vertex has its two remaining edges on top of each
                // other: it is not its own neighbor.
                [first, second] if first / 3 == second / 3 => {}
                [first, second] => {
                    neighbors[(first / 3) as usize][(first % 3) as usize] = second / 3;
                    neighbors[(second / 3) as usize][(second % 3) as usize] = first / 3;
                }
                _ => non_manifold_edge_count += 1,
            }
        }
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
