//! Alignment: `fit_transform` (anchors) and anchored ICP against a target.

use glam::Vec3;
use proptest::prelude::*;
use proptest::sample::select;
use springwrap_kernel::{
    AlignMethod, IcpAnchors, IcpSettings, IcpUpdate, KernelError, Transform, fit_transform,
    icp_anchored,
};

use crate::hostile::{SPECIAL_VALUES, config, distance, mild_vector, target, vector};

fn method() -> impl Strategy<Value = AlignMethod> {
    select(vec![
        AlignMethod::Rigid,
        AlignMethod::Similarity,
        AlignMethod::Affine,
    ])
}

fn weight() -> impl Strategy<Value = f32> {
    prop_oneof![8 => 0.0f32..2.0, 1 => select(SPECIAL_VALUES.to_vec()), 1 => Just(-1.0f32)]
}

/// A starting transform: mostly a rotation, scale and shift, sometimes hostile entries.
fn transform() -> impl Strategy<Value = Transform> {
    let entry = prop_oneof![
        10 => -1.5f64..1.5,
        1 => select(vec![f64::NAN, f64::INFINITY, 1e30, -1e12, 1e9, 0.0]),
    ];
    prop_oneof![
        3 => (-3.2f64..3.2, 0.5f64..2.0, mild_vector()).prop_map(|(angle, scale, shift)| {
            let (sin, cos) = angle.sin_cos();
            Transform::from_linear_translation(
                [[cos * scale, -sin * scale, 0.0], [sin * scale, cos * scale, 0.0], [0.0, 0.0, scale]],
                shift.as_dvec3(),
            )
        }),
        1 => (prop::array::uniform3(prop::array::uniform3(entry.clone())), prop::array::uniform3(entry))
            .prop_map(|(linear, shift)| {
                Transform::from_linear_translation(linear, glam::DVec3::from_array(shift))
            }),
        1 => Just(Transform::IDENTITY),
    ]
}

fn icp_settings() -> impl Strategy<Value = IcpSettings> {
    (
        select(vec![IcpUpdate::Rigid, IcpUpdate::Similarity]),
        prop_oneof![6 => 0u32..12, 1 => select(vec![100_001, u32::MAX])],
        prop_oneof![6 => 0.0f32..0.9, 1 => select(vec![1.0, -0.1, f32::NAN, 0.999_999])],
        distance(),
        prop_oneof![6 => 0.0f64..1e-3, 1 => select(vec![f64::NAN, -1.0, 2.0, f64::INFINITY])],
        any::<bool>(),
    )
        .prop_map(
            |(update, max_iterations, trim_fraction, max_distance, tolerance, ignore_boundary)| {
                IcpSettings {
                    update,
                    max_iterations,
                    trim_fraction,
                    max_distance,
                    tolerance,
                    ignore_boundary,
                }
            },
        )
}

fn fit_error(error: &KernelError) -> bool {
    matches!(
        error,
        KernelError::LengthMismatch { .. }
            | KernelError::NonFinite { .. }
            | KernelError::CoordinateOutOfRange { .. }
            | KernelError::InvalidArgument { .. }
            | KernelError::TooFewPairs { .. }
            | KernelError::CoincidentAnchors { .. }
            | KernelError::CollinearAnchors { .. }
            | KernelError::CoplanarAnchors { .. }
    )
}

proptest! {
    #![proptest_config(config("tests/fuzz/proptest-regressions/align.txt", 1500))]

    #[test]
    fn fit_transform_is_finite_or_refused(
        pairs in prop::collection::vec((vector(), vector(), weight()), 0..8),
        method in method(),
        weighted in any::<bool>(),
        truncate_weights in any::<bool>(),
    ) {
        let source: Vec<Vec3> = pairs.iter().map(|pair| pair.0).collect();
        let target: Vec<Vec3> = pairs.iter().map(|pair| pair.1).collect();
        let mut weights: Vec<f32> = pairs.iter().map(|pair| pair.2).collect();
        if truncate_weights {
            weights.pop();
        }
        match fit_transform(&source, &target, method, weighted.then_some(weights.as_slice())) {
            Ok(transform) => prop_assert!(transform.is_finite(), "{transform:?}"),
            Err(error) => prop_assert!(fit_error(&error), "{error:?}"),
        }
    }

    #[test]
    fn icp_is_finite_or_refused(
        mesh in target(),
        source in prop::collection::vec(prop_oneof![6 => mild_vector(), 1 => vector()], 0..24),
        anchors in prop::collection::vec((vector(), mild_vector()), 0..5),
        anchor_weight in prop_oneof![4 => 0.0f64..3.0, 1 => select(vec![f64::NAN, -1.0, 1e7, f64::INFINITY])],
        initial in transform(),
        settings in icp_settings(),
    ) {
        let (anchor_source, anchor_target): (Vec<Vec3>, Vec<Vec3>) = anchors.into_iter().unzip();
        let anchors = IcpAnchors { source: &anchor_source, target: &anchor_target, weight: anchor_weight };
        match icp_anchored(&mesh, &source, anchors, initial, settings) {
            Ok(report) => {
                prop_assert!(report.transform.is_finite(), "{report:?}");
                prop_assert!(report.rms_before.is_finite() && report.rms_after.is_finite(), "{report:?}");
            }
            Err(error) => prop_assert!(fit_error(&error), "{error:?}"),
        }
    }
}
