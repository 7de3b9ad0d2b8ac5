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
//! iterations (the data term's per-vertex weights), so each iteration costs one numeric
//! factorization and one solve.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, LltRef, SymbolicCholesky, SymmetricOrdering,
    factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMat, SparseColMatRef, Triplet};
use faer::{Conj, Mat, Side, get_global_parallelism};
use glam::DVec3;
use std::sync::Arc;

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

/// `A = Σ weight · s sᵀ` over the free vertices, factored once per change of its diagonal.
pub struct LinearSystem {
    /// Per layout vertex, its row in the system, or `None` when its position is fixed.
    row_of_vertex: Vec<Option<u32>>,
    /// Per row, the layout vertex.
    vertex_of_row: Vec<u32>,
    /// The stencils' part of `A` (lower triangle, CSC).
    matrix: SparseColMat<usize, f64>,
    /// Index of each row's diagonal entry in the matrix's values.
    diagonal: Vec<usize>,
    /// The factor's pattern (fill-reducing ordering, supernodes), analysed once.
    symbolic: Arc<SymbolicCholesky<usize>>,
    /// The right-hand side's part from the fixed vertices: `-Σ weight · s_a s_b x_b` per free `a`.
    fixed_right_hand_side: Vec<DVec3>,
    /// The factor's values, allocated at the first factorization and reused by the next ones;
    /// empty until then.
    factor: Vec<f64>,
}

impl std::fmt::Debug for LinearSystem {
    fn fmt(&self, formatter: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        formatter
            .debug_struct("LinearSystem")
            .field("rows", &self.vertex_of_row.len())
            .field("nonzeros", &self.matrix.val().len())
            .field("factor_nonzeros", &self.symbolic.len_val())
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
            symbolic: Arc::clone(&self.symbolic),
            fixed_right_hand_side: self.fixed_right_hand_side.clone(),
            factor: self.factor.clone(),
        }
    }
}

/// Per axis, the Euclidean norm of a column of `values`.
fn column_norms(values: &[DVec3]) -> DVec3 {
    column_dots(values, values).map(f64::sqrt)
}

/// Per axis, the dot product of the columns of `a` and `b`.
fn column_dots(a: &[DVec3], b: &[DVec3]) -> DVec3 {
    a.iter().zip(b).map(|(a, b)| *a * *b).sum()
}

fn solver_error(reason: impl std::fmt::Display) -> KernelError {
    KernelError::InvalidArgument {
        name: "wrap",
        reason: format!("the global step's linear system failed: {reason}"),
    }
}

