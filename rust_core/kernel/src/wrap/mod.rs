//! The wrap: a layout moved onto a target by minimising one energy whose weights are the
//! paper's forces (section 2.5).

pub mod anchor;
mod averaging_pyramid;
pub mod curve_constraint;
mod energy_solver;
mod global_phase;
pub mod linear_system;
mod multigrid;
mod ordered_sum;
pub mod plane_constraint;
pub mod profile;
pub mod settings;
mod similarity;
pub mod soft_pair;
pub mod solver;
mod system_assembly;

pub use anchor::{Anchor, AnchorTarget};
pub use curve_constraint::CurveConstraint;
pub use plane_constraint::PlaneConstraint;
pub use profile::{PhaseClock, PhaseTimes, WrapPhase};
pub use settings::{WrapSchedule, WrapSettings, WrapWeights};
pub use soft_pair::SoftPair;
pub use solver::{StepReport, WrapSolver};
