//! Parts: pieces of a layout that the target does not have (eyeballs, teeth, tongue, lashes) and
//! that follow the deformation of the layout's surface around them instead of being pulled onto
//! the target.
//!
//! - [`connected_pieces`]: the layout's separate pieces (connected components of its edges);
//! - [`SurfaceFollower`]: made once from the surface and the parts at rest (where the wrap starts),
//!   it moves the parts by the surface's motion: each part vertex is bound to its nearest surface
//!   vertices (compactly supported inverse-distance weights); a **rigid** piece moves by the best
//!   similarity (rotation and translation, and a uniform scale when asked; Horn's rotation) of the
//!   weighted motion of the surface around the whole piece, so it keeps its shape (an eyeball
//!   stays a sphere); a **soft** vertex moves by the best similarity of its own neighbourhood's
//!   motion (moving least squares), so a soft piece bends with its surface (lashes with their lid).
//!
//! Positions are f64. Inputs are checked once, at the boundary: coordinates finite and within
//! [`crate::MAX_COORDINATE`], lengths paired, indices in range.

mod follow;
mod neighbours;
mod pieces;

pub use follow::{FollowSettings, SurfaceFollower};
pub use pieces::connected_pieces;
