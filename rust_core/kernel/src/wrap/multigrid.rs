//! The preconditioner of the global step's conjugate gradients when the system is too large to
//! factor: an aggregation multigrid V-cycle.
//!
//! The rows are grouped into small aggregates (a row and those of its neighbours strongly
//! coupled to it), each aggregate one row of a coarser system `Pᵀ A P` (`P` piecewise constant:
//! a row of the coarse system moves its aggregate as one). Grouping again and again shrinks the
//! system by about five each time, until it is small enough to factor. A cycle smooths the
//! residual on each level (ℓ1-Jacobi: each row divided by the sum of its entries' magnitudes, a
//! smoother that converges on any symmetric positive definite matrix), hands what is left to the
//! coarser level and adds back its correction, then smooths again: the slow, smooth errors that
//! Jacobi alone takes thousands of iterations to remove are removed on the coarse levels.
//!
//! Only the diagonal of `A` changes between solves (the data weights); for a piecewise-constant
//! `P` the coarse systems' diagonals change by the sums of the changes over each aggregate, so the
//! hierarchy is built once and each solve only sums diagonals and factors the coarsest system.

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::{SparseColMat, SparseColMatRef, SymbolicSparseColMat};
use faer::{Mat, Side};
use glam::DVec3;
use rayon::prelude::*;

use super::ordered_sum::ordered_sum_mut;
use super::system_assembly::try_filled;
use crate::error::KernelError;

/// A level with at most this many rows is factored (a sparse Cholesky).
pub(crate) const COARSEST_ROWS: usize = 20_000;
/// A neighbour joins a row's aggregate when their coupling is at least this fraction of the
/// geometric mean of their diagonals.
const STRONG_COUPLING: f64 = 0.2;
/// At most this many levels (a level that hardly shrinks ends the hierarchy).
const MAX_LEVELS: usize = 12;

/// A symmetric matrix, both triangles, in compressed rows (column indices as `u32`), for
/// products that run on every core.
#[derive(Debug, Clone)]
pub(crate) struct FullRows {
    row_pointers: Vec<usize>,
    columns: Vec<u32>,
    values: Vec<f64>,
}

impl FullRows {
    /// Both triangles of the lower triangle `lower` (CSC).
    pub(crate) fn from_lower(lower: &SparseColMat<usize, f64>) -> Result<Self, KernelError> {
        let rows = lower.nrows();
        let column_pointers = lower.symbolic().col_ptr();
        let row_indices = lower.symbolic().row_idx();
        let values = lower.val();
        // Row i holds column j's entries (j <= i, the lower part) and row i's own column (the
        // upper part, the diagonal excepted).
        let mut row_pointers = try_filled(rows + 1, 0usize, "matrix")?;
        for column in 0..rows {
            let range = column_pointers[column]..column_pointers[column + 1];
            for &row in &row_indices[range] {
                row_pointers[row + 1] += 1;
                if row != column {
                    row_pointers[column + 1] += 1;
                }
            }
        }
        for row in 0..rows {
            row_pointers[row + 1] += row_pointers[row];
        }
        let total = row_pointers[rows];
        let mut columns = try_filled(total, 0u32, "matrix")?;
        let mut full_values = try_filled(total, 0.0f64, "matrix")?;
        let mut next = row_pointers.clone();
        for column in 0..rows {
            for entry in column_pointers[column]..column_pointers[column + 1] {
                let (row, value) = (row_indices[entry], values[entry]);
                columns[next[row]] = column as u32;
                full_values[next[row]] = value;
                next[row] += 1;
                if row != column {
                    columns[next[column]] = row as u32;
                    full_values[next[column]] = value;
                    next[column] += 1;
                }
            }
        }
        Ok(Self {
            row_pointers,
            columns,
            values: full_values,
        })
    }

    /// Number of rows.
    pub(crate) fn rows(&self) -> usize {
        self.row_pointers.len() - 1
    }

    /// The entries of `row`: (column, value).
    fn row(&self, row: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let range = self.row_pointers[row]..self.row_pointers[row + 1];
        self.columns[range.clone()]
            .iter()
            .map(|&column| column as usize)
            .zip(self.values[range].iter().copied())
    }

    /// The diagonal entry of `row` (0 when absent).
    fn diagonal(&self, row: usize) -> f64 {
        self.row(row)
            .filter(|&(column, _)| column == row)
            .map(|(_, value)| value)
            .sum()
    }

