//! The wrap's energy solver on targets whose answer is known, and its promise
//! that no layout face turns over.

mod common;

use std::sync::Arc;

use glam::Vec3;
use springwrap_kernel::{
    Anchor, AnchorTarget, KernelError, LayoutPoint, LayoutStructure, PlaneConstraint, StepReport,
    TargetMesh, TargetMeshOptions, WrapSettings, WrapSolver,
};

fn energy_settings() -> WrapSettings {
    WrapSettings::default()
}

fn wrap(
    target: &Arc<TargetMesh>,
    structure: &LayoutStructure,
    positions: &[Vec3],
    anchors: &[Anchor],
) -> (WrapSolver, StepReport) {
    let points = positions.iter().map(|&p| LayoutPoint::Space(p)).collect();
    let mut solver = WrapSolver::new(
        Arc::clone(target),
        structure.clone(),
        points,
        anchors,
        energy_settings(),
    )
    .unwrap();
    let report = solver.step(1000).unwrap();
    (solver, report)
}

/// Quad normals (from the diagonals) of a layout of `n` x `n` quads as made by
/// [`common::quad_layout`].
fn grid_quad_normals(n: u32, positions: &[Vec3]) -> Vec<Vec3> {
    let row = n + 1;
    let mut normals = Vec::new();
    for y in 0..n {
        for x in 0..n {
            let a = (y * row + x) as usize;
            let (b, c, d) = (a + 1, a + row as usize + 1, a + row as usize);
            normals.push((positions[c] - positions[a]).cross(positions[d] - positions[b]));
        }
    }
    normals
}

fn assert_anchors_met(solver: &WrapSolver, target: &TargetMesh, anchors: &[Anchor]) {
    for anchor in anchors {
        let AnchorTarget::Face(face_point) = anchor.target else {
            continue;
        };
        let wanted = target.face_point_position(face_point).unwrap();
        let position = solver.positions()[anchor.vertex as usize];
        assert_eq!(position, wanted, "anchor on vertex {}", anchor.vertex);
        assert_eq!(
            solver.points()[anchor.vertex as usize],
            LayoutPoint::Face(face_point)
        );
    }
}

#[test]
fn a_template_above_a_plane_lands_on_it_in_a_few_iterations() {
    let target = common::plane_target(40, 0.05, 0.0);
    let (structure, positions) = common::quad_layout(10, 0.1, Vec3::new(-0.5, -0.5, 0.3));
    let anchors = common::anchors_below(&target, &positions, &[0, 10, 110, 120, 60]);
    let (solver, report) = wrap(&target, &structure, &positions, &anchors);
    assert!(report.converged, "{report:?}");
    assert!(report.total_iterations <= 40, "{report:?}");
    assert_eq!(report.space_points, 0, "{report:?}");
    for (vertex, position) in solver.positions().iter().enumerate() {
        assert!(position.z.abs() < 1e-5, "vertex {vertex} at {position}");
    }
    assert_anchors_met(&solver, &target, &anchors);
    // The template's shape is kept: a flat grid stays an even grid.
    for normal in grid_quad_normals(10, solver.positions()) {
        assert!((normal.length() * 0.5 - 0.01).abs() < 1e-4, "{normal}");
    }
}

#[test]
fn points_over_a_hole_float_on_the_continued_surface() {
    let target = common::plane_target(40, 0.05, 0.25);
    let (structure, positions) = common::quad_layout(10, 0.1, Vec3::new(-0.5, -0.5, 0.2));
    let anchors = common::anchors_below(&target, &positions, &[0, 10, 110, 120]);
    let (solver, report) = wrap(&target, &structure, &positions, &anchors);
    assert!(report.converged, "{report:?}");
    for (vertex, (point, position)) in solver.points().iter().zip(solver.positions()).enumerate() {
        let over_hole = position.truncate().length() < 0.2;
        let far_from_hole = position.truncate().length() > 0.35;
        match point {
            LayoutPoint::Space(_) => {
                assert!(!far_from_hole, "vertex {vertex} at {position} did not land");
                assert!(
                    position.z.abs() < 0.01,
                    "vertex {vertex} at {position} sags"
                );
            }
            LayoutPoint::Face(_) => {
                assert!(
                    !over_hole,
                    "vertex {vertex} at {position} landed in the hole"
                );
                assert!(position.z.abs() < 1e-5, "vertex {vertex} at {position}");
            }
        }
    }
    assert!(report.space_points > 0, "{report:?}");
}

