//! # Springwrap kernel
//!
//! The geometry kernel of Springwrap, a tool that retargets a patch layout (a quad retopology
//! mesh) from one model onto another. Pure Rust: it knows nothing of Python or Blender.
//!
//! A [`TargetMesh`] is built once from vertices and triangles; it answers batched, parallel
//! queries: the exact closest point on the surface (the "face tree"), the nearest vertex (the
//! fast "vertex tree") and ray casts (projection). Every layout vertex is a [`LayoutPoint`]:
//! a [`FacePoint`] (a triangle and barycentric coordinates) or a free space-point.
//!
//! ```
//! use glam::Vec3;
//! use springwrap_kernel::{TargetMesh, TargetMeshOptions};
//!
//! // A unit square in the z = 0 plane, two triangles.
//! let vertices = vec![
//!     Vec3::new(0.0, 0.0, 0.0),
//!     Vec3::new(1.0, 0.0, 0.0),
//!     Vec3::new(1.0, 1.0, 0.0),
//!     Vec3::new(0.0, 1.0, 0.0),
//! ];
//! let triangles = vec![[0, 1, 2], [0, 2, 3]];
//! let mesh = TargetMesh::new(vertices, triangles, TargetMeshOptions::default())?;
//!
//! // Snap: the closest surface point, as a face-point.
//! let hit = mesh.closest_point(Vec3::new(0.25, 0.5, 2.0), f32::INFINITY).unwrap();
//! assert_eq!(hit.position, Vec3::new(0.25, 0.5, 0.0));
//! assert_eq!(hit.distance, 2.0);
//! assert_eq!(mesh.face_point_position(hit.face_point)?, hit.position);
//!
//! // Project: cast a ray down the z axis.
//! let hit = mesh.ray_cast(Vec3::new(0.75, 0.5, 1.0), -Vec3::Z, f32::INFINITY, false).unwrap();
//! assert_eq!(hit.distance, 1.0);
//!
//! // Every edge of the square's border is a boundary edge.
//! assert_eq!(mesh.boundary_edges().len(), 4);
//! # Ok::<(), springwrap_kernel::KernelError>(())
//! ```
//!
//! See `docs/architecture.md` in the repository for the layers and the why.

pub mod align;
pub mod bvh;
pub mod cancel;
pub mod correspond;
pub mod error;
pub mod face_point;
pub mod features;
pub mod fit;
pub mod layout;
pub mod mesh;
pub mod parts;
pub mod quality;
pub mod query;
pub mod surface;
pub mod validate;
pub mod wrap;

pub use align::{
    AlignMethod, IcpAnchors, IcpReport, IcpSettings, IcpUpdate, Transform, fit_transform, icp,
    icp_anchored,
};
pub use correspond::{
    GivenPair, Proposal, ProposalLayout, ProposalSettings, propose_correspondences,
};
pub use error::KernelError;
pub use face_point::{FacePoint, LayoutPoint, SurfaceHit, VertexHit};
pub use features::{
    FeatureCurve, FeatureCurveKind, FeatureRegion, FeatureSettings, Features, PrincipalCurvatures,
    automatic_scale, classify_regions, detect_features, mean_edge_length, principal_curvatures,
};
pub use fit::{
    BoundaryRule, FitRound, SubdivisionFit, SubdivisionFitSettings, SubdivisionStencils,
};
pub use layout::{Curve, CurveKind, LayoutStructure, LineTriple};
pub use mesh::{NO_TRIANGLE, TargetMesh, TargetMeshOptions, TriangleEdge};
pub use parts::{FollowSettings, SurfaceFollower, connected_pieces};
pub use quality::{
    DistanceTarget, LayoutFaces, LayoutReadout, PlacedLayout, PlacedReadout, face_normals,
    flipped_faces, layout_readout, placed_readout, vertex_stretch,
};
pub use surface::{WalkEnd, WalkOutcome};
pub use validate::{BARYCENTRIC_RANGE, MAX_COORDINATE};
pub use wrap::{
    Anchor, AnchorTarget, CurveConstraint, PhaseClock, PhaseTimes, PlaneConstraint, SoftPair,
    StepReport, WrapPhase, WrapSchedule, WrapSettings, WrapSolver, WrapWeights,
};
