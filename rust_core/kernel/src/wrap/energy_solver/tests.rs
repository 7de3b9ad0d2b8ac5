use super::*;
use crate::mesh::TargetMeshOptions;

/// A flat target (z = 0, [-1, 1]², 20 x 20 cells) and an `n` x `n` quad grid layout of cell
/// `size` at height `height`, lower corner at (-n size / 2, -n size / 2).
fn plane_and_grid(n: u32, size: f32, height: f32) -> (Arc<TargetMesh>, LayoutStructure, Vec<Vec3>) {
    let cells = 20u32;
    let row = cells + 1;
    let vertices = (0..row * row)
        .map(|index| {
            Vec3::new(
                (index % row) as f32 / cells as f32 * 2.0 - 1.0,
                (index / row) as f32 / cells as f32 * 2.0 - 1.0,
                0.0,
            )
        })
        .collect();
    let mut triangles = Vec::new();
    for y in 0..cells {
        for x in 0..cells {
            let a = y * row + x;
            triangles.push([a, a + 1, a + row + 1]);
            triangles.push([a, a + row + 1, a + row]);
        }
    }
    let target =
        Arc::new(TargetMesh::new(vertices, triangles, TargetMeshOptions::default()).unwrap());
    let layout_row = n + 1;
    let half = n as f32 * size * 0.5;
    let positions: Vec<Vec3> = (0..layout_row * layout_row)
        .map(|index| {
            Vec3::new(
                (index % layout_row) as f32 * size - half,
                (index / layout_row) as f32 * size - half,
                height,
            )
        })
        .collect();
    let mut corners = Vec::new();
    for y in 0..n {
        for x in 0..n {
            let a = y * layout_row + x;
            corners.extend([a, a + 1, a + layout_row + 1, a + layout_row]);
        }
    }
    let structure = LayoutStructure::new(
        positions.len(),
        &corners,
        &vec![4; (n * n) as usize],
        &[],
        &[],
    )
    .unwrap();
    (target, structure, positions)
}

fn solver(
    target: &Arc<TargetMesh>,
    structure: &LayoutStructure,
    positions: &[Vec3],
    rest: &[Vec3],
    anchors: &[Option<(AnchorTarget, Vec3)>],
) -> EnergySolver {
    let schedule = WrapSchedule::Local;
    solver_restarting(schedule, target, structure, positions, rest, anchors, false)
}

/// A solver following `schedule`, told whether it re-settles a region started again
/// (`EnergyInputs::region_restart`).
fn solver_restarting(
    schedule: WrapSchedule,
    target: &Arc<TargetMesh>,
    structure: &LayoutStructure,
    positions: &[Vec3],
    rest: &[Vec3],
    anchors: &[Option<(AnchorTarget, Vec3)>],
    region_restart: bool,
) -> EnergySolver {
    let points: Vec<LayoutPoint> = positions.iter().map(|&p| LayoutPoint::Space(p)).collect();
    EnergySolver::new(&EnergyInputs {
        target,
        structure,
        rest,
        positions,
        anchor_of_vertex: anchors,
        soft_pairs: &[],
        curve_target_of_vertex: &[],
        unreliable: &[],
        stiffness: &[],
        free: &[],
        points: &points,
        plane: None,
        on_plane: &[],
        plane_slide: true,
        mean_edge_length: 0.1,
        landing_distance: 0.025,
        settings: WrapSettings {
            schedule,
            ..WrapSettings::default()
        },
        profile: None,
        settled_start: false,
        region_restart,
    })
    .unwrap()
}

