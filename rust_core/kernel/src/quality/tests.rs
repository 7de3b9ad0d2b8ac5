//! The read-out's stretch, flips and distances against hand-made layouts and references.

use super::*;
use crate::align::Transform;

/// An n x n grid of quads in z = 0, unit cells: positions, corners, sizes, edges.
fn grid(n: u32) -> (Vec<DVec3>, Vec<u32>, Vec<u32>, Vec<[u32; 2]>) {
    let side = n + 1;
    let points = (0..side * side)
        .map(|index| DVec3::new(f64::from(index % side), f64::from(index / side), 0.0))
        .collect();
    let mut corners = Vec::new();
    let mut edges = Vec::new();
    for row in 0..n {
        for column in 0..n {
            let first = row * side + column;
            corners.extend([first, first + 1, first + side + 1, first + side]);
        }
    }
    for row in 0..side {
        for column in 0..side {
            let vertex = row * side + column;
            if column + 1 < side {
                edges.push([vertex, vertex + 1]);
            }
            if row + 1 < side {
                edges.push([vertex, vertex + side]);
            }
        }
    }
    let sizes = vec![4; (n * n) as usize];
    (points, corners, sizes, edges)
}

#[test]
fn a_layout_scaled_by_two_stretches_two_and_unchanged_reads_one() {
    let (points, _, _, edges) = grid(3);
    let doubled: Vec<DVec3> = points.iter().map(|&point| point * 2.0).collect();
    assert!(
        vertex_stretch(&doubled, &points, &edges)
            .unwrap()
            .iter()
            .all(|&s| (s - 2.0).abs() < 1e-12)
    );
    assert!(
        vertex_stretch(&points, &points, &edges)
            .unwrap()
            .iter()
            .all(|&s| s == 1.0)
    );
    let collapsed = vec![DVec3::ONE; points.len()];
    assert!(
        vertex_stretch(&points, &collapsed, &edges)
            .unwrap()
            .iter()
            .all(|&s| s == 1.0)
    );
}

#[test]
fn a_fold_flips_the_faces_it_turns_over_and_a_turn_flips_none() {
    let (points, corners, sizes, edges) = grid(4);
    let faces = LayoutFaces {
        corners: &corners,
        sizes: &sizes,
    };
    assert!(
        !flipped_faces(&points, &points, faces, &edges)
            .unwrap()
            .contains(&true)
    );
    let turned: Vec<DVec3> = points
        .iter()
        .map(|&p| DVec3::new(-p.x, p.y, -p.z + 3.0))
        .collect();
    assert!(
        !flipped_faces(&turned, &points, faces, &edges)
            .unwrap()
            .contains(&true)
    );
    let mut folded = points.clone();
    folded[6] = points[18] + DVec3::new(0.4, 0.4, 0.0); // an inner vertex dragged over others
    let flipped = flipped_faces(&folded, &points, faces, &edges).unwrap();
    let normals = face_normals(&folded, faces).unwrap();
    assert!(flipped.contains(&true));
    for (flip, normal) in flipped.iter().zip(&normals) {
        assert_eq!(*flip, normal.z < 0.0);
    }
}

#[test]
fn degenerate_and_non_finite_faces_are_not_flipped() {
    let (points, corners, sizes, edges) = grid(2);
    let faces = LayoutFaces {
        corners: &corners,
        sizes: &sizes,
    };
    let mut broken = points.clone();
    for &corner in &corners[..4] {
        broken[corner as usize] = DVec3::splat(0.5); // face 0 to a point
    }
    broken[8] = DVec3::NAN;
    let flipped = flipped_faces(&broken, &points, faces, &edges).unwrap();
    assert!(!flipped[0] && !flipped[3]);
    assert_eq!(face_normals(&broken, faces).unwrap()[0], DVec3::ZERO);
}

/// Numbers uniform in [-0.5, 0.5) from a linear congruential generator.
fn uniform(mut seed: u64) -> impl FnMut() -> f64 {
    move || {
        seed = seed
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    }
}