    /// `(A + diag(extra)) x`.
    pub(crate) fn multiply(&self, extra_diagonal: &[f64], x: &[DVec3]) -> Vec<DVec3> {
        (0..self.rows())
            .into_par_iter()
            .with_min_len(4096)
            .map(|row| {
                self.row(row)
                    .fold(x[row] * extra_diagonal[row], |sum, (column, value)| {
                        sum + x[column] * value
                    })
            })
            .collect()
    }

    /// `(A + diag(extra)) x` into `product`, and per axis the dot product of `x` and it.
    pub(crate) fn multiply_dot(
        &self,
        extra_diagonal: &[f64],
        x: &[DVec3],
        product: &mut [DVec3],
    ) -> DVec3 {
        // Grouped in fixed pieces, so that the conjugate gradients repeat to the bit.
        ordered_sum_mut(product, |row, product| {
            *product = self
                .row(row)
                .fold(x[row] * extra_diagonal[row], |sum, (column, value)| {
                    sum + x[column] * value
                });
            x[row] * *product
        })
    }

    /// Row `row` of `b - (A + diag(extra)) x`.
    #[inline]
    fn residual_at(&self, row: usize, extra_diagonal: &[f64], b: &[DVec3], x: &[DVec3]) -> DVec3 {
        self.row(row).fold(
            b[row] - x[row] * extra_diagonal[row],
            |sum, (column, value)| sum - x[column] * value,
        )
    }
}

/// One level of the hierarchy: its matrix and how its rows group into the next level's.
#[derive(Debug, Clone)]
struct Level {
    matrix: FullRows,
    /// Per row, the sum of its entries' magnitudes (the ℓ1-Jacobi smoother's divisor, without
    /// the extra diagonal).
    row_magnitudes: Vec<f64>,
    /// Per row, its aggregate (its row in the next level); empty on the coarsest level.
    aggregate_of_row: Vec<u32>,
    /// The rows of each aggregate: those of aggregate `a` are
    /// `members[member_pointers[a]..member_pointers[a + 1]]`; empty on the coarsest level.
    member_pointers: Vec<usize>,
    members: Vec<u32>,
}

/// The hierarchy of an `A` (without the solves' extra diagonal).
#[derive(Debug, Clone)]
pub(crate) struct Multigrid {
    levels: Vec<Level>,
    /// The coarsest level's pattern and its analysis, made once.
    coarsest_symbolic: Option<(SymbolicSparseColMat<usize>, SymbolicLlt<usize>)>,
}

/// What one solve's cycles need: each level's extra diagonal and smoother, the coarsest factor.
pub(crate) struct Prepared {
    extra: Vec<Vec<f64>>,
    inverse: Vec<Vec<f64>>,
    coarsest: Option<Llt<usize, f64>>,
}

fn multigrid_error(reason: &str) -> KernelError {
    KernelError::InvalidArgument {
        name: "wrap",
        reason: format!("the global step's multigrid failed: {reason}"),
    }
}

/// Groups the rows of `matrix` into aggregates: per row, its aggregate, and how many there are.
fn aggregate(matrix: &FullRows) -> (Vec<u32>, usize) {
    let rows = matrix.rows();
    let diagonal: Vec<f64> = (0..rows).map(|row| matrix.diagonal(row)).collect();
    let strong = |row: usize, column: usize, value: f64| {
        column != row
            && value.abs() >= STRONG_COUPLING * (diagonal[row] * diagonal[column]).abs().sqrt()
    };
    let mut aggregate_of_row = vec![u32::MAX; rows];
    let mut count = 0u32;
    // A row whose strong neighbours are all free starts an aggregate with them.
    for row in 0..rows {
        if aggregate_of_row[row] != u32::MAX {
            continue;
        }
        let free = matrix
            .row(row)
            .filter(|&(column, value)| strong(row, column, value))
            .all(|(column, _)| aggregate_of_row[column] == u32::MAX);
        if !free {
            continue;
        }
        aggregate_of_row[row] = count;
        for (column, value) in matrix.row(row) {
            if strong(row, column, value) {
                aggregate_of_row[column] = count;
            }
        }
        count += 1;
    }
    // The others join their most strongly coupled aggregated neighbour, or stand alone.
    let first_pass = aggregate_of_row.clone();
    for row in 0..rows {
        if first_pass[row] != u32::MAX {
            continue;
        }
        let joined = matrix
            .row(row)
            .filter(|&(column, value)| strong(row, column, value) && first_pass[column] != u32::MAX)
            .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
            .map(|(column, _)| first_pass[column]);
        aggregate_of_row[row] = joined.unwrap_or_else(|| {
            count += 1;
            count - 1
        });
    }
    (aggregate_of_row, count as usize)
}

