//! `TargetMesh::new` and what a built mesh derives (trees, adjacency, normals, bounds).

use proptest::prelude::*;
use springwrap_kernel::{KernelError, TargetMesh, TargetMeshOptions};

use crate::hostile::{config, raw_mesh};

proptest! {
    #![proptest_config(config("tests/fuzz/proptest-regressions/target_mesh.txt", 3000))]

    #[test]
    fn a_target_mesh_is_built_or_refused((vertices, triangles) in raw_mesh(), reject in any::<bool>()) {
        let vertex_count = vertices.len();
        let triangle_count = triangles.len();
        let options = TargetMeshOptions { reject_degenerate: reject };
        match TargetMesh::new(vertices, triangles, options) {
            Ok(mesh) => {
                mesh.prepare_all();
                let (low, high) = mesh.bounding_box();
                prop_assert!(low.is_finite() && high.is_finite());
                prop_assert_eq!(mesh.face_normals().len(), triangle_count);
                prop_assert!(mesh.face_normals().iter().all(|n| n.is_finite()));
                prop_assert_eq!(mesh.vertex_normals().len(), vertex_count);
                prop_assert!(mesh.vertex_normals().iter().all(|n| n.is_finite()));
                prop_assert!(mesh.degenerate_triangle_count() < triangle_count);
                for neighbors in mesh.triangle_neighbors() {
                    for &neighbor in neighbors {
                        prop_assert!(
                            neighbor == springwrap_kernel::NO_TRIANGLE
                                || (neighbor as usize) < triangle_count
                        );
                    }
                }
                let edges_valid = mesh
                    .boundary_edges()
                    .iter()
                    .all(|edge| (edge.triangle as usize) < triangle_count && edge.edge < 3);
                prop_assert!(edges_valid);
            }
            Err(
                KernelError::EmptyMesh { .. }
                | KernelError::NonFinite { what: "vertex", .. }
                | KernelError::CoordinateOutOfRange { what: "vertex", .. }
                | KernelError::VertexIndexOutOfRange { .. }
                | KernelError::DegenerateTriangle { .. }
                | KernelError::DegenerateMesh { .. },
            ) => {}
            Err(other) => prop_assert!(false, "undocumented error: {other:?}"),
        }
    }
}
