//! The input policy (`validate.rs`) at every entry point, and a regression test for each crash
//! the fuzz targets (`tests/fuzz`) or the bug reports found: finite-but-absurd values are refused with
//! the array, the row and the value; counts never drive an allocation the arrays do not back;
//! the single, unchecked queries find nothing instead of panicking.

mod common;

use std::sync::Arc;

use glam::Vec3;
use springwrap_kernel::mesh::MAX_ELEMENTS;
use springwrap_kernel::{
    Anchor, AnchorTarget, CurveConstraint, FacePoint, FeatureSettings, IcpAnchors, IcpSettings,
    KernelError, LayoutPoint, LayoutStructure, MAX_COORDINATE, TargetMesh, TargetMeshOptions,
    Transform, WrapSettings, WrapSolver, detect_features, icp_anchored,
};

fn unit_triangle() -> TargetMesh {
    TargetMesh::new(
        vec![Vec3::ZERO, Vec3::X, Vec3::Y],
        vec![[0, 1, 2]],
        TargetMeshOptions::default(),
    )
    .unwrap()
}

#[test]
fn a_layout_vertex_count_past_32_bit_indices_is_refused_without_allocating() {
    // The bug: `LayoutStructure(2**31, empty, empty)` aborted on a 51 GB allocation.
    for count in [1usize << 31, 1 << 40, usize::MAX] {
        let error = LayoutStructure::new(count, &[], &[], &[], &[]).unwrap_err();
        assert_eq!(
            error,
            KernelError::TooLarge {
                what: "layout vertices",
                count,
                max: MAX_ELEMENTS
            }
        );
    }
    // The largest count is accepted, and costs nothing: no vertex is used.
    let structure = LayoutStructure::new(MAX_ELEMENTS, &[], &[], &[], &[]).unwrap();
    assert_eq!(structure.vertex_count, MAX_ELEMENTS);
    assert!(structure.neighbors_of(MAX_ELEMENTS as u32 - 1).is_empty());
}

#[test]
fn a_face_on_vertices_near_2_pow_31_is_read_sparsely_not_allocated_densely() {
    // Found by the layout fuzz target: a valid face on vertex 2^31 - 2 made the structure
    // allocate per-vertex tables up to that index (an 11 GB allocation, then an abort).
    let top = MAX_ELEMENTS as u32 - 1;
    let corners = [top - 3, top - 2, top - 1, top];
    let sparse = LayoutStructure::new(MAX_ELEMENTS, &corners, &[4], &[], &[]).unwrap();
    let dense = LayoutStructure::new(4, &[0, 1, 2, 3], &[4], &[], &[]).unwrap();
    let shift = top - 3;
    assert_eq!(
        sparse.corners,
        dense.corners.iter().map(|v| v + shift).collect::<Vec<_>>()
    );
    assert_eq!(sparse.curves.len(), dense.curves.len());
    for vertex in 0..4 {
        let moved: Vec<u32> = dense
            .neighbors_of(vertex)
            .iter()
            .map(|v| v + shift)
            .collect();
        assert_eq!(sparse.neighbors_of(vertex + shift), moved.as_slice());
        assert_eq!(
            sparse.wedge_range(vertex + shift).len(),
            dense.wedge_range(vertex).len()
        );
    }
    assert!(sparse.neighbors_of(0).is_empty());
}

#[test]
fn a_mesh_at_3e38_is_out_of_range_not_degenerate() {
    // The bug: a kernel mesh with 3e38 coordinates was called "degenerate (zero area)".
    let error = TargetMesh::new(
        vec![Vec3::ZERO, Vec3::X * 3e38, Vec3::Y * 3e38],
        vec![[0, 1, 2]],
        TargetMeshOptions::default(),
    )
    .unwrap_err();
    assert_eq!(
        error,
        KernelError::CoordinateOutOfRange {
            what: "vertex",
            index: 1,
            value: 3e38,
            limit: MAX_COORDINATE
        }
    );
    assert_eq!(
        error.to_string(),
        "vertex 1 has a coordinate of 3e38, beyond the kernel's bound of ±1e8 model units"
    );
    // At the bound itself, the mesh is fine.
    let at_bound = vec![
        Vec3::ZERO,
        Vec3::X * MAX_COORDINATE,
        Vec3::Y * MAX_COORDINATE,
    ];
    assert!(TargetMesh::new(at_bound, vec![[0, 1, 2]], TargetMeshOptions::default()).is_ok());
}

#[test]
fn a_query_point_at_float_max_is_refused_not_beyond_max_distance() {
    // The bug: a layout vertex at FLT_MAX made snap report "beyond max distance".
    let mesh = unit_triangle();
    let points = [Vec3::ZERO, Vec3::new(f32::MAX, 0.0, 0.0)];
    assert_eq!(
        mesh.closest_points(&points, f32::INFINITY).unwrap_err(),
        KernelError::CoordinateOutOfRange {
            what: "point",
            index: 1,
            value: f32::MAX,
            limit: MAX_COORDINATE
        }
    );
    let directions = [Vec3::Z, Vec3::new(0.0, 0.0, -1e30)];
    assert!(matches!(
        mesh.ray_casts(&[Vec3::ZERO; 2], &directions, f32::INFINITY, false),
        Err(KernelError::CoordinateOutOfRange {
            what: "ray direction",
            index: 1,
            ..
        })
    ));
}