#[test]
fn the_fast_rotation_is_the_eigen_solvers() {
    let mut random = uniform(7);
    for case in 0..2000 {
        let mut cross: [[f64; 3]; 3] = std::array::from_fn(|_| std::array::from_fn(|_| random()));
        if case % 3 == 0 {
            cross[2] = [0.0; 3]; // planar neighbourhoods: rank 2
        }
        let fast = fast_horn_rotation(&cross, f64::INFINITY);
        let reference = horn_rotation(&cross);
        assert!(
            fast.dot(reference).abs() > 1.0 - 1e-9,
            "case {case}: {fast} against {reference}"
        );
    }
    assert_eq!(
        fast_horn_rotation(&[[0.0; 3]; 3], f64::INFINITY),
        glam::DQuat::IDENTITY
    );
}

#[test]
fn the_fast_rotation_started_from_the_spreads_is_the_eigen_solvers() {
    // Groups of points turned, scaled, squashed flat, jittered or scattered: the spreads' bound is
    // tight for the first, loose for the last; near and far from the origin. (Fewer than three
    // points have no single best rotation.)
    let mut random = uniform(5);
    for case in 0..3000 {
        let count = 3 + case % 7;
        let turn = glam::DQuat::from_axis_angle(
            DVec3::new(random(), random(), random() + 1.0).normalize(),
            7.0 * random(),
        );
        let (jitter, scale) =
            [(0.0, 1.0), (1e-9, 1.0), (0.05, 1.3), (0.5, 0.7), (5.0, 1.0)][case % 5];
        let far = DVec3::splat(if case % 2 == 0 { 0.0 } else { 1e5 });
        let rest: Vec<DVec3> = (0..count)
            .map(|_| {
                let point = DVec3::new(random(), random(), random());
                far + if case % 3 == 0 {
                    point * DVec3::new(1.0, 1.0, 0.0)
                } else {
                    point
                }
            })
            .collect();
        let now: Vec<DVec3> = rest
            .iter()
            .map(|&point| {
                let wobble = jitter * DVec3::new(random(), random(), random());
                turn * ((point - far) * scale) + wobble - far
            })
            .collect();
        let moments = Moments::of(&now, &rest, 0..count as u32);
        let bound = (moments.spread_rest * moments.spread_now).sqrt();
        let fast = fast_horn_rotation(&moments.cross, bound);
        let reference = fast_horn_rotation(&moments.cross, f64::INFINITY);
        assert!(
            fast.dot(reference).abs() > 1.0 - 1e-9,
            "case {case}: {fast} against {reference}"
        );
        assert!(
            (moments.best_rotation() * DVec3::X).distance(fast * DVec3::X) < 1e-12,
            "case {case}"
        );
        if jitter < 1.0 {
            let eigen = horn_rotation(&moments.cross);
            assert!(
                fast.dot(eigen).abs() > 1.0 - 1e-9,
                "case {case}: {fast} against {eigen}"
            );
        }
    }
}

#[test]
fn bad_indices_and_lengths_are_refused() {
    let (points, corners, sizes, edges) = grid(1);
    let faces = LayoutFaces {
        corners: &corners,
        sizes: &[3],
    };
    assert!(matches!(
        face_normals(&points, faces),
        Err(KernelError::LengthMismatch { .. })
    ));
    let bad = [0, 1, 9, 3];
    let faces = LayoutFaces {
        corners: &bad,
        sizes: &sizes,
    };
    assert!(matches!(
        face_normals(&points, faces),
        Err(KernelError::LayoutIndexOutOfRange { .. })
    ));
    assert!(matches!(
        vertex_stretch(&points, &points, &[[0, 7]]),
        Err(KernelError::LayoutIndexOutOfRange { .. })
    ));
    assert!(matches!(
        vertex_stretch(&points, &points[1..], &edges),
        Err(KernelError::LengthMismatch { .. })
    ));
}

/// Positions now and at rest, face corners, face sizes, edges.
type Warped = (Vec<DVec3>, Vec<DVec3>, Vec<u32>, Vec<u32>, Vec<[u32; 2]>);

/// A grid of `n` x `n` quads warped and folded at random.
fn warped(n: u32, seed: u64) -> Warped {
    let (rest, corners, sizes, edges) = grid(n);
    let mut random = uniform(seed);
    let points = rest
        .iter()
        .map(|p| {
            let bent = DVec3::new(p.x, p.y * p.y.cos(), p.y.sin() * 3.0);
            bent + 1.5 * DVec3::new(random(), random(), random()) + DVec3::splat(1e4)
        })
        .collect();
    (points, rest, corners, sizes, edges)
}