#[test]
fn the_global_step_zeroes_the_energys_gradient_by_finite_differences() {
    let (target, structure, rest) = plane_and_grid(6, 0.1, 0.05);
    // Start bent and shifted away from the rest shape, with one anchor, so that every term
    // (edges, lines, umbrellas at the corners' neighbours, data, fixed columns) is active.
    let positions: Vec<Vec3> = rest
        .iter()
        .map(|p| *p + Vec3::new(0.02 * (p.y * 9.0).sin(), 0.01, 0.1 * p.x * p.x))
        .collect();
    let mut anchors = vec![None; rest.len()];
    let anchor_position = Vec3::new(0.05, 0.0, 0.0);
    let hit = target.closest_point(anchor_position, 1.0).unwrap();
    anchors[24] = Some((AnchorTarget::Face(hit.face_point), hit.position));
    let mut solver = solver(&target, &structure, &positions, &rest, &anchors);
    solver.smooth_scales(Some(2)).unwrap();
    let normals = solver.layout_normals(&solver.positions);
    let correspondences = solver.correspondences(&normals, 0.2, NEVER).unwrap();
    assert!(correspondences.iter().filter(|c| c.is_some()).count() > 30);
    let data_weight = 3.0;
    let solution = solver
        .global_solve(&correspondences, data_weight, NEVER)
        .unwrap();
    let previous = solver.positions.clone();
    let energy =
        |positions: &[Vec3]| solver.energy_at(positions, &correspondences, data_weight, &previous);
    let gradient_norm = |at: &[Vec3]| {
        let step = 1e-3f32;
        let mut norm = 0.0f64;
        for vertex in 0..at.len() {
            if solver.fixed[vertex].is_some() {
                continue;
            }
            for axis in 0..3 {
                let mut plus = at.to_vec();
                let mut minus = at.to_vec();
                plus[vertex][axis] += step;
                minus[vertex][axis] -= step;
                let derivative = (energy(&plus) - energy(&minus)) / (2.0 * f64::from(step));
                norm += derivative * derivative;
            }
        }
        norm.sqrt()
    };
    let at_start = gradient_norm(&previous);
    let at_solution = gradient_norm(&solution);
    assert!(at_start > 0.1, "{at_start}");
    assert!(
        at_solution < at_start * 1e-3,
        "gradient {at_solution} at the solution, {at_start} at the start"
    );
    assert!(energy(&solution) < energy(&previous));
    assert_eq!(solution[24], hit.position, "the anchor is met exactly");
}

#[test]
fn the_safeguard_backs_off_exactly_the_steps_that_turn_a_corner() {
    let (target, structure, rest) = plane_and_grid(6, 0.1, 0.05);
    let solver = solver(&target, &structure, &rest, &rest, &vec![None; rest.len()]);
    // Every point moves down by 0.01; vertex 24 (interior) also jumps across its right-hand
    // neighbour, which turns its corners over.
    let mut proposed: Vec<Vec3> = rest.iter().map(|p| *p - Vec3::Z * 0.01).collect();
    proposed[24] += Vec3::new(0.25, 0.0, 0.0);
    let before = solver.corner_orientations(&rest);
    assert!(!solver.turned_corners(&before, &proposed).is_empty());
    let (accepted, held_back) = solver.safeguard(&proposed);
    assert!(solver.turned_corners(&before, &accepted).is_empty());
    assert!((1..=9).contains(&held_back), "{held_back}");
    let far_away = [0usize, 6, 42, 48];
    for vertex in far_away {
        assert_eq!(
            accepted[vertex], proposed[vertex],
            "vertex {vertex} far from the fold"
        );
    }
    assert_ne!(accepted[24], proposed[24]);
}

/// The safeguard as it reads: every round looks at every corner.
fn safeguard_looking_at_every_corner(solver: &EnergySolver, proposed: &[Vec3]) -> Vec<Vec3> {
    let before = solver.corner_orientations(&solver.positions);
    let mut fractions = vec![1.0f32; proposed.len()];
    let mut candidate = proposed.to_vec();
    for round in 0.. {
        let mut changed = false;
        for vertex in solver.turned_corners(&before, &candidate) {
            let vertex = vertex as usize;
            if solver.fixed[vertex].is_some() || fractions[vertex] == 0.0 {
                continue;
            }
            fractions[vertex] = if round >= BACKTRACK_HALVINGS {
                0.0
            } else {
                fractions[vertex] * 0.5
            };
            candidate[vertex] = solver.positions[vertex]
                + (proposed[vertex] - solver.positions[vertex]) * fractions[vertex];
            changed = true;
        }
        if !changed {
            return candidate;
        }
    }
    unreachable!()
}

