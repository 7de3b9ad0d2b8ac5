//! Alignment of a template to a target before the wrap (the paper's section 2.2): a rigid,
//! similarity or affine fit from anchor pairs, then point-to-plane ICP against the target.

pub mod fit;
pub mod icp;
pub mod linear_algebra;
pub mod transform;

pub use fit::{AlignMethod, fit_transform};
pub use icp::{IcpAnchors, IcpReport, IcpSettings, IcpUpdate, icp, icp_anchored};
pub use transform::Transform;
