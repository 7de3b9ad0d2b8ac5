//! The subdivision cage fit: Catmull–Clark stencils and the Gauss–Newton rounds that put the
//! subdivided surface on the target.

mod common;

use std::collections::HashMap;
use std::sync::atomic::{AtomicUsize, Ordering};

use glam::DVec3;
use springwrap_kernel::fit::{
    BoundaryRule, SubdivisionFit, SubdivisionFitSettings, SubdivisionStencils,
};
use springwrap_kernel::{KernelError, TargetMesh, TargetMeshOptions};

/// A cube of `n` × `n` quads a side, its vertices pushed onto the sphere of `radius` about the
/// origin, faces wound outwards: a subdivision cage with eight valence-3 vertices.
fn cube_sphere(n: i32, radius: f64) -> (Vec<DVec3>, Vec<u32>, Vec<u32>) {
    let mut index_of: HashMap<[i32; 3], u32> = HashMap::new();
    let mut positions = Vec::new();
    let mut corners = Vec::new();
    // Each side: a normal axis, its sign, and two tangent axes with u × v along the normal.
    let sides = [
        (0, 1, 1, 2),
        (0, -1, 2, 1),
        (1, 1, 2, 0),
        (1, -1, 0, 2),
        (2, 1, 0, 1),
        (2, -1, 1, 0),
    ];
    let mut vertex = |grid: [i32; 3]| -> u32 {
        *index_of.entry(grid).or_insert_with(|| {
            let point = DVec3::new(f64::from(grid[0]), f64::from(grid[1]), f64::from(grid[2]));
            positions.push(point.normalize() * radius);
            (positions.len() - 1) as u32
        })
    };
    for (axis, sign, u_axis, v_axis) in sides {
        for i in 0..n {
            for j in 0..n {
                let at = |du: i32, dv: i32| {
                    let mut grid = [0; 3];
                    grid[axis] = sign * n;
                    grid[u_axis] = 2 * (i + du) - n;
                    grid[v_axis] = 2 * (j + dv) - n;
                    grid
                };
                corners.extend([at(0, 0), at(1, 0), at(1, 1), at(0, 1)].map(&mut vertex));
            }
        }
    }
    let faces = corners.len() / 4;
    (positions, corners, vec![4; faces])
}

/// The cube cage of `cube_sphere(3, 1.0)` and its level-2 fit (default boundary rule and settings), with
/// `fixed` vertices held (none by default).
fn cube_cage_fit(fixed: Option<&[bool]>) -> (Vec<DVec3>, SubdivisionFit) {
    let (cage, corners, sizes) = cube_sphere(3, 1.0);
    let stencils =
        SubdivisionStencils::new(cage.len(), &corners, &sizes, 2, BoundaryRule::default()).unwrap();
    let free = vec![false; cage.len()];
    let fit = SubdivisionFit::new(
        stencils,
        fixed.unwrap_or(&free),
        SubdivisionFitSettings::default(),
    )
    .unwrap();
    (cage, fit)
}

fn sphere_target(radius: f32) -> TargetMesh {
    let (vertices, triangles) = common::uv_sphere(radius, 96, 192);
    TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap()
}

fn max_distance(distances: &[f32]) -> f32 {
    distances
        .iter()
        .copied()
        .filter(|d| d.is_finite())
        .fold(0.0, f32::max)
}

#[test]
fn the_limit_of_a_fine_vertex_does_not_depend_on_the_level() {
    // Fine vertices are numbered parents first, so level L's fine vertices are the first ones of
    // level L + 1, and the limit point of a vertex is where the surface passes, at any level.
    let (cage, mut corners, mut sizes) = cube_sphere(2, 1.0);
    // Triangles among the quads and an open border: cut one face off and split another in two.
    corners.truncate(corners.len() - 4);
    sizes.pop();
    let last_quad: Vec<u32> = corners.split_off(corners.len() - 4);
    sizes.pop();
    corners.extend_from_slice(&[last_quad[0], last_quad[1], last_quad[2]]);
    corners.extend_from_slice(&[last_quad[0], last_quad[2], last_quad[3]]);
    sizes.extend([3, 3]);
    for rule in [BoundaryRule::SmoothCorners, BoundaryRule::KeepCorners] {
        let fine: Vec<Vec<DVec3>> = (1..=4)
            .map(|levels| {
                SubdivisionStencils::new(cage.len(), &corners, &sizes, levels, rule)
                    .unwrap()
                    .apply(&cage)
                    .unwrap()
            })
            .collect();
        for pair in fine.windows(2) {
            for (coarse, finer) in pair[0].iter().zip(&pair[1]) {
                assert!(coarse.distance(*finer) < 1e-12, "{coarse} against {finer}");
            }
        }
    }
}