#[test]
fn the_safeguard_shortens_the_same_steps_as_rounds_over_every_corner() {
    let (target, structure, rest) = plane_and_grid(30, 0.05, 0.05);
    // Every third vertex anchored where it is: a corner owned by an anchor turns only when a free
    // neighbour moves, and its own step cannot be shortened.
    let anchors: Vec<_> = (0..rest.len())
        .map(|vertex| {
            (vertex % 3 == 0).then_some((AnchorTarget::Space(rest[vertex]), rest[vertex]))
        })
        .collect();
    let solver = solver(&target, &structure, &rest, &rest, &anchors);
    // A few scattered vertices jump across their neighbours by different lengths (some need one
    // halving, some every one), the rest move down a little: few corners turn, so the later
    // rounds look only around them.
    let mut state = 7u32;
    let mut random = move || {
        state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        (state >> 8) as f32 / (1 << 24) as f32
    };
    let mut halvings_seen = 0;
    for trial in 0..40 {
        let mut proposed: Vec<Vec3> = rest.iter().map(|p| *p - Vec3::Z * 0.002).collect();
        for vertex in (0..rest.len()).step_by(3) {
            proposed[vertex] = rest[vertex];
        }
        for _ in 0..=(trial % 6) {
            let vertex = ((random() * rest.len() as f32) as usize / 3 * 3 + 1) % rest.len();
            let length = 0.02 + random() * 0.3;
            let angle = random() * std::f32::consts::TAU;
            let lift = (random() - 0.5) * 0.2;
            proposed[vertex] += Vec3::new(angle.cos() * length, angle.sin() * length, lift);
        }
        let before = solver.corner_orientations(&rest);
        assert!(!solver.turned_corners(&before, &proposed).is_empty());
        let (accepted, held_back) = solver.safeguard(&proposed);
        assert!(held_back * 8 < rest.len(), "{held_back}");
        let reference = safeguard_looking_at_every_corner(&solver, &proposed);
        assert_eq!(accepted, reference, "trial {trial}");
        halvings_seen += accepted
            .iter()
            .zip(&proposed)
            .filter(|(accepted, proposed)| accepted != proposed)
            .count();
        assert!(solver.turned_corners(&before, &accepted).is_empty());
    }
    assert!(halvings_seen > 40, "{halvings_seen}");
}

/// A strip of a grid (its last two columns) folded up about a grid line by 10 degrees a step
/// through the safeguard of a solver following `schedule`: the least corner alignment at the
/// end and the angle the strip turned by, in degrees.
fn folded_strip(schedule: WrapSchedule) -> (f32, f32) {
    let (target, structure, rest) = plane_and_grid(10, 0.1, 0.05);
    let none = vec![None; rest.len()];
    let mut solver = solver_restarting(schedule, &target, &structure, &rest, &rest, &none, false);
    let hinge = rest[8].x;
    for step in 1..=18 {
        let angle = (step as f32 * 10.0).to_radians();
        let turn = Quat::from_rotation_y(-angle);
        let proposed: Vec<Vec3> = rest
            .iter()
            .map(|&p| {
                if p.x > hinge + 1e-6 {
                    let arm = Vec3::new(p.x - hinge, p.y, p.z - rest[0].z);
                    let turned = turn * Vec3::new(arm.x, 0.0, arm.z);
                    Vec3::new(hinge + turned.x, p.y, rest[0].z + turned.z)
                } else {
                    p
                }
            })
            .collect();
        solver.fit_similarities(false);
        let (accepted, _) = solver.safeguard(&proposed);
        solver.positions = accepted;
    }
    solver.fit_similarities(false);
    let worst = solver
        .corner_orientations(&solver.positions)
        .into_iter()
        .fold(f32::INFINITY, f32::min);
    let arm = solver.positions[10] - solver.positions[8];
    (worst, arm.z.atan2(arm.x).to_degrees())
}

#[test]
fn a_region_cannot_roll_over_by_small_steps() {
    // Each step is small to the strip's own neighbourhood; the safeguard's frame is the whole
    // layout's, so the strip stops before its faces turn over.
    let (worst, angle) = folded_strip(WrapSchedule::Local);
    assert!(worst >= 0.0, "a corner turned to cosine {worst}");
    // The strip did fold up, as far as the safeguard let it: past 60 degrees, short of flat.
    assert!(
        (60.0..150.0).contains(&angle),
        "the strip turned by {angle} degrees"
    );
}