/// Each vertex's closed ring, stored per vertex (what the blocks measure where needed).
fn ring_moments(points: &[DVec3], rest: &[DVec3], neighbours: &Neighbours) -> Vec<Moments> {
    (0..points.len() as u32)
        .map(|vertex| {
            let ring = std::iter::once(vertex).chain(neighbours.of(vertex).iter().copied());
            Moments::of(points, rest, ring)
        })
        .collect()
}

#[test]
fn flips_judged_by_blocks_are_those_of_rings_stored_per_vertex() {
    // 10,000 quads: two blocks of faces and then some; numbered along the grid and at random.
    let (points, rest, corners, sizes, edges) = warped(100, 7);
    let mut state = 11u64;
    let mut order: Vec<u32> = (0..points.len() as u32).collect();
    for index in (1..order.len()).rev() {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        order.swap(index, (state >> 33) as usize % (index + 1));
    }
    let shuffled = |positions: &[DVec3]| {
        let mut out = vec![DVec3::ZERO; positions.len()];
        for (old, &new) in order.iter().enumerate() {
            out[new as usize] = positions[old];
        }
        out
    };
    let renumber =
        |vertices: &[u32]| -> Vec<u32> { vertices.iter().map(|&v| order[v as usize]).collect() };
    let shuffled_edges: Vec<[u32; 2]> = edges
        .iter()
        .map(|&[a, b]| [order[a as usize], order[b as usize]])
        .collect();
    let layouts = [
        (points.clone(), rest.clone(), corners.clone(), edges.clone()),
        (
            shuffled(&points),
            shuffled(&rest),
            renumber(&corners),
            shuffled_edges,
        ),
    ];
    for (points, rest, corners, edges) in &layouts {
        let faces = LayoutFaces {
            corners,
            sizes: &sizes,
        };
        let starts = faces.starts(points.len()).unwrap();
        let neighbours = Neighbours::new(edges, points.len());
        let rings = ring_moments(points, rest, &neighbours);
        let expected: Vec<bool> = starts
            .iter()
            .zip(&sizes)
            .map(|(&start, &size)| {
                let corners = &corners[start..start + size as usize];
                let (normal, rest_normal) =
                    (newell_normal(points, corners), newell_normal(rest, corners));
                if normal == DVec3::ZERO || rest_normal == DVec3::ZERO {
                    return false;
                }
                let mut group = Moments::default();
                for &corner in corners {
                    group.merge(&rings[corner as usize]);
                }
                let facing = (group.best_rotation() * rest_normal).dot(normal);
                facing.is_finite() && facing < 0.0
            })
            .collect();
        assert!(expected.contains(&true) && expected.contains(&false));
        // Cached blocks, no cache at all, and (along the grid: the first block's 8,192 faces span
        // about 8,400 vertices, the second's about 1,900) a cache too narrow for the first only.
        for span in [RING_CACHE_SPAN, 0, 2_000] {
            for shortcut in [false, true] {
                let (flipped, _) =
                    flips_cached(points, rest, faces, &starts, &neighbours, span, shortcut);
                assert_eq!(flipped, expected, "span {span}, shortcut {shortcut}");
            }
        }
    }
}

#[test]
fn a_neighbourhood_merged_from_rings_has_the_groups_moments() {
    let (points, rest, corners, sizes, edges) = warped(6, 3);
    let neighbours = Neighbours::new(&edges, points.len());
    let rings = ring_moments(&points, &rest, &neighbours);
    for face in corners.chunks_exact(sizes[0] as usize) {
        let group = face.iter().flat_map(|&corner| {
            std::iter::once(corner).chain(neighbours.of(corner).iter().copied())
        });
        let direct = Moments::of(&points, &rest, group);
        let mut merged = Moments::default();
        for &corner in face {
            merged.merge(&rings[corner as usize]);
        }
        assert_eq!(merged.count, direct.count);
        assert!(merged.mean_now.distance(direct.mean_now) < 1e-9);
        assert!(merged.mean_rest.distance(direct.mean_rest) < 1e-9);
        for (a, b) in merged
            .cross
            .iter()
            .flatten()
            .zip(direct.cross.iter().flatten())
        {
            assert!((a - b).abs() < 1e-8 * (1.0 + b.abs()), "{a} against {b}");
        }
        for (a, b) in [
            (merged.spread_now, direct.spread_now),
            (merged.spread_rest, direct.spread_rest),
        ] {
            assert!((a - b).abs() < 1e-8 * (1.0 + b.abs()), "{a} against {b}");
        }
    }
}

