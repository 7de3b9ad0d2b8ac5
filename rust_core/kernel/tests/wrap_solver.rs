//! The wrap on targets whose answer is known: planes, with and without holes.

mod common;

use glam::Vec3;
use springwrap_kernel::{
    Anchor, AnchorTarget, KernelError, LayoutPoint, LayoutStructure, WrapSettings, WrapSolver,
};

fn edge_length_ratio(structure: &LayoutStructure, positions: &[Vec3]) -> f32 {
    let mut shortest = f32::INFINITY;
    let mut longest = 0.0f32;
    for vertex in 0..structure.vertex_count as u32 {
        for &other in structure.neighbors_of(vertex) {
            let length = positions[vertex as usize].distance(positions[other as usize]);
            shortest = shortest.min(length);
            longest = longest.max(length);
        }
    }
    longest / shortest
}

#[test]
fn a_template_above_a_plane_wraps_onto_it_through_its_anchors() {
    let target = common::plane_target(40, 0.05, 0.0);
    let (structure, positions) = common::quad_layout(10, 0.1, Vec3::new(-0.5, -0.5, 0.3));
    let anchors = common::anchors_below(&target, &positions, &[0, 10, 110, 120, 60]);
    let points = positions.iter().map(|&p| LayoutPoint::Space(p)).collect();
    let mut solver = WrapSolver::new(
        target.clone(),
        structure.clone(),
        points,
        &anchors,
        WrapSettings::default(),
    )
    .unwrap();
    let report = solver.step(2000).expect("the wrap steps");
    assert!(report.converged, "{report:?}");
    assert_eq!(report.space_points, 0, "{report:?}");
    for (vertex, position) in solver.positions().iter().enumerate() {
        assert!(position.z.abs() < 1e-5, "vertex {vertex} at {position}");
    }
    for anchor in &anchors {
        let AnchorTarget::Face(face_point) = anchor.target else {
            unreachable!()
        };
        let expected = target.face_point_position(face_point).unwrap();
        assert!(solver.positions()[anchor.vertex as usize].distance(expected) < 1e-3);
    }
    assert!(edge_length_ratio(&structure, solver.positions()) < 1.3);
    // No flipped quads: every quad still faces +z.
    let p = solver.positions();
    for y in 0..10u32 {
        for x in 0..10u32 {
            let a = (y * 11 + x) as usize;
            let normal = (p[a + 1] - p[a]).cross(p[a + 11] - p[a]);
            assert!(normal.z > 0.0, "quad ({x}, {y}) flipped");
        }
    }
}

#[test]
fn points_over_a_hole_stay_space_points_on_the_continued_surface() {
    let target = common::plane_target(40, 0.05, 0.2);
    let (structure, positions) = common::quad_layout(10, 0.1, Vec3::new(-0.5, -0.5, 0.3));
    let anchors = common::anchors_below(&target, &positions, &[0, 10, 110, 120]);
    let points = positions.iter().map(|&p| LayoutPoint::Space(p)).collect();
    let mut solver =
        WrapSolver::new(target, structure, points, &anchors, WrapSettings::default()).unwrap();
    let report = solver.step(3000).expect("the wrap steps");
    assert!(report.converged, "{report:?}");
    let mut over_hole = 0;
    for (vertex, (point, position)) in solver.points().iter().zip(solver.positions()).enumerate() {
        assert!(position.z.abs() < 2e-3, "vertex {vertex} at {position}");
        if position.truncate().length() < 0.15 {
            over_hole += 1;
            assert!(
                matches!(point, LayoutPoint::Space(_)),
                "vertex {vertex} over the hole is {point:?}"
            );
        } else if position.truncate().length() > 0.3 {
            assert!(
                matches!(point, LayoutPoint::Face(_)),
                "vertex {vertex} on the plane is {point:?}"
            );
        }
    }
    assert!(over_hole >= 5);
}

