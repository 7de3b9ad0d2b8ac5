//! The layout side: what the wrap's forces need to know about the layout mesh, and the layout's
//! feature lines.

pub mod feature_lines;
pub mod structure;

pub use feature_lines::{FeatureLine, LineKind, LineSettings, LineSource, feature_lines};
pub use structure::{Curve, CurveKind, LayoutStructure, LineTriple};