/// The rows of each aggregate of `aggregate_of_row` (`coarse_rows` aggregates): pointers and
/// members, as [`Level`] keeps them.
fn aggregate_members(
    aggregate_of_row: &[u32],
    coarse_rows: usize,
) -> Result<(Vec<usize>, Vec<u32>), KernelError> {
    // The rows of each aggregate.
    let mut member_pointers = try_filled(coarse_rows + 1, 0usize, "multigrid")?;
    for &aggregate in aggregate_of_row {
        member_pointers[aggregate as usize + 1] += 1;
    }
    for row in 0..coarse_rows {
        member_pointers[row + 1] += member_pointers[row];
    }
    let mut members = try_filled(aggregate_of_row.len(), 0u32, "multigrid")?;
    let mut next = member_pointers.clone();
    for (row, &aggregate) in aggregate_of_row.iter().enumerate() {
        members[next[aggregate as usize]] = row as u32;
        next[aggregate as usize] += 1;
    }
    Ok((member_pointers, members))
}

/// `Pᵀ A P` for the piecewise-constant `P` of `aggregate_of_row`, whose aggregates have the rows
/// `members` (from `member_pointers`).
fn coarsen(
    matrix: &FullRows,
    aggregate_of_row: &[u32],
    member_pointers: &[usize],
    members: &[u32],
) -> Result<FullRows, KernelError> {
    let coarse_rows = member_pointers.len() - 1;
    let coarse: Vec<Vec<(u32, f64)>> = (0..coarse_rows)
        .into_par_iter()
        .with_min_len(1024)
        .map(|coarse_row| {
            let mut entries: Vec<(u32, f64)> = Vec::new();
            for &row in &members[member_pointers[coarse_row]..member_pointers[coarse_row + 1]] {
                for (column, value) in matrix.row(row as usize) {
                    entries.push((aggregate_of_row[column], value));
                }
            }
            entries.sort_unstable_by_key(|&(column, _)| column);
            entries.dedup_by(|later, kept| {
                if later.0 == kept.0 {
                    kept.1 += later.1;
                    true
                } else {
                    false
                }
            });
            entries
        })
        .collect();
    let mut row_pointers = try_filled(coarse_rows + 1, 0usize, "multigrid")?;
    for (row, entries) in coarse.iter().enumerate() {
        row_pointers[row + 1] = row_pointers[row] + entries.len();
    }
    let total = row_pointers[coarse_rows];
    let mut columns = Vec::new();
    let mut values = Vec::new();
    columns
        .try_reserve_exact(total)
        .and_then(|()| values.try_reserve_exact(total))
        .map_err(|_| multigrid_error("out of memory"))?;
    for entries in coarse {
        for (column, value) in entries {
            columns.push(column);
            values.push(value);
        }
    }
    Ok(FullRows {
        row_pointers,
        columns,
        values,
    })
}

impl Level {
    fn new(matrix: FullRows) -> Self {
        let row_magnitudes = (0..matrix.rows())
            .map(|row| matrix.row(row).map(|(_, value)| value.abs()).sum())
            .collect();
        Self {
            matrix,
            row_magnitudes,
            aggregate_of_row: Vec::new(),
            member_pointers: Vec::new(),
            members: Vec::new(),
        }
    }
}

