//! The wrap: hybrid spring optimisation of a layout onto a target (the paper's section 2.5).

pub mod anchor;
pub mod curve_constraint;
mod energy_solver;
pub mod forces;
mod global_phase;
pub mod linear_system;
pub mod plane_constraint;
pub mod settings;
pub mod soft_pair;
pub mod solver;
mod system_assembly;

pub use anchor::{Anchor, AnchorTarget};
pub use curve_constraint::CurveConstraint;
pub use plane_constraint::PlaneConstraint;
pub use settings::{SolverKind, SpringRest, WrapSchedule, WrapSettings, WrapWeights};
pub use soft_pair::SoftPair;
pub use solver::{StepReport, WrapSolver};
