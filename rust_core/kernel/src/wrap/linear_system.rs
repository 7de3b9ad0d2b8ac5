//! The energy wrap's global step: one sparse symmetric positive definite matrix shared by x, y
//! and z, factored by a sparse Cholesky (faer).
//!
//! Every quadratic term of the energy is a *stencil*: a few `(vertex, coefficient)` pairs and a
//! weight, asking `Σ coefficient · x_vertex` to equal a target vector. The normal equations of the
//! sum of such terms are `A x = b` with `A = Σ weight · s sᵀ` — the same for the three coordinates,
//! so one factorization serves three right-hand sides. Vertices with a fixed position (anchors,
//! curve targets) are eliminated: their columns move to the right-hand side.
//!
//! The pattern of `A` depends only on the layout's connectivity and the fixed set: its symbolic
//! analysis (ordering, elimination tree) is done once per wrap. Only the diagonal changes between
//! iterations (the data term's per-vertex weights), so the factor of an earlier diagonal stays a
//! good preconditioner: [`LinearSystem::solve_reusing`] solves by conjugate gradients
//! preconditioned with it, warm-started at the current positions, and factors anew only when the
//! diagonal has moved too far for that to pay (predicted from how many rows changed a lot, or
//! foreseen from the rate of the first few iterations, or seen when they stall). A
//! factorization costs as much as a number of iterations that grows with the layout (estimated
//! from the factor's structure); when the factor would take more
//! memory than allowed (a few million layout points), there is no factor at all and the
//! conjugate gradients are preconditioned by an aggregation multigrid cycle (`multigrid.rs`).

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::SymbolicCholeskyRaw;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, LltRef, SymbolicCholesky, SymmetricOrdering,
    factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMat, SparseColMatRef, SymbolicSparseColMat};
use faer::{Conj, Mat, Side, get_global_parallelism};
use glam::DVec3;

use super::ordered_sum::{PIECE, add_in_order, ordered_sum};
use rayon::prelude::*;
use std::sync::Arc;

use super::multigrid::{COARSEST_ROWS, FullRows, Multigrid};
use super::system_assembly::{assemble, fixed_right_hand_side};
use crate::cancel::{NEVER, Stop, check};
use crate::error::KernelError;

/// The quadratic terms of an energy, in CSR form: term `t` asks
/// `Σ_k coefficients[k] · x[vertices[k]]` (over `offsets[t]..offsets[t + 1]`) to equal its target,
/// with weight `weights[t]`.
#[derive(Debug, Clone, Default)]
pub struct Stencils {
    /// Start of each term's entries; one more than there are terms.
    pub offsets: Vec<u32>,
    /// The vertex of each entry.
    pub vertices: Vec<u32>,
    /// The coefficient of each entry.
    pub coefficients: Vec<f64>,
    /// The weight of each term.
    pub weights: Vec<f64>,
}

impl Stencils {
    /// No terms.
    #[must_use]
    pub fn new() -> Self {
        Self {
            offsets: vec![0],
            ..Self::default()
        }
    }

    /// Adds a term with these entries and weight.
    pub fn push(&mut self, entries: impl IntoIterator<Item = (u32, f64)>, weight: f64) {
        for (vertex, coefficient) in entries {
            self.vertices.push(vertex);
            self.coefficients.push(coefficient);
        }
        self.offsets.push(self.vertices.len() as u32);
        self.weights.push(weight);
    }

    /// Number of terms.
    #[must_use]
    pub fn len(&self) -> usize {
        self.weights.len()
    }

    /// Whether there is no term.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.weights.is_empty()
    }

    /// The entries of term `term`.
    pub fn entries(&self, term: usize) -> impl Iterator<Item = (u32, f64)> + '_ {
        let range = self.offsets[term] as usize..self.offsets[term + 1] as usize;
        self.vertices[range.clone()]
            .iter()
            .copied()
            .zip(self.coefficients[range].iter().copied())
    }

    /// `Σ coefficient · x` of term `term` at `positions`.
    #[must_use]
    pub fn apply(&self, term: usize, positions: &[DVec3]) -> DVec3 {
        self.entries(term)
            .map(|(vertex, coefficient)| positions[vertex as usize] * coefficient)
            .sum()
    }
}