fn band_quad_normals(structure_rings: u32, segments: u32, positions: &[Vec3]) -> Vec<(Vec3, Vec3)> {
    let mut normals = Vec::new();
    for ring in 0..structure_rings {
        for segment in 0..segments {
            let a = (ring * segments + segment) as usize;
            let b = (ring * segments + (segment + 1) % segments) as usize;
            let (c, d) = (b + segments as usize, a + segments as usize);
            let centre = (positions[a] + positions[b] + positions[c] + positions[d]) * 0.25;
            normals.push((
                (positions[c] - positions[a]).cross(positions[b] - positions[d]),
                centre,
            ));
        }
    }
    normals
}

#[test]
fn a_band_wraps_onto_a_sphere_on_the_surface_with_every_face_outwards() {
    let (vertices, triangles) = common::uv_sphere(1.0, 48, 96);
    let target =
        Arc::new(TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap());
    let (structure, positions) = common::band_layout(Vec3::new(1.3, 1.1, 0.9), 12, 32);
    for (normal, centre) in band_quad_normals(12, 32, &positions) {
        assert!(normal.dot(centre) > 0.0, "the test's band faces outwards");
    }
    let anchors: Vec<Anchor> = [0u32, 8, 16, 24, 12 * 32, 12 * 32 + 16]
        .iter()
        .map(|&vertex| {
            let hit = target
                .closest_point(positions[vertex as usize].normalize(), f32::INFINITY)
                .unwrap();
            Anchor {
                vertex,
                target: AnchorTarget::Face(hit.face_point),
            }
        })
        .collect();
    let (solver, report) = wrap(&target, &structure, &positions, &anchors);
    assert!(report.converged, "{report:?}");
    assert_eq!(report.space_points, 0, "{report:?}");
    for (vertex, position) in solver.positions().iter().enumerate() {
        let hit = target.closest_point(*position, f32::INFINITY).unwrap();
        assert!(
            hit.distance < 1e-5,
            "vertex {vertex} is {} off",
            hit.distance
        );
    }
    for (normal, centre) in band_quad_normals(12, 32, solver.positions()) {
        assert!(normal.dot(centre) > 0.0, "a quad at {centre} turned over");
    }
    assert_anchors_met(&solver, &target, &anchors);
}

/// A bumpy height field `z = h(x, y)` over [-1, 1]², `cells` x `cells`.
fn bumpy_target(rng: &mut common::Rng, cells: u32) -> Arc<TargetMesh> {
    let (vertices, triangles) = common::grid(cells);
    let (a, b, c) = (
        rng.range(0.05, 0.2),
        rng.range(1.0, 4.0),
        rng.range(1.0, 4.0),
    );
    let phase = rng.range(0.0, 6.0);
    let vertices = vertices
        .into_iter()
        .map(|v| {
            let (x, y) = (
                v.x / cells as f32 * 2.0 - 1.0,
                v.y / cells as f32 * 2.0 - 1.0,
            );
            Vec3::new(x, y, a * (b * x + phase).sin() * (c * y).cos())
        })
        .collect();
    Arc::new(TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap())
}

#[test]
fn random_targets_and_anchor_moves_never_turn_a_face_over() {
    let mut rng = common::Rng::new(20_261_201);
    for case in 0..10 {
        let target = bumpy_target(&mut rng, 60);
        let n = 12;
        let (structure, mut positions) = common::quad_layout(n, 0.12, Vec3::new(-0.72, -0.72, 0.3));
        for position in &mut positions {
            *position += rng.point_in_box(0.02);
        }
        let before = grid_quad_normals(n, &positions);
        assert!(before.iter().all(|normal| normal.z > 0.0));
        // Anchors on every fourth vertex of every fourth row, pulled up to a cell and a half
        // from under their vertex: the layout must stretch and shear to meet them.
        let spaced: Vec<u32> = (0..=n / 4)
            .flat_map(|y| (0..=n / 4).map(move |x| y * 4 * (n + 1) + x * 4))
            .collect();
        let anchors: Vec<Anchor> = spaced
            .into_iter()
            .filter(|_| rng.unit() < 0.6)
            .collect::<Vec<_>>()
            .into_iter()
            .map(|vertex| {
                let moved = positions[vertex as usize] + rng.point_in_box(0.18);
                let below = Vec3::new(moved.x, moved.y, 0.0);
                let hit = target.closest_point(below, f32::INFINITY).unwrap();
                Anchor {
                    vertex,
                    target: AnchorTarget::Face(hit.face_point),
                }
            })
            .collect();
        let (solver, report) = wrap(&target, &structure, &positions, &anchors);
        assert!(report.converged, "case {case}: {report:?}");
        for (quad, normal) in grid_quad_normals(n, solver.positions()).iter().enumerate() {
            assert!(
                normal.z > 0.0,
                "case {case}: quad {quad} turned over: {normal}"
            );
        }
        for (vertex, (point, position)) in
            solver.points().iter().zip(solver.positions()).enumerate()
        {
            if let LayoutPoint::Face(face_point) = point {
                let on = target.face_point_position(*face_point).unwrap();
                assert_eq!(
                    on, *position,
                    "case {case}: face-point {vertex} off its face"
                );
            }
        }
        assert_anchors_met(&solver, &target, &anchors);
    }
}

