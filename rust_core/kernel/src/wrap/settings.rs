//! The wrap's parameters: the five weights of its energy and its stopping and landing controls.

use crate::error::KernelError;
use crate::validate::{SettingRange, check_setting};

/// The weights of the wrap's energy terms (the paper's α, β, γ_tp, γ_con, γ_fold, kept as the
/// energy's weights).
///
/// Each weight scales its terms relative to the default: at the default value a term has the
/// energy's own balance, at twice it twice its weight, at 0 it is off (see `wrap::energy_solver`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WrapWeights {
    /// α: fairness, the second differences along the grid lines (bends and uneven steps compared
    /// with the template's).
    pub fairness: f32,
    /// β: arc length, the edge terms (each edge's length and direction compared with the
    /// template's turned and scaled by its vertex's fit): the spacing along the grid lines.
    pub arc_length: f32,
    /// γ_tp: thin plate, the umbrella terms at points no grid line runs straight through (poles
    /// and the like): the surface continues smoothly around them.
    pub thin_plate: f32,
    /// γ_con: the pull of every free point onto its closest point on the target (the data
    /// term's weight λ at every stiffness level).
    pub constraint: f32,
    /// γ_fold: how far off the surface the layout is still drawn onto it (the data term's reach,
    /// the width of its robust weight): 0 draws nothing onto the target.
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

impl WrapWeights {
    /// Each weight over its default, in the order fairness, arc length, thin plate, constraint,
    /// folding: the factors the energy's terms are scaled by (1 at the defaults).
    #[must_use]
    pub fn relative(&self) -> [f64; 5] {
        let defaults = Self::default();
        let over = |value: f32, default: f32| f64::from(value) / f64::from(default);
        [
            over(self.fairness, defaults.fairness),
            over(self.arc_length, defaults.arc_length),
            over(self.thin_plate, defaults.thin_plate),
            over(self.constraint, defaults.constraint),
            over(self.folding, defaults.folding),
        ]
    }
}

/// How the wrap's stiffness relaxes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum WrapSchedule {
    /// Chosen from the anchors when the wrap starts: [`WrapSchedule::GlobalToLocal`] for a few
    /// anchors (3 to 11), or for more that slide far along the surface from where a similarity
    /// of the template puts them (a change of proportions) without turning each their own way (a
    /// pose); [`WrapSchedule::Local`] otherwise (see `wrap::global_phase::choose_schedule`).
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
    /// The energy's weights.
    pub weights: WrapWeights,
    /// A stiffness level ends once an iteration lowers the energy by less than this fraction of
    /// it (each level also has an iteration limit): smaller runs longer and fits closer.
    pub tolerance: f32,
    /// An anchored space-point lands on its face-point target when closer than this fraction of
    /// the layout's mean edge length; a free point lands (becomes a face-point) at the end when
    /// its closest surface point is within twice it.
    pub landing_distance: f32,
    /// At the end a free point lands (folds onto the surface) only where the layout faces the
    /// target's smoothed normal within this angle, in radians.
    pub fold_tolerance: f32,
    /// The stiffness schedule.
    pub schedule: WrapSchedule,
}

impl Default for WrapSettings {
    fn default() -> Self {
        Self {
            weights: WrapWeights::default(),
            tolerance: Self::DEFAULT_TOLERANCE,
            landing_distance: 0.25,
            fold_tolerance: 75f32.to_radians(),
            schedule: WrapSchedule::default(),
        }
    }
}

impl WrapSettings {
    /// Every numeric setting: its field (the binding's keyword), what it is, and its range. The
    /// one place these ranges are written.
    pub const RANGES: [(&'static str, &'static str, SettingRange); 8] = [
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
        // 0 would never be met: every level would run to its iteration limit.
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
    ];

    /// The default of [`WrapSettings::tolerance`]: a level ends below a 0.2 % decrease.
    pub const DEFAULT_TOLERANCE: f32 = 2e-3;

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
            _ => self.fold_tolerance,
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
        settings.fold_tolerance = 2.0;
        assert!(message(settings).starts_with("invalid fold_tolerance: "));
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
        assert_eq!(settings.validate(), Ok(()));
    }
}
