//! Assembly of the global step's matrix `A = Σ weight · s sᵀ` (over the free vertices) as its lower
//! triangle in compressed columns, without a list of triplets: each column's entries are counted,
//! filled, then sorted and merged in place. At a few million layout points a triplet list (24
//! bytes per product of two stencil entries) alone would take several gigabytes; this takes 12
//! bytes per product while assembling and 16 per distinct entry after.

use glam::DVec3;

use super::linear_system::Stencils;
use crate::error::KernelError;

/// The lower triangle of `A` in compressed columns (rows sorted within each column, the diagonal
/// first), and the right-hand side's part from the fixed vertices.
pub(crate) struct AssembledSystem {
    pub(crate) column_pointers: Vec<usize>,
    pub(crate) row_indices: Vec<usize>,
    pub(crate) values: Vec<f64>,
    /// `-Σ weight · s_a s_b x_b` per free row `a` over fixed vertices `b`.
    pub(crate) fixed_right_hand_side: Vec<DVec3>,
}

fn out_of_memory(what: &str) -> KernelError {
    KernelError::InvalidArgument {
        name: "wrap",
        reason: format!("out of memory for the global step's {what}"),
    }
}

/// A vector of `length` copies of `value`, or an error naming `what` when it cannot be allocated.
pub(crate) fn try_filled<T: Clone>(
    length: usize,
    value: T,
    what: &str,
) -> Result<Vec<T>, KernelError> {
    let mut values = Vec::new();
    values
        .try_reserve_exact(length)
        .map_err(|_| out_of_memory(what))?;
    values.resize(length, value);
    Ok(values)
}

/// Calls `visit(row_a, row_b, value)` for every product of two entries of a term whose vertices
/// are both free, `row_b <= row_a`, and `fixed(row_a, vertex_b, value)` when `b` is fixed.
fn for_each_product(
    stencils: &Stencils,
    row_of_vertex: &[Option<u32>],
    mut visit: impl FnMut(u32, u32, f64),
    mut fixed: impl FnMut(u32, u32, f64),
) {
    for term in 0..stencils.len() {
        let weight = stencils.weights[term];
        let range = stencils.offsets[term] as usize..stencils.offsets[term + 1] as usize;
        for entry_a in range.clone() {
            let Some(row_a) = row_of_vertex[stencils.vertices[entry_a] as usize] else {
                continue;
            };
            let coefficient_a = stencils.coefficients[entry_a] * weight;
            for entry_b in range.clone() {
                let vertex_b = stencils.vertices[entry_b];
                let value = coefficient_a * stencils.coefficients[entry_b];
                match row_of_vertex[vertex_b as usize] {
                    Some(row_b) if row_b <= row_a => visit(row_a, row_b, value),
                    Some(_) => {}
                    None => fixed(row_a, vertex_b, value),
                }
            }
        }
    }
}

/// The right-hand side's part from the fixed vertices at `fixed` (the same sums, in the same
/// order, as [`assemble`] makes them).
///
/// # Errors
/// [`KernelError::InvalidArgument`] when its memory cannot be allocated.
pub(crate) fn fixed_right_hand_side(
    stencils: &Stencils,
    row_of_vertex: &[Option<u32>],
    rows: usize,
    fixed: &[Option<DVec3>],
) -> Result<Vec<DVec3>, KernelError> {
    let mut right_hand_side = try_filled(rows, DVec3::ZERO, "right-hand side")?;
    for_each_product(
        stencils,
        row_of_vertex,
        |_, _, _| {},
        |row_a, vertex_b, value| {
            let position = fixed[vertex_b as usize].unwrap_or(DVec3::ZERO);
            right_hand_side[row_a as usize] -= position * value;
        },
    );
    Ok(right_hand_side)
}