#[test]
fn stepping_reports_progress_and_resumes() {
    let target = common::plane_target(20, 0.1, 0.0);
    let (structure, positions) = common::quad_layout(6, 0.2, Vec3::new(-0.6, -0.6, 0.2));
    let anchors = common::anchors_below(&target, &positions, &[0, 6, 42, 48]);
    let points: Vec<LayoutPoint> = positions.iter().map(|&p| LayoutPoint::Space(p)).collect();
    let settings = WrapSettings::default();
    let mut solver = WrapSolver::new(target, structure, points, &anchors, settings).unwrap();
    let start = solver.positions().to_vec();
    let first = solver.step(5).expect("the wrap steps");
    assert_eq!((first.iterations, first.total_iterations), (5, 5));
    assert!(!first.converged && solver.positions() != start.as_slice());
    // The whole wrap takes 8 iterations: the second call stops short of them.
    let second = solver.step(2).expect("the wrap steps");
    assert!(
        !second.converged && second.total_iterations == 7,
        "{second:?}"
    );
    let last = solver.step(1000).expect("the wrap steps");
    assert!(last.converged, "{last:?}");
    assert_eq!(last.total_iterations, 7 + last.iterations);
    assert!(last.landed == 4 && last.face_points == 49, "{last:?}");
}

#[test]
fn bad_wraps_are_refused_with_the_reason() {
    let target = common::plane_target(4, 1.0, 0.0);
    let (structure, positions) = common::quad_layout(2, 1.0, Vec3::ZERO);
    let points: Vec<LayoutPoint> = positions.iter().map(|&p| LayoutPoint::Space(p)).collect();
    let settings = WrapSettings::default();
    let error = WrapSolver::new(
        target.clone(),
        structure.clone(),
        points[..4].to_vec(),
        &[],
        settings,
    )
    .unwrap_err();
    assert!(matches!(error, KernelError::LengthMismatch { .. }));
    let mut collapsed = points.clone();
    collapsed[1] = collapsed[0];
    let error =
        WrapSolver::new(target.clone(), structure.clone(), collapsed, &[], settings).unwrap_err();
    assert!(error.to_string().contains("zero length"), "{error}");
    let mut not_finite = points.clone();
    not_finite[3] = LayoutPoint::Space(Vec3::NAN);
    let error =
        WrapSolver::new(target.clone(), structure.clone(), not_finite, &[], settings).unwrap_err();
    assert_eq!(
        error,
        KernelError::NonFinite {
            what: "layout point",
            index: 3
        }
    );
    let anchor = |vertex| Anchor {
        vertex,
        target: AnchorTarget::Space(Vec3::ZERO),
    };
    let error = WrapSolver::new(
        target.clone(),
        structure.clone(),
        points.clone(),
        &[anchor(99)],
        settings,
    )
    .unwrap_err();
    assert!(error.to_string().contains("vertex 99"), "{error}");
    let error = WrapSolver::new(
        target.clone(),
        structure.clone(),
        points.clone(),
        &[anchor(1), anchor(1)],
        settings,
    )
    .unwrap_err();
    assert!(
        error.to_string().contains("more than one anchor"),
        "{error}"
    );
    let mut bad = settings;
    bad.weights.fairness = f32::NAN;
    let error =
        WrapSolver::new(target.clone(), structure.clone(), points.clone(), &[], bad).unwrap_err();
    assert!(error.to_string().contains("fairness"), "{error}");
    let lonely = LayoutStructure::new(2, &[], &[], &[], &[]).unwrap();
    let error = WrapSolver::new(target, lonely, points[..2].to_vec(), &[], settings).unwrap_err();
    assert!(error.to_string().contains("no edges"), "{error}");
}