impl LinearSystem {
    /// Assembles the system of `stencils` over `vertex_count` vertices, `fixed[v]` giving the
    /// position of each fixed vertex, and analyses its pattern.
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] when the matrix cannot be built or analysed (out of
    /// memory).
    pub fn new(
        stencils: &Stencils,
        vertex_count: usize,
        fixed: &[Option<DVec3>],
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
        let mut triplets: Vec<Triplet<usize, usize, f64>> =
            (0..rows).map(|row| Triplet::new(row, row, 0.0)).collect();
        let mut fixed_right_hand_side = vec![DVec3::ZERO; rows];
        let mut entries: Vec<(u32, f64)> = Vec::new();
        for term in 0..stencils.len() {
            let weight = stencils.weights[term];
            entries.clear();
            entries.extend(stencils.entries(term));
            for &(vertex_a, coefficient_a) in &entries {
                let Some(row_a) = row_of_vertex[vertex_a as usize] else {
                    continue;
                };
                for &(vertex_b, coefficient_b) in &entries {
                    let value = weight * coefficient_a * coefficient_b;
                    match row_of_vertex[vertex_b as usize] {
                        Some(row_b) if row_b <= row_a => {
                            triplets.push(Triplet::new(row_a as usize, row_b as usize, value));
                        }
                        Some(_) => {}
                        None => {
                            let position = fixed[vertex_b as usize].unwrap_or(DVec3::ZERO);
                            fixed_right_hand_side[row_a as usize] -= position * value;
                        }
                    }
                }
            }
        }
        let matrix = SparseColMat::try_new_from_triplets(rows, rows, &triplets)
            .map_err(|error| solver_error(format!("{error:?}")))?;
        let column_pointers = matrix.symbolic().col_ptr();
        let row_indices = matrix.symbolic().row_idx();
        let diagonal = (0..rows)
            .map(|column| {
                (column_pointers[column]..column_pointers[column + 1])
                    .find(|&entry| row_indices[entry] == column)
                    .unwrap_or(usize::MAX)
            })
            .collect();
        let symbolic = factorize_symbolic_cholesky(
            matrix.symbolic(),
            Side::Lower,
            SymmetricOrdering::Amd,
            CholeskySymbolicParams::default(),
        )
        .map_err(|error| solver_error(format!("{error:?}")))?;
        Ok(Self {
            row_of_vertex,
            vertex_of_row,
            matrix,
            diagonal,
            symbolic: Arc::new(symbolic),
            fixed_right_hand_side,
            factor: Vec::new(),
        })
    }

    /// The memory a factorization takes, in bytes: the factor's values (known from the pattern's
    /// analysis, before anything is factored).
    #[must_use]
    pub fn factor_bytes(&self) -> usize {
        self.symbolic
            .len_val()
            .saturating_mul(std::mem::size_of::<f64>())
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
    /// [`KernelError::InvalidArgument`] when the matrix is not positive definite.
    pub fn factor(&mut self, extra_diagonal: &[f64]) -> Result<(), KernelError> {
        let mut values = self.matrix.val().to_vec();
        for (&entry, &extra) in self.diagonal.iter().zip(extra_diagonal) {
            values[entry] += extra;
        }
        let matrix = SparseColMatRef::new(self.matrix.symbolic(), &values);
        let length = self.symbolic.len_val();
        if self.factor.len() != length {
            self.factor.clear();
            self.factor
                .try_reserve_exact(length)
                .map_err(|_| solver_error("out of memory for the factor"))?;
            self.factor.resize(length, 0.0);
        }
        let parallelism = get_global_parallelism();
        let mut scratch = MemBuffer::try_new(
            self.symbolic
                .factorize_numeric_llt_scratch::<f64>(parallelism, faer::Spec::default()),
        )
        .map_err(|_| solver_error("out of memory for the factorization's workspace"))?;
        let factored = self.symbolic.factorize_numeric_llt::<f64>(
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
            return Err(solver_error(format!("{error:?}")));
        }
        Ok(())
    }

    /// Solves with the last factorization, in place, the columns of `columns` (one per axis).
    fn solve_with_factor(&self, columns: &mut Mat<f64>) -> Result<(), KernelError> {
        if self.factor.is_empty() && self.rows() > 0 {
            return Err(solver_error("solved before it was factored"));
        }
        let parallelism = get_global_parallelism();
        let mut scratch = MemBuffer::try_new(
            self.symbolic
                .solve_in_place_scratch::<f64>(columns.ncols(), parallelism),
        )
        .map_err(|_| solver_error("out of memory for the solve's workspace"))?;
        LltRef::<usize, f64>::new(&self.symbolic, &self.factor).solve_in_place_with_conj(
            Conj::No,
            columns.as_mut(),
            parallelism,
            MemStack::new(&mut scratch),
        );
        Ok(())
    }

    /// Solves `(A + diag(extra)) x = b + fixed part` with the last factorization, `b` given per
    /// row; returns `x` per row.
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] when nothing was factored yet.
    pub fn solve(&self, right_hand_side: &[DVec3]) -> Result<Vec<DVec3>, KernelError> {
        let rows = self.rows();
        let mut columns = Mat::<f64>::from_fn(rows, 3, |row, axis| {
            (right_hand_side[row] + self.fixed_right_hand_side[row])[axis]
        });
        self.solve_with_factor(&mut columns)?;
        Ok((0..rows)
            .map(|row| DVec3::new(columns[(row, 0)], columns[(row, 1)], columns[(row, 2)]))
            .collect())
    }

    /// Solves `(A + diag(extra)) x = b + fixed part` by conjugate gradients preconditioned with
    /// the last factorization (of `A + diag(extra')` for an earlier `extra'`), from `start`.
    /// Returns `None` when the relative residual of some axis is still above `tolerance` after
    /// `max_iterations` (the caller then factors anew), else `x` and the iterations it took.
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] when nothing was factored yet.
    pub fn solve_preconditioned(
        &self,
        extra_diagonal: &[f64],
        right_hand_side: &[DVec3],
        start: &[DVec3],
        tolerance: f64,
        max_iterations: usize,
    ) -> Result<Option<(Vec<DVec3>, usize)>, KernelError> {
        let rows = self.rows();
        let wanted: Vec<DVec3> = right_hand_side
            .iter()
            .zip(&self.fixed_right_hand_side)
            .map(|(b, fixed)| *b + *fixed)
            .collect();
        let target_norm = column_norms(&wanted) * tolerance;
        let mut solution = start.to_vec();
        let product = self.multiply(extra_diagonal, &solution);
        let mut residual: Vec<DVec3> = wanted
            .iter()
            .zip(&product)
            .map(|(b, ax)| *b - *ax)
            .collect();
        let precondition = |residual: &[DVec3]| -> Result<Vec<DVec3>, KernelError> {
            let mut columns = Mat::<f64>::from_fn(rows, 3, |row, axis| residual[row][axis]);
            self.solve_with_factor(&mut columns)?;
            Ok((0..rows)
                .map(|row| DVec3::new(columns[(row, 0)], columns[(row, 1)], columns[(row, 2)]))
                .collect())
        };
        let mut preconditioned = precondition(&residual)?;
        let mut direction = preconditioned.clone();
        let mut alignment = column_dots(&residual, &preconditioned);
        for iteration in 0..=max_iterations {
            let norms = column_norms(&residual);
            if norms.cmple(target_norm).all() {
                return Ok(Some((solution, iteration)));
            }
            if iteration == max_iterations {
                break;
            }
            let product = self.multiply(extra_diagonal, &direction);
            let curvature = column_dots(&direction, &product);
            let step = alignment / curvature;
            if !step.is_finite() {
                break;
            }
            for row in 0..rows {
                solution[row] += direction[row] * step;
                residual[row] -= product[row] * step;
            }
            preconditioned = precondition(&residual)?;
            let next_alignment = column_dots(&residual, &preconditioned);
            let ratio = next_alignment / alignment;
            alignment = next_alignment;
            for row in 0..rows {
                direction[row] = preconditioned[row] + direction[row] * ratio;
            }
        }
        Ok(None)
    }

    /// `(A + diag(extra)) x`, from the stored lower triangle.
    fn multiply(&self, extra_diagonal: &[f64], x: &[DVec3]) -> Vec<DVec3> {
        let mut product: Vec<DVec3> = x
            .iter()
            .zip(extra_diagonal)
            .map(|(x, extra)| *x * *extra)
            .collect();
        let column_pointers = self.matrix.symbolic().col_ptr();
        let row_indices = self.matrix.symbolic().row_idx();
        let values = self.matrix.val();
        for column in 0..self.rows() {
            for entry in column_pointers[column]..column_pointers[column + 1] {
                let row = row_indices[entry];
                let value = values[entry];
                product[row] += x[column] * value;
                if row != column {
                    product[column] += x[row] * value;
                }
            }
        }
        product
    }

    /// The layout vertex of each row.
    #[must_use]
    pub fn vertex_of_row(&self) -> &[u32] {
        &self.vertex_of_row
    }
}