#[test]
fn the_one_pass_readout_is_the_stretch_flips_and_size() {
    let (points, rest, corners, sizes, edges) = warped(12, 5);
    let faces = LayoutFaces {
        corners: &corners,
        sizes: &sizes,
    };
    let readout = layout_readout(&points, Some(&rest), faces, &edges).unwrap();
    let stretch = vertex_stretch(&points, &rest, &edges).unwrap();
    for (a, b) in readout.stretch.iter().zip(&stretch) {
        assert!((a - b).abs() < 1e-12 * b.abs().max(1.0));
    }
    let flipped = flipped_faces(&points, &rest, faces, &edges).unwrap();
    assert_eq!(readout.flipped, flipped);
    assert!(flipped.contains(&true) && flipped.contains(&false));
    let (low, high) = points
        .iter()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(low, high), p| {
            (low.min(*p), high.max(*p))
        });
    assert!((readout.diagonal - low.distance(high)).abs() < 1e-9);
    let unmeasured = layout_readout(&points, None, faces, &edges).unwrap();
    assert!(unmeasured.stretch.iter().all(|&s| s == 1.0));
    assert!(!unmeasured.flipped.contains(&true));
    assert_eq!(unmeasured.diagonal, readout.diagonal);
    let mut broken = points.clone();
    broken[0] = DVec3::NAN;
    let partial = layout_readout(&broken, Some(&rest), faces, &edges).unwrap();
    assert!(partial.diagonal > 0.0 && partial.diagonal <= readout.diagonal);
    assert!(partial.flipped.len() == flipped.len() && partial.stretch[0] == 1.0);
    assert!(matches!(
        layout_readout(&points, Some(&rest[1..]), faces, &edges),
        Err(KernelError::LengthMismatch { .. })
    ));
    assert_eq!(
        layout_readout(
            &[],
            None,
            LayoutFaces {
                corners: &[],
                sizes: &[]
            },
            &[]
        )
        .unwrap()
        .diagonal,
        0.0
    );
}

#[test]
fn surface_distances_match_the_closest_points_with_or_without_a_start() {
    let (points, corners, _, _) = grid(4);
    let vertices: Vec<Vec3> = points.iter().map(|point| point.as_vec3()).collect();
    let triangles: Vec<[u32; 3]> = corners
        .chunks_exact(4)
        .flat_map(|quad| [[quad[0], quad[1], quad[2]], [quad[0], quad[2], quad[3]]])
        .collect();
    let mesh = TargetMesh::new(vertices, triangles, crate::TargetMeshOptions::default()).unwrap();
    let queries = [
        DVec3::new(1.5, 2.5, 0.25),
        DVec3::new(-1.0, 2.0, 0.0),
        DVec3::NAN,
    ];
    let plain = mesh.surface_distances(&queries, None, 0.0).unwrap();
    let started = mesh
        .surface_distances(&queries, Some(&[30, 0, 5]), 1e-6)
        .unwrap();
    assert_eq!(plain, started);
    assert!((plain[0] - 0.25).abs() < 1e-7 && (plain[1] - 1.0).abs() < 1e-7);
    assert_eq!(plain[2], f64::INFINITY);
    assert!(mesh.surface_distances(&queries, Some(&[0]), 0.0).is_err());
    // On its own triangle within the tolerance: that triangle's distance, the same as the search's.
    let on = [DVec3::new(1.25, 1.5, 1e-7)];
    let found = mesh.surface_distances(&on, Some(&[8]), 1e-6).unwrap();
    assert!((found[0] - 1e-7).abs() < 1e-9);
    assert!((found[0] - mesh.surface_distances(&on, None, 0.0).unwrap()[0]).abs() < 1e-9);
}

