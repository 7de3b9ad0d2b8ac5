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

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::{SparseColMat, SparseColMatRef, Triplet};
use faer::{Mat, Side};
use glam::DVec3;

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
    symbolic: SymbolicLlt<usize>,
    /// The right-hand side's part from the fixed vertices: `-Σ weight · s_a s_b x_b` per free `a`.
    fixed_right_hand_side: Vec<DVec3>,
    factor: Option<Llt<usize, f64>>,
}

impl std::fmt::Debug for LinearSystem {
    fn fmt(&self, formatter: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        formatter
            .debug_struct("LinearSystem")
            .field("rows", &self.vertex_of_row.len())
            .field("nonzeros", &self.matrix.val().len())
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
            fixed_right_hand_side: self.fixed_right_hand_side.clone(),
            factor: self.factor.clone(),
        }
    }
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
        let symbolic = SymbolicLlt::try_new(matrix.symbolic(), Side::Lower)
            .map_err(|error| solver_error(format!("{error:?}")))?;
        Ok(Self {
            row_of_vertex,
            vertex_of_row,
            matrix,
            diagonal,
            symbolic,
            fixed_right_hand_side,
            factor: None,
        })
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
        let factor = Llt::try_new_with_symbolic(self.symbolic.clone(), matrix, Side::Lower)
            .map_err(|error| solver_error(format!("{error:?}")))?;
        self.factor = Some(factor);
        Ok(())
    }

    /// Solves `(A + diag(extra)) x = b + fixed part` with the last factorization, `b` given per
    /// row; returns `x` per row.
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] when nothing was factored yet.
    pub fn solve(&self, right_hand_side: &[DVec3]) -> Result<Vec<DVec3>, KernelError> {
        let factor = self
            .factor
            .as_ref()
            .ok_or_else(|| solver_error("solved before it was factored"))?;
        let rows = self.rows();
        let mut columns = Mat::<f64>::from_fn(rows, 3, |row, axis| {
            (right_hand_side[row] + self.fixed_right_hand_side[row])[axis]
        });
        factor.solve_in_place(columns.as_mut());
        Ok((0..rows)
            .map(|row| DVec3::new(columns[(row, 0)], columns[(row, 1)], columns[(row, 2)]))
            .collect())
    }

    /// The layout vertex of each row.
    #[must_use]
    pub fn vertex_of_row(&self) -> &[u32] {
        &self.vertex_of_row
    }
}
