//! The surface walk (`walk_many`): face-points moved along the target by displacements.

use proptest::prelude::*;
use springwrap_kernel::{FacePoint, KernelError, WalkEnd};

use crate::hostile::{barycentric, config, index, random_target, target, vector};

proptest! {
    #![proptest_config(config("tests/fuzz/proptest-regressions/walk.txt", 2500))]

    #[test]
    fn walks_end_on_the_surface_or_lifted_with_finite_numbers(
        mesh in prop_oneof![target(), random_target()],
        walks in prop::collection::vec(((index(300), barycentric()), vector()), 0..10),
    ) {
        let (starts, displacements): (Vec<FacePoint>, Vec<_>) = walks
            .into_iter()
            .map(|((triangle, barycentric), displacement)| {
                (FacePoint { triangle, barycentric }, displacement)
            })
            .unzip();
        match mesh.walk_many(&starts, &displacements) {
            Ok(ends) => {
                prop_assert_eq!(ends.len(), starts.len());
                for end in ends {
                    match end {
                        WalkEnd::OnSurface(face_point) => {
                            prop_assert!((face_point.triangle as usize) < mesh.triangles().len());
                            prop_assert!(face_point.barycentric.is_finite(), "{face_point:?}");
                        }
                        WalkEnd::Lifted { position, exit, .. } => {
                            prop_assert!(position.is_finite(), "{position:?}");
                            prop_assert!((exit.triangle as usize) < mesh.triangles().len());
                            prop_assert!(exit.barycentric.is_finite());
                        }
                    }
                }
            }
            Err(
                KernelError::TriangleIndexOutOfRange { .. }
                | KernelError::NonFinite { .. }
                | KernelError::CoordinateOutOfRange { what: "displacement", .. }
                | KernelError::InvalidArgument { name: "barycentric", .. },
            ) => {}
            Err(other) => prop_assert!(false, "undocumented error: {other:?}"),
        }
    }
}