#[test]
fn points_over_unreliable_data_behave_as_over_a_hole() {
    let target = common::plane_target(40, 0.05, 0.0);
    // The middle of the plane is "noisy": its triangles are flagged and must not hold points.
    let unreliable: Vec<bool> = target
        .triangles()
        .iter()
        .map(|corners| {
            let centre = corners
                .iter()
                .map(|&i| target.vertices()[i as usize])
                .sum::<Vec3>()
                / 3.0;
            centre.truncate().length() < 0.2
        })
        .collect();
    let (structure, positions) = common::quad_layout(10, 0.1, Vec3::new(-0.5, -0.5, 0.3));
    let anchors = common::anchors_below(&target, &positions, &[0, 10, 110, 120]);
    let points = positions.iter().map(|&p| LayoutPoint::Space(p)).collect();
    let mut solver = WrapSolver::new(target, structure, points, &anchors, WrapSettings::default())
        .unwrap()
        .with_unreliable_triangles(unreliable)
        .unwrap();
    let report = solver.step(3000).expect("the wrap steps");
    assert!(report.converged, "{report:?}");
    let mut over_noise = 0;
    for (vertex, (point, position)) in solver.points().iter().zip(solver.positions()).enumerate() {
        assert!(position.z.abs() < 2e-3, "vertex {vertex} at {position}");
        if position.truncate().length() < 0.15 {
            over_noise += 1;
            assert!(
                matches!(point, LayoutPoint::Space(_)),
                "vertex {vertex} on noise is {point:?}"
            );
        }
    }
    assert!(over_noise >= 5);
}

/// Distance from `point` to the polyline.
fn distance_to_polyline(point: Vec3, polyline: &[Vec3]) -> f32 {
    polyline
        .windows(2)
        .map(|pair| {
            let direction = pair[1] - pair[0];
            let t = ((point - pair[0]).dot(direction) / direction.length_squared()).clamp(0.0, 1.0);
            point.distance(pair[0] + direction * t)
        })
        .fold(f32::INFINITY, f32::min)
}

#[test]
fn a_border_held_to_a_curve_on_the_surface_lies_on_it_evenly() {
    use springwrap_kernel::CurveConstraint;
    let target = common::plane_target(40, 0.05, 0.0);
    let (structure, positions) = common::quad_layout(10, 0.1, Vec3::new(-0.5, -0.5, 0.3));
    let anchors = common::anchors_below(&target, &positions, &[0, 10, 110, 120]);
    // The bottom border (vertices 0..=10) is held to a wave drawn on the plane, end to end.
    let wave: Vec<Vec3> = (0..=200)
        .map(|step| {
            let x = -0.5 + step as f32 / 200.0;
            Vec3::new(
                x,
                -0.5 + 0.05 * (x * std::f32::consts::TAU * 2.0).sin(),
                0.0,
            )
        })
        .collect();
    let constraint = CurveConstraint {
        layout_vertices: (0..=10).collect(),
        target: wave.clone(),
        fractions: Vec::new(),
    };
    let points = positions.iter().map(|&p| LayoutPoint::Space(p)).collect();
    let mut solver = WrapSolver::new(target, structure, points, &anchors, WrapSettings::default())
        .unwrap()
        .with_curve_constraints(&[constraint])
        .unwrap();
    let report = solver.step(3000).expect("the wrap steps");
    assert!(report.converged, "{report:?}");
    let border: Vec<Vec3> = (0..=10).map(|vertex| solver.positions()[vertex]).collect();
    for (vertex, &position) in border.iter().enumerate() {
        assert!(
            distance_to_polyline(position, &wave) < 1e-3,
            "vertex {vertex} at {position}"
        );
        assert!(
            matches!(solver.points()[vertex], LayoutPoint::Face(_)),
            "vertex {vertex}"
        );
    }
    // Even spacing along the curve (arc-length matching): chord lengths within 20% of each other.
    let chords: Vec<f32> = border
        .windows(2)
        .map(|pair| pair[0].distance(pair[1]))
        .collect();
    let (shortest, longest) = chords
        .iter()
        .fold((f32::INFINITY, 0.0f32), |(a, b), &c| (a.min(c), b.max(c)));
    assert!(longest / shortest < 1.2, "chords {chords:?}");
}

