//! Anchors: a layout vertex paired with a target point.

use glam::Vec3;

use crate::face_point::FacePoint;

/// Where an anchor pulls its layout vertex.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AnchorTarget {
    /// A point on the target surface: the vertex lands there as a face-point.
    Face(FacePoint),
    /// A free point in space (e.g. over a hole): the vertex is pulled there and stays a space-point.
    Space(Vec3),
}

/// A point-to-point correspondence (the paper's section 2.4).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Anchor {
    /// The layout vertex.
    pub vertex: u32,
    /// Its target.
    pub target: AnchorTarget,
}
