//! Adjacency, boundaries and normals on meshes whose answers are known.

mod common;

use common::{grid, uv_sphere};
use glam::Vec3;
use springwrap_kernel::{NO_TRIANGLE, TargetMesh, TargetMeshOptions};

#[test]
fn a_closed_sphere_has_no_boundary_and_symmetric_adjacency() {
    let (vertices, triangles) = uv_sphere(1.0, 12, 20);
    let mesh = TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap();
    assert!(mesh.boundary_edges().is_empty());
    assert_eq!(mesh.non_manifold_edge_count(), 0);
    for (triangle, neighbors) in mesh.triangle_neighbors().iter().enumerate() {
        for &neighbor in neighbors {
            assert_ne!(neighbor, NO_TRIANGLE);
            assert!(mesh.triangle_neighbors()[neighbor as usize].contains(&(triangle as u32)));
        }
    }
    // Vertex normals of a sphere point outwards along the position.
    for (vertex, normal) in mesh.vertices().iter().zip(mesh.vertex_normals()) {
        assert!(normal.dot(vertex.normalize()) > 0.99);
    }
}

#[test]
fn a_grid_with_a_hole_reports_border_and_hole_edges() {
    let (vertices, mut triangles) = grid(6);
    // Remove the two triangles of cell (2, 2) and the two of cell (3, 2): a 2x1 hole.
    let cell = |x: usize, y: usize| (y * 6 + x) * 2;
    for index in [cell(3, 2) + 1, cell(3, 2), cell(2, 2) + 1, cell(2, 2)] {
        triangles.remove(index);
    }
    let mesh = TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap();
    // Outer border: 4 * 6 edges; hole: perimeter of a 2x1 rectangle = 6 edges.
    assert_eq!(mesh.boundary_edges().len(), 24 + 6);
    for edge in mesh.boundary_edges() {
        assert_eq!(
            mesh.triangle_neighbors()[edge.triangle as usize][usize::from(edge.edge)],
            NO_TRIANGLE
        );
    }
    // The grid faces +z.
    for normal in mesh.face_normals() {
        assert_eq!(*normal, Vec3::Z);
    }
    let (min, max) = mesh.bounding_box();
    assert_eq!((min, max), (Vec3::ZERO, Vec3::new(6.0, 6.0, 0.0)));
}

#[test]
fn degenerate_triangles_have_zero_normals_and_are_counted() {
    let vertices = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(2.0, 0.0, 0.0)];
    let triangles = vec![[0, 1, 2], [0, 1, 3], [2, 2, 2]];
    let mesh = TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap();
    assert_eq!(mesh.degenerate_triangle_count(), 2);
    assert_eq!(mesh.face_normals()[1], Vec3::ZERO);
    assert_eq!(mesh.face_normals()[2], Vec3::ZERO);
    assert_eq!(mesh.vertex_normals()[3], Vec3::ZERO);
    assert_eq!(mesh.vertex_normals()[0], Vec3::Z);
}

/// Adjacency by the definition: every undirected edge and the half-edges on it, in a map.
fn adjacency_by_definition(triangles: &[[u32; 3]]) -> (Vec<[u32; 3]>, Vec<(u32, u8)>, usize) {
    let mut edges: std::collections::BTreeMap<(u32, u32), Vec<u32>> =
        std::collections::BTreeMap::new();
    for (triangle, corners) in triangles.iter().enumerate() {
        for edge in 0..3 {
            let (start, end) = (corners[edge], corners[(edge + 1) % 3]);
            if start != end {
                edges
                    .entry((start.min(end), start.max(end)))
                    .or_default()
                    .push(triangle as u32 * 3 + edge as u32);
            }
        }
    }
    let mut neighbors = vec![[NO_TRIANGLE; 3]; triangles.len()];
    let mut boundary = Vec::new();
    let mut non_manifold = 0;
    for half_edges in edges.values() {
        match half_edges[..] {
            [only] => boundary.push((only / 3, (only % 3) as u8)),
            [first, second] if first / 3 == second / 3 => {}
            [first, second] => {
                neighbors[(first / 3) as usize][(first % 3) as usize] = second / 3;
                neighbors[(second / 3) as usize][(second % 3) as usize] = first / 3;
            }
            _ => non_manifold += 1,
        }
    }
    boundary.sort_unstable();
    (neighbors, boundary, non_manifold)
}

#[test]
fn adjacency_matches_its_definition_on_messy_soups() {
    // A grid with pseudo-random triangles added on top: repeated indices (collapsed edges), fins
    // (three or more triangles on an edge), fans around one vertex, duplicated triangles.
    let (vertices, mut triangles) = grid(12);
    let vertex_count = vertices.len() as u32;
    let mut state = 0x2545_f491_u32;
    let mut next = |modulus: u32| {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        state % modulus
    };
    for _ in 0..400 {
        let corners = match next(4) {
            0 => [next(vertex_count), next(vertex_count), next(vertex_count)],
            1 => {
                let vertex = next(vertex_count);
                [vertex, vertex, next(vertex_count)]
            }
            2 => triangles[next(triangles.len() as u32) as usize],
            _ => [0, next(vertex_count), next(vertex_count)],
        };
        triangles.push(corners);
    }
    let (neighbors, boundary, non_manifold) = adjacency_by_definition(&triangles);
    let mesh = TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap();
    assert_eq!(mesh.triangle_neighbors(), &neighbors[..]);
    let found: Vec<(u32, u8)> = mesh
        .boundary_edges()
        .iter()
        .map(|edge| (edge.triangle, edge.edge))
        .collect();
    assert_eq!(found, boundary);
    assert_eq!(mesh.non_manifold_edge_count(), non_manifold);
    assert!(non_manifold > 0 && !boundary.is_empty());
}