#[test]
fn a_curve_floating_above_the_surface_holds_its_points_in_space() {
    use springwrap_kernel::CurveConstraint;
    let target = common::plane_target(40, 0.05, 0.0);
    let (structure, positions) = common::quad_layout(10, 0.1, Vec3::new(-0.5, -0.5, 0.3));
    let anchors = common::anchors_below(&target, &positions, &[0, 10, 110, 120]);
    // The middle row (vertices 55..=65) is held to a straight line 0.1 above the plane.
    let line = vec![Vec3::new(-0.5, 0.0, 0.1), Vec3::new(0.5, 0.0, 0.1)];
    let middle: Vec<u32> = (55..=65).collect();
    let constraint = CurveConstraint {
        layout_vertices: middle.clone(),
        target: line.clone(),
        fractions: Vec::new(),
    };
    let points = positions.iter().map(|&p| LayoutPoint::Space(p)).collect();
    let mut solver = WrapSolver::new(target, structure, points, &anchors, WrapSettings::default())
        .unwrap()
        .with_curve_constraints(&[constraint])
        .unwrap();
    let report = solver.step(3000).expect("the wrap steps");
    assert!(report.converged, "{report:?}");
    for &vertex in &middle[1..middle.len() - 1] {
        let position = solver.positions()[vertex as usize];
        assert!(
            distance_to_polyline(position, &line) < 2e-3,
            "vertex {vertex} at {position}"
        );
        assert!(matches!(
            solver.points()[vertex as usize],
            LayoutPoint::Space(_)
        ));
    }
}

#[test]
fn bad_curve_constraints_are_refused() {
    use springwrap_kernel::CurveConstraint;
    let target = common::plane_target(4, 1.0, 0.0);
    let (structure, positions) = common::quad_layout(2, 1.0, Vec3::ZERO);
    let points: Vec<LayoutPoint> = positions.iter().map(|&p| LayoutPoint::Space(p)).collect();
    let solver = WrapSolver::new(target, structure, points, &[], WrapSettings::default()).unwrap();
    let line = vec![Vec3::ZERO, Vec3::X];
    let cases = [
        (
            vec![CurveConstraint {
                layout_vertices: vec![0],
                target: line.clone(),
                fractions: Vec::new(),
            }],
            "at least 2 vertices",
        ),
        (
            vec![CurveConstraint {
                layout_vertices: vec![0, 42],
                target: line.clone(),
                fractions: Vec::new(),
            }],
            "vertex 42",
        ),
        (
            vec![CurveConstraint {
                layout_vertices: vec![0, 1],
                target: vec![Vec3::ZERO],
                fractions: Vec::new(),
            }],
            "at least 2 points",
        ),
        (
            vec![CurveConstraint {
                layout_vertices: vec![0, 1],
                target: vec![Vec3::X, Vec3::X],
                fractions: Vec::new(),
            }],
            "zero length",
        ),
        (
            vec![
                CurveConstraint {
                    layout_vertices: vec![0, 1],
                    target: line.clone(),
                    fractions: Vec::new(),
                },
                CurveConstraint {
                    layout_vertices: vec![1, 2],
                    target: line.clone(),
                    fractions: Vec::new(),
                },
            ],
            "also in curve constraint 0",
        ),
    ];
    for (constraints, words) in cases {
        let error = solver
            .clone()
            .with_curve_constraints(&constraints)
            .unwrap_err();
        assert!(
            error.to_string().contains(words),
            "{error} should say {words}"
        );
    }
}

#[test]
fn a_point_balanced_at_a_hole_rim_does_not_keep_the_wrap_from_converging() {
    // A coarse layout whose anchors pull a vertex to the rim of a round hole.
    let target = common::plane_target(20, 0.15, 0.3);
    let (structure, positions) = common::quad_layout(4, 0.5, Vec3::new(-1.0, -1.0, 0.3));
    let anchored: Vec<u32> = [0u32, 2, 4]
        .iter()
        .flat_map(|&i| [0u32, 2, 4].map(|j| i * 5 + j))
        .collect();
    let anchors = common::anchors_at(&target, &positions, &anchored);
    let points = positions.iter().map(|&p| LayoutPoint::Space(p)).collect();
    let mut solver =
        WrapSolver::new(target, structure, points, &anchors, WrapSettings::default()).unwrap();
    let report = solver.step(2000).expect("the wrap steps");
    assert!(report.converged, "{report:?}");
}
