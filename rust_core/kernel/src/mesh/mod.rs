//! The target mesh and what is derived from it once: topology and normals.

pub mod normals;
pub mod target_mesh;
pub mod topology;

pub use target_mesh::{MAX_ELEMENTS, TargetMesh, TargetMeshOptions};
pub use topology::{NO_TRIANGLE, Topology, TriangleEdge};