/// Assembles `A` over the free vertices (`row_of_vertex`), `fixed[v]` the position of each
/// fixed vertex.
///
/// # Errors
/// [`KernelError::InvalidArgument`] when its memory cannot be allocated.
pub(crate) fn assemble(
    stencils: &Stencils,
    row_of_vertex: &[Option<u32>],
    rows: usize,
    fixed: &[Option<DVec3>],
) -> Result<AssembledSystem, KernelError> {
    // Per column, how many products land in it (one more for the diagonal, always present).
    let mut counts = try_filled(rows + 1, 1usize, "matrix")?;
    counts[rows] = 0;
    for_each_product(
        stencils,
        row_of_vertex,
        |_, row_b, _| counts[row_b as usize] += 1,
        |_, _, _| {},
    );
    let mut starts = counts;
    let mut total = 0;
    for start in &mut starts {
        let count = *start;
        *start = total;
        total += count;
    }
    let mut rows_of_entries = try_filled(total, 0u32, "matrix")?;
    let mut values_of_entries = try_filled(total, 0.0f64, "matrix")?;
    let mut next = starts.clone();
    for (column, slot) in next.iter_mut().take(rows).enumerate() {
        rows_of_entries[*slot] = column as u32;
        *slot += 1;
    }
    let mut fixed_right_hand_side = try_filled(rows, DVec3::ZERO, "right-hand side")?;
    for_each_product(
        stencils,
        row_of_vertex,
        |row_a, row_b, value| {
            let slot = &mut next[row_b as usize];
            rows_of_entries[*slot] = row_a;
            values_of_entries[*slot] = value;
            *slot += 1;
        },
        |row_a, vertex_b, value| {
            let position = fixed[vertex_b as usize].unwrap_or(DVec3::ZERO);
            fixed_right_hand_side[row_a as usize] -= position * value;
        },
    );
    drop(next);
    // Sort each column by row and merge equal rows, compacting toward the front.
    let mut column_pointers = try_filled(rows + 1, 0usize, "matrix")?;
    let mut write = 0;
    let mut pairs: Vec<(u32, f64)> = Vec::new();
    for column in 0..rows {
        let range = starts[column]..starts[column + 1];
        pairs.clear();
        pairs.extend(
            rows_of_entries[range.clone()]
                .iter()
                .copied()
                .zip(values_of_entries[range].iter().copied()),
        );
        pairs.sort_unstable_by_key(|&(row, _)| row);
        column_pointers[column] = write;
        let mut previous = u32::MAX;
        for &(row, value) in &pairs {
            if row == previous {
                values_of_entries[write - 1] += value;
            } else {
                rows_of_entries[write] = row;
                values_of_entries[write] = value;
                write += 1;
                previous = row;
            }
        }
    }
    column_pointers[rows] = write;
    drop(starts);
    rows_of_entries.truncate(write);
    values_of_entries.truncate(write);
    values_of_entries.shrink_to_fit();
    let mut row_indices = Vec::new();
    row_indices
        .try_reserve_exact(write)
        .map_err(|_| out_of_memory("matrix"))?;
    row_indices.extend(rows_of_entries.iter().map(|&row| row as usize));
    Ok(AssembledSystem {
        column_pointers,
        row_indices,
        values: values_of_entries,
        fixed_right_hand_side,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn columns_are_sorted_merged_and_start_with_their_diagonal() {
        // Vertex 1 fixed; rows 0 (vertex 0) and 1 (vertex 2).
        let mut stencils = Stencils::new();
        stencils.push([(0, 1.0), (1, -1.0)], 2.0);
        stencils.push([(2, 1.0), (0, -1.0)], 1.0);
        stencils.push([(0, 1.0), (2, -1.0)], 1.0);
        let fixed = [None, Some(DVec3::new(1.0, 2.0, 3.0)), None];
        let row_of_vertex = [Some(0), None, Some(1)];
        let system = assemble(&stencils, &row_of_vertex, 2, &fixed).unwrap();
        assert_eq!(system.column_pointers, vec![0, 2, 3]);
        assert_eq!(system.row_indices, vec![0, 1, 1]);
        // A = [[2 + 1 + 1, -2], [-2, 2]].
        assert_eq!(system.values, vec![4.0, -2.0, 2.0]);
        // Row 0: -(2 · 1 · -1) x_1 = 2 x_1.
        assert_eq!(system.fixed_right_hand_side[0], DVec3::new(2.0, 4.0, 6.0));
        assert_eq!(system.fixed_right_hand_side[1], DVec3::ZERO);
    }
}
