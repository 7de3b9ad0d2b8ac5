//! Feature detection: principal curvatures, regions and ridge / valley curves.

use proptest::prelude::*;
use springwrap_kernel::{FeatureSettings, KernelError, detect_features};

use crate::hostile::{config, distance, random_target, target};

proptest! {
    #![proptest_config(config("tests/fuzz/proptest-regressions/features.txt", 600))]

    #[test]
    fn features_are_finite_or_refused(
        mesh in prop_oneof![
            3 => target(),
            2 => random_target(),
        ],
        scale in prop_oneof![4 => 0.05f32..1.5, 1 => distance()],
        thresholds in (distance(), distance(), distance(), distance()),
        defaults in any::<bool>(),
    ) {
        let settings = if defaults {
            FeatureSettings::with_scale(scale)
        } else {
            FeatureSettings {
                scale,
                flat_threshold: thresholds.0,
                ridge_threshold: thresholds.1,
                min_length: thresholds.2,
                join_distance: thresholds.3,
            }
        };
        match detect_features(&mesh, &settings) {
            Ok(features) => {
                let curvatures = &features.curvatures;
                prop_assert!(curvatures.k1.iter().chain(&curvatures.k2).all(|k| k.is_finite()));
                prop_assert!(curvatures.d1.iter().chain(&curvatures.d2).all(|d| d.is_finite()));
                prop_assert_eq!(features.regions.len(), mesh.vertices().len());
                for curve in &features.curves {
                    prop_assert!(curve.points.iter().all(|p| p.is_finite()));
                }
            }
            Err(
                KernelError::InvalidScale { .. }
                | KernelError::InvalidArgument { .. }
                | KernelError::FlatSurface { .. },
            ) => {}
            Err(other) => prop_assert!(false, "undocumented error: {other:?}"),
        }
    }
}