#[test]
fn the_global_to_local_schedule_lets_a_corner_turn_less() {
    let (worst, angle) = folded_strip(WrapSchedule::GlobalToLocal);
    assert!(
        worst >= GLOBAL_MIN_ALIGNMENT - 1e-4,
        "a corner turned to cosine {worst}"
    );
    let (_, local_angle) = folded_strip(WrapSchedule::Local);
    assert!(
        angle > 20.0 && angle < local_angle - 20.0,
        "the strip turned by {angle} degrees, {local_angle} in the local schedule"
    );
}

#[test]
fn a_landing_that_would_turn_a_corner_is_refused() {
    let (target, structure, rest) = plane_and_grid(6, 0.1, 0.0);
    // The layout hovers just above the plane, but vertex 24 dips below it past its right-hand
    // neighbour's column: landing it straight down would fold its quads.
    let mut positions: Vec<Vec3> = rest.iter().map(|p| *p + Vec3::Z * 0.01).collect();
    positions[24] = Vec3::new(positions[25].x + 0.03, positions[24].y, 0.2);
    let mut solver = solver(
        &target,
        &structure,
        &positions,
        &rest,
        &vec![None; rest.len()],
    );
    solver.landing_distance = 1.0;
    let before = solver.corner_orientations(&positions);
    let (points, landed) = solver.land();
    assert!(solver.turned_corners(&before, &solver.positions).is_empty());
    // Vertex 24 stays up, and at most one neighbour whose quad it would fold; the others,
    // refused with it at first (their corners turn when all land at once), land one by one
    // afterwards (43 landed without that second pass).
    assert!(landed >= points.len() - 2, "{landed}");
    assert!(
        matches!(points[24], LayoutPoint::Space(_)),
        "{:?}",
        points[24]
    );
    for (vertex, point) in points.iter().enumerate() {
        if let LayoutPoint::Face(face_point) = point {
            assert_eq!(
                target.face_point_position(*face_point).unwrap(),
                solver.positions[vertex]
            );
        }
    }
}

#[test]
fn without_a_factor_the_wrap_ends_where_it_ends_with_one() {
    // A layout too large to factor is solved by multigrid-preconditioned iterations: on a small
    // grid above a plane (no factor allowed, a hierarchy of several levels), the same place as
    // with factors.
    let (target, structure, rest) = plane_and_grid(10, 0.1, 0.3);
    let mut anchors = vec![None; rest.len()];
    for corner in [0usize, 10, 110, 120] {
        let position = rest[corner] - Vec3::Z * 0.3;
        let hit = target.closest_point(position, 1.0).unwrap();
        anchors[corner] = Some((AnchorTarget::Face(hit.face_point), position));
    }
    let mut results = Vec::new();
    for limit in [MAX_FACTOR_BYTES, 0] {
        let mut wrap = solver(&target, &structure, &rest, &rest, &anchors);
        wrap.system = LinearSystem::new(&wrap.stencils, rest.len(), &wrap.fixed, limit).unwrap();
        assert_eq!(wrap.system.is_direct(), limit > 0);
        if limit == 0 {
            assert!(wrap.system.coarsen_to(12) >= 3);
        }
        while !wrap.iterate().unwrap().finished {}
        assert_eq!(wrap.system.statistics().factorizations > 0, limit > 0);
        results.push(wrap.positions.clone());
    }
    let largest = results[0]
        .iter()
        .zip(&results[1])
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, f32::max);
    assert!(largest < 1e-3, "{largest}");
    assert!(results[1].iter().all(|p| p.z.abs() < 1e-3), "on the plane");
}