#[test]
fn single_queries_find_nothing_for_points_the_batch_refuses() {
    // Found by the wrap fuzz target: `closest_point(NaN)` indexed the tree with u32::MAX.
    let mesh = unit_triangle();
    for point in [
        Vec3::NAN,
        Vec3::new(f32::INFINITY, 0.0, 0.0),
        Vec3::new(0.0, f32::MAX, 0.0),
        Vec3::splat(1e30),
    ] {
        assert!(
            mesh.closest_point(point, f32::INFINITY).is_none(),
            "{point}"
        );
        assert!(
            mesh.nearest_vertex(point, f32::INFINITY).is_none(),
            "{point}"
        );
        assert!(
            mesh.ray_cast(point, Vec3::Z, f32::INFINITY, true).is_none(),
            "{point}"
        );
        assert!(
            mesh.ray_cast(Vec3::Z, point, f32::INFINITY, true).is_none(),
            "{point}"
        );
    }
    assert!(mesh.closest_point(Vec3::Z, f32::NAN).is_none());
    assert!(mesh.closest_point(Vec3::Z, -1.0).is_none());
    assert!(mesh.closest_point(Vec3::Z, f32::INFINITY).is_some());
}

#[test]
fn barycentric_weights_outside_the_triangle_are_refused() {
    let mesh = unit_triangle();
    let face_point = FacePoint {
        triangle: 0,
        barycentric: Vec3::new(1e30, 0.0, 0.0),
    };
    let error = mesh.face_point_positions(&[face_point]).unwrap_err();
    assert!(
        matches!(
            error,
            KernelError::InvalidArgument {
                name: "barycentric",
                ..
            }
        ),
        "{error:?}"
    );
    assert!(
        error
            .to_string()
            .contains("barycentric 0 has a weight of 1000000000000000000000000000000")
    );
}

/// A 3 x 3 quad layout above a 2-unit plane, as space-points, and the plane.
fn wrap_inputs() -> (Arc<TargetMesh>, LayoutStructure, Vec<LayoutPoint>) {
    let target = common::plane_target(4, 0.5, 0.0);
    let (structure, positions) = common::quad_layout(3, 0.3, Vec3::new(-0.45, -0.45, 0.2));
    let points = positions.into_iter().map(LayoutPoint::Space).collect();
    (target, structure, points)
}

fn wrap_with_anchor(at: Vec3) -> Result<WrapSolver, KernelError> {
    let (target, structure, points) = wrap_inputs();
    let anchor = Anchor {
        vertex: 5,
        target: AnchorTarget::Space(at),
    };
    WrapSolver::new(
        target,
        structure,
        points,
        &[anchor],
        WrapSettings::default(),
    )
}

#[test]
fn an_anchor_at_a_clamped_infinity_or_far_away_is_refused() {
    // The bug: an anchor at (inf, 0, 0) set through Blender's property is stored as 3.4e38 and
    // was accepted (1e30 too): a 98-vertex wrap then took 27 s instead of 0.02 s.
    for value in [3.4e38, 1e30, -1e9] {
        assert_eq!(
            wrap_with_anchor(Vec3::new(value, 0.0, 0.0)).err().unwrap(),
            KernelError::CoordinateOutOfRange {
                what: "anchor target",
                index: 0,
                value,
                limit: MAX_COORDINATE
            }
        );
    }
    assert_eq!(
        wrap_with_anchor(Vec3::new(f32::NAN, 0.0, 0.0))
            .err()
            .unwrap(),
        KernelError::NonFinite {
            what: "anchor target",
            index: 0
        }
    );
    // Finite and within the bound, but absurd next to a target 2 units wide: beyond the region
    // the wrap can reach (ten times the size of the target and the layout's start).
    let error = wrap_with_anchor(Vec3::new(0.0, 1e7, 0.0)).err().unwrap();
    assert!(
        matches!(error, KernelError::BeyondReach { what: "anchor target", index: 0, distance, .. } if distance == 1e7),
        "{error:?}"
    );
    assert!(
        error
            .to_string()
            .starts_with("anchor target 0 is 1e7 from the target's centre")
    );
    // An anchor just beside the target is fine.
    assert!(wrap_with_anchor(Vec3::new(0.0, 0.0, 0.5)).is_ok());
}

