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
