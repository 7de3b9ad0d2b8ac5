//! Moving face-points along the target surface.

pub mod walk;

pub use walk::{WalkEnd, WalkOutcome};