#[test]
fn the_warm_up_carries_the_layout_with_its_anchors_as_rigidly_as_possible() {
    // Anchors far from the template (a posed limb): the corners of the grid, turned 70
    // degrees and shifted by three grid widths. Before any data term, the warm-up moves the
    // whole grid with them, with no step held back.
    let (target, structure, rest) = plane_and_grid(8, 0.1, 0.05);
    let motion = |p: Vec3| Quat::from_rotation_y(70f32.to_radians()) * p + Vec3::new(0.5, 0.3, 2.4);
    let mut anchors = vec![None; rest.len()];
    for vertex in [0, 8, 72, 80] {
        let position = motion(rest[vertex]);
        anchors[vertex] = Some((AnchorTarget::Space(position), position));
    }
    let mut solver = solver(&target, &structure, &rest, &rest, &anchors);
    let mut steps = 0;
    while solver.warming_up {
        let step = solver.iterate().unwrap();
        assert_eq!(step.held_back, 0);
        steps += 1;
    }
    assert!(steps <= WARMUP_MAX_ITERATIONS, "{steps}");
    for (vertex, position) in solver.positions.iter().enumerate() {
        let wanted = motion(rest[vertex]);
        assert!(
            position.distance(wanted) < 0.025,
            "vertex {vertex} at {position}, {wanted} wanted (edge 0.1)"
        );
    }
}

#[test]
fn without_a_factor_the_warm_up_runs_only_when_something_pulls_the_layout() {
    // With a factor the warm-up always runs; without one (a layout too large to factor), only
    // when a constraint moves the layout before the data term does.
    let (target, structure, rest) = plane_and_grid(6, 0.1, 0.2);
    let mut anchors = vec![None; rest.len()];
    let position = rest[0] - Vec3::Z * 0.2;
    let hit = target.closest_point(position, 1.0).unwrap();
    anchors[0] = Some((AnchorTarget::Face(hit.face_point), position));
    for (anchored, limit, warms_up) in [
        (false, MAX_FACTOR_BYTES, true),
        (false, 0, false),
        (true, 0, true),
    ] {
        let anchors = if anchored {
            anchors.clone()
        } else {
            vec![None; rest.len()]
        };
        let mut wrap = solver(&target, &structure, &rest, &rest, &anchors);
        assert!(wrap.warming_up);
        wrap.system = LinearSystem::new(&wrap.stencils, rest.len(), &wrap.fixed, limit).unwrap();
        assert_eq!(
            wrap.needs_warm_up(),
            warms_up,
            "anchored {anchored}, limit {limit}"
        );
    }
}

#[test]
fn the_global_to_local_pull_weakens_as_the_layout_faces_away_from_the_surface() {
    // A grid tilted 40 degrees over a plane: every point's pull onto the plane is the local
    // schedule's times cos 40° in the global-to-local schedule, and the same where the grid
    // lies flat (a quad in a crease is not turned onto a surface it does not face).
    let (target, structure, flat) = plane_and_grid(6, 0.1, 0.3);
    let tilt = Quat::from_rotation_y(40f32.to_radians());
    let tilted: Vec<Vec3> = flat
        .iter()
        .map(|&p| tilt * (p - Vec3::Z * 0.3) + Vec3::Z * 0.4)
        .collect();
    let none = vec![None; flat.len()];
    let weights = |schedule: WrapSchedule, positions: &[Vec3]| -> Vec<f32> {
        let mut wrap = solver_restarting(
            schedule, &target, &structure, positions, positions, &none, false,
        );
        let normals = wrap.layout_normals(positions);
        wrap.correspondences(&normals, 1.0, NEVER)
            .unwrap()
            .into_iter()
            .map(|correspondence| correspondence.map_or(0.0, |(weight, _)| weight))
            .collect()
    };
    for (positions, factor) in [(&tilted, 40f32.to_radians().cos()), (&flat, 1.0)] {
        let local = weights(WrapSchedule::Local, positions);
        let global = weights(WrapSchedule::GlobalToLocal, positions);
        for vertex in [16, 24, 32] {
            assert!(local[vertex] > 0.0, "vertex {vertex} is pulled");
            let ratio = global[vertex] / local[vertex];
            assert!(
                (ratio - factor).abs() < 1e-3,
                "vertex {vertex}: {ratio}, {factor} wanted"
            );
        }
    }
}

