//! Fuzz targets: one per kernel entry point, fed hostile values by proptest (on stable Rust).
//!
//! Each target generates inputs mixing plausible values (so that the work past the checks runs)
//! with hostile ones: NaN, ±infinity, 3.4e38, 1e30, values just past the kernel's bound, huge
//! and out-of-range counts and indices, empty arrays, degenerate triangles, duplicate vertices.
//! The property is the kernel's promise: it returns `Ok` or one of its documented errors, never
//! panics or aborts, and every number of an `Ok` result is finite.
//!
//! How many cases: each target has a base count (about 25 s for all of them on two shared cores,
//! what `make test` runs), multiplied by `SPRINGWRAP_FUZZ_SCALE` (`make fuzz` runs the long
//! campaign); `PROPTEST_CASES`, when set, is the count of every target instead. A failure is
//! shrunk, and its seed saved in `tests/fuzz/proptest-regressions/<target>.txt`; those files are
//! committed, and every later run replays them first.

#[path = "../common/mod.rs"]
mod common;

mod hostile;

mod align;
mod features;
mod layout;
mod queries;
mod target_mesh;
mod walk;
mod wrap;
