use super::*;

/// A closed chain of `n` vertices with edge terms and second differences, vertex 0 fixed at
/// the origin.
fn chain(n: u32) -> (Stencils, Vec<Option<DVec3>>) {
    let mut stencils = Stencils::new();
    for vertex in 0..n {
        let next = (vertex + 1) % n;
        let after = (vertex + 2) % n;
        stencils.push([(next, 1.0), (vertex, -1.0)], 1.0);
        stencils.push([(vertex, 1.0), (after, 1.0), (next, -2.0)], 0.5);
    }
    let mut fixed = vec![None; n as usize];
    fixed[0] = Some(DVec3::new(0.5, -1.0, 2.0));
    (stencils, fixed)
}

fn right_hand_side(rows: usize) -> Vec<DVec3> {
    (0..rows)
        .map(|row| {
            let t = row as f64;
            DVec3::new(t.sin(), (0.3 * t).cos(), 0.1 * t)
        })
        .collect()
}

/// The chain's system (with a factor allowed), its rows and a right-hand side.
fn chain_system(n: u32) -> (LinearSystem, usize, Vec<DVec3>) {
    let (stencils, fixed) = chain(n);
    let system = LinearSystem::new(&stencils, n as usize, &fixed, usize::MAX).unwrap();
    let rows = system.rows();
    (system, rows, right_hand_side(rows))
}

#[test]
fn a_solve_preconditioned_by_an_older_factor_matches_a_fresh_factor() {
    let (mut system, rows, b) = chain_system(60);
    let old: Vec<f64> = (0..rows).map(|row| 1.0 + (row % 3) as f64).collect();
    let new: Vec<f64> = (0..rows)
        .map(|row| {
            if row % 7 == 0 {
                0.0
            } else {
                1.2 + (row % 3) as f64
            }
        })
        .collect();
    system.factor(&old).unwrap();
    let (iterative, iterations, converged) = system
        .solve_preconditioned(
            &new,
            &b,
            &vec![DVec3::ZERO; rows],
            residual_only(1e-10),
            200,
        )
        .unwrap();
    assert!(converged);
    assert!(iterations > 0);
    system.factor(&new).unwrap();
    let direct = system.solve(&b).unwrap();
    for (a, b) in iterative.iter().zip(&direct) {
        assert!(a.distance(*b) < 1e-7, "{a} against {b}");
    }
    // From the answer itself it takes no iteration.
    let (_, iterations, converged) = system
        .solve_preconditioned(&new, &b, &direct, residual_only(1e-8), 5)
        .unwrap();
    assert!(converged);
    assert_eq!(iterations, 0);
}

#[test]
fn a_preconditioned_solve_that_does_not_converge_says_so() {
    let (mut system, rows, b) = chain_system(60);
    system.factor(&vec![100.0; rows]).unwrap();
    let (_, iterations, converged) = system
        .solve_preconditioned(
            &vec![0.0; rows],
            &b,
            &vec![DVec3::ZERO; rows],
            residual_only(1e-12),
            1,
        )
        .unwrap();
    assert_eq!((iterations, converged), (1, false));
}

#[test]
fn a_failed_factorization_leaves_nothing_to_solve_with() {
    let (mut system, rows, b) = chain_system(30);
    assert!(system.solve(&b).is_err(), "nothing factored yet");
    system.factor(&vec![1.0; rows]).unwrap();
    let first = system.solve(&b).unwrap();
    // Not positive definite: refused, and the earlier factor is not silently used.
    assert!(system.factor(&vec![-1e6; rows]).is_err());
    assert!(system.solve(&b).is_err());
    // Factoring again with the first diagonal gives the first answer.
    system.factor(&vec![1.0; rows]).unwrap();
    assert_eq!(system.solve(&b).unwrap(), first);
}

/// Tolerances on the residual alone.
fn residual_only(residual: f64) -> Tolerances {
    Tolerances {
        residual,
        step: 0.0,
        position: 0.0,
    }
}

/// A diagonal of one value per row, varied by `(row % 3) · spread`.
fn varied(rows: usize, base: f64, spread: f64) -> Vec<f64> {
    (0..rows)
        .map(|row| base + (row % 3) as f64 * spread)
        .collect()
}

#[test]
fn the_reuse_policy_factors_once_for_small_changes_and_again_for_large_ones() {
    let (mut system, rows, b) = chain_system(200);
    let zero = vec![DVec3::ZERO; rows];
    let first = system
        .solve_reusing(&varied(rows, 1.0, 0.1), &b, &zero, 0.0)
        .unwrap();
    assert_eq!(system.statistics().factorizations, 1);
    // A small change of the diagonal: iterations with the old factor, close to the exact answer.
    let changed = varied(rows, 1.1, 0.1);
    let reused = system.solve_reusing(&changed, &b, &first, 0.0).unwrap();
    let statistics = system.statistics();
    assert_eq!((statistics.solves, statistics.factorizations), (2, 1));
    assert!(statistics.iterations > 0);
    let mut exact = system.clone();
    exact.factor(&changed).unwrap();
    let exact = exact.solve(&b).unwrap();
    let scale = exact.iter().map(|x| x.length()).fold(0.0, f64::max);
    for (a, b) in reused.iter().zip(&exact) {
        assert!(a.distance(*b) < 1e-4 * scale, "{a} against {b}");
    }
    // Every row's diagonal ten times larger: factored anew without iterating.
    let iterations = system.statistics().iterations;
    let answer = system
        .solve_reusing(&varied(rows, 10.0, 1.0), &b, &reused, 0.0)
        .unwrap();
    assert_eq!(system.statistics().factorizations, 2);
    assert_eq!(system.statistics().iterations, iterations);
    assert!(answer.iter().all(|x| x.is_finite()));
}

