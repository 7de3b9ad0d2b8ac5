//! The rest shape: a template keeps its own spacing and curvature; the rest shape may be given in
//! any placement; a region of the layout that faces away from the target does not fold onto it.

mod common;

use std::sync::Arc;

use glam::{Quat, Vec3};
use springwrap_kernel::{
    Anchor, AnchorTarget, LayoutPoint, LayoutStructure, TargetMesh, TargetMeshOptions,
    WrapSettings, WrapSolver,
};

/// A grid layout with the given x and y coordinates of its columns and rows, at height `z`.
fn grid_layout(xs: &[f32], ys: &[f32], z: f32) -> (LayoutStructure, Vec<Vec3>) {
    let row = xs.len() as u32;
    let positions = ys
        .iter()
        .flat_map(|&y| xs.iter().map(move |&x| Vec3::new(x, y, z)))
        .collect();
    let mut corners = Vec::new();
    for y in 0..ys.len() as u32 - 1 {
        for x in 0..row - 1 {
            let a = y * row + x;
            corners.extend([a, a + 1, a + row + 1, a + row]);
        }
    }
    let faces = corners.len() / 4;
    let structure =
        LayoutStructure::new(xs.len() * ys.len(), &corners, &vec![4; faces], &[], &[]).unwrap();
    (structure, positions)
}

/// A flat target (z = 0), `cells` x `cells` cells of `scale`, centred on the origin.
fn plane_target(cells: u32, scale: f32) -> Arc<TargetMesh> {
    let (vertices, triangles) = common::grid(cells);
    let half = cells as f32 * 0.5;
    let vertices = vertices
        .iter()
        .map(|v| (*v - Vec3::new(half, half, 0.0)) * scale)
        .collect();
    Arc::new(TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap())
}

fn face_anchors(target: &TargetMesh, vertices: &[u32], positions: &[Vec3]) -> Vec<Anchor> {
    vertices
        .iter()
        .map(|&vertex| {
            let below = positions[vertex as usize] * Vec3::new(1.0, 1.0, 0.0);
            Anchor {
                vertex,
                target: AnchorTarget::Face(target.closest_point(below, 1.0).unwrap().face_point),
            }
        })
        .collect()
}

/// Columns dense in the middle (the way a layout is dense around an eye): spacing 0.02 there,
/// 0.08 outside.
fn uneven_columns() -> Vec<f32> {
    let mut xs = vec![-0.5, -0.42, -0.34, -0.26, -0.18, -0.1];
    for step in 1..=9 {
        xs.push(-0.1 + 0.02 * step as f32);
    }
    xs.extend([0.18, 0.26, 0.34, 0.42, 0.5]);
    xs
}

fn wrapped(anchors_at: &[u32]) -> (Vec<f32>, Vec<Vec3>) {
    let target = plane_target(40, 0.05);
    let xs = uneven_columns();
    let ys: Vec<f32> = (0..5).map(|i| -0.2 + 0.1 * i as f32).collect();
    let (structure, positions) = grid_layout(&xs, &ys, 0.2);
    let anchors = face_anchors(&target, anchors_at, &positions);
    let points = positions.iter().map(|&p| LayoutPoint::Space(p)).collect();
    let mut solver =
        WrapSolver::new(target, structure, points, &anchors, WrapSettings::default()).unwrap();
    let report = solver.step(20_000).expect("the wrap steps");
    assert!(report.converged, "{report:?}");
    assert_eq!(report.space_points, 0, "{report:?}");
    (xs, solver.positions().to_vec())
}

#[test]
fn a_template_keeps_its_own_spacing() {
    // Anchors at the four corners only: the spacing inside is the energy's choice.
    let columns = uneven_columns().len() as u32;
    let corners = [0, columns - 1, 4 * columns, 5 * columns - 1];
    let (xs, template) = wrapped(&corners);
    // The middle row, column by column: the template's spacing, within 2 % of the span.
    let middle = 2 * xs.len();
    for (column, &x) in xs.iter().enumerate() {
        let got = template[middle + column].x;
        assert!(
            (got - x).abs() < 0.02,
            "template rest: column {column} at x = {got}, the template has {x}"
        );
    }
}

