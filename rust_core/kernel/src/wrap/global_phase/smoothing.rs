//! Smoothing of per-vertex values over the layout by one factored solve instead of many rounds
//! of neighbour averaging.
//!
//! `r` rounds of averaging each vertex with its `d` edge neighbours spread a value about as far as
//! diffusion for a time `τ = r / (d + 1)`: each round moves it `d / (d + 1)` of the way to its
//! neighbours' mean. The implicit step `(I + τ L) x = x₀` (`L` the layout's graph Laplacian) does
//! the same in one sparse solve, whatever `τ`; the matrix `L + I / τ` is factored once per `τ`
//! (its pattern analysed once) and each set of values costs a triangular solve. Hundreds of rounds
//! of averaging over a body layout cost a second per wrap iteration; the solve a few milliseconds.

use glam::DVec3;

use crate::error::KernelError;
use crate::layout::LayoutStructure;
use crate::wrap::linear_system::{LinearSystem, Stencils};

/// The mean number of edge neighbours `d` of a quad layout's vertex: `rounds` of averaging are
/// diffusion for `rounds / (d + 1)`.
const MEAN_NEIGHBOURS: f64 = 4.0;

/// The layout's graph Laplacian, factored with `I / τ` on its diagonal for the last `τ` asked for.
#[derive(Debug, Clone)]
pub(crate) struct Smoother {
    system: LinearSystem,
    /// The rounds whose `τ` is factored, or `None`.
    factored: Option<usize>,
}

impl Smoother {
    /// The Laplacian of `structure`'s edges, its pattern analysed.
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] when the system cannot be built (out of memory).
    pub(crate) fn new(structure: &LayoutStructure) -> Result<Self, KernelError> {
        let mut stencils = Stencils::new();
        for vertex in 0..structure.vertex_count as u32 {
            for &other in structure.neighbors_of(vertex) {
                if other > vertex {
                    stencils.push([(vertex, 1.0), (other, -1.0)], 1.0);
                }
            }
        }
        let fixed = vec![None; structure.vertex_count];
        Ok(Self {
            system: LinearSystem::new(&stencils, structure.vertex_count, &fixed, usize::MAX)?,
            factored: None,
        })
    }

    /// The diffusion time that stands for `rounds` rounds of neighbour averaging.
    fn time_of(rounds: usize) -> f64 {
        rounds as f64 / (MEAN_NEIGHBOURS + 1.0)
    }

    /// Each column of `columns` (one value per vertex) smoothed as `rounds` rounds of neighbour
    /// averaging would (0: unchanged).
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] when a column's length is not the vertex count, or the
    /// factorization or a solve fails.
    pub(crate) fn smooth(
        &mut self,
        rounds: usize,
        columns: &mut [Vec<DVec3>],
    ) -> Result<(), KernelError> {
        if rounds == 0 {
            return Ok(());
        }
        let rows = self.system.rows();
        if let Some(column) = columns.iter().find(|column| column.len() != rows) {
            return Err(KernelError::InvalidArgument {
                name: "values",
                reason: format!("{} values to smooth over {rows} vertices", column.len()),
            });
        }
        let inverse_time = 1.0 / Self::time_of(rounds);
        if self.factored != Some(rounds) {
            self.factored = None;
            self.system.factor(&vec![inverse_time; rows])?;
            self.factored = Some(rounds);
        }
        for column in columns.iter_mut() {
            let right_hand_side: Vec<DVec3> =
                column.iter().map(|&value| value * inverse_time).collect();
            *column = self.system.solve(&right_hand_side)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A path of `count` vertices as a strip of quads (2 × count vertices, rows joined).
    fn strip(count: u32) -> LayoutStructure {
        let mut corners = Vec::new();
        for index in 0..count - 1 {
            corners.extend([index, index + 1, count + index + 1, count + index]);
        }
        let faces = vec![4; (count - 1) as usize];
        LayoutStructure::new(2 * count as usize, &corners, &faces, &[], &[]).unwrap()
    }

    #[test]
    fn a_constant_stays_and_a_spike_spreads_wider_with_more_rounds() {
        let structure = strip(40);
        let mut smoother = Smoother::new(&structure).unwrap();
        let mut constant = vec![vec![DVec3::splat(2.5); 80]];
        smoother.smooth(64, &mut constant).unwrap();
        assert!(
            constant[0]
                .iter()
                .all(|v| v.abs_diff_eq(DVec3::splat(2.5), 1e-9))
        );
        let spike = |smoother: &mut Smoother, rounds| {
            let mut values = vec![vec![DVec3::ZERO; 80]];
            values[0][20] = DVec3::X;
            smoother.smooth(rounds, &mut values).unwrap();
            let total: f64 = values[0].iter().map(|v| v.x).sum();
            assert!((total - 1.0).abs() < 1e-9, "the sum is kept: {total}");
            values[0][20].x
        };
        let (narrow, wide) = (spike(&mut smoother, 4), spike(&mut smoother, 256));
        assert!(narrow < 1.0 && wide < narrow * 0.5, "{narrow} {wide}");
        assert_eq!(spike(&mut smoother, 0), 1.0);
    }

    #[test]
    fn values_of_the_wrong_length_are_refused() {
        let mut smoother = Smoother::new(&strip(5)).unwrap();
        let mut values = vec![vec![DVec3::ZERO; 3]];
        let error = smoother.smooth(8, &mut values).unwrap_err();
        assert!(error.to_string().contains("3 values"), "{error}");
    }
}
