//! The layout side: what the wrap's forces need to know about the layout mesh.

pub mod structure;

pub use structure::{Curve, CurveKind, LayoutStructure, LineTriple};