#[test]
fn a_level_ends_once_its_points_barely_move() {
    // A grid just above a plane lies on it after the first level: the later levels' iterations
    // move it by less than LEVEL_SETTLED_MOVE mean edges, so each of those levels ends after
    // one iteration, where the energy's decrease alone let them run on. The result stays where
    // the full run ends it.
    let (target, structure, rest) = plane_and_grid(10, 0.1, 0.02);
    let anchors = vec![None; rest.len()];
    let mut runs = Vec::new();
    for settled_move in [0.0, LEVEL_SETTLED_MOVE * 0.1] {
        let mut wrap = solver(&target, &structure, &rest, &rest, &anchors);
        assert_eq!(
            wrap.level_settled_move,
            LEVEL_SETTLED_MOVE * 0.1,
            "in mean edges"
        );
        wrap.level_settled_move = settled_move;
        let mut iterations = 0;
        // Levels ended by their first iteration: only a still one may end a level so early.
        let mut ended_first = 0;
        loop {
            let (warming_up, level, before) = (wrap.warming_up, wrap.level, wrap.level_iterations);
            let step = wrap.iterate().unwrap();
            iterations += 1;
            let ended = step.finished || wrap.level != level;
            if ended && !warming_up && before == 0 && wrap.levels[level].max_iterations > 1 {
                ended_first += 1;
            }
            if step.finished {
                break;
            }
        }
        runs.push((iterations, ended_first, wrap.positions.clone()));
    }
    let (full, stopped) = (&runs[0], &runs[1]);
    assert!(
        stopped.0 < full.0,
        "{} iterations, {} in full",
        stopped.0,
        full.0
    );
    assert_eq!(full.1, 0);
    assert!(
        stopped.1 >= 2,
        "{} levels ended by their first iteration",
        stopped.1
    );
    let largest = full
        .2
        .iter()
        .zip(&stopped.2)
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, f32::max);
    assert!(largest < 1e-3, "{largest} from the full run (edge 0.1)");
    assert!(stopped.2.iter().all(|p| p.z.abs() < 1e-3), "on the plane");
}

#[test]
fn a_region_restart_starts_the_global_to_local_schedule_at_its_second_level() {
    let (target, structure, rest) = plane_and_grid(6, 0.1, 0.05);
    let mut anchors = vec![None; rest.len()];
    let hit = target.closest_point(rest[0], 1.0).unwrap();
    anchors[0] = Some((AnchorTarget::Face(hit.face_point), hit.position));
    let level = |schedule, restart| {
        let mut solver = solver_restarting(
            schedule, &target, &structure, &rest, &rest, &anchors, restart,
        );
        while solver.warming_up {
            solver.iterate().unwrap();
        }
        solver.level
    };
    assert_eq!(level(WrapSchedule::GlobalToLocal, false), 0);
    assert_eq!(
        level(WrapSchedule::GlobalToLocal, true),
        RESTART_FIRST_LEVEL
    );
    // The local schedule has no stiff levels to leave out.
    assert_eq!(level(WrapSchedule::Local, true), 0);
}

#[test]
fn a_region_restart_keeps_a_held_back_point_without_its_data_term() {
    let (target, structure, rest) = plane_and_grid(6, 0.1, 0.05);
    let none = vec![None; rest.len()];
    let mut moved = rest.clone();
    moved[10].z += 0.01;
    // Kept in the global-to-local schedule's region restart alone.
    for (schedule, restart, kept) in [
        (WrapSchedule::GlobalToLocal, false, false),
        (WrapSchedule::GlobalToLocal, true, true),
        (WrapSchedule::Local, true, false),
    ] {
        let mut solver =
            solver_restarting(schedule, &target, &structure, &rest, &rest, &none, restart);
        // Vertex 10's step held back, then nothing held back.
        solver.note_held_back(&rest, &moved);
        assert!(solver.held_back[10]);
        assert_eq!(solver.held_back.iter().filter(|&&held| held).count(), 1);
        solver.note_held_back(&moved, &moved);
        assert_eq!(
            solver.held_back[10], kept,
            "{schedule:?}, region restart: {restart}"
        );
        // Its correspondence is dropped while it is marked.
        solver.warming_up = false;
        let step = solver.iterate().unwrap();
        assert!(step.energy.is_finite());
        assert_eq!(
            solver.held_back.iter().filter(|&&held| held).count() >= 1,
            kept
        );
    }
}