#[test]
fn a_curve_with_a_nan_or_far_point_is_refused_naming_the_point() {
    let (target, structure, points) = wrap_inputs();
    let solver = || {
        WrapSolver::new(
            target.clone(),
            structure.clone(),
            points.clone(),
            &[],
            WrapSettings::default(),
        )
        .unwrap()
    };
    let constraint = |first: u32, points: Vec<Vec3>| CurveConstraint {
        layout_vertices: (first..first + 4).collect(),
        target: points,
        fractions: Vec::new(),
    };
    // Points are numbered through all the curves: the NaN is point 3 (of curve 1).
    let curves = [
        constraint(0, vec![Vec3::ZERO, Vec3::X * 0.5]),
        constraint(12, vec![Vec3::ZERO, Vec3::new(f32::NAN, 0.0, 0.0)]),
    ];
    let error = solver().with_curve_constraints(&curves).err().unwrap();
    assert_eq!(
        error,
        KernelError::NonFinite {
            what: "curve point",
            index: 3
        }
    );
    let far = [constraint(0, vec![Vec3::ZERO, Vec3::new(0.0, 1e6, 0.0)])];
    assert!(matches!(
        solver().with_curve_constraints(&far).err().unwrap(),
        KernelError::BeyondReach {
            what: "curve point",
            index: 1,
            ..
        }
    ));
}

#[test]
fn a_layout_point_or_rest_shape_beyond_the_bound_is_refused() {
    let (target, structure, mut points) = wrap_inputs();
    points[4] = LayoutPoint::Space(Vec3::new(0.0, 0.0, f32::MAX));
    let error = WrapSolver::new(
        target.clone(),
        structure.clone(),
        points,
        &[],
        WrapSettings::default(),
    )
    .err()
    .unwrap();
    assert!(
        matches!(
            error,
            KernelError::CoordinateOutOfRange {
                what: "layout point",
                index: 4,
                ..
            }
        ),
        "{error:?}"
    );
    let (_, _, points) = wrap_inputs();
    let mut rest: Vec<Vec3> = (0..16).map(|i| Vec3::new(i as f32, 0.0, 0.0)).collect();
    rest[7].y = -1e30;
    let error = WrapSolver::with_rest_shape(
        target,
        structure,
        points,
        Some(rest),
        &[],
        WrapSettings::default(),
    )
    .err()
    .unwrap();
    assert!(
        matches!(
            error,
            KernelError::CoordinateOutOfRange {
                what: "rest position",
                index: 7,
                ..
            }
        ),
        "{error:?}"
    );
}

#[test]
fn a_step_of_more_iterations_than_supported_is_refused() {
    let (target, structure, points) = wrap_inputs();
    let mut solver =
        WrapSolver::new(target, structure, points, &[], WrapSettings::default()).unwrap();
    let error = solver
        .step(WrapSettings::MAX_STEP_ITERATIONS + 1)
        .unwrap_err();
    assert!(
        matches!(
            error,
            KernelError::InvalidArgument {
                name: "iterations",
                ..
            }
        ),
        "{error:?}"
    );
    assert!(solver.step(0).is_ok());
}

#[test]
fn icp_refuses_absurd_anchors_transforms_and_settings() {
    let target = common::plane_target(4, 0.5, 0.0);
    let source = [Vec3::ZERO, Vec3::X * 0.2, Vec3::Y * 0.2, Vec3::splat(0.1)];
    let anchor_source = [Vec3::ZERO];
    let anchor_target = [Vec3::new(3.4e38, 0.0, 0.0)];
    let anchors = IcpAnchors {
        source: &anchor_source,
        target: &anchor_target,
        weight: 1.0,
    };
    let settings = IcpSettings::default();
    assert!(matches!(
        icp_anchored(&target, &source, anchors, Transform::IDENTITY, settings),
        Err(KernelError::CoordinateOutOfRange {
            what: "anchor target",
            ..
        })
    ));
    let shift = Transform::from_linear_translation(
        [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        glam::DVec3::new(1e12, 0.0, 0.0),
    );
    let error = icp_anchored(&target, &source, IcpAnchors::default(), shift, settings).unwrap_err();
    assert!(
        matches!(
            error,
            KernelError::InvalidArgument {
                name: "initial",
                ..
            }
        ),
        "{error:?}"
    );
    let many = IcpSettings {
        max_iterations: 100_001,
        ..settings
    };
    assert!(matches!(
        icp_anchored(
            &target,
            &source,
            IcpAnchors::default(),
            Transform::IDENTITY,
            many
        ),
        Err(KernelError::InvalidArgument {
            name: "max_iterations",
            ..
        })
    ));
}

#[test]
fn feature_thresholds_out_of_range_are_refused() {
    let (vertices, triangles) = common::uv_sphere(1.0, 8, 12);
    let mesh = TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap();
    let settings = FeatureSettings {
        flat_threshold: 1e30,
        ..FeatureSettings::with_scale(0.3)
    };
    assert_eq!(
        detect_features(&mesh, &settings).unwrap_err().to_string(),
        "invalid flat_threshold: the flat threshold must be within [0, 1000], not 1000000000000000000000000000000"
    );
}
