//! Vertex neighbourhoods: the vertices within a radius of a vertex, reached along mesh edges.

use glam::Vec3;

/// Vertex adjacency in compressed rows: the neighbours of vertex `v` are
/// `neighbors[offsets[v]..offsets[v + 1]]` (each undirected edge once per end, no repeats).
#[derive(Debug, Clone)]
pub struct VertexAdjacency {
    /// Row starts, one more than there are vertices.
    pub offsets: Vec<u32>,
    /// Neighbour vertex indices.
    pub neighbors: Vec<u32>,
}

impl VertexAdjacency {
    /// The adjacency of the triangles' edges (edges that join a vertex to itself are skipped).
    #[must_use]
    pub fn new(vertex_count: usize, triangles: &[[u32; 3]]) -> Self {
        let mut pairs: Vec<(u32, u32)> = Vec::with_capacity(triangles.len() * 6);
        for corners in triangles {
            for edge in 0..3 {
                let (start, end) = (corners[edge], corners[(edge + 1) % 3]);
                if start != end {
                    pairs.push((start, end));
                    pairs.push((end, start));
                }
            }
        }
        pairs.sort_unstable();
        pairs.dedup();
        let mut offsets = vec![0u32; vertex_count + 1];
        for &(start, _) in &pairs {
            offsets[start as usize + 1] += 1;
        }
        for vertex in 0..vertex_count {
            offsets[vertex + 1] += offsets[vertex];
        }
        let neighbors = pairs.into_iter().map(|(_, end)| end).collect();
        Self { offsets, neighbors }
    }

    /// The neighbours of `vertex`.
    #[must_use]
    pub fn of(&self, vertex: u32) -> &[u32] {
        let vertex = vertex as usize;
        &self.neighbors[self.offsets[vertex] as usize..self.offsets[vertex + 1] as usize]
    }
}

/// Reusable per-thread scratch space for [`gather`]: a visit stamp per vertex.
#[derive(Debug, Clone)]
pub struct Scratch {
    stamps: Vec<u32>,
    stamp: u32,
}

impl Scratch {
    /// Scratch space for a mesh of `vertex_count` vertices.
    #[must_use]
    pub fn new(vertex_count: usize) -> Self {
        Self {
            stamps: vec![0; vertex_count],
            stamp: 0,
        }
    }

    fn next_stamp(&mut self) -> u32 {
        self.stamp = self.stamp.wrapping_add(1);
        if self.stamp == 0 {
            self.stamps.fill(0);
            self.stamp = 1;
        }
        self.stamp
    }
}

/// The vertices reached from `center` along edges without leaving the ball of `radius` around it
/// (the centre first), into `out`. When fewer than `min_count` are found (a radius below the edge
/// length), whole rings of neighbours are added beyond the radius until there are enough or the
/// component is exhausted. Walking along edges keeps the two sides of a thin wall apart.
pub fn gather(
    positions: &[Vec3],
    adjacency: &VertexAdjacency,
    center: u32,
    radius: f32,
    min_count: usize,
    scratch: &mut Scratch,
    out: &mut Vec<u32>,
) {
    out.clear();
    let stamp = scratch.next_stamp();
    let origin = positions[center as usize];
    let radius_squared = radius * radius;
    scratch.stamps[center as usize] = stamp;
    out.push(center);
    // Vertices seen but outside the ball, kept for the ring expansion.
    let mut outside: Vec<u32> = Vec::new();
    let mut head = 0;
    while head < out.len() {
        let vertex = out[head];
        head += 1;
        for &neighbor in adjacency.of(vertex) {
            if scratch.stamps[neighbor as usize] == stamp {
                continue;
            }
            scratch.stamps[neighbor as usize] = stamp;
            if positions[neighbor as usize].distance_squared(origin) <= radius_squared {
                out.push(neighbor);
            } else {
                outside.push(neighbor);
            }
        }
    }
    while out.len() < min_count && !outside.is_empty() {
        let ring = std::mem::take(&mut outside);
        for &vertex in &ring {
            out.push(vertex);
        }
        for &vertex in &ring {
            for &neighbor in adjacency.of(vertex) {
                if scratch.stamps[neighbor as usize] != stamp {
                    scratch.stamps[neighbor as usize] = stamp;
                    outside.push(neighbor);
                }
            }
        }
    }
}
