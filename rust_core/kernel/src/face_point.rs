//! Layout points: face-points (on a target triangle) and space-points (free in 3D).

use glam::Vec3;

/// A point constrained to the target surface: a triangle and barycentric weights of its corners.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FacePoint {
    /// Index of the target triangle.
    pub triangle: u32,
    /// Weights of the triangle's corners 0, 1, 2 (non-negative, summing to 1).
    pub barycentric: Vec3,
}

/// Every layout vertex is exactly one of these (the paper's section 2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LayoutPoint {
    /// On the target surface; moves with it.
    Face(FacePoint),
    /// Free in 3D (detached, over a hole, or not yet attached).
    Space(Vec3),
}

/// A point found on the target surface by a query.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceHit {
    /// Where on the surface, as a face-point.
    pub face_point: FacePoint,
    /// The same point in space.
    pub position: Vec3,
    /// Distance from the query to `position`; for ray casts the signed ray parameter
    /// (negative behind the origin).
    pub distance: f32,
}

/// A target vertex found by the vertex tree, with a face-point sitting on it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VertexHit {
    /// The vertex index.
    pub vertex: u32,
    /// A face-point on a non-degenerate triangle using the vertex, with weight 1 at that corner.
    pub face_point: FacePoint,
    /// The vertex position.
    pub position: Vec3,
    /// Distance from the query to the vertex.
    pub distance: f32,
}
