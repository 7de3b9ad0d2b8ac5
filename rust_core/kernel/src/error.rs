//! The kernel's one error type.

use std::fmt;

/// Everything that can go wrong in the kernel. Each variant says when it occurs and what to do.
///
/// Inputs are checked once, at the boundary of each public function; once a [`crate::TargetMesh`]
/// exists, queries on it cannot fail except through their own arguments.
#[derive(Debug, Clone, PartialEq)]
pub enum KernelError {
    /// The mesh has no vertices or no triangles. Give a mesh with at least one triangle.
    EmptyMesh {
        /// Number of vertices given.
        vertex_count: usize,
        /// Number of triangles given.
        triangle_count: usize,
    },
    /// A coordinate of an input is NaN or infinite. Fix or remove that element.
    NonFinite {
        /// Which input: `"vertex"`, `"point"`, `"ray origin"`, `"ray direction"`, `"barycentric"`.
        what: &'static str,
        /// Index of the offending element in its array.
        index: usize,
    },
    /// A triangle refers to a vertex that does not exist.
    VertexIndexOutOfRange {
        /// The triangle.
        triangle: usize,
        /// Its corner (0, 1 or 2).
        corner: usize,
        /// The vertex index found there.
        vertex: u32,
        /// Number of vertices in the mesh.
        vertex_count: usize,
    },
    /// A layout face or edge refers to a vertex that does not exist.
    LayoutIndexOutOfRange {
        /// `"face"`, `"edge"` or `"seam"`.
        element: &'static str,
        /// Index of the face or edge.
        index: usize,
        /// The vertex index found there.
        vertex: u32,
        /// Number of layout vertices.
        vertex_count: usize,
    },
    /// A face-point refers to a triangle that does not exist (e.g. the target lost faces).
    TriangleIndexOutOfRange {
        /// Index of the face-point in its array.
        index: usize,
        /// The triangle it names.
        triangle: u32,
        /// Number of triangles in the mesh.
        triangle_count: usize,
    },
    /// A triangle has zero area; only raised when degenerate triangles are rejected.
    DegenerateTriangle {
        /// The triangle.
        triangle: usize,
    },
    /// Every triangle has zero area: there is no surface to attach points to.
    DegenerateMesh {
        /// Number of triangles, all degenerate.
        triangle_count: usize,
    },
    /// A ray direction has zero length, so it points nowhere.
    ZeroDirection {
        /// Index of the ray.
        index: usize,
    },
    /// Two arrays that must pair up element by element have different lengths.
    LengthMismatch {
        /// Which arrays.
        what: &'static str,
        /// Length of the first.
        first: usize,
        /// Length of the second.
        second: usize,
    },
    /// A scalar argument is outside its domain.
    InvalidArgument {
        /// The argument's name.
        name: &'static str,
        /// Why it was refused.
        reason: String,
    },
    /// An alignment has fewer point pairs than its method needs (3 for a rigid or similarity fit,
    /// 4 for an affine fit; ICP needs as many as its unknowns). Place more anchors.
    TooFewPairs {
        /// What was being solved: `"rigid fit"`, `"similarity fit"`, `"affine fit"`, `"ICP"`.
        what: &'static str,
        /// How many pairs were usable (pairs of zero weight, or trimmed, do not count).
        given: usize,
        /// The least number that can determine it.
        needed: usize,
    },
    /// All anchors of one side sit at one point, so no rotation or scale can be found. Spread them.
    CoincidentAnchors {
        /// `"source"` or `"target"`.
        side: &'static str,
    },
    /// The source (layout) or target anchors lie on one line, so a rigid or similarity fit cannot
    /// tell the rotation about that line. Add an anchor off the line on that side.
    CollinearAnchors {
        /// `"source"` or `"target"`.
        side: &'static str,
        /// Number of anchors.
        count: usize,
    },
    /// The source anchors lie in one plane, so an affine fit cannot find the third axis. Add an
    /// anchor off the plane, or use a rigid or similarity fit.
    CoplanarAnchors {
        /// Number of anchors.
        count: usize,
    },
    /// A feature-detection scale is not a positive finite radius no larger than the mesh's
    /// bounding-box diagonal. Give the radius (model units) over which to fit the surface, e.g. a
    /// few edge lengths, or the radius of the blends sought.
    InvalidScale {
        /// The scale given.
        scale: f32,
        /// The mesh's bounding-box diagonal.
        diagonal: f32,
    },
    /// Feature detection found no curvature: no vertex bends by `|k| × scale ≥ threshold` (a
    /// plane, or a scale far below the surface's features). Nothing is classified or traced.
    /// Pick a curved target, a larger scale or a lower flat threshold.
    FlatSurface {
        /// The largest `|k| × scale` found.
        largest: f32,
        /// The flat threshold it had to reach.
        threshold: f32,
    },
    /// The wrap diverged: a point's position stopped being finite or left the region the wrap
    /// can reach (ten times the size of the target and the layout's start about the target's
    /// centre). The positions are rolled back to where they were before the failing step; lower
    /// the thin plate weight, or use the energy solver.
    Diverged {
        /// The iteration (since the solver was made) at which it was seen.
        iteration: usize,
        /// The point that left.
        vertex: usize,
    },
    /// The input is larger than the kernel's 32-bit indices can address.
    TooLarge {
        /// What is too large.
        what: &'static str,
        /// How many were given.
        count: usize,
        /// The largest supported count.
        max: usize,
    },
    /// A coordinate is finite but beyond the kernel's bound ([`crate::validate::MAX_COORDINATE`]
    /// from the origin, each component): a vertex at 3.4e38 (a float32 infinity clamped by a UI
    /// field) or 1e30 is a broken value, not a place. Fix or remove that element.
    CoordinateOutOfRange {
        /// Which input, as in [`KernelError::NonFinite`].
        what: &'static str,
        /// Index of the offending element in its array.
        index: usize,
        /// The offending coordinate.
        value: f32,
        /// The bound it exceeds.
        limit: f32,
    },
    /// A wrap constraint (an anchor target, a target curve point, the mirror plane) lies beyond
    /// the region the wrap can reach: ten times the size of the target and the layout's start,
    /// about the target's centre (see [`KernelError::Diverged`]). Move it onto or near the target.
    BeyondReach {
        /// `"anchor target"`, `"curve point"` or `"plane"`.
        what: &'static str,
        /// Index of the offending element (the anchor, the curve point; 0 for the plane).
        index: usize,
        /// Its distance from the target's centre.
        distance: f32,
        /// The radius of the region the wrap can reach.
        reach: f32,
    },
    /// The caller asked a long computation to stop (its cancellation check said so); nothing it
    /// would have returned was made.
    Cancelled {
        /// What was stopped, e.g. `"subdivision fit round"`.
        what: &'static str,
    },
}