/// How the global step's solves went: for the benchmarks and the tests.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SolveStatistics {
    /// Solves asked for.
    pub solves: usize,
    /// Numeric factorizations made.
    pub factorizations: usize,
    /// Preconditioned conjugate-gradient iterations made.
    pub iterations: usize,
}

/// When a conjugate-gradient solve stops: whichever is met first.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tolerances {
    /// The residual of every axis within this fraction of the right-hand side's norm.
    pub residual: f64,
    /// The preconditioned residual's norm within this fraction of the start's.
    pub step: f64,
    /// The correction the preconditioner estimates, its root mean square over the rows
    /// (weighted by the diagonal), within this length (in model units).
    pub position: f64,
}

/// Relative residual (per axis, against the right-hand side) at which a solve is exact enough.
const RESIDUAL_TOLERANCE: f64 = 1e-7;
/// A warm-started solve also stops once the preconditioned residual has fallen to this fraction of
/// its value at the start: the step from the current positions is then known to about this
/// fraction of its length (in the energy's norm), far below what the next iteration changes.
const STEP_TOLERANCE: f64 = 1e-4;
/// When more than this fraction of the rows changed their extra diagonal by more than
/// [`OUTLIER_FACTOR`] (up or down) since the last factorization (a new stiffness level), the
/// system is factored anew without trying the old factor (measured on the body: such solves
/// never converged within the budget).
const OUTLIER_FACTOR: f64 = 2.0;
const OUTLIER_SHARE: f64 = 0.25;
/// Bounds of the iteration budget a factorization is worth.
const BUDGET_BOUNDS: (usize, usize) = (4, 60);
/// Without a factor: the most multigrid-preconditioned iterations of one solve (the step is then
/// taken as far as they got: each lowers the energy).
const MULTIGRID_ITERATIONS: usize = 60;
/// Layouts with more free rows than this are not analysed for a factorization at all (the
/// analysis alone would take seconds and gigabytes); their factor would pass any memory limit.
pub(crate) const MAX_DIRECT_ROWS: usize = 1_500_000;

/// What a cancelled wrap step reports as stopped.
pub(crate) const WRAP_STEP: &str = "wrap step";

/// `A = Σ weight · s sᵀ` over the free vertices, with its factor-reuse policy.
pub struct LinearSystem {
    /// Per layout vertex, its row in the system, or `None` when its position is fixed.
    row_of_vertex: Vec<Option<u32>>,
    /// Per row, the layout vertex.
    vertex_of_row: Vec<u32>,
    /// The stencils' part of `A` (lower triangle, CSC, each column's diagonal first).
    matrix: SparseColMat<usize, f64>,
    /// Index of each row's diagonal entry in the matrix's values.
    diagonal: Vec<usize>,
    /// The factor's pattern (fill-reducing ordering, supernodes), analysed once; `None` when the
    /// factor would take too much memory (solves are then multigrid-preconditioned).
    symbolic: Option<Arc<SymbolicCholesky<usize>>>,
    /// Without a factor: the multigrid hierarchy preconditioning the conjugate gradients.
    multigrid: Option<Multigrid>,
    /// With a factor: the matrix in both triangles, for products on every core (without, the
    /// multigrid's finest level is the same).
    full_rows: Option<FullRows>,
    /// The right-hand side's part from the fixed vertices: `-Σ weight · s_a s_b x_b` per free `a`.
    fixed_right_hand_side: Vec<DVec3>,
    /// The factor's values, allocated at the first factorization and reused by the next ones;
    /// empty until then.
    factor: Vec<f64>,
    /// The extra diagonal of the last factorization.
    factored_diagonal: Vec<f64>,
    /// How many preconditioned iterations cost about one factorization.
    iteration_budget: usize,
    statistics: SolveStatistics,
    /// Without a factor: the last solve's correction of its start (the next solve searches
    /// along it first); empty before.
    last_correction: Vec<DVec3>,
}