#[cfg(test)]
mod tests {
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

    #[test]
    fn a_solve_preconditioned_by_an_older_factor_matches_a_fresh_factor() {
        let (stencils, fixed) = chain(60);
        let mut system = LinearSystem::new(&stencils, 60, &fixed).unwrap();
        let rows = system.rows();
        let b = right_hand_side(rows);
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
        let (iterative, iterations) = system
            .solve_preconditioned(&new, &b, &vec![DVec3::ZERO; rows], 1e-10, 200)
            .unwrap()
            .expect("converges");
        assert!(iterations > 0);
        system.factor(&new).unwrap();
        let direct = system.solve(&b).unwrap();
        for (a, b) in iterative.iter().zip(&direct) {
            assert!(a.distance(*b) < 1e-7, "{a} against {b}");
        }
        // From the answer itself it takes no iteration.
        let (_, iterations) = system
            .solve_preconditioned(&new, &b, &direct, 1e-8, 5)
            .unwrap()
            .expect("converged at the start");
        assert_eq!(iterations, 0);
    }

    #[test]
    fn a_preconditioned_solve_that_does_not_converge_says_so() {
        let (stencils, fixed) = chain(60);
        let mut system = LinearSystem::new(&stencils, 60, &fixed).unwrap();
        let rows = system.rows();
        let b = right_hand_side(rows);
        system.factor(&vec![100.0; rows]).unwrap();
        let answer = system
            .solve_preconditioned(&vec![0.0; rows], &b, &vec![DVec3::ZERO; rows], 1e-12, 1)
            .unwrap();
        assert!(answer.is_none());
    }

    #[test]
    fn a_failed_factorization_leaves_nothing_to_solve_with() {
        let (stencils, fixed) = chain(30);
        let mut system = LinearSystem::new(&stencils, 30, &fixed).unwrap();
        let rows = system.rows();
        let b = right_hand_side(rows);
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
}