#[test]
fn a_cube_cage_on_a_sphere_shrinks_inside_it_and_the_fit_brings_its_surface_out() {
    let target = sphere_target(1.0);
    let (cage, fit) = cube_cage_fit(None);
    let before = fit.distances(&target, &cage, None).unwrap();
    // The subdivided surface of a cage on the sphere lies inside it.
    let fine = fit.fine_points(&cage, None).unwrap();
    assert!(fine.iter().all(|point| point.length() < 1.0 + 1e-3));
    let mut positions = cage.clone();
    for _ in 0..6 {
        positions = fit.round(&target, &positions, None).unwrap().positions;
    }
    let after = fit.distances(&target, &positions, None).unwrap();
    let (before_max, after_max) = (max_distance(&before), max_distance(&after));
    assert!(before_max > 0.02, "{before_max}");
    assert!(
        after_max * 5.0 < before_max,
        "max distance {before_max} -> {after_max}"
    );
    // The cage itself moved out, past the sphere.
    let mean_radius: f64 =
        positions.iter().map(|point| point.length()).sum::<f64>() / positions.len() as f64;
    assert!(mean_radius > 1.01, "{mean_radius}");
}

#[test]
fn fixed_vertices_stay_and_the_rest_still_fits() {
    let target = sphere_target(1.0);
    let fixed: Vec<bool> = (0..cube_sphere(3, 1.0).0.len())
        .map(|vertex| vertex % 7 == 0)
        .collect();
    let (cage, fit) = cube_cage_fit(Some(&fixed));
    let before = max_distance(&fit.distances(&target, &cage, None).unwrap());
    let mut positions = cage.clone();
    for _ in 0..6 {
        positions = fit.round(&target, &positions, None).unwrap().positions;
    }
    for (vertex, &held) in fixed.iter().enumerate() {
        if held {
            assert_eq!(positions[vertex], cage[vertex], "vertex {vertex} moved");
        }
    }
    let after = max_distance(&fit.distances(&target, &positions, None).unwrap());
    assert!(after < before, "{before} -> {after}");
}

#[test]
fn an_anchor_holds_its_vertex_limit_point_on_the_anchor() {
    let target = sphere_target(1.0);
    let (cage, fit) = cube_cage_fit(None);
    // Two anchors on the sphere, one a little off its vertex's own direction.
    let anchored = [0u32, 17];
    let points = [
        cage[0],
        (cage[17] + DVec3::new(0.03, -0.02, 0.01)).normalize(),
    ];
    let fit = fit.with_anchors(&anchored, &points).unwrap();
    let mut positions = cage.clone();
    for _ in 0..6 {
        positions = fit.round(&target, &positions, None).unwrap().positions;
    }
    let fine = fit.fine_points(&positions, None).unwrap();
    for (&vertex, point) in anchored.iter().zip(&points) {
        let gap = fine[vertex as usize].distance(*point);
        assert!(gap < 2e-3, "vertex {vertex}: {gap}");
    }
    // The rest still fits.
    let after = max_distance(&fit.distances(&target, &positions, None).unwrap());
    assert!(after < 0.02, "{after}");
    let error = SubdivisionFit::new(
        fit.stencils().clone(),
        &vec![false; cage.len()],
        SubdivisionFitSettings::default(),
    )
    .unwrap()
    .with_anchors(&[10_000], &[DVec3::ZERO])
    .unwrap_err();
    assert!(
        matches!(error, KernelError::LayoutIndexOutOfRange { .. }),
        "{error}"
    );
}

#[test]
fn offsets_shift_the_fine_points_and_the_fit_makes_up_for_them() {
    let target = sphere_target(1.0);
    let (cage, fit) = cube_cage_fit(None);
    let count = fit.stencils().fine_vertex_count();
    let offsets = vec![DVec3::new(0.0, 0.0, 0.01); count];
    let plain = fit.fine_points(&cage, None).unwrap();
    let shifted = fit.fine_points(&cage, Some(&offsets)).unwrap();
    assert!((shifted[5] - plain[5] - offsets[5]).length() < 1e-15);
    let mut positions = cage.clone();
    for _ in 0..6 {
        positions = fit
            .round(&target, &positions, Some(&offsets))
            .unwrap()
            .positions;
    }
    let with_offsets = fit.distances(&target, &positions, Some(&offsets)).unwrap();
    let before = fit.distances(&target, &cage, Some(&offsets)).unwrap();
    assert!(max_distance(&with_offsets) * 5.0 < max_distance(&before));
}

