//! A wrap step cancelled from another thread, and anchors moved between steps.

mod common;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use glam::Vec3;
use springwrap_kernel::{
    Anchor, AnchorTarget, KernelError, LayoutPoint, TargetMesh, WrapSettings, WrapSolver,
};

/// A 10 x 10 quad layout above a plane with its four corners and centre anchored below them.
fn plane_wrap() -> (Arc<TargetMesh>, WrapSolver, Vec<Anchor>) {
    let target = common::plane_target(40, 0.05, 0.0);
    let (structure, positions) = common::quad_layout(10, 0.1, Vec3::new(-0.5, -0.5, 0.3));
    let anchors = common::anchors_below(&target, &positions, &[0, 10, 110, 120, 60]);
    let points = positions.iter().map(|&p| LayoutPoint::Space(p)).collect();
    let solver = WrapSolver::new(
        target.clone(),
        structure,
        points,
        &anchors,
        WrapSettings::default(),
    )
    .unwrap();
    (target, solver, anchors)
}

#[test]
fn a_step_that_is_never_stopped_is_the_plain_step_bit_for_bit() {
    let (_, mut plain, _) = plane_wrap();
    let (_, mut asked, _) = plane_wrap();
    let flag = AtomicBool::new(false);
    for _ in 0..6 {
        let a = plain.step(3).unwrap();
        let b = asked
            .step_until(3, &|| flag.load(Ordering::Relaxed))
            .unwrap();
        assert_eq!(format!("{a:?}"), format!("{b:?}")); // as text: a NaN equals itself
        assert_eq!(plain.positions(), asked.positions());
    }
}

#[test]
fn a_cancelled_step_puts_the_points_back_and_every_later_step_says_so() {
    // From the first ask to a few iterations in (about ten asks an iteration).
    for asks_before_stop in [0, 1, 5, 40] {
        let (target, mut solver, anchors) = plane_wrap();
        solver.step(2).unwrap(); // the plane wrap converges in 8 iterations: 6 left to stop in
        let (points, positions) = (solver.points().to_vec(), solver.positions().to_vec());
        // The stop says true after a number of asks: somewhere inside an iteration.
        let asked = AtomicUsize::new(0);
        let stop = || asked.fetch_add(1, Ordering::Relaxed) >= asks_before_stop;
        let error = solver.step_until(50, &stop).unwrap_err();
        assert!(
            matches!(error, KernelError::Cancelled { what: "wrap step" }),
            "{error:?}"
        );
        assert_eq!(solver.points(), points.as_slice(), "{asks_before_stop}");
        assert_eq!(solver.positions(), positions.as_slice());
        assert_eq!(solver.step(1).unwrap_err(), error);
        assert_eq!(solver.set_anchors(&anchors).unwrap_err(), error);
        let _ = target;
    }
}

#[test]
fn the_first_step_setting_up_the_energy_can_be_cancelled() {
    let (_, mut solver, _) = plane_wrap();
    let start = solver.positions().to_vec();
    let error = solver.step_until(1, &|| true).unwrap_err();
    assert!(matches!(error, KernelError::Cancelled { .. }), "{error:?}");
    assert_eq!(solver.positions(), start.as_slice());
}

/// The anchors moved: the centre anchor 0.2 along x.
fn moved(target: &TargetMesh, anchors: &[Anchor]) -> Vec<Anchor> {
    anchors
        .iter()
        .map(|anchor| {
            if anchor.vertex != 60 {
                return *anchor;
            }
            let AnchorTarget::Face(face_point) = anchor.target else {
                unreachable!()
            };
            let position = target.face_point_position(face_point).unwrap() + Vec3::X * 0.2;
            let hit = target.closest_point(position, 1.0).unwrap();
            Anchor {
                vertex: 60,
                target: AnchorTarget::Face(hit.face_point),
            }
        })
        .collect()
}

fn anchor_position(target: &TargetMesh, anchors: &[Anchor], vertex: u32) -> Vec3 {
    let anchor = anchors
        .iter()
        .find(|anchor| anchor.vertex == vertex)
        .unwrap();
    match anchor.target {
        AnchorTarget::Face(face_point) => target.face_point_position(face_point).unwrap(),
        AnchorTarget::Space(position) => position,
    }
}

#[test]
fn an_anchor_moved_mid_wrap_ends_at_its_new_target_as_in_a_wrap_started_anew() {
    let (target, mut solver, anchors) = plane_wrap();
    solver.step(8).unwrap();
    let new_anchors = moved(&target, &anchors);
    // A wrap built anew from the points as they are now, with the moved anchor.
    let mut fresh = WrapSolver::new(
        target.clone(),
        common::quad_layout(10, 0.1, Vec3::ZERO).0,
        solver.points().to_vec(),
        &new_anchors,
        WrapSettings::default(),
    )
    .unwrap();
    solver.set_anchors(&new_anchors).unwrap();
    let report = solver.step(2000).unwrap();
    assert!(report.converged, "{report:?}");
    let wanted = anchor_position(&target, &new_anchors, 60);
    assert!(solver.positions()[60].distance(wanted) < 1e-5);
    assert!(solver.positions()[60].distance(anchor_position(&target, &anchors, 60)) > 0.19);
    assert!(fresh.step(2000).unwrap().converged);
    let largest = solver
        .positions()
        .iter()
        .zip(fresh.positions())
        .map(|(a, b)| a.distance(*b))
        .fold(0.0f32, f32::max);
    assert!(
        largest < 0.01,
        "{largest} from the wrap started anew (edge 0.1)"
    );
}

#[test]
fn anchors_added_or_removed_mid_wrap_set_the_energy_up_again() {
    let (target, mut solver, anchors) = plane_wrap();
    solver.step(5).unwrap();
    let mut more = anchors.clone();
    let position = solver.positions()[33] - Vec3::Z * 0.5;
    more.push(Anchor {
        vertex: 33,
        target: AnchorTarget::Face(target.closest_point(position, 1.0).unwrap().face_point),
    });
    solver.set_anchors(&more).unwrap();
    assert!(solver.step(2000).unwrap().converged);
    assert!(solver.positions()[33].distance(anchor_position(&target, &more, 33)) < 1e-5);
    solver.set_anchors(&anchors[..2]).unwrap();
    assert!(solver.anchor_targets().iter().flatten().count() == 2);
    assert!(solver.step(2000).unwrap().converged);
}

#[test]
fn a_bad_anchor_changes_nothing() {
    let (_, mut solver, anchors) = plane_wrap();
    solver.step(3).unwrap();
    let before = solver.anchor_targets().to_vec();
    let twice = [anchors[0], anchors[0]];
    assert!(matches!(
        solver.set_anchors(&twice),
        Err(KernelError::InvalidArgument { .. })
    ));
    let beyond = [Anchor {
        vertex: 999,
        target: AnchorTarget::Space(Vec3::ZERO),
    }];
    assert!(solver.set_anchors(&beyond).is_err());
    assert_eq!(solver.anchor_targets(), before.as_slice());
    solver.step(3).unwrap();
}
