//! Every error variant, provoked on purpose, with a message that names the problem.

use glam::Vec3;
use springwrap_kernel::{FacePoint, KernelError, TargetMesh, TargetMeshOptions};

fn triangle() -> (Vec<Vec3>, Vec<[u32; 3]>) {
    (vec![Vec3::ZERO, Vec3::X, Vec3::Y], vec![[0, 1, 2]])
}

fn mesh() -> TargetMesh {
    let (vertices, triangles) = triangle();
    TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap()
}

#[test]
fn empty_meshes() {
    let error = TargetMesh::new(vec![], vec![], TargetMeshOptions::default()).unwrap_err();
    assert_eq!(
        error,
        KernelError::EmptyMesh {
            vertex_count: 0,
            triangle_count: 0
        }
    );
    let error =
        TargetMesh::new(vec![Vec3::ZERO], vec![], TargetMeshOptions::default()).unwrap_err();
    assert!(error.to_string().contains("0 triangles"));
}

#[test]
fn non_finite_vertices_and_queries() {
    let (mut vertices, triangles) = triangle();
    vertices[1].y = f32::NAN;
    let error = TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap_err();
    assert_eq!(
        error,
        KernelError::NonFinite {
            what: "vertex",
            index: 1
        }
    );
    let mesh = mesh();
    let points = [Vec3::ZERO, Vec3::new(0.0, f32::INFINITY, 0.0)];
    assert_eq!(
        mesh.closest_points(&points, f32::INFINITY).unwrap_err(),
        KernelError::NonFinite {
            what: "point",
            index: 1
        }
    );
    assert!(mesh.nearest_vertices(&points, f32::INFINITY).is_err());
    let error = mesh
        .ray_casts(&points, &[Vec3::Z, Vec3::Z], f32::INFINITY, false)
        .unwrap_err();
    assert_eq!(
        error,
        KernelError::NonFinite {
            what: "ray origin",
            index: 1
        }
    );
    let error = mesh
        .ray_casts(
            &[Vec3::ZERO],
            &[Vec3::new(f32::NAN, 0.0, 1.0)],
            f32::INFINITY,
            false,
        )
        .unwrap_err();
    assert_eq!(
        error,
        KernelError::NonFinite {
            what: "ray direction",
            index: 0
        }
    );
    let nan_face_point = FacePoint {
        triangle: 0,
        barycentric: Vec3::NAN,
    };
    assert_eq!(
        mesh.face_point_positions(&[nan_face_point]).unwrap_err(),
        KernelError::NonFinite {
            what: "barycentric",
            index: 0
        }
    );
}

#[test]
fn out_of_range_indices() {
    let (vertices, _) = triangle();
    let error = TargetMesh::new(
        vertices,
        vec![[0, 1, 2], [0, 7, 1]],
        TargetMeshOptions::default(),
    )
    .unwrap_err();
    assert_eq!(
        error,
        KernelError::VertexIndexOutOfRange {
            triangle: 1,
            corner: 1,
            vertex: 7,
            vertex_count: 3
        }
    );
    assert!(error.to_string().contains("vertex 7"));
    let face_point = FacePoint {
        triangle: 4,
        barycentric: Vec3::X,
    };
    assert_eq!(
        mesh().face_point_position(face_point).unwrap_err(),
        KernelError::TriangleIndexOutOfRange {
            index: 0,
            triangle: 4,
            triangle_count: 1
        }
    );
}

#[test]
fn degenerate_triangles_and_meshes() {
    let vertices = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(2.0, 0.0, 0.0)];
    let error = TargetMesh::new(
        vertices.clone(),
        vec![[0, 1, 3]],
        TargetMeshOptions::default(),
    )
    .unwrap_err();
    assert_eq!(error, KernelError::DegenerateMesh { triangle_count: 1 });
    let strict = TargetMeshOptions {
        reject_degenerate: true,
    };
    let error = TargetMesh::new(vertices.clone(), vec![[0, 1, 2], [0, 1, 3]], strict).unwrap_err();
    assert_eq!(error, KernelError::DegenerateTriangle { triangle: 1 });
    assert!(
        TargetMesh::new(
            vertices,
            vec![[0, 1, 2], [0, 1, 3]],
            TargetMeshOptions::default()
        )
        .is_ok()
    );
}

#[test]
fn bad_rays_and_arguments() {
    let mesh = mesh();
    let error = mesh
        .ray_casts(&[Vec3::ZERO], &[Vec3::ZERO], 1.0, false)
        .unwrap_err();
    assert_eq!(error, KernelError::ZeroDirection { index: 0 });
    let error = mesh
        .ray_casts(&[Vec3::ZERO; 2], &[Vec3::Z], 1.0, false)
        .unwrap_err();
    assert!(matches!(
        error,
        KernelError::LengthMismatch {
            first: 2,
            second: 1,
            ..
        }
    ));
    for bad in [-1.0, f32::NAN] {
        let error = mesh.closest_points(&[Vec3::ZERO], bad).unwrap_err();
        assert!(matches!(
            error,
            KernelError::InvalidArgument {
                name: "max_distance",
                ..
            }
        ));
    }
}

#[test]
fn too_large_is_reported_in_words() {
    let error = KernelError::TooLarge {
        what: "triangles",
        count: 3_000_000_000,
        max: i32::MAX as usize,
    };
    assert!(error.to_string().contains("too many triangles"));
}

/// A strip of `count` triangles over `count + 2` vertices: large enough that the validation runs in parallel.
fn strip(count: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let vertices = (0..count + 2)
        .map(|index| Vec3::new((index / 2) as f32, (index % 2) as f32, 0.0))
        .collect();
    let triangles = (0..count)
        .map(|index| [index, index + 1, index + 2])
        .collect();
    (vertices, triangles)
}

#[test]
fn a_large_mesh_names_its_first_bad_vertex_and_triangle() {
    let (mut vertices, triangles) = strip(200_000);
    vertices[150_001].y = f32::INFINITY;
    vertices[90_003].z = f32::NAN;
    vertices[180_000].x = 3e9;
    assert_eq!(
        TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap_err(),
        KernelError::NonFinite {
            what: "vertex",
            index: 90_003
        }
    );
    let (mut vertices, triangles) = strip(200_000);
    vertices[170_000].x = -3e9;
    assert!(matches!(
        TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap_err(),
        KernelError::CoordinateOutOfRange { index: 170_000, .. }
    ));
    let (vertices, mut triangles) = strip(200_000);
    triangles[160_000][0] = 300_000;
    triangles[120_000][2] = 250_000;
    triangles[120_000][1] = 400_000;
    assert_eq!(
        TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap_err(),
        KernelError::VertexIndexOutOfRange {
            triangle: 120_000,
            corner: 1,
            vertex: 400_000,
            vertex_count: 200_002
        }
    );
}