impl fmt::Display for KernelError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::EmptyMesh {
                vertex_count,
                triangle_count,
            } => write!(
                f,
                "empty mesh: {vertex_count} vertices and {triangle_count} triangles (need at least one triangle)"
            ),
            Self::NonFinite { what, index } => {
                write!(f, "{what} {index} has a NaN or infinite coordinate")
            }
            Self::VertexIndexOutOfRange {
                triangle,
                corner,
                vertex,
                vertex_count,
            } => write!(
                f,
                "triangle {triangle} corner {corner} refers to vertex {vertex}, but the mesh has only {vertex_count} vertices"
            ),
            Self::LayoutIndexOutOfRange {
                element,
                index,
                vertex,
                vertex_count,
            } => write!(
                f,
                "layout {element} {index} refers to vertex {vertex}, but the layout has only {vertex_count} vertices"
            ),
            Self::TriangleIndexOutOfRange {
                index,
                triangle,
                triangle_count,
            } => write!(
                f,
                "face-point {index} refers to triangle {triangle}, but the mesh has only {triangle_count} triangles"
            ),
            Self::DegenerateTriangle { triangle } => {
                write!(f, "triangle {triangle} is degenerate (zero area)")
            }
            Self::DegenerateMesh { triangle_count } => write!(
                f,
                "all {triangle_count} triangles are degenerate (zero area): there is no surface"
            ),
            Self::ZeroDirection { index } => write!(f, "ray {index} has a zero-length direction"),
            Self::LengthMismatch {
                what,
                first,
                second,
            } => write!(f, "{what}: lengths differ ({first} and {second})"),
            Self::InvalidArgument { name, reason } => write!(f, "invalid {name}: {reason}"),
            Self::TooFewPairs {
                what,
                given,
                needed,
            } => write!(
                f,
                "{what}: {given} point pairs given, at least {needed} needed"
            ),
            Self::CoincidentAnchors { side } => write!(
                f,
                "the {side} anchors all sit at one point: no rotation or scale can be found"
            ),
            Self::CollinearAnchors { side, count } => write!(
                f,
                "the {count} {side} anchors lie on one line: the rotation about it is unknown (add one off the line)"
            ),
            Self::CoplanarAnchors { count } => write!(
                f,
                "the {count} anchors are coplanar: an affine fit needs 4 not in one plane"
            ),
            Self::InvalidScale { scale, diagonal } => write!(
                f,
                "invalid feature scale {scale}: give a radius > 0 and at most the mesh's diagonal ({diagonal})"
            ),
            Self::FlatSurface { largest, threshold } => write!(
                f,
                "the surface has no curvature at this scale (largest |k| x scale is {largest:.3}, the flat threshold {threshold}): nothing to detect; raise the scale or lower the flat threshold if it is curved"
            ),
            Self::Diverged { iteration, vertex } => write!(
                f,
                "the wrap diverged at iteration {iteration}: layout vertex {vertex} left the region it can reach \
                 (ten times the target's size); the layout was rolled back to before that step \
                 (lower the thin plate weight, or use the energy solver)"
            ),
            Self::Cancelled { what } => write!(f, "{what} cancelled"),
            Self::TooLarge { what, count, max } => {
                write!(f, "too many {what}: {count} (at most {max} supported)")
            }
            Self::CoordinateOutOfRange {
                what,
                index,
                value,
                limit,
            } => write!(
                f,
                "{what} {index} has a coordinate of {value:e}, beyond the kernel's bound of ±{limit:e} model units"
            ),
            Self::BeyondReach {
                what,
                index,
                distance,
                reach,
            } => write!(
                f,
                "{what} {index} is {distance:e} from the target's centre, beyond the region the wrap can reach \
                 ({reach:e}: ten times the size of the target and the layout's start)"
            ),
        }
    }
}

impl std::error::Error for KernelError {}
