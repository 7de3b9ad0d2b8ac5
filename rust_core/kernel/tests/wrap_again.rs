//! Wrapping a wrap's result again, with the same rest shape, target and anchors, and saying so
//! (`WrapSolver::with_settled_start`), changes it almost nothing: the second wrap re-settles the layout from where
//! it is instead of relaxing it back toward the template first.

mod common;

use std::sync::Arc;

use glam::Vec3;
use springwrap_kernel::{
    Anchor, LayoutPoint, LayoutStructure, TargetMesh, TargetMeshOptions, WrapSettings, WrapSolver,
};

/// Wraps `start` (rest shape `rest`) onto `target` to the end; the points and positions it ends with.
fn wrap(
    target: &Arc<TargetMesh>,
    structure: &LayoutStructure,
    start: Vec<LayoutPoint>,
    rest: &[Vec3],
    anchors: &[Anchor],
    settled: bool,
) -> (Vec<LayoutPoint>, Vec<Vec3>) {
    let mut solver = WrapSolver::with_rest_shape(
        Arc::clone(target),
        structure.clone(),
        start,
        Some(rest.to_vec()),
        anchors,
        WrapSettings::default(),
    )
    .unwrap()
    .with_settled_start(settled);
    let report = solver.step(1_000).expect("the wrap steps");
    assert!(report.converged, "{report:?}");
    (solver.points().to_vec(), solver.positions().to_vec())
}

/// The mean distance between two sets of positions.
fn mean_distance(a: &[Vec3], b: &[Vec3]) -> f32 {
    a.iter().zip(b).map(|(a, b)| a.distance(*b)).sum::<f32>() / a.len() as f32
}

/// The mean move of the second wrap over the mean move of the first (from the template).
fn second_over_first(
    target: &Arc<TargetMesh>,
    structure: &LayoutStructure,
    template: &[Vec3],
    anchors: &[Anchor],
) -> (f32, f32) {
    let start: Vec<LayoutPoint> = template.iter().map(|&p| LayoutPoint::Space(p)).collect();
    let (points, first) = wrap(target, structure, start, template, anchors, false);
    let (_, second) = wrap(target, structure, points.clone(), template, anchors, true);
    let (_, third) = wrap(target, structure, points, template, anchors, true);
    assert_eq!(second, third, "a wrap again is deterministic");
    let first_move = mean_distance(&first, template);
    (mean_distance(&second, &first) / first_move, first_move)
}

#[test]
fn a_wrapped_band_wrapped_again_stays_where_it_is() {
    let (vertices, triangles) = common::lumpy_egg(1.0, 48, 64);
    let target =
        Arc::new(TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap());
    let (structure, template) = common::band_layout(Vec3::new(1.1, 0.9, 0.7), 12, 32);
    let (ratio, first_move) = second_over_first(&target, &structure, &template, &[]);
    println!("no anchors: second wrap moved {ratio} of the first's {first_move}");
    assert!(
        ratio < 0.01,
        "the second wrap moved {ratio} of the first's move"
    );
}
