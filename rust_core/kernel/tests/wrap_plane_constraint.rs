//! The mirror plane as a constraint (paper, section 3): a seam held on a plane lands on the
//! target's cross-section with it, whatever shape that has (a closed loop, pieces around a hole).

mod common;

use std::sync::Arc;

use glam::{Quat, Vec3};
use springwrap_kernel::{
    CurveConstraint, KernelError, LayoutPoint, LayoutStructure, PlaneConstraint, TargetMesh,
    TargetMeshOptions, WrapSettings, WrapSolver,
};

/// The mirror plane of these tests: tilted, not through the sphere's centre nor its vertices.
fn plane() -> (Vec3, Vec3) {
    (
        Vec3::new(0.0, 0.03, 0.0),
        Vec3::new(0.2, 1.0, 0.1).normalize(),
    )
}

/// A sphere of radius 1 (48 rings, 64 segments), minus the triangles within `hole_radius` of
/// `hole_centre`.
fn sphere_target(hole_centre: Vec3, hole_radius: f32) -> Arc<TargetMesh> {
    let (vertices, triangles) = common::uv_sphere(1.0, 48, 64);
    let triangles = triangles
        .into_iter()
        .filter(|corners| {
            let centre = corners.iter().map(|&i| vertices[i as usize]).sum::<Vec3>() / 3.0;
            centre.distance(hole_centre) > hole_radius
        })
        .collect();
    Arc::new(TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap())
}

/// A band of quads across the plane (a mirrored layout): `around` columns closing into a loop,
/// `rows` rows on each side of the seam; the seam (vertices `0..around`) runs around the plane.
/// Positions on the unit sphere, except the seam: out at `seam_radius` and pushed off the plane
/// by `seam_offset` (alternating sides).
fn band_layout(
    around: u32,
    rows: u32,
    seam_radius: f32,
    seam_offset: f32,
) -> (LayoutStructure, Vec<Vec3>) {
    let (_, normal) = plane();
    let turn = Quat::from_rotation_arc(Vec3::Y, normal);
    // Rows in the order 0, 1, -1, 2, -2, ...: the seam first.
    let row_order: Vec<i32> = std::iter::once(0)
        .chain((1..=rows as i32).flat_map(|row| [row, -row]))
        .collect();
    let slot = |row: i32| row_order.iter().position(|&r| r == row).unwrap() as u32;
    let mut positions = Vec::new();
    for &row in &row_order {
        let latitude = 0.12 * row as f32;
        for column in 0..around {
            let azimuth = std::f32::consts::TAU * column as f32 / around as f32;
            let local = Vec3::new(
                latitude.cos() * azimuth.cos(),
                latitude.sin(),
                latitude.cos() * azimuth.sin(),
            );
            let mut position = turn * local;
            if row == 0 {
                position = position * seam_radius
                    + normal * seam_offset * if column % 2 == 0 { 1.0 } else { -1.0 };
            }
            positions.push(position);
        }
    }
    let mut corners = Vec::new();
    for row in -(rows as i32)..rows as i32 {
        let (low, high) = (slot(row) * around, slot(row + 1) * around);
        for column in 0..around {
            let next = (column + 1) % around;
            corners.extend([low + column, high + column, high + next, low + next]);
        }
    }
    let face_count = (2 * rows * around) as usize;
    let structure =
        LayoutStructure::new(positions.len(), &corners, &vec![4; face_count], &[], &[]).unwrap();
    (structure, positions)
}

/// Rows 1.. snapped onto the target as face-points, the seam left where it is as space-points.
fn start_points(target: &TargetMesh, positions: &[Vec3], around: u32) -> Vec<LayoutPoint> {
    positions
        .iter()
        .enumerate()
        .map(|(index, &position)| {
            if index < around as usize {
                LayoutPoint::Space(position)
            } else {
                LayoutPoint::Face(
                    target
                        .closest_point(position, f32::INFINITY)
                        .unwrap()
                        .face_point,
                )
            }
        })
        .collect()
}

