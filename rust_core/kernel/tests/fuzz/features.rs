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
        scale in prop_oneof![4 => 0.05f32..1.5, 1 => Just(0.0f32), 1 => distance()],
        thresholds in (distance(), distance(), distance(), distance()),
        hysteresis in prop_oneof![3 => 0.0f32..1.0, 1 => distance()],
        layout_edge_length in prop_oneof![2 => Just(0.0f32), 2 => 0.05f32..1.0, 1 => distance()],
        defaults in any::<bool>(),
    ) {
        let settings = if defaults {
            FeatureSettings { layout_edge_length, ..FeatureSettings::with_scale(scale) }
        } else {
            FeatureSettings {
                scale,
                layout_edge_length,
                flat_threshold: thresholds.0,
                ridge_threshold: thresholds.1,
                hysteresis,
                min_length: Some(thresholds.2),
                join_distance: Some(thresholds.3),
            }
        };
        match detect_features(&mesh, &settings) {
            Ok(features) => {
                let curvatures = &features.curvatures;
                prop_assert!(curvatures.k1.iter().chain(&curvatures.k2).all(|k| k.is_finite()));
                prop_assert!(curvatures.d1.iter().chain(&curvatures.d2).all(|d| d.is_finite()));
                prop_assert_eq!(features.regions.len(), mesh.vertices().len());
                prop_assert!(features.scale.is_finite() && features.scale > 0.0);
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
