//! One shape seen by the correspondence search: its vertices, edge graph and normals; geodesic
//! distances along its edges; each vertex's protrusion over a radius; its distinct points.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use glam::Vec3;
use rayon::prelude::*;

use crate::features::neighborhood::{Scratch, VertexAdjacency, gather};

/// Vertices per rayon task for the per-vertex measures.
const VERTICES_PER_TASK: usize = 256;

/// The fewest vertices a protrusion is measured over (a radius below the edge length still
/// gathers a ring).
const MIN_NEIGHBOURHOOD: usize = 7;

/// A triangulated surface: positions, edge graph, unit vertex normals, bounding-box diagonal.
pub(crate) struct Shape<'a> {
    pub positions: &'a [Vec3],
    pub adjacency: VertexAdjacency,
    pub normals: Vec<Vec3>,
    pub diagonal: f32,
}

impl<'a> Shape<'a> {
    /// The shape of `positions` and `triangles` (indices already checked).
    pub fn new(positions: &'a [Vec3], triangles: &[[u32; 3]]) -> Self {
        let adjacency = VertexAdjacency::new(positions.len(), triangles);
        let mut sums = vec![Vec3::ZERO; positions.len()];
        for corners in triangles {
            let [a, b, c] = corners.map(|corner| positions[corner as usize]);
            // The cross product's length is twice the area: an area-weighted normal.
            let normal = (b - a).cross(c - a);
            for &corner in corners {
                sums[corner as usize] += normal;
            }
        }
        let normals = sums.into_iter().map(Vec3::normalize_or_zero).collect();
        let (low, high) = positions.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(low, high), &p| (low.min(p), high.max(p)),
        );
        let diagonal = if positions.is_empty() {
            0.0
        } else {
            (high - low).length()
        };
        Self {
            positions,
            adjacency,
            normals,
            diagonal,
        }
    }

    /// Shortest distances along edges from the seeds (vertex, starting distance); infinity where
    /// no edge path leads.
    pub fn geodesic(&self, seeds: &[(u32, f32)]) -> Vec<f32> {
        let mut distances = vec![f32::INFINITY; self.positions.len()];
        let mut heap = BinaryHeap::new();
        for &(vertex, start) in seeds {
            if start < distances[vertex as usize] {
                distances[vertex as usize] = start;
                heap.push(Visit(start, vertex));
            }
        }
        while let Some(Visit(distance, vertex)) = heap.pop() {
            if distance > distances[vertex as usize] {
                continue;
            }
            let here = self.positions[vertex as usize];
            for &neighbour in self.adjacency.of(vertex) {
                let next = distance + here.distance(self.positions[neighbour as usize]);
                if next < distances[neighbour as usize] {
                    distances[neighbour as usize] = next;
                    heap.push(Visit(next, neighbour));
                }
            }
        }
        distances
    }

    /// Each listed vertex's protrusion at each radius: how far it stands out along its normal from
    /// the centroid of the surface within the radius (reached along edges), over the radius. A tip
    /// (fingertip, toe, nose) is near +0.5 to +1, a flat patch 0, a pit or crease negative. Being a
    /// ratio to the radius, it does not change when the shape is scaled.
    pub fn protrusions(&self, vertices: &[u32], radii: &[f32]) -> Vec<Vec<f32>> {
        self.per_vertex(vertices, |vertex, scratch, ball| {
            radii
                .iter()
                .map(|&radius| self.protrusion(vertex, radius, scratch, ball))
                .collect()
        })
    }

    /// `work(vertex, scratch, ball)` for each listed vertex in parallel, with per-task scratch space.
    fn per_vertex<T: Send>(
        &self,
        vertices: &[u32],
        work: impl Fn(u32, &mut Scratch, &mut Vec<u32>) -> T + Sync + Send,
    ) -> Vec<T> {
        vertices
            .par_iter()
            .with_min_len(VERTICES_PER_TASK)
            .map_init(
                || (Scratch::new(self.positions.len()), Vec::new()),
                |(scratch, ball), &vertex| work(vertex, scratch, ball),
            )
            .collect()
    }

    /// The vertices within `radius` of `vertex` along edges (the vertex first), into `ball`.
    fn ball(&self, vertex: u32, radius: f32, scratch: &mut Scratch, ball: &mut Vec<u32>) {
        gather(
            self.positions,
            &self.adjacency,
            vertex,
            radius,
            MIN_NEIGHBOURHOOD,
            scratch,
            ball,
        );
    }

    fn protrusion(
        &self,
        vertex: u32,
        radius: f32,
        scratch: &mut Scratch,
        ball: &mut Vec<u32>,
    ) -> f32 {
        self.ball(vertex, radius, scratch, ball);
        if ball.len() < 2 || radius <= 0.0 {
            return 0.0;
        }
        let sum: Vec3 = ball[1..].iter().map(|&v| self.positions[v as usize]).sum();
        let centroid = sum / (ball.len() - 1) as f32;
        let here = self.positions[vertex as usize];
        (here - centroid).dot(self.normals[vertex as usize]) / radius
    }

    /// The distinct points among `vertices` (with their protrusion `values`, same order): those
    /// whose |protrusion| reaches `threshold` and is the extreme of its sign within `radius`
    /// (reached along edges) among the listed vertices. `value_of[v]` is the protrusion of any
    /// listed vertex `v`, NaN for the others.
    pub fn extremes(
        &self,
        vertices: &[u32],
        value_of: &[f32],
        radius: f32,
        threshold: f32,
    ) -> Vec<u32> {
        self.per_vertex(vertices, |vertex, scratch, ball| {
            let value = value_of[vertex as usize];
            if value.is_nan() || value.abs() < threshold {
                return None;
            }
            self.ball(vertex, radius, scratch, ball);
            let sign = value.signum();
            let beaten = ball[1..].iter().any(|&other| {
                let other_value = value_of[other as usize] * sign;
                other_value > value * sign || (other_value == value * sign && other < vertex)
            });
            (!beaten).then_some(vertex)
        })
        .into_iter()
        .flatten()
        .collect()
    }
}

