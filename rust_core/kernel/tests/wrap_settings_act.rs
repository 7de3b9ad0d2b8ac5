//! Every wrap setting changes the result: a small layout wrapped onto a sphere with its defaults,
//! then with each setting moved away from its default, ends elsewhere.

mod common;

use std::sync::Arc;

use glam::Vec3;
use springwrap_kernel::{
    Anchor, AnchorTarget, LayoutPoint, LayoutStructure, TargetMesh, TargetMeshOptions,
    WrapSchedule, WrapSettings, WrapSolver,
};

/// A 6 x 6 grid of cell 0.2 above the top of a unit sphere, its middle quad split into two
/// triangles (so that some vertices have no grid line through them and the thin plate's umbrella
/// terms act), with its four corners anchored to the sphere 30 % wider apart in x than the grid.
fn case() -> (Arc<TargetMesh>, LayoutStructure, Vec<Vec3>, Vec<Anchor>) {
    let (vertices, triangles) = common::uv_sphere(1.0, 32, 64);
    let target =
        Arc::new(TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap());
    let (n, row) = (6u32, 7u32);
    let positions: Vec<Vec3> = (0..row * row)
        .map(|index| {
            Vec3::new(
                (index % row) as f32 * 0.2 - 0.6,
                (index / row) as f32 * 0.2 - 0.6,
                1.3,
            )
        })
        .collect();
    let (mut corners, mut sizes) = (Vec::new(), Vec::new());
    for y in 0..n {
        for x in 0..n {
            let a = y * row + x;
            if (x, y) == (2, 2) {
                corners.extend([a, a + 1, a + row + 1, a, a + row + 1, a + row]);
                sizes.extend([3, 3]);
            } else {
                corners.extend([a, a + 1, a + row + 1, a + row]);
                sizes.push(4);
            }
        }
    }
    let structure = LayoutStructure::new(positions.len(), &corners, &sizes, &[], &[]).unwrap();
    let anchors = [0, n, n * row, row * row - 1]
        .iter()
        .map(|&vertex| {
            let at = positions[vertex as usize] * Vec3::new(1.3, 1.0, 1.0);
            let hit = target.closest_point(at, f32::INFINITY).unwrap();
            Anchor {
                vertex,
                target: AnchorTarget::Face(hit.face_point),
            }
        })
        .collect();
    (target, structure, positions, anchors)
}

/// The wrapped positions and how many points ended on the surface.
fn wrapped(settings: WrapSettings) -> (Vec<Vec3>, usize) {
    let (target, structure, positions, anchors) = case();
    let points = positions.iter().map(|&p| LayoutPoint::Space(p)).collect();
    let mut solver = WrapSolver::new(target, structure, points, &anchors, settings).unwrap();
    let report = solver.step(1000).unwrap();
    assert!(report.converged, "{settings:?}: {report:?}");
    (solver.positions().to_vec(), report.face_points)
}

#[test]
fn each_setting_moved_from_its_default_changes_the_wrap() {
    let defaults = WrapSettings::default();
    let (reference, reference_face_points) = wrapped(defaults);
    assert_eq!(wrapped(defaults).0, reference, "the wrap is deterministic");
    let mut changed: Vec<(&str, WrapSettings)> = Vec::new();
    let mut add = |name, edit: &dyn Fn(&mut WrapSettings)| {
        let mut settings = defaults;
        edit(&mut settings);
        changed.push((name, settings));
    };
    add("fairness", &|s| s.weights.fairness = 1.0);
    add("arc_length", &|s| s.weights.arc_length = 0.1);
    add("thin_plate", &|s| s.weights.thin_plate = 0.5);
    add("constraint", &|s| s.weights.constraint = 0.05);
    add("folding", &|s| s.weights.folding = 0.05);
    add("tolerance", &|s| s.tolerance = 0.5);
    add("landing_distance", &|s| s.landing_distance = 0.0);
    add("fold_tolerance", &|s| s.fold_tolerance = 0.0);
    // The automatic schedule follows the global-to-local one for these four anchors.
    add("schedule", &|s| s.schedule = WrapSchedule::Local);
    // Every numeric setting of the kernel's table is among them.
    for (field, _, _) in WrapSettings::RANGES {
        assert!(
            changed.iter().any(|(name, _)| *name == field),
            "{field} is not tried"
        );
    }
    for (name, settings) in changed {
        let (positions, face_points) = wrapped(settings);
        let largest = positions
            .iter()
            .zip(&reference)
            .map(|(a, b)| a.distance(*b))
            .fold(0.0f32, f32::max);
        assert!(
            largest > 1e-4 || face_points != reference_face_points,
            "{name}: the wrap ended where the defaults put it (largest move {largest}, \
             {face_points} face-points)"
        );
    }
}
