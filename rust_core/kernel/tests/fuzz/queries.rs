//! The queries of a built mesh: closest point (snap), nearest vertex, ray casts (project) and
//! face-point positions.

use glam::Vec3;
use proptest::prelude::*;
use springwrap_kernel::{FacePoint, KernelError, SurfaceHit, TargetMesh};

use crate::hostile::{barycentric, config, distance, index, random_target, target, vector};

/// A mesh to query: one of the fixed targets, or a random one that its checks accepted.
fn mesh() -> impl Strategy<Value = std::sync::Arc<TargetMesh>> {
    prop_oneof![
        2 => target(),
        2 => random_target(),
    ]
}

fn check_hit(mesh: &TargetMesh, hit: &SurfaceHit, signed: bool) -> Result<(), TestCaseError> {
    prop_assert!((hit.face_point.triangle as usize) < mesh.triangles().len());
    prop_assert!(hit.face_point.barycentric.is_finite(), "{hit:?}");
    prop_assert!(hit.position.is_finite(), "{hit:?}");
    prop_assert!(hit.distance.is_finite(), "{hit:?}");
    prop_assert!(signed || hit.distance >= 0.0, "{hit:?}");
    Ok(())
}

/// The errors a query may return about its own arguments.
fn query_error(error: &KernelError) -> bool {
    matches!(
        error,
        KernelError::NonFinite { .. }
            | KernelError::CoordinateOutOfRange { .. }
            | KernelError::InvalidArgument {
                name: "max_distance",
                ..
            }
            | KernelError::LengthMismatch { .. }
            | KernelError::ZeroDirection { .. }
    )
}

proptest! {
    #![proptest_config(config("tests/fuzz/proptest-regressions/queries.txt", 2500))]

    #[test]
    fn snap_finds_finite_closest_points_or_refuses(
        mesh in mesh(),
        points in prop::collection::vec(vector(), 0..12),
        max_distance in distance(),
    ) {
        // The single, unchecked queries find nothing where the batch refuses, and never panic.
        for &point in &points {
            if let Some(hit) = mesh.closest_point(point, max_distance) {
                check_hit(&mesh, &hit, false)?;
            }
            if let Some(hit) = mesh.nearest_vertex(point, max_distance) {
                prop_assert!(hit.position.is_finite() && hit.distance.is_finite());
            }
        }
        match mesh.closest_points(&points, max_distance) {
            Ok(hits) => {
                prop_assert_eq!(hits.len(), points.len());
                for hit in hits.iter().flatten() {
                    check_hit(&mesh, hit, false)?;
                    prop_assert!(hit.distance <= max_distance);
                }
            }
            Err(error) => prop_assert!(query_error(&error), "{error:?}"),
        }
        match mesh.nearest_vertices(&points, max_distance) {
            Ok(hits) => {
                for hit in hits.iter().flatten() {
                    prop_assert!((hit.vertex as usize) < mesh.vertices().len());
                    prop_assert!(hit.position.is_finite() && hit.distance.is_finite());
                    prop_assert!(hit.face_point.barycentric.is_finite());
                }
            }
            Err(error) => prop_assert!(query_error(&error), "{error:?}"),
        }
    }

    #[test]
    fn project_finds_finite_hits_or_refuses(
        mesh in mesh(),
        rays in prop::collection::vec((vector(), vector()), 0..12),
        max_distance in distance(),
        both_directions in any::<bool>(),
    ) {
        let (origins, directions): (Vec<Vec3>, Vec<Vec3>) = rays.into_iter().unzip();
        for (&origin, &direction) in origins.iter().zip(&directions) {
            if let Some(hit) = mesh.ray_cast(origin, direction, max_distance, both_directions) {
                check_hit(&mesh, &hit, both_directions)?;
            }
        }
        match mesh.ray_casts(&origins, &directions, max_distance, both_directions) {
            Ok(hits) => {
                prop_assert_eq!(hits.len(), origins.len());
                for hit in hits.iter().flatten() {
                    check_hit(&mesh, hit, both_directions)?;
                    prop_assert!(hit.distance.abs() <= max_distance);
                }
            }
            Err(error) => prop_assert!(query_error(&error), "{error:?}"),
        }
    }

    #[test]
    fn face_point_positions_are_finite_or_refused(
        mesh in mesh(),
        face_points in prop::collection::vec((index(40), barycentric()), 0..10),
    ) {
        let face_points: Vec<FacePoint> = face_points
            .into_iter()
            .map(|(triangle, barycentric)| FacePoint { triangle, barycentric })
            .collect();
        match mesh.face_point_positions(&face_points) {
            Ok(positions) => prop_assert!(positions.iter().all(|p| p.is_finite()), "{positions:?}"),
            Err(
                KernelError::TriangleIndexOutOfRange { .. }
                | KernelError::NonFinite { what: "barycentric", .. }
                | KernelError::InvalidArgument { name: "barycentric", .. },
            ) => {}
            Err(other) => prop_assert!(false, "undocumented error: {other:?}"),
        }
    }
}