#[test]
fn the_rest_shape_counts_in_any_placement() {
    let target = plane_target(40, 0.05);
    let xs = uneven_columns();
    let ys: Vec<f32> = (0..5).map(|i| -0.2 + 0.1 * i as f32).collect();
    let (structure, positions) = grid_layout(&xs, &ys, 0.2);
    let columns = xs.len() as u32;
    let anchors = face_anchors(
        &target,
        &[0, columns - 1, 4 * columns, 5 * columns - 1],
        &positions,
    );
    // The template as made (placed elsewhere, turned, 3 x larger), and the layout squeezed
    // evenly where the wrap starts (as if it had been snapped and distorted).
    let turn = Quat::from_axis_angle(Vec3::new(1.0, 2.0, 3.0).normalize(), 1.1);
    let rest: Vec<Vec3> = positions
        .iter()
        .map(|&p| turn * p * 3.0 + Vec3::new(5.0, -2.0, 1.0))
        .collect();
    let start: Vec<LayoutPoint> = grid_layout(
        &(0..columns)
            .map(|i| -0.5 + i as f32 / (columns - 1) as f32)
            .collect::<Vec<_>>(),
        &ys,
        0.2,
    )
    .1
    .into_iter()
    .map(LayoutPoint::Space)
    .collect();
    let mut solver = WrapSolver::with_rest_shape(
        target,
        structure,
        start,
        Some(rest),
        &anchors,
        WrapSettings::default(),
    )
    .unwrap();
    let report = solver.step(20_000).expect("the spring solver steps");
    assert!(report.converged, "{report:?}");
    let middle = 2 * xs.len();
    for (column, &x) in xs.iter().enumerate() {
        let got = solver.positions()[middle + column].x;
        assert!(
            (got - x).abs() < 0.02,
            "column {column} at x = {got}, the template has {x}"
        );
    }
}

#[test]
fn a_rest_shape_of_the_wrong_size_or_with_a_nan_is_refused() {
    let target = plane_target(10, 0.2);
    let (structure, positions) = grid_layout(&[0.0, 0.1, 0.2], &[0.0, 0.1], 0.1);
    let points: Vec<LayoutPoint> = positions.iter().map(|&p| LayoutPoint::Space(p)).collect();
    let error = WrapSolver::with_rest_shape(
        target.clone(),
        structure.clone(),
        points.clone(),
        Some(positions[..3].to_vec()),
        &[],
        WrapSettings::default(),
    )
    .unwrap_err();
    assert!(error.to_string().contains("rest positions"), "{error}");
    let mut bad = positions.clone();
    bad[4].y = f32::NAN;
    let error = WrapSolver::with_rest_shape(
        target.clone(),
        structure.clone(),
        points.clone(),
        Some(bad),
        &[],
        WrapSettings::default(),
    )
    .unwrap_err();
    assert!(error.to_string().contains("rest position 4"), "{error}");
    // A snapped layout may have points at one place: only the rest shape's edges must not be zero.
    let mut collapsed = points.clone();
    collapsed[1] = collapsed[0];
    assert!(
        WrapSolver::with_rest_shape(
            target.clone(),
            structure.clone(),
            collapsed.clone(),
            Some(positions.clone()),
            &[],
            WrapSettings::default(),
        )
        .is_ok()
    );
    let error =
        WrapSolver::new(target, structure, collapsed, &[], WrapSettings::default()).unwrap_err();
    assert!(error.to_string().contains("zero length"), "{error}");
}

#[test]
fn a_flap_turned_away_from_the_target_does_not_fold_onto_it() {
    // A strip: its first 6 columns lie 0.05 above the plane facing up, then it turns down and
    // back under itself (a pocket, like a mouth bag): the last 4 columns face down.
    let target = plane_target(40, 0.05);
    let mut positions = Vec::new();
    let flat = [-0.5f32, -0.4, -0.3, -0.2, -0.1, 0.0];
    let back = [
        (0.05f32, -0.05f32),
        (0.0, -0.1),
        (-0.1, -0.12),
        (-0.2, -0.12),
    ];
    for &y in &[-0.1f32, 0.0, 0.1] {
        for &x in &flat {
            positions.push(Vec3::new(x, y, 0.05));
        }
        for &(x, z) in &back {
            positions.push(Vec3::new(x, y, z + 0.05));
        }
    }
    let row = 10u32;
    let mut corners = Vec::new();
    for y in 0..2u32 {
        for x in 0..row - 1 {
            let a = y * row + x;
            corners.extend([a, a + 1, a + row + 1, a + row]);
        }
    }
    let structure = LayoutStructure::new(30, &corners, &[4; 18], &[], &[]).unwrap();
    let anchors = face_anchors(&target, &[0, 5, 20, 25], &positions);
    let points = positions.iter().map(|&p| LayoutPoint::Space(p)).collect();
    let mut solver =
        WrapSolver::new(target, structure, points, &anchors, WrapSettings::default()).unwrap();
    let report = solver.step(5000).expect("the spring solver steps");
    assert!(report.face_points >= 15, "{report:?}");
    for y in 0..3usize {
        for x in 7..10usize {
            let vertex = y * 10 + x;
            assert!(
                matches!(solver.points()[vertex], LayoutPoint::Space(_)),
                "vertex {vertex} of the turned-back flap folded onto the plane"
            );
        }
    }
}
