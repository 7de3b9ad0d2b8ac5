//! The wrap's parameters: the five force weights and the iteration controls.

use crate::error::KernelError;
use crate::validate::{SettingRange, check_setting};

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
    Springs,
    /// One energy minimised by local–global steps with a sparse Cholesky, no face turned over
    /// (see `wrap::energy_solver`).
    #[default]
    Energy,
}

/// How the energy wrap's stiffness relaxes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum WrapSchedule {
    /// Chosen from the anchors when the wrap starts: [`WrapSchedule::GlobalToLocal`] for a few
    /// anchors (3 to 11), or for more whose positions no similarity of the template explains (a
    /// large change of shape); [`WrapSchedule::Local`] otherwise (see
    /// `wrap::global_phase::choose_schedule`).
    #[default]
    Auto,
    /// Rotations and one scale for all at first, then local scales: quick, and right when the
    /// layout starts near its place (many anchors, or a small change of shape).
    Local,
    /// Stiff, nearly affine levels first (per-vertex stretches and rotations averaged over many
    /// rings, a weak wide data term), then the local levels: for a few anchors on a large
    /// change of shape, where the local schedule settles into a wrong fit.
    GlobalToLocal,
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
    /// The energy solver's stiffness schedule.
    pub schedule: WrapSchedule,
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
            solver: SolverKind::default(),
            schedule: WrapSchedule::default(),
        }
    }
}

impl WrapSettings {
    /// Every numeric setting: its field (the binding's keyword), what it is, and its range. The
    /// one place these ranges are written.
    pub const RANGES: [(&'static str, &'static str, SettingRange); 9] = [
        (
            "fairness",
            "fairness weight",
            SettingRange::closed(0.0, 1.0),
        ),
        (
            "arc_length",
            "arc length weight",
            SettingRange::closed(0.0, 1.0),
        ),
        (
            "thin_plate",
            "thin plate weight",
            SettingRange::closed(0.0, 0.5),
        ),
        (
            "constraint",
            "constraint weight",
            SettingRange::closed(0.0, 1.0),
        ),
        ("folding", "folding weight", SettingRange::closed(0.0, 1.0)),
        // 0 would never be met: the wrap would always run to its iteration limit.
        ("tolerance", "tolerance", SettingRange::above(0.0, 1.0)),
        (
            "landing_distance",
            "landing distance",
            SettingRange::closed(0.0, 10.0),
        ),
        (
            "fold_tolerance",
            "fold tolerance",
            // (the float32 right angle, so that the setting's own value is inside)
            SettingRange::closed(0.0, std::f32::consts::FRAC_PI_2 as f64),
        ),
        ("momentum", "momentum", SettingRange::closed(0.0, 0.99)),
    ];

    /// The most iterations one [`crate::WrapSolver::step`] call takes (a billion: days of work
    /// on any layout; the wrap stops when it converges anyway).
    pub const MAX_STEP_ITERATIONS: usize = 1_000_000_000;

    /// The numeric setting named `field` (one of [`WrapSettings::RANGES`]).
    fn value_of(&self, field: &str) -> f32 {
        let weights = &self.weights;
        match field {
            "fairness" => weights.fairness,
            "arc_length" => weights.arc_length,
            "thin_plate" => weights.thin_plate,
            "constraint" => weights.constraint,
            "folding" => weights.folding,
            "tolerance" => self.tolerance,
            "landing_distance" => self.landing_distance,
            "fold_tolerance" => self.fold_tolerance,
            _ => self.momentum,
        }
    }

    /// Checks an iteration count for one step: at most [`WrapSettings::MAX_STEP_ITERATIONS`].
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] named `iterations`.
    pub fn check_step_iterations(iterations: usize) -> Result<(), KernelError> {
        check_setting(
            "iterations",
            "number of iterations of one step",
            iterations as f64,
            SettingRange::closed(0.0, Self::MAX_STEP_ITERATIONS as f64),
        )
    }

    /// Checks every number is finite and in its range.
    ///
    /// # Errors
    /// [`KernelError::InvalidArgument`] naming the first bad setting by its field (`fairness`,
    /// `arc_length`, ..., as this struct and [`WrapWeights`] spell it, and as the binding's
    /// keywords do) and saying its range.
    pub fn validate(&self) -> Result<(), KernelError> {
        for (field, label, range) in Self::RANGES {
            check_setting(field, label, self.value_of(field), range)?;
        }
        if self.solver == SolverKind::Energy && self.rest == SpringRest::Even {
            return Err(KernelError::InvalidArgument {
                name: "rest",
                reason:
                    "the even rest shape (straight, evenly spaced grid lines) needs the spring \
                         solver; the energy solver keeps the template's shape"
                        .to_owned(),
            });
        }
        if self.solver == SolverKind::Springs && self.schedule == WrapSchedule::GlobalToLocal {
            return Err(KernelError::InvalidArgument {
                name: "schedule",
                reason: "the global-to-local schedule needs the energy solver; the spring \
                         solver anneals by itself"
                    .to_owned(),
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn message(settings: WrapSettings) -> String {
        settings.validate().unwrap_err().to_string()
    }

    #[test]
    fn the_defaults_are_valid() {
        assert_eq!(WrapSettings::default().validate(), Ok(()));
    }

    #[test]
    fn a_bad_setting_is_named_by_its_field_with_its_range() {
        let defaults = WrapSettings::default();
        let mut settings = defaults;
        settings.weights.thin_plate = 0.7;
        assert_eq!(
            message(settings),
            "invalid thin_plate: the thin plate weight must be within [0, 0.5], not 0.7"
        );
        let mut settings = defaults;
        settings.weights.arc_length = f32::NAN;
        assert_eq!(
            message(settings),
            "invalid arc_length: the arc length weight must be within [0, 1], not NaN"
        );
        let mut settings = defaults;
        settings.momentum = 1.0;
        assert!(message(settings).starts_with("invalid momentum: "));
    }

    #[test]
    fn a_zero_tolerance_is_refused_but_any_other_bound_is_allowed() {
        let mut settings = WrapSettings {
            tolerance: 0.0,
            ..WrapSettings::default()
        };
        assert_eq!(
            message(settings),
            "invalid tolerance: the tolerance must be within (0, 1], not 0"
        );
        settings.tolerance = 1.0;
        settings.weights.fairness = 0.0;
        settings.weights.thin_plate = 0.5;
        settings.momentum = 0.0;
        assert_eq!(settings.validate(), Ok(()));
    }
}