fn wrap_band(target: Arc<TargetMesh>, around: u32, slide: bool) -> WrapSolver {
    let (structure, positions) = band_layout(around, 4, 1.1, 0.05);
    let points = start_points(&target, &positions, around);
    let (point, normal) = plane();
    let (_, rest) = band_layout(around, 4, 1.0, 0.0);
    let mut solver = WrapSolver::with_rest_shape(
        target,
        structure,
        points,
        Some(rest),
        &[],
        WrapSettings::default(),
    )
    .unwrap()
    .with_plane_constraint(&PlaneConstraint {
        vertices: (0..around).collect(),
        point,
        normal,
        slide,
    })
    .unwrap();
    let report = solver.step(3000).expect("the spring solver steps");
    assert!(report.converged, "{report:?}");
    solver
}

#[test]
fn a_seam_held_on_the_plane_lands_on_the_closed_cross_section() {
    let around = 40;
    let target = sphere_target(Vec3::splat(10.0), 0.0);
    let solver = wrap_band(target.clone(), around, true);
    let (point, normal) = plane();
    let seam = &solver.positions()[..around as usize];
    for (vertex, &position) in seam.iter().enumerate() {
        let off_plane = (position - point).dot(normal).abs();
        assert!(
            off_plane < 1e-5,
            "seam vertex {vertex} is {off_plane} off the plane"
        );
        assert!(
            matches!(solver.points()[vertex], LayoutPoint::Face(_)),
            "seam vertex {vertex} did not land on the surface"
        );
        let off_surface = target
            .closest_point(position, f32::INFINITY)
            .unwrap()
            .distance;
        assert!(
            off_surface < 1e-5,
            "seam vertex {vertex} is {off_surface} off the surface"
        );
    }
    // The seam still goes round evenly: no chord under half or over twice the mean.
    let chords: Vec<f32> = (0..around as usize)
        .map(|index| seam[index].distance(seam[(index + 1) % around as usize]))
        .collect();
    let mean = chords.iter().sum::<f32>() / chords.len() as f32;
    for chord in chords {
        assert!(
            (0.5 * mean..2.0 * mean).contains(&chord),
            "chord {chord}, mean {mean}"
        );
    }
}

#[test]
fn a_seam_over_a_hole_stays_on_the_plane_in_space_and_lands_elsewhere() {
    let around = 40;
    let (point, normal) = plane();
    // A hole on the cross-section: the seam is cut in two pieces of surface.
    let on_section = (Quat::from_rotation_arc(Vec3::Y, normal) * Vec3::X).normalize();
    let hole_centre = point + on_section;
    let target = sphere_target(hole_centre, 0.3);
    let solver = wrap_band(target.clone(), around, true);
    let mut over_hole = 0;
    let mut landed = 0;
    for (vertex, &position) in solver.positions()[..around as usize].iter().enumerate() {
        let off_plane = (position - point).dot(normal).abs();
        assert!(
            off_plane < 1e-5,
            "seam vertex {vertex} is {off_plane} off the plane"
        );
        match solver.points()[vertex] {
            LayoutPoint::Face(_) => {
                landed += 1;
                let off_surface = target
                    .closest_point(position, f32::INFINITY)
                    .unwrap()
                    .distance;
                assert!(
                    off_surface < 1e-5,
                    "seam vertex {vertex} is {off_surface} off the surface"
                );
            }
            LayoutPoint::Space(_) => {
                over_hole += 1;
                assert!(
                    position.distance(hole_centre) < 0.35,
                    "seam vertex {vertex} floats away from the hole"
                );
            }
        }
    }
    assert!(over_hole >= 2, "{over_hole} seam points over the hole");
    assert!(landed >= 30, "{landed} seam points landed");
}