impl Multigrid {
    /// The hierarchy of `matrix`, coarsened until a level has at most `coarsest_rows` rows
    /// ([`COARSEST_ROWS`] in the wrap).
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] when out of memory or when the coarsest pattern cannot
    /// be analysed.
    pub(crate) fn new(matrix: FullRows, coarsest_rows: usize) -> Result<Self, KernelError> {
        let mut levels = vec![Level::new(matrix)];
        while levels.len() < MAX_LEVELS {
            let level = levels.last_mut().expect("one level at least");
            let rows = level.matrix.rows();
            if rows <= coarsest_rows {
                break;
            }
            let (aggregate_of_row, coarse_rows) = aggregate(&level.matrix);
            if coarse_rows * 10 > rows * 9 {
                break; // hardly shrinks: iterate on this level
            }
            let (member_pointers, members) = aggregate_members(&aggregate_of_row, coarse_rows)?;
            let coarse = coarsen(&level.matrix, &aggregate_of_row, &member_pointers, &members)?;
            level.aggregate_of_row = aggregate_of_row;
            level.member_pointers = member_pointers;
            level.members = members;
            levels.push(Level::new(coarse));
        }
        let coarsest = &levels.last().expect("one level at least").matrix;
        let coarsest_symbolic = if coarsest.rows() <= coarsest_rows {
            let pattern = SymbolicSparseColMat::new_checked(
                coarsest.rows(),
                coarsest.rows(),
                coarsest.row_pointers.clone(),
                None,
                coarsest
                    .columns
                    .iter()
                    .map(|&column| column as usize)
                    .collect(),
            );
            let analysed = SymbolicLlt::try_new(pattern.as_ref(), Side::Lower)
                .map_err(|error| multigrid_error(&format!("{error:?}")))?;
            Some((pattern, analysed))
        } else {
            None
        };
        Ok(Self {
            levels,
            coarsest_symbolic,
        })
    }

    /// The finest level's matrix (the system's own).
    pub(crate) fn matrix(&self) -> &FullRows {
        &self.levels[0].matrix
    }

    /// Number of levels.
    #[cfg(test)]
    pub(crate) fn depth(&self) -> usize {
        self.levels.len()
    }

    /// Every level's extra diagonal and smoother, and the coarsest factor, for `A + diag(extra)`.
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] when the coarsest system is not positive definite.
    pub(crate) fn prepare(&self, extra_diagonal: &[f64]) -> Result<Prepared, KernelError> {
        let mut extra = vec![extra_diagonal.to_vec()];
        for (index, level) in self.levels.iter().enumerate().skip(1) {
            let mut sums = vec![0.0; level.matrix.rows()];
            let finer = &self.levels[index - 1];
            for (&aggregate, &value) in finer.aggregate_of_row.iter().zip(&extra[index - 1]) {
                sums[aggregate as usize] += value;
            }
            extra.push(sums);
        }
        let inverse = self
            .levels
            .iter()
            .zip(&extra)
            .map(|(level, extra)| {
                level
                    .row_magnitudes
                    .iter()
                    .zip(extra)
                    .map(|(magnitude, extra)| 1.0 / (magnitude + extra))
                    .collect()
            })
            .collect();
        let coarsest = match &self.coarsest_symbolic {
            Some((pattern, symbolic)) => {
                let level = self.levels.last().expect("one level at least");
                let mut values = level.matrix.values.clone();
                let coarsest_extra = extra.last().expect("one level at least");
                for (row, &extra) in coarsest_extra.iter().enumerate() {
                    let range = level.matrix.row_pointers[row]..level.matrix.row_pointers[row + 1];
                    for (value, &column) in values[range.clone()]
                        .iter_mut()
                        .zip(&level.matrix.columns[range])
                    {
                        if column as usize == row {
                            *value += extra;
                        }
                    }
                }
                let matrix = SparseColMatRef::new(pattern.as_ref(), &values);
                let factor = Llt::try_new_with_symbolic(symbolic.clone(), matrix, Side::Lower)
                    .map_err(|error| multigrid_error(&format!("{error:?}")))?;
                Some(factor)
            }
            None => None,
        };
        Ok(Prepared {
            extra,
            inverse,
            coarsest,
        })
    }

    /// One V-cycle on `residual` (one value per row of the finest level): an approximation of
    /// `(A + diag(extra))⁻¹ residual`, symmetric and positive definite in `residual`.
    pub(crate) fn cycle(&self, prepared: &Prepared, residual: &[DVec3]) -> Vec<DVec3> {
        self.cycle_at(0, prepared, residual)
    }

    fn cycle_at(&self, index: usize, prepared: &Prepared, b: &[DVec3]) -> Vec<DVec3> {
        let level = &self.levels[index];
        let extra = &prepared.extra[index];
        let inverse = &prepared.inverse[index];
        let last = index + 1 == self.levels.len();
        if last && let Some(factor) = &prepared.coarsest {
            let mut columns = Mat::<f64>::from_fn(b.len(), 3, |row, axis| b[row][axis]);
            factor.solve_in_place(columns.as_mut());
            return (0..b.len())
                .map(|row| DVec3::new(columns[(row, 0)], columns[(row, 1)], columns[(row, 2)]))
                .collect();
        }
        // One ℓ1-Jacobi sweep: `x + D⁻¹ (b - (A + diag(extra)) x)`, into a new vector.
        let smooth = |x: &[DVec3]| -> Vec<DVec3> {
            (0..x.len())
                .into_par_iter()
                .with_min_len(4096)
                .map(|row| x[row] + level.matrix.residual_at(row, extra, b, x) * inverse[row])
                .collect()
        };
        // One sweep before the coarse correction (from zero: a scaling of the residual) and one
        // after: symmetric, as the conjugate gradients need. Measured on a 512² torus grid wrap,
        // against two each side: a cycle passes over the finest matrix twice instead of four
        // times, the conjugate gradients take 11 % more iterations, the global steps a quarter
        // less processor time.
        let mut x: Vec<DVec3> = b
            .par_iter()
            .with_min_len(4096)
            .zip(inverse)
            .map(|(b, inverse)| *b * *inverse)
            .collect();
        if !last {
            // The residual summed over each aggregate, its members' rows in order, without a
            // vector of the finest residual (a pass over it and its memory saved).
            let pointers = &level.member_pointers;
            let coarse: Vec<DVec3> = (0..pointers.len() - 1)
                .into_par_iter()
                .with_min_len(1024)
                .map(|aggregate| {
                    level.members[pointers[aggregate]..pointers[aggregate + 1]]
                        .iter()
                        .map(|&row| level.matrix.residual_at(row as usize, extra, b, &x))
                        .sum()
                })
                .collect();
            let correction = self.cycle_at(index + 1, prepared, &coarse);
            x.par_iter_mut()
                .with_min_len(4096)
                .zip(&level.aggregate_of_row)
                .for_each(|(x, &aggregate)| *x += correction[aggregate as usize]);
        }
        x = smooth(&x);
        x
    }
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use crate::wrap::linear_system::{LinearSystem, Stencils, Tolerances};
    use crate::wrap::ordered_sum::in_pools;

    /// A `side` x `side` grid's energy terms: edges, and second differences along both axes
    /// (the wrap's arc-length and fairness terms), with a data weight on every row; the four
    /// corners fixed.
    fn grid(side: u32) -> (Stencils, Vec<Option<DVec3>>) {
        let index = |x: u32, y: u32| y * side + x;
        let mut stencils = Stencils::new();
        for y in 0..side {
            for x in 0..side {
                if x + 1 < side {
                    stencils.push([(index(x + 1, y), 1.0), (index(x, y), -1.0)], 1.0);
                }
                if y + 1 < side {
                    stencils.push([(index(x, y + 1), 1.0), (index(x, y), -1.0)], 1.0);
                }
                if x + 2 < side {
                    let line = [
                        (index(x, y), 1.0),
                        (index(x + 1, y), -2.0),
                        (index(x + 2, y), 1.0),
                    ];
                    stencils.push(line, 1.0);
                }
                if y + 2 < side {
                    let line = [
                        (index(x, y), 1.0),
                        (index(x, y + 1), -2.0),
                        (index(x, y + 2), 1.0),
                    ];
                    stencils.push(line, 1.0);
                }
            }
        }
        let mut fixed = vec![None; (side * side) as usize];
        for (corner, vertex) in [0, side - 1, side * (side - 1), side * side - 1]
            .into_iter()
            .enumerate()
        {
            fixed[vertex as usize] = Some(DVec3::new(corner as f64, 0.5, -1.0));
        }
        (stencils, fixed)
    }

    fn residual_only(residual: f64) -> Tolerances {
        Tolerances {
            residual,
            step: 0.0,
            position: 0.0,
        }
    }

    #[test]
    fn a_multigrid_preconditioned_solve_on_a_grid_equals_the_direct_solve() {
        let side = 80;
        let (stencils, fixed) = grid(side);
        let count = (side * side) as usize;
        let mut direct = LinearSystem::new(&stencils, count, &fixed, usize::MAX).unwrap();
        let mut iterative = LinearSystem::new(&stencils, count, &fixed, 0).unwrap();
        assert!(
            iterative.coarsen_to(200) >= 3,
            "a hierarchy of several levels"
        );
        let rows = direct.rows();
        // Weak data weights on some rows only: the smooth errors are what the coarse levels fix.
        let extra: Vec<f64> = (0..rows)
            .map(|row| if row % 5 == 0 { 1e-3 } else { 1e-6 })
            .collect();
        let b: Vec<DVec3> = (0..rows)
            .map(|row| {
                let t = row as f64;
                DVec3::new(t.sin(), (0.3 * t).cos(), 0.01 * t)
            })
            .collect();
        direct.factor(&extra).unwrap();
        let exact = direct.solve(&b).unwrap();
        let start = vec![DVec3::ZERO; rows];
        let (solution, iterations, converged) = iterative
            .solve_preconditioned(&extra, &b, &start, residual_only(1e-10), 200)
            .unwrap();
        assert!(converged, "{iterations} iterations");
        let scale = exact.iter().map(|x| x.length()).fold(0.0, f64::max);
        for (a, b) in solution.iter().zip(&exact) {
            assert!(a.distance(*b) < 1e-6 * scale, "{a} against {b}");
        }
        // To a residual of 1e-10 on a grid held only at its corners (6,400 rows, a near-null
        // space of smooth motions): 87 iterations measured.
        assert!(iterations < 120, "{iterations} iterations");
    }

    #[test]
    fn a_solve_searches_along_the_last_correction_first() {
        let side = 60;
        let (stencils, fixed) = grid(side);
        let count = (side * side) as usize;
        let system = || {
            let mut system = LinearSystem::new(&stencils, count, &fixed, 0).unwrap();
            system.coarsen_to(200);
            system
        };
        let mut hinted = system();
        let rows = hinted.rows();
        let extra = vec![1e-3; rows];
        let b: Vec<DVec3> = (0..rows)
            .map(|row| DVec3::new((row as f64 * 0.01).sin(), 1.0, 0.5))
            .collect();
        let first = hinted
            .solve_reusing(&extra, &b, &vec![DVec3::ZERO; rows], 1e-9)
            .unwrap();
        // The same right-hand side twice as large: the next correction is along the first.
        let twice: Vec<DVec3> = b.iter().map(|b| *b * 2.0).collect();
        let before = hinted.statistics().iterations;
        let second = hinted.solve_reusing(&extra, &twice, &first, 1e-9).unwrap();
        let with_hint = hinted.statistics().iterations - before;
        let mut fresh = system();
        let expected = fresh.solve_reusing(&extra, &twice, &first, 1e-9).unwrap();
        let without_hint = fresh.statistics().iterations;
        assert!(
            with_hint < without_hint,
            "{with_hint} against {without_hint}"
        );
        // Both stop once the step is known to 1e-4 of its length.
        let scale = expected.iter().map(|x| x.length()).fold(0.0, f64::max);
        for (a, b) in second.iter().zip(&expected) {
            assert!(a.distance(*b) < 1e-4 * scale, "{a} against {b}");
        }
    }

    #[test]
    fn a_multigrid_preconditioned_solve_repeats_to_the_bit_in_every_pool() {
        // 19,600 rows: rayon cuts a pass of this size into two pieces with one thread and four
        // with two (at least 4,096 rows each), so a sum grouped by rayon's pieces differs in its
        // last bits between the pools.
        let side = 140;
        let (stencils, fixed) = grid(side);
        let count = (side * side) as usize;
        let solve = || {
            let mut system = LinearSystem::new(&stencils, count, &fixed, 0).unwrap();
            system.coarsen_to(500);
            let rows = system.rows();
            let extra: Vec<f64> = (0..rows).map(|row| 1e-4 * (1 + row % 7) as f64).collect();
            let b: Vec<DVec3> = (0..rows)
                .map(|row| {
                    let t = row as f64;
                    DVec3::new(t.sin(), (0.3 * t).cos(), 0.01 * t)
                })
                .collect();
            let start = vec![DVec3::ZERO; rows];
            let (solution, iterations, _) = system
                .solve_preconditioned(&extra, &b, &start, residual_only(1e-9), 60)
                .unwrap();
            let bits: Vec<[u64; 3]> = solution
                .iter()
                .map(|x| x.to_array().map(f64::to_bits))
                .collect();
            (bits, iterations)
        };
        let runs = in_pools(&[1, 2, 3], solve);
        for (threads, run) in [2, 3].into_iter().zip(&runs[1..]) {
            assert_eq!(run.1, runs[0].1, "iterations with {threads} threads");
            assert!(run.0 == runs[0].0, "the solution with {threads} threads");
        }
    }
}