#[test]
fn held_points_end_exactly_on_the_plane_and_on_the_surface() {
    // A wavy target crossed by the plane x = 0.05; the layout's column at x = 0.05 is held on it.
    let (vertices, triangles) = common::grid(40);
    let vertices = vertices
        .iter()
        .map(|v| {
            let p = (*v - Vec3::new(20.0, 20.0, 0.0)) * 0.05;
            Vec3::new(p.x, p.y, 0.1 * (3.0 * p.y).sin() + 0.05 * (2.0 * p.x).cos())
        })
        .collect();
    let target =
        Arc::new(TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap());
    let (structure, positions) = common::quad_layout(10, 0.1, Vec3::new(-0.45, -0.5, 0.3));
    let held: Vec<u32> = (0..121).filter(|vertex| vertex % 11 == 5).collect();
    assert!(
        held.iter()
            .all(|&vertex| (positions[vertex as usize].x - 0.05).abs() < 1e-6)
    );
    let anchors = common::anchors_below(&target, &positions, &[0, 10, 110, 120]);
    for slide in [true, false] {
        let points = positions.iter().map(|&p| LayoutPoint::Space(p)).collect();
        let mut solver = WrapSolver::new(
            Arc::clone(&target),
            structure.clone(),
            points,
            &anchors,
            energy_settings(),
        )
        .unwrap()
        .with_plane_constraint(&PlaneConstraint {
            point: Vec3::new(0.05, 0.0, 0.0),
            normal: Vec3::X,
            vertices: held.clone(),
            slide,
        })
        .unwrap();
        let report = solver.step(1000).unwrap();
        assert!(report.converged, "{report:?}");
        for &vertex in &held {
            let position = solver.positions()[vertex as usize];
            assert!(
                (position.x - 0.05).abs() < 1e-6,
                "held vertex {vertex} at {position} (slide {slide})"
            );
            {
                let hit = target.closest_point(position, f32::INFINITY).unwrap();
                assert!(
                    hit.distance < 1e-4,
                    "held vertex {vertex} {} off the surface",
                    hit.distance
                );
            }
        }
        let normals = grid_quad_normals(10, solver.positions());
        assert!(
            normals.iter().all(|normal| normal.z > 0.0),
            "a quad turned over (slide {slide})"
        );
    }
}

/// A plane ([-1, 1]², 40 x 40 cells) with a round bump of height 0.15 and radius about 0.3 at
/// the origin.
fn bump_target() -> Arc<TargetMesh> {
    let (vertices, triangles) = common::grid(40);
    let vertices = vertices
        .iter()
        .map(|v| {
            let p = (*v - Vec3::new(20.0, 20.0, 0.0)) * 0.05;
            let r2 = p.truncate().length_squared();
            Vec3::new(p.x, p.y, 0.15 * (-r2 / (2.0 * 0.12 * 0.12)).exp())
        })
        .collect();
    Arc::new(TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap())
}

/// Wraps the 10 x 10 layout (cell 0.1, 0.3 above the plane, anchored at its corners) onto the
/// bump target, with the vertices within 0.2 of the axis set up by `region`.
fn wrap_over_bump(
    region: impl Fn(WrapSolver, Vec<bool>) -> WrapSolver,
) -> (WrapSolver, StepReport, Vec<bool>) {
    let target = bump_target();
    let (structure, positions) = common::quad_layout(10, 0.1, Vec3::new(-0.5, -0.5, 0.3));
    let anchors = common::anchors_below(&target, &positions, &[0, 10, 110, 120]);
    let inside: Vec<bool> = positions
        .iter()
        .map(|p| p.truncate().length() < 0.2)
        .collect();
    let points = positions.iter().map(|&p| LayoutPoint::Space(p)).collect();
    let solver = WrapSolver::new(target, structure, points, &anchors, energy_settings()).unwrap();
    let mut solver = region(solver, inside.clone());
    let report = solver.step(1000).unwrap();
    (solver, report, inside)
}

