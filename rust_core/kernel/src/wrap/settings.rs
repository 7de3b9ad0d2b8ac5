//! The wrap's parameters: the five force weights and the iteration controls.

use crate::error::KernelError;

pub use super::forces::SpringRest;

/// Scalar multipliers of the wrap's forces (the paper's α, β, γ_tp, γ_con, γ_fold).
///
/// Every force is a displacement (in model units) toward what it wants; a weight is the fraction
/// of it applied per iteration, so weights in `[0, 1]` are stable (thin plate: up to 0.5).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WrapWeights {
    /// α: fairness, straightening grid lines (second differences across the line).
    pub fairness: f32,
    /// β: equal arc length along grid lines.
    pub arc_length: f32,
    /// γ_tp: thin plate on space-points, continuing the surrounding surface over holes.
    pub thin_plate: f32,
    /// γ_con: attraction of anchored points to their targets.
    pub constraint: f32,
    /// γ_fold: fraction of the folding rotation applied per iteration.
    pub folding: f32,
}

impl Default for WrapWeights {
    fn default() -> Self {
        Self {
            fairness: 0.5,
            arc_length: 0.5,
            thin_plate: 0.2,
            constraint: 0.5,
            folding: 0.3,
        }
    }
}

/// Which algorithm moves the points.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SolverKind {
    /// The paper's force iteration: spring forces relaxed by Jacobi steps, folding, annealing.
    #[default]
    Springs,
    /// One energy minimised by local–global steps with a sparse Cholesky, no face turned over
    /// (see `wrap::energy_solver`).
    Energy,
}

/// Everything that controls a wrap besides the layout, the target and the anchors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WrapSettings {
    /// The force weights.
    pub weights: WrapWeights,
    /// Converged when no point moved more than this fraction of the layout's size in an iteration
    /// and no point changed state.
    pub tolerance: f32,
    /// An anchored space-point lands on its face-point target when closer than this fraction of
    /// the layout's mean edge length.
    pub landing_distance: f32,
    /// Starting folding tolerance in radians; it anneals by itself from how many points fold.
    pub fold_tolerance: f32,
    /// Heavy-ball momentum: the fraction of its previous move a free point carries into the next.
    /// Relaxing a spring grid by plain iterations takes a number of iterations that grows with the
    /// square of its width; momentum makes it grow with the width. 0 turns it off.
    pub momentum: f32,
    /// What the springs consider relaxed: the template's own bends and spacing (the default), or
    /// straight, evenly spaced grid lines (Krishnamurthy & Levoy).
    pub rest: SpringRest,
    /// The algorithm.
    pub solver: SolverKind,
}

impl Default for WrapSettings {
    fn default() -> Self {
        Self {
            weights: WrapWeights::default(),
            tolerance: 1e-5,
            landing_distance: 0.25,
            fold_tolerance: 10f32.to_radians(),
            momentum: 0.9,
            rest: SpringRest::Template,
            solver: SolverKind::Springs,
        }
    }
}

impl WrapSettings {
    /// Checks every number is finite and in its range.
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] naming the first bad setting.
    pub fn validate(&self) -> Result<(), KernelError> {
        let weights = self.weights;
        let checks: [(&'static str, f32, f32, f32); 9] = [
            ("fairness weight", weights.fairness, 0.0, 1.0),
            ("arc length weight", weights.arc_length, 0.0, 1.0),
            ("thin plate weight", weights.thin_plate, 0.0, 0.5),
            ("constraint weight", weights.constraint, 0.0, 1.0),
            ("folding weight", weights.folding, 0.0, 1.0),
            ("tolerance", self.tolerance, 0.0, 1.0),
            ("landing distance", self.landing_distance, 0.0, 10.0),
            (
                "fold tolerance",
                self.fold_tolerance,
                0.0,
                std::f32::consts::FRAC_PI_2,
            ),
            ("momentum", self.momentum, 0.0, 0.99),
        ];
        for (name, value, low, high) in checks {
            if !(low..=high).contains(&value) {
                return Err(KernelError::InvalidArgument {
                    name,
                    reason: format!("{value} is outside [{low}, {high}]"),
                });
            }
        }
        Ok(())
    }
}