/// A Dijkstra queue entry, ordered nearest first.
#[derive(PartialEq)]
struct Visit(f32, u32);

impl Eq for Visit {}

impl PartialOrd for Visit {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Visit {
    fn cmp(&self, other: &Self) -> Ordering {
        other
            .0
            .total_cmp(&self.0)
            .then_with(|| other.1.cmp(&self.1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat `n × n` grid of unit cells in z = 0 with its centre vertex raised by `height`.
    fn bump(n: u32, height: f32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut positions = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                positions.push(Vec3::new(i as f32, j as f32, 0.0));
            }
        }
        let centre = (n / 2) * (n + 1) + n / 2;
        positions[centre as usize].z = height;
        let mut triangles = Vec::new();
        for j in 0..n {
            for i in 0..n {
                let a = j * (n + 1) + i;
                triangles.push([a, a + 1, a + n + 2]);
                triangles.push([a, a + n + 2, a + n + 1]);
            }
        }
        (positions, triangles)
    }

    #[test]
    fn geodesic_distances_follow_edges() {
        let (positions, triangles) = bump(4, 0.0);
        let shape = Shape::new(&positions, &triangles);
        let distances = shape.geodesic(&[(0, 0.0)]);
        assert_eq!(distances[0], 0.0);
        assert!((distances[1] - 1.0).abs() < 1e-6);
        // The diagonal edge (0 → 6) is one step of √2.
        assert!((distances[6] - std::f32::consts::SQRT_2).abs() < 1e-6);
    }

    #[test]
    fn a_raised_vertex_protrudes_and_is_the_only_extreme() {
        let (positions, triangles) = bump(8, 1.0);
        let shape = Shape::new(&positions, &triangles);
        let all: Vec<u32> = (0..positions.len() as u32).collect();
        let values: Vec<f32> = shape
            .protrusions(&all, &[1.5])
            .into_iter()
            .map(|v| v[0])
            .collect();
        let centre = 4 * 9 + 4;
        assert!(values[centre] > 0.3, "{}", values[centre]);
        let extremes = shape.extremes(&all, &values, 1.5, 0.3);
        assert_eq!(extremes, vec![centre as u32]);
        // Flat: nothing stands out.
        let (flat, triangles) = bump(8, 0.0);
        let shape = Shape::new(&flat, &triangles);
        let values: Vec<f32> = shape
            .protrusions(&all, &[1.5])
            .into_iter()
            .map(|v| v[0])
            .collect();
        assert!(values.iter().all(|v| v.abs() < 1e-6));
    }
}