#[test]
fn bad_plane_constraints_are_refused() {
    let around = 8;
    let target = sphere_target(Vec3::splat(10.0), 0.0);
    let (structure, positions) = band_layout(around, 2, 1.1, 0.0);
    let points = start_points(&target, &positions, around);
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
    let refused = |constraint: PlaneConstraint, expected: &str| {
        let error = solver().with_plane_constraint(&constraint).err().unwrap();
        assert!(
            matches!(error, KernelError::InvalidArgument { .. }),
            "{error:?}"
        );
        assert!(
            error.to_string().contains(expected),
            "{error} lacks {expected:?}"
        );
    };
    refused(
        PlaneConstraint {
            vertices: vec![0],
            point: Vec3::ZERO,
            normal: Vec3::ZERO,
            slide: true,
        },
        "zero length",
    );
    // The input policy (validate.rs): a NaN point is NonFinite, a plane beyond the region the
    // wrap can reach is BeyondReach.
    let error = solver()
        .with_plane_constraint(&PlaneConstraint {
            vertices: vec![0],
            point: Vec3::NAN,
            normal: Vec3::Y,
            slide: true,
        })
        .err()
        .unwrap();
    assert_eq!(
        error,
        KernelError::NonFinite {
            what: "plane point",
            index: 0
        }
    );
    let error = solver()
        .with_plane_constraint(&PlaneConstraint {
            vertices: vec![0],
            point: Vec3::new(0.0, 1e7, 0.0),
            normal: Vec3::Y,
            slide: true,
        })
        .err()
        .unwrap();
    assert!(
        matches!(error, KernelError::BeyondReach { what: "plane", .. }),
        "{error:?}"
    );
    refused(
        PlaneConstraint {
            vertices: vec![99],
            point: Vec3::ZERO,
            normal: Vec3::Y,
            slide: true,
        },
        "vertex 99 does not exist",
    );
    let curve = CurveConstraint {
        layout_vertices: vec![0, 1],
        target: vec![Vec3::ZERO, Vec3::X],
        fractions: Vec::new(),
    };
    let error = solver()
        .with_curve_constraints(std::slice::from_ref(&curve))
        .unwrap()
        .with_plane_constraint(&PlaneConstraint {
            vertices: vec![1],
            point: Vec3::ZERO,
            normal: Vec3::Y,
            slide: true,
        })
        .err()
        .unwrap();
    assert!(
        error
            .to_string()
            .contains("also held by a curve constraint"),
        "{error}"
    );
    let error = solver()
        .with_plane_constraint(&PlaneConstraint {
            vertices: vec![1],
            point: Vec3::ZERO,
            normal: Vec3::Y,
            slide: true,
        })
        .unwrap()
        .with_curve_constraints(&[curve])
        .err()
        .unwrap();
    assert!(
        error
            .to_string()
            .contains("also held on the plane constraint"),
        "{error}"
    );
}

#[test]
fn a_held_seam_that_does_not_slide_only_moves_onto_the_cross_section() {
    let around = 40;
    let target = sphere_target(Vec3::splat(10.0), 0.0);
    let (point, normal) = plane();
    let mut solver = wrap_band(target.clone(), around, false);
    let settled: Vec<Vec3> = solver.positions()[..around as usize].to_vec();
    // Started off the plane and off the surface: on both now.
    for (vertex, &position) in settled.iter().enumerate() {
        let off_plane = (position - point).dot(normal).abs();
        assert!(
            off_plane < 1e-5,
            "seam vertex {vertex} is {off_plane} off the plane"
        );
        let off_surface = target
            .closest_point(position, f32::INFINITY)
            .unwrap()
            .distance;
        assert!(
            off_surface < 1e-5,
            "seam vertex {vertex} is {off_surface} off the surface"
        );
    }
    // And it stays there, whatever the springs say.
    solver.step(200).expect("the spring solver steps");
    for (vertex, (&now, &then)) in solver.positions().iter().zip(&settled).enumerate() {
        assert!(
            now.distance(then) < 1e-6,
            "seam vertex {vertex} slid by {}",
            now.distance(then)
        );
    }
}
