//! Fitting a subdivision cage to the target: Catmull–Clark stencils (Blender's rules) and the
//! Gauss–Newton rounds that move the cage so that its subdivided surface lies on the target.

pub mod catmull_clark;
pub mod subdivision_fit;

pub use catmull_clark::{BoundaryRule, MAX_LEVELS, SubdivisionStencils};
pub use subdivision_fit::{FitRound, POINTS_PER_CHECK, SubdivisionFit, SubdivisionFitSettings};