/// The largest relative change of a layout edge's length from the template's 0.1, over the
/// edges between two vertices of `region`.
fn worst_stretch(positions: &[Vec3], region: &[bool]) -> f32 {
    let row = 11;
    let mut worst = 0.0f32;
    for a in 0..positions.len() {
        for b in [a + 1, a + row] {
            let same_row = b != a + 1 || (a % row) + 1 < row;
            if b < positions.len() && same_row && region[a] && region[b] {
                let length = positions[a].distance(positions[b]);
                worst = worst.max((length / 0.1 - 1.0).abs());
            }
        }
    }
    worst
}

#[test]
fn free_vertices_float_over_the_target_and_change_nothing_far_away() {
    let (plain, plain_report, inside) = wrap_over_bump(|solver, _| solver);
    assert!(plain_report.converged, "{plain_report:?}");
    let (free, report, _) =
        wrap_over_bump(|solver, inside| solver.with_free_vertices(inside).unwrap());
    assert!(report.converged, "{report:?}");
    let mut floated = 0;
    for (vertex, &is_inside) in inside.iter().enumerate() {
        let (position, plain_position) = (free.positions()[vertex], plain.positions()[vertex]);
        if is_inside {
            // Not pulled, not landed: the template's flat shape, spanned by its neighbours.
            assert!(
                matches!(free.points()[vertex], LayoutPoint::Space(_)),
                "free vertex {vertex} landed"
            );
            assert!(
                matches!(plain.points()[vertex], LayoutPoint::Face(_)),
                "vertex {vertex} did not land without the group"
            );
            if plain_position.z - position.z > 0.02 {
                floated += 1;
            }
        } else if position.truncate().length() > 0.45 {
            assert!(
                position.distance(plain_position) < 5e-3,
                "vertex {vertex} far from the free region moved from {plain_position} to {position}"
            );
        }
    }
    // Over the bump's top the free points stay below the surface they would have landed on.
    assert!(floated >= 4, "{floated} free points below the bump");
}

#[test]
fn stiffness_one_keeps_the_templates_shape_and_zero_follows_the_target() {
    let neutral = |solver: WrapSolver, inside: Vec<bool>, value: f32| {
        let stiffness = inside
            .iter()
            .map(|&inside| if inside { value } else { 0.5 })
            .collect();
        solver.with_vertex_stiffness(stiffness).unwrap()
    };
    let (plain, _, inside) = wrap_over_bump(|solver, inside| neutral(solver, inside, 0.5));
    let (stiff, stiff_report, _) = wrap_over_bump(|solver, inside| neutral(solver, inside, 1.0));
    let (soft, soft_report, _) = wrap_over_bump(|solver, inside| neutral(solver, inside, 0.0));
    assert!(stiff_report.converged && soft_report.converged);
    let stretch = |solver: &WrapSolver| worst_stretch(solver.positions(), &inside);
    assert!(
        stretch(&stiff) < 0.5 * stretch(&plain),
        "stiff {} against neutral {}",
        stretch(&stiff),
        stretch(&plain)
    );
    assert!(
        stretch(&soft) >= stretch(&plain) * 0.999,
        "soft {} against neutral {}",
        stretch(&soft),
        stretch(&plain)
    );
    // The soft region is on the target, face-points all.
    for vertex in (0..inside.len()).filter(|&vertex| inside[vertex]) {
        assert!(
            matches!(soft.points()[vertex], LayoutPoint::Face(_)),
            "soft vertex {vertex} did not land"
        );
    }
}

#[test]
fn vertex_stiffness_and_free_vertices_are_checked_and_need_the_energy_solver() {
    let target = common::plane_target(40, 0.05, 0.0);
    let (structure, positions) = common::quad_layout(4, 0.1, Vec3::new(-0.2, -0.2, 0.1));
    let count = positions.len();
    let points: Vec<LayoutPoint> = positions.iter().map(|&p| LayoutPoint::Space(p)).collect();
    let make = |settings: WrapSettings| {
        WrapSolver::new(
            Arc::clone(&target),
            structure.clone(),
            points.clone(),
            &[],
            settings,
        )
        .unwrap()
    };
    let mut too_stiff = vec![0.5; count];
    too_stiff[3] = 1.5;
    let error = make(energy_settings())
        .with_vertex_stiffness(too_stiff)
        .unwrap_err();
    assert!(
        matches!(
            error,
            KernelError::InvalidArgument {
                name: "stiffness",
                ..
            }
        ),
        "{error:?}"
    );
    let mut not_a_number = vec![0.5; count];
    not_a_number[0] = f32::NAN;
    assert!(
        make(energy_settings())
            .with_vertex_stiffness(not_a_number)
            .is_err()
    );
    let error = make(energy_settings())
        .with_free_vertices(vec![false; count - 1])
        .unwrap_err();
    assert!(
        matches!(error, KernelError::LengthMismatch { .. }),
        "{error:?}"
    );
}