#[test]
fn without_a_factor_multigrid_preconditioned_iterations_solve_the_system() {
    let (stencils, fixed) = chain(60);
    let mut direct = LinearSystem::new(&stencils, 60, &fixed, usize::MAX).unwrap();
    let mut iterative = LinearSystem::new(&stencils, 60, &fixed, 0).unwrap();
    assert!(direct.is_direct() && !iterative.is_direct());
    assert_eq!(iterative.factor_bytes(), 0);
    let rows = direct.rows();
    let b = right_hand_side(rows);
    let extra = varied(rows, 0.5, 0.25);
    direct.factor(&extra).unwrap();
    let exact = direct.solve(&b).unwrap();
    assert!(iterative.factor(&extra).is_err(), "no factor to make");
    let (solution, iterations, converged) = iterative
        .solve_preconditioned(
            &extra,
            &b,
            &vec![DVec3::ZERO; rows],
            residual_only(1e-12),
            500,
        )
        .unwrap();
    // A system this small is its multigrid's only level, factored: one iteration solves it.
    assert!(converged && iterations >= 1);
    for (a, b) in solution.iter().zip(&exact) {
        assert!(a.distance(*b) < 1e-8, "{a} against {b}");
    }
    // The policy's solve gets close from the start too.
    let answer = iterative.solve_reusing(&extra, &b, &exact, 0.0).unwrap();
    for (a, b) in answer.iter().zip(&exact) {
        assert!(a.distance(*b) < 1e-8, "{a} against {b}");
    }
    assert_eq!(iterative.statistics().factorizations, 0);
}

#[test]
fn the_prediction_extrapolates_the_rate_so_far_on_the_slowest_axis() {
    // x: 1 to 1e-3 in 3 iterations, 1e-9 wanted: 3 more at that rate, 6 in all; y: already
    // there (ignored); z: no progress (never).
    let start = DVec3::new(1.0, 1.0, 1.0);
    let target = DVec3::new(1e-9, 1e-2, 1e-9);
    let x_only = predicted_iterations((start, DVec3::new(1e-3, 1e-3, 1e-12), target), 3);
    assert!((x_only - 9.0).abs() < 1e-9, "{x_only}");
    let stalled = predicted_iterations((start, DVec3::new(1e-3, 1e-3, 1.0), target), 3);
    assert!(stalled.is_infinite());
    // Every axis converged: nothing more.
    assert_eq!(
        predicted_iterations((start, DVec3::splat(1e-12), target), 3),
        3.0
    );
}

/// The chain's system factored at an extra diagonal of 1, then solved with the reuse policy
/// at `changed(row)`: the solve's statistics, its answer and the new diagonal's exact answer.
fn reuse_after(changed: impl Fn(usize) -> f64) -> (SolveStatistics, Vec<DVec3>, Vec<DVec3>) {
    let (mut system, rows, b) = chain_system(400);
    let zero = vec![DVec3::ZERO; rows];
    let first = system
        .solve_reusing(&vec![1.0; rows], &b, &zero, 0.0)
        .unwrap();
    assert_eq!(system.iteration_budget, 4, "the chain's budget");
    let changed: Vec<f64> = (0..rows).map(changed).collect();
    let answer = system.solve_reusing(&changed, &b, &first, 0.0).unwrap();
    let statistics = system.statistics();
    system.factor(&changed).unwrap();
    (statistics, answer, system.solve(&b).unwrap())
}

/// An irregular number in [0, 1) per row.
fn scattered(row: usize) -> f64 {
    ((row * 7919 + 13) % 101) as f64 / 101.0
}

#[test]
fn a_solve_foreseen_not_to_converge_within_the_budget_factors_before_spending_it() {
    // A fifth of the rows (too few to factor at once) up to a thousand times stiffer, at
    // irregular places: preconditioned by the old factor, the iterations would take 15.
    let (statistics, answer, exact) = reuse_after(|row| {
        let share = scattered(row);
        if share < 0.2 {
            1.0 + 5000.0 * share
        } else {
            1.0
        }
    });
    assert_eq!(statistics.factorizations, 2);
    assert_eq!(statistics.iterations, PREDICTION_START);
    // The answer is the new factor's.
    assert_eq!(answer, exact);
    // Every row a little stiffer: the iterations converge within the budget, at its last one;
    // the prediction does not give them up.
    let (statistics, answer, exact) = reuse_after(|row| 1.0 + 0.9 * scattered(row));
    assert_eq!((statistics.factorizations, statistics.iterations), (1, 4));
    let scale = exact.iter().map(|x| x.length()).fold(0.0, f64::max);
    for (a, b) in answer.iter().zip(&exact) {
        assert!(a.distance(*b) < 1e-4 * scale, "{a} against {b}");
    }
}