impl std::fmt::Debug for LinearSystem {
    fn fmt(&self, formatter: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        formatter
            .debug_struct("LinearSystem")
            .field("rows", &self.vertex_of_row.len())
            .field("nonzeros", &self.matrix.val().len())
            .field("factor_bytes", &self.factor_bytes())
            .field("iteration_budget", &self.iteration_budget)
            .finish_non_exhaustive()
    }
}

impl Clone for LinearSystem {
    fn clone(&self) -> Self {
        Self {
            row_of_vertex: self.row_of_vertex.clone(),
            vertex_of_row: self.vertex_of_row.clone(),
            matrix: self.matrix.clone(),
            diagonal: self.diagonal.clone(),
            symbolic: self.symbolic.clone(),
            multigrid: self.multigrid.clone(),
            full_rows: self.full_rows.clone(),
            fixed_right_hand_side: self.fixed_right_hand_side.clone(),
            factor: self.factor.clone(),
            factored_diagonal: self.factored_diagonal.clone(),
            iteration_budget: self.iteration_budget,
            statistics: self.statistics,
            last_correction: self.last_correction.clone(),
        }
    }
}

/// Per axis, the Euclidean norm of a column of `values`.
fn column_norms(values: &[DVec3]) -> DVec3 {
    column_dots(values, values).map(f64::sqrt)
}

/// Per axis, the dot product of the columns of `a` and `b`.
fn column_dots(a: &[DVec3], b: &[DVec3]) -> DVec3 {
    ordered_sum(a.len().min(b.len()), |row| a[row] * b[row])
}

fn solver_error(reason: impl std::fmt::Display) -> KernelError {
    KernelError::InvalidArgument {
        name: "wrap",
        reason: format!("the global step's linear system failed: {reason}"),
    }
}

/// Iterations after which a budgeted solve predicts whether it will converge.
const PREDICTION_START: usize = 3;

/// The iterations a solve would take in all, at the rate its preconditioned residual (`alignment`,
/// per axis) fell so far: from `start` to `now` in `done` iterations, down to `target`.
fn predicted_iterations((start, now, target): (DVec3, DVec3, DVec3), done: usize) -> f64 {
    (0..3)
        .filter(|&axis| now[axis] > target[axis])
        .map(|axis| {
            let rate = (now[axis] / start[axis]).ln() / done as f64;
            if rate < 0.0 {
                done as f64 + (target[axis] / now[axis]).ln() / rate
            } else {
                f64::INFINITY
            }
        })
        .fold(done as f64, f64::max)
}

/// The floating-point operations of a numeric factorization with this structure.
fn factorization_flops(symbolic: &SymbolicCholesky<usize>) -> f64 {
    match symbolic.raw() {
        SymbolicCholeskyRaw::Supernodal(supernodal) => {
            let begin = supernodal.supernode_begin();
            let end = supernodal.supernode_end();
            let values = supernodal.col_ptr_for_val();
            (0..supernodal.n_supernodes())
                .map(|node| {
                    let columns = (end[node] - begin[node]).max(1) as f64;
                    let length = (values[node + 1] - values[node]) as f64;
                    // A block of `rows` x `columns`: its update of the rows below costs
                    // about columns · rows².
                    length * (length / columns)
                })
                .sum()
        }
        SymbolicCholeskyRaw::Simplicial(simplicial) => {
            let pointers = simplicial.col_ptr();
            pointers
                .windows(2)
                .map(|pair| ((pair[1] - pair[0]) as f64).powi(2))
                .sum()
        }
    }
}

