//! Small dense solvers the fits need, in f64: a Jacobi eigen-solver for symmetric matrices and a
//! Cholesky solve for symmetric positive definite systems. glam has neither.

// Jacobi rotations and triangular solves index rows and columns together, as the textbook
// formulas do; iterator rewrites would hide which entry is which.
#![allow(clippy::needless_range_loop)]

/// Eigenvalues and eigenvectors of the symmetric matrix `matrix` by cyclic Jacobi rotations.
///
/// Returns `(values, vectors)` sorted by decreasing eigenvalue; `vectors[k]` is the unit
/// eigenvector of `values[k]`. Only the symmetric part of `matrix` is read.
#[must_use]
pub fn symmetric_eigen<const N: usize>(matrix: [[f64; N]; N]) -> ([f64; N], [[f64; N]; N]) {
    let mut a = matrix;
    for row in 0..N {
        for column in row + 1..N {
            let mean = 0.5 * (a[row][column] + a[column][row]);
            a[row][column] = mean;
            a[column][row] = mean;
        }
    }
    // Columns of `v` are the eigenvectors.
    let mut v = [[0.0; N]; N];
    for (index, row) in v.iter_mut().enumerate() {
        row[index] = 1.0;
    }
    let scale: f64 = a.iter().flatten().map(|x| x * x).sum::<f64>().sqrt();
    for _sweep in 0..64 {
        let off: f64 = (0..N)
            .flat_map(|p| (p + 1..N).map(move |q| (p, q)))
            .map(|(p, q)| a[p][q] * a[p][q])
            .sum::<f64>()
            .sqrt();
        if off <= f64::EPSILON * 1e-3 * scale || off == 0.0 {
            break;
        }
        for p in 0..N {
            for q in p + 1..N {
                if a[p][q] == 0.0 {
                    continue;
                }
                let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for k in 0..N {
                    let (akp, akq) = (a[k][p], a[k][q]);
                    a[k][p] = c * akp - s * akq;
                    a[k][q] = s * akp + c * akq;
                }
                for k in 0..N {
                    let (apk, aqk) = (a[p][k], a[q][k]);
                    a[p][k] = c * apk - s * aqk;
                    a[q][k] = s * apk + c * aqk;
                }
                for row in &mut v {
                    let (vkp, vkq) = (row[p], row[q]);
                    row[p] = c * vkp - s * vkq;
                    row[q] = s * vkp + c * vkq;
                }
            }
        }
    }
    let mut order: [usize; N] = std::array::from_fn(|index| index);
    order.sort_by(|&i, &j| a[j][j].total_cmp(&a[i][i]));
    let values = std::array::from_fn(|k| a[order[k]][order[k]]);
    let vectors = std::array::from_fn(|k| std::array::from_fn(|row| v[row][order[k]]));
    (values, vectors)
}

/// Solves `matrix * x = rhs` for a symmetric positive definite `matrix` by Cholesky (`L Lᵀ`).
///
/// Returns `None` when a pivot is not positive (the matrix is singular or indefinite).
#[must_use]
pub fn cholesky_solve<const N: usize>(matrix: &[[f64; N]; N], rhs: &[f64; N]) -> Option<[f64; N]> {
    let mut lower = [[0.0; N]; N];
    for row in 0..N {
        for column in 0..=row {
            let sum: f64 = (0..column).map(|k| lower[row][k] * lower[column][k]).sum();
            if row == column {
                let pivot = matrix[row][row] - sum;
                if pivot.is_nan() || pivot <= 0.0 {
                    return None;
                }
                lower[row][row] = pivot.sqrt();
            } else {
                lower[row][column] = (matrix[row][column] - sum) / lower[column][column];
            }
        }
    }
    let mut y = [0.0; N];
    for row in 0..N {
        let sum: f64 = (0..row).map(|k| lower[row][k] * y[k]).sum();
        y[row] = (rhs[row] - sum) / lower[row][row];
    }
    let mut x = [0.0; N];
    for row in (0..N).rev() {
        let sum: f64 = (row + 1..N).map(|k| lower[k][row] * x[k]).sum();
        x[row] = (y[row] - sum) / lower[row][row];
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eigen_of_a_known_matrix() {
        // Eigenvalues 3, 1 (for [1, 1]/√2 and [1, -1]/√2) plus 5 on its own axis.
        let (values, vectors) =
            symmetric_eigen([[2.0, 1.0, 0.0], [1.0, 2.0, 0.0], [0.0, 0.0, 5.0]]);
        assert!((values[0] - 5.0).abs() < 1e-12);
        assert!((values[1] - 3.0).abs() < 1e-12);
        assert!((values[2] - 1.0).abs() < 1e-12);
        assert!((vectors[1][0].abs() - 0.5f64.sqrt()).abs() < 1e-12);
        assert!((vectors[1][0] - vectors[1][1]).abs() < 1e-12);
    }

    #[test]
    fn cholesky_solves_and_refuses_singular() {
        let matrix = [[4.0, 2.0], [2.0, 3.0]];
        let x = cholesky_solve(&matrix, &[2.0, 1.0]).unwrap();
        assert!((4.0 * x[0] + 2.0 * x[1] - 2.0).abs() < 1e-12);
        assert!((2.0 * x[0] + 3.0 * x[1] - 1.0).abs() < 1e-12);
        assert!(cholesky_solve(&[[1.0, 1.0], [1.0, 1.0]], &[1.0, 1.0]).is_none());
    }
}