#[test]
fn a_face_proved_unflipped_is_not_flipped_by_horns_rotation() {
    // Groups turned and jittered, their first four points a face; the face's normal now is its
    // rest normal carried by the group's best rotation and turned again by up to 120 degrees (many
    // near 90); the rotation the proof starts from is the best one turned by up to 0.6 radians.
    let mut random = uniform(13);
    let (mut proved, mut unproved) = (0, 0);
    for case in 0..20_000 {
        let count = 5 + case % 9;
        let axis = |random: &mut dyn FnMut() -> f64| {
            DVec3::new(random(), random(), random() + 0.7).normalize()
        };
        let turn = glam::DQuat::from_axis_angle(axis(&mut random), 7.0 * random());
        let jitter = [0.0, 0.01, 0.05, 0.2, 0.6][case % 5];
        let far = DVec3::splat(if case % 2 == 0 { 0.0 } else { 1e4 });
        let flat = if case % 3 == 0 { 0.02 } else { 1.0 };
        let rest: Vec<DVec3> = (0..count)
            .map(|_| far + DVec3::new(random(), random(), flat * random()))
            .collect();
        let now: Vec<DVec3> = rest
            .iter()
            .map(|&point| {
                let wobble = jitter * DVec3::new(random(), random(), random());
                turn * (point - far) + wobble + far
            })
            .collect();
        let corners = [0, 1, 2, 3];
        let group = Moments::of(&now, &rest, 0..count as u32);
        let best = group.best_rotation();
        let rest_normal = newell_normal(&rest, &corners);
        let angle = if case % 2 == 0 {
            std::f64::consts::FRAC_PI_2 * (1.0 + 0.3 * random())
        } else {
            2.1 * (random() + 0.5)
        };
        let normal =
            glam::DQuat::from_axis_angle(axis(&mut random), angle) * (best * rest_normal) * 0.7;
        let start = glam::DQuat::from_axis_angle(axis(&mut random), 1.2 * random()) * best;
        let facing = (best * rest_normal).dot(normal);
        if group.keeps_facing(&glam::DMat3::from_quat(start), rest_normal, normal) {
            proved += 1;
            assert!(facing > 0.0, "case {case}: proved, facing {facing}");
        } else {
            unproved += 1;
        }
    }
    println!("{proved} proved, {unproved} not");
    assert!(
        proved > 1_000 && unproved > 1_000,
        "{proved} proved, {unproved} not"
    );
}

#[test]
fn the_shortcut_flips_the_same_faces_as_horns_rotation_everywhere() {
    // A grid turned round, creased along a line (one side folded up by 80 to 110 degrees), a
    // little bent and jittered (1 % to half an edge), some faces folded over: the faces proved
    // unflipped are judged without a fit, the others are fitted; the flags are the same.
    let (rest, corners, sizes, edges) = grid(60);
    let turn = glam::DQuat::from_axis_angle(DVec3::new(1.0, -2.0, 0.5).normalize(), 2.5);
    for (case, (jitter, crease)) in [(0.01, 80.0), (0.05, 95.0), (0.2, 100.0), (0.5, 110.0)]
        .into_iter()
        .enumerate()
    {
        let mut random = uniform(31 + case as u64);
        let hinge = glam::DQuat::from_rotation_x(f64::to_radians(crease));
        let mut points: Vec<DVec3> = rest
            .iter()
            .map(|&point| {
                let creased = if point.y > 30.0 {
                    DVec3::new(0.0, 30.0, 0.0) + hinge * (point - DVec3::new(0.0, 30.0, 0.0))
                } else {
                    point
                };
                let bent = creased + DVec3::new(0.0, 0.0, 0.002 * creased.x * creased.x);
                let wobble = jitter * DVec3::new(random(), random(), random());
                turn * (bent + wobble) + DVec3::splat(500.0)
            })
            .collect();
        for face in (0..sizes.len()).step_by(97) {
            let face_corners = &corners[4 * face..4 * face + 4];
            let centre = face_corners
                .iter()
                .map(|&vertex| points[vertex as usize])
                .sum::<DVec3>()
                / 4.0;
            let first = face_corners[0] as usize;
            points[first] = centre + (centre - points[first]) * 1.5;
        }
        let faces = LayoutFaces {
            corners: &corners,
            sizes: &sizes,
        };
        let starts = faces.starts(points.len()).unwrap();
        let neighbours = Neighbours::new(&edges, points.len());
        let span = RING_CACHE_SPAN;
        let (fitted, none) = flips_cached(&points, &rest, faces, &starts, &neighbours, span, false);
        let (proved, count) = flips_cached(&points, &rest, faces, &starts, &neighbours, span, true);
        assert_eq!(none, 0);
        assert_eq!(proved, fitted, "case {case}");
        let flips = fitted.iter().filter(|&&flip| flip).count();
        println!(
            "case {case}: {flips} flipped, {count} of {} proved",
            sizes.len()
        );
        assert!(flips >= 10, "case {case}: {flips} flipped");
        if jitter <= 0.05 {
            assert!(count > sizes.len() / 2, "case {case}: {count} proved");
        }
        if jitter <= 0.2 {
            assert!(count > 0, "case {case}: {count} proved");
        }
        assert!(count < sizes.len(), "case {case}: {count} proved");
    }
}