impl LinearSystem {
    /// Assembles the system of `stencils` over `vertex_count` vertices, `fixed[v]` giving the
    /// position of each fixed vertex, and analyses its pattern; a factor that would take more
    /// than `max_factor_bytes` is not planned (the solves are then iterative).
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] when the matrix cannot be built or analysed (out of
    /// memory).
    pub fn new(
        stencils: &Stencils,
        vertex_count: usize,
        fixed: &[Option<DVec3>],
        max_factor_bytes: usize,
    ) -> Result<Self, KernelError> {
        let mut row_of_vertex = vec![None; vertex_count];
        let mut vertex_of_row = Vec::new();
        for vertex in 0..vertex_count {
            if fixed[vertex].is_none() {
                row_of_vertex[vertex] = Some(vertex_of_row.len() as u32);
                vertex_of_row.push(vertex as u32);
            }
        }
        let rows = vertex_of_row.len();
        let assembled = assemble(stencils, &row_of_vertex, rows, fixed)?;
        let diagonal = assembled.column_pointers[..rows].to_vec();
        let symbolic_matrix = SymbolicSparseColMat::new_checked(
            rows,
            rows,
            assembled.column_pointers,
            None,
            assembled.row_indices,
        );
        let matrix = SparseColMat::new(symbolic_matrix, assembled.values);
        let mut symbolic = None;
        if rows <= MAX_DIRECT_ROWS {
            let analysed = factorize_symbolic_cholesky(
                matrix.symbolic(),
                Side::Lower,
                SymmetricOrdering::Amd,
                CholeskySymbolicParams::default(),
            )
            .map_err(|error| solver_error(format!("{error:?}")))?;
            if analysed
                .len_val()
                .saturating_mul(std::mem::size_of::<f64>())
                <= max_factor_bytes
            {
                symbolic = Some(Arc::new(analysed));
            }
        }
        let iteration_budget = symbolic.as_deref().map_or(0, |symbolic| {
            let solve = 2.0 * symbolic.len_val() as f64 + 2.0 * matrix.val().len() as f64;
            // Operations of a factorization over those of an iteration (three right-hand sides
            // through the factor and the matrix). On the body (13k rows) this says 10; measured:
            // factorization and solve 42 ms, an iteration about 5 ms (a shared machine).
            let ratio = factorization_flops(symbolic) / (3.0 * solve);
            (ratio.round() as usize).clamp(BUDGET_BOUNDS.0, BUDGET_BOUNDS.1)
        });
        let full_rows = FullRows::from_lower(&matrix)?;
        let (multigrid, full_rows) = match symbolic {
            Some(_) => (None, Some(full_rows)),
            None => (Some(Multigrid::new(full_rows, COARSEST_ROWS)?), None),
        };
        Ok(Self {
            row_of_vertex,
            vertex_of_row,
            matrix,
            diagonal,
            symbolic,
            multigrid,
            full_rows,
            fixed_right_hand_side: assembled.fixed_right_hand_side,
            factor: Vec::new(),
            factored_diagonal: Vec::new(),
            iteration_budget,
            statistics: SolveStatistics::default(),
            last_correction: Vec::new(),
        })
    }

    /// Moves the fixed vertices to `fixed` (the same vertices fixed as when the system was made,
    /// at other places): only the right-hand side's fixed part changes; the matrix and its
    /// factor stay.
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] when another set of vertices is fixed, or out of memory.
    pub fn move_fixed(
        &mut self,
        stencils: &Stencils,
        fixed: &[Option<DVec3>],
    ) -> Result<(), KernelError> {
        let same = fixed.len() == self.row_of_vertex.len()
            && fixed
                .iter()
                .zip(&self.row_of_vertex)
                .all(|(fixed, row)| fixed.is_some() == row.is_none());
        if !same {
            return Err(solver_error(
                "another set of vertices is fixed: the system must be made anew",
            ));
        }
        self.fixed_right_hand_side =
            fixed_right_hand_side(stencils, &self.row_of_vertex, self.rows(), fixed)?;
        Ok(())
    }

    /// The memory a factorization takes, in bytes: the factor's values (known from the pattern's
    /// analysis, before anything is factored); 0 when the solves are iterative.
    #[must_use]
    pub fn factor_bytes(&self) -> usize {
        self.symbolic.as_ref().map_or(0, |symbolic| {
            symbolic
                .len_val()
                .saturating_mul(std::mem::size_of::<f64>())
        })
    }

    /// Whether the system is solved with a factor (else by multigrid-preconditioned iterations).
    #[must_use]
    pub fn is_direct(&self) -> bool {
        self.symbolic.is_some()
    }

    /// How the solves went so far.
    #[must_use]
    pub fn statistics(&self) -> SolveStatistics {
        self.statistics
    }

    /// Number of free vertices (rows).
    #[must_use]
    pub fn rows(&self) -> usize {
        self.vertex_of_row.len()
    }

    /// The row of `vertex`, or `None` when it is fixed.
    #[must_use]
    pub fn row_of(&self, vertex: u32) -> Option<u32> {
        self.row_of_vertex[vertex as usize]
    }

    /// Factors `A + diag(extra)` (`extra`: one non-negative value per row).
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] when the matrix is not positive definite, or when the
    /// system has no factor (too large).
    pub fn factor(&mut self, extra_diagonal: &[f64]) -> Result<(), KernelError> {
        let Some(symbolic) = self.symbolic.clone() else {
            return Err(solver_error("the system is too large to factor"));
        };
        let mut values = self.matrix.val().to_vec();
        for (&entry, &extra) in self.diagonal.iter().zip(extra_diagonal) {
            values[entry] += extra;
        }
        let matrix = SparseColMatRef::new(self.matrix.symbolic(), &values);
        let length = symbolic.len_val();
        if self.factor.len() != length {
            self.factor.clear();
            self.factor
                .try_reserve_exact(length)
                .map_err(|_| solver_error("out of memory for the factor"))?;
            self.factor.resize(length, 0.0);
        }
        let parallelism = get_global_parallelism();
        let mut scratch = MemBuffer::try_new(
            symbolic.factorize_numeric_llt_scratch::<f64>(parallelism, faer::Spec::default()),
        )
        .map_err(|_| solver_error("out of memory for the factorization's workspace"))?;
        self.statistics.factorizations += 1;
        let factored = symbolic.factorize_numeric_llt::<f64>(
            &mut self.factor,
            matrix,
            Side::Lower,
            LltRegularization::default(),
            parallelism,
            MemStack::new(&mut scratch),
            faer::Spec::default(),
        );
        if let Err(error) = factored {
            // A failed factorization leaves nothing to solve with.
            self.factor.clear();
            self.factored_diagonal.clear();
            return Err(solver_error(format!("{error:?}")));
        }
        self.factored_diagonal.clear();
        self.factored_diagonal.extend_from_slice(extra_diagonal);
        Ok(())
    }

    /// Solves with the last factorization, in place, the columns of `columns` (one per axis).
    fn solve_with_factor(&self, columns: &mut Mat<f64>) -> Result<(), KernelError> {
        let Some(symbolic) = self.symbolic.as_deref() else {
            return Err(solver_error("the system is too large to factor"));
        };
        if self.factor.is_empty() && self.rows() > 0 {
            return Err(solver_error("solved before it was factored"));
        }
        let parallelism = get_global_parallelism();
        let mut scratch = MemBuffer::try_new(
            symbolic.solve_in_place_scratch::<f64>(columns.ncols(), parallelism),
        )
        .map_err(|_| solver_error("out of memory for the solve's workspace"))?;
        LltRef::<usize, f64>::new(symbolic, &self.factor).solve_in_place_with_conj(
            Conj::No,
            columns.as_mut(),
            parallelism,
            MemStack::new(&mut scratch),
        );
        Ok(())
    }

    /// `b` plus the fixed vertices' part, per row.
    fn full_right_hand_side(&self, right_hand_side: &[DVec3]) -> Vec<DVec3> {
        right_hand_side
            .iter()
            .zip(&self.fixed_right_hand_side)
            .map(|(b, fixed)| *b + *fixed)
            .collect()
    }

    /// The last factor applied to `values` (one per row).
    fn apply_factor(&self, values: &[DVec3]) -> Result<Vec<DVec3>, KernelError> {
        let rows = self.rows();
        let mut columns = Mat::<f64>::from_fn(rows, 3, |row, axis| values[row][axis]);
        self.solve_with_factor(&mut columns)?;
        Ok((0..rows)
            .map(|row| DVec3::new(columns[(row, 0)], columns[(row, 1)], columns[(row, 2)]))
            .collect())
    }

    /// Solves `(A + diag(extra)) x = b + fixed part` with the last factorization, `b` given per
    /// row; returns `x` per row.
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] when nothing was factored yet.
    pub fn solve(&self, right_hand_side: &[DVec3]) -> Result<Vec<DVec3>, KernelError> {
        self.apply_factor(&self.full_right_hand_side(right_hand_side))
    }

    /// Solves `(A + diag(extra)) x = b + fixed part`, warm-started at `start` (per row), with the
    /// reuse policy: conjugate gradients preconditioned by the last factorization when its
    /// diagonal is close enough to `extra` for that to cost less than a factorization (and they
    /// converge), else a new factorization; without a factor, multigrid-preconditioned iterations.
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] when a factorization fails.
    pub fn solve_reusing(
        &mut self,
        extra_diagonal: &[f64],
        right_hand_side: &[DVec3],
        start: &[DVec3],
        position_tolerance: f64,
    ) -> Result<Vec<DVec3>, KernelError> {
        self.solve_reusing_until(
            extra_diagonal,
            right_hand_side,
            start,
            position_tolerance,
            NEVER,
        )
    }

    /// [`LinearSystem::solve_reusing`], asking `stop` before a factorization and at every
    /// iteration of conjugate gradients.
    ///
    /// # Errors
    /// As [`LinearSystem::solve_reusing`]; [`KernelError::Cancelled`] once `stop` said true (the
    /// last factorization may be replaced already).
    pub fn solve_reusing_until(
        &mut self,
        extra_diagonal: &[f64],
        right_hand_side: &[DVec3],
        start: &[DVec3],
        position_tolerance: f64,
        stop: Stop<'_>,
    ) -> Result<Vec<DVec3>, KernelError> {
        self.statistics.solves += 1;
        let tolerances = Tolerances {
            residual: RESIDUAL_TOLERANCE,
            step: STEP_TOLERANCE,
            position: position_tolerance,
        };
        if !self.is_direct() {
            // The last solve's correction is searched along first: measured on a 1024² torus
            // grid wrap, 57 conjugate-gradient iterations in 15 solves instead of 77, the same
            // final energy.
            let mut last = std::mem::take(&mut self.last_correction);
            let hint = (last.len() == start.len()).then_some(last.as_slice());
            let (solution, _, _) = self.solve_preconditioned_until(
                extra_diagonal,
                right_hand_side,
                (start, hint),
                tolerances,
                (MULTIGRID_ITERATIONS, false),
                stop,
            )?;
            last.clear();
            last.extend(solution.iter().zip(start).map(|(x, s)| *x - *s));
            self.last_correction = last;
            return Ok(solution);
        }
        if !self.factor.is_empty()
            && self.outlying_rows(extra_diagonal) as f64 <= OUTLIER_SHARE * self.rows() as f64
        {
            let (solution, _, converged) = self.solve_preconditioned_until(
                extra_diagonal,
                right_hand_side,
                (start, None),
                tolerances,
                (self.iteration_budget, true),
                stop,
            )?;
            if converged {
                return Ok(solution);
            }
        }
        check(stop, WRAP_STEP)?;
        self.factor(extra_diagonal)?;
        self.solve(right_hand_side)
    }

    /// Rows whose extra diagonal differs from the last factorization's by more than
    /// [`OUTLIER_FACTOR`] (compared without the matrix's own diagonal: the shape terms hold
    /// smooth motions weakly, so a data weight small beside the diagonal still rules them).
    fn outlying_rows(&self, extra_diagonal: &[f64]) -> usize {
        extra_diagonal
            .iter()
            .zip(&self.factored_diagonal)
            .filter(|&(&new, &old)| !(old / OUTLIER_FACTOR..=old * OUTLIER_FACTOR).contains(&new))
            .count()
    }

    /// Solves `(A + diag(extra)) x = b + fixed part` by conjugate gradients from `start`,
    /// preconditioned with the last factorization (of `A + diag(extra')` for an earlier
    /// `extra'`), or by a multigrid cycle when there is no factor. Stops when `tolerances` are met or
    /// after `max_iterations`. Returns `x`, the iterations it took and whether it converged.
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] when the system has a factor but nothing was factored
    /// yet.
    pub fn solve_preconditioned(
        &mut self,
        extra_diagonal: &[f64],
        right_hand_side: &[DVec3],
        start: &[DVec3],
        tolerances: Tolerances,
        max_iterations: usize,
    ) -> Result<(Vec<DVec3>, usize, bool), KernelError> {
        self.solve_preconditioned_until(
            extra_diagonal,
            right_hand_side,
            (start, None),
            tolerances,
            (max_iterations, false),
            NEVER,
        )
    }

    /// [`LinearSystem::solve_preconditioned`], asking `stop` at every iteration; `start` also
    /// gives a direction to search along first. With `give_up`, the iterations stop (not
    /// converged) as soon as their rate so far says they would not converge within
    /// `max_iterations`.
    fn solve_preconditioned_until(
        &mut self,
        extra_diagonal: &[f64],
        right_hand_side: &[DVec3],
        (start, first_direction): (&[DVec3], Option<&[DVec3]>),
        tolerances: Tolerances,
        (max_iterations, give_up): (usize, bool),
        should_stop: Stop<'_>,
    ) -> Result<(Vec<DVec3>, usize, bool), KernelError> {
        let wanted = self.full_right_hand_side(right_hand_side);
        let target_norm = column_norms(&wanted) * tolerances.residual;
        let mut solution = start.to_vec();
        let product = self.multiply(extra_diagonal, &solution);
        let mut residual: Vec<DVec3> = wanted
            .iter()
            .zip(&product)
            .map(|(b, ax)| *b - *ax)
            .collect();
        let mut product = product;
        if let Some(direction) = first_direction {
            // The energy's minimum along `direction` first (per axis): one product more.
            let curvature = self.multiply_dot(extra_diagonal, direction, &mut product);
            let slope = column_dots(direction, &residual);
            let step = DVec3::select(curvature.cmpgt(DVec3::ZERO), slope / curvature, DVec3::ZERO);
            if step.is_finite() {
                for ((x, r), (d, ad)) in solution
                    .iter_mut()
                    .zip(residual.iter_mut())
                    .zip(direction.iter().zip(&product))
                {
                    *x += *d * step;
                    *r -= *ad * step;
                }
            }
        }
        let prepared = match &self.multigrid {
            Some(multigrid) => Some(multigrid.prepare(extra_diagonal)?),
            None => None,
        };
        let precondition = |residual: &[DVec3]| -> Result<Vec<DVec3>, KernelError> {
            match (&self.multigrid, &prepared) {
                (Some(multigrid), Some(prepared)) => Ok(multigrid.cycle(prepared, residual)),
                _ => self.apply_factor(residual),
            }
        };
        let mut preconditioned = precondition(&residual)?;
        let mut direction = preconditioned.clone();
        let mut alignment = column_dots(&residual, &preconditioned);
        let values = self.matrix.val();
        let diagonal_sum: f64 = self
            .diagonal
            .iter()
            .zip(extra_diagonal)
            .map(|(&entry, &extra)| values[entry] + extra)
            .sum();
        let target_alignment = (alignment * (tolerances.step * tolerances.step))
            .max(DVec3::splat(tolerances.position.powi(2) * diagonal_sum));
        let start_alignment = alignment;
        let mut iterations = 0;
        let mut converged = false;
        let mut norms = column_norms(&residual);
        let mut product = vec![DVec3::ZERO; residual.len()];
        loop {
            if norms.cmple(target_norm).all() || alignment.cmple(target_alignment).all() {
                converged = true;
                break;
            }
            if iterations == max_iterations
                || (give_up
                    && iterations >= PREDICTION_START
                    && predicted_iterations(
                        (start_alignment, alignment, target_alignment),
                        iterations,
                    ) > max_iterations as f64)
            {
                break;
            }
            check(should_stop, WRAP_STEP)?;
            let curvature = self.multiply_dot(extra_diagonal, &direction, &mut product);
            // An axis already solved (no residual) takes no step.
            let step = DVec3::select(
                curvature.cmpgt(DVec3::ZERO),
                alignment / curvature,
                DVec3::ZERO,
            );
            if !step.is_finite() {
                break;
            }
            iterations += 1;
            // The step, and the new residual's squared norms in the same pass.
            // Grouped in the fixed pieces of `ordered_sum`, so that a solve repeats to the bit.
            let pieces: Vec<DVec3> = solution
                .par_chunks_mut(PIECE)
                .zip(residual.par_chunks_mut(PIECE))
                .enumerate()
                .map(|(piece, (solution, residual))| {
                    let start = piece * PIECE;
                    solution
                        .iter_mut()
                        .zip(residual.iter_mut())
                        .enumerate()
                        .fold(DVec3::ZERO, |sum, (offset, (solution, residual))| {
                            *solution += direction[start + offset] * step;
                            *residual -= product[start + offset] * step;
                            sum + *residual * *residual
                        })
                })
                .collect();
            let squares = add_in_order(pieces);
            norms = squares.map(f64::sqrt);
            preconditioned = precondition(&residual)?;
            let next_alignment = column_dots(&residual, &preconditioned);
            let ratio = DVec3::select(
                alignment.cmpgt(DVec3::ZERO),
                next_alignment / alignment,
                DVec3::ZERO,
            );
            alignment = next_alignment;
            direction
                .par_iter_mut()
                .with_min_len(4096)
                .zip(&preconditioned)
                .for_each(|(direction, preconditioned)| {
                    *direction = *preconditioned + *direction * ratio;
                });
        }
        self.statistics.iterations += iterations;
        Ok((solution, iterations, converged))
    }

    /// The matrix in both triangles: the multigrid's finest level, or the direct system's copy.
    fn full_rows(&self) -> &FullRows {
        match (&self.multigrid, &self.full_rows) {
            (Some(multigrid), _) => multigrid.matrix(),
            (None, Some(full_rows)) => full_rows,
            (None, None) => {
                unreachable!("a system has its matrix in rows, with or without a factor")
            }
        }
    }

    /// `(A + diag(extra)) x` into `product`, and per axis the dot product of `x` and it.
    fn multiply_dot(&self, extra_diagonal: &[f64], x: &[DVec3], product: &mut [DVec3]) -> DVec3 {
        self.full_rows().multiply_dot(extra_diagonal, x, product)
    }

    /// `(A + diag(extra)) x`.
    fn multiply(&self, extra_diagonal: &[f64], x: &[DVec3]) -> Vec<DVec3> {
        self.full_rows().multiply(extra_diagonal, x)
    }

    /// Without a factor: rebuilds the multigrid hierarchy down to `coarsest_rows` (a system small
    /// enough to test has one level otherwise); returns its number of levels.
    #[cfg(test)]
    pub(crate) fn coarsen_to(&mut self, coarsest_rows: usize) -> usize {
        let multigrid = self.multigrid.take().expect("an iterative system");
        let rebuilt = Multigrid::new(multigrid.matrix().clone(), coarsest_rows).unwrap();
        let depth = rebuilt.depth();
        self.multigrid = Some(rebuilt);
        depth
    }

    /// The layout vertex of each row.
    #[must_use]
    pub fn vertex_of_row(&self) -> &[u32] {
        &self.vertex_of_row
    }
}

#[cfg(test)]
mod tests;