#[test]
fn over_a_hole_the_cage_follows_its_neighbours() {
    // The sphere without its top cap: the fine points over the hole have no trusted match.
    let (vertices, triangles) = common::uv_sphere(1.0, 96, 192);
    let triangles: Vec<[u32; 3]> = triangles
        .into_iter()
        .filter(|triangle| triangle.iter().any(|&v| vertices[v as usize].z < 0.75))
        .collect();
    let target = TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap();
    let (cage, fit) = cube_cage_fit(None);
    let first = fit.round(&target, &cage, None).unwrap();
    assert!(first.trusted < fit.stencils().fine_vertex_count());
    let mut positions = first.positions;
    for _ in 0..5 {
        positions = fit.round(&target, &positions, None).unwrap().positions;
    }
    // The top vertices, over the hole, moved out with the rest (outwards, about as far), and
    // were not pulled to the hole's rim.
    let side_growth = positions
        .iter()
        .zip(&cage)
        .filter(|(_, start)| start.z.abs() < 0.5)
        .map(|(end, start)| end.length() - start.length())
        .fold(0.0, f64::max);
    let top_z = cage.iter().map(|point| point.z).fold(f64::MIN, f64::max);
    for (vertex, start) in cage.iter().enumerate() {
        if start.z < top_z - 1e-9 {
            continue;
        }
        let moved = positions[vertex] - *start;
        assert!(
            moved.normalize().dot(start.normalize()) > 0.9,
            "{moved} at {start}"
        );
        assert!(
            moved.length() < 3.0 * side_growth,
            "{moved} against {side_growth}"
        );
    }
}

#[test]
fn bad_inputs_are_refused_with_the_reason() {
    let (cage, corners, sizes) = cube_sphere(1, 1.0);
    let stencils =
        SubdivisionStencils::new(cage.len(), &corners, &sizes, 1, BoundaryRule::default()).unwrap();
    let error = SubdivisionFit::new(
        stencils.clone(),
        &[false; 3],
        SubdivisionFitSettings::default(),
    )
    .unwrap_err();
    assert!(
        matches!(error, KernelError::LengthMismatch { .. }),
        "{error}"
    );
    for settings in [
        SubdivisionFitSettings {
            smoothness: -1.0,
            ..Default::default()
        },
        SubdivisionFitSettings {
            max_distance: 0.0,
            ..Default::default()
        },
        SubdivisionFitSettings {
            min_facing: 2.0,
            ..Default::default()
        },
        SubdivisionFitSettings {
            damping: f64::NAN,
            ..Default::default()
        },
        SubdivisionFitSettings {
            anchor_weight: 0.0,
            ..Default::default()
        },
    ] {
        let error =
            SubdivisionFit::new(stencils.clone(), &vec![false; cage.len()], settings).unwrap_err();
        assert!(
            matches!(error, KernelError::InvalidArgument { .. }),
            "{error}"
        );
    }
    let fit = SubdivisionFit::new(
        stencils,
        &vec![false; cage.len()],
        SubdivisionFitSettings::default(),
    )
    .unwrap();
    let target = sphere_target(1.0);
    let mut bad = cage.clone();
    bad[3].y = f64::NAN;
    let error = fit.round(&target, &bad, None).unwrap_err();
    assert_eq!(
        error,
        KernelError::NonFinite {
            what: "cage position",
            index: 3
        }
    );
    let error = fit.round(&target, &cage[..4], None).unwrap_err();
    assert!(
        matches!(error, KernelError::LengthMismatch { .. }),
        "{error}"
    );
    let error = fit
        .round(&target, &cage, Some(&[DVec3::ZERO; 2]))
        .unwrap_err();
    assert!(
        matches!(error, KernelError::LengthMismatch { .. }),
        "{error}"
    );
}

#[test]
fn a_round_asked_to_stop_inside_its_loops_returns_cancelled_and_an_unasked_one_is_the_plain_round()
{
    let target = sphere_target(1.0);
    let (cage, fit) = cube_cage_fit(None);
    let plain = fit.round(&target, &cage, None).unwrap();
    let never = fit.round_until(&target, &cage, None, &|| false).unwrap();
    assert_eq!(plain, never);
    // A stop that says yes at its n-th question: the round asks it past its start, inside its loops.
    for after in [1usize, 2, 3, 5] {
        let asked = AtomicUsize::new(0);
        let stop = || asked.fetch_add(1, Ordering::SeqCst) + 1 >= after;
        let outcome = fit.round_until(&target, &cage, None, &stop);
        assert!(
            matches!(outcome, Err(KernelError::Cancelled { .. })),
            "stopped at question {after}: {outcome:?}"
        );
    }
    // Every question answered no: the round asks more than a few times (its loops ask, not only its start).
    let asked = AtomicUsize::new(0);
    let counted = fit
        .round_until(&target, &cage, None, &|| {
            asked.fetch_add(1, Ordering::SeqCst);
            false
        })
        .unwrap();
    assert_eq!(counted, plain);
    assert!(asked.load(Ordering::SeqCst) > cage.len(), "{asked:?}");
}