#[test]
fn the_placed_readout_is_the_readout_and_distances_of_the_world_positions() {
    let (points, rest, corners, sizes, edges) = warped(12, 5);
    let local: Vec<Vec3> = points
        .iter()
        .map(|point| (*point - DVec3::splat(1e4)).as_vec3())
        .collect();
    let local_rest: Vec<Vec3> = rest.iter().map(|point| point.as_vec3()).collect();
    // A mirror, an uneven scale, a turn and a shift.
    let to_world = Transform {
        rows: [
            [0.0, 1.5, 0.0, 40.0],
            [0.5, 0.0, 0.0, -3.0],
            [0.0, 0.0, 2.0, 7.5],
        ],
    };
    assert!(to_world.determinant() < 0.0);
    let in_world = |points: &[Vec3]| -> Vec<DVec3> {
        points
            .iter()
            .map(|point| to_world.apply_f64(point.as_dvec3()))
            .collect()
    };
    let (world, world_rest) = (in_world(&local), in_world(&local_rest));
    let (grid_points, grid_corners, _, _) = grid(20);
    let mesh = TargetMesh::new(
        grid_points.iter().map(|point| point.as_vec3()).collect(),
        grid_corners
            .chunks_exact(4)
            .flat_map(|quad| [[quad[0], quad[1], quad[2]], [quad[0], quad[2], quad[3]]])
            .collect(),
        crate::TargetMeshOptions::default(),
    )
    .unwrap();
    let faces = LayoutFaces {
        corners: &corners,
        sizes: &sizes,
    };
    let layout = PlacedLayout {
        positions: &local,
        rest: Some(&local_rest),
        to_world: &to_world,
        faces,
        edges: &edges,
    };
    let target = DistanceTarget {
        mesh: &mesh,
        origin: DVec3::new(30.0, -5.0, 2.0),
        near: None,
        on_surface: 0.0,
    };
    let placed = placed_readout(layout, target).unwrap();
    let expected = layout_readout(&world, Some(&world_rest), faces, &edges).unwrap();
    assert_eq!(placed.layout, expected);
    assert!(expected.flipped.contains(&true) && expected.flipped.contains(&false));
    let framed: Vec<DVec3> = world.iter().map(|point| *point - target.origin).collect();
    assert_eq!(
        placed.distances,
        mesh.surface_distances(&framed, None, 0.0).unwrap()
    );
    // A rest shape not finite in the world is none; a rest shape or starts of another length are
    // refused.
    let mut stray = local_rest.clone();
    stray[3] = Vec3::NAN;
    let unmeasured = placed_readout(
        PlacedLayout {
            rest: Some(&stray),
            ..layout
        },
        target,
    )
    .unwrap();
    assert_eq!(
        unmeasured.layout,
        layout_readout(&world, None, faces, &edges).unwrap()
    );
    assert_eq!(unmeasured.distances, placed.distances);
    let short = PlacedLayout {
        rest: Some(&local_rest[1..]),
        ..layout
    };
    let no_starts = DistanceTarget {
        near: Some(&[0]),
        ..target
    };
    for outcome in [
        placed_readout(short, target),
        placed_readout(layout, no_starts),
    ] {
        assert!(matches!(outcome, Err(KernelError::LengthMismatch { .. })));
    }
}
